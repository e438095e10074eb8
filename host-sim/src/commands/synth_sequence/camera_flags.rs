//! `synth-sequence`'s camera flags: each effect of the camera model (`crate::synth::camera`)
//! and the ground photograph, all off unless given.

use std::path::PathBuf;

use crate::cli::values::{self, path};
use crate::commands::CommandError;
use crate::io::images::read_grey;
use crate::synth::camera::REFERENCE_EXPOSURE;
use crate::synth::{AutoExposure, Camera, Light, Shutter};
use crate::Frame;

/// The camera flags of `synth-sequence`.
#[derive(Debug, Clone, PartialEq, Default, clap::Args)]
#[command(next_help_heading = "Camera (each effect is off unless its flag is given)")]
pub struct CameraOptions {
    /// a photograph (PNG or JPEG, at most 4096 px a side) as the ground instead of the
    /// procedural texture: in grey, scaled to cover what the flight sees, sampled bilinearly
    #[arg(long, value_name = "IMAGE", value_parser = path)]
    pub scene: Option<PathBuf>,
    /// light level, 0.01 to 100000 lux: photon shot noise and read noise, amplified back to
    /// the ideal brightness (see below); --noise then defaults to 0
    #[arg(long, value_name = "LUX", value_parser = lux)]
    pub light: Option<f64>,
    /// read noise with --light, 0 to 1000 electrons [default: 3]
    #[arg(long, value_name = "E", value_parser = electrons)]
    pub read_noise: Option<f64>,
    /// exposure time, ms, at most a frame interval (1000 / --fps): motion blur, each row
    /// integrating the moving scene over it; with --light, the light collected
    /// [default: an instant, and 10 ms of light for --light]
    #[arg(long, value_name = "MS", value_parser = milliseconds)]
    pub exposure: Option<f64>,
    /// rolling shutter: the rows read one after the other, the last this many ms after the
    /// first, at most a frame interval [default: a global shutter]
    #[arg(long, value_name = "MS", value_parser = milliseconds)]
    pub rolling_shutter: Option<f64>,
    /// vignetting: the share of the brightness lost in the corners, 0 to 1, falling off with
    /// the square of the distance from the centre
    #[arg(long, value_name = "F", value_parser = share)]
    pub vignetting: Option<f64>,
    /// JPEG quality, 1 to 100: each frame encoded as JPEG and decoded back
    #[arg(long, value_name = "Q", value_parser = quality)]
    pub jpeg: Option<u8>,
    /// a sensor K times larger, 1 to 8, each K x K block of its pixels averaged into one frame
    /// pixel (binning: no aliasing; noise and rolling shutter per sensor pixel and row)
    #[arg(long, value_name = "K", value_parser = downscale)]
    pub downscale: Option<usize>,
    /// auto-exposure steps: every 8 frames the gain changes by 3 to 8% (kept within 0.7 to
    /// 1.4) and the black level moves within 4 grey levels, drawn from --seed; listed in
    /// exposure.csv
    #[arg(long)]
    pub auto_exposure: bool,
}

impl CameraOptions {
    /// The camera the flags describe, for frames at `fps` per second, its steps drawn from
    /// `seed`. Flags that are each valid but not together are a usage error.
    pub fn camera(&self, fps: f64, seed: u64) -> Result<Camera, CommandError> {
        if self.read_noise.is_some() && self.light.is_none() {
            return Err(usage(
                "--read-noise: needs --light, the sensor model it belongs to",
            ));
        }
        let shutter = Shutter {
            exposure: frame_share("--exposure", self.exposure, fps)?,
            readout: frame_share("--rolling-shutter", self.rolling_shutter, fps)?,
        };
        Ok(Camera {
            shutter,
            vignetting: self.vignetting.unwrap_or(0.0),
            light: self.light.map(|lux| self.light_model(lux)),
            downscale: self.downscale.unwrap_or(1),
            auto_exposure: self.auto_exposure.then_some(AutoExposure { seed }),
            jpeg_quality: self.jpeg,
        })
    }

    /// The photograph given by --scene, read and in grey.
    pub fn photo(&self) -> Result<Option<Frame>, CommandError> {
        let Some(scene) = &self.scene else {
            return Ok(None);
        };
        Ok(Some(read_grey(scene)?))
    }

    /// The sensor model at `lux`, with the exposure and read noise given.
    fn light_model(&self, lux: f64) -> Light {
        let light = Light::new(lux);
        Light {
            exposure: self.exposure.map_or(REFERENCE_EXPOSURE, |ms| ms / 1000.0),
            read_noise: self.read_noise.unwrap_or(light.read_noise),
            ..light
        }
    }
}

fn usage(line: &str) -> CommandError {
    CommandError::Usage(line.to_owned())
}

/// `ms` as a share of the frame interval at `fps`, which it must not exceed; 0 when not given.
fn frame_share(flag: &str, ms: Option<f64>, fps: f64) -> Result<f64, CommandError> {
    let Some(ms) = ms else {
        return Ok(0.0);
    };
    let interval = 1000.0 / fps;
    match ms <= interval {
        true => Ok(ms / interval),
        false => Err(usage(&format!(
            "{flag}: must not exceed the frame interval, {interval:.3} ms at --fps {fps} (got {ms})"
        ))),
    }
}

fn lux(text: &str) -> Result<f64, String> {
    let range = |v| (0.01..=100_000.0).contains(&v);
    values::number(text, range, "must be between 0.01 and 100000 lux")
}

fn electrons(text: &str) -> Result<f64, String> {
    let range = |v| (0.0..=1000.0).contains(&v);
    values::number(text, range, "must be between 0 and 1000 electrons")
}

fn milliseconds(text: &str) -> Result<f64, String> {
    let range = |v| v > 0.0 && v <= 1000.0;
    values::number(text, range, "must be more than 0 and at most 1000 ms")
}

fn share(text: &str) -> Result<f64, String> {
    let range = |v| (0.0..=1.0).contains(&v);
    values::number(text, range, "must be between 0 and 1")
}

fn quality(text: &str) -> Result<u8, String> {
    let range = |n| (1..=100).contains(&n);
    values::whole(text, range, "must be between 1 and 100").map(|n| n as u8)
}

fn downscale(text: &str) -> Result<usize, String> {
    let range = |n| (1..=8).contains(&n);
    values::whole(text, range, "must be between 1 and 8").map(|n| n as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_shares_of_the_frame_interval() {
        let options = CameraOptions {
            exposure: Some(10.0),
            rolling_shutter: Some(25.0),
            ..CameraOptions::default()
        };
        let camera = options.camera(20.0, 1).unwrap();
        assert_eq!(
            camera.shutter,
            Shutter {
                exposure: 0.2,
                readout: 0.5
            }
        );
        let error = options.camera(50.0, 1).unwrap_err().to_string();
        assert_eq!(
            error,
            "--rolling-shutter: must not exceed the frame interval, 20.000 ms at --fps 50 (got 25)"
        );
    }

    #[test]
    fn no_flag_is_the_ideal_camera_and_read_noise_needs_light() {
        assert_eq!(
            CameraOptions::default().camera(30.0, 4).unwrap(),
            Camera::default()
        );
        let lonely = CameraOptions {
            read_noise: Some(2.0),
            ..CameraOptions::default()
        };
        assert!(matches!(
            lonely.camera(30.0, 4),
            Err(CommandError::Usage(_))
        ));
        let lit = CameraOptions {
            light: Some(50.0),
            exposure: Some(20.0),
            ..CameraOptions::default()
        };
        let light = lit.camera(30.0, 4).unwrap().light.unwrap();
        assert_eq!(
            (light.lux, light.exposure, light.read_noise),
            (50.0, 0.02, 3.0)
        );
    }
}
