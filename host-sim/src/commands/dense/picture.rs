//! The motion overlay: a frame with its moving grid cells tinted and the boxes outlined.

use image::{Rgb, RgbImage};
use kestrel::dense::{mask_contains, GridLayout, GridNode, MotionBox};

use crate::viz::canvas::{grey, outline, tint};
use crate::Frame;

/// Tint of the cells of moving nodes.
pub const MASK_TINT: Rgb<u8> = Rgb([255, 40, 40]);
/// Outline of the boxes.
pub const BOX_COLOUR: Rgb<u8> = Rgb([40, 255, 40]);

/// The later frame of a pair with the cells of the moving nodes tinted, each moved by its node's
/// flow to where it is in that frame, and the boxes (already in that frame) outlined.
pub fn motion_overlay(
    later: &Frame,
    layout: &GridLayout,
    nodes: &[GridNode],
    mask: &[u32],
    boxes: &[MotionBox],
) -> RgbImage {
    let mut picture = grey(later, 255);
    for (index, node) in nodes.iter().enumerate().take(layout.len()) {
        if !mask_contains(mask, index) {
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
        tint(&mut picture, at, MASK_TINT, 0.45);
    }
    for b in boxes {
        let rect = (
            i64::from(b.x),
            i64::from(b.y),
            i64::from(b.w),
            i64::from(b.h),
        );
        outline(&mut picture, rect, BOX_COLOUR);
    }
    picture
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::Point;

    #[test]
    fn the_overlay_moves_cells_with_their_flow() {
        let layout = GridLayout::new(32, 16, 8).unwrap();
        let mut nodes = [GridNode::EMPTY; 8];
        nodes[1] = GridNode::tracked(Point::from_f32(3.0, 0.0));
        let picture = motion_overlay(&Frame::filled(32, 16, 0), &layout, &nodes, &[0b10], &[]);
        let pixel = |x, y| picture.get_pixel(x, y).0;
        // Cell (1, 0) covers x 8..16; moved 3 px right it covers 11..19.
        assert_eq!(pixel(10, 0), [0, 0, 0]);
        assert_ne!(pixel(11, 0), [0, 0, 0]);
        assert_ne!(pixel(18, 7), [0, 0, 0]);
        assert_eq!(pixel(19, 0), [0, 0, 0]);
    }
}
