//! The match sums of an LK iteration from sums over raw source pixels.
//!
//! An iteration needs four window sums of the next frame's bilinear samples `J` against the
//! template: `ΣJ`, `ΣJ·I`, `ΣJ·Ix` and `ΣJ·Iy`. A sample is a weighted sum of four source pixels,
//! the pixel under it and its right, lower and lower-right neighbours,
//! `J(k) = Σ_q w_q P(k + o_q) / 2^9` (grey x 32, weights of 14 bits), so for any template array
//! `T`
//!
//! `ΣJ·T = Σ_q w_q C_q[T] / 2^9`, with `C_q[T] = Σ_k P(k + o_q) T(k)`.
//!
//! The [`Correlations`] `C_q` depend only on the window's integer position, the weights only on
//! its sub-pixel offset. LK's steps after the first are mostly small, so most iterations land on
//! the same integer position as the one before (about three in four on natural images); they
//! reuse its correlations and cost a few multiplies instead of a pass over the window. The
//! samples are used exactly, rounded once per sum instead of once per sample.
//!
//! # Integer widths
//!
//! Products of a pixel and a template value are at most `255 * 8160 = 2_080_800 < 2^21`; one
//! row of the largest window (63 values) sums to less than `2^28` and the whole window
//! (`3969` values) to less than `2^33`. Weighted by `w_q` (summing to `2^14`), a combination is
//! below `2^47`.

use super::template::MatchSums;
use super::window::INTENSITY_BITS;
use super::window::WEIGHT_BITS;

/// Sums of the source pixels under a window against the template, for each bilinear neighbour
/// `q` (the pixel, right, below, below-right): `sums[q] = [ΣP, ΣP·I, ΣP·Ix, ΣP·Iy]`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Correlations {
    pub sums: [[i64; 4]; 4],
}

impl Correlations {
    /// The match sums of the window sampled with bilinear weights `w` (as in
    /// [`super::window::WindowOrigin`]), each rounded to the nearest integer.
    pub(crate) fn match_sums(&self, w: [i16; 4]) -> MatchSums {
        let shift = WEIGHT_BITS - INTENSITY_BITS;
        let combined = |t: usize| {
            let sum: i64 = w
                .iter()
                .zip(&self.sums)
                .map(|(&w, sums)| i64::from(w) * sums[t])
                .sum();
            (sum + (1 << (shift - 1))) >> shift
        };
        MatchSums {
            sj: combined(0),
            sji: combined(1),
            sjx: combined(2),
            sjy: combined(3),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The combination equals the window sums of the exact bilinear samples, computed sample by
    /// sample in 128 bits and rounded once.
    #[test]
    fn combination_equals_sums_of_exact_samples() {
        let mut state = 12_345u32;
        let mut next = |range: i32| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as i32 % range
        };
        const SIDE: usize = 7;
        let pixels: [[i32; SIDE + 1]; SIDE + 1] =
            core::array::from_fn(|_| core::array::from_fn(|_| next(256)));
        let templates: [[i32; SIDE * SIDE]; 4] = [
            [1; SIDE * SIDE],
            core::array::from_fn(|_| next(8161)),
            core::array::from_fn(|_| next(8161) - 4080),
            core::array::from_fn(|_| next(8161) - 4080),
        ];
        let offsets = [(0, 0), (0, 1), (1, 0), (1, 1)];
        let mut c = Correlations::default();
        for (q, (dy, dx)) in offsets.into_iter().enumerate() {
            for (t, template) in templates.iter().enumerate() {
                c.sums[q][t] = (0..SIDE * SIDE)
                    .map(|k| i64::from(pixels[k / SIDE + dy][k % SIDE + dx] * template[k]))
                    .sum();
            }
        }
        for w in [
            [16384, 0, 0, 0],
            [4096, 4096, 4096, 4096],
            [9000, 3000, 3384, 1000],
        ] {
            let m = c.match_sums(w);
            let exact = |t: usize| {
                let total: i128 = (0..SIDE * SIDE)
                    .map(|k| {
                        let (r, col) = (k / SIDE, k % SIDE);
                        let j: i128 = offsets
                            .iter()
                            .zip(w)
                            .map(|(&(dy, dx), w)| {
                                i128::from(w) * i128::from(pixels[r + dy][col + dx])
                            })
                            .sum();
                        j * i128::from(templates[t][k])
                    })
                    .sum();
                ((total + 256) >> 9) as i64
            };
            assert_eq!(
                [m.sj, m.sji, m.sjx, m.sjy],
                [0, 1, 2, 3].map(exact),
                "{w:?}"
            );
        }
    }
}
