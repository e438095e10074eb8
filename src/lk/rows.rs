//! Window loops for scalar cores (the Cortex-M4 of flight controllers).
//!
//! A core without SIMD gains nothing from [`super::flat`]'s padded rows and flat loops and pays
//! for every padding value, the gathered copy of the source pixels and the clears. Here window
//! buffers are packed (`pitch == window`), the patch has a one-pixel border and no padding, and
//! samples are interpolated straight from the frame's rows; only a window whose source pixels
//! cross the frame's edge is gathered first (a [`Source`] of either kind).
//!
//! Each operation on a window is one function, not inlined, whose loops run row by row: a
//! Cortex-M4 has thirteen free registers, and a loop inlined into a larger function or unrolled
//! four-fold (as LLVM does to short loops) spills the bilinear weights and accumulators. The
//! interpolation loop ends on two conditions, which keeps LLVM from unrolling it. Every value
//! equals the flat loops' bit for bit: the same bilinear sums and rounding ([`bilinear`]), the
//! same Scharr sums ([`rescale`]) and exact window sums.
//!
//! # Integer widths
//!
//! Sums of one row (at most [`MAX_WINDOW`] = 63 values) are exact in 32 bits: a product of two
//! values is at most `8160^2 = 66_585_600`, 63 of them `4_194_892_800 < 2^32` for the
//! non-negative `I*J` and `I*I` (kept as `u32`), and `|I*Ix| <= 33_292_800`, 63 of them
//! `2_097_446_400 < 2^31`. Rows add into 64 bits.

use super::template::{MatchSums, TemplateSums};
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
            Source::Frame(rows) => sample_patch(&w, &rows, layout, patch, intensity),
            Source::Gathered(rows) => sample_patch(&w, &rows, layout, patch, intensity),
        }
        derivatives(patch, layout, dx, dy);
        if !origin.fits(frame, layout.win + 2, layout.win + 2) {
            mask_outside(frame, origin, layout, dx, dy);
        }
        template_sums(intensity, dx, dy)
    }

    fn match_window(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        (source, j): (&mut [i16], &mut [i16]),
        t: &TemplateBuffers<'_>,
        gain_bias: bool,
    ) -> MatchSums {
        let w = origin.w.map(i32::from);
        let win = layout.win;
        match Source::of(frame, origin, win, source) {
            Source::Frame(rows) => sample(&w, &rows, win, j),
            Source::Gathered(rows) => sample(&w, &rows, win, j),
        }
        if gain_bias {
            match_sums::<true>(j, t)
        } else {
            match_sums::<false>(j, t)
        }
    }
}

/// The source pixels under a `side` x `side` window and their bilinear neighbours: a
/// `(side + 1)` square.
enum Source<'a> {
    /// The frame's own rows: the square's columns lie in the frame (rows above or below it
    /// repeat its first or last row).
    Frame(SourceRows<'a, u8>),
    /// A copy with the frame's edge pixels repeated beyond its left or right edge.
    Gathered(SourceRows<'a, i16>),
}

impl<'a> Source<'a> {
    fn of(
        frame: &ImageView<'a>,
        origin: &WindowOrigin,
        side: usize,
        scratch: &'a mut [i16],
    ) -> Self {
        let n = side + 1;
        if origin.x >= 0 && origin.x as usize + n <= frame.width() {
            return Source::Frame(SourceRows {
                px: frame.pixels(),
                stride: frame.stride(),
                x: origin.x as usize,
                y: origin.y,
                last_row: frame.height() as isize - 1,
                n,
            });
        }
        gather(frame, origin, n, n, scratch);
        Source::Gathered(SourceRows {
            px: scratch,
            stride: n,
            x: 0,
            y: 0,
            last_row: n as isize - 1,
            n,
        })
    }
}

/// The rows of a source square: row `r` is `n` pixels from `px[y' * stride + x]`, with
/// `y' = y + r` clamped to `0..=last_row`.
struct SourceRows<'a, P> {
    px: &'a [P],
    stride: usize,
    x: usize,
    y: isize,
    last_row: isize,
    n: usize,
}

impl<'a, P: Pixel> SourceRows<'a, P> {
    #[inline(always)]
    fn row(&self, r: usize) -> &'a [P] {
        let y = (self.y + r as isize).clamp(0, self.last_row) as usize;
        let row = self.px.get(y * self.stride + self.x..).unwrap_or(&[]);
        row.get(..self.n).unwrap_or(row)
    }
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
    source: &SourceRows<'_, P>,
    layout: &Layout,
    patch: &mut [i16],
    intensity: &mut [i16],
) {
    let (win, pp) = (layout.win, layout.patch_pitch);
    let mut top = source.row(0);
    let mut inner = intensity.chunks_exact_mut(win);
    for (r, out) in patch.chunks_exact_mut(pp).enumerate() {
        let bottom = source.row(r + 1);
        match if r == 0 { None } else { inner.next() } {
            Some(inner) => interpolate_twice(w, top, bottom, out, inner),
            None => interpolate(w, top, bottom, out),
        }
        top = bottom;
    }
}

/// Samples the `side` x `side` window into `out`, row by row.
#[inline(always)]
fn sample<P: Pixel>(w: &[i32; 4], source: &SourceRows<'_, P>, side: usize, out: &mut [i16]) {
    let mut top = source.row(0);
    for (r, out) in out.chunks_exact_mut(side).enumerate() {
        let bottom = source.row(r + 1);
        interpolate(w, top, bottom, out);
        top = bottom;
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

/// The match sums in one pass over the window (`ΣJ` and `ΣJI` only with `GAIN_BIAS`), exact
/// in 32 bits over chunks of [`MAX_ROW`] values.
#[inline(never)]
fn match_sums<const GAIN_BIAS: bool>(j: &[i16], t: &TemplateBuffers<'_>) -> MatchSums {
    let mut m = MatchSums::default();
    let chunks = j
        .chunks(MAX_ROW)
        .zip(t.intensity.chunks(MAX_ROW))
        .zip(t.dx.chunks(MAX_ROW).zip(t.dy.chunks(MAX_ROW)));
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
