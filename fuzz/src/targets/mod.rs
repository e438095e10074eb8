//! One module per fuzz target. Each `run` decodes its input with `arbitrary` and checks the
//! library's promises on it, panicking (so that libFuzzer reports a crash) when one is broken:
//! not only "no panic", but finite outputs, points inside the frame, statuses that agree with
//! positions and counts within capacity.
//!
//! The root test includes this module with `#[path]`, so the checks must build on stable Rust
//! with only `kestrel` and `arbitrary`.

use kestrel::lk::{Illumination, LkParams, TemplatePlacement};

pub mod dense;
pub mod detect;
pub mod ego;
pub mod frame;
pub mod lk;
#[cfg(feature = "mavlink")]
mod mavlink_frame;
pub mod motion;
pub mod picture;
pub mod sensor;
pub mod track;

/// A fuzz target.
pub struct Target {
    /// Its name: the binary and the corpus folder.
    pub name: &'static str,
    /// Its body: decodes the input and checks the library on it.
    pub run: fn(&[u8]),
    /// The decoded input, for reading a crash.
    pub show: fn(&[u8]) -> String,
}

/// Every target.
pub const ALL: &[Target] = &[
    Target {
        name: "frame",
        run: frame::run,
        show: frame::show,
    },
    Target {
        name: "detect",
        run: detect::run,
        show: detect::show,
    },
    Target {
        name: "lk",
        run: lk::run,
        show: lk::show,
    },
    Target {
        name: "track",
        run: track::run,
        show: track::show,
    },
    Target {
        name: "ego",
        run: ego::run,
        show: ego::show,
    },
    Target {
        name: "dense",
        run: dense::run,
        show: dense::show,
    },
    Target {
        name: "motion",
        run: motion::run,
        show: motion::show,
    },
    Target {
        name: "sensor",
        run: sensor::run,
        show: sensor::show,
    },
];

/// LK settings over the whole range the API validates and past it (windows up to 69, levels
/// up to 9, up to 39 iterations), as the lk and track targets draw them.
fn lk_params(
    window: u8,
    max_level: u8,
    max_iterations: u8,
    epsilon: f32,
    min_eigen_threshold: f32,
    plain: bool,
) -> LkParams {
    LkParams {
        window: usize::from(window % 70),
        max_level: usize::from(max_level % 10),
        max_iterations: u32::from(max_iterations % 40),
        epsilon,
        min_eigen_threshold,
        illumination: illumination(plain),
        template: template_placement(max_iterations),
    }
}

/// The illumination model a flag picks.
fn illumination(plain: bool) -> Illumination {
    if plain {
        Illumination::Plain
    } else {
        Illumination::GainBias
    }
}

/// The template placement, from the top bit of an iteration-count byte: every target's modulus
/// of the count ignores that bit, so the corpus keeps its meaning.
fn template_placement(max_iterations: u8) -> TemplatePlacement {
    if max_iterations & 0x80 == 0 {
        TemplatePlacement::AtPoint
    } else {
        TemplatePlacement::NearestPixel
    }
}

/// The decoded input as `{:#?}`.
fn show<'a, T: arbitrary::Arbitrary<'a> + core::fmt::Debug>(data: &'a [u8]) -> String {
    format!("{:#?}", decode::<T>(data))
}

/// Decodes a whole fuzz input as `T`; `None` when the bytes run out too early to say anything.
fn decode<'a, T: arbitrary::Arbitrary<'a>>(data: &'a [u8]) -> Option<T> {
    T::arbitrary_take_rest(arbitrary::Unstructured::new(data)).ok()
}
