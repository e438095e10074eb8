//! `host-sim track`: the library's KLT tracker over a sequence, one CSV row per live track per
//! frame, and optionally a picture of the trails per frame.
//!
//! The tracker run over a sequence, shared with the demo and the tests, is [`tracking`].

pub mod tracking;

use std::ffi::OsString;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::motion::{input, INPUT_HELP};
use super::{median, CommandError};
use crate::cli::values::{self, path};
use crate::io::csv::{CsvWriter, Fixed4};
use crate::io::images::write_rgb_png;
use crate::io::json::one_line;
use crate::io::{
    create_output_dir, describe_io_error, AtomicFile, FrameSource, OutputError, Progress,
};
use crate::viz::Trails;
use kestrel::track::FrameReport;
use serde_json::json;
use std::collections::HashMap;
use tracking::{
    config_for, preset, track_sequence, tracks_aimed_for, Preset, TrackedFrame, TrackerSettings,
    TrackingFailure, MAX_TRACKS,
};

/// Columns of tracks.csv: the contract's four, then the track's age in frames and its last
/// residual in grey levels.
pub const COLUMNS: [&str; 6] = ["frame", "id", "x", "y", "age", "residual"];

/// `host-sim track`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "follow corners through a sequence with the KLT tracker (tracks.csv, trail pictures)",
    before_help = "host-sim track: the library's KLT tracker over a sequence: corners detected, followed with
Lucas-Kanade, checked (forward-backward, residual, appearance), dropped and refilled.",
    after_help = "tracks.csv columns:
  frame     frame index, from 0
  id        track id; ids are never reused, and a track's first row is the frame it was
            detected in
  x,y       position in px, from the centre of the top-left pixel, x right, y down
  age       frames the track has been followed since it was detected
  residual  mean absolute intensity residual of its last step, grey levels

The firmware's configuration (firmware/src/pipeline.rs) is --window 9 --levels 2 --template
nearest-pixel; the flow sensor's is --preset flow-sensor.

A bad frame ends the run with an error naming it; tracks.csv then holds every frame before it.
Progress is shown on stderr when it is a terminal.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line."
)]
pub struct TrackOptions {
    #[arg(value_name = "INPUT", value_parser = input, help = INPUT_HELP)]
    pub input: OsString,
    /// tracks, one row per live track per frame (see below)
    #[arg(long, value_name = "FILE", value_parser = path)]
    pub out: PathBuf,
    /// number of tracks aimed for, 1 to 1000 [default: 100; the preset's with --preset]
    #[arg(long, value_name = "N", value_parser = max_tracks)]
    pub max_tracks: Option<usize>,
    /// flow-sensor: the library's TrackerConfig::flow_sensor() (25 tracks, 7x7 windows on two
    /// levels of a box-mean pyramid, FAST corners), the settings a flight controller runs at
    /// 400 Hz; flags given beside it override it [default: none, the tracker's defaults]
    #[arg(long, value_name = "NAME", value_parser = preset)]
    pub preset: Option<Preset>,
    #[command(flatten)]
    pub settings: TrackerSettings,
    /// one PNG per frame (000000.png, ...) with each track's trail over its last 10 frames,
    /// coloured by id; DIR is created if missing
    #[arg(long, value_name = "DIR", value_parser = path)]
    pub viz: Option<PathBuf>,
    /// write {"frames", "median_frame_seconds", "mean_frame_seconds", "mean_track_life",
    /// "drops": {reason: count}, "refused", "revived"}: the library's time per frame (decoding
    /// and writing excluded), the frames a track is live in on average, the tracks dropped by
    /// each gate (lost, out_of_frame, residual, appearance, relocation, forward_backward), the
    /// corners not started because their step from the frame before already failed the
    /// residual gate, and the dropped tracks revived with their ids on a still camera
    #[arg(long, value_name = "S.json", value_parser = path)]
    pub stats: Option<PathBuf>,
}

fn max_tracks(text: &str) -> Result<usize, String> {
    let range = |n| (1..=MAX_TRACKS as i64).contains(&n);
    values::whole(text, range, "must be between 1 and 1000").map(|n| n as usize)
}

/// `--refill-below` within the tracks aimed for: checked before any file is touched.
fn check_refill_below(options: &TrackOptions) -> Result<(), CommandError> {
    let Some(below) = options.settings.refill_below else {
        return Ok(());
    };
    let max_tracks = tracks_aimed_for(options.preset, options.max_tracks);
    match below <= max_tracks {
        true => Ok(()),
        false => Err(CommandError::Usage(format!(
            "--refill-below: must be at most the {max_tracks} tracks aimed for (got {below})"
        ))),
    }
}

impl From<TrackingFailure> for CommandError {
    fn from(failure: TrackingFailure) -> Self {
        CommandError::Processing(format!("cannot track {failure}"))
    }
}

/// Runs `track`.
///
/// The CSV is created before any work (an unwritable path fails at once) and committed at the
/// end; when a frame is bad, the rows of the frames before it are committed and the bad frame
/// is the error. Nothing is committed when no frame could be read, or when writing the CSV
/// itself failed (it could end in the middle of a frame).
pub fn run(options: &TrackOptions) -> Result<(), CommandError> {
    check_refill_below(options)?;
    let out = AtomicFile::create(&options.out)?;
    let stats = options
        .stats
        .as_deref()
        .map(AtomicFile::create)
        .transpose()?;
    if let Some(dir) = &options.viz {
        create_output_dir(dir)?;
    }
    let source = FrameSource::open(&options.input)?;
    let mut progress = Progress::new("track", source.frame_count());
    let mut csv = CsvWriter::new(out, &COLUMNS).map_err(|e| write_error(&options.out, &e))?;
    let mut trails = Trails::new();
    let (mut frames_done, mut csv_failed) = (0, false);
    let mut seconds = Vec::new();

    let frames = source.map(|frame| frame.map_err(CommandError::from));
    let configure = |width, height| {
        let base = match options.preset {
            Some(preset) => preset.config(options.max_tracks),
            None => config_for(width, height, tracks_aimed_for(None, options.max_tracks)),
        };
        options.settings.apply(base)
    };
    let mut lives = TrackLives::default();
    let outcome = track_sequence(frames, configure, |tracked| {
        // The picture first: a frame's rows are only written once all its outputs are.
        if let Some(dir) = &options.viz {
            trails.update(tracked.tracks);
            let picture = trails.draw(tracked.frame);
            write_rgb_png(&dir.join(frame_picture_name(tracked.index)), &picture)?;
        }
        write_rows(&mut csv, tracked).map_err(|e| {
            csv_failed = true;
            write_error(&options.out, &e)
        })?;
        frames_done = tracked.index + 1;
        seconds.push(tracked.seconds);
        lives.add(tracked);
        progress.update(frames_done);
        Ok(())
    });
    progress.finish();
    if frames_done > 0 && !csv_failed {
        csv.finish()
            .map_err(|e| write_error(&options.out, &e))?
            .commit()?;
        if let Some(stats) = stats {
            write_stats(stats, &mut seconds, &lives)?;
        }
    }
    outcome.map(|_| ())
}

/// The count of one reason's drops in a frame's report.
type DropCount = fn(&FrameReport) -> usize;

/// Why tracks end, as `--stats` names them, and the count of each in a frame's report.
const DROP_REASONS: [(&str, DropCount); 6] = [
    ("lost", |r| r.dropped_lost),
    ("out_of_frame", |r| r.dropped_out_of_frame),
    ("residual", |r| r.dropped_residual),
    ("appearance", |r| r.dropped_appearance),
    ("relocation", |r| r.dropped_relocation),
    ("forward_backward", |r| r.dropped_fb),
];

/// How long tracks lived and why they ended, over a run.
#[derive(Debug, Default)]
struct TrackLives {
    /// Frames each track was live in, by id (its first frame included).
    frames: HashMap<u32, u64>,
    /// Tracks dropped for each of [`DROP_REASONS`].
    drops: [u64; DROP_REASONS.len()],
    /// Corners not started because they would have failed their first step.
    refused: u64,
    /// Dropped tracks revived where their feature showed again.
    revived: u64,
}

impl TrackLives {
    fn add(&mut self, tracked: &TrackedFrame<'_>) {
        for track in tracked.tracks {
            *self.frames.entry(track.id).or_insert(0) += 1;
        }
        for (total, (_, count)) in self.drops.iter_mut().zip(DROP_REASONS) {
            *total += count(&tracked.report) as u64;
        }
        self.refused += tracked.report.refused as u64;
        self.revived += tracked.report.revived as u64;
    }

    /// The mean of the frames each track was live in, tracks still live at the end counted to
    /// the last frame.
    fn mean(&self) -> f64 {
        self.frames.values().sum::<u64>() as f64 / self.frames.len().max(1) as f64
    }
}

/// `{"frames", "median_frame_seconds", "mean_frame_seconds", "mean_track_life", "drops",
/// "refused", "revived"}`: the library's time per frame (pyramid, tracking, gates, detection),
/// decoding and writing excluded, the frames a track lived in on average, the tracks each gate
/// dropped, the corners refused at birth and the dropped tracks revived.
fn write_stats(
    mut file: AtomicFile,
    seconds: &mut [f64],
    lives: &TrackLives,
) -> Result<(), CommandError> {
    let mean = seconds.iter().sum::<f64>() / seconds.len().max(1) as f64;
    let drops = DROP_REASONS
        .iter()
        .zip(lives.drops)
        .map(|((reason, _), n)| (reason.to_string(), json!(n)))
        .collect::<serde_json::Map<_, _>>();
    let summary = one_line(&json!({
        "frames": seconds.len(),
        "median_frame_seconds": median(seconds),
        "mean_frame_seconds": mean,
        "mean_track_life": lives.mean(),
        "drops": drops,
        "refused": lives.refused,
        "revived": lives.revived,
    }));
    file.write_all(summary.as_bytes())
        .map_err(|e| file.write_error(&e))?;
    Ok(file.commit()?)
}

/// The rows of one frame: every live track, oldest first.
pub(crate) fn write_rows(
    csv: &mut CsvWriter<impl Write>,
    tracked: &TrackedFrame<'_>,
) -> io::Result<()> {
    for track in tracked.tracks {
        csv.record((
            tracked.index,
            track.id,
            Fixed4(track.position.x.to_num()),
            Fixed4(track.position.y.to_num()),
            track.age,
            Fixed4(track.residual.to_num()),
        ))?;
    }
    Ok(())
}

/// The file name of frame `index`'s picture: zero-padded, so that names sort like frames and
/// `ffmpeg -i DIR/%06d.png` reads them back.
pub fn frame_picture_name(index: usize) -> String {
    format!("{index:06}.png")
}

/// An error writing the output at `path`.
pub(crate) fn write_error(path: &Path, error: &io::Error) -> CommandError {
    CommandError::Output(OutputError::new(
        path,
        format!("cannot write: {}", describe_io_error(error)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::track::{FrameReport, Track};
    use kestrel::{Point, Q16};

    #[test]
    fn rows_carry_the_frame_the_id_the_position_and_more() {
        let frame = crate::Frame::filled(4, 4, 0);
        let tracks = [Track {
            id: 7,
            position: Point::from_f32(1.5, 2.25),
            previous: Point::from_f32(1.5, 2.25),
            age: 3,
            residual: Q16::from_num(0.5),
            born: 2,
            ..Track::default()
        }];
        let tracked = TrackedFrame {
            index: 5,
            frame: &frame,
            tracks: &tracks,
            report: FrameReport::default(),
            seconds: 0.0,
        };
        let mut csv = CsvWriter::new(Vec::new(), &COLUMNS).unwrap();
        write_rows(&mut csv, &tracked).unwrap();
        let text = String::from_utf8(csv.finish().unwrap()).unwrap();
        assert_eq!(
            text,
            "frame,id,x,y,age,residual\n5,7,1.5000,2.2500,3,0.5000\n"
        );
    }

    #[test]
    fn picture_names_sort_like_frames() {
        assert_eq!(frame_picture_name(7), "000007.png");
        assert!(frame_picture_name(99) < frame_picture_name(100));
    }
}
