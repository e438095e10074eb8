//! The Kestrel host simulator: decodes recorded frames, runs the library on them, compares it
//! with an f32 reference implementation and writes standard formats.

pub mod cli;
pub mod commands;
pub mod egomotion;
pub mod frame;
pub mod io;
pub mod progress;
pub mod reference;
pub mod stabilize;
pub mod synth;

pub use frame::Frame;
