//! Soak: the library's KLT tracker over a long synthetic flight, checking that nothing drifts
//! with time: memory, track ids, track counts and accuracy.
//!
//! The camera circles above a seeded scene (160 x 120 px) on a closed path: a 20 px swing in
//! x and y, ±3° of roll and ±3 % of zoom, one lap every 240 frames, so points leave and enter
//! the view and tracks die and are born all along. The laps are rendered once; each frame gets
//! fresh sensor noise (uniform, -1..1 grey levels), so no two frames are alike. The truth of
//! every track is the camera's motion from the frame it was born in.
//!
//! Checked over the whole run:
//! - the per-frame loop allocates nothing (a counting allocator in this test binary), and the
//!   resident set does not grow;
//! - ids are never reused: every new track's id is above all ids before it, a live track keeps
//!   its id and its birth frame, and the tracks come oldest first;
//! - the tracker never holds more than its capacity, and always holds a useful number;
//! - in every window of [`WINDOW`] frames, at least [`MIN_WITHIN_1PX`] of the tracks followed
//!   and [`MIN_YOUNG_WITHIN_1PX`] of the young ones are within 1 px of the truth, none is
//!   farther than [`MAX_ERROR`], and every position is finite and inside the frame.
//!
//! `KESTREL_SOAK_FRAMES` sets the length (default [`CI_FRAMES`], about 10-20 s in release).
//! A longer run, 20 000 frames:
//!
//! ```sh
//! KESTREL_SOAK_FRAMES=20000 cargo test --release -p host-sim --test soak -- --nocapture
//! ```
//!
//! On a shared 2-core machine (2026-11-22), it printed:
//!
//! ```text
//! soak: 20000 frames of 160x120 in 90.1 s (4.50 ms per frame, checks included)
//!   allocations in the per-frame loop: 0; resident set 8.34 MiB at frame 50, 8.34 MiB at the end
//!   live tracks min 61 / median 81 / max 92; 9736 tracks born, last id 9735
//!   within 1 px of the truth: 99.36 % of 1629168 track-frames (worst window 99.24 %); by age:
//!   under 64 frames 99.19 % (worst window 98.89 %), under 512 frames 98.58 %, older 99.78 %;
//!   worst error 5.44 px
//! ```
//!
//! and the default run (3000 frames) 99.37 % within 1 px (worst window 99.31 %), young tracks
//! 99.25 %, tracks of 64-511 frames 98.82 %, older 99.85 %, worst error 5.44 px. A 100 000-frame
//! run: 99.36 % (worst window 99.17 %), young tracks 99.18 % (worst window 98.81 %), 64-511
//! frames 98.45 %, older 99.78 %, worst error 5.58 px, live tracks min 61 / median 82.
//!
//! LK follows a window from frame to frame, and its sub-pixel errors add up over hundreds of
//! frames of rotation and zoom. Without relocation on the birth patch
//! (`Relocation::every` 0) old tracks drift: a 100 000-frame run had 73.80 % of
//! all track-frames within 1 px, 98.27 % of those under 64 frames, 82.54 % under 512 frames
//! and 25.45 % of older ones, worst error 7.06 px. The largest errors left are tracks at the
//! frame's edge, where the birth patch reaches outside the frame and is not relocated.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Instant;

use host_sim::synth::{Homography, Scene, SceneSpec, SplitMix64};
use host_sim::tracking::{config_for, HostBuffers};
use host_sim::Frame;
use kestrel::track::{Track, Tracker};
use kestrel::ImageView;

/// Frames of the run unless `KESTREL_SOAK_FRAMES` says otherwise.
const CI_FRAMES: usize = 3_000;
/// Frames per accuracy window.
const WINDOW: usize = 1_000;
/// Frames of one lap of the camera path.
const LAP: usize = 240;
const WIDTH: usize = 160;
const HEIGHT: usize = 120;
/// The tracker's capacity and target.
const MAX_TRACKS: usize = 100;
/// Frames before the memory baseline is taken: the tracker has filled up by then.
const WARM_UP: usize = 50;

/// Track ages (frames) that split the accuracy figures into bands: young, mature, old.
const AGE_BANDS: [u32; 2] = [64, 512];
/// The least share of followed tracks within 1 px of the truth, in every window: all tracks,
/// and young ones. Relocation on the birth patch keeps old tracks as accurate as young ones
/// (see the figures above), so the first bound holds for tracks of every age.
const MIN_WITHIN_1PX: f64 = 0.98;
const MIN_YOUNG_WITHIN_1PX: f64 = 0.98;
/// The largest distance from the truth allowed of any live track: a track this far off is
/// confident wrong output, which the gates must drop first.
const MAX_ERROR: f64 = 6.5;
/// The fewest live tracks after the first frame.
const MIN_LIVE: usize = 40;
/// The most the resident set may grow over the run: page-level noise, not a leak.
const MAX_RSS_GROWTH: usize = 64 * 1024;

// ---------------------------------------------------------------------------------------------
// Allocations, counted per thread so that the test harness's own threads do not count.

struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: every call is passed to the system allocator unchanged; counting touches only a
// const-initialised thread local, which neither allocates nor panics.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as for `alloc`.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: as for `alloc`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

/// The resident set of this process in bytes, from `/proc/self/statm` (pages of 4 KiB).
fn resident_bytes() -> usize {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("/proc/self/statm");
    let pages: usize = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}

// ---------------------------------------------------------------------------------------------
// The flight.

/// The camera's warp from the scene to the frames at `phase` frames into a lap.
fn camera(phase: usize) -> Homography {
    let angle = std::f64::consts::TAU * phase as f64 / LAP as f64;
    let centre = ((WIDTH - 1) as f64 / 2.0, (HEIGHT - 1) as f64 / 2.0);
    Homography::similarity(
        1.0 + 0.03 * angle.sin(),
        3f64.to_radians() * (2.0 * angle).sin(),
        (20.0 * angle.cos() - 20.0, 20.0 * angle.sin()),
        centre,
    )
}

/// One lap: the noise-free frames and, for each, the camera and its inverse.
struct Lap {
    frames: Vec<Frame>,
    cameras: Vec<(Homography, Homography)>,
}

impl Lap {
    fn render() -> Self {
        let scene = Scene::new(SceneSpec::new(WIDTH, HEIGHT, 2026));
        let cameras: Vec<_> = (0..LAP)
            .map(|phase| {
                let warp = camera(phase);
                (warp, warp.inverse().unwrap())
            })
            .collect();
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let frames = render_all(&scene, &cameras, threads);
        Self { frames, cameras }
    }

    /// Where the point seen at `pixel` in frame `from` is seen in frame `to`.
    fn truth(&self, from: usize, pixel: (f64, f64), to: usize) -> (f64, f64) {
        let (u, v) = self.cameras[from % LAP].1.apply(pixel.0, pixel.1);
        self.cameras[to % LAP].0.apply(u, v)
    }

    /// Frame `k` into `out`: the lap's frame with the noise of frame `k`.
    fn frame_into(&self, k: usize, out: &mut [u8]) {
        let clean = &self.frames[k % LAP].data;
        let mut rng = SplitMix64::substream(7, k as u64);
        for (pixels, clean) in out.chunks_mut(32).zip(clean.chunks(32)) {
            // Two bits a pixel: 0 and 3 leave it, 1 adds one, 2 takes one away.
            let mut bits = rng.next_u64();
            for (pixel, &value) in pixels.iter_mut().zip(clean) {
                *pixel = match bits & 3 {
                    1 => value.saturating_add(1),
                    2 => value.saturating_sub(1),
                    _ => value,
                };
                bits >>= 2;
            }
        }
    }
}

fn render_all(scene: &Scene, cameras: &[(Homography, Homography)], threads: usize) -> Vec<Frame> {
    let lighting = host_sim::synth::Lighting::UNCHANGED;
    std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|t| {
                scope.spawn(move || {
                    (t..LAP)
                        .step_by(threads)
                        .map(|k| (k, scene.render(&cameras[k].0, lighting, k as u64)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        let mut frames: Vec<(usize, Frame)> = workers
            .into_iter()
            .flat_map(|w| w.join().unwrap())
            .collect();
        frames.sort_by_key(|(k, _)| *k);
        frames.into_iter().map(|(_, frame)| frame).collect()
    })
}

// ---------------------------------------------------------------------------------------------
// What the run checks as it goes. Everything is sized before the loop, so that the loop
// allocates only if the tracker does.

/// Where and when a live track was born.
#[derive(Debug, Clone, Copy)]
struct Birth {
    id: u32,
    frame: usize,
    at: (f64, f64),
}

/// Figures of one window of frames.
#[derive(Debug, Clone, Copy, Default)]
struct WindowFigures {
    first_frame: usize,
    /// Track-frames followed, per age band.
    followed: [u64; 3],
    /// Of those, within 1 px of the truth.
    within_1px: [u64; 3],
    worst_error: f64,
    min_live: usize,
    births: u64,
}

impl WindowFigures {
    /// The share of the track-frames of age `bands` within 1 px of the truth (0 without any).
    fn share(&self, bands: std::ops::Range<usize>) -> f64 {
        let followed: u64 = self.followed[bands.clone()].iter().sum();
        let within: u64 = self.within_1px[bands].iter().sum();
        within as f64 / followed.max(1) as f64
    }
}

#[derive(Debug)]
struct Checks {
    births: Vec<Birth>,
    /// The highest id ever seen.
    last_id: Option<u32>,
    /// How many frames after the first had each number of live tracks. A histogram, not a
    /// list: a list's pages would be touched as it fills, and grow the resident set.
    live: [u64; MAX_TRACKS + 1],
    windows: Vec<WindowFigures>,
}

impl Checks {
    fn new(frames: usize) -> Self {
        Self {
            births: Vec::with_capacity(MAX_TRACKS),
            last_id: None,
            live: [0; MAX_TRACKS + 1],
            windows: Vec::with_capacity(frames / WINDOW + 1),
        }
    }

    /// Checks the tracks after frame `k`.
    fn frame(&mut self, k: usize, tracks: &[Track], lap: &Lap) {
        assert!(
            tracks.len() <= MAX_TRACKS,
            "frame {k}: {} tracks",
            tracks.len()
        );
        assert!(
            k == 0 || tracks.len() >= MIN_LIVE,
            "frame {k}: {} tracks",
            tracks.len()
        );
        assert!(
            tracks.windows(2).all(|p| p[0].id < p[1].id),
            "frame {k}: ids out of order"
        );
        if k % WINDOW == 0 {
            self.windows.push(WindowFigures {
                first_frame: k,
                min_live: usize::MAX,
                ..WindowFigures::default()
            });
        }
        if k > 0 {
            self.live[tracks.len()] += 1;
        }
        // Tracks that died: both lists are in id order.
        self.births
            .retain(|birth| tracks.binary_search_by_key(&birth.id, |t| t.id).is_ok());
        let window = self.windows.last_mut().unwrap();
        window.min_live = window.min_live.min(tracks.len());
        for track in tracks {
            let (x, y) = (
                track.position.x.to_num::<f64>(),
                track.position.y.to_num::<f64>(),
            );
            assert!(
                (0.0..=(WIDTH - 1) as f64).contains(&x) && (0.0..=(HEIGHT - 1) as f64).contains(&y),
                "frame {k}: track {} at ({x}, {y}) is outside the frame",
                track.id
            );
            if track.age == 0 {
                assert_eq!(track.born as usize, k, "frame {k}: new track {}", track.id);
                assert!(
                    self.last_id.is_none_or(|last| track.id > last),
                    "frame {k}: id {} reused",
                    track.id
                );
                self.last_id = Some(track.id);
                self.births.push(Birth {
                    id: track.id,
                    frame: k,
                    at: (x, y),
                });
                window.births += 1;
                continue;
            }
            let birth = self.births[self
                .births
                .binary_search_by_key(&track.id, |b| b.id)
                .unwrap_or_else(|_| panic!("frame {k}: track {} has no birth", track.id))];
            assert_eq!(
                track.born as usize, birth.frame,
                "frame {k}: track {} changed birth",
                track.id
            );
            assert_eq!(
                track.age as usize,
                k - birth.frame,
                "frame {k}: track {} age",
                track.id
            );
            let truth = lap.truth(birth.frame, birth.at, k);
            let error = (x - truth.0).hypot(y - truth.1);
            assert!(error.is_finite(), "frame {k}: track {}", track.id);
            let band = AGE_BANDS.iter().filter(|&&age| track.age >= age).count();
            window.followed[band] += 1;
            window.within_1px[band] += u64::from(error <= 1.0);
            window.worst_error = window.worst_error.max(error);
        }
        // New tracks were pushed after the old ones, with higher ids: still in id order.
    }
}

// ---------------------------------------------------------------------------------------------

fn soak_frames() -> usize {
    match std::env::var("KESTREL_SOAK_FRAMES") {
        Ok(text) => text
            .parse()
            .ok()
            .filter(|&n| n > WARM_UP)
            .unwrap_or_else(|| {
                panic!("KESTREL_SOAK_FRAMES must be a whole number above {WARM_UP}, not {text:?}")
            }),
        Err(_) => CI_FRAMES,
    }
}

#[test]
fn the_tracker_runs_a_long_flight_without_drifting() {
    let frames = soak_frames();
    let lap = Lap::render();
    let config = config_for(WIDTH, HEIGHT, MAX_TRACKS);
    let mut buffers = HostBuffers::new(&config, WIDTH, HEIGHT);
    let mut tracker = Tracker::<MAX_TRACKS>::new(config, WIDTH, HEIGHT, buffers.lend()).unwrap();
    let mut checks = Checks::new(frames);
    let (mut prev, mut next) = (vec![0u8; WIDTH * HEIGHT], vec![0u8; WIDTH * HEIGHT]);

    let clock = Instant::now();
    lap.frame_into(0, &mut prev);
    tracker
        .start(ImageView::packed(&prev, WIDTH, HEIGHT).unwrap())
        .unwrap();
    checks.frame(0, tracker.tracks(), &lap);
    let (mut rss_start, mut allocations_start) = (0, 0);
    for k in 1..frames {
        if k == WARM_UP {
            rss_start = resident_bytes();
            allocations_start = allocations();
        }
        lap.frame_into(k, &mut next);
        let views = (
            ImageView::packed(&prev, WIDTH, HEIGHT).unwrap(),
            ImageView::packed(&next, WIDTH, HEIGHT).unwrap(),
        );
        let report = tracker.process(views.0, views.1, None).unwrap();
        assert_eq!(report.live, tracker.tracks().len());
        assert_eq!(tracker.frame_index(), Some(k as u32));
        checks.frame(k, tracker.tracks(), &lap);
        std::mem::swap(&mut prev, &mut next);
    }
    let allocated = allocations() - allocations_start;
    let rss_end = resident_bytes();
    let seconds = clock.elapsed().as_secs_f64();

    report(frames, seconds, allocated, (rss_start, rss_end), &checks);
    assert_eq!(allocated, 0, "the per-frame loop allocated");
    assert!(
        rss_end <= rss_start + MAX_RSS_GROWTH,
        "resident set grew from {rss_start} to {rss_end} bytes"
    );
    for window in &checks.windows {
        let from = window.first_frame;
        let (all, young) = (window.share(0..3), window.share(0..1));
        assert!(
            all >= MIN_WITHIN_1PX && young >= MIN_YOUNG_WITHIN_1PX,
            "window from frame {from}: {all:.4} of all and {young:.4} of young tracks within 1 px: {window:?}"
        );
        assert!(
            window.worst_error <= MAX_ERROR,
            "window from frame {from}: {window:?}"
        );
    }
    // Tracks must have come and gone all along, or the run proved little about ids.
    assert!(
        checks.windows.iter().all(|w| w.births >= 10),
        "{:?}",
        checks.windows
    );
}

/// Prints the run's figures (shown with `--nocapture`).
fn report(frames: usize, seconds: f64, allocated: u64, rss: (usize, usize), checks: &Checks) {
    let mut total = WindowFigures::default();
    for window in &checks.windows {
        for band in 0..3 {
            total.followed[band] += window.followed[band];
            total.within_1px[band] += window.within_1px[band];
        }
        total.worst_error = total.worst_error.max(window.worst_error);
        total.births += window.births;
    }
    let worst = |bands: std::ops::Range<usize>| {
        let shares = checks.windows.iter().map(|w| w.share(bands.clone()));
        100.0 * shares.fold(f64::INFINITY, f64::min)
    };
    let live = live_figures(&checks.live);
    println!(
        "soak: {frames} frames of {WIDTH}x{HEIGHT} in {seconds:.1} s ({:.2} ms per frame, checks \
         included)\n  allocations in the per-frame loop: {allocated}; resident set {:.2} MiB at \
         frame {WARM_UP}, {:.2} MiB at the end\n  live tracks min {} / median {} / max {}; {} \
         tracks born, last id {}\n  within 1 px of the truth: {:.2} % of {} track-frames (worst \
         window {:.2} %); by age: under {} frames {:.2} % (worst window {:.2} %), under {} \
         frames {:.2} %, older {:.2} %; worst error {:.2} px",
        1000.0 * seconds / frames as f64,
        rss.0 as f64 / 1048576.0,
        rss.1 as f64 / 1048576.0,
        live.0,
        live.1,
        live.2,
        total.births,
        checks.last_id.unwrap_or(0),
        100.0 * total.share(0..3),
        total.followed.iter().sum::<u64>(),
        worst(0..3),
        AGE_BANDS[0],
        100.0 * total.share(0..1),
        worst(0..1),
        AGE_BANDS[1],
        100.0 * total.share(1..2),
        100.0 * total.share(2..3),
        total.worst_error,
    );
}

/// The least, median and most live tracks of a histogram of frames by live tracks.
fn live_figures(histogram: &[u64]) -> (usize, usize, usize) {
    let frames: u64 = histogram.iter().sum();
    let counts = || histogram.iter().enumerate().filter(|(_, &n)| n > 0);
    let least = counts().next().map_or(0, |(live, _)| live);
    let most = counts().next_back().map_or(0, |(live, _)| live);
    let mut seen = 0;
    let median = counts()
        .find(|(_, &n)| {
            seen += n;
            2 * seen > frames
        })
        .map_or(0, |(live, _)| live);
    (least, median, most)
}
