//! The MAVLink OPTICAL_FLOW_RAD accumulator, and the OPTICAL_FLOW reading of the same integration.

use super::camera::Camera;
use super::ransac::{EgoMotion, EgoStatus};
use super::rotation::Rotation;

/// The longest frame interval accepted, microseconds.
///
/// ```
/// use kestrel::ego::MAX_INTERVAL_US;
/// use kestrel::ego::{Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, ModelKind};
/// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
/// let mut acc = FlowRadAccumulator::new(camera, 0);
/// let still = EgoMotion { quality: 100, ..EgoMotion::failed(ModelKind::Homography, EgoStatus::Ok) };
/// assert_eq!(acc.add(&still, MAX_INTERVAL_US + 1, None), EgoStatus::BadInput);
/// ```
pub const MAX_INTERVAL_US: u32 = 1_000_000;

/// One OPTICAL_FLOW_RAD reading (MAVLink message 106), in the sensor frame.
///
/// Every field is finite. MAVLink encodes a missing gyro as NaN and an unknown distance as a
/// negative number; here they are `None`, and [`OpticalFlowRad::wire_gyro`] and
/// [`OpticalFlowRad::wire_distance`] give the wire values.
///
/// ```
/// use kestrel::ego::OpticalFlowRad;
/// let flow = OpticalFlowRad::default();
/// assert_eq!(flow.quality, 0);
/// assert!(flow.wire_gyro()[0].is_nan());
/// assert_eq!(flow.wire_distance(), -1.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OpticalFlowRad {
    /// Timestamp of the readout, microseconds (since boot or the UNIX epoch).
    pub time_usec: u64,
    /// Sensor ID.
    pub sensor_id: u8,
    /// Time the flow and gyro were integrated over, microseconds.
    pub integration_time_us: u32,
    /// Flow about X, rad: positive for a right-hand rotation about X, negative for motion
    /// along +Y. 0 when `quality` is 0.
    pub integrated_x: f32,
    /// Flow about Y, rad: positive for a right-hand rotation about Y and for motion along +X.
    /// 0 when `quality` is 0.
    pub integrated_y: f32,
    /// Right-hand rotation about X, rad; `None` unless every frame had a gyro reading.
    pub integrated_xgyro: Option<f32>,
    /// Right-hand rotation about Y, rad; `None` unless every frame had a gyro reading.
    pub integrated_ygyro: Option<f32>,
    /// Right-hand rotation about Z, rad; `None` unless every frame had a gyro reading.
    pub integrated_zgyro: Option<f32>,
    /// Temperature, centidegrees Celsius.
    pub temperature: i16,
    /// 0 (no valid flow) to 255.
    pub quality: u8,
    /// Age of the distance at readout, microseconds (0 when unknown).
    pub time_delta_distance_us: u32,
    /// Distance to the centre of the flow field, metres; `None` when unknown.
    pub distance: Option<f32>,
}

impl OpticalFlowRad {
    /// `integrated_xgyro`, `_ygyro`, `_zgyro` as MAVLink sends them: NaN when there is no gyro.
    ///
    /// ```
    /// use kestrel::ego::OpticalFlowRad;
    /// let flow = OpticalFlowRad { integrated_xgyro: Some(0.1), ..Default::default() };
    /// assert_eq!(flow.wire_gyro()[0], 0.1);
    /// assert!(flow.wire_gyro()[1].is_nan());
    /// ```
    pub fn wire_gyro(&self) -> [f32; 3] {
        [
            self.integrated_xgyro,
            self.integrated_ygyro,
            self.integrated_zgyro,
        ]
        .map(|g| g.unwrap_or(f32::NAN))
    }

    /// `distance` as MAVLink sends it: -1 when unknown.
    ///
    /// ```
    /// use kestrel::ego::OpticalFlowRad;
    /// let flow = OpticalFlowRad { distance: Some(1.5), ..Default::default() };
    /// assert_eq!(flow.wire_distance(), 1.5);
    /// ```
    pub fn wire_distance(&self) -> f32 {
        self.distance.unwrap_or(-1.0)
    }
}

/// One OPTICAL_FLOW reading (MAVLink message 100): the same integration as an
/// [`OpticalFlowRad`], in the units of the older message, which ArduPilot reads.
///
/// Made by [`OpticalFlow::from_rad`] (or [`FlowRadAccumulator::optical_flow`]), so both
/// messages of a readout carry the same flow, signs and quality:
///
/// - `flow_rate_x/y` (rad/s) are `integrated_x/y` divided by the integration time: positive
///   for a right-hand rotation about the sensor axis. ArduPilot uses these whenever a sensor
///   has sent one non-zero.
/// - `flow_x/y` (deci-pixels) are the same flow as the image displacement at the principal
///   point, `10 f tan(integrated)`: exact when a readout integrates one frame pair. ArduPilot
///   falls back to them for sensors that never fill `flow_rate_x/y`.
/// - `flow_comp_m_x/y` (m/s) are the rates less the gyro's, times the distance: the speed over
///   the ground the flow implies, with the same signs; 0 without a gyro or a distance (neither
///   autopilot reads them).
///
/// Every field is finite. A reading that would not be (a NaN put into the public fields of an
/// `OpticalFlowRad`, a zero focal length) is sent as no flow with quality 0.
///
/// ```
/// use kestrel::ego::{OpticalFlow, OpticalFlowRad};
/// let rad = OpticalFlowRad {
///     integration_time_us: 10_000,
///     integrated_x: 0.005,
///     quality: 180,
///     ..Default::default()
/// };
/// let flow = OpticalFlow::from_rad(&rad, (140.0, 140.0));
/// assert!((flow.flow_rate_x - 0.5).abs() < 1e-6); // 0.005 rad in 10 ms
/// assert_eq!((flow.flow_x, flow.flow_y, flow.quality), (7, 0, 180)); // 0.7 px
/// assert_eq!((flow.flow_comp_m_x, flow.wire_ground_distance()), (0.0, -1.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OpticalFlow {
    /// Timestamp of the readout, microseconds (the OPTICAL_FLOW_RAD reading's).
    pub time_usec: u64,
    /// Sensor ID.
    pub sensor_id: u8,
    /// Flow about X as image displacement at the principal point, deci-pixels (saturated).
    pub flow_x: i16,
    /// Flow about Y as image displacement at the principal point, deci-pixels (saturated).
    pub flow_y: i16,
    /// `flow_rate_x` less the gyro's rate about X, times the distance, m/s; 0 when unknown.
    pub flow_comp_m_x: f32,
    /// `flow_rate_y` less the gyro's rate about Y, times the distance, m/s; 0 when unknown.
    pub flow_comp_m_y: f32,
    /// 0 (no valid flow) to 255, as in the OPTICAL_FLOW_RAD reading.
    pub quality: u8,
    /// Distance to the ground, metres; `None` when unknown.
    pub ground_distance: Option<f32>,
    /// Flow rate about X, rad/s.
    pub flow_rate_x: f32,
    /// Flow rate about Y, rad/s.
    pub flow_rate_y: f32,
}

impl OpticalFlow {
    /// The OPTICAL_FLOW reading of `reading`, for a camera of focal lengths `(fx, fy)` px.
    ///
    /// ```
    /// use kestrel::ego::{OpticalFlow, OpticalFlowRad};
    /// let rad = OpticalFlowRad {
    ///     integration_time_us: 20_000,
    ///     integrated_y: -0.01,
    ///     integrated_ygyro: Some(0.0),
    ///     integrated_xgyro: Some(0.0),
    ///     integrated_zgyro: Some(0.0),
    ///     distance: Some(2.0),
    ///     quality: 99,
    ///     ..Default::default()
    /// };
    /// let flow = OpticalFlow::from_rad(&rad, (100.0, 100.0));
    /// assert!((flow.flow_rate_y + 0.5).abs() < 1e-6);
    /// assert!((flow.flow_comp_m_y + 1.0).abs() < 1e-6); // -0.5 rad/s at 2 m
    /// assert_eq!((flow.flow_y, flow.ground_distance), (-10, Some(2.0)));
    /// // Nothing that is not finite reaches the wire: such a reading has quality 0.
    /// let broken = OpticalFlowRad { integrated_x: f32::NAN, quality: 200, ..rad };
    /// assert_eq!(OpticalFlow::from_rad(&broken, (100.0, 100.0)).quality, 0);
    /// ```
    pub fn from_rad(reading: &OpticalFlowRad, (fx, fy): (f32, f32)) -> Self {
        let empty = Self {
            time_usec: reading.time_usec,
            sensor_id: reading.sensor_id,
            ground_distance: reading.distance.filter(|d| d.is_finite() && *d >= 0.0),
            ..Self::default()
        };
        if reading.quality == 0 || reading.integration_time_us == 0 {
            return empty;
        }
        let seconds = reading.integration_time_us as f32 * 1e-6;
        let rate = (
            reading.integrated_x / seconds,
            reading.integrated_y / seconds,
        );
        let pixels = (
            fx * libm::tanf(reading.integrated_x),
            fy * libm::tanf(reading.integrated_y),
        );
        let comp = match (reading.integrated_xgyro, reading.integrated_ygyro) {
            (Some(gx), Some(gy)) => empty
                .ground_distance
                .map(|d| ((rate.0 - gx / seconds) * d, (rate.1 - gy / seconds) * d)),
            _ => None,
        };
        // A speed that cannot be known (a NaN put in the gyro) is unknown, not a spoilt flow.
        let comp = comp
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .unwrap_or((0.0, 0.0));
        if ![rate.0, rate.1, pixels.0, pixels.1]
            .iter()
            .all(|v| v.is_finite())
        {
            return empty;
        }
        Self {
            flow_x: deci_pixels(pixels.0),
            flow_y: deci_pixels(pixels.1),
            flow_comp_m_x: comp.0,
            flow_comp_m_y: comp.1,
            quality: reading.quality,
            flow_rate_x: rate.0,
            flow_rate_y: rate.1,
            ..empty
        }
    }

    /// `ground_distance` as MAVLink sends it: -1 when unknown.
    ///
    /// ```
    /// use kestrel::ego::OpticalFlow;
    /// let flow = OpticalFlow { ground_distance: Some(3.0), ..Default::default() };
    /// assert_eq!(flow.wire_ground_distance(), 3.0);
    /// assert_eq!(OpticalFlow::default().wire_ground_distance(), -1.0);
    /// ```
    pub fn wire_ground_distance(&self) -> f32 {
        self.ground_distance.unwrap_or(-1.0)
    }
}

/// Pixels as deci-pixels, rounded and saturated to `i16` (a finite input).
fn deci_pixels(pixels: f32) -> i16 {
    let deci = libm::roundf(pixels * 10.0);
    // Clamped to the range of `i16` first, so `as` only drops the (zero) fraction.
    #[allow(clippy::cast_possible_truncation)]
    let deci = deci.clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16;
    deci
}

/// The MAVLink OPTICAL_FLOW_RAD accumulator, and the OPTICAL_FLOW reading of the same integration.
///
/// An angular-rate flow sensor integrates flow and gyro between readouts: the camera may run at
/// 100 Hz while the autopilot reads 20 times a second. Per frame pair, [`FlowRadAccumulator::add`]
/// takes the fitted motion, the frame interval and (optionally) the gyro integrated over it, and
/// adds
///
/// - the angular flow at the principal point ([`Camera::angular_flow`]) to `integrated_x/y`,
/// - the interval to `integration_time_us`,
/// - the gyro rotation vector to `integrated_xgyro/ygyro/zgyro`,
///
/// all in the sensor frame with MAVLink's signs (see [`Rotation`](super::Rotation)): a right-hand rotation
/// about X gives positive `integrated_x`, and under pure rotation the flow equals the gyro. PX4
/// subtracts the gyro itself, so the flow is reported with its rotational part.
/// [`FlowRadAccumulator::readout`] returns the sums and starts a new integration.
///
/// ```
/// use kestrel::ego::{Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, Homography,
///     ModelKind};
/// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
/// let mut acc = FlowRadAccumulator::new(camera, 0);
/// // Two frame pairs in which the image moved 2 px to the right, 10 ms each.
/// let motion = EgoMotion {
///     model: Homography::translation(2.0, 0.0).unwrap(),
///     kind: ModelKind::Translation,
///     inliers: 60,
///     rms_residual: 0.2,
///     quality: 200,
///     status: EgoStatus::Ok,
///     iterations: 3,
/// };
/// assert_eq!(acc.add(&motion, 10_000, Some([0.001, 0.0, 0.0])), EgoStatus::Ok);
/// assert_eq!(acc.add(&motion, 10_000, Some([0.001, 0.0, 0.0])), EgoStatus::Ok);
/// let flow = acc.readout(1_000_000);
/// assert_eq!((flow.integration_time_us, flow.quality), (20_000, 200));
/// assert!((flow.integrated_x - 2.0 * (2.0f32 / 146.44).atan()).abs() < 1e-4);
/// assert_eq!(flow.integrated_xgyro, Some(0.002));
/// assert_eq!(acc.frames(), 0);
/// ```
///
/// Integrates frame-to-frame motion and gyro readings into [`OpticalFlowRad`] readouts.
///
/// The readout's `quality` is the rounded mean of the frames' [`EgoMotion::quality`], or 0 when
/// no frame was added or any frame since the last readout was unusable (a motion estimate that
/// was not `Ok`, a bad interval or a bad gyro reading): the flow integral would then miss part
/// of the integration time. See also the module example.
///
/// ```
/// use kestrel::ego::{Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, ModelKind};
/// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
/// let mut acc = FlowRadAccumulator::new(camera, 0);
/// let still = EgoMotion { quality: 120, ..EgoMotion::failed(ModelKind::Homography, EgoStatus::Ok) };
/// for _ in 0..4 {
///     acc.add(&still, 2_500, Some([0.0; 3]));
/// }
/// let flow = acc.readout(10_000);
/// assert_eq!((flow.integration_time_us, flow.quality, flow.integrated_x), (10_000, 120, 0.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowRadAccumulator {
    camera: Camera,
    sensor_id: u8,
    temperature: i16,
    /// Metres, and when they were measured (microseconds, the readout's clock).
    distance: Option<(f32, u64)>,
    flow: (f32, f32),
    gyro: [f32; 3],
    integration_time_us: u32,
    frames: u16,
    frames_with_gyro: u16,
    quality_sum: u32,
    unusable: bool,
}

impl FlowRadAccumulator {
    /// An empty accumulator for `camera`, reporting as `sensor_id`.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, FlowRadAccumulator};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
    /// let mut acc = FlowRadAccumulator::new(camera, 3);
    /// let empty = acc.readout(0);
    /// assert_eq!((empty.sensor_id, empty.quality, empty.integrated_xgyro), (3, 0, None));
    /// ```
    pub fn new(camera: Camera, sensor_id: u8) -> Self {
        Self {
            camera,
            sensor_id,
            temperature: 0,
            distance: None,
            flow: (0.0, 0.0),
            gyro: [0.0; 3],
            integration_time_us: 0,
            frames: 0,
            frames_with_gyro: 0,
            quality_sum: 0,
            unusable: false,
        }
    }

    /// Adds one frame pair: its motion estimate, the time between the two frames
    /// (1..=[`MAX_INTERVAL_US`] microseconds) and the gyro integrated over that time (rad,
    /// sensor frame), if there is a gyro. Returns `Ok`, or why the frame spoils the readout:
    /// the motion's own status, [`EgoStatus::BadInput`] for a bad interval or gyro reading
    /// (NaN, infinite, or beyond [`super::MAX_BODY_RATE`]), [`EgoStatus::Degenerate`] when the
    /// motion has no image of the principal point.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator,
    ///     ModelKind};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
    /// let mut acc = FlowRadAccumulator::new(camera, 0);
    /// let lost = EgoMotion::failed(ModelKind::Homography, EgoStatus::NoConsensus);
    /// assert_eq!(acc.add(&lost, 10_000, None), EgoStatus::NoConsensus);
    /// let still = EgoMotion { quality: 90, status: EgoStatus::Ok, ..lost };
    /// assert_eq!(acc.add(&still, 10_000, Some([f32::NAN, 0.0, 0.0])), EgoStatus::BadInput);
    /// assert_eq!(acc.readout(0).quality, 0);
    /// ```
    pub fn add(
        &mut self,
        motion: &EgoMotion,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
    ) -> EgoStatus {
        let status = self.add_frame(motion, interval_us, gyro);
        if status != EgoStatus::Ok {
            self.unusable = true;
        }
        status
    }

    fn add_frame(
        &mut self,
        motion: &EgoMotion,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
    ) -> EgoStatus {
        self.frames = self.frames.saturating_add(1);
        if !(1..=MAX_INTERVAL_US).contains(&interval_us) {
            return EgoStatus::BadInput;
        }
        self.integration_time_us = self.integration_time_us.saturating_add(interval_us);
        if let Some(vector) = gyro {
            let Ok(rotation) = Rotation::from_integrated_gyro(vector, interval_us) else {
                return EgoStatus::BadInput;
            };
            for (sum, v) in self.gyro.iter_mut().zip(rotation.vector()) {
                *sum += v;
            }
            self.frames_with_gyro = self.frames_with_gyro.saturating_add(1);
        }
        if !motion.is_ok() {
            return motion.status;
        }
        let Some((x, y)) = self.camera.angular_flow(&motion.model) else {
            return EgoStatus::Degenerate;
        };
        self.flow.0 += x;
        self.flow.1 += y;
        self.quality_sum = self.quality_sum.saturating_add(u32::from(motion.quality));
        EgoStatus::Ok
    }

    /// Sets the temperature reported from now on, centidegrees Celsius.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, FlowRadAccumulator};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
    /// let mut acc = FlowRadAccumulator::new(camera, 0);
    /// acc.set_temperature(2_150);
    /// assert_eq!(acc.readout(0).temperature, 2_150);
    /// ```
    pub fn set_temperature(&mut self, centidegrees: i16) {
        self.temperature = centidegrees;
    }

    /// Sets the distance to the ground (metres) measured at `sampled_at_us` on the readout
    /// clock. A negative, NaN or infinite distance means unknown.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, FlowRadAccumulator};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
    /// let mut acc = FlowRadAccumulator::new(camera, 0);
    /// acc.set_distance(2.5, 1_000);
    /// let flow = acc.readout(4_000);
    /// assert_eq!((flow.distance, flow.time_delta_distance_us), (Some(2.5), 3_000));
    /// acc.set_distance(f32::NAN, 5_000);
    /// assert_eq!(acc.readout(6_000).distance, None);
    /// ```
    pub fn set_distance(&mut self, metres: f32, sampled_at_us: u64) {
        self.distance = (metres >= 0.0 && metres.is_finite()).then_some((metres, sampled_at_us));
    }

    /// The OPTICAL_FLOW reading of `reading` (a readout of this accumulator) in this
    /// accumulator's camera: both messages from the same integration.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator,
    ///     Homography, ModelKind};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
    /// let mut acc = FlowRadAccumulator::new(camera, 0);
    /// let motion = EgoMotion {
    ///     model: Homography::translation(1.5, -0.5).unwrap(),
    ///     quality: 150,
    ///     ..EgoMotion::failed(ModelKind::Translation, EgoStatus::Ok)
    /// };
    /// acc.add(&motion, 10_000, None);
    /// let rad = acc.readout(10_000);
    /// let flow = acc.optical_flow(&rad);
    /// assert_eq!((flow.flow_x, flow.flow_y, flow.quality), (15, -5, rad.quality));
    /// assert!((flow.flow_rate_x - rad.integrated_x * 100.0).abs() < 1e-5);
    /// ```
    pub fn optical_flow(&self, reading: &OpticalFlowRad) -> OpticalFlow {
        let params = self.camera.params();
        OpticalFlow::from_rad(reading, (params.focal_x, params.focal_y))
    }

    /// Frame pairs added since the last readout.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, FlowRadAccumulator};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
    /// assert_eq!(FlowRadAccumulator::new(camera, 0).frames(), 0);
    /// ```
    pub fn frames(&self) -> u16 {
        self.frames
    }

    /// The integrals since the last readout, stamped `time_usec`; starts a new integration
    /// (temperature and distance are kept).
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, FlowRadAccumulator};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
    /// let mut acc = FlowRadAccumulator::new(camera, 0);
    /// assert_eq!(acc.readout(42).time_usec, 42);
    /// ```
    pub fn readout(&mut self, time_usec: u64) -> OpticalFlowRad {
        let usable = self.frames > 0 && !self.unusable;
        let quality = if usable {
            let frames = u32::from(self.frames);
            let mean = self
                .quality_sum
                .saturating_add(frames / 2)
                .checked_div(frames)
                .unwrap_or(0);
            u8::try_from(mean.clamp(1, 255)).unwrap_or(u8::MAX)
        } else {
            0
        };
        let flow = if usable { self.flow } else { (0.0, 0.0) };
        let gyro_known = self.frames > 0 && self.frames_with_gyro == self.frames;
        let gyro = |axis: f32| gyro_known.then_some(axis);
        let (distance, time_delta_distance_us) = match self.distance {
            Some((metres, at)) => {
                let age = time_usec.saturating_sub(at);
                (Some(metres), u32::try_from(age).unwrap_or(u32::MAX))
            }
            None => (None, 0),
        };
        let reading = OpticalFlowRad {
            time_usec,
            sensor_id: self.sensor_id,
            integration_time_us: self.integration_time_us,
            integrated_x: flow.0,
            integrated_y: flow.1,
            integrated_xgyro: gyro(self.gyro[0]),
            integrated_ygyro: gyro(self.gyro[1]),
            integrated_zgyro: gyro(self.gyro[2]),
            temperature: self.temperature,
            quality,
            time_delta_distance_us,
            distance,
        };
        *self = Self {
            temperature: self.temperature,
            distance: self.distance,
            ..Self::new(self.camera, self.sensor_id)
        };
        reading
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ego::{CameraParams, Homography, ModelKind};

    fn accumulator() -> FlowRadAccumulator {
        let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
        FlowRadAccumulator::new(camera, 7)
    }

    fn motion(quality: u8) -> EgoMotion {
        EgoMotion {
            quality,
            status: EgoStatus::Ok,
            ..EgoMotion::failed(ModelKind::Homography, EgoStatus::Ok)
        }
    }

    #[test]
    fn quality_is_the_rounded_mean() {
        let mut acc = accumulator();
        for q in [100, 101, 101] {
            acc.add(&motion(q), 5_000, None);
        }
        let flow = acc.readout(0);
        assert_eq!((flow.quality, flow.integration_time_us), (101, 15_000));
        assert_eq!(flow.integrated_zgyro, None);
    }

    #[test]
    fn a_frame_without_gyro_drops_the_gyro_integral() {
        let mut acc = accumulator();
        acc.add(&motion(50), 5_000, Some([0.01, 0.0, 0.0]));
        acc.add(&motion(50), 5_000, None);
        let flow = acc.readout(0);
        assert_eq!((flow.integrated_xgyro, flow.quality), (None, 50));
    }

    #[test]
    fn bad_intervals_and_absurd_gyros_zero_the_quality() {
        for (interval, gyro) in [
            (0, None),
            (2_000_000, None),
            (10_000, Some([0.0, 1.0, 0.0])),
            (10_000, Some([0.0, 0.0, f32::INFINITY])),
        ] {
            let mut acc = accumulator();
            acc.add(&motion(200), 10_000, None);
            assert_eq!(acc.add(&motion(200), interval, gyro), EgoStatus::BadInput);
            let flow = acc.readout(0);
            assert_eq!((flow.quality, flow.integrated_x), (0, 0.0));
        }
    }

    #[test]
    fn optical_flow_carries_the_same_integration() {
        let mut acc = accumulator();
        acc.set_distance(1.5, 0);
        let shift = EgoMotion {
            model: Homography::translation(0.65, -0.42).unwrap(),
            ..motion(180)
        };
        acc.add(&shift, 10_000, Some([0.001, -0.002, 0.0]));
        let rad = acc.readout(10_000);
        let flow = acc.optical_flow(&rad);
        assert_eq!(
            (flow.time_usec, flow.sensor_id, flow.quality),
            (10_000, 7, 180)
        );
        assert_eq!((flow.flow_x, flow.flow_y), (7, -4)); // 6.5 and -4.2 dpix
        assert!((flow.flow_rate_x - rad.integrated_x / 0.01).abs() < 1e-6);
        assert!((flow.flow_rate_y - rad.integrated_y / 0.01).abs() < 1e-6);
        let comp_x = (rad.integrated_x - 0.001) / 0.01 * 1.5;
        assert!((flow.flow_comp_m_x - comp_x).abs() < 1e-5);
        assert_eq!(flow.ground_distance, Some(1.5));
    }

    #[test]
    fn optical_flow_of_a_spoilt_or_absurd_reading_has_no_flow() {
        let good = OpticalFlowRad {
            integration_time_us: 10_000,
            integrated_x: 0.01,
            quality: 100,
            ..Default::default()
        };
        for broken in [
            OpticalFlowRad { quality: 0, ..good },
            OpticalFlowRad {
                integration_time_us: 0,
                ..good
            },
            OpticalFlowRad {
                integrated_y: f32::INFINITY,
                ..good
            },
        ] {
            let flow = OpticalFlow::from_rad(&broken, (100.0, 100.0));
            assert_eq!(
                (flow.quality, flow.flow_x, flow.flow_rate_x),
                (0, 0, 0.0),
                "{broken:?}"
            );
        }
        // A NaN gyro spoils only the speed over the ground, which becomes unknown.
        let no_gyro = OpticalFlowRad {
            distance: Some(2.0),
            integrated_xgyro: Some(f32::NAN),
            integrated_ygyro: Some(0.0),
            ..good
        };
        let flow = OpticalFlow::from_rad(&no_gyro, (100.0, 100.0));
        assert_eq!(
            (flow.quality, flow.flow_x, flow.flow_comp_m_x),
            (100, 10, 0.0)
        );
        // A finite but huge displacement saturates the deci-pixels; the rate stays true.
        let fast = OpticalFlowRad {
            integrated_x: 1.5,
            ..good
        };
        let flow = OpticalFlow::from_rad(&fast, (1000.0, 1000.0));
        assert_eq!((flow.flow_x, flow.quality), (i16::MAX, 100));
        assert!((flow.flow_rate_x - 150.0).abs() < 1e-3);
    }

    #[test]
    fn a_motion_without_a_principal_point_image_is_degenerate() {
        let mut acc = accumulator();
        // Horizon line x = 50 - ..., beyond the principal point (79.5, 59.5).
        let m = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -0.02, 0.0, 1.0];
        let away = EgoMotion {
            model: Homography::from_matrix(m).unwrap(),
            ..motion(100)
        };
        assert_eq!(acc.add(&away, 10_000, None), EgoStatus::Degenerate);
    }
}
