//! Gaussian image pyramids in caller-owned storage.
//!
//! Level 0 is the caller's frame itself (a camera DMA buffer is never copied). Each coarser level
//! is the previous one blurred with the 5x5 binomial kernel `[1 4 6 4 1]^T [1 4 6 4 1] / 256`,
//! rounded, and subsampled to `(w + 1) / 2` x `(h + 1) / 2`, with mirrored borders
//! (`dcb|abcd|cba`): the same filter, size rule and border as OpenCV's `pyrDown`, so tracking
//! results are comparable. Firmware sizes the storage with [`pyramid_storage_len`] at compile time.
//!
//! [`PyramidFilter::Box`] halves each level by 2 x 2 averages instead, as a flow sensor does:
//! four halving adds per eight pixels with the Cortex-M4's UHADD8, a small fraction of the
//! Gaussian's cost, for a little more aliasing on the coarse levels.

use crate::config_error::bound_number;
use crate::frame::ImageView;
use crate::{Bound, ConfigError};

/// The deepest pyramid Kestrel builds: levels `0..=MAX_LEVEL`.
pub const MAX_LEVEL: usize = 7;

/// Width or height of pyramid level `level` for a level-0 size `size`: halved, rounded up.
///
/// ```
/// use kestrel::pyramid::level_size;
/// assert_eq!(level_size(321, 0), 321);
/// assert_eq!(level_size(321, 1), 161);
/// assert_eq!(level_size(321, 3), 41);
/// assert_eq!(level_size(1, 5), 1);
/// ```
pub const fn level_size(size: usize, level: usize) -> usize {
    // Halving and rounding up `level` times is one division by 2^level, rounded up.
    if level >= usize::BITS as usize {
        return if size == 0 { 0 } else { 1 };
    }
    size.div_ceil(1 << level)
}

/// Bytes of storage for levels `1..=max_level` of a pyramid over a `width` x `height` frame.
///
/// Level 0 is the frame itself and needs no storage. Use it to declare static buffers:
///
/// ```
/// use kestrel::pyramid::pyramid_storage_len;
/// const LEN: usize = pyramid_storage_len(160, 120, 3);
/// static mut STORAGE: [u8; LEN] = [0; LEN];
/// assert_eq!(LEN, 80 * 60 + 40 * 30 + 20 * 15);
/// ```
pub const fn pyramid_storage_len(width: usize, height: usize, max_level: usize) -> usize {
    let mut total = 0;
    let mut l = 1;
    while l <= max_level {
        total += level_size(width, l) * level_size(height, l);
        l += 1;
    }
    total
}

/// An image pyramid: level 0 borrowed from the caller's frame, coarser levels in caller storage.
///
/// ```
/// use kestrel::ImageView;
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
/// let pixels = [128u8; 64 * 48];
/// let frame = ImageView::packed(&pixels, 64, 48).unwrap();
/// let mut storage = [0u8; pyramid_storage_len(64, 48, 3)];
/// let pyramid = Pyramid::build(frame, 3, &mut storage).unwrap();
/// assert_eq!(pyramid.max_level(), 3);
/// assert_eq!(pyramid.level(3).unwrap().width(), 8);
/// assert_eq!(pyramid.level(2).unwrap().get(0, 0), Some(128));
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Pyramid<'a> {
    base: ImageView<'a>,
    levels: [Option<ImageView<'a>>; MAX_LEVEL + 1],
    max_level: usize,
}

/// How each pyramid level is made from the one below it.
///
/// ```
/// use kestrel::ImageView;
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid, PyramidFilter};
///
/// // One bright pixel at (2, 2): the box mean keeps it in its 2 x 2 block, the Gaussian
/// // spreads it to the level-1 pixels around.
/// let mut pixels = [0u8; 64];
/// pixels[2 * 8 + 2] = 160;
/// let frame = ImageView::packed(&pixels, 8, 8).unwrap();
/// let mut storage = [[0u8; pyramid_storage_len(8, 8, 1)]; 3];
/// let [a, b, c] = &mut storage;
/// let built = Pyramid::build(frame, 1, a).unwrap();
/// let gaussian = Pyramid::build_with(frame, 1, PyramidFilter::Gaussian, b).unwrap();
/// let boxed = Pyramid::build_with(frame, 1, PyramidFilter::Box, c).unwrap();
/// let at = |p: &Pyramid, x, y| p.level(1).unwrap().get(x, y).unwrap();
/// assert_eq!((at(&boxed, 1, 1), at(&boxed, 0, 1)), (40, 0));
/// assert!(at(&gaussian, 1, 1) > 0 && at(&gaussian, 0, 1) > 0);
/// // `Pyramid::build` uses the default filter, the Gaussian.
/// assert!((0..4).all(|y| (0..4).all(|x| at(&built, x, y) == at(&gaussian, x, y))));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PyramidFilter {
    /// OpenCV's `pyrDown`: the 5x5 binomial blur, rounded, every second pixel kept.
    #[default]
    Gaussian,
    /// The mean of each 2 x 2 block, by two halving adds that each truncate (`UHADD8`'s
    /// rounding: at most 3/4 of a grey level below the exact mean), the last column and row
    /// repeated on odd sizes. A coarse pixel covers its block, so its centre lies half a fine
    /// pixel right of and below the fine pixel it is indexed by: the same on both frames, so
    /// the motion LK finds on a coarse level is unchanged, and the finest level, which is the
    /// frame itself, settles the position.
    Box,
}

impl<'a> Pyramid<'a> {
    /// Builds levels `1..=max_level` of `frame` into `storage` with the Gaussian filter.
    ///
    /// `max_level` is at most [`MAX_LEVEL`], and `storage` holds at least
    /// [`pyramid_storage_len`]`(width, height, max_level)` bytes; otherwise the refusal names
    /// `"max_level"` or `"storage"`.
    ///
    /// ```
    /// use kestrel::ImageView;
    /// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
    /// use kestrel::{Bound, ConfigError};
    /// let pixels = [0u8; 16];
    /// let frame = ImageView::packed(&pixels, 4, 4).unwrap();
    /// let refused = Pyramid::build(frame, 1, &mut [0u8; 3]).unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "storage", bound: Bound::MinLen(4) });
    /// assert_eq!(refused.to_string(), "storage must hold at least 4 elements");
    /// let deep = Pyramid::build(frame, 8, &mut [0u8; 64]).unwrap_err();
    /// assert_eq!(deep.to_string(), "max_level must be at most 7");
    /// ```
    pub fn build(
        frame: ImageView<'a>,
        max_level: usize,
        storage: &'a mut [u8],
    ) -> Result<Self, ConfigError> {
        Self::build_with(frame, max_level, PyramidFilter::Gaussian, storage)
    }

    /// Builds levels `1..=max_level` of `frame` into `storage` with `filter`.
    ///
    /// ```
    /// use kestrel::ImageView;
    /// use kestrel::pyramid::{pyramid_storage_len, Pyramid, PyramidFilter};
    /// let pixels: [u8; 16] = [0, 2, 10, 20, 4, 6, 30, 40, 9, 9, 9, 9, 9, 9, 9, 9];
    /// let frame = ImageView::packed(&pixels, 4, 4).unwrap();
    /// let mut storage = [0u8; pyramid_storage_len(4, 4, 1)];
    /// let pyramid = Pyramid::build_with(frame, 1, PyramidFilter::Box, &mut storage).unwrap();
    /// let level = pyramid.level(1).unwrap();
    /// assert_eq!((level.get(0, 0), level.get(1, 0), level.get(1, 1)), (Some(3), Some(25), Some(9)));
    /// ```
    pub fn build_with(
        frame: ImageView<'a>,
        max_level: usize,
        filter: PyramidFilter,
        storage: &'a mut [u8],
    ) -> Result<Self, ConfigError> {
        let needed = Self::check(&frame, max_level, storage.len())?;
        let mut levels = [None; MAX_LEVEL + 1];
        levels[0] = Some(frame);
        let mut finer = frame;
        let mut rest = storage;
        for slot in levels.iter_mut().take(max_level + 1).skip(1) {
            let (w, h) = (finer.width().div_ceil(2), finer.height().div_ceil(2));
            let (buf, tail) = core::mem::take(&mut rest).split_at_mut(w * h);
            rest = tail;
            match filter {
                PyramidFilter::Gaussian => Gaussian::downsample(&finer, buf, w, h),
                PyramidFilter::Box => BoxMean::downsample(&finer, buf, w, h),
            }
            let coarser = level_view(buf, w, h, needed)?;
            *slot = Some(coarser);
            finer = coarser;
        }
        Ok(Self {
            base: frame,
            levels,
            max_level,
        })
    }

    /// Views a pyramid whose levels `1..=max_level` were already built into `storage` by
    /// [`Pyramid::build`] for a frame of the same size (a tracker keeps the previous frame's
    /// pyramid this way without rebuilding it).
    ///
    /// ```
    /// use kestrel::ImageView;
    /// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
    /// let pixels = [9u8; 20 * 10];
    /// let frame = ImageView::packed(&pixels, 20, 10).unwrap();
    /// let mut storage = [0u8; pyramid_storage_len(20, 10, 2)];
    /// Pyramid::build(frame, 2, &mut storage).unwrap();
    /// let again = Pyramid::from_storage(frame, 2, &storage).unwrap();
    /// assert_eq!(again.level(2).unwrap().get(4, 2), Some(9));
    /// ```
    pub fn from_storage(
        frame: ImageView<'a>,
        max_level: usize,
        storage: &'a [u8],
    ) -> Result<Self, ConfigError> {
        let needed = Self::check(&frame, max_level, storage.len())?;
        let mut levels = [None; MAX_LEVEL + 1];
        levels[0] = Some(frame);
        let mut rest = storage;
        for (l, slot) in levels.iter_mut().enumerate().take(max_level + 1).skip(1) {
            let (w, h) = (level_size(frame.width(), l), level_size(frame.height(), l));
            let (buf, tail) = rest.split_at(w * h);
            rest = tail;
            *slot = Some(level_view(buf, w, h, needed)?);
        }
        Ok(Self {
            base: frame,
            levels,
            max_level,
        })
    }

    /// Checks the level count and the storage's length, and returns the length needed.
    fn check(
        frame: &ImageView<'_>,
        max_level: usize,
        storage: usize,
    ) -> Result<usize, ConfigError> {
        if max_level > MAX_LEVEL {
            let bound = Bound::AtMost(bound_number(MAX_LEVEL));
            return Err(ConfigError::new("max_level", bound));
        }
        let needed = pyramid_storage_len(frame.width(), frame.height(), max_level);
        if storage < needed {
            return Err(ConfigError::min_len("storage", needed));
        }
        Ok(needed)
    }

    /// Index of the coarsest level.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// # use kestrel::pyramid::Pyramid;
    /// let pixels = [0u8; 4];
    /// let p = Pyramid::build(ImageView::packed(&pixels, 2, 2).unwrap(), 0, &mut []).unwrap();
    /// assert_eq!(p.max_level(), 0);
    /// ```
    pub const fn max_level(&self) -> usize {
        self.max_level
    }

    /// Level `level` (0 = full resolution), or `None` beyond [`Pyramid::max_level`].
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// # use kestrel::pyramid::Pyramid;
    /// let pixels = [0u8; 4];
    /// let p = Pyramid::build(ImageView::packed(&pixels, 2, 2).unwrap(), 0, &mut []).unwrap();
    /// assert!(p.level(0).is_some());
    /// assert!(p.level(1).is_none());
    /// ```
    pub fn level(&self, level: usize) -> Option<ImageView<'a>> {
        self.levels.get(level).copied().flatten()
    }

    /// The full-resolution frame.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// # use kestrel::pyramid::Pyramid;
    /// let pixels = [3u8; 4];
    /// let p = Pyramid::build(ImageView::packed(&pixels, 2, 2).unwrap(), 0, &mut []).unwrap();
    /// assert_eq!(p.base().get(1, 1), Some(3));
    /// ```
    pub fn base(&self) -> ImageView<'a> {
        self.base
    }
}

/// The view of one coarser level, `w` x `h` pixels in `buf`. It cannot be refused: `w` and `h`
/// are those of a level of a valid frame (1 to [`crate::frame::MAX_DIMENSION`]) and `buf` is
/// `w * h` bytes of a storage of at least `needed` bytes; were it ever refused, the storage is
/// what could not hold it.
fn level_view(buf: &[u8], w: usize, h: usize, needed: usize) -> Result<ImageView<'_>, ConfigError> {
    ImageView::packed(buf, w, h).map_err(|_| ConfigError::min_len("storage", needed))
}

/// Logs the base frame's geometry and the depth, not the levels' pixels.
#[cfg(feature = "defmt")]
impl defmt::Format for Pyramid<'_> {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(
            f,
            "Pyramid {{ base: {}, max_level: {=usize} }}",
            self.base,
            self.max_level
        );
    }
}

/// Mirrors an index into `0..n` the way OpenCV's `BORDER_REFLECT_101` does (`dcb|abcd|cba`).
#[inline]
pub(crate) fn reflect101(i: isize, n: usize) -> usize {
    if i >= 0 && (i as usize) < n {
        return i as usize;
    }
    reflect_outside(i, n)
}

/// [`reflect101`] for an index outside `0..n`: rare (a few per row), so out of line.
#[cold]
#[inline(never)]
fn reflect_outside(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n <= 1 {
        return 0;
    }
    let mut i = i;
    // Two reflections suffice for the 2-pixel reach of the 5-tap kernel, even on 2-pixel images.
    while i < 0 || i >= n {
        i = if i < 0 { -i } else { 2 * n - 2 - i };
    }
    i as usize
}

// The level filters: the box mean, and the Gaussian, one loop on every target whose innermost
// kernel is `dsp`'s. `strips` is the Gaussian filter the host ran before, kept for the tests as
// the reference that the one loop gives the same pixels as.
mod box_mean;
mod gaussian;
#[cfg(test)]
mod strips;

use box_mean::BoxMean;
use gaussian::Gaussian;

/// One way to blur a level with the 5x5 binomial kernel and keep every second pixel into `dst`
/// (`w` x `h`).
trait Downsample {
    fn downsample(src: &ImageView<'_>, dst: &mut [u8], w: usize, h: usize);
}

/// The five source rows under output row `y`, mirrored at the top and bottom.
fn source_rows<'a>(src: &ImageView<'a>, y: usize) -> [&'a [u8]; 5] {
    let sh = src.height();
    core::array::from_fn(|k| src.row(reflect101(2 * y as isize - 2 + k as isize, sh)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect101_mirrors_without_repeating_the_edge() {
        assert_eq!(reflect101(-1, 5), 1);
        assert_eq!(reflect101(-2, 5), 2);
        assert_eq!(reflect101(5, 5), 3);
        assert_eq!(reflect101(6, 5), 2);
        assert_eq!(reflect101(-2, 2), 0);
        assert_eq!(reflect101(3, 2), 1);
        assert_eq!(reflect101(-3, 1), 0);
    }

    #[test]
    fn level_size_is_repeated_halving_rounded_up() {
        for size in 0..300usize {
            let mut halved = size;
            for level in 0..12 {
                assert_eq!(
                    level_size(size, level),
                    halved,
                    "size {size}, level {level}"
                );
                halved = halved.div_ceil(2);
            }
        }
        assert_eq!(level_size(usize::MAX, 1), usize::MAX / 2 + 1);
        assert_eq!(level_size(usize::MAX, 200), 1);
        assert_eq!(level_size(0, 200), 0);
    }

    #[test]
    fn constant_image_stays_constant() {
        let pixels = [200u8; 33 * 17];
        let frame = ImageView::packed(&pixels, 33, 17).unwrap();
        let mut storage = [0u8; pyramid_storage_len(33, 17, 4)];
        let p = Pyramid::build(frame, 4, &mut storage).unwrap();
        for l in 1..=4 {
            let v = p.level(l).unwrap();
            assert_eq!(v.width(), level_size(33, l));
            for y in 0..v.height() {
                assert!(v.row(y).iter().all(|&px| px == 200));
            }
        }
    }

    #[test]
    fn matches_direct_5x5_convolution() {
        // A deterministic pattern wide enough to span several strips.
        let (w, h) = (203usize, 9usize);
        let mut pixels = [0u8; 203 * 9];
        for (i, p) in pixels.iter_mut().enumerate() {
            *p = ((i * 7919 + (i / 203) * 31) % 256) as u8;
        }
        let frame = ImageView::packed(&pixels, w, h).unwrap();
        let mut storage = [0u8; pyramid_storage_len(203, 9, 1)];
        let p = Pyramid::build(frame, 1, &mut storage).unwrap();
        assert_direct_convolution(&frame, &p.level(1).unwrap());
    }

    /// Both ways of filtering give the direct convolution's pixels, at every width from the
    /// narrowest (all mirrored columns) through several words, with the extremes 0 and 255.
    #[test]
    fn strips_and_gaussian_match_direct_convolution() {
        let mut state = 99u32;
        let pixels: [u8; 77 * 7] = core::array::from_fn(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            match state >> 29 {
                0 => 0,
                1 => 255,
                _ => (state >> 24) as u8,
            }
        });
        for w in 1..=77 {
            for h in [1, 2, 5, 7] {
                let frame = ImageView::packed(&pixels[..w * h], w, h).unwrap();
                let (lw, lh) = (level_size(w, 1), level_size(h, 1));
                let mut strips = [0u8; 39 * 4];
                let mut gaussian = [0u8; 39 * 4];
                strips::Strips::downsample(&frame, &mut strips[..lw * lh], lw, lh);
                Gaussian::downsample(&frame, &mut gaussian[..lw * lh], lw, lh);
                let level = |px| ImageView::packed(px, lw, lh).unwrap();
                assert_direct_convolution(&frame, &level(&strips[..lw * lh]));
                assert_direct_convolution(&frame, &level(&gaussian[..lw * lh]));
            }
        }
    }

    /// The one filter loop gives the strips filter's pixels, through every level of pyramids
    /// over seeded frames of odd and even sizes, wide enough for several SSE2 blocks and strips.
    #[test]
    fn one_loop_matches_the_strips_filter() {
        let mut state = 0x5EED_u32;
        let pixels: [u8; 211 * 37] = core::array::from_fn(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            match state % 16 {
                0 => 0,
                1 => 255,
                _ => (state >> 24) as u8,
            }
        });
        let sizes = [
            (211, 37),
            (161, 41),
            (97, 13),
            (33, 9),
            (17, 5),
            (9, 3),
            (160, 37),
        ];
        for (w, h) in sizes {
            let mut finer = [0u8; 211 * 37];
            finer[..w * h].copy_from_slice(&pixels[(211 * 37 - w * h)..]);
            let (mut fw, mut fh) = (w, h);
            for level in 1..=4 {
                let frame = ImageView::packed(&finer[..fw * fh], fw, fh).unwrap();
                let (lw, lh) = (level_size(fw, 1), level_size(fh, 1));
                let mut strips = [0u8; 106 * 19];
                let mut one = [0u8; 106 * 19];
                strips::Strips::downsample(&frame, &mut strips[..lw * lh], lw, lh);
                Gaussian::downsample(&frame, &mut one[..lw * lh], lw, lh);
                assert_eq!(
                    strips[..lw * lh],
                    one[..lw * lh],
                    "{w}x{h}, level {level} ({lw}x{lh})"
                );
                finer[..lw * lh].copy_from_slice(&one[..lw * lh]);
                (fw, fh) = (lw, lh);
            }
        }
    }

    fn assert_direct_convolution(frame: &ImageView<'_>, level: &ImageView<'_>) {
        let (w, h) = (frame.width(), frame.height());
        let k = [1u32, 4, 6, 4, 1];
        for y in 0..level.height() {
            for x in 0..level.width() {
                let mut sum = 0u32;
                for (j, kj) in k.iter().enumerate() {
                    for (i, ki) in k.iter().enumerate() {
                        let sy = reflect101(2 * y as isize - 2 + j as isize, h);
                        let sx = reflect101(2 * x as isize - 2 + i as isize, w);
                        sum += kj * ki * u32::from(frame.get(sx, sy).unwrap());
                    }
                }
                assert_eq!(level.get(x, y).unwrap(), ((sum + 128) >> 8) as u8);
            }
        }
    }

    /// The box filter equals the 2 x 2 truncated means pixel by pixel, word path and edges,
    /// on odd and even sizes.
    #[test]
    fn box_filter_matches_direct_means() {
        let mut state = 99u32;
        let px: [u8; 37 * 23] = core::array::from_fn(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 24) as u8
        });
        for (w, h) in [(37, 23), (32, 16), (9, 3), (1, 1), (8, 2)] {
            let frame = ImageView::packed(&px[..w * h], w, h).unwrap();
            let mut storage = [0u8; 37 * 23];
            let p = Pyramid::build_with(frame, 1, PyramidFilter::Box, &mut storage).unwrap();
            let level = p.level(1).unwrap();
            let at = |x: usize, y: usize| u32::from(px[y.min(h - 1) * w + x.min(w - 1)]);
            for y in 0..level.height() {
                for x in 0..level.width() {
                    let (a, b) = (at(2 * x, 2 * y), at(2 * x + 1, 2 * y));
                    let (c, d) = (at(2 * x, 2 * y + 1), at(2 * x + 1, 2 * y + 1));
                    let mean = ((a + c) / 2 + (b + d) / 2) / 2;
                    assert_eq!(level.get(x, y), Some(mean as u8), "{w}x{h} at {x},{y}");
                }
            }
        }
    }

    #[test]
    fn storage_and_level_errors() {
        let pixels = [0u8; 16];
        let frame = ImageView::packed(&pixels, 4, 4).unwrap();
        let mut small = [0u8; 3];
        assert_eq!(
            Pyramid::build(frame, 1, &mut small).unwrap_err(),
            ConfigError::min_len("storage", 4)
        );
        let mut big = [0u8; 64];
        assert_eq!(
            Pyramid::build(frame, 8, &mut big).unwrap_err(),
            ConfigError::new("max_level", Bound::AtMost(7))
        );
        assert_eq!(
            Pyramid::from_storage(frame, 2, &small).unwrap_err(),
            ConfigError::min_len("storage", 5)
        );
    }

    #[test]
    fn one_pixel_frame_builds_every_level() {
        let pixels = [77u8];
        let frame = ImageView::packed(&pixels, 1, 1).unwrap();
        let mut storage = [0u8; pyramid_storage_len(1, 1, 7)];
        let p = Pyramid::build(frame, 7, &mut storage).unwrap();
        assert_eq!(p.level(7).unwrap().get(0, 0), Some(77));
    }
}
