//! Division-free scaling for the per-point 2x2 solve.
//!
//! LK divides by the determinant of the gradient matrix and by the window's intensity variance.
//! Both are constant for a point at one pyramid level, so each is turned once into a normalised
//! reciprocal (one `u64 / u32` division) and every iteration then multiplies: the inner loop of a
//! Cortex-M4 has no 64-bit divider.

/// `1 / d` as `mantissa * 2^-shift`, with the mantissa in `[2^31, 2^32]`: 31 bits of precision.
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
                                            // 1/d ~= 2^63 / top * 2^-(63 + 96 - lz); 2^63 / top lies in (2^31, 2^32].
        let mantissa = (1u64 << 63) / top;
        Some(Self {
            mantissa,
            shift: 63 + 96 - lz,
        })
    }

    /// `round(x * 2^extra / d)` for `|x| < 2^90`, saturating to the `i64` range.
    ///
    /// `extra` is the number of fractional bits wanted in the result (16 for Q16).
    pub(crate) fn scale(&self, x: i128, extra: u32) -> i64 {
        // |x| < 2^90 and mantissa <= 2^32 keep the product below 2^123.
        let product = x.saturating_mul(self.mantissa as i128);
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reciprocal_scales_to_31_bits() {
        let cases: [(i128, u128, u32); 6] = [
            (1, 3, 16),
            (-5_000_000_000, 7_777_777, 16),
            (123_456_789_012_345, 98_765_432_109_876_543_210, 40),
            (1 << 80, 1 << 70, 0),
            (-(1 << 60), 3, 0),
            (17, 1, 16),
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
    fn zero_has_no_reciprocal() {
        assert!(Reciprocal::of(0).is_none());
    }
}
