//! The Gaussian level filter, on every target: each row's inner outputs by the innermost kernel
//! [`crate::dsp::binomial::binomial_row`] (two pixels per 32-bit word on the Cortex-M4, SSE2 on
//! x86-64), the mirrored columns at its two ends here.

use super::{reflect101, source_rows, Downsample};
use crate::frame::ImageView;

/// The one Gaussian filter loop: per output row, the outputs whose kernels lie within whole
/// source words go to [`crate::dsp::binomial::binomial_row`] in one run; the columns whose
/// kernel reaches past the row's ends take the direct path with mirrored columns.
pub(super) struct Gaussian;

impl Downsample for Gaussian {
    fn downsample(src: &ImageView<'_>, dst: &mut [u8], w: usize, h: usize) {
        let sw = src.width();
        // Output pairs (2k, 2k + 1) for k in 1..=pairs read source words k - 1 ..= k + 1.
        let pairs = sw.saturating_sub(8) / 4;
        let inner = 2..(2 + 2 * pairs).min(w);
        for (y, out_row) in dst.chunks_exact_mut(w).take(h).enumerate() {
            let rows = source_rows(src, y);
            if let Some(out) = out_row.get_mut(inner.clone()) {
                crate::dsp::binomial::binomial_row(&rows, out);
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
