//! The Kestrel host simulator: decodes recorded frames, runs the library on them, compares it
//! with an f32 reference implementation and writes standard formats.

pub mod cli;
pub mod commands;
pub mod frame;
pub mod io;
pub mod reference;
pub mod sensor;
pub mod synth;
pub mod viz;

pub use frame::Frame;

// The parts of the commands that tests, benchmarks and other commands use, at their short paths.
pub use commands::track::tracking;
pub use commands::{dense, egomotion, stabilize};
