//! `host-sim flow`: sparse pyramidal LK of given points from one frame to the next.

use std::io::{self, Write};
use std::path::PathBuf;

use kestrel::lk::{scratch_len, Illumination, LkParams, LucasKanade, PointTrack, TrackStatus};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::{Point, Q16};

use super::{check_same_size, time_core, CommandError};
use crate::cli::values::{self, path};
use crate::io::csv::{read_points, CsvWriter, Fixed4};
use crate::io::images::read_grey;
use crate::io::json::one_line;
use crate::io::AtomicFile;
use crate::{reference, Frame};
use serde_json::json;

/// Columns of the output file: the contract's six, then the status by name.
pub const COLUMNS: [&str; 7] = ["x", "y", "nx", "ny", "ok", "err", "status"];

/// Which implementation tracks the points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Engine {
    /// The library's Q16 tracker.
    #[default]
    Library,
    /// The f32 reference implementation.
    Reference,
}

/// `host-sim flow`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "track points from one frame to the next (sparse pyramidal Lucas-Kanade)",
    before_help = "host-sim flow: track points from frame A to frame B with the library's Q16 pyramidal
Lucas-Kanade (or the f32 reference).",
    after_help = concat!("O.csv columns:
  x,y      the input point
  nx,ny    its position in B (the last estimate when ok is 0)
  ok       1 when tracked; 0 when outside the image, too little texture or not converged
  err      mean absolute intensity residual over the window, grey levels (0 when ok is 0)
  status   tracked, out_of_bounds, low_texture or not_converged

Coordinates are pixels from the centre of the top-left pixel, x right, y down.
Nothing is written unless every step succeeds.

", "Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.")
)]
pub struct FlowOptions {
    /// first frame: PNG, JPEG, PGM or BMP, converted to BT.601 grey
    #[arg(long, value_name = "A", value_parser = path)]
    pub prev: PathBuf,
    /// second frame, the same size as A
    #[arg(long, value_name = "B", value_parser = path)]
    pub next: PathBuf,
    /// points to track: a header line starting with x,y, then one point per line
    #[arg(long, value_name = "P.csv", value_parser = path)]
    pub points: PathBuf,
    /// results, one row per point in input order (see below)
    #[arg(long, value_name = "O.csv", value_parser = path)]
    pub out: PathBuf,
    /// window side in px, odd, 3 to 63
    #[arg(long, value_name = "N", default_value_t = 21, value_parser = values::window)]
    pub window: usize,
    /// coarsest pyramid level, 0 to 7, like OpenCV's maxLevel
    #[arg(long, value_name = "L", default_value_t = 3, value_parser = values::levels)]
    pub levels: usize,
    /// iterations per level, at least 1
    #[arg(long, value_name = "K", default_value_t = 30, value_parser = max_iters)]
    pub max_iters: u32,
    /// stop when a step is shorter than E px, finite and >= 0
    #[arg(long, value_name = "E", default_value_t = 0.01, value_parser = epsilon)]
    pub epsilon: f32,
    /// brightness model between the frames: gain-bias (fit a gain and a bias per window;
    /// robust to exposure changes) or plain
    #[arg(long, value_name = "M", default_value = "gain-bias", value_parser = illumination)]
    pub illumination: Illumination,
    /// run the f32 reference implementation instead of the library
    #[arg(long)]
    pub reference: bool,
    /// run the core (build both pyramids, track every point) N times, N >= 1
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = values::repeat)]
    pub repeat: usize,
    /// write {"points": n, "repeat": N, "median_core_seconds": t}; decoding is not timed
    #[arg(long, value_name = "S.json", value_parser = path)]
    pub stats: Option<PathBuf>,
}

impl FlowOptions {
    /// The LK parameters the flags give.
    pub fn params(&self) -> LkParams {
        LkParams {
            window: self.window,
            max_level: self.levels,
            max_iterations: self.max_iters,
            epsilon: self.epsilon,
            illumination: self.illumination,
            ..LkParams::default()
        }
    }

    /// Which implementation runs.
    pub fn engine(&self) -> Engine {
        match self.reference {
            true => Engine::Reference,
            false => Engine::Library,
        }
    }
}

/// Iterations are a `u32` in the library.
fn max_iters(text: &str) -> Result<u32, String> {
    let range = |n| (1..=i64::from(u32::MAX)).contains(&n);
    values::whole(text, range, "must be at least 1").map(|n| n as u32)
}

fn epsilon(text: &str) -> Result<f32, String> {
    let finite = |e: f64| e.is_finite() && e >= 0.0;
    values::number(text, finite, "must be a finite number >= 0").map(|e| e as f32)
}

/// `--illumination plain|gain-bias`, shared by every command that runs LK.
pub fn illumination(text: &str) -> Result<Illumination, String> {
    let names = [
        ("plain", Illumination::Plain),
        ("gain-bias", Illumination::GainBias),
    ];
    values::choice(text, &names)
}

/// One point's result, in the output file's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointFlow {
    /// Position in the next frame (the last estimate when not tracked).
    pub x: f64,
    /// Position in the next frame (the last estimate when not tracked).
    pub y: f64,
    /// Whether the point was tracked, and why not.
    pub status: TrackStatus,
    /// Mean absolute intensity residual over the window, grey levels.
    pub residual: f64,
}

/// Runs `flow`. Outputs are created before any work, so an unwritable path fails fast, and
/// committed only after everything succeeded, so an error leaves no output behind.
pub fn run(options: &FlowOptions) -> Result<(), CommandError> {
    let mut out = AtomicFile::create(&options.out)?;
    let mut stats = options
        .stats
        .as_deref()
        .map(AtomicFile::create)
        .transpose()?;

    let prev = read_grey(&options.prev)?;
    let next = read_grey(&options.next)?;
    check_same_size(&options.prev, &options.next, &prev, &next)?;
    let points = read_points(&options.points)?;

    let (flows, median_seconds) = match options.engine() {
        Engine::Library => {
            let mut tracker = LibraryTracker::new(&options.params(), &prev, &points)?;
            let ((), seconds) = time_core(options.repeat, || tracker.track(&prev, &next))?;
            (tracker.flows(), seconds)
        }
        Engine::Reference => {
            let (tracks, seconds) = time_core(options.repeat, || {
                Ok(reference::track_points(
                    &prev,
                    &next,
                    &points,
                    None,
                    &options.params(),
                ))
            })?;
            (tracks.iter().map(reference_flow).collect(), seconds)
        }
    };

    write_flow_csv(&mut out, &points, &flows).map_err(|e| out.write_error(&e))?;
    if let Some(stats) = &mut stats {
        let summary = one_line(&json!({
            "points": points.len(),
            "repeat": options.repeat,
            "median_core_seconds": median_seconds,
        }));
        stats
            .write_all(summary.as_bytes())
            .map_err(|e| stats.write_error(&e))?;
    }
    out.commit()?;
    if let Some(stats) = stats {
        stats.commit()?;
    }
    Ok(())
}

/// The name of a status in the output's `status` column.
pub fn status_name(status: TrackStatus) -> &'static str {
    match status {
        TrackStatus::Tracked => "tracked",
        TrackStatus::OutOfBounds => "out_of_bounds",
        TrackStatus::LowTexture => "low_texture",
        TrackStatus::NotConverged => "not_converged",
    }
}

/// The library's tracker with host-allocated storage for one frame size and point list.
///
/// Everything is allocated up front, as firmware would in statics, so that [`Self::track`] is
/// exactly the core being timed: both pyramids built and every point tracked.
struct LibraryTracker {
    lk: LucasKanade,
    levels: usize,
    prev_storage: Vec<u8>,
    next_storage: Vec<u8>,
    scratch: Vec<i16>,
    starts: Vec<Point>,
    tracks: Vec<PointTrack>,
}

impl LibraryTracker {
    fn new(params: &LkParams, frame: &Frame, points: &[(f32, f32)]) -> Result<Self, CommandError> {
        let lk = LucasKanade::new(*params).map_err(|e| tracking_failed(&e))?;
        let levels = params.max_level;
        let storage_len = pyramid_storage_len(frame.width, frame.height, levels);
        Ok(Self {
            lk,
            levels,
            prev_storage: vec![0; storage_len],
            next_storage: vec![0; storage_len],
            scratch: vec![0; scratch_len(params.window)],
            starts: points.iter().map(|&(x, y)| Point::from_f32(x, y)).collect(),
            tracks: vec![PointTrack::default(); points.len()],
        })
    }

    /// The core: builds both pyramids and tracks every point.
    fn track(&mut self, prev: &Frame, next: &Frame) -> Result<(), CommandError> {
        let prev_view = prev.view().map_err(|e| tracking_failed(&e))?;
        let next_view = next.view().map_err(|e| tracking_failed(&e))?;
        let prev_pyramid = Pyramid::build(prev_view, self.levels, &mut self.prev_storage)
            .map_err(|e| tracking_failed(&e))?;
        let next_pyramid = Pyramid::build(next_view, self.levels, &mut self.next_storage)
            .map_err(|e| tracking_failed(&e))?;
        self.lk
            .track_points(
                &prev_pyramid,
                &next_pyramid,
                &self.starts,
                None,
                &mut self.tracks,
                &mut self.scratch,
            )
            .map_err(|e| tracking_failed(&e))
    }

    fn flows(&self) -> Vec<PointFlow> {
        self.tracks
            .iter()
            .map(|track| PointFlow {
                x: q16_to_f64(track.position.x),
                y: q16_to_f64(track.position.y),
                status: track.status,
                residual: q16_to_f64(track.residual),
            })
            .collect()
    }
}

fn tracking_failed(error: &dyn std::fmt::Display) -> CommandError {
    CommandError::Processing(format!("cannot track: {error}"))
}

/// A Q16 value as `f64`, exactly (an `f32` would drop fraction bits beyond 256 px).
fn q16_to_f64(value: Q16) -> f64 {
    f64::from(value.to_bits()) / 65536.0
}

fn reference_flow(track: &reference::RefTrack) -> PointFlow {
    PointFlow {
        x: f64::from(track.x),
        y: f64::from(track.y),
        status: track.status,
        residual: f64::from(track.residual),
    }
}

fn write_flow_csv(out: impl Write, points: &[(f32, f32)], flows: &[PointFlow]) -> io::Result<()> {
    let mut csv = CsvWriter::new(out, &COLUMNS)?;
    for (&(x, y), flow) in points.iter().zip(flows) {
        let ok = u8::from(flow.status == TrackStatus::Tracked);
        csv.record((
            Fixed4(f64::from(x)),
            Fixed4(f64::from(y)),
            Fixed4(flow.x),
            Fixed4(flow.y),
            ok,
            Fixed4(flow.residual),
            status_name(flow.status),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_follow_the_points_and_only_tracked_is_ok() {
        let points = [(1.0, 2.0), (-5.0, 3.5)];
        let flows = [
            PointFlow {
                x: 3.0,
                y: 2.25,
                status: TrackStatus::Tracked,
                residual: 1.5,
            },
            PointFlow {
                x: -5.0,
                y: 3.5,
                status: TrackStatus::OutOfBounds,
                residual: 0.0,
            },
        ];
        let mut text = Vec::new();
        write_flow_csv(&mut text, &points, &flows).unwrap();
        assert_eq!(
            String::from_utf8(text).unwrap(),
            "x,y,nx,ny,ok,err,status\n\
             1.0000,2.0000,3.0000,2.2500,1,1.5000,tracked\n\
             -5.0000,3.5000,-5.0000,3.5000,0,0.0000,out_of_bounds\n"
        );
    }
}
