//! Per-frame costs and flow errors summed over a run of the sequence.

use cortex_m_semihosting::hprintln;

use crate::meter::{instructions, Ticks};
use crate::pipeline::{Flow, FrameError, POINTS};
use crate::report::{millipx_to_q16, Px};
use crate::scene::MOTION_MILLIPX;
use crate::stages::{Stage, StageTimes};

/// The median displacement minus the scene motion, Q16 bits.
pub fn flow_error(flow: &Flow) -> Option<(i32, i32)> {
    let (dx, dy) = flow.median?;
    let (mx, my) = MOTION_MILLIPX;
    Some((dx - millipx_to_q16(mx), dy - millipx_to_q16(my)))
}

/// Costs and flow quality over the tracked frames of one run of the sequence.
#[derive(Default)]
pub struct Summary {
    /// Ticks per stage, summed over the frames.
    pub times: StageTimes,
    /// Frames added.
    pub frames: u64,
    /// The most expensive frame, all stages.
    pub worst_frame: Ticks,
    /// The fewest points tracked in a frame.
    pub min_tracked: Option<usize>,
    /// The largest error of a frame's median flow on either axis, Q16 bits.
    pub worst_error: i32,
    /// The stack high-water mark of the firmware from boot to the end of the run, printing
    /// included, bytes from the top of RAM.
    pub stack_peak: usize,
    /// The deepest stack of the pipeline itself, bytes below the stack pointer of its caller.
    pub pipeline_stack: usize,
}

impl Summary {
    /// Adds one frame's costs and outcome.
    pub fn add(&mut self, times: &StageTimes, outcome: &Result<Option<Flow>, FrameError>) {
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
            "per_frame instructions={} worst={} frames={} points={} tracked_min={} worst_error={} \
             stack_peak={} pipeline_stack={}",
            self.per_frame(self.times.total()),
            instructions(self.worst_frame),
            self.frames,
            POINTS,
            self.min_tracked.unwrap_or(0),
            Px(self.worst_error),
            self.stack_peak,
            self.pipeline_stack,
        );
    }
}
