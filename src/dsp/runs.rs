//! Kernels over runs of `i16` values, the innermost operations of the LK window loops: the
//! copy of a frame block into `i16`, a template sampled between pixels with its derivatives,
//! the template's window sums, the correlations of a next-frame block with the template, and
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
//!
//! The kernels that take a whole window (`widen_rows`, `sampled_template`, `correlate`, here
//! and in SSE2) index and count with plain arithmetic, as `lk`'s loops do: their indices are
//! bounded by the window shapes LK validates (at most 66 x 66 values) and checked against the
//! buffers before use, and their sums by the widths `lk` proves (`correlation.rs`,
//! `template.rs`); the arithmetic lint is off for those functions only.

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

/// The template of a window between pixels, from the `(win + 3)` square of pixels under its
/// patch: in the frame where they lie, `frame = Some((block, stride))` (rows `stride` apart,
/// as `ImageView::block` gives them), or gathered into `source` (rows `win + 3` apart, values
/// `0..=255` on every LK call); with a frame block, `source` is scratch of `(win + 3)^2`
/// values or more. Returns the patch, the `(win + 2)` square of [`bilinear`] samples with
/// weights `w`, in `patch` (rows `win + 2` apart), its inner `win` square, the template's
/// intensities, in `intensity`, and the [`scharr_row`] derivatives of that square in `dx`
/// and `dy` (window buffers: `win` rows of `win` values, `pitch` apart). The values between
/// rows (each row's padding) are scratch as well: the caller clears them. So is the patch:
/// the SSE2 code keeps it in registers.
#[inline(always)]
pub(crate) fn sampled_template(
    w: &[i32; 4],
    frame: Option<(&[u8], usize)>,
    source: &mut [i16],
    patch: &mut [i16],
    pitch: usize,
    [intensity, dx, dy]: [&mut [i16]; 3],
) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::sampled_template(w, frame, source, patch, pitch, [intensity, dx, dy]);
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::sampled_template(w, frame, source, patch, pitch, [intensity, dx, dy]);
    }
}

/// Copies the rows of `cols` pixels of a frame block (`stride` apart, the last ending at the
/// block's end, as `ImageView::block` gives them) into `out` as `i16`, `pitch >= cols` apart,
/// for as many rows as both hold.
#[inline(always)]
pub(crate) fn widen_rows(block: &[u8], stride: usize, cols: usize, out: &mut [i16], pitch: usize) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::widen_rows(block, stride, cols, out, pitch);
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::widen_rows(block, stride, cols, out, pitch);
    }
}

/// The sum over an LK window of `|J 2^16 - gain I - bias|` (wrapping in 32 bits, as `u32`):
/// `J` the bilinear samples (weights `w`, rounded as [`bilinear`]) of the window's source block
/// `block` (the `(win + 1)` square, rows `pitch = win + 1` apart, and a value of slack) and `I`
/// the template's `intensity` (`win` rows of `pitch` values; the padding is not read).
#[inline(always)]
pub(crate) fn abs_residual(
    w: &[i16; 4],
    block: &[i16],
    pitch: usize,
    intensity: &[i16],
    correction: (i32, i32),
) -> u64 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::abs_residual(w, block, pitch, intensity, correction)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::abs_residual(w, block, pitch, intensity, correction)
    }
}

/// Template values summed in 32 bits before widening: a product of two is at most
/// `8160^2 = 66_585_600` for intensities of 8-bit pixels, 64 of them below `2^32` (`ΣI²`,
/// read unsigned) and the signed sums below `2^31`.
pub(crate) const TEMPLATE_CHUNK: usize = 64;

/// The template's window sums over its intensity and gradient buffers (padding zero):
/// `[Σ gx², Σ gx gy, Σ gy², Σ gx, Σ gy, Σ i, Σ i², Σ i gx, Σ i gy]`, each summed in 32 bits over
/// [`TEMPLATE_CHUNK`] values at a time, wrapping, and the chunks in 64 bits (`Σ i²`'s 32 bits
/// read unsigned, the others signed).
#[inline(always)]
pub(crate) fn template_sums(intensity: &[i16], dx: &[i16], dy: &[i16]) -> [i64; 9] {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::template_sums(intensity, dx, dy)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::template_sums(intensity, dx, dy)
    }
}

/// Pixel-template products summed in 32 bits before widening: `1024 * 2_080_800 < 2^31` for
/// pixels and template values of 8-bit pixels (widths in `lk`'s `correlation.rs`).
pub(crate) const CORRELATION_CHUNK: usize = 1024;

/// The correlations of an LK window's source block with the template's three buffers
/// `t = [I, Ix, Iy]`, for each bilinear neighbour `q` (the pixel, right, below, below-right):
/// `[ΣP, ΣP·I, ΣP·Ix, ΣP·Iy]` over the window.
///
/// `block` is the `(win + 1)` square of pixels, rows `pitch = win + 1` apart, and a value of
/// slack; each template buffer holds `win` rows of `pitch` values whose last (padding) value
/// is zero. Neighbour `q`'s pixels under the window are then the run of the block starting at
/// `[0, 1, pitch, pitch + 1][q]`, as long as a template buffer, and each product sum is a flat
/// dot product (the padding drops the run's extra column). Products are summed in 32 bits
/// over [`CORRELATION_CHUNK`] values at a time, wrapping, and the chunks in 64 bits; `ΣP`
/// exactly (at most `64^2 * 32767 < 2^31`).
#[inline(always)]
pub(crate) fn correlate(block: &[i16], pitch: usize, t: [&[i16]; 3]) -> [[i64; 4]; 4] {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::correlate(block, pitch, t)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::correlate(block, pitch, t)
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

    /// [`super::abs_residual`], row by row: each sample's bilinear sum as two dual
    /// multiply-accumulates (the pixel pair of each row against its two weights), corrected
    /// and summed at once.
    #[allow(clippy::arithmetic_side_effects)]
    pub(crate) fn abs_residual(
        w: &[i16; 4],
        block: &[i16],
        pitch: usize,
        intensity: &[i16],
        correction: (i32, i32),
    ) -> u64 {
        let win = pitch.saturating_sub(1);
        let [w00, w01, w10, w11] = w.map(|w| u32::from(w as u16));
        let weights = (w00 | (w01 << 16), w10 | (w11 << 16));
        let mut total = 0u64;
        let mut at = 0;
        while let (Some(top), Some(bottom), Some(i)) = (
            block.get(at..at + pitch),
            block.get(at + pitch..at + 2 * pitch),
            intensity.get(at..at + win),
        ) {
            total += residual_row(weights, top, bottom, i, correction);
            at += pitch;
        }
        total
    }

    /// [`abs_residual`] of one row: the samples between `top` and `bottom` (pixel `k` and
    /// `k + 1` of each) against the template row `i`.
    #[inline(never)]
    fn residual_row(
        (upper, lower): (u32, u32),
        top: &[i16],
        bottom: &[i16],
        i: &[i16],
        (gain, bias): (i32, i32),
    ) -> u64 {
        const ROUND: i32 = 1 << (super::WEIGHT_BITS - super::SAMPLE_BITS - 1);
        let mut total = 0u64;
        let pixels = top.windows(2).zip(bottom.windows(2));
        for (&i, (t, b)) in i.iter().zip(pixels) {
            // The same sum and rounding as `bilinear`, two products per instruction, and the
            // same truncation.
            let sum = smlad(pair(b), lower, smlad(pair(t), upper, ROUND));
            #[allow(clippy::cast_possible_truncation)]
            let j = (sum >> (super::WEIGHT_BITS - super::SAMPLE_BITS)) as i16;
            let corrected = (i32::from(j) << 16).wrapping_sub(gain.wrapping_mul(i32::from(i)));
            total = total.wrapping_add(u64::from(corrected.abs_diff(bias)));
        }
        total
    }

    /// [`super::template_sums`] in two passes of dual multiply-accumulates over each chunk
    /// (even in length, or ending a buffer whose rows end in their zero padding column, so its
    /// values pair up): the gradients' sums and products, then the intensities' with
    /// themselves and the gradients. A plain sum is a multiply-accumulate with ones.
    #[inline(never)]
    pub(crate) fn template_sums(intensity: &[i16], dx: &[i16], dy: &[i16]) -> [i64; 9] {
        let mut s = [0i64; 9];
        let chunk = super::TEMPLATE_CHUNK;
        let rows = intensity
            .chunks(chunk)
            .zip(dx.chunks(chunk).zip(dy.chunks(chunk)));
        for (i, (gx, gy)) in rows {
            let [gxx, gxy, gyy, sx, sy] = gradient_sums(gx, gy);
            let [si, sii, six, siy] = intensity_sums(i, gx, gy);
            // `Σ i²` of a chunk, read unsigned.
            let sii = sii as u32;
            let sums = [
                i64::from(gxx),
                i64::from(gxy),
                i64::from(gyy),
                i64::from(sx),
                i64::from(sy),
                i64::from(si),
                i64::from(sii),
                i64::from(six),
                i64::from(siy),
            ];
            for (total, v) in s.iter_mut().zip(sums) {
                *total = total.wrapping_add(v);
            }
        }
        s
    }

    /// [`super::correlate`]: `ΣP` of each neighbour from the block's total, first and last
    /// rows and columns, then each neighbour's run against the three buffers by [`dot3`].
    #[allow(clippy::arithmetic_side_effects)]
    #[inline(never)]
    pub(crate) fn correlate(block: &[i16], pitch: usize, t: [&[i16]; 3]) -> [[i64; 4]; 4] {
        let p = pitch;
        let n = t[0].len();
        let mut sums = pixel_sums(block, pitch).map(|plain| [plain, 0, 0, 0]);
        for (sums, offset) in sums.iter_mut().zip([0, 1, p, p + 1]) {
            // offset + n <= p + 1 + win p = the block's (win + 1) p + 1.
            let run = block.get(offset..offset + n);
            debug_assert!(run.is_some(), "a run past the block");
            [sums[1], sums[2], sums[3]] = chunked_dot3(run.unwrap_or(&[]), t);
        }
        sums
    }

    /// `ΣP` of each neighbour over the window, from the block's total, its first and last rows
    /// and columns: the samples' own pixels are the block without its last row and column,
    /// their right neighbours the block without its last row and first column, and so on.
    #[allow(clippy::arithmetic_side_effects)]
    fn pixel_sums(block: &[i16], pitch: usize) -> [i64; 4] {
        let (p, win) = (pitch, pitch.saturating_sub(1));
        // The block is the (win + 1)-square, p = win + 1 apart, and a value of slack.
        let square = block.get(..p * p).unwrap_or(&[]);
        // The block's total by pairs; its first and last columns by one load a row.
        let total = sum(square);
        let (mut left, mut right) = (0, 0);
        for row in square.chunks_exact(p.max(1)) {
            left += row.first().map_or(0, |&v| i32::from(v));
            right += row.last().map_or(0, |&v| i32::from(v));
        }
        let row_sum = |r: usize| sum(square.get(r * p..(r + 1) * p).unwrap_or(&[]));
        let at = |k: usize| square.get(k).map_or(0, |&v| i32::from(v));
        let (top, bottom) = (row_sum(0), row_sum(win));
        let without = |row: i32, col: i32, corner: usize| total - row - col + at(corner);
        [
            without(bottom, right, win * p + win),
            without(bottom, left, win * p),
            without(top, right, win),
            without(top, left, 0),
        ]
        .map(i64::from)
    }

    /// `[Σ a[k] b0[k], Σ a[k] b1[k], Σ a[k] b2[k]]` by [`dot3`] over
    /// [`super::CORRELATION_CHUNK`] values at a time, widened between chunks.
    #[allow(clippy::arithmetic_side_effects)]
    fn chunked_dot3(a: &[i16], b: [&[i16]; 3]) -> [i64; 3] {
        let mut total = [0i64; 3];
        for (k, a) in a.chunks(super::CORRELATION_CHUNK).enumerate() {
            let start = k * super::CORRELATION_CHUNK;
            // `a` is a window run and each `b` a window buffer: the same length.
            let part = b.map(|v| v.get(start..start + a.len()).unwrap_or(&[]));
            for (t, s) in total.iter_mut().zip(dot3(a, part)) {
                *t += i64::from(s);
            }
        }
        total
    }

    /// [`super::widen_rows`]: rows of the common windows' lengths unrolled. Bare-metal
    /// targets, short of flash, unroll only the lengths of the flight presets' 7 and 9 px
    /// windows, not those of the 21 px default.
    #[inline(always)]
    pub(crate) fn widen_rows(
        block: &[u8],
        stride: usize,
        cols: usize,
        out: &mut [i16],
        pitch: usize,
    ) {
        if pitch != cols {
            return copy_any_rows(block, stride, cols, out, pitch);
        }
        match cols {
            8 => copy_rows::<8>(block, stride, out),
            10 => copy_rows::<10>(block, stride, out),
            12 => copy_rows::<12>(block, stride, out),
            #[cfg(not(target_os = "none"))]
            22 => copy_rows::<22>(block, stride, out),
            #[cfg(not(target_os = "none"))]
            24 => copy_rows::<24>(block, stride, out),
            _ => copy_any_rows(block, stride, cols, out, cols),
        }
    }

    /// Copies rows of `cols` pixels, `stride` apart in `block`, into `out` (`pitch` apart).
    #[inline(never)]
    fn copy_any_rows(block: &[u8], stride: usize, cols: usize, out: &mut [i16], pitch: usize) {
        for (dst, src) in out
            .chunks_mut(pitch.max(1))
            .zip(block.chunks(stride.max(1)))
        {
            dst.iter_mut()
                .take(cols)
                .zip(src)
                .for_each(|(d, &s)| *d = i16::from(s));
        }
    }

    /// Copies rows of `N` pixels, `stride` apart in `block`, into `out` (`N` apart).
    fn copy_rows<const N: usize>(block: &[u8], stride: usize, out: &mut [i16]) {
        for (dst, src) in out.chunks_exact_mut(N).zip(block.chunks(stride.max(1))) {
            // `block` is a frame block of `N`-pixel rows (its last row ends at its last pixel),
            // so every chunk holds `N` pixels and every `out` chunk is `N` long.
            let (Ok(dst), Some(Ok(src))) = (
                <&mut [i16; N]>::try_from(dst),
                src.get(..N).map(<&[u8; N]>::try_from),
            ) else {
                debug_assert!(
                    src.len() >= N,
                    "a block row of {} pixels, {N} wanted",
                    src.len()
                );
                return;
            };
            *dst = src.map(i16::from);
        }
    }

    /// [`super::sampled_template`], row by row: the patch's rows of samples (the inner ones
    /// stored in `intensity` as well), then the derivatives' rows. The window side is the
    /// number of `intensity` rows (`intensity.len() / pitch`).
    #[allow(clippy::arithmetic_side_effects)]
    #[inline(never)]
    pub(crate) fn sampled_template(
        w: &[i32; 4],
        frame: Option<(&[u8], usize)>,
        source: &mut [i16],
        patch: &mut [i16],
        pitch: usize,
        [intensity, dx, dy]: [&mut [i16]; 3],
    ) {
        let pitch = pitch.max(1);
        let win = intensity.len() / pitch;
        let (side, n) = (win + 2, win + 3);
        // The pixels, copied from the frame when they lie there.
        if let Some((block, stride)) = frame {
            widen_rows(block, stride, n, source, n);
        }
        let source = source.get(..n * n).unwrap_or(source);
        let sources = source.chunks(n).zip(source.chunks(n).skip(1));
        let mut inner = intensity
            .chunks_exact_mut(pitch)
            .map(|row| row.get_mut(..win).unwrap_or(&mut []));
        for (r, ((top, bottom), out)) in sources.zip(patch.chunks_exact_mut(side)).enumerate() {
            match if r == 0 { None } else { inner.next() } {
                Some(inner) => bilinear_row_twice(w, top, bottom, out, inner),
                None => bilinear_row(w, top, bottom, out),
            }
        }
        let patch_rows = patch.chunks_exact(side);
        let below = patch_rows.clone().skip(1).zip(patch_rows.clone().skip(2));
        let outputs = dx.chunks_exact_mut(pitch).zip(dy.chunks_exact_mut(pitch));
        for ((dx_row, dy_row), (up, (mid, down))) in outputs.zip(patch_rows.zip(below)) {
            let (Some(dx_row), Some(dy_row)) = (dx_row.get_mut(..win), dy_row.get_mut(..win))
            else {
                continue;
            };
            scharr_row(up, mid, down, dx_row, dy_row);
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
    fn dot3_is_the_three_dot_products_modulo_2_32() {
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
            }
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
                assert_eq!(portable::intensity_sums(i, gx, gy), intensities, "{len}");
                assert_eq!(portable::sum(i), intensities[0], "{len}");
                assert_eq!(
                    template_sums(i, gx, gy),
                    portable::template_sums(i, gx, gy),
                    "{len}"
                );
            }
        }
        // Buffers of unequal lengths, and windows' buffers (chunks of 64, the last shorter) of
        // template values at their extremes.
        let a = v.run::<30>(30);
        for (la, lb) in [(30, 21), (9, 30), (3, 0)] {
            let (x, y) = (&a[..la], &a[..lb]);
            assert_eq!(template_sums(y, x, x), portable::template_sums(y, x, x));
        }
        for len in [56, 90, 110, 462, 1056, 3969] {
            let mut buffers = [[0i16; 3969]; 3];
            for (b, extreme) in buffers.iter_mut().zip([8160, 4080, -4080]) {
                for (k, value) in b.iter_mut().take(len).enumerate() {
                    *value = if k % 3 == 0 {
                        extreme
                    } else {
                        v.next() & 0x0FFF
                    };
                }
            }
            let [i, x, y] = buffers.each_ref().map(|b| &b[..len]);
            let sums = template_sums(i, x, y);
            assert_eq!(sums, portable::template_sums(i, x, y), "{len}");
            let exact: i64 = i.iter().map(|&v| i64::from(v) * i64::from(v)).sum();
            assert_eq!(sums[6], exact, "{len}");
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
                        // The portable row and inner row: the row, and its samples but the
                        // first and the last again.
                        let (mut row, mut inner) = ([-1i16; 80], [-1i16; 80]);
                        portable::bilinear_row_twice(&w, t, b, &mut row[..n], &mut inner[..n - 2]);
                        assert_eq!(row, reference, "{w:?} {n} {lt} {lb}");
                        let reached = (lt.min(lb).min(80).saturating_sub(1)).clamp(1, n - 1);
                        assert_eq!(inner[..reached - 1], row[1..reached], "{w:?} {n} {lt} {lb}");
                    }
                }
            }
        }
    }

    /// Every window side the SSE2 template code takes in its two ways (two registers a patch
    /// row, and column blocks) and those it leaves to the portable code, on pixels and on any
    /// `i16`, with LK's weights and others: the same template values as the portable rows.
    #[test]
    fn sampled_templates_agree_with_the_reference() {
        const MAX: usize = 26;
        const LEN: usize = (MAX + 3) * (MAX + 3) + 8;
        let mut v = Values(0x7E57);
        for round in 0..60 {
            for win in [3, 5, 7, 8, 9, 10, 11, 13, 14, 15, 16, 17, 21, 23, 26] {
                let n = win + 3;
                let w = weights(&mut v);
                let mut source = [0i16; LEN];
                for (k, s) in source.iter_mut().enumerate() {
                    *s = match round % 4 {
                        // Pixels, with the slack past the square anything.
                        0 | 1 if k < n * n => v.next() & 0xFF,
                        2 if k < n * n => [0, 255][k % 2],
                        // One value outside the pixels' range, or any i16.
                        3 if k == (round * 7) % (n * n) => 256,
                        _ => v.next(),
                    };
                }
                // The same pixels in a frame, rows 40 apart, its block ending at the block's
                // last pixel.
                let mut frame = [0u8; 40 * (MAX + 3)];
                for r in 0..n {
                    for c in 0..n {
                        frame[r * 40 + c] = source[r * n + c] as u8;
                    }
                }
                let block = &frame[..(n - 1) * 40 + n];
                let from_frame = round % 4 < 3;
                for (pitch, len) in [(win, n * n), (win + 1, n * n + 8), (win + 3, LEN)] {
                    let out = || [[-1i16; MAX * (MAX + 3)]; 3];
                    let (mut fast, mut reference, mut framed) = (out(), out(), out());
                    let mut patch = [0i16; (MAX + 2) * (MAX + 2)];
                    let patch = &mut patch[..(win + 2) * (win + 2)];
                    let m = win * pitch;
                    let (mut gathered, mut scratch) = (source, [0i16; LEN]);
                    let [i, x, y] = &mut fast;
                    let out = [&mut i[..m], &mut x[..m], &mut y[..m]];
                    sampled_template(&w, None, &mut gathered[..len], patch, pitch, out);
                    let [i, x, y] = &mut reference;
                    let out = [&mut i[..m], &mut x[..m], &mut y[..m]];
                    portable::sampled_template(&w, None, &mut source[..len], patch, pitch, out);
                    if from_frame {
                        let [i, x, y] = &mut framed;
                        let out = [&mut i[..m], &mut x[..m], &mut y[..m]];
                        let frame = Some((block, 40));
                        sampled_template(&w, frame, &mut scratch[..len], patch, pitch, out);
                    }
                    for (k, (f, r)) in fast.iter().zip(&reference).enumerate() {
                        for row in 0..win {
                            let at = row * pitch..row * pitch + win;
                            let (f, r) = (&f[at.clone()], &r[at.clone()]);
                            assert_eq!(f, r, "{w:?} win {win} pitch {pitch} row {row}");
                            if from_frame {
                                let framed = &framed[k][at];
                                assert_eq!(framed, r, "{w:?} win {win} pitch {pitch} row {row}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// Windows whose runs fit one chunk and windows of several, on pixels and on any `i16`: the
    /// same correlations as the portable code, whose pixel sums are the window's.
    #[test]
    fn correlations_agree_with_the_reference() {
        const MAX: usize = 63;
        let mut v = Values(0xC0DE);
        for round in 0..12 {
            for win in [1, 2, 3, 7, 8, 9, 15, 21, 31, 32, 40, MAX] {
                let p = win + 1;
                let n = win * p;
                let mut block = [0i16; (MAX + 1) * (MAX + 1) + 1];
                let mut t = [[0i16; MAX * (MAX + 1)]; 3];
                for b in block.iter_mut().take(p * p + 1) {
                    *b = if round % 2 == 0 {
                        v.next() & 0xFF
                    } else {
                        v.next()
                    };
                }
                for buf in t.iter_mut() {
                    for (k, value) in buf.iter_mut().take(n).enumerate() {
                        *value = if k % p == win { 0 } else { v.next() };
                    }
                }
                let t = t.each_ref().map(|b| &b[..n]);
                let fast = correlate(&block[..p * p + 1], p, t);
                let reference = portable::correlate(&block[..p * p + 1], p, t);
                assert_eq!(fast, reference, "win {win} round {round}");
                let at = |r: usize, c: usize| i64::from(block[r * p + c]);
                for (q, (dr, dc)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
                    let plain: i64 = (0..win)
                        .flat_map(|r| (0..win).map(move |c| (r, c)))
                        .map(|(r, c)| at(r + dr, c + dc))
                        .sum();
                    assert_eq!(fast[q][0], plain, "win {win} neighbour {q}");
                }
            }
        }
    }

    /// Windows the SSE2 residual takes and those it leaves to the portable code, on pixels and
    /// on any `i16`, with LK's weights, gains and biases and others: the same sums as the
    /// portable rows, whatever the template's padding holds.
    #[test]
    fn residuals_agree_with_the_reference() {
        const MAX: usize = 63;
        let mut v = Values(0x5E5);
        let next32 = |v: &mut Values| (i32::from(v.next()) << 16) ^ i32::from(v.next());
        for round in 0..40 {
            for win in [1, 3, 6, 7, 8, 9, 15, 21, 31, MAX] {
                let p = win + 1;
                let n = win * p;
                let mut block = [0i16; (MAX + 1) * (MAX + 1) + 1];
                let mut intensity = [0i16; MAX * (MAX + 1)];
                for b in block.iter_mut().take(p * p + 1) {
                    *b = if round % 2 == 0 {
                        v.next() & 0xFF
                    } else {
                        v.next()
                    };
                }
                for i in intensity.iter_mut().take(n) {
                    *i = if round % 2 == 0 {
                        (v.next() & 0xFF) * 32
                    } else {
                        v.next()
                    };
                }
                let w = weights(&mut v).map(|w| w as i16);
                let gain = match round % 4 {
                    0 | 1 => (1 << 14) + (next32(&mut v) & 0x3_FFFF),
                    2 => next32(&mut v) >> 1,
                    _ => next32(&mut v),
                };
                let bias = next32(&mut v);
                let (block, intensity) = (&block[..p * p + 1], &intensity[..n]);
                let fast = abs_residual(&w, block, p, intensity, (gain, bias));
                let reference = portable::abs_residual(&w, block, p, intensity, (gain, bias));
                assert_eq!(
                    fast, reference,
                    "win {win} round {round} {w:?} {gain} {bias}"
                );
            }
        }
    }

    /// Blocks of every width up to 40 from frames of several strides, into rows as far apart
    /// or further: the same rows as the portable copy, and nothing else written.
    #[test]
    fn widened_rows_agree_with_the_reference() {
        let mut v = Values(0xF00D);
        let frame: [u8; 64 * 48] = core::array::from_fn(|_| v.next() as u8);
        for cols in 1..=40 {
            for (stride, rows) in [(cols, 1), (cols, 5), (64, 12), (cols + 3, 9)] {
                for pitch in [cols, cols + 1, cols + 5] {
                    let span = (rows - 1) * stride + cols;
                    let block = &frame[7..7 + span];
                    let len = rows * pitch + 3;
                    let (mut fast, mut reference) = ([-1i16; 1024], [-1i16; 1024]);
                    widen_rows(block, stride, cols, &mut fast[..len], pitch);
                    portable::widen_rows(block, stride, cols, &mut reference[..len], pitch);
                    assert_eq!(fast, reference, "{cols} {stride} {rows} {pitch}");
                    for (k, &x) in fast.iter().enumerate() {
                        let (r, c) = (k / pitch, k % pitch);
                        if r < rows && c < cols {
                            assert_eq!(x, i16::from(block[r * stride + c]));
                        } else {
                            assert_eq!(x, -1, "{k}");
                        }
                    }
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
