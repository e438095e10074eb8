//! The measured stages of the per-frame pipeline.
//!
//! A new stage (refill, ego-motion, dense grid, ...) is a new [`Stage`] variant with its name;
//! the pipeline wraps its work in [`StageTimes::run`] and the report picks it up.

use crate::meter::{Meter, Ticks};

/// One measured step of the per-frame pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Levels 1.. of the new frame's pyramid (level 0 is the frame itself).
    Pyramid,
    /// Pyramidal LK of every point from the previous frame into the new one.
    Track,
}

impl Stage {
    /// Every stage, in pipeline order.
    pub const ALL: [Stage; 2] = [Stage::Pyramid, Stage::Track];

    /// The name the report and `bench/target.sh` use.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Pyramid => "pyramid",
            Stage::Track => "track",
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
        self.ticks[stage.index()] += ticks;
        result
    }

    /// Ticks spent in `stage`.
    pub fn get(&self, stage: Stage) -> Ticks {
        self.ticks[stage.index()]
    }

    /// Ticks spent in every stage together.
    pub fn total(&self) -> Ticks {
        self.ticks.iter().fold(Ticks(0), |sum, &t| sum + t)
    }

    /// Adds another set of times, stage by stage.
    pub fn accumulate(&mut self, other: &StageTimes) {
        for (sum, &t) in self.ticks.iter_mut().zip(&other.ticks) {
            *sum += t;
        }
    }
}
