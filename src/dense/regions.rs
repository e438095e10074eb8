//! Connected regions of a node mask, as bounding boxes in pixels: [`find_boxes`].
//!
//! Each region is found by a flood fill whose stack is a caller-owned slice of one `u32` per
//! node: a node is pushed at most once, since it leaves the `unvisited` set as it is pushed.

use super::grid::{GridLayout, GridNode, NEIGHBOURS};
use super::mask::{mask_contains, mask_set, words_for};
use crate::q16::{Point, Q16};
use crate::ConfigError;

/// A moving region: the pixels its nodes' cells cover in the previous frame, and its flow.
///
/// ```
/// use kestrel::dense::MotionBox;
/// use kestrel::Point;
/// let b = MotionBox { x: 16, y: 8, w: 24, h: 16, nodes: 6, mean_flow: Point::from_f32(2.6, -1.0) };
/// assert_eq!(b.area(), 384);
/// let moved = b.in_next_frame(160, 120);
/// assert_eq!((moved.x, moved.y, moved.w, moved.h), (19, 7, 24, 16));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionBox {
    /// Leftmost column, px.
    pub x: u16,
    /// Top row, px.
    pub y: u16,
    /// Width, px.
    pub w: u16,
    /// Height, px.
    pub h: u16,
    /// Nodes in the region.
    pub nodes: u32,
    /// Mean flow of the region's nodes that have one (measured or filled), px: the region's
    /// own motion plus the camera's.
    pub mean_flow: Point,
}

impl MotionBox {
    /// Area in pixels.
    ///
    /// ```
    /// # use kestrel::dense::MotionBox;
    /// assert_eq!(MotionBox { w: 3, h: 5, ..MotionBox::default() }.area(), 15);
    /// ```
    pub fn area(&self) -> u32 {
        // Below 2^32: both factors are below 2^16.
        u32::from(self.w).saturating_mul(u32::from(self.h))
    }

    /// Pixels this box shares with `other`.
    ///
    /// ```
    /// # use kestrel::dense::MotionBox;
    /// let a = MotionBox { x: 0, y: 0, w: 8, h: 8, ..MotionBox::default() };
    /// let b = MotionBox { x: 4, y: 6, w: 8, h: 8, ..MotionBox::default() };
    /// assert_eq!(a.overlap_area(&b), 8);
    /// assert_eq!(a.overlap_area(&MotionBox { x: 8, ..b }), 0);
    /// ```
    pub fn overlap_area(&self, other: &MotionBox) -> u32 {
        let shared = |a: u16, al: u16, b: u16, bl: u16| {
            let (a, b) = (u32::from(a), u32::from(b));
            let end = a
                .saturating_add(u32::from(al))
                .min(b.saturating_add(u32::from(bl)));
            end.saturating_sub(a.max(b))
        };
        let w = shared(self.x, self.w, other.x, other.w);
        // Below 2^32: both factors are below 2^17.
        w.saturating_mul(shared(self.y, self.h, other.y, other.h))
    }

    /// The ground between this box and `other`, px: the larger of the gaps between their
    /// column spans and between their row spans (0 when they touch or overlap).
    ///
    /// ```
    /// # use kestrel::dense::MotionBox;
    /// let a = MotionBox { x: 0, y: 0, w: 8, h: 8, ..MotionBox::default() };
    /// assert_eq!(a.gap_to(&MotionBox { x: 11, y: 2, w: 4, h: 4, ..a }), 3);
    /// assert_eq!(a.gap_to(&MotionBox { x: 4, y: 14, ..a }), 6);
    /// assert_eq!(a.gap_to(&MotionBox { x: 4, y: 4, ..a }), 0);
    /// ```
    pub fn gap_to(&self, other: &MotionBox) -> u16 {
        let gap = |a: u16, a_len: u16, b: u16, b_len: u16| {
            let (a_end, b_end) = (a.saturating_add(a_len), b.saturating_add(b_len));
            b.saturating_sub(a_end).max(a.saturating_sub(b_end))
        };
        gap(self.x, self.w, other.x, other.w).max(gap(self.y, self.h, other.y, other.h))
    }

    /// The box around this one and `other`, with this one's nodes and flow.
    ///
    /// ```
    /// # use kestrel::dense::MotionBox;
    /// # use kestrel::Point;
    /// let flow = |x| Point::from_f32(x, 0.0);
    /// let torso = MotionBox { x: 40, y: 20, w: 10, h: 16, nodes: 5, mean_flow: flow(2.0) };
    /// let leg = MotionBox { x: 38, y: 36, w: 6, h: 12, nodes: 2, mean_flow: flow(4.0) };
    /// let body = torso.union(&leg);
    /// assert_eq!((body.x, body.y, body.w, body.h), (38, 20, 12, 28));
    /// assert_eq!((body.nodes, body.mean_flow), (5, torso.mean_flow));
    /// ```
    pub fn union(&self, other: &MotionBox) -> MotionBox {
        let (x0, y0) = (self.x.min(other.x), self.y.min(other.y));
        let x1 = self
            .x
            .saturating_add(self.w)
            .max(other.x.saturating_add(other.w));
        let y1 = self
            .y
            .saturating_add(self.h)
            .max(other.y.saturating_add(other.h));
        MotionBox {
            x: x0,
            y: y0,
            w: x1.saturating_sub(x0),
            h: y1.saturating_sub(y0),
            ..*self
        }
    }

    /// The box moved by its mean flow (rounded to whole pixels) and clipped to a `width` x
    /// `height` frame: where the region is in the next frame.
    ///
    /// ```
    /// # use kestrel::dense::MotionBox;
    /// # use kestrel::Point;
    /// let b = MotionBox { x: 0, y: 0, w: 8, h: 8, nodes: 1, mean_flow: Point::from_f32(-3.0, 0.0) };
    /// let moved = b.in_next_frame(64, 64);
    /// assert_eq!((moved.x, moved.w), (0, 5));
    /// ```
    pub fn in_next_frame(&self, width: usize, height: usize) -> MotionBox {
        let (x, w) = shift_span(self.x, self.w, self.mean_flow.x, width);
        let (y, h) = shift_span(self.y, self.h, self.mean_flow.y, height);
        MotionBox {
            x,
            y,
            w,
            h,
            ..*self
        }
    }
}

/// `start..start + len` moved by `shift` rounded, clipped to `0..size`.
fn shift_span(start: u16, len: u16, shift: Q16, size: usize) -> (u16, u16) {
    let shift = shift.saturating_round().to_num::<i32>();
    let size = i32::try_from(size).unwrap_or(i32::MAX);
    let lo = i32::from(start).saturating_add(shift).clamp(0, size);
    let hi = i32::from(start)
        .saturating_add(i32::from(len))
        .saturating_add(shift)
        .clamp(lo, size);
    (to_u16(lo), to_u16(hi.saturating_sub(lo)))
}

fn to_u16(v: impl TryInto<u16>) -> u16 {
    v.try_into().unwrap_or(u16::MAX)
}

/// How many regions a search found and how many boxes it wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RegionCount {
    /// Regions of at least the minimum size.
    pub regions: usize,
    /// Boxes written: the largest regions, at most the output's length.
    pub boxes: usize,
}

/// Which regions give boxes, and how boxes are drawn around them.
///
/// ```
/// use kestrel::dense::{find_boxes, BoxRules, GridLayout, GridNode, MotionBox};
/// use kestrel::Point;
///
/// // A 4 x 4 grid of 8 px cells: a region of two nodes side by side, at (1, 1) and (2, 1).
/// let layout = GridLayout::new(32, 32, 8).unwrap();
/// let nodes = [GridNode::tracked(Point::from_f32(1.0, 0.0)); 16];
/// let mask = [0b0110_0000];
/// let find = |rules| {
///     let mut boxes = [MotionBox::default(); 1];
///     let found = find_boxes(&layout, &nodes, &mask, &mut [0], &mut [0; 16], &rules, &mut boxes);
///     let b = boxes[0];
///     (found.unwrap().boxes, (b.x, b.y, b.w, b.h))
/// };
/// // Two nodes are too few for the default's three.
/// assert_eq!(find(BoxRules::default()).0, 0);
/// // The region's cells, inset on each side; one node high, it keeps its cell's height.
/// assert_eq!(find(BoxRules { min_nodes: 2, inset: 0 }), (1, (8, 8, 16, 8)));
/// assert_eq!(find(BoxRules { min_nodes: 2, inset: 4 }), (1, (12, 8, 8, 8)));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoxRules {
    /// Area floor: regions with fewer nodes give no box. Three by default: with 9 px windows
    /// on an 8 px grid, an object of 10 px already moves a 2 x 2 block of nodes, while one or
    /// two nodes alone are more often wrong LK estimates than objects.
    pub min_nodes: u32,
    /// Pixels removed from each side of a region's cells, keeping at least one cell per side;
    /// about half the LK window (4 for the dense default of 9 px). A region one node wide can
    /// hold an object from a few pixels to a cell and a window wide, so it keeps its cell.
    pub inset: usize,
}

impl Default for BoxRules {
    fn default() -> Self {
        Self {
            min_nodes: 3,
            inset: 4,
        }
    }
}

/// Finds the 8-connected regions of `mask` with at least `rules.min_nodes` nodes and writes
/// their boxes into `boxes`, largest first (equal sizes in the raster order of their first
/// node). When there are more regions than boxes, the largest are kept.
///
/// Regions are 8-connected (a small object moving diagonally across a coarse grid often
/// touches its next node only at a corner). A region's box is its nodes' cells, clipped to the
/// frame and inset on every side ([`BoxRules::inset`]): a node whose LK window reaches into a
/// moving object picks up the object's motion, so the cells of a region overhang the object by
/// about half a window.
///
/// `unvisited` is a mask's worth of scratch, `stack` one `u32` per node ([`GridLayout::len`]);
/// a shorter `mask`, `unvisited` or `stack` is refused by name.
///
/// ```
/// use kestrel::dense::{find_boxes, BoxRules, GridLayout, GridNode, MotionBox};
/// use kestrel::Point;
///
/// // A 4 x 4 grid of 8 px cells: an L of three nodes, and one lone node.
/// let layout = GridLayout::new(32, 32, 8).unwrap();
/// let nodes = [GridNode::tracked(Point::from_f32(1.0, 0.0)); 16];
/// let mask = [0b1000_0000_0001_0011];
/// let mut boxes = [MotionBox::default(); 4];
/// let rules = BoxRules { min_nodes: 2, inset: 2 };
/// let found = find_boxes(&layout, &nodes, &mask, &mut [0], &mut [0; 16], &rules, &mut boxes).unwrap();
/// assert_eq!((found.regions, found.boxes), (1, 1));
/// assert_eq!((boxes[0].x, boxes[0].y, boxes[0].w, boxes[0].h, boxes[0].nodes), (2, 2, 12, 12, 3));
/// let short = find_boxes(&layout, &nodes, &mask, &mut [0], &mut [0; 8], &rules, &mut boxes);
/// assert_eq!(short.unwrap_err().to_string(), "stack must hold at least 16 elements");
/// ```
pub fn find_boxes(
    layout: &GridLayout,
    nodes: &[GridNode],
    mask: &[u32],
    unvisited: &mut [u32],
    stack: &mut [u32],
    rules: &BoxRules,
    boxes: &mut [MotionBox],
) -> Result<RegionCount, ConfigError> {
    let words = words_for(layout.len());
    if mask.len() < words {
        return Err(ConfigError::min_len("mask", words));
    }
    if unvisited.len() < words {
        return Err(ConfigError::min_len("unvisited", words));
    }
    if stack.len() < layout.len() {
        return Err(ConfigError::min_len("stack", layout.len()));
    }
    if let (Some(to), Some(from)) = (unvisited.get_mut(..words), mask.get(..words)) {
        to.copy_from_slice(from);
    }
    let mut found = RegionCount::default();
    for seed in 0..layout.len() {
        if !mask_contains(unvisited, seed) {
            continue;
        }
        let region = flood(layout, nodes, unvisited, stack, seed);
        if region.nodes >= rules.min_nodes {
            found.regions = found.regions.saturating_add(1);
            let found_box = region.to_box(layout, rules.inset);
            found.boxes = keep_largest(boxes, found.boxes, found_box);
        }
    }
    Ok(found)
}

/// What a flood fill gathers about one region.
struct Region {
    cols: (usize, usize),
    rows: (usize, usize),
    nodes: u32,
    flow_sum: (i64, i64),
    flows: i64,
}

impl Region {
    fn new(col: usize, row: usize) -> Self {
        Self {
            cols: (col, col),
            rows: (row, row),
            nodes: 0,
            flow_sum: (0, 0),
            flows: 0,
        }
    }

    fn add(&mut self, col: usize, row: usize, node: Option<&GridNode>) {
        self.cols = (self.cols.0.min(col), self.cols.1.max(col));
        self.rows = (self.rows.0.min(row), self.rows.1.max(row));
        self.nodes = self.nodes.saturating_add(1);
        if let Some(n) = node.filter(|n| n.has_flow()) {
            // At most 2^24 nodes of i32 flows: the sums fit an i64.
            self.flow_sum.0 = self
                .flow_sum
                .0
                .saturating_add(i64::from(n.flow.x.to_bits()));
            self.flow_sum.1 = self
                .flow_sum
                .1
                .saturating_add(i64::from(n.flow.y.to_bits()));
            self.flows = self.flows.saturating_add(1);
        }
    }

    fn to_box(&self, layout: &GridLayout, inset: usize) -> MotionBox {
        let (x, y, w, h) = layout.span_rect(self.cols.0, self.rows.0, self.cols.1, self.rows.1);
        let (x, w) = inset_span(x, w, inset, layout.cell());
        let (y, h) = inset_span(y, h, inset, layout.cell());
        // A mean of Q16 values is within their range.
        let mean = |sum: i64| {
            let mean = sum.checked_div(self.flows).unwrap_or(0);
            Q16::from_bits(i32::try_from(mean).unwrap_or_default())
        };
        MotionBox {
            x: to_u16(x),
            y: to_u16(y),
            w: to_u16(w),
            h: to_u16(h),
            nodes: self.nodes,
            mean_flow: Point::new(mean(self.flow_sum.0), mean(self.flow_sum.1)),
        }
    }
}

/// `start..start + len` with up to `inset` removed from each end, keeping at least `keep`.
///
/// The frame's edges are inset too: an object cut by the edge then loses up to `inset` px of
/// its box, but one that merely comes near the edge (and so moves the edge node) does not gain
/// a whole cell.
fn inset_span(start: usize, len: usize, inset: usize, keep: usize) -> (usize, usize) {
    let cut = inset.min(len.saturating_sub(keep) / 2);
    // cut <= len / 2.
    (
        start.saturating_add(cut),
        len.saturating_sub(cut.saturating_mul(2)),
    )
}

/// Flood-fills the region of `seed` out of `unvisited`.
fn flood(
    layout: &GridLayout,
    nodes: &[GridNode],
    unvisited: &mut [u32],
    stack: &mut [u32],
    seed: usize,
) -> Region {
    let (col, row) = layout.node(seed);
    let mut region = Region::new(col, row);
    let mut top = 0;
    push(unvisited, stack, &mut top, seed);
    while top > 0 {
        top = top.saturating_sub(1);
        let Some(index) = stack.get(top).map(|&i| i as usize) else {
            break;
        };
        let (col, row) = layout.node(index);
        region.add(col, row, nodes.get(index));
        for offset in NEIGHBOURS {
            let next = layout.neighbour(index, offset);
            if let Some(next) = next.filter(|&n| mask_contains(unvisited, n)) {
                push(unvisited, stack, &mut top, next);
            }
        }
    }
    region
}

/// Pushes `index` and removes it from `unvisited`, so no node is pushed twice and the stack
/// never needs more than one slot per node.
fn push(unvisited: &mut [u32], stack: &mut [u32], top: &mut usize, index: usize) {
    mask_set(unvisited, index, false);
    if let Some(slot) = stack.get_mut(*top) {
        // Node indices are below the grid's length, itself far below 2^32 for 4096 px frames.
        *slot = u32::try_from(index).unwrap_or(u32::MAX);
        *top = top.saturating_add(1);
    }
}

/// Inserts `new` into the first `len` boxes, kept sorted largest first (after the boxes of the
/// same size already there); drops the smallest when full. Returns the new length.
fn keep_largest(boxes: &mut [MotionBox], len: usize, new: MotionBox) -> usize {
    let len = len.min(boxes.len());
    let at = boxes
        .get(..len)
        .map_or(0, |kept| kept.partition_point(|b| b.nodes >= new.nodes));
    let grown = len.saturating_add(1).min(boxes.len());
    // Empty when the new box is smaller than every kept one and there is no room left.
    if let Some(tail) = boxes.get_mut(at..grown).filter(|t| !t.is_empty()) {
        tail.rotate_right(1);
        if let Some(slot) = tail.first_mut() {
            *slot = new;
        }
    }
    grown
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sized(nodes: u32) -> MotionBox {
        MotionBox {
            nodes,
            ..MotionBox::default()
        }
    }

    #[test]
    fn the_largest_boxes_are_kept_in_order() {
        let mut boxes = [MotionBox::default(); 3];
        let mut len = 0;
        for n in [2, 5, 3, 5, 1, 9] {
            len = keep_largest(&mut boxes, len, sized(n));
        }
        assert_eq!(len, 3);
        assert_eq!(boxes.map(|b| b.nodes), [9, 5, 5]);
        assert_eq!(keep_largest(&mut [], 0, sized(1)), 0);
    }

    #[test]
    fn diagonal_nodes_join_and_the_flow_is_averaged() {
        // 4 x 3 grid: nodes 0 and 5 touch at a corner; node 11 is alone.
        let layout = GridLayout::new(32, 24, 8).unwrap();
        let mut nodes = [GridNode::EMPTY; 12];
        nodes[0] = GridNode::tracked(Point::from_f32(1.0, 2.0));
        nodes[5] = GridNode::tracked(Point::from_f32(3.0, 0.0));
        let mask = [1 | 1 << 5 | 1 << 11];
        let mut boxes = [MotionBox::default(); 2];
        let rules = BoxRules {
            min_nodes: 1,
            inset: 0,
        };
        let found = find_boxes(
            &layout,
            &nodes,
            &mask,
            &mut [0],
            &mut [0; 12],
            &rules,
            &mut boxes,
        );
        assert_eq!(
            found,
            Ok(RegionCount {
                regions: 2,
                boxes: 2
            })
        );
        assert_eq!((boxes[0].w, boxes[0].h, boxes[0].nodes), (16, 16, 2));
        // With an inset, the one-node region keeps its whole cell.
        let rules = BoxRules {
            min_nodes: 1,
            inset: 4,
        };
        find_boxes(
            &layout,
            &nodes,
            &mask,
            &mut [0],
            &mut [0; 12],
            &rules,
            &mut boxes,
        )
        .unwrap();
        assert_eq!(
            (boxes[0].x, boxes[0].w, boxes[1].x, boxes[1].w),
            (4, 8, 24, 8)
        );
        assert_eq!(boxes[0].mean_flow.to_f32(), (2.0, 1.0));
        // The lone node has no flow: its mean is zero.
        assert_eq!((boxes[1].x, boxes[1].y, boxes[1].nodes), (24, 16, 1));
        assert_eq!(boxes[1].mean_flow, Point::default());
    }

    #[test]
    fn short_buffers_are_refused() {
        let layout = GridLayout::new(64, 64, 8).unwrap(); // 64 nodes: 2 words
        let nodes = [GridNode::EMPTY; 64];
        let run = |mask: &[u32], unvisited_len: usize, stack_len: usize, boxes_len: usize| {
            let mut boxes = [MotionBox::default(); 2];
            let (mut unvisited, mut stack) = ([0u32; 2], [0u32; 64]);
            find_boxes(
                &layout,
                &nodes,
                mask,
                &mut unvisited[..unvisited_len],
                &mut stack[..stack_len],
                &BoxRules::default(),
                &mut boxes[..boxes_len],
            )
        };
        assert_eq!(run(&[0], 2, 64, 1), Err(ConfigError::min_len("mask", 2)));
        assert_eq!(
            run(&[0; 2], 1, 64, 1),
            Err(ConfigError::min_len("unvisited", 2))
        );
        assert_eq!(
            run(&[0; 2], 2, 63, 1),
            Err(ConfigError::min_len("stack", 64))
        );
        // No room for boxes is not an error: the regions are still counted.
        assert_eq!(
            run(&[u32::MAX; 2], 2, 64, 0),
            Ok(RegionCount {
                regions: 1,
                boxes: 0
            })
        );
    }

    #[test]
    fn insets_keep_the_minimum() {
        assert_eq!(inset_span(8, 24, 4, 4), (12, 16));
        assert_eq!(inset_span(0, 16, 4, 4), (4, 8));
        assert_eq!(inset_span(8, 8, 4, 4), (10, 4));
        assert_eq!(inset_span(60, 3, 4, 4), (60, 3));
    }

    #[test]
    fn moving_a_box_clips_it_to_the_frame() {
        let b = MotionBox {
            x: 150,
            y: 2,
            w: 10,
            h: 10,
            nodes: 1,
            mean_flow: Point::from_f32(5.4, -4.6),
        };
        let moved = b.in_next_frame(160, 120);
        assert_eq!((moved.x, moved.y, moved.w, moved.h), (155, 0, 5, 7));
    }
}
