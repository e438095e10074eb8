//! `host-sim synth-sequence`: a seeded synthetic flight with exact ground truth, for
//! `egomotion` and `stabilize` and the scripts that check them.
//!
//! DIR receives `frames/frame_NNNNN.png`, `truth.csv` (the exact homography of every frame
//! pair, in ego.csv's layout) and, for paths that turn at a constant rate, `gyro.csv` (the exact
//! body rates, sampled every millisecond from frame 0 to the last frame, in the layout
//! `egomotion --gyro` reads).

use std::fmt::Write as _;
use std::path::PathBuf;

use super::CommandError;
use crate::egomotion::FrameClock;
use crate::io::atomic::write_atomically;
use crate::io::images::write_png;
use crate::io::{create_output_dir, Progress};
use crate::synth::{FlightPath, FlightSequence, SceneSpec};

/// Everything `synth-sequence` needs, validated by the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthSequenceOptions {
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// The camera's path.
    pub path: FlightPath,
    /// Number of frames, at least 2.
    pub frames: usize,
    /// Frame width in px.
    pub width: usize,
    /// Frame height in px.
    pub height: usize,
    /// Seed of the scene, the path and the objects.
    pub seed: u64,
    /// Independently moving objects drawn over the scene.
    pub objects: usize,
    /// Sensor noise, grey levels (standard deviation).
    pub noise: f64,
    /// Frame rate, for the gyro log's clock.
    pub fps: f64,
}

/// Gyro samples per second in gyro.csv.
const GYRO_RATE_HZ: u64 = 1000;

/// Runs `synth-sequence`.
pub fn run(options: &SynthSequenceOptions) -> Result<(), CommandError> {
    let frames_dir = options.out.join("frames");
    create_output_dir(&frames_dir)?;
    let spec =
        SceneSpec::new(options.width, options.height, options.seed).with_noise(options.noise);
    let sequence = FlightSequence::new(spec, options.path, options.objects);
    let mut progress = Progress::new("synth-sequence", Some(options.frames));
    for k in 0..options.frames {
        write_png(&frames_dir.join(frame_name(k)), &sequence.frame(k))?;
        progress.update(k + 1);
    }
    progress.finish();
    write_atomically(
        &options.out.join("truth.csv"),
        truth_csv(&sequence, options.frames).as_bytes(),
    )?;
    let clock = FrameClock::new(options.fps);
    if let Some(rates) = sequence.flight().body_rates(options.fps) {
        let end_us = clock.time_us(options.frames - 1);
        write_atomically(
            &options.out.join("gyro.csv"),
            gyro_csv(rates, end_us).as_bytes(),
        )?;
    }
    Ok(())
}

/// The file name of frame `k`: zero-padded, so file-name order is frame order.
pub fn frame_name(k: usize) -> String {
    format!("frame_{k:05}.png")
}

/// `frame,h11,...,h33`: the homography from frame-1 to frame for every pair, exact to f64.
fn truth_csv(sequence: &FlightSequence, frames: usize) -> String {
    let mut text = String::from("frame,h11,h12,h13,h21,h22,h23,h31,h32,h33\n");
    for k in 1..frames {
        let m = sequence.flight().pair_homography(k).m;
        let entries: Vec<String> = m.iter().flatten().map(|v| format!("{v:e}")).collect();
        let _ = writeln!(text, "{k},{}", entries.join(","));
    }
    text
}

/// `t_us,gx,gy,gz` every millisecond from 0 to `end_us` (and at `end_us`), constant `rates`.
fn gyro_csv(rates: [f64; 3], end_us: u64) -> String {
    let step = 1_000_000 / GYRO_RATE_HZ;
    let mut text = String::from("t_us,gx,gy,gz\n");
    let mut times: Vec<u64> = (0..=end_us).step_by(step as usize).collect();
    if times.last() != Some(&end_us) {
        times.push(end_us);
    }
    for t in times {
        let _ = writeln!(text, "{t},{:e},{:e},{:e}", rates[0], rates[1], rates[2]);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gyro_log_covers_every_frame() {
        let text = gyro_csv([1.0, -0.5, 0.0], 2_500);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t_us,gx,gy,gz");
        assert_eq!(lines[1], "0,1e0,-5e-1,0e0");
        assert_eq!(lines.last().unwrap().split(',').next(), Some("2500"));
        assert_eq!(lines.len(), 1 + 4);
    }

    #[test]
    fn frame_names_sort_in_frame_order() {
        assert!(frame_name(9) < frame_name(10));
        assert_eq!(frame_name(3), "frame_00003.png");
    }
}
