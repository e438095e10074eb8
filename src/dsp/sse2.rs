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

use super::runs::{portable, SAMPLE_BITS, WEIGHT_BITS};
use core::arch::x86_64::{
    __m128i, _mm_add_epi16, _mm_add_epi32, _mm_and_si128, _mm_loadu_si128, _mm_madd_epi16,
    _mm_or_si128, _mm_packs_epi32, _mm_packus_epi16, _mm_set1_epi16, _mm_set1_epi32,
    _mm_setzero_si128, _mm_slli_epi16, _mm_slli_epi32, _mm_slli_si128, _mm_srai_epi32,
    _mm_srli_epi16, _mm_srli_si128, _mm_storel_epi64, _mm_storeu_si128, _mm_unpackhi_epi16,
    _mm_unpacklo_epi16,
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

/// [`super::runs::dot3`].
#[inline(never)]
pub(super) fn dot3(a: &[i16], b: [&[i16]; 3]) -> [i32; 3] {
    if a.len() < LANES || b.iter().any(|b| b.len() != a.len()) {
        return portable::dot3(a, b);
    }
    let [b0, b1, b2] = b;
    let mut acc = [zero(); 3];
    let mut add3 = |x, [y0, y1, y2]: [__m128i; 3]| {
        acc = [
            add(acc[0], madd(x, y0)),
            add(acc[1], madd(x, y1)),
            add(acc[2], madd(x, y2)),
        ];
    };
    for ((x, y0), (y1, y2)) in whole(a).zip(whole(b0)).zip(whole(b1).zip(whole(b2))) {
        add3(x, [y0, y1, y2]);
    }
    // `a`'s last block masked: the products of the lanes counted already are zero.
    if let (Some(x), Some(y0), Some(y1), Some(y2)) = (last_masked(a), last(b0), last(b1), last(b2))
    {
        add3(x, [y0, y1, y2]);
    }
    acc.map(|acc| lanes_sum(acc, 0))
}

/// [`super::runs::gradient_sums`].
#[inline(never)]
pub(super) fn gradient_sums(gx: &[i16], gy: &[i16]) -> [i32; 5] {
    if gx.len() < LANES || gx.len() != gy.len() {
        return portable::gradient_sums(gx, gy);
    }
    let ones = pairs_of(1, 1);
    let mut acc = [zero(); 5];
    let mut add5 = |x, y| {
        let terms = [
            madd(x, x),
            madd(x, y),
            madd(y, y),
            madd(x, ones),
            madd(y, ones),
        ];
        for (acc, term) in acc.iter_mut().zip(terms) {
            *acc = add(*acc, term);
        }
    };
    for (x, y) in whole(gx).zip(whole(gy)) {
        add5(x, y);
    }
    if let (Some(x), Some(y)) = (last_masked(gx), last_masked(gy)) {
        add5(x, y);
    }
    acc.map(|acc| lanes_sum(acc, 0))
}

/// [`super::runs::intensity_sums`].
#[inline(never)]
pub(super) fn intensity_sums(i: &[i16], gx: &[i16], gy: &[i16]) -> [i32; 4] {
    if i.len() < LANES || gx.len() != i.len() || gy.len() != i.len() {
        return portable::intensity_sums(i, gx, gy);
    }
    let ones = pairs_of(1, 1);
    let mut acc = [zero(); 4];
    let mut add4 = |v, x, y| {
        let terms = [madd(v, ones), madd(v, v), madd(v, x), madd(v, y)];
        for (acc, term) in acc.iter_mut().zip(terms) {
            *acc = add(*acc, term);
        }
    };
    for (v, (x, y)) in whole(i).zip(whole(gx).zip(whole(gy))) {
        add4(v, x, y);
    }
    // Every term has a factor from `i`: its mask is enough.
    if let (Some(v), Some(x), Some(y)) = (last_masked(i), last(gx), last(gy)) {
        add4(v, x, y);
    }
    acc.map(|acc| lanes_sum(acc, 0))
}

/// [`super::runs::sum`].
#[inline(never)]
pub(super) fn sum(v: &[i16]) -> i32 {
    if v.len() < LANES {
        return portable::sum(v);
    }
    let ones = pairs_of(1, 1);
    let acc = whole(v)
        .chain(last_masked(v))
        .fold(zero(), |acc, x| add(acc, madd(x, ones)));
    lanes_sum(acc, 0)
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
    (upper, lower): (__m128i, __m128i),
    (t0, t1): (__m128i, __m128i),
    (b0, b1): (__m128i, __m128i),
) -> __m128i {
    const SHIFT: i32 = (WEIGHT_BITS - SAMPLE_BITS) as i32;
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let round = _mm_set1_epi32(1 << (SHIFT - 1));
        let four = |top, bottom| {
            let sum = add(add(madd(top, upper), madd(bottom, lower)), round);
            low_halves(_mm_srai_epi32::<SHIFT>(sum))
        };
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

/// [`super::runs::bilinear_row_twice`]: the row, and its inner samples again from the rows
/// one value on (cheaper than a call to copy them).
#[inline(never)]
pub(super) fn bilinear_row_twice(
    w: &[i32; 4],
    top: &[i16],
    bottom: &[i16],
    out: &mut [i16],
    inner: &mut [i16],
) {
    // A row of `inner.len() + 2` samples from rows one value longer, as the patch rows are;
    // the portable code takes any other shape.
    let n = inner.len();
    let shaped = n >= LANES
        && out.len() == n.saturating_add(2)
        && top.len() > out.len()
        && bottom.len() > out.len();
    if !shaped {
        return portable::bilinear_row_twice(w, top, bottom, out, inner);
    }
    bilinear_row(w, top, bottom, out);
    bilinear_row(w, from(top, 1), from(bottom, 1), inner);
}

/// Scharr sums of eight outputs, as two registers of four 32-bit lanes: the PMADDWD of the
/// interleaved pairs `(a[k], b[k])` of each of three pairs of rows with its weight pair, added.
#[inline(always)]
fn weighted3(terms: [(__m128i, __m128i, __m128i); 3]) -> (__m128i, __m128i) {
    let (mut low, mut high) = (zero(), zero());
    for (a, b, w) in terms {
        // SAFETY: register arithmetic on an SSE2 target (module docs).
        let (lo, hi) = unsafe { (_mm_unpacklo_epi16(a, b), _mm_unpackhi_epi16(a, b)) };
        low = add(low, madd(lo, w));
        high = add(high, madd(hi, w));
    }
    (low, high)
}

/// [`super::runs::rescale`] of eight sums in two registers, packed.
#[inline(always)]
fn rescale8((low, high): (__m128i, __m128i)) -> __m128i {
    // SAFETY: register arithmetic on an SSE2 target (module docs).
    unsafe {
        let round = _mm_set1_epi32(1 << (SAMPLE_BITS - 1));
        let four = |s| low_halves(_mm_srai_epi32::<{ SAMPLE_BITS as i32 }>(add(s, round)));
        _mm_packs_epi32(four(low), four(high))
    }
}

/// [`super::runs::scharr_row`]. Every sum is exact in 32 bits for any `i16` samples (at most
/// `16 * 65535 < 2^21`), so the order of its terms does not change it:
/// `dx = 3 (u[k+2] - u[k]) + 10 (m[k+2] - m[k]) + 3 (d[k+2] - d[k])` and
/// `dy = 3 (d[k] - u[k]) + 10 (d[k+1] - u[k+1]) + 3 (d[k+2] - u[k+2])`, each term a PMADDWD
/// of interleaved values with a pair `(c, -c)`.
#[inline(never)]
pub(super) fn scharr_row(up: &[i16], mid: &[i16], down: &[i16], dx: &mut [i16], dy: &mut [i16]) {
    let n = dx.len();
    let reach = n.saturating_add(2);
    let shaped = n >= LANES
        && dy.len() == n
        && up.len() >= reach
        && mid.len() >= reach
        && down.len() >= reach;
    if !shaped {
        return portable::scharr_row(up, mid, down, dx, dy);
    }
    let (three, ten) = (pairs_of(3, -3), pairs_of(10, -10));
    let derivatives =
        |[u0, u1, u2]: [__m128i; 3], [m0, m2]: [__m128i; 2], [d0, d1, d2]: [__m128i; 3]| {
            let gx = weighted3([(u2, u0, three), (m2, m0, ten), (d2, d0, three)]);
            let gy = weighted3([(d0, u0, three), (d1, u1, ten), (d2, u2, three)]);
            (rescale8(gx), rescale8(gy))
        };
    // Rows of `n + 2` values: those at `k + 2` of every output `k` are there.
    let shifted = |row| (whole(row), whole(from(row, 1)), whole(from(row, 2)));
    let ((u0, u1, u2), (m0, _, m2), (d0, d1, d2)) = (shifted(up), shifted(mid), shifted(down));
    let rows = (u0.zip(u1).zip(u2)).zip(m0.zip(m2)).zip(d0.zip(d1).zip(d2));
    let mut outputs = dx.chunks_exact_mut(LANES).zip(dy.chunks_exact_mut(LANES));
    for ((gx, gy), ((((u0, u1), u2), (m0, m2)), ((d0, d1), d2))) in (&mut outputs).zip(rows) {
        let (x, y) = derivatives([u0, u1, u2], [m0, m2], [d0, d1, d2]);
        if let (Ok(gx), Ok(gy)) = (
            <&mut [i16; LANES]>::try_from(gx),
            <&mut [i16; LANES]>::try_from(gy),
        ) {
            store(gx, x);
            store(gy, y);
        }
    }
    if n % LANES == 0 {
        return;
    }
    // The last eight outputs, overlapping the last whole block.
    let start = n.saturating_sub(LANES);
    let at = |row: &[i16], k: usize| load_at(row, start.saturating_add(k));
    if let (Some(u0), Some(u1), Some(u2), Some(m0), Some(m2), Some(d0), Some(d1), Some(d2)) = (
        at(up, 0),
        at(up, 1),
        at(up, 2),
        at(mid, 0),
        at(mid, 2),
        at(down, 0),
        at(down, 1),
        at(down, 2),
    ) {
        let (x, y) = derivatives([u0, u1, u2], [m0, m2], [d0, d1, d2]);
        store_at(dx, start, x);
        store_at(dy, start, y);
    }
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
    let mut j = 0;
    loop {
        let block = j.min(last);
        let pixels = binomial8(rows, block.checked_mul(2)?.checked_add(2)?)?;
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
