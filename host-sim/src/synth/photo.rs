//! A photograph as the ground, instead of the procedural texture (`synth-sequence --scene`).
//!
//! The photograph, in grey, is scaled uniformly so that it covers a given part of the ground
//! plane (the part a flight sees), centred on it, and sampled bilinearly. Beyond its edges the
//! nearest edge pixel's grey is taken (clamping); the covering keeps that to the margins.
//!
//! A photograph much finer than the frames is first reduced with a triangle filter to about
//! one of its pixels per frame pixel, so that sampling it does not alias; a coarser one is
//! magnified as it is, and looks soft.

use image::imageops::{self, FilterType};
use image::GrayImage;

use super::texture::Extent;
use crate::Frame;

/// Photograph pixels per plane unit (frame pixel) above which the photograph is reduced first.
const MAX_DENSITY: f64 = 1.5;

/// A grey photograph laid on the ground plane.
#[derive(Debug, Clone)]
pub struct Photo {
    /// Grey levels, row by row.
    grey: Vec<f32>,
    width: usize,
    height: usize,
    /// Photograph pixels per plane unit.
    density: f64,
    /// The plane point under the photograph's centre.
    centre: (f64, f64),
}

impl Photo {
    /// `photo` scaled to cover `extent` of the plane and centred on it.
    ///
    /// ```
    /// use host_sim::synth::{Extent, Photo};
    /// use host_sim::Frame;
    /// let photo = Frame { width: 2, height: 1, data: vec![0, 200] };
    /// let extent = Extent { left: 0.0, top: 0.0, right: 100.0, bottom: 10.0 };
    /// let ground = Photo::covering(&photo, extent);
    /// assert_eq!(ground.value(50.0, 5.0), 100.0); // halfway between the two pixels
    /// assert_eq!(ground.value(-500.0, 5.0), 0.0); // beyond the edge: the edge pixel
    /// ```
    pub fn covering(photo: &Frame, extent: Extent) -> Self {
        let density = cover_density(photo.width, photo.height, &extent);
        let photo = match density > MAX_DENSITY {
            true => reduce(photo, density),
            false => photo.clone(),
        };
        Self {
            grey: photo.data.iter().map(|&v| f32::from(v)).collect(),
            density: cover_density(photo.width, photo.height, &extent),
            width: photo.width,
            height: photo.height,
            centre: (
                (extent.left + extent.right) / 2.0,
                (extent.top + extent.bottom) / 2.0,
            ),
        }
    }

    /// The grey level at plane point (`u`, `v`), bilinear between the four nearest pixels.
    pub fn value(&self, u: f64, v: f64) -> f64 {
        let x = (u - self.centre.0) * self.density + (self.width as f64 - 1.0) / 2.0;
        let y = (v - self.centre.1) * self.density + (self.height as f64 - 1.0) / 2.0;
        let (x0, fx) = split(x, self.width);
        let (y0, fy) = split(y, self.height);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let at = |x: usize, y: usize| f64::from(self.grey[y * self.width + x]);
        let top = at(x0, y0) + fx * (at(x1, y0) - at(x0, y0));
        let bottom = at(x0, y1) + fx * (at(x1, y1) - at(x0, y1));
        top + fy * (bottom - top)
    }
}

/// The photograph pixels per plane unit that make a `width` x `height` photograph cover
/// `extent`: the smaller of the two axes' ratios, so that the other axis overhangs.
fn cover_density(width: usize, height: usize, extent: &Extent) -> f64 {
    let across = width as f64 / extent.width().max(f64::MIN_POSITIVE);
    let down = height as f64 / extent.height().max(f64::MIN_POSITIVE);
    across.min(down)
}

/// `photo` reduced by `density`, to about one pixel per plane unit.
fn reduce(photo: &Frame, density: f64) -> Frame {
    let side = |n: usize| ((n as f64 / density).round() as u32).max(1);
    let (width, height) = (side(photo.width), side(photo.height));
    let image = GrayImage::from_fn(photo.width as u32, photo.height as u32, |x, y| {
        image::Luma([photo.at(x as usize, y as usize)])
    });
    let reduced = imageops::resize(&image, width, height, FilterType::Triangle);
    Frame {
        width: width as usize,
        height: height as usize,
        data: reduced.into_raw(),
    }
}

/// The pixel at or before position `p` of an axis of `n` pixels, clamped to it, and the
/// fraction of the way to the next one.
fn split(p: f64, n: usize) -> (usize, f64) {
    let p = p.clamp(0.0, (n - 1) as f64);
    let whole = p.floor();
    (whole as usize, p - whole)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(width: usize, height: usize) -> Frame {
        let data = (0..height)
            .flat_map(|_| (0..width).map(|x| (x * 255 / (width - 1)) as u8))
            .collect();
        Frame {
            width,
            height,
            data,
        }
    }

    #[test]
    fn the_photograph_covers_the_extent_on_both_axes() {
        // A 2:1 photograph over a 1:1 extent: its height fits, its width overhangs.
        let extent = Extent {
            left: -10.0,
            top: -10.0,
            right: 90.0,
            bottom: 90.0,
        };
        let photo = Photo::covering(&ramp(200, 100), extent);
        assert_eq!(photo.density, 1.0);
        // The extent's left and right edges fall inside the photograph, not at its ends.
        assert!(photo.value(-10.0, 40.0) > 50.0);
        assert!(photo.value(90.0, 40.0) < 205.0);
        assert!((photo.value(40.0, 40.0) - 127.5).abs() < 1.0);
    }

    #[test]
    fn a_fine_photograph_is_reduced_before_sampling() {
        let extent = Extent {
            left: 0.0,
            top: 0.0,
            right: 50.0,
            bottom: 25.0,
        };
        let photo = Photo::covering(&ramp(400, 200), extent);
        assert_eq!((photo.width, photo.height), (50, 25));
        assert!((photo.density - 1.0).abs() < 1e-12);
        let (left, right) = (photo.value(0.0, 10.0), photo.value(49.0, 10.0));
        assert!(left < 10.0 && right > 245.0, "{left} {right}");
    }
}
