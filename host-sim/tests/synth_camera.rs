//! `host-sim synth-sequence`'s outputs, held byte for byte to hashes of recorded runs.

mod common;

use std::fs;
use std::path::Path;

use common::{host_sim, Scratch};
use host_sim::io::images::read_grey;

/// FNV-1a, 64 bits: a hash that no library version can change.
fn fnv1a(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// The hash of every frame's pixels (decoded, so a PNG encoder's choices do not count) and of
/// every text file the run wrote, in name order.
fn run_hash(dir: &Path) -> u64 {
    let mut hash = FNV_OFFSET;
    for name in common::entries(&dir.join("frames")) {
        let frame = read_grey(&dir.join("frames").join(&name)).unwrap();
        hash = fnv1a(hash, &frame.data);
    }
    for name in common::entries(dir) {
        if name.ends_with(".csv") {
            hash = fnv1a(hash, &fs::read(dir.join(name)).unwrap());
        }
    }
    hash
}

/// Runs `synth-sequence` with `args` into a fresh directory of `scratch` and returns it.
fn synth(scratch: &Scratch, name: &str, args: &[&str]) -> std::path::PathBuf {
    let out = scratch.path(name);
    let mut words: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"synth-sequence", &"--out", &out];
    words.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
    let output = host_sim(&words);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{args:?}: {stderr}");
    out
}

/// Runs without any camera flag, and the hashes of their outputs as recorded at commit 3870d6f,
/// before the camera model.
const UNCHANGED_RUNS: [(&[&str], u64); 3] = [
    (&[], 0xf17e504e8c1e02e9),
    (
        &[
            "--path",
            "perspective",
            "--objects",
            "2",
            "--frames",
            "6",
            "--width",
            "96",
            "--height",
            "72",
        ],
        0x32467c6b4d61494d,
    ),
    (
        &[
            "--path", "shake", "--noise", "0", "--frames", "5", "--seed", "7",
        ],
        0xd797b03f0d2dc4b7,
    ),
];

#[test]
fn without_camera_flags_the_frames_are_byte_for_byte_unchanged() {
    let scratch = Scratch::new("synth-unchanged");
    let hashes: Vec<u64> = UNCHANGED_RUNS
        .iter()
        .enumerate()
        .map(|(k, (args, _))| run_hash(&synth(&scratch, &format!("run{k}"), args)))
        .collect();
    let expected: Vec<u64> = UNCHANGED_RUNS.iter().map(|(_, hash)| *hash).collect();
    assert_eq!(hashes, expected, "{hashes:#018x?}");
}
