//! Camera motion over a frame sequence on the host: the library's detection, tracking and robust
//! fitting per consecutive frame pair, gyro logs integrated over the frame intervals, and the
//! clock that stamps the frames.
//!
//! [`MotionEstimator`] is what `host-sim egomotion` and `host-sim stabilize` run per frame; it
//! owns every buffer the library borrows, sized once for the sequence's frame size, as firmware
//! would in statics.

mod clock;
mod estimator;
mod gyro;

pub use clock::FrameClock;
pub use estimator::{
    EstimatorSettings, MotionEstimator, PairMotion, DEFAULT_MAX_POINTS, DEFAULT_THRESHOLD,
};
pub use gyro::{GyroLog, GyroSample};
