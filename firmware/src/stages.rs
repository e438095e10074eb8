//! The measured stages of the per-frame pipeline.
//!
//! The pipeline wraps each step in [`StageTimes::run`] (or adds a [`Stopwatch`] lap with
//! [`StageTimes::add`]) and the report picks every stage up by its name.
//!
//! [`Stopwatch`]: crate::meter::Stopwatch

use crate::meter::{Meter, Ticks};

/// One measured step of the per-frame pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// The tracker's frame checks and levels 1.. of the new frame's pyramid (level 0 is the
    /// frame itself).
    Pyramid,
    /// Every live track followed forward and back with LK, the gates, and the tracker's
    /// bookkeeping.
    Track,
    /// Shi-Tomasi detection on pyramid level 1 and the start of new tracks, in the frames where
    /// fewer than the refill threshold are live.
    Refill,
    /// RANSAC on the tracks' displacements, the OPTICAL_FLOW_RAD readout and its MAVLink frame.
    Ego,
    /// LK at every node of the 8 px grid, and the fill of invalid nodes.
    Dense,
    /// The dominant motion of the grid, the motion mask and its boxes.
    Boxes,
}

impl Stage {
    /// Every stage, in pipeline order.
    pub const ALL: [Stage; 6] = [
        Stage::Pyramid,
        Stage::Track,
        Stage::Refill,
        Stage::Ego,
        Stage::Dense,
        Stage::Boxes,
    ];

    /// The stages of the budget figure: pyramid, tracking and refill.
    pub const BUDGET: [Stage; 3] = [Stage::Pyramid, Stage::Track, Stage::Refill];

    /// The name the report and `bench/target.sh` use.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Pyramid => "pyramid",
            Stage::Track => "track",
            Stage::Refill => "refill",
            Stage::Ego => "ego",
            Stage::Dense => "dense",
            Stage::Boxes => "boxes",
        }
    }

    const fn index(self) -> usize {
        self as usize
    }
}

/// Ticks spent in each stage, for one frame or summed over many.
#[derive(Debug, Clone, Copy, Default)]
pub struct StageTimes {
    ticks: [Ticks; Stage::ALL.len()],
}

impl StageTimes {
    /// Runs `work` as `stage`, adding the ticks it took.
    pub fn run<R>(&mut self, meter: &Meter, stage: Stage, work: impl FnOnce() -> R) -> R {
        let (result, ticks) = meter.measure(work);
        self.add(stage, ticks);
        result
    }

    /// Adds `ticks` to `stage`.
    pub fn add(&mut self, stage: Stage, ticks: Ticks) {
        self.ticks[stage.index()] += ticks;
    }

    /// Ticks spent in `stage`.
    pub fn get(&self, stage: Stage) -> Ticks {
        self.ticks[stage.index()]
    }

    /// Ticks spent in `stages` together.
    pub fn sum(&self, stages: &[Stage]) -> Ticks {
        stages.iter().fold(Ticks(0), |sum, &s| sum + self.get(s))
    }

    /// Ticks spent in every stage together.
    pub fn total(&self) -> Ticks {
        self.sum(&Stage::ALL)
    }

    /// Adds another set of times, stage by stage.
    pub fn accumulate(&mut self, other: &StageTimes) {
        for (sum, &t) in self.ticks.iter_mut().zip(&other.ticks) {
            *sum += t;
        }
    }
}
