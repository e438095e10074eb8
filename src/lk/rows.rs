//! Window loops for scalar cores (the Cortex-M4 of flight controllers).
//!
//! A core without SIMD gains nothing from [`super::flat`]'s padded rows and flat loops and pays
//! for every padding value, the gathered copy of the source pixels and the clears. Here window
//! buffers are packed (`pitch == window`), the patch has a one-pixel border and no padding,
//! samples are interpolated straight from the frame's rows (source rows are copied only where
//! the window crosses the frame's left or right edge), and each loop runs over one row.
//!
//! LLVM unrolls short loops four-fold on the Cortex-M4; where that runs out of registers (a
//! loop with many live values inside a larger function) the loop is a function of its own or
//! ends on two conditions, which keeps it rolled. Every value equals the flat loops' bit for bit:
//! the same bilinear sums and rounding ([`bilinear`]) and the same Scharr sums ([`rescale`]).

use super::flat;
use super::template::{MatchSums, TemplateSums};
use super::window::{bilinear, rescale, Layout, Loops, TemplateBuffers, WindowOrigin};
use super::MAX_WINDOW;
use crate::frame::ImageView;

/// The packed, row-by-row loops.
pub(crate) struct Rows;

impl Loops for Rows {
    fn layout(win: usize) -> Layout {
        Layout {
            win,
            pitch: win,
            patch_pitch: win + 2,
            patch_len: (win + 2) * (win + 2),
            source_len: 0,
        }
    }

    fn sample_patch(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        _source: &mut [i16],
        patch: &mut [i16],
    ) {
        sample(frame, origin, layout.win + 2, patch);
    }

    fn sample_window(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        _source: &mut [i16],
        out: &mut [i16],
    ) {
        sample(frame, origin, layout.win, out);
    }

    fn derivatives(
        patch: &[i16],
        layout: &Layout,
        intensity: &mut [i16],
        dx: &mut [i16],
        dy: &mut [i16],
    ) {
        let (win, pp) = (layout.win, layout.patch_pitch);
        let outputs = intensity
            .chunks_exact_mut(win)
            .zip(dx.chunks_exact_mut(win).zip(dy.chunks_exact_mut(win)));
        let patch_rows = patch.chunks_exact(pp);
        let below = patch_rows.clone().skip(1).zip(patch_rows.clone().skip(2));
        for ((i_row, (dx_row, dy_row)), (up, (mid, down))) in outputs.zip(patch_rows.zip(below)) {
            scharr_row(up, mid, down, i_row, dx_row, dy_row);
        }
    }

    fn template_sums(t: &TemplateBuffers<'_>) -> TemplateSums {
        flat::template_sums(t.intensity, t.dx, t.dy)
    }

    fn match_sums(j: &[i16], t: &TemplateBuffers<'_>, gain_bias: bool) -> MatchSums {
        if gain_bias {
            match_sums::<true>(j, t)
        } else {
            match_sums::<false>(j, t)
        }
    }
}

/// Samples the `side` x `side` square at `origin` into `out` (packed rows, grey x 32).
fn sample(frame: &ImageView<'_>, origin: &WindowOrigin, side: usize, out: &mut [i16]) {
    let w = origin.w.map(i32::from);
    let mut out_rows = out.chunks_exact_mut(side);
    source_rows(frame, origin, side, |top, bottom| {
        if let Some(row) = out_rows.next() {
            interpolate_row(w, top, bottom, row);
        }
    });
}

/// Calls `f(top, bottom)` for each of `side` output rows with the `side + 1` source pixels of
/// the row and of the one below; outside the frame the nearest edge pixel repeats.
#[inline(always)]
fn source_rows(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    side: usize,
    mut f: impl FnMut(&[u8], &[u8]),
) {
    let n = side + 1;
    if let Some(mut rows) = frame.block(origin.x, origin.y, n, n) {
        // The whole block lies in the frame: slices of its rows.
        let Some(mut top) = rows.next() else {
            return;
        };
        for bottom in rows {
            f(top, bottom);
            top = bottom;
        }
        return;
    }
    // Rows above or below the frame repeat its first or last row.
    let last_row = frame.height() as isize - 1;
    let row_at = |r: usize| frame.row((origin.y + r as isize).clamp(0, last_row) as usize);
    if origin.x >= 0 && origin.x as usize + n <= frame.width() {
        // Columns inside the frame: slices of its rows.
        let x = origin.x as usize;
        let span = |r: usize| row_at(r).get(x..x + n).unwrap_or(&[]);
        let mut top = span(0);
        for r in 1..=side {
            let bottom = span(r);
            f(top, bottom);
            top = bottom;
        }
        return;
    }
    // Columns beyond the left or right edge: copies of the rows with the edge pixel repeated.
    let mut buffers = [[0u8; MAX_WINDOW + 3]; 2];
    let [top, bottom] = &mut buffers;
    let (mut top, mut bottom) = (&mut top[..n], &mut bottom[..n]);
    clamped_row(row_at(0), origin.x, top);
    for r in 1..=side {
        clamped_row(row_at(r), origin.x, bottom);
        f(top, bottom);
        core::mem::swap(&mut top, &mut bottom);
    }
}

/// Copies `out.len()` pixels of `row` from column `x` on, repeating the edge pixels outside.
fn clamped_row(row: &[u8], x: isize, out: &mut [u8]) {
    let (Some(&first), Some(&last)) = (row.first(), row.last()) else {
        return;
    };
    // `out[start..end]` lies in the frame.
    let len = out.len() as isize;
    let start = (-x).clamp(0, len) as usize;
    let end = (row.len() as isize - x).clamp(start as isize, len) as usize;
    let (left, rest) = out.split_at_mut(start);
    let (inside, right) = rest.split_at_mut(end - start);
    left.iter_mut().for_each(|o| *o = first);
    let from = (x + start as isize) as usize;
    for (o, &p) in inside.iter_mut().zip(row.get(from..).unwrap_or(&[])) {
        *o = p;
    }
    right.iter_mut().for_each(|o| *o = last);
}

/// One row of bilinear samples from `out.len() + 1` pixels of two source rows.
///
/// Each pixel's right neighbour is the next sample's left one and stays in a register. The loop
/// stops at the end of whichever row is shortest; with that second exit LLVM keeps it rolled,
/// which on a Cortex-M4 is shorter than its four-fold unrolling (that spills the weights).
#[inline(always)]
fn interpolate_row(w: [i32; 4], top: &[u8], bottom: &[u8], out: &mut [i16]) {
    let (Some((&a, top)), Some((&c, bottom))) = (top.split_first(), bottom.split_first()) else {
        return;
    };
    let (mut a, mut c) = (i32::from(a), i32::from(c));
    for (k, o) in out.iter_mut().enumerate() {
        let (Some(&b), Some(&d)) = (top.get(k), bottom.get(k)) else {
            break;
        };
        let (b, d) = (i32::from(b), i32::from(d));
        *o = bilinear(w, a, b, c, d);
        (a, c) = (b, d);
    }
}

/// One template row: its intensities (the middle patch row without its border) and Scharr
/// derivatives, from three patch rows of `win + 2` values.
///
/// Each output reads its 3 x 3 neighbourhood afresh: carrying column sums from one output to
/// the next would save loads but keeps more values live than a Cortex-M4 has registers. Not
/// inlined, so that the row loop has every register.
#[inline(never)]
fn scharr_row(
    up: &[i16],
    mid: &[i16],
    down: &[i16],
    intensity: &mut [i16],
    dx: &mut [i16],
    dy: &mut [i16],
) {
    let neighbourhoods = up.windows(3).zip(mid.windows(3)).zip(down.windows(3));
    let outputs = intensity.iter_mut().zip(dx.iter_mut().zip(dy.iter_mut()));
    for ((i, (gx, gy)), ((u, m), d)) in outputs.zip(neighbourhoods) {
        let (&[ul, uc, ur], &[ml, mc, mr], &[dl, dc, dr]) = (u, m, d) else {
            continue;
        };
        let [ul, uc, ur, ml, mr, dl, dc, dr] = [ul, uc, ur, ml, mr, dl, dc, dr].map(i32::from);
        *gx = rescale(3 * ((ur - ul) + (dr - dl)) + 10 * (mr - ml));
        *gy = rescale(3 * ((dl - ul) + (dr - ur)) + 10 * (dc - uc));
        *i = mc;
    }
}

/// The match sums in one pass over the window (`ΣJ` and `ΣJI` only with `GAIN_BIAS`), in chunks
/// of [`flat::CHUNK`] values summed exactly in 32 bits (the widths of `flat.rs`).
fn match_sums<const GAIN_BIAS: bool>(j: &[i16], t: &TemplateBuffers<'_>) -> MatchSums {
    let mut m = MatchSums::default();
    let chunks = j
        .chunks(flat::CHUNK)
        .zip(t.intensity.chunks(flat::CHUNK))
        .zip(t.dx.chunks(flat::CHUNK).zip(t.dy.chunks(flat::CHUNK)));
    for ((j, i), (gx, gy)) in chunks {
        let (mut sj, mut sji, mut sjx, mut sjy) = (0i32, 0u32, 0i32, 0i32);
        for ((&j, &i), (&gx, &gy)) in j.iter().zip(i).zip(gx.iter().zip(gy)) {
            let j = i32::from(j);
            sjx += j * i32::from(gx);
            sjy += j * i32::from(gy);
            if GAIN_BIAS {
                sj += j;
                sji = sji.wrapping_add((j * i32::from(i)) as u32);
            }
        }
        m.sj += i64::from(sj);
        m.sji += i64::from(sji);
        m.sjx += i64::from(sjx);
        m.sjy += i64::from(sjy);
    }
    m
}
