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
//! {left, right} pass with the same sign the pixel cannot be a corner. The survivors get the
//! exact segment test on bit masks, and only real corners are scored, over the arcs that pass.
//! Once the output is full, the threshold is raised to the weakest kept corner's score: weaker
//! corners could not be kept, nor suppress one that is.
//!
//! Cost on a Cortex-M4 (instructions counted under QEMU) at 160 x 120: about 0.5-0.6 M for a
//! frame without texture, 0.8-3.3 M on synthetic textures that are corners almost everywhere
//! (threshold 80 down to 10, 100 corners kept). Run it on a pyramid level or a [`Region`] when
//! that is too much.
//!
//! Non-maximum suppression keeps a corner only when its score is strictly higher than the score
//! of each of its 8 neighbours that is a corner, like OpenCV. (OpenCV gives non-corners and
//! corners of score 0 the same value, so at threshold 0 it drops every score-0 corner; here a
//! score-0 corner with no corner next to it is kept.) It needs three rows of one byte per pixel,
//! see [`fast_scratch_len`]. The 3-pixel frame border, where the circle does not fit, is never a
//! corner.

use super::{Corner, ExclusionMask, Region, StrongestCorners};
use crate::frame::ImageView;
use crate::ConfigError;

/// Pixels at the frame edge where the circle does not fit.
pub const FAST_BORDER: usize = 3;

/// Bytes of scratch [`Fast::detect`] needs with non-maximum suppression on frames `width` pixels
/// wide: three rows of one byte per pixel.
///
/// ```
/// use kestrel::detect::fast_scratch_len;
/// static mut SCRATCH: [u8; fast_scratch_len(160)] = [0; fast_scratch_len(160)];
/// assert_eq!(fast_scratch_len(160), 480);
/// ```
pub const fn fast_scratch_len(width: usize) -> usize {
    width.saturating_mul(3)
}

/// FAST-9 corners (Rosten & Drummond): a pixel is a corner when 9 contiguous pixels of the
/// 16-pixel circle of radius 3 around it are all brighter than it by more than `threshold`, or
/// all darker; its score is the largest threshold at which it still is (OpenCV's
/// `cornerScore<16>`). The cheap detector: most pixels are rejected after two or four reads.
/// On a Cortex-M4 at 160 x 120 it costs about 0.5-0.6 M instructions on a frame without
/// texture and 0.8-3.3 M on synthetic textures that are corners almost everywhere; run it on a
/// pyramid level or a [`Region`] when that is too much. The 3-pixel frame border is never a
/// corner.
///
/// ```
/// use kestrel::detect::{fast_scratch_len, Fast};
/// use kestrel::detect::{Corner, Region};
/// use kestrel::ImageView;
///
/// // Three bright dots on a grey frame, of contrast 200, 70 and 5.
/// let mut pixels = [50u8; 32 * 16];
/// (pixels[8 * 32 + 6], pixels[8 * 32 + 16], pixels[8 * 32 + 26]) = (250, 120, 55);
/// let image = ImageView::packed(&pixels, 32, 16).unwrap();
/// let corners = |threshold| {
///     let fast = Fast { threshold, ..Fast::default() };
///     let mut out = [Corner::default(); 8];
///     fast.detect(&image, Region::full(&image), None, &mut [0u8; fast_scratch_len(32)], &mut out)
/// };
/// // A larger threshold keeps fewer corners.
/// assert_eq!(corners(0), Ok(3));
/// assert_eq!(corners(Fast::default().threshold), Ok(2));
/// assert_eq!(corners(100), Ok(1));
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
    /// `threshold`. `scratch` must hold [`fast_scratch_len`]`(image.width())` bytes when `nonmax` is
    /// set and may be empty otherwise (a shorter one is refused, as `"scratch"`). An empty
    /// region or output gives `Ok(0)`.
    ///
    /// ```
    /// use kestrel::detect::{fast_scratch_len, Fast};
    /// use kestrel::detect::{Corner, Region};
    /// use kestrel::ImageView;
    ///
    /// // Three bright dots on a grey frame; the faintest is below the threshold.
    /// let mut pixels = [50u8; 32 * 16];
    /// pixels[8 * 32 + 6] = 250; // (6, 8): contrast 200
    /// pixels[8 * 32 + 16] = 120; // (16, 8): contrast 70
    /// pixels[8 * 32 + 26] = 55; // (26, 8): contrast 5
    /// let image = ImageView::packed(&pixels, 32, 16).unwrap();
    /// let mut scratch = [0u8; fast_scratch_len(32)];
    /// let mut corners = [Corner::default(); 8];
    /// let n = Fast::default()
    ///     .detect(&image, Region::full(&image), None, &mut scratch, &mut corners)
    ///     .unwrap();
    /// assert_eq!(n, 2);
    /// assert_eq!((corners[0].pixel(), corners[0].score), ((6, 8), 199));
    /// assert_eq!((corners[1].pixel(), corners[1].score), ((16, 8), 69));
    ///
    /// let short = Fast::default().detect(&image, Region::full(&image), None, &mut [], &mut corners);
    /// assert_eq!(short.unwrap_err().to_string(), "scratch must hold at least 96 elements");
    /// ```
    pub fn detect(
        &self,
        image: &ImageView<'_>,
        region: Region,
        mask: Option<&ExclusionMask>,
        scratch: &mut [u8],
        out: &mut [Corner],
    ) -> Result<usize, ConfigError> {
        let needed = fast_scratch_len(image.width());
        if self.nonmax && scratch.len() < needed {
            return Err(ConfigError::min_len("scratch", needed));
        }
        let area = region.clip(image.width(), image.height(), FAST_BORDER);
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
            let threshold = sink.threshold(self.threshold);
            Rows::around(image, y).for_each_corner(area.x, area.right(), threshold, |x, rank| {
                sink.offer(x, y, rank)
            });
        }
    }

    /// The corners of `area` that are strict maxima of their 3 x 3 neighbourhood.
    ///
    /// Ranks are computed for `area` grown by one pixel (so that corners at the region's edge
    /// are compared with their neighbours outside it) into three rolling rows.
    // Per-pixel row loop: indices are bounded by the region, clipped to the frame once in
    // `detect`; see the crate's note on hot loops.
    #[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
    fn detect_nonmax(
        &self,
        image: &ImageView<'_>,
        area: Region,
        scratch: &mut [u8],
        sink: &mut Sink<'_, '_>,
    ) {
        let scored = area.grow_one(image.width(), image.height(), FAST_BORDER);
        let w = scored.width;
        // `detect` checked the scratch against fast_scratch_len, three rows of the frame's width,
        // and the scored area is inside the frame. Were it short, nothing is offered and
        // `detect` reports no corner rather than corners ranked from stale rows.
        let ring = scratch.get_mut(..3 * w);
        debug_assert!(ring.is_some(), "ring of 3 x {w} in a shorter scratch");
        let Some(ring) = ring else {
            return;
        };
        let (above, rest) = ring.split_at_mut(w);
        let (middle, below) = rest.split_at_mut(w);
        let (mut above, mut middle, mut below) = (above, middle, below);

        // The row above the scored area is off the frame's valid part: no corners there.
        above.fill(0);
        rank_row(image, scored.y, scored.x, self.threshold, middle);
        for y in scored.y..scored.bottom() {
            if y + 1 < scored.bottom() {
                let threshold = sink.threshold(self.threshold);
                rank_row(image, y + 1, scored.x, threshold, below);
            } else {
                below.fill(0);
            }
            if y >= area.y && y < area.bottom() {
                suppress_row(above, middle, below, scored.x, area, y, sink);
            }
            (above, middle, below) = (middle, below, above);
        }
    }
}

/// Ranks (score + 1, or 0 for "not a corner at `threshold`") of row `y`, columns
/// `x0..x0 + out.len()`.
// Per-pixel row loop: indices are bounded by the region, clipped to the frame once in
// `detect`; see the crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
fn rank_row(image: &ImageView<'_>, y: usize, x0: usize, threshold: u8, out: &mut [u8]) {
    out.fill(0);
    let x1 = x0 + out.len();
    Rows::around(image, y).for_each_corner(x0, x1, threshold, |x, rank| {
        if let Some(slot) = out.get_mut(x - x0) {
            *slot = rank;
        }
    });
}

/// Offers the strict local maxima of `middle` (row `y`) that lie in `area` to `sink`.
///
/// The three rows hold ranks of columns `x0..`; neighbours beyond their ends count as 0.
// Per-pixel row loop: indices are bounded by the region, clipped to the frame once in
// `detect`; see the crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
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
    let first = area.x - x0;
    // The rows span the scored area, which is `area` grown by one: `area` is inside them.
    let candidates = middle.get(first..area.right() - x0);
    debug_assert!(candidates.is_some(), "area {area:?} outside the ranked row");
    let Some(candidates) = candidates else {
        return;
    };
    for (i, &rank) in (first..).zip(candidates).filter(|&(_, &rank)| rank > 0) {
        let (left, right) = (i.checked_sub(1), Some(i + 1));
        let beaten = [left, Some(i), right].into_iter().any(|j| {
            at(above, j) >= rank || at(below, j) >= rank || (j != Some(i) && at(middle, j) >= rank)
        });
        if !beaten {
            sink.offer(x0 + i, y, rank);
        }
    }
}

/// Where detected corners go: through the mask into the strongest-corner collection.
struct Sink<'s, 'a> {
    best: &'s mut StrongestCorners<'a>,
    mask: Option<&'s ExclusionMask>,
}

impl Sink<'_, '_> {
    /// The threshold worth testing at: `threshold`, raised to the weakest kept corner's score
    /// once the output is full.
    ///
    /// A pixel scoring below that can neither be kept nor suppress a corner that is kept (which
    /// scores at least the final, higher bar), so treating it as no corner changes nothing and
    /// spares scoring it.
    fn threshold(&self, threshold: u8) -> u8 {
        match self.best.bar() {
            Some(weakest) => u8::try_from(weakest.score)
                .unwrap_or(u8::MAX)
                .max(threshold),
            None => threshold,
        }
    }

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

// Per-pixel row loop: indices are bounded by the region, clipped to the frame once in
// `detect`; see the crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
impl<'a> Rows<'a> {
    /// The rows around row `y`; rows off the frame are empty, which makes every pixel of row
    /// `y` a non-corner.
    fn around(image: &ImageView<'a>, y: usize) -> Self {
        Self(core::array::from_fn(|i| {
            match (y + i).checked_sub(FAST_BORDER) {
                Some(r) => image.row(r),
                None => &[],
            }
        }))
    }

    /// The centre and the 16 circle pixels of column `x`, or `None` when the circle does not
    /// fit in the frame.
    fn circle(&self, x: usize) -> Option<(u8, [u8; 16])> {
        let x0 = x.checked_sub(FAST_BORDER)?;
        let patch =
            |r: usize| -> Option<&[u8; 7]> { self.0.get(r)?.get(x0..x0 + 7)?.try_into().ok() };
        let (r0, r1, r2, r3) = (patch(0)?, patch(1)?, patch(2)?, patch(3)?);
        let (r4, r5, r6) = (patch(4)?, patch(5)?, patch(6)?);
        // Clockwise from the top; indices 0, 4, 8 and 12 are the compass points:
        //
        //           15  0  1
        //        14           2
        //     13                 3
        //     12        c        4
        //     11                 5
        //        10           6
        //            9  8  7
        let circle = [
            r0[3], r0[4], r1[5], r2[6], r3[6], r4[6], r5[5], r6[4], //
            r6[3], r6[2], r5[1], r4[0], r3[0], r2[0], r1[1], r0[2],
        ];
        Some((r3[3], circle))
    }

    /// Calls `found(x, rank)` for each corner at `threshold` in columns `x0..x1`, where `rank` is
    /// its score + 1.
    ///
    /// The loop only reads the centre and the four compass points of its circle, which rejects
    /// most pixels; the rest of the test is out of line so that this loop stays small.
    fn for_each_corner(
        &self,
        x0: usize,
        x1: usize,
        threshold: u8,
        mut found: impl FnMut(usize, u8),
    ) {
        let [top, _, _, mid, _, _, bottom] = &self.0;
        // `around[i]` and `around[i + 6]` are the left and right compass points of column x0 + i.
        let around = x0
            .checked_sub(FAST_BORDER)
            .and_then(|l| mid.get(l..x1 + FAST_BORDER));
        let (Some(top), Some(mid), Some(bottom), Some(around)) =
            (top.get(x0..x1), mid.get(x0..x1), bottom.get(x0..x1), around)
        else {
            // Rows off the frame are empty (see `around`), and a pixel whose circle leaves
            // the frame is no corner: the row has none. Not a fallback.
            return;
        };
        for (i, ((&c, &p0), &p8)) in mid.iter().zip(top).zip(bottom).enumerate() {
            let (bright_above, dark_below) =
                (c.saturating_add(threshold), c.saturating_sub(threshold));
            // v lies in dark_below..=bright_above exactly when v - dark_below (wrapping) does not
            // exceed the span: one compare per pixel for the common case of no contrast.
            let span = bright_above - dark_below;
            if p0.wrapping_sub(dark_below) <= span && p8.wrapping_sub(dark_below) <= span {
                continue;
            }
            // Bit 0: darker than c - t; bit 1: brighter than c + t. Saturation is exact here: a
            // pixel cannot be brighter than 255 or darker than 0.
            let class = |v: u8| u8::from(v < dark_below) | (u8::from(v > bright_above) << 1);
            let vertical = class(p0) | class(p8);
            let (Some(&p12), Some(&p4)) = (around.get(i), around.get(i + 6)) else {
                continue;
            };
            if vertical & (class(p4) | class(p12)) == 0 {
                continue;
            }
            let x = x0 + i;
            let rank = self.rank(x, c, threshold);
            if rank > 0 {
                found(x, rank);
            }
        }
    }

    /// Score + 1 of the pixel in column `x`, of value `c`, when it is a corner at `threshold`,
    /// else 0.
    #[inline(never)]
    fn rank(&self, x: usize, c: u8, threshold: u8) -> u8 {
        let (bright_above, dark_below) = (c.saturating_add(threshold), c.saturating_sub(threshold));
        let Some((_, circle)) = self.circle(x) else {
            return 0;
        };
        // The exact segment test on bit masks first: most pixels that pass the compass test
        // still fail, and scoring them would be wasted.
        let (mut brighter, mut darker) = (0u32, 0u32);
        for (k, &v) in circle.iter().enumerate() {
            brighter |= u32::from(v > bright_above) << k;
            darker |= u32::from(v < dark_below) << k;
        }
        // Two arcs of 9 out of 16 pixels overlap, so at most one sign passes, and the other
        // sign has no arc at all: the score comes from this sign alone, and from the arcs that
        // pass (any other arc has a pixel within the threshold).
        let bright_arcs = arc_starts(brighter);
        if bright_arcs != 0 {
            return best_arc_min(&circle.map(|v| v.saturating_sub(c)), bright_arcs);
        }
        let dark_arcs = arc_starts(darker);
        if dark_arcs != 0 {
            return best_arc_min(&circle.map(|v| c.saturating_sub(v)), dark_arcs);
        }
        0
    }
}

/// The starts of the runs of 9 contiguous set bits (wrapping around) in a 16-bit circle mask,
/// as a 16-bit mask.
fn arc_starts(mask: u32) -> u32 {
    let m = mask | (mask << 16);
    // After each step, bit k says that bits k.. of `m` are set for a run of 2, 4, 8, then 9.
    let run2 = m & (m >> 1);
    let run4 = run2 & (run2 >> 2);
    let run8 = run4 & (run4 >> 4);
    let run9 = run8 & (m >> 8);
    run9 & 0xFFFF
}

/// The largest, over the 16 arcs of 9 contiguous circle pixels and both signs, of the smallest
/// absolute difference between an arc pixel and the centre `c`: the FAST score plus one, or 0
/// when no arc is all brighter or all darker than the centre.
fn circle_rank(c: u8, circle: &[u8; 16]) -> u8 {
    let brighter = circle.map(|v| v.saturating_sub(c));
    let darker = circle.map(|v| c.saturating_sub(v));
    best_arc_min(&brighter, ALL_ARCS).max(best_arc_min(&darker, ALL_ARCS))
}

/// Every arc start, for [`best_arc_min`].
const ALL_ARCS: u32 = 0xFFFF;

/// Max, over the arcs of 9 starting at the set bits of `starts`, of the arc's minimum.
///
/// Detection passes only the arcs that clear the threshold, usually one to four, so this costs
/// a few dozen compares instead of the 144 of all arcs.
// `k + i` is masked to 0..16 and `rest` is non-zero where it is decremented.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
fn best_arc_min(v: &[u8; 16], starts: u32) -> u8 {
    let mut best = 0;
    let mut rest = starts & ALL_ARCS;
    while rest != 0 {
        let k = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        let arc_min = (0..9).fold(u8::MAX, |m, i| m.min(v[(k + i) & 15]));
        best = best.max(arc_min);
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
/// use kestrel::detect::fast9_score;
/// use kestrel::ImageView;
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
    let (c, circle) = Rows::around(image, y).circle(x)?;
    circle_rank(c, &circle).checked_sub(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Circle pixels `(x, y)` in a 7 x 7 patch centred on (3, 3), in the order `Rows::circle`
    /// reads them: clockwise from the top.
    const CIRCLE: [(usize, usize); 16] = [
        (3, 0),
        (4, 0),
        (5, 1),
        (6, 2),
        (6, 3),
        (6, 4),
        (5, 5),
        (4, 6),
        (3, 6),
        (2, 6),
        (1, 5),
        (0, 4),
        (0, 3),
        (0, 2),
        (1, 1),
        (2, 0),
    ];

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
            assert_eq!(best_arc_min(&v, ALL_ARCS), brute);
            // Restricted to the arcs that clear a threshold, the best is unchanged.
            for threshold in [0u8, 39, 40, 119, 200] {
                let mask = v
                    .iter()
                    .enumerate()
                    .fold(0u32, |m, (k, &d)| m | (u32::from(d > threshold) << k));
                let starts = arc_starts(mask);
                let expected = if brute > threshold { brute } else { 0 };
                assert_eq!(best_arc_min(&v, starts), expected);
            }
        }
    }

    #[test]
    fn arc_mask_test_matches_brute_force() {
        for mask in 0..=0xFFFFu32 {
            let brute = (0..16).any(|k| (0..9).all(|i| mask >> ((k + i) % 16) & 1 == 1));
            assert_eq!(arc_starts(mask) != 0, brute, "{mask:#06x}");
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
