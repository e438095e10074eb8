//! The library's KLT tracker run over a sequence of host frames, in host-allocated buffers.

use std::fmt;
use std::time::Instant;

use kestrel::detect::Corner;
use kestrel::detect::{Grid, MAX_CELLS_PER_SIDE};
use kestrel::lk::{scratch_len, Illumination, LkParams, TemplatePlacement};
use kestrel::track::{
    detect_scratch_len, tracker_storage_len, FrameReport, Gates, Refill, Relocation, Track,
    Tracker, TrackerBuffers, TrackerConfig, TrackerError,
};
use kestrel::ConfigError;
use kestrel::ImageError;

use crate::cli::values;
use crate::Frame;

/// The most tracks host-sim follows at once.
pub const MAX_TRACKS: usize = 1000;

/// Tracks allowed per grid cell; with about one cell per two tracks, a cell can take half again
/// its share.
const PER_CELL: u8 = 3;

/// The LK flags `track` and `egomotion` share, each overriding the configuration it is
/// applied to when given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::Args)]
pub struct LkSettings {
    /// LK window side, odd, 3 to 63 [default: 21; 7 with --preset flow-sensor]
    #[arg(long, value_name = "N", value_parser = window)]
    pub window: Option<usize>,
    /// coarsest pyramid level LK searches, 0 to 7 [default: 3; 1 with the preset]
    #[arg(long, value_name = "L", value_parser = values::levels)]
    pub levels: Option<usize>,
    /// plain, or gain-bias: a brightness gain and bias fitted between frames
    /// [default: gain-bias]
    #[arg(long, value_name = "M", value_parser = illumination)]
    pub illumination: Option<Illumination>,
    /// at-point (interpolated at each point, OpenCV's) or nearest-pixel (on the pixel nearest
    /// it, cheaper: the firmware's) [default: at-point; nearest-pixel with the preset]
    #[arg(long, value_name = "P", value_parser = template)]
    pub template: Option<TemplatePlacement>,
}

impl LkSettings {
    /// `lk` with the given settings in place of its own.
    pub fn apply(&self, lk: LkParams) -> LkParams {
        LkParams {
            window: self.window.unwrap_or(lk.window),
            max_level: self.levels.unwrap_or(lk.max_level),
            illumination: self.illumination.unwrap_or(lk.illumination),
            template: self.template.unwrap_or(lk.template),
            ..lk
        }
    }
}

/// The tracker's flags: LK's and the gates', each overriding the configuration it is applied
/// to when given.
///
/// ```
/// use host_sim::tracking::{LkSettings, Preset, TrackerSettings};
/// let lk = LkSettings { window: Some(9), ..LkSettings::default() };
/// let settings = TrackerSettings { lk, ..TrackerSettings::default() };
/// let config = settings.apply(Preset::FlowSensor.config(None));
/// assert_eq!((config.lk.window, config.lk.max_level), (9, 1));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, clap::Args)]
pub struct TrackerSettings {
    #[command(flatten)]
    pub lk: LkSettings,
    /// forward-backward gate, px, >= 0 [default: 1]
    #[arg(long, value_name = "PX", value_parser = non_negative)]
    pub fb_threshold: Option<f32>,
    /// residual gate, grey levels, >= 0 [default: 12]
    #[arg(long, value_name = "G", value_parser = non_negative)]
    pub max_residual: Option<f32>,
    /// appearance gate: least correlation with the track's birth patch, -1 to 1 (-1 turns it
    /// off) [default: 0.8]
    #[arg(long, value_name = "C", value_parser = correlation)]
    pub min_correlation: Option<f32>,
    /// appearance gate's floor: on a frame whose tracks' correlations with their birth patches
    /// spread widely (leaves in the wind, a grainy or compressed clip), a track is dropped
    /// only when its correlation stands far below the others' or below this; from
    /// --min-correlation up the gate is fixed, -1 to 1 [default: 0.6]
    #[arg(long, value_name = "C", value_parser = correlation)]
    pub least_correlation: Option<f32>,
    /// relative residual gate: a track whose residual is more than this many times the
    /// frame's median residual (at least one grey level), and than this many times its own
    /// usual residual once it has made four steps, is dropped, >= 0 [default: 3]
    #[arg(long, value_name = "R", value_parser = non_negative)]
    pub residual_ratio: Option<f32>,
    /// relocation limit, px: a track whose birth patch is not found within this distance is
    /// dropped, >= 0 [default: 0.75]
    #[arg(long, value_name = "PX", value_parser = non_negative)]
    pub max_relocation: Option<f32>,
    /// relocation period, frames: each track is moved back onto its birth patch once in
    /// this many frames, twice as many once its image has turned (0 turns relocation off)
    /// [default: 8; 16 with the flow-sensor preset]
    #[arg(long, value_name = "F", value_parser = frames_period)]
    pub relocate_every: Option<u32>,
    /// refill cooldown, frames: for this many frames no new track starts near where a track
    /// failed a gate in its first four frames, nor near a corner whose step from the frame
    /// before fails the residual gate, which does not start (0 turns both off) [default: 32;
    /// 0 with the flow-sensor preset]
    #[arg(long, value_name = "F")]
    pub refill_cooldown: Option<u16>,
    /// refill threshold: new corners are detected when fewer than this many tracks are live
    /// after a frame, 0 to --max-tracks (0 detects on the first frame only) [default: nine
    /// tenths of --max-tracks; four fifths with the flow-sensor preset]
    #[arg(long, value_name = "N")]
    pub refill_below: Option<usize>,
    /// on a camera that moves half a pixel a frame or more, no track starts where the frame's
    /// median step takes it out of the view within this many frames (0 turns it off)
    /// [default: 20; 0 with the flow-sensor preset]
    #[arg(long, value_name = "F")]
    pub leaving_within: Option<u16>,
    /// revival window, frames: on a still camera a track at least 8 frames old that a gate
    /// drops is kept aside this long and revived, with its id, where its birth patch shows
    /// again at its place (0 turns it off) [default: 32; 0 with the flow-sensor preset]
    #[arg(long, value_name = "F")]
    pub revive_within: Option<u16>,
}

impl TrackerSettings {
    /// `config` with every given setting in place of its own.
    pub fn apply(&self, config: TrackerConfig) -> TrackerConfig {
        let (gates, relocation, refill) = (config.gates, config.relocation, config.refill);
        TrackerConfig {
            lk: self.lk.apply(config.lk),
            gates: Gates {
                fb_threshold: self.fb_threshold.unwrap_or(gates.fb_threshold),
                max_residual: self.max_residual.unwrap_or(gates.max_residual),
                min_correlation: self.min_correlation.unwrap_or(gates.min_correlation),
                least_correlation: self.least_correlation.unwrap_or(gates.least_correlation),
                residual_ratio: self.residual_ratio.unwrap_or(gates.residual_ratio),
                ..gates
            },
            relocation: Relocation {
                max_distance: self.max_relocation.unwrap_or(relocation.max_distance),
                every: self.relocate_every.unwrap_or(relocation.every),
                revive_within: self.revive_within.unwrap_or(relocation.revive_within),
                ..relocation
            },
            refill: Refill {
                cooldown: self.refill_cooldown.unwrap_or(refill.cooldown),
                below: self.refill_below.unwrap_or(refill.below),
                leaving_within: self.leaving_within.unwrap_or(refill.leaving_within),
                ..refill
            },
            ..config
        }
    }
}

fn window(text: &str) -> Result<usize, String> {
    let odd = |n: i64| (3..=63).contains(&n) && n % 2 == 1;
    values::whole(text, odd, "must be an odd number from 3 to 63").map(|n| n as usize)
}

fn illumination(text: &str) -> Result<Illumination, String> {
    crate::commands::flow::illumination(text)
}

fn template(text: &str) -> Result<TemplatePlacement, String> {
    let names = [
        ("at-point", TemplatePlacement::AtPoint),
        ("nearest-pixel", TemplatePlacement::NearestPixel),
    ];
    values::choice(text, &names)
}

fn non_negative(text: &str) -> Result<f32, String> {
    values::number(text, |v| v >= 0.0, "must be a number >= 0").map(|v| v as f32)
}

fn frames_period(text: &str) -> Result<u32, String> {
    let range = |n: i64| (0..=1_000_000).contains(&n);
    values::whole(text, range, "must be a whole number from 0 to 1000000").map(|n| n as u32)
}

fn correlation(text: &str) -> Result<f32, String> {
    let range = |v| (-1.0..=1.0).contains(&v);
    values::number(text, range, "must be between -1 and 1").map(|v| v as f32)
}

/// `--preset NAME`.
pub fn preset(text: &str) -> Result<Preset, String> {
    values::choice(text, &[("flow-sensor", Preset::FlowSensor)])
}

/// A named tracker configuration of the library's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// [`TrackerConfig::flow_sensor`].
    FlowSensor,
}

impl Preset {
    /// The preset's configuration, with `max_tracks` (and a refill threshold at four fifths of
    /// it) when given.
    ///
    /// ```
    /// use host_sim::tracking::Preset;
    /// assert_eq!(Preset::FlowSensor.config(None).max_tracks, 25);
    /// assert_eq!(Preset::FlowSensor.config(Some(40)).refill.below, 32);
    /// ```
    pub fn config(self, max_tracks: Option<usize>) -> TrackerConfig {
        let preset = match self {
            Preset::FlowSensor => TrackerConfig::flow_sensor(),
        };
        match max_tracks {
            Some(n) => TrackerConfig {
                max_tracks: n,
                refill: Refill {
                    below: n * 4 / 5,
                    ..preset.refill
                },
                ..preset
            },
            None => preset,
        }
    }
}

/// Tracks aimed for without a count or a preset.
pub const DEFAULT_MAX_TRACKS: usize = 100;

/// The tracks aimed for: `max_tracks` when given, else `preset`'s, else
/// [`DEFAULT_MAX_TRACKS`].
///
/// ```
/// use host_sim::tracking::{tracks_aimed_for, Preset};
/// assert_eq!(tracks_aimed_for(None, None), 100);
/// assert_eq!(tracks_aimed_for(Some(Preset::FlowSensor), None), 25);
/// assert_eq!(tracks_aimed_for(Some(Preset::FlowSensor), Some(40)), 40);
/// ```
pub fn tracks_aimed_for(preset: Option<Preset>, max_tracks: Option<usize>) -> usize {
    max_tracks.unwrap_or_else(|| preset.map_or(DEFAULT_MAX_TRACKS, |p| p.config(None).max_tracks))
}

/// The library's default settings for `max_tracks` tracks on `width` x `height` frames, with a
/// refill below 90% of the target and a grid of about one cell per two tracks shaped like the
/// frame (8 x 6 cells for 100 tracks at 4:3). The library's own default refills below 80 of
/// 100: detection is the costliest step on a flight controller, and there it runs less often;
/// on recorded flights the extra live tracks are worth it (85 on average or more on host-sim's
/// flights, 80 on its climb with 80).
///
/// ```
/// use host_sim::tracking::config_for;
/// let config = config_for(320, 240, 100);
/// assert_eq!((config.max_tracks, config.refill.below), (100, 90));
/// assert_eq!((config.refill.grid.cols, config.refill.grid.rows), (8, 6));
/// ```
pub fn config_for(width: usize, height: usize, max_tracks: usize) -> TrackerConfig {
    let cells = max_tracks.div_ceil(2).max(1) as f64;
    let aspect = width as f64 / height.max(1) as f64;
    let side = |v: f64| (v.round() as usize).clamp(1, MAX_CELLS_PER_SIDE);
    let cols = side((cells * aspect).sqrt());
    let rows = side(cells / cols as f64);
    TrackerConfig {
        max_tracks,
        refill: Refill {
            below: max_tracks * 9 / 10,
            grid: Grid {
                cols,
                rows,
                per_cell: PER_CELL,
            },
            ..Refill::default()
        },
        ..TrackerConfig::default()
    }
}

/// A tracker error, with the frame it happened on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrackingFailure {
    /// The frame, counted from 0.
    pub frame: usize,
    /// What the library said.
    pub error: TrackingError,
}

/// What the library refused while tracking a sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackingError {
    /// The tracker's settings or buffers, for the first frame's size.
    Config(ConfigError),
    /// A frame's pixels could not be viewed.
    Image(ImageError),
    /// A frame.
    Frame(TrackerError),
}

impl fmt::Display for TrackingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TrackingError::Config(e) => e.fmt(f),
            TrackingError::Image(e) => e.fmt(f),
            TrackingError::Frame(e) => e.fmt(f),
        }
    }
}

impl fmt::Display for TrackingFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "frame {}: {}", self.frame, self.error)
    }
}

impl std::error::Error for TrackingFailure {}

/// What the tracker made of one frame.
#[derive(Debug, Clone, Copy)]
pub struct TrackedFrame<'a> {
    /// The frame's index, from 0.
    pub index: usize,
    /// The frame.
    pub frame: &'a Frame,
    /// The live tracks after it.
    pub tracks: &'a [Track],
    /// What happened in it.
    pub report: FrameReport,
    /// Time the library took on it (pyramid, tracking, gates, detection), seconds.
    pub seconds: f64,
}

/// Runs a tracker (capacity [`MAX_TRACKS`]) over `frames` and hands every frame's result to
/// `each`, in order; `configure` gives its settings for the first frame's width and height.
/// Returns the number of frames.
///
/// Stops at the first error, from `frames` (a bad frame), from the tracker, or from `each`,
/// once the frames before it were handed to `each`.
pub fn track_sequence<E>(
    frames: impl IntoIterator<Item = Result<Frame, E>>,
    configure: impl FnOnce(usize, usize) -> TrackerConfig,
    mut each: impl FnMut(&TrackedFrame<'_>) -> Result<(), E>,
) -> Result<usize, E>
where
    E: From<TrackingFailure>,
{
    let mut frames = frames.into_iter();
    let Some(first) = frames.next().transpose()? else {
        return Ok(0);
    };
    let fail = |frame: usize| move |error| E::from(TrackingFailure { frame, error });
    let config = configure(first.width, first.height);
    let mut buffers = HostBuffers::new(&config, first.width, first.height);
    let mut tracker = Tracker::<MAX_TRACKS>::new(config, first.width, first.height, buffers.lend())
        .map_err(|e| fail(0)(TrackingError::Config(e)))?;

    let clock = Instant::now();
    let view = first.view().map_err(|e| fail(0)(TrackingError::Image(e)))?;
    let report = tracker
        .start(view)
        .map_err(|e| fail(0)(TrackingError::Frame(e)))?;
    let seconds = clock.elapsed().as_secs_f64();
    each(&TrackedFrame {
        index: 0,
        frame: &first,
        tracks: tracker.tracks(),
        report,
        seconds,
    })?;

    let mut prev = first;
    let mut count = 1;
    for next in frames {
        let next = next?;
        let index = count;
        let unviewable = |e| fail(index)(TrackingError::Image(e));
        let (prev_view, next_view) = (
            prev.view().map_err(unviewable)?,
            next.view().map_err(unviewable)?,
        );
        let clock = Instant::now();
        let report = tracker
            .process(prev_view, next_view, None)
            .map_err(|e| fail(index)(TrackingError::Frame(e)))?;
        let seconds = clock.elapsed().as_secs_f64();
        each(&TrackedFrame {
            index,
            frame: &next,
            tracks: tracker.tracks(),
            report,
            seconds,
        })?;
        prev = next;
        count += 1;
    }
    Ok(count)
}

/// A tracker's buffers on the heap, allocated once for a frame size as firmware would in
/// statics.
#[derive(Debug, Clone)]
pub struct HostBuffers {
    /// Two pyramids and FAST's rows.
    pub storage: Vec<u8>,
    /// LK scratch.
    pub lk_scratch: Vec<i16>,
    /// Shi-Tomasi scratch.
    pub detect_scratch: Vec<i32>,
    /// Candidate corners: three per track.
    pub candidates: Vec<Corner>,
}

impl HostBuffers {
    /// Buffers for a tracker of `config` on `width` x `height` frames.
    pub fn new(config: &TrackerConfig, width: usize, height: usize) -> Self {
        // Three candidates a track spread new tracks well even where one patch is busy.
        let candidates = 3 * config.max_tracks;
        Self {
            storage: vec![0; tracker_storage_len(width, height, config.pyramid_levels())],
            lk_scratch: vec![0; scratch_len(config.lk.window)],
            detect_scratch: vec![0; detect_scratch_len(width, config.refill.level, candidates)],
            candidates: vec![Corner::default(); candidates],
        }
    }

    /// The buffers, lent to a tracker.
    pub fn lend(&mut self) -> TrackerBuffers<'_> {
        TrackerBuffers {
            storage: &mut self.storage,
            lk_scratch: &mut self.lk_scratch,
            detect_scratch: &mut self.detect_scratch,
            candidates: &mut self.candidates,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{CameraPath, Scene, SceneSpec, Sequence};

    #[test]
    fn grids_follow_the_track_count_and_the_frame_shape() {
        let grid = |w, h, n| {
            let g = config_for(w, h, n).refill.grid;
            (g.cols, g.rows)
        };
        assert_eq!(grid(160, 120, 100), (8, 6));
        assert_eq!(grid(640, 360, 100), (9, 6));
        assert_eq!(grid(100, 400, 40), (2, 10));
        assert_eq!(grid(320, 240, 1), (1, 1));
        assert_eq!(grid(320, 240, MAX_TRACKS), (26, 19));
        let config = config_for(320, 240, MAX_TRACKS);
        let room = config.refill.grid.cols
            * config.refill.grid.rows
            * usize::from(config.refill.grid.per_cell);
        assert!(room >= MAX_TRACKS);
    }

    #[test]
    fn every_frame_is_handed_over_until_the_first_error() {
        let scene = Scene::new(SceneSpec::new(96, 72, 3).with_noise(1.0));
        let path = CameraPath {
            pan: (0.5, 0.0),
            ..CameraPath::still((47.5, 35.5))
        };
        let sequence = Sequence::new(scene, path, 4);
        let frames: Vec<Result<Frame, String>> = sequence
            .frames()
            .map(Ok)
            .chain([Err("broken".to_owned())])
            .collect();
        let mut seen = Vec::new();
        let outcome = track_sequence(
            frames,
            |w, h| config_for(w, h, 30),
            |f| {
                seen.push((f.index, f.tracks.len()));
                Ok(())
            },
        );
        assert_eq!(outcome, Err("broken".to_owned()));
        assert_eq!(seen.len(), 4);
        assert!(seen.iter().all(|&(_, live)| live > 0), "{seen:?}");
    }

    impl From<TrackingFailure> for String {
        fn from(failure: TrackingFailure) -> Self {
            failure.to_string()
        }
    }
}
