//! Hostile frames through the whole pipeline: the tracker, ego-motion on its tracks, and the
//! dense grid with its motion boxes on the same frames.
//!
//! A camera can deliver black, white, saturated or noisy frames, a frame twice, a frame of
//! another scene, or a sudden exposure jump. The pipeline must then degrade to few or no
//! tracks and low quality, never to confident wrong output. Each test states what that means
//! for its frames; in all of them:
//!
//! - a *wrong track* is a live track more than [`WRONG_PX`] from where the scene point it
//!   was born on truly is, and there are none;
//! - a *confident wrong ego-motion* is an `Ok` estimate that moves the frame's corners more
//!   than [`WRONG_PX`] on average from the truth, or any `Ok` estimate where there is no truth
//!   (unrelated frames, a pattern that does not determine the motion); there are none;
//! - a *wrong node* is a measured dense node whose flow is more than [`WRONG_PX`] from the
//!   truth, or any measured node where there is no truth; there are at most [`WRONG_NODES`],
//!   unless the grid degraded to at most [`FEW_NODES`] measured nodes;
//! - a *false box* is a motion box in a scene where nothing moves but the camera, and there
//!   are none.
//!
//! Frames are 160 x 120 renderings of seeded synthetic scenes with 1 grey level of sensor
//! noise, unless a test says otherwise. Every figure is printed; to see them:
//! `cargo test --release --test hostile_frames -- --nocapture --test-threads 1`.

use host_sim::dense::{MotionFrame, MotionRunner, MotionSettings};
use host_sim::synth::{Homography, Lighting, Scene, SceneSpec, SplitMix64};
use host_sim::tracking::HostBuffers;
use host_sim::Frame;
use kestrel::dense::GridNode;
use kestrel::ego::{EgoMotion, EgoStatus, Ransac, RansacParams};
use kestrel::track::{FrameReport, Track, Tracker, TrackerConfig};

const W: usize = 160;
const H: usize = 120;
/// Tracker capacity.
const N: usize = 100;
/// Farther than this from the truth is wrong, px.
const WRONG_PX: f32 = 1.0;
/// Wrong tracks allowed in a frame: 5 % of the capacity.
const WRONG_TRACKS: usize = 5;
/// Wrong measured nodes allowed in a frame: 5 % of the 20 x 15 grid...
const WRONG_NODES: usize = 15;
/// ...unless the grid degraded to at most this many measured nodes, 20 % of it (the dense grid
/// has no forward-backward check: after a scene cut a few nodes converge on a wrong match).
const FEW_NODES: usize = 60;

/// A scene id and a position in its reference view, or a shift of it.
type ScenePoint = (u64, (f32, f32));

/// A frame, and how the scene it shows relates to the other frames of its sequence.
struct Shot {
    frame: Frame,
    /// The scene (`Some(id)`), shifted by this much from its reference view; `None` when the
    /// frame shows nothing that moves with any scene (flat, noise).
    truth: Option<ScenePoint>,
}

/// The textured scene `seed` shifted by `shift`, lit by `lighting`, noise draw `index`.
fn scene(seed: u64, shift: (f32, f32), lighting: Lighting, index: u64) -> Shot {
    let spec = SceneSpec::new(W, H, seed)
        .with_noise(1.0)
        .with_supersample(1);
    let warp = Homography::translation(f64::from(shift.0), f64::from(shift.1));
    Shot {
        frame: Scene::new(spec).render(&warp, lighting, index),
        truth: Some((seed, shift)),
    }
}

fn lit(seed: u64, shift: (f32, f32), index: u64) -> Shot {
    scene(seed, shift, Lighting::UNCHANGED, index)
}

/// A frame without any scene in it.
fn pattern(mut pixel: impl FnMut(usize, usize) -> u8) -> Shot {
    let mut frame = Frame::filled(W, H, 0);
    for y in 0..H {
        for x in 0..W {
            frame.data[y * W + x] = pixel(x, y);
        }
    }
    Shot { frame, truth: None }
}

fn noise(seed: u64) -> Shot {
    let mut rng = SplitMix64::new(seed);
    pattern(|_, _| (rng.next_u64() >> 56) as u8)
}

/// What the pipeline made of one frame (after the first).
struct Outcome {
    report: FrameReport,
    tracks: Vec<Track>,
    /// Live tracks' errors against the truth (empty without truth).
    track_errors: Vec<f32>,
    ego: EgoMotion,
    /// Mean distance of the frame's corners under the ego-motion from the truth, px.
    ego_error: Option<f32>,
    dense: MotionFrame,
    nodes: Vec<GridNode>,
    /// Measured nodes' errors against the truth.
    node_errors: Vec<f32>,
}

impl Outcome {
    fn valid_nodes(&self) -> usize {
        self.nodes.iter().filter(|n| n.is_valid()).count()
    }

    fn wrong_tracks(&self) -> usize {
        self.track_errors.iter().filter(|&&e| e > WRONG_PX).count()
    }

    fn wrong_nodes(&self) -> usize {
        self.node_errors.iter().filter(|&&e| e > WRONG_PX).count()
    }

    fn print(&self, label: &str, k: usize) {
        let r = &self.report;
        eprintln!(
            "{label} frame {k}: live {} (tracked {} added {} dropped lost {} residual {} \
             appearance {} fb {}), {} wrong; ego {:?} quality {} inliers {} \
             error {}; dense valid {} ({} wrong) moving {}, boxes {}",
            r.live,
            r.tracked,
            r.added,
            r.dropped_lost,
            r.dropped_residual,
            r.dropped_appearance,
            r.dropped_fb,
            self.wrong_tracks(),
            self.ego.status,
            self.ego.quality,
            self.ego.inliers,
            self.ego_error
                .map_or("-".to_string(), |e| format!("{e:.3} px")),
            self.valid_nodes(),
            self.wrong_nodes(),
            self.dense.summary.moving,
            self.dense.summary.boxes,
        );
    }
}

/// Runs the tracker, ego-motion and the dense pipeline over `shots`; one outcome per frame
/// after the first.
fn run(label: &str, shots: &[Shot]) -> Vec<Outcome> {
    let config = TrackerConfig::default();
    let mut buffers = HostBuffers::new(&config, W, H);
    let mut tracker = Tracker::<N>::new(config, W, H, buffers.lend()).unwrap();
    let ransac = Ransac::new(RansacParams::default()).unwrap();
    let mut dense = MotionRunner::new(MotionSettings::default(), W, H).unwrap();

    let first = &shots[0];
    let report = tracker.start(first.frame.view().unwrap()).unwrap();
    eprintln!("{label} frame 0: {} tracks", report.live);
    assert!(dense.push(first.frame.clone()).unwrap().is_none());
    // Where each live track's scene point is in its scene's reference view.
    let mut origins: Vec<(u32, Option<ScenePoint>)> = tracker
        .tracks()
        .iter()
        .map(|t| (t.id, origin(t, first.truth)))
        .collect();
    let mut outcomes = Vec::new();
    for (k, pair) in shots.windows(2).enumerate() {
        let (prev, next) = (&pair[0], &pair[1]);
        let before: Vec<Track> = tracker.tracks().to_vec();
        let report = tracker
            .process(prev.frame.view().unwrap(), next.frame.view().unwrap(), None)
            .unwrap();
        let tracks = tracker.tracks().to_vec();
        let truth = match (prev.truth, next.truth) {
            (Some((a, from)), Some((b, to))) if a == b => Some((to.0 - from.0, to.1 - from.1)),
            _ => None,
        };

        // Tracks born earlier are checked against where their scene point is now.
        let mut track_errors = Vec::new();
        for t in tracks.iter().filter(|t| t.age > 0) {
            let born_on = origins.iter().find(|(id, _)| *id == t.id).and_then(|o| o.1);
            let (x, y) = t.position.to_f32();
            match (born_on, next.truth) {
                (Some((a, (ox, oy))), Some((b, (sx, sy)))) if a == b => {
                    track_errors.push((x - (ox + sx)).hypot(y - (oy + sy)));
                }
                // Followed from a scene into a frame that does not show it: wrong by any
                // measure.
                _ => track_errors.push(f32::INFINITY),
            }
        }
        origins.retain(|(id, _)| tracks.iter().any(|t| t.id == *id));
        for t in tracks.iter().filter(|t| t.age == 0) {
            origins.push((t.id, origin(t, next.truth)));
        }

        let pairs: Vec<((f32, f32), (f32, f32))> = tracks
            .iter()
            .filter_map(|t| {
                let b = before.iter().find(|b| b.id == t.id)?;
                Some((b.position.to_f32(), t.position.to_f32()))
            })
            .collect();
        let mut flags = vec![false; pairs.len()];
        let ego = ransac.estimate(&pairs, &mut flags).unwrap();
        let ego_error = truth.filter(|_| ego.is_ok()).map(|(dx, dy)| {
            let corners = [
                (0.0, 0.0),
                (W as f32, 0.0),
                (0.0, H as f32),
                (W as f32, H as f32),
            ];
            let total: f32 = corners
                .iter()
                .map(|&(x, y)| {
                    let (ex, ey) = ego.model.apply((x, y)).unwrap_or((f32::MAX, f32::MAX));
                    (ex - (x + dx)).hypot(ey - (y + dy))
                })
                .sum();
            total / 4.0
        });

        let found = dense.push(next.frame.clone()).unwrap().unwrap();
        let nodes = dense.nodes().to_vec();
        let node_errors = nodes
            .iter()
            .filter(|n| n.is_valid())
            .map(|n| match truth {
                Some((dx, dy)) => {
                    let (fx, fy) = n.flow.to_f32();
                    (fx - dx).hypot(fy - dy)
                }
                None => f32::INFINITY,
            })
            .collect();
        let outcome = Outcome {
            report,
            tracks,
            track_errors,
            ego,
            ego_error,
            dense: found,
            nodes,
            node_errors,
        };
        outcome.print(label, k + 1);
        outcomes.push(outcome);
    }
    outcomes
}

/// Where the scene point under `track` is in its scene's reference view.
fn origin(track: &Track, truth: Option<ScenePoint>) -> Option<ScenePoint> {
    let (seed, (sx, sy)) = truth?;
    let (x, y) = track.position.to_f32();
    Some((seed, (x - sx, y - sy)))
}

/// At most [`WRONG_TRACKS`] wrong tracks, at most [`WRONG_NODES`] wrong nodes unless at most
/// [`FEW_NODES`] were measured, no confident wrong ego-motion, and no box: nothing in these
/// scenes moves but the camera.
fn assert_nothing_confidently_wrong(label: &str, outcomes: &[Outcome]) {
    for (k, o) in outcomes.iter().enumerate() {
        let k = k + 1;
        assert!(
            o.wrong_tracks() <= WRONG_TRACKS,
            "{label} frame {k}: {} wrong tracks",
            o.wrong_tracks()
        );
        if o.ego.is_ok() {
            let error = o.ego_error.unwrap_or(f32::INFINITY);
            assert!(
                error <= WRONG_PX,
                "{label} frame {k}: ego-motion quality {} is {error} px off",
                o.ego.quality
            );
        } else {
            assert_eq!(o.ego.quality, 0);
        }
        assert!(
            o.wrong_nodes() <= WRONG_NODES || o.valid_nodes() <= FEW_NODES,
            "{label} frame {k}: {} wrong nodes of {}",
            o.wrong_nodes(),
            o.valid_nodes()
        );
        assert_eq!(o.dense.summary.boxes, 0, "{label} frame {k}: false boxes");
    }
}

/// The outcome of a frame with nothing to measure: no tracks, ego quality 0, no measured
/// node, no box.
fn assert_blank(label: &str, k: usize, o: &Outcome) {
    assert_eq!(o.tracks.len(), 0, "{label} frame {k}: tracks");
    assert_eq!(
        (o.ego.status, o.ego.quality),
        (EgoStatus::TooFewTracks, 0),
        "{label} frame {k}: ego"
    );
    assert_eq!(o.valid_nodes(), 0, "{label} frame {k}: measured nodes");
    assert_eq!(o.dense.summary.boxes, 0, "{label} frame {k}: boxes");
}

#[test]
fn black_and_white_frames_end_every_track() {
    for (label, value) in [("black", 0u8), ("white", 255)] {
        let shots = [
            lit(1, (0.0, 0.0), 0),
            lit(1, (1.0, 0.5), 1),
            pattern(|_, _| value),
            pattern(|_, _| value),
            lit(1, (2.0, 1.0), 2),
            lit(1, (3.0, 1.5), 3),
        ];
        let outcomes = run(label, &shots);
        assert_nothing_confidently_wrong(label, &outcomes);
        // Into the flat frame and within it: nothing.
        assert_blank(label, 2, &outcomes[1]);
        assert_blank(label, 3, &outcomes[2]);
        // Back to the scene: new tracks are born, and the motion is found again.
        assert!(
            outcomes[3].report.added >= 60,
            "{label}: refill after the flat frames"
        );
        assert!(outcomes[4].ego.is_ok() && outcomes[4].ego.quality >= 128);
    }
}

#[test]
fn a_tracker_started_on_a_flat_frame_waits_for_texture() {
    let shots = [
        pattern(|_, _| 90),
        pattern(|_, _| 90),
        lit(2, (0.0, 0.0), 0),
        lit(2, (1.5, -1.0), 1),
    ];
    let outcomes = run("flat start", &shots);
    assert_nothing_confidently_wrong("flat start", &outcomes);
    assert_blank("flat start", 1, &outcomes[0]);
    assert!(outcomes[1].report.added >= 60);
    assert!(outcomes[2].ego.is_ok() && outcomes[2].ego.quality >= 128);
}

#[test]
fn a_saturated_frame_leaves_few_tracks_and_no_confident_motion() {
    // Gain 3 and bias +60: most of the second frame's pixels clip at 255 (measured: 91 %).
    let blown = Lighting {
        gain: 3.0,
        bias: 60.0,
    };
    let shots = [
        lit(3, (0.0, 0.0), 0),
        scene(3, (2.0, 1.0), blown, 1),
        scene(3, (4.0, 2.0), blown, 2),
        lit(3, (6.0, 3.0), 3),
    ];
    let clipped = shots[1].frame.data.iter().filter(|&&v| v == 255).count();
    let share = clipped as f32 / (W * H) as f32;
    eprintln!("saturated: {:.0}% of the pixels at 255", 100.0 * share);
    assert!(share >= 0.8);
    let outcomes = run("saturated", &shots);
    assert_nothing_confidently_wrong("saturated", &outcomes);
}

#[test]
fn pure_noise_gives_no_confident_motion() {
    let shots = [
        lit(4, (0.0, 0.0), 0),
        noise(40),
        noise(41),
        noise(42),
        lit(4, (1.0, 1.0), 1),
    ];
    let outcomes = run("noise", &shots);
    assert_nothing_confidently_wrong("noise", &outcomes);
    for (k, o) in outcomes.iter().enumerate().take(4) {
        assert!(!o.ego.is_ok(), "noise frame {}: ego {:?}", k + 1, o.ego);
        assert_eq!(o.dense.summary.boxes, 0, "noise frame {}: boxes", k + 1);
    }
}

#[test]
fn a_single_bright_pixel_is_not_a_scene() {
    // The dot is a scene of its own (id 99): a track on it is right if it follows it.
    let dot = |at: (usize, usize)| Shot {
        truth: Some((99, (at.0 as f32 - 80.0, at.1 as f32 - 60.0))),
        ..pattern(move |x, y| if (x, y) == at { 255 } else { 0 })
    };
    let shots = [dot((80, 60)), dot((80, 60)), dot((83, 61)), dot((83, 61))];
    let outcomes = run("one pixel", &shots);
    assert_nothing_confidently_wrong("one pixel", &outcomes);
    for (k, o) in outcomes.iter().enumerate() {
        // A handful of tracks at most, all on the dot; never enough for ego-motion.
        assert!(
            o.tracks.len() <= 4,
            "one pixel frame {}: {} tracks",
            k + 1,
            o.tracks.len()
        );
        assert_eq!(o.ego.quality, 0);
    }
}

#[test]
fn stripes_give_no_motion_along_them() {
    // Vertical sinusoidal stripes, 8 px period, with sensor noise of 1 grey level, moving
    // diagonally: the motion across the stripes is observable, the motion along them is not.
    let stripes = |shift: (f32, f32), seed: u64| {
        let mut rng = SplitMix64::new(seed);
        pattern(move |x, _| {
            let v = 128.0 + 80.0 * ((x as f32 - shift.0) * core::f32::consts::TAU / 8.0).sin();
            let n = rng.gaussian() as f32;
            (v + n).round().clamp(0.0, 255.0) as u8
        })
    };
    let shots = [
        stripes((0.0, 0.0), 1),
        stripes((1.0, 3.0), 2),
        stripes((2.0, 6.0), 3),
        stripes((3.0, 9.0), 4),
    ];
    let outcomes = run("stripes", &shots);
    for (k, o) in outcomes.iter().enumerate() {
        let k = k + 1;
        assert_eq!(o.tracks.len(), 0, "stripes frame {k}: tracks");
        assert!(!o.ego.is_ok(), "stripes frame {k}: ego {:?}", o.ego);
        // No node may claim to know the motion along the stripes.
        assert_eq!(o.valid_nodes(), 0, "stripes frame {k}: measured nodes");
    }
}

#[test]
fn a_repeated_frame_is_zero_motion() {
    let shots = [
        lit(5, (0.0, 0.0), 0),
        lit(5, (2.0, 1.0), 1),
        lit(5, (2.0, 1.0), 1),
        lit(5, (4.0, 2.0), 2),
    ];
    assert_eq!(shots[1].frame, shots[2].frame);
    let outcomes = run("repeated", &shots);
    assert_nothing_confidently_wrong("repeated", &outcomes);
    let repeated = &outcomes[1];
    assert_eq!(repeated.report.dropped(), 0);
    // Every track stays put, within LK's convergence threshold (0.01 px). The refill may add
    // tracks after them, by the edge the moving frame before passed over (Refill::leaving_within).
    let kept = outcomes[0].tracks.len();
    assert_eq!(repeated.tracks.len(), kept + repeated.report.added);
    for (a, b) in outcomes[0].tracks.iter().zip(&repeated.tracks) {
        let ((ax, ay), (bx, by)) = (a.position.to_f32(), b.position.to_f32());
        assert_eq!(a.id, b.id);
        assert!((ax - bx).hypot(ay - by) <= 0.01, "{a:?} moved to {b:?}");
    }
    assert!(repeated.ego.is_ok() && repeated.ego.quality >= 250);
    assert!(repeated.ego_error.unwrap() <= 1e-3);
    assert!(repeated.nodes.iter().all(|n| n.flow == Default::default()));
    assert_eq!(repeated.dense.summary.boxes, 0);
    // The next real step is tracked as before.
    assert!(outcomes[2].ego.is_ok() && outcomes[2].ego_error.unwrap() <= 0.1);
}

#[test]
fn a_frame_from_another_scene_ends_the_tracks() {
    let shots = [
        lit(6, (0.0, 0.0), 0),
        lit(6, (1.0, 0.0), 1),
        lit(7, (0.0, 0.0), 0),
        lit(6, (2.0, 0.0), 2),
        lit(6, (3.0, 0.0), 3),
    ];
    let outcomes = run("swapped", &shots);
    assert_nothing_confidently_wrong("swapped", &outcomes);
    for k in [2, 3] {
        let o = &outcomes[k - 1];
        let survivors = o.tracks.iter().filter(|t| t.age > 0).count();
        assert!(
            survivors <= 5,
            "swapped frame {k}: {survivors} tracks survive"
        );
        assert!(!o.ego.is_ok(), "swapped frame {k}: ego {:?}", o.ego);
        assert_eq!(o.dense.summary.boxes, 0, "swapped frame {k}: boxes");
    }
    assert!(outcomes[3].ego.is_ok() && outcomes[3].ego_error.unwrap() <= 0.1);
}

#[test]
fn an_exposure_jump_moves_no_track() {
    // The tracks kept through the jump, at least. Measured: darker, 81 of 81; brighter, 67 of
    // 81 (the residual gate drops 14 whose windows clip).
    for (label, lighting, min_kept) in [
        (
            "darker",
            Lighting {
                gain: 0.5,
                bias: -10.0,
            },
            0.97,
        ),
        (
            "brighter",
            Lighting {
                gain: 1.25,
                bias: 15.0,
            },
            0.8,
        ),
    ] {
        let shots = [
            lit(8, (0.0, 0.0), 0),
            lit(8, (1.5, -1.0), 1),
            scene(8, (3.0, -2.0), lighting, 2),
            scene(8, (4.5, -3.0), lighting, 3),
        ];
        let outcomes = run(label, &shots);
        // The brighter frame clips its brightest patches at 255, where no gain and bias relate
        // the frames, and a few dense nodes there converge on wrong matches (measured: 7
        // moving nodes, 6 of them more than 1 px off, out of 232 measured) that gather into
        // one region. It moves in that one pair only, so it is no box: boxes must persist over
        // two pairs.
        assert_nothing_confidently_wrong(label, &outcomes);
        check_jump(label, &outcomes, min_kept);
    }
}

/// At least `min_kept` of the tracks survive the jump, and the motion is found through it.
fn check_jump(label: &str, outcomes: &[Outcome], min_kept: f32) {
    let jump = &outcomes[1];
    let kept = jump.report.tracked as f32 / outcomes[0].report.live as f32;
    eprintln!(
        "{label}: {:.0}% of the tracks kept through the jump",
        100.0 * kept
    );
    assert!(kept >= min_kept, "{label}: tracks kept");
    assert!(jump.ego.is_ok() && jump.ego_error.unwrap() <= 0.1);
}
