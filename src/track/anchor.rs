//! What a track looked like when it was born, and whether it still looks like that.
//!
//! LK follows a track from frame to frame, so its idea of the feature is always one frame old:
//! a window that slides off its feature a little each frame (pushed by the edge of an occluder
//! coming over it, or by an object moving beside it) matches its previous frame well at every
//! step, and no residual or forward-backward check notices. Shi and Tomasi's answer is to
//! compare the feature with its first appearance. An [`Anchor`] keeps a coarse patch of it,
//! 7 x 7 samples 2 px apart, and the tracker drops a track whose patch no longer correlates with
//! it. The correlation is zero-mean and normalised, so lighting changes do not matter, and the
//! patch is sparse so that the slow change of a feature under rotation and zoom matters little.

use crate::frame::ImageView;
use crate::q16::Point;

/// Samples per side of the patch.
const SIDE: usize = 7;
/// Samples in the patch.
const SAMPLES: usize = SIDE * SIDE;
/// Distance between samples, px (a power of two, as a shift).
const SPACING_SHIFT: u32 = 1;

/// The appearance of a track's feature when it was born.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Anchor {
    /// Grey levels, row by row.
    samples: [u8; SAMPLES],
}

impl Anchor {
    /// The patch of `frame` around `position`.
    pub(super) fn capture(frame: &ImageView<'_>, position: Point) -> Self {
        let fine = patch(frame, position);
        // Grey x 16 rounded to grey: 49 bytes a track.
        Self {
            samples: fine.map(|v| (v.saturating_add(8) >> 4).min(255) as u8),
        }
    }

    /// True when the patch of `frame` around `position` correlates with the anchor by at
    /// least `min_correlation` (zero-mean normalised cross-correlation, `-1..=1`). A patch
    /// without any contrast matches nothing: whatever the feature was, it is gone.
    pub(super) fn matches(
        &self,
        frame: &ImageView<'_>,
        position: Point,
        min_correlation: f32,
    ) -> bool {
        let now = patch(frame, position);
        let Moments {
            covariance,
            var_a,
            var_b,
        } = Moments::of(&self.samples, &now);
        if var_a == 0 || var_b == 0 {
            return false;
        }
        // corr >= t  <=>  cov * |cov| >= t * |t| * var_a * var_b, without a square root.
        let (cov, va, vb) = (covariance as f32, var_a as f32, var_b as f32);
        cov * cov.abs() >= min_correlation * min_correlation.abs() * va * vb
    }
}

/// `n` times the covariance and the two variances of two patches: exact integers.
///
/// With samples below 2^12 and 49 of them, every sum stays below 2^18 (squares 2^30) and
/// every product below 2^60: `i64` never overflows.
struct Moments {
    covariance: i64,
    var_a: i64,
    var_b: i64,
}

impl Moments {
    // Bounded as the type's documentation shows: no operation here can overflow.
    #[allow(clippy::arithmetic_side_effects)]
    fn of(a: &[u8; SAMPLES], b: &[u16; SAMPLES]) -> Self {
        let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0i64, 0i64, 0i64, 0i64, 0i64);
        for (&x, &y) in a.iter().zip(b) {
            let (x, y) = (i64::from(x), i64::from(y));
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
            sab += x * y;
        }
        let n = SAMPLES as i64;
        Self {
            covariance: n * sab - sa * sb,
            var_a: n * saa - sa * sa,
            var_b: n * sbb - sb * sb,
        }
    }
}

/// The 7 x 7 samples, 2 px apart, centred on `position`, bilinear, grey x 16.
// `i < SAMPLES = 49`: the sample's column and row are small.
#[allow(clippy::arithmetic_side_effects)]
fn patch(frame: &ImageView<'_>, position: Point) -> [u16; SAMPLES] {
    // SIDE is 7.
    #[allow(clippy::cast_possible_truncation)]
    const HALF: i32 = (SIDE / 2) as i32;
    // Every sample shares the position's fraction, so the weights are computed once.
    let (x, y) = (position.x.to_bits(), position.y.to_bits());
    let weights = Bilinear::new(x, y);
    let (x0, y0) = (x >> 16, y >> 16);
    core::array::from_fn(|i| {
        let at = |v: usize| i32::try_from(v).unwrap_or(0) - HALF;
        let (col, row) = (at(i % SIDE), at(i / SIDE));
        let sx = x0.saturating_add(col << SPACING_SHIFT);
        let sy = y0.saturating_add(row << SPACING_SHIFT);
        weights.sample(frame, sx, sy)
    })
}

/// Bilinear weights of 8 bits for one sub-pixel fraction.
#[derive(Debug, Clone, Copy)]
struct Bilinear {
    fx: u32,
    fy: u32,
}

impl Bilinear {
    fn new(x: i32, y: i32) -> Self {
        // The top 8 of the 16 fraction bits.
        let fraction = |v: i32| ((v & 0xffff) >> 8) as u32;
        Self {
            fx: fraction(x),
            fy: fraction(y),
        }
    }

    /// The frame between pixels (`x`, `y`) and (`x + 1`, `y + 1`), edges repeated, grey x 16.
    // Weights are below 2^8 and grey levels below 2^8: every sum stays below 2^24.
    #[allow(clippy::arithmetic_side_effects)]
    fn sample(&self, frame: &ImageView<'_>, x: i32, y: i32) -> u16 {
        let px = |x: i32, y: i32| u32::from(pixel(frame, x, y));
        let (x1, y1) = (x.saturating_add(1), y.saturating_add(1));
        let top = px(x, y) * (256 - self.fx) + px(x1, y) * self.fx;
        let bottom = px(x, y1) * (256 - self.fx) + px(x1, y1) * self.fx;
        let value = top * (256 - self.fy) + bottom * self.fy;
        // value < 2^24: grey x 2^16, rounded to grey x 16.
        u16::try_from((value + (1 << 11)) >> 12).unwrap_or(u16::MAX)
    }
}

/// The pixel at (`x`, `y`), the nearest edge pixel outside the frame.
fn pixel(frame: &ImageView<'_>, x: i32, y: i32) -> u8 {
    let clamp = |v: i32, size: usize| (v.max(0) as usize).min(size.saturating_sub(1));
    frame
        .get(clamp(x, frame.width()), clamp(y, frame.height()))
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured() -> [u8; 40 * 40] {
        core::array::from_fn(|i| {
            let (x, y) = ((i % 40) as u32, (i / 40) as u32);
            ((x * 37 + y * 91 + (x * y) % 13 * 17) % 251) as u8
        })
    }

    #[test]
    fn a_feature_matches_itself_and_not_its_neighbourhood() {
        let pixels = textured();
        let frame = ImageView::packed(&pixels, 40, 40).unwrap();
        let anchor = Anchor::capture(&frame, Point::from_f32(20.0, 20.0));
        assert!(anchor.matches(&frame, Point::from_f32(20.0, 20.0), 0.999));
        assert!(!anchor.matches(&frame, Point::from_f32(23.0, 20.0), 0.5));
    }

    #[test]
    fn brightness_gain_and_bias_do_not_matter() {
        let pixels = textured();
        let brighter: [u8; 40 * 40] = core::array::from_fn(|i| pixels[i] / 2 + 60);
        let a = ImageView::packed(&pixels, 40, 40).unwrap();
        let b = ImageView::packed(&brighter, 40, 40).unwrap();
        let anchor = Anchor::capture(&a, Point::from_f32(18.0, 21.0));
        assert!(anchor.matches(&b, Point::from_f32(18.0, 21.0), 0.99));
    }

    #[test]
    fn a_flat_patch_matches_nothing() {
        let pixels = textured();
        let flat = [90u8; 40 * 40];
        let a = ImageView::packed(&pixels, 40, 40).unwrap();
        let anchor = Anchor::capture(&a, Point::from_f32(20.0, 20.0));
        let covered = ImageView::packed(&flat, 40, 40).unwrap();
        assert!(!anchor.matches(&covered, Point::from_f32(20.0, 20.0), -1.0));
    }

    #[test]
    fn bilinear_samples_interpolate_and_clamp() {
        let pixels = [0u8, 100, 200, 255];
        let frame = ImageView::packed(&pixels, 2, 2).unwrap();
        let half = Bilinear::new(1 << 15, 0);
        assert_eq!(half.sample(&frame, 0, 0), 50 * 16);
        let none = Bilinear::new(0, 0);
        assert_eq!(none.sample(&frame, 5, 5), 255 * 16);
        assert_eq!(none.sample(&frame, -3, -1), 0);
        let far = Point::from_bits(i32::MAX, i32::MIN);
        assert_eq!(patch(&frame, far).len(), SAMPLES);
    }
}
