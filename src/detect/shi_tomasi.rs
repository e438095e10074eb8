//! Shi-Tomasi corners ("Good features to track"): the minimum eigenvalue of the structure tensor.
//!
//! For each pixel, the gradients `gx`, `gy` of a 3 x 3 Sobel filter are summed over a
//! `block` x `block` square around it into the structure tensor
//! `A = [Σgx² Σgxgy; Σgxgy Σgy²]`, and its smaller eigenvalue
//! `λmin = (a11 + a22)/2 - sqrt(((a11 - a22)/2)² + a12²)` says how well a window there can be
//! tracked: LK inverts the same matrix. This is OpenCV's `goodFeaturesToTrack` with its defaults
//! (Sobel 3 x 3, block 3).
//!
//! # Score scale
//!
//! The score of a corner is `floor(2 λmin)`, computed exactly in integers
//! (`a11 + a22 - ceil(sqrt((a11 - a22)² + 4 a12²))`). Sobel gradients have a gain of 8 per grey
//! level per pixel (|g| <= 1020): a 3 x 3 block whose gradients are (8, 0) at six pixels and
//! (0, 8) at three has `a11 = 384`, `a22 = 192`, `a12 = 0`, so `λmin = 192` and the score is 384;
//! a straight edge or a ramp scores 0. OpenCV's `cornerMinEigenVal` value is
//! `score / (2 (4 · block · 255)²)` away from the border.
//!
//! # Integer widths
//!
//! `|g| <= 4 · 255 = 1020`, so a product is at most 1 040 400 < 2^20, and a block sum at most
//! `7² · 1 040 400 = 50 979 600 < 2^26`: the tensor entries fit `i32` with room to spare.
//! `a11 + a22 < 2^27`; `(a11 - a22)² + 4 a12² <= (a11 + a22)² < 2^54` (Cauchy-Schwarz gives
//! `a12² <= a11 a22`), so the discriminant fits `u64`, and its root `u32`.
//!
//! # Memory and cost
//!
//! No score image is stored: per-column sums of the tensor over the `block` rows around the
//! current row are slid down the frame (adding the entering row's products, subtracting the
//! leaving row's), and scores live in three rolling rows for the 3 x 3 non-maximum suppression,
//! `6 · width` words in all (see [`shi_tomasi_scratch_len`]). The strongest local maxima go straight into
//! the caller's output slice (a min-heap while scanning); once it is full, a pixel whose score
//! cannot beat the weakest kept corner is recognised without a square root
//! (`score >= c` iff `a11 + a22 - c >= 0` and `(a11 + a22 - c)² >= disc`) and stored as 0. That
//! never changes the result: such a pixel could neither be kept nor suppress a kept one.
//!
//! After the scan, the quality level (relative to the strongest corner found) and the minimum
//! distance are applied to the kept corners, strongest first, like OpenCV.
//!
//! The Sobel filter is applied separably and the block sums slide along the row, so a pixel
//! costs about 115 Cortex-M4 instructions (two gradient rows, the block sum and the
//! square-root-free test): 2.2 M at 160 x 120 without texture, 3.3-3.5 M on dense synthetic
//! textures with block 3 and 100 corners kept (counted under QEMU). At 80 x 60 (pyramid level 1)
//! that is a quarter.

use super::{Corner, ExclusionMask, Region, StrongestCorners};
use crate::config_error::bound_number;
use crate::frame::ImageView;
use crate::{Bound, ConfigError};

/// The largest block side accepted.
pub const MAX_BLOCK: usize = 7;

/// Cells per side of the grid that enforces the minimum distance.
const DISTANCE_GRID: usize = 16;

/// `i32` words of scratch [`ShiTomasi::detect`] needs on frames `width` pixels wide with an output
/// of `capacity` corners: the larger of the scan's `6 · width` and the minimum-distance grid's
/// `256 + capacity`.
///
/// ```
/// use kestrel::detect::shi_tomasi_scratch_len;
/// static mut SCRATCH: [i32; shi_tomasi_scratch_len(160, 100)] = [0; shi_tomasi_scratch_len(160, 100)];
/// assert_eq!(shi_tomasi_scratch_len(160, 100), 960);
/// assert_eq!(shi_tomasi_scratch_len(32, 500), 756);
/// ```
pub const fn shi_tomasi_scratch_len(width: usize, capacity: usize) -> usize {
    let scan = width.saturating_mul(6);
    let distance = (DISTANCE_GRID * DISTANCE_GRID).saturating_add(capacity);
    if scan > distance {
        scan
    } else {
        distance
    }
}

/// Shi-Tomasi corners ("Good features to track"): each pixel scored by the smaller eigenvalue
/// of the structure tensor of 3 x 3 Sobel gradients summed over a `block` x `block` square,
/// the matrix LK inverts, so the corners LK tracks best. This is OpenCV's
/// `goodFeaturesToTrack` with its defaults; the score of a corner is `floor(2 λmin)`, exact in
/// integers (OpenCV's `cornerMinEigenVal` is `score / (2 (4 · block · 255)²)`). A pixel costs
/// about 115 Cortex-M4 instructions: 2.2 M at 160 x 120 without texture, 3.3-3.5 M on dense
/// synthetic textures (block 3, 100 corners kept); a quarter of that on pyramid level 1.
///
/// ```
/// use kestrel::detect::{shi_tomasi_scratch_len, ShiTomasi};
/// use kestrel::detect::{Corner, Region};
/// use kestrel::ImageView;
///
/// // A bright 12 x 12 square on a dark frame: its corners are about 11 px apart.
/// let pixels: [u8; 32 * 32] = core::array::from_fn(|i| {
///     let (x, y) = (i % 32, i / 32);
///     if (10..22).contains(&x) && (10..22).contains(&y) { 200 } else { 20 }
/// });
/// let image = ImageView::packed(&pixels, 32, 32).unwrap();
/// let corners = |min_distance| {
///     let st = ShiTomasi { min_distance, ..ShiTomasi::default() };
///     let mut out = [Corner::default(); 16];
///     st.detect(&image, Region::full(&image), None, &mut [0i32; shi_tomasi_scratch_len(32, 16)], &mut out)
/// };
/// assert_eq!(corners(ShiTomasi::default().min_distance), Ok(4));
/// // Beyond the square's diagonal, one corner is left.
/// assert_eq!(corners(20), Ok(1));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ShiTomasi {
    /// Side of the square the gradients are summed over: odd, `3..=7`.
    pub block: usize,
    /// Corners scoring `quality_level` times the strongest corner's score or less are dropped
    /// (OpenCV's `qualityLevel`), in `0.0..=1.0`; 0 keeps every corner with a positive score.
    pub quality_level: f32,
    /// Corners closer than this many pixels (Euclidean) to a stronger kept corner are dropped;
    /// 0 keeps them all.
    pub min_distance: u16,
}

impl Default for ShiTomasi {
    /// Block 3 and quality level 0.01 as in OpenCV; a minimum distance of 10 px.
    fn default() -> Self {
        Self {
            block: 3,
            quality_level: 0.01,
            min_distance: 10,
        }
    }
}

impl ShiTomasi {
    /// Finds the corners of `image` inside `region` and outside `mask`, writes the strongest
    /// of them to `out`, strongest first, and returns how many were written.
    ///
    /// Corners are the 3 x 3 local maxima of the score (ties all kept, like OpenCV) with a
    /// positive score. The `out.len()` strongest are kept, then the quality level and the
    /// minimum distance are applied to them, so `out` is both the candidate buffer and the
    /// result: with a large minimum distance give it room for more corners than needed and
    /// use a prefix. `scratch` must hold [`shi_tomasi_scratch_len`]`(image.width(), out.len())` words.
    /// Pixels within `block / 2 + 1` of the frame edge are never corners.
    ///
    /// ```
    /// use kestrel::detect::{shi_tomasi_scratch_len, ShiTomasi};
    /// use kestrel::detect::{Corner, Region};
    /// use kestrel::ImageView;
    ///
    /// // A bright 12 x 12 square on a dark 32 x 32 frame: one corner near each of its corners.
    /// let pixels: [u8; 32 * 32] = core::array::from_fn(|i| {
    ///     let (x, y) = (i % 32, i / 32);
    ///     if (10..22).contains(&x) && (10..22).contains(&y) { 200 } else { 20 }
    /// });
    /// let image = ImageView::packed(&pixels, 32, 32).unwrap();
    /// let mut scratch = [0i32; shi_tomasi_scratch_len(32, 16)];
    /// let mut corners = [Corner::default(); 16];
    /// let n = ShiTomasi::default()
    ///     .detect(&image, Region::full(&image), None, &mut scratch, &mut corners)
    ///     .unwrap();
    /// assert_eq!(n, 4);
    /// for c in &corners[..n] {
    ///     let (x, y) = c.pixel();
    ///     assert!((x == 10 || x == 21) && (y == 10 || y == 21), "{x} {y}");
    /// }
    /// ```
    pub fn detect(
        &self,
        image: &ImageView<'_>,
        region: Region,
        mask: Option<&ExclusionMask>,
        scratch: &mut [i32],
        out: &mut [Corner],
    ) -> Result<usize, ConfigError> {
        let (reach, quality) = self.checked()?;
        let needed = shi_tomasi_scratch_len(image.width(), out.len());
        if scratch.len() < needed {
            return Err(ConfigError::min_len("scratch", needed));
        }
        let area = region.clip(image.width(), image.height(), reach.saturating_add(1));
        if area.is_empty() || out.is_empty() {
            return Ok(0);
        }
        let mut best = StrongestCorners::new(out);
        let scan = Scan {
            image,
            reach,
            area,
            mask,
        };
        scan.run(scratch, &mut best);
        // `best` fills `out` from its start and counts what it wrote, and `above_quality` keeps
        // a prefix of those: both ranges are inside `out`.
        let found = best.finish();
        debug_assert!(found <= out.len(), "{found} corners in {} slots", out.len());
        let kept = above_quality(out.get(..found).unwrap_or(&[]), quality);
        debug_assert!(kept <= found);
        let spaced = space_out(
            out.get_mut(..kept).unwrap_or(&mut []),
            self.min_distance,
            image,
            scratch,
        );
        Ok(spaced)
    }

    /// Checks the settings without detecting anything, so that a configuration can be refused
    /// when it is made rather than on the first frame; a refusal names `"block"` or
    /// `"quality_level"`.
    ///
    /// ```
    /// use kestrel::detect::ShiTomasi;
    /// use kestrel::{Bound, ConfigError};
    /// assert_eq!(ShiTomasi::default().validate(), Ok(()));
    /// let even = ShiTomasi { block: 4, ..ShiTomasi::default() };
    /// let refused = even.validate().unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "block", bound: Bound::OddRange { min: 3, max: 7 } });
    /// assert_eq!(refused.to_string(), "block must be odd, 3 to 7");
    /// let over = ShiTomasi { quality_level: 1.5, ..ShiTomasi::default() };
    /// assert_eq!(over.validate().unwrap_err().to_string(), "quality_level must be 0 to 1");
    /// ```
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.checked().map(|_| ())
    }

    /// `block / 2` and the quality level in Q16, or why the settings are refused.
    fn checked(&self) -> Result<(usize, u64), ConfigError> {
        let block = Bound::OddRange {
            min: 3,
            max: bound_number(MAX_BLOCK),
        };
        let reach = block_reach(self.block).ok_or(ConfigError::new("block", block))?;
        let quality = Bound::Range { min: 0, max: 1 };
        let quality =
            quality_q16(self.quality_level).ok_or(ConfigError::new("quality_level", quality))?;
        Ok((reach, quality))
    }
}

/// `block / 2` for a valid block side, `None` otherwise.
fn block_reach(block: usize) -> Option<usize> {
    if block % 2 == 1 && (3..=MAX_BLOCK).contains(&block) {
        Some(block / 2)
    } else {
        None
    }
}

/// The quality level as a fraction of 2^16, rounded; `None` when outside `0.0..=1.0` or NaN.
fn quality_q16(level: f32) -> Option<u64> {
    if (0.0..=1.0).contains(&level) {
        // In 0.0..=65536.5: the cast is exact after rounding.
        #[allow(clippy::cast_possible_truncation)]
        Some((level * 65536.0 + 0.5) as u64)
    } else {
        None
    }
}

/// How many of the strongest-first `corners` score above `quality` (Q16) times the first one.
fn above_quality(corners: &[Corner], quality: u64) -> usize {
    let Some(strongest) = corners.first() else {
        return 0;
    };
    // score < 2^27 and quality <= 2^16: both products fit u64.
    let bar = u64::from(strongest.score).saturating_mul(quality);
    corners
        .iter()
        .take_while(|c| (u64::from(c.score) << 16) > bar)
        .count()
}

/// Keeps, strongest first, the corners at least `min_distance` px from every stronger kept one,
/// moving them to the front of `corners`; returns how many there are.
///
/// Kept corners are chained per cell of a grid whose cells are at least `min_distance` wide, so
/// only the 3 x 3 cells around a corner are searched. `scratch` holds the chain heads, then one
/// link per kept corner.
fn space_out(
    corners: &mut [Corner],
    min_distance: u16,
    image: &ImageView<'_>,
    scratch: &mut [i32],
) -> usize {
    if min_distance == 0 {
        return corners.len();
    }
    let d = usize::from(min_distance);
    let cell = d
        .max(image.width().div_ceil(DISTANCE_GRID))
        .max(image.height().div_ceil(DISTANCE_GRID));
    let cols = image.width().div_ceil(cell);
    // The caller checked the scratch against scratch_len, so the split succeeds; were it to
    // fail, no corner is reported rather than corners too close together.
    let split = scratch.split_at_mut_checked(DISTANCE_GRID * DISTANCE_GRID);
    debug_assert!(
        split.is_some(),
        "space_out: scratch shorter than its chain heads"
    );
    let Some((heads, links)) = split else {
        return 0;
    };
    heads.fill(-1);
    let min_sq = d.saturating_mul(d);
    // cell >= d >= 1.
    let cell_of = |c: &Corner| {
        let (x, y) = c.pixel();
        (
            x.checked_div(cell).unwrap_or(0),
            y.checked_div(cell).unwrap_or(0),
        )
    };
    let head = |cx: usize, cy: usize| cy.saturating_mul(cols).saturating_add(cx);

    let mut kept = 0usize;
    for i in 0..corners.len() {
        let Some(&corner) = corners.get(i) else {
            break;
        };
        let (cx, cy) = cell_of(&corner);
        let (x, y) = corner.pixel();
        let mut clear = true;
        'cells: for ny in cy.saturating_sub(1)..=cy.saturating_add(1) {
            for nx in cx.saturating_sub(1)..=cx.saturating_add(1).min(cols.saturating_sub(1)) {
                let mut j = heads.get(head(nx, ny)).copied().unwrap_or(-1);
                while let Some(other) = usize::try_from(j).ok().and_then(|j| corners.get(j)) {
                    let (ox, oy) = other.pixel();
                    let dist_sq = x
                        .abs_diff(ox)
                        .saturating_pow(2)
                        .saturating_add(y.abs_diff(oy).saturating_pow(2));
                    if dist_sq < min_sq {
                        clear = false;
                        break 'cells;
                    }
                    j = usize::try_from(j)
                        .ok()
                        .and_then(|j| links.get(j))
                        .copied()
                        .unwrap_or(-1);
                }
            }
        }
        if !clear {
            continue;
        }
        // kept <= i < corners.len() <= links.len(), and kept fits i32 as it indexes a slice of
        // at most scratch.len() words.
        if let (Some(slot), Some(link), Some(head)) = (
            corners.get_mut(kept),
            links.get_mut(kept),
            heads.get_mut(head(cx, cy)),
        ) {
            *slot = corner;
            *link = *head;
            *head = i32::try_from(kept).unwrap_or(-1);
            kept = kept.saturating_add(1);
        }
    }
    kept
}

/// One pass of the scoring window down the frame.
struct Scan<'i, 'm> {
    image: &'i ImageView<'i>,
    /// `block / 2`.
    reach: usize,
    /// Pixels that may become corners.
    area: Region,
    mask: Option<&'m ExclusionMask>,
}

/// Column sums of the three tensor entries over the `block` rows around the current row,
/// interleaved as `[xx, xy, yy]` per column so that one pointer walks them.
struct ColumnSums<'s>(&'s mut [i32]);

// Per-pixel structure-tensor loop: indices are bounded by the region, clipped to the frame
// once in `detect`, and the sums are bounded as the module documentation shows; see the
// crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
impl Scan<'_, '_> {
    /// Scores every pixel of the area grown by one (so corners at its edge meet all their
    /// neighbours) and offers the local maxima in the area to `best`.
    fn run(&self, scratch: &mut [i32], best: &mut StrongestCorners<'_>) {
        let scored = self
            .area
            .grow_one(self.image.width(), self.image.height(), self.reach + 1);
        let (sw, cw) = (scored.width, scored.width + 2 * self.reach);
        // The tensor columns reach `reach` px beyond the scored columns on each side.
        let x0 = scored.x - self.reach;
        // cw + sw <= 2 x the frame's width, and `detect` checked the scratch against
        // scratch_len (6 words a column): the split succeeds. Were it to fail, nothing is
        // offered and `detect` reports no corner.
        let len = scratch.len();
        let split = split_scratch(scratch, cw, sw);
        debug_assert!(
            split.is_some(),
            "scan scratch of {len} for 3 x ({cw} + {sw})"
        );
        let Some((sums, ring)) = split else {
            return;
        };
        let (mut sums, [mut above, mut middle, mut below]) = (sums, ring);

        for y in scored.y - self.reach..=scored.y + self.reach {
            sums.add_row::<false>(self.image, y, x0);
        }
        above.fill(0);
        self.score_row(&sums, best.bar(), middle);
        for y in scored.y..scored.bottom() {
            if y + 1 < scored.bottom() {
                sums.add_row::<false>(self.image, y + 1 + self.reach, x0);
                sums.add_row::<true>(self.image, y - self.reach, x0);
                self.score_row(&sums, best.bar(), below);
            } else {
                below.fill(0);
            }
            if y >= self.area.y && y < self.area.bottom() {
                self.suppress_row(above, middle, below, scored.x, y, best);
            }
            (above, middle, below) = (middle, below, above);
        }
    }

    /// Scores of the current row from the column sums. With a `bar` (the weakest kept corner),
    /// pixels that cannot beat it score 0 without a square root.
    fn score_row(&self, sums: &ColumnSums<'_>, bar: Option<&Corner>, out: &mut [i32]) {
        let block = 2 * self.reach + 1;
        let floor = bar.map_or(1, |c| c.score.max(1));
        // A running sum over the block: add the entering column, score, drop the leaving one.
        let mut tensor = sums
            .columns()
            .take(block - 1)
            .fold(Tensor::ZERO, Tensor::add);
        let slide = sums.columns().skip(block - 1).zip(sums.columns());
        for ((entering, leaving), score) in slide.zip(out) {
            tensor = tensor.add(entering);
            // Scores are below 2^27 and fit i32.
            *score = tensor.score_if_at_least(floor).map_or(0, |s| s as i32);
            tensor = tensor.sub(leaving);
        }
    }

    /// Offers the pixels of `middle` (row `y`) in the area that score at least as much as all 8
    /// neighbours and more than 0. The rows hold scores of columns `x0..`.
    fn suppress_row(
        &self,
        above: &[i32],
        middle: &[i32],
        below: &[i32],
        x0: usize,
        y: usize,
        best: &mut StrongestCorners<'_>,
    ) {
        let at = |row: &[i32], i: Option<usize>| i.and_then(|i| row.get(i)).copied().unwrap_or(0);
        for x in self.area.x..self.area.right() {
            let i = x - x0;
            let score = at(middle, Some(i));
            if score <= 0 {
                continue;
            }
            let (left, right) = (i.checked_sub(1), Some(i + 1));
            let beaten = [left, Some(i), right]
                .into_iter()
                .any(|j| at(above, j) > score || at(below, j) > score || at(middle, j) > score);
            if beaten || self.mask.is_some_and(|m| m.is_excluded(x, y)) {
                continue;
            }
            // score > 0 was checked above.
            best.offer(Corner::new(x, y, score as u32));
        }
    }
}

/// Splits the scan scratch into three tensor column sums of `cw` words and three score rows of
/// `sw` words.
// Per-pixel structure-tensor loop: indices are bounded by the region, clipped to the frame
// once in `detect`, and the sums are bounded as the module documentation shows; see the
// crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
fn split_scratch(
    scratch: &mut [i32],
    cw: usize,
    sw: usize,
) -> Option<(ColumnSums<'_>, [&mut [i32]; 3])> {
    let (sums, rest) = scratch.split_at_mut_checked(3 * cw)?;
    let (above, rest) = rest.split_at_mut_checked(sw)?;
    let (middle, rest) = rest.split_at_mut_checked(sw)?;
    let (below, _) = rest.split_at_mut_checked(sw)?;
    sums.fill(0);
    Some((ColumnSums(sums), [above, middle, below]))
}

// Per-pixel structure-tensor loop: indices are bounded by the region, clipped to the frame
// once in `detect`, and the sums are bounded as the module documentation shows; see the
// crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
impl ColumnSums<'_> {
    /// The sums of each column as a tensor.
    fn columns(&self) -> impl Iterator<Item = Tensor> + '_ {
        self.0.chunks_exact(3).map(|column| match *column {
            [xx, xy, yy] => Tensor { xx, xy, yy },
            _ => Tensor::ZERO,
        })
    }

    /// Adds the gradient products of row `y`, columns `x0..x0 + len`, to the sums, or
    /// subtracts them when `SUBTRACT` (the row leaving the block).
    fn add_row<const SUBTRACT: bool>(&mut self, image: &ImageView<'_>, y: usize, x0: usize) {
        // The scored area was clipped to `reach + 1` px inside the frame, so the block's rows
        // and a pixel around them are in it. A missing row would leave the sums unbalanced;
        // it cannot be, by that clipping.
        let rows = SobelRows::around(image, y, x0, self.0.len() / 3);
        debug_assert!(
            rows.is_some(),
            "Sobel rows around ({x0}, {y}) leave the frame"
        );
        let Some(rows) = rows else {
            return;
        };
        for ((gx, gy), column) in rows.gradients().zip(self.0.chunks_exact_mut(3)) {
            let [xx, xy, yy] = column else {
                continue;
            };
            if SUBTRACT {
                *xx -= gx * gx;
                *xy -= gx * gy;
                *yy -= gy * gy;
            } else {
                *xx += gx * gx;
                *xy += gx * gy;
                *yy += gy * gy;
            }
        }
    }
}

/// The three pixel rows a row of 3 x 3 Sobel gradients reads.
struct SobelRows<'a> {
    up: &'a [u8],
    mid: &'a [u8],
    down: &'a [u8],
}

// Per-pixel structure-tensor loop: indices are bounded by the region, clipped to the frame
// once in `detect`, and the sums are bounded as the module documentation shows; see the
// crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
impl<'a> SobelRows<'a> {
    /// Rows `y - 1 ..= y + 1`, columns `x0 - 1 .. x0 + len + 1`, or `None` when they leave the
    /// frame.
    fn around(image: &ImageView<'a>, y: usize, x0: usize, len: usize) -> Option<Self> {
        let cols = x0.checked_sub(1)?..x0 + len + 1;
        Some(Self {
            up: image.row(y.checked_sub(1)?).get(cols.clone())?,
            mid: image.row(y).get(cols.clone())?,
            down: image.row(y + 1).get(cols)?,
        })
    }

    /// `(gx, gy)` for each inner column, gain 8 per grey level per pixel.
    ///
    /// The Sobel kernels are separable: with `s = up + 2 mid + down` and `t = down - up` per
    /// column, `gx = s[j + 1] - s[j - 1]` and `gy = t[j - 1] + 2 t[j] + t[j + 1]`, so each column
    /// is read once and the two previous columns are carried along.
    fn gradients(&self) -> impl Iterator<Item = (i32, i32)> + '_ {
        let mut columns = self
            .up
            .iter()
            .zip(self.mid)
            .zip(self.down)
            .map(|((&u, &m), &d)| {
                let (u, m, d) = (i32::from(u), i32::from(m), i32::from(d));
                (u + 2 * m + d, d - u)
            });
        let first = columns.next().unwrap_or_default();
        let second = columns.next().unwrap_or_default();
        columns.scan((first, second), |(before, here), after| {
            let gradient = (after.0 - before.0, before.1 + 2 * here.1 + after.1);
            (*before, *here) = (*here, after);
            Some(gradient)
        })
    }
}

/// A structure tensor `[xx xy; xy yy]` summed over a block (entries below 2^26 in magnitude).
#[derive(Debug, Clone, Copy)]
struct Tensor {
    xx: i32,
    xy: i32,
    yy: i32,
}

// Per-pixel structure-tensor loop: indices are bounded by the region, clipped to the frame
// once in `detect`, and the sums are bounded as the module documentation shows; see the
// crate's note on hot loops. The score's root is below 2^27, so it fits a u32.
#[allow(
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation
)]
impl Tensor {
    const ZERO: Tensor = Tensor {
        xx: 0,
        xy: 0,
        yy: 0,
    };

    fn add(self, other: Tensor) -> Tensor {
        Tensor {
            xx: self.xx + other.xx,
            xy: self.xy + other.xy,
            yy: self.yy + other.yy,
        }
    }

    fn sub(self, other: Tensor) -> Tensor {
        Tensor {
            xx: self.xx - other.xx,
            xy: self.xy - other.xy,
            yy: self.yy - other.yy,
        }
    }

    /// `a11 + a22` (below 2^27: `xx` and `yy` are sums of squares, so not negative).
    fn trace(&self) -> u32 {
        self.xx.unsigned_abs() + self.yy.unsigned_abs()
    }

    /// `(a11 - a22)² + 4 a12²`, so that `2 λmin = trace - sqrt(disc)`. Both terms are squares
    /// of numbers below 2^27, so each is one 32 x 32 -> 64-bit multiply.
    fn disc(&self) -> u64 {
        let diff = u64::from(self.xx.abs_diff(self.yy));
        let cross = u64::from(2 * self.xy.unsigned_abs());
        diff * diff + cross * cross
    }

    /// `floor(2 λmin)`.
    fn score(&self) -> u32 {
        let disc = self.disc();
        let root = isqrt(disc);
        let ceil_root = if root * root < disc { root + 1 } else { root };
        // disc <= trace² for a sum of outer products, so this does not underflow, and the
        // root is below 2^27.
        self.trace().saturating_sub(ceil_root as u32)
    }

    /// The score when it is at least `floor`, decided without a square root otherwise.
    fn score_if_at_least(&self, floor: u32) -> Option<u32> {
        // Most pixels stop here: too little gradient energy to reach the bar at all.
        let margin = u64::from(self.trace().checked_sub(floor)?);
        // score >= floor  <=>  trace - sqrt(disc) >= floor  <=>  margin² >= disc.
        if margin * margin < self.disc() {
            return None;
        }
        Some(self.score())
    }
}

/// `floor(sqrt(n))`, exactly: a float estimate refined once and corrected by a step or two.
///
/// The estimate is `n · (1/√n)`, the reciprocal root from the classic bit trick and three
/// Newton steps (relative error below 2^-21 after rounding), so that no square-root function
/// is needed (core has none without `std`) and the FPU does the work. One more step in
/// integers, `(n - r²) / 2r` in f32, brings it within one of the root, and the loops settle
/// the last unit; every comparison is exact in 64 bits (a square that overflows is too big).
// Float and integer arithmetic on bounded values: `r < 2^32 + 2`, squares checked.
#[allow(clippy::arithmetic_side_effects, clippy::cast_possible_truncation)]
fn isqrt(n: u64) -> u64 {
    if n < 2 {
        return n;
    }
    // Conversions through 32 bits only, which the FPU does in one instruction each (64-bit
    // ones are library calls on a Cortex-M4); the estimate needs no more precision.
    let x = (n >> 32) as u32 as f32 * 4_294_967_296.0 + n as u32 as f32;
    let mut y = f32::from_bits(0x5F37_59DF - (x.to_bits() >> 1));
    for _ in 0..3 {
        y *= 1.5 - 0.5 * x * y * y;
    }
    // Below 2^32 + 2^9 for every u64: saturating at u32::MAX loses nothing the loops below
    // cannot restore.
    let mut root = u64::from((x * y) as u32);
    if let Some(square) = root.checked_mul(root) {
        // The distance to n over the slope of the square, in f32: n and the square agree in
        // their high bits, so the difference fits 32 bits unless the estimate is far off.
        let gap = n.abs_diff(square);
        if let Ok(gap) = u32::try_from(gap) {
            let step = (gap as f32 / (2.0 * root.max(1) as u32 as f32)) as u32;
            root = if square <= n {
                root.saturating_add(u64::from(step))
            } else {
                root.saturating_sub(u64::from(step)).max(1)
            };
        }
    }
    let square_above = |r: u64| r.checked_mul(r).is_none_or(|sq| sq > n);
    while square_above(root) {
        root -= 1;
    }
    while !square_above(root + 1) {
        root += 1;
    }
    root
}

/// The Shi-Tomasi score `floor(2 λmin)` of pixel (`x`, `y`) with a `block` x `block` window, or
/// `None` when the block is invalid or the window and its Sobel border leave the frame.
///
/// [`ShiTomasi::detect`] reports exactly these scores.
///
/// ```
/// use kestrel::detect::min_eigen_score;
/// use kestrel::ImageView;
///
/// // A plain ramp has gradient in one direction only: λmin = 0.
/// let ramp: [u8; 8 * 8] = core::array::from_fn(|i| (i % 8) as u8 * 10);
/// let image = ImageView::packed(&ramp, 8, 8).unwrap();
/// assert_eq!(min_eigen_score(&image, 4, 4, 3), Some(0));
/// assert_eq!(min_eigen_score(&image, 1, 4, 3), None);
/// assert_eq!(min_eigen_score(&image, 4, 4, 4), None);
/// ```
// Per-pixel structure-tensor loop: indices are bounded by the region, clipped to the frame
// once in `detect`, and the sums are bounded as the module documentation shows; see the
// crate's note on hot loops.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
pub fn min_eigen_score(image: &ImageView<'_>, x: usize, y: usize, block: usize) -> Option<u32> {
    let reach = block_reach(block)?;
    let x0 = x.checked_sub(reach)?;
    let mut tensor = Tensor {
        xx: 0,
        xy: 0,
        yy: 0,
    };
    for row in y.checked_sub(reach)?..=y + reach {
        let rows = SobelRows::around(image, row, x0, block)?;
        for (gx, gy) in rows.gradients() {
            tensor.xx += gx * gx;
            tensor.xy += gx * gy;
            tensor.yy += gy * gy;
        }
    }
    Some(tensor.score())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isqrt_is_exact() {
        for n in 0..100_000u64 {
            let r = isqrt(n);
            assert!(r * r <= n && (r + 1) * (r + 1) > n, "{n}");
        }
        let mut n = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..100_000 {
            n ^= n << 13;
            n ^= n >> 7;
            n ^= n << 17;
            let v = n >> (n % 64);
            let r = u128::from(isqrt(v));
            assert!(
                r * r <= u128::from(v) && (r + 1) * (r + 1) > u128::from(v),
                "{v}"
            );
        }
        assert_eq!(isqrt(u64::MAX), u64::from(u32::MAX));
        for k in [1u64 << 26, (1 << 27) - 1, 1 << 31, u64::from(u32::MAX)] {
            assert_eq!(isqrt(k * k), k);
            assert_eq!(isqrt(k * k - 1), k - 1);
        }
    }

    #[test]
    fn sqrt_free_bar_agrees_with_the_score() {
        let mut seed = 0x00C0_FFEE_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for _ in 0..20_000 {
            let xx = (next() % 5_000_000) as i32;
            let yy = (next() % 5_000_000) as i32;
            let limit = (f64::from(xx) * f64::from(yy)).sqrt() as i32;
            let xy = (next() % (2 * limit as u32 + 1)) as i32 - limit;
            let t = Tensor { xx, xy, yy };
            let score = t.score();
            for floor in [0, score.saturating_sub(1), score, score + 1, score + 1000] {
                assert_eq!(t.score_if_at_least(floor).is_some(), score >= floor);
            }
        }
    }

    #[test]
    fn tensor_score_at_the_widest_block_does_not_overflow() {
        let full = 49 * 1020 * 1020;
        for (xx, xy, yy) in [(full, 0, full), (full, full, full), (full, -full, full)] {
            let t = Tensor { xx, xy, yy };
            let exact = {
                let (a, b, c) = (f64::from(xx), f64::from(xy), f64::from(yy));
                (a + c) - ((a - c).powi(2) + 4.0 * b * b).sqrt()
            };
            assert_eq!(f64::from(t.score()), exact.floor());
        }
    }

    #[test]
    fn quality_and_block_are_validated() {
        assert_eq!(quality_q16(0.01), Some(655));
        assert_eq!(quality_q16(1.0), Some(65536));
        assert_eq!(quality_q16(f32::NAN), None);
        assert_eq!(quality_q16(-0.1), None);
        assert_eq!(block_reach(5), Some(2));
        assert_eq!(block_reach(9), None);
        assert_eq!(block_reach(1), None);
    }
}
