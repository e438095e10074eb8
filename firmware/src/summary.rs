//! Per-frame costs and check figures summed over a run of the sequence.

use cortex_m_semihosting::hprintln;

use crate::checks::Verdict;
use crate::meter::{instructions, Ticks};
use crate::pipeline::Tracked;
use crate::report::{Micro, Milli};
use crate::stages::{Stage, StageTimes};

/// Costs and check figures over the tracked frames of the sequence.
#[derive(Default)]
pub struct Summary {
    /// Ticks per stage, summed over the frames.
    pub times: StageTimes,
    /// Frames added.
    pub frames: u64,
    /// Frames in which the tracker detected new corners, and the ticks of those detections.
    pub refills: u64,
    pub refill_ticks: Ticks,
    /// The most expensive frame in the budget stages.
    pub worst_budget: Ticks,
    /// The most expensive frame, all stages.
    pub worst_frame: Ticks,
    /// Tracks followed into a frame, summed over the frames.
    pub followed: u64,
    /// Live tracks after the last frame, and the fewest after any frame.
    pub last_live: usize,
    pub min_live: Option<usize>,
    /// The worst figures of the checks.
    pub worst_track_error: f32,
    pub worst_flow_error: f32,
    pub min_box_iou: Option<f32>,
    pub false_boxes: usize,
    /// The stack high-water mark from boot to the first frame, bytes from the top of RAM.
    pub boot_stack: usize,
    /// The stack high-water mark over the frames, printing included, bytes from the top of RAM.
    pub frames_stack: usize,
    /// The deepest stack of the pipeline itself, bytes below the stack pointer of its caller.
    pub pipeline_stack: usize,
}

impl Summary {
    /// Adds one frame's costs and check figures.
    pub fn add(&mut self, times: &StageTimes, tracked: &Tracked, verdict: &Verdict) {
        self.times.accumulate(times);
        self.frames += 1;
        if tracked.report.detected {
            self.refills += 1;
            self.refill_ticks += times.get(Stage::Refill);
        }
        self.worst_budget = self.worst_budget.max(times.sum(&Stage::BUDGET));
        self.worst_frame = self.worst_frame.max(times.total());
        self.followed += tracked.report.tracked as u64;
        self.last_live = tracked.report.live;
        let live = tracked.report.live;
        self.min_live = Some(self.min_live.map_or(live, |m| m.min(live)));
        self.worst_track_error = self.worst_track_error.max(verdict.track_error);
        self.worst_flow_error = self.worst_flow_error.max(verdict.flow_error);
        if verdict.box_asked {
            let iou = verdict.box_iou;
            self.min_box_iou = Some(self.min_box_iou.map_or(iou, |m| m.min(iou)));
        }
        self.false_boxes += verdict.false_boxes;
    }

    /// Instructions per frame on average.
    pub fn per_frame(&self, ticks: Ticks) -> u64 {
        instructions(ticks) / self.frames.max(1)
    }

    /// Prints the per-stage and per-frame records.
    pub fn print(&self) {
        for stage in Stage::ALL {
            hprintln!(
                "stage name={} instructions_per_frame={}",
                stage.name(),
                self.per_frame(self.times.get(stage))
            );
        }
        hprintln!(
            "refills frames={} instructions_per_refill={}",
            self.refills,
            instructions(self.refill_ticks) / self.refills.max(1),
        );
        hprintln!(
            "per_frame instructions={} all_stages={} worst={} worst_all_stages={} frames={} \
             followed={} tracks={} tracks_min={} track_error_worst={} flow_error_worst={} box_iou_min={} \
             false_boxes={} stack_peak={} boot_stack={} frames_stack={} pipeline_stack={}",
            self.per_frame(self.times.sum(&Stage::BUDGET)),
            self.per_frame(self.times.total()),
            instructions(self.worst_budget),
            instructions(self.worst_frame),
            self.frames,
            self.followed,
            self.last_live,
            self.min_live.unwrap_or(0),
            Milli(self.worst_track_error),
            Micro(self.worst_flow_error),
            Milli(self.min_box_iou.unwrap_or(0.0)),
            self.false_boxes,
            self.boot_stack.max(self.frames_stack),
            self.boot_stack,
            self.frames_stack,
            self.pipeline_stack,
        );
    }
}
