//! What the command-line tests share: scratch directories, running the binary, and the error
//! contract's check.

// Each test binary compiles its own copy and uses a part of it.
#![allow(dead_code)]

use std::fs;
use std::path::PathBuf;
use std::process::{Command, Output};

/// A directory for one test's files, removed when the test ends.
pub struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    pub fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("host-sim-cli-{test}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        Self { dir }
    }

    /// The directory itself.
    pub fn dir(&self) -> &std::path::Path {
        &self.dir
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// The names in the directory, sorted.
    pub fn entries(&self) -> Vec<String> {
        entries(&self.dir)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.dir);
    }
}

/// The names in `dir`, sorted.
pub fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Runs the `host-sim` binary with `args`.
pub fn host_sim(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args.iter().map(|a| a.as_ref()))
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap()
}

/// Checks the error contract: exit `code`, exactly one stderr line starting `host-sim: ` and
/// naming `culprit`, nothing on stdout, no panic or backtrace.
pub fn assert_one_line_error(output: &Output, code: i32, culprit: &str) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(output.status.code(), Some(code), "stderr: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "not one line: {stderr:?}");
    assert!(stderr.ends_with('\n'), "{stderr:?}");
    assert!(stderr.starts_with("host-sim: "), "{stderr:?}");
    assert!(
        stderr.contains(culprit),
        "{stderr:?} does not name {culprit:?}"
    );
    let lower = stderr.to_lowercase();
    assert!(
        !lower.contains("panicked") && !lower.contains("backtrace"),
        "{stderr:?}"
    );
    assert!(output.stdout.is_empty(), "stdout: {:?}", output.stdout);
    stderr
}

/// FNV-1a, 64 bits, over `bytes`, continuing from `hash`: a hash no library version can change.
pub fn fnv1a(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The hash of a `synth-sequence` run in `dir`: every frame's pixels (decoded, so a PNG
/// encoder's choices do not count) and every CSV file it wrote, in name order.
pub fn synth_run_hash(dir: &std::path::Path) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325;
    for name in entries(&dir.join("frames")) {
        let frame = host_sim::io::images::read_grey(&dir.join("frames").join(&name)).unwrap();
        hash = fnv1a(hash, &frame.data);
    }
    for name in entries(dir) {
        if name.ends_with(".csv") {
            hash = fnv1a(hash, &std::fs::read(dir.join(name)).unwrap());
        }
    }
    hash
}

/// Runs `synth-sequence --out DIR` with `args`, DIR `name` in `scratch`.
pub fn run_synth(scratch: &Scratch, name: &str, args: &[&str]) -> (std::path::PathBuf, Output) {
    let out = scratch.path(name);
    let mut words: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"synth-sequence", &"--out", &out];
    words.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
    (out.clone(), host_sim(&words))
}

/// Runs `synth-sequence` with `args` into a fresh directory of `scratch` and returns it.
pub fn synth(scratch: &Scratch, name: &str, args: &[&str]) -> std::path::PathBuf {
    let (out, output) = run_synth(scratch, name, args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{args:?}: {stderr}");
    out
}

/// Frame `k` of a `synth-sequence` run in `dir`.
pub fn synth_frame(dir: &std::path::Path, k: usize) -> host_sim::Frame {
    host_sim::io::images::read_grey(&dir.join("frames").join(format!("frame_{k:05}.png"))).unwrap()
}

/// Runs `synth-sequence` with each of `runs`' arguments and checks each run's
/// [`synth_run_hash`] against the hash beside it (recorded before a change that must leave such
/// runs as they were).
pub fn assert_synth_hashes(scratch: &Scratch, runs: &[(&[&str], u64)]) {
    let hashes: Vec<u64> = runs
        .iter()
        .enumerate()
        .map(|(k, (args, _))| synth_run_hash(&synth(scratch, &format!("run{k}"), args)))
        .collect();
    let expected: Vec<u64> = runs.iter().map(|(_, hash)| *hash).collect();
    assert_eq!(hashes, expected, "{hashes:#018x?}");
}
