//! Window geometry shared by both sets of window loops: buffer shapes, where a window sits in
//! the frame with its bilinear weights, and the border mask.
//!
//! Windows are sampled with bilinear weights of 14 fractional bits and kept as grey x 32
//! (5 fractional bits), the precision OpenCV uses; dropping those bits costs 2-5x in accuracy on
//! weak texture. Pixels outside the frame repeat the nearest edge pixel, so points near the border
//! keep their whole window.
//!
//! Derivatives are taken on the interpolated template patch instead of on the whole frame.
//! Interpolation and the Scharr filter are both linear and shift-invariant, so the result equals
//! interpolating a full derivative image (up to rounding), without the two i16 planes per level
//! that a full derivative image would cost in RAM.
//!
//! The window loops ([`Loops`]) are [`super::rows`] on every target; the tests hold them to an
//! independent implementation, `super::flat` (built for the tests only; rows padded to vector widths, flat loops), bit
//! for bit.

use super::correlation::Correlations;
use super::template::{abs_residual_of, Correction, TemplateSums};
use crate::frame::ImageView;
use core::ops::Range;

/// `buf[range]`, for a range the buffer layout puts inside `buf`.
///
/// Every LK buffer is cut once from a scratch checked against [`super::scratch_len`], to the
/// lengths [`Layout`] gives, and the loops take only ranges those lengths cover: a range
/// outside is a layout bug. Debug builds (the tests, fuzzing) stop on it; release builds read
/// an empty run, which adds nothing to a sum and writes nothing, rather than panic. The check
/// compiles away in release, so the hot loops cost what a plain `get` does.
#[inline(always)]
pub(crate) fn in_layout<T>(buf: &[T], range: Range<usize>) -> &[T] {
    let run = buf.get(range.clone());
    debug_assert!(run.is_some(), "{range:?} outside a buffer of {}", buf.len());
    run.unwrap_or(&[])
}

/// [`in_layout`] for a buffer being written.
#[inline(always)]
pub(crate) fn in_layout_mut<T>(buf: &mut [T], range: Range<usize>) -> &mut [T] {
    let len = buf.len();
    let run = buf.get_mut(range.clone());
    debug_assert!(run.is_some(), "{range:?} outside a buffer of {len}");
    run.unwrap_or(&mut [])
}

/// Fractional bits of the bilinear weights.
pub(crate) const WEIGHT_BITS: u32 = crate::dsp::runs::WEIGHT_BITS;
/// Fractional bits kept in sampled intensities (grey x 32).
pub(crate) const INTENSITY_BITS: u32 = crate::dsp::runs::SAMPLE_BITS;

/// The shape of every buffer for one window size.
///
/// Window buffers (template, gradients, next-frame window) are row-major, `pitch` values apart;
/// columns past the window are padding, zero wherever they would enter a sum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Layout {
    /// Window side in pixels.
    pub win: usize,
    /// Distance between rows of the window buffers.
    pub pitch: usize,
    /// Distance between rows of the template patch (the window and a one-pixel border).
    pub patch_pitch: usize,
    /// Values in the template patch buffer.
    pub patch_len: usize,
    /// Values in the buffer that source pixels are gathered into (zero when unused).
    pub source_len: usize,
}

impl Layout {
    /// Values in a window buffer.
    pub(crate) const fn window_len(&self) -> usize {
        self.win * self.pitch
    }

    /// The window's values of each row of a window buffer, without the padding.
    pub(crate) fn rows<'b>(&self, buf: &'b [i16]) -> impl Iterator<Item = &'b [i16]> + 'b {
        let win = self.win;
        // Rows of `pitch` >= `win + 1` values hold the window's `win`.
        buf.chunks_exact(self.pitch)
            .map(move |row| in_layout(row, 0..win))
    }
}

/// One implementation of the window loops. Both give the same values bit for bit; they differ
/// in buffer layout and loop shape only.
pub(crate) trait Loops {
    /// The buffer shapes for a `win` x `win` window.
    fn layout(win: usize) -> Layout;

    /// Samples the template patch, the `win + 2` square at `origin`, into `patch` (grey x 32)
    /// and derives the template from it: its intensities (the patch without its one-pixel
    /// border) and Scharr derivatives, rescaled to the Scharr gain of 32 per grey level per pixel
    /// (`|value| <= 16 * 255 = 4080`, OpenCV's scale), with the gradients of pixels outside the
    /// frame zeroed ([`mask_outside`]); padding zero. Returns the template's window sums.
    /// `scratch` is the source buffer (`layout.source_len` values) and the patch.
    fn template(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        scratch: (&mut [i16], &mut [i16]),
        out: TemplateOut<'_>,
    ) -> TemplateSums;

    /// The [`Correlations`] of the source pixels under the `win` square at `origin` (its integer
    /// position only) with the template. `source` is scratch of `layout.source_len` values.
    fn correlate(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        source: &mut [i16],
        t: &TemplateBuffers<'_>,
    ) -> Correlations;

    /// Samples the next window, the `win` square at `origin`, into the window buffer `j`
    /// (padding zero). `source` is scratch of `layout.source_len` values.
    fn sample_window(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        source: &mut [i16],
        j: &mut [i16],
    );

    /// The sum over the next window at `origin` of `|J 2^16 - gain I - bias|`
    /// ([`Correction::distance`]) against the template's `intensity`. `source` holds what
    /// [`Loops::correlate`] last left there, for a window at this integer position (loops may
    /// read their gathered block from it); `j` is scratch for the samples.
    fn abs_residual(
        frame: &ImageView<'_>,
        origin: &WindowOrigin,
        layout: &Layout,
        (source, j): (&mut [i16], &mut [i16]),
        intensity: &[i16],
        correction: Correction,
    ) -> u64 {
        Self::sample_window(frame, origin, layout, source, j);
        abs_residual_of(layout, intensity, j, correction)
    }
}

/// The buffers a template is derived into, laid out like [`TemplateBuffers`].
#[derive(Debug)]
pub(crate) struct TemplateOut<'s> {
    pub intensity: &'s mut [i16],
    pub dx: &'s mut [i16],
    pub dy: &'s mut [i16],
}

/// The template's window buffers, laid out alike: intensities (grey x 32) and Scharr gradients.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TemplateBuffers<'s> {
    pub intensity: &'s [i16],
    pub dx: &'s [i16],
    pub dy: &'s [i16],
}

/// Where a window starts in the frame and how its samples are interpolated.
#[derive(Debug, Clone, Copy)]
pub(crate) struct WindowOrigin {
    /// Column of the top-left source pixel (may be negative or past the edge).
    pub x: isize,
    /// Row of the top-left source pixel.
    pub y: isize,
    /// Bilinear weights of the four neighbours; they sum to `2^14`. Kept as `i16` so that
    /// weight x pixel products are 16 x 16-bit multiplies, which vectorise on every SIMD ISA.
    pub w: [i16; 4],
}

impl WindowOrigin {
    /// The origin of a `side` x `side` window whose top-left sample sits `reach` px left of and
    /// above the centre `(cx, cy)`, given in Q16 raw bits.
    pub(crate) fn new(cx: i32, cy: i32, reach: usize) -> Self {
        let fx = (cx & 0xFFFF) >> (16 - WEIGHT_BITS);
        let fy = (cy & 0xFFFF) >> (16 - WEIGHT_BITS);
        let one = 1 << WEIGHT_BITS;
        let round = 1 << (WEIGHT_BITS - 1);
        let w00 = ((one - fx) * (one - fy) + round) >> WEIGHT_BITS;
        let w01 = (fx * (one - fy) + round) >> WEIGHT_BITS;
        let w10 = ((one - fx) * fy + round) >> WEIGHT_BITS;
        let w11 = one - w00 - w01 - w10;
        // The four weights as one 64-bit value, stored at once: read back as one load (on
        // x86-64), four 16-bit stores would stall it.
        let lane = |w: i32, k: u32| u64::from(w as u16) << (16 * k);
        let packed = (lane(w00, 0) | lane(w01, 1) | lane(w10, 2) | lane(w11, 3)).to_le_bytes();
        let half = |k: usize| i16::from_le_bytes([packed[2 * k], packed[2 * k + 1]]);
        Self {
            x: (cx >> 16) as isize - reach as isize,
            y: (cy >> 16) as isize - reach as isize,
            w: [half(0), half(1), half(2), half(3)],
        }
    }

    /// True when every sample of a `rows` x `cols` window at this origin, with its bilinear
    /// neighbours, lies in the frame.
    pub(crate) fn fits(&self, frame: &ImageView<'_>, rows: usize, cols: usize) -> bool {
        self.x >= 0
            && self.y >= 0
            && self.x as usize + cols < frame.width()
            && self.y as usize + rows < frame.height()
    }

    /// True when no sample of a `side` x `side` window at this origin touches the frame.
    pub(crate) fn misses(&self, frame: &ImageView<'_>, side: usize) -> bool {
        let side = side as isize;
        self.x + side < 0
            || self.y + side < 0
            || self.x >= frame.width() as isize
            || self.y >= frame.height() as isize
    }
}

/// Scharr's smoothing, shared by every Scharr sum of the window loops (and the kernels of
/// `dsp`, which define it).
pub(crate) use crate::dsp::runs::scharr_smooth;

/// Copies `rows` x `cols` pixels from `origin` into `out` (row-major, `cols` apart), repeating
/// edge pixels outside the frame.
pub(crate) fn gather(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    rows: usize,
    cols: usize,
    out: &mut [i16],
) {
    let stride = frame.stride();
    if let Some(block) = frame.block(origin.x, origin.y, cols, rows) {
        // Inside the frame: a plain copy, row by row.
        crate::dsp::runs::widen_rows(block, stride, cols, out, cols);
        return;
    }
    let (width, height) = (frame.width() as isize, frame.height() as isize);
    // The part of each row that lies in the frame, as offsets into the row, and the rows that
    // do.
    let start = (-origin.x).clamp(0, cols as isize) as usize;
    let end = (width - origin.x).clamp(start as isize, cols as isize) as usize;
    let top = (-origin.y).clamp(0, rows as isize) as usize;
    let bottom = (height - origin.y).clamp(top as isize, rows as isize) as usize;
    let inside = frame.block(
        origin.x + start as isize,
        origin.y + top as isize,
        end - start,
        bottom - top,
    );
    let Some(inside) = inside.filter(|_| start < end && top < bottom) else {
        // No pixel of the window in the frame (its rows or its columns all outside).
        return gather_outside(frame, origin, rows, cols, out);
    };
    // The part in the frame, then each of its rows repeats its first and last pixel, which
    // are the frame's, outwards; the rows above and below repeat the first and last row.
    let out = out.get_mut(..rows * cols).unwrap_or(&mut []);
    let first = top * cols + start;
    crate::dsp::runs::widen_rows(inside, stride, end - start, &mut out[first..], cols);
    for r in top..bottom {
        let row = &mut out[r * cols..(r + 1) * cols];
        let (left, right) = (row[start], row[end - 1]);
        row[..start].fill(left);
        row[end..].fill(right);
    }
    for r in 0..top {
        out.copy_within(top * cols..(top + 1) * cols, r * cols);
    }
    for r in bottom..rows {
        out.copy_within((bottom - 1) * cols..bottom * cols, r * cols);
    }
}

/// [`gather`] for a window none of whose pixels is in the frame: every value repeats the
/// frame's pixel nearest to it.
fn gather_outside(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    rows: usize,
    cols: usize,
    out: &mut [i16],
) {
    let (width, height) = (frame.width() as isize, frame.height() as isize);
    for (r, dst) in out.chunks_exact_mut(cols).take(rows).enumerate() {
        let y = (origin.y + r as isize).clamp(0, height - 1) as usize;
        let row = frame.row(y);
        for (c, d) in dst.iter_mut().enumerate() {
            let x = (origin.x + c as isize).clamp(0, width - 1) as usize;
            *d = row.get(x).map_or(0, |&v| i16::from(v));
        }
    }
}

/// Zeroes the gradients of template pixels that lie outside `frame`.
///
/// Outside the frame the sampler repeats edge pixels, which do not move with the scene; with
/// zero gradients those pixels drop out of the gradient matrix and the mismatch vector, so a point
/// near the border is tracked on the part of its window that is real image. `origin` is the
/// origin of the template's patch.
pub(crate) fn mask_outside(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    layout: &Layout,
    dx: &mut [i16],
    dy: &mut [i16],
) {
    // The template starts one pixel inside the patch; a sample between pixels needs its right
    // and lower neighbours too.
    let reach_x = isize::from(origin.w[1] != 0 || origin.w[3] != 0);
    let reach_y = isize::from(origin.w[2] != 0 || origin.w[3] != 0);
    // Template columns and rows `first..end` lie in the frame.
    let inside = |start: isize, reach: isize, size: usize, count: usize| {
        let first = (-start).clamp(0, count as isize);
        let end = (size as isize - reach - start).clamp(first, count as isize);
        (first as usize, end as usize)
    };
    let (first_col, end_col) = inside(origin.x + 1, reach_x, frame.width(), layout.pitch);
    let (first_row, end_row) = inside(origin.y + 1, reach_y, frame.height(), layout.win);
    // Row by row (not by `chunks`, whose count is a division).
    let p = layout.pitch;
    for r in 0..layout.win {
        let (left, right) = match r {
            _ if r < first_row || r >= end_row => (p, p),
            _ if first_col == 0 && end_col >= p => continue,
            _ => (first_col, end_col),
        };
        for buf in [&mut *dx, &mut *dy] {
            let Some(row) = buf.get_mut(r * p..(r + 1) * p) else {
                continue;
            };
            let (outside_left, rest) = row.split_at_mut(left.min(p));
            outside_left.fill(0);
            rest.iter_mut().skip(right - left).for_each(|v| *v = 0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::flat::Flat;
    use super::super::rows::Rows;
    use super::*;

    fn ramp() -> [u8; 64 * 64] {
        core::array::from_fn(|i| ((i % 64) * 3 + i / 64) as u8)
    }

    /// Pseudo-random pixels: texture at every scale, including the extremes 0 and 255.
    fn noise<const N: usize>(seed: u32) -> [u8; N] {
        let mut state = seed;
        core::array::from_fn(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            match state >> 29 {
                0 => 0,
                1 => 255,
                _ => (state >> 24) as u8,
            }
        })
    }

    /// The window's values row after row, padding dropped.
    fn packed(layout: &Layout, buf: &[i16]) -> [i16; 63 * 63] {
        let mut out = [0i16; 63 * 63];
        let win = layout.win;
        for (r, row) in layout.rows(buf).take(win).enumerate() {
            out[r * win..(r + 1) * win].copy_from_slice(row);
        }
        out
    }

    /// Samples a `side` x `side` window centred at `(cx, cy)` (Q16 bits), padding dropped.
    fn window<L: Loops>(frame: &ImageView<'_>, cx: i32, cy: i32, side: usize) -> [i16; 63 * 63] {
        let layout = L::layout(side);
        let mut source = [0i16; 4096];
        let mut out = [0i16; 4096];
        let origin = WindowOrigin::new(cx, cy, side / 2);
        L::sample_window(
            frame,
            &origin,
            &layout,
            &mut source,
            &mut out[..layout.window_len()],
        );
        packed(&layout, &out)
    }

    /// Everything a template computes at a centre: intensity, gradients and sums, unpadded, and
    /// the correlations and samples of a window half a pixel off.
    struct TemplateParts {
        intensity: [i16; 63 * 63],
        dx: [i16; 63 * 63],
        dy: [i16; 63 * 63],
        sums: TemplateSums,
        correlations: Correlations,
        next: [i16; 63 * 63],
    }

    fn template<L: Loops>(frame: &ImageView<'_>, c: (i32, i32), win: usize) -> TemplateParts {
        let layout = L::layout(win);
        let mut source = [0i16; 4096];
        let mut patch = [0i16; 4096];
        let [mut i, mut dx, mut dy, mut j] = [[0i16; 4096]; 4];
        let origin = WindowOrigin::new(c.0, c.1, win / 2 + 1);
        let n = layout.window_len();
        let out = TemplateOut {
            intensity: &mut i[..n],
            dx: &mut dx[..n],
            dy: &mut dy[..n],
        };
        let sums = L::template(frame, &origin, &layout, (&mut source, &mut patch), out);
        let t = TemplateBuffers {
            intensity: &i[..n],
            dx: &dx[..n],
            dy: &dy[..n],
        };
        let next = WindowOrigin::new(c.0 + 32768, c.1 - 16384, win / 2);
        let correlations = L::correlate(frame, &next, &layout, &mut source, &t);
        L::sample_window(frame, &next, &layout, &mut source, &mut j[..n]);
        TemplateParts {
            intensity: packed(&layout, t.intensity),
            dx: packed(&layout, t.dx),
            dy: packed(&layout, t.dy),
            sums,
            correlations,
            next: packed(&layout, &j[..n]),
        }
    }

    fn both(check: impl Fn(&dyn Fn(&ImageView<'_>, i32, i32, usize) -> [i16; 63 * 63])) {
        check(&window::<Flat>);
        check(&window::<Rows>);
    }

    #[test]
    fn bilinear_sample_of_a_ramp_is_exact() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        both(|window| {
            // Centre (20.25, 10.5): the top-left sample of a 3x3 window is at (19.25, 9.5).
            let out = window(&frame, 20 * 65536 + 16384, 10 * 65536 + 32768, 3);
            assert_eq!(out[0], ((19.25 * 3.0 + 9.5) * 32.0) as i16);
            assert_eq!(out[4], ((20.25 * 3.0 + 10.5) * 32.0) as i16);
            assert_eq!(out[8], ((21.25 * 3.0 + 11.5) * 32.0) as i16);
        });
    }

    #[test]
    fn clamped_path_repeats_the_edge() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        both(|window| {
            let out = window(&frame, 0, 0, 5);
            // Rows and columns -2 and -1 repeat row/column 0.
            assert_eq!(out[0], 0);
            assert_eq!(out[2], 0);
            assert_eq!(out[3], 3 * 32);
            assert_eq!(out[5], 0);
            assert_eq!(out[15], 32);
        });
    }

    #[test]
    fn windows_entirely_outside_repeat_the_nearest_pixels() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        both(|window| {
            // Far right and below: every sample is the bottom-right pixel.
            let out = window(&frame, 100 << 16, 90 << 16, 3);
            assert!(out[..9]
                .iter()
                .all(|&v| v == i16::from(px[63 * 64 + 63]) * 32));
            // Far left: every sample of a row is that row's first pixel.
            let out = window(&frame, -50 << 16, 10 << 16, 3);
            assert_eq!(&out[..9], &[288, 288, 288, 320, 320, 320, 352, 352, 352]);
        });
    }

    /// Blocks inside the frame, over each edge and corner, and wholly outside it: every value
    /// is the frame's pixel nearest to it, and nothing past the block is written.
    #[test]
    fn gather_repeats_the_nearest_pixel() {
        const W: usize = 23;
        const H: usize = 17;
        let px = noise::<{ W * H }>(11);
        let frame = ImageView::packed(&px, W, H).unwrap();
        for (rows, cols) in [(1, 1), (4, 3), (10, 10), (12, 12), (9, 20), (30, 30)] {
            for y in -35..H as isize + 5 {
                for x in -35..W as isize + 5 {
                    let origin = WindowOrigin {
                        x,
                        y,
                        w: [1 << 14, 0, 0, 0],
                    };
                    let mut out = [-1i16; 32 * 32];
                    gather(&frame, &origin, rows, cols, &mut out[..rows * cols + 2]);
                    for r in 0..rows {
                        for c in 0..cols {
                            let sy = (y + r as isize).clamp(0, H as isize - 1) as usize;
                            let sx = (x + c as isize).clamp(0, W as isize - 1) as usize;
                            let want = i16::from(px[sy * W + sx]);
                            assert_eq!(out[r * cols + c], want, "{rows}x{cols} at {x},{y}");
                        }
                    }
                    assert!(out[rows * cols..].iter().all(|&v| v == -1));
                }
            }
        }
    }

    #[test]
    fn scharr_of_a_ramp_has_gain_32() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        for t in [
            template::<Flat>(&frame, (30 << 16, 30 << 16), 3),
            template::<Rows>(&frame, (30 << 16, 30 << 16), 3),
        ] {
            assert!(t.dx[..9].iter().all(|&g| g == 3 * 32));
            assert!(t.dy[..9].iter().all(|&g| g == 32));
            assert_eq!(t.intensity[4], (30 * 3 + 30) * 32);
        }
    }

    /// The mask zeroes exactly the gradients of template pixels whose sample, with the
    /// neighbours it reads, is not wholly in the frame.
    #[test]
    fn mask_zeroes_the_pixels_outside() {
        let px = [0u8; 30 * 20];
        let frame = ImageView::packed(&px, 30, 20).unwrap();
        for layout in [Flat::layout(5), Rows::layout(5), Rows::layout(9)] {
            let win = layout.win;
            for (cx, cy) in [
                (0, 0),
                (29, 19),
                (2, 10),
                (27, 18),
                (-3, 5),
                (15, 23),
                (15, 10),
            ] {
                for frac in [0, 0x8000, 0x4000] {
                    let origin =
                        WindowOrigin::new((cx << 16) + frac, (cy << 16) + frac / 2, win / 2 + 1);
                    let n = layout.window_len();
                    let (mut dx, mut dy) = ([1i16; 256], [1i16; 256]);
                    mask_outside(&frame, &origin, &layout, &mut dx[..n], &mut dy[..n]);
                    for k in 0..n {
                        let (r, c) = ((k / layout.pitch) as isize, (k % layout.pitch) as isize);
                        let (x, y) = (origin.x + 1 + c, origin.y + 1 + r);
                        let reach_x = isize::from(origin.w[1] != 0 || origin.w[3] != 0);
                        let reach_y = isize::from(origin.w[2] != 0 || origin.w[3] != 0);
                        let inside = x >= 0 && x + reach_x < 30 && y >= 0 && y + reach_y < 20;
                        assert_eq!((dx[k], dy[k]), if inside { (1, 1) } else { (0, 0) }, "{k}");
                    }
                }
            }
        }
    }

    #[test]
    fn flat_padding_is_zero() {
        let px = noise::<{ 40 * 30 }>(3);
        let frame = ImageView::packed(&px, 40, 30).unwrap();
        let layout = Flat::layout(5);
        let (mut source, mut out) = ([0i16; 256], [-1i16; 256]);
        let origin = WindowOrigin::new(20 << 16, 15 << 16, 2);
        let n = layout.window_len();
        Flat::sample_window(&frame, &origin, &layout, &mut source, &mut out[..n]);
        for row in out[..n].chunks_exact(layout.pitch) {
            assert_eq!(row[5..], [0, 0, 0]);
        }
    }

    /// The two sets of loops agree bit for bit on every value and sum, for windows inside the
    /// frame, across each edge and corner, and wholly outside it, at many sub-pixel offsets and
    /// on whole pixels.
    #[test]
    fn flat_and_row_loops_agree() {
        const W: usize = 47;
        const H: usize = 35;
        let px = noise::<{ W * H }>(7);
        let bright = [255u8; W * H];
        for pixels in [&px, &bright] {
            let frame = ImageView::packed(pixels, W, H).unwrap();
            for win in [3, 5, 9, 21] {
                let mut k = 0i32;
                for cy in (-14..=H as i32 + 12).step_by(3) {
                    for cx in (-14..=W as i32 + 12).step_by(3) {
                        // Sub-pixel offsets cycling through integers, halves and odd fractions.
                        // And every centre on a whole pixel, where templates take no weights.
                        k = (k * 31 + 7919) & 0xFFFF;
                        let between = ((cx << 16) + k, (cy << 16) + ((k * 7) & 0xFFFF));
                        for c in [between, (cx << 16, cy << 16)] {
                            let (f, r) = (
                                template::<Flat>(&frame, c, win),
                                template::<Rows>(&frame, c, win),
                            );
                            let at = (win, c);
                            assert_eq!(f.intensity, r.intensity, "{at:?}");
                            assert_eq!(f.dx, r.dx, "{at:?}");
                            assert_eq!(f.dy, r.dy, "{at:?}");
                            assert_eq!(f.sums, r.sums, "{at:?}");
                            assert_eq!(f.correlations, r.correlations, "{at:?}");
                            assert_eq!(f.next, r.next, "{at:?}");
                        }
                    }
                }
            }
        }
    }
}
