//! The tests' reference window loops: padded, flat loops shaped for LLVM's auto-vectoriser,
//! which x86-64 and AArch64 ran before the row loops ([`super::rows`], every target's now) had
//! SSE2 kernels. Written independently of the row loops, they hold them to the same values bit
//! for bit in the tests of `lk`, `window` and here.
//!
//! Every window buffer is row-major with a pitch of `window + 3`: the columns past the window
//! are padding, kept at zero where they would enter a sum. Sampling, derivatives and window sums
//! are then single flat loops over `rows * pitch` values, which vectorise without a scalar tail
//! per row (a 21-px row would leave one of 5 px). Source pixels are first gathered into an `i16`
//! block so that the interpolation, and each bilinear neighbour's correlation with the
//! template, is one flat loop over equal-length shifted runs.
//!
//! # Integer widths
//!
//! Intensities are grey x 32 (`<= 8160`), gradients `|Ix| <= 4080`. A product of two is at most
//! `8160^2 = 66_585_600`, so [`CHUNK`] = 64 consecutive products sum to at most `4_261_478_400`:
//! below `u32::MAX` for `I*I` (non-negative) and, for the signed products
//! (`|I*Ix| <= 33_292_800`, 64 of them `<= 2_130_739_200`), below `i32::MAX`. Chunk sums are
//! exact in 32 bits (and vectorise), windows add chunks in 64 bits (`<= 2.7e11` at 63 x 63).

use super::correlation::Correlations;
use super::template::TemplateSums;
use super::window::{
    gather, in_layout, mask_outside, scharr_smooth, Layout, Loops, TemplateBuffers, TemplateOut,
    WindowOrigin,
};
use crate::dsp::runs::{bilinear, rescale};
use crate::frame::ImageView;

/// Template products summed in 32 bits before widening: the most that provably cannot overflow.
const CHUNK: usize = 64;

/// The padded, flat loops.
pub(crate) struct Flat;

impl Loops for Flat {
    fn layout(win: usize) -> Layout {
        // The window, its two derivative border columns and the bilinear neighbour of the last.
        let pitch = win + 3;
        Layout {
            win,
            pitch,
            patch_pitch: pitch,
            // Two values of slack for the flat Scharr loop's last reads.
            patch_len: (win + 2) * pitch + 2,
            // The patch's source pixels: one more row, one value of slack.
            source_len: (win + 3) * pitch + 1,
        }
    }

    fn template(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        (source, patch): (&mut [i16], &mut [i16]),
        out: TemplateOut<'_>,
    ) -> TemplateSums {
        let side = layout.win + 2;
        sample(frame, origin, side, layout.pitch, source, patch);
        scharr(patch, layout, out.dx, out.dy);
        if !origin.fits(frame, side, side) {
            mask_outside(frame, origin, layout, out.dx, out.dy);
        }
        inner(patch, layout, out.intensity);
        template_sums(out.intensity, out.dx, out.dy)
    }

    fn correlate(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        source: &mut [i16],
        t: &TemplateBuffers<'_>,
    ) -> Correlations {
        let (win, p) = (layout.win, layout.pitch);
        gather(frame, origin, win + 1, p, source);
        if let Some(slack) = source.get_mut((win + 1) * p) {
            *slack = 0;
        }
        // Each neighbour's pixels under the window are one run of the gathered rows; the
        // template's zero padding drops the columns past the window from the products.
        let mut c = Correlations::default();
        for (sums, offset) in c.sums.iter_mut().zip([0, 1, p, p + 1]) {
            // offset + win p <= (win + 1) p + 1 <= source_len.
            let run = in_layout(source, offset..offset + win * p);
            let plain = layout.rows(run).flatten().map(|&v| i64::from(v)).sum();
            let [si, sx, sy] = correlate_run(run, t);
            *sums = [plain, si, sx, sy];
        }
        c
    }

    fn sample_window(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        source: &mut [i16],
        j: &mut [i16],
    ) {
        sample(frame, origin, layout.win, layout.pitch, source, j);
        clear_padding(layout, j);
    }
}

/// Pixel-template products summed in 32 bits before widening: `1024 * 2_080_800 < 2^31`
/// (widths in `correlation.rs`).
const CORRELATION_CHUNK: usize = 1024;

/// `[ΣP·I, ΣP·Ix, ΣP·Iy]` of a run of source pixels against the template.
fn correlate_run(run: &[i16], t: &TemplateBuffers<'_>) -> [i64; 3] {
    let mut sums = [0i64; 3];
    let chunks = run
        .chunks(CORRELATION_CHUNK)
        .zip(t.intensity.chunks(CORRELATION_CHUNK))
        .zip(
            t.dx.chunks(CORRELATION_CHUNK)
                .zip(t.dy.chunks(CORRELATION_CHUNK)),
        );
    for ((p, i), (gx, gy)) in chunks {
        let (mut si, mut sx, mut sy) = (0i32, 0i32, 0i32);
        for ((&p, &i), (&gx, &gy)) in p.iter().zip(i).zip(gx.iter().zip(gy)) {
            let p = i32::from(p);
            si += p * i32::from(i);
            sx += p * i32::from(gx);
            sy += p * i32::from(gy);
        }
        for (sum, chunk) in sums.iter_mut().zip([si, sx, sy]) {
            *sum += i64::from(chunk);
        }
    }
    sums
}

/// Zeroes the padding columns of a window buffer so they add nothing to window sums.
fn clear_padding(layout: &Layout, buf: &mut [i16]) {
    for row in buf.chunks_exact_mut(layout.pitch) {
        row.iter_mut().skip(layout.win).for_each(|v| *v = 0);
    }
}

/// Samples `rows` rows of `pitch` values of `frame` at `origin` into `out` (grey x 32).
///
/// `source` receives the `(rows + 1) x pitch` pixels under the window first (edge pixels repeat
/// outside the frame), so the interpolation is one flat loop. Only the first `pitch - 1` values of
/// each output row are meaningful; callers clear or ignore the rest.
fn sample(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    rows: usize,
    pitch: usize,
    source: &mut [i16],
    out: &mut [i16],
) {
    gather(frame, origin, rows + 1, pitch, source);
    if let Some(slack) = source.get_mut((rows + 1) * pitch) {
        *slack = 0;
    }
    let n = rows * pitch;
    let w = origin.w.map(i32::from);
    // k + n <= (rows + 1) pitch + 1, the gathered rows and their slack, within source_len.
    let run = |k: usize| in_layout(source, k..k + n);
    // Four equal-length shifted runs (pixel, right, below, below-right) vectorise cleanly.
    let quads = run(0)
        .iter()
        .zip(run(1))
        .zip(run(pitch).iter().zip(run(pitch + 1)));
    for (o, ((&a, &b), (&c, &d))) in out.iter_mut().take(n).zip(quads) {
        *o = bilinear(w, a.into(), b.into(), c.into(), d.into());
    }
}

/// Copies the template (the patch without its one-pixel border) into `out`, padding cleared.
fn inner(patch: &[i16], layout: &Layout, out: &mut [i16]) {
    let n = layout.window_len();
    if let Some(src) = patch.get(layout.pitch + 1..layout.pitch + 1 + n) {
        out.iter_mut().zip(src).for_each(|(d, &s)| *d = s);
    }
    clear_padding(layout, out);
}

/// Scharr derivatives of the template inside its patch, padding cleared.
fn scharr(patch: &[i16], layout: &Layout, dx: &mut [i16], dy: &mut [i16]) {
    let (n, p) = (layout.window_len(), layout.pitch);
    // Output k is the template pixel whose patch neighbourhood starts at patch[k].
    // k + n <= 2 p + 2 + win p = patch_len.
    let run = |k: usize| in_layout(patch, k..k + n);
    let w = |v: &i16| i32::from(*v);
    let (ul, uc, ur) = (run(0), run(1), run(2));
    let (ml, mr) = (run(p), run(p + 2));
    let (dl, dc, dr) = (run(2 * p), run(2 * p + 1), run(2 * p + 2));
    let horizontal = ul
        .iter()
        .zip(ur)
        .zip(ml.iter().zip(mr))
        .zip(dl.iter().zip(dr));
    for (gx, (((a, b), (c, d)), (e, f))) in dx.iter_mut().zip(horizontal) {
        *gx = rescale(scharr_smooth(w(b) - w(a), w(d) - w(c), w(f) - w(e)));
    }
    let vertical = ul
        .iter()
        .zip(dl)
        .zip(uc.iter().zip(dc))
        .zip(ur.iter().zip(dr));
    for (gy, (((a, b), (c, d)), (e, f))) in dy.iter_mut().zip(vertical) {
        *gy = rescale(scharr_smooth(w(b) - w(a), w(d) - w(c), w(f) - w(e)));
    }
    clear_padding(layout, dx);
    clear_padding(layout, dy);
}

/// The template's window sums, in 32-bit chunks widened to 64 bits.
fn template_sums(intensity: &[i16], dx: &[i16], dy: &[i16]) -> TemplateSums {
    TemplateSums::in_chunks::<CHUNK>(intensity, dx, dy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every sum over a 63 x 63 window (the largest accepted) at the extreme values of pixels,
    /// samples and the Scharr filter, checked against 128-bit arithmetic.
    #[test]
    fn window_sums_are_exact_at_the_extremes() {
        const SIDE: usize = super::super::MAX_WINDOW;
        // A window buffer without padding: every value counts.
        let intensity = [8160i16; SIDE * SIDE];
        for (gx_sign, gy_sign) in [(1i16, 1i16), (1, -1), (-1, -1)] {
            let dx = [4080 * gx_sign; SIDE * SIDE];
            let dy = [4080 * gy_sign; SIDE * SIDE];
            let s = template_sums(&intensity, &dx, &dy);
            let n = (SIDE * SIDE) as i128;
            let (gx, gy) = (4080 * gx_sign as i128, 4080 * gy_sign as i128);
            assert_eq!(s.gxx as i128, n * gx * gx);
            assert_eq!(s.gxy as i128, n * gx * gy);
            assert_eq!(s.sii as i128, n * 8160 * 8160);
            assert_eq!(s.six as i128, n * 8160 * gx);
            assert_eq!(s.siy as i128, n * 8160 * gy);
            let t = TemplateBuffers {
                intensity: &intensity,
                dx: &dx,
                dy: &dy,
            };
            let p = [255i16; SIDE * SIDE];
            let [si, sx, sy] = correlate_run(&p, &t);
            assert_eq!(si as i128, n * 255 * 8160);
            assert_eq!(sx as i128, n * 255 * gx);
            assert_eq!(sy as i128, n * 255 * gy);
        }
    }
}
