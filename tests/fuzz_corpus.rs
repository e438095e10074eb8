//! Replays the fuzz corpus and the crash regressions through the fuzz targets' checks.
//!
//! The targets' bodies live in `fuzz/src/targets/` and are included here as they are, so the
//! README's test command runs every committed input on stable Rust, without libFuzzer: a
//! regression of a crash the fuzzer once found fails here. `cargo fuzz` (see `fuzz/README.md`)
//! explores further.

#[path = "../fuzz/src/targets/mod.rs"]
mod targets;

use std::fs;
use std::path::{Path, PathBuf};

/// The committed inputs of one target: its corpus and its regressions.
fn inputs(target: &str) -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut files = Vec::new();
    for dir in ["corpus", "regressions"] {
        let Ok(entries) = fs::read_dir(root.join(dir).join(target)) else {
            continue;
        };
        files.extend(
            entries
                .filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.is_file()),
        );
    }
    files.sort();
    files
}

/// Runs every committed input of `target`, naming the file that fails.
fn replay(target: &str) {
    let run = target_named(target).run;
    let files = inputs(target);
    assert!(!files.is_empty(), "no corpus for {target}");
    for file in &files {
        let data = fs::read(file).expect("a readable corpus file");
        let outcome = std::panic::catch_unwind(|| run(&data));
        assert!(outcome.is_ok(), "{target}: {} fails", file.display());
    }
}

#[test]
fn frame_corpus() {
    replay("frame");
}

#[test]
fn detect_corpus() {
    replay("detect");
}

#[test]
fn lk_corpus() {
    replay("lk");
}

#[test]
fn track_corpus() {
    replay("track");
}

#[test]
fn ego_corpus() {
    replay("ego");
}

#[test]
fn dense_corpus() {
    replay("dense");
}

#[test]
fn motion_corpus() {
    replay("motion");
}

#[test]
fn sensor_corpus() {
    replay("sensor");
}

fn target_named(name: &str) -> &'static targets::Target {
    targets::ALL
        .iter()
        .find(|t| t.name == name)
        .expect("a known target")
}

/// Every target has a test above.
#[test]
fn every_target_is_replayed() {
    let names: Vec<&str> = targets::ALL.iter().map(|t| t.name).collect();
    assert_eq!(
        names,
        ["frame", "detect", "lk", "track", "ego", "dense", "motion", "sensor"]
    );
}

/// The checks themselves run on inputs made here, so a corpus that no longer decodes (after a
/// change to an input type) does not leave them untested.
#[test]
fn targets_accept_any_bytes() {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for len in [0usize, 1, 7, 64, 512, 4096] {
        let data: Vec<u8> = (0..len)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        for target in targets::ALL {
            (target.run)(&data);
        }
    }
}

/// Prints a fuzz input as its target decodes it, to read a crash:
/// `FUZZ_SHOW=lk:fuzz/artifacts/lk/crash-... cargo test --release --test fuzz_corpus show -- --ignored --nocapture`
#[test]
#[ignore = "a tool, run by hand with FUZZ_SHOW=target:file"]
fn show() {
    let spec = std::env::var("FUZZ_SHOW").expect("FUZZ_SHOW=target:file");
    let (name, file) = spec.split_once(':').expect("FUZZ_SHOW=target:file");
    let data = fs::read(file).expect("a readable input");
    println!("{}", (target_named(name).show)(&data));
    (target_named(name).run)(&data);
}
