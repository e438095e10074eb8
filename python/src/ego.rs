//! Ego-motion (robust model fits to point pairs) and the flow sensor's reading with its
//! MAVLink 2 frames.

use kestrel::ego::mavlink::{
    encode_heartbeat, encode_optical_flow, encode_optical_flow_rad, MavlinkHeader, MAX_FRAME_LEN,
};
use kestrel::ego::{
    CameraParams, EgoMotion as LibraryMotion, EgoStatus, ModelKind, OpticalFlow, OpticalFlowRad,
    Ransac, RansacParams, DEFAULT_SEED,
};
use kestrel::sensor::{FlowSensor as LibrarySensor, FlowSensorConfig};
use kestrel::track::{FrameReport, TrackerConfig};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::arrays;
use crate::settings::{self, value_error};
use crate::tracker::Buffers;

fn model_kind(name: &str) -> PyResult<ModelKind> {
    match name {
        "translation" => Ok(ModelKind::Translation),
        "similarity" => Ok(ModelKind::Similarity),
        "affine" => Ok(ModelKind::Affine),
        "homography" => Ok(ModelKind::Homography),
        other => Err(value_error(format!(
            "model must be 'translation', 'similarity', 'affine' or 'homography': got {other:?}"
        ))),
    }
}

fn model_name(kind: ModelKind) -> &'static str {
    match kind {
        ModelKind::Translation => "translation",
        ModelKind::Similarity => "similarity",
        ModelKind::Affine => "affine",
        ModelKind::Homography => "homography",
    }
}

fn status_name(status: EgoStatus) -> &'static str {
    match status {
        EgoStatus::Ok => "ok",
        EgoStatus::TooFewTracks => "too_few_tracks",
        EgoStatus::Degenerate => "degenerate",
        EgoStatus::NoConsensus => "no_consensus",
        EgoStatus::BadInput => "bad_input",
    }
}

/// The camera's motion between two frames, as the library's RANSAC fits it.
#[pyclass(module = "kestrel", frozen, get_all)]
pub struct EgoMotion {
    /// The model as a 3 x 3 homography, float64, mapping previous-frame pixels to next-frame
    /// pixels (identity when status is not "ok").
    matrix: Py<PyAny>,
    /// Per pair, bool (N,): whether it agrees with the model (None for a flow sensor's
    /// reading).
    inliers: Option<Py<PyAny>>,
    /// "translation", "similarity", "affine" or "homography".
    model: &'static str,
    /// "ok", "too_few_tracks", "degenerate", "no_consensus" or "bad_input".
    status: &'static str,
    /// Number of inliers.
    inlier_count: u16,
    /// Root-mean-square transfer error of the inliers, px.
    rms_residual: f32,
    /// 0 (no model) to 255, as MAVLink's quality.
    quality: u8,
    /// RANSAC samples drawn.
    iterations: u16,
}

#[pymethods]
impl EgoMotion {
    /// True when a model was found.
    #[getter]
    fn ok(&self) -> bool {
        self.status == "ok"
    }

    fn __repr__(&self) -> String {
        format!(
            "EgoMotion(model={:?}, status={:?}, inliers={}, rms_residual={:.3}, quality={})",
            self.model, self.status, self.inlier_count, self.rms_residual, self.quality
        )
    }
}

fn ego_motion(
    py: Python<'_>,
    m: &LibraryMotion,
    inliers: Option<Vec<bool>>,
) -> PyResult<EgoMotion> {
    let matrix: Vec<f64> = m.model.matrix().iter().map(|&v| f64::from(v)).collect();
    let inliers = match inliers {
        Some(v) => {
            let n = v.len();
            Some(arrays::array(py, v, &[n])?.into_any().unbind())
        }
        None => None,
    };
    Ok(EgoMotion {
        matrix: arrays::array(py, matrix, &[3, 3])?.into_any().unbind(),
        inliers,
        model: model_name(m.kind),
        status: status_name(m.status),
        inlier_count: m.inliers,
        rms_residual: m.rms_residual,
        quality: m.quality,
        iterations: m.iterations,
    })
}

/// Fits the dominant motion between point pairs with the library's deterministic RANSAC
/// (as cv2.findHomography / cv2.estimateAffinePartial2D do with RANSAC) and returns an
/// EgoMotion: the 3 x 3 matrix, the inlier mask, a status and a 0-255 quality.
///
/// prev_pts, next_pts: float32 (N, 1, 2) or (N, 2), the same N >= 1, finite.
/// model: "translation", "similarity" (shift, rotation, scale), "affine" or "homography".
/// threshold: inlier threshold on the transfer error, px, in (0, 1000].
/// max_iterations: samples drawn at most, 1 to 65535.
/// confidence: probability of an all-inlier sample before stopping early, in (0, 1).
/// min_inliers: inliers needed for a consensus, 0 to 65535 (raised to the model's minimal
///     sample plus one).
/// seed: sample generator seed (None: the library's fixed default, so results repeat).
///
/// Too few pairs or no consensus is a status, not an exception.
#[pyfunction]
#[pyo3(signature = (prev_pts, next_pts, model="homography", threshold=1.0, max_iterations=200,
    confidence=0.995, min_inliers=8, seed=None))]
#[allow(clippy::too_many_arguments)]
pub fn estimate_motion(
    py: Python<'_>,
    prev_pts: &Bound<'_, PyAny>,
    next_pts: &Bound<'_, PyAny>,
    model: &str,
    threshold: f64,
    max_iterations: i64,
    confidence: f64,
    min_inliers: i64,
    seed: Option<u64>,
) -> PyResult<EgoMotion> {
    let a = arrays::points(prev_pts, "prev_pts")?;
    let b = arrays::points(next_pts, "next_pts")?;
    if a.len() != b.len() {
        return Err(value_error(format!(
            "prev_pts has {} points but next_pts has {}",
            a.len(),
            b.len()
        )));
    }
    let max_iterations = u16::try_from(max_iterations)
        .ok()
        .filter(|&n| n >= 1)
        .ok_or_else(|| {
            value_error(format!(
                "max_iterations must be 1 to 65535: got {max_iterations}"
            ))
        })?;
    let min_inliers = u16::try_from(min_inliers)
        .map_err(|_| value_error(format!("min_inliers must be 0 to 65535: got {min_inliers}")))?;
    let params = RansacParams {
        model: model_kind(model)?,
        threshold: threshold as f32,
        max_iterations,
        confidence: confidence as f32,
        min_inliers,
        seed: seed.unwrap_or(DEFAULT_SEED),
    };
    let ransac = Ransac::new(params).map_err(|e| value_error(format!("RANSAC settings: {e}")))?;
    let pairs: Vec<((f32, f32), (f32, f32))> = a.into_iter().zip(b).collect();
    let mut inliers = vec![false; pairs.len()];
    let motion = py
        .detach(|| ransac.estimate(&pairs, &mut inliers))
        .map_err(|e| value_error(e.to_string()))?;
    ego_motion(py, &motion, Some(inliers))
}

fn mavlink_bytes<'py>(
    py: Python<'py>,
    encode: impl FnOnce(MavlinkHeader, &mut [u8]) -> Result<usize, kestrel::ego::mavlink::EncodeError>,
    system_id: i64,
    component_id: i64,
    sequence: i64,
) -> PyResult<Bound<'py, PyBytes>> {
    let byte = |v: i64, name: &str| {
        u8::try_from(v).map_err(|_| value_error(format!("{name} must be 0 to 255: got {v}")))
    };
    let header = MavlinkHeader {
        system_id: byte(system_id, "system_id")?,
        component_id: byte(component_id, "component_id")?,
        sequence: byte(sequence, "sequence")?,
    };
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(header, &mut buf).map_err(|e| value_error(format!("MAVLink encoding: {e}")))?;
    Ok(PyBytes::new(py, &buf[..n]))
}

/// One OPTICAL_FLOW_RAD reading (MAVLink message 106, PX4's sign conventions) and the
/// OPTICAL_FLOW reading (message 100, ArduPilot's) of the same integration.
#[pyclass(module = "kestrel", frozen)]
pub struct FlowReading {
    rad: OpticalFlowRad,
    flow: OpticalFlow,
}

#[pymethods]
impl FlowReading {
    /// Time of the readout, us.
    #[getter]
    fn time_usec(&self) -> u64 {
        self.rad.time_usec
    }
    /// Sensor id.
    #[getter]
    fn sensor_id(&self) -> u8 {
        self.rad.sensor_id
    }
    /// Integration time, us.
    #[getter]
    fn integration_time_us(&self) -> u32 {
        self.rad.integration_time_us
    }
    /// Flow integrated about the sensor's X axis, rad.
    #[getter]
    fn integrated_x(&self) -> f32 {
        self.rad.integrated_x
    }
    /// Flow integrated about the sensor's Y axis, rad.
    #[getter]
    fn integrated_y(&self) -> f32 {
        self.rad.integrated_y
    }
    /// Integrated gyro (x, y, z), rad, or None without a gyro.
    #[getter]
    fn integrated_gyro(&self) -> Option<(f32, f32, f32)> {
        match (
            self.rad.integrated_xgyro,
            self.rad.integrated_ygyro,
            self.rad.integrated_zgyro,
        ) {
            (Some(x), Some(y), Some(z)) => Some((x, y, z)),
            _ => None,
        }
    }
    /// Temperature, centidegrees Celsius.
    #[getter]
    fn temperature(&self) -> i16 {
        self.rad.temperature
    }
    /// 0 (invalid) to 255.
    #[getter]
    fn quality(&self) -> u8 {
        self.rad.quality
    }
    /// Time since the distance was sampled, us.
    #[getter]
    fn time_delta_distance_us(&self) -> u32 {
        self.rad.time_delta_distance_us
    }
    /// Distance to the ground, m, or None when unknown.
    #[getter]
    fn distance(&self) -> Option<f32> {
        self.rad.distance
    }
    /// OPTICAL_FLOW's flow rates (x, y), rad/s.
    #[getter]
    fn flow_rate(&self) -> (f32, f32) {
        (self.flow.flow_rate_x, self.flow.flow_rate_y)
    }
    /// OPTICAL_FLOW's flow_x, flow_y, dpix x 10 over the integration.
    #[getter]
    fn flow_pixels(&self) -> (i16, i16) {
        (self.flow.flow_x, self.flow.flow_y)
    }

    /// The OPTICAL_FLOW_RAD reading as a MAVLink 2 frame (bytes, CRC included).
    #[pyo3(signature = (system_id=1, component_id=100, sequence=0))]
    fn optical_flow_rad_mavlink<'py>(
        &self,
        py: Python<'py>,
        system_id: i64,
        component_id: i64,
        sequence: i64,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let rad = self.rad;
        mavlink_bytes(
            py,
            |h, buf| encode_optical_flow_rad(&rad, h, buf),
            system_id,
            component_id,
            sequence,
        )
    }

    /// The OPTICAL_FLOW reading as a MAVLink 2 frame (bytes, CRC included).
    #[pyo3(signature = (system_id=1, component_id=100, sequence=0))]
    fn optical_flow_mavlink<'py>(
        &self,
        py: Python<'py>,
        system_id: i64,
        component_id: i64,
        sequence: i64,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let flow = self.flow;
        mavlink_bytes(
            py,
            |h, buf| encode_optical_flow(&flow, h, buf),
            system_id,
            component_id,
            sequence,
        )
    }

    fn __repr__(&self) -> String {
        format!(
            "FlowReading(integrated_x={:+.5}, integrated_y={:+.5}, integration_time_us={}, quality={})",
            self.rad.integrated_x, self.rad.integrated_y, self.rad.integration_time_us, self.rad.quality
        )
    }
}

/// A HEARTBEAT from a camera (MAV_TYPE_CAMERA) as a MAVLink 2 frame, what a flow sensor sends
/// about once a second.
#[pyfunction]
#[pyo3(signature = (system_id=1, component_id=100, sequence=0))]
pub fn heartbeat_mavlink(
    py: Python<'_>,
    system_id: i64,
    component_id: i64,
    sequence: i64,
) -> PyResult<Bound<'_, PyBytes>> {
    mavlink_bytes(py, encode_heartbeat, system_id, component_id, sequence)
}

/// The library's flow sensor (kestrel::sensor::FlowSensor) with its buffers and the previous
/// frame it takes again with the next.
struct SensorLive {
    /// Borrows `buffers`; cleared first (see `Drop`), and declared first.
    sensor: Option<LibrarySensor<'static, SENSOR_TRACKS>>,
    buffers: Buffers,
    prev: Vec<u8>,
    width: usize,
    height: usize,
}

impl Drop for SensorLive {
    fn drop(&mut self) {
        // The sensor's borrows end here, before the buffers are freed.
        self.sensor = None;
    }
}

/// Tracks the flow sensor follows at most: the preset's.
const SENSOR_TRACKS: usize = TrackerConfig::flow_sensor().max_tracks;

/// The flow sensor exactly as firmware runs it: the library's FlowSensor (the tracker with
/// TrackerConfig::flow_sensor(), 25 tracks, 7 px windows on two levels of a box-mean pyramid,
/// FAST corners; a similarity fitted by RANSAC to the tracks' correspondences; the
/// OPTICAL_FLOW_RAD integration over a pinhole camera; a gyro, when given, seeds the search
/// and goes into the reading).
///
/// FlowSensor(width=None, height=None, *, fov=1.0, focal=None, sensor_id=0)
///
/// width, height: the frame size; when None, the first frame's size is taken.
/// fov: horizontal field of view, radians, between 0 and pi (used when focal is None).
/// focal: focal length, px (1 to 100000).
/// sensor_id: the id in OPTICAL_FLOW_RAD, 0 to 255.
///
/// `push(frame, interval_us, gyro=None)` takes each frame with the time since the previous
/// one and returns the pair's EgoMotion (None for the first frame, which starts the tracks);
/// `readout(time_usec)` returns the FlowReading integrated since the last readout and starts
/// the next integration. A frame of another size raises ValueError and, as on the board,
/// spoils the reading (quality 0). The GIL is released while the sensor works; it keeps a
/// packed copy of the last frame.
#[pyclass(module = "kestrel")]
pub struct FlowSensor {
    config: FlowSensorConfig,
    fov: f32,
    focal: Option<f32>,
    live: Option<SensorLive>,
    frames: u64,
    report: Option<FrameReport>,
}

impl FlowSensor {
    fn make(&mut self, w: usize, h: usize) -> PyResult<()> {
        let (w16, h16) = (w as u16, h as u16);
        let mut camera = CameraParams::from_horizontal_fov(w16, h16, self.fov);
        if let Some(f) = self.focal {
            camera.focal_x = f;
            camera.focal_y = f;
        }
        let config = FlowSensorConfig {
            camera,
            ..self.config
        };
        let mut live = SensorLive {
            sensor: None,
            buffers: Buffers::new(&config.tracker, w, h),
            prev: Vec::new(),
            width: w,
            height: h,
        };
        // SAFETY: lent once; the sensor is dropped before the buffers (`Drop for SensorLive`).
        let lent = unsafe { live.buffers.lend() };
        let sensor = LibrarySensor::new(config, w, h, lent)
            .map_err(|e| value_error(format!("flow sensor refused {w}x{h} frames: {e}")))?;
        live.sensor = Some(sensor);
        self.live = Some(live);
        Ok(())
    }
}

#[pymethods]
impl FlowSensor {
    #[new]
    #[pyo3(signature = (width=None, height=None, *, fov=1.0, focal=None, sensor_id=0))]
    fn new(
        width: Option<i64>,
        height: Option<i64>,
        fov: f64,
        focal: Option<f64>,
        sensor_id: i64,
    ) -> PyResult<Self> {
        if !(fov.is_finite() && fov > 0.0 && fov < std::f64::consts::PI) {
            return Err(value_error(format!(
                "fov must be a horizontal field of view in radians, between 0 and pi: got {fov}"
            )));
        }
        if let Some(f) = focal {
            if !(1.0..=100_000.0).contains(&f) {
                return Err(value_error(format!(
                    "focal must be a focal length from 1 to 100000 px: got {f}"
                )));
            }
        }
        let sensor_id = u8::try_from(sensor_id)
            .map_err(|_| value_error(format!("sensor_id must be 0 to 255: got {sensor_id}")))?;
        let mut config = FlowSensorConfig::new(CameraParams::from_horizontal_fov(64, 64, 1.0));
        config.sensor_id = sensor_id;
        let mut sensor = FlowSensor {
            config,
            fov: fov as f32,
            focal: focal.map(|f| f as f32),
            live: None,
            frames: 0,
            report: None,
        };
        if let Some((w, h)) = settings::frame_size(width, height)? {
            sensor.make(w, h)?;
        }
        Ok(sensor)
    }

    /// Takes the next frame (2-D uint8) and the time since the previous frame, us (1 to
    /// 1000000), with the gyro's integrated rotation over that interval (x, y, z), rad, in
    /// PX4's sensor frame, if there is one. Returns the camera's EgoMotion for the pair, its
    /// inliers over the pair's correspondences (None for the first frame, which starts the
    /// tracks), after adding it to the integration.
    #[pyo3(signature = (frame, interval_us, gyro=None))]
    fn push(
        &mut self,
        py: Python<'_>,
        frame: &Bound<'_, PyAny>,
        interval_us: i64,
        gyro: Option<(f64, f64, f64)>,
    ) -> PyResult<Option<EgoMotion>> {
        let frame = arrays::frame(frame, "frame")?;
        let (w, h) = frame.size();
        let interval = u32::try_from(interval_us)
            .ok()
            .filter(|&i| (1..=kestrel::ego::MAX_INTERVAL_US).contains(&i))
            .ok_or_else(|| {
                value_error(format!(
                    "interval_us must be 1 to 1000000: got {interval_us}"
                ))
            })?;
        let gyro = gyro.map(|(x, y, z)| [x as f32, y as f32, z as f32]);
        if let Some(g) = gyro {
            if g.iter().any(|v| !v.is_finite()) {
                return Err(value_error("gyro must be three finite numbers (rad)"));
            }
        }
        if self.live.is_none() {
            self.make(w, h)?;
        }
        let Some(live) = self.live.as_mut() else {
            return Err(value_error("flow sensor could not be made"));
        };
        let Some(sensor) = live.sensor.as_mut() else {
            return Err(value_error("flow sensor could not be made"));
        };
        if (live.width, live.height) != (w, h) {
            // A frame the board could not use: the reading's quality will be 0.
            sensor.refuse(interval);
            return Err(value_error(format!(
                "frame is {w}x{h} but the sensor was made for {}x{} frames",
                live.width, live.height
            )));
        }
        let pixels = frame.pixels();
        let prev = &mut live.prev;
        let (width, height) = (live.width, live.height);
        type Stepped = (Option<(LibraryMotion, Vec<bool>)>, FrameReport);
        let (pair, report) = py
            .detach(|| -> Result<Stepped, String> {
                let next = pixels.view()?;
                let stepped = if prev.is_empty() {
                    (None, sensor.start(next).map_err(|e| e.to_string())?)
                } else {
                    let before = kestrel::ImageView::packed(prev, width, height)
                        .map_err(|e| e.to_string())?;
                    let step = sensor
                        .process(before, next, interval, gyro)
                        .map_err(|e| e.to_string())?;
                    (Some((step.motion, sensor.pairs().1.to_vec())), step.report)
                };
                *prev = pixels.to_packed();
                Ok(stepped)
            })
            .map_err(value_error)?;
        self.frames += 1;
        self.report = Some(report);
        match pair {
            Some((motion, inliers)) => ego_motion(py, &motion, Some(inliers)).map(Some),
            None => Ok(None),
        }
    }

    /// The reading integrated since the last readout, time-stamped `time_usec`; starts the
    /// next integration.
    fn readout(&mut self, time_usec: u64) -> PyResult<FlowReading> {
        let sensor = self
            .live
            .as_mut()
            .and_then(|l| l.sensor.as_mut())
            .ok_or_else(|| value_error("no frame yet: push frames before reading out"))?;
        let rad = sensor.readout(time_usec);
        let flow = sensor.optical_flow(&rad);
        Ok(FlowReading { rad, flow })
    }

    /// Sets the ground distance, m, sampled at `sampled_at_us`, for the next readouts.
    fn set_distance(&mut self, metres: f32, sampled_at_us: u64) -> PyResult<()> {
        let sensor = self
            .live
            .as_mut()
            .and_then(|l| l.sensor.as_mut())
            .ok_or_else(|| value_error("no frame yet: push a frame first"))?;
        sensor.accumulator_mut().set_distance(metres, sampled_at_us);
        Ok(())
    }

    /// Frames pushed.
    #[getter]
    fn frames(&self) -> u64 {
        self.frames
    }

    /// The tracker's account of the last frame, `(live, tracked, dropped, added)` tracks, or
    /// None before the first frame.
    #[getter]
    fn tracker_report(&self) -> Option<(usize, usize, usize, usize)> {
        self.report
            .map(|r| (r.live, r.tracked, r.dropped(), r.added))
    }
}
