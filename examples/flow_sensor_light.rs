//! Flow-sensor accuracy against the light level: the flow-sensor preset and PX4FLOW's block
//! matching on the same seeded flights, filmed by host-sim's camera model from daylight down to
//! where neither gives a usable flow.
//!
//! ```sh
//! cargo run --release --example flow_sensor_light     # prints a markdown table
//! ```
//!
//! The flights are a subset of `benches/flow_sensor.rs`'s (160x120, pan, yaw and climb on
//! several seeds, pairs one to four frames apart, no moving objects), each frame shot by
//! `host_sim::synth::Camera` with a light level (photon shot noise and 3 electrons of read
//! noise, amplified back to the ideal brightness) and an exposure that blurs each frame over the
//! motion during it. The frames come at 100 per second, so a 10 ms exposure spans the whole
//! frame interval: on these flights the image moves 0.6-3.2 px a frame, and is blurred over as
//! much. Two exposure settings:
//!
//! - short: 2 ms at every light level, so the blur stays a fifth of a frame's motion and the
//!   noise grows as the light falls;
//! - auto: 2 ms at 1000 lux, lengthened as the light falls to collect the same light, up to the
//!   10 ms frame interval (reached at 200 lux); below that the noise grows, with the blur at its
//!   longest. This is what a sensor's exposure control does, not host-sim's `--auto-exposure`
//!   (gain steps), which is off here.
//!
//! Errors are the distance between an estimator's flow and the true displacement of the
//! principal point (as in `benches/flow_sensor.rs`), over the pairs where it gives a flow. "No
//! flow" is the share of pairs with quality 0, "> 1 px off" the share of all pairs given a flow
//! (quality above 0) that is more than 1 px from the truth, "quality" the mean quality of the
//! pairs given a flow (0-255, as OPTICAL_FLOW_RAD's): PX4FLOW's `valid blocks x 255 / 25`, the
//! preset's `EgoMotion::quality`.

use std::time::Instant;

use host_sim::sensor::{
    centre_motion, kestrel_preset_rated, percentile, px4flow_rated, RatedEstimator,
};
use host_sim::synth::{Camera, FlightPath, FlightSequence, Light, SceneSpec, Shutter};
use host_sim::Frame;

const WIDTH: usize = 160;
const HEIGHT: usize = 120;
/// Frame pairs per flight.
const PAIRS: usize = 20;
/// The frame interval, ms (100 frames a second).
const FRAME_INTERVAL_MS: f64 = 10.0;
/// The light levels, lux, brightest first.
const LIGHT: [f64; 11] = [
    1000.0, 300.0, 100.0, 60.0, 30.0, 10.0, 5.0, 2.0, 1.0, 0.5, 0.2,
];
/// A flow further than this from the truth is a wrong flow, px.
const WRONG_PX: f64 = 1.0;
/// The share of pairs that must get a flow within [`WRONG_PX`] for an estimator to count as
/// working at a light level.
const WORKING_SHARE: f64 = 0.9;

/// The flights: (path, seed, frames between the two of a pair), within PX4FLOW's ±4 px search.
const FLIGHTS: [(FlightPath, u64, usize); 8] = [
    (FlightPath::Pan, 7, 1),
    (FlightPath::Pan, 1, 1),
    (FlightPath::Pan, 3, 1),
    (FlightPath::Yaw, 3, 1),
    (FlightPath::Yaw, 9, 1),
    (FlightPath::Climb, 4, 1),
    (FlightPath::Climb, 3, 1),
    (FlightPath::Climb, 3, 4),
];

/// How the exposure time follows the light.
#[derive(Debug, Clone, Copy)]
enum Exposure {
    /// The same time at every light level, ms.
    Fixed(f64),
    /// This many ms at 1000 lux, longer in proportion as the light falls, up to the frame
    /// interval.
    Auto(f64),
}

impl Exposure {
    /// The exposure time at `lux`, ms.
    fn at(self, lux: f64) -> f64 {
        match self {
            Exposure::Fixed(ms) => ms,
            Exposure::Auto(ms) => (ms * 1000.0 / lux).min(FRAME_INTERVAL_MS),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Exposure::Fixed(_) => "short",
            Exposure::Auto(_) => "auto",
        }
    }
}

const EXPOSURES: [Exposure; 2] = [Exposure::Fixed(2.0), Exposure::Auto(2.0)];

/// The camera at `lux` with an exposure of `ms`: a global shutter, nothing else.
fn camera(lux: f64, ms: f64) -> Camera {
    Camera {
        shutter: Shutter {
            exposure: ms / FRAME_INTERVAL_MS,
            readout: 0.0,
        },
        light: Some(Light {
            exposure: ms / 1000.0,
            ..Light::new(lux)
        }),
        ..Camera::default()
    }
}

/// The frame pairs of every flight through `camera`, with the true centre displacement of each.
fn render(camera: Camera) -> Vec<(Frame, Frame, (f64, f64))> {
    let mut pairs = Vec::new();
    for (path, seed, step) in FLIGHTS {
        let sequence =
            FlightSequence::new(SceneSpec::new(WIDTH, HEIGHT, seed), path, 0).with_camera(camera);
        let frames: Vec<Frame> = (0..PAIRS + step).map(|k| sequence.frame(k)).collect();
        for k in 0..PAIRS {
            let truth = centre_motion(sequence.flight(), k, k + step);
            pairs.push((frames[k].clone(), frames[k + step].clone(), truth));
        }
    }
    pairs
}

/// One estimator's figures at one light level.
struct Stats {
    /// Errors of the pairs given a flow, px, sorted.
    errors: Vec<f64>,
    /// Sum of the qualities of the pairs given a flow.
    quality_sum: f64,
    pairs: usize,
}

impl Stats {
    fn of(estimator: &mut RatedEstimator, pairs: &[(Frame, Frame, (f64, f64))]) -> Self {
        let mut stats = Stats {
            errors: Vec::new(),
            quality_sum: 0.0,
            pairs: pairs.len(),
        };
        for (prev, next, (tx, ty)) in pairs {
            if let Some(reading) = estimator(prev, next) {
                let (x, y) = reading.flow;
                stats
                    .errors
                    .push((f64::from(x) - tx).hypot(f64::from(y) - ty));
                stats.quality_sum += f64::from(reading.quality);
            }
        }
        stats.errors.sort_by(f64::total_cmp);
        stats
    }

    fn share(&self, count: usize) -> f64 {
        count as f64 / self.pairs.max(1) as f64
    }

    fn no_flow(&self) -> f64 {
        1.0 - self.share(self.errors.len())
    }

    fn wrong(&self) -> f64 {
        self.share(self.errors.iter().filter(|&&e| e > WRONG_PX).count())
    }

    fn right(&self) -> f64 {
        self.share(self.errors.iter().filter(|&&e| e <= WRONG_PX).count())
    }

    fn mean_quality(&self) -> Option<f64> {
        (!self.errors.is_empty()).then(|| self.quality_sum / self.errors.len() as f64)
    }

    /// Median, p90, no flow, wrong, quality: five table cells.
    fn cells(&self) -> String {
        format!(
            "{} | {} | {:.0} % | {:.0} % | {}",
            px(percentile(&self.errors, 0.5)),
            px(percentile(&self.errors, 0.9)),
            100.0 * self.no_flow(),
            100.0 * self.wrong(),
            self.mean_quality()
                .map_or_else(|| "-".to_string(), |q| format!("{q:.0}")),
        )
    }
}

fn px(value: Option<f64>) -> String {
    value.map_or_else(|| "-".to_string(), |v| format!("{v:.3}"))
}

fn main() {
    let started = Instant::now();
    let mut estimators: [(&str, RatedEstimator); 2] = [
        ("PX4FLOW", px4flow_rated()),
        ("Kestrel preset", kestrel_preset_rated()),
    ];
    println!(
        "Centre-flow error on {} seeded {WIDTH}x{HEIGHT} flights, {PAIRS} pairs each, 100 \
         frames/s; error over the pairs given a flow, > {WRONG_PX} px off and no flow over all \
         pairs, quality the mean over the pairs given a flow\n",
        FLIGHTS.len()
    );
    println!(
        "| exposure | light, lux | ms | noise at mid grey | PX4FLOW median px | p90 px | no flow \
         | > 1 px off | quality | preset median px | p90 px | no flow | > 1 px off | quality |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut summary = Vec::new();
    for exposure in EXPOSURES {
        // The darkest light at which each estimator still works, and its figures there.
        let mut working: [Option<(f64, f64)>; 2] = [None; 2];
        for lux in LIGHT {
            let ms = exposure.at(lux);
            let camera = camera(lux, ms);
            let pairs = render(camera);
            let stats: Vec<Stats> = estimators
                .iter_mut()
                .map(|(_, estimator)| Stats::of(estimator, &pairs))
                .collect();
            println!(
                "| {} | {lux} | {ms:.1} | {:.1} | {} | {} |",
                exposure.name(),
                camera.light.map_or(0.0, |light| light.noise_at(127.5)),
                stats[0].cells(),
                stats[1].cells(),
            );
            for (slot, stats) in working.iter_mut().zip(&stats) {
                if stats.right() >= WORKING_SHARE {
                    *slot = Some((lux, stats.mean_quality().unwrap_or(0.0)));
                }
            }
        }
        for ((name, _), found) in estimators.iter().zip(working) {
            summary.push(match found {
                Some((lux, quality)) => format!(
                    "{}: {name} gives a flow within {WRONG_PX} px on {:.0} % of pairs down to \
                     {lux} lux (mean quality there {quality:.0})",
                    exposure.name(),
                    100.0 * WORKING_SHARE
                ),
                None => format!("{}: {name} never works", exposure.name()),
            });
        }
    }
    println!();
    for line in summary {
        println!("{line}");
    }
    println!(
        "\n{} pairs per light level, {:.1} s in all",
        FLIGHTS.len() * PAIRS,
        started.elapsed().as_secs_f64()
    );
}
