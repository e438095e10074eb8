//! Image views with arbitrary sizes, strides and buffer lengths, and pyramids built on them.
//!
//! The geometry check is compared with an independent statement of the rule (in 128-bit
//! arithmetic, so it cannot overflow where the library's might), and every accepted view must
//! read exactly the bytes its geometry names. Pyramids must refuse too many levels and short
//! storage, size each level as documented, keep every level within the frame's grey range
//! (the blur is a weighted mean) and read back identically through `from_storage`.

use arbitrary::Arbitrary;
use kestrel::pyramid::{level_size, pyramid_storage_len, Pyramid, MAX_LEVEL};
use kestrel::{Bound, ConfigError};
use kestrel::{ImageError, ImageView, MAX_DIMENSION};

/// Larger buffers only slow the fuzzer down; the geometry still reaches 4097 px and beyond.
const MAX_BUFFER: usize = 1 << 16;

#[derive(Arbitrary, Debug)]
struct Input {
    width: u16,
    height: u16,
    stride: u16,
    /// Buffer length, within `MAX_BUFFER`.
    len: u16,
    levels: u8,
    /// Storage bytes added to (or, when negative, taken from) what the pyramid needs.
    storage_delta: i8,
    pixels: Vec<u8>,
}

/// The decoded input, for reading a crash.
pub fn show(data: &[u8]) -> String {
    super::show::<Input>(data)
}

pub fn run(data: &[u8]) {
    let Some(input) = super::decode::<Input>(data) else {
        return;
    };
    let buffer = fill(&input.pixels, usize::from(input.len) % MAX_BUFFER);
    let (w, h, s) = (
        usize::from(input.width),
        usize::from(input.height),
        usize::from(input.stride),
    );
    let result = ImageView::new(&buffer, w, h, s);
    assert_eq!(
        result.map(|v| (v.width(), v.height(), v.stride())),
        expected_geometry(buffer.len(), w, h, s).map(|()| (w, h, s)),
        "geometry {w} x {h} stride {s} over {} bytes",
        buffer.len()
    );
    if let Ok(view) = result {
        check_view(&view, &buffer);
        check_pyramid(view, usize::from(input.levels % 10), input.storage_delta);
    }
}

/// The buffer: the fuzzer's bytes repeated to `len`.
fn fill(pixels: &[u8], len: usize) -> Vec<u8> {
    if pixels.is_empty() {
        return vec![0; len];
    }
    pixels.iter().copied().cycle().take(len).collect()
}

/// The documented rule for a valid geometry.
fn expected_geometry(len: usize, w: usize, h: usize, s: usize) -> Result<(), ImageError> {
    if w == 0 || h == 0 {
        return Err(ImageError::ZeroSize);
    }
    if w > MAX_DIMENSION || h > MAX_DIMENSION {
        return Err(ImageError::TooLarge);
    }
    if s < w {
        return Err(ImageError::StrideTooSmall);
    }
    let needed = s as u128 * (h as u128 - 1) + w as u128;
    if needed > len as u128 {
        return Err(ImageError::BufferTooSmall);
    }
    Ok(())
}

/// Rows and pixels come from where the geometry says, and nothing outside it is readable.
fn check_view(view: &ImageView<'_>, buffer: &[u8]) {
    let (w, h, s) = (view.width(), view.height(), view.stride());
    for y in [0, h / 2, h - 1] {
        let row = view.row(y);
        assert_eq!(row, &buffer[y * s..y * s + w], "row {y}");
        for x in [0, w / 2, w - 1] {
            assert_eq!(view.get(x, y), Some(buffer[y * s + x]));
        }
        assert_eq!(view.get(w, y), None);
    }
    assert!(view.row(h).is_empty());
    assert_eq!(view.get(0, h), None);
    assert!(view.same_size(&ImageView::new(buffer, w, h, s).unwrap()));
}

/// Builds a pyramid of `levels` levels in storage `delta` bytes off the documented length.
fn check_pyramid(view: ImageView<'_>, levels: usize, delta: i8) {
    let (w, h) = (view.width(), view.height());
    // Deep pyramids of huge frames are slow to build and add nothing over shallow ones.
    if w * h > 1 << 15 {
        return;
    }
    let needed = pyramid_storage_len(w, h, levels.min(MAX_LEVEL));
    let len = needed.saturating_add_signed(isize::from(delta));
    let mut storage = vec![0xA5u8; len];
    let result = Pyramid::build(view, levels, &mut storage);
    let expected = if levels > MAX_LEVEL {
        Err(ConfigError {
            field: "max_level",
            bound: Bound::AtMost(7),
        })
    } else if len < needed {
        Err(ConfigError {
            field: "storage",
            bound: Bound::MinLen(needed),
        })
    } else {
        Ok(levels)
    };
    assert_eq!(result.map(|p| p.max_level()), expected);
    let Ok(pyramid) = result else {
        return;
    };
    let (lo, hi) = grey_range(&view);
    let mut built = Vec::new();
    for level in 0..=levels {
        let image = pyramid.level(level).expect("every level up to max_level");
        assert_eq!(
            (image.width(), image.height()),
            (level_size(w, level), level_size(h, level)),
            "level {level} size"
        );
        let (l, u) = grey_range(&image);
        assert!(lo <= l && u <= hi, "level {level} leaves the frame's range");
        built.push(pixels(&image));
    }
    assert!(pyramid.level(levels + 1).is_none());
    assert_eq!(pyramid.base().row(0), view.row(0));
    let again = Pyramid::from_storage(view, levels, &storage).expect("storage was accepted once");
    for (level, pixels_built) in built.iter().enumerate() {
        let image = again.level(level).expect("every level up to max_level");
        assert_eq!(&pixels(&image), pixels_built, "level {level} read back");
    }
}

/// Every pixel, row by row.
fn pixels(image: &ImageView<'_>) -> Vec<u8> {
    (0..image.height())
        .flat_map(|y| image.row(y).iter().copied())
        .collect()
}

/// The darkest and brightest pixel.
fn grey_range(image: &ImageView<'_>) -> (u8, u8) {
    (0..image.height())
        .flat_map(|y| image.row(y).iter().copied())
        .fold((u8::MAX, u8::MIN), |(lo, hi), p| (lo.min(p), hi.max(p)))
}
