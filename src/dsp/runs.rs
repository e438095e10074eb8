//! Kernels over runs of `i16` values, the innermost operations of the LK window loops: dot
//! products of one run with three others, the template's window sums, the sum of a run, and
//! rows of bilinear samples.
//!
//! Each kernel has one definition, in [`portable`]: plain Rust built on [`super::smlad`], which a
//! Cortex-M4 runs as SMLAD (two multiply-accumulates an instruction) and other targets as two
//! multiplies. x86-64 runs SSE2 code instead ([`super::sse2`]): PMADDWD is SMLAD four lanes
//! wide, and SSE2 is part of the x86-64 baseline, so every x86-64 machine runs it. The SSE2
//! versions return what the portable ones return, bit for bit, on every input (the tests below
//! compare them on seeded random runs and the extreme values): sums wrap modulo 2^32 as SMLAD's
//! do, and a sum modulo 2^32 does not depend on the order of its terms, so four lanes added
//! at the end give the bits one accumulator does. Where a caller's sums are exact (`lk` proves
//! its bounds), so are these. Inputs the SSE2 code is not shaped for (runs of different
//! lengths, weights outside `i16`) go to the portable code.
//!
//! Other targets (AArch64 among them) run the portable code, which LLVM vectorises where it
//! can.

use super::smlad;

/// Fractional bits of the bilinear weights of [`bilinear`].
pub(crate) const WEIGHT_BITS: u32 = 14;
/// Fractional bits kept in a bilinear sample (grey x 32 for 8-bit pixels).
pub(crate) const SAMPLE_BITS: u32 = 5;

/// The halves `(1, 1)`: SMLAD with it sums a pair.
pub(crate) const ONES: u32 = 0x0001_0001;

/// Two neighbouring values as one word, the first in the low half: the operand of SMLAD, and
/// one 32-bit load on the Cortex-M4, which reads words at any even address. A single value
/// (the end of an odd run) pairs with a zero.
#[inline(always)]
pub(crate) fn pair(v: &[i16]) -> u32 {
    match *v {
        [lo, hi] => u32::from(lo as u16) | (u32::from(hi as u16) << 16),
        [lo] => u32::from(lo as u16),
        _ => 0,
    }
}

/// The pairs of `v` and its odd last value, if any, as a pair with a zero.
#[inline(always)]
pub(crate) fn pairs(v: &[i16]) -> (core::slice::ChunksExact<'_, i16>, u32) {
    let pairs = v.chunks_exact(2);
    let tail = pair(pairs.remainder());
    (pairs, tail)
}

/// One bilinear sample, `(w00 a + w01 b + w10 c + w11 d + 2^8) >> 9` truncated to `i16`, from
/// the pixel, its right neighbour, the one below and the one below-right, with weights of
/// [`WEIGHT_BITS`] summing to `2^14`: grey x 32 for 8-bit pixels, rounded to nearest. Every
/// sample of the LK windows is rounded exactly this way. The sum wraps modulo 2^32 (it cannot
/// for weights summing to `2^14` and pixels of 8 bits: it is below `2^22`).
#[inline(always)]
pub(crate) fn bilinear([w00, w01, w10, w11]: [i32; 4], a: i32, b: i32, c: i32, d: i32) -> i16 {
    let round = 1 << (WEIGHT_BITS - SAMPLE_BITS - 1);
    let sum = w00
        .wrapping_mul(a)
        .wrapping_add(w01.wrapping_mul(b))
        .wrapping_add(w10.wrapping_mul(c))
        .wrapping_add(w11.wrapping_mul(d));
    // Truncating, as `as` does: the samples of 8-bit pixels are at most 8160.
    #[allow(clippy::cast_possible_truncation)]
    let sample = (sum.wrapping_add(round) >> (WEIGHT_BITS - SAMPLE_BITS)) as i16;
    sample
}

/// Scharr's smoothing across a derivative, `3 a + 10 b + 3 c`: the kernel of every Scharr sum
/// of the LK window loops. A derivative is the smoothing of three differences across it, or
/// (separably) the difference of two smoothings. Wrapping (it cannot for samples of 8-bit
/// pixels: `16 * 8160 < 2^17`).
#[inline(always)]
pub(crate) fn scharr_smooth(a: i32, b: i32, c: i32) -> i32 {
    a.wrapping_add(c)
        .wrapping_mul(3)
        .wrapping_add(b.wrapping_mul(10))
}

/// Drops the [`SAMPLE_BITS`] of a Scharr sum of samples (`|s| <= 16 * 8160`), rounding, and
/// truncates to `i16`: the result is at the Scharr gain of 32 per grey level (`<= 4080`).
#[inline(always)]
pub(crate) fn rescale(s: i32) -> i16 {
    // Truncating, as `as` does: the sums of samples of 8-bit pixels give at most 4080.
    #[allow(clippy::cast_possible_truncation)]
    let value = (s.wrapping_add(1 << (SAMPLE_BITS - 1)) >> SAMPLE_BITS) as i16;
    value
}

/// `[Σ a b0, Σ a b1, Σ a b2]` over runs of one length, modulo 2^32: each value of `a` loaded
/// once for three multiply-accumulates.
#[inline(always)]
pub(crate) fn dot3(a: &[i16], b: [&[i16]; 3]) -> [i32; 3] {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::dot3(a, b)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::dot3(a, b)
    }
}

/// `[Σ gx², Σ gx gy, Σ gy², Σ gx, Σ gy]` over runs of one length, modulo 2^32.
#[inline(always)]
pub(crate) fn gradient_sums(gx: &[i16], gy: &[i16]) -> [i32; 5] {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::gradient_sums(gx, gy)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::gradient_sums(gx, gy)
    }
}

/// `[Σ i, Σ i², Σ i gx, Σ i gy]` over runs of one length, modulo 2^32.
#[inline(always)]
pub(crate) fn intensity_sums(i: &[i16], gx: &[i16], gy: &[i16]) -> [i32; 4] {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::intensity_sums(i, gx, gy)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::intensity_sums(i, gx, gy)
    }
}

/// `Σ v`, modulo 2^32.
#[inline(always)]
pub(crate) fn sum(v: &[i16]) -> i32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::sum(v)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::sum(v)
    }
}

/// One row of [`bilinear`] samples: `out[k]` from `top[k]`, `top[k + 1]`, `bottom[k]` and
/// `bottom[k + 1]`, for every `k` that both rows reach (rows of `out.len() + 1` values fill
/// `out`; samples they do not reach are left alone).
#[inline(always)]
pub(crate) fn bilinear_row(w: &[i32; 4], top: &[i16], bottom: &[i16], out: &mut [i16]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::bilinear_row(w, top, bottom, out);
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::bilinear_row(w, top, bottom, out);
    }
}

/// [`bilinear_row`] for a row of `inner.len() + 2` samples that also stores the samples but
/// the first and the last in `inner` (a template patch row and its template row).
#[inline(always)]
pub(crate) fn bilinear_row_twice(
    w: &[i32; 4],
    top: &[i16],
    bottom: &[i16],
    out: &mut [i16],
    inner: &mut [i16],
) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::bilinear_row_twice(w, top, bottom, out, inner);
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::bilinear_row_twice(w, top, bottom, out, inner);
    }
}

/// One row of Scharr derivatives from three rows of samples (`up`, `mid`, `down`): `dx[k]` and
/// `dy[k]` are those of the sample at column `k + 1`, the [`rescale`]d horizontal and vertical
/// Scharr sums, for every `k` the rows reach (rows of `dx.len() + 2` values fill `dx` and `dy`;
/// outputs they do not reach are left alone).
#[inline(always)]
pub(crate) fn scharr_row(up: &[i16], mid: &[i16], down: &[i16], dx: &mut [i16], dy: &mut [i16]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::scharr_row(up, mid, down, dx, dy);
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::scharr_row(up, mid, down, dx, dy);
    }
}

/// The kernels in plain Rust over [`smlad`]: the reference, and the code of every target but
/// x86-64.
///
/// Each loop is its own function, not inlined: a Cortex-M4 has thirteen free registers, and a
/// loop inlined into a larger function spills its accumulators and pointers. The loops over
/// pairs end on two conditions (or zip several runs), which keeps LLVM from unrolling them.
pub(crate) mod portable {
    use super::{bilinear, pair, pairs, rescale, scharr_smooth, smlad, ONES};

    /// [`super::dot3`]. An odd last value pairs with a zero.
    #[inline(never)]
    pub(crate) fn dot3(a: &[i16], [b0, b1, b2]: [&[i16]; 3]) -> [i32; 3] {
        let ((a, at), (b0, t0), (b1, t1), (b2, t2)) = (pairs(a), pairs(b0), pairs(b1), pairs(b2));
        let (mut s0, mut s1, mut s2) = (smlad(at, t0, 0), smlad(at, t1, 0), smlad(at, t2, 0));
        for ((x, y0), (y1, y2)) in a.zip(b0).zip(b1.zip(b2)) {
            let x = pair(x);
            s0 = smlad(x, pair(y0), s0);
            s1 = smlad(x, pair(y1), s1);
            s2 = smlad(x, pair(y2), s2);
        }
        [s0, s1, s2]
    }

    /// [`super::gradient_sums`].
    #[inline(never)]
    pub(crate) fn gradient_sums(gx: &[i16], gy: &[i16]) -> [i32; 5] {
        let ((gx, xt), (gy, yt)) = (pairs(gx), pairs(gy));
        let sums = |x: u32, y: u32, s: [i32; 5]| {
            [
                smlad(x, x, s[0]),
                smlad(x, y, s[1]),
                smlad(y, y, s[2]),
                smlad(x, ONES, s[3]),
                smlad(y, ONES, s[4]),
            ]
        };
        let mut s = sums(xt, yt, [0; 5]);
        for (x, y) in gx.zip(gy) {
            s = sums(pair(x), pair(y), s);
        }
        s
    }

    /// [`super::intensity_sums`].
    #[inline(never)]
    pub(crate) fn intensity_sums(i: &[i16], gx: &[i16], gy: &[i16]) -> [i32; 4] {
        let ((i, it), (gx, xt), (gy, yt)) = (pairs(i), pairs(gx), pairs(gy));
        let sums = |v: u32, x: u32, y: u32, s: [i32; 4]| {
            [
                smlad(v, ONES, s[0]),
                smlad(v, v, s[1]),
                smlad(v, x, s[2]),
                smlad(v, y, s[3]),
            ]
        };
        let mut s = sums(it, xt, yt, [0; 4]);
        for (v, (x, y)) in i.zip(gx.zip(gy)) {
            s = sums(pair(v), pair(x), pair(y), s);
        }
        s
    }

    /// [`super::sum`], by pairs.
    #[inline(always)]
    pub(crate) fn sum(v: &[i16]) -> i32 {
        let (twos, tail) = pairs(v);
        twos.fold(smlad(tail, ONES, 0), |sum, two| smlad(pair(two), ONES, sum))
    }

    /// [`super::bilinear_row`].
    ///
    /// Each pixel's right neighbour is the next sample's left one and stays in a register. The
    /// loop stops at the end of `out` or of the shorter source row: with two exits LLVM keeps
    /// it rolled. Not inlined, so that the weights stay in registers.
    #[inline(never)]
    pub(crate) fn bilinear_row(w: &[i32; 4], top: &[i16], bottom: &[i16], out: &mut [i16]) {
        let w = *w;
        let (Some((&a, top)), Some((&c, bottom))) = (top.split_first(), bottom.split_first())
        else {
            return;
        };
        let (mut a, mut c) = (a.into(), c.into());
        for (k, o) in out.iter_mut().enumerate() {
            let (Some(&b), Some(&d)) = (top.get(k), bottom.get(k)) else {
                break;
            };
            let (b, d) = (b.into(), d.into());
            *o = bilinear(w, a, b, c, d);
            (a, c) = (b, d);
        }
    }

    /// [`super::scharr_row`]. Separable: each column's vertical smoothing `3 u + 10 m + 3 d`
    /// and difference `d - u` are computed once and carried to the next two outputs, which
    /// then need one column of loads each.
    #[inline(never)]
    pub(crate) fn scharr_row(
        up: &[i16],
        mid: &[i16],
        down: &[i16],
        dx: &mut [i16],
        dy: &mut [i16],
    ) {
        let mut columns = up.iter().zip(mid).zip(down).map(|((&u, &m), &d)| {
            let [u, m, d] = [u, m, d].map(i32::from);
            (scharr_smooth(u, m, d), d.wrapping_sub(u))
        });
        let (Some((mut v0, mut h0)), Some((mut v1, mut h1))) = (columns.next(), columns.next())
        else {
            return;
        };
        for ((gx, gy), (v2, h2)) in dx.iter_mut().zip(dy.iter_mut()).zip(columns) {
            *gx = rescale(v2.wrapping_sub(v0));
            *gy = rescale(scharr_smooth(h0, h1, h2));
            (v0, h0, v1, h1) = (v1, h1, v2, h2);
        }
    }

    /// [`super::bilinear_row_twice`]: each inner sample is stored twice, which costs less
    /// than copying the row afterwards.
    #[inline(never)]
    pub(crate) fn bilinear_row_twice(
        w: &[i32; 4],
        top: &[i16],
        bottom: &[i16],
        out: &mut [i16],
        inner: &mut [i16],
    ) {
        let w = *w;
        let n = inner.len();
        let (Some((first, rest)), Some(&[a, b]), Some(&[c, d])) =
            (out.split_first_mut(), top.get(..2), bottom.get(..2))
        else {
            return;
        };
        *first = bilinear(w, a.into(), b.into(), c.into(), d.into());
        let (mut a, mut c) = (b.into(), d.into());
        let (middle, last) = rest.split_at_mut(n.min(rest.len()));
        // Both rows are at least two long, checked above.
        let (top, bottom) = (top.get(2..).unwrap_or(&[]), bottom.get(2..).unwrap_or(&[]));
        for (k, (o, i)) in middle.iter_mut().zip(inner.iter_mut()).enumerate() {
            let (Some(&b), Some(&d)) = (top.get(k), bottom.get(k)) else {
                break;
            };
            let (b, d) = (b.into(), d.into());
            let v = bilinear(w, a, b, c, d);
            (*o, *i) = (v, v);
            (a, c) = (b, d);
        }
        if let (Some(o), Some(&b), Some(&d)) = (last.first_mut(), top.get(n), bottom.get(n)) {
            *o = bilinear(w, a, b.into(), c, d.into());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded xorshift stream of `i16` values: a third at the extremes of the range and of
    /// 8-bit pixels (`-32768`, `32767`, `0`, `255`, `±1`), the rest uniform.
    struct Values(u32);

    impl Values {
        fn next(&mut self) -> i16 {
            let mut x = self.0;
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            self.0 = x;
            match x % 24 {
                0 => i16::MIN,
                1 => i16::MAX,
                2 => 0,
                3 => 255,
                4 => 1,
                5 => -1,
                6 | 7 => (x >> 16) as i16 & 0xFF,
                _ => (x >> 16) as i16,
            }
        }

        fn run<const N: usize>(&mut self, len: usize) -> [i16; N] {
            let mut run = [0i16; N];
            run.iter_mut().take(len).for_each(|v| *v = self.next());
            run
        }
    }

    /// Lengths around the SSE2 blocks of 8 values and the LK runs (a 21 px window's 462).
    const LENGTHS: [usize; 14] = [0, 1, 2, 7, 8, 9, 15, 16, 17, 63, 64, 90, 462, 1024];

    #[test]
    fn dot3_agrees_with_the_reference() {
        let mut v = Values(0x1234_5678);
        for _ in 0..40 {
            for len in LENGTHS {
                let a = v.run::<1024>(len);
                let b: [[i16; 1024]; 3] = core::array::from_fn(|_| v.run(len));
                let b = b.each_ref().map(|b| &b[..len]);
                let exact = b.map(|b| {
                    let s: i64 = a
                        .iter()
                        .zip(b)
                        .map(|(&x, &y)| i64::from(x) * i64::from(y))
                        .sum();
                    s as i32
                });
                assert_eq!(portable::dot3(&a[..len], b), exact, "{len}");
                assert_eq!(dot3(&a[..len], b), exact, "{len}");
            }
        }
        // The one pair that overflows SMLAD and PMADDWD alike, and runs of unequal lengths.
        let min = [i16::MIN; 24];
        assert_eq!(dot3(&min, [&min; 3]), portable::dot3(&min, [&min; 3]));
        let a = v.run::<40>(40);
        let b = v.run::<40>(40);
        for (la, lb) in [(40, 33), (17, 40), (9, 8), (0, 5)] {
            let b = [&b[..lb], &b[..la.min(lb)], &b[..]];
            assert_eq!(dot3(&a[..la], b), portable::dot3(&a[..la], b), "{la} {lb}");
        }
    }

    #[test]
    fn template_sums_agree_with_the_reference() {
        let mut v = Values(0xBEEF);
        for _ in 0..200 {
            for len in LENGTHS {
                let [i, gx, gy] = core::array::from_fn::<[i16; 1024], 3, _>(|_| v.run(len));
                let (i, gx, gy) = (&i[..len], &gx[..len], &gy[..len]);
                let wide = |f: &dyn Fn(usize) -> i64| (0..len).map(f).sum::<i64>() as i32;
                let (x, y, t) = (
                    |k: usize| i64::from(gx[k]),
                    |k: usize| i64::from(gy[k]),
                    |k: usize| i64::from(i[k]),
                );
                let gradients = [
                    wide(&|k| x(k) * x(k)),
                    wide(&|k| x(k) * y(k)),
                    wide(&|k| y(k) * y(k)),
                    wide(&x),
                    wide(&y),
                ];
                let intensities = [
                    wide(&t),
                    wide(&|k| t(k) * t(k)),
                    wide(&|k| t(k) * x(k)),
                    wide(&|k| t(k) * y(k)),
                ];
                assert_eq!(portable::gradient_sums(gx, gy), gradients, "{len}");
                assert_eq!(gradient_sums(gx, gy), gradients, "{len}");
                assert_eq!(portable::intensity_sums(i, gx, gy), intensities, "{len}");
                assert_eq!(intensity_sums(i, gx, gy), intensities, "{len}");
                assert_eq!(portable::sum(i), intensities[0], "{len}");
                assert_eq!(sum(i), intensities[0], "{len}");
            }
        }
        let a = v.run::<30>(30);
        for (la, lb) in [(30, 21), (9, 30), (3, 0)] {
            let (x, y) = (&a[..la], &a[..lb]);
            assert_eq!(gradient_sums(x, y), portable::gradient_sums(x, y));
            assert_eq!(intensity_sums(y, x, x), portable::intensity_sums(y, x, x));
        }
    }

    /// Weights as `WindowOrigin` makes them (summing to `2^14`), at their ends, and beyond.
    fn weights(v: &mut Values) -> [i32; 4] {
        let w = v.next() as u16;
        match w % 8 {
            0 => [1 << 14, 0, 0, 0],
            1 => [0, 0, 0, 1 << 14],
            2 => [4096; 4],
            // Out of the `i16` range: the SSE2 code hands these to the portable one.
            3 => [40_000, -7, 3, 1],
            _ => {
                let (fx, fy) = (
                    i32::from(w >> 2) & 0x3FFF,
                    i32::from(v.next() as u16) & 0x3FFF,
                );
                let one = 1 << 14;
                let w00 = ((one - fx) * (one - fy) + 8192) >> 14;
                let w01 = (fx * (one - fy) + 8192) >> 14;
                let w10 = ((one - fx) * fy + 8192) >> 14;
                [w00, w01, w10, one - w00 - w01 - w10]
            }
        }
    }

    #[test]
    fn bilinear_rows_agree_with_the_reference() {
        let mut v = Values(77);
        for round in 0..400 {
            let w = weights(&mut v);
            // Pixels of 8 bits (every LK sample) and, every other round, any `i16`.
            let pixel = |v: &mut Values| {
                if round % 2 == 0 {
                    v.next() & 0xFF
                } else {
                    v.next()
                }
            };
            let top: [i16; 80] = core::array::from_fn(|_| pixel(&mut v));
            let bottom: [i16; 80] = core::array::from_fn(|_| pixel(&mut v));
            for n in [0usize, 1, 5, 7, 8, 9, 10, 11, 16, 21, 23, 24, 63, 65] {
                // Rows one value longer than the samples, as the LK loops pass them, and
                // shorter or longer rows.
                for (lt, lb) in [(n + 1, n + 1), (n + 9, n + 3), (n, n + 1), (n / 2, n + 1)] {
                    let (t, b) = (&top[..lt.min(80)], &bottom[..lb.min(80)]);
                    let (mut fast, mut reference) = ([-1i16; 80], [-1i16; 80]);
                    bilinear_row(&w, t, b, &mut fast[..n]);
                    portable::bilinear_row(&w, t, b, &mut reference[..n]);
                    assert_eq!(fast, reference, "{w:?} {n} {lt} {lb}");
                    if n >= 2 {
                        let (mut fi, mut ri) = ([-1i16; 80], [-1i16; 80]);
                        let (mut fast, mut reference) = ([-1i16; 80], [-1i16; 80]);
                        bilinear_row_twice(&w, t, b, &mut fast[..n], &mut fi[..n - 2]);
                        portable::bilinear_row_twice(
                            &w,
                            t,
                            b,
                            &mut reference[..n],
                            &mut ri[..n - 2],
                        );
                        assert_eq!((fast, fi), (reference, ri), "{w:?} {n} {lt} {lb}");
                    }
                }
            }
        }
    }

    #[test]
    fn scharr_rows_agree_with_the_reference() {
        let mut v = Values(4242);
        for round in 0..600 {
            // Samples of 8-bit pixels (grey x 32), and every other round any `i16`.
            let sample = |v: &mut Values| {
                if round % 2 == 0 {
                    (v.next() & 0xFF) * 32
                } else {
                    v.next()
                }
            };
            let rows: [[i16; 70]; 3] =
                core::array::from_fn(|_| core::array::from_fn(|_| sample(&mut v)));
            for n in [0usize, 1, 2, 5, 7, 8, 9, 10, 15, 16, 17, 21, 31, 63] {
                for (lu, lm, ld) in [
                    (n + 2, n + 2, n + 2),
                    (n + 5, n + 3, n + 9),
                    (n + 1, n + 2, n + 2),
                    (n / 2, n + 2, n),
                ] {
                    let (u, m, d) = (
                        &rows[0][..lu.min(70)],
                        &rows[1][..lm.min(70)],
                        &rows[2][..ld.min(70)],
                    );
                    let mut fast = ([-1i16; 70], [-1i16; 70]);
                    let mut reference = ([-1i16; 70], [-1i16; 70]);
                    scharr_row(u, m, d, &mut fast.0[..n], &mut fast.1[..n]);
                    portable::scharr_row(u, m, d, &mut reference.0[..n], &mut reference.1[..n]);
                    assert_eq!(fast, reference, "{n} {lu} {lm} {ld}");
                }
            }
        }
    }

    /// The samples are the bilinear formula's, value by value.
    #[test]
    fn bilinear_row_is_the_formula() {
        let top = [10i16, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110];
        let bottom = [0i16, 255, 0, 255, 0, 255, 0, 255, 0, 255, 0];
        let w = [9000, 3000, 3384, 1000];
        let mut out = [0i16; 10];
        bilinear_row(&w, &top, &bottom, &mut out);
        for (k, &o) in out.iter().enumerate() {
            let [a, b, c, d] = [top[k], top[k + 1], bottom[k], bottom[k + 1]].map(i32::from);
            let exact = (w[0] * a + w[1] * b + w[2] * c + w[3] * d + 256) >> 9;
            assert_eq!(i32::from(o), exact, "{k}");
        }
    }
}
