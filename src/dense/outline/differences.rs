//! How well a motion explains a pixel: absolute differences between the previous frame and
//! the next sampled where the motion carries the pixel, row by row, and their 3 x 3 sums.
//!
//! Samples and differences are grey x 16 ([`SUB_BITS`]): the next frame is sampled bilinearly
//! in sixteenths of a pixel, and a whole-grey difference would throw those away.

use super::area::Area;
use crate::dense::motion::CameraMotion;
use crate::frame::ImageView;
use crate::q16::{q16_from_f32, Point};

/// Bits of a sample below the grey level: samples and differences are grey x 16.
pub(super) const SUB_BITS: u32 = 4;

/// A difference the camera cannot give: its sample lies outside the next frame. Above any
/// 3 x 3 sum of real differences (9 x 255 x 16 = 36 720), so any sum it enters is too.
pub(super) const UNKNOWN: u16 = u16::MAX;

/// Differences of row `y` (pixels `area.x - 1 ..= area.x + area.w`) between the previous frame
/// and the next sampled at the camera's flow, which is evaluated at the row's two ends and
/// taken as linear between them; [`UNKNOWN`] where the sample leaves the next frame.
pub(super) fn camera_row(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    camera: &dyn CameraMotion,
    area: &Area,
    y: usize,
    out: &mut [u16],
) {
    let first = area.x.saturating_sub(1);
    let last = area.x + area.w;
    let at = |x: usize| {
        let (dx, dy) = camera.flow_at(x as f32, y as f32);
        (flow_bits(dx), flow_bits(dy))
    };
    let ((x0, y0), (x1, y1)) = (at(first), at(last));
    let steps = (last - first).max(1) as i64;
    // Linear from one end's flow to the other's, Q16: both flows are below 2^30.
    let step = |a: i32, b: i32| ((i64::from(b) - i64::from(a)) / steps) as i32;
    let (sx, sy) = (step(x0, x1), step(y0, y1));
    let source = prev.row(y);
    let mut flow = (x0, y0);
    for (i, slot) in out.iter_mut().enumerate() {
        let x = first + i;
        if i > 0 {
            flow = (flow.0.saturating_add(sx), flow.1.saturating_add(sy));
        }
        *slot = match (source.get(x), sample(next, x, y, flow)) {
            (Some(&p), Some(q)) => (u32::from(p) << SUB_BITS).abs_diff(q) as u16,
            _ => UNKNOWN,
        };
    }
}

/// Differences of row `y` between the previous frame and the next sampled at one constant
/// flow; the largest difference where the sample leaves the next frame (the object cannot be
/// there).
pub(super) fn flow_row(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    area: &Area,
    y: usize,
    flow: Option<&Point>,
    out: &mut [u16],
) {
    let flow = flow.map_or((0, 0), |f| (f.x.to_bits(), f.y.to_bits()));
    let first = area.x.saturating_sub(1);
    let source = prev.row(y);
    for (i, slot) in out.iter_mut().enumerate() {
        let x = first + i;
        *slot = match (source.get(x), sample(next, x, y, flow)) {
            (Some(&p), Some(q)) => (u32::from(p) << SUB_BITS).abs_diff(q) as u16,
            _ => 255 << SUB_BITS,
        };
    }
}

/// The previous frame's texture along row `y`: the absolute differences of each pixel to its
/// right and lower neighbours, summed, grey x 16. It is what a one-pixel misalignment costs,
/// so a flow must match clearly better than it to claim a pixel.
pub(super) fn texture_row(prev: &ImageView<'_>, area: &Area, y: usize, out: &mut [u16]) {
    let first = area.x - 1;
    let (here, below) = (prev.row(y), prev.row(y + 1));
    for (i, slot) in out.iter_mut().enumerate() {
        let x = first + i;
        let p = here.get(x).map_or(0, |&v| i32::from(v));
        let right = here.get(x + 1).map_or(p, |&v| i32::from(v));
        let down = below.get(x).map_or(p, |&v| i32::from(v));
        // At most 2 x 255 x 16 < 2^16.
        *slot = (((right - p).unsigned_abs() + (down - p).unsigned_abs()) << SUB_BITS) as u16;
    }
}

/// The 3 x 3 sums of the `w` pixels of a row from its three rows of differences (`w + 2`
/// each, in any order: a sum does not care), saturated at [`UNKNOWN`], given to `out` by
/// column.
pub(super) fn sums3(rows: &[u16], w: usize, mut out: impl FnMut(usize, u16)) {
    let len = w + 2;
    // Callers pass three rows of `w + 2` (checked where the ring and the camera's costs are
    // laid out); on fewer, `out` is not called and the callers' rows keep their fill.
    debug_assert!(rows.len() >= 3 * len, "sums3: {} < 3 x {len}", rows.len());
    let (Some(a), Some(b), Some(c)) = (
        rows.get(..len),
        rows.get(len..2 * len),
        rows.get(2 * len..3 * len),
    ) else {
        return;
    };
    let column = |x: usize| u32::from(a[x]) + u32::from(b[x]) + u32::from(c[x]);
    let (mut left, mut middle) = (column(0), column(1));
    for x in 0..w {
        let right = column(x + 2);
        out(x, (left + middle + right).min(u32::from(UNKNOWN)) as u16);
        (left, middle) = (middle, right);
    }
}

/// The sum of absolute differences, grey x 16, between the 3 x 3 neighbourhood of (`x`, `y`)
/// in `prev` and the one `shift` away from it in `next`; the largest sum where that one is
/// not wholly inside `next`.
pub(super) fn sad3(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    (x, y): (usize, usize),
    (dx, dy): (i32, i32),
) -> u32 {
    const OUTSIDE: u32 = 9 * (255 << SUB_BITS);
    let (px, py) = (x as isize - 1, y as isize - 1);
    let (Some(a), Some(b)) = (
        prev.block(px, py, 3, 3),
        next.block(px + dx as isize, py + dy as isize, 3, 3),
    ) else {
        return OUTSIDE;
    };
    let (sa, sb) = (prev.stride(), next.stride());
    let mut sum = 0u32;
    for r in 0..3 {
        for c in 0..3 {
            let (p, q) = (a.get(r * sa + c), b.get(r * sb + c));
            sum += p.zip(q).map_or(255, |(&p, &q)| u32::from(p.abs_diff(q)));
        }
    }
    sum << SUB_BITS
}

/// The next frame at (`x`, `y`) moved by `flow` (Q16), bilinear in sixteenths of a pixel,
/// grey x 16; `None` when the four pixels are not all inside.
pub(super) fn sample(
    next: &ImageView<'_>,
    x: usize,
    y: usize,
    (fx, fy): (i32, i32),
) -> Option<u32> {
    let px = (x as i64) * 65_536 + i64::from(fx);
    let py = (y as i64) * 65_536 + i64::from(fy);
    let (ix, iy) = (
        usize::try_from(px >> 16).ok()?,
        usize::try_from(py >> 16).ok()?,
    );
    let (ax, ay) = (((px >> 12) & 15) as u32, ((py >> 12) & 15) as u32);
    let top = next.row(iy);
    let bottom = next.row(iy + 1);
    let (a, b) = (u32::from(*top.get(ix)?), u32::from(*top.get(ix + 1)?));
    let (c, d) = (u32::from(*bottom.get(ix)?), u32::from(*bottom.get(ix + 1)?));
    let upper = a * (16 - ax) + b * ax;
    let lower = c * (16 - ax) + d * ax;
    // Weights in 256ths: (upper (16 - ay) + lower ay) / 256 grey, x 16 after >> 4.
    Some((upper * (16 - ay) + lower * ay + 8) >> 4)
}

/// A flow in pixels as Q16 bits; NaN or a flow beyond the frame's reach gives 0 (no motion).
pub(super) fn flow_bits(v: f32) -> i32 {
    if v.is_finite() && v.abs() < 16_384.0 {
        q16_from_f32(v).to_bits()
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_is_above_every_sum_of_nine_differences() {
        // The widest difference, 255 grey x 16, nine times.
        assert!(9 * (255u32 << SUB_BITS) < u32::from(UNKNOWN));
    }
}
