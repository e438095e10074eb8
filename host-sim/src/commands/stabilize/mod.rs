//! `host-sim stabilize`: camera-motion-compensated frames (video stabilization).
//!
//! The motion of every frame pair is measured like `egomotion` does; a pair whose fit fails
//! is taken to move like the last pair that was measured (the camera keeps its course), which
//! keeps the path continuous. See [`crate::stabilize`] for the smoothing and the warp.

mod path;
mod stabilizer;
mod warp;

pub use path::PathPoint;
pub use stabilizer::Stabilizer;
pub use warp::warp_bilinear;

use std::ffi::OsString;
use std::path::PathBuf;

use kestrel::ego::ModelKind;

use super::egomotion::{max_points, model, threshold};
use super::motion::{input, INPUT_HELP};
use super::synth_sequence::frame_name;
use super::CommandError;
use crate::cli::values::{self, path};
use crate::egomotion::{EstimatorSettings, MotionEstimator, DEFAULT_MAX_POINTS, DEFAULT_THRESHOLD};
use crate::io::images::write_png;
use crate::io::{create_output_dir, FrameSource, Progress};
use crate::synth::Homography;
use crate::Frame;

/// Frames on each side of a frame that its smoothed camera position is averaged over, unless
/// told otherwise: half a second at 30 frames per second.
pub const DEFAULT_SMOOTHING: usize = 15;

/// `host-sim stabilize`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "write camera-motion-compensated frames (video stabilization)",
    before_help = "host-sim stabilize: write camera-motion-compensated frames (video stabilization).

The camera's motion between frames is measured like 'host-sim egomotion' does and chained
into its path; the path's shift, rotation and scale about the frame centre are averaged over
a window of frames centred on each frame; and each frame is warped (bilinear, black outside)
to the view of the averaged path. A steady pan, turn or zoom is kept, shake is removed. A
frame pair whose fit fails is taken to move like the last pair measured.",
    after_help = "At most N + 1 frames are held in memory. A bad frame stops the run; the frames before it are
written.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line."
)]
pub struct StabilizeOptions {
    #[arg(value_name = "INPUT", value_parser = input, help = INPUT_HELP)]
    pub input: OsString,
    /// output directory, created if missing: frame_00000.png, frame_00001.png, ... (8-bit
    /// grey, the input's size, in input order)
    #[arg(long, value_name = "DIR", value_parser = path)]
    pub out: PathBuf,
    /// translation, similarity, affine or homography
    #[arg(long, value_name = "M", default_value = "similarity", value_parser = model)]
    pub model: ModelKind,
    /// frames on each side of a frame that its path is averaged over, 1 to 1000; near the ends
    /// of the sequence the window shrinks to stay centred
    #[arg(long, value_name = "N", default_value_t = DEFAULT_SMOOTHING, value_parser = smoothing)]
    pub smoothing: usize,
    /// points tracked per pair, 8 to 2000
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_POINTS, value_parser = max_points)]
    pub max_points: usize,
    /// RANSAC inlier threshold, 0.05 to 100 px
    #[arg(long, value_name = "PX", default_value_t = DEFAULT_THRESHOLD, value_parser = threshold)]
    pub threshold: f32,
}

impl StabilizeOptions {
    /// How motion is measured.
    pub fn settings(&self) -> EstimatorSettings {
        EstimatorSettings {
            model: self.model,
            max_points: self.max_points,
            threshold: self.threshold,
            ..EstimatorSettings::default()
        }
    }
}

fn smoothing(text: &str) -> Result<usize, String> {
    let range = |n| (1..=1000).contains(&n);
    values::whole(text, range, "must be between 1 and 1000 frames").map(|n| n as usize)
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
                    MotionEstimator::new(&self.options.settings(), frame.width, frame.height)
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
