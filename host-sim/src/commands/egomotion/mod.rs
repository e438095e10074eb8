//! `host-sim egomotion`: the camera's motion between consecutive frames, and the autopilot's
//! MAVLink stream.
//!
//! Each frame pair gets one row of `ego.csv` and, with `--mavlink`, one OPTICAL_FLOW_RAD and one
//! OPTICAL_FLOW message (see [`crate::egomotion::MavlinkLink`]): the flow accumulator is read out
//! after every pair, so each message integrates exactly one frame interval. A pair whose fit fails gets the identity homography, zero inliers and quality 0
//! (the library's convention: no motion is claimed), never a stale model.
//!
//! The command's parts live beside it: the per-pair estimator (estimator.rs, with the
//! defaults), gyro logs (gyro.rs), the frame clock (clock.rs) and the MAVLink link (link.rs).

mod clock;
mod estimator;
mod gyro;
mod link;
mod sensor;

pub use clock::{FrameClock, Pacer};
pub use estimator::{
    EstimatorSettings, MotionEstimator, PairMotion, DEFAULT_MAX_POINTS, DEFAULT_THRESHOLD,
};
pub use gyro::{GyroLog, GyroSample, GYRO_COLUMNS};
pub use link::{MavlinkDestination, MavlinkLink, SendFailures};
pub use sensor::{PresetSensor, SensorPair, SensorSettings};

use std::ffi::OsString;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use kestrel::ego::{EgoStatus, FlowRadAccumulator, OpticalFlow, OpticalFlowRad, Rotation};

use kestrel::ego::ModelKind;
use kestrel::ego::FOCAL_RANGE;

use super::motion::{input, INPUT_HELP};
use super::CommandError;
use crate::cli::values::{self, path};
use crate::io::csv::CsvWriter;
use crate::io::json::one_line;
use crate::io::{AtomicFile, FrameSource, Progress};
use crate::tracking::{preset, HostBuffers, LkSettings, Preset};
use crate::Frame;
use serde_json::json;

/// Columns of ego.csv: the contract's twelve, then the extras.
pub const COLUMNS: [&str; 17] = [
    "frame",
    "h11",
    "h12",
    "h13",
    "h21",
    "h22",
    "h23",
    "h31",
    "h32",
    "h33",
    "inliers",
    "quality",
    "tracked",
    "rms",
    "integrated_x",
    "integrated_y",
    "status",
];

/// `host-sim egomotion`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "camera motion between consecutive frames, and OPTICAL_FLOW_RAD for autopilots",
    before_help = "host-sim egomotion: the camera's motion between consecutive frames, and the autopilot's
MAVLink stream.

Per frame pair: Shi-Tomasi corners in the earlier frame, spread by a grid; the library's Q16
pyramidal Lucas-Kanade to the later frame (seeded by the gyro's prediction with --gyro); the
motion model fitted by RANSAC; the OPTICAL_FLOW_RAD reading of the pair's interval.",
    after_help = "ego.csv columns:
  frame            the later frame of the pair (1, 2, ...)
  h11..h33         the homography from pixels of frame-1 to pixels of frame, row-major,
                   h33 = 1; the identity when the fit failed
  inliers          tracked points within --threshold of the model (0 when the fit failed)
  quality          0..255 as in OPTICAL_FLOW_RAD: 0 when the fit failed or the gyro reading
                   was unusable (then the fitted homography is still given)
  tracked          points tracked from frame-1 to frame, fitted by RANSAC
  rms              RMS inlier residual, px
  integrated_x,y   OPTICAL_FLOW_RAD angular flow over the interval, rad (0 when quality is 0)
  status           ok, too_few_tracks, degenerate, no_consensus, bad_input or bad_gyro

Coordinates are pixels from the centre of the top-left pixel, x right, y down. A bad frame
stops the run; the rows (and MAVLink frames) of the pairs before it are kept. Progress is
shown on stderr when it is a terminal.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line."
)]
pub struct EgomotionOptions {
    #[arg(value_name = "INPUT", value_parser = input, help = INPUT_HELP)]
    pub input: OsString,
    /// results, one row per frame pair (see below)
    #[arg(long, value_name = "ego.csv", value_parser = path)]
    pub out: PathBuf,
    /// translation, similarity, affine or homography [default: homography; with --preset
    /// flow-sensor, the sensor's similarity]
    #[arg(long, value_name = "M", value_parser = model)]
    pub model: Option<ModelKind>,
    /// focal length in px, 1 to 100000 [default: that of a 60 degree horizontal field of view;
    /// the principal point is the frame centre]
    #[arg(long, value_name = "PX", value_parser = focal)]
    pub focal: Option<f32>,
    /// gyro log: columns t_us,gx,gy,gz; time in microseconds on the frames' clock (frame k at
    /// k / fps s), body rates in rad/s about the sensor axes (X to the top of the image, Y to
    /// its right, Z along the optical axis), linear between samples. Intervals the log does not
    /// cover have no gyro reading.
    #[arg(long, value_name = "G.csv", value_parser = path)]
    pub gyro: Option<PathBuf>,
    /// MAVLink 2 stream: per frame pair OPTICAL_FLOW_RAD (id 106, read by PX4) and
    /// OPTICAL_FLOW (id 100, read by ArduPilot), after a HEARTBEAT at each new second of the
    /// frame clock; system 1, component 100, one sequence from 0. DEST is a file (raw bytes,
    /// back to back) or udp:HOST:PORT (datagrams to a listener, like MAVProxy's or
    /// QGroundControl's udpout; a listener that is missing or stops costs nothing, failed sends
    /// are counted on stderr at the end)
    #[arg(long, value_name = "DEST", value_parser = mavlink)]
    pub mavlink: Option<MavlinkDestination>,
    /// pace the replay in real time at HZ frame pairs per second, 0.1 to 10000 [default: as
    /// fast as it can]
    #[arg(long, value_name = "HZ", value_parser = rate)]
    pub rate: Option<f64>,
    /// frame rate, 1 to 10000 [default: the y4m header's or the video's, else 30]
    #[arg(long, value_name = "F", value_parser = fps)]
    pub fps: Option<f64>,
    /// points tracked per pair, 8 to 2000 [default: 200; 25 with --preset]
    #[arg(long, value_name = "N", value_parser = max_points)]
    pub max_points: Option<usize>,
    /// flow-sensor: the library's flow sensor (kestrel::sensor::FlowSensor), the pipeline the
    /// firmware runs: TrackerConfig::flow_sensor()'s tracker (25 tracks kept from frame to
    /// frame; 7x7 windows on two levels of a box-mean pyramid, nearest-pixel templates, 10
    /// iterations) and a similarity fit of its tracks; --max-points, --window, --levels,
    /// --model and --threshold given beside it override it [default: none: corners detected
    /// afresh in every pair, OpenCV's LK settings]
    #[arg(long, value_name = "NAME", value_parser = preset)]
    pub preset: Option<Preset>,
    #[command(flatten)]
    pub lk: LkSettings,
    /// RANSAC inlier threshold, 0.05 to 100 px; raise it for blurred or noisy video [default:
    /// 0.5; with --preset flow-sensor, the sensor's 1]
    #[arg(long, value_name = "PX", value_parser = threshold)]
    pub threshold: Option<f32>,
    /// write {"frames", "pairs", "mean_tracked_points", "median_pair_seconds",
    /// "mean_pair_seconds"}; per pair the new frame's pyramid, detection, tracking and the fit
    /// are timed, decoding is not
    #[arg(long, value_name = "S.json", value_parser = path)]
    pub stats: Option<PathBuf>,
}

impl EgomotionOptions {
    /// How motion is measured: the preset's LK and pyramid when given, the flags over them.
    pub fn settings(&self) -> EstimatorSettings {
        let mut settings = EstimatorSettings {
            model: self.model.unwrap_or(ModelKind::Homography),
            focal: self.focal,
            threshold: self.threshold.unwrap_or(DEFAULT_THRESHOLD),
            max_points: self.max_points.unwrap_or(DEFAULT_MAX_POINTS),
            ..EstimatorSettings::default()
        };
        if let Some(preset) = self.preset {
            let config = preset.config(None);
            settings.lk = config.lk;
            settings.pyramid = config.pyramid;
            settings.max_points = self.max_points.unwrap_or(config.max_tracks);
        }
        settings.lk = self.lk.apply(settings.lk);
        settings
    }

    /// The flow sensor's settings with `--preset`, the flags over them.
    pub fn sensor_settings(&self) -> Option<SensorSettings> {
        let preset = SensorSettings::new(self.preset?, self.max_points, &self.lk);
        Some(SensorSettings {
            model: self.model,
            threshold: self.threshold.unwrap_or(preset.threshold),
            focal: self.focal,
            ..preset
        })
    }
}

fn focal(text: &str) -> Result<f32, String> {
    let range = |f: f64| FOCAL_RANGE.contains(&(f as f32)) && f.is_finite();
    let says = "must be a focal length between 1 and 100000 px";
    values::number(text, range, says).map(|f| f as f32)
}

/// `--fps`, shared with `synth-sequence`.
pub fn fps(text: &str) -> Result<f64, String> {
    let range = |f| (1.0..=10_000.0).contains(&f);
    values::number(text, range, "must be between 1 and 10000 frames per second")
}

fn rate(text: &str) -> Result<f64, String> {
    let range = |r| (0.1..=10_000.0).contains(&r);
    values::number(
        text,
        range,
        "must be between 0.1 and 10000 frame pairs per second",
    )
}

/// `--threshold`, shared with `stabilize`.
pub fn threshold(text: &str) -> Result<f32, String> {
    let range = |t| (0.05..=100.0).contains(&t);
    values::number(text, range, "must be between 0.05 and 100 px").map(|t| t as f32)
}

/// `--max-points`, shared with `stabilize`.
pub fn max_points(text: &str) -> Result<usize, String> {
    let range = |n| (8..=2000).contains(&n);
    values::whole(text, range, "must be between 8 and 2000").map(|n| n as usize)
}

/// `--model`, shared with `stabilize`.
pub fn model(text: &str) -> Result<ModelKind, String> {
    match text {
        "translation" => Ok(ModelKind::Translation),
        "similarity" => Ok(ModelKind::Similarity),
        "affine" => Ok(ModelKind::Affine),
        "homography" => Ok(ModelKind::Homography),
        _ => Err(format!(
            "must be translation, similarity, affine or homography (got \"{text}\")"
        )),
    }
}

/// `--mavlink`: a file path, or `udp:HOST:PORT`.
fn mavlink(text: &str) -> Result<MavlinkDestination, String> {
    match text.is_empty() {
        true => Err("must not be empty".into()),
        false => MavlinkDestination::parse(text.as_ref()),
    }
}

/// The outcome of one frame pair, as written to ego.csv and the MAVLink stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairReport {
    /// The later frame of the pair (1, 2, ...).
    pub frame: usize,
    /// The measured motion.
    pub pair: PairMotion,
    /// The autopilot reading for the pair's interval.
    pub reading: OpticalFlowRad,
    /// The same reading as OPTICAL_FLOW.
    pub flow: OpticalFlow,
    /// When the pair's later frame was taken, microseconds on the frame clock.
    pub time_us: u64,
    /// Why the reading is unusable, or `Ok`.
    pub status: PairStatus,
}

/// Whether a pair's reading is usable, and why not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairStatus {
    /// The accumulator's verdict: `Ok`, the fit's failure, or `Degenerate` for a motion that
    /// has no image of the principal point.
    Flow(EgoStatus),
    /// The gyro reading over the interval was NaN, infinite or beyond the library's range.
    BadGyro,
}

impl PairStatus {
    /// The name in ego.csv's `status` column.
    pub fn name(self) -> &'static str {
        match self {
            PairStatus::Flow(EgoStatus::Ok) => "ok",
            PairStatus::Flow(EgoStatus::TooFewTracks) => "too_few_tracks",
            PairStatus::Flow(EgoStatus::Degenerate) => "degenerate",
            PairStatus::Flow(EgoStatus::NoConsensus) => "no_consensus",
            PairStatus::Flow(EgoStatus::BadInput) => "bad_input",
            PairStatus::BadGyro => "bad_gyro",
        }
    }
}

/// Runs `egomotion`. Outputs are created before any work, so an unwritable path fails fast. A
/// bad frame stops the run: the pairs before it are kept (committed), then the error is
/// reported; an error before the first frame writes nothing.
pub fn run(options: &EgomotionOptions) -> Result<(), CommandError> {
    let mut outputs = Outputs::create(options)?;
    let gyro = options.gyro.as_deref().map(GyroLog::read).transpose()?;
    let source = FrameSource::open(&options.input)?;
    let fps = options
        .fps
        .or(source.frame_rate())
        .unwrap_or(FrameClock::DEFAULT_FPS);
    let frame_count = source.frame_count();
    let mut frames = source.enumerate().peekable();
    // The flow sensor's buffers are the caller's, sized by the first frame.
    let first_size = match frames.peek() {
        Some((_, Ok(frame))) => Some((frame.width, frame.height)),
        _ => None,
    };
    let sensor_settings = options.sensor_settings();
    let mut buffers = sensor_settings
        .zip(first_size)
        .map(|(settings, (w, h))| HostBuffers::new(&settings.tracker, w, h));
    let engine = match (sensor_settings, first_size, buffers.as_mut()) {
        (Some(settings), Some((w, h)), Some(buffers)) => {
            let sensor = PresetSensor::new(&settings, w, h, buffers)
                .map_err(|problem| CommandError::Processing(format!("frame 0: {problem}")))?;
            Engine::Sensor(sensor)
        }
        _ => Engine::Pairwise(None),
    };
    let mut run = SequenceRun::new(options, FrameClock::new(fps), gyro, engine);
    let mut progress = Progress::new("egomotion", frame_count);
    let pacer = options.rate.map(Pacer::new);
    let mut failure = None;
    for (index, frame) in frames {
        if let Some(pacer) = &pacer {
            pacer.wait(index);
        }
        let step = frame
            .map_err(CommandError::from)
            .and_then(|frame| run.push(index, frame))
            .and_then(|report| match report {
                Some(report) => outputs.write(&report),
                None => Ok(()),
            });
        if let Err(error) = step {
            failure = Some(error);
            break;
        }
        progress.update(index + 1);
    }
    progress.finish();
    if run.frames == 0 {
        // Nothing was read: there are no results to keep.
        return Err(failure.unwrap_or_else(|| CommandError::Processing("no frames".into())));
    }
    outputs.finish(&run)?;
    failure.map_or(Ok(()), Err)
}

/// What measures the motion of each frame pair.
enum Engine<'m> {
    /// Corners detected afresh in every pair, made for the first frame's size (the default).
    Pairwise(Option<Box<(MotionEstimator, FlowRadAccumulator)>>),
    /// The library's flow sensor (`--preset`): the firmware's pipeline.
    Sensor(PresetSensor<'m>),
}

/// The state carried from frame to frame.
struct SequenceRun<'m> {
    settings: EstimatorSettings,
    clock: FrameClock,
    gyro: Option<GyroLog>,
    engine: Engine<'m>,
    frames: usize,
    pair_seconds: Vec<f64>,
    tracked_total: usize,
}

impl<'m> SequenceRun<'m> {
    fn new(
        options: &EgomotionOptions,
        clock: FrameClock,
        gyro: Option<GyroLog>,
        engine: Engine<'m>,
    ) -> Self {
        Self {
            settings: options.settings(),
            clock,
            gyro,
            engine,
            frames: 0,
            pair_seconds: Vec::new(),
            tracked_total: 0,
        }
    }

    /// Takes frame `index`; returns the report of the pair it ends, if any.
    fn push(&mut self, index: usize, frame: Frame) -> Result<Option<PairReport>, CommandError> {
        let failed =
            |problem: String| CommandError::Processing(format!("frame {index}: {problem}"));
        let gyro = (index > 0).then(|| self.gyro_over(index)).flatten();
        let interval_us = self.clock.interval_us(index);
        let rotation = gyro.and_then(|g| Rotation::from_integrated_gyro(g, interval_us).ok());
        let time_us = self.clock.time_us(index);
        let start = Instant::now();
        let (pair, reading, flow, flow_status) = match &mut self.engine {
            Engine::Sensor(sensor) => {
                self.frames += 1;
                let Some(done) = sensor
                    .push(frame, interval_us, gyro, time_us)
                    .map_err(failed)?
                else {
                    return Ok(None);
                };
                self.pair_seconds.push(start.elapsed().as_secs_f64());
                (done.pair, done.reading, done.flow, done.step.integrated)
            }
            Engine::Pairwise(state) => {
                let (estimator, accumulator) = match state {
                    Some(state) => &mut **state,
                    None => {
                        let estimator =
                            MotionEstimator::new(&self.settings, frame.width, frame.height)
                                .map_err(failed)?;
                        let accumulator = FlowRadAccumulator::new(*estimator.camera(), 0);
                        &mut **state.insert(Box::new((estimator, accumulator)))
                    }
                };
                self.frames += 1;
                let Some(pair) = estimator.push(frame, rotation.as_ref()).map_err(failed)? else {
                    return Ok(None);
                };
                self.pair_seconds.push(start.elapsed().as_secs_f64());
                let flow_status = accumulator.add(&pair.motion, interval_us, gyro);
                let reading = accumulator.readout(time_us);
                let flow = accumulator.optical_flow(&reading);
                (pair, reading, flow, flow_status)
            }
        };
        self.tracked_total += pair.tracked;
        let status = match (gyro, rotation) {
            (Some(_), None) => PairStatus::BadGyro,
            _ => PairStatus::Flow(flow_status),
        };
        Ok(Some(PairReport {
            frame: index,
            pair,
            reading,
            flow,
            time_us,
            status,
        }))
    }

    /// The gyro integrated over the interval that ends at frame `index`, when the log covers it.
    fn gyro_over(&self, index: usize) -> Option<[f32; 3]> {
        let log = self.gyro.as_ref()?;
        let t0 = self.clock.time_us(index - 1) as f64;
        let t1 = self.clock.time_us(index) as f64;
        log.integrate(t0, t1).map(|v| v.map(|a| a as f32))
    }
}

/// The output files, open from the start.
struct Outputs {
    csv: CsvWriter<AtomicFile>,
    mavlink: Option<MavlinkLink>,
    stats: Option<AtomicFile>,
}

impl Outputs {
    fn create(options: &EgomotionOptions) -> Result<Self, CommandError> {
        let out = AtomicFile::create(&options.out)?;
        let mavlink = options
            .mavlink
            .as_ref()
            .map(MavlinkLink::open)
            .transpose()?;
        let stats = options
            .stats
            .as_deref()
            .map(AtomicFile::create)
            .transpose()?;
        let header_error = |e: std::io::Error| CommandError::from(out_error(&options.out, &e));
        let csv = CsvWriter::new(out, &COLUMNS).map_err(header_error)?;
        Ok(Self {
            csv,
            mavlink,
            stats,
        })
    }

    fn write(&mut self, report: &PairReport) -> Result<(), CommandError> {
        write_row(&mut self.csv, report).map_err(|e| self.csv_error(&e))?;
        if let Some(mavlink) = &mut self.mavlink {
            mavlink.send(report.time_us, &report.reading, &report.flow)?;
        }
        Ok(())
    }

    fn csv_error(&mut self, error: &std::io::Error) -> CommandError {
        CommandError::Output(self.csv.get_ref().write_error(error))
    }

    /// Writes the timing summary and commits every file.
    fn finish(self, run: &SequenceRun<'_>) -> Result<(), CommandError> {
        if let Some(mut stats) = self.stats {
            let summary = timing_summary(run);
            stats
                .write_all(summary.as_bytes())
                .map_err(|e| stats.write_error(&e))?;
            stats.commit()?;
        }
        let undelivered = self.mavlink.map(MavlinkLink::finish).transpose()?.flatten();
        let target = self.csv.get_ref().target().to_owned();
        let csv_error = |e: std::io::Error| CommandError::from(out_error(&target, &e));
        self.csv.finish().map_err(csv_error)?.commit()?;
        if let Some((link, failures)) = undelivered {
            report_send_failures(&link, &failures);
        }
        Ok(())
    }
}

fn out_error(path: &std::path::Path, error: &std::io::Error) -> crate::io::OutputError {
    crate::io::OutputError::new(
        path,
        format!("cannot write: {}", crate::io::describe_io_error(error)),
    )
}

/// `{"frames": n, "pairs": p, "mean_tracked_points": t, "median_pair_seconds": s,
/// "mean_pair_seconds": m}`: per pair, the core is building the new frame's pyramid, detecting
/// in the previous frame, tracking and fitting; decoding and writing are not timed.
fn timing_summary(run: &SequenceRun<'_>) -> String {
    let pairs = run.pair_seconds.len();
    let mut seconds = run.pair_seconds.clone();
    seconds.sort_by(f64::total_cmp);
    let median = match pairs {
        0 => 0.0,
        n if n % 2 == 1 => seconds[n / 2],
        n => (seconds[n / 2 - 1] + seconds[n / 2]) / 2.0,
    };
    let mean = |total: f64| {
        if pairs == 0 {
            0.0
        } else {
            total / pairs as f64
        }
    };
    one_line(&json!({
        "frames": run.frames,
        "pairs": pairs,
        "mean_tracked_points": mean(run.tracked_total as f64),
        "median_pair_seconds": median,
        "mean_pair_seconds": mean(seconds.iter().sum()),
    }))
}

/// One ego.csv row. Matrix entries are printed in full (the shortest text that reads back as
/// the same `f32`), so scripts see exactly what the library computed.
fn write_row(csv: &mut CsvWriter<AtomicFile>, report: &PairReport) -> std::io::Result<()> {
    let m = report.pair.motion.model.matrix();
    let r = &report.reading;
    csv.record((
        report.frame,
        m,
        report.pair.motion.inliers,
        r.quality,
        report.pair.tracked,
        report.pair.motion.rms_residual,
        r.integrated_x,
        r.integrated_y,
        report.status.name(),
    ))
}

/// One stderr line for the datagrams a UDP link could not send: never an error, a listener
/// may come and go.
fn report_send_failures(link: &str, failures: &SendFailures) {
    eprintln!(
        "host-sim: {link}: {} of {} MAVLink datagrams could not be sent (last: {})",
        failures.failed,
        failures.attempted,
        failures.last.as_deref().unwrap_or("unknown")
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_names_are_snake_case() {
        assert_eq!(PairStatus::Flow(EgoStatus::Ok).name(), "ok");
        assert_eq!(
            PairStatus::Flow(EgoStatus::NoConsensus).name(),
            "no_consensus"
        );
        assert_eq!(PairStatus::BadGyro.name(), "bad_gyro");
    }

    #[test]
    fn the_contract_columns_come_first() {
        let contract = "frame,h11,h12,h13,h21,h22,h23,h31,h32,h33,inliers,quality";
        assert!(COLUMNS.join(",").starts_with(contract));
    }
}
