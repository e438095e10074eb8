//! Kestrel on an STM32F405: the per-frame pipeline (pyramid, tracker with refill, ego-motion and
//! its OPTICAL_FLOW_RAD frame, dense grid and motion boxes) on synthetic frames in flash, checked
//! against the scene's ground truth, with its cost measured per stage; and the flow-sensor
//! preset, whose readouts go out as MAVLink 2 on USART2 (`bench/mavlink_link.sh` reads them).
//!
//! `cargo run --release` runs it in QEMU (see `.cargo/config.toml`); `bench/target.sh` at the
//! repository root runs it and prints the table. The output is one `key=value` record per line.
//! The firmware exits through semihosting: success only when every check passed.
#![no_std]
#![no_main]

mod bad_input;
mod budget;
mod camera;
mod checks;
mod dense;
mod dsp_check;
mod ego;
mod link;
mod link_check;
mod memory;
mod meter;
mod pipeline;
mod profile;
mod px4flow;
mod report;
mod scene;
mod sensor;
mod stack;
mod stages;
mod summary;
mod usart;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};

use dense::DenseMemory;
use meter::{instructions, Meter};
use pipeline::{BudgetMemory, Pipeline};
use report::{millipx_to_q16, Px};
use scene::{FRAMES, HEIGHT, MOTION_MILLIPX, OBJECT_MOTION_MILLIPX, WIDTH};

/// The calibration may deviate from 1000 / 21 instructions per tick by this much (0.1 %).
const CALIBRATION_TOLERANCE_PPM: i64 = 1000;

#[entry]
fn main() -> ! {
    static mut TRACKER_MEMORY: BudgetMemory = BudgetMemory::new();
    static mut DENSE_MEMORY: DenseMemory = DenseMemory::new();
    static mut SENSOR_MEMORY: sensor::SensorMemory = sensor::SensorMemory::new();

    let Some(peripherals) = cortex_m::Peripherals::take() else {
        fail("core peripherals already taken")
    };
    let meter = Meter::new(peripherals.SYST);
    print_config();
    let calibrated = calibrate(&meter);
    let dsp_checked = dsp_check::run();
    let pipeline = make_pipeline(TRACKER_MEMORY, DENSE_MEMORY);
    memory::print();
    let link_checked = link_check::run();
    let passed = budget::run(pipeline, &meter) && calibrated && dsp_checked && link_checked;
    let mut link = link::Link::new();
    let passed = sensor::run(&meter, SENSOR_MEMORY, &mut link) && passed;
    profile::run(&meter, pipeline);
    px4flow::run(&meter);
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

/// Makes the pipeline into its static: a `singleton!`, whose static stays in `.bss` where an
/// `Option` of the pipeline would not (its `None` is not all zeros, which would put 11 KB in
/// `.data` and its image in flash). Not inlined: the pipeline is built on the stack before it
/// moves, and that space must be free again before the first frame.
#[inline(never)]
fn make_pipeline(
    tracker: &'static mut BudgetMemory,
    dense: &'static mut DenseMemory,
) -> &'static mut Pipeline {
    let pipeline = match Pipeline::new(tracker, dense) {
        Ok(p) => p,
        Err(e) => fail_with("invalid pipeline settings", e),
    };
    match cortex_m::singleton!(: Pipeline = pipeline) {
        Some(p) => p,
        None => fail("the pipeline was made twice"),
    }
}

fn print_config() {
    let config = pipeline::tracker_config();
    hprintln!(
        "config frame={}x{} frames={} max_tracks={} refill_below={} window={} max_level={} \
         levels={} max_iterations={} illumination={:?} detect_level={} cell={} motion={},{} \
         object_motion={},{}",
        WIDTH,
        HEIGHT,
        FRAMES,
        config.max_tracks,
        config.refill.below,
        config.lk.window,
        config.lk.max_level,
        config.lk.max_level + 1,
        config.lk.max_iterations,
        config.lk.illumination,
        config.refill.level,
        dense::CELL,
        Px(millipx_to_q16(MOTION_MILLIPX.0)),
        Px(millipx_to_q16(MOTION_MILLIPX.1)),
        Px(millipx_to_q16(OBJECT_MOTION_MILLIPX.0)),
        Px(millipx_to_q16(OBJECT_MOTION_MILLIPX.1)),
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
