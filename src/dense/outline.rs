//! Moving regions outlined at pixel resolution.
//!
//! The grid knows where something moves only to a cell and a window: on an 8 px grid with 9 px
//! windows a 10 px object moves a block of nodes about twice its size, and two objects a few
//! pixels apart move one block between them; a small object faster than LK's reach leaves
//! nodes that match nothing. An [`Outliner`] looks at the pixels of each candidate box (grown
//! by a margin) in the previous frame and asks which motion explains each one: the camera's,
//! or one of a few object flows. Those come from a vote on pyramid level 1 (each pixel the
//! camera does not explain votes for the whole-pixel shift that matches it best), from the
//! candidate's own flow and from its moving nodes, and are refined by Gauss-Newton on the
//! pixels that chose them. A pixel belongs to an object when one of those flows matches its
//! 3 x 3 neighbourhood in the next frame clearly better than the camera's flow does (sums of
//! absolute differences, the next frame sampled bilinearly) and better than its own texture
//! would allow a misaligned match to. Connected object pixels whose flows agree within a pixel
//! make one outline; its box is theirs, and its flow the flow most of them chose.
//!
//! So two objects that share a region but not a pixel get a box each, a box fits its object to
//! the pixel, and a region whose nodes were mismeasured (on still ground every pixel matches
//! the camera) gives no box at all.
//!
//! Pixels the camera carries out of the next frame cannot be told and belong to nothing. A
//! candidate too large for the scratch keeps its grid box: it is a large object, which the grid
//! already boxes well.
//!
//! The work is bounded by the candidate's area: per level-1 pixel the camera does not explain,
//! one 3 x 3 difference per shift within the reach; per level-0 pixel and labelling, one
//! bilinear sample and one difference per flow tried (at most [`MAX_FLOWS`], the camera's and
//! the texture), and the sums of three rows kept in a ring. It is host-sized work: on the
//! STM32F405 one 160 x 120 frame's outlines cost millions of instructions (see
//! `firmware/README.md`).
//!
//! ```
//! use kestrel::dense::grid::{grid_len, GridLayout, GridNode};
//! use kestrel::dense::mask::{mask_words, set};
//! use kestrel::dense::motion::CameraMotion;
//! use kestrel::dense::outline::{outline_scratch_len, OutlineParams, Outliner};
//! use kestrel::dense::regions::MotionBox;
//! use kestrel::frame::ImageView;
//! use kestrel::pyramid::{pyramid_storage_len, Pyramid};
//! use kestrel::Point;
//!
//! // A still camera over ground with a 10 x 10 object that moves 3 px right.
//! const W: usize = 64;
//! const H: usize = 48;
//! let ground = |x: usize, y: usize| ((x * 7 + y * 13 + (x * y) % 11 * 19) % 200) as u8;
//! let object = |x: usize, y: usize| ((x * 29 + y * 5 + (x ^ y) * 23) % 240) as u8 + 10;
//! let frame = |shift: usize| -> [u8; W * H] {
//!     core::array::from_fn(|i| {
//!         let (x, y) = (i % W, i / W);
//!         let inside = (20 + shift..30 + shift).contains(&x) && (16..26).contains(&y);
//!         if inside { object(x - shift, y) } else { ground(x, y) }
//!     })
//! };
//! let (a, b) = (frame(0), frame(3));
//! let mut storage = [[0u8; pyramid_storage_len(W, H, 1)]; 2];
//! let [sa, sb] = &mut storage;
//! let prev = Pyramid::build(ImageView::packed(&a, W, H).unwrap(), 1, sa).unwrap();
//! let next = Pyramid::build(ImageView::packed(&b, W, H).unwrap(), 1, sb).unwrap();
//!
//! // The grid found the object's motion at two nodes, in a region boxed from 16 to 40 px.
//! let layout = GridLayout::new(W, H, 8).unwrap();
//! let mut nodes = [GridNode::tracked(Point::default()); grid_len(W, H, 8)];
//! let mut mask = [0u32; mask_words(W, H, 8)];
//! for (col, row) in [(2, 2), (3, 2)] {
//!     let index = layout.index(col, row).unwrap();
//!     nodes[index] = GridNode::tracked(Point::from_f32(3.0, 0.0));
//!     set(&mut mask, index, true);
//! }
//! struct Still;
//! impl CameraMotion for Still {
//!     fn predict(&self, _: f32, _: f32) -> (f32, f32) { (0.0, 0.0) }
//! }
//! let candidate = MotionBox { x: 16, y: 12, w: 24, h: 16, nodes: 2, mean_flow: Point::from_f32(3.0, 0.0) };
//!
//! let outliner = Outliner::new(OutlineParams::default()).unwrap();
//! let mut scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
//! let mut boxes = [MotionBox::default(); 4];
//! let n = outliner
//!     .outline(&prev, &next, &Still, &layout, &nodes, &mask, &[candidate], &mut scratch, &mut boxes)
//!     .unwrap();
//! assert_eq!(n, 1);
//! // The object's 10 x 10 pixels from (20, 16), to within a pixel on every side.
//! let b = boxes[0];
//! let sides = [(b.x, 20), (b.y, 16), (b.x + b.w, 30), (b.y + b.h, 26)];
//! assert!(sides.iter().all(|&(got, want)| got.abs_diff(want) <= 1), "{b:?}");
//! let (dx, dy) = boxes[0].mean_flow.to_f32();
//! assert!((dx - 3.0).abs() < 0.1 && dy.abs() < 0.1);
//! ```

use super::grid::{GridLayout, GridNode};
use super::mask::contains;
use super::motion::CameraMotion;
use super::regions::MotionBox;
use super::DenseError;
use crate::frame::ImageView;
use crate::pyramid::Pyramid;
use crate::q16::{q16_from_f32, Point, Q16};

/// The most object flows tried at one candidate (besides the camera's): up to
/// [`VOTED_FLOWS`] from the vote, the candidate's own, and its nodes'.
pub const MAX_FLOWS: usize = 6;

/// The most flows taken from the vote: the objects one candidate region holds, which on
/// an 8 px grid is rarely more than three.
pub const VOTED_FLOWS: usize = 3;

/// The widest and highest area a scratch can hold: pixel indices are `u16`.
pub const MAX_SIDE: usize = 255;

/// The smallest [`OutlineParams::side`]: the labelling keeps four rows of sums where the
/// flood fill's stack (`side` x `side`) will be.
pub const MIN_SIDE: usize = 8;

/// The largest [`OutlineParams::reach`], px: 65 x 65 bins at most.
pub const MAX_REACH: usize = 128;

/// Bits of a sample below the grey level: samples and differences are grey x 16.
const SUB_BITS: u32 = 4;

/// A difference the camera cannot give: its sample lies outside the next frame. Above any
/// 3 x 3 sum of real differences (9 x 255 x 16 = 36 720), so any sum it enters is too.
const UNKNOWN: u16 = u16::MAX;

/// Flows closer than this on both axes are tried once, Q16 (half a pixel).
const SAME_FLOW: i32 = 1 << 15;

/// Neighbouring object pixels join one outline when their flows differ by at most this on
/// both axes, Q16 (one pixel).
const JOINED_FLOW: i32 = 1 << 16;

/// Scratch, in `u16`, for areas up to `side` x `side` pixels and motions up to `reach` px:
/// the pixel labels, a flood-fill stack, the three-row ring of differences of every flow
/// tried, and the vote's bins. The vote on level 1 borrows the labels and the stack.
///
/// ```
/// use kestrel::dense::outline::{outline_scratch_len, OutlineParams};
/// // Labels and stack, 8 x 3 ring rows of 50, 9 x 9 vote bins.
/// assert_eq!(outline_scratch_len(48, 8), 2 * 48 * 48 + 24 * 50 + 81);
/// const LEN: usize = outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8);
/// static mut SCRATCH: [u16; LEN] = [0; LEN];
/// ```
pub const fn outline_scratch_len(side: usize, reach: usize) -> usize {
    let pixels = side.saturating_mul(side);
    let ring = RING_ROWS * side.saturating_add(2);
    pixels
        .saturating_mul(2)
        .saturating_add(ring)
        .saturating_add(bins(reach))
}

/// Rows of the ring: three for the camera, each flow, and the texture.
const RING_ROWS: usize = (MAX_FLOWS + 2) * 3;

/// Bins of the vote over shifts of up to `reach` px (`reach / 2` on the level searched).
const fn bins(reach: usize) -> usize {
    let side = (reach / 2).saturating_mul(2).saturating_add(1);
    side.saturating_mul(side)
}

/// How candidates are outlined.
///
/// A still camera over ground where a 10 x 10 object moves 3 px right, boxed by the grid
/// (the setup of the module example):
///
/// ```
/// # use kestrel::dense::grid::{grid_len, GridLayout, GridNode};
/// # use kestrel::dense::mask::{mask_words, set};
/// # use kestrel::dense::motion::CameraMotion;
/// # use kestrel::dense::outline::{outline_scratch_len, OutlineParams, Outliner};
/// # use kestrel::dense::regions::MotionBox;
/// # use kestrel::frame::ImageView;
/// # use kestrel::pyramid::{pyramid_storage_len, Pyramid};
/// # use kestrel::Point;
/// #
/// # // A still camera over ground with a 10 x 10 object that moves 3 px right.
/// # const W: usize = 64;
/// # const H: usize = 48;
/// # let ground = |x: usize, y: usize| ((x * 7 + y * 13 + (x * y) % 11 * 19) % 200) as u8;
/// # let object = |x: usize, y: usize| ((x * 29 + y * 5 + (x ^ y) * 23) % 240) as u8 + 10;
/// # let frame = |shift: usize| -> [u8; W * H] {
/// #     core::array::from_fn(|i| {
/// #         let (x, y) = (i % W, i / W);
/// #         let inside = (20 + shift..30 + shift).contains(&x) && (16..26).contains(&y);
/// #         if inside { object(x - shift, y) } else { ground(x, y) }
/// #     })
/// # };
/// # let (a, b) = (frame(0), frame(3));
/// # let mut storage = [[0u8; pyramid_storage_len(W, H, 1)]; 2];
/// # let [sa, sb] = &mut storage;
/// # let prev = Pyramid::build(ImageView::packed(&a, W, H).unwrap(), 1, sa).unwrap();
/// # let next = Pyramid::build(ImageView::packed(&b, W, H).unwrap(), 1, sb).unwrap();
/// #
/// # // The grid found the object's motion at two nodes, in a region boxed from 16 to 40 px.
/// # let layout = GridLayout::new(W, H, 8).unwrap();
/// # let mut nodes = [GridNode::tracked(Point::default()); grid_len(W, H, 8)];
/// # let mut mask = [0u32; mask_words(W, H, 8)];
/// # for (col, row) in [(2, 2), (3, 2)] {
/// #     let index = layout.index(col, row).unwrap();
/// #     nodes[index] = GridNode::tracked(Point::from_f32(3.0, 0.0));
/// #     set(&mut mask, index, true);
/// # }
/// # struct Still;
/// # impl CameraMotion for Still {
/// #     fn predict(&self, _: f32, _: f32) -> (f32, f32) { (0.0, 0.0) }
/// # }
/// # let candidate = MotionBox { x: 16, y: 12, w: 24, h: 16, nodes: 2, mean_flow: Point::from_f32(3.0, 0.0) };
/// #
/// let outline = |params: OutlineParams| {
///     let mut scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
///     let mut boxes = [MotionBox::default(); 4];
///     let outliner = Outliner::new(params).unwrap();
///     outliner
///         .outline(&prev, &next, &Still, &layout, &nodes, &mask, &[candidate], &mut scratch, &mut boxes)
///         .unwrap()
/// };
/// assert_eq!(outline(OutlineParams::default()), 1);
/// // The object's 100 pixels are too few for an outline of at least 200.
/// assert_eq!(outline(OutlineParams { min_pixels: 200, ..OutlineParams::default() }), 0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutlineParams {
    /// Pixels added on every side of a candidate box before it is searched. A region's box is
    /// its cells inset by half a window ([`super::regions::BoxRules::inset`], 4 px); 6 px
    /// gives back those 4 and 2 px more for an object the nodes saw only in part.
    pub margin: usize,
    /// How much better, in grey levels per pixel of the 3 x 3 neighbourhood, an object's flow
    /// must match than the camera's, besides matching at most half as badly and better than
    /// half the texture there: a floor under those two ratios where both matches are close
    /// to noise. On the seeded flights of `bench/motion_vs_truth.py` (noise 1.5 grey levels),
    /// 2 found more objects and fewer false ones than 4 or 6.
    pub min_gain: u16,
    /// Smallest outline, pixels: smaller groups are chance matches.
    pub min_pixels: usize,
    /// Gauss-Newton steps of each flow on the pixels that chose it, each followed by a new
    /// labelling: a node's flow is measured over a window that also sees the ground, so the
    /// object's own pixels give its flow more exactly, and more of them then match.
    pub refinements: usize,
    /// The widest and highest area searched, px, [`MIN_SIDE`] to [`MAX_SIDE`]: the scratch is
    /// [`outline_scratch_len`] of it.
    pub side: usize,
    /// The largest motion searched beside the camera's, px, on each axis: the objects' flows
    /// are found by a vote of the area's pixels over the shifts within this reach, on pyramid
    /// level 1. At most [`MAX_REACH`].
    pub reach: usize,
}

impl OutlineParams {
    /// The default [`OutlineParams::side`]: a region of 4 x 4 nodes of 8 px and its margins.
    pub const DEFAULT_SIDE: usize = 48;
}

impl Default for OutlineParams {
    fn default() -> Self {
        Self {
            margin: 6,
            min_gain: 2,
            min_pixels: 16,
            refinements: 2,
            side: Self::DEFAULT_SIDE,
            reach: 8,
        }
    }
}

/// Outlines moving regions at pixel resolution. See the module documentation.
#[derive(Debug, Clone, Copy)]
pub struct Outliner {
    params: OutlineParams,
}

/// The pixels of one candidate searched, in the previous frame.
#[derive(Debug, Clone, Copy)]
struct Area {
    x: usize,
    y: usize,
    w: usize,
    h: usize,
}

/// The flows tried at one candidate, Q16.
struct Flows {
    flows: [Point; MAX_FLOWS],
    len: usize,
}

impl Flows {
    const EMPTY: Self = Self {
        flows: [Point::from_bits(0, 0); MAX_FLOWS],
        len: 0,
    };

    /// Adds `flow` unless it is full or a flow within [`SAME_FLOW`] is there.
    fn add(&mut self, flow: Point) {
        let known = self
            .flows
            .iter()
            .take(self.len)
            .any(|f| close(f, &flow, SAME_FLOW));
        if let Some(slot) = self.flows.get_mut(self.len).filter(|_| !known) {
            *slot = flow;
            self.len += 1;
        }
    }
}

/// A camera's flow on pyramid level 1: half its flow at twice the coordinates.
struct Scaled<'a, C>(&'a C);

impl<C: CameraMotion> CameraMotion for Scaled<'_, C> {
    fn predict(&self, x: f32, y: f32) -> (f32, f32) {
        let (dx, dy) = self.0.predict(2.0 * x, 2.0 * y);
        (0.5 * dx, 0.5 * dy)
    }
}

/// Half of a level-0 flow, rounded to a whole level-1 pixel; 0 for NaN or out of reach.
fn round_half(v: f32) -> i32 {
    (flow_bits(v) + (1 << 16)) >> 17
}

/// Differences between `prev` and `next` sampled at the camera's flow, over the area and a
/// pixel around it, into `rows` (`area.w + 2` a row); [`UNKNOWN`] where the camera's sample
/// leaves `next`.
fn camera_costs(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    area: &Area,
    camera: &dyn CameraMotion,
    rows: &mut [u16],
) {
    let row_len = area.w + 2;
    // The vote's area is at most (side / 2 + 1) px on a side, so its rows and the pixel around
    // them, (side / 2 + 3)^2 <= side^2 for a side of at least MIN_SIDE, fit in the labels'
    // side x side. Checked once, before any row is written.
    let needed = (area.h + 2) * row_len;
    debug_assert!(
        rows.len() >= needed,
        "camera costs: {} < {needed}",
        rows.len()
    );
    let Some(rows) = rows.get_mut(..needed) else {
        return;
    };
    for (r, out) in rows.chunks_exact_mut(row_len).enumerate() {
        camera_row(prev, next, camera, area, area.y + r - 1, out);
    }
}

/// How many times a flow's 3 x 3 mismatch the texture of the previous frame there must be:
/// the sum of absolute differences to the right and below neighbours is what a one-pixel
/// misalignment costs, so a pixel whose match is not clearly better than that (flat ground,
/// which any flow matches) belongs to no object.
const TEXTURE_RATIO: u32 = 2;

/// The previous frame's texture along row `y`: the absolute differences of each pixel to its
/// right and lower neighbours, summed, grey x 16.
fn texture_row(prev: &ImageView<'_>, area: &Area, y: usize, out: &mut [u16]) {
    let first = area.x - 1;
    let (here, below) = (prev.row(y), prev.row(y + 1));
    for (i, slot) in out.iter_mut().enumerate() {
        let x = first + i;
        let p = here.get(x).map_or(0, |&v| i32::from(v));
        let right = here.get(x + 1).map_or(p, |&v| i32::from(v));
        let down = below.get(x).map_or(p, |&v| i32::from(v));
        // At most 2 x 255 x 16 < 2^16.
        *slot = (((right - p).unsigned_abs() + (down - p).unsigned_abs()) << SUB_BITS) as u16;
    }
}

/// The sum of absolute differences, grey x 16, between the 3 x 3 neighbourhood of (`x`, `y`)
/// in `prev` and the one `shift` away from it in `next`; the largest sum where that one is
/// not wholly inside `next`.
fn sad3(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    (x, y): (usize, usize),
    (dx, dy): (i32, i32),
) -> u32 {
    const OUTSIDE: u32 = 9 * (255 << SUB_BITS);
    let (px, py) = (x as isize - 1, y as isize - 1);
    let (Some(a), Some(b)) = (
        prev.block(px, py, 3, 3),
        next.block(px + dx as isize, py + dy as isize, 3, 3),
    ) else {
        return OUTSIDE;
    };
    let (sa, sb) = (prev.stride(), next.stride());
    let mut sum = 0u32;
    for r in 0..3 {
        for c in 0..3 {
            let (p, q) = (a.get(r * sa + c), b.get(r * sb + c));
            sum += p.zip(q).map_or(255, |(&p, &q)| u32::from(p.abs_diff(q)));
        }
    }
    sum << SUB_BITS
}

impl Outliner {
    /// Validates `params`: a side of [`MIN_SIDE`] to [`MAX_SIDE`] px and a reach of at most
    /// [`MAX_REACH`] px.
    ///
    /// ```
    /// use kestrel::dense::outline::{OutlineParams, Outliner, MAX_SIDE};
    /// use kestrel::dense::DenseError;
    /// let wide = OutlineParams { side: MAX_SIDE + 1, ..OutlineParams::default() };
    /// assert_eq!(Outliner::new(wide).unwrap_err(), DenseError::BadOutline);
    /// ```
    pub fn new(params: OutlineParams) -> Result<Self, DenseError> {
        if !(MIN_SIDE..=MAX_SIDE).contains(&params.side) || params.reach > MAX_REACH {
            return Err(DenseError::BadOutline);
        }
        Ok(Self { params })
    }

    /// The parameters this outliner was built with.
    ///
    /// ```
    /// use kestrel::dense::outline::{OutlineParams, Outliner};
    /// let params = OutlineParams { margin: 2, side: 32, reach: 4, ..OutlineParams::default() };
    /// assert_eq!(*Outliner::new(params).unwrap().params(), params);
    /// ```
    pub fn params(&self) -> &OutlineParams {
        &self.params
    }

    /// Outlines each of `candidates` (boxes in `prev` from [`super::motion::MotionDetector`],
    /// whose cleaned mask `mask` is) and writes the outlines into `boxes`, in the candidates'
    /// order; returns how many it wrote. A candidate gives no outline, one, or several; one too
    /// large for the scratch is copied as it is. An outline that mostly covers one written
    /// before (two candidates' margins meeting on one object) is not written again. `scratch`
    /// is [`outline_scratch_len`] of [`OutlineParams::side`] and [`OutlineParams::reach`];
    /// the vote needs level 1 of both pyramids, and without it only the candidate's and its
    /// nodes' flows are tried.
    ///
    /// An outline's `nodes` are its candidate's, and its `mean_flow` the flow most of its
    /// pixels chose. See the module example.
    #[allow(clippy::too_many_arguments)]
    pub fn outline(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: &impl CameraMotion,
        layout: &GridLayout,
        nodes: &[GridNode],
        mask: &[u32],
        candidates: &[MotionBox],
        scratch: &mut [u16],
        boxes: &mut [MotionBox],
    ) -> Result<usize, DenseError> {
        let (base, next_base) = (prev.base(), next.base());
        if !base.same_size(&next_base)
            || base.width() != layout.width()
            || base.height() != layout.height()
        {
            return Err(DenseError::FrameSizeMismatch);
        }
        if nodes.len() < layout.len() {
            return Err(DenseError::NodesTooShort);
        }
        if scratch.len() < outline_scratch_len(self.params.side, self.params.reach) {
            return Err(DenseError::ScratchTooSmall);
        }
        let pixels = self.params.side.saturating_mul(self.params.side);
        let (labels, rest) = scratch.split_at_mut(pixels);
        let (stack, rest) = rest.split_at_mut(pixels);
        let (ring, votes) = rest.split_at_mut(RING_ROWS * (self.params.side + 2));
        let mut written = 0usize;
        for candidate in candidates {
            let Some(area) = self.area(&base, candidate) else {
                written = push_new(boxes, written, *candidate);
                continue;
            };
            let mut flows = match (prev.level(1), next.level(1)) {
                (Some(prev1), Some(next1)) => {
                    let (mut flows, half) =
                        self.vote(&prev1, &next1, camera, &area, labels, stack, votes);
                    // The vote's flows are whole level-1 pixels: to a pixel at level 0 at best.
                    // Its voters (in `stack` past the level-1 pixels' costs) refine them. The
                    // level-1 area is at most a quarter of the stack's side x side, so the
                    // range is never empty; were it, no pixel would take part (label 0).
                    debug_assert!(half.w * half.h <= stack.len());
                    let voters = stack.get(half.w * half.h..).unwrap_or(&[]);
                    for _ in 0..self.params.refinements {
                        refine(&base, &next_base, &area, &mut flows, |col, row| {
                            let (x, y) = ((area.x + col) / 2, (area.y + row) / 2);
                            let inside = (half.x..half.x + half.w).contains(&x)
                                && (half.y..half.y + half.h).contains(&y);
                            if !inside {
                                return 0;
                            }
                            // Inside the level-1 area, so both differences are >= 0 and
                            // the index is below half.w * half.h, the voters' length.
                            let at = (y - half.y) * half.w + (x - half.x);
                            debug_assert!(at < voters.len());
                            voters.get(at).copied().unwrap_or(0)
                        });
                    }
                    flows
                }
                // A pyramid of one level: no vote, the nodes' flows alone.
                _ => Flows::EMPTY,
            };
            // The candidate's own flow: a region's mean, or where a box of the pair before
            // said its object would be.
            flows.add(candidate.mean_flow);
            // And the flows its moving nodes measured: a slow object's, which the vote's whole
            // pixels do not resolve.
            let measured = flows_in(layout, nodes, mask, &area);
            for flow in measured.flows.iter().take(measured.len) {
                flows.add(*flow);
            }
            if flows.len == 0 {
                continue;
            }
            self.label(
                &base, &next_base, camera, &area, &flows, labels, ring, stack,
            );
            for _ in 0..self.params.refinements {
                refine(&base, &next_base, &area, &mut flows, |col, row| {
                    labels.get(row * area.w + col).copied().unwrap_or(0)
                });
                self.label(
                    &base, &next_base, camera, &area, &flows, labels, ring, stack,
                );
            }
            written = self.gather(&area, &flows, candidate, labels, stack, boxes, written);
        }
        Ok(written)
    }

    /// The objects' flows in `area`, by a vote on pyramid level 1: each pixel there that the
    /// camera's flow does not explain votes for the whole-pixel shift (within the reach of the
    /// camera's flow at the area's centre) whose 3 x 3 neighbourhood matches best; the
    /// [`VOTED_FLOWS`] shifts with the most votes, each at least a quarter of
    /// [`OutlineParams::min_pixels`] (a level-1 pixel is four), are the flows, doubled to
    /// level 0. Each voter's flow (its shift's, or a chosen one beside it) is left in `best`
    /// past the level-1 pixels, for the first refinement.
    #[allow(clippy::too_many_arguments)]
    fn vote(
        &self,
        prev: &ImageView<'_>,
        next: &ImageView<'_>,
        camera: &impl CameraMotion,
        area: &Area,
        diffs: &mut [u16],
        best: &mut [u16],
        votes: &mut [u16],
    ) -> (Flows, Area) {
        let half = Area {
            x: (area.x / 2).max(1),
            y: (area.y / 2).max(1),
            w: area
                .w
                .div_ceil(2)
                .min(prev.width().saturating_sub(area.x / 2 + 1)),
            h: area
                .h
                .div_ceil(2)
                .min(prev.height().saturating_sub(area.y / 2 + 1)),
        };
        let reach = (self.params.reach / 2) as i32;
        let side = 2 * reach as usize + 1;
        votes.iter_mut().take(side * side).for_each(|v| *v = 0);
        let (cx, cy) = camera.predict((area.x + area.w / 2) as f32, (area.y + area.h / 2) as f32);
        let centre = (round_half(cx), round_half(cy));
        let pixels = half.w * half.h;
        let (best_cost, best_shift) = best.split_at_mut(pixels);
        // The camera's costs first: a pixel it explains votes for nothing.
        let level1 = Scaled(camera);
        camera_costs(prev, next, &half, &level1, diffs);
        let row_len = half.w + 2;
        for (row, costs) in best_cost.chunks_mut(half.w.max(1)).enumerate() {
            // Rows below half.h + 2, all written by camera_costs (see there for why they fit).
            let rows = diffs.get(row * row_len..(row + 3) * row_len);
            debug_assert!(rows.is_some(), "vote: row {row} of the camera's costs");
            sums3(rows.unwrap_or(&[]), half.w, |x, e| costs[x] = e);
        }
        let gain = (9 * u32::from(self.params.min_gain)) << SUB_BITS;
        let (camera_costs, shifts) = (best_cost, best_shift);
        for (i, (cam, shift)) in camera_costs.iter().zip(shifts.iter_mut()).enumerate() {
            let cam = u32::from(*cam);
            *shift = NO_BIN;
            // A pixel whose camera match is within the gain cannot vote: skip its search.
            if cam >= u32::from(UNKNOWN) || cam <= gain {
                continue;
            }
            let (x, y) = (half.x + i % half.w, half.y + i / half.w);
            let mut best = (u32::MAX, NO_BIN);
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let e = sad3(prev, next, (x, y), (centre.0 + dx, centre.1 + dy));
                    if e < best.0 {
                        let bin = (dy + reach) as usize * side + (dx + reach) as usize;
                        best = (e, bin as u16);
                    }
                }
            }
            if best.0 + gain < cam && 2 * best.0 < cam {
                if let Some(v) = votes.get_mut(usize::from(best.1)) {
                    *v = v.saturating_add(1);
                    *shift = best.1;
                }
            }
        }
        let mut flows = Flows::EMPTY;
        let mut chosen = [NO_BIN; MAX_FLOWS];
        let floor = (self.params.min_pixels / 4).max(1);
        // The shifts with the most votes, without suppressing their neighbours: two objects
        // a pixel apart in flow vote for neighbouring shifts.
        while flows.len < VOTED_FLOWS {
            let Some((bin, count)) = votes
                .iter_mut()
                .take(side * side)
                .enumerate()
                .max_by_key(|(_, v)| **v)
            else {
                break;
            };
            if usize::from(*count) < floor {
                break;
            }
            *count = 0;
            let (bx, by) = ((bin % side) as i32, (bin / side) as i32);
            let level0 = |c: i32, d: i32| Q16::from_bits((c + d - reach) << 17);
            let before = flows.len;
            flows.add(Point::new(level0(centre.0, bx), level0(centre.1, by)));
            if let Some(slot) = chosen.get_mut(before).filter(|_| flows.len > before) {
                *slot = bin as u16;
            }
        }
        // A voter's flow is its shift's, or a chosen shift's beside its own.
        let near = |a: u16, b: u16| {
            let (a, b, side) = (i32::from(a), i32::from(b), side as i32);
            (a % side - b % side).abs() <= 1 && (a / side - b / side).abs() <= 1
        };
        for s in shifts.iter_mut() {
            let own = chosen.iter().position(|&c| c == *s);
            let beside = || {
                chosen
                    .iter()
                    .position(|&c| c != NO_BIN && *s != NO_BIN && near(c, *s))
            };
            *s = own.or_else(beside).map_or(0, |k| k as u16 + 1);
        }
        (flows, half)
    }

    /// The candidate grown by the margin, clipped to the pixels whose 3 x 3 neighbourhood is
    /// inside the frame; `None` when it is wider or higher than the scratch's side.
    fn area(&self, frame: &ImageView<'_>, b: &MotionBox) -> Option<Area> {
        let margin = self.params.margin;
        let span = |start: u16, len: u16, size: usize| {
            let lo = usize::from(start).saturating_sub(margin).max(1);
            let hi = usize::from(start)
                .saturating_add(usize::from(len))
                .saturating_add(margin)
                .min(size.saturating_sub(1));
            (lo, hi.saturating_sub(lo))
        };
        let (x, w) = span(b.x, b.w, frame.width());
        let (y, h) = span(b.y, b.h, frame.height());
        let fits = (1..=self.params.side).contains(&w) && (1..=self.params.side).contains(&h);
        fits.then_some(Area { x, y, w, h })
    }

    /// Writes each pixel's label into `labels` (row by row, `area.w` a row): 0 for the camera
    /// or nothing, `k + 1` for object flow `k`. `rows` holds four rows of sums (the stack is
    /// free while labelling).
    #[allow(clippy::too_many_arguments)]
    fn label(
        &self,
        prev: &ImageView<'_>,
        next: &ImageView<'_>,
        camera: &impl CameraMotion,
        area: &Area,
        flows: &Flows,
        labels: &mut [u16],
        ring: &mut [u16],
        rows: &mut [u16],
    ) {
        let hypotheses = flows.len.saturating_add(1);
        let row_len = area.w.saturating_add(2);
        // The ring holds three rows for each of the MAX_FLOWS + 2 hypotheses at the scratch's
        // side, and the area is at most that side wide, so every row below fits. Checked once
        // here so that a broken scratch leaves no pixel labelled from an older labelling.
        let needed = (hypotheses + 1) * 3 * row_len;
        let fits =
            ring.len() >= needed && rows.len() >= 4 * area.w && labels.len() >= area.w * area.h;
        debug_assert!(fits, "labelling scratch too short for {area:?}");
        if !fits {
            labels.fill(0);
            return;
        }
        // One row of 3 x 3 sums needs rows y - 1, y and y + 1 of differences: each new row
        // of differences completes the sums of the row above it.
        for yy in area.y.saturating_sub(1)..=area.y.saturating_add(area.h) {
            let slot = yy % 3;
            for h in 0..=hypotheses {
                let start = (h * 3 + slot) * row_len;
                // Inside `needed`, checked above.
                let Some(row) = ring.get_mut(start..start.saturating_add(row_len)) else {
                    continue;
                };
                match h {
                    0 => camera_row(prev, next, camera, area, yy, row),
                    _ if h == hypotheses => texture_row(prev, area, yy, row),
                    _ => flow_row(prev, next, area, yy, flows.flows.get(h - 1), row),
                }
            }
            if yy > area.y {
                self.decide_row(area, yy - 1, hypotheses, ring, rows, labels);
            }
        }
    }

    /// Labels row `y` of the area from the three rows of differences around it: each
    /// hypothesis's 3 x 3 sums along the row from running column sums, the best object flow's
    /// kept in `rows` beside the camera's and the texture's.
    fn decide_row(
        &self,
        area: &Area,
        y: usize,
        hypotheses: usize,
        ring: &[u16],
        rows: &mut [u16],
        labels: &mut [u16],
    ) {
        let w = area.w;
        let (camera, rest) = rows.split_at_mut(w);
        let (texture, rest) = rest.split_at_mut(w);
        let (best, rest) = rest.split_at_mut(w);
        let (chosen, _) = rest.split_at_mut(w.min(rest.len()));
        best.iter_mut().for_each(|b| *b = u16::MAX);
        for h in 0..=hypotheses {
            let kind = match h {
                0 => Sums::Camera,
                _ if h == hypotheses => Sums::Texture,
                _ => Sums::Flow(h as u16),
            };
            // The ring's length was checked by `label`, the only caller.
            let rows = ring.get(h * 3 * (w + 2)..(h + 1) * 3 * (w + 2));
            debug_assert!(rows.is_some(), "ring rows of hypothesis {h}");
            sums3(rows.unwrap_or(&[]), w, |x, e| match kind {
                Sums::Camera => camera[x] = e,
                Sums::Texture => texture[x] = e,
                Sums::Flow(k) => {
                    if e < best[x] {
                        best[x] = e;
                        chosen[x] = k;
                    }
                }
            });
        }
        let gain = (9 * u32::from(self.params.min_gain)) << SUB_BITS;
        let base = (y - area.y) * w;
        for x in 0..w {
            let (cam, e, tex) = (
                u32::from(camera[x]),
                u32::from(best[x]),
                u32::from(texture[x]),
            );
            // Better than the camera, and than a misalignment of half a pixel would match.
            let object = cam < u32::from(UNKNOWN)
                && e + gain < cam
                && 2 * e < cam
                && TEXTURE_RATIO * e < tex;
            if let Some(label) = labels.get_mut(base + x) {
                *label = if object { chosen[x] } else { 0 };
            }
        }
    }

    /// Joins the labelled pixels into outlines and writes those of at least
    /// [`OutlineParams::min_pixels`]; returns the new number written.
    #[allow(clippy::too_many_arguments)]
    fn gather(
        &self,
        area: &Area,
        flows: &Flows,
        candidate: &MotionBox,
        labels: &mut [u16],
        stack: &mut [u16],
        boxes: &mut [MotionBox],
        mut written: usize,
    ) -> usize {
        let joined = joined_flows(flows);
        let mut found: heapless::Vec<(usize, MotionBox), 16> = heapless::Vec::new();
        for seed in 0..area.w * area.h {
            let Some(&label) = labels.get(seed) else {
                break;
            };
            if label == 0 || label & VISITED != 0 {
                continue;
            }
            let outline = flood(area, &joined, labels, stack, seed);
            if outline.pixels < self.params.min_pixels {
                continue;
            }
            let chosen = (0..flows.len)
                .max_by_key(|&k| outline.votes.get(k).copied().unwrap_or(0))
                .unwrap_or(0);
            let b = MotionBox {
                x: to_u16(area.x + outline.cols.0),
                y: to_u16(area.y + outline.rows.0),
                w: to_u16(outline.cols.1 + 1 - outline.cols.0),
                h: to_u16(outline.rows.1 + 1 - outline.rows.0),
                nodes: candidate.nodes,
                mean_flow: flows.flows.get(chosen).copied().unwrap_or_default(),
            };
            // A full list keeps the largest outlines: it drops its smallest to make room, so
            // the insertion below always has a free slot at a position <= its length.
            let at = found.iter().position(|(p, _)| *p < outline.pixels);
            let at = match (found.is_full(), at) {
                (true, None) => continue,
                (true, Some(at)) => {
                    found.pop();
                    at
                }
                (false, at) => at.unwrap_or(found.len()),
            };
            let inserted = found.insert(at, (outline.pixels, b));
            debug_assert!(inserted.is_ok(), "a free slot was made above");
        }
        // The largest first: a speck of chance matches on an object is covered by it, and one
        // beside it (where it uncovers or covers the ground) is far smaller than it.
        let largest = found.first().map_or(0, |(pixels, _)| *pixels);
        for (pixels, b) in found {
            if pixels.saturating_mul(SPECK_RATIO) >= largest {
                written = push_new(boxes, written, b);
            }
        }
        written
    }
}

/// An outline with fewer than one in this many of the pixels of its candidate's largest is a
/// speck of chance matches at that object's edge, where it covers or uncovers ground; two
/// objects in one region are rarely that unequal.
const SPECK_RATIO: usize = 8;

/// Which row of sums [`Outliner::decide_row`] is filling.
#[derive(Clone, Copy)]
enum Sums {
    Camera,
    Texture,
    Flow(u16),
}

/// The 3 x 3 sums of the `w` pixels of a row from its three rows of differences (`w + 2`
/// each, in any order: a sum does not care), saturated at [`UNKNOWN`], given to `out` by
/// column.
fn sums3(rows: &[u16], w: usize, mut out: impl FnMut(usize, u16)) {
    let len = w + 2;
    // Callers pass three rows of `w + 2` (checked where the ring and the camera's costs are
    // laid out); on fewer, `out` is not called and the callers' rows keep their fill.
    debug_assert!(rows.len() >= 3 * len, "sums3: {} < 3 x {len}", rows.len());
    let (Some(a), Some(b), Some(c)) = (
        rows.get(..len),
        rows.get(len..2 * len),
        rows.get(2 * len..3 * len),
    ) else {
        return;
    };
    let column = |x: usize| u32::from(a[x]) + u32::from(b[x]) + u32::from(c[x]);
    let (mut left, mut middle) = (column(0), column(1));
    for x in 0..w {
        let right = column(x + 2);
        out(x, (left + middle + right).min(u32::from(UNKNOWN)) as u16);
        (left, middle) = (middle, right);
    }
}

/// A level-1 pixel that voted for nothing (the camera explains it).
const NO_BIN: u16 = u16::MAX;

/// The high bit of a label: its pixel was pushed by a flood fill.
const VISITED: u16 = 1 << 15;

/// What a flood fill gathers about one outline: its extent in the area, pixels, and the
/// pixels that chose each flow.
struct Outline {
    cols: (usize, usize),
    rows: (usize, usize),
    pixels: usize,
    votes: [usize; MAX_FLOWS],
}

/// Fills the outline of pixel `seed`: 4-connected labelled pixels whose flows join.
fn flood(
    area: &Area,
    joined: &[u8; MAX_FLOWS],
    labels: &mut [u16],
    stack: &mut [u16],
    seed: usize,
) -> Outline {
    let (col, row) = (seed % area.w, seed / area.w);
    let mut outline = Outline {
        cols: (col, col),
        rows: (row, row),
        pixels: 0,
        votes: [0; MAX_FLOWS],
    };
    let mut top = 0usize;
    mark(labels, stack, &mut top, seed);
    while top > 0 {
        top -= 1;
        let Some(at) = stack.get(top).map(|&i| usize::from(i)) else {
            break;
        };
        let label = labels.get(at).map_or(0, |&l| l & !VISITED);
        let (col, row) = (at % area.w, at / area.w);
        outline.cols = (outline.cols.0.min(col), outline.cols.1.max(col));
        outline.rows = (outline.rows.0.min(row), outline.rows.1.max(row));
        outline.pixels += 1;
        if let Some(votes) = outline.votes.get_mut(usize::from(label).saturating_sub(1)) {
            *votes += 1;
        }
        let joins = joined
            .get(usize::from(label).saturating_sub(1))
            .copied()
            .unwrap_or(0);
        let mut visit = |next: usize| {
            let other = labels.get(next).copied().unwrap_or(0);
            let free = other != 0 && other & VISITED == 0;
            if free && joins & (1 << (other - 1)) != 0 {
                mark(labels, stack, &mut top, next);
            }
        };
        if col > 0 {
            visit(at - 1);
        }
        if col + 1 < area.w {
            visit(at + 1);
        }
        if row > 0 {
            visit(at - area.w);
        }
        if row + 1 < area.h {
            visit(at + area.w);
        }
    }
    outline
}

/// Marks pixel `at` visited and pushes it: no pixel is pushed twice, so the stack never needs
/// more than one slot per pixel.
fn mark(labels: &mut [u16], stack: &mut [u16], top: &mut usize, at: usize) {
    if let Some(label) = labels.get_mut(at) {
        *label |= VISITED;
    }
    if let Some(slot) = stack.get_mut(*top) {
        // Below MAX_SIDE^2 < 2^16.
        *slot = at as u16;
        *top += 1;
    }
}

/// One Gauss-Newton step of each flow on the pixels labelled with it: the shift that best
/// explains, to first order, the differences between the previous frame and the next sampled
/// at the flow, by the previous frame's gradient (central differences). A flow with too few
/// pixels or a singular system is kept.
fn refine(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    area: &Area,
    flows: &mut Flows,
    label_of: impl Fn(usize, usize) -> u16,
) {
    // Per flow: gxx, gxy, gyy, gx e, gy e; gradients and differences grey x 16 (|g| < 2^12,
    // |e| < 2^12), so each product is below 2^24 and 2^16 pixels of them below 2^40.
    let mut sums = [[0i64; 5]; MAX_FLOWS];
    for row in 0..area.h {
        let y = area.y + row;
        let (up, here, down) = (prev.row(y - 1), prev.row(y), prev.row(y + 1));
        for col in 0..area.w {
            let label = usize::from(label_of(col, row));
            let (Some(flow), Some(sum)) = (
                label.checked_sub(1).and_then(|k| flows.flows.get(k)),
                label.checked_sub(1).and_then(|k| sums.get_mut(k)),
            ) else {
                continue;
            };
            let x = area.x + col;
            let at = |r: &[u8], x: usize| i64::from(r.get(x).copied().unwrap_or(0));
            let gx = (at(here, x + 1) - at(here, x - 1)) << (SUB_BITS - 1);
            let gy = (at(down, x) - at(up, x)) << (SUB_BITS - 1);
            let Some(q) = sample(next, x, y, (flow.x.to_bits(), flow.y.to_bits())) else {
                continue;
            };
            let e = i64::from(q) - (at(here, x) << SUB_BITS);
            for (s, v) in sum
                .iter_mut()
                .zip([gx * gx, gx * gy, gy * gy, gx * e, gy * e])
            {
                *s += v;
            }
        }
    }
    for (flow, [gxx, gxy, gyy, bx, by]) in flows.flows.iter_mut().zip(sums).take(flows.len) {
        let det = (gxx as f32) * (gyy as f32) - (gxy as f32) * (gxy as f32);
        if det <= 0.0 || !det.is_finite() {
            continue;
        }
        // delta = -G^-1 b, px.
        let dx = -((gyy as f32) * (bx as f32) - (gxy as f32) * (by as f32)) / det;
        let dy = -((gxx as f32) * (by as f32) - (gxy as f32) * (bx as f32)) / det;
        if dx.abs() < 2.0 && dy.abs() < 2.0 {
            *flow = Point::new(
                flow.x.saturating_add(q16_from_f32(dx)),
                flow.y.saturating_add(q16_from_f32(dy)),
            );
        }
    }
}

/// For each flow, the flows (bit `j` for flow `j`) within [`JOINED_FLOW`] of it.
fn joined_flows(flows: &Flows) -> [u8; MAX_FLOWS] {
    core::array::from_fn(|i| {
        let Some(a) = flows.flows.get(i).filter(|_| i < flows.len) else {
            return 0;
        };
        flows
            .flows
            .iter()
            .take(flows.len)
            .enumerate()
            .filter(|(_, b)| close(a, b, JOINED_FLOW))
            .fold(0u8, |bits, (j, _)| bits | (1 << j))
    })
}

fn close(a: &Point, b: &Point, within: i32) -> bool {
    let d = |p: Q16, q: Q16| p.to_bits().abs_diff(q.to_bits());
    d(a.x, b.x) <= within.unsigned_abs() && d(a.y, b.y) <= within.unsigned_abs()
}

/// The distinct flows of the moving measured nodes whose centres lie in `area`, the first
/// [`MAX_FLOWS`] in raster order.
fn flows_in(layout: &GridLayout, nodes: &[GridNode], mask: &[u32], area: &Area) -> Flows {
    let mut flows = Flows::EMPTY;
    for (index, node) in nodes.iter().take(layout.len()).enumerate() {
        let (col, row) = layout.node(index);
        let (x, y) = layout.centre(col, row);
        let inside =
            (area.x..area.x + area.w).contains(&x) && (area.y..area.y + area.h).contains(&y);
        if inside && contains(mask, index) && node.is_valid() {
            flows.add(node.flow);
        }
    }
    flows
}

/// Differences of row `y` (pixels `area.x - 1 ..= area.x + area.w`) between the previous frame
/// and the next sampled at the camera's flow, which is predicted at the row's two ends and
/// taken as linear between them; [`UNKNOWN`] where the sample leaves the next frame.
fn camera_row(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    camera: &dyn CameraMotion,
    area: &Area,
    y: usize,
    out: &mut [u16],
) {
    let first = area.x.saturating_sub(1);
    let last = area.x + area.w;
    let at = |x: usize| {
        let (dx, dy) = camera.predict(x as f32, y as f32);
        (flow_bits(dx), flow_bits(dy))
    };
    let ((x0, y0), (x1, y1)) = (at(first), at(last));
    let steps = (last - first).max(1) as i64;
    // Linear from one end's flow to the other's, Q16: both flows are below 2^30.
    let step = |a: i32, b: i32| ((i64::from(b) - i64::from(a)) / steps) as i32;
    let (sx, sy) = (step(x0, x1), step(y0, y1));
    let source = prev.row(y);
    let mut flow = (x0, y0);
    for (i, slot) in out.iter_mut().enumerate() {
        let x = first + i;
        if i > 0 {
            flow = (flow.0.saturating_add(sx), flow.1.saturating_add(sy));
        }
        *slot = match (source.get(x), sample(next, x, y, flow)) {
            (Some(&p), Some(q)) => (u32::from(p) << SUB_BITS).abs_diff(q) as u16,
            _ => UNKNOWN,
        };
    }
}

/// Differences of row `y` between the previous frame and the next sampled at one constant
/// flow; the largest difference where the sample leaves the next frame (the object cannot be
/// there).
fn flow_row(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    area: &Area,
    y: usize,
    flow: Option<&Point>,
    out: &mut [u16],
) {
    let flow = flow.map_or((0, 0), |f| (f.x.to_bits(), f.y.to_bits()));
    let first = area.x.saturating_sub(1);
    let source = prev.row(y);
    for (i, slot) in out.iter_mut().enumerate() {
        let x = first + i;
        *slot = match (source.get(x), sample(next, x, y, flow)) {
            (Some(&p), Some(q)) => (u32::from(p) << SUB_BITS).abs_diff(q) as u16,
            _ => 255 << SUB_BITS,
        };
    }
}

/// The next frame at (`x`, `y`) moved by `flow` (Q16), bilinear in sixteenths of a pixel,
/// grey x 16; `None` when the four pixels are not all inside.
fn sample(next: &ImageView<'_>, x: usize, y: usize, (fx, fy): (i32, i32)) -> Option<u32> {
    let px = (x as i64) * 65_536 + i64::from(fx);
    let py = (y as i64) * 65_536 + i64::from(fy);
    let (ix, iy) = (
        usize::try_from(px >> 16).ok()?,
        usize::try_from(py >> 16).ok()?,
    );
    let (ax, ay) = (((px >> 12) & 15) as u32, ((py >> 12) & 15) as u32);
    let top = next.row(iy);
    let bottom = next.row(iy + 1);
    let (a, b) = (u32::from(*top.get(ix)?), u32::from(*top.get(ix + 1)?));
    let (c, d) = (u32::from(*bottom.get(ix)?), u32::from(*bottom.get(ix + 1)?));
    let upper = a * (16 - ax) + b * ax;
    let lower = c * (16 - ax) + d * ax;
    // Weights in 256ths: (upper (16 - ay) + lower ay) / 256 grey, x 16 after >> 4.
    Some((upper * (16 - ay) + lower * ay + 8) >> 4)
}

/// A flow in pixels as Q16 bits; NaN or a flow beyond the frame's reach gives 0 (no motion).
fn flow_bits(v: f32) -> i32 {
    if v.is_finite() && v.abs() < 16_384.0 {
        q16_from_f32(v).to_bits()
    } else {
        0
    }
}

fn to_u16(v: usize) -> u16 {
    u16::try_from(v).unwrap_or(u16::MAX)
}

/// Writes `b` at `written` unless it and a box written before mostly cover each other, in which
/// case the larger of the two is kept there; returns the new count (unchanged when `boxes` is
/// full).
fn push_new(boxes: &mut [MotionBox], written: usize, b: MotionBox) -> usize {
    let (kept, room) = boxes.split_at_mut(written.min(boxes.len()));
    match kept.iter_mut().find(|a| covers(a, &b)) {
        // One object's two outlines (a speck of it seen from another candidate): the larger
        // stays.
        Some(a) => {
            if b.area() > a.area() {
                *a = b;
            }
            written
        }
        None => match room.first_mut() {
            Some(slot) => {
                *slot = b;
                written + 1
            }
            None => written,
        },
    }
}

/// True when the two boxes share at least half the smaller one's area.
fn covers(a: &MotionBox, b: &MotionBox) -> bool {
    2 * a.overlap_area(b) >= a.area().min(b.area()).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dense::grid::grid_len;
    use crate::dense::mask::{mask_words, set};
    use crate::pyramid::pyramid_storage_len;

    const W: usize = 96;
    const H: usize = 64;
    const CELL: usize = 8;

    struct Still;
    impl CameraMotion for Still {
        fn predict(&self, _: f32, _: f32) -> (f32, f32) {
            (0.0, 0.0)
        }
    }

    /// An object's top-left pixel and its motion, px.
    type Object = ((usize, usize), (usize, usize));

    fn ground(x: usize, y: usize) -> u8 {
        ((x * 7 + y * 13 + (x * y) % 11 * 19) % 200) as u8
    }

    fn texture(x: usize, y: usize) -> u8 {
        ((x * 29 + y * 5 + (x ^ y) * 23) % 240) as u8 + 10
    }

    /// The ground with 10 x 10 objects of their own textures, top-left at `(x, y)`, in the
    /// next frame moved by their `(dx, dy)`.
    fn frame(objects: &[Object], moved: bool) -> [u8; W * H] {
        core::array::from_fn(|i| {
            let (x, y) = (i % W, i / W);
            for (id, &((ox, oy), (dx, dy))) in objects.iter().enumerate() {
                let (ox, oy) = if moved { (ox + dx, oy + dy) } else { (ox, oy) };
                if (ox..ox + 10).contains(&x) && (oy..oy + 10).contains(&y) {
                    return texture(x - ox + 37 * id, y - oy);
                }
            }
            ground(x, y)
        })
    }

    /// Outlines `candidate` between the two frames of `objects`, the nodes in `moving` set
    /// to `flow`.
    fn outline(
        objects: &[Object],
        moving: &[(usize, usize)],
        flow: (f32, f32),
        candidate: MotionBox,
    ) -> heapless::Vec<MotionBox, 8> {
        outline_on_levels(1, objects, moving, flow, &[candidate])
    }

    /// [`outline`] of several candidates on pyramids with `levels` levels above the frame.
    fn outline_on_levels(
        levels: usize,
        objects: &[Object],
        moving: &[(usize, usize)],
        flow: (f32, f32),
        candidates: &[MotionBox],
    ) -> heapless::Vec<MotionBox, 8> {
        let (a, b) = (frame(objects, false), frame(objects, true));
        let mut storage = [[0u8; pyramid_storage_len(W, H, 1)]; 2];
        let [sa, sb] = &mut storage;
        let prev = Pyramid::build(ImageView::packed(&a, W, H).unwrap(), levels, sa).unwrap();
        let next = Pyramid::build(ImageView::packed(&b, W, H).unwrap(), levels, sb).unwrap();
        let layout = GridLayout::new(W, H, CELL).unwrap();
        let mut nodes = [GridNode::tracked(Point::default()); grid_len(W, H, CELL)];
        let mut mask = [0u32; mask_words(W, H, CELL)];
        for &(col, row) in moving {
            let index = layout.index(col, row).unwrap();
            nodes[index] = GridNode::tracked(Point::from_f32(flow.0, flow.1));
            set(&mut mask, index, true);
        }
        let outliner = Outliner::new(OutlineParams::default()).unwrap();
        let mut scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
        let mut boxes = [MotionBox::default(); 8];
        let n = outliner
            .outline(
                &prev,
                &next,
                &Still,
                &layout,
                &nodes,
                &mask,
                candidates,
                &mut scratch,
                &mut boxes,
            )
            .unwrap();
        boxes.iter().take(n).copied().collect()
    }

    fn candidate(x: u16, y: u16, w: u16, h: u16) -> MotionBox {
        MotionBox {
            x,
            y,
            w,
            h,
            nodes: 4,
            mean_flow: Point::default(),
        }
    }

    #[test]
    fn two_objects_in_one_region_get_a_box_each() {
        // 10 px objects 4 px apart, one moving 4 px right, the other 4 px down: the grid sees
        // one region, with one blended flow at its nodes.
        let objects = [((30, 20), (4, 0)), ((44, 22), (0, 4))];
        let moving = [
            (3, 2),
            (4, 2),
            (5, 2),
            (6, 2),
            (3, 3),
            (4, 3),
            (5, 3),
            (6, 3),
        ];
        let boxes = outline(&objects, &moving, (2.0, 2.0), candidate(28, 20, 32, 16));
        let mut found: heapless::Vec<_, 8> = boxes
            .iter()
            .map(|b| (b.x, b.y, b.w, b.h, b.mean_flow.to_f32()))
            .collect();
        found.sort_unstable_by_key(|b| b.0);
        assert_eq!(found.len(), 2, "{found:?}");
        let near =
            |(x, y): (f32, f32), (u, v): (f32, f32)| (x - u).abs() < 0.1 && (y - v).abs() < 0.1;
        // Each box within a pixel of its object on every side (a 3 x 3 neighbourhood half on
        // the object may take its flow).
        let fits = |b: &(u16, u16, u16, u16, (f32, f32)), (x, y): (i32, i32)| {
            let sides = [(b.0, x), (b.1, y), (b.0 + b.2, x + 10), (b.1 + b.3, y + 10)];
            sides
                .iter()
                .all(|&(got, want)| (i32::from(got) - want).abs() <= 1)
        };
        assert!(
            fits(&found[0], (30, 20)) && fits(&found[1], (44, 22)),
            "{found:?}"
        );
        assert!(
            near(found[0].4, (4.0, 0.0)) && near(found[1].4, (0.0, 4.0)),
            "{found:?}"
        );
    }

    #[test]
    fn an_object_in_the_top_left_corner_is_outlined() {
        // The area starts at the frame's first row and column, where the level-1 area starts
        // one pixel in: the refinement's weights are asked for pixels left of and above it.
        let objects = [((0, 0), (3, 0))];
        let moving = [(0, 0), (1, 0), (0, 1), (1, 1)];
        let boxes = outline(&objects, &moving, (3.0, 0.0), candidate(0, 0, 16, 14));
        assert_eq!(boxes.len(), 1, "{boxes:?}");
        let found = boxes[0];
        assert!(found.x <= 1 && found.y <= 1, "{found:?}");
        let (dx, dy) = found.mean_flow.to_f32();
        assert!((dx - 3.0).abs() < 0.1 && dy.abs() < 0.1, "{found:?}");
    }

    #[test]
    fn without_level_1_the_nodes_flow_is_tried() {
        // No vote without level 1: the candidate's and its nodes' flows alone, refined.
        let objects = [((40, 24), (3, 0))];
        let moving = [(5, 3), (6, 3), (5, 4), (6, 4)];
        let boxes = outline_on_levels(
            0,
            &objects,
            &moving,
            (2.6, 0.2),
            &[candidate(36, 20, 20, 18)],
        );
        assert_eq!(boxes.len(), 1, "{boxes:?}");
        let found = boxes[0];
        let sides = [
            (found.x, 40),
            (found.y, 24),
            (found.x + found.w, 50),
            (found.y + found.h, 34),
        ];
        assert!(
            sides.iter().all(|&(got, want)| got.abs_diff(want) <= 1),
            "{found:?}"
        );
        // The nodes' 2.6 px, refined on the object's pixels to within a quarter pixel.
        let (dx, dy) = found.mean_flow.to_f32();
        assert!((dx - 3.0).abs() < 0.25 && dy.abs() < 0.25, "{found:?}");
    }

    #[test]
    fn two_candidates_on_one_object_write_one_box() {
        // Their margins meet on the object: the second's outline covers the first's.
        let objects = [((40, 24), (3, 0))];
        let moving = [(5, 3), (6, 3), (5, 4), (6, 4)];
        let candidates = [candidate(36, 20, 16, 18), candidate(42, 22, 16, 16)];
        let boxes = outline_on_levels(1, &objects, &moving, (3.0, 0.0), &candidates);
        assert_eq!(boxes.len(), 1, "{boxes:?}");
    }

    #[test]
    fn a_region_of_mismeasured_nodes_gives_no_box() {
        // Nothing moves; four nodes claim 3 px.
        let boxes = outline(
            &[],
            &[(4, 3), (5, 3), (4, 4), (5, 4)],
            (3.0, 0.0),
            candidate(36, 28, 16, 16),
        );
        assert!(boxes.is_empty(), "{boxes:?}");
    }

    #[test]
    fn a_candidate_larger_than_the_scratch_keeps_its_grid_box() {
        let big = candidate(2, 2, 90, 40);
        assert_eq!(outline(&[], &[], (0.0, 0.0), big).as_slice(), &[big]);
    }

    #[test]
    fn bad_parameters_and_short_buffers_are_refused() {
        let narrow = OutlineParams {
            side: MIN_SIDE - 1,
            ..OutlineParams::default()
        };
        assert_eq!(Outliner::new(narrow).unwrap_err(), DenseError::BadOutline);
        let far = OutlineParams {
            reach: MAX_REACH + 1,
            ..OutlineParams::default()
        };
        assert_eq!(Outliner::new(far).unwrap_err(), DenseError::BadOutline);
        let a = [0u8; W * H];
        let view = ImageView::packed(&a, W, H).unwrap();
        let pyramid = Pyramid::build(view, 0, &mut []).unwrap();
        let layout = GridLayout::new(W, H, CELL).unwrap();
        let nodes = [GridNode::EMPTY; grid_len(W, H, CELL)];
        let mask = [0u32; mask_words(W, H, CELL)];
        let outliner = Outliner::new(OutlineParams::default()).unwrap();
        let mut short = [0u16; 10];
        let run = |scratch: &mut [u16], nodes: &[GridNode]| {
            outliner.outline(
                &pyramid,
                &pyramid,
                &Still,
                &layout,
                nodes,
                &mask,
                &[],
                scratch,
                &mut [],
            )
        };
        assert_eq!(run(&mut short, &nodes), Err(DenseError::ScratchTooSmall));
        let mut scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
        assert_eq!(
            run(&mut scratch, &nodes[1..]),
            Err(DenseError::NodesTooShort)
        );
        assert_eq!(run(&mut scratch, &nodes), Ok(0));
    }

    #[test]
    fn unknown_is_above_every_sum_of_nine_differences() {
        // The widest difference, 255 grey x 16, nine times.
        assert!(9 * (255u32 << SUB_BITS) < u32::from(UNKNOWN));
    }
}
