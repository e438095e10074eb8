//! The firmware's checks of its own results against the scene's ground truth.
//!
//! Each check returns the figure it measured, so the report shows how close a pass was; the
//! tolerances are here, in one place.

use kestrel::dense::MotionBox;
use kestrel::ego::mavlink::OPTICAL_FLOW_RAD_ID;
use kestrel::ego::{EgoStatus, OpticalFlowRad};
use kestrel::Point;

use crate::pipeline::{Tracked, MAX_TRACKS};
use crate::scene::{object_origin_millipx, MOTION_MILLIPX, OBJECT_MOTION_MILLIPX, OBJECT_SIDE};

/// The largest median error of the tracks' frame-to-frame displacements, px.
pub const TRACK_TOLERANCE: f32 = 0.08;
/// The fewest live tracks after any frame.
pub const MIN_LIVE_TRACKS: usize = 70;
/// The largest error of the OPTICAL_FLOW_RAD flow, as pixels at the principal point.
pub const FLOW_TOLERANCE_PX: f32 = 0.05;
/// The smallest overlap (intersection over union) of the best box with the object.
pub const MIN_BOX_IOU: f32 = 0.3;
/// The first frame whose pair must box the object: a region is boxed once it has moved in
/// two consecutive pairs, so the first pair (frames 0 and 1) boxes nothing.
pub const FIRST_BOXED_FRAME: usize = 2;
/// Tracks this close to the object's edge (px) are left out of the error: their windows see
/// both motions.
const EDGE_MARGIN: f32 = 6.0;

/// What the checks of one frame measured, and whether it passed.
#[derive(Debug, Clone, Copy, Default)]
pub struct Verdict {
    /// Median error of the checked tracks' displacements, px.
    pub track_error: f32,
    /// Tracks whose displacement was checked.
    pub checked_tracks: usize,
    /// Error of the reading's flow, rad, the larger axis.
    pub flow_error: f32,
    /// The best box's overlap with the object.
    pub box_iou: f32,
    /// Boxes that do not touch the object.
    pub false_boxes: usize,
    /// Whether a box had to find the object (from [`FIRST_BOXED_FRAME`] on).
    pub box_asked: bool,
    /// Whether every check passed.
    pub passed: bool,
}

/// The truth for a frame pair ending in frame `frame`: where the object was before it.
struct Truth {
    /// The object's rectangle in the previous frame: left, top, right, bottom, px.
    object: (f32, f32, f32, f32),
}

impl Truth {
    fn of(frame: usize) -> Self {
        let (x, y) = object_origin_millipx(frame.saturating_sub(1));
        let (x, y) = (x as f32 / 1000.0, y as f32 / 1000.0);
        let side = OBJECT_SIDE as f32;
        Self {
            object: (x, y, x + side, y + side),
        }
    }

    /// The displacement of a point at `p` in the previous frame, px; `None` near the object's
    /// edge.
    fn motion(&self, (x, y): (f32, f32)) -> Option<(f32, f32)> {
        let (l, t, r, b) = self.object;
        let inside = |m: f32| x > l + m && x < r - m && y > t + m && y < b - m;
        let millipx = |(dx, dy): (i32, i32)| (dx as f32 / 1000.0, dy as f32 / 1000.0);
        if inside(EDGE_MARGIN) {
            Some(millipx(OBJECT_MOTION_MILLIPX))
        } else if !inside(-EDGE_MARGIN) {
            Some(millipx(MOTION_MILLIPX))
        } else {
            None
        }
    }
}

/// Checks frame `frame`'s output: the tracks, the flow reading and its MAVLink frame, the boxes.
pub fn check(
    frame: usize,
    tracked: &Tracked,
    pairs: &[(Point, Point)],
    mavlink: &[u8],
    boxes: &[MotionBox],
    focal: f32,
) -> Verdict {
    let truth = Truth::of(frame);
    let (track_error, checked_tracks) = track_error(&truth, pairs);
    let flow_error = flow_error(&tracked.flow, focal);
    let (box_iou, false_boxes) = box_overlap(&truth, boxes);
    let box_asked = frame >= FIRST_BOXED_FRAME;
    let passed = checked_tracks > 0
        && track_error <= TRACK_TOLERANCE
        && tracked.report.live >= MIN_LIVE_TRACKS
        && tracked.motion.status == EgoStatus::Ok
        && tracked.flow.quality > 0
        && flow_error <= flow_tolerance(focal)
        && encodes(&tracked.flow, mavlink)
        && (box_iou >= MIN_BOX_IOU || !box_asked)
        && false_boxes == 0;
    Verdict {
        track_error,
        checked_tracks,
        flow_error,
        box_iou,
        false_boxes,
        box_asked,
        passed,
    }
}

/// The flow tolerance in rad: [`FLOW_TOLERANCE_PX`] seen from the camera.
pub fn flow_tolerance(focal: f32) -> f32 {
    atan_small(FLOW_TOLERANCE_PX / focal)
}

/// The median endpoint error of the pairs' displacements, and how many pairs were checked.
fn track_error(truth: &Truth, pairs: &[(Point, Point)]) -> (f32, usize) {
    let mut errors = [0.0f32; MAX_TRACKS];
    let mut n = 0;
    for (before, now) in pairs {
        let (bx, by) = before.to_f32();
        let (nx, ny) = now.to_f32();
        let Some((mx, my)) = truth.motion((bx, by)) else {
            continue;
        };
        let (ex, ey) = (nx - bx - mx, ny - by - my);
        if let Some(slot) = errors.get_mut(n) {
            *slot = sqrt(ex * ex + ey * ey);
            n += 1;
        }
    }
    let errors = &mut errors[..n];
    errors.sort_unstable_by(f32::total_cmp);
    (errors.get(n / 2).copied().unwrap_or(f32::INFINITY), n)
}

/// The larger axis error of the reading's flow against the camera's motion, rad.
pub fn flow_error(flow: &OpticalFlowRad, focal: f32) -> f32 {
    let (mx, my) = MOTION_MILLIPX;
    // Image x is flow about X, image y flow about Y (see kestrel::ego::Camera::angular_flow).
    let expected_x = atan_small(mx as f32 / 1000.0 / focal);
    let expected_y = atan_small(my as f32 / 1000.0 / focal);
    let ex = (flow.integrated_x - expected_x).abs();
    let ey = (flow.integrated_y - expected_y).abs();
    if ex.is_nan() || ey.is_nan() {
        f32::INFINITY
    } else {
        ex.max(ey)
    }
}

/// Whether `frame` is the MAVLink 2 OPTICAL_FLOW_RAD frame of `flow`.
fn encodes(flow: &OpticalFlowRad, frame: &[u8]) -> bool {
    let id = OPTICAL_FLOW_RAD_ID.to_le_bytes();
    let header = frame.first() == Some(&0xFD) && frame.get(7..10) == id.get(..3);
    header
        && payload_f32(frame, 12) == Some(flow.integrated_x)
        && frame_quality(frame) == flow.quality
}

/// The quality byte of an OPTICAL_FLOW_RAD frame: MAVLink 2 trims trailing zero bytes of the
/// payload, so a missing byte is 0.
pub fn frame_quality(frame: &[u8]) -> u8 {
    const QUALITY: usize = 43;
    let payload_len = usize::from(frame.get(1).copied().unwrap_or(0));
    if payload_len > QUALITY {
        frame.get(10 + QUALITY).copied().unwrap_or(0)
    } else {
        0
    }
}

/// The `f32` at byte `offset` of the frame's payload.
fn payload_f32(frame: &[u8], offset: usize) -> Option<f32> {
    let bytes = frame.get(10 + offset..14 + offset)?;
    Some(f32::from_le_bytes(bytes.try_into().ok()?))
}

/// The best box's overlap with the object, and the boxes that do not touch it.
fn box_overlap(truth: &Truth, boxes: &[MotionBox]) -> (f32, usize) {
    let mut best = 0.0f32;
    let mut false_boxes = 0;
    for b in boxes {
        let (l, t) = (f32::from(b.x), f32::from(b.y));
        let (r, bottom) = (l + f32::from(b.w), t + f32::from(b.h));
        let (ol, ot, or, ob) = truth.object;
        let w = (r.min(or) - l.max(ol)).max(0.0);
        let h = (bottom.min(ob) - t.max(ot)).max(0.0);
        let intersection = w * h;
        if intersection == 0.0 {
            false_boxes += 1;
        }
        let union = (r - l) * (bottom - t) + (or - ol) * (ob - ot) - intersection;
        best = best.max(intersection / union.max(1.0));
    }
    (best, false_boxes)
}

/// `atan` of a small angle's tangent (below 0.01 here): two terms of its series are exact to
/// 1e-11 rad.
fn atan_small(x: f32) -> f32 {
    x - x * x * x / 3.0
}

/// Square root by Newton's method (`core` has none).
pub fn sqrt(x: f32) -> f32 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    let mut r = f32::from_bits((x.to_bits() >> 1) + 0x1fc0_0000);
    for _ in 0..5 {
        r = 0.5 * (r + x / r);
    }
    r
}
