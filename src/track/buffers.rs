//! The caller-owned memory of a tracker, and the `const fn`s that size it.
//!
//! A tracker keeps the previous frame's pyramid (levels 1 and up; level 0 is the caller's frame
//! buffer, never copied) and builds the new frame's pyramid beside it, then swaps the roles of
//! the two halves. Everything else it needs between frames is a few hundred bytes inside the
//! [`super::Tracker`] itself.

use crate::detect::{fast_scratch_len, shi_tomasi_scratch_len, Corner};
use crate::pyramid::{level_size, pyramid_storage_len};

/// Bytes of [`TrackerBuffers::storage`] for `width` x `height` frames and pyramids down to
/// level `max_level` ([`super::TrackerConfig::pyramid_levels`]): two pyramids, and the three
/// rows FAST uses for non-maximum suppression.
///
/// ```
/// use kestrel::track::tracker_storage_len;
/// const LEN: usize = tracker_storage_len(160, 120, 3);
/// static STORAGE: [u8; LEN] = [0; LEN];
/// assert_eq!(LEN, 2 * (80 * 60 + 40 * 30 + 20 * 15) + 3 * 160);
/// ```
pub const fn tracker_storage_len(width: usize, height: usize, max_level: usize) -> usize {
    pyramid_storage_len(width, height, max_level)
        .saturating_mul(2)
        .saturating_add(fast_scratch_len(width))
}

/// `i32` words of [`TrackerBuffers::detect_scratch`] for Shi-Tomasi detection on pyramid level
/// `detect_level` of frames `width` px wide, with `candidates` candidate corners. FAST needs
/// none: give it an empty slice.
///
/// ```
/// use kestrel::track::detect_scratch_len;
/// assert_eq!(detect_scratch_len(320, 1, 200), 6 * 160);
/// ```
pub const fn detect_scratch_len(width: usize, detect_level: usize, candidates: usize) -> usize {
    shi_tomasi_scratch_len(level_size(width, detect_level), candidates)
}

/// The memory a [`super::Tracker`] works in, borrowed for its whole life.
///
/// Firmware declares each buffer as a `static` sized by the `const fn`s of this module (and
/// [`crate::lk::scratch_len`]), takes `&'static mut` references to them once at start-up
/// (`cortex_m::singleton!`, `static_cell`), and hands them over here.
///
/// ```
/// use kestrel::detect::Corner;
/// use kestrel::lk::scratch_len;
/// use kestrel::track::{detect_scratch_len, tracker_storage_len, TrackerBuffers};
/// let mut storage = [0u8; tracker_storage_len(160, 120, 3)];
/// let mut lk_scratch = [0i16; scratch_len(21)];
/// let mut detect_scratch = [0i32; detect_scratch_len(160, 1, 200)];
/// let mut candidates = [Corner::default(); 200];
/// let buffers = TrackerBuffers {
///     storage: &mut storage,
///     lk_scratch: &mut lk_scratch,
///     detect_scratch: &mut detect_scratch,
///     candidates: &mut candidates,
/// };
/// assert_eq!(buffers.candidates.len(), 200);
/// ```
#[derive(Debug)]
pub struct TrackerBuffers<'a> {
    /// Two pyramids and FAST's rows: [`tracker_storage_len`] bytes.
    pub storage: &'a mut [u8],
    /// Lucas-Kanade scratch: [`crate::lk::scratch_len`]`(window)` values.
    pub lk_scratch: &'a mut [i16],
    /// Shi-Tomasi scratch: [`detect_scratch_len`] words; may be empty with FAST.
    pub detect_scratch: &'a mut [i32],
    /// Candidate corners of one detection, at least [`super::TrackerConfig::max_tracks`]. The
    /// strongest candidates are kept before they are spaced out and bucketed, so two to four
    /// times the track count spreads new tracks better over a frame with one very textured
    /// patch.
    pub candidates: &'a mut [Corner],
}

/// The storage split into its parts.
pub(super) struct StorageParts<'s> {
    /// The pyramid half `first` names, then the other.
    pub halves: [&'s mut [u8]; 2],
    /// FAST's three rows.
    pub fast_rows: &'s mut [u8],
}

/// Splits `storage` into two pyramids of `width` x `height` frames down to `max_level`, and
/// the rest.
pub(super) fn split_storage(
    storage: &mut [u8],
    width: usize,
    height: usize,
    max_level: usize,
) -> StorageParts<'_> {
    let pyramid_len = pyramid_storage_len(width, height, max_level);
    let (first, rest) = storage.split_at_mut(pyramid_len.min(storage.len()));
    let (second, fast_rows) = rest.split_at_mut(pyramid_len.min(rest.len()));
    StorageParts {
        halves: [first, second],
        fast_rows,
    }
}
