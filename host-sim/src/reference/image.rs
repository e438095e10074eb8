//! Grey images with `f32` pixels and bilinear sampling.

use crate::Frame;

/// A grey image with `f32` pixels in grey levels (nominally 0..255), row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct FloatImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` pixels, row by row.
    pub data: Vec<f32>,
}

impl FloatImage {
    /// The frame's pixels as `f32`.
    pub fn from_frame(frame: &Frame) -> Self {
        Self {
            width: frame.width,
            height: frame.height,
            data: frame.data.iter().map(|&p| f32::from(p)).collect(),
        }
    }

    /// The pixel at (`x`, `y`); panics outside the image.
    pub fn at(&self, x: usize, y: usize) -> f32 {
        assert!(
            x < self.width && y < self.height,
            "({x}, {y}) is outside the image"
        );
        self.data[y * self.width + x]
    }

    /// The pixel at (`x`, `y`) with both coordinates clamped to the image, so that the edge
    /// pixels repeat outwards without end (the border rule of the library's window sampling).
    pub fn clamped(&self, x: isize, y: isize) -> f32 {
        let x = x.clamp(0, self.width as isize - 1) as usize;
        let y = y.clamp(0, self.height as isize - 1) as usize;
        self.data[y * self.width + x]
    }

    /// Bilinear interpolation at (`x`, `y`), in pixel coordinates whose origin is the centre of
    /// the top-left pixel; outside the image the edge pixels repeat.
    ///
    /// ```
    /// use host_sim::reference::FloatImage;
    /// let image = FloatImage { width: 2, height: 1, data: vec![10.0, 20.0] };
    /// assert_eq!(image.sample(0.25, 0.0), 12.5);
    /// assert_eq!(image.sample(-3.0, 7.0), 10.0);
    /// ```
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        let (left, top) = (x.floor(), y.floor());
        let (fx, fy) = (x - left, y - top);
        let (col, row) = (left as isize, top as isize);
        let upper = lerp(self.clamped(col, row), self.clamped(col + 1, row), fx);
        let lower = lerp(
            self.clamped(col, row + 1),
            self.clamped(col + 1, row + 1),
            fx,
        );
        lerp(upper, lower, fy)
    }

    /// True when (`x`, `y`) lies within the pixel centres: `[0, w - 1] x [0, h - 1]`.
    pub fn contains(&self, x: f32, y: f32) -> bool {
        let max_x = (self.width - 1) as f32;
        let max_y = (self.height - 1) as f32;
        (0.0..=max_x).contains(&x) && (0.0..=max_y).contains(&y)
    }
}

/// `a` moved a fraction `t` of the way towards `b`.
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> FloatImage {
        let (width, height) = (8, 6);
        let data = (0..width * height)
            .map(|i| (3 * (i % width) + (i / width)) as f32)
            .collect();
        FloatImage {
            width,
            height,
            data,
        }
    }

    #[test]
    fn bilinear_sample_of_a_ramp_is_exact_inside() {
        let image = ramp();
        assert_eq!(image.sample(2.25, 3.5), 3.0 * 2.25 + 3.5);
        assert_eq!(image.sample(6.0, 5.0), 23.0);
    }

    #[test]
    fn samples_outside_repeat_the_edge() {
        let image = ramp();
        assert_eq!(image.sample(-2.5, 0.0), 0.0);
        assert_eq!(image.sample(7.0, 9.75), 26.0);
        assert_eq!(image.sample(100.0, -100.0), 21.0);
    }

    #[test]
    fn contains_the_pixel_centres_only() {
        let image = ramp();
        assert!(image.contains(0.0, 0.0) && image.contains(7.0, 5.0));
        assert!(!image.contains(-0.01, 2.0) && !image.contains(7.01, 2.0));
        assert!(!image.contains(f32::NAN, 2.0));
    }
}
