//! Flow-sensor accuracy on seeded flights: how far each estimator's flow is from the true
//! displacement of the image centre, pair by pair.
//!
//! `cargo bench --bench flow_sensor` (a plain program: prints a markdown table). Each flight is
//! a `host_sim::synth::FlightSequence` of 160x120 frames over textured ground, with sensor
//! noise of 1.5 grey levels and no moving objects; frame pairs are `step` frames apart, so one
//! path gives motions from about half a pixel to beyond PX4FLOW's ±4 px search. The truth of a
//! pair is where the pair's homography takes the principal point (the frame centre,
//! (79.5, 59.5)): the flow a flow sensor should report there. A flight's error figures are over
//! the pairs where the estimator gives a flow; "no flow" is its share of pairs without one
//! (quality 0). "Beyond ±4 px" is the share of pairs whose centre moves more than 4 px on an
//! axis, past PX4FLOW's integer search (its half-pixel step still reaches 4.5 px).
//!
//! Estimators take two frames and return a flow in px per pair (x right, y down: how far the
//! image content moved from the first frame to the second), or `None` for no flow. Every
//! estimator in `estimators()` runs on the same rendered frames.

use host_sim::sensor::{
    centre_motion, kestrel_preset, percentile, px4flow_block_matching, Estimator,
};
use host_sim::synth::{FlightPath, FlightSequence, SceneSpec};
use host_sim::Frame;

const WIDTH: usize = 160;
const HEIGHT: usize = 120;
/// Sensor noise, grey levels (standard deviation).
const NOISE: f64 = 1.5;
/// Frame pairs per flight.
const PAIRS: usize = 40;
/// PX4FLOW's search radius, px: pairs moving further on an axis are counted apart.
const SEARCH_RADIUS: f64 = 4.0;

/// A flight to render: the path, its seed and how many frames apart the two of a pair are.
#[derive(Debug, Clone, Copy)]
struct FlightCase {
    path: FlightPath,
    seed: u64,
    step: usize,
}

/// The flights: (path, seed, step). Pans move the centre by 1.1-3.2 px per frame on these
/// seeds, yaws and climbs by their drift (0.6-0.8 px) while the image turns or zooms about it;
/// steps of 2-8 frames scale both, up to 6.3 px per pair, beyond PX4FLOW's search on 4 flights.
fn flights() -> Vec<FlightCase> {
    use FlightPath::{Climb, Pan, Yaw};
    [
        (Pan, 7, 1),
        (Pan, 1, 1),
        (Pan, 3, 1),
        (Pan, 1, 2),
        (Pan, 2, 3),
        (Pan, 1, 3),
        (Pan, 4, 2),
        (Pan, 3, 2),
        (Yaw, 3, 1),
        (Yaw, 9, 1),
        (Yaw, 3, 4),
        (Yaw, 9, 6),
        (Climb, 4, 1),
        (Climb, 3, 1),
        (Climb, 3, 4),
        (Climb, 9, 8),
        (Climb, 3, 8),
    ]
    .into_iter()
    .map(|(path, seed, step)| FlightCase { path, seed, step })
    .collect()
}

/// The estimators compared, by name. Add more here: each runs on every flight's frames.
fn estimators() -> Vec<(&'static str, Estimator)> {
    vec![
        ("PX4FLOW (px4flow, ±4 px)", px4flow_block_matching()),
        ("Kestrel flow-sensor preset", kestrel_preset()),
    ]
}

/// A flight's frames and the true centre displacement of each pair.
struct FlightFrames {
    case: FlightCase,
    frames: Vec<Frame>,
    /// Pair `k` is frames `k` and `k + step`.
    truth: Vec<(f64, f64)>,
}

impl FlightFrames {
    fn render(case: FlightCase) -> Self {
        let spec = SceneSpec::new(WIDTH, HEIGHT, case.seed).with_noise(NOISE);
        let sequence = FlightSequence::new(spec, case.path, 0);
        let frames = (0..PAIRS + case.step).map(|k| sequence.frame(k)).collect();
        let truth = (0..PAIRS)
            .map(|k| centre_motion(sequence.flight(), k, k + case.step))
            .collect();
        Self {
            case,
            frames,
            truth,
        }
    }

    /// The pairs: first frame, second frame, true centre displacement.
    fn pairs(&self) -> impl Iterator<Item = (&Frame, &Frame, (f64, f64))> {
        self.truth
            .iter()
            .enumerate()
            .map(|(k, &truth)| (&self.frames[k], &self.frames[k + self.case.step], truth))
    }
}

/// One estimator's figures on one flight (or on several, merged).
#[derive(Default)]
struct Stats {
    /// Centre-flow errors of the pairs with a flow, px, sorted.
    errors: Vec<f64>,
    /// Pairs in all.
    pairs: usize,
}

impl Stats {
    fn median(&self) -> Option<f64> {
        percentile(&self.errors, 0.5)
    }

    fn p90(&self) -> Option<f64> {
        percentile(&self.errors, 0.9)
    }

    /// Share of pairs without a flow.
    fn no_flow_share(&self) -> f64 {
        1.0 - self.errors.len() as f64 / self.pairs.max(1) as f64
    }

    fn merge(&mut self, other: &Stats) {
        self.errors.extend(&other.errors);
        self.errors.sort_by(f64::total_cmp);
        self.pairs += other.pairs;
    }
}

/// Runs `estimator` on every pair of `flight` and compares its flow with the true
/// displacement of the image centre.
fn centre_flow_errors(flight: &FlightFrames, estimator: &mut Estimator) -> Stats {
    let mut errors: Vec<f64> = flight
        .pairs()
        .filter_map(|(prev, next, (tx, ty))| {
            let (x, y) = estimator(prev, next)?;
            Some((f64::from(x) - tx).hypot(f64::from(y) - ty))
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    Stats {
        errors,
        pairs: flight.truth.len(),
    }
}

fn px(value: Option<f64>) -> String {
    value.map_or_else(|| "-".to_string(), |v| format!("{v:.3}"))
}

fn main() {
    let flights: Vec<FlightFrames> = flights().into_iter().map(FlightFrames::render).collect();
    let mut estimators = estimators();
    println!(
        "Centre-flow error on {WIDTH}x{HEIGHT} flights, noise {NOISE} grey levels, {PAIRS} \
         pairs per flight (error over the pairs with a flow)\n"
    );
    println!(
        "| flight | frame step | centre motion px/pair, median / max | beyond ±{SEARCH_RADIUS} px \
         | estimator | median error px | p90 error px | no flow (quality 0) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut all: Vec<Stats> = estimators.iter().map(|_| Stats::default()).collect();
    for flight in &flights {
        let mut motion: Vec<f64> = flight.truth.iter().map(|&(x, y)| x.hypot(y)).collect();
        motion.sort_by(f64::total_cmp);
        let beyond = flight
            .truth
            .iter()
            .filter(|(x, y)| x.abs() > SEARCH_RADIUS || y.abs() > SEARCH_RADIUS)
            .count();
        for ((name, estimator), pooled) in estimators.iter_mut().zip(&mut all) {
            let stats = centre_flow_errors(flight, estimator);
            pooled.merge(&stats);
            println!(
                "| {} seed {} | {} | {} / {} | {:.0} % | {} | {} | {} | {:.0} % |",
                flight.case.path.name(),
                flight.case.seed,
                flight.case.step,
                px(percentile(&motion, 0.5)),
                px(motion.last().copied()),
                100.0 * beyond as f64 / flight.truth.len() as f64,
                name,
                px(stats.median()),
                px(stats.p90()),
                100.0 * stats.no_flow_share(),
            );
        }
    }
    for ((name, _), pooled) in estimators.iter().zip(&all) {
        println!(
            "| all {} flights | | | | {} | {} | {} | {:.0} % |",
            flights.len(),
            name,
            px(pooled.median()),
            px(pooled.p90()),
            100.0 * pooled.no_flow_share(),
        );
    }
}
