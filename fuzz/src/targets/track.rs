//! The track manager fed an arbitrary sequence of starts and frames: the same scene moved and
//! relit, other scenes, frames of another size, short buffers, wrong previous frames, wild
//! predictions, and arbitrary settings and buffer sizes.
//!
//! The tracker must refuse what it documents (a frame of another size, `process` before
//! `start`) and leave its tracks alone when it does; never refuse the frame it was given last;
//! and after every frame hold at most `max_tracks` tracks, inside the frame, with unique ids
//! never seen before for new tracks, ages and birth frames that follow the frame count, and a
//! report whose counts add up.

use super::picture::{Change, Frame, FrameInput, Picture};
use arbitrary::Arbitrary;
use kestrel::detect::Corner;
use kestrel::detect::{Fast, Grid, ShiTomasi};
use kestrel::lk::scratch_len;
use kestrel::pyramid::PyramidFilter;
use kestrel::track::{
    detect_scratch_len, tracker_storage_len, Detector, FrameReport, Gates, Refill, Relocation,
    Search, Track, Tracker, TrackerBuffers, TrackerConfig, TrackerError,
};
use kestrel::{ConfigError, Point, Q16};
use std::collections::HashSet;

/// The tracker's capacity.
const N: usize = 16;
/// Frames per input: enough for tracks to age, drop and refill.
const MAX_STEPS: usize = 12;

#[derive(Arbitrary, Debug)]
struct Input {
    width: u8,
    height: u8,
    config: ConfigInput,
    storage_delta: i8,
    lk_delta: i8,
    detect_delta: i8,
    candidates: u8,
    scene: Picture,
    steps: Vec<Step>,
}

#[derive(Arbitrary, Debug)]
struct ConfigInput {
    window: u8,
    max_level: u8,
    max_iterations: u8,
    epsilon: f32,
    min_eigen_threshold: f32,
    plain: bool,
    max_tracks: u8,
    refill_below: u8,
    fast: Option<(u8, bool)>,
    block: u8,
    quality: f32,
    detect_level: u8,
    grid: (u8, u8, u8),
    border: u16,
    min_distance: u16,
    fb_threshold: f32,
    max_residual: f32,
    residual_ratio: f32,
    min_correlation: f32,
}

#[derive(Arbitrary, Debug)]
enum Step {
    Start(FrameInput),
    Process {
        prev: PrevInput,
        next: FrameInput,
        predict: Option<Predict>,
    },
}

#[derive(Arbitrary, Debug)]
enum PrevInput {
    /// The frame given last, as the contract asks.
    Last,
    /// Some other frame.
    Wrong(FrameInput),
}

#[derive(Arbitrary, Debug, Clone, Copy)]
enum Predict {
    /// A shift in 1/4 px.
    Shift(i8, i8),
    /// Everything to one arbitrary position.
    Wild(i32, i32),
}

/// The decoded input, for reading a crash.
pub fn show(data: &[u8]) -> String {
    super::show::<Input>(data)
}

pub fn run(data: &[u8]) {
    let Some(input) = super::decode::<Input>(data) else {
        return;
    };
    let (w, h) = (
        usize::from(input.width % 64) + 1,
        usize::from(input.height % 64) + 1,
    );
    let config = tracker_config(&input.config);
    let levels = config.pyramid_levels().min(7);
    let with_delta = |len: usize, delta: i8| len.saturating_add_signed(delta.into());
    let mut storage = vec![0u8; with_delta(tracker_storage_len(w, h, levels), input.storage_delta)];
    let lk_len = scratch_len(config.lk.window.min(63));
    let mut lk_scratch = vec![0i16; with_delta(lk_len, input.lk_delta)];
    let candidates = usize::from(input.candidates % 40);
    let detect_len = detect_scratch_len(w, config.refill.level.min(7), candidates);
    let mut detect_scratch = vec![0i32; with_delta(detect_len, input.detect_delta)];
    let mut corners = vec![Corner::default(); candidates];
    let buffers = TrackerBuffers {
        storage: &mut storage,
        lk_scratch: &mut lk_scratch,
        detect_scratch: &mut detect_scratch,
        candidates: &mut corners,
    };
    let tracker = match Tracker::<N>::new(config, w, h, buffers) {
        Ok(tracker) => tracker,
        Err(e) => {
            check_refusal(e, &input, &config);
            return;
        }
    };
    let mut model = Model {
        tracker,
        input: &input,
        size: (w, h),
        last: None,
        frames: 0,
        seen: HashSet::new(),
    };
    for step in input.steps.iter().take(MAX_STEPS) {
        model.step(step);
    }
}

fn tracker_config(c: &ConfigInput) -> TrackerConfig {
    let detector = match c.fast {
        Some((threshold, nonmax)) => Detector::Fast(Fast { threshold, nonmax }),
        None => Detector::ShiTomasi(ShiTomasi {
            block: usize::from(c.block % 10),
            quality_level: c.quality,
            min_distance: 0,
        }),
    };
    TrackerConfig {
        lk: super::lk_params(
            c.window,
            c.max_level,
            c.max_iterations,
            c.epsilon,
            c.min_eigen_threshold,
            c.plain,
        ),
        max_tracks: usize::from(c.max_tracks % 20),
        // The quotients the moduli ignore, so the corpus keeps its meaning: the search from
        // predictions (fine reach 0-1.5 px, 0 = whole pyramid).
        search: Search {
            constant_velocity: (c.block / 10) % 2 == 0,
            fine_reach: f32::from((c.block / 20) % 4) * 0.5,
        },
        gates: Gates {
            fb_threshold: c.fb_threshold,
            // More quotients: the forward-backward schedule (every 1-8 frames, doubt 0-1.75 px).
            fb_every: 1 + u32::from(c.grid.0 / 36) % 8,
            fb_doubt: f32::from((c.grid.1 / 36) % 8) * 0.25,
            max_residual: c.max_residual,
            residual_ratio: c.residual_ratio,
            min_correlation: c.min_correlation,
            // The detection level's quotient: a fixed appearance gate, or a floor 0.1-0.4 below.
            least_correlation: c.min_correlation - f32::from((c.detect_level / 10) % 5) * 0.1,
        },
        refill: Refill {
            below: usize::from(c.refill_below % 20),
            detector,
            level: usize::from(c.detect_level % 10),
            grid: Grid {
                cols: usize::from(c.grid.0 % 36),
                rows: usize::from(c.grid.1 % 36),
                per_cell: c.grid.2,
            },
            border: c.border,
            min_distance: c.min_distance,
            // The window's quotient: no cooldown, or 8-24 frames of it.
            cooldown: u16::from(c.window / 70) * 8,
            // The border's quotient: none, or 10-30 frames.
            leaving_within: (c.border / 50 % 4) * 10,
        },
        // More quotients: relocation every 0-12 frames from age 0-12, limits of 0-6 px in
        // quarters, and NaN at the top.
        relocation: Relocation {
            every: u32::from(c.max_tracks / 20),
            from_age: u32::from(c.refill_below / 20),
            max_distance: match c.detect_level / 10 {
                25 => f32::NAN,
                quarters => f32::from(quarters) * 0.25,
            },
            revive_within: u16::from(c.window / 40) * 8,
            at_edge: (c.window / 20) % 2 == 0,
        },
        pyramid: if (c.block / 80) % 2 == 0 {
            PyramidFilter::Gaussian
        } else {
            PyramidFilter::Box
        },
    }
}

/// A buffer is refused only when it is short.
fn check_refusal(e: ConfigError, input: &Input, config: &TrackerConfig) {
    match e.field {
        "buffers.storage" => assert!(input.storage_delta < 0),
        "buffers.lk_scratch" => assert!(input.lk_delta < 0),
        "buffers.detect_scratch" => assert!(input.detect_delta < 0),
        "buffers.candidates" => {
            assert!(usize::from(input.candidates % 40) < config.max_tracks)
        }
        "max_tracks" => assert!(config.max_tracks == 0 || config.max_tracks > N),
        "refill.below" => assert!(config.refill.below > config.max_tracks),
        "relocation.max_distance" => assert!(config.relocation.max_distance.is_nan()),
        "search.fine_reach" | "gates.fb_every" => {
            panic!("a valid search or schedule was refused: {config:?}")
        }
        "width" | "height" => panic!("a 1..=64 px frame was refused"),
        _ => {}
    }
}

/// The tracker, and what a caller knows about it.
struct Model<'t, 'i> {
    tracker: Tracker<'t, N>,
    input: &'i Input,
    size: (usize, usize),
    /// The frame given last.
    last: Option<Frame>,
    /// Frames accepted so far.
    frames: u32,
    /// Every id handed out so far.
    seen: HashSet<u32>,
}

impl Model<'_, '_> {
    fn frame(&self, f: &FrameInput) -> Frame {
        f.render(&self.input.scene, self.size)
    }

    fn step(&mut self, step: &Step) {
        match step {
            Step::Start(f) => {
                let next = self.frame(f);
                let Some(view) = next.view() else {
                    return;
                };
                let before = self.tracker.tracks().to_vec();
                let result = self.tracker.start(view);
                // Every setting and buffer was checked by `new`: a frame of the right size
                // always starts.
                let must_pass = (next.width, next.height) == self.size;
                self.after(result, &before, &next, true, must_pass);
            }
            Step::Process {
                prev,
                next,
                predict,
            } => self.process(prev, next, *predict),
        }
    }

    fn process(&mut self, prev: &PrevInput, next: &FrameInput, predict: Option<Predict>) {
        let prev_frame = match (prev, &self.last) {
            (PrevInput::Last, Some(last)) => last.clone(),
            (PrevInput::Last, None) => self.frame(&FrameInput::Scene(Change::default())),
            (PrevInput::Wrong(f), _) => self.frame(f),
        };
        let next_frame = self.frame(next);
        let (Some(prev_view), Some(next_view)) = (prev_frame.view(), next_frame.view()) else {
            return;
        };
        let shift = move |p: Point| match predict {
            Some(Predict::Shift(dx, dy)) => Point::new(
                p.x.saturating_add(Q16::from_num(dx) / 4),
                p.y.saturating_add(Q16::from_num(dy) / 4),
            ),
            Some(Predict::Wild(x, y)) => Point::from_bits(x, y),
            None => p,
        };
        let before = self.tracker.tracks().to_vec();
        let result = self.tracker.process(
            prev_view,
            next_view,
            predict
                .is_some()
                .then_some(&shift as &dyn Fn(Point) -> Point),
        );
        let is_last = self
            .last
            .as_ref()
            .is_some_and(|l| same_frame(l, &prev_frame));
        let must_pass = is_last && (next_frame.width, next_frame.height) == self.size;
        self.after(result, &before, &next_frame, false, must_pass);
    }

    /// Checks the tracks and the report after a frame.
    fn after(
        &mut self,
        result: Result<FrameReport, TrackerError>,
        before: &[Track],
        next: &Frame,
        start: bool,
        must_pass: bool,
    ) {
        let size_ok = (next.width, next.height) == self.size;
        let report = match result {
            Ok(report) => report,
            Err(e) => {
                assert!(!must_pass, "a valid frame was refused: {e:?}");
                if !size_ok {
                    assert_eq!(e, TrackerError::FrameSizeMismatch);
                }
                if !start && self.last.is_none() && e != TrackerError::FrameSizeMismatch {
                    assert_eq!(e, TrackerError::NotStarted);
                }
                assert_eq!(
                    self.tracker.tracks(),
                    before,
                    "a refused frame changed tracks"
                );
                return;
            }
        };
        assert!(size_ok, "a frame of another size was accepted");
        assert!(start || self.last.is_some(), "process before start");
        let index = self.frames;
        self.frames += 1;
        self.last = Some(next.clone());
        assert_eq!(self.tracker.frame_index(), Some(index));
        self.check_tracks(&report, before, index, start);
    }

    fn check_tracks(&mut self, report: &FrameReport, before: &[Track], index: u32, start: bool) {
        let config = *self.tracker.config();
        let tracks = self.tracker.tracks();
        let (w, h) = self.size;
        assert_eq!(report.live, tracks.len());
        assert!(tracks.len() <= config.max_tracks && tracks.len() <= N);
        let previous = if start { 0 } else { before.len() };
        assert_eq!(report.tracked + report.dropped(), previous, "{report:?}");
        let followed = report.tracked + report.revived;
        assert_eq!(report.live, followed + report.added, "{report:?}");
        assert!(report.added == 0 || report.detected);
        if !start {
            assert_eq!(report.detected, followed < config.refill.below);
        }
        let mut ids = HashSet::new();
        for (i, t) in tracks.iter().enumerate() {
            assert!(ids.insert(t.id), "duplicate id {}", t.id);
            let inside = |v: Q16, size: usize| v >= Q16::ZERO && v <= Q16::from_num(size - 1);
            assert!(inside(t.position.x, w) && inside(t.position.y, h), "{t:?}");
            assert!(t.residual >= Q16::ZERO, "{t:?}");
            if i < report.tracked {
                let old = before.iter().find(|b| b.id == t.id).expect("a survivor");
                assert_eq!((t.age, t.born), (old.age + 1, old.born), "{t:?}");
            } else if i < followed {
                // Revived: dropped earlier on a still camera, back with its id and age.
                assert!(self.seen.contains(&t.id), "revived id {} never seen", t.id);
                assert!(
                    !before.iter().any(|b| b.id == t.id),
                    "revived while live: {t:?}"
                );
                assert!(t.age >= 8 && t.born < index, "{t:?}");
            } else {
                assert!(self.seen.insert(t.id), "id {} reused", t.id);
                assert_eq!((t.age, t.born, t.residual), (0, index, Q16::ZERO), "{t:?}");
            }
        }
    }
}

/// The same geometry and bytes.
fn same_frame(a: &Frame, b: &Frame) -> bool {
    (a.width, a.height, a.stride, &a.pixels) == (b.width, b.height, b.stride, &b.pixels)
}
