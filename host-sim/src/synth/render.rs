//! From a continuous scene to 8-bit frames: area sampling, lighting, sensor noise, quantisation.

use super::rng::SplitMix64;
use crate::Frame;

/// The brightness of a frame relative to the scene: `I' = gain * I + bias`, saturating to 0..255
/// (auto-exposure, a cloud).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Multiplies the scene's grey levels.
    pub gain: f64,
    /// Added after the gain, grey levels.
    pub bias: f64,
}

impl Lighting {
    /// The scene as it is.
    pub const UNCHANGED: Self = Self {
        gain: 1.0,
        bias: 0.0,
    };

    /// `gain * value + bias`.
    pub fn apply(&self, value: f64) -> f64 {
        self.gain * value + self.bias
    }
}

impl Default for Lighting {
    fn default() -> Self {
        Self::UNCHANGED
    }
}

/// The mean of `scene` over every pixel of a `width` x `height` frame, estimated on a
/// `supersample` x `supersample` grid per pixel, row by row.
///
/// `scene(x, y)` is the grey level at frame position (`x`, `y`), origin at the centre of the
/// top-left pixel; pixel (`i`, `j`) covers `[i - 1/2, i + 1/2] x [j - 1/2, j + 1/2]`. Averaging
/// over the pixel's area is what a sensor does and keeps sharp edges from aliasing.
pub fn area_sample(
    width: usize,
    height: usize,
    supersample: usize,
    scene: impl Fn(f64, f64) -> f64,
) -> Vec<f64> {
    let n = supersample.max(1);
    // Sub-sample offsets from the pixel centre, symmetric about it.
    let offsets: Vec<f64> = (0..n).map(|k| (k as f64 + 0.5) / n as f64 - 0.5).collect();
    let mut out = Vec::with_capacity(width * height);
    for j in 0..height {
        for i in 0..width {
            let mut sum = 0.0;
            for dy in &offsets {
                for dx in &offsets {
                    sum += scene(i as f64 + dx, j as f64 + dy);
                }
            }
            out.push(sum / (n * n) as f64);
        }
    }
    out
}

/// What the sensor adds to the scene: lighting, Gaussian noise, rounding and saturation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exposure {
    /// The frame's lighting.
    pub lighting: Lighting,
    /// Standard deviation of the additive noise, grey levels (0 for none).
    pub noise_sigma: f64,
    /// Seed of the noise; frames with different seeds get independent noise.
    pub noise_seed: u64,
}

impl Exposure {
    /// Turns grey levels (as from [`area_sample`]) into an 8-bit frame.
    pub fn develop(&self, width: usize, height: usize, radiance: &[f64]) -> Frame {
        assert_eq!(radiance.len(), width * height, "one grey level per pixel");
        let mut rng = SplitMix64::new(self.noise_seed);
        let data = radiance
            .iter()
            .map(|&v| {
                let noise = if self.noise_sigma > 0.0 {
                    self.noise_sigma * rng.gaussian()
                } else {
                    0.0
                };
                (self.lighting.apply(v) + noise).round().clamp(0.0, 255.0) as u8
            })
            .collect();
        Frame {
            width,
            height,
            data,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_sampling_averages_over_the_pixel() {
        // A vertical step at x = 2.0 splits pixel 2 in half.
        let step = |x: f64, _: f64| if x < 2.0 { 0.0 } else { 100.0 };
        let v = area_sample(4, 1, 4, step);
        assert_eq!(v, vec![0.0, 0.0, 50.0, 100.0]);
        // A linear ramp is unchanged by area sampling.
        let ramp = area_sample(3, 2, 3, |x, y| 10.0 * x + y);
        assert!((ramp[4] - 11.0).abs() < 1e-12);
    }

    #[test]
    fn lighting_and_noise_then_saturation() {
        let exposure = Exposure {
            lighting: Lighting {
                gain: 1.25,
                bias: 15.0,
            },
            noise_sigma: 0.0,
            noise_seed: 0,
        };
        let frame = exposure.develop(3, 1, &[0.0, 100.0, 250.0]);
        assert_eq!(frame.data, vec![15, 140, 255]);
        let noisy = Exposure {
            noise_sigma: 2.0,
            ..exposure
        };
        let a = noisy.develop(3, 1, &[100.0; 3]);
        assert_eq!(a, noisy.develop(3, 1, &[100.0; 3]));
        assert!(a.data.iter().all(|&p| (130..=150).contains(&p)));
    }
}
