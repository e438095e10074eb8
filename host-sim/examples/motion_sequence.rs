//! Writes a seeded synthetic sequence with moving objects and its ground truth, for
//! `host-sim motion` and the benchmarks: the scenes of the library's motion tests
//! ([`host_sim::synth::objects::Scenario`]).
//!
//! Usage: `cargo run --release -p host-sim --example motion_sequence -- OUT_DIR still|moving
//! [WIDTH HEIGHT FRAMES SEED]` (defaults 160 120 30 1 for `still`, 320 240 30 1 for `moving`).
//!
//! OUT_DIR gets `frames/frame_NNNN.png` for every frame and `truth.csv` with the columns
//! `frame,object,x,y,w,h,moves`: each object's box in each frame (pixel edges, not clipped to
//! the frame) and 1 when it moves.

use std::path::PathBuf;
use std::process::ExitCode;

use host_sim::io::atomic::write_atomically;
use host_sim::io::csv::CsvWriter;
use host_sim::io::images::write_png;
use host_sim::synth::objects::Scenario;

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
    let scenario = if moving {
        Scenario::MovingCamera
    } else {
        Scenario::StillCamera
    };
    let sequence = scenario.sequence(width, height, frames, seed);
    let dir = PathBuf::from(out);
    let frames_dir = dir.join("frames");
    std::fs::create_dir_all(&frames_dir).map_err(|e| format!("{out}: {e}"))?;
    let columns = ["frame", "object", "x", "y", "w", "h", "moves"];
    let mut truth = CsvWriter::new(Vec::new(), &columns).map_err(|e| e.to_string())?;
    for k in 0..frames {
        write_png(
            &frames_dir.join(format!("frame_{k:04}.png")),
            &sequence.frame(k),
        )
        .map_err(|e| e.to_string())?;
        for (i, (b, object)) in sequence.boxes(k).iter().zip(sequence.objects()).enumerate() {
            let moves = u8::from(object.moves());
            let [x, y, w, h] = [b.x, b.y, b.w, b.h].map(|v| format!("{v:.3}"));
            let row = (k, i, x, y, w, h, moves);
            truth.record(row).map_err(|e| e.to_string())?;
        }
    }
    let truth = truth.finish().map_err(|e| e.to_string())?;
    write_atomically(&dir.join("truth.csv"), &truth).map_err(|e| e.to_string())
}
