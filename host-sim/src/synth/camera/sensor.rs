//! The sensor's noise at a light level: photon shot noise and read noise.
//!
//! The model: a pixel of grey level `g` (0 to 255, what an ideal camera would record) collects
//! on average `g / 255 * WHITE_ELECTRONS * (lux / REFERENCE_LUX) * (exposure /
//! REFERENCE_EXPOSURE)` electrons, 10,000 for white at 1,000 lux and 10 ms. The count is
//! Poisson (shot noise), and reading it adds Gaussian read noise of a few electrons. The gain
//! that follows turns the mean back into `g` (the auto exposure holds the mean brightness), so
//! it amplifies the noise in low light: the noise's variance in grey levels is
//! `g / e + (read / e)²` with `e` electrons per grey level. The well's capacity is not
//! modelled.

use crate::synth::SplitMix64;

/// Electrons a white pixel (grey 255) collects at the reference light and exposure.
pub const WHITE_ELECTRONS: f64 = 10_000.0;
/// The reference light level, lux.
pub const REFERENCE_LUX: f64 = 1_000.0;
/// The reference exposure time, seconds (also the exposure assumed when none is given).
pub const REFERENCE_EXPOSURE: f64 = 0.010;
/// Read noise of a small CMOS sensor, electrons.
pub const READ_NOISE: f64 = 3.0;
/// Mean electron count up to which the shot noise is drawn exactly; above it, a normal draw of
/// the same mean and variance, which the Poisson law is close to by then.
const EXACT_POISSON_MEAN: f64 = 30.0;

/// A light level and the sensor's noise at it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// Illuminance, lux.
    pub lux: f64,
    /// Exposure time, seconds.
    pub exposure: f64,
    /// Read noise, electrons.
    pub read_noise: f64,
}

impl Light {
    /// `lux` with the reference exposure and the default read noise.
    pub fn new(lux: f64) -> Self {
        Self {
            lux,
            exposure: REFERENCE_EXPOSURE,
            read_noise: READ_NOISE,
        }
    }

    /// Mean electrons per grey level.
    ///
    /// ```
    /// use host_sim::synth::Light;
    /// assert_eq!(Light::new(1000.0).electrons_per_grey() * 255.0, 10_000.0);
    /// ```
    pub fn electrons_per_grey(&self) -> f64 {
        WHITE_ELECTRONS / 255.0 * (self.lux / REFERENCE_LUX) * (self.exposure / REFERENCE_EXPOSURE)
    }

    /// The grey level the sensor records for a pixel whose ideal grey level is `grey`.
    pub fn sense(&self, grey: f64, rng: &mut SplitMix64) -> f64 {
        let per_grey = self.electrons_per_grey();
        let electrons = poisson(grey.max(0.0) * per_grey, rng) + self.read_noise * rng.gaussian();
        electrons / per_grey
    }

    /// The standard deviation of [`Light::sense`] at `grey`, grey levels.
    ///
    /// ```
    /// use host_sim::synth::Light;
    /// let dim = Light { read_noise: 0.0, ..Light::new(10.0) };
    /// // 100 electrons per white pixel: 50 at mid grey, a tenth of which is the shot noise.
    /// assert!((dim.noise_at(127.5) - 127.5 / 50f64.sqrt()).abs() < 1e-9);
    /// ```
    pub fn noise_at(&self, grey: f64) -> f64 {
        let per_grey = self.electrons_per_grey();
        (grey.max(0.0) / per_grey + (self.read_noise / per_grey).powi(2)).sqrt()
    }
}

/// A Poisson draw of mean `mean` (see [`EXACT_POISSON_MEAN`]).
fn poisson(mean: f64, rng: &mut SplitMix64) -> f64 {
    if mean <= 0.0 {
        return 0.0;
    }
    if mean > EXACT_POISSON_MEAN {
        return (mean + mean.sqrt() * rng.gaussian()).round().max(0.0);
    }
    // Knuth: the number of uniform draws whose product stays above e^-mean.
    let limit = (-mean).exp();
    let (mut count, mut product) = (0.0, rng.next_f64());
    while product > limit {
        count += 1.0;
        product *= rng.next_f64();
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moments(draws: &[f64]) -> (f64, f64) {
        let n = draws.len() as f64;
        let mean = draws.iter().sum::<f64>() / n;
        let variance = draws.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n;
        (mean, variance)
    }

    #[test]
    fn poisson_draws_have_the_mean_as_their_variance() {
        let mut rng = SplitMix64::new(3);
        for mean in [0.5, 4.0, 25.0, 400.0] {
            let draws: Vec<f64> = (0..40_000).map(|_| poisson(mean, &mut rng)).collect();
            let (m, v) = moments(&draws);
            assert!((m - mean).abs() < 0.03 * mean.max(1.0), "{mean}: mean {m}");
            assert!(
                (v - mean).abs() < 0.05 * mean.max(1.0),
                "{mean}: variance {v}"
            );
        }
        assert_eq!(poisson(0.0, &mut rng), 0.0);
    }

    #[test]
    fn the_noise_at_mid_grey_is_what_the_help_says() {
        // host-sim synth-sequence --help quotes these: 1.8, 7.5 and 30 grey levels.
        let sigma = |lux| Light::new(lux).noise_at(127.5);
        assert!((sigma(1000.0) - 1.80).abs() < 0.01, "{}", sigma(1000.0));
        assert!((sigma(60.0) - 7.47).abs() < 0.01, "{}", sigma(60.0));
        assert!((sigma(5.0) - 29.74).abs() < 0.01, "{}", sigma(5.0));
    }

    #[test]
    fn the_sensed_grey_keeps_its_mean_and_has_the_modelled_noise() {
        let mut rng = SplitMix64::new(9);
        let light = Light::new(20.0);
        for grey in [20.0, 100.0, 200.0] {
            let draws: Vec<f64> = (0..40_000).map(|_| light.sense(grey, &mut rng)).collect();
            let (m, v) = moments(&draws);
            let sigma = light.noise_at(grey);
            assert!((m - grey).abs() < 0.05 * sigma, "{grey}: mean {m}");
            assert!(
                (v.sqrt() / sigma - 1.0).abs() < 0.03,
                "{grey}: {} vs {sigma}",
                v.sqrt()
            );
        }
    }
}
