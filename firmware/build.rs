//! Puts the repository's `memory.x` on the link path and renders the synthetic frames that the
//! firmware keeps in flash.

use std::env;
use std::error::Error;
use std::f64::consts::TAU;
use std::fs;
use std::path::{Path, PathBuf};

#[path = "src/scene.rs"]
mod scene;

/// Plane waves summed into the texture: amplitude (grey levels), wavelength (px), direction
/// (degrees), phase (radians). Five directions and incommensurate wavelengths leave no window
/// without gradient in both axes and no period that could alias the motion.
const WAVES: [(f64, f64, f64, f64); 5] = [
    (30.0, 37.0, 20.0, 0.3),
    (25.0, 23.0, 75.0, 1.1),
    (20.0, 15.0, 130.0, 2.0),
    (15.0, 11.0, 160.0, 0.7),
    (12.0, 29.0, 105.0, 2.5),
];

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

/// Every frame, packed, one after the other: frame `k` is the texture moved by `k` times the
/// scene motion, so a point at `p` in frame `k - 1` is at `p + motion` in frame `k`.
fn render_frames() -> Vec<u8> {
    let (mx, my) = scene::MOTION_MILLIPX;
    let (mx, my) = (f64::from(mx) / 1000.0, f64::from(my) / 1000.0);
    let mut pixels = Vec::with_capacity(scene::FRAMES * scene::FRAME_LEN);
    for k in 0..scene::FRAMES {
        let (sx, sy) = (k as f64 * mx, k as f64 * my);
        for y in 0..scene::HEIGHT {
            for x in 0..scene::WIDTH {
                let grey = texture(x as f64 - sx, y as f64 - sy);
                pixels.push(grey.round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    pixels
}

/// A smooth texture defined everywhere, so a translated frame is exact up to 8-bit rounding.
fn texture(x: f64, y: f64) -> f64 {
    let waves = WAVES
        .iter()
        .map(|&(amplitude, wavelength, degrees, phase)| {
            let (sin, cos) = degrees.to_radians().sin_cos();
            amplitude * (TAU * (x * cos + y * sin) / wavelength + phase).sin()
        });
    128.0 + waves.sum::<f64>()
}
