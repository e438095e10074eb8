//! The synthetic camera sequence: its size, the camera's motion and the moving object, which
//! the firmware must recover.
//!
//! `build.rs` renders the frames from these numbers and the firmware checks its results against
//! them, so the ground truth has one source. Lengths are in thousandths of a pixel, so that both
//! sides compute the same positions exactly.

/// Frame width in pixels.
pub const WIDTH: usize = 160;
/// Frame height in pixels.
pub const HEIGHT: usize = 120;
/// Frames in the sequence.
pub const FRAMES: usize = 12;
/// Bytes of one packed 8-bit grey frame.
pub const FRAME_LEN: usize = WIDTH * HEIGHT;
/// How far the static scene moves between two consecutive frames (the camera's motion), in
/// thousandths of a pixel (x to the right, y down). Sub-pixel and different on both axes, so
/// neither rounding nor a swapped axis can pass the checks.
pub const MOTION_MILLIPX: (i32, i32) = (650, -350);
/// Side of the moving object, a textured square, in pixels.
pub const OBJECT_SIDE: i32 = 24;
/// The object's top-left corner in frame 0, in thousandths of a pixel.
pub const OBJECT_START_MILLIPX: (i32, i32) = (96_000, 40_000);
/// How far the object moves between two consecutive frames, in thousandths of a pixel: about
/// 2 px per frame against the background, well above the motion mask's 0.8 px threshold.
pub const OBJECT_MOTION_MILLIPX: (i32, i32) = (-1_100, 850);
/// Time between two frames, microseconds (100 frames per second).
pub const FRAME_INTERVAL_US: u32 = 10_000;
/// The camera's horizontal field of view, degrees.
pub const FIELD_OF_VIEW_DEGREES: f32 = 60.0;

/// The object's top-left corner in frame `frame`, in thousandths of a pixel.
pub const fn object_origin_millipx(frame: usize) -> (i32, i32) {
    let k = frame as i32;
    (
        OBJECT_START_MILLIPX.0 + k * OBJECT_MOTION_MILLIPX.0,
        OBJECT_START_MILLIPX.1 + k * OBJECT_MOTION_MILLIPX.1,
    )
}
