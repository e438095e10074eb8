//! `host-sim motion`: moving-object boxes along a sequence.
//!
//! Between each frame and the one before it: grid flow, the camera's dominant motion fitted and
//! removed (a still camera fits to nearly zero, so it needs no flag), the motion mask, its
//! regions and the boxes of those that persist over consecutive pairs, moved into the later
//! frame.

use std::ffi::OsString;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use kestrel::dense::{
    BoxRules, DenseParams, MaskStructure, MotionBox, MotionParams, OutlineParams, OUTLINE_MAX_REACH,
};

use super::dense::{refused, GridFlags};
use super::{median, CommandError};
use crate::cli::values::{self, path};
use crate::dense::picture::motion_overlay;
use crate::dense::{MotionFrame, MotionRunner, MotionSettings, OUTLINE_REACH, PERSIST_PAIRS};
use crate::io::csv::CsvWriter;
use crate::io::images::write_rgb_png;
use crate::io::json::one_line;
use crate::io::{create_output_dir, AtomicFile, FrameSource, OutputError, Progress};
use crate::Frame;
use serde_json::json;

/// Columns of boxes.csv: the contract's five, then the region's size in grid nodes.
pub const COLUMNS: [&str; 6] = ["frame", "x", "y", "w", "h", "nodes"];

/// `host-sim motion`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "boxes around what moves in a sequence, the camera's own motion removed",
    before_help = "host-sim motion: moving objects in a sequence. Between each frame and the one before it: the
library's grid flow, the camera's motion fitted to it and removed (a still camera needs no
flag: its motion fits to nearly zero), the nodes that still move and their connected regions.
Each region is then outlined at pixel level: its pixels vote for the motions that explain
them better than the camera's, and connected pixels of one motion make one box (two objects in
one region get two; a region of mismeasured nodes gets none). A box is reported once its
object has moved in two consecutive frame pairs (--persist): a region that moves in one pair
alone (a wrong match, a patch clipped by an exposure jump) gives no box, and an object's first
pair gives none either. Reported boxes within 4 px of each other whose motions against the
camera differ by at most a pixel or half the faster one's are parts of one body (a walker's
legs and torso) and are joined into one box. On a still camera each box then grows over the
pixels connected to it that changed between the two frames by more than 15 grey levels (on
the half-resolution image; a change by a shadow's factor does not count), which a walker's
flat coat and trousers do though they give no flow, and takes in the boxes it then overlaps;
a box at most half as tall standing below another (a walker's feet, at most half its height
under it) is joined to it, unless it changed as a shadow does.",
    after_help = "boxes.csv columns:
  frame      the later frame of the pair, counted from 0 (so the first row has frame 1 or
             more)
  x,y,w,h    the box in that frame: left column, top row, width and height in whole pixels
  nodes      the region's size in grid nodes

A bad frame stops the run: the boxes of the frames before it are written, and the error names
the frame. Progress is shown on stderr when it is a terminal.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line."
)]
pub struct MotionOptions {
    #[arg(value_name = "INPUT", value_parser = input, help = INPUT_HELP)]
    pub input: OsString,
    /// one row per box (see below)
    #[arg(long, value_name = "boxes.csv", value_parser = path)]
    pub out: PathBuf,
    /// one PNG per frame from the second on, frame_NNNNNN.png: the frame with the moving grid
    /// cells tinted red and the boxes outlined in green
    #[arg(long, value_name = "DIR", value_parser = path)]
    pub viz: Option<PathBuf>,
    /// write {"frames": n, "median_frame_seconds": t}: the library's time per frame (pyramid,
    /// grid flow, camera motion, mask, boxes), decoding excluded
    #[arg(long, value_name = "S.json", value_parser = path)]
    pub stats: Option<PathBuf>,
    #[command(flatten)]
    pub grid: GridFlags,
    /// a node moves when its flow differs from the camera's by more than PX, finite and > 0
    #[arg(long, value_name = "PX", default_value_t = 0.8, value_parser = threshold)]
    pub threshold: f32,
    /// smallest region looked at, in grid nodes, N >= 1 (with --no-outline, smallest region
    /// reported; 3 is then a good floor)
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = min_nodes)]
    pub min_nodes: u32,
    /// fastest motion of an object searched beside the camera's, PX a frame on each axis, 0 to
    /// 128 (the search runs on pyramid level 1, in steps of 2 px, then refines)
    #[arg(long, value_name = "PX", default_value_t = OUTLINE_REACH, value_parser = reach)]
    pub reach: usize,
    /// box each region's grid cells (inset by half a window) instead of outlining the pixels
    /// that move in it
    #[arg(long)]
    pub no_outline: bool,
    /// close the mask with an N x N square first: 0 (no closing), 2 or 3
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = structure)]
    pub close: u8,
    /// then open it with an N x N square: 0 (no opening), 2 or 3
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = structure)]
    pub open: u8,
    /// report a region once it has moved in N consecutive frame pairs (its box overlaps the
    /// box of the pair before, moved by its flow, and their flows agree within 2 px and a
    /// quarter), 1 to 10; 1 reports every pair's regions
    #[arg(long, value_name = "N", default_value_t = PERSIST_PAIRS, value_parser = persist)]
    pub persist: u8,
}

impl MotionOptions {
    /// Every setting of the pipeline.
    pub fn settings(&self) -> MotionSettings {
        let defaults = MotionParams::default();
        let host_defaults = MotionSettings::default();
        MotionSettings {
            dense: self.grid.params(DenseParams::for_motion()),
            motion: MotionParams {
                threshold: self.threshold,
                close: square(self.close),
                open: square(self.open),
                boxes: BoxRules {
                    min_nodes: self.min_nodes,
                    ..defaults.boxes
                },
                ..defaults
            },
            outline: host_defaults
                .outline
                .filter(|_| !self.no_outline)
                .map(|outline| OutlineParams {
                    reach: self.reach,
                    ..outline
                }),
            persist_pairs: self.persist,
            ..host_defaults
        }
    }
}

fn persist(text: &str) -> Result<u8, String> {
    let range = |n| (1..=10).contains(&n);
    values::whole(text, range, "must be between 1 and 10").map(|n| n as u8)
}

fn reach(text: &str) -> Result<usize, String> {
    let range = |n| (0..=OUTLINE_MAX_REACH as i64).contains(&n);
    values::whole(text, range, "must be between 0 and 128").map(|n| n as usize)
}

fn threshold(text: &str) -> Result<f32, String> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    values::number(text, positive, "must be a finite number > 0").map(|v| v as f32)
}

fn min_nodes(text: &str) -> Result<u32, String> {
    let range = |n| (1..=i64::from(u32::MAX)).contains(&n);
    values::whole(text, range, "must be at least 1").map(|n| n as u32)
}

fn structure(text: &str) -> Result<u8, String> {
    let sides = |n| matches!(n, 0 | 2 | 3);
    values::whole(text, sides, "must be 0 (none), 2 or 3").map(|n| n as u8)
}

/// The square of side `n` (`--close`, `--open`), none for 0.
fn square(n: u8) -> Option<MaskStructure> {
    match n {
        2 => Some(MaskStructure::Square2),
        3 => Some(MaskStructure::Square3),
        _ => None,
    }
}

/// The help of the sequence commands' INPUT.
pub const INPUT_HELP: &str = "a directory of frames (PNG, JPEG, PGM or BMP, in file-name order), \
     a .y4m file (the Y plane), - for y4m on standard input, or a video file (mp4, mkv, avi, mov, \
     webm, ...: any other file; ffmpeg, which must be on the PATH, decodes it to full-range grey)";

/// The INPUT argument of the sequence commands, which must not be empty.
pub fn input(text: &str) -> Result<OsString, String> {
    match text.is_empty() {
        true => {
            Err("must not be empty: a directory of frames, a .y4m file, a video file, or -".into())
        }
        false => Ok(OsString::from(text)),
    }
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
        let rows = csv.finish().map_err(|e| out.write_error(&e))?;
        out.write_all(&rows).map_err(|e| out.write_error(&e))?;
        out.commit()?;
        if let Some(mut stats) = stats.take() {
            let summary = one_line(&json!({
                "frames": pass.frames,
                "median_frame_seconds": median(&mut pass.seconds),
            }));
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
        let settings = options.settings();
        let refused = |e| refused(e, &settings.dense, Path::new(name), (width, height));
        let runner = match &mut runner {
            Some(runner) => runner,
            None => runner.insert(MotionRunner::new(settings, width, height).map_err(refused)?),
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
        csv.record((frame, b.x, b.y, b.w, b.h, b.nodes))?;
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
    let picture = motion_overlay(later, runner.layout(), runner.nodes(), &found.mask, boxes);
    write_rgb_png(&dir.join(format!("frame_{index:06}.png")), &picture)
}
