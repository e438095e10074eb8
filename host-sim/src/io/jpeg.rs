//! Whether a JPEG file is whole.
//!
//! JPEG decoders are lenient by design: a file cut short in its compressed data decodes without
//! an error, the missing rows filled with grey. A frame written half-way (a recorder stopped, a
//! copy interrupted) would then reach the tracker as a picture with a flat band and nothing to
//! say it is wrong. So the file's structure is walked first, and a file that ends before its
//! end-of-image marker is refused. Bytes after the marker (some cameras append data) are
//! ignored; anything else wrong in the structure is left to the decoder to report.

/// Start of image.
const SOI: u8 = 0xD8;
/// End of image.
const EOI: u8 = 0xD9;
/// Start of scan: compressed data follows its header.
const SOS: u8 = 0xDA;

/// `Ok` when `bytes` reach the end-of-image marker, the problem otherwise.
///
/// ```
/// use host_sim::io::jpeg::check_complete;
/// // SOI, a scan of two data bytes (one a stuffed 0xFF), EOI.
/// let whole = [0xFF, 0xD8, 0xFF, 0xDA, 0, 2, 0x12, 0xFF, 0x00, 0xFF, 0xD9];
/// assert!(check_complete(&whole).is_ok());
/// assert!(check_complete(&whole[..8]).is_err());
/// ```
pub fn check_complete(bytes: &[u8]) -> Result<(), String> {
    let truncated = || "JPEG data ends before its end-of-image marker (truncated file)".to_owned();
    if bytes.get(..2) != Some(&[0xFF, SOI]) {
        // Not laid out as expected: the decoder will say what is wrong.
        return Ok(());
    }
    let mut at = 2;
    loop {
        let code = match marker_at(bytes, &mut at) {
            Marker::Code(code) => code,
            Marker::End => return Err(truncated()),
            // Not a marker where one belongs: the decoder will say what is wrong.
            Marker::Other => return Ok(()),
        };
        match code {
            EOI => return Ok(()),
            // Restart markers and TEM have no length.
            0xD0..=0xD7 | 0x01 => at += 2,
            code => {
                let length = segment_length(bytes, at).ok_or_else(truncated)?;
                at += 2 + length;
                if code == SOS {
                    at = end_of_scan(bytes, at).ok_or_else(truncated)?;
                }
            }
        }
    }
}

/// What is found where a marker should be.
enum Marker {
    /// A marker and its code.
    Code(u8),
    /// The end of the data.
    End,
    /// Anything else.
    Other,
}

/// The marker at `at`, after moving `at` past any fill bytes (`0xFF` repeated) before it.
fn marker_at(bytes: &[u8], at: &mut usize) -> Marker {
    while bytes.get(*at) == Some(&0xFF) && bytes.get(*at + 1) == Some(&0xFF) {
        *at += 1;
    }
    match (bytes.get(*at), bytes.get(*at + 1)) {
        (Some(0xFF), Some(&code)) => Marker::Code(code),
        (Some(0xFF), None) | (None, _) => Marker::End,
        _ => Marker::Other,
    }
}

/// The length of the segment whose marker is at `marker` (it counts its own two bytes), when
/// the whole segment is there.
fn segment_length(bytes: &[u8], marker: usize) -> Option<usize> {
    let high = *bytes.get(marker + 2)?;
    let low = *bytes.get(marker + 3)?;
    let length = usize::from(u16::from_be_bytes([high, low]));
    (marker + 2 + length <= bytes.len()).then_some(length)
}

/// The index of the marker that ends the compressed data starting at `at`: the first `0xFF`
/// that is neither a stuffed data byte (`0xFF 0x00`) nor a restart marker.
fn end_of_scan(bytes: &[u8], at: usize) -> Option<usize> {
    let data = bytes.get(at..)?;
    data.windows(2)
        .position(|pair| pair[0] == 0xFF && !matches!(pair[1], 0x00 | 0xD0..=0xD7 | 0xFF))
        .map(|offset| at + offset)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{DynamicImage, GrayImage, ImageFormat, Luma};
    use std::io::Cursor;

    fn jpeg(width: u32, height: u32) -> Vec<u8> {
        let image = GrayImage::from_fn(width, height, |x, y| Luma([(x * 7 + y * 13) as u8]));
        let mut bytes = Cursor::new(Vec::new());
        DynamicImage::ImageLuma8(image)
            .write_to(&mut bytes, ImageFormat::Jpeg)
            .unwrap();
        bytes.into_inner()
    }

    #[test]
    fn a_whole_file_passes_with_or_without_trailing_bytes() {
        let whole = jpeg(40, 30);
        assert_eq!(check_complete(&whole), Ok(()));
        let mut trailing = whole.clone();
        trailing.extend_from_slice(b"appended by a camera");
        assert_eq!(check_complete(&trailing), Ok(()));
    }

    #[test]
    fn every_cut_is_found() {
        let whole = jpeg(40, 30);
        for len in 2..whole.len() {
            assert!(check_complete(&whole[..len]).is_err(), "cut at {len}");
        }
    }

    #[test]
    fn files_that_do_not_start_like_a_jpeg_are_left_to_the_decoder() {
        assert_eq!(check_complete(b"GIF89a"), Ok(()));
        assert_eq!(check_complete(&[]), Ok(()));
    }
}
