//! Where to evaluate a tracker: grids of points and the textured ones among them.

use crate::reference::{min_eigenvalue, FloatImage};
use crate::Frame;

/// Points on a regular grid `step` px apart, at least `margin` px from every edge of a `width` x
/// `height` frame (pixel-centre coordinates), row by row.
///
/// ```
/// use host_sim::synth::grid_points;
/// assert_eq!(grid_points(30, 20, 8, 5.0), vec![(5.0, 5.0), (13.0, 5.0), (21.0, 5.0),
///                                              (5.0, 13.0), (13.0, 13.0), (21.0, 13.0)]);
/// ```
pub fn grid_points(width: usize, height: usize, step: usize, margin: f32) -> Vec<(f32, f32)> {
    let axis = |size: usize| {
        let last = size as f32 - 1.0 - margin;
        (0..)
            .map(move |k| margin + (k * step) as f32)
            .take_while(move |&v| v <= last)
    };
    axis(height)
        .flat_map(|y| axis(width).map(move |x| (x, y)))
        .collect()
}

/// The candidates whose `window` x `window` template in `frame` has a smaller gradient-matrix
/// eigenvalue per pixel of at least `min_strength` (grey levels per pixel, squared): the points
/// where a tracker can be expected to work, as a Shi-Tomasi detector would choose them.
///
/// For scale: OpenCV's default LK threshold (1e-4 in its units) is a strength of about 0.1; a
/// strength of 25 means gradients of about 5 grey levels per pixel in every direction.
pub fn textured_points(
    frame: &Frame,
    candidates: &[(f32, f32)],
    window: usize,
    min_strength: f32,
) -> Vec<(f32, f32)> {
    let image = FloatImage::from_frame(frame);
    candidates
        .iter()
        .copied()
        .filter(|&(x, y)| min_eigenvalue(&image, x, y, window) >= min_strength)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_respects_the_margin() {
        let points = grid_points(100, 50, 10, 12.0);
        assert!(points
            .iter()
            .all(|&(x, y)| (12.0..=87.0).contains(&x) && (12.0..=37.0).contains(&y)));
        assert_eq!(points.len(), 8 * 3);
        assert!(grid_points(10, 10, 4, 6.0).is_empty());
    }

    #[test]
    fn flat_halves_are_not_textured() {
        // Left half flat, right half a checkerboard of 4-px squares.
        let (w, h) = (64, 32);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if x < 32 {
                    90
                } else if (x / 4 + y / 4) % 2 == 0 {
                    40
                } else {
                    160
                }
            })
            .collect();
        let frame = Frame {
            width: w,
            height: h,
            data,
        };
        let picked = textured_points(&frame, &[(10.0, 16.0), (48.0, 16.0)], 9, 10.0);
        assert_eq!(picked, vec![(48.0, 16.0)]);
    }
}
