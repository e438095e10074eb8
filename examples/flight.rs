//! The per-frame loop a flight controller runs, on the host: frames in, tracks, the camera's
//! motion and the autopilot's OPTICAL_FLOW_RAD out.
//!
//! ```sh
//! cargo run --release --example flight            # 160x120, 60 frames of a yawing flight
//! cargo run --release --example flight -- 200     # more frames
//! ```
//!
//! Every buffer is a fixed-size array sized by the library's `const fn`s, exactly as firmware
//! would declare its `static`s; nothing here needs a heap except rendering the synthetic frames
//! (host-sim's seeded scenes, which also give the true motion to compare against).

use host_sim::synth::{FlightPath, FlightSequence, Homography as Warp, SceneSpec};
use kestrel::detect::Corner;
use kestrel::ego::{
    Camera, CameraParams, EgoMotion, FlowRadAccumulator, ModelKind, Ransac, RansacParams,
};
use kestrel::lk::scratch_len;
use kestrel::track::{detect_scratch_len, tracker_storage_len, Tracker, TrackerBuffers};
use kestrel::{ImageView, Point};

const WIDTH: usize = 160;
const HEIGHT: usize = 120;
const TRACKS: usize = 100;
/// The coarsest pyramid level and the LK window: `TrackerConfig`'s defaults (OpenCV's).
const MAX_LEVEL: usize = 3;
const WINDOW: usize = 21;
/// Candidate corners offered to the spreading grid: three per track.
const CANDIDATES: usize = 3 * TRACKS;
/// The camera runs at 100 frames/s; the autopilot reads the flow every 5 frames (20 Hz).
const FRAME_INTERVAL_US: u32 = 10_000;
const FRAMES_PER_READOUT: usize = 5;

fn main() -> Result<(), String> {
    let frames: usize = match std::env::args().nth(1) {
        Some(n) => n
            .parse()
            .map_err(|_| format!("frame count {n:?} is not a number"))?,
        None => 60,
    };
    let config = host_sim::tracking::config_for(WIDTH, HEIGHT, TRACKS);

    if (config.pyramid_levels(), config.lk.window) != (MAX_LEVEL, WINDOW) {
        return Err("the buffers below are sized for another configuration".into());
    }

    // What firmware places in RAM, sized at compile time.
    let mut storage = [0u8; tracker_storage_len(WIDTH, HEIGHT, MAX_LEVEL)];
    let mut lk_scratch = [0i16; scratch_len(WINDOW)];
    let mut detect_scratch = [0i32; detect_scratch_len(WIDTH, 1, CANDIDATES)];
    let mut candidates = [Corner::default(); CANDIDATES];
    print_memory(&storage, &lk_scratch, &detect_scratch, &candidates);
    let buffers = TrackerBuffers {
        storage: &mut storage,
        lk_scratch: &mut lk_scratch,
        detect_scratch: &mut detect_scratch,
        candidates: &mut candidates,
    };
    let mut tracker = Tracker::<TRACKS>::new(config, WIDTH, HEIGHT, buffers)
        .map_err(|e| format!("tracker: {e}"))?;
    let ransac = Ransac::new(RansacParams {
        // A camera looking down at flat ground, turning about its axis: the image moves by a
        // similarity. Four degrees of freedom extrapolate to the frame's corners far better than a
        // homography's eight fitted to tracks that bunch up after a turn.
        model: ModelKind::Similarity,
        ..RansacParams::default()
    })
    .map_err(|e| format!("ransac: {e}"))?;
    let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0))
        .map_err(|e| format!("camera: {e}"))?;
    let mut flow = FlowRadAccumulator::new(camera, 0);

    let sequence = FlightSequence::new(SceneSpec::new(WIDTH, HEIGHT, 7), FlightPath::Yaw, 1);
    let mut prev = sequence.frame(0);
    tracker
        .start(view(&prev.data)?)
        .map_err(|e| format!("frame 0: {e}"))?;
    let mut errors = Vec::with_capacity(frames);

    println!("frame  live  added  inliers  quality  motion error (px, frame corners)");
    for k in 1..frames {
        let next = sequence.frame(k);
        let report = tracker
            .process(view(&prev.data)?, view(&next.data)?, None)
            .map_err(|e| format!("frame {k}: {e}"))?;
        let motion = camera_motion(&ransac, &tracker);
        flow.add(&motion, FRAME_INTERVAL_US, None);

        let error = motion_error(&motion, &sequence.flight().pair_homography(k));
        if let Some(e) = error {
            errors.push(e);
        }
        println!(
            "{k:5}  {:4}  {:5}  {:7}  {:7}  {}",
            report.live,
            report.added,
            motion.inliers,
            motion.quality,
            error.map_or("-".into(), |e| format!("{e:.3}")),
        );
        if k % FRAMES_PER_READOUT == 0 {
            let out = flow.readout(k as u64 * u64::from(FRAME_INTERVAL_US));
            println!(
                "       OPTICAL_FLOW_RAD integrated_x {:+.5} rad, integrated_y {:+.5} rad over {} us, quality {}",
                out.integrated_x, out.integrated_y, out.integration_time_us, out.quality
            );
        }
        prev = next;
    }
    errors.sort_by(f64::total_cmp);
    if let Some(median) = errors.get(errors.len() / 2) {
        println!(
            "median motion error {median:.3} px over {} frame pairs",
            errors.len()
        );
    }
    Ok(())
}

/// The camera's motion from the tracks that lived through the frame: each one's
/// correspondence between the two frames ([`Tracker::correspondences`]).
fn camera_motion(ransac: &Ransac, tracker: &Tracker<'_, TRACKS>) -> EgoMotion {
    let mut pairs: heapless::Vec<(Point, Point), TRACKS> = heapless::Vec::new();
    tracker.correspondences(&mut pairs);
    let mut inliers = [false; TRACKS];
    match ransac.estimate(&pairs, &mut inliers[..pairs.len()]) {
        Ok(motion) => motion,
        Err(_) => EgoMotion::failed(ModelKind::Similarity, kestrel::ego::EgoStatus::BadInput),
    }
}

/// The largest distance between where the estimated and the true motion send the frame's
/// corners; `None` when no motion was estimated.
fn motion_error(motion: &EgoMotion, truth: &Warp) -> Option<f64> {
    if !motion.is_ok() {
        return None;
    }
    let m = motion.model.matrix().map(f64::from);
    let estimate = Warp {
        m: [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]],
    };
    Some(estimate.distance(truth, WIDTH as f64, HEIGHT as f64))
}

fn view(pixels: &[u8]) -> Result<ImageView<'_>, String> {
    ImageView::packed(pixels, WIDTH, HEIGHT).map_err(|e| format!("frame: {e}"))
}

fn print_memory(storage: &[u8], lk: &[i16], detect: &[i32], candidates: &[Corner]) {
    let bytes = core::mem::size_of_val(storage)
        + core::mem::size_of_val(lk)
        + core::mem::size_of_val(detect)
        + core::mem::size_of_val(candidates);
    println!(
        "caller-owned buffers: {bytes} bytes (pyramids {} B, LK scratch {} B, detection {} B, candidates {} B); the tracker itself {} B",
        core::mem::size_of_val(storage),
        core::mem::size_of_val(lk),
        core::mem::size_of_val(detect),
        core::mem::size_of_val(candidates),
        core::mem::size_of::<Tracker<'_, TRACKS>>(),
    );
}
