//! The run kernels of [`super::runs`] and the pyramid's row kernel of [`super::binomial`] in
//! SSE2, which every x86-64 CPU has.
//!
//! PMADDWD (`_mm_madd_epi16`) multiplies eight pairs of `i16` and adds each two neighbouring
//! products into one of four 32-bit lanes: SMLAD four times over. Its one overflowing case (two
//! products of -32768 by -32768, 2^31) gives `i32::MIN`, which is 2^31 modulo 2^32, so lanes
//! that add its results with PADDD hold the exact sums modulo 2^32, as SMLAD's accumulator
//! does.
//!
//! Each kernel runs blocks of 8 values. The LK runs are rarely a multiple of 8 long (a 9 px
//! window's rows, its 90-value correlation runs), so the values past the last whole block are
//! not handed to a scalar loop: sums take the run's last 8 values with the lanes already
//! counted masked to zero, and rows of samples compute their last 8 samples again, overlapping
//! the block before (the same values, stored twice). Runs shorter than 8 go to the portable
//! kernels.
//!
//! # Safety
//!
//! The `unsafe` here is of two kinds. Loads and stores (`_mm_loadu_si128`, `_mm_storeu_si128`,
//! `_mm_storel_epi64`) take a pointer: each reads or writes the 16 bytes of an `[i16; 8]` or
//! `[u8; 16]` borrowed for the call (`_mm_storel_epi64` the 8 bytes of a `[u8; 8]`), so it stays
//! in bounds, and the unaligned forms need no alignment. The arithmetic
//! intrinsics touch registers only; they are `unsafe` to call before Rust 1.87 because they
//! need SSE2, which this module is compiled only with (`target_feature = "sse2"`, on for
//! every x86-64 target).

// Arithmetic intrinsics are safe functions from Rust 1.87 on, `unsafe` before (the crate's
// `rust-version` is 1.85): their `unsafe` blocks are needed on old compilers only.
#![allow(unused_unsafe)]

use super::runs::{portable, CORRELATION_CHUNK, SAMPLE_BITS, TEMPLATE_CHUNK, WEIGHT_BITS};
use core::arch::x86_64::{
    __m128i, _mm_add_epi16, _mm_add_epi32, _mm_add_epi64, _mm_and_si128, _mm_andnot_si128,
    _mm_cmpeq_epi16, _mm_cmpgt_epi16, _mm_cmpgt_epi32, _mm_cvtsi128_si32, _mm_cvtsi32_si128,
    _mm_loadl_epi64, _mm_loadu_si128, _mm_madd_epi16, _mm_movemask_epi8, _mm_or_si128,
    _mm_packs_epi32, _mm_packus_epi16, _mm_set1_epi16, _mm_set1_epi32, _mm_setzero_si128,
    _mm_slli_epi16, _mm_slli_epi32, _mm_slli_si128, _mm_srai_epi32, _mm_srli_epi16, _mm_srli_si128,
    _mm_storel_epi64, _mm_storeu_si128, _mm_sub_epi16, _mm_sub_epi32, _mm_unpackhi_epi16,
    _mm_unpackhi_epi32, _mm_unpackhi_epi64, _mm_unpacklo_epi16, _mm_unpacklo_epi32,
    _mm_unpacklo_epi64, _mm_unpacklo_epi8, _mm_xor_si128,
};

/// `i16` values in a register.
const LANES: usize = 8;

/// Eight values as a register.
#[inline(always)]
fn load(v: &[i16; LANES]) -> __m128i {
    // SAFETY: reads the 16 bytes of `v`, with no alignment needed (module docs).
    unsafe { _mm_loadu_si128(v.as_ptr().cast()) }
}

/// The eight values of `run` from `start`, if it holds them.
#[inline(always)]
fn load_at(run: &[i16], start: usize) -> Option<__m128i> {
    let block = run.get(start..start.checked_add(LANES)?)?;
    <&[i16; LANES]>::try_from(block).ok().map(load)
}

/// Stores a register's eight values in `out`.
#[inline(always)]
fn store(out: &mut [i16; LANES], v: __m128i) {
    // SAFETY: writes the 16 bytes of `out`, with no alignment needed (module docs).
    unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), v) }
}

/// Stores a register's eight values in `out` from `start`, if it holds them.
#[inline(always)]
fn store_at(out: &mut [i16], start: usize, v: __m128i) {
    let end = start.saturating_add(LANES);
    if let Some(Ok(block)) = out.get_mut(start..end).map(<&mut [i16; LANES]>::try_from) {
        store(block, v);
    }
}

/// PMADDWD: `a0 b0 + a1 b1`, ... in four 32-bit lanes.
#[inline(always)]
fn madd(a: __m128i, b: __m128i) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe { _mm_madd_epi16(a, b) }
}

/// PADDD: lane-wise sums, wrapping.
#[inline(always)]
fn add(a: __m128i, b: __m128i) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe { _mm_add_epi32(a, b) }
}

/// A register of zeros.
#[inline(always)]
fn zero() -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe { _mm_setzero_si128() }
}

/// A register of the `i16` pair `(lo, hi)` four times.
#[inline(always)]
fn pairs_of(lo: i16, hi: i16) -> __m128i {
    let word = u32::from(lo as u16) | (u32::from(hi as u16) << 16);
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe { _mm_set1_epi32(word as i32) }
}

/// The sum of the four lanes and `tail`, wrapping.
#[inline(always)]
fn lanes_sum(v: __m128i, tail: i32) -> i32 {
    let mut lanes = [0i32; 4];
    // SAFETY: writes the 16 bytes of `lanes`, with no alignment needed (module docs).
    unsafe { _mm_storeu_si128(lanes.as_mut_ptr().cast(), v) };
    lanes.into_iter().fold(tail, i32::wrapping_add)
}

/// The whole blocks of eight values of a run, as registers.
#[inline(always)]
fn whole(run: &[i16]) -> impl Iterator<Item = __m128i> + '_ {
    // `chunks_exact` yields blocks of `LANES` values: the conversion always succeeds.
    run.chunks_exact(LANES)
        .filter_map(|b| <&[i16; LANES]>::try_from(b).ok().map(load))
}

/// Lane masks: the eight values from `MASKS[r]` keep the last `r` lanes of a block.
const MASKS: [i16; 2 * LANES] = [0, 0, 0, 0, 0, 0, 0, 0, -1, -1, -1, -1, -1, -1, -1, -1];

/// Lane-wise AND.
#[inline(always)]
fn and(a: __m128i, b: __m128i) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe { _mm_and_si128(a, b) }
}

/// The last eight values of a run of at least eight whose length is not a multiple of eight
/// (`None` otherwise): the block past its whole blocks, overlapping the last of them.
#[inline(always)]
fn last(run: &[i16]) -> Option<__m128i> {
    if run.len() % LANES == 0 {
        return None;
    }
    load_at(run, run.len().checked_sub(LANES)?)
}

/// [`last`] with the lanes that the whole blocks count already zeroed: added to their sums, it
/// adds the values past them only.
#[inline(always)]
fn last_masked(run: &[i16]) -> Option<__m128i> {
    Some(and(last(run)?, load_at(&MASKS, run.len() % LANES)?))
}

/// [`super::runs::correlate`] in two passes over the window's runs, one for the neighbours on
/// the window's rows (offsets 0 and 1) and one for those on the rows below (`pitch` and
/// `pitch + 1`): each template block loaded once a pass for the six products of two runs, and
/// the first run of each pass summed as well. `ΣP` of each neighbour is then its row run's
/// sum without the run's extra column (the block's last column for the pixel and the one
/// below, its first for the right neighbours). Products wrap in 32-bit lanes over chunks of
/// [`CORRELATION_CHUNK`] values, as the portable code's do.
#[allow(clippy::arithmetic_side_effects)]
#[inline(never)]
pub(super) fn correlate(block: &[i16], pitch: usize, t: [&[i16]; 3]) -> [[i64; 4]; 4] {
    let n = t[0].len();
    let p = pitch;
    let win = p.saturating_sub(1);
    let shaped = win >= 1
        && n >= LANES
        && n == win * p
        && t.iter().all(|b| b.len() == n)
        && block.len() > p * p;
    if !shaped {
        return portable::correlate(block, p, t);
    }
    let mut sums = [[0i64; 4]; 4];
    let mut runs = [0i32; 2];
    for start in (0..n).step_by(CORRELATION_CHUNK) {
        let len = (n - start).min(CORRELATION_CHUNK);
        let part = t.map(|v| v.get(start..start + len).unwrap_or(&[]));
        for (pass, base) in [0, p].into_iter().enumerate() {
            let from = base + start;
            let run = block.get(from..from + len + 1);
            // The runs of the flight presets' windows and of the 21 px default, of known
            // lengths: their loops without bounds checks.
            let products = match len {
                56 => run.and_then(|run| correlate_pass_of::<56>(run, part)),
                90 => run.and_then(|run| correlate_pass_of::<90>(run, part)),
                462 => run.and_then(|run| correlate_pass_of::<462>(run, part)),
                _ => run.and_then(|run| correlate_pass(run, part)),
            };
            let Some(([first, second], sum)) = products else {
                return portable::correlate(block, p, t);
            };
            let pair = sums.iter_mut().skip(2 * pass).zip([first, second]);
            for (sums, dots) in pair {
                for (s, d) in sums.iter_mut().skip(1).zip(dots) {
                    *s += i64::from(d);
                }
            }
            if let Some(run) = runs.get_mut(pass) {
                *run = run.wrapping_add(sum);
            }
        }
    }
    // The block's first and last columns over all its rows, then without the last row (the
    // rows of the first pass) and without the first (those of the second).
    let at = |k: usize| block.get(k).map_or(0, |&v| i32::from(v));
    let (mut left, mut right) = (0, 0);
    let mut k = 0;
    while k < p * p {
        left += at(k);
        right += at(k + win);
        k += p;
    }
    let (last_row, first_row) = (win * p, 0);
    let left = [left - at(last_row), left - at(first_row)];
    let right = [right - at(last_row + win), right - at(first_row + win)];
    sums[0][0] = i64::from(runs[0] - right[0]);
    sums[1][0] = i64::from(runs[0] - left[0]);
    sums[2][0] = i64::from(runs[1] - right[1]);
    sums[3][0] = i64::from(runs[1] - left[1]);
    sums
}

/// [`correlate_pass`] for runs of `LEN` values.
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn correlate_pass_of<const LEN: usize>(
    run: &[i16],
    t: [&[i16]; 3],
) -> Option<([[i32; 3]; 2], i32)> {
    let first: &[i16; LEN] = run.get(..LEN)?.try_into().ok()?;
    let second: &[i16; LEN] = run.get(1..LEN + 1)?.try_into().ok()?;
    let [t0, t1, t2]: [&[i16; LEN]; 3] = [
        t[0].try_into().ok()?,
        t[1].try_into().ok()?,
        t[2].try_into().ok()?,
    ];
    if LEN < LANES {
        return None;
    }
    let at = |v: &[i16; LEN], k: usize| -> __m128i {
        let block: &[i16; LANES] = v[k..k + LANES].try_into().unwrap_or(&[0; LANES]);
        load(block)
    };
    let ones = pairs_of(1, 1);
    let mut acc = [[zero(); 3]; 2];
    let mut total = zero();
    let mut add_block = |k: usize, mask: Option<__m128i>| {
        let (x0, x1) = (at(first, k), at(second, k));
        let [y0, y1, y2] = [at(t0, k), at(t1, k), at(t2, k)].map(|y| mask.map_or(y, |m| and(y, m)));
        for (acc, x) in acc.iter_mut().zip([x0, x1]) {
            *acc = [
                add(acc[0], madd(x, y0)),
                add(acc[1], madd(x, y1)),
                add(acc[2], madd(x, y2)),
            ];
        }
        total = add(total, madd(mask.map_or(x0, |m| and(x0, m)), ones));
    };
    for b in 0..LEN / LANES {
        add_block(b * LANES, None);
    }
    if LEN % LANES != 0 {
        add_block(LEN - LANES, load_at(&MASKS, LEN % LANES));
    }
    let [[a0, a1, a2], [b0, b1, b2]] = acc;
    let [d0, d1, d2, d3] = lane_sums4([a0, a1, a2, b0]);
    let [d4, d5, sum, _] = lane_sums4([b1, b2, total, zero()]);
    Some(([[d0, d1, d2], [d3, d4, d5]], sum))
}

/// The dot products of the runs `run[..len]` and `run[1..len + 1]` with the three template
/// runs of length `len` (at least 8), and the sum of the first run, wrapping; `None` for other
/// shapes.
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn correlate_pass(run: &[i16], t: [&[i16]; 3]) -> Option<([[i32; 3]; 2], i32)> {
    let len = t[0].len();
    let (first, second) = (run.get(..len)?, run.get(1..len + 1)?);
    if len < LANES || t.iter().any(|v| v.len() != len) {
        return None;
    }
    let ones = pairs_of(1, 1);
    let mut acc = [[zero(); 3]; 2];
    let mut total = zero();
    let mut add_block = |x0, x1, [y0, y1, y2]: [__m128i; 3], x0_masked| {
        for (acc, x) in acc.iter_mut().zip([x0, x1]) {
            *acc = [
                add(acc[0], madd(x, y0)),
                add(acc[1], madd(x, y1)),
                add(acc[2], madd(x, y2)),
            ];
        }
        total = add(total, madd(x0_masked, ones));
    };
    let [t0, t1, t2] = t;
    let blocks = whole(first)
        .zip(whole(second))
        .zip(whole(t0).zip(whole(t1)).zip(whole(t2)));
    for ((x0, x1), ((y0, y1), y2)) in blocks {
        add_block(x0, x1, [y0, y1, y2], x0);
    }
    // The last block, overlapping: the template values counted already masked to zero.
    if let (Some(x0), Some(x0_masked), Some(x1), Some(y0), Some(y1), Some(y2)) = (
        last(first),
        last_masked(first),
        last(second),
        last_masked(t0),
        last_masked(t1),
        last_masked(t2),
    ) {
        add_block(x0, x1, [y0, y1, y2], x0_masked);
    }
    let [[a0, a1, a2], [b0, b1, b2]] = acc;
    let [d0, d1, d2, d3] = lane_sums4([a0, a1, a2, b0]);
    let [d4, d5, sum, _] = lane_sums4([b1, b2, total, zero()]);
    Some(([[d0, d1, d2], [d3, d4, d5]], sum))
}

/// [`super::runs::abs_residual`] over the window's flat run, as [`correlate`] reads it: the
/// samples at the run's `k` from the block's values at `k`, `k + 1`, `k + pitch` and
/// `k + pitch + 1`, eight at a time, their distances in 32-bit lanes widened into 64-bit sums;
/// a lane counter of columns drops each row's padding position, and the last block, overlapping
/// the one before, the lanes it counted. The gain times `I` as two PMADDWDs of `I` with the
/// gain's low 15 bits and the rest, the second shifted by 15: wrapping as the portable
/// product does, for gains of magnitude below `2^30` (the others go to the portable code, as
/// do windows under 7 px).
#[allow(clippy::arithmetic_side_effects)]
#[inline(never)]
pub(super) fn abs_residual(
    w: &[i16; 4],
    block: &[i16],
    pitch: usize,
    intensity: &[i16],
    (gain, bias): (i32, i32),
) -> u64 {
    let p = pitch;
    let win = p.saturating_sub(1);
    let n = win * p;
    let weights = weight_pairs(&w.map(i32::from));
    let shaped = win >= LANES - 1 && intensity.len() == n && block.len() > p * p;
    // The gain's low 15 bits and the rest, and the window's columns, as `i16`.
    let small = (
        i16::try_from(gain & 0x7FFF),
        i16::try_from(gain >> 15),
        i16::try_from(p),
    );
    let (Some(weights), true, (Ok(gain_low), Ok(gain_high), Ok(p16))) = (weights, shaped, small)
    else {
        return portable::abs_residual(w, block, pitch, intensity, (gain, bias));
    };
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    let (low15, high, bias_lanes) = unsafe {
        (
            pairs_of(gain_low, 0),
            pairs_of(gain_high, 0),
            _mm_set1_epi32(bias),
        )
    };
    // The distances of the eight samples of the run from `k`, those in `drop` lanes zeroed,
    // widened and added to `acc`.
    let mut acc = (zero(), zero());
    let mut add8 = |k: usize, drop: __m128i| -> Option<()> {
        let (p0, p1) = (load_at(block, k)?, load_at(block, k + 1)?);
        let (p2, p3) = (load_at(block, k + p)?, load_at(block, k + p + 1)?);
        let i = load_at(intensity, k)?;
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        unsafe {
            let four = |top, bottom, i, drop| {
                // The sample as i16, shifted up 16: its low 16 bits.
                let j = _mm_slli_epi32::<16>(sample4(weights, top, bottom));
                let gi = add(madd(i, low15), _mm_slli_epi32::<15>(madd(i, high)));
                let corrected = _mm_sub_epi32(j, gi);
                let below = _mm_cmpgt_epi32(bias_lanes, corrected);
                let d = _mm_sub_epi32(corrected, bias_lanes);
                // |corrected - bias| as u32: the wrapped difference, negated where negative.
                let distance =
                    _mm_andnot_si128(drop, _mm_sub_epi32(_mm_xor_si128(d, below), below));
                (
                    _mm_unpacklo_epi32(distance, zero()),
                    _mm_unpackhi_epi32(distance, zero()),
                )
            };
            let (drop_low, drop_high) = (
                _mm_unpacklo_epi16(drop, drop),
                _mm_unpackhi_epi16(drop, drop),
            );
            let (a, b) = four(
                _mm_unpacklo_epi16(p0, p1),
                _mm_unpacklo_epi16(p2, p3),
                _mm_unpacklo_epi16(i, zero()),
                drop_low,
            );
            let (c, d) = four(
                _mm_unpackhi_epi16(p0, p1),
                _mm_unpackhi_epi16(p2, p3),
                _mm_unpackhi_epi16(i, zero()),
                drop_high,
            );
            acc = (
                _mm_add_epi64(acc.0, _mm_add_epi64(a, c)),
                _mm_add_epi64(acc.1, _mm_add_epi64(b, d)),
            );
        }
        Some(())
    };
    // The column of each lane's value, and the padding column.
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    let (eight, wrap, padding) = unsafe {
        (
            _mm_set1_epi16(8),
            _mm_set1_epi16(p16),
            _mm_set1_epi16(p16 - 1),
        )
    };
    let lanes = load(&[0, 1, 2, 3, 4, 5, 6, 7]);
    let mut column = lanes;
    let mut k = 0;
    let mut done = Some(());
    while k + LANES <= n {
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let drop = unsafe { _mm_cmpeq_epi16(column, padding) };
        done = done.and(add8(k, drop));
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        column = unsafe {
            let next = _mm_add_epi16(column, eight);
            _mm_sub_epi16(
                next,
                _mm_and_si128(
                    _mm_cmpgt_epi16(next, _mm_sub_epi16(wrap, load(&[1; LANES]))),
                    wrap,
                ),
            )
        };
        k += LANES;
    }
    let rest = n - k;
    if rest > 0 {
        // The last eight values, from column p - 8 of the last row (n is a multiple of p);
        // the lanes the blocks before counted dropped too.
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let drop = unsafe {
            let start = _mm_set1_epi16(p16 - 8);
            // rest < 8.
            #[allow(clippy::cast_possible_truncation)]
            let counted = _mm_cmpgt_epi16(_mm_set1_epi16((LANES - rest) as i16), lanes);
            _mm_or_si128(
                _mm_cmpeq_epi16(_mm_add_epi16(start, lanes), padding),
                counted,
            )
        };
        done = done.and(add8(n - LANES, drop));
    }
    if done.is_none() {
        return portable::abs_residual(w, block, pitch, intensity, (gain, bias));
    }
    let mut halves = [0u64; 2];
    // SAFETY: writes the 16 bytes of `halves`, with no alignment needed (module docs).
    unsafe { _mm_storeu_si128(halves.as_mut_ptr().cast(), _mm_add_epi64(acc.0, acc.1)) };
    halves[0].wrapping_add(halves[1])
}

/// [`super::runs::template_sums`]: the nine products of each block of eight values in one pass
/// (the last block of a chunk that is not a multiple of eight long overlapping the one
/// before, masked), and the lanes of each chunk's sums added at its end.
#[inline(never)]
pub(super) fn template_sums(intensity: &[i16], dx: &[i16], dy: &[i16]) -> [i64; 9] {
    let n = intensity.len();
    if n < LANES || dx.len() != n || dy.len() != n {
        return portable::template_sums(intensity, dx, dy);
    }
    // The buffers of the flight presets' windows and of the 21 px default, of known lengths:
    // their loops without bounds checks.
    let sums = match n {
        56 => template_sums_of::<56>(intensity, dx, dy),
        90 => template_sums_of::<90>(intensity, dx, dy),
        462 => template_sums_of::<462>(intensity, dx, dy),
        _ => None,
    };
    if let Some(sums) = sums {
        return sums;
    }
    let mut s = [0i64; 9];
    let chunks = intensity
        .chunks(TEMPLATE_CHUNK)
        .zip(dx.chunks(TEMPLATE_CHUNK).zip(dy.chunks(TEMPLATE_CHUNK)));
    for (i, (gx, gy)) in chunks {
        let part = if i.len() < LANES {
            portable::template_sums(i, gx, gy)
        } else {
            chunk_sums(i, gx, gy)
        };
        for (total, v) in s.iter_mut().zip(part) {
            *total = total.wrapping_add(v);
        }
    }
    s
}

/// [`template_sums`] of buffers of `N` values (chunks of at least 8), in chunks of constant
/// lengths.
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn template_sums_of<const N: usize>(i: &[i16], x: &[i16], y: &[i16]) -> Option<[i64; 9]> {
    let (i, x, y): (&[i16; N], &[i16; N], &[i16; N]) =
        (i.try_into().ok()?, x.try_into().ok()?, y.try_into().ok()?);
    let mut s = [0i64; 9];
    let mut start = 0;
    while start < N {
        let end = (start + TEMPLATE_CHUNK).min(N);
        let part = chunk_sums(&i[start..end], &x[start..end], &y[start..end]);
        for (total, v) in s.iter_mut().zip(part) {
            *total = total.wrapping_add(v);
        }
        start = end;
    }
    Some(s)
}

/// The sums of [`template_sums`] over one chunk of at least 8 values: the nine products of
/// each block of eight values in one pass (the last, when the chunk is not a multiple of eight
/// long, overlapping the one before, masked), and the lanes added at the end.
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn chunk_sums(i: &[i16], gx: &[i16], gy: &[i16]) -> [i64; 9] {
    let ones = pairs_of(1, 1);
    let mut acc = [zero(); 9];
    let mut add9 = |v, x, y| {
        let terms = [
            madd(x, x),
            madd(x, y),
            madd(y, y),
            madd(x, ones),
            madd(y, ones),
            madd(v, ones),
            madd(v, v),
            madd(v, x),
            madd(v, y),
        ];
        for (acc, term) in acc.iter_mut().zip(terms) {
            *acc = add(*acc, term);
        }
    };
    let len = i.len().min(gx.len()).min(gy.len());
    let at = |v: &[i16], k: usize| load_at(v, k).unwrap_or(zero());
    let mut k = 0;
    while k + LANES <= len {
        add9(at(i, k), at(gx, k), at(gy, k));
        k += LANES;
    }
    if k < len && len >= LANES {
        let start = len - LANES;
        let mask = load_at(&MASKS, len % LANES).unwrap_or(zero());
        let masked = |v: &[i16]| and(at(v, start), mask);
        add9(masked(i), masked(gx), masked(gy));
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7, a8] = acc;
    let (first, second) = (lane_sums4([a0, a1, a2, a3]), lane_sums4([a4, a5, a6, a7]));
    [
        i64::from(first[0]),
        i64::from(first[1]),
        i64::from(first[2]),
        i64::from(first[3]),
        i64::from(second[0]),
        i64::from(second[1]),
        // `Σ i²` of a chunk, read unsigned.
        i64::from(second[2] as u32),
        i64::from(second[3]),
        i64::from(lanes_sum(a8, 0)),
    ]
}

/// The sums of the four lanes of each of four registers, wrapping: a transpose by unpacks,
/// added as it goes.
#[inline(always)]
fn lane_sums4([a, b, c, d]: [__m128i; 4]) -> [i32; 4] {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    let sums = unsafe {
        // (a0 + a2, b0 + b2, a1 + a3, b1 + b3) and the same for c and d.
        let ab = add(_mm_unpacklo_epi32(a, b), _mm_unpackhi_epi32(a, b));
        let cd = add(_mm_unpacklo_epi32(c, d), _mm_unpackhi_epi32(c, d));
        add(_mm_unpacklo_epi64(ab, cd), _mm_unpackhi_epi64(ab, cd))
    };
    let mut lanes = [0i32; 4];
    // SAFETY: writes the 16 bytes of `lanes`, with no alignment needed (module docs).
    unsafe { _mm_storeu_si128(lanes.as_mut_ptr().cast(), sums) };
    lanes
}

/// `row` from `start` on (empty past its end).
#[inline(always)]
fn from(row: &[i16], start: usize) -> &[i16] {
    row.get(start..).unwrap_or(&[])
}

/// Sign-extends the low 16 bits of each 32-bit lane: `as i16` before a pack, which then
/// cannot saturate.
#[inline(always)]
fn low_halves(v: __m128i) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe { _mm_srai_epi32::<16>(_mm_slli_epi32::<16>(v)) }
}

/// The weights as the PMADDWD operands of the upper and the lower row, `(w00, w01)` and
/// `(w10, w11)` four times; `None` when a weight is outside `0..=i16::MAX` (never for LK's
/// weights, which are at most `2^14`).
#[inline(always)]
fn weight_pairs(w: &[i32; 4]) -> Option<(__m128i, __m128i)> {
    let [w00, w01, w10, w11] = *w;
    if (w00 | w01 | w10 | w11) as u32 > i16::MAX as u32 {
        return None;
    }
    // Each weight is in 0..=i16::MAX, checked above.
    #[allow(clippy::cast_possible_truncation)]
    let half = |w: i32| w as i16;
    Some((
        pairs_of(half(w00), half(w01)),
        pairs_of(half(w10), half(w11)),
    ))
}

/// Eight bilinear samples from the rows' values at `k` and at `k + 1`: lane by lane,
/// [`super::runs::bilinear`]'s sum (PMADDWD of interleaved `(t[k], t[k + 1])` pairs with the
/// weight pairs), rounding, shift and truncation.
#[inline(always)]
fn bilinear8(
    weights: (__m128i, __m128i),
    (t0, t1): (__m128i, __m128i),
    (b0, b1): (__m128i, __m128i),
) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let four = |top, bottom| low_halves(sample4(weights, top, bottom));
        let low = four(_mm_unpacklo_epi16(t0, t1), _mm_unpacklo_epi16(b0, b1));
        let high = four(_mm_unpackhi_epi16(t0, t1), _mm_unpackhi_epi16(b0, b1));
        _mm_packs_epi32(low, high)
    }
}

/// [`super::runs::bilinear_row`].
#[inline(never)]
pub(super) fn bilinear_row(w: &[i32; 4], top: &[i16], bottom: &[i16], out: &mut [i16]) {
    let n = out.len();
    let shaped = n >= LANES && top.len() > n && bottom.len() > n;
    let (Some(weights), true) = (weight_pairs(w), shaped) else {
        return portable::bilinear_row(w, top, bottom, out);
    };
    // Rows at least `n + 1` long: the values at `k + 1` of every output `k` are there.
    let rows = (whole(top).zip(whole(from(top, 1)))).zip(whole(bottom).zip(whole(from(bottom, 1))));
    let mut blocks = out.chunks_exact_mut(LANES);
    for (o, (t, b)) in (&mut blocks).zip(rows) {
        if let Ok(o) = <&mut [i16; LANES]>::try_from(o) {
            store(o, bilinear8(weights, t, b));
        }
    }
    if blocks.into_remainder().is_empty() {
        return;
    }
    // The last eight samples, overlapping the last whole block.
    let start = n.saturating_sub(LANES);
    let next = start.saturating_add(1);
    if let (Some(t0), Some(t1), Some(b0), Some(b1)) = (
        load_at(top, start),
        load_at(top, next),
        load_at(bottom, start),
        load_at(bottom, next),
    ) {
        store_at(out, start, bilinear8(weights, (t0, t1), (b0, b1)));
    }
}

/// [`super::runs::widen_rows`]: each row in blocks of eight pixels widened to `i16`, the last
/// block overlapping the one before when `cols` is not a multiple of eight. Rows under eight
/// pixels go to the portable code.
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
pub(super) fn widen_rows(block: &[u8], stride: usize, cols: usize, out: &mut [i16], pitch: usize) {
    if cols < LANES || stride < cols || pitch < cols {
        return portable::widen_rows(block, stride, cols, out, pitch);
    }
    let widen = |src: &[u8], dst: &mut [i16], at: usize| {
        let pixels = src.get(at..at + LANES).map(<&[u8; LANES]>::try_from);
        if let Some(Ok(pixels)) = pixels {
            // SAFETY: reads the 8 bytes of `pixels`, with no alignment needed (module docs);
            // the rest is register arithmetic on an SSE2 target.
            let wide = unsafe {
                let bytes = _mm_loadl_epi64(pixels.as_ptr().cast());
                _mm_unpacklo_epi8(bytes, zero())
            };
            store_at(dst, at, wide);
        }
    };
    let last = cols - LANES;
    // Row by row without `chunks`, whose zip would divide the lengths by the strides.
    let (mut from, mut to) = (0, 0);
    while let (Some(src), Some(dst)) = (block.get(from..from + cols), out.get_mut(to..to + cols)) {
        let mut c = 0;
        while c < last {
            widen(src, dst, c);
            c += LANES;
        }
        widen(src, dst, last);
        (from, to) = (from + stride, to + pitch);
    }
}

/// True when every value of `v` is a pixel, `0..=255`.
#[inline(always)]
fn all_pixels(v: &[i16]) -> bool {
    if v.len() < LANES {
        return v.iter().all(|&x| (0..=255).contains(&x));
    }
    let ored = whole(v).chain(last(v)).fold(zero(), |acc, x| unsafe {
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        _mm_or_si128(acc, x)
    });
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let high = _mm_and_si128(ored, _mm_set1_epi16(!0xFF));
        _mm_movemask_epi8(_mm_cmpeq_epi16(high, zero())) == 0xFFFF
    }
}

/// [`weight_pairs`] for weights that make samples of pixels `0..=8160`: each at least zero
/// and their sum at most `2^14` (LK's sum to `2^14`).
#[inline(always)]
fn pixel_weight_pairs(w: &[i32; 4]) -> Option<(__m128i, __m128i)> {
    let in_range = w.iter().all(|&v| (0..=1 << WEIGHT_BITS).contains(&v));
    (in_range && w.iter().sum::<i32>() <= 1 << WEIGHT_BITS).then_some(())?;
    weight_pairs(w)
}

/// `(v + 16) >> 5` of two registers of four 32-bit sums, packed: [`super::runs::rescale`] of
/// sums whose results fit `i16` (those of samples of pixels, at most 4080).
#[inline(always)]
fn rescale_exact(low: __m128i, high: __m128i) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let round = _mm_set1_epi32(1 << (SAMPLE_BITS - 1));
        let four = |s| _mm_srai_epi32::<{ SAMPLE_BITS as i32 }>(add(s, round));
        _mm_packs_epi32(four(low), four(high))
    }
}

/// `3 (a + c) + 10 b` lane by lane as two registers of four 32-bit sums: Scharr's smoothing
/// of values whose pair sums fit `i16`.
#[inline(always)]
fn smooth(a: __m128i, b: __m128i, c: __m128i) -> (__m128i, __m128i) {
    let weights = pairs_of(3, 10);
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let outer = _mm_add_epi16(a, c);
        let low = madd(_mm_unpacklo_epi16(outer, b), weights);
        let high = madd(_mm_unpackhi_epi16(outer, b), weights);
        (low, high)
    }
}

/// Four samples between pixels, as 32-bit lanes, from the interleaved pixel pairs of the rows
/// above (`top`) and below (`bottom`) and the weights' pairs.
#[inline(always)]
fn sample4((upper, lower): (__m128i, __m128i), top: __m128i, bottom: __m128i) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let round = _mm_set1_epi32(1 << (WEIGHT_BITS - SAMPLE_BITS - 1));
        let sum = add(add(madd(top, upper), madd(bottom, lower)), round);
        _mm_srai_epi32::<{ (WEIGHT_BITS - SAMPLE_BITS) as i32 }>(sum)
    }
}

/// Eight samples between pixels, exact in `i16` (0..=8160): [`sample4`] of both halves, packed.
#[inline(always)]
fn sample8(
    weights: (__m128i, __m128i),
    top: (__m128i, __m128i),
    bottom: (__m128i, __m128i),
) -> __m128i {
    let (low, high) = (
        sample4(weights, top.0, bottom.0),
        sample4(weights, top.1, bottom.1),
    );
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe { _mm_packs_epi32(low, high) }
}

/// A patch row's samples one and two columns right of each lane of `a0`, whose next eight
/// columns are `a1`: `(middle0, right0, middle1, right1)`, zeros shifted in past `a1`.
#[inline(always)]
fn neighbours(a0: __m128i, a1: __m128i) -> (__m128i, __m128i, __m128i, __m128i) {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        (
            _mm_or_si128(_mm_srli_si128::<2>(a0), _mm_slli_si128::<14>(a1)),
            _mm_or_si128(_mm_srli_si128::<4>(a0), _mm_slli_si128::<12>(a1)),
            _mm_srli_si128::<2>(a1),
            _mm_srli_si128::<4>(a1),
        )
    }
}

/// A window row's `(dx, dy)` from its three patch rows' differences two columns apart and the
/// horizontal smoothings of the patch rows above and below it.
#[inline(always)]
fn derivatives(
    [d_up, d_mid, d_down]: [__m128i; 3],
    s_up: (__m128i, __m128i),
    s_down: (__m128i, __m128i),
) -> (__m128i, __m128i) {
    let (low, high) = smooth(d_up, d_mid, d_down);
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    let (gy_low, gy_high) = unsafe {
        (
            _mm_sub_epi32(s_down.0, s_up.0),
            _mm_sub_epi32(s_down.1, s_up.1),
        )
    };
    (rescale_exact(low, high), rescale_exact(gy_low, gy_high))
}

/// [`super::runs::sampled_template`]. For pixels `0..=255` and weights that sum to at most
/// `2^14` (every LK call) the samples are `0..=8160`: differences and pair sums of samples fit
/// `i16`, and the Scharr sums become separable at no loss: `dx` is the vertical smoothing of
/// the rows' differences two columns apart, `dy` the difference of the rows' horizontal
/// smoothings two rows apart. The patch is never stored: each column block of the window walks
/// down the patch rows with the last two rows' differences and smoothings in registers.
/// Windows under 8 px, and any other input, go to the portable code.
#[allow(clippy::arithmetic_side_effects)]
#[inline(never)]
pub(super) fn sampled_template(
    w: &[i32; 4],
    frame: Option<(&[u8], usize)>,
    source: &mut [i16],
    patch: &mut [i16],
    pitch: usize,
    [intensity, dx, dy]: [&mut [i16]; 3],
) {
    let win = intensity.len().checked_div(pitch).unwrap_or(0);
    let n = win.saturating_add(3);
    let shaped = win >= LANES
        && pitch >= win
        && intensity.len() == win * pitch
        && dx.len() == intensity.len()
        && dy.len() == intensity.len()
        && source.len() >= n * n;
    let weights = pixel_weight_pairs(w).filter(|_| shaped);
    // The 9 and 10 px windows inside the frame read its pixels where they lie.
    if let (Some(weights), Some((block, stride)), 9 | 10) = (weights, frame, win) {
        let pairs = |r| frame_pairs(block, stride, n, r);
        if template_rows_12(weights, pairs, n, pitch, [intensity, dx, dy]).is_some() {
            return;
        }
    }
    if let Some((block, stride)) = frame {
        widen_rows(block, stride, n, source, n);
    }
    let pixels = shaped && all_pixels(source.get(..n * n).unwrap_or(&[]));
    let Some(weights) = weights.filter(|_| pixels) else {
        return portable::sampled_template(w, None, source, patch, pitch, [intensity, dx, dy]);
    };
    let source = &*source;
    // Patches up to 16 px wide, in two registers a row, when the source has the slack the
    // second register's loads reach into.
    let slack = source.len() >= n * n + LANES;
    if slack && (win == 9 || win == 10) {
        let pairs = |r| gathered_pairs(source, n, r);
        let done = template_rows_12(weights, pairs, n, pitch, [intensity, dx, dy]);
        debug_assert!(done.is_some(), "shaped inputs hold every block");
        return;
    }
    if slack && win + 2 <= 2 * LANES {
        let done = template_rows_16(weights, source, n, pitch, [intensity, dx, dy]);
        debug_assert!(done.is_some(), "shaped inputs hold every block");
        return;
    }
    // Column blocks at 0, 8, ... and, if the window is not a multiple of 8 wide, its last 8.
    let last = win - LANES;
    let mut c = 0;
    loop {
        let start = c.min(last);
        let done = template_column(weights, source, n, start, pitch, [intensity, dx, dy]);
        debug_assert!(done.is_some(), "shaped inputs hold every block");
        if start == last {
            return;
        }
        c += LANES;
    }
}

/// Row `r` of gathered values `n` apart: the `REACH` values from its start, if `source` holds
/// them.
#[inline(always)]
fn source_row<const REACH: usize>(source: &[i16], n: usize, r: usize) -> Option<&[i16; REACH]> {
    let start = r.checked_mul(n)?;
    source
        .get(start..start.checked_add(REACH)?)?
        .try_into()
        .ok()
}

/// Eight values of `row` from `k` in a register, if it holds them.
#[inline(always)]
fn eight_at<const REACH: usize>(row: &[i16; REACH], k: usize) -> Option<__m128i> {
    row.get(k..k.checked_add(LANES)?)
        .and_then(|v| v.try_into().ok())
        .map(load)
}

/// [`template_rows_12`]'s source row `r` from gathered values (rows `n` apart, with the slack
/// its four-lane loads reach into): the interleaved pairs (value k, value k + 1) of columns
/// 0..8 in two registers, of columns 8..12 in one.
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn gathered_pairs(source: &[i16], n: usize, r: usize) -> Option<((__m128i, __m128i), __m128i)> {
    const REACH: usize = LANES + 1 + 4;
    let row = source_row::<REACH>(source, n, r)?;
    let at = |k: usize| eight_at(row, k);
    let load4 = |k: usize| -> Option<__m128i> {
        let four: &[i16; 4] = row.get(k..k + 4)?.try_into().ok()?;
        // SAFETY: reads the 8 bytes of `four`, with no alignment needed (module docs).
        Some(unsafe { _mm_loadl_epi64(four.as_ptr().cast()) })
    };
    let (a, b) = (at(0)?, at(1)?);
    let (c, d) = (load4(LANES)?, load4(LANES + 1)?);
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    Some(unsafe {
        (
            (_mm_unpacklo_epi16(a, b), _mm_unpackhi_epi16(a, b)),
            _mm_unpacklo_epi16(c, d),
        )
    })
}

/// [`gathered_pairs`] from the frame's pixels where they lie (rows `stride` apart, each `n` long
/// to the block's end), widened as they are loaded. The four-lane values from column 9 come
/// from column 8's shifted when the row ends at column 11 (its last lane, outside the patch's
/// source, is then zero).
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn frame_pairs(
    block: &[u8],
    stride: usize,
    n: usize,
    r: usize,
) -> Option<((__m128i, __m128i), __m128i)> {
    let start = r.checked_mul(stride)?;
    let row = block.get(start..start.checked_add(n)?)?;
    let eight = |k: usize| -> Option<__m128i> {
        let pixels: &[u8; LANES] = row.get(k..k + LANES)?.try_into().ok()?;
        // SAFETY: reads the 8 bytes of `pixels`, with no alignment needed (module docs); the
        // rest is register arithmetic on an SSE2 target.
        Some(unsafe { _mm_unpacklo_epi8(_mm_loadl_epi64(pixels.as_ptr().cast()), zero()) })
    };
    let four = |k: usize| -> Option<__m128i> {
        let pixels: [u8; 4] = row.get(k..k + 4)?.try_into().ok()?;
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        Some(unsafe { _mm_unpacklo_epi8(_mm_cvtsi32_si128(i32::from_le_bytes(pixels)), zero()) })
    };
    let (a, b, c) = (eight(0)?, eight(1)?, four(LANES)?);
    let d = match four(LANES + 1) {
        Some(d) => d,
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        None => unsafe { _mm_srli_si128::<2>(c) },
    };
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    Some(unsafe {
        (
            (_mm_unpacklo_epi16(a, b), _mm_unpackhi_epi16(a, b)),
            _mm_unpacklo_epi16(c, d),
        )
    })
}

/// [`template_rows_16`] for windows of 9 and 10 px, whose second column block holds one or
/// two window columns: the patch rows' samples from column 8 on need only their first four
/// (the block's columns and the two to their right), so that block runs on four lanes, its
/// sums in one register of 32-bit lanes, and stores its one or two window columns.
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn template_rows_12(
    sample_weights: (__m128i, __m128i),
    pairs: impl Fn(usize) -> Option<((__m128i, __m128i), __m128i)>,
    n: usize,
    pitch: usize,
    [intensity, dx, dy]: [&mut [i16]; 3],
) -> Option<()> {
    let win = n.checked_sub(3)?;
    let weights = pairs_of(3, 10);
    // `3 (a + c) + 10 b` of the first four lanes.
    let smooth4 = |a: __m128i, b: __m128i, c: __m128i| {
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        unsafe { madd(_mm_unpacklo_epi16(_mm_add_epi16(a, c), b), weights) }
    };
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    let rescale4 = |s: __m128i| unsafe {
        let round = _mm_set1_epi32(1 << (SAMPLE_BITS - 1));
        let v = _mm_srai_epi32::<{ SAMPLE_BITS as i32 }>(add(s, round));
        _mm_packs_epi32(v, v)
    };
    // The first two values of a register at `at` in `buf`, if it holds them.
    let put2 = |buf: &mut [i16], at: usize, v: __m128i| {
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let bits = unsafe { _mm_cvtsi128_si32(v) };
        // The register's first two 16-bit lanes, low first: the one or two window columns.
        #[allow(clippy::cast_possible_truncation)]
        let lanes = [bits as i16, (bits >> 16) as i16];
        if win > LANES + 1 {
            if let Some(Ok(two)) = buf.get_mut(at..at + 2).map(<&mut [i16; 2]>::try_from) {
                *two = lanes;
            }
        } else if let Some(one) = buf.get_mut(at) {
            *one = lanes[0];
        }
    };
    let (mut top, mut top_right) = pairs(0)?;
    let zeros = (zero(), zero());
    let (mut d0, mut s0) = ([zero(); 2], [zeros; 2]);
    let (mut d1, mut s1) = ([zero(); 2], [zero(); 2]);
    for r in 0..n - 1 {
        let (bottom, bottom_right) = pairs(r + 1)?;
        let a0 = sample8(sample_weights, top, bottom);
        let right = sample4(sample_weights, top_right, bottom_right);
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let a1 = unsafe { _mm_packs_epi32(right, right) };
        (top, top_right) = (bottom, bottom_right);
        let (middle0, right0, middle1, right1) = neighbours(a0, a1);
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let (diff0, diff1) = unsafe { (_mm_sub_epi16(right0, a0), _mm_sub_epi16(right1, a1)) };
        let smooth0 = smooth(a0, middle0, right0);
        let smooth1 = smooth4(a1, middle1, right1);
        if r >= 1 && r <= win {
            let at = (r - 1) * pitch;
            store_at(intensity, at, middle0);
            put2(intensity, at + LANES, middle1);
        }
        if r >= 2 {
            let at = (r - 2) * pitch;
            let (gx0, gy0) = derivatives([d0[0], d0[1], diff0], s0[0], smooth0);
            // SAFETY: register arithmetic on an SSE2 target (module docs).
            let gy1 = rescale4(unsafe { _mm_sub_epi32(smooth1, s1[0]) });
            let gx1 = rescale4(smooth4(d1[0], d1[1], diff1));
            store_at(dx, at, gx0);
            store_at(dy, at, gy0);
            put2(dx, at + LANES, gx1);
            put2(dy, at + LANES, gy1);
        }
        (d0, s0) = ([d0[1], diff0], [s0[1], smooth0]);
        (d1, s1) = ([d1[1], diff1], [s1[1], smooth1]);
    }
    Some(())
}

/// [`sampled_template`] for windows of 8 to 14 px, whose patch rows are at most 16 samples:
/// each patch row in two registers (columns `0..8` and `8..16`), the window's two column
/// blocks from them by lane shifts. The second block, when shorter than 8, is stored whole
/// where the buffer holds it: its lanes past the window land in the padding column, which the
/// caller clears, and in the next row, which is stored after it. `None` if a load or store
/// left its buffer (never for the shapes `sampled_template` checks and a source of
/// `n^2 + 8` values: the second register's loads reach at most 7 values past the square).
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn template_rows_16(
    sample_weights: (__m128i, __m128i),
    source: &[i16],
    n: usize,
    pitch: usize,
    [intensity, dx, dy]: [&mut [i16]; 3],
) -> Option<()> {
    const REACH: usize = 2 * LANES + 1;
    let win = n.checked_sub(3)?;
    // The interleaved pairs (value k, value k + 1) of source row `r`, columns 0.. and 8..
    let pairs = |r: usize| -> Option<[(__m128i, __m128i); 2]> {
        let row = source_row::<REACH>(source, n, r)?;
        let at = |k: usize| eight_at(row, k);
        let (a, b, c, d) = (at(0)?, at(1)?, at(LANES)?, at(LANES + 1)?);
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        Some(unsafe {
            [
                (_mm_unpacklo_epi16(a, b), _mm_unpackhi_epi16(a, b)),
                (_mm_unpacklo_epi16(c, d), _mm_unpackhi_epi16(c, d)),
            ]
        })
    };
    // Stores block `b` of window row `row` (see above).
    let put = |buf: &mut [i16], row: usize, b: usize, v: __m128i| {
        let at = row * pitch + b * LANES;
        if at + LANES <= buf.len() {
            store_at(buf, at, v);
        } else {
            let mut lanes = [0i16; LANES];
            store(&mut lanes, v);
            let end = (row * pitch + win).min(buf.len());
            if let Some(out) = buf.get_mut(at..end) {
                out.iter_mut().zip(lanes).for_each(|(o, v)| *o = v);
            }
        }
    };
    // One column block: the patch row's samples from its first column (`a`) with the middle
    // and right neighbours, their difference two columns apart and horizontal smoothing.
    let block = |a: __m128i, middle: __m128i, right: __m128i| {
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let difference = unsafe { _mm_sub_epi16(right, a) };
        (difference, smooth(a, middle, right))
    };
    let second = win > LANES;
    let [mut top0, mut top1] = pairs(0)?;
    let zeros = (zero(), zero());
    let (mut d0, mut s0) = ([zero(); 2], [zeros; 2]);
    let (mut d1, mut s1) = ([zero(); 2], [zeros; 2]);
    for r in 0..n - 1 {
        let [bottom0, bottom1] = pairs(r + 1)?;
        let a0 = sample8(sample_weights, top0, bottom0);
        let a1 = sample8(sample_weights, top1, bottom1);
        (top0, top1) = (bottom0, bottom1);
        let (middle0, right0, middle1, right1) = neighbours(a0, a1);
        let (diff0, smooth0) = block(a0, middle0, right0);
        let (diff1, smooth1) = block(a1, middle1, right1);
        if r >= 1 && r <= win {
            put(intensity, r - 1, 0, middle0);
            if second {
                put(intensity, r - 1, 1, middle1);
            }
        }
        if r >= 2 {
            let (gx, gy) = derivatives([d0[0], d0[1], diff0], s0[0], smooth0);
            put(dx, r - 2, 0, gx);
            put(dy, r - 2, 0, gy);
            if second {
                let (gx, gy) = derivatives([d1[0], d1[1], diff1], s1[0], smooth1);
                put(dx, r - 2, 1, gx);
                put(dy, r - 2, 1, gy);
            }
        }
        (d0, s0) = ([d0[1], diff0], [s0[1], smooth0]);
        (d1, s1) = ([d1[1], diff1], [s1[1], smooth1]);
    }
    Some(())
}

/// The eight window columns from `c` of [`sampled_template`], down every patch row; `None` if a
/// load or store left its buffer (never for the shapes `sampled_template` checks: the last
/// load of a block ends at the source's `n^2`).
#[allow(clippy::arithmetic_side_effects)]
#[inline(always)]
fn template_column(
    sample_weights: (__m128i, __m128i),
    source: &[i16],
    n: usize,
    c: usize,
    pitch: usize,
    [intensity, dx, dy]: [&mut [i16]; 3],
) -> Option<()> {
    // The interleaved pairs (value k, value k + 1) of source row `r` from column `x`.
    let pairs = |r: usize, x: usize| -> Option<(__m128i, __m128i)> {
        let at = r.checked_mul(n)?.checked_add(x)?;
        let (a, b) = (load_at(source, at)?, load_at(source, at.checked_add(1)?)?);
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        Some(unsafe { (_mm_unpacklo_epi16(a, b), _mm_unpackhi_epi16(a, b)) })
    };
    let (mut top_a, mut top_b) = (pairs(0, c)?, pairs(0, c.checked_add(2)?)?);
    // The last two patch rows' differences two columns apart and horizontal smoothings.
    let mut differences = [zero(); 2];
    let mut smoothings = [(zero(), zero()); 2];
    for r in 0..n - 1 {
        let (bottom_a, bottom_b) = (pairs(r + 1, c)?, pairs(r + 1, c + 2)?);
        // Patch columns c.., c + 2.. and, between them, c + 1..: the template's intensities.
        let a = sample8(sample_weights, top_a, bottom_a);
        let b = sample8(sample_weights, top_b, bottom_b);
        (top_a, top_b) = (bottom_a, bottom_b);
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let (middle, difference) = unsafe {
            let last_lane = _mm_slli_si128::<14>(_mm_set1_epi16(-1));
            let from_b = _mm_and_si128(_mm_slli_si128::<2>(b), last_lane);
            (
                _mm_or_si128(_mm_srli_si128::<2>(a), from_b),
                _mm_sub_epi16(b, a),
            )
        };
        let smoothing = smooth(a, middle, b);
        if let Some(row) = r.checked_sub(1).filter(|&row| row < n - 3) {
            store_at(intensity, row * pitch + c, middle);
        }
        if let Some(row) = r.checked_sub(2) {
            let [d_up, d_mid] = differences;
            let (gx, gy) = derivatives([d_up, d_mid, difference], smoothings[0], smoothing);
            let at = row * pitch + c;
            store_at(dx, at, gx);
            store_at(dy, at, gy);
        }
        differences = [differences[1], difference];
        smoothings = [smoothings[1], smoothing];
    }
    Some(())
}

/// Sixteen pixels of `row` from `start`, if it holds them.
#[inline(always)]
fn load_pixels(row: &[u8], start: usize) -> Option<__m128i> {
    let block: &[u8; 16] = row.get(start..start.checked_add(16)?)?.try_into().ok()?;
    // SAFETY: reads the 16 bytes of `block`, with no alignment needed (module docs).
    Some(unsafe { _mm_loadu_si128(block.as_ptr().cast()) })
}

/// The vertical `[1 4 6 4 1]` sums of the sixteen columns from `start` of the five rows: the
/// even columns' and the odd columns' in eight 16-bit lanes each (at most `16 * 255`).
#[inline(always)]
fn vertical_sums16(rows: &[&[u8]; 5], start: usize) -> Option<(__m128i, __m128i)> {
    let [a, b, c, d, e] = [
        load_pixels(rows[0], start)?,
        load_pixels(rows[1], start)?,
        load_pixels(rows[2], start)?,
        load_pixels(rows[3], start)?,
        load_pixels(rows[4], start)?,
    ];
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let low_bytes = _mm_set1_epi16(0x00FF);
        // a + e + 4 (b + c + d) + 2 c, in 16-bit lanes: no lane carries into the next.
        let sum = |[a, b, c, d, e]: [__m128i; 5]| {
            let inner = _mm_add_epi16(_mm_add_epi16(b, c), d);
            let outer = _mm_add_epi16(a, e);
            _mm_add_epi16(
                _mm_add_epi16(outer, _mm_slli_epi16::<2>(inner)),
                _mm_slli_epi16::<1>(c),
            )
        };
        let words = [a, b, c, d, e];
        let even = sum(words.map(|v| _mm_and_si128(v, low_bytes)));
        let odd = sum(words.map(|v| _mm_srli_epi16::<8>(v)));
        Some((even, odd))
    }
}

/// Eight outputs of [`super::binomial::binomial_row`] whose kernels start at source column
/// `start`, as the low eight bytes of a register.
#[inline(always)]
fn binomial8(rows: &[&[u8]; 5], start: usize) -> Option<__m128i> {
    // E[m] and O[m]: columns start + 2m and start + 2m + 1; then E[m + 2] and O[m + 2].
    let (even, odd) = vertical_sums16(rows, start)?;
    let (even2, odd2) = vertical_sums16(rows, start.checked_add(4)?)?;
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        // E[m + 1]: lanes 1..=7 of E beside lane 6 of E[m + 2], and so for O.
        let next = |v: __m128i, v2: __m128i| {
            _mm_or_si128(
                _mm_slli_si128::<2>(v2),
                _mm_srli_si128::<14>(_mm_slli_si128::<12>(v)),
            )
        };
        let (even1, odd1) = (next(even, even2), next(odd, odd2));
        // E[m] + 4 O[m] + 6 E[m+1] + 4 O[m+1] + E[m+2] + 128 <= 256 * 255 + 128 < 2^16.
        let fours = _mm_add_epi16(_mm_add_epi16(odd, odd1), even1);
        let sum = _mm_add_epi16(
            _mm_add_epi16(even, even2),
            _mm_add_epi16(_mm_slli_epi16::<2>(fours), _mm_slli_epi16::<1>(even1)),
        );
        let rounded = _mm_srli_epi16::<8>(_mm_add_epi16(sum, _mm_set1_epi16(128)));
        Some(_mm_packus_epi16(rounded, rounded))
    }
}

/// [`super::binomial::binomial_row`] in blocks of eight outputs; the outputs past the last
/// whole block are computed again with the block before (the same values, stored twice).
/// Fewer than eight outputs, and inputs outside the kernel's contract (an odd count, short
/// rows), go to the portable kernel, so the bytes written are always the portable ones.
pub(super) fn binomial_row(rows: &[&[u8]; 5], out: &mut [u8]) {
    let len = out.len();
    let needed = len.saturating_mul(2).saturating_add(8);
    let shaped = len >= LANES && len % 2 == 0 && rows.iter().all(|r| r.len() >= needed);
    if !shaped || binomial_blocks(rows, out).is_none() {
        super::binomial::portable::binomial_row(rows, out);
    }
}

/// The blocks of [`binomial_row`]; `None` if a load left the rows (never for shaped inputs:
/// block `j <= len - 8` reads source columns up to `2j + 21 < 2 len + 8`).
#[inline(always)]
fn binomial_blocks(rows: &[&[u8]; 5], out: &mut [u8]) -> Option<()> {
    let last = out.len().checked_sub(LANES)?;
    let reach = rows.iter().map(|r| r.len()).min()?;
    // The vertical sums of the block's 16 columns, when the block before computed them.
    let mut ahead: Option<(__m128i, __m128i)> = None;
    let mut j = 0;
    loop {
        let block = j.min(last);
        let start = block.checked_mul(2)?.checked_add(2)?;
        let pixels = match start.checked_add(32) {
            // A whole block whose next 16 columns are in the rows: this block's sums and
            // those, which the next block starts from.
            Some(end) if block == j && end <= reach => {
                let here = match ahead {
                    Some(sums) => sums,
                    None => vertical_sums16(rows, start)?,
                };
                let next = vertical_sums16(rows, start.checked_add(16)?)?;
                ahead = Some(next);
                binomial8_from(here, next)
            }
            _ => binomial8(rows, start)?,
        };
        let target: &mut [u8; 8] = out
            .get_mut(block..block.checked_add(LANES)?)?
            .try_into()
            .ok()?;
        // SAFETY: writes the 8 bytes of `target`, with no alignment needed (module docs).
        unsafe { _mm_storel_epi64(target.as_mut_ptr().cast(), pixels) };
        if block == last {
            return Some(());
        }
        j = j.saturating_add(LANES);
    }
}

/// [`binomial8`] from the vertical sums of its 16 columns, `(E[m], O[m])`, and of the 16 after
/// them, `(E[m + 8], O[m + 8])`: `E[m + 1]`, `O[m + 1]` and `E[m + 2]` by lane shifts across
/// the two, instead of a second pass over the rows.
#[inline(always)]
fn binomial8_from((even, odd): (__m128i, __m128i), (even8, odd8): (__m128i, __m128i)) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let even1 = _mm_or_si128(_mm_srli_si128::<2>(even), _mm_slli_si128::<14>(even8));
        let odd1 = _mm_or_si128(_mm_srli_si128::<2>(odd), _mm_slli_si128::<14>(odd8));
        let even2 = _mm_or_si128(_mm_srli_si128::<4>(even), _mm_slli_si128::<12>(even8));
        // The same sum as `binomial8`'s.
        let fours = _mm_add_epi16(_mm_add_epi16(odd, odd1), even1);
        let sum = _mm_add_epi16(
            _mm_add_epi16(even, even2),
            _mm_add_epi16(_mm_slli_epi16::<2>(fours), _mm_slli_epi16::<1>(even1)),
        );
        let rounded = _mm_srli_epi16::<8>(_mm_add_epi16(sum, _mm_set1_epi16(128)));
        _mm_packus_epi16(rounded, rounded)
    }
}
