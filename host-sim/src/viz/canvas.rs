//! Drawing on RGB pictures with imageproc: dimmed grey frames as backgrounds, blended lines,
//! dots with a rim, tinted and outlined rectangles, contact sheets. Coordinates are the
//! library's (origin at the centre of the top-left pixel); anything off the picture is clipped.

use image::{imageops, Rgb, RgbImage};
use imageproc::drawing::{
    draw_antialiased_line_segment_mut, draw_filled_circle_mut, draw_hollow_circle_mut,
    draw_hollow_rect_mut,
};
use imageproc::pixelops::interpolate;
use imageproc::rect::Rect;

use crate::Frame;

/// `frame` in grey, its brightness scaled by `brightness`/255 (255 keeps it; less lets coloured
/// marks stand out).
pub fn grey(frame: &Frame, brightness: u32) -> RgbImage {
    RgbImage::from_fn(frame.width as u32, frame.height as u32, |x, y| {
        let v = u32::from(frame.at(x as usize, y as usize)) * brightness / 255;
        Rgb([v as u8; 3])
    })
}

/// An anti-aliased line from `a` to `b`, blended over the picture with opacity `alpha`.
pub fn line(image: &mut RgbImage, a: (f32, f32), b: (f32, f32), colour: Rgb<u8>, alpha: f32) {
    let alpha = alpha.clamp(0.0, 1.0);
    draw_antialiased_line_segment_mut(image, nearest(a), nearest(b), colour, |ink, under, w| {
        interpolate(ink, under, w * alpha)
    });
}

/// A filled disc of `radius` px (whole pixels) around `centre`, ringed in black so that it shows on
/// bright backgrounds too.
pub fn dot(image: &mut RgbImage, centre: (f32, f32), radius: f32, colour: Rgb<u8>) {
    let (centre, radius) = (nearest(centre), radius as i32);
    draw_hollow_circle_mut(image, centre, radius + 1, Rgb([0, 0, 0]));
    draw_filled_circle_mut(image, centre, radius, colour);
}

/// Blends `colour` into the rectangle (`x`, `y`, `w`, `h`) with weight `alpha` in `0..=1`.
/// imageproc fills rectangles opaquely, so the blend is done here, pixel by pixel.
pub fn tint(image: &mut RgbImage, (x, y, w, h): (i64, i64, i64, i64), colour: Rgb<u8>, alpha: f32) {
    let (width, height) = (i64::from(image.width()), i64::from(image.height()));
    for py in y.max(0)..(y + h).min(height) {
        for px in x.max(0)..(x + w).min(width) {
            let pixel = image.get_pixel_mut(px as u32, py as u32);
            *pixel = interpolate(colour, *pixel, alpha);
        }
    }
}

/// The one-pixel outline of the rectangle (`x`, `y`, `w`, `h`).
pub fn outline(image: &mut RgbImage, (x, y, w, h): (i64, i64, i64, i64), colour: Rgb<u8>) {
    if w > 0 && h > 0 {
        let at = |v: i64| v.clamp(-1 << 30, 1 << 30) as i32;
        let rect = Rect::at(at(x), at(y)).of_size(w.min(1 << 30) as u32, h.min(1 << 30) as u32);
        draw_hollow_rect_mut(image, rect, colour);
    }
}

/// The pixel nearest to a point; far-off and non-finite coordinates land far off the picture.
fn nearest((x, y): (f32, f32)) -> (i32, i32) {
    let one = |v: f32| match v.is_finite() {
        true => v.round().clamp(-1e6, 1e6) as i32,
        false => -1_000_000,
    };
    (one(x), one(y))
}

/// `images` side by side, `columns` to a row, each shrunk by `shrink` (1 keeps the size) and
/// framed by a 2 px white gap. All images must have the size of the first; an empty list gives
/// an empty picture.
pub fn contact_sheet(images: &[RgbImage], columns: usize, shrink: u32) -> RgbImage {
    const GAP: u32 = 2;
    let Some(first) = images.first() else {
        return RgbImage::new(0, 0);
    };
    let shrink = shrink.max(1);
    let (w, h) = (first.width() / shrink, first.height() / shrink);
    let columns = columns.clamp(1, images.len());
    let rows = images.len().div_ceil(columns);
    let width = columns as u32 * (w + GAP) + GAP;
    let height = rows as u32 * (h + GAP) + GAP;
    let mut sheet = RgbImage::from_pixel(width, height, Rgb([255, 255, 255]));
    for (i, image) in images.iter().enumerate() {
        let tile = imageops::thumbnail(image, w, h);
        let (col, row) = ((i % columns) as u32, (i / columns) as u32);
        let (x, y) = (GAP + col * (w + GAP), GAP + row * (h + GAP));
        imageops::replace(&mut sheet, &tile, i64::from(x), i64::from(y));
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lit(image: &RgbImage) -> Vec<(u32, u32)> {
        let dark = |p: &Rgb<u8>| p.0 == [0, 0, 0];
        let on = image.enumerate_pixels().filter(|(_, _, p)| !dark(p));
        on.map(|(x, y, _)| (x, y)).collect()
    }

    #[test]
    fn lines_reach_their_ends_and_are_clipped() {
        let mut image = RgbImage::new(10, 10);
        line(&mut image, (1.0, 1.0), (8.0, 4.0), Rgb([255, 0, 0]), 1.0);
        let pixels = lit(&image);
        assert!(pixels.contains(&(1, 1)) && pixels.contains(&(8, 4)));
        let mut off = RgbImage::new(5, 5);
        line(&mut off, (-20.0, 2.0), (30.0, 2.0), Rgb([9, 9, 9]), 1.0);
        dot(&mut off, (f32::NAN, 1e30), 2.0, Rgb([9, 9, 9]));
        assert_eq!(lit(&off).len(), 5);
    }

    #[test]
    fn tints_blend_and_outlines_are_one_pixel() {
        let mut image = grey(&Frame::filled(6, 4, 100), 255);
        tint(&mut image, (-2, -2, 4, 4), Rgb([200, 0, 100]), 0.5);
        assert_eq!(image.get_pixel(1, 1).0, [150, 50, 100]);
        assert_eq!(image.get_pixel(2, 2).0, [100, 100, 100]);
        outline(&mut image, (4, 2, 5, 5), Rgb([1, 2, 3]));
        assert_eq!(image.get_pixel(4, 3).0, [1, 2, 3]);
        assert_eq!(image.get_pixel(5, 3).0, [100, 100, 100]);
    }

    #[test]
    fn a_contact_sheet_tiles_its_images() {
        let images = vec![RgbImage::from_pixel(20, 10, Rgb([1, 2, 3])); 5];
        let sheet = contact_sheet(&images, 3, 2);
        assert_eq!((sheet.width(), sheet.height()), (3 * 12 + 2, 2 * 7 + 2));
        assert_eq!(sheet.get_pixel(2, 2).0, [1, 2, 3]);
        assert_eq!(sheet.get_pixel(0, 0).0, [255, 255, 255]);
        assert_eq!(contact_sheet(&[], 3, 2).width(), 0);
    }
}
