//! A stand-in camera: the synthetic frames rendered by `build.rs`, kept in flash.
//!
//! On a flight controller the frames would come from a DCMI DMA buffer; here they are read in
//! place from flash, which the library borrows just the same.

use crate::scene::{FRAMES, FRAME_LEN};

/// Every frame of the sequence, packed, one after the other.
/// An array rather than a reference, so that its symbol has the blob's size and the harness can
/// tell the test frames apart from the program's own flash.
static FRAMES_BLOB: [u8; FRAMES * FRAME_LEN] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/frames.bin"));

/// The pixels of frame `index`, or an empty slice past the last frame.
pub fn frame(index: usize) -> &'static [u8] {
    let start = index * FRAME_LEN;
    FRAMES_BLOB.get(start..start + FRAME_LEN).unwrap_or(&[])
}
