//! `--preset flow-sensor`: the library's flow sensor ([`kestrel::sensor::FlowSensor`]), the
//! pipeline the firmware runs, fed the sequence's frames.

use kestrel::ego::{ModelKind, OpticalFlow, OpticalFlowRad, RansacParams};
use kestrel::sensor::{FlowSensor, FlowSensorConfig, FlowStep};
use kestrel::track::TrackerConfig;

use super::estimator::{camera, PairMotion};
use crate::tracking::{HostBuffers, LkSettings, Preset, MAX_TRACKS};
use crate::Frame;

/// The preset's settings: its tracker with the command line's point count and LK flags over
/// it, and its similarity fit unless another model is asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSettings {
    /// The tracker's configuration.
    pub tracker: TrackerConfig,
    /// The model fitted, when not the preset's.
    pub model: Option<ModelKind>,
    /// RANSAC inlier threshold, px.
    pub threshold: f32,
    /// Focal length in pixels; `None` for a 60 degree horizontal field of view.
    pub focal: Option<f32>,
}

impl SensorSettings {
    /// `preset` with `max_points` and the `lk` flags over it.
    pub fn new(preset: Preset, max_points: Option<usize>, lk: &LkSettings) -> Self {
        let mut tracker = preset.config(max_points);
        tracker.lk = lk.apply(tracker.lk);
        Self {
            tracker,
            model: None,
            threshold: RansacParams::default().threshold,
            focal: None,
        }
    }
}

/// The flow sensor over caller-owned buffers, and the frame it saw last.
pub struct PresetSensor<'m> {
    sensor: Box<FlowSensor<'m, MAX_TRACKS>>,
    size: (usize, usize),
    previous: Option<Frame>,
}

/// One frame pair through the sensor.
pub struct SensorPair {
    /// The motion and the tracks it was fitted to.
    pub pair: PairMotion,
    /// What the pair integrated into the reading.
    pub step: FlowStep,
    /// The reading read out after the pair.
    pub reading: OpticalFlowRad,
    /// The same reading as OPTICAL_FLOW.
    pub flow: OpticalFlow,
}

impl<'m> PresetSensor<'m> {
    /// A sensor for `width` x `height` frames in `buffers` (made for `settings.tracker`).
    pub fn new(
        settings: &SensorSettings,
        width: usize,
        height: usize,
        buffers: &'m mut HostBuffers,
    ) -> Result<Self, String> {
        let mut config = FlowSensorConfig::new(*camera(settings.focal, width, height)?.params());
        config.tracker = settings.tracker;
        config.ransac.threshold = settings.threshold;
        if let Some(model) = settings.model {
            config.ransac.model = model;
        }
        let sensor = FlowSensor::new(config, width, height, buffers.lend())
            .map_err(|e| format!("flow sensor: {e}"))?;
        Ok(Self {
            sensor: Box::new(sensor),
            size: (width, height),
            previous: None,
        })
    }

    /// Takes the next frame, taken `interval_us` after the previous one (with the gyro
    /// integrated over the interval, if known); returns the pair it ends, read out at
    /// `time_us`, or `None` for the first frame.
    pub fn push(
        &mut self,
        frame: Frame,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
        time_us: u64,
    ) -> Result<Option<SensorPair>, String> {
        if (frame.width, frame.height) != self.size {
            let (width, height) = self.size;
            return Err(format!(
                "frame is {}x{} but the flow sensor was made for {width}x{height}",
                frame.width, frame.height
            ));
        }
        let next = frame.view().map_err(|e| e.to_string())?;
        let Some(previous) = self.previous.take() else {
            self.sensor
                .start(next)
                .map_err(|e| format!("flow sensor: {e}"))?;
            self.previous = Some(frame);
            return Ok(None);
        };
        let prev = previous.view().map_err(|e| e.to_string())?;
        let step = self.sensor.process(prev, next, interval_us, gyro);
        let step = match step {
            Ok(step) => step,
            Err(e) => {
                // The sensor keeps the frame it saw last.
                self.previous = Some(previous);
                return Err(format!("flow sensor: {e}"));
            }
        };
        self.previous = Some(frame);
        let reading = self.sensor.readout(time_us);
        let flow = self.sensor.optical_flow(&reading);
        let pair = PairMotion {
            motion: step.motion,
            corners: step.report.live,
            tracked: self.sensor.pairs().0.len(),
        };
        Ok(Some(SensorPair {
            pair,
            step,
            reading,
            flow,
        }))
    }
}
