//! `host-sim synth`: seeded frame pairs with exact ground truth, for benchmarks and scripts.
//!
//! Each pair is a procedural scene and the same scene under a known warp (a translation in a
//! random direction up to `max_shift`, a rotation within ±1° and a zoom within ±2% about the
//! centre), optionally with a brightness gain and bias and sensor noise. The points are the
//! textured nodes of a grid whose true positions stay inside the second frame.

use std::path::PathBuf;

use super::CommandError;
use crate::cli::values::{self, path};
use crate::io::atomic::write_atomically;
use crate::io::create_output_dir;
use crate::io::csv::CsvWriter;
use crate::io::images::write_png;
use crate::synth::{
    grid_points, pair_with_lighting, textured_points, true_position, Homography, Lighting,
    SceneSpec, SplitMix64,
};

/// `host-sim synth`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "write seeded synthetic frame pairs with exact ground truth",
    before_help = "host-sim synth: write seeded synthetic frame pairs with exact ground truth.

Each pair is a procedural scene and the same scene under a known warp: a translation in a
random direction up to --max-shift px, a rotation within 1 degree and a zoom within 2% about
the centre.",
    after_help = "Files in DIR, for each pair NNN:
  pairNNN_a.png, pairNNN_b.png   the two frames (8-bit grey)
  pairNNN_points.csv             x,y: points to track, for 'host-sim flow --points'
  pairNNN_truth.csv              x,y,tx,ty: each point and its true position in frame b
  manifest.csv                   pair,a,b,points,truth,dx,dy,angle_deg,scale,gain,bias

Exit status: 0 success; 1 an output that cannot be written; 2 bad command line."
)]
pub struct SynthOptions {
    /// output directory, created if missing
    #[arg(long, value_name = "DIR", value_parser = path)]
    pub out: PathBuf,
    /// number of pairs, 1 to 1000
    #[arg(long, value_name = "N", default_value_t = 10, value_parser = pairs)]
    pub pairs: usize,
    /// frame width, 16 to 4096 px
    #[arg(long, value_name = "W", default_value_t = 320, value_parser = size)]
    pub width: usize,
    /// frame height, 16 to 4096 px
    #[arg(long, value_name = "H", default_value_t = 240, value_parser = size)]
    pub height: usize,
    /// seed of the whole set, a whole number >= 0
    #[arg(long, value_name = "S", default_value_t = 1, value_parser = seed)]
    pub seed: u64,
    /// largest translation, 0 to 100 px
    #[arg(long, value_name = "PX", default_value_t = 20.0, value_parser = shift)]
    pub max_shift: f64,
    /// brightness gain of the second frame, 0.1 to 10
    #[arg(long, value_name = "G", default_value_t = 1.0, value_parser = gain)]
    pub gain: f64,
    /// brightness bias of the second frame, -255 to 255 grey levels
    #[arg(long, value_name = "B", default_value_t = 0.0, value_parser = bias)]
    pub bias: f64,
    /// sensor noise, 0 to 50 grey levels
    #[arg(long, value_name = "SIGMA", default_value_t = 1.5, value_parser = noise)]
    pub noise: f64,
    /// at most N textured points per pair, 1 to 100000
    #[arg(long, value_name = "N", default_value_t = 300, value_parser = points)]
    pub points: usize,
}

impl SynthOptions {
    /// The brightness change of the second frame.
    fn lighting(&self) -> Lighting {
        Lighting {
            gain: self.gain,
            bias: self.bias,
        }
    }
}

fn pairs(text: &str) -> Result<usize, String> {
    let range = |n| (1..=1000).contains(&n);
    values::whole(text, range, "must be between 1 and 1000").map(|n| n as usize)
}

/// A frame side, shared with `synth-sequence`.
pub fn size(text: &str) -> Result<usize, String> {
    let range = |n| (16..=4096).contains(&n);
    values::whole(text, range, "must be between 16 and 4096").map(|n| n as usize)
}

/// A seed, shared with `synth-sequence`.
pub fn seed(text: &str) -> Result<u64, String> {
    values::whole(text, |n| n >= 0, "must be a whole number >= 0").map(|n| n as u64)
}

fn shift(text: &str) -> Result<f64, String> {
    values::number(
        text,
        |v| (0.0..=100.0).contains(&v),
        "must be between 0 and 100",
    )
}

fn gain(text: &str) -> Result<f64, String> {
    values::number(
        text,
        |v| (0.1..=10.0).contains(&v),
        "must be between 0.1 and 10",
    )
}

fn bias(text: &str) -> Result<f64, String> {
    let range = |v| (-255.0..=255.0).contains(&v);
    values::number(text, range, "must be between -255 and 255")
}

/// Sensor noise, shared with `synth-sequence`.
pub fn noise(text: &str) -> Result<f64, String> {
    values::number(
        text,
        |v| (0.0..=50.0).contains(&v),
        "must be between 0 and 50",
    )
}

fn points(text: &str) -> Result<usize, String> {
    let range = |n| (1..=100_000).contains(&n);
    values::whole(text, range, "must be between 1 and 100000").map(|n| n as usize)
}

/// Columns of manifest.csv.
const MANIFEST_COLUMNS: [&str; 11] = [
    "pair",
    "a",
    "b",
    "points",
    "truth",
    "dx",
    "dy",
    "angle_deg",
    "scale",
    "gain",
    "bias",
];

/// Writing CSV into memory fails only on a bug.
fn text_error(error: std::io::Error) -> CommandError {
    CommandError::Processing(format!("cannot format CSV: {error}"))
}

/// Smallest structure-tensor eigenvalue per pixel (grey levels per pixel, squared) for a grid
/// node to count as textured: gradients of about 3 grey levels per pixel in every direction.
const MIN_STRENGTH: f32 = 10.0;
/// Window over which texture is judged, px.
const TEXTURE_WINDOW: usize = 21;

/// One generated pair: the warp and the points with their true positions.
struct GeneratedPair {
    warp: Homography,
    shift: (f64, f64),
    angle_deg: f64,
    scale: f64,
    points: Vec<((f32, f32), (f32, f32))>,
}

/// Runs `synth`.
pub fn run(options: &SynthOptions) -> Result<(), CommandError> {
    create_output_dir(&options.out)?;
    let mut manifest = CsvWriter::new(Vec::new(), &MANIFEST_COLUMNS).map_err(text_error)?;
    for index in 0..options.pairs {
        let names = PairNames::new(index);
        let generated = write_pair(options, index, &names)?;
        let (shift, angle, scale) = (generated.shift, generated.angle_deg, generated.scale);
        let row = (
            index,
            &names.a,
            &names.b,
            &names.points,
            &names.truth,
            format!("{:.4}", shift.0),
            format!("{:.4}", shift.1),
            format!("{angle:.4}"),
            format!("{scale:.5}"),
            options.gain,
            options.bias,
        );
        manifest.record(row).map_err(text_error)?;
    }
    let manifest = manifest.finish().map_err(text_error)?;
    write_atomically(&options.out.join("manifest.csv"), &manifest)?;
    Ok(())
}

/// File names of one pair inside the output directory.
struct PairNames {
    a: String,
    b: String,
    points: String,
    truth: String,
}

impl PairNames {
    fn new(index: usize) -> Self {
        Self {
            a: format!("pair{index:03}_a.png"),
            b: format!("pair{index:03}_b.png"),
            points: format!("pair{index:03}_points.csv"),
            truth: format!("pair{index:03}_truth.csv"),
        }
    }
}

fn write_pair(
    options: &SynthOptions,
    index: usize,
    names: &PairNames,
) -> Result<GeneratedPair, CommandError> {
    let spec = SceneSpec::new(
        options.width,
        options.height,
        scene_seed(options.seed, index),
    )
    .with_noise(options.noise);
    let generated = generate(options, index, &spec);
    let (a, b) = pair_with_lighting(&spec, &generated.warp, options.lighting());
    let dir = &options.out;
    write_png(&dir.join(&names.a), &a)?;
    write_png(&dir.join(&names.b), &b)?;
    let mut points = CsvWriter::new(Vec::new(), &["x", "y"]).map_err(text_error)?;
    let mut truth = CsvWriter::new(Vec::new(), &["x", "y", "tx", "ty"]).map_err(text_error)?;
    for &((x, y), (tx, ty)) in &generated.points {
        points.record((x, y)).map_err(text_error)?;
        let row = (x, y, format!("{tx:.5}"), format!("{ty:.5}"));
        truth.record(row).map_err(text_error)?;
    }
    let points = points.finish().map_err(text_error)?;
    let truth = truth.finish().map_err(text_error)?;
    write_atomically(&dir.join(&names.points), &points)?;
    write_atomically(&dir.join(&names.truth), &truth)?;
    Ok(generated)
}

/// A distinct scene per pair.
fn scene_seed(seed: u64, index: usize) -> u64 {
    seed.wrapping_mul(1_000_003).wrapping_add(index as u64)
}

/// Draws the pair's warp and selects its points.
fn generate(options: &SynthOptions, index: usize, spec: &SceneSpec) -> GeneratedPair {
    let mut rng = SplitMix64::substream(options.seed, index as u64);
    let magnitude = rng.uniform(0.0, options.max_shift);
    let direction = rng.uniform(0.0, std::f64::consts::TAU);
    let shift = (magnitude * direction.cos(), magnitude * direction.sin());
    let angle_deg = rng.uniform(-1.0, 1.0);
    let scale = rng.uniform(0.98, 1.02);
    let (w, h) = (options.width as f64, options.height as f64);
    let centre = ((w - 1.0) / 2.0, (h - 1.0) / 2.0);
    let warp = Homography::similarity(scale, angle_deg.to_radians(), shift, centre);

    let (first, _) = crate::synth::pair(spec, &Homography::IDENTITY);
    let step = grid_step(options);
    let grid = grid_points(options.width, options.height, step, 12.0);
    let inside = |(x, y): (f32, f32)| {
        let (w, h) = (w as f32, h as f32);
        x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0
    };
    let candidates: Vec<_> = textured_points(&first, &grid, TEXTURE_WINDOW, MIN_STRENGTH)
        .into_iter()
        .map(|(x, y)| ((x, y), true_position(&warp, x, y)))
        .filter(|&(_, t)| inside(t))
        .collect();
    // Spread the kept points over the whole frame rather than its top rows.
    let keep = options.points.min(candidates.len());
    let points = (0..keep)
        .filter_map(|k| candidates.get(k * candidates.len() / keep))
        .copied()
        .collect();
    GeneratedPair {
        warp,
        shift,
        angle_deg,
        scale,
        points,
    }
}

/// A grid spacing that offers about twice the wanted number of points, since some nodes lack
/// texture or leave the frame.
fn grid_step(options: &SynthOptions) -> usize {
    let area = (options.width * options.height) as f64;
    let wanted = (2 * options.points.max(1)) as f64;
    ((area / wanted).sqrt().floor() as usize).clamp(4, 64)
}
