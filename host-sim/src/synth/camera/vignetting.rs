//! Vignetting: the lens lets less light through towards the corners of the frame.

/// A quadratic radial falloff: the brightness at distance `r` from the frame centre is
/// multiplied by `1 - loss * (r / r_corner)²`, so the corner pixels keep `1 - loss` of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vignetting {
    /// Share of the brightness lost at the corners, 0 to 1.
    pub loss: f64,
    /// The frame centre, px.
    centre: (f64, f64),
    /// Squared distance from the centre to the corner pixels' centres, px².
    corner_squared: f64,
}

impl Vignetting {
    /// `loss` at the corners of a `width` x `height` frame.
    pub fn new(loss: f64, width: usize, height: usize) -> Self {
        let centre = ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0);
        Self {
            loss,
            centre,
            corner_squared: (centre.0 * centre.0 + centre.1 * centre.1).max(f64::MIN_POSITIVE),
        }
    }

    /// The share of the light that reaches frame position (`x`, `y`).
    ///
    /// ```
    /// use host_sim::synth::Vignetting;
    /// let lens = Vignetting::new(0.4, 101, 51);
    /// assert_eq!(lens.factor(50.0, 25.0), 1.0);
    /// assert!((lens.factor(0.0, 0.0) - 0.6).abs() < 1e-12);
    /// ```
    pub fn factor(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.centre.0, y - self.centre.1);
        1.0 - self.loss * (dx * dx + dy * dy) / self.corner_squared
    }
}
