//! One module per fuzz target. Each `run` decodes its input with `arbitrary` and checks the
//! library's promises on it, panicking (so that libFuzzer reports a crash) when one is broken:
//! not only "no panic", but finite outputs, points inside the frame, statuses that agree with
//! positions and counts within capacity.
//!
//! The root test includes this module with `#[path]`, so the checks must build on stable Rust
//! with only `kestrel` and `arbitrary`.

pub mod dense;
pub mod detect;
pub mod ego;
pub mod frame;
pub mod lk;
#[cfg(feature = "mavlink")]
mod mavlink_frame;
pub mod picture;
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
];

/// The decoded input as `{:#?}`.
fn show<'a, T: arbitrary::Arbitrary<'a> + core::fmt::Debug>(data: &'a [u8]) -> String {
    format!("{:#?}", decode::<T>(data))
}

/// Decodes a whole fuzz input as `T`; `None` when the bytes run out too early to say anything.
fn decode<'a, T: arbitrary::Arbitrary<'a>>(data: &'a [u8]) -> Option<T> {
    T::arbitrary_take_rest(arbitrary::Unstructured::new(data)).ok()
}
