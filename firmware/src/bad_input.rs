//! Frames the library must refuse with an error value, while the firmware keeps running.

use cortex_m_semihosting::hprintln;
use kestrel::track::TrackerError;
use kestrel::ImageError;

use crate::checks::frame_quality;
use crate::meter::Meter;
use crate::pipeline::{FrameError, Pipeline};
use crate::scene::{FRAME_LEN, HEIGHT, WIDTH};
use crate::stages::StageTimes;

/// A frame the library must refuse, and the error it must refuse it with.
pub struct BadInput {
    pub name: &'static str,
    pub pixels: &'static [u8],
    pub size: (usize, usize),
    pub expected: FrameError,
}

/// The bad frames, cut from `good`, a valid frame: a buffer one byte short, a zero-size frame
/// and a frame of the wrong size.
pub fn cases(good: &'static [u8]) -> [BadInput; 3] {
    [
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
            expected: FrameError::Track(TrackerError::FrameSizeMismatch),
        },
    ]
}

/// Feeds frames the library must refuse: each must come back as an error value, with a flow
/// reading of quality 0 (in the reading and in its MAVLink frame), and the frames after them
/// must be processed as before. The bad frames are [`cases`] of `good`, a valid frame.
pub fn feed(pipeline: &mut Pipeline, meter: &Meter, good: &'static [u8]) -> bool {
    let mut ok = true;
    for case in cases(good) {
        let mut times = StageTimes::default();
        let outcome = pipeline.process(case.pixels, case.size, meter, &mut times);
        let (flow, mavlink) = pipeline.latest_flow();
        let quality = flow.quality;
        let wire_quality = frame_quality(mavlink);
        let outcome = outcome.map(|_| ());
        hprintln!(
            "bad_input case={} outcome={:?} quality={} mavlink_quality={}",
            case.name,
            outcome,
            quality,
            wire_quality
        );
        if outcome != Err(case.expected) || quality != 0 || wire_quality != 0 {
            hprintln!(
                "error bad input {}: expected Err({:?}) and quality 0",
                case.name,
                case.expected
            );
            ok = false;
        }
    }
    ok
}
