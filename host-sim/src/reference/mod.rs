//! The `f32` reference implementation: the oracle the fixed-point library is tested against.
//!
//! The same algorithm as [`kestrel::lk`], step for step, in plain floating point and written for
//! clarity rather than speed: pyramids are not rounded to 8 bits, windows and gradients are not
//! quantised, and sums are taken around the mean instead of in exact integers. Where the two
//! disagree by more than the library's documented precision, one of them is wrong.
//!
//! Coordinates follow the library: the origin is the centre of the top-left pixel, x to the
//! right, y down; at pyramid level `l` a position is divided by `2^l`.

mod image;
mod lk;
mod pyramid;
mod window;

pub use image::FloatImage;
pub use lk::{track_points, track_points_in, RefTrack};
pub use pyramid::{downsample, pyramid, reflect101};
pub use window::{min_eigenvalue, scharr, window_misses, GradientMatrix, Template, Window};
