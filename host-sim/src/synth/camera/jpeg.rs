//! Lossy compression: a frame encoded as JPEG and decoded back, as a camera that streams or
//! records JPEG (or MJPEG) delivers it.

use std::io::Cursor;

use image::codecs::jpeg::JpegEncoder;
use image::ExtendedColorType;

use crate::io::images::decode_grey;
use crate::Frame;

/// `frame` after a JPEG round trip at `quality` (1 to 100), with the `image` crate's encoder
/// (8 x 8 blocks; grey frames have no chroma to subsample).
pub fn round_trip(frame: &Frame, quality: u8) -> Frame {
    let mut bytes = Vec::new();
    JpegEncoder::new_with_quality(Cursor::new(&mut bytes), quality)
        .encode(
            &frame.data,
            frame.width as u32,
            frame.height as u32,
            ExtendedColorType::L8,
        )
        // Frames are at most 4096 px a side, far within JPEG's 65,535, and encoded in memory.
        .expect("a rendered frame encodes as JPEG");
    decode_grey(&bytes).expect("the encoder's JPEG decodes")
}
