//! The bodies of Kestrel's fuzz targets, shared by the `cargo fuzz` binaries in `fuzz_targets/`
//! and by the root test `tests/fuzz_corpus.rs`, which replays the committed corpus on stable
//! Rust without libFuzzer.

pub mod targets;
