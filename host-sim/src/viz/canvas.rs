//! An RGB picture to draw on: a dimmed grey frame as background, lines, dots, blending.

use image::{imageops, Rgb, RgbImage};

use crate::Frame;

/// How much of its brightness the grey background keeps, so that coloured marks stand out.
const BACKGROUND: u32 = 180;

/// An RGB picture with drawing in sub-pixel coordinates (the library's: origin at the centre
/// of the top-left pixel).
#[derive(Debug, Clone)]
pub struct Canvas {
    image: RgbImage,
}

impl Canvas {
    /// `frame` in grey, dimmed to `BACKGROUND`/255 of its brightness.
    pub fn from_frame(frame: &Frame) -> Self {
        let image = RgbImage::from_fn(frame.width as u32, frame.height as u32, |x, y| {
            let v = u32::from(frame.at(x as usize, y as usize)) * BACKGROUND / 255;
            Rgb([v as u8; 3])
        });
        Self { image }
    }

    /// The picture.
    pub fn image(&self) -> &RgbImage {
        &self.image
    }

    /// The picture, consumed.
    pub fn into_image(self) -> RgbImage {
        self.image
    }

    /// Blends `colour` over pixel (`x`, `y`) with opacity `alpha` (0..=1); outside pixels are
    /// ignored.
    pub fn blend(&mut self, x: i64, y: i64, colour: Rgb<u8>, alpha: f32) {
        let (Ok(x), Ok(y)) = (u32::try_from(x), u32::try_from(y)) else {
            return;
        };
        if x >= self.image.width() || y >= self.image.height() {
            return;
        }
        let alpha = alpha.clamp(0.0, 1.0);
        let pixel = self.image.get_pixel_mut(x, y);
        for (channel, &c) in pixel.0.iter_mut().zip(&colour.0) {
            let mixed = f32::from(*channel) * (1.0 - alpha) + f32::from(c) * alpha;
            *channel = mixed.round() as u8;
        }
    }

    /// A one-pixel line from `a` to `b` (Bresenham between the nearest pixels).
    pub fn line(&mut self, a: (f32, f32), b: (f32, f32), colour: Rgb<u8>, alpha: f32) {
        let (mut x, mut y) = (nearest(a.0), nearest(a.1));
        let (x1, y1) = (nearest(b.0), nearest(b.1));
        let (dx, dy) = ((x1 - x).abs(), -(y1 - y).abs());
        let (sx, sy) = ((x1 - x).signum(), (y1 - y).signum());
        let mut error = dx + dy;
        loop {
            self.blend(x, y, colour, alpha);
            if x == x1 && y == y1 {
                break;
            }
            let twice = 2 * error;
            if twice >= dy {
                error += dy;
                x += sx;
            }
            if twice <= dx {
                error += dx;
                y += sy;
            }
        }
    }

    /// A filled disc of `radius` px around `centre`, with a dark rim so that it shows on
    /// bright backgrounds too.
    pub fn dot(&mut self, centre: (f32, f32), radius: f32, colour: Rgb<u8>) {
        let reach = radius.ceil() as i64 + 1;
        let (cx, cy) = (nearest(centre.0), nearest(centre.1));
        for y in cy - reach..=cy + reach {
            for x in cx - reach..=cx + reach {
                let d = (x as f32 - centre.0).hypot(y as f32 - centre.1);
                if d <= radius {
                    self.blend(x, y, colour, 1.0);
                } else if d <= radius + 1.0 {
                    self.blend(x, y, Rgb([0, 0, 0]), 0.6);
                }
            }
        }
    }
}

/// The pixel nearest to a coordinate; far-off coordinates saturate.
fn nearest(v: f32) -> i64 {
    if v.is_finite() {
        v.round().clamp(-1e9, 1e9) as i64
    } else {
        -1
    }
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

    fn blank(width: usize, height: usize) -> Canvas {
        Canvas::from_frame(&Frame::filled(width, height, 0))
    }

    fn lit(canvas: &Canvas) -> Vec<(u32, u32)> {
        canvas
            .image()
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0 != [0, 0, 0])
            .map(|(x, y, _)| (x, y))
            .collect()
    }

    #[test]
    fn lines_join_their_ends_without_gaps() {
        let mut c = blank(10, 10);
        c.line((1.0, 1.0), (8.0, 4.0), Rgb([255, 0, 0]), 1.0);
        let pixels = lit(&c);
        assert!(pixels.contains(&(1, 1)) && pixels.contains(&(8, 4)));
        // One pixel per column for a shallow line.
        assert_eq!(pixels.len(), 8);
        let mut steep = blank(10, 10);
        steep.line((2.0, 9.0), (3.0, 0.0), Rgb([0, 255, 0]), 1.0);
        assert_eq!(lit(&steep).len(), 10);
    }

    #[test]
    fn drawing_off_the_canvas_is_clipped() {
        let mut c = blank(5, 5);
        c.line((-20.0, 2.0), (30.0, 2.0), Rgb([9, 9, 9]), 1.0);
        c.dot((f32::NAN, 1e30), 2.0, Rgb([9, 9, 9]));
        assert_eq!(lit(&c).len(), 5);
    }

    #[test]
    fn blending_mixes_colours() {
        let mut c = Canvas::from_frame(&Frame::filled(1, 1, 255));
        c.blend(0, 0, Rgb([0, 0, 0]), 0.5);
        assert_eq!(c.image().get_pixel(0, 0).0, [90, 90, 90]);
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
