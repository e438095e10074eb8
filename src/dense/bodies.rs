//! The reported boxes that are parts of one body, joined: [`join_bodies`].
//!
//! The outline joins the parts of one body only inside one candidate region. A walker's parts
//! often come from regions of their own: the mask breaks at the leg that stands on the ground,
//! and an arm or the head moves apart from the torso for a pair or two. Each part then
//! persists, and a walker is reported as two or three boxes. So the reported boxes that lie
//! within [`BODY_GAP`] of each other and move alike against the camera are joined, by the
//! outline's own rule for the parts of one region: their motions differ by at most a pixel or
//! half the faster one's. Against the camera, not as flows: under a camera that pans, two
//! objects passing each other have flows that differ by less than half the faster one's.
//!
//! Two objects that pass each other often touch. Against the camera their motions differ by
//! 0.7 to 2 times the faster one's on the flights of `bench/motion_vs_truth.py`, and none of
//! their 56 touching pairs by less than half; the parts of one walker in OpenCV's vtest clip
//! (frame 176) by 0.28 to 0.95. Walkers that walk side by side at one pace are joined, as a
//! background subtractor joins them.

use super::motion::CameraMotion;
use super::outline::moves_alike;
use super::regions::MotionBox;
use crate::q16::Point;

/// Boxes at most this far apart, px (the ground between them), may be parts of one body: the
/// reach of the parts of one region in the outline.
pub const BODY_GAP: u16 = 4;

/// Joins the first `count` of `boxes` that are parts of one body (within [`BODY_GAP`] px of
/// each other, moving alike against `camera`) into one box each, with the larger part's
/// nodes and flow, where the earlier part was; returns how many boxes are left, at the front
/// of `boxes` in their order.
///
/// A still camera; a walker's torso, and its leg below it swinging at nearly twice its speed,
/// join; a cyclist passing beside the walker the other way stays a box of its own:
///
/// ```
/// use kestrel::dense::{join_bodies, MotionBox};
/// use kestrel::ego::Homography;
/// use kestrel::Point;
///
/// let still = Homography::IDENTITY;
/// let part = |x, y, w, h, flow: (f32, f32)| MotionBox {
///     x, y, w, h, nodes: 1, mean_flow: Point::from_f32(flow.0, flow.1),
/// };
/// let torso = part(40, 20, 12, 18, (2.0, 0.0));
/// let leg = part(42, 40, 6, 12, (3.6, 0.2));
/// let cyclist = part(53, 22, 14, 20, (-3.0, 0.0));
/// let mut boxes = [torso, leg, cyclist];
/// let left = join_bodies(&mut boxes, 3, &still);
/// assert_eq!(left, 2);
/// assert_eq!((boxes[0].x, boxes[0].y, boxes[0].w, boxes[0].h), (40, 20, 12, 32));
/// assert_eq!(boxes[1], cyclist);
/// ```
pub fn join_bodies(boxes: &mut [MotionBox], count: usize, camera: &impl CameraMotion) -> usize {
    let one_body = |a: &MotionBox, b: &MotionBox| {
        a.gap_to(b) <= BODY_GAP && moves_alike(against_camera(a, camera), against_camera(b, camera))
    };
    join_pairs(boxes, count, one_body, larger_first)
}

/// Whether `part` lies below `body` as a walker's legs or feet lie below its coat: no taller
/// than half of `body`, its top below `body`'s middle, at most half `body`'s height under it,
/// and half its width or more within `body`'s columns. Whatever their motions: a foot that
/// stands on the ground does not move while the body above it does.
pub(super) fn stands_below(body: &MotionBox, part: &MotionBox) -> bool {
    let (top, height) = (u32::from(body.y), u32::from(body.h));
    let (part_top, part_height) = (u32::from(part.y), u32::from(part.h));
    let bottom = top.saturating_add(height);
    let columns = |b: &MotionBox| {
        (
            u32::from(b.x),
            u32::from(b.x).saturating_add(u32::from(b.w)),
        )
    };
    let ((left, right), (part_left, part_right)) = (columns(body), columns(part));
    let shared = right.min(part_right).saturating_sub(left.max(part_left));
    part_height.saturating_mul(2) <= height
        && part_top.saturating_mul(2) >= top.saturating_mul(2).saturating_add(height)
        && part_top.saturating_sub(bottom).saturating_mul(2) <= height
        && shared.saturating_mul(2) >= u32::from(part.w)
}

/// The box around `a` and `b`, with the larger one's nodes and flow.
pub(super) fn larger_first(a: &MotionBox, b: &MotionBox) -> MotionBox {
    if a.area() >= b.area() {
        a.union(b)
    } else {
        b.union(a)
    }
}

/// Joins the first `count` of `boxes` two at a time, each time the first pair `i < j` that
/// `one_body` takes for parts of one body, into `merge(i, j)` where `i` was, until no two are;
/// returns how many boxes are left, at the front of `boxes` in their order. The outline joins
/// the parts of one region so, and [`join_bodies`] the reported boxes.
pub(super) fn join_pairs(
    boxes: &mut [MotionBox],
    count: usize,
    one_body: impl Fn(&MotionBox, &MotionBox) -> bool,
    merge: impl Fn(&MotionBox, &MotionBox) -> MotionBox,
) -> usize {
    let mut count = count.min(boxes.len());
    while let Some((i, j)) = first_pair(boxes.get(..count).unwrap_or(&[]), &one_body) {
        debug_assert!(i < j && j < count, "a pair of the first {count} boxes");
        let (Some(a), Some(b)) = (boxes.get(i), boxes.get(j)) else {
            break;
        };
        let body = merge(a, b);
        if let Some(slot) = boxes.get_mut(i) {
            *slot = body;
        }
        boxes.copy_within(j.saturating_add(1)..count, j);
        count = count.saturating_sub(1);
    }
    count
}

/// The first pair `i < j` of `boxes` that `one_body` takes for parts of one body.
fn first_pair(
    boxes: &[MotionBox],
    one_body: &impl Fn(&MotionBox, &MotionBox) -> bool,
) -> Option<(usize, usize)> {
    boxes.iter().enumerate().find_map(|(i, a)| {
        let rest = boxes.iter().enumerate().skip(i.saturating_add(1));
        rest.filter(|(_, b)| one_body(a, b))
            .map(|(j, _)| (i, j))
            .next()
    })
}

/// The flow of `b` less the camera's at its centre.
fn against_camera(b: &MotionBox, camera: &impl CameraMotion) -> Point {
    let centre = |start: u16, len: u16| f32::from(start) + f32::from(len) / 2.0;
    let (dx, dy) = camera.flow_at(centre(b.x, b.w), centre(b.y, b.h));
    let camera = Point::from_f32(dx, dy);
    Point::new(
        b.mean_flow.x.saturating_sub(camera.x),
        b.mean_flow.y.saturating_sub(camera.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera panning `.0` px a frame to the right.
    struct Pan(f32);

    impl CameraMotion for Pan {
        fn flow_at(&self, _x: f32, _y: f32) -> (f32, f32) {
            (self.0, 0.0)
        }
    }

    fn part(x: u16, y: u16, w: u16, h: u16, flow: (f32, f32)) -> MotionBox {
        MotionBox {
            x,
            y,
            w,
            h,
            nodes: 1,
            mean_flow: Point::from_f32(flow.0, flow.1),
        }
    }

    #[test]
    fn a_small_box_below_a_body_and_within_its_columns_stands_below_it() {
        let torso = part(40, 20, 12, 20, (2.0, 0.0));
        let still = (0.0, 0.0);
        // A foot 8 px below, planted: whatever its motion.
        assert!(stands_below(&torso, &part(42, 48, 6, 8, still)));
        assert!(!stands_below(&part(42, 48, 6, 8, still), &torso));
        // Taller than half the body: a person of its own.
        assert!(!stands_below(&torso, &part(42, 48, 6, 11, still)));
        // More than half the body's height below it, or beside it.
        assert!(!stands_below(&torso, &part(42, 51, 6, 8, still)));
        assert!(!stands_below(&torso, &part(49, 42, 8, 8, still)));
        // Overlapping the body's lower half is standing below it too.
        assert!(stands_below(&torso, &part(44, 32, 6, 10, still)));
        assert!(!stands_below(&torso, &part(44, 28, 6, 10, still)));
    }

    #[test]
    fn motion_is_judged_against_the_camera() {
        // A camera panning 6 px a frame: two objects beside each other that move 2.5 px and
        // -1.5 px against it (flows 8.5 and 4.5 px) are two bodies, though their flows differ
        // by less than half the faster one's; on a still camera, two passing each other are two
        // as well.
        let pan = Pan(6.0);
        let a = part(10, 10, 10, 10, (8.5, 0.0));
        let b = part(22, 10, 10, 10, (4.5, 0.0));
        let mut boxes = [a, b];
        assert_eq!(join_bodies(&mut boxes, 2, &Pan(0.0)), 1, "alike as flows");
        let mut boxes = [a, b];
        assert_eq!(join_bodies(&mut boxes, 2, &pan), 2);
        let still = Pan(0.0);
        let b = part(22, 10, 10, 10, (-8.5, 0.0));
        let mut boxes = [a, b];
        assert_eq!(join_bodies(&mut boxes, 2, &still), 2);
        // Against the pan, a part moving 3.5 px beside one moving 2.5 px: one body.
        let c = part(22, 10, 10, 10, (9.5, 0.0));
        let mut boxes = [a, c];
        assert_eq!(join_bodies(&mut boxes, 2, &pan), 1);
    }

    #[test]
    fn joining_reaches_four_pixels_and_chains() {
        let still = Pan(0.0);
        // Legs, torso, head: each within 4 px of the next only; the legs, the largest, give
        // the body its flow, and the body stays where the legs were.
        let legs = part(40, 37, 14, 16, (1.8, 0.2));
        let torso = part(40, 20, 12, 14, (1.2, 0.0));
        let head = part(44, 10, 6, 6, (1.0, 0.0));
        let far = part(59, 20, 6, 6, (1.2, 0.0));
        let mut boxes = [far, legs, torso, head];
        assert_eq!(join_bodies(&mut boxes, 4, &still), 2);
        assert_eq!(boxes[0], far);
        assert_eq!(
            (boxes[1].x, boxes[1].y, boxes[1].w, boxes[1].h),
            (40, 10, 14, 43)
        );
        assert_eq!(boxes[1].mean_flow, legs.mean_flow);
    }

    #[test]
    fn boxes_past_the_count_are_left_alone() {
        let still = Pan(0.0);
        let small = part(0, 0, 4, 4, (1.0, 0.0));
        let big = part(30, 30, 10, 10, (1.0, 0.0));
        let beside = part(4, 0, 4, 4, (1.0, 0.0));
        let unread = part(8, 0, 4, 4, (1.0, 0.0));
        let mut boxes = [small, big, beside, unread];
        // The two small ones join into an 8 x 4 box in the first place.
        assert_eq!(join_bodies(&mut boxes, 3, &still), 2);
        assert_eq!((boxes[0].x, boxes[0].w), (0, 8));
        assert_eq!(boxes[1], big);
        assert_eq!(boxes[3], unread);
        // A count past the slice is the slice: the 8 x 4 box, the stale copy of the one it
        // took in and the box that was not read join into one 12 x 4.
        assert_eq!(join_bodies(&mut boxes, 9, &still), 2);
        assert_eq!((boxes[0].x, boxes[0].w), (0, 12));
    }
}
