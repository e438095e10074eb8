//! Where the instructions go: variants of the budget configuration over the same sequence.

use cortex_m_semihosting::hprintln;
use kestrel::lk::{Illumination, LkParams};

use crate::camera;
use crate::meter::Meter;
use crate::pipeline::{self, Buffers, Pipeline, POINTS};
use crate::report::Px;
use crate::scene::{FRAMES, HEIGHT, WIDTH};
use crate::stages::{Stage, StageTimes};
use crate::summary::Summary;

/// Where the instructions go: the costs of one template and of the iterations after it, and
/// variants of the budget configuration over the same sequence. Reported, never checked.
// Never inlined: bench/target_profile.py stops counting where this function is first entered.
#[inline(never)]
pub fn run(meter: &Meter, buffers: Buffers) {
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
        (
            "three_iterations",
            LkParams {
                max_iterations: 3,
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
        Err(e) => crate::fail_with("variant parameters", e),
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
