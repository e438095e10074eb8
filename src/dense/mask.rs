//! Node masks: one bit per grid node ([`mask_words`]), and morphology on the grid
//! ([`mask_close`], [`mask_open`] with a [`MaskStructure`]).

use super::grid::{grid_len, GridLayout};
use crate::ConfigError;

/// `u32` words of a mask over the grid of `cell` px cells on a `width` x `height` frame.
///
/// A node mask is a caller-owned `&mut [u32]` of this many words; bit `i % 32` of word
/// `i / 32` is node `i` (row by row, like the node slice). Bits past the last node stay clear.
/// [`mask_contains`], [`mask_set`] and [`mask_count`] read and write it; [`mask_close`] and
/// [`mask_open`] clean it.
///
/// ```
/// use kestrel::dense::mask_words;
/// static mut MASK: [u32; mask_words(160, 120, 8)] = [0; mask_words(160, 120, 8)];
/// assert_eq!(mask_words(160, 120, 8), 10); // 300 nodes
/// assert_eq!(mask_words(320, 240, 8), 38); // 1200 nodes
/// ```
pub const fn mask_words(width: usize, height: usize, cell: usize) -> usize {
    words_for(grid_len(width, height, cell))
}

/// Words holding `nodes` bits.
pub(crate) const fn words_for(nodes: usize) -> usize {
    nodes.div_ceil(32)
}

/// True when node `index` is set; false beyond the mask.
///
/// ```
/// use kestrel::dense::mask_contains;
/// let mask = [0b101, 1 << 31];
/// assert!(mask_contains(&mask, 0) && !mask_contains(&mask, 1) && mask_contains(&mask, 2));
/// assert!(mask_contains(&mask, 63) && !mask_contains(&mask, 64));
/// ```
pub fn mask_contains(mask: &[u32], index: usize) -> bool {
    mask.get(index / 32)
        .is_some_and(|word| word & (1 << (index % 32)) != 0)
}

/// Sets node `index` to `value`; nothing beyond the mask.
///
/// ```
/// use kestrel::dense::{mask_contains, mask_set};
/// let mut mask = [0u32; 2];
/// mask_set(&mut mask, 40, true);
/// assert!(mask_contains(&mask, 40));
/// mask_set(&mut mask, 40, false);
/// assert_eq!(mask, [0, 0]);
/// ```
pub fn mask_set(mask: &mut [u32], index: usize, value: bool) {
    if let Some(word) = mask.get_mut(index / 32) {
        let bit = 1 << (index % 32);
        if value {
            *word |= bit;
        } else {
            *word &= !bit;
        }
    }
}

/// Number of set nodes among the first `len`.
///
/// ```
/// use kestrel::dense::mask_count;
/// assert_eq!(mask_count(&[0b1011, 1], 33), 4);
/// assert_eq!(mask_count(&[0b1011, 1], 2), 2);
/// ```
pub fn mask_count(mask: &[u32], len: usize) -> usize {
    (0..len).filter(|&i| mask_contains(mask, i)).count()
}

/// A structuring element on the grid, for [`mask_close`] and [`mask_open`].
///
/// Closing (dilate, then erode) joins the fragments of one object and fills one-node holes;
/// opening (erode, then dilate) removes specks smaller than the structuring element. Both are
/// translation invariant, so even the 2 x 2 element has no bias towards a corner.
///
/// At the grid's edge: the erosion of an opening treats nodes beyond the grid as set, so an
/// object entering at the frame's edge is not eaten away by it; the erosion of a closing
/// treats them as clear, so a closing never grows an object into the edge row, and it keeps
/// every node that was set (a gap in the edge row itself stays open).
///
/// ```
/// use kestrel::dense::{mask_contains, mask_count, mask_open, mask_set, GridLayout, MaskStructure};
/// // A 6 x 4 grid: a 2 x 2 block inside, a lone node, and a 2 x 2 block in a corner.
/// let layout = GridLayout::new(48, 32, 8).unwrap();
/// let (inside, lone, corner) = ([7, 8, 13, 14], 10, [16, 17, 22, 23]);
/// let opened = |structure| {
///     let mut mask = [0u32];
///     for &i in inside.iter().chain(&corner).chain(&[lone]) {
///         mask_set(&mut mask, i, true);
///     }
///     mask_open(&layout, &mut mask, &mut [0], structure).unwrap();
///     mask
/// };
/// // The 2 x 2 element removes the lone node and keeps both blocks.
/// let two = opened(MaskStructure::Square2);
/// assert!(!mask_contains(&two, lone) && mask_count(&two, 24) == 8);
/// // The 3 x 3 element removes the block inside the grid too, but keeps the one in the
/// // corner: beyond the grid counts as set.
/// let three = opened(MaskStructure::Square3);
/// assert!(corner.iter().all(|&i| mask_contains(&three, i)) && mask_count(&three, 24) == 4);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MaskStructure {
    /// A 2 x 2 square: opening keeps every node that is part of a 2 x 2 block of set nodes.
    Square2,
    /// A 3 x 3 square centred on the node.
    Square3,
}

impl MaskStructure {
    /// The element's (column, row) offsets.
    fn offsets(self) -> &'static [(isize, isize)] {
        match self {
            MaskStructure::Square2 => &[(0, 0), (1, 0), (0, 1), (1, 1)],
            MaskStructure::Square3 => &[
                (-1, -1),
                (0, -1),
                (1, -1),
                (-1, 0),
                (0, 0),
                (1, 0),
                (-1, 1),
                (0, 1),
                (1, 1),
            ],
        }
    }
}

/// Closes `mask` with `structure` (dilation, then erosion); `temp` is a second mask's worth of
/// scratch.
///
/// ```
/// use kestrel::dense::{mask_close, mask_contains, GridLayout, MaskStructure};
/// // A 5 x 3 grid whose middle row has a one-node gap: closing fills it.
/// let layout = GridLayout::new(40, 24, 8).unwrap();
/// let mut mask = [0b11011 << 5];
/// mask_close(&layout, &mut mask, &mut [0], MaskStructure::Square3).unwrap();
/// assert_eq!(mask, [0b11111 << 5]);
/// ```
pub fn mask_close(
    layout: &GridLayout,
    mask: &mut [u32],
    temp: &mut [u32],
    structure: MaskStructure,
) -> Result<(), ConfigError> {
    check(layout, mask, temp)?;
    dilate(layout, mask, temp, structure);
    for index in 0..layout.len() {
        // In place: node `index` of `mask` is read once, just before it is written.
        let closed = mask_contains(mask, index) || eroded(layout, temp, index, structure, false);
        mask_set(mask, index, closed);
    }
    Ok(())
}

/// Opens `mask` with `structure` (erosion, then dilation); `temp` is a second mask's worth of
/// scratch.
///
/// ```
/// use kestrel::dense::{mask_open, GridLayout, MaskStructure};
/// // A 4 x 2 grid: a lone node on the left, a 2 x 2 block on the right.
/// let layout = GridLayout::new(32, 16, 8).unwrap();
/// let mut mask = [0b1100_1101];
/// mask_open(&layout, &mut mask, &mut [0], MaskStructure::Square2).unwrap();
/// assert_eq!(mask, [0b1100_1100]);
/// ```
pub fn mask_open(
    layout: &GridLayout,
    mask: &mut [u32],
    temp: &mut [u32],
    structure: MaskStructure,
) -> Result<(), ConfigError> {
    check(layout, mask, temp)?;
    for index in 0..layout.len() {
        mask_set(temp, index, eroded(layout, mask, index, structure, true));
    }
    dilate(layout, temp, mask, structure);
    Ok(())
}

/// Refuses a `mask` or `temp` shorter than the layout's [`mask_words`], by name.
fn check(layout: &GridLayout, mask: &[u32], temp: &[u32]) -> Result<(), ConfigError> {
    let words = words_for(layout.len());
    if mask.len() < words {
        return Err(ConfigError::min_len("mask", words));
    }
    if temp.len() < words {
        return Err(ConfigError::min_len("temp", words));
    }
    Ok(())
}

/// `dst(p) = OR over b of src(p - b)`, nodes beyond the grid clear.
fn dilate(layout: &GridLayout, src: &[u32], dst: &mut [u32], structure: MaskStructure) {
    for index in 0..layout.len() {
        let hit = structure.offsets().iter().any(|&(dc, dr)| {
            let mirrored = (dc.saturating_neg(), dr.saturating_neg());
            neighbour(layout, src, index, mirrored).unwrap_or(false)
        });
        mask_set(dst, index, hit);
    }
}

/// `AND over b of src(p + b)` at node `index`, nodes beyond the grid reading as `outside`.
fn eroded(
    layout: &GridLayout,
    src: &[u32],
    index: usize,
    structure: MaskStructure,
    outside: bool,
) -> bool {
    structure
        .offsets()
        .iter()
        .all(|&offset| neighbour(layout, src, index, offset).unwrap_or(outside))
}

/// The bit of the node `offset` (columns, rows) away from node `index`; `None` off the grid.
fn neighbour(
    layout: &GridLayout,
    mask: &[u32],
    index: usize,
    offset: (isize, isize),
) -> Option<bool> {
    layout
        .neighbour(index, offset)
        .map(|i| mask_contains(mask, i))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mask from rows of `#` (set) and `.` (clear).
    fn mask_of(rows: &[&str]) -> (GridLayout, [u32; 4]) {
        let (cols, n) = (rows[0].len(), rows.len());
        let layout = GridLayout::new(cols * 4, n * 4, 4).unwrap();
        let mut mask = [0u32; 4];
        for (r, line) in rows.iter().enumerate() {
            for (c, ch) in line.chars().enumerate() {
                mask_set(&mut mask, r * cols + c, ch == '#');
            }
        }
        (layout, mask)
    }

    #[test]
    fn opening_with_3x3_removes_anything_thinner_than_three() {
        let (layout, mut mask) =
            mask_of(&["........", ".###..#.", ".###.##.", ".###....", "........"]);
        let (_, expected) = mask_of(&["........", ".###....", ".###....", ".###....", "........"]);
        mask_open(&layout, &mut mask, &mut [0; 4], MaskStructure::Square3).unwrap();
        assert_eq!(mask, expected);
    }

    #[test]
    fn closing_joins_fragments_without_growing_into_the_edge() {
        let (layout, mut mask) = mask_of(&["##.##...", "#...#...", "##.##...", "........"]);
        let (_, expected) = mask_of(&["##.##...", "#####...", "#####...", "........"]);
        mask_close(&layout, &mut mask, &mut [0; 4], MaskStructure::Square3).unwrap();
        assert_eq!(mask, expected);
    }

    #[test]
    fn short_masks_are_refused() {
        let layout = GridLayout::new(64, 64, 4).unwrap(); // 256 nodes, 8 words
        let mut mask = [0u32; 8];
        assert_eq!(
            mask_close(&layout, &mut mask, &mut [0; 7], MaskStructure::Square2),
            Err(ConfigError::min_len("temp", 8))
        );
        assert_eq!(
            mask_open(&layout, &mut mask[..7], &mut [0; 8], MaskStructure::Square2),
            Err(ConfigError::min_len("mask", 8))
        );
    }
}
