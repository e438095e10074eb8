//! How like its birth patch a track must still look in a frame: the appearance gate's limit,
//! from the gate's threshold and from how alike the frame's tracks look.
//!
//! A fixed threshold assumes that a correct track's patch changes as little on every camera
//! and scene as on the one it was tuned on. On a still camera over a tree in the wind, the
//! leaves turn and cover each other, and the frame's tracks, right as they are, look less like
//! their birth patches than a correct track over still ground does: the same threshold drops
//! half of them. What the tracks of one frame look like says what this frame does to a correct
//! track. So the gate is the threshold while the frame's tracks agree, and lowered, down to a
//! floor, when they spread widely: a track is dropped when its likeness is an outlier of the
//! frame's (more than [`SPREAD_DEVIATIONS`] median absolute deviations below their median), or
//! below the floor; never one that passes the threshold. A walker covering ground tracks is
//! such an outlier, since the rest of the ground keeps its looks. Tracks whose image has turned
//! since their birth keep the threshold (see [`super::anchor`]).

use super::anchor::likeness_limit;
use super::follow::median;
use crate::q16::Q16;

/// How far below the frame's median likeness, in median absolute deviations, a track's
/// likeness may lie: six, about four standard deviations of a normal spread.
const SPREAD_DEVIATIONS: i32 = 6;

/// The fewest tracks whose likeness says how the frame treats a correct track.
const ENOUGH: usize = 8;

/// The appearance gate of a frame: the least likeness ([`super::anchor::Anchor::likeness`]) a
/// track passes with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct AppearanceGate {
    /// The threshold's likeness, the strictest the gate is.
    strict: Q16,
    /// The floor's likeness, the most lenient; `None` when the gate does not follow the frame.
    least: Option<Q16>,
}

impl AppearanceGate {
    /// The gate of `min_correlation`, lowered on frames whose tracks spread widely, down to
    /// `least_correlation` (`None`: never lowered).
    /// A floor of -1 or less leaves only the frame's spread: a patch without contrast, whose
    /// likeness is [`Q16::MIN`], still fails.
    pub(super) fn new(min_correlation: f32, least_correlation: Option<f32>) -> Self {
        let strict = likeness_limit(min_correlation);
        let least = least_correlation.map(|c| likeness_limit(c.max(-1.0)));
        debug_assert!(
            least.is_none_or(|least| least < strict),
            "a floor at or above the threshold is a fixed gate"
        );
        Self { strict, least }
    }

    /// The threshold's likeness: the limit while the frame's tracks agree.
    pub(super) fn strict(&self) -> Q16 {
        self.strict
    }

    /// Whether the limit depends on the frame's tracks (see [`AppearanceGate::limit`]).
    pub(super) fn follows_frame(&self) -> bool {
        self.least.is_some()
    }

    /// The frame's limit, from the likeness of its tracked steps (`likeness`, Q16 bits,
    /// reordered): their median less [`SPREAD_DEVIATIONS`] median absolute deviations, raised
    /// to the floor, lowered to the threshold. With fewer than [`ENOUGH`] steps, or a gate
    /// that does not follow the frame, the threshold.
    pub(super) fn limit(&self, likeness: &mut [i32]) -> Q16 {
        let Some(least) = self.least else {
            return self.strict;
        };
        if likeness.len() < ENOUGH {
            return self.strict;
        }
        let Some(centre) = median(likeness) else {
            return self.strict;
        };
        for value in likeness.iter_mut() {
            *value = value.saturating_sub(centre).saturating_abs();
        }
        let Some(deviation) = median(likeness) else {
            return self.strict;
        };
        let spread = deviation.saturating_mul(SPREAD_DEVIATIONS);
        let outlier = Q16::from_bits(centre.saturating_sub(spread));
        outlier.max(least).min(self.strict)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limit(gate: AppearanceGate, likeness: &[f32]) -> f32 {
        let mut values: heapless::Vec<i32, 32> = likeness
            .iter()
            .map(|&l| crate::q16::q16_from_f32(l).to_bits())
            .collect();
        gate.limit(&mut values).to_num()
    }

    #[test]
    fn tracks_that_agree_keep_the_threshold_and_a_wide_spread_lowers_it_to_the_floor() {
        let gate = AppearanceGate::new(0.8, Some(0.6));
        // Ground tracks that look like their birth patches, and two a walker covers: outliers.
        let ground = [1.0, 0.98, 1.02, 0.99, 1.0, 0.97, 1.01, 0.2, 0.1, 1.0];
        assert!((limit(gate, &ground) - 0.64).abs() < 1e-4);
        // Leaves in the wind: likeness from 0.5 to 1, the limit as low as the floor lets it go.
        let leaves = [1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.95, 0.85, 0.75, 0.65];
        assert!((limit(gate, &leaves) - 0.36).abs() < 1e-4);
        // Between the two: the median (0.9) less six deviations (0.05 each).
        let loose = [0.95, 0.85, 0.9, 0.9, 0.95, 0.85, 0.9, 0.95, 0.85];
        assert!((limit(gate, &loose) - 0.6).abs() < 1e-3);
    }

    #[test]
    fn few_tracks_or_a_fixed_gate_keep_the_threshold() {
        let leaves = [1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.95, 0.85, 0.75, 0.65];
        assert!((limit(AppearanceGate::new(0.8, None), &leaves) - 0.64).abs() < 1e-4);
        let few = AppearanceGate::new(0.8, Some(0.6));
        assert!((limit(few, &leaves[..ENOUGH - 1]) - 0.64).abs() < 1e-4);
        // A scene cut: every track anti-correlated, no spread, the floor, which drops them all.
        assert!((limit(few, &[-1.0; 10]) - 0.36).abs() < 1e-4);
        // Without a floor, a flat frame's tracks (no contrast: the least likeness there is)
        // still fail.
        let no_floor = AppearanceGate::new(0.8, Some(f32::NEG_INFINITY));
        let mut flat = [Q16::MIN.to_bits(); 10];
        assert!(no_floor.limit(&mut flat) > Q16::MIN);
    }
}
