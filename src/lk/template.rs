//! The template: one point's window in the previous frame at one pyramid level, with everything
//! that stays fixed while LK iterates (Bouguet's method: the gradient matrix is built and inverted
//! once per point and level; each iteration only resamples the next frame).
//!
//! # Illumination model
//!
//! With [`Illumination::GainBias`] the next window is modelled as `J = a * I + b` plus the motion.
//! Each iteration fits the gain `a` and bias `b` to the current window by least squares, which
//! only needs four sums over `J` (`ΣJ`, `ΣJI`, `ΣJIx`, `ΣJIy`), and LK then drives the
//! illumination-corrected residual `J - a I - b` to zero. A brightness change between frames
//! (auto-exposure, a cloud) therefore moves no point.
//!
//! # Integer widths
//!
//! Window sums are exact: intensities are grey x 32 (`<= 8160`), gradients `|Ix| <= 4080`, and
//! each set of window loops proves its own accumulator widths (`flat.rs`, `rows.rs`). Over the
//! largest window (`n = 63 x 63 = 3969 < 2^12`) the sums are bounded by
//!
//! - `|ΣJ·Ix|, |ΣI·Ix| <= n * 8160 * 4080 < 2^37`, `ΣJI, ΣI² <= n * 8160^2 < 2^38`,
//! - `ΣJ, ΣI <= n * 8160 < 2^25`, `|ΣIx| <= n * 4080 < 2^24`, `gxx, gyy <= n * 4080^2 < 2^36`.
//!
//! An iteration's products of sums therefore fit `i64`: `n ΣJ·Ix - ΣJ ΣIx` and
//! `n ΣI·Ix - ΣI ΣIx` below `2^50`, the gain covariance below `2^51`, the mismatch `b` below
//! `2^53` (see [`Template::step`]). Only the template's determinant (`< 2^72`, times `n` in
//! gain-bias mode) and variance need `i128`, once per template.

use core::marker::PhantomData;

use super::correlation::Correlations;
use super::wide::{round_shift, to_i32, Fractions, Reciprocal};
use super::window::{Layout, Loops, TemplateBuffers, WindowOrigin, INTENSITY_BITS};
use super::Illumination;
use crate::frame::ImageView;

/// The gain estimate is clamped to `[1/4, 4]` (Q16): no lighting change between two frames of a
/// flight is larger, and the clamp keeps a mismatched window from producing a wild step.
const GAIN_MIN: i64 = 1 << 14;
const GAIN_MAX: i64 = 1 << 18;

/// Ridge term of the gain fit, as a variance per pixel in (grey x 32)^2: (2 grey levels)^2.
///
/// On a low-contrast window the least-squares gain is decided by noise and jumps between
/// iterations, which keeps LK from converging. Adding this variance to both the covariance and
/// the variance pulls the gain towards 1 on windows whose contrast is comparable to sensor noise
/// (where a gain change is invisible anyway; the bias still absorbs the offset) and leaves it
/// unchanged on textured windows.
const GAIN_RIDGE: i64 = (2 * 32) * (2 * 32);
const ONE: i64 = 1 << 16;

/// Window sums of the template that every iteration needs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct TemplateSums {
    /// Gradient matrix `[gxx gxy; gxy gyy]`.
    pub gxx: i64,
    pub gxy: i64,
    pub gyy: i64,
    /// `ΣI`, `ΣI²`, `ΣIx`, `ΣIy`, `ΣI·Ix`, `ΣI·Iy`.
    pub si: i64,
    pub sii: i64,
    pub sx: i64,
    pub sy: i64,
    pub six: i64,
    pub siy: i64,
}

impl TemplateSums {
    /// The sums over a template's intensity and derivative buffers (padding holds zeros),
    /// accumulated in 32 bits over `CHUNK` values at a time and widened to 64 bits between
    /// chunks: exact for chunks of up to 64 values at the extremes (tests in `flat` and
    /// `rows`). The sums of the tests' reference loops (`flat`).
    #[cfg(test)]
    pub(crate) fn in_chunks<const CHUNK: usize>(intensity: &[i16], dx: &[i16], dy: &[i16]) -> Self {
        let mut s = Self::default();
        let chunks = intensity
            .chunks(CHUNK)
            .zip(dx.chunks(CHUNK).zip(dy.chunks(CHUNK)));
        for (i_chunk, (x_chunk, y_chunk)) in chunks {
            let (mut gxx, mut gxy, mut gyy) = (0i32, 0i32, 0i32);
            let (mut si, mut sii, mut sx, mut sy, mut six, mut siy) =
                (0i32, 0u32, 0i32, 0i32, 0i32, 0i32);
            for ((&i, &gx), &gy) in i_chunk.iter().zip(x_chunk).zip(y_chunk) {
                let (i, gx, gy) = (i32::from(i), i32::from(gx), i32::from(gy));
                gxx += gx * gx;
                gxy += gx * gy;
                gyy += gy * gy;
                si += i;
                sii = sii.wrapping_add((i * i) as u32);
                sx += gx;
                sy += gy;
                six += i * gx;
                siy += i * gy;
            }
            s.gxx += i64::from(gxx);
            s.gxy += i64::from(gxy);
            s.gyy += i64::from(gyy);
            s.si += i64::from(si);
            s.sii += i64::from(sii);
            s.sx += i64::from(sx);
            s.sy += i64::from(sy);
            s.six += i64::from(six);
            s.siy += i64::from(siy);
        }
        s
    }
}

/// Window sums that involve the next frame `J`: `ΣJ`, `ΣJI` (gain and bias only), `ΣJ·Ix`,
/// `ΣJ·Iy`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct MatchSums {
    pub sj: i64,
    pub sji: i64,
    pub sjx: i64,
    pub sjy: i64,
}

/// Why a template cannot be used at this level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TemplateError {
    /// The smaller eigenvalue of the gradient matrix is below the threshold.
    LowTexture,
}

/// One LK update: the Q16 step to add to the position.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Step {
    pub dx: i32,
    pub dy: i32,
}

/// A point's window at one level with its precomputed solve, for the window loops `L`.
pub(crate) struct Template<'s, L> {
    layout: Layout,
    /// The template intensities and gradients, laid out like `J` (padding zero).
    buffers: TemplateBuffers<'s>,
    sums: TemplateSums,
    illumination: Illumination,
    /// Window area `n`.
    n: i64,
    /// `adj(G) / det(G)` (plain) or `adj(G) / (n det(G))` (gain and bias): `[gyy, gxy, gxx]`
    /// over the determinant.
    inverse: Fractions<3>,
    /// `1 / (n ΣI² - (ΣI)² + n² ridge)`, for the gain fit.
    variance: Option<Fractions<1>>,
    /// `n ΣI·Ix - ΣI ΣIx` and the same for `y` (gain and bias), split for exact `i64` products
    /// with the gain: `(value >> 16, value & 0xFFFF)`.
    centred_ig: [(i64, i64); 2],
    loops: PhantomData<L>,
}

impl<'s, L: Loops> Template<'s, L> {
    /// Builds the template from its intensities and derivatives (padding cleared) and their
    /// window sums.
    ///
    /// `min_eigen` is the smallest acceptable eigenvalue of the gradient matrix in its integer
    /// scale (see [`super::LucasKanade`]).
    pub(crate) fn new(
        buffers: TemplateBuffers<'s>,
        sums: TemplateSums,
        layout: Layout,
        illumination: Illumination,
        min_eigen: u64,
    ) -> Result<Self, TemplateError> {
        if !min_eigenvalue_at_least(&sums, min_eigen) {
            return Err(TemplateError::LowTexture);
        }
        let det = i128::from(sums.gxx) * i128::from(sums.gyy) - i128::from(sums.gxy).pow(2);
        let n = (layout.win * layout.win) as i64;
        let scaled_det = match illumination {
            Illumination::Plain => det,
            Illumination::GainBias => det * i128::from(n),
        };
        let inverse = u128::try_from(scaled_det)
            .ok()
            .and_then(Reciprocal::of)
            .ok_or(TemplateError::LowTexture)?
            .fractions([sums.gyy, sums.gxy, sums.gxx]);
        let variance_n = i128::from(n) * i128::from(sums.sii) - i128::from(sums.si).pow(2);
        let ridge = i128::from(n * n * GAIN_RIDGE);
        let variance = u128::try_from(variance_n + ridge)
            .ok()
            .and_then(Reciprocal::of)
            .map(|r| r.fractions([1]));
        let centred = |sig: i64, sg: i64| {
            let ig = n * sig - sums.si * sg;
            (ig >> 16, ig & 0xFFFF)
        };
        Ok(Self {
            layout,
            buffers,
            sums,
            illumination,
            n,
            inverse,
            variance,
            centred_ig: [centred(sums.six, sums.sx), centred(sums.siy, sums.sy)],
            loops: PhantomData,
        })
    }

    /// The layout of the template's buffers.
    pub(crate) fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The template's buffers.
    pub(crate) fn buffers(&self) -> &TemplateBuffers<'s> {
        &self.buffers
    }

    /// One LK step for the next frame's window with the correlations `c` of its integer
    /// position and the bilinear weights `w` of its sub-pixel offset.
    pub(crate) fn step(&self, c: &Correlations, w: [i16; 4]) -> Step {
        let m = c.match_sums(w);
        let (bx, by) = self.mismatch(&m);
        // delta = -G^-1 b, with G^-1 = adj(G) / det(G); b scaled to i32 so that each product
        // with a coefficient (< 2^30) stays below 2^60.
        let (bx, by, e) = to_i32(bx, by);
        let [yy, xy, xx] = self.inverse.values;
        let product = |c: i32, b: i32| i64::from(c) * i64::from(b);
        let to_step = |u: i64| {
            let v = -round_shift(u, self.inverse.shift - 16 - e as i32);
            v.clamp(-(i32::MAX as i64), i32::MAX as i64) as i32
        };
        Step {
            dx: to_step(product(yy, bx) - product(xy, by)),
            dy: to_step(product(xx, by) - product(xy, bx)),
        }
    }

    /// The mismatch vector `b = Σ residual ∇I`, scaled by `n` in gain-bias mode; `|b| < 2^53`.
    fn mismatch(&self, m: &MatchSums) -> (i64, i64) {
        let s = &self.sums;
        match self.illumination {
            // Each term below 2^37.
            Illumination::Plain => (m.sjx - s.six, m.sjy - s.siy),
            Illumination::GainBias => {
                let (n, gain) = (self.n, self.gain(m));
                // n ΣJ·Ig - ΣJ ΣIg - gain (n ΣI·Ig - ΣI ΣIg) / 2^16: the first two terms below
                // 2^50; the gain (<= 2^18) times the split centred sum below 2^52 and 2^34.
                let centred = |sjg: i64, sg: i64, (ig_high, ig_low): (i64, i64)| {
                    let jg = n * sjg - m.sj * sg;
                    jg - (gain * ig_high + ((gain * ig_low) >> 16))
                };
                let [igx, igy] = self.centred_ig;
                (centred(m.sjx, s.sx, igx), centred(m.sjy, s.sy, igy))
            }
        }
    }

    /// Least-squares gain of `J ~ a I + b` over the window with the [`GAIN_RIDGE`] term, Q16,
    /// clamped; 1 in plain mode.
    fn gain(&self, m: &MatchSums) -> i64 {
        let Some(variance) = self.variance else {
            return ONE;
        };
        if self.illumination == Illumination::Plain {
            return ONE;
        }
        let n = self.n;
        // n ΣJI - ΣJ ΣI + n² ridge: each term below 2^50.
        let covariance = n * m.sji - m.sj * self.sums.si + n * n * GAIN_RIDGE;
        let (covariance, _, e) = to_i32(covariance, 0);
        let [inverse] = variance.values;
        let gain = i64::from(covariance) * i64::from(inverse);
        round_shift(gain, variance.shift - 16 - e as i32).clamp(GAIN_MIN, GAIN_MAX)
    }

    /// Mean absolute residual over the next frame's window at `origin` in grey levels (Q16 raw
    /// bits), after the gain and bias correction in gain-bias mode; `c` are the window's
    /// correlations, `source` holds the source block they were computed from (see
    /// [`Loops::abs_residual`]) and `j` is scratch.
    pub(crate) fn residual(
        &self,
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        c: &Correlations,
        (source, j): (&mut [i16], &mut [i16]),
    ) -> i32 {
        let m = c.match_sums(origin.w);
        let gain = self.gain(&m);
        let n = self.n;
        // bias (Q16, grey x 32) = (ΣJ - a ΣI) / n.
        let bias = match self.illumination {
            Illumination::Plain => 0,
            Illumination::GainBias => ((m.sj << 16) - gain * self.sums.si) / n,
        };
        // The gain is at most 2^18 and I at most 8160, J at most 8160: J 2^16 (< 2^29) minus
        // a I (< 2^31) is exact in 32 bits, and so is the bias, an average of such values;
        // their distance fits 32 bits unsigned, and a row of at most 63 of them 38 bits.
        let correction = Correction {
            gain: gain as i32,
            bias: bias.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
        };
        let total = L::abs_residual(
            frame,
            origin,
            &self.layout,
            (source, j),
            self.buffers.intensity,
            correction,
        );
        let total = total as i64;
        // Drop the 5 intensity bits: grey levels, Q16.
        let mean = total / (n << INTENSITY_BITS);
        mean.min(i32::MAX as i64) as i32
    }
}

/// The illumination correction of a residual, `J 2^16 - gain I - bias` (Q16 gain, bias in
/// Q16 grey x 32).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Correction {
    pub gain: i32,
    pub bias: i32,
}

impl Correction {
    /// `|J 2^16 - gain I - bias|` of one sample `j` against the template's `i`.
    #[inline(always)]
    pub(crate) fn distance(self, i: i16, j: i16) -> u32 {
        let corrected = (i32::from(j) << 16) - self.gain * i32::from(i);
        corrected.abs_diff(self.bias)
    }
}

/// The sum of [`Correction::distance`] over a window's sampled values `j` and the template's
/// intensities, laid out alike.
pub(crate) fn abs_residual_of(layout: &Layout, intensity: &[i16], j: &[i16], c: Correction) -> u64 {
    let rows = layout.rows(intensity).zip(layout.rows(j));
    rows.take(layout.win)
        .map(|(i_row, j_row)| -> u64 {
            i_row
                .iter()
                .zip(j_row)
                .map(|(&i, &jv)| u64::from(c.distance(i, jv)))
                .sum()
        })
        .sum()
}

/// `λ_min(G) >= tau` without a square root: both diagonal entries reach `tau` and
/// `(gxx - tau)(gyy - tau) >= gxy²`.
fn min_eigenvalue_at_least(s: &TemplateSums, tau: u64) -> bool {
    let small = |v: i64| v.unsigned_abs() < 1 << 31;
    if small(s.gxx) && small(s.gxy) && small(s.gyy) && tau < 1 << 31 {
        // Every product below 2^62: the same test in 64 bits.
        let (a, b, c, tau) = (s.gxx, s.gxy, s.gyy, tau as i64);
        return a >= tau && c >= tau && (a - tau) * (c - tau) >= b * b && a * c - b * b > 0;
    }
    let tau = tau as i128;
    let (a, b, c) = (s.gxx as i128, s.gxy as i128, s.gyy as i128);
    let det = a * c - b * b;
    a >= tau && c >= tau && (a - tau) * (c - tau) >= b * b && det > 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenvalue_test_matches_closed_form() {
        let cases = [
            (100, 0, 100),
            (100, 99, 100),
            (50, -20, 400),
            (1000, 10, 10),
        ];
        // At 2^26 the sums take the 128-bit path, at 1 the 64-bit one.
        for ((a, b, c), scale) in cases.into_iter().flat_map(|g| [(g, 1), (g, 1 << 26)]) {
            let s = TemplateSums {
                gxx: a * scale,
                gxy: b * scale,
                gyy: c * scale,
                ..Default::default()
            };
            let (a, b, c) = (a as f64, b as f64, c as f64);
            let lambda = (a + c - ((a - c) * (a - c) + 4.0 * b * b).sqrt()) / 2.0;
            for tau in [0u64, 1, 5, 9, 10, 11, 30, 49, 50, 51, 99, 100, 101] {
                assert_eq!(
                    min_eigenvalue_at_least(&s, tau * scale as u64),
                    lambda >= tau as f64 && a * c - b * b > 0.0,
                    "G = [{a} {b}; {b} {c}] * {scale}, tau {tau}"
                );
            }
        }
    }
}
