//! The camera's motion from the tracks, and what the autopilot gets from it: an
//! OPTICAL_FLOW_RAD reading per frame pair, encoded as a MAVLink 2 frame.
//!
//! The tracker reports where each track is now; the positions of the previous frame are kept
//! here by track id, so that each track followed into the new frame gives one correspondence.

use heapless::Vec;
use kestrel::ego::mavlink::{encode_optical_flow_rad, EncodeError, MavlinkHeader, MAX_FRAME_LEN};
use kestrel::ego::{
    Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, ModelKind, OpticalFlow,
    OpticalFlowRad, Ransac, RansacParams,
};
use kestrel::track::Track;
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
    /// The previous frame's track positions, by ascending id.
    history: Vec<(u32, Point), MAX_TRACKS>,
    /// The latest frame pair's correspondences, and which of them the model explains.
    pairs: Vec<(Point, Point), MAX_TRACKS>,
    inliers: [bool; MAX_TRACKS],
    /// The latest reading and its MAVLink frame.
    reading: OpticalFlowRad,
    frame: [u8; MAX_FRAME_LEN],
    frame_len: usize,
    sequence: u8,
    time_usec: u64,
}

impl Ego {
    /// A RANSAC fit of `model` with the library's other defaults and a 60 degree camera.
    pub fn new(model: ModelKind) -> Result<Self, FrameError> {
        let params = RansacParams {
            model,
            ..RansacParams::default()
        };
        let ransac = Ransac::new(params).map_err(FrameError::Ego)?;
        let params = CameraParams::from_horizontal_fov(WIDTH as u16, HEIGHT as u16, fov_radians());
        let camera = Camera::new(params).map_err(FrameError::Camera)?;
        Ok(Self {
            ransac,
            camera,
            accumulator: FlowRadAccumulator::new(camera, SENSOR_ID),
            history: Vec::new(),
            pairs: Vec::new(),
            inliers: [false; MAX_TRACKS],
            reading: OpticalFlowRad::default(),
            frame: [0; MAX_FRAME_LEN],
            frame_len: 0,
            sequence: 0,
            time_usec: 0,
        })
    }

    /// Keeps the tracks' positions for the next frame.
    pub fn remember(&mut self, tracks: &[Track]) {
        self.history.clear();
        for track in tracks {
            // The tracker holds at most MAX_TRACKS tracks: the push cannot fail.
            let _ = self.history.push((track.id, track.position));
        }
        self.history.sort_unstable_by_key(|&(id, _)| id);
    }

    /// Fits the camera's motion to the tracks followed into this frame, integrates it into
    /// the flow reading, reads it out and encodes it.
    pub fn estimate(
        &mut self,
        tracks: &[Track],
    ) -> Result<(EgoMotion, OpticalFlowRad), FrameError> {
        self.pair(tracks);
        self.remember(tracks);
        let inliers = self.inliers.get_mut(..self.pairs.len()).unwrap_or(&mut []);
        let motion = self
            .ransac
            .estimate(&self.pairs, inliers)
            .map_err(FrameError::Ego)?;
        self.accumulator.add(&motion, FRAME_INTERVAL_US, None);
        self.read_out().map_err(FrameError::Mavlink)?;
        Ok((motion, self.reading))
    }

    /// The reading of a refused frame: the integration is spoilt, so its quality is 0.
    pub fn refuse(&mut self) -> Result<(), EncodeError> {
        let refused = EgoMotion::failed(ModelKind::Homography, EgoStatus::BadInput);
        self.accumulator.add(&refused, FRAME_INTERVAL_US, None);
        self.read_out()
    }

    /// The latest frame pair's correspondences.
    pub fn pairs(&self) -> &[(Point, Point)] {
        &self.pairs
    }

    /// The latest reading and its MAVLink frame.
    pub fn latest(&self) -> (&OpticalFlowRad, &[u8]) {
        (
            &self.reading,
            self.frame.get(..self.frame_len).unwrap_or(&[]),
        )
    }

    /// The latest reading as OPTICAL_FLOW: the same integration, in ArduPilot's message.
    pub fn optical_flow(&self) -> OpticalFlow {
        self.accumulator.optical_flow(&self.reading)
    }

    /// The camera's focal length, px.
    pub fn focal_length(&self) -> f32 {
        self.camera.params().focal_x
    }

    /// Pairs every track followed into this frame with its position in the previous one.
    fn pair(&mut self, tracks: &[Track]) {
        self.pairs.clear();
        for track in tracks.iter().filter(|t| t.age > 0) {
            let Ok(at) = self.history.binary_search_by_key(&track.id, |&(id, _)| id) else {
                continue;
            };
            if let Some(&(_, before)) = self.history.get(at) {
                // At most one pair per track: the push cannot fail either.
                let _ = self.pairs.push((before, track.position));
            }
        }
    }

    /// One reading per frame pair, as a flow sensor at the camera's frame rate would send.
    fn read_out(&mut self) -> Result<(), EncodeError> {
        self.time_usec += u64::from(FRAME_INTERVAL_US);
        self.reading = self.accumulator.readout(self.time_usec);
        let header = MavlinkHeader {
            system_id: SYSTEM_ID,
            component_id: COMPONENT_ID,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        self.frame_len = encode_optical_flow_rad(&self.reading, header, &mut self.frame)?;
        Ok(())
    }
}

/// The field of view in radians.
fn fov_radians() -> f32 {
    FIELD_OF_VIEW_DEGREES * core::f32::consts::PI / 180.0
}
