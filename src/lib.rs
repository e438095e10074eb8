//! Kestrel: allocation-free, fixed-point sparse optical flow for flight controllers.
//!
//! The data flows through the modules in this order:
//!
//! 1. [`ImageView`]: a borrowed 8-bit grey frame with a stride; positions are [`Point`]s of
//!    [`Q16`] coordinates. These and [`ConfigError`] live at the crate's root.
//! 2. [`pyramid`]: Gaussian pyramids in caller-owned storage.
//! 3. [`detect`]: FAST-9 and Shi-Tomasi corners, spread over the frame by a grid.
//! 4. [`lk`]: Q16 pyramidal Lucas-Kanade, robust to brightness gain and bias.
//! 5. [`track`]: the KLT track manager: detection, tracking, outlier rejection, refill, ids.
//! 6. [`ego`]: the camera's motion from the tracks (robust model fitting), gyro derotation,
//!    and the autopilot's OPTICAL_FLOW_RAD output.
//! 7. [`dense`]: LK on a regular grid, the camera's dominant motion, and the boxes of what
//!    moves besides it.
//! 8. [`sensor`]: the flow sensor, frames in and the autopilot's readings out, as one type
//!    over the tracker and ego-motion.
//!
//! [`dsp`] holds the Cortex-M4 DSP instructions (USADA8, UHADD8, SMLAD) with their portable
//! equivalents, and the LK window loops' innermost kernels, in SSE2 on x86-64.
//!
//! Nothing allocates: every buffer is owned by the caller and sized by a `const fn`, so firmware
//! can place it in a `static`.
//!
//! A refused setting or buffer is a [`ConfigError`]: the field as the caller writes it
//! (`"lk.window"`, `"buffers.storage"`) and the [`Bound`] it broke. What a frame can meet is
//! each module's own error, apart ([`track::TrackerError`], [`lk::LkError`],
//! [`dense::DenseError`], [`sensor::FlowSensorError`]).
#![no_std]
// Unsafe code is denied everywhere but in `dsp`, whose `asm!` blocks are register-only
// instructions and whose SSE2 code loads and stores only the arrays it borrows (see below).
#![deny(unsafe_code)]
#![warn(missing_docs)]
// Panics stay out of the library: no unwrap, expect, panic, todo, unimplemented or
// unreachable, no indexing or slicing that can go out of bounds, and no integer arithmetic
// that can overflow (checked, saturating or wrapping operations say what happens instead).
// Narrowing `as` casts are flagged too (`try_from`, or an allow where `as` saturating is the
// point). CI runs clippy with `-D warnings`. Tests may panic.
#![cfg_attr(
    not(test),
    warn(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::todo,
        clippy::unimplemented,
        clippy::unreachable,
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation
    )
)]

mod config_error;
pub mod dense;
pub mod detect;
// The one module allowed `unsafe`: its `asm!` blocks are single DSP instructions that read and
// write registers only. Each is `options(pure, nomem, nostack)`: it touches no memory and no
// stack, so it cannot create a dangling, aliased or out-of-bounds access, and its result
// depends on its inputs alone. The portable versions next to them are the reference, checked
// against the instructions bit for bit on the target (firmware/src/dsp_check.rs). Its SSE2
// kernels (`dsp::sse2`, x86-64 only) load and store 16 bytes at a time from `[i16; 8]` and
// `[u8; 16]` arrays they borrow (8 bytes into a borrowed `[u8; 8]`), and are checked against
// their portable versions bit for bit by the tests.
#[allow(unsafe_code)]
pub mod dsp;
pub mod ego;
mod frame;
// The LK core and the pyramid are hot per-pixel loops: window sums, bilinear sampling and the
// pyramid filter index pixel rows and multiply samples millions of times a frame. Their
// indices and sums are validated once up front (frame geometry in `frame`, positions against
// the level's size, window sizes at `LucasKanade::new`, sum bounds proven in `lk::template`
// and `tests/lk_core.rs`), so they index directly and use plain arithmetic; checked
// operations there would cost a compare per sample. The indexing and arithmetic lints are off
// for these two modules only, and so is the narrowing-cast lint, since their fixed-point
// conversions narrow values whose range the same proofs bound.
#[cfg_attr(
    not(test),
    allow(
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation
    )
)]
pub mod lk;
#[cfg_attr(
    not(test),
    allow(
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation
    )
)]
pub mod pyramid;
mod q16;
pub mod sensor;
pub mod track;

pub use config_error::{Bound, ConfigError};
pub use frame::{frame_len, ImageError, ImageView, MAX_DIMENSION};
pub use q16::{Point, Q16};
