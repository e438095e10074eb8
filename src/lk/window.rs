//! Sub-pixel window sampling and Scharr derivatives.
//!
//! Windows are sampled with bilinear weights of 14 fractional bits and kept as grey x 32
//! (5 fractional bits), the precision OpenCV uses; dropping those bits costs 2-5x in accuracy on
//! weak texture. Pixels outside the frame repeat the nearest edge pixel, so points near the border
//! keep their whole window.
//!
//! Every window buffer is row-major with a pitch of `window + 3` ([`Layout`]): the columns past
//! the window are padding, kept at zero where they would enter a sum. Sampling, derivatives and
//! window sums are then single flat loops over `rows * pitch` values, which vectorise without a
//! scalar tail per row (a 21-px row would leave one of 5 px).
//!
//! Derivatives are taken on the interpolated template patch instead of on the whole frame.
//! Interpolation and the Scharr filter are both linear and shift-invariant, so the result equals
//! interpolating a full derivative image (up to rounding), without the two i16 planes per level
//! that a full derivative image would cost in RAM.

use crate::frame::ImageView;

/// Fractional bits of the bilinear weights.
const WEIGHT_BITS: u32 = 14;
/// Fractional bits kept in sampled intensities (grey x 32).
pub(crate) const INTENSITY_BITS: u32 = 5;

/// The shape of every window buffer for one window size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Layout {
    /// Window side in pixels.
    pub win: usize,
    /// Distance between rows in every buffer: the window, its two derivative border columns and
    /// the bilinear neighbour of the last one.
    pub pitch: usize,
}

impl Layout {
    pub(crate) const fn new(win: usize) -> Self {
        Self {
            win,
            pitch: win + 3,
        }
    }

    /// Values in a window buffer (template, gradients, next-frame window).
    pub(crate) const fn window_len(&self) -> usize {
        self.win * self.pitch
    }

    /// Values in the template patch (window plus a one-pixel border), with two values of slack
    /// for the flat Scharr loop's last reads.
    pub(crate) const fn patch_len(&self) -> usize {
        (self.win + 2) * self.pitch + 2
    }

    /// Values in the gathered source pixels of a patch: one more row, one value of slack.
    pub(crate) const fn source_len(&self) -> usize {
        (self.win + 3) * self.pitch + 1
    }

    /// Zeroes the padding columns of a window buffer so they add nothing to window sums.
    pub(crate) fn clear_padding(&self, buf: &mut [i16]) {
        for row in buf.chunks_exact_mut(self.pitch) {
            row.iter_mut().skip(self.win).for_each(|v| *v = 0);
        }
    }

    /// The window's values of each row of a window buffer, without the padding.
    pub(crate) fn rows<'b>(&self, buf: &'b [i16]) -> impl Iterator<Item = &'b [i16]> + 'b {
        let win = self.win;
        buf.chunks_exact(self.pitch)
            .map(move |row| row.get(..win).unwrap_or(&[]))
    }
}

/// Where a window starts in the frame and how its samples are interpolated.
#[derive(Debug, Clone, Copy)]
pub(crate) struct WindowOrigin {
    /// Column of the top-left source pixel (may be negative or past the edge).
    x: isize,
    /// Row of the top-left source pixel.
    y: isize,
    /// Bilinear weights of the four neighbours; they sum to `2^14`. Kept as `i16` so that
    /// weight x pixel products are 16 x 16-bit multiplies, which vectorise on every SIMD ISA.
    w: [i16; 4],
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
        Self {
            x: (cx >> 16) as isize - reach as isize,
            y: (cy >> 16) as isize - reach as isize,
            w: [w00 as i16, w01 as i16, w10 as i16, w11 as i16],
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

/// Samples `rows` rows of `layout.pitch` values of `frame` at `origin` into `out` (grey x 32).
///
/// `source` receives the `(rows + 1) x pitch` pixels under the window first (edge pixels repeat
/// outside the frame), so the interpolation is one flat loop. Only the first `pitch - 1` values of
/// each output row are meaningful; callers clear or ignore the rest.
pub(crate) fn sample(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    rows: usize,
    layout: &Layout,
    source: &mut [i16],
    out: &mut [i16],
) {
    let pitch = layout.pitch;
    gather(frame, origin, rows + 1, pitch, source);
    if let Some(slack) = source.get_mut((rows + 1) * pitch) {
        *slack = 0;
    }
    let n = rows * pitch;
    let [w00, w01, w10, w11] = origin.w.map(i32::from);
    let run = |k: usize| source.get(k..k + n).unwrap_or(&[]);
    // Four equal-length shifted runs (pixel, right, below, below-right) vectorise cleanly.
    let quads = run(0)
        .iter()
        .zip(run(1))
        .zip(run(pitch).iter().zip(run(pitch + 1)));
    let round = 1 << (WEIGHT_BITS - INTENSITY_BITS - 1);
    for (o, ((&a, &b), (&c, &d))) in out.iter_mut().take(n).zip(quads) {
        let [a, b, c, d] = [a, b, c, d].map(i32::from);
        let sum = w00 * a + w01 * b + w10 * c + w11 * d;
        *o = ((sum + round) >> (WEIGHT_BITS - INTENSITY_BITS)) as i16;
    }
}

/// Copies `rows` x `cols` pixels from `origin` into `out` (row-major, `cols` apart), repeating
/// edge pixels outside the frame.
fn gather(frame: &ImageView<'_>, origin: &WindowOrigin, rows: usize, cols: usize, out: &mut [i16]) {
    let (width, height) = (frame.width() as isize, frame.height() as isize);
    // The part of each row that lies in the frame, as offsets into the row.
    let start = (-origin.x).clamp(0, cols as isize) as usize;
    let end = (width - origin.x).clamp(start as isize, cols as isize) as usize;
    let first_x = (origin.x + start as isize).max(0) as usize;
    for (r, dst) in out.chunks_exact_mut(cols).take(rows).enumerate() {
        let y = (origin.y + r as isize).clamp(0, height - 1) as usize;
        let row = frame.row(y);
        if let (Some(dst), Some(src)) = (
            dst.get_mut(start..end),
            row.get(first_x..first_x + end - start),
        ) {
            dst.iter_mut()
                .zip(src)
                .for_each(|(d, &s)| *d = i16::from(s));
        }
        let (first, last) = (row.first(), row.last());
        let (first, last) = (first.copied().unwrap_or(0), last.copied().unwrap_or(0));
        dst.iter_mut()
            .take(start)
            .for_each(|d| *d = i16::from(first));
        dst.iter_mut().skip(end).for_each(|d| *d = i16::from(last));
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
    // The template starts one pixel inside the patch.
    let (x0, y0) = (origin.x + 1, origin.y + 1);
    // A sample between pixels needs its right and lower neighbours too.
    let reach_x = isize::from(origin.w[1] != 0 || origin.w[3] != 0);
    let reach_y = isize::from(origin.w[2] != 0 || origin.w[3] != 0);
    let inside_x = |c: usize| {
        let x = x0 + c as isize;
        x >= 0 && x + reach_x < frame.width() as isize
    };
    let inside_y = |r: usize| {
        let y = y0 + r as isize;
        y >= 0 && y + reach_y < frame.height() as isize
    };
    let rows = dx
        .chunks_exact_mut(layout.pitch)
        .zip(dy.chunks_exact_mut(layout.pitch));
    for (r, (dx_row, dy_row)) in rows.enumerate() {
        let row_inside = inside_y(r);
        for (c, (gx, gy)) in dx_row.iter_mut().zip(dy_row.iter_mut()).enumerate() {
            if !row_inside || !inside_x(c) {
                *gx = 0;
                *gy = 0;
            }
        }
    }
}

/// Copies the template (the patch without its one-pixel border) into `out`, padding cleared.
pub(crate) fn inner(patch: &[i16], layout: &Layout, out: &mut [i16]) {
    let n = layout.window_len();
    if let Some(src) = patch.get(layout.pitch + 1..layout.pitch + 1 + n) {
        out.iter_mut().zip(src).for_each(|(d, &s)| *d = s);
    }
    layout.clear_padding(out);
}

/// Scharr derivatives of the template inside its patch, padding cleared.
///
/// The patch holds grey x 32; the outputs are rescaled to the Scharr gain of 32 per grey level
/// per pixel (`|value| <= 16 * 255 = 4080`), the scale OpenCV's LK works in.
pub(crate) fn scharr(patch: &[i16], layout: &Layout, dx: &mut [i16], dy: &mut [i16]) {
    let (n, p) = (layout.window_len(), layout.pitch);
    // Output k is the template pixel whose patch neighbourhood starts at patch[k].
    let run = |k: usize| patch.get(k..k + n).unwrap_or(&[]);
    let w = |v: &i16| i32::from(*v);
    // |s| <= 16 * 8160; dropping the 5 intensity bits brings it back to <= 4080.
    let rescale = |s: i32| ((s + (1 << (INTENSITY_BITS - 1))) >> INTENSITY_BITS) as i16;
    let (ul, uc, ur) = (run(0), run(1), run(2));
    let (ml, mr) = (run(p), run(p + 2));
    let (dl, dc, dr) = (run(2 * p), run(2 * p + 1), run(2 * p + 2));
    let horizontal = ul
        .iter()
        .zip(ur)
        .zip(ml.iter().zip(mr))
        .zip(dl.iter().zip(dr));
    for (gx, (((a, b), (c, d)), (e, f))) in dx.iter_mut().zip(horizontal) {
        *gx = rescale(3 * (w(b) - w(a)) + 10 * (w(d) - w(c)) + 3 * (w(f) - w(e)));
    }
    let vertical = ul
        .iter()
        .zip(dl)
        .zip(uc.iter().zip(dc))
        .zip(ur.iter().zip(dr));
    for (gy, (((a, b), (c, d)), (e, f))) in dy.iter_mut().zip(vertical) {
        *gy = rescale(3 * (w(b) - w(a)) + 10 * (w(d) - w(c)) + 3 * (w(f) - w(e)));
    }
    layout.clear_padding(dx);
    layout.clear_padding(dy);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> [u8; 64 * 64] {
        core::array::from_fn(|i| ((i % 64) * 3 + i / 64) as u8)
    }

    /// Samples a `side` x `side` window centred at `(cx, cy)` (Q16 bits), padding dropped.
    fn window(frame: &ImageView<'_>, cx: i32, cy: i32, side: usize) -> [i16; 81] {
        let layout = Layout::new(side);
        let mut source = [0i16; 256];
        let mut out = [0i16; 128];
        let origin = WindowOrigin::new(cx, cy, side / 2);
        sample(frame, &origin, side, &layout, &mut source, &mut out);
        let mut packed = [0i16; 81];
        for (r, row) in layout.rows(&out).take(side).enumerate() {
            packed[r * side..(r + 1) * side].copy_from_slice(row);
        }
        packed
    }

    #[test]
    fn bilinear_sample_of_a_ramp_is_exact() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        // Centre (20.25, 10.5): the top-left sample of a 3x3 window is at (19.25, 9.5).
        let out = window(&frame, 20 * 65536 + 16384, 10 * 65536 + 32768, 3);
        assert_eq!(out[0], ((19.25 * 3.0 + 9.5) * 32.0) as i16);
        assert_eq!(out[4], ((20.25 * 3.0 + 10.5) * 32.0) as i16);
        assert_eq!(out[8], ((21.25 * 3.0 + 11.5) * 32.0) as i16);
    }

    #[test]
    fn clamped_path_repeats_the_edge() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        let out = window(&frame, 0, 0, 5);
        // Rows and columns -2 and -1 repeat row/column 0.
        assert_eq!(out[0], 0);
        assert_eq!(out[2], 0);
        assert_eq!(out[3], 3 * 32);
        assert_eq!(out[15], 32);
    }

    #[test]
    fn windows_entirely_outside_repeat_the_nearest_pixels() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        // Far right and below: every sample is the bottom-right pixel.
        let out = window(&frame, 100 << 16, 90 << 16, 3);
        assert!(out[..9]
            .iter()
            .all(|&v| v == i16::from(px[63 * 64 + 63]) * 32));
        // Far left: every sample of a row is that row's first pixel.
        let out = window(&frame, -50 << 16, 10 << 16, 3);
        assert_eq!(&out[..9], &[288, 288, 288, 320, 320, 320, 352, 352, 352]);
    }

    #[test]
    fn scharr_of_a_ramp_has_gain_32() {
        let px = ramp();
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        let layout = Layout::new(3);
        let origin = WindowOrigin::new(30 << 16, 30 << 16, 2);
        let mut source = [0i16; 64];
        let mut patch = [0i16; 64];
        sample(&frame, &origin, 5, &layout, &mut source, &mut patch);
        let (mut dx, mut dy) = ([0i16; 18], [0i16; 18]);
        scharr(&patch, &layout, &mut dx, &mut dy);
        for (gx, gy) in layout.rows(&dx).zip(layout.rows(&dy)) {
            assert!(gx.iter().all(|&g| g == 3 * 32));
            assert!(gy.iter().all(|&g| g == 32));
        }
        assert_eq!(dx[3..6], [0, 0, 0], "padding is cleared");
    }
}
