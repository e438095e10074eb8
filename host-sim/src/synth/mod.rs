//! Seeded synthetic sequences with exact ground truth.
//!
//! A [`Scene`] is a procedural [`Texture`] on a plane, with [`MovingObject`]s in front of it; a
//! camera sees it through a [`Homography`] (frame 0 sees it unwarped), so the true position in
//! any frame of every point of frame 0 is known exactly. Frames are area-sampled, lit
//! ([`Lighting`]), given sensor noise and quantised to 8 bits. Everything is fixed by a seed:
//! the same [`SceneSpec`] renders the same frames, bit for bit, on any machine.
//!
//! ```
//! use host_sim::synth::{grid_points, pair, textured_points, true_position, Homography, SceneSpec};
//! let spec = SceneSpec::new(96, 72, 7).with_noise(1.0).with_supersample(2);
//! let warp = Homography::translation(3.25, -1.5);
//! let (prev, next) = pair(&spec, &warp);
//! let points = textured_points(&prev, &grid_points(96, 72, 8, 12.0), 21, 10.0);
//! let truth: Vec<(f32, f32)> = points.iter().map(|&(x, y)| true_position(&warp, x, y)).collect();
//! assert_eq!(truth.len(), points.len());
//! ```

pub mod camera;
mod flight;
mod glider;
mod homography;
mod object;
pub mod objects;
mod photo;
mod points;
mod render;
mod rng;
pub mod rotation;
mod scene;
mod sequence;
mod texture;

pub use camera::{AutoExposure, Camera, Light, Shot, Shutter, Subject, Vignetting};
pub use flight::{Flight, FlightPath, FlightSequence, OBJECT_SHARE};
pub use glider::{Body, Glider, GliderSize, Mover};
pub use homography::Homography;
pub use object::{MovingObject, Surface};
pub use photo::Photo;
pub use points::{grid_points, textured_points};
pub use render::{area_sample, Exposure, Lighting};
pub use rng::{lattice, mix, SplitMix64};
pub use scene::{pair, pair_with_lighting, true_position, Scene, SceneSpec};
pub use sequence::{CameraPath, Sequence};
pub use texture::{Extent, Texture};
