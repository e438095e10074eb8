//! A cheap check that the caller's "previous frame" is the frame the tracker saw last.
//!
//! The tracker keeps the previous frame's coarser pyramid levels but not its pixels: with
//! camera ping-pong buffers the caller passes the previous buffer again. Should the camera have
//! refilled that buffer in the meantime (a missed frame, a driver bug), LK would compare the new
//! frame with itself and report every track as perfectly still. A few dozen pixels spread over
//! the frame, compared exactly, catch that with next to no cost; sensor noise alone makes two
//! real frames differ in some of them.

use crate::frame::ImageView;

/// Pixels sampled per frame.
const SAMPLES: usize = 32;
/// Steps the sampled rows through a permutation of `0..SAMPLES` (odd, so coprime with 32):
/// every sample has its own column and its own row.
const ROW_STEP: usize = 11;

/// The size of a frame and a sparse sample of its pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Fingerprint {
    width: usize,
    height: usize,
    samples: [u8; SAMPLES],
}

impl Fingerprint {
    /// The fingerprint of `frame`.
    // `k < SAMPLES` and sides are at most 4096 px: the products stay below 2^18.
    #[allow(clippy::arithmetic_side_effects)]
    pub(super) fn of(frame: &ImageView<'_>) -> Self {
        let (width, height) = (frame.width(), frame.height());
        let samples = core::array::from_fn(|k| {
            // Cell centres of a SAMPLES x SAMPLES grid over the frame, one per column.
            let x = (2 * k + 1) * width / (2 * SAMPLES);
            let y = (2 * (k * ROW_STEP % SAMPLES) + 1) * height / (2 * SAMPLES);
            frame.get(x, y).unwrap_or(0)
        });
        Self {
            width,
            height,
            samples,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_changed_sampled_pixel_or_a_new_size_changes_the_fingerprint() {
        let mut pixels = [7u8; 64 * 48];
        let a = Fingerprint::of(&ImageView::packed(&pixels, 64, 48).unwrap());
        // Sample 0 is at column 1, row 0.
        pixels[1] = 8;
        let b = Fingerprint::of(&ImageView::packed(&pixels, 64, 48).unwrap());
        assert_ne!(a, b);
        let c = Fingerprint::of(&ImageView::packed(&pixels[..48 * 64], 48, 64).unwrap());
        assert_ne!(b, c);
    }

    #[test]
    fn the_stride_does_not_matter() {
        let packed: [u8; 6] = [1, 2, 3, 4, 5, 6];
        let padded: [u8; 8] = [1, 2, 3, 0, 4, 5, 6, 0];
        let a = Fingerprint::of(&ImageView::packed(&packed, 3, 2).unwrap());
        let b = Fingerprint::of(&ImageView::new(&padded, 3, 2, 4).unwrap());
        assert_eq!(a, b);
    }

    #[test]
    fn tiny_frames_are_fine() {
        let pixel = [9u8];
        let f = Fingerprint::of(&ImageView::packed(&pixel, 1, 1).unwrap());
        assert_eq!(f.samples, [9; SAMPLES]);
    }
}
