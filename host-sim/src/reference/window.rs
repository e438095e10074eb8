//! Windows around a point: bilinear samples, Scharr gradients and the gradient matrix.

use super::FloatImage;

/// Scharr's 3x3 derivative taps across the derivative axis, normalised so that a ramp of one grey
/// level per pixel has a derivative of exactly 1 (the unnormalised filter has a gain of 32).
const SCHARR_SMOOTH: [f32; 3] = [3.0 / 32.0, 10.0 / 32.0, 3.0 / 32.0];

/// A `side` x `side` grid of values, row by row, centred on a point.
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    /// Samples per row and column (odd).
    pub side: usize,
    /// `side * side` values, row by row.
    pub values: Vec<f32>,
}

impl Window {
    /// Samples `image` bilinearly on the unit grid of `side` x `side` points centred on
    /// (`x`, `y`); samples outside the image repeat the edge pixels.
    pub fn sample(image: &FloatImage, (x, y): (f32, f32), side: usize) -> Self {
        let reach = (side / 2) as f32;
        let mut values = Vec::with_capacity(side * side);
        for row in 0..side {
            for col in 0..side {
                let dx = col as f32 - reach;
                let dy = row as f32 - reach;
                values.push(image.sample(x + dx, y + dy));
            }
        }
        Self { side, values }
    }

    /// The value at (`col`, `row`) of the grid.
    pub fn at(&self, col: usize, row: usize) -> f32 {
        self.values[row * self.side + col]
    }

    /// The mean of the values.
    pub fn mean(&self) -> f32 {
        self.values.iter().sum::<f32>() / self.values.len() as f32
    }
}

/// True when no sample of a `side` x `side` window centred on (`x`, `y`) touches `image`: every
/// source pixel it would read, bilinear neighbours included, lies outside the image.
///
/// The window's samples read columns `floor(x) - side / 2 ..= floor(x) - side / 2 + side`
/// (the last one through the bilinear weight of the rightmost sample), and likewise rows.
pub fn window_misses(image: &FloatImage, (x, y): (f32, f32), side: usize) -> bool {
    let reach = (side / 2) as isize;
    let (left, top) = (x.floor() as isize - reach, y.floor() as isize - reach);
    let side = side as isize;
    left + side < 0
        || top + side < 0
        || left >= image.width as isize
        || top >= image.height as isize
}

/// True when a bilinear sample at (`x`, `y`) reads a pixel outside `image`: its top-left pixel,
/// or the right or lower neighbour that a fractional position also weighs in.
fn reads_outside(image: &FloatImage, x: f32, y: f32) -> bool {
    let reach = |v: f32, n: usize| {
        let base = v.floor();
        let needs_next = v > base;
        base < 0.0 || base + f32::from(u8::from(needs_next)) > (n - 1) as f32
    };
    reach(x, image.width) || reach(y, image.height)
}

/// The template of one point at one pyramid level: the previous frame's window with its
/// gradients, everything that stays fixed while LK iterates.
#[derive(Debug, Clone, PartialEq)]
pub struct Template {
    /// Intensities, grey levels.
    pub intensities: Window,
    /// Horizontal derivative, grey levels per pixel.
    pub dx: Window,
    /// Vertical derivative, grey levels per pixel.
    pub dy: Window,
}

impl Template {
    /// Samples the `side` x `side` template centred on `centre`.
    ///
    /// The derivatives are taken on a patch one sample larger on each side, interpolated like
    /// the window itself, so that the window's border has neighbours to differentiate with.
    pub fn sample(image: &FloatImage, centre: (f32, f32), side: usize) -> Self {
        let patch = Window::sample(image, centre, side + 2);
        let (mut dx, mut dy) = scharr(&patch);
        // Outside the image the sampler repeats edge pixels, which do not move with the scene:
        // samples that read such pixels get zero gradients and drop out of the solve.
        let reach = (side / 2) as f32;
        for i in 0..side * side {
            let x = centre.0 + (i % side) as f32 - reach;
            let y = centre.1 + (i / side) as f32 - reach;
            if reads_outside(image, x, y) {
                dx.values[i] = 0.0;
                dy.values[i] = 0.0;
            }
        }
        let inner = |col: usize, row: usize| patch.at(col + 1, row + 1);
        let intensities = Window {
            side,
            values: (0..side * side)
                .map(|i| inner(i % side, i / side))
                .collect(),
        };
        Self {
            intensities,
            dx,
            dy,
        }
    }

    /// Samples per side.
    pub fn side(&self) -> usize {
        self.intensities.side
    }

    /// The gradient matrix (structure tensor) summed over the window.
    pub fn gradient_matrix(&self) -> GradientMatrix {
        let mut g = GradientMatrix::default();
        for (&gx, &gy) in self.dx.values.iter().zip(&self.dy.values) {
            g.gxx += gx * gx;
            g.gxy += gx * gy;
            g.gyy += gy * gy;
        }
        g
    }
}

/// Scharr derivatives of the inner `side - 2` square of a patch, grey levels per pixel.
pub fn scharr(patch: &Window) -> (Window, Window) {
    let inner = patch.side - 2;
    let mut dx = Vec::with_capacity(inner * inner);
    let mut dy = Vec::with_capacity(inner * inner);
    for row in 1..=inner {
        for col in 1..=inner {
            let mut gx = 0.0;
            let mut gy = 0.0;
            for (k, weight) in SCHARR_SMOOTH.iter().enumerate() {
                // Central difference across the axis, smoothed along it.
                gx += weight * (patch.at(col + 1, row + k - 1) - patch.at(col - 1, row + k - 1));
                gy += weight * (patch.at(col + k - 1, row + 1) - patch.at(col + k - 1, row - 1));
            }
            dx.push(gx);
            dy.push(gy);
        }
    }
    let window = |values| Window {
        side: inner,
        values,
    };
    (window(dx), window(dy))
}

/// The symmetric gradient matrix `G = Σ [Ix² IxIy; IxIy Iy²]` of a window, gradients in grey
/// levels per pixel.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GradientMatrix {
    /// `Σ Ix²`.
    pub gxx: f32,
    /// `Σ Ix Iy`.
    pub gxy: f32,
    /// `Σ Iy²`.
    pub gyy: f32,
}

impl GradientMatrix {
    /// The smaller eigenvalue.
    pub fn min_eigenvalue(&self) -> f32 {
        let half_trace = (self.gxx + self.gyy) / 2.0;
        let half_gap = (self.gxx - self.gyy) / 2.0;
        half_trace - (half_gap * half_gap + self.gxy * self.gxy).sqrt()
    }

    /// The determinant.
    pub fn determinant(&self) -> f32 {
        self.gxx * self.gyy - self.gxy * self.gxy
    }

    /// `-G⁻¹ b`: the LK step for the mismatch vector `b`; `None` when `G` is singular.
    pub fn step(&self, (bx, by): (f32, f32)) -> Option<(f32, f32)> {
        let det = self.determinant();
        if det <= 0.0 {
            return None;
        }
        let x = (self.gyy * bx - self.gxy * by) / det;
        let y = (self.gxx * by - self.gxy * bx) / det;
        Some((-x, -y))
    }
}

/// The smaller eigenvalue of the gradient matrix of the `window` x `window` template centred on
/// (`x`, `y`), divided by the window area: the mean texture strength, in (grey levels per pixel)².
///
/// This is the Shi-Tomasi score LK thresholds; OpenCV's scale (and
/// [`kestrel::lk::LkParams::min_eigen_threshold`]) is this value divided by 1024.
///
/// ```
/// use host_sim::reference::{min_eigenvalue, FloatImage};
/// let flat = FloatImage { width: 40, height: 40, data: vec![50.0; 1600] };
/// assert_eq!(min_eigenvalue(&flat, 20.0, 20.0, 21), 0.0);
/// ```
pub fn min_eigenvalue(image: &FloatImage, x: f32, y: f32, window: usize) -> f32 {
    let template = Template::sample(image, (x, y), window);
    let area = (window * window) as f32;
    template.gradient_matrix().min_eigenvalue() / area
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: usize, height: usize, f: impl Fn(f32, f32) -> f32) -> FloatImage {
        let data = (0..width * height)
            .map(|i| f((i % width) as f32, (i / width) as f32))
            .collect();
        FloatImage {
            width,
            height,
            data,
        }
    }

    #[test]
    fn scharr_of_a_ramp_is_its_slope() {
        let ramp = image(32, 32, |x, y| 3.0 * x + y);
        let template = Template::sample(&ramp, (15.25, 14.5), 5);
        assert!(template.dx.values.iter().all(|&g| (g - 3.0).abs() < 1e-4));
        assert!(template.dy.values.iter().all(|&g| (g - 1.0).abs() < 1e-4));
        assert_eq!(template.intensities.at(2, 2), 3.0 * 15.25 + 14.5);
    }

    #[test]
    fn a_ramp_has_no_second_eigenvalue() {
        let ramp = image(32, 32, |x, y| 3.0 * x + y);
        let g = Template::sample(&ramp, (16.0, 16.0), 7).gradient_matrix();
        assert!((g.gxx - 49.0 * 9.0).abs() < 1e-2);
        assert!(g.min_eigenvalue().abs() < 1e-2);
    }

    #[test]
    fn step_solves_the_two_by_two_system() {
        let g = GradientMatrix {
            gxx: 4.0,
            gxy: 1.0,
            gyy: 3.0,
        };
        let (x, y) = g.step((6.0, 7.0)).unwrap();
        // G (x, y) = -b.
        assert!((4.0 * x + y + 6.0).abs() < 1e-5 && (x + 3.0 * y + 7.0).abs() < 1e-5);
        assert!(GradientMatrix::default().step((1.0, 1.0)).is_none());
    }

    #[test]
    fn window_misses_only_when_no_source_pixel_is_inside() {
        let frame = image(10, 10, |_, _| 0.0);
        // A 5-wide window centred at x reads columns floor(x) - 2 ..= floor(x) + 3.
        assert!(!window_misses(&frame, (-3.0, 5.0), 5));
        assert!(window_misses(&frame, (-4.0, 5.0), 5));
        assert!(!window_misses(&frame, (11.9, 5.0), 5));
        assert!(window_misses(&frame, (12.0, 5.0), 5));
    }
}
