//! The budget configuration over the whole sequence: every frame printed and checked against
//! the scene's ground truth, with bad input fed in the middle.

use cortex_m_semihosting::hprintln;

use crate::bad_input;
use crate::camera;
use crate::checks::{self, Verdict};
use crate::meter::instructions;
use crate::meter::Meter;
use crate::pipeline::{FrameError, FrameOutput, Pipeline, Tracked};
use crate::report::{Micro, Milli};
use crate::scene::{FRAMES, HEIGHT, WIDTH};
use crate::stack;
use crate::stages::{Stage, StageTimes};
use crate::summary::Summary;

/// Bad input arrives after this frame, so the frames after it show that the pipeline kept going.
const BAD_INPUT_AFTER: usize = 5;

/// Runs the pipeline over the sequence, printing and checking every frame.
pub fn run(pipeline: &mut Pipeline, meter: &Meter) -> bool {
    let mut ok = true;
    let mut sum = Summary::default();
    for index in 0..FRAMES {
        let mut times = StageTimes::default();
        // The repaint erases the high-water mark so far: keep it first. Before the first frame
        // it is the start-up's (calibration, the pipeline made and moved into its static).
        let so_far = stack::repaint();
        if index == 0 {
            sum.boot_stack = so_far;
        } else {
            sum.frames_stack = sum.frames_stack.max(so_far);
        }
        let at_call = stack::depth();
        let outcome = pipeline.process(camera::frame(index), (WIDTH, HEIGHT), meter, &mut times);
        sum.pipeline_stack = sum.pipeline_stack.max(stack::peak() - at_call);
        ok &= match outcome {
            Ok(FrameOutput::Started(tracks)) if index == 0 => {
                hprintln!(
                    "prime instructions={} tracks={}",
                    instructions(times.total()),
                    tracks
                );
                true
            }
            Ok(FrameOutput::Tracked(tracked)) if index > 0 => {
                let verdict = check_frame(index, pipeline, &tracked);
                report_frame(index, &times, &tracked, &verdict);
                sum.add(&times, &tracked, &verdict);
                verdict.passed
            }
            other => unexpected(index, other),
        };
        if index == BAD_INPUT_AFTER {
            ok &= bad_input::feed(pipeline, meter, camera::frame(BAD_INPUT_AFTER + 1));
        }
    }
    sum.frames_stack = sum.frames_stack.max(stack::peak());
    sum.print();
    let focal = pipeline.focal_length();
    hprintln!(
        "tolerances track_error={} live_tracks={} flow_px={} flow_rad={} box_iou={}",
        Milli(checks::TRACK_TOLERANCE),
        checks::MIN_LIVE_TRACKS,
        Milli(checks::FLOW_TOLERANCE_PX),
        Micro(checks::flow_tolerance(focal)),
        Milli(checks::MIN_BOX_IOU),
    );
    ok
}

fn check_frame(index: usize, pipeline: &Pipeline, tracked: &Tracked) -> Verdict {
    let (_, mavlink) = pipeline.latest_flow();
    checks::check(
        index,
        tracked,
        pipeline.pairs(),
        mavlink,
        pipeline.boxes(),
        pipeline.focal_length(),
    )
}

fn unexpected(index: usize, outcome: Result<FrameOutput, FrameError>) -> bool {
    // The error alone: printing a whole frame's output would link the formatting of every
    // type in it, 1 KB of flash for a line that should never appear.
    match outcome {
        Ok(FrameOutput::Started(tracks)) => {
            hprintln!(
                "error frame {}: the tracker started over ({} tracks)",
                index,
                tracks
            )
        }
        Ok(FrameOutput::Tracked(_)) => {
            hprintln!(
                "error frame {}: tracked where the tracker should start",
                index
            )
        }
        Err(e) => hprintln!("error frame {}: {:?}", index, e),
    }
    false
}

/// Prints one frame's costs and check figures, and what failed.
fn report_frame(index: usize, times: &StageTimes, tracked: &Tracked, verdict: &Verdict) {
    let r = &tracked.report;
    hprintln!(
        "frame {} pyramid={} track={} refill={} ego={} dense={} boxes={} budget={} total={} \
         live={} tracked={} added={} dropped={} checked={} track_error={} inliers={} \
         quality={} flow_x={} flow_y={} flow_error={} nodes={} filled={} moving={} \
         box_count={} box_iou={} false_boxes={}",
        index,
        instructions(times.get(Stage::Pyramid)),
        instructions(times.get(Stage::Track)),
        instructions(times.get(Stage::Refill)),
        instructions(times.get(Stage::Ego)),
        instructions(times.get(Stage::Dense)),
        instructions(times.get(Stage::Boxes)),
        instructions(times.sum(&Stage::BUDGET)),
        instructions(times.total()),
        r.live,
        r.tracked,
        r.added,
        r.dropped(),
        verdict.checked_tracks,
        Milli(verdict.track_error),
        tracked.motion.inliers,
        tracked.flow.quality,
        Micro(tracked.flow.integrated_x),
        Micro(tracked.flow.integrated_y),
        Micro(verdict.flow_error),
        tracked.grid.tracked,
        tracked.grid.filled,
        tracked.moving.moving,
        tracked.moving.boxes,
        Milli(verdict.box_iou),
        verdict.false_boxes,
    );
    if !verdict.passed {
        hprintln!(
            "error frame {}: a check failed (tolerances: median track error {} px, at least {} \
             live tracks, flow within {} px at the principal point, ego status Ok (got {:?}), \
             best box IoU {}, no false box)",
            index,
            Milli(checks::TRACK_TOLERANCE),
            checks::MIN_LIVE_TRACKS,
            Milli(checks::FLOW_TOLERANCE_PX),
            tracked.motion.status,
            Milli(checks::MIN_BOX_IOU),
        );
    }
}
