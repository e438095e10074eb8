//! Colour pictures of frames: an RGB canvas, and the motion overlay drawn on it.

use std::path::Path;

use kestrel::dense::grid::{GridLayout, GridNode};
use kestrel::dense::mask::contains;
use kestrel::dense::regions::MotionBox;

use crate::io::atomic::write_atomically;
use crate::io::images::encode_rgb_png;
use crate::io::OutputError;
use crate::Frame;

/// An RGB picture, three bytes per pixel, row by row.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Canvas {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// `3 * width * height` bytes.
    pub rgb: Vec<u8>,
}

/// Tint of the cells of moving nodes.
pub const MASK_TINT: [u8; 3] = [255, 40, 40];
/// Outline of the boxes.
pub const BOX_COLOUR: [u8; 3] = [40, 255, 40];

impl Canvas {
    /// A black canvas.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            rgb: vec![0; 3 * width * height],
        }
    }

    /// The grey frame in colour.
    pub fn from_grey(frame: &Frame) -> Self {
        Self {
            width: frame.width,
            height: frame.height,
            rgb: frame.data.iter().flat_map(|&g| [g, g, g]).collect(),
        }
    }

    /// The pixel at (`x`, `y`); `None` outside.
    pub fn pixel(&self, x: usize, y: usize) -> Option<[u8; 3]> {
        let i = self.offset(x, y)?;
        let p = self.rgb.get(i..i + 3)?;
        Some([p[0], p[1], p[2]])
    }

    /// Sets the pixel at (`x`, `y`); nothing outside.
    pub fn set(&mut self, x: usize, y: usize, colour: [u8; 3]) {
        if let Some(p) = self.offset(x, y).and_then(|i| self.rgb.get_mut(i..i + 3)) {
            p.copy_from_slice(&colour);
        }
    }

    /// Blends `colour` into the rectangle (`x`, `y`, `w`, `h`) with weight `alpha` in `0..=1`;
    /// the part outside the canvas is skipped.
    pub fn tint(&mut self, (x, y, w, h): (i64, i64, i64, i64), colour: [u8; 3], alpha: f32) {
        for py in y.max(0)..(y + h).min(self.height as i64) {
            for px in x.max(0)..(x + w).min(self.width as i64) {
                let (px, py) = (px as usize, py as usize);
                if let Some(old) = self.pixel(px, py) {
                    let mixed: [u8; 3] = std::array::from_fn(|c| {
                        let v = f32::from(old[c]) * (1.0 - alpha) + f32::from(colour[c]) * alpha;
                        v.round().clamp(0.0, 255.0) as u8
                    });
                    self.set(px, py, mixed);
                }
            }
        }
    }

    /// Draws the one-pixel outline of the rectangle (`x`, `y`, `w`, `h`).
    pub fn outline(&mut self, (x, y, w, h): (i64, i64, i64, i64), colour: [u8; 3]) {
        if w <= 0 || h <= 0 {
            return;
        }
        let (right, bottom) = (x + w - 1, y + h - 1);
        let mut plot = |px: i64, py: i64| {
            if let (Ok(px), Ok(py)) = (usize::try_from(px), usize::try_from(py)) {
                self.set(px, py, colour);
            }
        };
        for px in x..=right {
            plot(px, y);
            plot(px, bottom);
        }
        for py in y..=bottom {
            plot(x, py);
            plot(right, py);
        }
    }

    /// Writes the canvas to `path` as a PNG, atomically.
    pub fn write_png(&self, path: &Path) -> Result<(), OutputError> {
        let bytes = encode_rgb_png(self.width, self.height, &self.rgb)
            .map_err(|problem| OutputError::new(path, problem))?;
        write_atomically(path, &bytes)
    }

    fn offset(&self, x: usize, y: usize) -> Option<usize> {
        (x < self.width && y < self.height).then(|| 3 * (y * self.width + x))
    }
}

/// The later frame of a pair with the cells of the moving nodes tinted, each moved by its node's
/// flow to where it is in that frame, and the boxes (already in that frame) outlined.
pub fn motion_overlay(
    later: &Frame,
    layout: &GridLayout,
    nodes: &[GridNode],
    mask: &[u32],
    boxes: &[MotionBox],
) -> Canvas {
    let mut canvas = Canvas::from_grey(later);
    for (index, node) in nodes.iter().enumerate().take(layout.len()) {
        if !contains(mask, index) {
            continue;
        }
        let (col, row) = layout.node(index);
        let (x, y, w, h) = layout.cell_rect(col, row);
        let (dx, dy) = node.flow.to_f32();
        let at = (
            x as i64 + dx.round() as i64,
            y as i64 + dy.round() as i64,
            w as i64,
            h as i64,
        );
        canvas.tint(at, MASK_TINT, 0.45);
    }
    for b in boxes {
        let rect = (
            i64::from(b.x),
            i64::from(b.y),
            i64::from(b.w),
            i64::from(b.h),
        );
        canvas.outline(rect, BOX_COLOUR);
    }
    canvas
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::Point;

    #[test]
    fn tints_blend_and_outlines_stay_inside() {
        let mut canvas = Canvas::from_grey(&Frame::filled(6, 4, 100));
        canvas.tint((-2, -2, 4, 4), [200, 0, 100], 0.5);
        assert_eq!(canvas.pixel(1, 1), Some([150, 50, 100]));
        assert_eq!(canvas.pixel(2, 2), Some([100, 100, 100]));
        canvas.outline((4, 2, 5, 5), [1, 2, 3]);
        assert_eq!(canvas.pixel(4, 3), Some([1, 2, 3]));
        assert_eq!(canvas.pixel(5, 2), Some([1, 2, 3]));
        assert_eq!(canvas.pixel(5, 3), Some([100, 100, 100]));
        assert_eq!(canvas.pixel(6, 0), None);
    }

    #[test]
    fn the_overlay_moves_cells_with_their_flow() {
        let layout = GridLayout::new(32, 16, 8).unwrap();
        let mut nodes = [GridNode::EMPTY; 8];
        nodes[1] = GridNode::tracked(Point::from_f32(3.0, 0.0));
        let canvas = motion_overlay(&Frame::filled(32, 16, 0), &layout, &nodes, &[0b10], &[]);
        // Cell (1, 0) covers x 8..16; moved 3 px right it covers 11..19.
        assert_eq!(canvas.pixel(10, 0), Some([0, 0, 0]));
        assert_ne!(canvas.pixel(11, 0), Some([0, 0, 0]));
        assert_ne!(canvas.pixel(18, 7), Some([0, 0, 0]));
        assert_eq!(canvas.pixel(19, 0), Some([0, 0, 0]));
    }
}
