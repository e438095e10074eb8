//! An auto-exposure loop's steps: every few frames the camera changes its gain by a few
//! percent, and its black level a little, as a loop chasing a target brightness does.

use crate::synth::{Lighting, SplitMix64};

/// Frames between two steps: the loop changes the exposure of frames 8, 16, 24, ...
pub const PERIOD: usize = 8;
/// Smallest and largest change of the gain in one step, a share of the gain.
const GAIN_STEP: (f64, f64) = (0.03, 0.08);
/// The gains the loop keeps to: a step that would leave them goes the other way.
const GAIN_RANGE: (f64, f64) = (0.7, 1.4);
/// Largest black-level offset, grey levels.
const BIAS: f64 = 4.0;
/// The random stream of the steps (the scene, path and objects use others).
const STREAM: u64 = 6 << 32;

/// A seeded sequence of auto-exposure steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AutoExposure {
    /// Seed of the steps.
    pub seed: u64,
}

impl AutoExposure {
    /// The gain and bias of frame `k`: unchanged until the first step.
    ///
    /// ```
    /// use host_sim::synth::{AutoExposure, Lighting};
    /// let loop_ = AutoExposure { seed: 1 };
    /// assert_eq!(loop_.lighting(7), Lighting::UNCHANGED);
    /// let stepped = loop_.lighting(8);
    /// assert!((0.03..=0.08).contains(&(stepped.gain - 1.0).abs()));
    /// assert_eq!(loop_.lighting(15), stepped);
    /// ```
    pub fn lighting(&self, k: usize) -> Lighting {
        (1..=k / PERIOD).fold(Lighting::UNCHANGED, |before, step| self.step(before, step))
    }

    /// Step `step` (from 1) of the loop, from `before`.
    fn step(&self, before: Lighting, step: usize) -> Lighting {
        let mut rng = SplitMix64::substream(self.seed, STREAM | step as u64);
        let change = rng.uniform(GAIN_STEP.0, GAIN_STEP.1);
        let (up, down) = (before.gain * (1.0 + change), before.gain * (1.0 - change));
        let brighter = (rng.below(2) == 0 && up <= GAIN_RANGE.1) || down < GAIN_RANGE.0;
        Lighting {
            gain: if brighter { up } else { down },
            bias: rng.uniform(-BIAS, BIAS),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gain_wanders_within_its_range_in_steps() {
        let loop_ = AutoExposure { seed: 5 };
        let gains: Vec<f64> = (0..2000).map(|k| loop_.lighting(k).gain).collect();
        assert!(gains
            .iter()
            .all(|g| (GAIN_RANGE.0 * 0.92..=GAIN_RANGE.1 * 1.08).contains(g)));
        let changes = gains.windows(2).filter(|pair| pair[0] != pair[1]).count();
        assert_eq!(changes, 1999 / PERIOD);
        assert!(gains.iter().any(|&g| g > 1.1) && gains.iter().any(|&g| g < 0.9));
    }
}
