//! Gaussian pyramids in `f32`.
//!
//! The same filter, size rule and border as the library's (and OpenCV's `pyrDown`): the 5x5
//! binomial kernel `[1 4 6 4 1]^T [1 4 6 4 1] / 256`, every second pixel kept, `(w + 1) / 2` x
//! `(h + 1) / 2`, mirrored borders (`dcb|abcd|cba`). The library rounds each level to 8 bits; this
//! one does not, so comparing the two also measures what that rounding costs.

use super::FloatImage;
use crate::Frame;

/// The binomial taps, each axis; the 2-D kernel is their outer product over 256.
const TAPS: [f32; 5] = [1.0, 4.0, 6.0, 4.0, 1.0];

/// Levels `0..=max_level` of `frame`'s Gaussian pyramid; level 0 is the frame itself.
///
/// ```
/// use host_sim::reference::pyramid;
/// let frame = host_sim::Frame::filled(33, 20, 7);
/// let levels = pyramid(&frame, 2);
/// assert_eq!((levels[2].width, levels[2].height), (9, 5));
/// assert!(levels[2].data.iter().all(|&v| v == 7.0));
/// ```
pub fn pyramid(frame: &Frame, max_level: usize) -> Vec<FloatImage> {
    let mut levels = vec![FloatImage::from_frame(frame)];
    for _ in 0..max_level {
        let coarser = downsample(levels.last().expect("level 0 is always present"));
        levels.push(coarser);
    }
    levels
}

/// One pyramid step: blur with the binomial kernel, keep every second pixel.
pub fn downsample(image: &FloatImage) -> FloatImage {
    let (width, height) = (image.width.div_ceil(2), image.height.div_ceil(2));
    let mut data = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            data.push(blurred(image, 2 * x, 2 * y));
        }
    }
    FloatImage {
        width,
        height,
        data,
    }
}

/// The binomial blur of `image` at pixel (`x`, `y`), borders mirrored.
fn blurred(image: &FloatImage, x: usize, y: usize) -> f32 {
    let mut sum = 0.0;
    for (j, ky) in TAPS.iter().enumerate() {
        let row = reflect101(y as isize + j as isize - 2, image.height);
        for (i, kx) in TAPS.iter().enumerate() {
            let col = reflect101(x as isize + i as isize - 2, image.width);
            sum += ky * kx * image.at(col, row);
        }
    }
    sum / 256.0
}

/// Mirrors an index into `0..n` without repeating the edge (`dcb|abcd|cba`), as OpenCV's
/// `BORDER_REFLECT_101` does; repeated reflection covers images narrower than the kernel.
pub fn reflect101(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let last = n as isize - 1;
    let mut i = i;
    while !(0..=last).contains(&i) {
        i = if i < 0 { -i } else { 2 * last - i };
    }
    i as usize
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
    fn matches_the_library_up_to_its_rounding() {
        let (w, h) = (37, 23);
        let data = (0..w * h)
            .map(|i| ((i * 7919 + (i / w) * 31) % 256) as u8)
            .collect();
        let frame = Frame {
            width: w,
            height: h,
            data,
        };
        let levels = pyramid(&frame, 2);
        let mut storage = vec![0u8; kestrel::pyramid::pyramid_storage_len(w, h, 2)];
        let library =
            kestrel::pyramid::Pyramid::build(frame.view().unwrap(), 2, &mut storage).unwrap();
        // Level 1 is filtered from the same 8-bit frame: only the final rounding differs.
        let fixed = library.level(1).unwrap();
        for y in 0..levels[1].height {
            for x in 0..levels[1].width {
                let expected = f32::from(fixed.get(x, y).unwrap());
                assert!((levels[1].at(x, y) - expected).abs() <= 0.5);
            }
        }
        assert_eq!(levels[2].width, library.level(2).unwrap().width());
    }

    #[test]
    fn a_linear_ramp_is_preserved_away_from_the_border() {
        let (w, h) = (16, 12);
        let data = (0..w * h).map(|i| (2 * (i % w) + (i / w)) as u8).collect();
        let frame = Frame {
            width: w,
            height: h,
            data,
        };
        let level = &pyramid(&frame, 1)[1];
        // Level-1 pixel (x, y) sits over level-0 pixel (2x, 2y); the kernel is symmetric.
        assert_eq!(level.at(3, 2), (2 * 6 + 4) as f32);
    }
}
