//! The flow sensor: frames in, the autopilot's OPTICAL_FLOW_RAD (and OPTICAL_FLOW) readings out.
//!
//! [`FlowSensor`] is the whole pipeline a flow-sensor board runs, in one type: the tracker
//! ([`crate::track`], with the [`TrackerConfig::flow_sensor`] preset by default), the camera's
//! motion fitted to the tracks' correspondences ([`crate::ego::Ransac`]), and its integration
//! into the reading ([`FlowRadAccumulator`]). A gyro, when there is one, seeds the tracker's
//! search and goes into the reading. The firmware, `host-sim egomotion --preset flow-sensor`
//! and the tests all run this type, so a reading on the host is the board's reading.
//!
//! Memory: the tracker's buffers are the caller's ([`TrackerBuffers`], sized by
//! [`crate::track::tracker_storage_len`] and friends); the sensor itself holds its
//! correspondences, `N` of them, so a `static` of it is its whole footprint.
//!
//! ```
//! use kestrel::ego::CameraParams;
//! use kestrel::ImageView;
//! use kestrel::sensor::{FlowSensor, FlowSensorConfig};
//! use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig};
//! use kestrel::lk::scratch_len;
//! use kestrel::detect::Corner;
//!
//! // The preset's 25 tracks on 64 x 64 frames, FAST on pyramid level 1 (no detection scratch).
//! let camera = CameraParams::from_horizontal_fov(64, 64, 1.0);
//! let config = FlowSensorConfig::new(camera);
//! const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
//! let mut storage = [0u8; tracker_storage_len(64, 64, PRESET.pyramid_levels())];
//! let mut lk_scratch = [0i16; scratch_len(PRESET.lk.window)];
//! let mut candidates = [Corner::default(); 75];
//! let buffers = TrackerBuffers {
//!     storage: &mut storage,
//!     lk_scratch: &mut lk_scratch,
//!     detect_scratch: &mut [],
//!     candidates: &mut candidates,
//! };
//! let mut sensor = FlowSensor::<25>::new(config, 64, 64, buffers).unwrap();
//!
//! // Smooth texture; the second frame is the first moved 1 px to the left (10 ms apart).
//! let canvas: [u8; 66 * 64] = core::array::from_fn(|i| {
//!     let (x, y) = ((i % 66) as f32, (i / 66) as f32);
//!     (128.0 + 60.0 * (x * 0.45).sin() * (y * 0.38).cos() + 40.0 * (x * 0.21 + y * 0.3).sin()) as u8
//! });
//! let first = ImageView::new(&canvas, 64, 64, 66).unwrap();
//! let second = ImageView::new(&canvas[1..], 64, 64, 66).unwrap();
//! sensor.start(first).unwrap();
//! let step = sensor.process(first, second, 10_000, None).unwrap();
//! assert!(step.motion.is_ok());
//! // Every track followed gives a correspondence, and the fitted motion explains them all.
//! let (pairs, inliers) = sensor.pairs();
//! assert_eq!(pairs.len(), step.report.tracked);
//! assert!(pairs.len() >= 8 && inliers.iter().all(|&i| i));
//! let reading = sensor.readout(10_000);
//! // Image motion to the left is negative flow about the sensor's X axis (PX4's convention):
//! // 1 px at a focal length of 58.6 px, 17 mrad.
//! assert!(reading.quality > 0);
//! assert!((reading.integrated_x + 1.0 / 58.6).abs() < 0.0005);
//! assert!(reading.integrated_y.abs() < 0.0005);
//! ```

use crate::ego::{
    Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, ModelKind, OpticalFlow,
    OpticalFlowRad, Ransac, RansacError, RansacParams, Rotation,
};
use crate::frame::ImageView;
use crate::q16::Point;
use crate::track::{
    FrameReport, Track, Tracker, TrackerBuffers, TrackerConfig, TrackerError, TrackerStage,
};
use crate::ConfigError;
use heapless::Vec;

/// The settings [`FlowSensor::new`] checks, as paths from its [`FlowSensorConfig`], one list
/// per part: a refusal from the tracker, the fit or the camera is named so.
const TRACKER_PATHS: [&str; 21] = [
    "tracker.lk.window",
    "tracker.lk.max_level",
    "tracker.lk.max_iterations",
    "tracker.lk.epsilon",
    "tracker.lk.min_eigen_threshold",
    "tracker.max_tracks",
    "tracker.search.fine_reach",
    "tracker.gates.fb_threshold",
    "tracker.gates.fb_every",
    "tracker.gates.fb_doubt",
    "tracker.gates.max_residual",
    "tracker.gates.residual_ratio",
    "tracker.gates.min_correlation",
    "tracker.gates.least_correlation",
    "tracker.refill.below",
    "tracker.refill.level",
    "tracker.refill.grid.cols",
    "tracker.refill.grid.rows",
    "tracker.refill.detector.block",
    "tracker.refill.detector.quality_level",
    "tracker.relocation.max_distance",
];
const RANSAC_PATHS: [&str; 3] = [
    "ransac.threshold",
    "ransac.max_iterations",
    "ransac.confidence",
];
const CAMERA_PATHS: [&str; 6] = [
    "camera.focal_x",
    "camera.focal_y",
    "camera.principal_x",
    "camera.principal_y",
    "camera.k1",
    "camera.k2",
];

/// How a [`FlowSensor`] is made.
///
/// ```
/// use kestrel::ego::{CameraParams, ModelKind};
/// use kestrel::sensor::FlowSensorConfig;
/// use kestrel::track::TrackerConfig;
/// let config = FlowSensorConfig::new(CameraParams::from_horizontal_fov(160, 120, 1.0));
/// // The tracker's flow-sensor preset, and a similarity for the camera's motion: a downward
/// // camera sees the ground shift, turn (yaw) and zoom (climb).
/// assert_eq!(config.tracker, TrackerConfig::flow_sensor());
/// assert_eq!(config.ransac.model, ModelKind::Similarity);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowSensorConfig {
    /// The tracker's settings.
    pub tracker: TrackerConfig,
    /// The fit of the camera's motion to the tracks.
    pub ransac: RansacParams,
    /// The camera: the reading's angles are pixels through its lens.
    pub camera: CameraParams,
    /// The sensor's id in OPTICAL_FLOW_RAD.
    pub sensor_id: u8,
}

impl FlowSensorConfig {
    /// The tracker's [`TrackerConfig::flow_sensor`] preset and a similarity fit with the
    /// library's other RANSAC defaults, for `camera`, as sensor 0.
    ///
    /// ```
    /// use kestrel::ego::CameraParams;
    /// use kestrel::sensor::FlowSensorConfig;
    /// let config = FlowSensorConfig::new(CameraParams::from_horizontal_fov(160, 120, 1.0));
    /// assert_eq!((config.sensor_id, config.tracker.max_tracks), (0, 25));
    /// ```
    pub fn new(camera: CameraParams) -> Self {
        Self {
            tracker: TrackerConfig::flow_sensor(),
            ransac: RansacParams {
                model: ModelKind::Similarity,
                ..RansacParams::default()
            },
            camera,
            sensor_id: 0,
        }
    }
}

/// Why a [`FlowSensor`] could not take a frame (a sensor that could not be made is a
/// [`ConfigError`] of [`FlowSensor::new`]).
///
/// ```
/// # use kestrel::ego::CameraParams;
/// # use kestrel::ImageView;
/// # use kestrel::sensor::{FlowSensor, FlowSensorConfig, FlowSensorError};
/// # use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig, TrackerError};
/// # use kestrel::{detect::Corner, lk::scratch_len};
/// # let config = FlowSensorConfig::new(CameraParams::from_horizontal_fov(64, 64, 1.0));
/// # const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
/// # let mut storage = [0u8; tracker_storage_len(64, 64, PRESET.pyramid_levels())];
/// # let mut lk_scratch = [0i16; scratch_len(PRESET.lk.window)];
/// # let mut candidates = [Corner::default(); 75];
/// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #     detect_scratch: &mut [], candidates: &mut candidates };
/// let mut sensor = FlowSensor::<25>::new(config, 64, 64, buffers).unwrap();
/// let flat = [90u8; 64 * 64];
/// let frame = ImageView::packed(&flat, 64, 64).unwrap();
/// // Frames before the first one.
/// let refused = sensor.process(frame, frame, 10_000, None).unwrap_err();
/// assert_eq!(refused, FlowSensorError::Tracker(TrackerError::NotStarted));
/// assert_eq!(refused.to_string(), "tracker: no previous frame: call start first");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlowSensorError {
    /// The tracker refused the frame.
    Tracker(TrackerError),
    /// The motion fit could not run on the correspondences (never expected: there is one
    /// inlier flag per correspondence, and at most `N` of them).
    Ransac(RansacError),
}

impl core::fmt::Display for FlowSensorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FlowSensorError::Tracker(e) => write!(f, "tracker: {e}"),
            FlowSensorError::Ransac(e) => write!(f, "motion fit: {e}"),
        }
    }
}

/// What one frame pair gave.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowStep {
    /// The tracker's account of the frame.
    pub report: FrameReport,
    /// The camera's motion between the two frames.
    pub motion: EgoMotion,
    /// Whether the pair went into the reading: [`EgoStatus::Ok`], or why it spoils the
    /// integration (the motion's own status, a bad interval or gyro reading).
    pub integrated: EgoStatus,
}

/// A stage of [`FlowSensor::process_observed`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorStage {
    /// A stage of the tracker.
    Tracker(TrackerStage),
    /// The camera's motion fitted to the correspondences and integrated into the reading.
    Fit,
}

/// The flow-sensor pipeline: see the [module documentation](self).
pub struct FlowSensor<'m, const N: usize> {
    tracker: Tracker<'m, N>,
    ransac: Ransac,
    camera: Camera,
    accumulator: FlowRadAccumulator,
    /// The latest frame pair's correspondences, and which of them the motion explains.
    pairs: Vec<(Point, Point), N>,
    inliers: [bool; N],
}

impl<'m, const N: usize> FlowSensor<'m, N> {
    /// A sensor for `width` x `height` frames over the caller's tracker `buffers`.
    ///
    /// A refusal names the setting by its path in `config` (`"camera.focal_x"`,
    /// `"ransac.threshold"`, `"tracker.max_tracks"`, `"tracker.lk.window"`), or the frame size
    /// (`"width"`, `"height"`) or the buffer (`"buffers.storage"`, ...) as
    /// [`Tracker::new`] does. See the [module documentation](self) for a whole example.
    ///
    /// ```
    /// use kestrel::ego::CameraParams;
    /// use kestrel::sensor::{FlowSensor, FlowSensorConfig};
    /// use kestrel::track::TrackerBuffers;
    /// use kestrel::{Bound, ConfigError};
    /// let buffers = || TrackerBuffers {
    ///     storage: &mut [], lk_scratch: &mut [], detect_scratch: &mut [], candidates: &mut [],
    /// };
    /// let good = FlowSensorConfig::new(CameraParams::from_horizontal_fov(64, 64, 1.0));
    /// let camera = CameraParams { focal_x: -1.0, ..good.camera };
    /// let made = FlowSensor::<25>::new(FlowSensorConfig { camera, ..good }, 64, 64, buffers());
    /// let range = Bound::Range { min: 1, max: 100_000 };
    /// assert_eq!(made.err(), Some(ConfigError { field: "camera.focal_x", bound: range }));
    /// let mut wide = good;
    /// wide.tracker.lk.window = 64;
    /// let made = FlowSensor::<25>::new(wide, 64, 64, buffers());
    /// assert_eq!(made.err().unwrap().to_string(), "tracker.lk.window must be odd, 3 to 63");
    /// let made = FlowSensor::<25>::new(good, 64, 64, buffers());
    /// assert_eq!(made.err().unwrap().field, "buffers.storage");
    /// ```
    pub fn new(
        config: FlowSensorConfig,
        width: usize,
        height: usize,
        buffers: TrackerBuffers<'m>,
    ) -> Result<Self, ConfigError> {
        let camera = Camera::new(config.camera).map_err(|e| e.nested(&CAMERA_PATHS))?;
        let ransac = Ransac::new(config.ransac).map_err(|e| e.nested(&RANSAC_PATHS))?;
        let tracker = Tracker::new(config.tracker, width, height, buffers)
            .map_err(|e| e.nested(&TRACKER_PATHS))?;
        Ok(Self {
            tracker,
            ransac,
            camera,
            accumulator: FlowRadAccumulator::new(camera, config.sensor_id),
            pairs: Vec::new(),
            inliers: [false; N],
        })
    }

    /// Starts (or restarts) the tracks on `frame`, the first of a sequence. The integration
    /// so far is kept: a restart loses no reading.
    pub fn start(&mut self, frame: ImageView<'_>) -> Result<FrameReport, FlowSensorError> {
        self.pairs.clear();
        self.tracker.start(frame).map_err(FlowSensorError::Tracker)
    }

    /// Follows the tracks from `prev` (the frame given last) to `next`, taken `interval_us`
    /// microseconds later, fits the camera's motion and integrates it into the reading.
    /// `gyro`, the gyro integrated over the interval (rad, sensor frame), seeds the tracker's
    /// search with the rotation's image motion and goes into the reading.
    ///
    /// A frame the tracker refuses (another size, not the previous frame, before
    /// [`FlowSensor::start`]) is an error, leaves the tracks as they were and spoils the
    /// reading: its quality will be 0.
    pub fn process(
        &mut self,
        prev: ImageView<'_>,
        next: ImageView<'_>,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
    ) -> Result<FlowStep, FlowSensorError> {
        self.process_observed(prev, next, interval_us, gyro, |_| {})
    }

    /// [`FlowSensor::process`], calling `stage_ended` as each [`SensorStage`] ends: firmware
    /// reads a cycle counter there to time the tracker and the motion fit apart.
    ///
    /// ```
    /// # use kestrel::ego::CameraParams;
    /// # use kestrel::ImageView;
    /// # use kestrel::sensor::{FlowSensor, FlowSensorConfig, SensorStage};
    /// # use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig, TrackerStage};
    /// # use kestrel::{detect::Corner, lk::scratch_len};
    /// # let config = FlowSensorConfig::new(CameraParams::from_horizontal_fov(64, 64, 1.0));
    /// # const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
    /// # let mut storage = [0u8; tracker_storage_len(64, 64, PRESET.pyramid_levels())];
    /// # let mut lk_scratch = [0i16; scratch_len(PRESET.lk.window)];
    /// # let mut candidates = [Corner::default(); 75];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut [], candidates: &mut candidates };
    /// let mut sensor = FlowSensor::<25>::new(config, 64, 64, buffers).unwrap();
    /// let flat = [90u8; 64 * 64];
    /// let frame = ImageView::packed(&flat, 64, 64).unwrap();
    /// sensor.start(frame).unwrap();
    /// let mut stages = heapless::Vec::<SensorStage, 4>::new();
    /// let step = sensor.process_observed(frame, frame, 10_000, None, |s| stages.push(s).unwrap());
    /// // No corner on a flat frame: the tracker refills in vain and the fit finds no motion.
    /// assert!(!step.unwrap().motion.is_ok());
    /// assert_eq!(stages, [
    ///     SensorStage::Tracker(TrackerStage::Pyramid),
    ///     SensorStage::Tracker(TrackerStage::Follow),
    ///     SensorStage::Tracker(TrackerStage::Refill),
    ///     SensorStage::Fit,
    /// ]);
    /// ```
    pub fn process_observed(
        &mut self,
        prev: ImageView<'_>,
        next: ImageView<'_>,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
        mut stage_ended: impl FnMut(SensorStage),
    ) -> Result<FlowStep, FlowSensorError> {
        let rotation = gyro.and_then(|g| Rotation::from_integrated_gyro(g, interval_us).ok());
        let camera = self.camera;
        let seed = rotation.map(|r| {
            move |p: Point| {
                let moved = camera.predict(&r, p.to_f32());
                moved.map_or(p, |(x, y)| Point::from_f32(x, y))
            }
        });
        let predict = seed.as_ref().map(|f| f as &dyn Fn(Point) -> Point);
        let tracked = self.tracker.process_observed(prev, next, predict, |stage| {
            stage_ended(SensorStage::Tracker(stage));
        });
        let report = match tracked {
            Ok(report) => report,
            Err(e) => {
                self.refuse(interval_us);
                return Err(FlowSensorError::Tracker(e));
            }
        };
        self.tracker.correspondences(&mut self.pairs);
        let inliers = self.inliers.get_mut(..self.pairs.len());
        debug_assert!(inliers.is_some(), "more pairs than the tracker's capacity");
        let motion = match inliers {
            Some(inliers) => self.ransac.estimate(&self.pairs, inliers),
            None => Err(RansacError::LengthMismatch),
        };
        let motion = match motion {
            Ok(motion) => motion,
            Err(e) => {
                self.refuse(interval_us);
                return Err(FlowSensorError::Ransac(e));
            }
        };
        let integrated = self.accumulator.add(&motion, interval_us, gyro);
        stage_ended(SensorStage::Fit);
        Ok(FlowStep {
            report,
            motion,
            integrated,
        })
    }

    /// A frame that never came, or could not be used, `interval_us` after the last: the
    /// reading's quality will be 0.
    ///
    /// ```
    /// # use kestrel::ego::CameraParams;
    /// # use kestrel::sensor::{FlowSensor, FlowSensorConfig};
    /// # use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig};
    /// # use kestrel::{detect::Corner, lk::scratch_len};
    /// # let config = FlowSensorConfig::new(CameraParams::from_horizontal_fov(64, 64, 1.0));
    /// # const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
    /// # let mut storage = [0u8; tracker_storage_len(64, 64, PRESET.pyramid_levels())];
    /// # let mut lk_scratch = [0i16; scratch_len(PRESET.lk.window)];
    /// # let mut candidates = [Corner::default(); 75];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut [], candidates: &mut candidates };
    /// let mut sensor = FlowSensor::<25>::new(config, 64, 64, buffers).unwrap();
    /// sensor.refuse(10_000);
    /// let reading = sensor.readout(10_000);
    /// assert_eq!((reading.quality, reading.integration_time_us), (0, 10_000));
    /// ```
    pub fn refuse(&mut self, interval_us: u32) {
        let refused = EgoMotion::failed(self.ransac.params().model, EgoStatus::BadInput);
        self.accumulator.add(&refused, interval_us, None);
    }

    /// The reading integrated since the last readout, stamped `time_usec`; starts the next
    /// integration. Encode it for the autopilot with `kestrel::ego::mavlink` (feature
    /// `mavlink`).
    ///
    /// See the [module documentation](self).
    pub fn readout(&mut self, time_usec: u64) -> OpticalFlowRad {
        self.accumulator.readout(time_usec)
    }

    /// `reading` (a readout of this sensor) as OPTICAL_FLOW, ArduPilot's message.
    ///
    /// ```
    /// # use kestrel::ego::CameraParams;
    /// # use kestrel::sensor::{FlowSensor, FlowSensorConfig};
    /// # use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig};
    /// # use kestrel::{detect::Corner, lk::scratch_len};
    /// # let config = FlowSensorConfig::new(CameraParams::from_horizontal_fov(64, 64, 1.0));
    /// # const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
    /// # let mut storage = [0u8; tracker_storage_len(64, 64, PRESET.pyramid_levels())];
    /// # let mut lk_scratch = [0i16; scratch_len(PRESET.lk.window)];
    /// # let mut candidates = [Corner::default(); 75];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut [], candidates: &mut candidates };
    /// let mut sensor = FlowSensor::<25>::new(config, 64, 64, buffers).unwrap();
    /// sensor.refuse(10_000);
    /// let reading = sensor.readout(10_000);
    /// let flow = sensor.optical_flow(&reading);
    /// assert_eq!((flow.quality, flow.flow_x, flow.flow_y), (0, 0, 0));
    /// ```
    pub fn optical_flow(&self, reading: &OpticalFlowRad) -> OpticalFlow {
        self.accumulator.optical_flow(reading)
    }

    /// Sets the temperature and the distance to the ground the readings report (see
    /// [`FlowRadAccumulator::set_temperature`] and [`FlowRadAccumulator::set_distance`]).
    pub fn accumulator_mut(&mut self) -> &mut FlowRadAccumulator {
        &mut self.accumulator
    }

    /// The live tracks.
    ///
    /// See the [module documentation](self).
    pub fn tracks(&self) -> &[Track] {
        self.tracker.tracks()
    }

    /// The tracker, for its configuration and frame index.
    ///
    /// See the [module documentation](self).
    pub fn tracker(&self) -> &Tracker<'m, N> {
        &self.tracker
    }

    /// The latest frame pair's correspondences, and for each whether the motion explains it.
    ///
    /// See the [module documentation](self).
    pub fn pairs(&self) -> (&[(Point, Point)], &[bool]) {
        let inliers = self.inliers.get(..self.pairs.len());
        debug_assert!(inliers.is_some(), "more pairs than the tracker's capacity");
        (&self.pairs, inliers.unwrap_or(&[]))
    }

    /// The camera the readings are in.
    ///
    /// See the [module documentation](self).
    pub fn camera(&self) -> &Camera {
        &self.camera
    }
}
