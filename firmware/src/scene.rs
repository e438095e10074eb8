//! The synthetic camera sequence: its size and the motion the firmware must recover.
//!
//! `build.rs` renders the frames from these numbers and the firmware checks its flow against
//! them, so the ground truth has one source.

/// Frame width in pixels.
pub const WIDTH: usize = 160;
/// Frame height in pixels.
pub const HEIGHT: usize = 120;
/// Frames in the sequence.
pub const FRAMES: usize = 12;
/// Bytes of one packed 8-bit grey frame.
pub const FRAME_LEN: usize = WIDTH * HEIGHT;
/// How far the scene moves between two consecutive frames, in thousandths of a pixel
/// (x to the right, y down). Sub-pixel and different on both axes, so neither rounding nor a
/// swapped axis can pass the check.
pub const MOTION_MILLIPX: (i32, i32) = (650, -350);
