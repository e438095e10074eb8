//! Frames the library must refuse with an error value, while the firmware keeps running.

use cortex_m_semihosting::hprintln;
use kestrel::frame::ImageError;
use kestrel::lk::LkError;

use crate::meter::Meter;
use crate::pipeline::{FrameError, Pipeline};
use crate::scene::{FRAME_LEN, HEIGHT, WIDTH};
use crate::stages::StageTimes;

/// A frame the library must refuse, and the error it must refuse it with.
struct BadInput {
    name: &'static str,
    pixels: &'static [u8],
    size: (usize, usize),
    expected: FrameError,
}

/// Feeds frames the library must refuse: each must come back as an error value, with quality 0,
/// and the frames after them must track as before. The bad frames are cut from `good`, a valid
/// frame of the sequence.
pub fn feed(pipeline: &mut Pipeline, meter: &Meter, good: &'static [u8]) -> bool {
    let cases = [
        BadInput {
            name: "short_buffer",
            pixels: good.get(..FRAME_LEN - 1).unwrap_or(&[]),
            size: (WIDTH, HEIGHT),
            expected: FrameError::Image(ImageError::BufferTooSmall),
        },
        BadInput {
            name: "zero_size",
            pixels: &[],
            size: (0, 0),
            expected: FrameError::Image(ImageError::ZeroSize),
        },
        BadInput {
            name: "wrong_size",
            pixels: good.get(..(WIDTH / 2) * (HEIGHT / 2)).unwrap_or(&[]),
            size: (WIDTH / 2, HEIGHT / 2),
            expected: FrameError::Track(LkError::FrameSizeMismatch),
        },
    ];
    let mut ok = true;
    for case in cases {
        let mut times = StageTimes::default();
        let outcome = pipeline.process(case.pixels, case.size, meter, &mut times);
        let quality = match outcome {
            Ok(Some(flow)) => flow.quality(),
            _ => 0,
        };
        hprintln!(
            "bad_input case={} outcome={:?} quality={}",
            case.name,
            outcome,
            quality
        );
        if outcome != Err(case.expected) {
            hprintln!(
                "error bad input {}: expected Err({:?})",
                case.name,
                case.expected
            );
            ok = false;
        }
    }
    ok
}
