//! `host-sim stabilize`: camera-motion-compensated frames (video stabilization).
//!
//! The motion of every frame pair is measured like `egomotion` does; a pair whose fit fails
//! is taken to move like the last pair that was measured (the camera keeps its course), which
//! keeps the path continuous. See [`crate::stabilize`] for the smoothing and the warp.

use std::ffi::OsString;
use std::path::PathBuf;

use super::synth_sequence::frame_name;
use super::CommandError;
use crate::egomotion::{EstimatorSettings, MotionEstimator};
use crate::io::images::write_png;
use crate::io::{create_output_dir, FrameSource, Progress};
use crate::stabilize::Stabilizer;
use crate::synth::Homography;
use crate::Frame;

/// Frames on each side of a frame that its smoothed camera position is averaged over, unless
/// told otherwise: half a second at 30 frames per second.
pub const DEFAULT_SMOOTHING: usize = 15;

/// Everything `stabilize` needs, validated by the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct StabilizeOptions {
    /// The sequence: a directory of frames, a y4m file, or `-` for y4m on stdin.
    pub input: OsString,
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// How motion is measured.
    pub settings: EstimatorSettings,
    /// Averaging radius in frames.
    pub smoothing: usize,
}

/// Runs `stabilize`. Frames are written as soon as they are stabilized; a bad frame stops the
/// run after the frames before it are written.
pub fn run(options: &StabilizeOptions) -> Result<(), CommandError> {
    let source = FrameSource::open(&options.input)?;
    create_output_dir(&options.out)?;
    let mut run = StabilizeRun::new(options);
    let mut progress = Progress::new("stabilize", source.frame_count());
    let mut failure = None;
    for (index, frame) in source.enumerate() {
        let step = frame
            .map_err(CommandError::from)
            .and_then(|frame| run.push(index, frame));
        if let Err(error) = step {
            failure = Some(error);
            break;
        }
        progress.update(index + 1);
    }
    progress.finish();
    run.finish()?;
    failure.map_or(Ok(()), Err)
}

/// The state carried from frame to frame.
struct StabilizeRun<'a> {
    options: &'a StabilizeOptions,
    /// Made for the first frame's size.
    state: Option<(MotionEstimator, Stabilizer)>,
    /// The last motion measured, used for pairs whose fit fails.
    last_motion: Homography,
}

impl<'a> StabilizeRun<'a> {
    fn new(options: &'a StabilizeOptions) -> Self {
        Self {
            options,
            state: None,
            last_motion: Homography::IDENTITY,
        }
    }

    fn push(&mut self, index: usize, frame: Frame) -> Result<(), CommandError> {
        let failed =
            |problem: String| CommandError::Processing(format!("frame {index}: {problem}"));
        let (estimator, stabilizer) = match &mut self.state {
            Some(state) => state,
            None => {
                let estimator =
                    MotionEstimator::new(&self.options.settings, frame.width, frame.height)
                        .map_err(failed)?;
                let stabilizer = Stabilizer::new(self.options.smoothing, frame.width, frame.height);
                self.state.insert((estimator, stabilizer))
            }
        };
        if let Some(pair) = estimator.push(frame.clone(), None).map_err(failed)? {
            if pair.motion.is_ok() {
                self.last_motion = to_f64(&pair.motion.model);
            }
        }
        let ready = stabilizer.push(frame, &self.last_motion);
        write_frames(&self.options.out, ready)
    }

    /// Writes the frames still waiting for the path ahead of them.
    fn finish(self) -> Result<(), CommandError> {
        match self.state {
            Some((_, stabilizer)) => write_frames(&self.options.out, stabilizer.finish()),
            None => Ok(()),
        }
    }
}

fn write_frames(dir: &std::path::Path, frames: Vec<(usize, Frame)>) -> Result<(), CommandError> {
    for (index, frame) in frames {
        write_png(&dir.join(frame_name(index)), &frame)?;
    }
    Ok(())
}

/// The library's `f32` homography in `f64`, for chaining over long sequences.
fn to_f64(model: &kestrel::ego::Homography) -> Homography {
    let m = model.matrix().map(f64::from);
    Homography {
        m: [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]],
    }
}
