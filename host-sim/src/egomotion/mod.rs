//! Camera motion over a frame sequence on the host: the library's detection, tracking and robust
//! fitting per consecutive frame pair, gyro logs integrated over the frame intervals, the
//! clock that stamps the frames, and the MAVLink link the readings go out on.
//!
//! [`MotionEstimator`] is what `host-sim egomotion` and `host-sim stabilize` run per frame; it
//! owns every buffer the library borrows, sized once for the sequence's frame size, as firmware
//! would in statics.

mod clock;
mod estimator;
mod gyro;
mod link;

pub use clock::{FrameClock, Pacer};
pub use estimator::{
    EstimatorSettings, MotionEstimator, PairMotion, DEFAULT_MAX_POINTS, DEFAULT_THRESHOLD,
};
pub use gyro::{GyroLog, GyroSample, GYRO_COLUMNS};
pub use link::{MavlinkDestination, MavlinkLink, SendFailures};
