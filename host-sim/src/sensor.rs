//! Flow-sensor estimators on frame pairs, for comparing them on the same frames: the library's
//! flow-sensor preset and PX4FLOW's block matching (the `px4flow` crate), and the truth they
//! are measured against, the true displacement of the principal point. Each comes plain (the
//! flow or none) and rated (the flow with the quality the sensor would send with it).
//!
//! ```
//! use host_sim::sensor::{kestrel_preset, px4flow_block_matching};
//! use host_sim::synth::{FlightPath, FlightSequence, SceneSpec};
//! let sequence = FlightSequence::new(SceneSpec::new(160, 120, 1), FlightPath::Pan, 0);
//! let (a, b) = (sequence.frame(0), sequence.frame(1));
//! let truth = host_sim::sensor::centre_motion(sequence.flight(), 0, 1);
//! for mut estimate in [px4flow_block_matching(), kestrel_preset()] {
//!     let (x, y) = estimate(&a, &b).unwrap();
//!     assert!((f64::from(x) - truth.0).hypot(f64::from(y) - truth.1) < 0.3);
//! }
//! ```

use kestrel::detect::Corner;
use kestrel::ego::{CameraParams, EgoStatus};
use kestrel::lk::scratch_len;
use kestrel::sensor::{FlowSensor, FlowSensorConfig};
use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig};
use px4flow::{BlockMatcher, Config, Workspace};

use crate::synth::Flight;
use crate::Frame;

/// An estimator: two frames in, the flow at the principal point in px out (x right, y down:
/// how far the image content moved from the first frame to the second), or `None` for no flow
/// (quality 0).
pub type Estimator = Box<dyn FnMut(&Frame, &Frame) -> Option<(f32, f32)>>;

/// A flow with the quality a sensor reports for it, 1 to 255 as in OPTICAL_FLOW_RAD (quality 0,
/// no flow, is a rated estimator's `None`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// Flow at the principal point, px per pair (x right, y down).
    pub flow: (f32, f32),
    /// The sensor's confidence in it, 1 to 255.
    pub quality: u8,
}

/// An estimator that rates its flow: two frames in, a [`Reading`] out, or `None` for no flow.
pub type RatedEstimator = Box<dyn FnMut(&Frame, &Frame) -> Option<Reading>>;

/// `rated` without its quality.
fn unrated(mut rated: RatedEstimator) -> Estimator {
    Box::new(move |prev: &Frame, next: &Frame| rated(prev, next).map(|reading| reading.flow))
}

/// PX4FLOW's block matching with its defaults (±4 px): the mean of its valid blocks' flow.
pub fn px4flow_block_matching() -> Estimator {
    unrated(px4flow_rated())
}

/// [`px4flow_block_matching`] with PX4FLOW's quality, `valid blocks x 255 / 25`.
pub fn px4flow_rated() -> RatedEstimator {
    let matcher = BlockMatcher::new(Config::default()).expect("PX4FLOW's defaults are valid");
    let mut workspace = Workspace::new();
    Box::new(move |prev: &Frame, next: &Frame| {
        let (prev, next) = (prev.view().ok()?, next.view().ok()?);
        let flow = matcher.flow(&prev, &next, &mut workspace).ok()?;
        flow.is_valid().then_some(Reading {
            flow: (flow.x, flow.y),
            quality: flow.quality,
        })
    })
}

/// The library's flow sensor (`kestrel::sensor::FlowSensor`, the firmware's: the
/// `TrackerConfig::flow_sensor()` tracker and a similarity fit) on one frame pair, started cold
/// on the first frame (no motion known, so every track is searched on both levels and checked
/// forward-backward); the flow is where the fit moves the principal point. `None` when the
/// frames cannot be tracked or the fit fails.
pub fn kestrel_preset() -> Estimator {
    unrated(kestrel_preset_rated())
}

/// [`kestrel_preset`] with the fit's quality, `EgoMotion::quality`: what the firmware sends in
/// OPTICAL_FLOW_RAD for the pair.
pub fn kestrel_preset_rated() -> RatedEstimator {
    const TRACKS: usize = 25;
    let config = TrackerConfig::flow_sensor();
    let mut storage = Vec::new();
    let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
    let mut candidates = vec![Corner::default(); 3 * TRACKS];
    Box::new(move |prev: &Frame, next: &Frame| {
        let (prev, next) = (prev.view().ok()?, next.view().ok()?);
        let (width, height) = (prev.width(), prev.height());
        storage.resize(
            tracker_storage_len(width, height, config.pyramid_levels()),
            0,
        );
        let buffers = TrackerBuffers {
            storage: &mut storage,
            lk_scratch: &mut lk_scratch,
            detect_scratch: &mut [],
            candidates: &mut candidates,
        };
        let size = |v: usize| u16::try_from(v).ok();
        let fov = std::f32::consts::FRAC_PI_3;
        let camera = CameraParams::from_horizontal_fov(size(width)?, size(height)?, fov);
        let mut sensor =
            FlowSensor::<TRACKS>::new(FlowSensorConfig::new(camera), width, height, buffers)
                .ok()?;
        sensor.start(prev).ok()?;
        // The interval only scales the reading; the flow in pixels is the motion's.
        let motion = sensor.process(prev, next, 10_000, None).ok()?.motion;
        if motion.status != EgoStatus::Ok {
            return None;
        }
        let centre = ((width as f32 - 1.0) / 2.0, (height as f32 - 1.0) / 2.0);
        let (x, y) = motion.model.apply(centre)?;
        Some(Reading {
            flow: (x - centre.0, y - centre.1),
            quality: motion.quality,
        })
    })
}

/// Where the flight's homography from frame `from` to frame `to` takes the principal point
/// (the frame centre), less where it was: the flow a flow sensor should report.
pub fn centre_motion(flight: &Flight, from: usize, to: usize) -> (f64, f64) {
    let pair = flight
        .homography(from)
        .inverse()
        .expect("a camera in front of the ground sees it through an invertible warp")
        .then(&flight.homography(to));
    let (cx, cy) = flight.principal_point();
    let (x, y) = pair.apply(cx, cy);
    (x - cx, y - cy)
}

/// The `q` quantile of `sorted` errors (nearest rank, `q` from 0 to 1), `None` when there are
/// none: the median and p90 the flow-sensor comparisons report.
///
/// ```
/// use host_sim::sensor::percentile;
/// let errors = [0.1, 0.2, 0.3, 0.4, 1.5];
/// assert_eq!(percentile(&errors, 0.5), Some(0.3));
/// assert_eq!(percentile(&errors, 0.9), Some(1.5));
/// assert_eq!(percentile(&[], 0.5), None);
/// ```
pub fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted.get(rank.clamp(1, sorted.len().max(1)) - 1).copied()
}
