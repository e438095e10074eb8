//! Puts the repository's `memory.x` on the link path and renders the synthetic frames that the
//! firmware keeps in flash.
//!
//! The scene is a background of blurred blocks over soft plane waves, moving by the camera's
//! motion, and a checkered square moving on its own across it. Both are defined at every real
//! position, so a frame moved by a sub-pixel amount is exact up to 8-bit rounding, and the
//! rendering is a pure function of `src/scene.rs`: the same bytes on every build.

use std::env;
use std::error::Error;
use std::f64::consts::{PI, TAU};
use std::fs;
use std::path::{Path, PathBuf};

// The firmware uses the rest of the scene: the camera model and the frame interval.
#[allow(dead_code)]
#[path = "src/scene.rs"]
pub mod scene;

/// Plane waves under the blocks: amplitude (grey levels), wavelength (px), direction
/// (degrees), phase (radians). They give every dense-grid window some texture in both axes.
const WAVES: [(f64, f64, f64, f64); 4] = [
    (12.0, 37.0, 20.0, 0.3),
    (10.0, 23.0, 75.0, 1.1),
    (8.0, 15.0, 130.0, 2.0),
    (6.0, 11.0, 160.0, 0.7),
];
/// Blocks of the background: each has four corners for the detector.
const BLOCKS: usize = 110;
/// Width of a block's or the object's edge, px: blurred enough for sub-pixel LK, sharp
/// enough for strong corners.
const EDGE: f64 = 0.6;
/// The background extends this far beyond the frame, px, so nothing new comes in flat.
const MARGIN: f64 = 16.0;

/// A rectangle of the background: left, top, right, bottom (px) and its grey offset.
struct Block {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
    grey: f64,
}

fn main() -> Result<(), Box<dyn Error>> {
    let out = PathBuf::from(env::var("OUT_DIR")?);
    place_memory_layout(&out)?;
    fs::write(out.join("frames.bin"), render_frames())?;
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=src/scene.rs");
    Ok(())
}

/// Copies `../memory.x`, the one description of the board's memory, where the linker finds it.
fn place_memory_layout(out: &Path) -> Result<(), Box<dyn Error>> {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../memory.x");
    fs::copy(&source, out.join("memory.x"))?;
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", source.display());
    Ok(())
}

/// Every frame, packed, one after the other: in frame `k` the background has moved by `k`
/// times the camera's motion and the object sits at [`scene::object_origin_millipx`]`(k)`.
pub fn render_frames() -> Vec<u8> {
    let blocks = blocks();
    let millipx = |v: i32| f64::from(v) / 1000.0;
    let (mx, my) = scene::MOTION_MILLIPX;
    let mut pixels = Vec::with_capacity(scene::FRAMES * scene::FRAME_LEN);
    for k in 0..scene::FRAMES {
        let (sx, sy) = (k as f64 * millipx(mx), k as f64 * millipx(my));
        let (ox, oy) = scene::object_origin_millipx(k);
        let (ox, oy) = (millipx(ox), millipx(oy));
        for y in 0..scene::HEIGHT {
            for x in 0..scene::WIDTH {
                let (x, y) = (x as f64, y as f64);
                let back = background(&blocks, x - sx, y - sy);
                let (u, v) = (x - ox, y - oy);
                let alpha = object_mask(u, v);
                let grey = alpha * object(u, v) + (1.0 - alpha) * back;
                pixels.push(grey.round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    pixels
}

/// The background's blocks, from a fixed-seed generator over the frame and its margin.
fn blocks() -> Vec<Block> {
    let mut rng = SplitMix64(0x4B45_5354_5245_4C00);
    (0..BLOCKS)
        .map(|_| {
            let x0 = -MARGIN + rng.unit() * (scene::WIDTH as f64 + 2.0 * MARGIN);
            let y0 = -MARGIN + rng.unit() * (scene::HEIGHT as f64 + 2.0 * MARGIN);
            let (w, h) = (7.0 + rng.unit() * 9.0, 7.0 + rng.unit() * 9.0);
            let magnitude = 40.0 + rng.unit() * 30.0;
            let grey = if rng.unit() < 0.5 {
                -magnitude
            } else {
                magnitude
            };
            Block {
                x0,
                y0,
                x1: x0 + w,
                y1: y0 + h,
                grey,
            }
        })
        .collect()
}

/// The static scene at scene coordinates (`x`, `y`).
fn background(blocks: &[Block], x: f64, y: f64) -> f64 {
    let waves: f64 = WAVES
        .iter()
        .map(|&(amplitude, wavelength, degrees, phase)| {
            let (sin, cos) = degrees.to_radians().sin_cos();
            amplitude * (TAU * (x * cos + y * sin) / wavelength + phase).sin()
        })
        .sum();
    let blocks: f64 = blocks
        .iter()
        .map(|b| b.grey * span(x, b.x0, b.x1) * span(y, b.y0, b.y1))
        .sum();
    128.0 + waves + blocks
}

/// How much of the object covers object coordinates (`u`, `v`): 1 inside, 0 outside.
fn object_mask(u: f64, v: f64) -> f64 {
    let side = f64::from(scene::OBJECT_SIDE);
    span(u, 0.0, side) * span(v, 0.0, side)
}

/// The object's own texture: a checkerboard of 6 px squares with soft edges.
fn object(u: f64, v: f64) -> f64 {
    let square = |t: f64| (3.0 * (PI * t / 6.0).sin()).tanh();
    128.0 + 80.0 * square(u) * square(v)
}

/// A soft indicator of `lo <= t <= hi`, edges [`EDGE`] px wide.
fn span(t: f64, lo: f64, hi: f64) -> f64 {
    let step = |s: f64| 1.0 / (1.0 + (-s / EDGE).exp());
    step(t - lo) * step(hi - t)
}

/// A small deterministic generator (SplitMix64), so the scene needs no crate.
struct SplitMix64(u64);

impl SplitMix64 {
    /// A uniform number in `[0, 1)`.
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}
