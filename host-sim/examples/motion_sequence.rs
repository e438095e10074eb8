//! Writes a seeded synthetic sequence with moving objects and its ground truth, for
//! `host-sim motion` and the benchmarks: the same scenes as the library's motion tests.
//!
//! Usage: `cargo run --release -p host-sim --example motion_sequence -- OUT_DIR still|moving
//! [WIDTH HEIGHT FRAMES SEED]` (defaults 160 120 30 1 for `still`, 320 240 30 1 for `moving`).
//!
//! OUT_DIR gets `frames/frame_NNNN.png` for every frame and `truth.csv` with the columns
//! `frame,object,x,y,w,h,moves`: each object's box in each frame (pixel edges, not clipped to
//! the frame) and 1 when it moves.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use host_sim::io::atomic::write_atomically;
use host_sim::io::images::write_png;
use host_sim::synth::objects::{scatter_objects, BoxPx, ObjectSequence, ObjectSpec};
use host_sim::synth::{CameraPath, Scene, SceneSpec};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("motion_sequence: {message}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: &[String]) -> Result<(), String> {
    let [out, kind, rest @ ..] = args else {
        return Err(
            "usage: motion_sequence OUT_DIR still|moving [WIDTH HEIGHT FRAMES SEED]".into(),
        );
    };
    let moving = match kind.as_str() {
        "still" => false,
        "moving" => true,
        other => return Err(format!("'{other}': expected still or moving")),
    };
    let number = |i: usize, default: usize| -> Result<usize, String> {
        rest.get(i).map_or(Ok(default), |v| {
            v.parse().map_err(|_| format!("'{v}' is not a number"))
        })
    };
    let (w, h) = if moving { (320, 240) } else { (160, 120) };
    let (width, height) = (number(0, w)?, number(1, h)?);
    let (frames, seed) = (number(2, 30)?, number(3, 1)? as u64);
    let sequence = sequence(moving, width, height, frames, seed);
    let dir = PathBuf::from(out);
    let frames_dir = dir.join("frames");
    std::fs::create_dir_all(&frames_dir).map_err(|e| format!("{out}: {e}"))?;
    let mut truth = String::from("frame,object,x,y,w,h,moves\n");
    for k in 0..frames {
        write_png(
            &frames_dir.join(format!("frame_{k:04}.png")),
            &sequence.frame(k),
        )
        .map_err(|e| e.to_string())?;
        for (i, (b, object)) in sequence.boxes(k).iter().zip(sequence.objects()).enumerate() {
            let moves = u8::from(object.moves());
            let _ = writeln!(
                truth,
                "{k},{i},{:.3},{:.3},{:.3},{:.3},{moves}",
                b.x, b.y, b.w, b.h
            );
        }
    }
    write_atomically(&dir.join("truth.csv"), truth.as_bytes()).map_err(|e| e.to_string())
}

/// The scenes of `tests/dense_motion.rs`: a still camera over objects of 10 to 40 px (one of
/// them standing still), or a camera panning, rolling and zooming over targets of 10 to 25 px.
fn sequence(moving: bool, width: usize, height: usize, frames: usize, seed: u64) -> ObjectSequence {
    let centre = (width as f64 / 2.0, height as f64 / 2.0);
    let (spec, camera, margin) = if moving {
        let spec = ObjectSpec {
            moving: 8,
            still: 0,
            sizes: (10.0, 25.0),
            speeds: (1.5, 3.0),
            gap: 24.0,
        };
        let camera = CameraPath {
            pan: (1.5, -0.8),
            rotation: 0.4f64.to_radians(),
            zoom: 1.006,
            centre,
        };
        (spec, camera, 24.0)
    } else {
        let spec = ObjectSpec {
            moving: 4,
            still: 1,
            sizes: (10.0, 40.0),
            speeds: (1.0, 3.0),
            gap: 24.0,
        };
        (spec, CameraPath::still(centre), 0.0)
    };
    let area = BoxPx {
        x: margin,
        y: margin,
        w: width as f64 - 2.0 * margin,
        h: height as f64 - 2.0 * margin,
    };
    let objects = scatter_objects(seed, &spec, area, frames);
    let scene = Scene::new(SceneSpec::new(width, height, seed).with_noise(1.5));
    ObjectSequence::new(scene, objects, camera, frames)
}
