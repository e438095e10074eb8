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

use cortex_m_semihosting::hprintln;
use kestrel::ego::ModelKind;
use kestrel::frame::ImageView;
use kestrel::lk::scratch_len;
use kestrel::track::{tracker_storage_len, Tracker, TrackerConfig};

use crate::bad_input;
use crate::camera;
use crate::checks::{flow_error, flow_tolerance, frame_quality};
use crate::ego::Ego;
use crate::link::{Link, SendCost};
use crate::meter::{instructions, Meter};
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

/// The flow sensor: the preset's tracker and its motion fit.
struct Sensor<'m> {
    tracker: Tracker<'static, TRACKS>,
    ego: Ego,
    previous: Option<ImageView<'static>>,
    meter: &'m Meter,
    /// The latest frame's motion fit, reading and MAVLink frame.
    ego_instructions: u64,
}

impl<'m> Sensor<'m> {
    fn new(memory: &'static mut SensorMemory, meter: &'m Meter) -> Result<Self, FrameError> {
        let tracker =
            Tracker::new(CONFIG, WIDTH, HEIGHT, memory.buffers()).map_err(FrameError::Track)?;
        Ok(Self {
            tracker,
            ego: Ego::new(ModelKind::Similarity)?,
            previous: None,
            meter,
            ego_instructions: 0,
        })
    }

    /// One frame: tracked from the previous one, fitted and read out; a refused frame reads
    /// out with quality 0 and leaves the tracker as it was.
    fn frame(&mut self, pixels: &'static [u8], size: (usize, usize)) -> Result<bool, FrameError> {
        let outcome = self.track(pixels, size);
        if outcome.is_err() {
            self.ego.refuse().map_err(FrameError::Mavlink)?;
        }
        outcome
    }

    /// True when the frame was tracked (not the first).
    fn track(&mut self, pixels: &'static [u8], (w, h): (usize, usize)) -> Result<bool, FrameError> {
        let next = ImageView::packed(pixels, w, h).map_err(FrameError::Image)?;
        let Some(prev) = self.previous else {
            self.tracker.start(next).map_err(FrameError::Track)?;
            self.ego.remember(self.tracker.tracks());
            self.previous = Some(next);
            return Ok(false);
        };
        self.tracker
            .process(prev, next, None)
            .map_err(FrameError::Track)?;
        self.previous = Some(next);
        let ego = &mut self.ego;
        let tracks = self.tracker.tracks();
        let (fit, ticks) = self.meter.measure(|| ego.estimate(tracks));
        fit?;
        self.ego_instructions = instructions(ticks);
        Ok(true)
    }
}

/// Sends the latest readout on `link`, timed into `cost`.
fn send(sensor: &Sensor<'_>, link: &mut Link, cost: &mut SendCost) {
    let (rad, _) = sensor.ego.latest();
    let flow = sensor.ego.optical_flow();
    let ((), ticks) = sensor.meter.measure(|| link.send(rad, &flow));
    cost.add(instructions(ticks));
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
    let focal = sensor.ego.focal_length();
    let mut cost = SendCost::default();
    let (mut ok, mut total, mut worst, mut frames, mut worst_error) = (true, 0, 0, 0, 0.0f32);
    for index in 0..FRAMES {
        let (outcome, ticks) =
            meter.measure(|| sensor.frame(camera::frame(index), (WIDTH, HEIGHT)));
        let spent = instructions(ticks);
        if outcome != Ok(false) {
            send(&sensor, link, &mut cost);
        }
        match outcome {
            Ok(true) => {
                let (flow, _) = sensor.ego.latest();
                let error = flow_error(flow, focal);
                hprintln!(
                    "sensor_frame {} instructions={} ego={} tracks={} quality={} flow_error={}",
                    index,
                    spent,
                    sensor.ego_instructions,
                    sensor.tracker.tracks().len(),
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
        sensor.tracker.tracks().len()
    );
    fly(&mut sensor, link, &mut cost);
    ok
}

/// Flies the frames back and forth after the sequence, sending every readout, until
/// [`LINK_SECONDS_US`] of frame clock have passed; prints the link's record.
fn fly(sensor: &mut Sensor<'_>, link: &mut Link, cost: &mut SendCost) {
    let mut clock = sensor.ego.latest().0.time_usec;
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
        clock = sensor.ego.latest().0.time_usec;
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
        let (flow, mavlink) = sensor.ego.latest();
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
