//! Ego-motion: how the camera moved between two frames, and what the autopilot gets from it.
//!
//! The data flows through its parts in this order, every type at this module's path:
//!
//! 1. [`fit`]: translation, similarity, affine and homography models ([`ModelKind`]) fitted to
//!    tracks by least squares; every model is reported as a [`Homography`].
//! 2. [`Ransac`]: deterministic, bounded-time robust estimation of the dominant motion, with
//!    an inlier count, a residual and a quality figure: [`EgoMotion`].
//! 3. [`Rotation`] and [`Camera`]: gyro rotations in PX4's sensor frame, a pinhole camera with
//!    radial distortion, and derotation: the rotational flow a gyro predicts, to seed LK in fast
//!    turns and to remove from the measured flow.
//! 4. [`FlowRadAccumulator`]: the MAVLink OPTICAL_FLOW_RAD accumulator, with PX4's sign
//!    conventions, and the OPTICAL_FLOW reading of the same integration (ArduPilot's message).
//! 5. `mavlink` (feature `mavlink`): OPTICAL_FLOW_RAD, OPTICAL_FLOW and HEARTBEAT as MAVLink 2
//!    frames, and what PX4 and ArduPilot expect of them.
//!
//! Model fitting is `f32`: a frame has at most a few hundred tracks and the Cortex-M4F has a
//! single-precision FPU. Inputs are validated (NaN, infinities and absurd values are rejected
//! with a status) and outputs checked, so no NaN or infinity ever leaves the module; the one
//! exception is MAVLink's own encoding of a missing gyro, made explicit as `Option` here.
//! Nothing allocates and nothing panics; the state types are small `Copy` values.
//!
//! ```
//! use kestrel::ego::{Camera, CameraParams, EgoStatus, FlowRadAccumulator, Ransac, RansacParams};
//! // Tracks on a 8 x 6 grid; the image moved 1.5 px to the right and 0.5 px down.
//! let mut tracks = [((0.0f32, 0.0f32), (0.0f32, 0.0f32)); 48];
//! for (i, t) in tracks.iter_mut().enumerate() {
//!     let (x, y) = ((i % 8) as f32 * 20.0 + 10.0, (i / 8) as f32 * 20.0 + 8.0);
//!     *t = ((x, y), (x + 1.5, y + 0.5));
//! }
//! let ransac = Ransac::new(RansacParams::default()).unwrap();
//! let mut inliers = [false; 48];
//! let motion = ransac.estimate(&tracks, &mut inliers).unwrap();
//! assert_eq!((motion.status, motion.inliers), (EgoStatus::Ok, 48));
//!
//! let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
//! let mut flow = FlowRadAccumulator::new(camera, 0);
//! flow.add(&motion, 10_000, None);
//! let reading = flow.readout(10_000);
//! // Image right is sensor +Y: motion to the right is flow about +X.
//! assert!(reading.integrated_x > 0.0 && reading.integrated_y > 0.0);
//! assert_eq!(reading.integrated_xgyro, None);
//! ```

mod linalg;

mod camera;
mod flow_rad;
#[cfg(feature = "mavlink")]
pub mod mavlink;
mod model;
mod ransac;
mod rotation;

pub use camera::{Camera, CameraError, CameraParams, FOCAL_RANGE, MAX_DISTORTION};
pub use flow_rad::{FlowRadAccumulator, OpticalFlow, OpticalFlowRad, MAX_INTERVAL_US};
pub use model::{fit, Correspondence, FitError, Homography, ModelKind, MAX_COORDINATE};
pub use ransac::{
    EgoMotion, EgoStatus, Ransac, RansacError, RansacParams, DEFAULT_SEED, FULL_SUPPORT, MAX_REFITS,
};
pub use rotation::{GyroError, Rotation, MAX_BODY_RATE, MAX_ROTATION};
