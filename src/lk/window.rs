//! Sub-pixel window sampling and Scharr derivatives.
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

use crate::frame::ImageView;

/// Fractional bits of the bilinear weights.
const WEIGHT_BITS: u32 = 14;
/// Fractional bits kept in sampled intensities (grey x 32).
pub(crate) const INTENSITY_BITS: u32 = 5;
/// The largest window side plus the one-pixel derivative border and the bilinear neighbour.
const MAX_SPAN: usize = super::MAX_WINDOW + 3;

/// Where a window starts in the frame and how its samples are interpolated.
#[derive(Debug, Clone, Copy)]
pub(crate) struct WindowOrigin {
    /// Column of the top-left source pixel (may be negative or past the edge).
    x: isize,
    /// Row of the top-left source pixel.
    y: isize,
    /// Bilinear weights of the four neighbours; they sum to `2^14`.
    w: [i32; 4],
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
            w: [w00, w01, w10, w11],
        }
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

/// Samples a `side` x `side` window of `frame` at `origin` into `out` (row-major, grey x 32).
pub(crate) fn sample(frame: &ImageView<'_>, origin: &WindowOrigin, side: usize, out: &mut [i16]) {
    if fits(frame, origin, side) {
        sample_inside(frame, origin, side, out);
    } else {
        sample_clamped(frame, origin, side, out);
    }
}

#[inline(always)]
fn interpolate(w: &[i32; 4], a: u8, b: u8, c: u8, d: u8) -> i16 {
    let sum = w[0] * i32::from(a) + w[1] * i32::from(b) + w[2] * i32::from(c) + w[3] * i32::from(d);
    ((sum + (1 << (WEIGHT_BITS - INTENSITY_BITS - 1))) >> (WEIGHT_BITS - INTENSITY_BITS)) as i16
}

/// The fast path: every source pixel, including the bilinear neighbours, lies in the frame.
fn sample_inside(frame: &ImageView<'_>, origin: &WindowOrigin, side: usize, out: &mut [i16]) {
    let (x0, y0) = (origin.x as usize, origin.y as usize);
    for (r, out_row) in out.chunks_exact_mut(side).take(side).enumerate() {
        let top = frame.row(y0 + r).get(x0..x0 + side + 1).unwrap_or(&[]);
        let bottom = frame.row(y0 + r + 1).get(x0..x0 + side + 1).unwrap_or(&[]);
        for ((o, t), b) in out_row
            .iter_mut()
            .zip(top.windows(2))
            .zip(bottom.windows(2))
        {
            *o = interpolate(&origin.w, t[0], t[1], b[0], b[1]);
        }
    }
}

/// The border path: source coordinates are clamped to the frame (edge pixels repeat).
fn sample_clamped(frame: &ImageView<'_>, origin: &WindowOrigin, side: usize, out: &mut [i16]) {
    let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
    let mut cols = [0usize; MAX_SPAN];
    for (i, c) in cols.iter_mut().enumerate().take(side + 1) {
        *c = clamp(origin.x + i as isize, frame.width());
    }
    for (r, out_row) in out.chunks_exact_mut(side).take(side).enumerate() {
        let top = frame.row(clamp(origin.y + r as isize, frame.height()));
        let bottom = frame.row(clamp(origin.y + r as isize + 1, frame.height()));
        let px = |row: &[u8], i: usize| row.get(cols[i]).copied().unwrap_or(0);
        for (c, o) in out_row.iter_mut().enumerate() {
            *o = interpolate(
                &origin.w,
                px(top, c),
                px(top, c + 1),
                px(bottom, c),
                px(bottom, c + 1),
            );
        }
    }
}

/// Zeroes the gradients of template pixels that lie outside `frame`.
///
/// Outside the frame the sampler repeats edge pixels, which do not move with the scene; with
/// zero gradients those pixels drop out of the gradient matrix and the mismatch vector, so a point
/// near the border is tracked on the part of its window that is real image.
pub(crate) fn mask_outside(
    frame: &ImageView<'_>,
    origin: &WindowOrigin,
    side: usize,
    dx: &mut [i16],
    dy: &mut [i16],
) {
    // `origin` is the patch origin; the template starts one pixel further in.
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
    let rows = dx.chunks_exact_mut(side).zip(dy.chunks_exact_mut(side));
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

/// True when every sample of a `side` x `side` window at `origin`, with its bilinear
/// neighbours, lies in the frame.
pub(crate) fn fits(frame: &ImageView<'_>, origin: &WindowOrigin, side: usize) -> bool {
    origin.x >= 0
        && origin.y >= 0
        && origin.x as usize + side < frame.width()
        && origin.y as usize + side < frame.height()
}

/// Scharr derivatives of the inner `side - 2` square of a `side` x `side` patch.
///
/// The patch holds grey x 32; the outputs are rescaled to the Scharr gain of 32 per grey level
/// per pixel (`|value| <= 16 * 255 = 4080`), the scale OpenCV's LK works in.
pub(crate) fn scharr(patch: &[i16], side: usize, dx: &mut [i16], dy: &mut [i16]) {
    let inner = side - 2;
    let rows = patch.chunks_exact(side);
    let triples = rows.clone().zip(rows.clone().skip(1)).zip(rows.skip(2));
    let out_rows = dx.chunks_exact_mut(inner).zip(dy.chunks_exact_mut(inner));
    for (((up, mid), down), (dx_row, dy_row)) in triples.zip(out_rows) {
        let taps = up.windows(3).zip(mid.windows(3)).zip(down.windows(3));
        for (((u, m), d), (gx, gy)) in taps.zip(dx_row.iter_mut().zip(dy_row.iter_mut())) {
            let (u, m, d) = (widen3(u), widen3(m), widen3(d));
            let sx = 3 * (u[2] - u[0]) + 10 * (m[2] - m[0]) + 3 * (d[2] - d[0]);
            let sy = 3 * (d[0] - u[0]) + 10 * (d[1] - u[1]) + 3 * (d[2] - u[2]);
            // |s| <= 16 * 8160; dropping the 5 intensity bits brings it back to <= 4080.
            *gx = ((sx + (1 << (INTENSITY_BITS - 1))) >> INTENSITY_BITS) as i16;
            *gy = ((sy + (1 << (INTENSITY_BITS - 1))) >> INTENSITY_BITS) as i16;
        }
    }
}

/// The three taps of a `windows(3)` item as `i32`.
#[inline(always)]
fn widen3(taps: &[i16]) -> [i32; 3] {
    match taps {
        [a, b, c, ..] => [i32::from(*a), i32::from(*b), i32::from(*c)],
        _ => [0; 3],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> [u8; 64 * 64] {
        let mut px = [0u8; 64 * 64];
        for y in 0..h {
            for x in 0..w {
                px[y * w + x] = (x * 3 + y) as u8;
            }
        }
        px
    }

    #[test]
    fn bilinear_sample_of_a_ramp_is_exact() {
        let px = ramp(64, 64);
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        // Centre (20.25, 10.5): the top-left sample of a 3x3 window is at (19.25, 9.5).
        let origin = WindowOrigin::new(20 * 65536 + 16384, 10 * 65536 + 32768, 1);
        let mut out = [0i16; 9];
        sample(&frame, &origin, 3, &mut out);
        let expected = (19.25 * 3.0 + 9.5) * 32.0;
        assert_eq!(out[0], expected as i16);
        assert_eq!(out[4], ((20.25 * 3.0 + 10.5) * 32.0) as i16);
    }

    #[test]
    fn clamped_path_repeats_the_edge() {
        let px = ramp(64, 64);
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        let origin = WindowOrigin::new(0, 0, 2);
        let mut out = [0i16; 25];
        sample(&frame, &origin, 5, &mut out);
        // Rows and columns -2 and -1 repeat row/column 0.
        assert_eq!(out[0], 0);
        assert_eq!(out[2], 0);
        assert_eq!(out[3], 3 * 32);
        assert_eq!(out[15], 32);
    }

    #[test]
    fn scharr_of_a_ramp_has_gain_32() {
        let px = ramp(64, 64);
        let frame = ImageView::packed(&px, 64, 64).unwrap();
        let origin = WindowOrigin::new(30 << 16, 30 << 16, 2);
        let mut patch = [0i16; 25];
        sample(&frame, &origin, 5, &mut patch);
        let (mut dx, mut dy) = ([0i16; 9], [0i16; 9]);
        scharr(&patch, 5, &mut dx, &mut dy);
        assert!(dx.iter().all(|&g| g == 3 * 32));
        assert!(dy.iter().all(|&g| g == 32));
    }
}
