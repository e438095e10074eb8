//! The camera's motion from the tracks, and what the autopilot gets from it: an
//! OPTICAL_FLOW_RAD reading per frame pair, encoded as a MAVLink 2 frame.
//!
//! The tracker gives each track followed into the new frame as one correspondence
//! ([`Tracker::correspondences`]).

use heapless::Vec;
use kestrel::ego::mavlink::{encode_optical_flow_rad, EncodeError, MavlinkHeader, MAX_FRAME_LEN};
use kestrel::ego::{
    Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, ModelKind, OpticalFlowRad,
    Ransac, RansacParams,
};
use kestrel::track::Tracker;
use kestrel::Point;

use crate::pipeline::{FrameError, MAX_TRACKS};
use crate::scene::{FIELD_OF_VIEW_DEGREES, FRAME_INTERVAL_US, HEIGHT, WIDTH};

/// The vehicle's MAVLink system id.
const SYSTEM_ID: u8 = 1;
/// MAV_COMP_ID_CAMERA.
const COMPONENT_ID: u8 = 100;
/// The flow sensor's id in OPTICAL_FLOW_RAD.
const SENSOR_ID: u8 = 0;

/// The ego-motion stage and its state between frames.
pub struct Ego {
    ransac: Ransac,
    camera: Camera,
    accumulator: FlowRadAccumulator,
    /// The latest frame pair's correspondences, and which of them the model explains.
    pairs: Vec<(Point, Point), MAX_TRACKS>,
    inliers: [bool; MAX_TRACKS],
    readout: Readout,
}

impl Ego {
    /// A RANSAC fit of `model` with the library's other defaults and a 60 degree camera.
    pub fn new(model: ModelKind) -> Result<Self, FrameError> {
        let params = RansacParams {
            model,
            ..RansacParams::default()
        };
        let ransac = Ransac::new(params).map_err(FrameError::Config)?;
        let params = CameraParams::from_horizontal_fov(WIDTH as u16, HEIGHT as u16, fov_radians());
        let camera = Camera::new(params).map_err(FrameError::Config)?;
        Ok(Self {
            ransac,
            camera,
            accumulator: FlowRadAccumulator::new(camera, SENSOR_ID),
            pairs: Vec::new(),
            inliers: [false; MAX_TRACKS],
            readout: Readout::default(),
        })
    }

    /// Fits the camera's motion to the tracks followed into this frame, integrates it into
    /// the flow reading, reads it out and encodes it.
    pub fn estimate(
        &mut self,
        tracker: &Tracker<'_, MAX_TRACKS>,
    ) -> Result<(EgoMotion, OpticalFlowRad), FrameError> {
        tracker.correspondences(&mut self.pairs);
        let inliers = self.inliers.get_mut(..self.pairs.len()).unwrap_or(&mut []);
        let motion = self
            .ransac
            .estimate(&self.pairs, inliers)
            .map_err(FrameError::Ego)?;
        self.accumulator.add(&motion, FRAME_INTERVAL_US, None);
        let reading = self.readout.take(&mut self.accumulator);
        reading.map_err(FrameError::Mavlink)?;
        Ok((motion, self.readout.reading))
    }

    /// The reading of a refused frame: the integration is spoilt, so its quality is 0.
    pub fn refuse(&mut self) -> Result<(), EncodeError> {
        let refused = EgoMotion::failed(ModelKind::Homography, EgoStatus::BadInput);
        self.accumulator.add(&refused, FRAME_INTERVAL_US, None);
        self.readout.take(&mut self.accumulator).map(|_| ())
    }

    /// The latest frame pair's correspondences.
    pub fn pairs(&self) -> &[(Point, Point)] {
        &self.pairs
    }

    /// The latest reading and its MAVLink frame.
    pub fn latest(&self) -> (&OpticalFlowRad, &[u8]) {
        self.readout.latest()
    }

    /// The camera's focal length, px.
    pub fn focal_length(&self) -> f32 {
        self.camera.params().focal_x
    }
}

/// The readings sent to the autopilot, one per frame pair as a flow sensor at the camera's frame
/// rate would send, each with its MAVLink frame.
pub struct Readout {
    /// The latest reading and its MAVLink frame.
    pub reading: OpticalFlowRad,
    frame: [u8; MAX_FRAME_LEN],
    frame_len: usize,
    sequence: u8,
    time_usec: u64,
}

impl Default for Readout {
    fn default() -> Self {
        Self {
            reading: OpticalFlowRad::default(),
            frame: [0; MAX_FRAME_LEN],
            frame_len: 0,
            sequence: 0,
            time_usec: 0,
        }
    }
}

impl Readout {
    /// Reads `accumulator` out a frame interval after the last readout and encodes it.
    pub fn take(
        &mut self,
        accumulator: &mut FlowRadAccumulator,
    ) -> Result<&OpticalFlowRad, EncodeError> {
        let time_usec = self.next_time();
        self.keep(accumulator.readout(time_usec))
    }

    /// The time stamp of the next readout: a frame interval after the last.
    pub fn next_time(&mut self) -> u64 {
        self.time_usec += u64::from(FRAME_INTERVAL_US);
        self.time_usec
    }

    /// Keeps `reading` as the latest and encodes it.
    pub fn keep(&mut self, reading: OpticalFlowRad) -> Result<&OpticalFlowRad, EncodeError> {
        self.reading = reading;
        self.encode()
    }

    fn encode(&mut self) -> Result<&OpticalFlowRad, EncodeError> {
        let header = MavlinkHeader {
            system_id: SYSTEM_ID,
            component_id: COMPONENT_ID,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        self.frame_len = encode_optical_flow_rad(&self.reading, header, &mut self.frame)?;
        Ok(&self.reading)
    }

    /// The latest reading and its MAVLink frame.
    pub fn latest(&self) -> (&OpticalFlowRad, &[u8]) {
        (
            &self.reading,
            self.frame.get(..self.frame_len).unwrap_or(&[]),
        )
    }
}

/// The field of view in radians.
pub fn fov_radians() -> f32 {
    FIELD_OF_VIEW_DEGREES * core::f32::consts::PI / 180.0
}
