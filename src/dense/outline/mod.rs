//! Moving regions outlined at pixel resolution: [`Outliner`].

// The stages `Outliner::outline` runs on each candidate, in this order: the area searched,
// the vote for its flows, their refinement, the labelling of its pixels, the flood fill that
// joins them into outlines, and the boxes written. The scratch is cut once for all of them.
mod area;
mod boxes;
mod flood;
mod label;
mod refine;
mod vote;
// What the stages share: the flows tried, the pixel differences, and the scratch's parts.
mod differences;
mod flows;
mod scratch;

pub use scratch::outline_scratch_len;
// What makes two parts one body, shared with the join of the reported boxes.
pub(super) use boxes::moves_alike;

use super::grid::{GridLayout, GridNode};
use super::motion::CameraMotion;
use super::regions::MotionBox;
use super::DenseError;
use crate::config_error::bound_number;
use crate::frame::ImageView;
use crate::pyramid::Pyramid;
use crate::{Bound, ConfigError};
use area::Area;
use boxes::push_new;
use differences::SUB_BITS;
use flows::Flows;
use refine::refine;
use scratch::OutlineScratch;

/// The most object flows tried at one candidate (besides the camera's): up to
/// [`OUTLINE_VOTED_FLOWS`] from the vote, the candidate's own, and its nodes'.
pub const OUTLINE_MAX_FLOWS: usize = 6;

/// The most flows taken from the vote: the objects one candidate region holds, which on
/// an 8 px grid is rarely more than three.
pub const OUTLINE_VOTED_FLOWS: usize = 3;

/// The widest and highest area a scratch can hold: pixel indices are `u16`.
pub const OUTLINE_MAX_SIDE: usize = 255;

/// The smallest [`OutlineParams::side`]: the labelling keeps four rows of sums where the
/// flood fill's stack (`side` x `side`) will be.
pub const OUTLINE_MIN_SIDE: usize = 8;

/// The largest [`OutlineParams::reach`], px: 65 x 65 bins at most.
pub const OUTLINE_MAX_REACH: usize = 128;

/// How candidates are outlined.
///
/// A still camera over ground where a 10 x 10 object moves 3 px right, boxed by the grid
/// (the setup of [`Outliner`]'s example):
///
/// ```
/// # use kestrel::dense::{
/// #     grid_len, mask_set, mask_words, outline_scratch_len, CameraMotion, GridLayout, GridNode,
/// #     MotionBox, OutlineParams, Outliner,
/// # };
/// # use kestrel::ImageView;
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
/// #     mask_set(&mut mask, index, true);
/// # }
/// # struct Still;
/// # impl CameraMotion for Still {
/// #     fn flow_at(&self, _: f32, _: f32) -> (f32, f32) { (0.0, 0.0) }
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
    /// The widest and highest area searched, px, [`OUTLINE_MIN_SIDE`] to [`OUTLINE_MAX_SIDE`]: the scratch is
    /// [`outline_scratch_len`] of it.
    pub side: usize,
    /// The largest motion searched beside the camera's, px, on each axis: the objects' flows
    /// are found by a vote of the area's pixels over the shifts within this reach, on pyramid
    /// level 1. At most [`OUTLINE_MAX_REACH`].
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

/// Outlines moving regions at pixel resolution.
///
/// The grid knows where something moves only to a cell and a window: on an 8 px grid with 9 px
/// windows a 10 px object moves a block of nodes about twice its size, and two objects a few
/// pixels apart move one block between them; a small object faster than LK's reach leaves
/// nodes that match nothing. An `Outliner` looks at the pixels of each candidate box (grown
/// by a margin) in the previous frame and asks which motion explains each one: the camera's,
/// or one of a few object flows. Those come from a vote on pyramid level 1 (each pixel the
/// camera does not explain votes for the whole-pixel shift that matches it best), from the
/// candidate's own flow and from its moving nodes, and are refined by Gauss-Newton on the
/// pixels that chose them. A pixel belongs to an object when one of those flows matches its
/// 3 x 3 neighbourhood in the next frame clearly better than the camera's flow does (sums of
/// absolute differences, the next frame sampled bilinearly) and better than its own texture
/// would allow a misaligned match to. Connected object pixels whose flows agree within a pixel
/// make one outline; its box is theirs, and its flow the flow most of them chose.
///
/// So two objects that share a region but not a pixel get a box each, a box fits its object to
/// the pixel, and a region whose nodes were mismeasured (on still ground every pixel matches
/// the camera) gives no box at all.
///
/// Pixels the camera carries out of the next frame cannot be told and belong to nothing. A
/// candidate too large for the scratch keeps its grid box: it is a large object, which the grid
/// already boxes well.
///
/// The work is bounded by the candidate's area: per level-1 pixel the camera does not explain,
/// one 3 x 3 difference per shift within the reach; per level-0 pixel and labelling, one
/// bilinear sample and one difference per flow tried (at most [`OUTLINE_MAX_FLOWS`], the camera's and
/// the texture), and the sums of three rows kept in a ring. It is host-sized work: on the
/// STM32F405 one 160 x 120 frame's outlines cost millions of instructions (see
/// `firmware/README.md`).
///
/// ```
/// use kestrel::dense::{
///     grid_len, mask_set, mask_words, outline_scratch_len, CameraMotion, GridLayout, GridNode,
///     MotionBox, OutlineParams, Outliner,
/// };
/// use kestrel::ImageView;
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
/// use kestrel::Point;
///
/// // A still camera over ground with a 10 x 10 object that moves 3 px right.
/// const W: usize = 64;
/// const H: usize = 48;
/// let ground = |x: usize, y: usize| ((x * 7 + y * 13 + (x * y) % 11 * 19) % 200) as u8;
/// let object = |x: usize, y: usize| ((x * 29 + y * 5 + (x ^ y) * 23) % 240) as u8 + 10;
/// let frame = |shift: usize| -> [u8; W * H] {
///     core::array::from_fn(|i| {
///         let (x, y) = (i % W, i / W);
///         let inside = (20 + shift..30 + shift).contains(&x) && (16..26).contains(&y);
///         if inside { object(x - shift, y) } else { ground(x, y) }
///     })
/// };
/// let (a, b) = (frame(0), frame(3));
/// let mut storage = [[0u8; pyramid_storage_len(W, H, 1)]; 2];
/// let [sa, sb] = &mut storage;
/// let prev = Pyramid::build(ImageView::packed(&a, W, H).unwrap(), 1, sa).unwrap();
/// let next = Pyramid::build(ImageView::packed(&b, W, H).unwrap(), 1, sb).unwrap();
///
/// // The grid found the object's motion at two nodes, in a region boxed from 16 to 40 px.
/// let layout = GridLayout::new(W, H, 8).unwrap();
/// let mut nodes = [GridNode::tracked(Point::default()); grid_len(W, H, 8)];
/// let mut mask = [0u32; mask_words(W, H, 8)];
/// for (col, row) in [(2, 2), (3, 2)] {
///     let index = layout.index(col, row).unwrap();
///     nodes[index] = GridNode::tracked(Point::from_f32(3.0, 0.0));
///     mask_set(&mut mask, index, true);
/// }
/// struct Still;
/// impl CameraMotion for Still {
///     fn flow_at(&self, _: f32, _: f32) -> (f32, f32) { (0.0, 0.0) }
/// }
/// let candidate = MotionBox { x: 16, y: 12, w: 24, h: 16, nodes: 2, mean_flow: Point::from_f32(3.0, 0.0) };
///
/// let outliner = Outliner::new(OutlineParams::default()).unwrap();
/// let mut scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
/// let mut boxes = [MotionBox::default(); 4];
/// let n = outliner
///     .outline(&prev, &next, &Still, &layout, &nodes, &mask, &[candidate], &mut scratch, &mut boxes)
///     .unwrap();
/// assert_eq!(n, 1);
/// // The object's 10 x 10 pixels from (20, 16), to within a pixel on every side.
/// let b = boxes[0];
/// let sides = [(b.x, 20), (b.y, 16), (b.x + b.w, 30), (b.y + b.h, 26)];
/// assert!(sides.iter().all(|&(got, want)| got.abs_diff(want) <= 1), "{b:?}");
/// let (dx, dy) = boxes[0].mean_flow.to_f32();
/// assert!((dx - 3.0).abs() < 0.1 && dy.abs() < 0.1);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Outliner {
    params: OutlineParams,
}

impl Outliner {
    /// Validates `params`: a side of [`OUTLINE_MIN_SIDE`] to [`OUTLINE_MAX_SIDE`] px and a reach of at most
    /// [`OUTLINE_MAX_REACH`] px (refused as `"side"` or `"reach"`).
    ///
    /// ```
    /// use kestrel::dense::{OutlineParams, Outliner, OUTLINE_MAX_SIDE};
    /// use kestrel::{Bound, ConfigError};
    /// let wide = OutlineParams { side: OUTLINE_MAX_SIDE + 1, ..OutlineParams::default() };
    /// let refused = Outliner::new(wide).unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "side", bound: Bound::Range { min: 8, max: 255 } });
    /// assert_eq!(refused.to_string(), "side must be 8 to 255");
    /// ```
    pub fn new(params: OutlineParams) -> Result<Self, ConfigError> {
        if !(OUTLINE_MIN_SIDE..=OUTLINE_MAX_SIDE).contains(&params.side) {
            let bound = Bound::Range {
                min: bound_number(OUTLINE_MIN_SIDE),
                max: bound_number(OUTLINE_MAX_SIDE),
            };
            return Err(ConfigError::new("side", bound));
        }
        if params.reach > OUTLINE_MAX_REACH {
            let bound = Bound::AtMost(bound_number(OUTLINE_MAX_REACH));
            return Err(ConfigError::new("reach", bound));
        }
        Ok(Self { params })
    }

    /// The parameters this outliner was built with.
    ///
    /// ```
    /// use kestrel::dense::{OutlineParams, Outliner};
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
    /// pixels chose. See [`Outliner`]'s example.
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
            let short = ConfigError::min_len("nodes", layout.len());
            return Err(DenseError::Config(short));
        }
        let (side, reach) = (self.params.side, self.params.reach);
        let Some(mut scratch) = OutlineScratch::split(scratch, side, reach) else {
            let short = ConfigError::min_len("scratch", outline_scratch_len(side, reach));
            return Err(DenseError::Config(short));
        };
        let frames = (&base, &next_base);
        let level1 = prev.level(1).zip(next.level(1));
        let mut written = 0usize;
        for candidate in candidates {
            let Some(area) = Area::around(candidate, &base, self.params.margin, self.params.side)
            else {
                written = push_new(boxes, written, *candidate);
                continue;
            };
            let mut flows = match &level1 {
                Some((prev1, next1)) => {
                    self.voted_flows((prev1, next1), frames, camera, &area, &mut scratch)
                }
                // A pyramid of one level: no vote, the nodes' flows alone.
                None => Flows::EMPTY,
            };
            // The candidate's own flow: a region's mean, or where a box of the pair before
            // said its object would be.
            flows.add(candidate.mean_flow);
            // And the flows its moving nodes measured: a slow object's, which the vote's whole
            // pixels do not resolve.
            let measured = Flows::of_nodes(layout, nodes, mask, &area);
            for flow in measured.iter() {
                flows.add(*flow);
            }
            if flows.len == 0 {
                continue;
            }
            self.label_refined(frames, camera, &area, &mut flows, &mut scratch);
            written = self.gather(&area, &flows, candidate, &mut scratch, boxes, written);
        }
        Ok(written)
    }

    /// The vote's flows on level 1 (`level1`), each refined on the level-0 pixels (`frames`)
    /// whose level-1 pixel voted for it.
    fn voted_flows(
        &self,
        level1: (&ImageView<'_>, &ImageView<'_>),
        frames: (&ImageView<'_>, &ImageView<'_>),
        camera: &impl CameraMotion,
        area: &Area,
        scratch: &mut OutlineScratch<'_>,
    ) -> Flows {
        let (mut flows, half) = self.vote(level1, camera, area, scratch);
        // The vote's flows are whole level-1 pixels: to a pixel at level 0 at best. Its voters
        // refine them; were there none, no pixel would take part (label 0).
        let voters = scratch.voters(half.pixels());
        for _ in 0..self.params.refinements {
            refine(frames, area, &mut flows, |col, row| {
                let (x, y) = ((area.x + col) / 2, (area.y + row) / 2);
                if !half.contains(x, y) {
                    return 0;
                }
                // Inside the level-1 area, so both differences are >= 0 and the index is
                // below half.w * half.h, the voters' length.
                let at = (y - half.y) * half.w + (x - half.x);
                debug_assert!(at < voters.len());
                voters.get(at).copied().unwrap_or(0)
            });
        }
        flows
    }

    /// Labels the area's pixels, then [`OutlineParams::refinements`] times refines each flow on
    /// the pixels that chose it and labels them again.
    fn label_refined(
        &self,
        frames: (&ImageView<'_>, &ImageView<'_>),
        camera: &impl CameraMotion,
        area: &Area,
        flows: &mut Flows,
        scratch: &mut OutlineScratch<'_>,
    ) {
        self.label(frames, camera, area, flows, scratch);
        for _ in 0..self.params.refinements {
            let labels = &*scratch.labels;
            refine(frames, area, flows, |col, row| {
                labels.get(row * area.w + col).copied().unwrap_or(0)
            });
            self.label(frames, camera, area, flows, scratch);
        }
    }

    /// How much less than the camera's a flow's 3 x 3 sum must be to claim a pixel, grey x 16:
    /// [`OutlineParams::min_gain`] at each of the nine pixels.
    fn gain(&self) -> u32 {
        (9 * u32::from(self.params.min_gain)) << SUB_BITS
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dense::grid::grid_len;
    use crate::dense::mask::{mask_set, mask_words};
    use crate::pyramid::pyramid_storage_len;
    use crate::q16::Point;

    const W: usize = 96;
    const H: usize = 64;
    const CELL: usize = 8;

    struct Still;
    impl CameraMotion for Still {
        fn flow_at(&self, _: f32, _: f32) -> (f32, f32) {
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
            mask_set(&mut mask, index, true);
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

    /// One object 3 px right from (40, 24), and the four nodes on it.
    const ONE_OBJECT: [Object; 1] = [((40, 24), (3, 0))];
    const ITS_NODES: [(usize, usize); 4] = [(5, 3), (6, 3), (5, 4), (6, 4)];

    #[test]
    fn without_level_1_the_nodes_flow_is_tried() {
        // No vote without level 1: the candidate's and its nodes' flows alone, refined.
        let candidates = [candidate(36, 20, 20, 18)];
        let boxes = outline_on_levels(0, &ONE_OBJECT, &ITS_NODES, (2.6, 0.2), &candidates);
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
        let candidates = [candidate(36, 20, 16, 18), candidate(42, 22, 16, 16)];
        let boxes = outline_on_levels(1, &ONE_OBJECT, &ITS_NODES, (3.0, 0.0), &candidates);
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
            side: OUTLINE_MIN_SIDE - 1,
            ..OutlineParams::default()
        };
        let sides = Bound::Range { min: 8, max: 255 };
        assert_eq!(
            Outliner::new(narrow).unwrap_err(),
            ConfigError::new("side", sides)
        );
        let far = OutlineParams {
            reach: OUTLINE_MAX_REACH + 1,
            ..OutlineParams::default()
        };
        assert_eq!(
            Outliner::new(far).unwrap_err(),
            ConfigError::new("reach", Bound::AtMost(128))
        );
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
        let needed = outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8);
        assert_eq!(
            run(&mut short, &nodes),
            Err(DenseError::Config(ConfigError::min_len("scratch", needed)))
        );
        let mut scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
        assert_eq!(
            run(&mut scratch, &nodes[1..]),
            Err(DenseError::Config(ConfigError::min_len(
                "nodes",
                grid_len(W, H, CELL)
            )))
        );
        assert_eq!(run(&mut scratch, &nodes), Ok(0));
    }
}
