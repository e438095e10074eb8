//! Pyramidal Lucas-Kanade in `f32`, step for step the library's algorithm (Bouguet's method).
//!
//! Per point, from the coarsest level to the finest: sample the template window around the point
//! in the previous frame, reject it if its gradient matrix is too weak, then iterate: sample the
//! next frame at the estimate, fit the brightness change, step by `-G⁻¹ b`, until the step is
//! below epsilon, two steps cancel, or the iterations run out. The estimate, doubled, seeds the
//! next finer level. Only the outcome at full resolution decides the status.

use kestrel::lk::{Illumination, LkParams, TrackStatus};

use super::window::{window_misses, GradientMatrix, Template, Window};
use super::{pyramid, FloatImage};
use crate::Frame;

/// Two consecutive steps whose sum is below this on both axes (px) bounce around the optimum.
const OSCILLATION: f32 = 0.01;
/// The fitted gain is clamped to `[1/4, 4]`, as in the library: no lighting change between two
/// frames is larger, and the clamp keeps a mismatched window from producing a wild step.
const GAIN_MIN: f32 = 0.25;
const GAIN_MAX: f32 = 4.0;
/// Ridge term of the gain fit, a variance per pixel in grey levels squared: (2 grey levels)^2,
/// the same as the library's.
const GAIN_RIDGE: f32 = 4.0;
/// OpenCV's eigenvalue threshold is in its own scale: gradients x 32 (so `G` x 1024), and the
/// eigenvalue divided by 2^20 * area. In grey levels per pixel that is `λ_min / (1024 area)`.
const OPENCV_EIGEN_SCALE: f32 = 1024.0;

/// The result for one point, the `f32` counterpart of [`kestrel::lk::PointTrack`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefTrack {
    /// Estimated horizontal position in the next frame (the last estimate when not tracked).
    pub x: f32,
    /// Estimated vertical position in the next frame.
    pub y: f32,
    /// Whether the position can be trusted, and why not.
    pub status: TrackStatus,
    /// Mean absolute residual over the window at the final position, grey levels (after the gain
    /// and bias correction in gain-bias mode); zero when not tracked.
    pub residual: f32,
}

impl RefTrack {
    /// True for [`TrackStatus::Tracked`].
    pub fn is_tracked(&self) -> bool {
        self.status == TrackStatus::Tracked
    }

    /// The position as a pair.
    pub fn position(&self) -> (f32, f32) {
        (self.x, self.y)
    }

    fn lost(status: TrackStatus, (x, y): (f32, f32)) -> Self {
        Self {
            x,
            y,
            status,
            residual: 0.0,
        }
    }
}

/// Tracks `points` from `prev` to `next` with pyramids of `params.max_level` levels.
///
/// `guesses`, when given, holds a predicted position in `next` for each point. Coordinates are
/// read as the library reads them from `f32` ([`kestrel::Point::from_f32`]): NaN as 0, and
/// saturated to the Q16 range, so that both implementations start from the same place. Panics if
/// `guesses` and `points` differ in length or if the window is not odd and at least 3 (the
/// library refuses such parameters).
///
/// ```
/// use host_sim::reference::track_points;
/// use kestrel::lk::{LkParams, TrackStatus};
/// let frame = host_sim::Frame::filled(40, 30, 80);
/// let tracks = track_points(&frame, &frame, &[(20.0, 15.0), (-1.0, 3.0)], None, &LkParams::default());
/// assert_eq!(tracks[0].status, TrackStatus::LowTexture);
/// assert_eq!(tracks[1].status, TrackStatus::OutOfBounds);
/// ```
pub fn track_points(
    prev: &Frame,
    next: &Frame,
    points: &[(f32, f32)],
    guesses: Option<&[(f32, f32)]>,
    params: &LkParams,
) -> Vec<RefTrack> {
    let prev = pyramid(prev, params.max_level);
    let next = pyramid(next, params.max_level);
    track_points_in(&prev, &next, points, guesses, params)
}

/// Tracks `points` between two pyramids built by [`pyramid`], so that one pyramid can serve
/// several calls. The coarsest level used is the smallest of `params.max_level` and both depths.
///
/// Panics as [`track_points`] does, and if a pyramid is empty.
pub fn track_points_in(
    prev: &[FloatImage],
    next: &[FloatImage],
    points: &[(f32, f32)],
    guesses: Option<&[(f32, f32)]>,
    params: &LkParams,
) -> Vec<RefTrack> {
    assert!(
        params.window >= 3 && params.window % 2 == 1,
        "the window must be odd and at least 3"
    );
    if let Some(g) = guesses {
        assert_eq!(g.len(), points.len(), "one guess per point");
    }
    points
        .iter()
        .enumerate()
        .map(|(i, &point)| {
            let guess = guesses.map(|g| as_library_reads(g[i]));
            track_point(prev, next, as_library_reads(point), guess, params)
        })
        .collect()
}

/// The Q16 range: ±32768 px.
const Q16_LIMIT: f32 = 32768.0;

/// A position as [`kestrel::Point::from_f32`] reads it: NaN as 0, saturated to the Q16 range
/// (without its 1/65536 px steps, far below the precision compared; at ±32768 an `f32` has no
/// finer steps than that anyway).
fn as_library_reads((x, y): (f32, f32)) -> (f32, f32) {
    let read = |v: f32| {
        if v.is_nan() {
            0.0
        } else {
            v.clamp(-Q16_LIMIT, Q16_LIMIT)
        }
    };
    (read(x), read(y))
}

/// How the iterations at one level ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LevelOutcome {
    Converged,
    LowTexture,
    LeftFrame,
    IterationsExhausted,
}

/// One point through all pyramid levels.
fn track_point(
    prev: &[FloatImage],
    next: &[FloatImage],
    point: (f32, f32),
    guess: Option<(f32, f32)>,
    params: &LkParams,
) -> RefTrack {
    if !prev[0].contains(point.0, point.1) {
        return RefTrack::lost(TrackStatus::OutOfBounds, point);
    }
    let top = params.max_level.min(prev.len() - 1).min(next.len() - 1);
    // The estimate lives in the current level's coordinates.
    let mut estimate = at_level(guess.unwrap_or(point), top);
    let mut outcome = LevelOutcome::Converged;
    let mut finest = None;
    for level in (0..=top).rev() {
        let template = Template::sample(&prev[level], at_level(point, level), params.window);
        match LevelSolver::new(template, params) {
            Some(solver) => {
                outcome = solver.iterate(&next[level], &mut estimate, params);
                if level == 0 {
                    finest = Some(solver);
                }
            }
            // A weak window at a coarse level skips that level; at full resolution it is final.
            None => outcome = LevelOutcome::LowTexture,
        }
        if level > 0 {
            estimate = (2.0 * estimate.0, 2.0 * estimate.1);
        }
    }
    let status = match outcome {
        LevelOutcome::LowTexture => TrackStatus::LowTexture,
        LevelOutcome::LeftFrame => TrackStatus::OutOfBounds,
        LevelOutcome::IterationsExhausted => TrackStatus::NotConverged,
        LevelOutcome::Converged if !next[0].contains(estimate.0, estimate.1) => {
            TrackStatus::OutOfBounds
        }
        LevelOutcome::Converged => TrackStatus::Tracked,
    };
    match finest {
        Some(solver) if status == TrackStatus::Tracked => RefTrack {
            x: estimate.0,
            y: estimate.1,
            status,
            residual: solver.residual(&next[0], estimate),
        },
        _ => RefTrack::lost(status, estimate),
    }
}

/// A full-resolution position at pyramid level `level`.
fn at_level((x, y): (f32, f32), level: usize) -> (f32, f32) {
    let scale = 0.5f32.powi(level as i32);
    (x * scale, y * scale)
}

/// Brightness of the next window modelled as `J ≈ gain * I + bias`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Fit {
    gain: f32,
    bias: f32,
}

impl Fit {
    const UNCHANGED: Fit = Fit {
        gain: 1.0,
        bias: 0.0,
    };

    /// The least-squares fit of `j` against `i`, gain clamped, with a ridge term: both the
    /// variance and the covariance get [`GAIN_RIDGE`] added, which pulls the gain towards 1 on
    /// windows whose contrast is comparable to sensor noise.
    fn least_squares(i: &Window, j: &Window) -> Self {
        let (mean_i, mean_j) = (i.mean(), j.mean());
        let mut variance = 0.0;
        let mut covariance = 0.0;
        for (&a, &b) in i.values.iter().zip(&j.values) {
            variance += (a - mean_i) * (a - mean_i);
            covariance += (a - mean_i) * (b - mean_j);
        }
        let n = i.values.len() as f32;
        let ridge = n * GAIN_RIDGE;
        let gain = ((covariance + ridge) / (variance + ridge)).clamp(GAIN_MIN, GAIN_MAX);
        Fit {
            gain,
            bias: mean_j - gain * mean_i,
        }
    }
}

/// One point at one level: the template and its gradient matrix.
struct LevelSolver {
    template: Template,
    gradient: GradientMatrix,
    illumination: Illumination,
}

impl LevelSolver {
    /// `None` when the template lacks texture: the smaller eigenvalue of its gradient matrix per
    /// pixel is below the threshold, or the matrix is singular.
    fn new(template: Template, params: &LkParams) -> Option<Self> {
        let gradient = template.gradient_matrix();
        let area = (template.side() * template.side()) as f32;
        let strength = gradient.min_eigenvalue() / area;
        if strength < params.min_eigen_threshold * OPENCV_EIGEN_SCALE
            || gradient.determinant() <= 0.0
        {
            return None;
        }
        Some(Self {
            template,
            gradient,
            illumination: params.illumination,
        })
    }

    /// The LK iterations at one level, moving `estimate` (this level's coordinates).
    fn iterate(
        &self,
        next: &FloatImage,
        estimate: &mut (f32, f32),
        params: &LkParams,
    ) -> LevelOutcome {
        let side = self.template.side();
        let mut previous: Option<(f32, f32)> = None;
        for _ in 0..params.max_iterations {
            if window_misses(next, *estimate, side) {
                return LevelOutcome::LeftFrame;
            }
            let j = Window::sample(next, *estimate, side);
            let step = self
                .gradient
                .step(self.mismatch(&j))
                .expect("LevelSolver::new checked that G is invertible");
            estimate.0 += step.0;
            estimate.1 += step.1;
            if step.0 * step.0 + step.1 * step.1 <= params.epsilon * params.epsilon {
                return LevelOutcome::Converged;
            }
            if let Some(p) = previous {
                if (step.0 + p.0).abs() < OSCILLATION && (step.1 + p.1).abs() < OSCILLATION {
                    // The estimate bounces around the optimum: settle midway.
                    estimate.0 -= step.0 / 2.0;
                    estimate.1 -= step.1 / 2.0;
                    return LevelOutcome::Converged;
                }
            }
            previous = Some(step);
        }
        LevelOutcome::IterationsExhausted
    }

    /// The brightness fit for the next window `j`.
    fn fit(&self, j: &Window) -> Fit {
        match self.illumination {
            Illumination::Plain => Fit::UNCHANGED,
            Illumination::GainBias => Fit::least_squares(&self.template.intensities, j),
        }
    }

    /// `b = Σ (J - gain I - bias) ∇I`: the mismatch projected on the template's gradients.
    fn mismatch(&self, j: &Window) -> (f32, f32) {
        let fit = self.fit(j);
        let t = &self.template;
        let mut b = (0.0, 0.0);
        for (k, &i) in t.intensities.values.iter().enumerate() {
            let r = j.values[k] - fit.gain * i - fit.bias;
            b.0 += r * t.dx.values[k];
            b.1 += r * t.dy.values[k];
        }
        b
    }

    /// Mean absolute residual `|J - gain I - bias|` at `position`, grey levels.
    fn residual(&self, next: &FloatImage, position: (f32, f32)) -> f32 {
        let i = &self.template.intensities;
        let j = Window::sample(next, position, i.side);
        let fit = self.fit(&j);
        let total: f32 = i
            .values
            .iter()
            .zip(&j.values)
            .map(|(&a, &b)| (b - fit.gain * a - fit.bias).abs())
            .sum();
        total / i.values.len() as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth blob centred at (`cx`, 32) on a 64 x 64 frame, brightness `gain * v + bias`.
    fn blob(cx: f32, gain: f32, bias: f32) -> Frame {
        let data = (0..64 * 64)
            .map(|i| {
                let (x, y) = ((i % 64) as f32 - cx, (i / 64) as f32 - 32.0);
                let v = 200.0 / (1.0 + (x * x + y * y) / 40.0);
                (gain * v + bias).round().clamp(0.0, 255.0) as u8
            })
            .collect();
        Frame {
            width: 64,
            height: 64,
            data,
        }
    }

    fn params(illumination: Illumination) -> LkParams {
        LkParams {
            max_level: 2,
            illumination,
            ..LkParams::default()
        }
    }

    #[test]
    fn follows_a_shifted_blob() {
        let (a, b) = (blob(30.0, 1.0, 0.0), blob(31.5, 1.0, 0.0));
        for illumination in [Illumination::Plain, Illumination::GainBias] {
            let track = track_points(&a, &b, &[(27.0, 30.0)], None, &params(illumination))[0];
            assert!(track.is_tracked(), "{track:?}");
            assert!((track.x - 28.5).abs() < 0.05 && (track.y - 30.0).abs() < 0.05);
            assert!(track.residual < 2.0);
        }
    }

    #[test]
    fn gain_bias_mode_ignores_a_brightness_change() {
        let (a, b) = (blob(30.0, 1.0, 0.0), blob(31.5, 1.2, 10.0));
        let track = track_points(
            &a,
            &b,
            &[(27.0, 30.0)],
            None,
            &params(Illumination::GainBias),
        )[0];
        assert!(track.is_tracked(), "{track:?}");
        assert!((track.x - 28.5).abs() < 0.05 && (track.y - 30.0).abs() < 0.05);
    }

    #[test]
    fn a_guess_far_outside_the_frame_is_out_of_bounds() {
        let a = blob(30.0, 1.0, 0.0);
        let guess = [(200.0, 30.0)];
        let track = track_points(
            &a,
            &a,
            &[(27.0, 30.0)],
            Some(&guess),
            &params(Illumination::Plain),
        );
        assert_eq!(track[0].status, TrackStatus::OutOfBounds);
        assert_eq!(track[0].residual, 0.0);
    }

    #[test]
    fn coordinates_are_read_as_the_library_reads_them() {
        let a = blob(30.0, 1.0, 0.0);
        let p = params(Illumination::Plain);
        let nan_guess = track_points(&a, &a, &[(27.0, 30.0)], Some(&[(f32::NAN, 30.0)]), &p);
        let zero_guess = track_points(&a, &a, &[(27.0, 30.0)], Some(&[(0.0, 30.0)]), &p);
        assert_eq!(nan_guess, zero_guess);
        // A NaN point is the point 0 on that axis, inside the frame.
        let nan_point = track_points(&a, &a, &[(f32::NAN, 30.0)], None, &p)[0];
        assert_ne!(nan_point.status, TrackStatus::OutOfBounds);
        assert_eq!(as_library_reads((1e9, -1e9)), (32768.0, -32768.0));
    }

    #[test]
    fn a_guess_is_where_the_search_starts() {
        // Identical frames: starting 2 px off, LK walks back to the point.
        let a = blob(30.0, 1.0, 0.0);
        let guess = [(29.0, 31.0)];
        let track = track_points(
            &a,
            &a,
            &[(27.0, 30.0)],
            Some(&guess),
            &params(Illumination::Plain),
        )[0];
        assert!(track.is_tracked(), "{track:?}");
        assert!((track.x - 27.0).abs() < 0.02 && (track.y - 30.0).abs() < 0.02);
        assert!(track.residual < 0.5);
    }
}
