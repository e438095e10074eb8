//! The window loops, one set for every target.
//!
//! Window buffers have a single padding column (`pitch == window + 1`, zero in the template),
//! just enough for the next frame's source block, gathered once as `i16` with the same pitch,
//! to line up with them: each bilinear neighbour's correlation with a template array is then
//! one flat dot product. The template patch has a one-pixel border and no padding and is
//! interpolated from a gathered copy of its pixels as `i16` too: one set of loops for windows
//! inside the frame and over its edge, and on the Cortex-M4 no slower than reading the frame's
//! bytes in place (the copy's loads need no widening).
//!
//! The innermost operations (dot products of `i16` runs, the template's sums, rows of bilinear
//! samples) are the kernels of [`crate::dsp::runs`], the only code that differs by target:
//! SMLAD, two multiply-accumulates an instruction, on the Cortex-M4; SSE2's PMADDWD, eight, on
//! x86-64; portable Rust elsewhere; the same values bit for bit on every target. The rest runs
//! row by row, each loop in a small function of its own: a Cortex-M4 has thirteen free
//! registers, and a loop inlined into a larger function or unrolled four-fold (as LLVM does to
//! short loops) spills the bilinear weights and accumulators. The tests hold every value to
//! the padded reference loops of `flat.rs` bit for bit: the same bilinear sums and rounding
//! ([`crate::dsp::runs::bilinear`]), the same Scharr sums ([`crate::dsp::runs::rescale`]) and exact window sums
//! and correlations.
//!
//! # Integer widths
//!
//! Template sums over at most [`super::MAX_WINDOW`] = 63 values are exact in 32 bits: a product of
//! two values is at most `8160^2 = 66_585_600`, 63 of them `4_194_892_800 < 2^32` for the
//! non-negative `I*I` (kept as `u32`), and `|I*Ix| <= 33_292_800`, 63 of them
//! `2_097_446_400 < 2^31`; chunks add into 64 bits. Correlations are narrower still (see
//! `correlation.rs`).

use super::correlation::Correlations;
use super::template::{Correction, TemplateSums};
use super::window::{
    gather, in_layout, in_layout_mut, mask_outside, scharr_smooth, Layout, Loops, TemplateBuffers,
    TemplateOut, WindowOrigin, INTENSITY_BITS, WEIGHT_BITS,
};
use crate::dsp::runs;
use crate::frame::ImageView;

/// The packed, row-by-row loops.
pub(crate) struct Rows;

impl Loops for Rows {
    fn layout(win: usize) -> Layout {
        Layout {
            win,
            pitch: win + 1,
            patch_pitch: win + 2,
            patch_len: (win + 2) * (win + 2),
            // The patch's source pixels when they must be gathered; the next window's, always,
            // need `(win + 1)^2` and a value of slack.
            // and a block of slack for the SSE2 template's loads.
            source_len: (win + 3) * (win + 3) + 8,
        }
    }

    fn template(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        (source, patch): (&mut [i16], &mut [i16]),
        out: TemplateOut<'_>,
    ) -> TemplateSums {
        let w = origin.w.map(i32::from);
        let TemplateOut { intensity, dx, dy } = out;
        let side = layout.win + 2;
        if origin.w == [1 << WEIGHT_BITS, 0, 0, 0] {
            // On a pixel: the samples are the pixels themselves.
            let out = (&mut *intensity, &mut *dx, &mut *dy);
            let (win, pitch, stride) = (layout.win, layout.pitch, frame.stride());
            match frame.block(origin.x, origin.y, side, side) {
                // The two windows the presets use (the flow sensor's 7, the tracker's 9) read
                // the pixels where they lie, in rows of a known length: unrolled, without
                // bounds checks or per-row set-up. Each costs about 900 bytes of flash.
                Some(px) if win == 7 => fixed_pixel_template::<7, 9>(px, stride, pitch, out),
                Some(px) if win == 9 => fixed_pixel_template::<9, 11>(px, stride, pitch, out),
                // Other windows, and windows over the frame's edge (rare), copy the pixels
                // first: one set of general rows serves them all.
                _ => {
                    gather(frame, origin, side, side, source);
                    // (win + 2)^2 <= source_len = (win + 3)^2.
                    let px = in_layout(source, 0..side * side);
                    any_pixel_template(px, side, layout, out);
                }
            }
        } else {
            // The patch's source pixels where they lie in the frame, or gathered.
            let n = side + 1;
            let block = frame.block(origin.x, origin.y, n, n);
            if block.is_none() {
                gather(frame, origin, n, n, source);
            }
            // n^2 + 8 = (win + 3)^2 + 8 = source_len.
            let px = in_layout_mut(source, 0..n * n + 8);
            let patch = in_layout_mut(patch, 0..side * side);
            let out = [&mut *intensity, &mut *dx, &mut *dy];
            let frame = block.map(|block| (block, frame.stride()));
            runs::sampled_template(&w, frame, px, patch, layout.pitch, out);
        }
        clear_template_padding(layout, [&mut *intensity, &mut *dx, &mut *dy]);
        if !origin.fits(frame, layout.win + 2, layout.win + 2) {
            mask_outside(frame, origin, layout, dx, dy);
        }
        template_sums(intensity, dx, dy)
    }

    fn correlate(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        source: &mut [i16],
        t: &TemplateBuffers<'_>,
    ) -> Correlations {
        let block = next_block(frame, origin, layout, source);
        correlate(block, layout, t)
    }

    fn sample_window(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        source: &mut [i16],
        j: &mut [i16],
    ) {
        let block = next_block(frame, origin, layout, source);
        let w = origin.w.map(i32::from);
        let rows = row_pairs(block, layout.pitch).zip(j.chunks_exact_mut(layout.pitch));
        for ((top, bottom), out) in rows {
            runs::bilinear_row(
                &w,
                top,
                bottom,
                // Rows of `pitch` = `win + 1` values.
                in_layout_mut(out, 0..layout.win),
            );
        }
        clear_padding(layout, j);
    }

    /// One pass over the block `correlate` gathered into `source` for this integer position
    /// ([`runs::abs_residual`]): nothing is gathered or stored.
    fn abs_residual(
        _frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        (source, _): (&mut [i16], &mut [i16]),
        intensity: &[i16],
        correction: Correction,
    ) -> u64 {
        let p = layout.pitch;
        // (win + 1)^2 + 1 <= source_len = (win + 3)^2.
        let block = in_layout(source, 0..(layout.win + 1) * p + 1);
        let Correction { gain, bias } = correction;
        runs::abs_residual(&origin.w, block, p, intensity, (gain, bias))
    }
}

/// Gathers the next window's `(win + 1)` square of source pixels into `source`, rows
/// `layout.pitch` apart, with a zero after it: the run of each bilinear neighbour then lines up
/// with the window buffers.
fn next_block<'s>(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    layout: &Layout,
    source: &'s mut [i16],
) -> &'s [i16] {
    let n = layout.win + 1;
    gather(frame, origin, n, n, source);
    if let Some(slack) = source.get_mut(n * n) {
        *slack = 0;
    }
    // (win + 1)^2 + 1 <= source_len = (win + 3)^2.
    in_layout(source, 0..n * n + 1)
}

/// Zeroes the padding column of the template's three window buffers, in one pass.
fn clear_template_padding(layout: &Layout, [i, x, y]: [&mut [i16]; 3]) {
    let mut k = layout.win;
    while let (Some(i), Some(x), Some(y)) = (i.get_mut(k), x.get_mut(k), y.get_mut(k)) {
        (*i, *x, *y) = (0, 0, 0);
        k += layout.pitch;
    }
}

/// Zeroes the padding column of a window buffer (by steps of a row, not `chunks`, whose
/// count is a division).
fn clear_padding(layout: &Layout, buf: &mut [i16]) {
    let mut k = layout.win;
    while let Some(pad) = buf.get_mut(k) {
        *pad = 0;
        k += layout.pitch;
    }
}

/// The row pairs of a source square: each row with the one below.
#[inline(always)]
fn row_pairs<P>(px: &[P], stride: usize) -> impl Iterator<Item = (&[P], &[P])> {
    // Every square the callers pass has at least two rows.
    let below = in_layout(px, stride..px.len());
    px.chunks(stride.max(1)).zip(below.chunks(stride.max(1)))
}

/// The correlations of the next window's gathered source block with the template
/// ([`runs::correlate`]).
fn correlate(block: &[i16], layout: &Layout, t: &TemplateBuffers<'_>) -> Correlations {
    Correlations {
        sums: runs::correlate(block, layout.pitch, [t.intensity, t.dx, t.dy]),
    }
}

/// The template of a window on whole pixels, from the `(win + 2)` square of pixels `px` (rows
/// `stride` apart) under its patch: intensities are the pixels (grey x 32) and the Scharr sums
/// of whole pixels are already at the gain of 32, equal to those of [`derivatives`] on the
/// samples (which are the pixels times 32) without their rounding.
fn any_pixel_template(
    px: &[i16],
    stride: usize,
    layout: &Layout,
    (intensity, dx, dy): (&mut [i16], &mut [i16], &mut [i16]),
) {
    let (win, p) = (layout.win, layout.pitch);
    let rows = px.chunks(stride.max(1));
    let below = rows.clone().skip(1).zip(rows.clone().skip(2));
    let outputs = intensity
        .chunks_exact_mut(p)
        .zip(dx.chunks_exact_mut(p).zip(dy.chunks_exact_mut(p)));
    for ((i_row, (dx_row, dy_row)), (up, (mid, down))) in outputs.zip(rows.zip(below)) {
        let (Some(i_row), Some(dx_row), Some(dy_row)) = (
            i_row.get_mut(..win),
            dx_row.get_mut(..win),
            dy_row.get_mut(..win),
        ) else {
            continue;
        };
        pixel_row(up, mid, down, i_row, dx_row, dy_row);
    }
}

/// The template's rows, as [`any_pixel_template`], for a `W` x `W` window (`S = W + 2` pixels per
/// patch row). Each row is unrolled; the rows are not, which keeps the code small.
#[inline(never)]
fn fixed_pixel_template<const W: usize, const S: usize>(
    px: &[u8],
    stride: usize,
    pitch: usize,
    (intensity, dx, dy): (&mut [i16], &mut [i16], &mut [i16]),
) {
    let row = |r: usize| -> Option<&[u8; S]> {
        let start = r * stride;
        px.get(start..start + S)?.try_into().ok()
    };
    fn out<const W: usize>(buf: &mut [i16], start: usize) -> Option<&mut [i16; W]> {
        buf.get_mut(start..start + W)?.try_into().ok()
    }
    for r in 0..W {
        // `px` is the frame block of the `S`-square patch and the outputs are window buffers
        // of `W` rows `pitch` >= `W` apart: every row below is there.
        let (Some(up), Some(mid), Some(down)) = (row(r), row(r + 1), row(r + 2)) else {
            debug_assert!(px.is_empty(), "patch row {r} outside its block");
            return;
        };
        let (Some(i_row), Some(dx_row), Some(dy_row)) = (
            out::<W>(intensity, r * pitch),
            out::<W>(dx, r * pitch),
            out::<W>(dy, r * pitch),
        ) else {
            debug_assert!(intensity.is_empty(), "window row {r} outside its buffer");
            return;
        };
        let column = |k: usize| {
            let [u, m, d]: [i32; 3] = [up[k].into(), mid[k].into(), down[k].into()];
            (scharr_smooth(u, m, d), d - u)
        };
        let ((mut v0, mut h0), (mut v1, mut h1)) = (column(0), column(1));
        for k in 0..W {
            let (v2, h2) = column(k + 2);
            let m: i32 = mid[k + 1].into();
            i_row[k] = (m << INTENSITY_BITS) as i16;
            dx_row[k] = (v2 - v0) as i16;
            dy_row[k] = scharr_smooth(h0, h1, h2) as i16;
            (v0, h0, v1, h1) = (v1, h1, v2, h2);
        }
    }
}

/// One template row on whole pixels: intensities and Scharr derivatives, as [`crate::dsp::runs::scharr_row`].
#[inline(never)]
fn pixel_row(
    up: &[i16],
    mid: &[i16],
    down: &[i16],
    intensity: &mut [i16],
    dx: &mut [i16],
    dy: &mut [i16],
) {
    let mut columns = up.iter().zip(mid).zip(down).map(|((&u, &m), &d)| {
        let [u, m, d]: [i32; 3] = [u.into(), m.into(), d.into()];
        (scharr_smooth(u, m, d), d - u, m)
    });
    let (Some((mut v0, mut h0, _)), Some((mut v1, mut h1, mut m1))) =
        (columns.next(), columns.next())
    else {
        // Patch rows hold `win + 2` >= 3 pixels.
        debug_assert!(intensity.is_empty(), "pixel rows under two values");
        return;
    };
    let outputs = intensity.iter_mut().zip(dx.iter_mut().zip(dy.iter_mut()));
    for ((i, (gx, gy)), (v2, h2, m2)) in outputs.zip(columns) {
        *i = (m1 << INTENSITY_BITS) as i16;
        *gx = (v2 - v0) as i16;
        *gy = scharr_smooth(h0, h1, h2) as i16;
        (v0, h0, v1, h1, m1) = (v1, h1, v2, h2, m2);
    }
}

/// The template's window sums ([`runs::template_sums`]).
fn template_sums(intensity: &[i16], dx: &[i16], dy: &[i16]) -> TemplateSums {
    let [gxx, gxy, gyy, sx, sy, si, sii, six, siy] = runs::template_sums(intensity, dx, dy);
    TemplateSums {
        gxx,
        gxy,
        gyy,
        si,
        sii,
        sx,
        sy,
        six,
        siy,
    }
}
