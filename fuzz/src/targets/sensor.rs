//! The flow sensor (`kestrel::sensor::FlowSensor`) fed an arbitrary sequence of frames,
//! intervals, gyro readings (NaN, infinite, too fast), refusals and readouts, with arbitrary
//! camera and fit settings over the flow-sensor preset's tracker.
//!
//! The sensor must refuse exactly what it documents (a camera or fit the library rejects, a
//! frame of another size, a frame that is not the previous one, `process` before `start`), and
//! after every frame pair hold one correspondence per track followed, inside the frame; every
//! reading must be finite, and its quality 0 whenever a frame since the last readout was
//! refused or spoilt the integration.

use super::picture::{Change, Frame, FrameInput, Picture};
use arbitrary::Arbitrary;
use kestrel::detect::Corner;
use kestrel::ego::{Camera, CameraParams, EgoStatus, ModelKind, Ransac, RansacParams};
use kestrel::lk::scratch_len;
use kestrel::sensor::{FlowSensor, FlowSensorConfig, FlowSensorError};
use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig, TrackerError};
use kestrel::{ConfigError, Q16};

/// The sensor's capacity: the preset's 25 tracks.
const N: usize = 25;
/// Steps per input.
const MAX_STEPS: usize = 14;

#[derive(Arbitrary, Debug)]
struct Input {
    width: u8,
    height: u8,
    camera: CameraInput,
    model: u8,
    threshold: f32,
    scene: Picture,
    steps: Vec<Step>,
}

#[derive(Arbitrary, Debug)]
enum CameraInput {
    /// A camera of the frame's size with a field of view of `degrees` (any, 0 and 180
    /// included).
    FieldOfView(u8),
    /// Any parameters, NaN and nonsense included.
    Raw(f32, f32, f32, f32, f32, f32),
}

#[derive(Arbitrary, Debug)]
enum Step {
    Start(FrameInput),
    Process {
        wrong_prev: Option<FrameInput>,
        next: FrameInput,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
    },
    Refuse(u32),
    Readout(u32),
}

/// The decoded input, for reading a crash.
pub fn show(data: &[u8]) -> String {
    super::show::<Input>(data)
}

pub fn run(data: &[u8]) {
    let Some(input) = super::decode::<Input>(data) else {
        return;
    };
    let (w, h) = (
        usize::from(input.width % 64) + 1,
        usize::from(input.height % 64) + 1,
    );
    let preset = TrackerConfig::flow_sensor();
    let mut storage = vec![0u8; tracker_storage_len(w, h, preset.pyramid_levels())];
    let mut lk_scratch = vec![0i16; scratch_len(preset.lk.window)];
    let mut corners = vec![Corner::default(); 3 * N];
    let buffers = TrackerBuffers {
        storage: &mut storage,
        lk_scratch: &mut lk_scratch,
        detect_scratch: &mut [],
        candidates: &mut corners,
    };
    let camera = match input.camera {
        CameraInput::FieldOfView(degrees) => {
            let fov = f32::from(degrees).to_radians();
            CameraParams::from_horizontal_fov(w as u16, h as u16, fov)
        }
        CameraInput::Raw(focal_x, focal_y, principal_x, principal_y, k1, k2) => CameraParams {
            focal_x,
            focal_y,
            principal_x,
            principal_y,
            k1,
            k2,
        },
    };
    let model = match input.model % 4 {
        0 => ModelKind::Translation,
        1 => ModelKind::Similarity,
        2 => ModelKind::Affine,
        _ => ModelKind::Homography,
    };
    let mut config = FlowSensorConfig::new(camera);
    config.ransac = RansacParams {
        model,
        threshold: input.threshold,
        ..config.ransac
    };
    let sensor = match FlowSensor::<N>::new(config, w, h, buffers) {
        Ok(sensor) => sensor,
        Err(e) => {
            // Refused for its camera or its fit only, exactly when the library rejects them,
            // and named by the setting's path in the configuration.
            let part = |field: &str| ConfigError {
                field: e.field.strip_prefix(field).unwrap_or("not this part"),
                ..e
            };
            match e.field.split('.').next() {
                Some("camera") => assert_eq!(Camera::new(camera).err(), Some(part("camera."))),
                Some("ransac") => {
                    assert_eq!(Ransac::new(config.ransac).err(), Some(part("ransac.")))
                }
                _ => panic!("the preset's tracker was refused: {e:?}"),
            }
            return;
        }
    };
    assert!(Camera::new(camera).is_ok() && Ransac::new(config.ransac).is_ok());
    let mut model = Model {
        sensor,
        input: &input,
        size: (w, h),
        last: None,
        spoilt: false,
    };
    for step in input.steps.iter().take(MAX_STEPS) {
        model.step(step);
    }
}

/// The sensor, and what a caller knows about it.
struct Model<'s, 'i> {
    sensor: FlowSensor<'s, N>,
    input: &'i Input,
    size: (usize, usize),
    /// The frame given last.
    last: Option<Frame>,
    /// True when a frame since the last readout was refused or spoilt the integration.
    spoilt: bool,
}

impl Model<'_, '_> {
    fn frame(&self, f: &FrameInput) -> Frame {
        f.render(&self.input.scene, self.size)
    }

    fn step(&mut self, step: &Step) {
        match step {
            Step::Start(f) => {
                let next = self.frame(f);
                let Some(view) = next.view() else {
                    return;
                };
                let size_ok = (next.width, next.height) == self.size;
                match self.sensor.start(view) {
                    Ok(report) => {
                        assert!(size_ok, "a frame of another size was started on");
                        assert!(report.live <= N);
                        self.last = Some(next);
                    }
                    Err(e) => {
                        assert!(!size_ok, "a frame of the sensor's size was refused: {e:?}");
                        assert_eq!(e, FlowSensorError::Tracker(TrackerError::FrameSizeMismatch));
                    }
                }
            }
            Step::Process {
                wrong_prev,
                next,
                interval_us,
                gyro,
            } => self.process(wrong_prev.as_ref(), next, *interval_us, *gyro),
            Step::Refuse(interval_us) => {
                self.sensor.refuse(*interval_us);
                self.spoilt = true;
            }
            Step::Readout(time) => self.readout(u64::from(*time)),
        }
    }

    fn process(
        &mut self,
        wrong_prev: Option<&FrameInput>,
        next: &FrameInput,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
    ) {
        let prev = match (wrong_prev, &self.last) {
            (Some(f), _) => self.frame(f),
            (None, Some(last)) => last.clone(),
            (None, None) => self.frame(&FrameInput::Scene(Change::default())),
        };
        let next_frame = self.frame(next);
        let (Some(prev_view), Some(next_view)) = (prev.view(), next_frame.view()) else {
            return;
        };
        let before = self.sensor.tracks().to_vec();
        let is_last = self.last.as_ref().is_some_and(|l| l.pixels == prev.pixels);
        let size_ok = (next_frame.width, next_frame.height) == self.size;
        let step = match self.sensor.process(prev_view, next_view, interval_us, gyro) {
            Ok(step) => step,
            Err(e) => {
                assert!(
                    !(is_last && size_ok),
                    "the previous frame and one of the right size were refused: {e:?}"
                );
                assert!(matches!(e, FlowSensorError::Tracker(_)), "{e:?}");
                assert_eq!(
                    self.sensor.tracks(),
                    before,
                    "a refused frame changed tracks"
                );
                self.spoilt = true;
                return;
            }
        };
        assert!(
            size_ok && self.last.is_some(),
            "a frame the tracker must refuse was taken"
        );
        self.last = Some(next_frame);
        if step.integrated != EgoStatus::Ok {
            self.spoilt = true;
        }
        let (pairs, inliers) = self.sensor.pairs();
        assert_eq!(pairs.len(), step.report.tracked, "{:?}", step.report);
        assert_eq!(inliers.len(), pairs.len());
        assert!(pairs.len() <= self.sensor.tracks().len());
        let (w, h) = self.size;
        let inside = |v: Q16, size: usize| v >= Q16::ZERO && v <= Q16::from_num(size - 1);
        for (before, now) in pairs {
            assert!(inside(now.x, w) && inside(now.y, h), "{now:?}");
            assert!(inside(before.x, w) && inside(before.y, h), "{before:?}");
        }
        if step.motion.is_ok() {
            assert!(step.motion.inliers as usize <= pairs.len());
            assert!(step.motion.rms_residual.is_finite());
        }
    }

    fn readout(&mut self, time: u64) {
        let reading = self.sensor.readout(time);
        assert!(reading.integrated_x.is_finite() && reading.integrated_y.is_finite());
        if self.spoilt {
            assert_eq!(
                reading.quality, 0,
                "a spoilt integration read out {reading:?}"
            );
        }
        if reading.quality == 0 {
            assert_eq!((reading.integrated_x, reading.integrated_y), (0.0, 0.0));
        }
        let flow = self.sensor.optical_flow(&reading);
        assert!(flow.flow_comp_m_x.is_finite() && flow.flow_comp_m_y.is_finite());
        assert!(flow.flow_rate_x.is_finite() && flow.flow_rate_y.is_finite());
        self.spoilt = false;
    }
}
