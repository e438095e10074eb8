//! Labelled pixels joined into outlines by a flood fill.
//!
//! An outline is 4-connected object pixels whose flows agree within a pixel: two objects that
//! share a region but not a pixel, or whose flows differ, are outlined apart.

use super::area::Area;
use super::OUTLINE_MAX_FLOWS;

/// The high bit of a label: its pixel was pushed by a flood fill.
pub(super) const VISITED: u16 = 1 << 15;

/// What a flood fill gathers about one outline: its extent in the area, pixels, and the
/// pixels that chose each flow.
pub(super) struct Outline {
    pub cols: (usize, usize),
    pub rows: (usize, usize),
    pub pixels: usize,
    pub votes: [usize; OUTLINE_MAX_FLOWS],
}

impl Outline {
    /// An outline of no pixels yet, its extent at (`col`, `row`).
    fn at(col: usize, row: usize) -> Self {
        Self {
            cols: (col, col),
            rows: (row, row),
            pixels: 0,
            votes: [0; OUTLINE_MAX_FLOWS],
        }
    }

    /// Adds the pixel at (`col`, `row`), labelled `label` (its flow's index + 1).
    fn take(&mut self, col: usize, row: usize, label: u16) {
        self.cols = (self.cols.0.min(col), self.cols.1.max(col));
        self.rows = (self.rows.0.min(row), self.rows.1.max(row));
        self.pixels += 1;
        if let Some(votes) = self.votes.get_mut(usize::from(label).saturating_sub(1)) {
            *votes += 1;
        }
    }
}

/// Fills the outline of pixel `seed`: 4-connected labelled pixels whose flows join
/// (`joined`, from [`super::flows::Flows::joined`]). Marks its pixels [`VISITED`] in `labels`;
/// `stack` holds the pixels to visit.
pub(super) fn flood(
    area: &Area,
    joined: &[u8; OUTLINE_MAX_FLOWS],
    labels: &mut [u16],
    stack: &mut [u16],
    seed: usize,
) -> Outline {
    let mut outline = Outline::at(seed % area.w, seed / area.w);
    let mut top = 0usize;
    mark(labels, stack, &mut top, seed);
    while top > 0 {
        top -= 1;
        let Some(at) = stack.get(top).map(|&i| usize::from(i)) else {
            break;
        };
        let label = labels.get(at).map_or(0, |&l| l & !VISITED);
        let (col, row) = (at % area.w, at / area.w);
        outline.take(col, row, label);
        let joins = joined
            .get(usize::from(label).saturating_sub(1))
            .copied()
            .unwrap_or(0);
        let mut visit = |next: usize| {
            let other = labels.get(next).copied().unwrap_or(0);
            let free = other != 0 && other & VISITED == 0;
            if free && joins & (1 << (other - 1)) != 0 {
                mark(labels, stack, &mut top, next);
            }
        };
        if col > 0 {
            visit(at - 1);
        }
        if col + 1 < area.w {
            visit(at + 1);
        }
        if row > 0 {
            visit(at - area.w);
        }
        if row + 1 < area.h {
            visit(at + area.w);
        }
    }
    outline
}

/// Marks pixel `at` visited and pushes it: no pixel is pushed twice, so the stack never needs
/// more than one slot per pixel.
fn mark(labels: &mut [u16], stack: &mut [u16], top: &mut usize, at: usize) {
    if let Some(label) = labels.get_mut(at) {
        *label |= VISITED;
    }
    if let Some(slot) = stack.get_mut(*top) {
        // Below OUTLINE_MAX_SIDE^2 < 2^16.
        *slot = at as u16;
        *top += 1;
    }
}
