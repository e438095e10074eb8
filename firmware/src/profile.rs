//! Where tracking's instructions go: `LucasKanade::track_points` in variants of the budget
//! configuration, on the last frame pair's pyramids (lent by the tracker), for a 10x10 grid of
//! points. Reported, never checked.

use cortex_m_semihosting::hprintln;
use kestrel::lk::{Illumination, LkParams, LucasKanade, PointTrack};
use kestrel::ImageView;
use kestrel::Point;

use crate::camera;
use crate::meter::{instructions, Meter};
use crate::pipeline::{tracker_config, Pipeline};
use crate::report::{millipx_to_q16, Px};
use crate::scene::{FRAMES, HEIGHT, MOTION_MILLIPX, WIDTH};

/// Points across and down the grid.
const GRID_SIDE: usize = 10;
/// Points tracked per variant.
pub const POINTS: usize = GRID_SIDE * GRID_SIDE;

/// Runs every variant on the last frame pair and prints its cost and accuracy.
// Never inlined: bench/target_profile.py stops counting where this function is first entered.
#[inline(never)]
pub fn run(meter: &Meter, pipeline: &mut Pipeline) {
    let views = (
        ImageView::packed(camera::frame(FRAMES - 2), WIDTH, HEIGHT),
        ImageView::packed(camera::frame(FRAMES - 1), WIDTH, HEIGHT),
    );
    let (Ok(prev), Ok(next)) = views else {
        hprintln!("error profile: the last frames are missing");
        return;
    };
    let (prev, next, scratch) = match pipeline.latest_pair(prev, next) {
        Ok(pair) => pair,
        Err(e) => {
            hprintln!("error profile: no pyramids of the last pair: {:?}", e);
            return;
        }
    };
    let points = grid();
    // Where a track's constant-velocity prediction puts each point: the scene's motion.
    let motion = Point::from_bits(
        millipx_to_q16(MOTION_MILLIPX.0),
        millipx_to_q16(MOTION_MILLIPX.1),
    );
    let predicted = points.map(|p| Point::new(p.x + motion.x, p.y + motion.y));
    let mut tracks = [PointTrack::default(); POINTS];
    for (name, params, predict) in variants() {
        let guesses = predict.then_some(&predicted[..]);
        let Ok(lk) = LucasKanade::new(params) else {
            hprintln!("error profile: variant {} refused", name);
            continue;
        };
        let (result, ticks) =
            meter.measure(|| lk.track_points(&prev, &next, &points, guesses, &mut tracks, scratch));
        if let Err(e) = result {
            hprintln!("error profile: variant {}: {:?}", name, e);
            continue;
        }
        let (tracked, error) = accuracy(&points, &tracks);
        let track = instructions(ticks);
        hprintln!(
            "variant name={} window={} max_level={} max_iterations={} illumination={:?} \
             track={} track_per_point={} tracked={} median_error={}",
            name,
            params.window,
            params.max_level,
            params.max_iterations,
            params.illumination,
            track,
            track / POINTS as u64,
            tracked,
            error.map_or(Px(i32::MAX), Px),
        );
    }
}

/// The budget's LK settings and variants of them, and whether each starts from the
/// prediction.
fn variants() -> [(&'static str, LkParams, bool); 9] {
    let budget = tracker_config().lk;
    // With epsilon 0 every point runs exactly its iteration limit at the single level.
    let one_level = LkParams {
        max_level: 0,
        epsilon: 0.0,
        ..budget
    };
    let iterations = |n| LkParams {
        max_iterations: n,
        ..one_level
    };
    [
        ("one_iteration", iterations(1), false),
        ("two_iterations", iterations(2), false),
        ("three_iterations", iterations(3), false),
        ("budget", budget, false),
        (
            "level_0_predicted",
            LkParams {
                max_level: 0,
                ..budget
            },
            true,
        ),
        (
            "plain_illumination",
            LkParams {
                illumination: Illumination::Plain,
                ..budget
            },
            false,
        ),
        (
            "window_7",
            LkParams {
                window: 7,
                ..budget
            },
            false,
        ),
        (
            "max_level_1",
            LkParams {
                max_level: 1,
                ..budget
            },
            false,
        ),
        (
            "epsilon_0.03",
            LkParams {
                epsilon: 0.03,
                ..budget
            },
            false,
        ),
    ]
}

/// Tracked points, and the largest axis error of their median displacement against the
/// camera's motion (the object covers a few of the points; the median ignores them).
fn accuracy(points: &[Point; POINTS], tracks: &[PointTrack; POINTS]) -> (usize, Option<i32>) {
    let mut dx = [0i32; POINTS];
    let mut dy = [0i32; POINTS];
    let mut n = 0;
    for (point, track) in points.iter().zip(tracks).filter(|(_, t)| t.is_tracked()) {
        dx[n] = (track.position.x - point.x).to_bits();
        dy[n] = (track.position.y - point.y).to_bits();
        n += 1;
    }
    let median = |values: &mut [i32]| {
        values.sort_unstable();
        values.get(values.len() / 2).copied()
    };
    let error = median(&mut dx[..n])
        .zip(median(&mut dy[..n]))
        .map(|(x, y)| {
            let ex = x - millipx_to_q16(MOTION_MILLIPX.0);
            let ey = y - millipx_to_q16(MOTION_MILLIPX.1);
            ex.saturating_abs().max(ey.saturating_abs())
        });
    (n, error)
}

/// A `GRID_SIDE` x `GRID_SIDE` grid of cell centres over the whole frame: 8 px from the side
/// edges, 6 px from the top, so at the coarser levels the outer windows cross the border.
fn grid() -> [Point; POINTS] {
    let cell = |i: usize, size: usize| ((2 * i + 1) * size / (2 * GRID_SIDE)) as i32;
    core::array::from_fn(|k| {
        let (column, row) = (k % GRID_SIDE, k / GRID_SIDE);
        Point::from_bits(cell(column, WIDTH) << 16, cell(row, HEIGHT) << 16)
    })
}
