//! The flow-sensor preset (`TrackerConfig::flow_sensor`) as a flow sensor runs it: per frame the
//! tracker (pyramid, tracking, refill), a similarity fit of the camera's motion and its
//! OPTICAL_FLOW_RAD reading with the MAVLink frame, all timed as one, over the same frames as the
//! budget run and with the same bad input. Its budget is 420,000 instructions a frame (400 Hz at
//! 168 MHz); its flow must be within 0.05 px of the scene's motion at the principal point.
//!
//! Every readout goes out on the autopilot link ([`Link`]), timed apart from the frame. After
//! the checked sequence the sensor keeps flying the frames back and forth (the motion reverses
//! at each end) until [`LINK_SECONDS`] of frame clock have passed, so the stream carries a
//! heartbeat every second; those frames are sent, not checked here (`bench/mavlink_link.sh`
//! checks every message on the host).

use core::fmt::Write;

use cortex_m_semihosting::hprintln;
use heapless::String;
use kestrel::ego::mavlink::MAX_FRAME_LEN;
use kestrel::ego::{CameraParams, OpticalFlow};
use kestrel::lk::scratch_len;
use kestrel::sensor::{FlowSensor, FlowSensorConfig, FlowSensorError, SensorStage};
use kestrel::track::{tracker_storage_len, TrackerConfig};
use kestrel::ConfigError;
use kestrel::ImageView;

use crate::bad_input;
use crate::camera;
use crate::checks::{flow_error, flow_tolerance, frame_quality};
use crate::ego::{fov_radians, Readout};
use crate::link::{Link, SendCost};
use crate::meter::{instructions, Meter, Stopwatch, Ticks};
use crate::pipeline::{FrameError, TrackerMemory};
use crate::report::Micro;
use crate::scene::{FRAMES, FRAME_INTERVAL_US, HEIGHT, WIDTH};

/// Frame clock the link runs for, microseconds: past the heartbeats at 0, 1 and 2 s.
pub const LINK_SECONDS_US: u64 = 2_050_000;
/// [`LINK_SECONDS_US`] for the docs.
pub const LINK_SECONDS: f32 = 2.05;

/// The preset's settings.
const CONFIG: TrackerConfig = TrackerConfig::flow_sensor();
/// Its tracks.
pub const TRACKS: usize = CONFIG.max_tracks;
/// Corner candidates of one detection: three per track.
const CANDIDATES: usize = 3 * TRACKS;
const STORAGE_LEN: usize = tracker_storage_len(WIDTH, HEIGHT, CONFIG.pyramid_levels());
const LK_SCRATCH_LEN: usize = scratch_len(CONFIG.lk.window);

/// The preset's buffers; FAST needs no detection scratch.
pub type SensorMemory = TrackerMemory<STORAGE_LEN, LK_SCRATCH_LEN, 0, CANDIDATES>;

/// The library's flow sensor over the scene's camera, and what the autopilot is sent.
struct Sensor<'m> {
    sensor: FlowSensor<'static, TRACKS>,
    previous: Option<ImageView<'static>>,
    readout: Readout,
    meter: &'m Meter,
    /// The latest frame's motion fit, reading and MAVLink frame.
    ego_instructions: u64,
}

impl<'m> Sensor<'m> {
    fn new(memory: &'static mut SensorMemory, meter: &'m Meter) -> Result<Self, ConfigError> {
        let camera = CameraParams::from_horizontal_fov(WIDTH as u16, HEIGHT as u16, fov_radians());
        let config = FlowSensorConfig::new(camera);
        Ok(Self {
            sensor: FlowSensor::new(config, WIDTH, HEIGHT, memory.buffers())?,
            previous: None,
            readout: Readout::default(),
            meter,
            ego_instructions: 0,
        })
    }

    /// One frame: tracked from the previous one, fitted and read out; a refused frame reads
    /// out with quality 0 and leaves the tracker as it was. True when the frame was tracked
    /// (not the first).
    fn frame(&mut self, pixels: &'static [u8], size: (usize, usize)) -> Result<bool, FrameError> {
        let outcome = self.track(pixels, size);
        if outcome != Ok(false) {
            let sensor = &mut self.sensor;
            let readout = &mut self.readout;
            let (kept, ticks) = self.meter.measure(|| {
                let reading = sensor.readout(readout.next_time());
                readout.keep(reading).map(|_| ())
            });
            kept.map_err(FrameError::Mavlink)?;
            self.ego_instructions += instructions(ticks);
        }
        outcome
    }

    fn track(&mut self, pixels: &'static [u8], (w, h): (usize, usize)) -> Result<bool, FrameError> {
        // The sensor refuses the frames it is given itself; one that is not a frame at all is
        // refused here, to the same effect.
        let next = match ImageView::packed(pixels, w, h) {
            Ok(next) => next,
            Err(e) => {
                self.sensor.refuse(FRAME_INTERVAL_US);
                return Err(FrameError::Image(e));
            }
        };
        let Some(prev) = self.previous else {
            self.sensor.start(next).map_err(frame_error)?;
            self.previous = Some(next);
            return Ok(false);
        };
        let mut watch = Stopwatch::start(self.meter);
        let mut fit = Ticks(0);
        let step = self
            .sensor
            .process_observed(prev, next, FRAME_INTERVAL_US, None, |stage| {
                let lap = watch.lap();
                if stage == SensorStage::Fit {
                    fit = lap;
                }
            });
        self.ego_instructions = instructions(fit);
        step.map_err(frame_error)?;
        self.previous = Some(next);
        Ok(true)
    }

    /// The latest reading as OPTICAL_FLOW.
    fn optical_flow(&self) -> OpticalFlow {
        self.sensor.optical_flow(&self.readout.reading)
    }

    fn focal_length(&self) -> f32 {
        self.sensor.camera().params().focal_x
    }
}

/// The library's refusal as the harness's: the same causes as the budget run's pipeline.
fn frame_error(e: FlowSensorError) -> FrameError {
    match e {
        FlowSensorError::Tracker(e) => FrameError::Track(e),
        FlowSensorError::Ransac(e) => FrameError::Ego(e),
    }
}

/// Sends the latest readout on `link`, timed into `cost`.
fn send(sensor: &Sensor<'_>, link: &mut Link, cost: &mut SendCost) {
    let (rad, _) = sensor.readout.latest();
    let flow = sensor.optical_flow();
    let ((), ticks) = sensor.meter.measure(|| link.send(rad, &flow));
    cost.add(instructions(ticks));
}

/// Prints the latest readout's OPTICAL_FLOW_RAD frame in hex: `tests/flow_sensor_firmware.rs`
/// runs the library's flow sensor on the same frames on the host and must get these bytes.
fn print_readout(sensor: &Sensor<'_>) {
    let (_, frame) = sensor.readout.latest();
    let mut hex: String<{ 2 * MAX_FRAME_LEN }> = String::new();
    for byte in frame {
        // Two digits per byte of at most MAX_FRAME_LEN: the string has room.
        let _ = write!(hex, "{byte:02x}");
    }
    hprintln!("sensor_readout {}", hex.as_str());
}

/// Runs the preset over the sequence with the budget run's bad input after frame 5, sending
/// every readout on `link`; prints a line per frame and a summary, then flies on for the link
/// ([`fly`]). False when its flow misses the scene's motion, a bad frame is not refused with
/// quality 0, or the preset cannot be made.
#[inline(never)]
pub fn run(meter: &Meter, memory: &'static mut SensorMemory, link: &mut Link) -> bool {
    let mut sensor = match Sensor::new(memory, meter) {
        Ok(s) => s,
        Err(e) => {
            hprintln!("error sensor preset refused: {:?}", e);
            return false;
        }
    };
    let focal = sensor.focal_length();
    let mut cost = SendCost::default();
    let (mut ok, mut total, mut worst, mut frames, mut worst_error) = (true, 0, 0, 0, 0.0f32);
    for index in 0..FRAMES {
        let (outcome, ticks) =
            meter.measure(|| sensor.frame(camera::frame(index), (WIDTH, HEIGHT)));
        let spent = instructions(ticks);
        if outcome != Ok(false) {
            send(&sensor, link, &mut cost);
            print_readout(&sensor);
        }
        match outcome {
            Ok(true) => {
                let (flow, _) = sensor.readout.latest();
                let error = flow_error(flow, focal);
                hprintln!(
                    "sensor_frame {} instructions={} ego={} tracks={} quality={} flow_error={}",
                    index,
                    spent,
                    sensor.ego_instructions,
                    sensor.sensor.tracks().len(),
                    flow.quality,
                    Micro(error)
                );
                ok &= error <= flow_tolerance(focal);
                worst_error = worst_error.max(error);
                total += spent;
                worst = worst.max(spent);
                frames += 1;
            }
            Ok(false) => hprintln!("sensor_prime instructions={}", spent),
            Err(e) => {
                hprintln!("error sensor frame {}: {:?}", index, e);
                ok = false;
            }
        }
        if index == 5 {
            ok &= refuses_bad_input(&mut sensor, camera::frame(6), link, &mut cost);
        }
    }
    let mean = total / frames.max(1);
    hprintln!(
        "sensor instructions_per_frame={} worst={} frames={} flow_error_px={} tracks={}",
        mean,
        worst,
        frames,
        Micro(worst_error * focal),
        sensor.sensor.tracks().len()
    );
    fly(&mut sensor, link, &mut cost);
    ok
}

/// Flies the frames back and forth after the sequence, sending every readout, until
/// [`LINK_SECONDS_US`] of frame clock have passed; prints the link's record.
fn fly(sensor: &mut Sensor<'_>, link: &mut Link, cost: &mut SendCost) {
    let mut clock = sensor.readout.latest().0.time_usec;
    let mut position = FRAMES;
    let mut errors = 0u32;
    while clock < LINK_SECONDS_US {
        // 0, 1, ..., 11, 10, ..., 1, 0, 1, ...: every pair one step of the scene's motion.
        let period = 2 * (FRAMES - 1);
        let phase = position % period;
        let index = if phase < FRAMES {
            phase
        } else {
            period - phase
        };
        if sensor.frame(camera::frame(index), (WIDTH, HEIGHT)).is_err() {
            errors += 1;
        }
        send(sensor, link, cost);
        clock = sensor.readout.latest().0.time_usec;
        position += 1;
    }
    link.pump();
    let counts = link.counts();
    hprintln!(
        "link heartbeats={} optical_flow_rad={} optical_flow={} invalid={} dropped={} bytes={} \
         pending={} readouts={} instructions_per_frame={} worst={} seconds={} frame_us={} \
         flight_errors={}",
        counts.heartbeats,
        counts.flow_rad,
        counts.flow,
        counts.invalid,
        counts.dropped,
        counts.bytes,
        link.pending(),
        cost.readouts,
        cost.mean(),
        cost.worst,
        LINK_SECONDS,
        FRAME_INTERVAL_US,
        errors
    );
}

/// The budget run's bad frames ([`bad_input::cases`]): each an error value with a reading of
/// quality 0.
fn refuses_bad_input(
    sensor: &mut Sensor<'_>,
    good: &'static [u8],
    link: &mut Link,
    cost: &mut SendCost,
) -> bool {
    let mut ok = true;
    for case in bad_input::cases(good) {
        let outcome = sensor.frame(case.pixels, case.size).map(|_| ());
        send(sensor, link, cost);
        print_readout(sensor);
        let (flow, mavlink) = sensor.readout.latest();
        let refused =
            outcome == Err(case.expected) && flow.quality == 0 && frame_quality(mavlink) == 0;
        hprintln!(
            "sensor_bad_input case={} outcome={:?} quality={} mavlink_quality={}",
            case.name,
            outcome,
            flow.quality,
            frame_quality(mavlink)
        );
        ok &= refused;
    }
    ok
}
