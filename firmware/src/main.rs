//! Kestrel on an STM32F405: the per-frame pipeline on synthetic frames in flash, checked against
//! the known scene motion, with its cost measured per stage.
//!
//! `cargo run --release` runs it in QEMU (see `.cargo/config.toml`); `bench/target.sh` at the
//! repository root runs it and prints the table. The output is one `key=value` record per line.
//! The firmware exits through semihosting: success only when every check passed.
#![no_std]
#![no_main]

mod bad_input;
mod budget;
mod camera;
mod meter;
mod pipeline;
mod profile;
mod report;
mod scene;
mod stack;
mod stages;
mod summary;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use kestrel::lk::{LkParams, PointTrack};

use meter::{instructions, Meter};
use pipeline::{Buffers, Pipeline, NO_TRACK, POINTS, PYRAMID_LEN, SCRATCH_LEN};
use report::{millipx_to_q16, Px};
use scene::{FRAMES, HEIGHT, MOTION_MILLIPX, WIDTH};

/// The calibration may deviate from 1000 / 21 instructions per tick by this much (0.1 %).
const CALIBRATION_TOLERANCE_PPM: i64 = 1000;

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
    let tracked_correctly = budget::run(&mut pipeline, meter);
    profile::run(meter, pipeline.into_buffers());
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

/// Reports what went wrong, then fails.
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

/// A fault would otherwise spin in the default handler until the host's timeout.
#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    hprintln!("hard fault at pc {:#010x}", frame.pc());
    fail("hard fault")
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic {}", info);
    fail("panic")
}
