//! Corner detection: where to start new tracks.
//!
//! Two detectors share one output type, [`Corner`]:
//!
//! - [`Fast`]: FAST-9 (Rosten & Drummond), the cheap one: a handful of integer compares per pixel.
//! - [`ShiTomasi`]: the minimum eigenvalue of the structure tensor, the corners LK tracks best.
//!
//! [`Grid`] then spreads the detected corners over the frame, so that flow is measured everywhere
//! and not only on the one textured patch of ground.
//!
//! Nothing allocates. Both detectors write into a caller-provided `&mut [Corner]` and return how
//! many corners they wrote; when more corners are found than fit, the strongest are kept, and the
//! output is always sorted strongest first, so a prefix of it is the best smaller set. Detection
//! can be restricted to a [`Region`] and kept away from existing tracks with an
//! [`ExclusionMask`].
//!
//! Detection fails only on its settings and its scratch, each refusal a
//! [`ConfigError`](crate::ConfigError) that names them: `"block"`, `"quality_level"`,
//! `"scratch"`, a grid's `"cols"` and `"rows"`.

mod fast;
mod grid;
mod shi_tomasi;

pub use fast::{fast9_score, fast_scratch_len, Fast, FAST_BORDER};
pub use grid::{Grid, MAX_CELLS_PER_SIDE};
pub use shi_tomasi::{min_eigen_score, shi_tomasi_scratch_len, ShiTomasi, MAX_BLOCK};

use crate::frame::{ImageView, MAX_DIMENSION};
use crate::q16::{Point, Q16};

/// The smaller of two sizes, usable in `const fn`.
const fn min(a: usize, b: usize) -> usize {
    if a < b {
        a
    } else {
        b
    }
}

/// A detected corner: an integer pixel position and a detector-specific strength.
///
/// Scores of the two detectors are not comparable with each other; within one detector, higher
/// is stronger.
///
/// ```
/// use kestrel::detect::Corner;
/// let c = Corner::new(12, 7, 40);
/// assert_eq!(c.pixel(), (12, 7));
/// assert_eq!(c.position.to_f32(), (12.0, 7.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Corner {
    /// Pixel centre of the corner, as a Q16 point with a zero fraction.
    pub position: Point,
    /// Corner strength; the unit depends on the detector.
    pub score: u32,
}

impl Corner {
    /// A corner at pixel (`x`, `y`); coordinates beyond the Q16 range saturate.
    ///
    /// ```
    /// use kestrel::detect::Corner;
    /// assert_eq!(Corner::new(3, 4, 9).score, 9);
    /// ```
    pub fn new(x: usize, y: usize, score: u32) -> Self {
        Self {
            position: Point::new(Q16::saturating_from_num(x), Q16::saturating_from_num(y)),
            score,
        }
    }

    /// The pixel that contains the position (floored; negative coordinates become 0).
    ///
    /// ```
    /// use kestrel::detect::Corner;
    /// use kestrel::Point;
    /// let c = Corner { position: Point::from_f32(4.75, -2.0), score: 1 };
    /// assert_eq!(c.pixel(), (4, 0));
    /// ```
    pub fn pixel(&self) -> (usize, usize) {
        (floor_pixel(self.position.x), floor_pixel(self.position.y))
    }

    /// True when `self` ranks before `other`: a higher score, or the same score earlier in
    /// raster order (top to bottom, then left to right). The order is total, so results do not
    /// depend on the order in which corners were found.
    ///
    /// ```
    /// use kestrel::detect::Corner;
    /// assert!(Corner::new(9, 9, 5).is_stronger_than(&Corner::new(0, 0, 4)));
    /// assert!(Corner::new(9, 0, 5).is_stronger_than(&Corner::new(0, 1, 5)));
    /// ```
    pub fn is_stronger_than(&self, other: &Corner) -> bool {
        self.rank_key() > other.rank_key()
    }

    /// Sort key: larger is stronger.
    fn rank_key(&self) -> (u32, core::cmp::Reverse<(Q16, Q16)>) {
        (
            self.score,
            core::cmp::Reverse((self.position.y, self.position.x)),
        )
    }
}

/// Sorts `corners` strongest first (see [`Corner::is_stronger_than`]).
pub(crate) fn sort_strongest_first(corners: &mut [Corner]) {
    corners.sort_unstable_by_key(|c| core::cmp::Reverse(c.rank_key()));
}

/// The integer pixel containing a Q16 coordinate, clamped at 0.
fn floor_pixel(v: Q16) -> usize {
    // `>> 16` floors, also for negative values; the clamp makes the cast lossless.
    (v.to_bits() >> 16).max(0) as usize
}

/// A rectangle of pixels: columns `x..x + width`, rows `y..y + height`.
///
/// Detectors only report corners inside the region, but read the pixels around it, so a corner
/// found in a region is exactly a corner found in the whole frame that lies in the region.
///
/// ```
/// use kestrel::detect::Region;
/// let r = Region::new(10, 20, 30, 40);
/// assert!(r.contains(10, 20) && r.contains(39, 59));
/// assert!(!r.contains(40, 20));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Region {
    /// Leftmost column.
    pub x: usize,
    /// Top row.
    pub y: usize,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
}

impl Region {
    /// A region from its top-left pixel and size.
    ///
    /// ```
    /// use kestrel::detect::Region;
    /// assert_eq!(Region::new(1, 2, 3, 4).width, 3);
    /// ```
    pub const fn new(x: usize, y: usize, width: usize, height: usize) -> Self {
        Self {
            x,
            y,
            width,
            height,
        }
    }

    /// The whole of `image`.
    ///
    /// ```
    /// use kestrel::detect::Region;
    /// use kestrel::ImageView;
    /// let image = ImageView::packed(&[0; 12], 4, 3).unwrap();
    /// assert_eq!(Region::full(&image), Region::new(0, 0, 4, 3));
    /// ```
    pub const fn full(image: &ImageView<'_>) -> Self {
        Self::new(0, 0, image.width(), image.height())
    }

    /// True when the region holds no pixel.
    ///
    /// ```
    /// use kestrel::detect::Region;
    /// assert!(Region::new(5, 5, 0, 9).is_empty());
    /// ```
    pub const fn is_empty(&self) -> bool {
        self.width == 0 || self.height == 0
    }

    /// True when pixel (`x`, `y`) lies in the region.
    ///
    /// ```
    /// use kestrel::detect::Region;
    /// assert!(!Region::new(0, 0, 2, 2).contains(2, 0));
    /// ```
    pub const fn contains(&self, x: usize, y: usize) -> bool {
        x >= self.x
            && x.saturating_sub(self.x) < self.width
            && y >= self.y
            && y.saturating_sub(self.y) < self.height
    }

    /// The part of the region inside a `width` x `height` frame shrunk by `border` pixels on
    /// every side; empty when nothing is left.
    ///
    /// ```
    /// use kestrel::detect::Region;
    /// let r = Region::new(0, 5, 100, 100).clip(20, 10, 3);
    /// assert_eq!(r, Region::new(3, 5, 14, 2));
    /// assert!(Region::new(50, 0, 4, 4).clip(20, 10, 0).is_empty());
    /// ```
    pub const fn clip(&self, width: usize, height: usize, border: usize) -> Region {
        let (x0, x1) = clip_span(self.x, self.width, width, border);
        let (y0, y1) = clip_span(self.y, self.height, height, border);
        Region::new(x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0))
    }

    /// The region grown by one pixel on every side, then clipped like [`Region::clip`].
    const fn grow_one(&self, width: usize, height: usize, border: usize) -> Region {
        let grown = Region::new(
            self.x.saturating_sub(1),
            self.y.saturating_sub(1),
            self.width.saturating_add(if self.x > 0 { 2 } else { 1 }),
            self.height.saturating_add(if self.y > 0 { 2 } else { 1 }),
        );
        grown.clip(width, height, border)
    }

    /// One past the rightmost column.
    const fn right(&self) -> usize {
        self.x.saturating_add(self.width)
    }

    /// One past the bottom row.
    const fn bottom(&self) -> usize {
        self.y.saturating_add(self.height)
    }
}

/// `start..start + len` intersected with `border..size - border`, as an ordered pair.
const fn clip_span(start: usize, len: usize, size: usize, border: usize) -> (usize, usize) {
    let lo_limit = border;
    let hi_limit = size.saturating_sub(border);
    let lo = if start > lo_limit { start } else { lo_limit };
    let end = start.saturating_add(len);
    let hi = if end < hi_limit { end } else { hi_limit };
    if lo < hi {
        (lo, hi)
    } else {
        (lo, lo)
    }
}

/// Cells per side of an [`ExclusionMask`]: each row of cells is one `u64`.
const MASK_CELLS: usize = 64;

/// A coarse occupancy bitmap marking where new corners are not wanted, typically around the
/// points already being tracked.
///
/// The frame is divided into at most 64 x 64 square cells whose side is the smallest power of
/// two that makes the grid fit (4 px at 160 x 120, 8 px at 320 x 240, 16 px at 640 x 480). Excluding a square of
/// radius `r` around a point marks every cell it touches, so every pixel within `r` px (along
/// each axis) is excluded, and some up to one cell further. The mask is 512 bytes plus a few
/// words and costs one shift and mask per lookup.
///
/// ```
/// use kestrel::detect::ExclusionMask;
/// use kestrel::Point;
/// let mut mask = ExclusionMask::new(160, 120);
/// assert_eq!(mask.cell_size(), 4);
/// mask.exclude_around(Point::from_f32(50.0, 60.0), 5);
/// assert!(mask.is_excluded(45, 55) && mask.is_excluded(55, 65));
/// assert!(!mask.is_excluded(70, 60));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExclusionMask {
    /// Bit `c` of `rows[r]` marks the cell in column `c`, row `r`.
    rows: [u64; MASK_CELLS],
    /// Cell side is `1 << shift` pixels.
    shift: u32,
    width: usize,
    height: usize,
}

impl ExclusionMask {
    /// An empty mask for a `width` x `height` frame.
    ///
    /// ```
    /// use kestrel::detect::ExclusionMask;
    /// let mask = ExclusionMask::new(640, 480);
    /// assert_eq!(mask.cell_size(), 16);
    /// assert!(!mask.is_excluded(10, 10));
    /// ```
    pub const fn new(width: usize, height: usize) -> Self {
        // Frames are at most MAX_DIMENSION px, so the loop ends with a shift of at most 6.
        let w = min(width, MAX_DIMENSION).saturating_sub(1);
        let h = min(height, MAX_DIMENSION).saturating_sub(1);
        let mut shift = 0u32;
        while (w >> shift) >= MASK_CELLS || (h >> shift) >= MASK_CELLS {
            shift = shift.saturating_add(1);
        }
        Self {
            rows: [0; MASK_CELLS],
            shift,
            width,
            height,
        }
    }

    /// Side of one cell in pixels.
    ///
    /// ```
    /// use kestrel::detect::ExclusionMask;
    /// assert_eq!(ExclusionMask::new(64, 64).cell_size(), 1);
    /// assert_eq!(ExclusionMask::new(65, 10).cell_size(), 2);
    /// ```
    pub const fn cell_size(&self) -> usize {
        1 << self.shift
    }

    /// Removes every exclusion.
    ///
    /// ```
    /// use kestrel::detect::ExclusionMask;
    /// use kestrel::Point;
    /// let mut mask = ExclusionMask::new(100, 100);
    /// mask.exclude_around(Point::from_f32(10.0, 10.0), 2);
    /// mask.clear();
    /// assert!(!mask.is_excluded(10, 10));
    /// ```
    pub fn clear(&mut self) {
        self.rows = [0; MASK_CELLS];
    }

    /// Excludes the square of pixels within `radius` of `point` along both axes, rounded out to
    /// whole cells. Points off the frame exclude the part of their square that is on it.
    ///
    /// ```
    /// use kestrel::detect::ExclusionMask;
    /// use kestrel::Point;
    /// let mut mask = ExclusionMask::new(160, 120);
    /// mask.exclude_around(Point::from_f32(-3.0, 10.0), 4);
    /// assert!(mask.is_excluded(0, 10) && !mask.is_excluded(8, 10));
    /// ```
    pub fn exclude_around(&mut self, point: Point, radius: u16) {
        let r = i64::from(radius);
        // Floor to the pixel holding the point; i64 keeps the box arithmetic overflow-free.
        let px = i64::from(point.x.to_bits() >> 16);
        let py = i64::from(point.y.to_bits() >> 16);
        let (Some((c0, c1)), Some((r0, r1))) = (
            self.cell_span(px.saturating_sub(r), px.saturating_add(r), self.width),
            self.cell_span(py.saturating_sub(r), py.saturating_add(r), self.height),
        ) else {
            // The square is wholly off the frame: there is nothing to exclude.
            return;
        };
        // c1 < 64, so the shifts stay in range.
        let bits = (u64::MAX >> 63usize.saturating_sub(c1)) & (u64::MAX << c0);
        for row in self.rows.iter_mut().take(r1.saturating_add(1)).skip(r0) {
            *row |= bits;
        }
    }

    /// Excludes the square of `radius` around every point, see [`ExclusionMask::exclude_around`].
    ///
    /// ```
    /// use kestrel::detect::ExclusionMask;
    /// use kestrel::Point;
    /// let tracks = [Point::from_f32(20.0, 20.0), Point::from_f32(90.0, 40.0)];
    /// let mut mask = ExclusionMask::new(160, 120);
    /// mask.exclude_all(&tracks, 6);
    /// assert!(mask.is_excluded(20, 25) && mask.is_excluded(85, 40));
    /// ```
    pub fn exclude_all(&mut self, points: &[Point], radius: u16) {
        for &p in points {
            self.exclude_around(p, radius);
        }
    }

    /// True when pixel (`x`, `y`) is excluded. Pixels off the frame are never excluded.
    ///
    /// ```
    /// use kestrel::detect::ExclusionMask;
    /// assert!(!ExclusionMask::new(10, 10).is_excluded(99, 99));
    /// ```
    pub fn is_excluded(&self, x: usize, y: usize) -> bool {
        if x >= self.width || y >= self.height {
            return false;
        }
        let (cx, cy) = (x >> self.shift, y >> self.shift);
        match self.rows.get(cy) {
            Some(row) if cx < MASK_CELLS => (row >> cx) & 1 == 1,
            _ => false,
        }
    }

    /// The cells covering pixels `lo..=hi` clipped to `0..size`, or `None` when none are left.
    fn cell_span(&self, lo: i64, hi: i64, size: usize) -> Option<(usize, usize)> {
        let last = i64::try_from(size).ok()?.checked_sub(1)?;
        let (lo, hi) = (lo.max(0), hi.min(last));
        if lo > hi {
            return None;
        }
        // Both are in 0..size, and size >> shift < 64.
        let cell = |v: i64| (usize::try_from(v).unwrap_or(0) >> self.shift).min(MASK_CELLS - 1);
        Some((cell(lo), cell(hi)))
    }
}

/// Keeps the strongest corners offered, up to the capacity of a caller's slice.
///
/// The slice is a binary min-heap ordered by [`Corner::is_stronger_than`] while corners are
/// offered, so each offer costs `O(log n)` and the weakest kept corner is always at hand as the
/// bar a new corner must clear.
pub(crate) struct StrongestCorners<'a> {
    slots: &'a mut [Corner],
    len: usize,
}

impl<'a> StrongestCorners<'a> {
    /// An empty collection that can hold `slots.len()` corners.
    pub(crate) fn new(slots: &'a mut [Corner]) -> Self {
        Self { slots, len: 0 }
    }

    /// True when every slot is taken.
    pub(crate) fn is_full(&self) -> bool {
        self.len == self.slots.len()
    }

    /// The weakest corner kept, once the collection is full: a new corner must beat it.
    pub(crate) fn bar(&self) -> Option<&Corner> {
        if self.is_full() {
            self.slots.first()
        } else {
            None
        }
    }

    /// Adds `corner`, evicting the weakest kept corner when full and `corner` is stronger.
    pub(crate) fn offer(&mut self, corner: Corner) {
        if !self.is_full() {
            if let Some(slot) = self.slots.get_mut(self.len) {
                *slot = corner;
                self.sift_up(self.len);
                self.len = self.len.saturating_add(1);
            }
        } else if let Some(weakest) = self.slots.first_mut() {
            if corner.is_stronger_than(weakest) {
                *weakest = corner;
                self.sift_down(0);
            }
        }
    }

    /// Sorts the kept corners strongest first and returns how many there are.
    pub(crate) fn finish(self) -> usize {
        if let Some(kept) = self.slots.get_mut(..self.len) {
            sort_strongest_first(kept);
        }
        self.len
    }

    /// True when slot `a` is weaker than slot `b` (min-heap order).
    fn weaker(&self, a: usize, b: usize) -> bool {
        match (self.slots.get(a), self.slots.get(b)) {
            (Some(a), Some(b)) => b.is_stronger_than(a),
            _ => false,
        }
    }

    fn sift_up(&mut self, mut i: usize) {
        while let Some(before) = i.checked_sub(1) {
            let parent = before / 2;
            if !self.weaker(i, parent) {
                break;
            }
            self.slots.swap(i, parent);
            i = parent;
        }
    }

    fn sift_down(&mut self, mut i: usize) {
        loop {
            // i < len <= the slot count: no overflow.
            let left = i.saturating_mul(2).saturating_add(1);
            let right = left.saturating_add(1);
            let mut weakest = i;
            if left < self.len && self.weaker(left, weakest) {
                weakest = left;
            }
            if right < self.len && self.weaker(right, weakest) {
                weakest = right;
            }
            if weakest == i {
                break;
            }
            self.slots.swap(i, weakest);
            i = weakest;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strongest_corners_keeps_the_best_and_sorts_them() {
        let mut slots = [Corner::default(); 4];
        let mut best = StrongestCorners::new(&mut slots);
        for (i, score) in [5u32, 1, 9, 3, 7, 7, 2, 8].into_iter().enumerate() {
            best.offer(Corner::new(i, 0, score));
        }
        assert_eq!(best.bar().map(|c| c.score), Some(7));
        let n = best.finish();
        let scores: [u32; 4] = core::array::from_fn(|i| slots[i].score);
        assert_eq!(n, 4);
        assert_eq!(scores, [9, 8, 7, 7]);
        // Of the two 7s, the earlier (x = 4) ranks first.
        assert_eq!(slots[2].pixel(), (4, 0));
    }

    #[test]
    fn strongest_corners_with_no_room_keeps_nothing() {
        let mut slots: [Corner; 0] = [];
        let mut best = StrongestCorners::new(&mut slots);
        best.offer(Corner::new(1, 1, 1));
        assert!(best.bar().is_none());
        assert_eq!(best.finish(), 0);
    }

    #[test]
    fn region_clip_handles_huge_and_outside_regions() {
        let all = Region::new(0, 0, usize::MAX, usize::MAX);
        assert_eq!(all.clip(10, 8, 3), Region::new(3, 3, 4, 2));
        assert!(Region::new(usize::MAX, 0, 5, 5).clip(10, 8, 0).is_empty());
        assert!(Region::new(0, 0, 10, 10).clip(5, 5, 3).is_empty());
        assert_eq!(
            Region::new(4, 4, 1, 1).grow_one(10, 10, 0),
            Region::new(3, 3, 3, 3)
        );
        assert_eq!(
            Region::new(0, 0, 2, 2).grow_one(10, 10, 1),
            Region::new(1, 1, 2, 2)
        );
    }

    #[test]
    fn exclusion_mask_covers_the_square_rounded_to_cells() {
        let mut mask = ExclusionMask::new(160, 120);
        mask.exclude_around(Point::from_f32(80.0, 60.0), 6);
        for y in 0..120usize {
            for x in 0..160usize {
                let inside = x.abs_diff(80) <= 6 && y.abs_diff(60) <= 6;
                let near = x.abs_diff(80) <= 6 + 4 && y.abs_diff(60) <= 6 + 4;
                let excluded = mask.is_excluded(x, y);
                assert!(!inside || excluded, "({x}, {y}) should be excluded");
                assert!(near || !excluded, "({x}, {y}) should not be excluded");
            }
        }
    }

    #[test]
    fn exclusion_mask_survives_extreme_points_and_sizes() {
        let mut mask = ExclusionMask::new(usize::MAX, usize::MAX);
        mask.exclude_around(Point::from_f32(32767.0, -32768.0), u16::MAX);
        let mut empty = ExclusionMask::new(0, 0);
        empty.exclude_around(Point::default(), 3);
        assert!(!empty.is_excluded(0, 0));
        let mut mask = ExclusionMask::new(4096, 4096);
        mask.exclude_around(Point::from_f32(4095.0, 4095.0), 0);
        assert!(mask.is_excluded(4095, 4095));
        assert!(!mask.is_excluded(0, 0));
    }
}
