//! `host-sim motion`: moving-object boxes along a sequence.
//!
//! Between each frame and the one before it: grid flow, the camera's dominant motion fitted and
//! removed (a still camera fits to nearly zero, so it needs no flag), the motion mask, its
//! regions and their boxes, moved into the later frame.

use std::ffi::OsString;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use kestrel::dense::regions::MotionBox;

use super::dense::refused;
use super::{median, CommandError};
use crate::dense::picture::motion_overlay;
use crate::dense::{MotionFrame, MotionRunner, MotionSettings};
use crate::io::csv::CsvWriter;
use crate::io::json::JsonObject;
use crate::io::{create_output_dir, AtomicFile, FrameSource, OutputError, Progress};
use crate::Frame;

/// Columns of boxes.csv: the contract's five, then the region's size in grid nodes.
pub const COLUMNS: [&str; 6] = ["frame", "x", "y", "w", "h", "nodes"];

/// Everything `motion` needs, validated by the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionOptions {
    /// The sequence: a directory, a `.y4m` file, or `-` for y4m on standard input.
    pub input: OsString,
    /// CSV of the boxes.
    pub out: PathBuf,
    /// Directory for the pictures, if any.
    pub viz: Option<PathBuf>,
    /// Every setting of the pipeline.
    pub settings: MotionSettings,
    /// Where to write the timing summary, if anywhere.
    pub stats: Option<PathBuf>,
}

/// Runs `motion`. A bad frame stops the run; the boxes of the frames before it are written,
/// then the error is returned.
pub fn run(options: &MotionOptions) -> Result<(), CommandError> {
    let mut out = AtomicFile::create(&options.out)?;
    let mut stats = options
        .stats
        .as_deref()
        .map(AtomicFile::create)
        .transpose()?;
    if let Some(dir) = &options.viz {
        create_output_dir(dir)?;
    }
    let source = FrameSource::open(&options.input)?;
    let name = source.name().to_owned();

    let mut csv = CsvWriter::new(Vec::new(), &COLUMNS).map_err(|e| out.write_error(&e))?;
    let mut pass = Pass::default();
    let outcome = detect(options, source, &name, &mut csv, &mut pass);
    if let Some(progress) = pass.progress.take() {
        progress.finish();
    }

    if pass.frames > 0 {
        out.write_all(&csv.into_inner())
            .map_err(|e| out.write_error(&e))?;
        out.commit()?;
        if let Some(mut stats) = stats.take() {
            let summary = JsonObject::new()
                .integer("frames", pass.frames as u64)
                .number("median_frame_seconds", median(&mut pass.seconds))
                .finish();
            stats
                .write_all(summary.as_bytes())
                .map_err(|e| stats.write_error(&e))?;
            stats.commit()?;
        }
    }
    outcome
}

/// What a run has done so far.
#[derive(Debug, Default)]
struct Pass {
    /// Frames decoded and processed.
    frames: usize,
    /// Library time per frame, s.
    seconds: Vec<f64>,
    progress: Option<Progress>,
}

/// Feeds every frame of `source` to the pipeline, writing boxes (and pictures) as it goes;
/// stops at the first bad frame.
fn detect(
    options: &MotionOptions,
    source: FrameSource,
    name: &str,
    csv: &mut CsvWriter<Vec<u8>>,
    pass: &mut Pass,
) -> Result<(), CommandError> {
    let mut runner: Option<MotionRunner> = None;
    for (index, frame) in source.enumerate() {
        let frame = frame?;
        let (width, height) = (frame.width, frame.height);
        let refused = |e| refused(e, &options.settings.dense, Path::new(name), (width, height));
        let runner = match &mut runner {
            Some(runner) => runner,
            None => {
                runner.insert(MotionRunner::new(options.settings, width, height).map_err(refused)?)
            }
        };
        // The pictures need the later frame after the runner took it.
        let later = options.viz.as_ref().map(|_| frame.clone());
        let start = Instant::now();
        let found = runner.push(frame).map_err(refused)?;
        pass.seconds.push(start.elapsed().as_secs_f64());
        pass.frames += 1;
        pass.progress
            .get_or_insert_with(|| Progress::new("motion", None))
            .update(index + 1);
        let Some(found) = found else {
            continue;
        };
        let boxes = found.boxes_in_later_frame(width, height);
        write_boxes(csv, index, &boxes)
            .map_err(|e| OutputError::new(&options.out, e.to_string()))?;
        if let (Some(dir), Some(later)) = (&options.viz, later) {
            write_picture(dir, index, &later, runner, &found, &boxes)?;
        }
    }
    Ok(())
}

/// One row per box, `frame` being the later frame of the pair.
fn write_boxes(csv: &mut CsvWriter<Vec<u8>>, frame: usize, boxes: &[MotionBox]) -> io::Result<()> {
    for b in boxes {
        csv.record(&[&frame, &b.x, &b.y, &b.w, &b.h, &b.nodes])?;
    }
    Ok(())
}

/// Writes the picture of frame `index`: the frame, the moving cells tinted, the boxes.
fn write_picture(
    dir: &Path,
    index: usize,
    later: &Frame,
    runner: &MotionRunner,
    found: &MotionFrame,
    boxes: &[MotionBox],
) -> Result<(), OutputError> {
    let canvas = motion_overlay(later, runner.layout(), runner.nodes(), &found.mask, boxes);
    canvas.write_png(&dir.join(format!("frame_{index:06}.png")))
}
