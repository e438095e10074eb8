//! Boxes grown over the pixels that changed between the two frames, on a still camera.
//!
//! The grid's flow is measured where a mover has texture: a walker's face, the folds and edges
//! of its clothes. A dark coat or plain trousers are flat inside, so their nodes have no flow
//! of their own, and a walker's box often holds its upper body alone, or one of two walkers
//! who walk together. Where the camera is still, the pixels a mover covers or uncovers change
//! between the frames even where they are flat, and they join its parts: each box grows over
//! the changed pixels connected to it, as a background subtractor's silhouette would.
//!
//! A shadow changes the ground too; it dims it by a factor and keeps its texture, so a pixel
//! whose darker value is between two fifths and nine tenths of its brighter one does not count
//! as changed. The growth runs on pyramid level 1 (half the resolution, smoothed by the
//! pyramid's filter), where a sensor's noise is about half as strong.
//!
//! A walker's feet or the bottom of its legs are often a box of their own below its body, with
//! ground between them that did not change enough to grow over (trousers of the street's
//! brightness), and a foot that stands does not move with the body. So after the growth a small
//! box that stands below a larger one (`bodies::stands_below`) is joined to it, unless it changed as a
//! shadow does: darkened or brightened by a shadow's factor with the ground's texture kept
//! under it (its changed pixels' darker values correlate with their brighter ones).

use super::bodies::{join_pairs, larger_first, stands_below};
use super::motion::CameraMotion;
use super::regions::MotionBox;
use crate::frame::ImageView;
use crate::pyramid::Pyramid;
use crate::q16::Q16;

/// Grey levels a pixel of pyramid level 1 must change by between the frames to count as
/// changed: well above a sensor's noise, smoothed by the pyramid.
const CHANGE_LEVELS: u8 = 15;

/// How far apart, pixels of level 1 on each axis, two changed pixels may lie and still connect
/// (one unchanged pixel between them): a mover's outline breaks where it crosses ground of its
/// own brightness. A side of a box grows only while the row or column just outside it holds a
/// changed pixel so connected to one inside.
const REACH: usize = 2;

/// The camera is taken as still when it moves no pixel of the frame by more than this, px.
const STILL_PX: f32 = 0.5;

/// The growth is left out when more than this share of the frame changed (an exposure step, a
/// scene cut): the changed pixels then say nothing about the movers.
const MOST_CHANGED: (usize, usize) = (3, 10);

/// Each side of a box grows at most by this many times its own length: a box does not follow
/// a long stretch of changed pixels across the frame.
const MOST_GROWTH: usize = 3;

/// Grows each of the first `count` of `boxes` over the pixels connected to it that changed
/// between `prev` and `next`, when `camera` is still, and joins to a box that grew the boxes
/// it then overlaps (parts of one body, or movers whose changed pixels touch, as a background
/// subtractor's silhouettes do), with the larger one's nodes and flow; returns how many boxes
/// are left, at the front of `boxes` in their order. The changed pixels hold a mover where it
/// is in both frames; the box stays in the earlier frame, the side that grew ahead of its flow
/// brought back by it. Then a small box that stands below a larger one, as feet below a
/// body, is joined to it unless it changed as a shadow does (see the module documentation),
/// one join at a time: a body that took its feet is judged by its new height for the next. A
/// moving camera, a frame pair that changed nearly everywhere, or pyramids without level 1
/// leave the boxes as they are.
///
/// A walker in a dark coat and trousers on light ground, 4 px to the right a frame: its flow was
/// measured on the coat, whose box the trousers' changed edges grow down to the feet. A box
/// on still ground beside it does not grow.
///
/// ```
/// use kestrel::dense::{grow_over_change, MotionBox};
/// use kestrel::ego::Homography;
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
/// use kestrel::{ImageView, Point};
///
/// const W: usize = 64;
/// const H: usize = 48;
/// // Light ground; a coat 12 px wide from row 10 to 25, two legs 4 px wide to row 39.
/// let frame = |left: usize| -> Vec<u8> {
///     (0..W * H)
///         .map(|i| {
///             let (x, y) = (i % W, i / W);
///             let coat = (left..left + 12).contains(&x) && (10..26).contains(&y);
///             let legs = (26..40).contains(&y)
///                 && ((left + 1..left + 5).contains(&x) || (left + 7..left + 11).contains(&x));
///             if coat || legs { 40 } else { 170 }
///         })
///         .collect()
/// };
/// let (a, b) = (frame(20), frame(24));
/// let mut sa = [0u8; pyramid_storage_len(W, H, 1)];
/// let mut sb = [0u8; pyramid_storage_len(W, H, 1)];
/// let prev = Pyramid::build(ImageView::packed(&a, W, H).unwrap(), 1, &mut sa).unwrap();
/// let next = Pyramid::build(ImageView::packed(&b, W, H).unwrap(), 1, &mut sb).unwrap();
/// let flow = Point::from_f32(4.0, 0.0);
/// let coat = MotionBox { x: 20, y: 10, w: 14, h: 16, nodes: 4, mean_flow: flow };
/// let ground = MotionBox { x: 50, y: 30, w: 8, h: 8, nodes: 1, mean_flow: flow };
/// let mut boxes = [coat, ground];
/// assert_eq!(grow_over_change(&prev, &next, &mut boxes, 2, &Homography::IDENTITY), 2);
/// let walker = boxes[0];
/// // Down to the feet, where the walker is in the earlier frame.
/// assert_eq!((walker.x, walker.y, walker.w, walker.h), (20, 10, 14, 30));
/// assert_eq!(boxes[1], ground);
/// // A planted foot's box just below the legs, on ground that did not change, is joined to
/// // the walker; the box on still ground beside it is not.
/// let foot = MotionBox { x: 22, y: 42, w: 8, h: 4, nodes: 1, mean_flow: Point::default() };
/// let mut boxes = [coat, foot, ground];
/// assert_eq!(grow_over_change(&prev, &next, &mut boxes, 3, &Homography::IDENTITY), 2);
/// assert_eq!((boxes[0].x, boxes[0].y, boxes[0].w, boxes[0].h), (20, 10, 14, 36));
/// assert_eq!(boxes[1], ground);
/// // A camera that pans leaves the boxes as they are.
/// let mut boxes = [coat, ground];
/// let pan = Homography::translation(3.0, 0.0).unwrap();
/// assert_eq!(grow_over_change(&prev, &next, &mut boxes, 2, &pan), 2);
/// assert_eq!(boxes[0], coat);
/// ```
pub fn grow_over_change(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    boxes: &mut [MotionBox],
    count: usize,
    camera: &impl CameraMotion,
) -> usize {
    let count = count.min(boxes.len());
    let (Some(a), Some(b)) = (prev.level(1), next.level(1)) else {
        return count;
    };
    let base = prev.base();
    if count == 0 || !a.same_size(&b) || !is_still(camera, &base) {
        return count;
    }
    let change = Change {
        a,
        b,
        full: (base.width(), base.height()),
    };
    if change.nearly_everywhere() {
        return count;
    }
    let mut count = count;
    let mut i = 0;
    while i < count {
        let Some(&found) = boxes.get(i) else {
            break;
        };
        let mut body = change.grown(&found);
        if body != found {
            // The boxes the grown one now overlaps are joined to it. Boxes that overlapped
            // before, none of them grown, stay as they were (two walkers passing each other).
            // Each join may bring the body over a box already passed: the search starts over.
            let mut j = 0;
            while j < count {
                match boxes.get(j) {
                    Some(other) if j != i && body.overlap_area(other) > 0 => {
                        body = larger_first(&body, other);
                        boxes.copy_within(j.saturating_add(1)..count, j);
                        count = count.saturating_sub(1);
                        if j < i {
                            i = i.saturating_sub(1);
                        }
                        j = 0;
                    }
                    _ => j = j.saturating_add(1),
                }
            }
            if let Some(slot) = boxes.get_mut(i) {
                *slot = body;
            }
        }
        i = i.saturating_add(1);
    }
    let legs_of =
        |body: &MotionBox, part: &MotionBox| stands_below(body, part) && !change.is_shadow(part);
    join_pairs(
        boxes,
        count,
        |a, b| legs_of(a, b) || legs_of(b, a),
        larger_first,
    )
}

/// Whether `camera` moves no pixel of `frame` by more than [`STILL_PX`]: its corners and
/// centre are checked, which bound a homography's flow over the frame but for a strong
/// perspective.
fn is_still(camera: &impl CameraMotion, frame: &ImageView<'_>) -> bool {
    #[allow(clippy::cast_precision_loss)] // frame sides are at most 4096
    let (w, h) = (frame.width() as f32, frame.height() as f32);
    let points = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h), (w / 2.0, h / 2.0)];
    points.iter().all(|&(x, y)| {
        let (dx, dy) = camera.flow_at(x, y);
        dx * dx + dy * dy <= STILL_PX * STILL_PX
    })
}

/// Level 1 of both frames of a pair, and the full frame's size.
struct Change<'f> {
    a: ImageView<'f>,
    b: ImageView<'f>,
    full: (usize, usize),
}

/// One axis of a box found, full-resolution pixels, and which of its ends grew on level 1.
struct Side {
    start: usize,
    end: usize,
    low_grew: bool,
    high_grew: bool,
}

impl Side {
    fn of(start: u16, len: u16, low_grew: bool, high_grew: bool) -> Self {
        let start = usize::from(start);
        Self {
            start,
            end: start.saturating_add(usize::from(len)),
            low_grew,
            high_grew,
        }
    }

    /// The ends of this axis once grown to the level-1 ends `(low, high)`, within `size`.
    /// The changed pixels hold the mover where it is in both frames, and the box is in the
    /// earlier one: the end that grew ahead of the motion `flow` comes back by it, as far as
    /// the end found.
    fn grown(&self, (low, high): (usize, usize), size: usize, flow: Q16) -> (usize, usize) {
        // Rounded to whole pixels; Q16 bits of a flow far below 2^15 px.
        let ahead = flow.to_bits().saturating_add(1 << 15) >> 16;
        let shift = usize::try_from(ahead.unsigned_abs()).unwrap_or(usize::MAX);
        let mut start = if self.low_grew {
            low.saturating_mul(2).min(self.start)
        } else {
            self.start
        };
        let mut end = if self.high_grew {
            high.saturating_mul(2).min(size).max(self.end)
        } else {
            self.end
        };
        if ahead > 0 && self.high_grew {
            end = end.saturating_sub(shift).max(self.end);
        }
        if ahead < 0 && self.low_grew {
            start = start.saturating_add(shift).min(self.start);
        }
        (start, end)
    }
}

/// Pixels a part must have changed by for [`Change::is_shadow`] to judge it.
const SHADOW_PIXELS: usize = 8;

/// The least correlation of a shadow's pixels with the ground they darken.
const SHADOW_TEXTURE: f32 = 0.7;

/// Sums of pixel pairs, for their correlation: up to 2^16 pixels of values below 2^8 keep
/// every sum below 2^32 and `n` times a sum below 2^48, exact in `u64`; a larger part (none
/// that stands below a body comes near) saturates, a wrong verdict at worst.
#[derive(Default)]
struct Sums {
    n: usize,
    a: u64,
    b: u64,
    aa: u64,
    bb: u64,
    ab: u64,
}

impl Sums {
    fn add(&mut self, a: u8, b: u8) {
        let (a, b) = (u64::from(a), u64::from(b));
        self.n = self.n.saturating_add(1);
        self.a = self.a.saturating_add(a);
        self.b = self.b.saturating_add(b);
        self.aa = self.aa.saturating_add(a.saturating_mul(a));
        self.bb = self.bb.saturating_add(b.saturating_mul(b));
        self.ab = self.ab.saturating_add(a.saturating_mul(b));
    }

    /// Whether the pairs correlate positively by more than `threshold` (at least 0).
    fn correlates_above(&self, threshold: f32) -> bool {
        debug_assert!(
            threshold >= 0.0,
            "squared, a negative threshold would flip the test"
        );
        let n = u64::try_from(self.n).unwrap_or(u64::MAX);
        let var = |squares: u64, sum: u64| {
            n.saturating_mul(squares)
                .saturating_sub(sum.saturating_mul(sum))
        };
        let (var_a, var_b) = (var(self.aa, self.a), var(self.bb, self.b));
        let (products, means) = (n.saturating_mul(self.ab), self.a.saturating_mul(self.b));
        if products <= means || var_a == 0 || var_b == 0 {
            return false;
        }
        // Once a part, in floating point: corr > t  <=>  cov^2 > t^2 var_a var_b (cov > 0).
        #[allow(clippy::cast_precision_loss)] // a threshold's test: 24 bits are plenty
        let [cov, var_a, var_b] = [products.saturating_sub(means), var_a, var_b].map(|v| v as f32);
        cov * cov > threshold * threshold * var_a * var_b
    }
}

impl Change<'_> {
    /// The values of pixel (`x`, `y`) of level 1 in both frames, when they differ by more
    /// than [`CHANGE_LEVELS`].
    fn differs(&self, x: usize, y: usize) -> Option<(u8, u8)> {
        let (a, b) = (self.a.get(x, y)?, self.b.get(x, y)?);
        (a.abs_diff(b) > CHANGE_LEVELS).then_some((a, b))
    }

    /// Whether pixel (`x`, `y`) of level 1 changed between the frames by more than
    /// [`CHANGE_LEVELS`] and not as a shadow does; false off the level.
    fn at(&self, x: usize, y: usize) -> bool {
        let Some((a, b)) = self.differs(x, y) else {
            return false;
        };
        let (dark, bright) = (u16::from(a.min(b)), u16::from(a.max(b)));
        // Each product is below 10 x 255.
        let times = |k: u16, v: u16| k.saturating_mul(v);
        let shadow = times(5, dark) >= times(2, bright) && times(10, dark) <= times(9, bright);
        !shadow
    }

    /// Whether more than [`MOST_CHANGED`] of the level changed, shadows or not (an exposure
    /// step dims or brightens the frame by a factor as a shadow does), judged on every fourth
    /// pixel of every fourth row.
    fn nearly_everywhere(&self) -> bool {
        let (w, h) = (self.a.width(), self.a.height());
        let (mut changed, mut seen) = (0usize, 0usize);
        for y in (0..h).step_by(4) {
            for x in (0..w).step_by(4) {
                seen = seen.saturating_add(1);
                changed = changed.saturating_add(usize::from(self.differs(x, y).is_some()));
            }
        }
        let (share, of) = MOST_CHANGED;
        changed.saturating_mul(of) > seen.saturating_mul(share)
    }

    /// Whether `part` (at full resolution) changed between the frames as a shadow falling on
    /// the ground or leaving it does: most of its changed pixels darkened or brightened by a
    /// shadow's factor, and the ground's texture kept under it (the changed pixels' values in
    /// the two frames correlate by more than [`SHADOW_TEXTURE`]). A walker's dark legs over a
    /// pale street darken the street by a shadow's factor too, but put their own look in its
    /// place. False when fewer than [`SHADOW_PIXELS`] pixels changed.
    fn is_shadow(&self, part: &MotionBox) -> bool {
        let span = Span::of(part, self.size());
        let mut sums = Sums::default();
        let mut shadow = 0usize;
        for y in span.y0..span.y1 {
            for x in span.x0..span.x1 {
                if let Some((a, b)) = self.differs(x, y) {
                    sums.add(a.min(b), a.max(b));
                    shadow = shadow.saturating_add(usize::from(!self.at(x, y)));
                }
            }
        }
        let changed = sums.n;
        changed >= SHADOW_PIXELS
            && shadow.saturating_mul(2) > changed
            && sums.correlates_above(SHADOW_TEXTURE)
    }

    /// The size of level 1.
    fn size(&self) -> (usize, usize) {
        (self.a.width(), self.a.height())
    }

    /// `found` (px of the full frame) grown side by side, on level 1, over the changed pixels
    /// within [`REACH`] of a changed pixel inside it, until none is, or until a side has grown
    /// by [`MOST_GROWTH`] times the box's length.
    fn grown(&self, found: &MotionBox) -> MotionBox {
        let (w, h) = self.size();
        let start = Span::of(found, (w, h));
        if start.x0 >= start.x1 || start.y0 >= start.y1 {
            return *found;
        }
        let reach = |low: usize, high: usize| MOST_GROWTH.saturating_mul(high.saturating_sub(low));
        let (across, down) = (reach(start.x0, start.x1), reach(start.y0, start.y1));
        let limit = Span {
            x0: start.x0.saturating_sub(across),
            y0: start.y0.saturating_sub(down),
            x1: start.x1.saturating_add(across).min(w),
            y1: start.y1.saturating_add(down).min(h),
        };
        let mut span = start;
        while let Some(wider) = self.step(&span, &limit) {
            span = wider;
        }
        if span == start {
            return *found;
        }
        // Back to full resolution: only the sides that grew move, inside the frame.
        let (fw, fh) = self.full;
        let x = Side::of(found.x, found.w, span.x0 < start.x0, span.x1 > start.x1);
        let y = Side::of(found.y, found.h, span.y0 < start.y0, span.y1 > start.y1);
        let (x0, x1) = x.grown((span.x0, span.x1), fw, found.mean_flow.x);
        let (y0, y1) = y.grown((span.y0, span.y1), fh, found.mean_flow.y);
        let px = |v: usize| u16::try_from(v).unwrap_or(u16::MAX);
        MotionBox {
            x: px(x0),
            y: px(y0),
            w: px(x1.saturating_sub(x0)),
            h: px(y1.saturating_sub(y0)),
            ..*found
        }
    }

    /// `span` grown by one pixel on every side where a changed pixel just outside it lies
    /// within [`REACH`] of a changed pixel inside it, within `limit`; `None` when no side grows.
    fn step(&self, span: &Span, limit: &Span) -> Option<Span> {
        let mut wider = *span;
        let (rows, columns) = (span.y0..span.y1, span.x0..span.x1);
        let column = |x: usize| rows.clone().any(|y| self.linked((x, y), span));
        let row = |y: usize| columns.clone().any(|x| self.linked((x, y), span));
        // Each side moves at most to its limit, which lies inside the level.
        if span.x0 > limit.x0 && column(span.x0.saturating_sub(1)) {
            wider.x0 = span.x0.saturating_sub(1);
        }
        if span.x1 < limit.x1 && column(span.x1) {
            wider.x1 = span.x1.saturating_add(1);
        }
        if span.y0 > limit.y0 && row(span.y0.saturating_sub(1)) {
            wider.y0 = span.y0.saturating_sub(1);
        }
        if span.y1 < limit.y1 && row(span.y1) {
            wider.y1 = span.y1.saturating_add(1);
        }
        (wider != *span).then_some(wider)
    }

    /// Whether pixel `(x, y)` changed and a changed pixel of `span` lies within [`REACH`] of
    /// it on both axes.
    fn linked(&self, (x, y): (usize, usize), span: &Span) -> bool {
        if !self.at(x, y) {
            return false;
        }
        let near = |v: usize, low: usize, high: usize| {
            v.saturating_sub(REACH).max(low)..v.saturating_add(REACH + 1).min(high)
        };
        let (xs, ys) = (near(x, span.x0, span.x1), near(y, span.y0, span.y1));
        ys.into_iter()
            .any(|yi| xs.clone().any(|xi| self.at(xi, yi)))
    }
}

/// A box on level 1, in pixels, ends excluded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Span {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl Span {
    /// The pixels of level 1 (`size`) that box `b` of the full frame covers.
    fn of(b: &MotionBox, (w, h): (usize, usize)) -> Self {
        Self {
            x0: usize::from(b.x >> 1),
            y0: usize::from(b.y >> 1),
            x1: usize::from(b.x.saturating_add(b.w)).div_ceil(2).min(w),
            y1: usize::from(b.y.saturating_add(b.h)).div_ceil(2).min(h),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ego::Homography;
    use crate::pyramid::pyramid_storage_len;
    use crate::q16::Point;

    const W: usize = 64;
    const H: usize = 48;

    /// Light ground, with `value` over the columns `left..left + 12` of rows 10 to 39.
    fn frame(left: usize, ground: u8, value: u8) -> [u8; W * H] {
        core::array::from_fn(|i| {
            let (x, y) = (i % W, i / W);
            let on = (left..left + 12).contains(&x) && (10..40).contains(&y);
            if on {
                value
            } else {
                ground
            }
        })
    }

    /// The boxes grown between frames `a` and `b` under a still camera.
    fn grow(a: &[u8], b: &[u8], boxes: &mut [MotionBox]) -> usize {
        let mut sa = [0u8; pyramid_storage_len(W, H, 1)];
        let mut sb = [0u8; pyramid_storage_len(W, H, 1)];
        let prev = Pyramid::build(ImageView::packed(a, W, H).unwrap(), 1, &mut sa).unwrap();
        let next = Pyramid::build(ImageView::packed(b, W, H).unwrap(), 1, &mut sb).unwrap();
        let count = boxes.len();
        grow_over_change(&prev, &next, boxes, count, &Homography::IDENTITY)
    }

    fn part(x: u16, y: u16, flow: f32) -> MotionBox {
        MotionBox {
            x,
            y,
            w: 8,
            h: 8,
            nodes: 1,
            mean_flow: Point::from_f32(flow, 0.0),
        }
    }

    #[test]
    fn a_dark_mover_grows_and_its_shadow_does_not() {
        let top = part(24, 10, 4.0);
        let mut boxes = [top];
        grow(&frame(20, 170, 20), &frame(24, 170, 20), &mut boxes);
        assert_eq!((boxes[0].y, boxes[0].h), (10, 30), "grown down the mover");
        // The same moving patch dimming the ground to 0.6 of its brightness: a shadow.
        let mut boxes = [top];
        grow(&frame(20, 170, 102), &frame(24, 170, 102), &mut boxes);
        assert_eq!(boxes[0], top);
    }

    #[test]
    fn a_grown_box_takes_in_the_parts_it_reaches_before_and_after_it() {
        let (foot, top, hand) = (part(22, 34, 2.0), part(24, 10, 4.0), part(52, 20, -1.0));
        let mut boxes = [foot, top, hand];
        assert_eq!(
            grow(&frame(20, 170, 20), &frame(24, 170, 20), &mut boxes[..]),
            2
        );
        assert_eq!((boxes[0].x, boxes[0].y, boxes[0].h), (20, 10, 32));
        // The foot's box grew first, over the whole mover: the larger box, its flow kept. A
        // box away from the mover stays as it was.
        assert_eq!((boxes[0].mean_flow, boxes[1]), (foot.mean_flow, hand));
    }

    /// Textured ground, with a patch of 8 x 8 px at (`left`, 32) that is `patch` of the
    /// ground's value there and of the pixel's place in the patch.
    fn feet_frame(left: usize, patch: impl Fn(u8, (usize, usize)) -> u8) -> [u8; W * H] {
        core::array::from_fn(|i| {
            let (x, y) = (i % W, i / W);
            let ground = 90 + ((x + 2 * y) % 24 * 5) as u8;
            let on = (left..left + 8).contains(&x) && (32..40).contains(&y);
            if on {
                patch(ground, (x - left, y - 32))
            } else {
                ground
            }
        })
    }

    #[test]
    fn feet_below_a_body_join_it_and_a_shadow_below_it_does_not() {
        // A body whose box ends 8 px above the feet: beyond the growth's reach.
        let body = MotionBox {
            x: 18,
            y: 4,
            w: 14,
            h: 20,
            nodes: 6,
            mean_flow: Point::from_f32(4.0, 0.0),
        };
        let feet = part(20, 32, 4.0);
        let mut boxes = [body, feet];
        let dark = |_, _| 20;
        assert_eq!(
            grow(&feet_frame(20, dark), &feet_frame(24, dark), &mut boxes),
            1
        );
        assert_eq!((boxes[0].x, boxes[0].y, boxes[0].h), (18, 4, 36));
        assert_eq!(boxes[0].mean_flow, body.mean_flow);
        // Shoes of a texture of their own, about 0.6 times the ground's brightness: a shadow's
        // factor, but not the ground's look.
        let shoes = |_, (x, y): (usize, usize)| 62 + ((3 * x + y) % 8 * 3) as u8;
        let mut boxes = [body, feet];
        let (a, b) = (feet_frame(20, shoes), feet_frame(24, shoes));
        assert_eq!(grow(&a, &b, &mut boxes), 1);
        // The same patch 0.6 times the ground below it keeps the ground's texture: a shadow.
        let shade = |g: u8, _| (u16::from(g) * 3 / 5) as u8;
        let mut boxes = [body, feet];
        assert_eq!(
            grow(&feet_frame(20, shade), &feet_frame(24, shade), &mut boxes),
            2
        );
        assert_eq!(boxes[0], body);
    }

    #[test]
    fn pairs_correlate_when_one_follows_the_other() {
        let sums = |pairs: &[(u8, u8)]| {
            let mut s = Sums::default();
            pairs.iter().for_each(|&(a, b)| s.add(a, b));
            s
        };
        // Darker values 0.6 times the brighter ones: a shade over a texture.
        let shade = [(60, 100), (72, 120), (84, 140), (66, 110), (90, 150)];
        assert!(sums(&shade).correlates_above(0.7));
        // The same brighter values under darker ones of their own.
        let own = [(70, 100), (60, 120), (75, 140), (62, 110), (66, 150)];
        assert!(!sums(&own).correlates_above(0.7));
        // Against each other, or without any spread on one side: no correlation.
        let against = [(90, 100), (80, 120), (70, 140), (85, 110), (60, 150)];
        assert!(!sums(&against).correlates_above(0.0));
        assert!(!sums(&[(60, 100), (60, 120), (60, 140)]).correlates_above(0.0));
    }

    #[test]
    fn an_exposure_step_leaves_the_boxes() {
        let top = part(24, 10, 4.0);
        let mut boxes = [top];
        // The whole frame 60 levels brighter, the mover too.
        grow(&frame(20, 100, 20), &frame(24, 160, 80), &mut boxes);
        assert_eq!(boxes[0], top);
    }

    #[test]
    fn boxes_that_overlapped_before_and_did_not_grow_stay_apart() {
        let (a, b) = (part(2, 2, 1.0), part(6, 4, -1.0));
        let still = frame(20, 170, 170);
        let mut boxes = [a, b];
        assert_eq!(grow(&still, &still, &mut boxes), 2);
        assert_eq!(boxes, [a, b]);
    }
}
