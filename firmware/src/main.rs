//! Kestrel on an STM32F405: the per-frame pipeline on synthetic frames in flash, checked against
//! the known scene motion, with its cost measured per stage.
//!
//! `cargo run --release` runs it in QEMU (see `.cargo/config.toml`); `bench/target.sh` at the
//! repository root runs it and prints the table. The output is one `key=value` record per line.
//! The firmware exits through semihosting: success only when every check passed.
#![no_std]
#![no_main]

mod camera;
mod meter;
mod pipeline;
mod report;
mod scene;
mod stack;
mod stages;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use kestrel::frame::ImageError;
use kestrel::lk::{Illumination, LkError, LkParams, PointTrack};

use meter::{instructions, Meter, Ticks};
use pipeline::{Buffers, Flow, FrameError, Pipeline, NO_TRACK, POINTS, PYRAMID_LEN, SCRATCH_LEN};
use report::{millipx_to_q16, Px};
use scene::{FRAMES, FRAME_LEN, HEIGHT, MOTION_MILLIPX, WIDTH};
use stages::{Stage, StageTimes};

/// The largest error of a frame's median displacement that passes: 0.05 px.
const TOLERANCE: i32 = millipx_to_q16(50);
/// The smallest share of points that must be tracked in every frame, in percent.
const MIN_TRACKED_PERCENT: usize = 90;
/// The calibration may deviate from 1000 / 21 instructions per tick by this much (0.1 %).
const CALIBRATION_TOLERANCE_PPM: i64 = 1000;
/// Bad input arrives after this frame, so the frames after it show that the pipeline kept going.
const BAD_INPUT_AFTER: usize = 5;

#[entry]
fn main() -> ! {
    static mut PYRAMIDS: [[u8; PYRAMID_LEN]; 2] = [[0; PYRAMID_LEN]; 2];
    static mut TRACKS: [PointTrack; POINTS] = [NO_TRACK; POINTS];
    static mut SCRATCH: [i16; SCRATCH_LEN] = [0; SCRATCH_LEN];

    let [first, second] = PYRAMIDS;
    let buffers = Buffers {
        pyramids: [first, second],
        tracks: TRACKS,
        scratch: SCRATCH,
    };
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        fail("core peripherals already taken")
    };
    let meter = Meter::new(peripherals.SYST);
    let passed = run(&meter, buffers);
    hprintln!("stack peak={} reserved={}", stack::peak(), stack::size());
    if passed {
        hprintln!("result pass");
        debug::exit(debug::EXIT_SUCCESS);
    } else {
        hprintln!("result FAIL");
        debug::exit(debug::EXIT_FAILURE);
    }
    loop {
        cortex_m::asm::wfi();
    }
}

/// Calibrates the meter, runs the budget configuration with its checks, then the profile.
fn run(meter: &Meter, buffers: Buffers) -> bool {
    let params = pipeline::budget_params();
    print_config(&params);
    let calibrated = calibrate(meter);
    let mut pipeline = match Pipeline::new(params, buffers) {
        Ok(p) => p,
        Err(e) => {
            hprintln!("error invalid LK parameters: {:?}", e);
            return false;
        }
    };
    let tracked_correctly = budget_run(&mut pipeline, meter);
    profile(meter, pipeline.into_buffers());
    calibrated && tracked_correctly
}

fn print_config(params: &LkParams) {
    hprintln!(
        "config frame={}x{} frames={} points={} window={} max_level={} levels={} \
         max_iterations={} illumination={:?} motion={},{}",
        WIDTH,
        HEIGHT,
        FRAMES,
        POINTS,
        params.window,
        params.max_level,
        params.max_level + 1,
        params.max_iterations,
        params.illumination,
        Px(millipx_to_q16(MOTION_MILLIPX.0)),
        Px(millipx_to_q16(MOTION_MILLIPX.1)),
    );
}

/// Checks the ticks-to-instructions formula against a loop of known length.
fn calibrate(meter: &Meter) -> bool {
    let calibration = meter::calibrate(meter);
    let error = calibration.error_ppm();
    hprintln!(
        "calibration loop_instructions={} ticks={} milli_instructions_per_tick={} \
         formula_instructions={} error_ppm={}",
        calibration.loop_instructions,
        calibration.ticks.0,
        calibration.milli_instructions_per_tick(),
        instructions(calibration.ticks),
        error,
    );
    let ok = error.abs() <= CALIBRATION_TOLERANCE_PPM;
    if !ok {
        hprintln!("error SysTick does not count 21 ticks per 1000 instructions");
    }
    ok
}

/// Runs the budget configuration over the sequence, printing and checking every frame.
fn budget_run(pipeline: &mut Pipeline, meter: &Meter) -> bool {
    let mut ok = true;
    let mut sum = Summary::default();
    for index in 0..FRAMES {
        let mut times = StageTimes::default();
        let outcome = pipeline.process(camera::frame(index), (WIDTH, HEIGHT), meter, &mut times);
        if index == 0 {
            ok &= report_first_frame(&times, &outcome);
        } else {
            ok &= report_frame(index, &times, &outcome);
            sum.add(&times, &outcome);
        }
        if index == BAD_INPUT_AFTER {
            ok &= feed_bad_input(pipeline, meter);
        }
    }
    sum.print();
    ok
}

fn report_first_frame(times: &StageTimes, outcome: &Result<Option<Flow>, FrameError>) -> bool {
    hprintln!("prime pyramid={}", instructions(times.get(Stage::Pyramid)));
    if outcome != &Ok(None) {
        hprintln!(
            "error the first frame should only prime the pyramid: {:?}",
            outcome
        );
        return false;
    }
    true
}

/// Prints one frame's costs and flow; false when the flow misses the known motion.
fn report_frame(
    index: usize,
    times: &StageTimes,
    outcome: &Result<Option<Flow>, FrameError>,
) -> bool {
    let flow = match outcome {
        Ok(Some(flow)) => flow,
        other => {
            hprintln!("error frame {} produced no flow: {:?}", index, other);
            return false;
        }
    };
    let Some((dx, dy)) = flow.median else {
        hprintln!("error frame {} tracked no point", index);
        return false;
    };
    let (ex, ey) = flow_error(flow).unwrap_or((i32::MAX, i32::MAX));
    hprintln!(
        "frame {} pyramid={} track={} total={} tracked={} quality={} median={},{} error={},{}",
        index,
        instructions(times.get(Stage::Pyramid)),
        instructions(times.get(Stage::Track)),
        instructions(times.total()),
        flow.tracked,
        flow.quality(),
        Px(dx),
        Px(dy),
        Px(ex),
        Px(ey),
    );
    let accurate = ex.abs() <= TOLERANCE && ey.abs() <= TOLERANCE;
    let enough = flow.tracked * 100 >= MIN_TRACKED_PERCENT * POINTS;
    if !accurate {
        hprintln!(
            "error frame {}: median flow {},{} px, expected {},{} px (tolerance {})",
            index,
            Px(dx),
            Px(dy),
            Px(dx - ex),
            Px(dy - ey),
            Px(TOLERANCE),
        );
    }
    if !enough {
        hprintln!(
            "error frame {}: {} of {} points tracked, fewer than {}%",
            index,
            flow.tracked,
            POINTS,
            MIN_TRACKED_PERCENT
        );
    }
    accurate && enough
}

/// The median displacement minus the scene motion, Q16 bits.
fn flow_error(flow: &Flow) -> Option<(i32, i32)> {
    let (dx, dy) = flow.median?;
    let (mx, my) = MOTION_MILLIPX;
    Some((dx - millipx_to_q16(mx), dy - millipx_to_q16(my)))
}

/// Sums of the budget run over the tracked frames.
#[derive(Default)]
struct Summary {
    times: StageTimes,
    frames: u64,
    worst_frame: Ticks,
    min_tracked: Option<usize>,
    worst_error: i32,
}

impl Summary {
    fn add(&mut self, times: &StageTimes, outcome: &Result<Option<Flow>, FrameError>) {
        self.times.accumulate(times);
        self.frames += 1;
        self.worst_frame = self.worst_frame.max(times.total());
        let flow = match outcome {
            Ok(Some(flow)) => Some(flow),
            _ => None,
        };
        let tracked = flow.map_or(0, |f| f.tracked);
        self.min_tracked = Some(self.min_tracked.map_or(tracked, |m| m.min(tracked)));
        let (ex, ey) = flow.and_then(flow_error).unwrap_or((i32::MAX, i32::MAX));
        self.worst_error = self
            .worst_error
            .max(ex.saturating_abs())
            .max(ey.saturating_abs());
    }

    fn per_frame(&self, ticks: Ticks) -> u64 {
        instructions(ticks) / self.frames.max(1)
    }

    fn print(&self) {
        for stage in Stage::ALL {
            hprintln!(
                "stage name={} instructions_per_frame={}",
                stage.name(),
                self.per_frame(self.times.get(stage))
            );
        }
        hprintln!(
            "per_frame instructions={} worst={} frames={} points={} tracked_min={} worst_error={}",
            self.per_frame(self.times.total()),
            instructions(self.worst_frame),
            self.frames,
            POINTS,
            self.min_tracked.unwrap_or(0),
            Px(self.worst_error),
        );
    }
}

/// A frame the library must refuse, and the error it must refuse it with.
struct BadInput {
    name: &'static str,
    pixels: &'static [u8],
    size: (usize, usize),
    expected: FrameError,
}

/// Feeds frames the library must refuse: each must come back as an error value, with quality 0,
/// and the frames after them must track as before.
fn feed_bad_input(pipeline: &mut Pipeline, meter: &Meter) -> bool {
    let good = camera::frame(BAD_INPUT_AFTER + 1);
    let cases = [
        BadInput {
            name: "short_buffer",
            pixels: good.get(..FRAME_LEN - 1).unwrap_or(&[]),
            size: (WIDTH, HEIGHT),
            expected: FrameError::Image(ImageError::BufferTooSmall),
        },
        BadInput {
            name: "zero_size",
            pixels: &[],
            size: (0, 0),
            expected: FrameError::Image(ImageError::ZeroSize),
        },
        BadInput {
            name: "wrong_size",
            pixels: good.get(..(WIDTH / 2) * (HEIGHT / 2)).unwrap_or(&[]),
            size: (WIDTH / 2, HEIGHT / 2),
            expected: FrameError::Track(LkError::FrameSizeMismatch),
        },
    ];
    let mut ok = true;
    for case in cases {
        let mut times = StageTimes::default();
        let outcome = pipeline.process(case.pixels, case.size, meter, &mut times);
        let quality = match outcome {
            Ok(Some(flow)) => flow.quality(),
            _ => 0,
        };
        hprintln!(
            "bad_input case={} outcome={:?} quality={}",
            case.name,
            outcome,
            quality
        );
        if outcome != Err(case.expected) {
            hprintln!(
                "error bad input {}: expected Err({:?})",
                case.name,
                case.expected
            );
            ok = false;
        }
    }
    ok
}

/// Where the instructions go: the costs of one template and one iteration, and variants of the
/// budget configuration over the same sequence. Reported, never checked.
fn profile(meter: &Meter, buffers: Buffers) {
    let budget = pipeline::budget_params();
    // With epsilon 0 every point runs exactly its iteration limit at the single level.
    let one_level = LkParams {
        max_level: 0,
        epsilon: 0.0,
        ..budget
    };
    let variants = [
        (
            "one_iteration",
            LkParams {
                max_iterations: 1,
                ..one_level
            },
        ),
        (
            "two_iterations",
            LkParams {
                max_iterations: 2,
                ..one_level
            },
        ),
        ("budget", budget),
        (
            "plain_illumination",
            LkParams {
                illumination: Illumination::Plain,
                ..budget
            },
        ),
        (
            "window_7",
            LkParams {
                window: 7,
                ..budget
            },
        ),
        (
            "max_level_1",
            LkParams {
                max_level: 1,
                ..budget
            },
        ),
        (
            "max_iterations_10",
            LkParams {
                max_iterations: 10,
                ..budget
            },
        ),
        (
            "epsilon_0.03",
            LkParams {
                epsilon: 0.03,
                ..budget
            },
        ),
    ];
    let mut buffers = buffers;
    for (name, params) in variants {
        let (sum, returned) = variant_run(meter, params, buffers);
        buffers = returned;
        hprintln!(
            "variant name={} window={} max_level={} max_iterations={} illumination={:?} \
             pyramid={} track={} track_per_point={} tracked_min={} worst_error={}",
            name,
            params.window,
            params.max_level,
            params.max_iterations,
            params.illumination,
            sum.per_frame(sum.times.get(Stage::Pyramid)),
            sum.per_frame(sum.times.get(Stage::Track)),
            sum.per_frame(sum.times.get(Stage::Track)) / POINTS as u64,
            sum.min_tracked.unwrap_or(0),
            Px(sum.worst_error),
        );
    }
}

/// Runs the sequence with `params` in `buffers`, quietly; gives the buffers back.
fn variant_run(meter: &Meter, params: LkParams, buffers: Buffers) -> (Summary, Buffers) {
    let mut sum = Summary::default();
    let mut pipeline = match Pipeline::new(params, buffers) {
        Ok(p) => p,
        Err(e) => fail_with("variant parameters", e),
    };
    for index in 0..FRAMES {
        let mut times = StageTimes::default();
        let outcome = pipeline.process(camera::frame(index), (WIDTH, HEIGHT), meter, &mut times);
        if index > 0 {
            sum.add(&times, &outcome);
        }
    }
    (sum, pipeline.into_buffers())
}

fn fail_with(what: &str, error: impl core::fmt::Debug) -> ! {
    hprintln!("error {}: {:?}", what, error);
    fail("giving up")
}

/// Reports a failure to the host and ends the QEMU run with a non-zero status.
fn fail(reason: &str) -> ! {
    hprintln!("result FAIL {}", reason);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic {}", info);
    fail("panic")
}
