//! Window loops for scalar cores (the Cortex-M4 of flight controllers).
//!
//! A core without SIMD gains nothing from [`super::flat`]'s padded rows and flat loops and pays
//! for every padding value, the gathered copy of the source pixels and the clears. Here window
//! buffers are packed (`pitch == window`), the patch has a one-pixel border and no padding, and
//! samples are interpolated straight from the frame's rows; only a window whose source pixels
//! cross the frame's edge is gathered first (a [`Source`] of either kind).
//!
//! The loops run row by row, each in a small function of its own: a Cortex-M4 has thirteen
//! free registers, and a loop inlined into a larger function or unrolled four-fold (as LLVM does
//! to short loops) spills the bilinear weights and accumulators. The loops over pixel pairs end
//! on two conditions, which keeps LLVM from unrolling them. Every value equals the flat loops'
//! bit for bit: the same bilinear sums and rounding ([`bilinear`]), the same Scharr sums
//! ([`rescale`]) and exact window sums and correlations.
//!
//! # Integer widths
//!
//! Template sums over at most [`MAX_WINDOW`] = 63 values are exact in 32 bits: a product of
//! two values is at most `8160^2 = 66_585_600`, 63 of them `4_194_892_800 < 2^32` for the
//! non-negative `I*I` (kept as `u32`), and `|I*Ix| <= 33_292_800`, 63 of them
//! `2_097_446_400 < 2^31`; chunks add into 64 bits. Correlations are narrower still (see
//! `correlation.rs`).

use super::correlation::Correlations;
use super::template::TemplateSums;
use super::window::{
    bilinear, gather, mask_outside, rescale, Layout, Loops, TemplateBuffers, TemplateOut,
    WindowOrigin,
};
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
            // The patch's source pixels when they must be gathered.
            source_len: (win + 3) * (win + 3),
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
        match Source::of(frame, origin, layout.win + 2, source) {
            Source::Frame(px, s) => sample_patch(&w, px, s, layout, patch, intensity),
            Source::Gathered(px, s) => sample_patch(&w, px, s, layout, patch, intensity),
        }
        derivatives(patch, layout, dx, dy);
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
        match Source::of(frame, origin, layout.win, source) {
            Source::Frame(px, stride) => correlate(px, stride, layout.win, t),
            Source::Gathered(px, stride) => correlate(px, stride, layout.win, t),
        }
    }

    fn sample_window(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        source: &mut [i16],
        j: &mut [i16],
    ) {
        let w = origin.w.map(i32::from);
        match Source::of(frame, origin, layout.win, source) {
            Source::Frame(px, stride) => sample(&w, px, stride, layout.win, j),
            Source::Gathered(px, stride) => sample(&w, px, stride, layout.win, j),
        }
    }
}

/// The source pixels under a `side` x `side` window and their bilinear neighbours: a
/// `(side + 1)` square, from its top-left pixel on, rows `stride` apart.
enum Source<'a> {
    /// The frame's own pixels: the square lies in the frame.
    Frame(&'a [u8], usize),
    /// A copy with the frame's edge pixels repeated outside it.
    Gathered(&'a [i16], usize),
}

impl<'a> Source<'a> {
    fn of(
        frame: &ImageView<'a>,
        origin: &WindowOrigin,
        side: usize,
        scratch: &'a mut [i16],
    ) -> Self {
        let n = side + 1;
        if let Some(px) = frame.block(origin.x, origin.y, n, n) {
            return Source::Frame(px, frame.stride());
        }
        gather(frame, origin, n, n, scratch);
        Source::Gathered(scratch.get(..n * n).unwrap_or(&[]), n)
    }
}

/// The row pairs of a source square: each row with the one below.
#[inline(always)]
fn row_pairs<P>(px: &[P], stride: usize) -> impl Iterator<Item = (&[P], &[P])> {
    let below = px.get(stride..).unwrap_or(&[]);
    px.chunks(stride.max(1)).zip(below.chunks(stride.max(1)))
}

/// A pixel of a [`Source`].
trait Pixel: Copy + Into<i32> {}
impl Pixel for u8 {}
impl Pixel for i16 {}

/// Row `r` of a buffer of `pitch`-value rows, `len` values long (empty past the end).
#[inline(always)]
fn row<T>(buf: &[T], r: usize, pitch: usize, len: usize) -> &[T] {
    buf.get(r * pitch..r * pitch + len).unwrap_or(&[])
}

/// [`row`] for writing.
#[inline(always)]
fn row_mut<T>(buf: &mut [T], r: usize, pitch: usize, len: usize) -> &mut [T] {
    buf.get_mut(r * pitch..r * pitch + len).unwrap_or(&mut [])
}

/// Samples the template patch into `patch`, and its interior, the template's intensities, into
/// `intensity` as well: storing each interior sample twice costs less than copying afterwards.
#[inline(always)]
fn sample_patch<P: Pixel>(
    w: &[i32; 4],
    px: &[P],
    stride: usize,
    layout: &Layout,
    patch: &mut [i16],
    intensity: &mut [i16],
) {
    let (win, pp) = (layout.win, layout.patch_pitch);
    let rows = row_pairs(px, stride).zip(patch.chunks_exact_mut(pp));
    let mut inner = intensity.chunks_exact_mut(win);
    for (r, ((top, bottom), out)) in rows.enumerate() {
        match if r == 0 { None } else { inner.next() } {
            Some(inner) => interpolate_twice(w, top, bottom, out, inner),
            None => interpolate(w, top, bottom, out),
        }
    }
}

/// Samples the `side` x `side` window into `out`, row by row.
#[inline(always)]
fn sample<P: Pixel>(w: &[i32; 4], px: &[P], stride: usize, side: usize, out: &mut [i16]) {
    for ((top, bottom), out) in row_pairs(px, stride).zip(out.chunks_exact_mut(side)) {
        interpolate(w, top, bottom, out);
    }
}

/// One row of bilinear samples from `out.len() + 1` pixels of two source rows.
///
/// Each pixel's right neighbour is the next sample's left one and stays in a register. The loop
/// stops at the end of `out` or of the shorter source row: with two exits LLVM keeps it rolled.
/// Not inlined, so that the weights stay in registers.
#[inline(never)]
fn interpolate<P: Pixel>(w: &[i32; 4], top: &[P], bottom: &[P], out: &mut [i16]) {
    let w = *w;
    let (Some((&a, top)), Some((&c, bottom))) = (top.split_first(), bottom.split_first()) else {
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

/// [`interpolate`] for a patch row, storing the samples but the first and the last in `inner`
/// as well.
#[inline(never)]
fn interpolate_twice<P: Pixel>(
    w: &[i32; 4],
    top: &[P],
    bottom: &[P],
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

/// The correlations of a source square with the template: one template array at a time, and
/// the pixel sums.
fn correlate<P: Pixel>(
    px: &[P],
    stride: usize,
    win: usize,
    t: &TemplateBuffers<'_>,
) -> Correlations {
    let [own, right, below, below_right] = pixel_sums(px, stride, win);
    let [i, x, y] = [t.intensity, t.dx, t.dy].map(|t| correlate_template(px, stride, t, win));
    Correlations {
        sums: [
            [own, i[0], x[0], y[0]],
            [right, i[1], x[1], y[1]],
            [below, i[2], x[2], y[2]],
            [below_right, i[3], x[3], y[3]],
        ],
    }
}

/// `ΣP` of each neighbour: source rows `0..win` hold the samples' own pixels and right
/// neighbours (columns `0..win` and `1..=win`), rows `1..=win` their lower ones. At most
/// `64^2 * 255 < 2^31`.
#[inline(never)]
fn pixel_sums<P: Pixel>(px: &[P], stride: usize, win: usize) -> [i64; 4] {
    let mut sums = [0i32; 4];
    for (s, row) in px.chunks(stride.max(1)).take(win + 1).enumerate() {
        let total: i32 = row.iter().take(win + 1).map(|&v| v.into()).sum();
        let first = row.first().map_or(0, |&v| v.into());
        let last = row.get(win).map_or(0, |&v| v.into());
        let (left, right) = (total - last, total - first);
        if s < win {
            sums[0] += left;
            sums[1] += right;
        }
        if s > 0 {
            sums[2] += left;
            sums[3] += right;
        }
    }
    sums.map(i64::from)
}

/// Pixel-template products summed in 32 bits before widening: `1024 * 2_080_800 < 2^31`
/// (widths in `correlation.rs`).
const CORRELATION_CHUNK: usize = 1024;

/// `[ΣP·T, ΣP_right·T, ΣP_below·T, ΣP_below_right·T]` for one template array `T`, template row
/// by template row, in 32 bits over as many rows as [`CORRELATION_CHUNK`] allows.
#[inline(never)]
fn correlate_template<P: Pixel>(px: &[P], stride: usize, t: &[i16], win: usize) -> [i64; 4] {
    let mut total = [0i64; 4];
    let rows = row_pairs(px, stride).zip(t.chunks_exact(win.max(1)));
    let chunk_rows = (CORRELATION_CHUNK / win.max(1)).max(1);
    let (mut sums, mut left) = ([0i32; 4], chunk_rows);
    for ((top, bottom), t) in rows {
        for (sum, row) in sums.iter_mut().zip(correlate_row(top, bottom, t)) {
            *sum += row;
        }
        left -= 1;
        if left == 0 {
            for (total, sum) in total.iter_mut().zip(&mut sums) {
                *total += i64::from(core::mem::take(sum));
            }
            left = chunk_rows;
        }
    }
    for (total, sum) in total.iter_mut().zip(sums) {
        *total += i64::from(sum);
    }
    total
}

/// The four neighbours' sums of one template row `t` against source rows `top` and `bottom`.
///
/// Each pixel's right neighbour is the next column's pixel and stays in a register; as in
/// [`interpolate`], the loop ends on two conditions, which keeps it rolled.
#[inline(always)]
fn correlate_row<P: Pixel>(top: &[P], bottom: &[P], t: &[i16]) -> [i32; 4] {
    let (Some((&a, top)), Some((&c, bottom))) = (top.split_first(), bottom.split_first()) else {
        return [0; 4];
    };
    let (mut a, mut c): (i32, i32) = (a.into(), c.into());
    let mut sums = [0i32; 4];
    for (k, &t) in t.iter().enumerate() {
        let (Some(&b), Some(&d)) = (top.get(k), bottom.get(k)) else {
            break;
        };
        let (b, d, t): (i32, i32, i32) = (b.into(), d.into(), t.into());
        sums[0] += a * t;
        sums[1] += b * t;
        sums[2] += c * t;
        sums[3] += d * t;
        (a, c) = (b, d);
    }
    sums
}

/// The Scharr derivatives of the template inside its patch.
fn derivatives(patch: &[i16], layout: &Layout, dx: &mut [i16], dy: &mut [i16]) {
    let (win, pp) = (layout.win, layout.patch_pitch);
    for r in 0..win {
        let [up, mid, down] = [r, r + 1, r + 2].map(|k| row(patch, k, pp, pp));
        scharr_row(
            up,
            mid,
            down,
            row_mut(dx, r, win, win),
            row_mut(dy, r, win, win),
        );
    }
}

/// One template row's Scharr derivatives from three patch rows of `win + 2` values.
///
/// Each output reads its 3 x 3 neighbourhood afresh: carrying column sums from one output to
/// the next would save loads but keeps more values live than a Cortex-M4 has registers.
#[inline(never)]
fn scharr_row(up: &[i16], mid: &[i16], down: &[i16], dx: &mut [i16], dy: &mut [i16]) {
    let neighbourhoods = up.windows(3).zip(mid.windows(3)).zip(down.windows(3));
    for ((gx, gy), ((u, m), d)) in dx.iter_mut().zip(dy.iter_mut()).zip(neighbourhoods) {
        let (&[ul, uc, ur], &[ml, _, mr], &[dl, dc, dr]) = (u, m, d) else {
            continue;
        };
        let [ul, uc, ur, ml, mr, dl, dc, dr] = [ul, uc, ur, ml, mr, dl, dc, dr].map(i32::from);
        *gx = rescale(3 * ((ur - ul) + (dr - dl)) + 10 * (mr - ml));
        *gy = rescale(3 * ((dl - ul) + (dr - ur)) + 10 * (dc - uc));
    }
}

/// The template's window sums, in two passes of few accumulators each.
#[inline(never)]
fn template_sums(intensity: &[i16], dx: &[i16], dy: &[i16]) -> TemplateSums {
    let mut s = TemplateSums::default();
    for (gx, gy) in dx.chunks(MAX_ROW).zip(dy.chunks(MAX_ROW)) {
        let (mut gxx, mut gxy, mut gyy, mut sx, mut sy) = (0i32, 0i32, 0i32, 0i32, 0i32);
        for (&gx, &gy) in gx.iter().zip(gy) {
            let (gx, gy) = (i32::from(gx), i32::from(gy));
            gxx += gx * gx;
            gxy += gx * gy;
            gyy += gy * gy;
            sx += gx;
            sy += gy;
        }
        s.gxx += i64::from(gxx);
        s.gxy += i64::from(gxy);
        s.gyy += i64::from(gyy);
        s.sx += i64::from(sx);
        s.sy += i64::from(sy);
    }
    let chunks = intensity.chunks(MAX_ROW);
    for (i, (gx, gy)) in chunks.zip(dx.chunks(MAX_ROW).zip(dy.chunks(MAX_ROW))) {
        let (mut si, mut sii, mut six, mut siy) = (0i32, 0u32, 0i32, 0i32);
        for (&i, (&gx, &gy)) in i.iter().zip(gx.iter().zip(gy)) {
            let i = i32::from(i);
            si += i;
            sii = sii.wrapping_add((i * i) as u32);
            six += i * i32::from(gx);
            siy += i * i32::from(gy);
        }
        s.si += i64::from(si);
        s.sii += i64::from(sii);
        s.six += i64::from(six);
        s.siy += i64::from(siy);
    }
    s
}

/// Values summed in 32 bits before widening: as many as the largest window's row (module docs).
const MAX_ROW: usize = super::MAX_WINDOW;
