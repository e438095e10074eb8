//! `host-sim synth`: seeded frame pairs with exact ground truth, for benchmarks and scripts.
//!
//! Each pair is a procedural scene and the same scene under a known warp (a translation in a
//! random direction up to `max_shift`, a rotation within ±1° and a zoom within ±2% about the
//! centre), optionally with a brightness gain and bias and sensor noise. The points are the
//! textured nodes of a grid whose true positions stay inside the second frame.

use std::fmt::Write as _;
use std::path::PathBuf;

use super::CommandError;
use crate::io::atomic::write_atomically;
use crate::io::create_output_dir;
use crate::io::images::write_png;
use crate::synth::{
    grid_points, pair_with_lighting, textured_points, true_position, Homography, Lighting,
    SceneSpec, SplitMix64,
};

/// Everything `synth` needs, validated by the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthOptions {
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Number of pairs.
    pub pairs: usize,
    /// Frame width in px.
    pub width: usize,
    /// Frame height in px.
    pub height: usize,
    /// Seed of the whole set.
    pub seed: u64,
    /// Largest translation, px.
    pub max_shift: f64,
    /// Brightness change of the second frame.
    pub lighting: Lighting,
    /// Sensor noise, grey levels (standard deviation).
    pub noise: f64,
    /// At most this many points per pair.
    pub points: usize,
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
    let mut manifest = String::from("pair,a,b,points,truth,dx,dy,angle_deg,scale,gain,bias\n");
    for index in 0..options.pairs {
        let names = PairNames::new(index);
        let generated = write_pair(options, index, &names)?;
        let _ = writeln!(
            manifest,
            "{index},{},{},{},{},{:.4},{:.4},{:.4},{:.5},{},{}",
            names.a,
            names.b,
            names.points,
            names.truth,
            generated.shift.0,
            generated.shift.1,
            generated.angle_deg,
            generated.scale,
            options.lighting.gain,
            options.lighting.bias,
        );
    }
    write_atomically(&options.out.join("manifest.csv"), manifest.as_bytes())?;
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
    let (a, b) = pair_with_lighting(&spec, &generated.warp, options.lighting);
    let dir = &options.out;
    write_png(&dir.join(&names.a), &a)?;
    write_png(&dir.join(&names.b), &b)?;
    let (mut points, mut truth) = (String::from("x,y\n"), String::from("x,y,tx,ty\n"));
    for &((x, y), (tx, ty)) in &generated.points {
        let _ = writeln!(points, "{x},{y}");
        let _ = writeln!(truth, "{x},{y},{tx:.5},{ty:.5}");
    }
    write_atomically(&dir.join(&names.points), points.as_bytes())?;
    write_atomically(&dir.join(&names.truth), truth.as_bytes())?;
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
