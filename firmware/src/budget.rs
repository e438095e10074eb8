//! The budget configuration over the whole sequence: every frame printed and checked against
//! the known scene motion, with bad input fed in the middle.

use cortex_m_semihosting::hprintln;

use crate::bad_input;
use crate::camera;
use crate::meter::{instructions, Meter};
use crate::pipeline::{Flow, FrameError, Pipeline, POINTS};
use crate::report::{millipx_to_q16, Px};
use crate::scene::{FRAMES, HEIGHT, WIDTH};
use crate::stack;
use crate::stages::{Stage, StageTimes};
use crate::summary::{flow_error, Summary};

/// The largest error of a frame's median displacement that passes: 0.05 px.
const TOLERANCE: i32 = millipx_to_q16(50);
/// The smallest share of points that must be tracked in every frame, in percent.
const MIN_TRACKED_PERCENT: usize = 90;
/// Bad input arrives after this frame, so the frames after it show that the pipeline kept going.
const BAD_INPUT_AFTER: usize = 5;

/// Runs the budget configuration over the sequence, printing and checking every frame.
pub fn run(pipeline: &mut Pipeline, meter: &Meter) -> bool {
    let mut ok = true;
    let mut sum = Summary::default();
    for index in 0..FRAMES {
        let mut times = StageTimes::default();
        // The repaint erases the high-water mark so far: keep it first.
        sum.stack_peak = sum.stack_peak.max(stack::repaint());
        let at_call = stack::depth();
        let outcome = pipeline.process(camera::frame(index), (WIDTH, HEIGHT), meter, &mut times);
        sum.pipeline_stack = sum.pipeline_stack.max(stack::peak() - at_call);
        if index == 0 {
            ok &= report_first_frame(&times, &outcome);
        } else {
            ok &= report_frame(index, &times, &outcome);
            sum.add(&times, &outcome);
        }
        if index == BAD_INPUT_AFTER {
            ok &= bad_input::feed(pipeline, meter, camera::frame(BAD_INPUT_AFTER + 1));
        }
    }
    sum.stack_peak = sum.stack_peak.max(stack::peak());
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
