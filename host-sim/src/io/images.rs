//! Single images (PNG, JPEG, PGM, BMP) decoded to 8-bit grey.
//!
//! Colour is converted with the BT.601 luma weights in exact integer arithmetic,
//! `Y = round((299 R + 587 G + 114 B) / 1000)`, so every platform and build gives the same grey
//! frame bit for bit. 16-bit samples are scaled to 8 bits with rounding (`round(v / 257)`),
//! folded into the same formula. Alpha is ignored: the colour of each pixel is used as stored.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageFormat, ImageReader};

use super::jpeg::check_complete;
use super::{check_frame_size, describe_io_error, InputError};
use crate::Frame;

/// File extensions (lower case) of the image formats frame directories may hold.
pub const IMAGE_EXTENSIONS: &[&str] = &["png", "jpg", "jpeg", "pgm", "ppm", "pnm", "bmp"];

/// The formats host-sim decodes, for messages.
const SUPPORTED: &str = "PNG, JPEG, PGM or BMP";

/// True when `path` has the extension of a supported image format (any letter case).
pub fn has_image_extension(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Reads and decodes the image at `path` to grey.
///
/// The format is recognised from the file's content, not its name.
pub fn read_grey(path: &Path) -> Result<Frame, InputError> {
    let bytes = std::fs::read(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {}", describe_io_error(&e))))?;
    decode_grey(&bytes).map_err(|problem| InputError::file(path, problem))
}

/// Decodes an encoded image to grey; the error is the problem, for the caller to attach a name.
pub fn decode_grey(bytes: &[u8]) -> Result<Frame, String> {
    let corrupt = |e: &dyn std::fmt::Display| format!("corrupt or unsupported image: {e}");
    match reader(bytes)?.format() {
        Some(ImageFormat::Png | ImageFormat::Pnm | ImageFormat::Bmp) => {}
        Some(ImageFormat::Jpeg) => check_complete(bytes).map_err(|e| corrupt(&e))?,
        _ => return Err(format!("not a {SUPPORTED} image")),
    }
    // The size from the header first: a damaged or hostile header can claim gigapixels, which
    // the decoder would allocate before finding that the data is missing.
    let (width, height) = reader(bytes)?.into_dimensions().map_err(|e| corrupt(&e))?;
    check_frame_size(width as usize, height as usize)?;
    let image = reader(bytes)?.decode().map_err(|e| corrupt(&e))?;
    Ok(to_grey(&image))
}

/// A reader of `bytes` that knows their format from their content.
fn reader(bytes: &[u8]) -> Result<ImageReader<Cursor<&[u8]>>, String> {
    ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot read: {}", describe_io_error(&e)))
}

/// Encodes a grey frame as an 8-bit grey PNG.
pub fn encode_png(frame: &Frame) -> Result<Vec<u8>, String> {
    let (width, height) = (frame.width as u32, frame.height as u32);
    let image = image::GrayImage::from_raw(width, height, frame.data.clone())
        .ok_or_else(|| "frame buffer does not match its size".to_owned())?;
    let mut bytes = Vec::new();
    image
        .write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    Ok(bytes)
}

/// Encodes `width` x `height` RGB pixels (three bytes each, row by row) as a colour PNG.
pub fn encode_rgb_png(width: usize, height: usize, rgb: &[u8]) -> Result<Vec<u8>, String> {
    let image = image::RgbImage::from_raw(width as u32, height as u32, rgb.to_vec())
        .ok_or_else(|| "pixel buffer does not match its size".to_owned())?;
    let mut bytes = Vec::new();
    image
        .write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    Ok(bytes)
}

/// Writes `frame` to `path` as a grey PNG, atomically.
pub fn write_png(path: &Path, frame: &Frame) -> Result<(), super::OutputError> {
    let bytes = encode_png(frame).map_err(|problem| super::OutputError::new(path, problem))?;
    super::atomic::write_atomically(path, &bytes)
}

/// Writes an RGB picture to `path` as a PNG, atomically.
pub fn write_rgb_png(path: &Path, image: &image::RgbImage) -> Result<(), super::OutputError> {
    let (width, height) = (image.width() as usize, image.height() as usize);
    let bytes = encode_rgb_png(width, height, image.as_raw())
        .map_err(|problem| super::OutputError::new(path, problem))?;
    super::atomic::write_atomically(path, &bytes)
}

/// Converts any decoded image to an 8-bit grey frame (see the module documentation).
pub fn to_grey(image: &DynamicImage) -> Frame {
    let (width, height) = (image.width() as usize, image.height() as usize);
    let data: Vec<u8> = match image {
        DynamicImage::ImageLuma8(grey) => grey.as_raw().clone(),
        DynamicImage::ImageLumaA8(grey) => grey.pixels().map(|p| p.0[0]).collect(),
        DynamicImage::ImageRgb8(rgb) => rgb.pixels().map(|p| luma8(p.0)).collect(),
        DynamicImage::ImageRgba8(rgba) => rgba
            .pixels()
            .map(|p| luma8([p.0[0], p.0[1], p.0[2]]))
            .collect(),
        DynamicImage::ImageLuma16(grey) => grey.pixels().map(|p| scale16(p.0[0])).collect(),
        DynamicImage::ImageLumaA16(grey) => grey.pixels().map(|p| scale16(p.0[0])).collect(),
        // 16-bit colour, float colour, and any layout added to `image` later.
        other => other.to_rgb16().pixels().map(|p| luma16(p.0)).collect(),
    };
    Frame {
        width,
        height,
        data,
    }
}

/// BT.601 luma of an 8-bit RGB pixel, rounded to nearest.
///
/// ```
/// use host_sim::io::images::luma8;
/// assert_eq!(luma8([255, 255, 255]), 255);
/// assert_eq!(luma8([255, 0, 0]), 76); // 76.245
/// assert_eq!(luma8([0, 255, 0]), 150); // 149.685
/// assert_eq!(luma8([0, 0, 255]), 29); // 29.07
/// ```
pub fn luma8([r, g, b]: [u8; 3]) -> u8 {
    let weighted = 299 * u32::from(r) + 587 * u32::from(g) + 114 * u32::from(b);
    // At most 255 * 1000 before rounding, so the quotient fits a u8.
    ((weighted + 500) / 1000) as u8
}

/// BT.601 luma of a 16-bit RGB pixel, rounded to the nearest 8-bit grey level.
///
/// ```
/// use host_sim::io::images::luma16;
/// assert_eq!(luma16([65535, 65535, 65535]), 255);
/// assert_eq!(luma16([257 * 200, 257 * 100, 257 * 50]), host_sim::io::images::luma8([200, 100, 50]));
/// ```
pub fn luma16([r, g, b]: [u16; 3]) -> u8 {
    let weighted = 299 * u64::from(r) + 587 * u64::from(g) + 114 * u64::from(b);
    // Divide by 1000 for the weights and by 257 for 16 to 8 bits (65535 = 255 * 257) at once.
    ((weighted + 128_500) / 257_000) as u8
}

/// A 16-bit sample rounded to 8 bits.
fn scale16(value: u16) -> u8 {
    // 257 is odd, so `v / 257` is never exactly halfway and adding 128 rounds to nearest.
    ((u32::from(value) + 128) / 257) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{ImageBuffer, Luma, LumaA, Rgb, Rgba};

    fn encode(image: DynamicImage, format: ImageFormat) -> Vec<u8> {
        let mut bytes = Cursor::new(Vec::new());
        image.write_to(&mut bytes, format).unwrap();
        bytes.into_inner()
    }

    #[test]
    fn grey_png_is_kept_exactly() {
        let grey = ImageBuffer::from_fn(5, 3, |x, y| Luma([(x * 40 + y) as u8]));
        let frame = decode_grey(&encode(DynamicImage::ImageLuma8(grey), ImageFormat::Png)).unwrap();
        assert_eq!((frame.width, frame.height), (5, 3));
        assert_eq!(frame.at(4, 2), 162);
    }

    #[test]
    fn colour_and_alpha_use_bt601_luma() {
        let rgba = ImageBuffer::from_fn(2, 1, |x, _| {
            if x == 0 {
                Rgba([255, 0, 0, 0])
            } else {
                Rgba([10, 200, 30, 255])
            }
        });
        let frame = decode_grey(&encode(DynamicImage::ImageRgba8(rgba), ImageFormat::Png)).unwrap();
        assert_eq!(frame.data, [76, luma8([10, 200, 30])]);
    }

    #[test]
    fn sixteen_bit_inputs_are_rounded_to_eight() {
        let grey = ImageBuffer::from_fn(3, 1, |x, _| Luma([[0u16, 32896, 65535][x as usize]]));
        assert_eq!(
            to_grey(&DynamicImage::ImageLuma16(grey)).data,
            [0, 128, 255]
        );
        let grey_alpha = ImageBuffer::from_pixel(1, 1, LumaA([257u16 * 9, 0]));
        assert_eq!(to_grey(&DynamicImage::ImageLumaA16(grey_alpha)).data, [9]);
        let rgb = ImageBuffer::from_pixel(1, 1, Rgb([257u16 * 10, 257 * 200, 257 * 30]));
        let frame = decode_grey(&encode(DynamicImage::ImageRgb16(rgb), ImageFormat::Png)).unwrap();
        assert_eq!(frame.data, [luma8([10, 200, 30])]);
    }

    #[test]
    fn pgm_and_bmp_decode() {
        let grey = ImageBuffer::from_fn(4, 4, |x, y| Luma([(x * 50 + y) as u8]));
        let image = DynamicImage::ImageLuma8(grey);
        for format in [ImageFormat::Pnm, ImageFormat::Bmp] {
            let frame = decode_grey(&encode(image.clone(), format)).unwrap();
            assert_eq!(frame.at(3, 1), 151, "{format:?}");
        }
    }

    #[test]
    fn garbage_and_truncated_files_are_refused() {
        assert_eq!(
            decode_grey(b"hello, world").unwrap_err(),
            "not a PNG, JPEG, PGM or BMP image"
        );
        let grey = ImageBuffer::from_pixel(16, 16, Luma([7u8]));
        let png = encode(DynamicImage::ImageLuma8(grey), ImageFormat::Png);
        let error = decode_grey(&png[..png.len() / 2]).unwrap_err();
        assert!(error.starts_with("corrupt"), "{error}");
    }

    #[test]
    fn image_extensions_ignore_case() {
        assert!(has_image_extension(Path::new("a/0001.PNG")));
        assert!(has_image_extension(Path::new("b.jpeg")));
        assert!(!has_image_extension(Path::new("notes.txt")));
        assert!(!has_image_extension(Path::new("png")));
    }
}
