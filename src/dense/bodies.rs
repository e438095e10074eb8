//! The reported boxes that are parts of one body, joined: [`join_bodies`].
//!
//! The outline joins the parts of one body only inside one candidate region. A walker's parts
//! often come from regions of their own: the mask breaks at the leg that stands on the ground,
//! and an arm or the head moves apart from the torso for a pair or two. Each part then
//! persists, and a walker is reported as two or three boxes. So the reported boxes that lie
//! within [`BODY_GAP`] of each other and move alike against the camera are joined.
//!
//! "Alike" must be looser than inside a region (a leg swings at up to twice its torso's speed,
//! and a region's flow is a mean), yet keep apart two objects that pass each other, which
//! often touch. Against the camera, two such objects' motions differ by 0.7 to 2 times the
//! faster one's on the flights of `bench/motion_vs_truth.py` (4 of the 56 touching pairs
//! under 0.75); the parts of one walker in OpenCV's vtest clip (frame 176), by 0.28 to 0.95.
//! At three quarters, the flights' recall moves from 0.911 to 0.901 (160 x 120) and from
//! 0.954 to 0.948 (320 x 240), and vtest's walkers come in 1.12 boxes each instead of 1.15.

use super::motion::CameraMotion;
use super::regions::MotionBox;
use crate::q16::Point;

/// Boxes at most this far apart, px (the ground between them), may be parts of one body: the
/// same reach as the parts of one region ([`super::outline`]'s).
pub const BODY_GAP: u16 = 4;

/// Parts of one body move alike against the camera: their motions differ by at most three
/// quarters of the faster one's (as squares: 9/16), or of a pixel for slower parts.
const BODY_FLOW_NUM: i64 = 9;
const BODY_FLOW_DEN: i64 = 16;

/// One pixel, as a squared Q16 length.
const ONE_PX_SQ: i64 = 1 << 32;

/// Joins the first `count` of `boxes` that are parts of one body (within [`BODY_GAP`] px of
/// each other, moving alike against `camera`) into one box each, with the larger part's
/// nodes and flow; returns how many boxes are left, at the front of `boxes`, largest first.
///
/// A still camera; a walker's torso, and its leg below it swinging at twice its speed, join;
/// a cyclist passing beside the walker the other way stays a box of its own:
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
/// let leg = part(42, 40, 6, 12, (3.5, 0.5));
/// let cyclist = part(53, 22, 14, 20, (-3.0, 0.0));
/// let mut boxes = [torso, leg, cyclist];
/// let left = join_bodies(&mut boxes, 3, &still);
/// assert_eq!(left, 2);
/// assert_eq!((boxes[0].x, boxes[0].y, boxes[0].w, boxes[0].h), (40, 20, 12, 32));
/// assert_eq!(boxes[1], cyclist);
/// ```
pub fn join_bodies(boxes: &mut [MotionBox], count: usize, camera: &impl CameraMotion) -> usize {
    let mut count = count.min(boxes.len());
    let mut joined = false;
    while let Some((i, j)) = first_parts_of_one_body(boxes.get(..count).unwrap_or(&[]), camera) {
        // `i < j < count`, as found.
        let (Some(&a), Some(&b)) = (boxes.get(i), boxes.get(j)) else {
            break;
        };
        let body = if a.area() >= b.area() {
            a.union(&b)
        } else {
            b.union(&a)
        };
        if let Some(slot) = boxes.get_mut(i) {
            *slot = body;
        }
        boxes.copy_within(j.saturating_add(1)..count, j);
        count = count.saturating_sub(1);
        joined = true;
    }
    if joined {
        largest_first(boxes.get_mut(..count).unwrap_or(&mut []));
    }
    count
}

/// The first pair `i < j` of `boxes` that are parts of one body.
fn first_parts_of_one_body(
    boxes: &[MotionBox],
    camera: &impl CameraMotion,
) -> Option<(usize, usize)> {
    boxes.iter().enumerate().find_map(|(i, a)| {
        let rest = boxes.iter().enumerate().skip(i.saturating_add(1));
        rest.filter(|(_, b)| a.gap_to(b) <= BODY_GAP && moves_alike(a, b, camera))
            .map(|(j, _)| (i, j))
            .next()
    })
}

/// True when the motions of `a` and `b` against `camera` (each box's flow less the camera's at
/// its centre) differ by at most three quarters of the faster one, or of a pixel.
fn moves_alike(a: &MotionBox, b: &MotionBox, camera: &impl CameraMotion) -> bool {
    let (ax, ay) = against_camera(a, camera);
    let (bx, by) = against_camera(b, camera);
    let sq = |x: i64, y: i64| x.saturating_mul(x).saturating_add(y.saturating_mul(y));
    let apart = sq(ax.saturating_sub(bx), ay.saturating_sub(by));
    let faster = sq(ax, ay).max(sq(bx, by)).max(ONE_PX_SQ);
    apart.saturating_mul(BODY_FLOW_DEN) <= faster.saturating_mul(BODY_FLOW_NUM)
}

/// The flow of `b` less the camera's at its centre, Q16 bits.
fn against_camera(b: &MotionBox, camera: &impl CameraMotion) -> (i64, i64) {
    let centre = |start: u16, len: u16| f32::from(start) + f32::from(len) / 2.0;
    let (cx, cy) = camera.flow_at(centre(b.x, b.w), centre(b.y, b.h));
    let camera = Point::from_f32(cx, cy);
    let own = |flow: Point| (i64::from(flow.x.to_bits()), i64::from(flow.y.to_bits()));
    let ((fx, fy), (cx, cy)) = (own(b.mean_flow), own(camera));
    (fx.saturating_sub(cx), fy.saturating_sub(cy))
}

/// Sorts `boxes` by area, largest first, keeping the order of equal ones (few boxes: an
/// insertion sort, no allocation).
fn largest_first(boxes: &mut [MotionBox]) {
    for i in 1..boxes.len() {
        let mut k = i;
        while let Some(before) = k.checked_sub(1) {
            let (Some(a), Some(b)) = (boxes.get(before), boxes.get(k)) else {
                break;
            };
            if a.area() >= b.area() {
                break;
            }
            boxes.swap(before, k);
            k = before;
        }
    }
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
    fn motion_is_judged_against_the_camera() {
        // A camera panning 6 px a frame: two objects beside each other that move 2 px and
        // -2 px against it (flows 8 and 4 px) are two bodies, though their flows differ by
        // half the faster one's; on a still camera, two passing each other are two as well.
        let pan = Pan(6.0);
        let a = part(10, 10, 10, 10, (8.0, 0.0));
        let b = part(22, 10, 10, 10, (4.0, 0.0));
        let mut boxes = [a, b];
        assert_eq!(join_bodies(&mut boxes, 2, &pan), 2);
        let still = Pan(0.0);
        let b = part(22, 10, 10, 10, (-8.0, 0.0));
        let mut boxes = [a, b];
        assert_eq!(join_bodies(&mut boxes, 2, &still), 2);
        // Against the pan, a part moving 3.5 px beside one moving 2 px: one body.
        let c = part(22, 10, 10, 10, (9.5, 0.0));
        let mut boxes = [a, c];
        assert_eq!(join_bodies(&mut boxes, 2, &pan), 1);
    }

    #[test]
    fn joining_reaches_four_pixels_and_chains() {
        let still = Pan(0.0);
        // Head, torso, legs: each within 4 px of the next only; the legs, the largest, lead.
        let head = part(44, 10, 6, 6, (1.0, 0.0));
        let torso = part(40, 20, 12, 14, (1.2, 0.0));
        let legs = part(40, 37, 14, 16, (1.8, 0.2));
        let far = part(59, 20, 6, 6, (1.2, 0.0));
        let mut boxes = [legs, torso, head, far];
        assert_eq!(join_bodies(&mut boxes, 4, &still), 2);
        assert_eq!(
            (boxes[0].x, boxes[0].y, boxes[0].w, boxes[0].h),
            (40, 10, 14, 43)
        );
        assert_eq!(boxes[0].mean_flow, legs.mean_flow);
        // 5 px away stays apart.
        assert_eq!(boxes[1], far);
    }

    #[test]
    fn boxes_past_the_count_are_left_alone_and_the_result_is_largest_first() {
        let still = Pan(0.0);
        let small = part(0, 0, 4, 4, (1.0, 0.0));
        let big = part(30, 30, 10, 10, (1.0, 0.0));
        let beside = part(4, 0, 4, 4, (1.0, 0.0));
        let unread = part(8, 0, 4, 4, (1.0, 0.0));
        let mut boxes = [small, big, beside, unread];
        // The two small ones join into an 8 x 4 box, which stays after the 10 x 10 one.
        assert_eq!(join_bodies(&mut boxes, 3, &still), 2);
        assert_eq!(boxes[0], big);
        assert_eq!((boxes[1].x, boxes[1].w), (0, 8));
        assert_eq!(boxes[3], unread);
        // A count past the slice is the slice: the 8 x 4 box, the stale copy of the one it
        // took in and the box that was not read join into one 12 x 4.
        assert_eq!(join_bodies(&mut boxes, 9, &still), 2);
        assert_eq!((boxes[1].x, boxes[1].w), (0, 12));
    }
}
