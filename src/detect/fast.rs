//! FAST-9 corners (Rosten & Drummond, "Machine learning for high-speed corner detection").
//!
//! A pixel `p` is a corner when 9 contiguous pixels of the 16-pixel Bresenham circle of radius 3
//! around it are all brighter than `p + t` or all darker than `p - t` (strictly), for the
//! threshold `t`. Its score is the largest `t` for which it is still a corner: the best arc's
//! smallest absolute difference to `p`, minus one. This is OpenCV's `cornerScore<16>` and
//! `imageproc`'s `fast_corner_score`.
//!
//! Most pixels are rejected after two or four reads: an arc of 9 always covers two neighbouring
//! pixels of the four at the compass points, so unless one of {top, bottom} and one of
//! {left, right} pass with the same sign the pixel cannot be a corner.
//!
//! Non-maximum suppression keeps a corner only when its score is strictly higher than the score
//! of each of its 8 neighbours that is a corner, like OpenCV. (OpenCV gives non-corners and
//! corners of score 0 the same value, so at threshold 0 it drops every score-0 corner; here a
//! score-0 corner with no corner next to it is kept.) It needs three rows of one byte per pixel,
//! see [`scratch_len`]. The 3-pixel frame border, where the circle does not fit, is never a
//! corner.

use super::{Corner, DetectError, ExclusionMask, Region, StrongestCorners};
use crate::frame::ImageView;

/// Pixels at the frame edge where the circle does not fit.
pub const BORDER: usize = 3;

/// Circle offsets `(dx, dy)`, clockwise from the top; indices 0, 4, 8 and 12 are the compass
/// points.
const CIRCLE: [(usize, usize); 16] = {
    // Offsets are stored shifted by +3 so they index a 7 x 7 patch centred on the pixel.
    let d: [(i8, i8); 16] = [
        (0, -3),
        (1, -3),
        (2, -2),
        (3, -1),
        (3, 0),
        (3, 1),
        (2, 2),
        (1, 3),
        (0, 3),
        (-1, 3),
        (-2, 2),
        (-3, 1),
        (-3, 0),
        (-3, -1),
        (-2, -2),
        (-1, -3),
    ];
    let mut out = [(0usize, 0usize); 16];
    let mut i = 0;
    while i < 16 {
        out[i] = ((d[i].0 + 3) as usize, (d[i].1 + 3) as usize);
        i += 1;
    }
    out
};

/// Bytes of scratch [`Fast::detect`] needs with non-maximum suppression on frames `width` pixels
/// wide: three rows of one byte per pixel.
///
/// ```
/// use kestrel::detect::fast::scratch_len;
/// static mut SCRATCH: [u8; scratch_len(160)] = [0; scratch_len(160)];
/// assert_eq!(scratch_len(160), 480);
/// ```
pub const fn scratch_len(width: usize) -> usize {
    3 * width
}

/// FAST-9 detector settings.
///
/// ```
/// use kestrel::detect::fast::Fast;
/// let fast = Fast::default();
/// assert_eq!((fast.threshold, fast.nonmax), (10, true));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fast {
    /// Brightness difference, in grey levels, that circle pixels must exceed. 0 accepts any
    /// arc of 9 pixels that all differ from the centre in the same direction.
    pub threshold: u8,
    /// Keep only corners whose score is a strict local maximum over their 3 x 3 neighbourhood.
    pub nonmax: bool,
}

impl Default for Fast {
    /// OpenCV's `FastFeatureDetector` defaults: threshold 10, non-maximum suppression on.
    fn default() -> Self {
        Self {
            threshold: 10,
            nonmax: true,
        }
    }
}

impl Fast {
    /// Finds the corners of `image` inside `region` and outside `mask`, and writes the strongest
    /// `out.len()` of them to `out`, strongest first. Returns how many were written.
    ///
    /// The score of each [`Corner`] is its FAST score (see [`fast9_score`]), at least
    /// `threshold`. `scratch` must hold [`scratch_len`]`(image.width())` bytes when `nonmax` is
    /// set and may be empty otherwise. An empty region or output gives `Ok(0)`.
    ///
    /// ```
    /// use kestrel::detect::fast::{scratch_len, Fast};
    /// use kestrel::detect::{Corner, Region};
    /// use kestrel::frame::ImageView;
    ///
    /// // Three bright dots on a grey frame; the faintest is below the threshold.
    /// let mut pixels = [50u8; 32 * 16];
    /// pixels[8 * 32 + 6] = 250; // (6, 8): contrast 200
    /// pixels[8 * 32 + 16] = 120; // (16, 8): contrast 70
    /// pixels[8 * 32 + 26] = 55; // (26, 8): contrast 5
    /// let image = ImageView::packed(&pixels, 32, 16).unwrap();
    /// let mut scratch = [0u8; scratch_len(32)];
    /// let mut corners = [Corner::default(); 8];
    /// let n = Fast::default()
    ///     .detect(&image, Region::full(&image), None, &mut scratch, &mut corners)
    ///     .unwrap();
    /// assert_eq!(n, 2);
    /// assert_eq!((corners[0].pixel(), corners[0].score), ((6, 8), 199));
    /// assert_eq!((corners[1].pixel(), corners[1].score), ((16, 8), 69));
    /// ```
    pub fn detect(
        &self,
        image: &ImageView<'_>,
        region: Region,
        mask: Option<&ExclusionMask>,
        scratch: &mut [u8],
        out: &mut [Corner],
    ) -> Result<usize, DetectError> {
        if self.nonmax && scratch.len() < scratch_len(image.width()) {
            return Err(DetectError::ScratchTooSmall);
        }
        let area = region.clip(image.width(), image.height(), BORDER);
        let mut best = StrongestCorners::new(out);
        if !area.is_empty() {
            let mut sink = Sink {
                best: &mut best,
                mask,
            };
            if self.nonmax {
                self.detect_nonmax(image, area, scratch, &mut sink);
            } else {
                self.detect_all(image, area, &mut sink);
            }
        }
        Ok(best.finish())
    }

    /// Every corner of `area`, without suppression.
    fn detect_all(&self, image: &ImageView<'_>, area: Region, sink: &mut Sink<'_, '_>) {
        for y in area.y..area.bottom() {
            let rows = Rows::around(image, y);
            for x in area.x..area.right() {
                let rank = rows.rank(x, self.threshold);
                if rank > 0 {
                    sink.offer(x, y, rank);
                }
            }
        }
    }

    /// The corners of `area` that are strict maxima of their 3 x 3 neighbourhood.
    ///
    /// Ranks are computed for `area` grown by one pixel (so that corners at the region's edge
    /// are compared with their neighbours outside it) into three rolling rows.
    fn detect_nonmax(
        &self,
        image: &ImageView<'_>,
        area: Region,
        scratch: &mut [u8],
        sink: &mut Sink<'_, '_>,
    ) {
        let scored = area.grow_one(image.width(), image.height(), BORDER);
        let w = scored.width;
        let Some(ring) = scratch.get_mut(..3 * w) else {
            return;
        };
        let (above, rest) = ring.split_at_mut(w);
        let (middle, below) = rest.split_at_mut(w);
        let (mut above, mut middle, mut below) = (above, middle, below);

        // The row above the scored area is off the frame's valid part: no corners there.
        above.fill(0);
        self.rank_row(image, scored.y, scored.x, middle);
        for y in scored.y..scored.bottom() {
            if y + 1 < scored.bottom() {
                self.rank_row(image, y + 1, scored.x, below);
            } else {
                below.fill(0);
            }
            if y >= area.y && y < area.bottom() {
                suppress_row(above, middle, below, scored.x, area, y, sink);
            }
            (above, middle, below) = (middle, below, above);
        }
    }

    /// Ranks (score + 1, or 0 for "not a corner") of row `y`, columns `x0..x0 + out.len()`.
    fn rank_row(&self, image: &ImageView<'_>, y: usize, x0: usize, out: &mut [u8]) {
        let rows = Rows::around(image, y);
        for (x, rank) in (x0..).zip(out.iter_mut()) {
            *rank = rows.rank(x, self.threshold);
        }
    }
}

/// Offers the strict local maxima of `middle` (row `y`) that lie in `area` to `sink`.
///
/// The three rows hold ranks of columns `x0..`; neighbours beyond their ends count as 0.
fn suppress_row(
    above: &[u8],
    middle: &[u8],
    below: &[u8],
    x0: usize,
    area: Region,
    y: usize,
    sink: &mut Sink<'_, '_>,
) {
    let at = |row: &[u8], i: Option<usize>| i.and_then(|i| row.get(i)).copied().unwrap_or(0);
    for x in area.x..area.right() {
        let i = x - x0;
        let rank = at(middle, Some(i));
        if rank == 0 {
            continue;
        }
        let (left, right) = (i.checked_sub(1), Some(i + 1));
        let beaten = [left, Some(i), right].into_iter().any(|j| {
            at(above, j) >= rank || at(below, j) >= rank || (j != Some(i) && at(middle, j) >= rank)
        });
        if !beaten {
            sink.offer(x, y, rank);
        }
    }
}

/// Where detected corners go: through the mask into the strongest-corner collection.
struct Sink<'s, 'a> {
    best: &'s mut StrongestCorners<'a>,
    mask: Option<&'s ExclusionMask>,
}

impl Sink<'_, '_> {
    /// Offers the corner at (`x`, `y`) of rank `rank` (score + 1, at least 1).
    fn offer(&mut self, x: usize, y: usize, rank: u8) {
        if self.mask.is_some_and(|m| m.is_excluded(x, y)) {
            return;
        }
        self.best
            .offer(Corner::new(x, y, u32::from(rank.saturating_sub(1))));
    }
}

/// The seven rows `y - 3 ..= y + 3` around a pixel row.
struct Rows<'a>([&'a [u8]; 7]);

impl<'a> Rows<'a> {
    /// The rows around row `y`; rows off the frame are empty, which makes every pixel of row
    /// `y` a non-corner.
    fn around(image: &ImageView<'a>, y: usize) -> Self {
        Self(core::array::from_fn(|i| {
            match (y + i).checked_sub(BORDER) {
                Some(r) => image.row(r),
                None => &[],
            }
        }))
    }

    /// The 7 x 7 patch centred on column `x`, or `None` when it does not fit in the frame.
    fn patch(&self, x: usize) -> Option<[[u8; 7]; 7]> {
        let x0 = x.checked_sub(BORDER)?;
        let mut patch = [[0u8; 7]; 7];
        for (dst, row) in patch.iter_mut().zip(self.0.iter()) {
            let src: &[u8; 7] = row.get(x0..x0 + 7)?.try_into().ok()?;
            *dst = *src;
        }
        Some(patch)
    }

    /// Score + 1 of the pixel in column `x` when it is a corner at `threshold`, else 0.
    fn rank(&self, x: usize, threshold: u8) -> u8 {
        let [top, _, _, mid, _, _, bottom] = &self.0;
        let (Some(&c), Some(&p0), Some(&p8)) = (mid.get(x), top.get(x), bottom.get(x)) else {
            return 0;
        };
        let bright_above = c.saturating_add(threshold);
        let dark_below = c.saturating_sub(threshold);
        // Bit 0: darker than c - t; bit 1: brighter than c + t. Saturation is exact here: a
        // pixel cannot be brighter than 255 or darker than 0.
        let class = |v: u8| u8::from(v < dark_below) | (u8::from(v > bright_above) << 1);
        let vertical = class(p0) | class(p8);
        if vertical == 0 {
            return 0;
        }
        let (Some(&p4), Some(&p12)) = (mid.get(x + 3), x.checked_sub(3).and_then(|l| mid.get(l)))
        else {
            return 0;
        };
        if vertical & (class(p4) | class(p12)) == 0 {
            return 0;
        }
        let Some(patch) = self.patch(x) else {
            return 0;
        };
        let rank = circle_rank(&patch);
        if rank > threshold {
            rank
        } else {
            0
        }
    }
}

/// The largest, over the 16 arcs of 9 contiguous circle pixels and both signs, of the smallest
/// absolute difference between an arc pixel and the centre: the FAST score plus one, or 0 when no
/// arc is all brighter or all darker than the centre.
fn circle_rank(patch: &[[u8; 7]; 7]) -> u8 {
    let [_, _, _, [_, _, _, c, _, _, _], _, _, _] = *patch;
    let mut brighter = [0u8; 16];
    let mut darker = [0u8; 16];
    for ((b, d), &(dx, dy)) in brighter
        .iter_mut()
        .zip(darker.iter_mut())
        .zip(CIRCLE.iter())
    {
        let v = patch
            .get(dy)
            .and_then(|row| row.get(dx))
            .copied()
            .unwrap_or(c);
        *b = v.saturating_sub(c);
        *d = c.saturating_sub(v);
    }
    best_arc_min(&brighter).max(best_arc_min(&darker))
}

/// Max over the 16 circular windows of 9 of the window minimum.
///
/// Windows starting at `k` and `k + 1` (k even) share the 8 values `k + 1 ..= k + 8`, so each pair
/// costs one 8-value minimum and two compares, as in OpenCV.
fn best_arc_min(v: &[u8; 16]) -> u8 {
    let mut best = 0;
    for k in (0..16).step_by(2) {
        let shared = (1..=8).fold(u8::MAX, |m, i| m.min(v[(k + i) & 15]));
        let first = shared.min(v[k & 15]);
        let second = shared.min(v[(k + 9) & 15]);
        best = best.max(first).max(second);
    }
    best
}

/// The FAST-9 score of pixel (`x`, `y`): the largest threshold at which it is a corner, or `None`
/// when it is not a corner even at threshold 0 or lies within 3 px of the frame edge.
///
/// A pixel is reported by [`Fast::detect`] at threshold `t` (before suppression) exactly when
/// its score is at least `t`.
///
/// ```
/// use kestrel::detect::fast::fast9_score;
/// use kestrel::frame::ImageView;
///
/// // A dark pixel at the tip of a bright wedge: the 9 circle pixels to its right are 100,
/// // the others 50, the centre 40. Darkest arc pixel minus the centre is 60, so the score is 59.
/// let mut pixels = [50u8; 7 * 7];
/// pixels[3 * 7 + 3] = 40;
/// for &(x, y) in &[(3, 0), (4, 0), (5, 1), (6, 2), (6, 3), (6, 4), (5, 5), (4, 6), (3, 6)] {
///     pixels[y * 7 + x] = 100;
/// }
/// let image = ImageView::packed(&pixels, 7, 7).unwrap();
/// assert_eq!(fast9_score(&image, 3, 3), Some(59));
/// assert_eq!(fast9_score(&image, 2, 3), None);
/// ```
pub fn fast9_score(image: &ImageView<'_>, x: usize, y: usize) -> Option<u8> {
    if x >= image.width() || y >= image.height() {
        return None;
    }
    match Rows::around(image, y).patch(x).map(|p| circle_rank(&p)) {
        Some(rank) if rank > 0 => Some(rank - 1),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes `values` onto the circle around the centre of a 7 x 7 patch of `background`.
    fn ring(center: u8, background: u8, values: [u8; 16]) -> [u8; 49] {
        let mut px = [background; 49];
        px[3 * 7 + 3] = center;
        for (&(dx, dy), v) in CIRCLE.iter().zip(values) {
            px[dy * 7 + dx] = v;
        }
        px
    }

    /// A circle whose pixels `start..start + len` (mod 16) are `arc`, the rest `other`.
    fn arc(start: usize, len: usize, arc: u8, other: u8) -> [u8; 16] {
        core::array::from_fn(|i| {
            if (i + 16 - start) % 16 < len {
                arc
            } else {
                other
            }
        })
    }

    fn score(px: &[u8; 49]) -> Option<u8> {
        fast9_score(&ImageView::packed(px, 7, 7).unwrap(), 3, 3)
    }

    #[test]
    fn nine_contiguous_is_a_corner_eight_is_not() {
        for start in 0..16 {
            let nine = ring(100, 100, arc(start, 9, 160, 100));
            let eight = ring(100, 100, arc(start, 8, 160, 100));
            assert_eq!(score(&nine), Some(59), "start {start}");
            assert_eq!(score(&eight), None, "start {start}");
            let dark = ring(100, 100, arc(start, 9, 30, 100));
            assert_eq!(score(&dark), Some(69), "start {start}");
        }
    }

    #[test]
    fn score_is_the_largest_threshold_that_still_detects() {
        // An arc of 9 with contrasts 30..=41 (min 30) and the rest at +25: the whole ring
        // (min 25) is beaten by the arc, so the score is 29.
        let mut values = [125u8; 16];
        for (i, v) in values.iter_mut().enumerate().skip(3).take(9) {
            *v = 130 + i as u8;
        }
        values[7] = 130;
        let px = ring(100, 100, values);
        assert_eq!(score(&px), Some(29));
        let image = ImageView::packed(&px, 7, 7).unwrap();
        for t in [0u8, 10, 28, 29, 30, 31, 255] {
            let mut out = [Corner::default(); 4];
            let fast = Fast {
                threshold: t,
                nonmax: false,
            };
            let n = fast
                .detect(&image, Region::full(&image), None, &mut [], &mut out)
                .unwrap();
            assert_eq!(n, usize::from(t <= 29), "threshold {t}");
        }
    }

    #[test]
    fn mixed_signs_do_not_form_an_arc() {
        // 9 contiguous pixels all differ by 50, but alternately brighter and darker.
        let values: [u8; 16] = core::array::from_fn(|i| if i % 2 == 0 { 150 } else { 50 });
        assert_eq!(score(&ring(100, 100, values)), None);
    }

    #[test]
    fn extreme_contrast_saturates_cleanly() {
        assert_eq!(score(&ring(0, 0, arc(5, 9, 255, 0))), Some(254));
        assert_eq!(score(&ring(255, 255, arc(5, 9, 0, 255))), Some(254));
        // A 16-pixel ring of 255 around 0: every arc qualifies.
        assert_eq!(score(&ring(0, 0, [255; 16])), Some(254));
    }

    #[test]
    fn best_arc_min_matches_brute_force() {
        let mut seed = 0x1234_5678u32;
        for _ in 0..2000 {
            let v: [u8; 16] = core::array::from_fn(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                (seed % 7) as u8 * 40
            });
            let brute = (0..16)
                .map(|k| (0..9).map(|i| v[(k + i) % 16]).min().unwrap())
                .max()
                .unwrap();
            assert_eq!(best_arc_min(&v), brute);
        }
    }

    #[test]
    fn pixels_near_the_border_are_never_corners() {
        let px = ring(100, 100, arc(0, 9, 200, 100));
        let image = ImageView::packed(&px, 7, 7).unwrap();
        for y in 0..7 {
            for x in 0..7 {
                assert_eq!(fast9_score(&image, x, y).is_some(), (x, y) == (3, 3));
            }
        }
        assert_eq!(fast9_score(&image, 70, 3), None);
    }
}
