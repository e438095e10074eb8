//! The Gaussian level filter two pixels per 32-bit word, for scalar cores (the Cortex-M4).

use super::{reflect101, source_rows, Downsample};
use crate::frame::ImageView;

/// Two pixels per 32-bit word, for scalar cores.
///
/// A word of four source pixels splits into its even and odd columns, two 16-bit lanes each;
/// the vertical `[1 4 6 4 1]` sums of both lanes take one addition each (a sum is at most
/// `16 * 255`, so lanes never carry into each other). With `E` and `O` the even and odd
/// columns' vertical sums, output `x` is `E[x-1] + 4 O[x-1] + 6 E[x] + 4 O[x] + E[x+1]`: two
/// outputs per word, again one addition per term (at most `256 * 255 + 128 < 2^16`). Columns
/// whose kernel reaches past the row's ends take the direct path with mirrored columns.
pub(super) struct Words;

impl Downsample for Words {
    fn downsample(src: &ImageView<'_>, dst: &mut [u8], w: usize, h: usize) {
        let sw = src.width();
        // Output pairs (2k, 2k + 1) for k in 1..=pairs read source words k - 1 ..= k + 1.
        let pairs = sw.saturating_sub(8) / 4;
        let inner = 2..(2 + 2 * pairs).min(w);
        for (y, out_row) in dst.chunks_exact_mut(w).take(h).enumerate() {
            let rows = source_rows(src, y);
            if let Some(out) = out_row.get_mut(inner.clone()) {
                word_row(&rows, out);
            }
            let edges = (0..inner.start.min(w)).chain(inner.end.max(inner.start)..w);
            for x in edges {
                if let Some(o) = out_row.get_mut(x) {
                    *o = mirrored_pixel(&rows, x, sw);
                }
            }
        }
    }
}

/// The even and odd columns' vertical sums of four source columns, two 16-bit lanes each.
#[inline(always)]
fn vertical_lanes(words: [u32; 5]) -> (u32, u32) {
    const LANES: u32 = 0x00FF_00FF;
    let even = words.map(|w| w & LANES);
    let odd = words.map(|w| (w >> 8) & LANES);
    let sum = |[a, b, c, d, e]: [u32; 5]| a + e + 4 * (b + d) + 6 * c;
    (sum(even), sum(odd))
}

/// Output columns 2, 3, ... of one row, two per source word, from the row's second word on.
#[inline(never)]
fn word_row(rows: &[&[u8]; 5], out: &mut [u8]) {
    let word = |c: &[u8]| c.try_into().map_or(0, u32::from_le_bytes);
    let [r0, r1, r2, r3, r4] = rows.map(|r| r.chunks_exact(4));
    let mut lanes = r0
        .zip(r1)
        .zip(r2)
        .zip(r3.zip(r4))
        .map(|(((a, b), c), (d, e))| vertical_lanes([a, b, c, d, e].map(word)));
    let (Some((mut even, mut odd)), Some((mut next_even, mut next_odd))) =
        (lanes.next(), lanes.next())
    else {
        // Rows of fewer than two words have no inner pairs: the caller passes an empty
        // output then (`inner` is empty), so there is nothing to write.
        debug_assert!(
            out.is_empty(),
            "{} outputs from rows under two words",
            out.len()
        );
        return;
    };
    for (pair, (after_even, after_odd)) in out.chunks_exact_mut(2).zip(lanes) {
        // The previous word's high lane beside this word's low lane, and so on.
        let left = (even >> 16) | (next_even << 16);
        let right = (next_even >> 16) | (after_even << 16);
        let odd_left = (odd >> 16) | (next_odd << 16);
        let sum = left + right + 6 * next_even + 4 * (odd_left + next_odd) + 0x0080_0080;
        let pixels = ((sum >> 8) & 0xFF) | ((sum >> 16) & 0xFF00);
        pair.copy_from_slice(&(pixels as u16).to_le_bytes());
        (even, odd, next_even, next_odd) = (next_even, next_odd, after_even, after_odd);
    }
}

/// One output pixel straight from the 5x5 kernel, with mirrored columns.
// Only the pixels at a row's two ends come here: kept out of line and rolled up, it costs a call
// per border pixel instead of a copy of the kernel at each call site.
#[inline(never)]
fn mirrored_pixel(rows: &[&[u8]; 5], x: usize, width: usize) -> u8 {
    const KERNEL: [u32; 5] = [1, 4, 6, 4, 1];
    let columns: [usize; 5] =
        core::array::from_fn(|i| reflect101(2 * x as isize - 2 + i as isize, width));
    let mut sum = 128;
    for (row, kj) in rows.iter().zip(KERNEL) {
        let taps = columns.iter().zip(KERNEL);
        let across: u32 = taps
            .map(|(&sx, ki)| ki * u32::from(row.get(sx).copied().unwrap_or(0)))
            .sum();
        sum += kj * across;
    }
    (sum >> 8) as u8
}
