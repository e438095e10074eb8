//! The camera between a synthetic scene and its frames: when each row sees the scene
//! ([`Shutter`]: exposure time, rolling shutter), what the lens and the sensor do to the light
//! ([`Vignetting`], [`Light`]: shot and read noise, binning), an auto-exposure loop's steps
//! ([`AutoExposure`]) and lossy compression (JPEG).
//!
//! Each sensor pixel's grey level goes through, in order: the scene averaged over the pixel's
//! area and its row's exposure, vignetting, the auto-exposure gain and bias, shot and read
//! noise at the light level, the scene's additive Gaussian noise; then `downscale` x
//! `downscale` sensor pixels are averaged into one frame pixel (binning), rounded to 8 bits,
//! and the frame goes through JPEG.
//!
//! Frame `k`'s reference instant is `t = k`, the middle of its first row's exposure: the
//! flight's ground truth (homographies, gyro, the objects' boxes) holds at that instant.
//!
//! [`Camera::default`] is the ideal camera: an instant global shutter, no vignetting, no light
//! model, no binning, no steps, no JPEG. Its frames are, bit for bit, the ones host-sim
//! rendered before the camera model existed.

mod auto_exposure;
mod jpeg;
mod sensor;
mod shutter;
mod vignetting;

pub use auto_exposure::AutoExposure;
pub use sensor::{Light, READ_NOISE, REFERENCE_EXPOSURE, REFERENCE_LUX, WHITE_ELECTRONS};
pub use shutter::Shutter;
pub use vignetting::Vignetting;

use super::area_sample;
use super::{Lighting, SplitMix64};
use crate::Frame;

/// A scene a camera films: what it shows at any instant, and how fast its image moves.
pub trait Subject {
    /// The grey level at frame position (`x`, `y`) at instant `t` (frame intervals from frame
    /// 0; frame `k` is at `t = k`).
    fn view(&self, t: f64) -> impl Fn(f64, f64) -> f64 + '_;

    /// How far, at most, any point of the image moves from instant `t0` to `t1`, px.
    fn travel(&self, t0: f64, t1: f64) -> f64;
}

/// The frame a camera takes: its index and size, and the scene's rendering settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shot {
    /// Frame index, from 0.
    pub index: usize,
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Samples per sensor pixel and axis.
    pub supersample: usize,
    /// Standard deviation of the additive Gaussian noise, grey levels (0 for none).
    pub noise_sigma: f64,
    /// Seed of the frame's noise.
    pub noise_seed: u64,
}

/// How a camera turns the scene into frames (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// When each row sees the scene.
    pub shutter: Shutter,
    /// Share of the brightness lost at the frame's corners, 0 to 1.
    pub vignetting: f64,
    /// The light level, for shot and read noise; `None` for none.
    pub light: Option<Light>,
    /// Sensor pixels per frame pixel along each axis, averaged into one (1: none).
    pub downscale: usize,
    /// The auto-exposure loop's steps; `None` for a fixed exposure.
    pub auto_exposure: Option<AutoExposure>,
    /// The quality each frame is JPEG-compressed at; `None` for none.
    pub jpeg_quality: Option<u8>,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            shutter: Shutter::default(),
            vignetting: 0.0,
            light: None,
            downscale: 1,
            auto_exposure: None,
            jpeg_quality: None,
        }
    }
}

impl Camera {
    /// The frame `shot` of `subject`.
    pub fn shoot(&self, shot: &Shot, subject: &impl Subject) -> Frame {
        let frame = Frame {
            width: shot.width,
            height: shot.height,
            data: self.expose(shot, subject),
        };
        match self.jpeg_quality {
            Some(quality) => jpeg::round_trip(&frame, quality),
            None => frame,
        }
    }

    /// The frame's pixels, row by row: each frame row from its bin of sensor rows, each sensor
    /// row from the subject's views at its instants.
    fn expose(&self, shot: &Shot, subject: &impl Subject) -> Vec<u8> {
        let grid = SensorGrid::new(shot, self.downscale);
        let k = shot.index as f64;
        let half = self.shutter.exposure / 2.0;
        let offsets = self
            .shutter
            .exposure_offsets(subject.travel(k - half, k + half));
        let mut darkroom = Darkroom::new(self, shot);
        // A global shutter reads every row at the frame's instant: their views are shared.
        let (mut views, mut views_instant) = (views_at(subject, k, &offsets), k);
        let mut data = Vec::with_capacity(shot.width * shot.height);
        for row in 0..shot.height {
            let mut bins = vec![0.0; shot.width];
            for sensor_row in row * grid.scale..(row + 1) * grid.scale {
                let instant = self.shutter.row_instant(shot.index, sensor_row, grid.rows);
                if instant != views_instant {
                    (views, views_instant) = (views_at(subject, instant, &offsets), instant);
                }
                let radiance = sense_row(&views, &grid, sensor_row, shot.supersample);
                darkroom.develop_row(&radiance, &grid, sensor_row, &mut bins);
            }
            data.extend(bins.into_iter().map(|sum| grid.bin(sum)));
        }
        data
    }
}

/// The views of `subject` at `instant` plus each of the exposure's `offsets`.
fn views_at<'a>(
    subject: &'a impl Subject,
    instant: f64,
    offsets: &[f64],
) -> Vec<impl Fn(f64, f64) -> f64 + 'a> {
    offsets
        .iter()
        .map(|offset| subject.view(instant + offset))
        .collect()
}

/// The radiance of sensor row `row`: each pixel area-sampled on a `supersample` grid in every
/// one of `views`, the instants of its exposure, and averaged over them.
fn sense_row<V: Fn(f64, f64) -> f64>(
    views: &[V],
    grid: &SensorGrid,
    row: usize,
    supersample: usize,
) -> Vec<f64> {
    let y = row as f64;
    let sample = |view: &V| {
        area_sample(grid.width, 1, supersample, |sx, sy| {
            view(grid.to_frame(sx), grid.to_frame(sy + y))
        })
    };
    match views {
        [only] => sample(only),
        views => average(views.iter().map(sample)),
    }
}

/// The sensor's pixels: `scale` x `scale` of them per frame pixel.
struct SensorGrid {
    scale: usize,
    width: usize,
    rows: usize,
}

impl SensorGrid {
    fn new(shot: &Shot, scale: usize) -> Self {
        let scale = scale.max(1);
        Self {
            scale,
            width: shot.width * scale,
            rows: shot.height * scale,
        }
    }

    /// The frame coordinate of sensor coordinate `s` (pixel centres on both sides).
    fn to_frame(&self, s: f64) -> f64 {
        let scale = self.scale as f64;
        s / scale + (0.5 / scale - 0.5)
    }

    /// The 8-bit frame pixel of the `sum` of a bin's sensor pixels.
    fn bin(&self, sum: f64) -> u8 {
        let mean = sum / (self.scale * self.scale) as f64;
        mean.round().clamp(0.0, 255.0) as u8
    }
}

/// The element-wise mean of equally long rows.
fn average(rows: impl ExactSizeIterator<Item = Vec<f64>>) -> Vec<f64> {
    let count = rows.len() as f64;
    let mut sums: Vec<f64> = Vec::new();
    for row in rows {
        sums.resize(row.len(), 0.0);
        sums.iter_mut().zip(row).for_each(|(sum, v)| *sum += v);
    }
    sums.into_iter().map(|sum| sum / count).collect()
}

/// What happens to each sensor pixel's radiance on its way to a grey level, with the frame's
/// random streams.
struct Darkroom {
    lighting: Lighting,
    vignetting: Option<Vignetting>,
    light: Option<Light>,
    noise_sigma: f64,
    /// The additive noise's stream: the stream of the frames before the camera model.
    noise: SplitMix64,
    /// The shot and read noise's stream.
    photons: SplitMix64,
}

impl Darkroom {
    fn new(camera: &Camera, shot: &Shot) -> Self {
        let lighting = camera
            .auto_exposure
            .map_or(Lighting::UNCHANGED, |ae| ae.lighting(shot.index));
        let vignetting = (camera.vignetting > 0.0)
            .then(|| Vignetting::new(camera.vignetting, shot.width, shot.height));
        Self {
            lighting,
            vignetting,
            light: camera.light,
            noise_sigma: shot.noise_sigma,
            noise: SplitMix64::new(shot.noise_seed),
            photons: SplitMix64::substream(shot.noise_seed, 1),
        }
    }

    /// Adds each pixel of sensor row `row`, developed from its `radiance`, to its frame pixel's
    /// bin.
    fn develop_row(&mut self, radiance: &[f64], grid: &SensorGrid, row: usize, bins: &mut [f64]) {
        let y = grid.to_frame(row as f64);
        for (i, &value) in radiance.iter().enumerate() {
            bins[i / grid.scale] += self.develop(value, grid.to_frame(i as f64), y);
        }
    }

    /// The grey level the sensor records for `radiance` at frame position (`x`, `y`).
    fn develop(&mut self, radiance: f64, x: f64, y: f64) -> f64 {
        let through_lens = match &self.vignetting {
            Some(vignetting) => radiance * vignetting.factor(x, y),
            None => radiance,
        };
        let exposed = self.lighting.apply(through_lens);
        let sensed = match &self.light {
            Some(light) => light.sense(exposed, &mut self.photons),
            None => exposed,
        };
        let noise = if self.noise_sigma > 0.0 {
            self.noise_sigma * self.noise.gaussian()
        } else {
            0.0
        };
        sensed + noise
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pattern of period `wavelength` px across x (or y, `vertical`), moving `speed` px per
    /// frame along x, around grey level 128.
    struct Drift {
        speed: f64,
        wavelength: f64,
        vertical: bool,
    }

    impl Subject for Drift {
        fn view(&self, t: f64) -> impl Fn(f64, f64) -> f64 + '_ {
            move |x, y| {
                let along = if self.vertical { y } else { x - self.speed * t };
                128.0 + 100.0 * (std::f64::consts::TAU * along / self.wavelength).sin()
            }
        }

        fn travel(&self, t0: f64, t1: f64) -> f64 {
            self.speed * (t1 - t0).abs()
        }
    }

    /// The subject `delay` frame intervals later.
    struct Later<'a, S>(&'a S, f64);

    impl<S: Subject> Subject for Later<'_, S> {
        fn view(&self, t: f64) -> impl Fn(f64, f64) -> f64 + '_ {
            self.0.view(t + self.1)
        }

        fn travel(&self, t0: f64, t1: f64) -> f64 {
            self.0.travel(t0 + self.1, t1 + self.1)
        }
    }

    fn shot(index: usize, width: usize, height: usize) -> Shot {
        Shot {
            index,
            width,
            height,
            supersample: 2,
            noise_sigma: 0.0,
            noise_seed: 7,
        }
    }

    /// The amplitude of the sinusoid in a frame row: half its range.
    fn amplitude(frame: &Frame, row: usize) -> f64 {
        let line = &frame.data[row * frame.width..(row + 1) * frame.width];
        let (low, high) = (line.iter().min().unwrap(), line.iter().max().unwrap());
        f64::from(high - low) / 2.0
    }

    #[test]
    fn each_row_of_a_rolling_shutter_is_the_scene_at_its_own_instant() {
        let drift = Drift {
            speed: 6.0,
            wavelength: 9.0,
            vertical: false,
        };
        let rolling = Camera {
            shutter: Shutter {
                exposure: 0.0,
                readout: 0.75,
            },
            ..Camera::default()
        };
        let (width, height) = (40, 16);
        let frame = rolling.shoot(&shot(3, width, height), &drift);
        for row in [0, 5, 15] {
            let delay = 0.75 * row as f64 / height as f64;
            let still = Camera::default().shoot(&shot(3, width, height), &Later(&drift, delay));
            let span = row * width..(row + 1) * width;
            assert_eq!(frame.data[span.clone()], still.data[span], "row {row}");
        }
        let global = Camera::default().shoot(&shot(3, width, height), &drift);
        assert_eq!(frame.data[..width], global.data[..width]);
        assert_ne!(frame.data[width * 15..], global.data[width * 15..]);
    }

    #[test]
    fn an_exposure_blurs_along_the_motion_by_its_sinc() {
        // Moving 8 px over a whole-frame exposure, a 16 px sinusoid keeps sinc(pi 8 / 16) =
        // 0.637 of its amplitude; across the motion it keeps all of it.
        let blur = Camera {
            shutter: Shutter {
                exposure: 1.0,
                readout: 0.0,
            },
            ..Camera::default()
        };
        let (along, across) = [false, true]
            .map(|vertical| Drift {
                speed: 8.0,
                wavelength: 16.0,
                vertical,
            })
            .into();
        let sharp = amplitude(&Camera::default().shoot(&shot(2, 64, 4), &along), 1);
        let blurred = amplitude(&blur.shoot(&shot(2, 64, 4), &along), 1);
        let x = std::f64::consts::PI * 8.0 / 16.0;
        assert!(
            (blurred / sharp - x.sin() / x).abs() < 0.02,
            "{blurred} / {sharp}"
        );
        let still = Camera::default().shoot(&shot(2, 4, 64), &across);
        assert_eq!(blur.shoot(&shot(2, 4, 64), &across), still);
    }

    #[test]
    fn binning_averages_sensor_pixels_without_moving_the_image() {
        let drift = Drift {
            speed: 0.0,
            wavelength: 23.0,
            vertical: false,
        };
        let plain = Camera::default().shoot(&shot(0, 48, 8), &drift);
        let binned = Camera {
            downscale: 4,
            ..Camera::default()
        }
        .shoot(&shot(0, 48, 8), &drift);
        let worst = plain
            .data
            .iter()
            .zip(&binned.data)
            .map(|(&a, &b)| (i32::from(a) - i32::from(b)).abs())
            .max();
        assert!(worst <= Some(1), "{worst:?}");
    }

    #[test]
    fn binning_two_by_two_halves_the_shot_noise() {
        let flat = Drift {
            speed: 0.0,
            wavelength: f64::INFINITY,
            vertical: false,
        };
        let spread = |downscale| {
            let camera = Camera {
                light: Some(Light::new(20.0)),
                downscale,
                ..Camera::default()
            };
            let frame = camera.shoot(&shot(0, 100, 100), &flat);
            let n = frame.data.len() as f64;
            let mean = frame.data.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
            let variance = frame
                .data
                .iter()
                .map(|&v| (f64::from(v) - mean).powi(2))
                .sum::<f64>()
                / n;
            variance.sqrt()
        };
        let (one, two) = (spread(1), spread(2));
        let modelled = Light::new(20.0).noise_at(128.0);
        assert!((one / modelled - 1.0).abs() < 0.05, "{one} vs {modelled}");
        assert!((two / one - 0.5).abs() < 0.05, "{two} vs {one}");
    }
}
