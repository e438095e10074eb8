//! Division-free scaling for the per-point 2x2 solve.
//!
//! LK divides by the determinant of the gradient matrix and by the window's intensity variance.
//! Both are constant for a point at one pyramid level, so each is turned once into a normalised
//! reciprocal (one `u64 / u64` division), and the constants an iteration multiplies by are kept
//! as [`Fractions`]: `i32` below `2^30` sharing one binary exponent. An iteration then scales its
//! own operands to `i32` ([`to_i32`], at most `2^30`), so that every product is below `2^60` and
//! a sum of two fits `i64` with room to round; a Cortex-M4 does each product in one `SMULL`.
//! Each rounding is relative `2^-28` or finer, far below the Q16 resolution of a step.

/// `1 / d` as `mantissa * 2^-shift`, with the mantissa in `[2^31, 2^32)`: 31 bits of precision.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Reciprocal {
    mantissa: u64,
    shift: u32,
}

impl Reciprocal {
    /// The reciprocal of `d`; `None` for `d == 0`.
    pub(crate) fn of(d: u128) -> Option<Self> {
        if d == 0 {
            return None;
        }
        // Normalise d to [2^127, 2^128) and keep its top 32 bits: d ~= top * 2^(96 - lz).
        let lz = d.leading_zeros();
        let top = ((d << lz) >> 96) as u64; // in [2^31, 2^32)
        if top == 1 << 31 {
            // 2^63 / top would be 2^32, one bit too many: the same value one exponent lower.
            return Some(Self {
                mantissa: 1 << 31,
                shift: 62 + 96 - lz,
            });
        }
        // 1/d ~= 2^63 / top * 2^-(63 + 96 - lz); 2^63 / top lies in (2^31, 2^32).
        let mantissa = u64::from(crate::dsp::div_2_63(top as u32));
        Some(Self {
            mantissa,
            shift: 63 + 96 - lz,
        })
    }

    /// `round(x * 2^extra / d)` for `|x| < 2^90`, saturating to the `i64` range.
    ///
    /// `extra` is the number of fractional bits wanted in the result (16 for Q16).
    #[cfg(test)]
    pub(crate) fn scale(&self, x: i128, extra: u32) -> i64 {
        // |x| < 2^90 and mantissa < 2^32 keep the product below 2^122.
        let product = x * self.mantissa as i128;
        let total = self.shift as i64 - extra as i64;
        let scaled = if total <= 0 {
            product.saturating_mul(1i128 << (-total).min(126))
        } else if total >= 127 {
            0
        } else {
            let t = total as u32;
            (product + (1i128 << (t - 1))) >> t
        };
        scaled.clamp(i64::MIN as i128, i64::MAX as i128) as i64
    }

    /// `c / d` for each `c` of `numerators` (`|c| < 2^63`) as [`Fractions`].
    pub(crate) fn fractions<const N: usize>(&self, numerators: [i64; N]) -> Fractions<N> {
        let largest = numerators.iter().fold(0, |m, c| m | c.unsigned_abs());
        let bits = (64 - largest.leading_zeros()).max(1);
        // c * mantissa < 2^(bits + 32): shifting right by bits + 2 leaves less than 2^30, and
        // at least 2^28 for the largest numerator.
        let drop = bits + 2;
        let values = numerators.map(|c| {
            let product = i128::from(c) * i128::from(self.mantissa);
            ((product + (1i128 << (drop - 1))) >> drop) as i32
        });
        Fractions {
            values,
            shift: self.shift as i32 - drop as i32,
        }
    }
}

/// Fractions `c / d` as `values[k] * 2^-shift`, each `|value| < 2^30`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Fractions<const N: usize> {
    pub values: [i32; N],
    pub shift: i32,
}

/// `x` and `y` (`|x|, |y| < 2^62`) divided by one power of two `2^e` (rounded) so that both are
/// at most `2^30` in magnitude: `(x', y', e)`.
#[inline]
pub(crate) fn to_i32(x: i64, y: i64) -> (i32, i32, u32) {
    let bits = 64 - (x.unsigned_abs() | y.unsigned_abs()).leading_zeros();
    if bits <= 30 {
        return (x as i32, y as i32, 0);
    }
    let e = bits - 30;
    let narrow = |v: i64| round_shift(v, e as i32) as i32;
    (narrow(x), narrow(y), e)
}

/// `round(v * 2^-t)` (halves up) for `|v| < 2^62`; a negative `t` shifts left, saturating far
/// beyond the `i32` range.
#[inline]
pub(crate) fn round_shift(v: i64, t: i32) -> i64 {
    match t {
        0 => v,
        // (v + 2^(t-1)) >> t without forming 2^(t-1): one variable 64-bit shift fewer.
        1..=62 => ((v >> (t - 1)) + 1) >> 1,
        63.. => 0,
        _ => v.saturating_mul(1 << (-t).min(40)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reciprocal_scales_to_31_bits() {
        let cases: [(i128, u128, u32); 7] = [
            (1, 3, 16),
            (-5_000_000_000, 7_777_777, 16),
            (123_456_789_012_345, 98_765_432_109_876_543_210, 40),
            (1 << 80, 1 << 70, 0),
            (-(1 << 60), 3, 0),
            (17, 1, 16),
            (1 << 40, 1 << 31, 16),
        ];
        for (x, d, extra) in cases {
            let exact = x as f64 * 2f64.powi(extra as i32) / d as f64;
            let got = Reciprocal::of(d).unwrap().scale(x, extra) as f64;
            let tolerance = exact.abs() * 2f64.powi(-30) + 1.0;
            assert!(
                (got - exact).abs() <= tolerance,
                "{x} * 2^{extra} / {d}: got {got}, want {exact}"
            );
        }
    }

    #[test]
    fn long_division_matches_64_bit_division() {
        let mut v = (1u32 << 31) + 1;
        let mut step = 1u32;
        while v > 1 << 31 {
            let exact = (1u64 << 63) / u64::from(v);
            assert_eq!(u64::from(crate::dsp::portable::div_2_63(v)), exact, "{v}");
            assert_eq!(u64::from(crate::dsp::div_2_63(v)), exact, "{v}");
            v = v.wrapping_add(step);
            step = step.wrapping_mul(3).wrapping_add(7) % 99_991;
        }
        for v in [
            u32::MAX,
            u32::MAX - 1,
            (1 << 31) + 2,
            0xC000_0000,
            0x8000_FFFF,
            0xFFFF_0000,
        ] {
            let exact = (1u64 << 63) / u64::from(v);
            assert_eq!(u64::from(crate::dsp::portable::div_2_63(v)), exact, "{v}");
            assert_eq!(u64::from(crate::dsp::div_2_63(v)), exact, "{v}");
        }
    }

    #[test]
    fn zero_has_no_reciprocal() {
        assert!(Reciprocal::of(0).is_none());
    }

    /// Fractions keep 28 to 30 bits for the largest numerator and are exact to 2^-28 relative.
    #[test]
    fn fractions_keep_28_to_30_bits() {
        let cases: [([i64; 3], u128); 5] = [
            ([1_000, -77, 5], 3),
            ([66_070_000_000, -12_345_678_901, 66_070_000_000], 1 << 84),
            ([1, 0, -1], 1),
            ([-(1 << 62), 1, 1 << 40], 12_345),
            ([7, 7, 7], u128::MAX >> 1),
        ];
        for (numerators, d) in cases {
            let f = Reciprocal::of(d).unwrap().fractions(numerators);
            let largest = f.values.iter().map(|v| v.unsigned_abs()).max().unwrap();
            assert!((1 << 28..1 << 30).contains(&largest), "{f:?}");
            for (c, v) in numerators.iter().zip(f.values) {
                let exact = *c as f64 / d as f64;
                let got = v as f64 * 2f64.powi(-f.shift);
                let tolerance = (largest as f64 * 2f64.powi(-f.shift)) * 2f64.powi(-28);
                assert!(
                    (got - exact).abs() <= tolerance,
                    "{c} / {d}: {got} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn operands_shrink_to_i32() {
        assert_eq!(to_i32(5, -7), (5, -7, 0));
        assert_eq!(to_i32((1 << 30) - 1, 0), ((1 << 30) - 1, 0, 0));
        assert_eq!(to_i32(1 << 30, 0), (1 << 29, 0, 1));
        assert_eq!(to_i32((1 << 52) + (1 << 22), -3), ((1 << 29) + 1, 0, 23));
        assert_eq!(to_i32((1 << 53) - 1, 0), (1 << 30, 0, 23));
        let (x, y, e) = to_i32(-(1 << 52) + 1, (1 << 40) + 12_345);
        assert_eq!((x, y, e), (-(1 << 30), 1 << 18, 22));
        assert_eq!(to_i32(-(1 << 61), 1), (-(1 << 29), 0, 32));
    }

    #[test]
    fn rounding_shifts() {
        assert_eq!(round_shift(5, 1), 3);
        assert_eq!(round_shift(-5, 1), -2);
        assert_eq!(round_shift(-6, 2), -1);
        assert_eq!(round_shift(1 << 61, 70), 0);
        assert_eq!(round_shift(3, -4), 48);
        assert_eq!(round_shift(-3, -100), -3 << 40);
        assert_eq!(round_shift(0, -100), 0);
    }
}
