//! The Kestrel host simulator: decodes recorded frames, runs the library on them, compares it
//! with an f32 reference implementation and writes standard formats.

pub mod cli;
pub mod commands;
pub mod dense;
pub mod egomotion;
pub mod frame;
pub mod io;
pub mod reference;
pub mod sensor;
pub mod stabilize;
pub mod synth;
pub mod tracking;
pub mod viz;

pub use frame::Frame;
