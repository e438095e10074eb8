//! The Gaussian level filter in strips, which the host ran before the one loop of
//! [`super::gaussian`]: each strip of output columns first sums five source rows `[1 4 6 4 1]` into
//! a small buffer, then filters that buffer horizontally at every second column. Kept for the
//! tests only, as the reference that the one loop gives the same pixels as.

use super::{reflect101, source_rows, Downsample};
use crate::frame::ImageView;

/// Output columns filtered per pass; bounds the stack used for one vertically filtered strip.
const STRIP: usize = 64;

/// Separable in strips, for SIMD units: each strip of output columns first sums five source
/// rows `[1 4 6 4 1]` into a small buffer, then filters that buffer horizontally at every second
/// column.
pub(super) struct Strips;

impl Downsample for Strips {
    fn downsample(src: &ImageView<'_>, dst: &mut [u8], w: usize, h: usize) {
        for (y, out_row) in dst.chunks_exact_mut(w).take(h).enumerate() {
            strips(&source_rows(src, y), 0..w, out_row);
        }
    }
}

/// Output columns `columns` of one row, strip by strip.
fn strips(rows: &[&[u8]; 5], columns: core::ops::Range<usize>, out_row: &mut [u8]) {
    // Vertical sums for the source columns of one strip: at most 16 * 255, fits u16.
    let mut column_sums = [0u16; 2 * STRIP + 3];
    let mut x0 = columns.start;
    while x0 < columns.end {
        let x1 = (x0 + STRIP).min(columns.end);
        // Source columns 2*x0-2 ..= 2*(x1-1)+2.
        let count = 2 * (x1 - x0) + 3;
        vertical_sums(rows, 2 * x0 as isize - 2, &mut column_sums[..count]);
        // `columns` lies within the output row (the callers pass 0..w of a row of w).
        let outputs = out_row.get_mut(x0..x1);
        debug_assert!(outputs.is_some(), "columns {x0}..{x1} of {}", out_row.len());
        let outputs = outputs.unwrap_or(&mut []);
        horizontal_filter(&column_sums[..count], outputs);
        x0 = x1;
    }
}
/// `sums[i] = [1 4 6 4 1] . rows[..][first + i]`, with mirrored columns outside the rows.
fn vertical_sums(rows: &[&[u8]; 5], first: isize, sums: &mut [u16]) {
    let width = rows[0].len() as isize;
    // Offsets into `sums` of the columns that lie inside the rows.
    let lo = (-first).clamp(0, sums.len() as isize) as usize;
    let hi = (width - first).clamp(lo as isize, sums.len() as isize) as usize;
    for i in (0..lo).chain(hi..sums.len()) {
        let x = reflect101(first + i as isize, width as usize);
        let px = |k: usize| u16::from(rows[k].get(x).copied().unwrap_or(0));
        if let Some(s) = sums.get_mut(i) {
            *s = px(0) + 4 * px(1) + 6 * px(2) + 4 * px(3) + px(4);
        }
    }
    // Interior: five equal-length runs, vectorised.
    let start = (first + lo as isize).max(0) as usize;
    // start + hi - lo = first + hi <= width by the clamp above, and the five source rows are
    // one width: every run is inside its row.
    let run = |k: usize| {
        let run = rows[k].get(start..start + hi - lo);
        debug_assert!(
            run.is_some(),
            "source row {k} shorter than {}",
            start + hi - lo
        );
        run.unwrap_or(&[])
    };
    let taps = run(0)
        .iter()
        .zip(run(1))
        .zip(run(2).iter().zip(run(3)).zip(run(4)));
    // lo <= hi <= sums.len() by the clamps above.
    let interior = sums.get_mut(lo..hi).unwrap_or(&mut []);
    for (s, ((&a, &b), ((&c, &d), &e))) in interior.iter_mut().zip(taps) {
        let [a, b, c, d, e] = [a, b, c, d, e].map(u16::from);
        *s = a + 4 * b + 6 * c + 4 * d + e;
    }
}

/// `out[x] = [1 4 6 4 1] . sums[2x..2x+5] / 256`, rounded.
///
/// Each output shares three sums with the next; they are carried, so each output reads two.
fn horizontal_filter(sums: &[u16], out: &mut [u8]) {
    // A strip sums at least 2 x 1 + 3 = 5 source columns.
    debug_assert!(sums.len() >= 3, "{} vertical sums", sums.len());
    let (Some(&[a, b, c]), Some(rest)) = (sums.get(..3), sums.get(3..)) else {
        return;
    };
    let (mut a, mut b, mut c) = (u32::from(a), u32::from(b), u32::from(c));
    for (o, pair) in out.iter_mut().zip(rest.chunks_exact(2)) {
        let &[d, e] = pair else {
            continue;
        };
        let (d, e) = (u32::from(d), u32::from(e));
        *o = ((a + 4 * (b + d) + 6 * c + e + 128) >> 8) as u8;
        (a, b, c) = (c, d, e);
    }
}
