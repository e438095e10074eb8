//! Property tests: invariants of the library checked on generated input.
//!
//! - A pure translation of a textured scene is recovered by LK within a stated bound.
//! - Zero motion gives zero flow, in LK, the tracker, the dense grid and ego-motion.
//! - No NaN or out-of-range value leaves the library, whatever the input: LK results, tracker
//!   tracks and reports, dense nodes, dominant motion and boxes, ego-motion estimates and the
//!   OPTICAL_FLOW_RAD fields (as a struct and on the wire).
//! - Statuses agree with positions: a tracked point, a live track and a measured node are inside
//!   the frame.
//! - A tracker never holds more than `max_tracks` (nor its capacity `N`) tracks, and ids are
//!   unique and never reused.
//!
//! Every test runs a fixed number of cases from a fixed seed, so each run draws the same
//! cases; a failure prints the shrunk input. To see the figures:
//! `cargo test --release --test properties -- --nocapture --test-threads 1`.

use std::collections::BTreeSet;
use std::sync::atomic::{AtomicU32, Ordering};

use host_sim::dense::{MotionRunner, MotionSettings};
use host_sim::synth::{grid_points, pair, textured_points, true_position, Homography, SceneSpec};
use host_sim::tracking::HostBuffers;
use host_sim::Frame;
use kestrel::dense::{DenseParams, DominantFitParams, MotionParams, NodeStatus};
use kestrel::detect::{Fast, Grid, ShiTomasi};
use kestrel::ego::mavlink::{encode_optical_flow_rad, MavlinkHeader, MAX_FRAME_LEN};
use kestrel::ego::{
    Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, ModelKind, Ransac, RansacParams,
};
use kestrel::lk::{
    scratch_len, Illumination, LkParams, LucasKanade, PointTrack, TemplatePlacement, TrackStatus,
};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::track::{Detector, Gates, Refill, Track, Tracker, TrackerConfig, TrackerError};
use kestrel::ImageView;
use kestrel::{Point, Q16};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};

/// `cases` cases drawn from a fixed seed, no failure files.
fn config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0x4B45_5354_5245_4C07),
        max_shrink_iters: 2000,
        ..Config::default()
    }
}

// ---------------------------------------------------------------------------------------------
// Generated frames

/// What a generated frame shows.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Pattern {
    /// Every pixel independent and uniform.
    Noise,
    /// One grey level.
    Flat(u8),
    /// Random grey 4 x 4 blocks: corners everywhere.
    Blocks,
    /// Sums of sinusoids: smooth texture.
    Smooth,
    /// Vertical stripes: gradient in x only.
    Stripes,
}

fn pattern() -> impl Strategy<Value = Pattern> {
    prop_oneof![
        1 => Just(Pattern::Noise),
        1 => any::<u8>().prop_map(Pattern::Flat),
        3 => Just(Pattern::Blocks),
        3 => Just(Pattern::Smooth),
        1 => Just(Pattern::Stripes),
    ]
}

fn hash(seed: u64, a: i64, b: i64) -> u64 {
    let mut z = seed
        ^ (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (b as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The grey level of `pattern` of `seed` at scene point (`x`, `y`).
fn scene_value(pattern: Pattern, seed: u64, x: i64, y: i64) -> u8 {
    match pattern {
        Pattern::Noise => hash(seed, x, y) as u8,
        Pattern::Flat(v) => v,
        Pattern::Blocks => hash(seed, x.div_euclid(4), y.div_euclid(4)) as u8,
        Pattern::Smooth => {
            let f = |k: i64| 0.15 + (hash(seed, k, -1) % 1000) as f64 / 2500.0;
            let (x, y) = (x as f64, y as f64);
            let v = 128.0
                + 50.0 * (f(0) * x).sin() * (f(1) * y).cos()
                + 40.0 * (f(2) * (x + y)).sin()
                + 30.0 * (f(3) * (x - 0.7 * y)).cos();
            v.clamp(0.0, 255.0) as u8
        }
        Pattern::Stripes => {
            if x.rem_euclid(8) < 4 {
                40
            } else {
                210
            }
        }
    }
}

/// A `width` x `height` frame of `pattern`, the scene shifted by `shift` px.
fn frame(pattern: Pattern, seed: u64, width: usize, height: usize, shift: (i64, i64)) -> Frame {
    let mut f = Frame::filled(width, height, 0);
    for y in 0..height {
        for x in 0..width {
            f.data[y * width + x] =
                scene_value(pattern, seed, x as i64 - shift.0, y as i64 - shift.1);
        }
    }
    f
}

/// The frame's pixels in rows `stride` bytes apart, padding bytes set to `pad`.
fn strided(frame: &Frame, stride: usize, pad: u8) -> Vec<u8> {
    let mut data = vec![pad; stride * (frame.height - 1) + frame.width];
    for y in 0..frame.height {
        let row = &frame.data[y * frame.width..(y + 1) * frame.width];
        data[y * stride..y * stride + frame.width].copy_from_slice(row);
    }
    data
}

/// True when `p` is inside a `width` x `height` frame: `[0, width - 1] x [0, height - 1]`.
fn inside(p: Point, width: usize, height: usize) -> bool {
    let (x, y) = p.to_f32();
    (0.0..=(width - 1) as f32).contains(&x) && (0.0..=(height - 1) as f32).contains(&y)
}

/// A point anywhere: mostly in or near a `width` x `height` frame, sometimes any Q16 value.
fn point(width: usize, height: usize) -> impl Strategy<Value = Point> {
    let (w, h) = (width as f32, height as f32);
    prop_oneof![
        4 => (-4.0f32..w + 4.0, -4.0f32..h + 4.0).prop_map(|(x, y)| Point::from_f32(x, y)),
        1 => (any::<i32>(), any::<i32>()).prop_map(|(x, y)| Point::from_bits(x, y)),
    ]
}

/// Where a point is, relative to a frame of any size.
#[derive(Debug, Clone, Copy)]
enum Place {
    /// At these fractions of the frame's width and height: mostly inside, some just outside.
    Share(f32, f32),
    /// Any Q16 position.
    Bits(i32, i32),
}

impl Place {
    fn at(self, width: usize, height: usize) -> Point {
        match self {
            Place::Share(x, y) => Point::from_f32(x * width as f32, y * height as f32),
            Place::Bits(x, y) => Point::from_bits(x, y),
        }
    }
}

fn place() -> impl Strategy<Value = Place> {
    prop_oneof![
        6 => (-0.1f32..1.1, -0.1f32..1.1).prop_map(|(x, y)| Place::Share(x, y)),
        1 => (any::<i32>(), any::<i32>()).prop_map(|(x, y)| Place::Bits(x, y)),
    ]
}

fn mean_abs_residual_ok(r: Q16) -> bool {
    (Q16::ZERO..=Q16::from_num(255)).contains(&r)
}

// ---------------------------------------------------------------------------------------------
// Translation and zero motion

/// Largest error of any tracked point under a pure translation, px.
const TRANSLATION_MAX_ERROR: f32 = 0.25;
/// Largest median error of the tracked points of one pair, px.
const TRANSLATION_MEDIAN_ERROR: f32 = 0.1;
/// Smallest share of the textured points tracked.
const TRANSLATION_TRACKED: f32 = 0.98;

/// How far LK may move a point of a frame tracked onto itself, px: its convergence threshold
/// (`epsilon`, 0.01 px by default). The pyramid's coarse levels see the point with its low
/// bits shifted out, so the finest level starts up to 2^-13 px off and stops once a step is
/// below epsilon; on smooth and blocky scenes the point comes back within a few Q16 steps, on
/// pure noise (where interpolation is far from linear) within a few thousandths of a pixel.
const ZERO_FLOW_TOLERANCE: Q16 = Q16::lit("0.01");
/// Largest residual of a frame tracked onto itself, grey levels.
const ZERO_FLOW_RESIDUAL: Q16 = Q16::lit("1");
/// The largest move seen so far, Q16 bits (each new worst is printed).
static ZERO_FLOW_WORST: AtomicU32 = AtomicU32::new(0);

proptest! {
    #![proptest_config(config(100))]

    /// A seeded 128 x 96 scene with sensor noise of 1 grey level, moved by up to 8 px in each
    /// direction: LK (default parameters) on a grid of textured points recovers the shift.
    #[test]
    fn a_pure_translation_is_recovered(
        seed in 0u64..1_000_000,
        dx in -8.0f64..8.0,
        dy in -8.0f64..8.0,
    ) {
        let (w, h) = (128, 96);
        let warp = Homography::translation(dx, dy);
        let (prev, next) = pair(&SceneSpec::new(w, h, seed).with_noise(1.0), &warp);
        let points = textured_points(&prev, &grid_points(w, h, 10, 20.0), 21, 10.0);
        prop_assume!(points.len() >= 10);
        let q: Vec<Point> = points.iter().map(|&(x, y)| Point::from_f32(x, y)).collect();
        let out = track(&prev, &next, &q, LkParams::default());
        let mut errors: Vec<f32> = Vec::new();
        for (&(x, y), r) in points.iter().zip(&out) {
            if r.is_tracked() {
                let (tx, ty) = true_position(&warp, x, y);
                let (ex, ey) = r.position.to_f32();
                errors.push((ex - tx).hypot(ey - ty));
            }
        }
        errors.sort_by(f32::total_cmp);
        let share = errors.len() as f32 / points.len() as f32;
        prop_assert!(share >= TRANSLATION_TRACKED, "tracked {share}");
        let median = errors[errors.len() / 2];
        let worst = errors[errors.len() - 1];
        prop_assert!(median <= TRANSLATION_MEDIAN_ERROR, "median {median} px");
        prop_assert!(worst <= TRANSLATION_MAX_ERROR, "worst {worst} px");
    }
}

proptest! {
    #![proptest_config(config(200))]

    /// A frame tracked onto itself: every tracked point stays exactly where it was, with zero
    /// residual; so does every live track of a tracker given the same frame twice, every
    /// measured node of the dense grid, and the ego-motion of those tracks is the identity.
    #[test]
    fn zero_motion_gives_zero_flow(
        pattern in pattern(),
        seed in any::<u64>(),
        width in 48usize..120,
        height in 40usize..96,
        points in prop::collection::vec(point(120, 96), 1..40),
    ) {
        let f = frame(pattern, seed, width, height, (0, 0));
        let out = track(&f, &f, &points, LkParams::default());
        for (p, r) in points.iter().zip(&out) {
            if r.is_tracked() {
                let off = (r.position.x - p.x).abs().max((r.position.y - p.y).abs());
                let bits = off.to_bits() as u32;
                if ZERO_FLOW_WORST.fetch_max(bits, Ordering::Relaxed) < bits {
                    eprintln!("zero motion: LK moved a point by {off} px");
                }
                prop_assert!(off <= ZERO_FLOW_TOLERANCE, "{:?} moved to {:?}", p, r);
                prop_assert!(r.residual <= ZERO_FLOW_RESIDUAL, "{:?}", r);
            }
        }

        let config = TrackerConfig {
            max_tracks: 32,
            refill: Refill { below: 0, ..Refill::default() },
            ..TrackerConfig::default()
        };
        let mut buffers = HostBuffers::new(&config, width, height);
        let mut tracker = Tracker::<32>::new(config, width, height, buffers.lend()).unwrap();
        let view = f.view().unwrap();
        tracker.start(view).unwrap();
        let born: Vec<Track> = tracker.tracks().to_vec();
        let report = tracker.process(view, view, None).unwrap();
        prop_assert_eq!(report.dropped(), 0);
        prop_assert_eq!(tracker.tracks().len(), born.len());
        for (a, b) in born.iter().zip(tracker.tracks()) {
            prop_assert_eq!((a.id, a.position), (b.id, b.position));
        }

        let pairs: Vec<((f32, f32), (f32, f32))> =
            born.iter().map(|t| (t.position.to_f32(), t.position.to_f32())).collect();
        let ransac = Ransac::new(RansacParams::default()).unwrap();
        let mut flags = vec![false; pairs.len()];
        let motion = ransac.estimate(&pairs, &mut flags).unwrap();
        if motion.is_ok() {
            for corner in [(0.0, 0.0), (width as f32, 0.0), (0.0, height as f32)] {
                let (x, y) = motion.model.apply(corner).unwrap();
                prop_assert!((x - corner.0).hypot(y - corner.1) < 1e-3);
            }
        }

        let mut runner = MotionRunner::new(MotionSettings::default(), width, height).unwrap();
        runner.push(f.clone()).unwrap();
        let found = runner.push(f.clone()).unwrap().unwrap();
        for node in runner.nodes().iter().filter(|n| n.has_flow()) {
            prop_assert_eq!(node.flow, Point::default());
        }
        prop_assert_eq!(found.summary.boxes, 0);
    }
}

/// LK of `params` (levels clamped to what the frames allow) from `prev` to `next`.
fn track(prev: &Frame, next: &Frame, points: &[Point], params: LkParams) -> Vec<PointTrack> {
    let levels = params.max_level;
    let mut a = vec![0u8; pyramid_storage_len(prev.width, prev.height, levels)];
    let mut b = vec![0u8; pyramid_storage_len(next.width, next.height, levels)];
    let prev = Pyramid::build(prev.view().unwrap(), levels, &mut a).unwrap();
    let next = Pyramid::build(next.view().unwrap(), levels, &mut b).unwrap();
    let lk = LucasKanade::new(params).unwrap();
    let mut out = vec![PointTrack::default(); points.len()];
    let mut scratch = vec![0i16; scratch_len(params.window)];
    lk.track_points(&prev, &next, points, None, &mut out, &mut scratch)
        .unwrap();
    out
}

// ---------------------------------------------------------------------------------------------
// LK on arbitrary input

fn lk_params() -> impl Strategy<Value = LkParams> {
    (
        (1usize..=31).prop_map(|k| 2 * k + 1),
        0usize..=6,
        1u32..=40,
        prop_oneof![Just(0.0f32), 0.0f32..0.5, Just(1e-6)],
        prop_oneof![Just(0.0f32), 0.0f32..0.05],
        prop_oneof![Just(Illumination::Plain), Just(Illumination::GainBias)],
        prop_oneof![
            Just(TemplatePlacement::AtPoint),
            Just(TemplatePlacement::NearestPixel)
        ],
    )
        .prop_map(
            |(
                window,
                max_level,
                max_iterations,
                epsilon,
                min_eigen_threshold,
                illumination,
                template,
            )| {
                LkParams {
                    window,
                    max_level,
                    max_iterations,
                    epsilon,
                    min_eigen_threshold,
                    illumination,
                    template,
                }
            },
        )
}

/// Two arbitrary frames, the second possibly shifted, lit differently or of another scene.
#[derive(Debug, Clone)]
struct FramePair {
    prev: Frame,
    next: Frame,
    stride_pad: usize,
}

fn frame_pair(max_side: usize) -> impl Strategy<Value = FramePair> {
    (
        (1usize..=max_side, 1usize..=max_side),
        (pattern(), pattern(), any::<u64>(), any::<bool>()),
        (-6i64..=6, -6i64..=6),
        0usize..5,
    )
        .prop_map(
            |((width, height), (p1, p2, seed, same), shift, stride_pad)| {
                let prev = frame(p1, seed, width, height, (0, 0));
                let next = if same {
                    frame(p1, seed, width, height, shift)
                } else {
                    frame(p2, seed ^ 1, width, height, shift)
                };
                FramePair {
                    prev,
                    next,
                    stride_pad,
                }
            },
        )
}

proptest! {
    #![proptest_config(config(1000))]

    /// Arbitrary frames (1 to 64 px a side, padded strides), parameters and points (anywhere
    /// in Q16, guesses too): a tracked point is inside the next frame with a residual in
    /// `0..=255`; any other status has residual 0.
    #[test]
    fn lk_statuses_agree_with_positions(
        frames in frame_pair(64),
        params in lk_params(),
        points in prop::collection::vec((place(), prop::option::of(place())), 1..24),
    ) {
        let FramePair { prev, next, stride_pad } = frames;
        let (w, h) = (prev.width, prev.height);
        let points: Vec<(Point, Option<Point>)> =
            points.into_iter().map(|(p, g)| (p.at(w, h), g.map(|g| g.at(w, h)))).collect();
        let stride = w + stride_pad;
        let (a, b) = (strided(&prev, stride, 0xAA), strided(&next, stride, 0x55));
        let prev_view = ImageView::new(&a, w, h, stride).unwrap();
        let next_view = ImageView::new(&b, w, h, stride).unwrap();
        let levels = params.max_level;
        let mut sa = vec![0u8; pyramid_storage_len(w, h, levels)];
        let mut sb = vec![0u8; pyramid_storage_len(w, h, levels)];
        let (Ok(pa), Ok(pb)) = (
            Pyramid::build(prev_view, levels, &mut sa),
            Pyramid::build(next_view, levels, &mut sb),
        ) else {
            return Ok(());
        };
        let lk = LucasKanade::new(params).unwrap();
        let mut scratch = vec![0i16; scratch_len(params.window)];
        let (p, g): (Vec<Point>, Vec<Option<Point>>) = points.into_iter().unzip();
        let guesses: Vec<Point> = p.iter().zip(&g).map(|(p, g)| g.unwrap_or(*p)).collect();
        let mut out = vec![PointTrack::default(); p.len()];
        lk.track_points(&pa, &pb, &p, Some(&guesses), &mut out, &mut scratch).unwrap();
        for (i, r) in out.iter().enumerate() {
            let single = lk.track_point(&pa, &pb, p[i], Some(guesses[i]), &mut scratch).unwrap();
            prop_assert_eq!(single, *r, "track_point and track_points differ");
            match r.status {
                TrackStatus::Tracked => {
                    prop_assert!(inside(r.position, w, h), "tracked outside: {:?}", r);
                    prop_assert!(mean_abs_residual_ok(r.residual), "residual {:?}", r);
                }
                _ => prop_assert_eq!(r.residual, Q16::ZERO),
            }
            if !inside(p[i], w, h) {
                prop_assert_eq!(r.status, TrackStatus::OutOfBounds);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The tracker on arbitrary sequences

/// Capacity of the trackers under test.
const N: usize = 16;

fn tracker_config() -> impl Strategy<Value = TrackerConfig> {
    (
        (1usize..=N, 0usize..=N),
        ((1usize..=12).prop_map(|k| 2 * k + 1), 0usize..=3, 1u32..=30),
        (any::<bool>(), 1u8..=40, 0usize..=2),
        (1usize..=8, 1usize..=8, 1u8..=4),
        (0u16..=12, 0u16..=10),
        (
            prop_oneof![Just(f32::INFINITY), 0.1f32..3.0],
            prop_oneof![Just(f32::INFINITY), 1.0f32..30.0],
            prop_oneof![Just(f32::INFINITY), 1.0f32..5.0],
            prop_oneof![Just(-1.0f32), 0.0f32..1.0],
        ),
    )
        .prop_map(
            |(
                (max_tracks, refill),
                (window, max_level, max_iterations),
                (fast, threshold, detect_level),
                (cols, rows, per_cell),
                (border, min_distance),
                (fb_threshold, max_residual, residual_ratio, min_correlation),
            )| {
                let detector = if fast {
                    Detector::Fast(Fast {
                        threshold,
                        nonmax: true,
                    })
                } else {
                    Detector::ShiTomasi(ShiTomasi {
                        min_distance: 0,
                        ..ShiTomasi::default()
                    })
                };
                TrackerConfig {
                    lk: LkParams {
                        window,
                        max_level,
                        max_iterations,
                        ..TrackerConfig::default().lk
                    },
                    max_tracks,
                    refill: Refill {
                        below: refill.min(max_tracks),
                        detector,
                        level: detect_level,
                        grid: Grid {
                            cols,
                            rows,
                            per_cell,
                        },
                        border,
                        min_distance,
                        ..Refill::default()
                    },
                    gates: Gates {
                        fb_threshold,
                        max_residual,
                        residual_ratio,
                        min_correlation,
                        ..Gates::default()
                    },
                    ..TrackerConfig::default()
                }
            },
        )
}

/// One frame of a generated sequence.
#[derive(Debug, Clone, Copy)]
enum Step {
    /// The scene moved by this much since the frame before.
    Move(i64, i64),
    /// Another scene.
    Other(Pattern, u64),
    /// Called with a wrong previous frame: must be refused, tracks untouched.
    WrongPrevious,
    /// `start` again on the current frame.
    Restart,
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        8 => (-4i64..=4, -4i64..=4).prop_map(|(x, y)| Step::Move(x, y)),
        1 => (pattern(), any::<u64>()).prop_map(|(p, s)| Step::Other(p, s)),
        1 => Just(Step::WrongPrevious),
        1 => Just(Step::Restart),
    ]
}

proptest! {
    #![proptest_config(config(400))]

    /// Arbitrary settings and frame sequences (16 to 96 px a side, scenes moving by up to
    /// 4 px a frame, swapped for others, restarts, wrong previous frames): after every frame the
    /// tracker holds at most `max_tracks` tracks, each inside the frame with a residual in
    /// `0..=255`, ids unique within the frame and never reused, ages and birth frames
    /// consistent, and the report adds up.
    #[test]
    fn the_tracker_keeps_its_invariants(
        config in tracker_config(),
        (width, height) in (16usize..=96, 16usize..=96),
        (first, seed) in (pattern(), any::<u64>()),
        steps in prop::collection::vec(step(), 1..8),
    ) {
        let mut buffers = HostBuffers::new(&config, width, height);
        let mut tracker = Tracker::<N>::new(config, width, height, buffers.lend()).unwrap();
        let mut current = frame(first, seed, width, height, (0, 0));
        let mut frame_index = 0u32;
        let mut offset = (0, 0);
        let report = tracker.start(current.view().unwrap()).unwrap();
        let mut ids_seen: BTreeSet<u32> = BTreeSet::new();
        let mut previous: Vec<Track> = Vec::new();
        check_tracks(tracker.tracks(), &previous, &mut ids_seen, frame_index, &config, (width, height))?;
        prop_assert_eq!(report.added, tracker.tracks().len());
        previous = tracker.tracks().to_vec();
        for step in steps {
            let next = match step {
                Step::Move(dx, dy) => {
                    offset = (offset.0 + dx, offset.1 + dy);
                    frame(first, seed, width, height, offset)
                }
                Step::Other(p, s) => frame(p, s, width, height, (0, 0)),
                Step::WrongPrevious => {
                    let mut wrong = current.clone();
                    for v in wrong.data.iter_mut() {
                        *v = v.wrapping_add(1);
                    }
                    let result = tracker.process(wrong.view().unwrap(), current.view().unwrap(), None);
                    prop_assert_eq!(result, Err(TrackerError::NotThePreviousFrame));
                    prop_assert_eq!(tracker.tracks(), &previous[..]);
                    continue;
                }
                Step::Restart => {
                    frame_index += 1;
                    let report = tracker.start(current.view().unwrap()).unwrap();
                    prop_assert_eq!(report.added, tracker.tracks().len());
                    check_tracks(tracker.tracks(), &[], &mut ids_seen, frame_index, &config, (width, height))?;
                    previous = tracker.tracks().to_vec();
                    continue;
                }
            };
            frame_index += 1;
            let report = tracker.process(current.view().unwrap(), next.view().unwrap(), None).unwrap();
            prop_assert_eq!(report.live, tracker.tracks().len());
            prop_assert_eq!(report.tracked + report.dropped(), previous.len());
            prop_assert_eq!(report.live, report.tracked + report.revived + report.added);
            prop_assert!(report.added == 0 || report.detected);
            check_tracks(tracker.tracks(), &previous, &mut ids_seen, frame_index, &config, (width, height))?;
            prop_assert_eq!(tracker.frame_index(), Some(frame_index));
            previous = tracker.tracks().to_vec();
            current = next;
        }
    }
}

/// The invariants of the tracks after frame `index`, given the tracks before it.
fn check_tracks(
    tracks: &[Track],
    before: &[Track],
    ids_seen: &mut BTreeSet<u32>,
    index: u32,
    config: &TrackerConfig,
    (width, height): (usize, usize),
) -> Result<(), TestCaseError> {
    prop_assert!(tracks.len() <= config.max_tracks && tracks.len() <= N);
    let ids: BTreeSet<u32> = tracks.iter().map(|t| t.id).collect();
    prop_assert_eq!(ids.len(), tracks.len(), "an id twice");
    let highest_before = ids_seen.iter().next_back().copied();
    for t in tracks {
        prop_assert!(inside(t.position, width, height), "track outside: {:?}", t);
        prop_assert!(mean_abs_residual_ok(t.residual), "residual {:?}", t);
        match before.iter().find(|b| b.id == t.id) {
            Some(b) => {
                prop_assert_eq!((t.born, t.age), (b.born, b.age + 1));
            }
            // Revived: dropped earlier on a still camera, back with its id, birth and age.
            None if ids_seen.contains(&t.id) => {
                prop_assert!(t.age >= 8 && t.born < index, "revived: {:?}", t);
            }
            None => {
                prop_assert!(highest_before.is_none_or(|h| t.id > h));
                prop_assert_eq!((t.born, t.age), (index, 0));
                prop_assert_eq!(t.residual, Q16::ZERO);
            }
        }
    }
    ids_seen.extend(ids);
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Dense grid and motion boxes on arbitrary input

fn dense_settings() -> impl Strategy<Value = MotionSettings> {
    (
        2usize..=16,
        (1usize..=10).prop_map(|k| 2 * k + 1),
        0usize..=3,
        0u8..=3,
        any::<bool>(),
        0.0f32..40.0,
    )
        .prop_map(
            |(cell, window, max_level, fill_passes, include_filled, max_residual)| {
                let defaults = DenseParams::for_motion();
                MotionSettings {
                    dense: DenseParams {
                        cell,
                        lk: LkParams {
                            window,
                            max_level,
                            ..defaults.lk
                        },
                        max_residual,
                        fill_passes,
                        ..defaults
                    },
                    fit: DominantFitParams::default(),
                    motion: MotionParams {
                        include_filled,
                        ..MotionParams::default()
                    },
                    ..MotionSettings::default()
                }
            },
        )
}

proptest! {
    #![proptest_config(config(500))]

    /// Arbitrary frames (1 to 96 px a side) and grid settings: a measured node's flow takes its
    /// centre to a point inside the frame, no node without flow has one, filled nodes carry a
    /// fill pass, the dominant motion is finite and its counts consistent, and every box (and
    /// every box moved into the next frame) lies inside the frame, with a mean flow smaller
    /// than the frame.
    #[test]
    fn dense_outputs_stay_in_range(
        frames in frame_pair(96),
        settings in dense_settings(),
    ) {
        let FramePair { prev, next, .. } = frames;
        let (w, h) = (prev.width, prev.height);
        let Ok(mut runner) = MotionRunner::new(settings, w, h) else {
            // Refused settings (cell larger than the frame, frame too small for the pyramid).
            return Ok(());
        };
        prop_assert!(runner.push(prev).unwrap().is_none());
        let Ok(found) = runner.push(next) else {
            return Ok(());
        };
        let found = found.unwrap();
        let layout = *runner.layout();
        for (i, node) in runner.nodes().iter().enumerate() {
            let (col, row) = layout.node(i);
            let (cx, cy) = layout.centre(col, row);
            let centre = Point::from_f32(cx as f32, cy as f32);
            let (fx, fy) = node.flow.to_f32();
            match node.status {
                NodeStatus::Tracked => {
                    let end = Point::new(centre.x + node.flow.x, centre.y + node.flow.y);
                    prop_assert!(inside(end, w, h), "node {} flows out: {:?}", i, node);
                    prop_assert_eq!(node.fill_pass, 0);
                }
                NodeStatus::Filled => {
                    prop_assert!(node.fill_pass >= 1 && node.fill_pass <= settings.dense.fill_passes);
                    prop_assert!(fx.abs() <= w as f32 && fy.abs() <= h as f32);
                }
                _ => prop_assert_eq!((node.flow, node.fill_pass), (Point::default(), 0)),
            }
        }
        let camera = found.camera;
        let coefficients = camera.motion.dx.iter().chain(&camera.motion.dy);
        prop_assert!(coefficients.into_iter().all(|c| c.is_finite()), "{:?}", camera);
        prop_assert!(camera.spread.is_finite() && camera.spread >= 0.0);
        let measured = runner.nodes().iter().filter(|n| n.is_valid()).count();
        prop_assert!(camera.inliers <= camera.measured && camera.measured <= measured);
        prop_assert!(found.summary.boxes <= found.candidates);
        // A region may be outlined as several boxes, or as none.
        prop_assert!(found.candidates <= host_sim::dense::MAX_BOXES);
        prop_assert!(found.summary.moving <= layout.len());
        for b in &found.boxes {
            prop_assert!(b.w > 0 && b.h > 0 && b.nodes > 0, "{:?}", b);
        }
        // Moved into the later frame a box may leave it: clipped, it is then empty.
        for b in found.boxes.iter().chain(&found.boxes_in_later_frame(w, h)) {
            prop_assert!(usize::from(b.x) + usize::from(b.w) <= w, "{:?}", b);
            prop_assert!(usize::from(b.y) + usize::from(b.h) <= h, "{:?}", b);
            let (mx, my) = b.mean_flow.to_f32();
            prop_assert!(mx.abs() <= w as f32 && my.abs() <= h as f32, "{:?}", b);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Ego-motion and OPTICAL_FLOW_RAD on arbitrary tracks

/// Any `f32`: ordinary coordinates, extremes, NaN and infinities.
fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => -50.0f32..400.0,
        1 => any::<f32>(),
        1 => prop::sample::select(vec![
            0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, f32::MIN,
            f32::MIN_POSITIVE, 65_536.0, -65_536.0, 1e30,
        ]),
    ]
}

/// Tracks: most follow one model (so that estimates succeed), the rest are outliers; in a
/// quarter of the cases the outliers may be anything, NaN and infinities included.
fn tracks() -> impl Strategy<Value = Vec<((f32, f32), (f32, f32))>> {
    let anything = prop_oneof![
        3 => ((0.0f32..320.0, 0.0f32..240.0), (0.0f32..320.0, 0.0f32..240.0)),
        1 => ((coordinate(), coordinate()), (coordinate(), coordinate())),
    ];
    (
        (-5.0f32..5.0, -5.0f32..5.0, -0.05f32..0.05, 0.95f32..1.05),
        prop::collection::vec(
            prop_oneof![
                6 => (0.0f32..320.0, 0.0f32..240.0).prop_map(|p| (p, None)),
                1 => ((0.0f32..320.0, 0.0f32..240.0), (0.0f32..320.0, 0.0f32..240.0))
                    .prop_map(|(p, q)| (p, Some(q))),
            ],
            0..80,
        ),
        prop::collection::vec(anything, 0..3),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(|((tx, ty, angle, scale), raw, wild, use_wild, at_end)| {
            let (s, c) = (scale * angle.sin(), scale * angle.cos());
            let mut tracks: Vec<_> = raw
                .into_iter()
                .map(|((x, y), other)| {
                    let moved = (c * x - s * y + tx, s * x + c * y + ty);
                    ((x, y), other.unwrap_or(moved))
                })
                .collect();
            if use_wild && at_end {
                tracks.extend(wild);
            } else if use_wild {
                tracks.splice(0..0, wild);
            }
            tracks
        })
}

fn ransac_params() -> impl Strategy<Value = RansacParams> {
    (
        prop::sample::select(vec![
            ModelKind::Translation,
            ModelKind::Similarity,
            ModelKind::Affine,
            ModelKind::Homography,
        ]),
        prop_oneof![0.01f32..5.0, Just(1000.0f32)],
        1u16..=300,
        0.01f32..0.9999,
        0u16..=40,
        any::<u64>(),
    )
        .prop_map(
            |(model, threshold, max_iterations, confidence, min_inliers, seed)| RansacParams {
                model,
                threshold,
                max_iterations,
                confidence,
                min_inliers,
                seed,
            },
        )
}

/// One frame interval and gyro reading, anything.
fn interval_and_gyro() -> impl Strategy<Value = (u32, Option<[f32; 3]>)> {
    (
        prop_oneof![4 => 1u32..100_000, 1 => any::<u32>()],
        prop::option::of(prop_oneof![
            3 => [-0.05f32..0.05, -0.05f32..0.05, -0.05f32..0.05],
            1 => [coordinate(), coordinate(), coordinate()],
        ]),
    )
}

fn assert_motion_in_range(
    motion: &EgoMotion,
    params: &RansacParams,
    tracks: usize,
    flags: &[bool],
) -> Result<(), TestCaseError> {
    prop_assert!(
        motion.model.matrix().iter().all(|m| m.is_finite()),
        "{:?}",
        motion
    );
    prop_assert!(motion.rms_residual.is_finite() && motion.rms_residual >= 0.0);
    prop_assert!(motion.iterations <= params.max_iterations);
    let marked = flags.iter().filter(|&&f| f).count();
    if motion.is_ok() {
        prop_assert!(motion.quality >= 1);
        prop_assert!(motion.rms_residual <= params.threshold);
        prop_assert!(usize::from(motion.inliers) <= tracks);
        prop_assert_eq!(marked, usize::from(motion.inliers));
    } else {
        prop_assert_eq!((motion.quality, motion.inliers, marked), (0, 0, 0));
        prop_assert_eq!(motion.rms_residual, 0.0);
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(2000))]

    /// Arbitrary tracks (NaN, infinities and extremes among them) and estimator settings:
    /// every field of the estimate is finite, quality is 0 exactly when the status is not Ok,
    /// and the inlier flags agree with the count. Fed with arbitrary intervals and gyro
    /// readings to the OPTICAL_FLOW_RAD accumulator, the readout's flow is finite and at most
    /// a quarter turn per frame, a gyro integral is finite when present, quality is 0 once
    /// any frame was unusable, and the MAVLink frame carries the same values.
    #[test]
    fn ego_motion_and_flow_rad_stay_in_range(
        tracks in tracks(),
        params in ransac_params(),
        frames in prop::collection::vec(interval_and_gyro(), 1..6),
        distance in coordinate(),
        time in any::<u64>(),
    ) {
        let ransac = Ransac::new(params).unwrap();
        let mut flags = vec![false; tracks.len()];
        let motion = ransac.estimate(&tracks, &mut flags).unwrap();
        assert_motion_in_range(&motion, &params, tracks.len(), &flags)?;
        if tracks.iter().any(|&((a, b), (c, d))| ![a, b, c, d].iter().all(|v| v.is_finite())) {
            prop_assert_eq!(motion.status, EgoStatus::BadInput);
        }

        let camera = Camera::new(CameraParams::from_horizontal_fov(320, 240, 1.2)).unwrap();
        let mut acc = FlowRadAccumulator::new(camera, 3);
        acc.set_distance(distance, time / 2);
        let mut all_ok = true;
        let mut total_us = 0u64;
        for &(interval, gyro) in &frames {
            all_ok &= acc.add(&motion, interval, gyro) == EgoStatus::Ok;
            if (1..=1_000_000).contains(&interval) {
                total_us += u64::from(interval);
            }
        }
        prop_assert_eq!(acc.frames() as usize, frames.len());
        let flow = acc.readout(time);
        let quarter_turns = frames.len() as f32 * core::f32::consts::FRAC_PI_2;
        for v in [flow.integrated_x, flow.integrated_y] {
            prop_assert!(v.is_finite() && v.abs() <= quarter_turns, "{:?}", flow);
        }
        for g in [flow.integrated_xgyro, flow.integrated_ygyro, flow.integrated_zgyro] {
            prop_assert!(g.is_none_or(f32::is_finite), "{:?}", flow);
        }
        prop_assert!(flow.distance.is_none_or(|d| d.is_finite() && d >= 0.0));
        prop_assert_eq!(u64::from(flow.integration_time_us), total_us.min(u64::from(u32::MAX)));
        if all_ok {
            prop_assert!(flow.quality >= 1);
        } else {
            prop_assert_eq!((flow.quality, flow.integrated_x, flow.integrated_y), (0, 0.0, 0.0));
        }
        prop_assert_eq!(acc.frames(), 0);

        let mut wire = [0u8; MAX_FRAME_LEN];
        let header = MavlinkHeader { system_id: 1, component_id: 2, sequence: 3 };
        let len = encode_optical_flow_rad(&flow, header, &mut wire).unwrap();
        // MAVLink 2: 10 header bytes, then the payload with its trailing zeros cut.
        let payload_len = usize::from(wire[1]);
        prop_assert_eq!(len, 10 + payload_len + 2);
        let mut payload = [0u8; 44];
        payload[..payload_len].copy_from_slice(&wire[10..10 + payload_len]);
        let f32_at = |at: usize| f32::from_le_bytes(payload[at..at + 4].try_into().unwrap());
        prop_assert_eq!(f32_at(12).to_bits(), flow.integrated_x.to_bits());
        prop_assert_eq!(f32_at(16).to_bits(), flow.integrated_y.to_bits());
        let gyro_on_wire = [f32_at(20), f32_at(24), f32_at(28)];
        let gyro = [flow.integrated_xgyro, flow.integrated_ygyro, flow.integrated_zgyro];
        for (wired, g) in gyro_on_wire.iter().zip(gyro) {
            // NaN on the wire is MAVLink's "no gyro", and nothing else is NaN.
            prop_assert_eq!(wired.is_nan(), g.is_none());
        }
        let wired_distance = f32_at(36);
        prop_assert!(wired_distance.is_finite());
        prop_assert_eq!(payload[43], flow.quality);
    }
}
