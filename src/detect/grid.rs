//! Grid bucketing: spread corners over the whole frame.
//!
//! Detectors return the strongest corners, which in a real scene cluster on the one textured
//! patch (a road marking, a tree line). Flow measured there alone says little about rotation and
//! breaks when that patch leaves the view. [`Grid`] splits the frame into `cols` x `rows` cells
//! and keeps at most `per_cell` corners in each, counting the points already tracked in a cell
//! against its allowance, so new corners go where tracks are missing.

use super::{sort_strongest_first, Corner};
use crate::config_error::bound_number;
use crate::q16::Point;
use crate::{Bound, ConfigError};

/// The most columns or rows a [`Grid`] may have.
pub const MAX_CELLS_PER_SIDE: usize = 32;

/// A `cols` x `rows` bucketing grid allowing `per_cell` features per cell: it spreads corners
/// over the whole frame. Detectors return the strongest corners, which in a real scene cluster
/// on one textured patch (a road marking, a tree line); flow measured there alone says little
/// about rotation and breaks when that patch leaves the view. Points already tracked in a cell
/// count against its allowance, so new corners go where tracks are missing.
///
/// ```
/// use kestrel::detect::Grid;
/// let grid = Grid { cols: 4, rows: 3, per_cell: 2 };
/// assert_eq!(grid.cell_of(160, 120, 159, 0), Some((3, 0)));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Grid {
    /// Columns of cells, `1..=MAX_CELLS_PER_SIDE`.
    pub cols: usize,
    /// Rows of cells, `1..=MAX_CELLS_PER_SIDE`.
    pub rows: usize,
    /// Features (tracked points plus new corners) allowed per cell; 0 keeps nothing.
    pub per_cell: u8,
}

impl Grid {
    /// The cell holding pixel (`x`, `y`) of a `width` x `height` frame, or `None` off the frame.
    /// Cells split the frame as evenly as integers allow.
    ///
    /// ```
    /// use kestrel::detect::Grid;
    /// let grid = Grid { cols: 3, rows: 2, per_cell: 1 };
    /// assert_eq!(grid.cell_of(90, 60, 29, 29), Some((0, 0)));
    /// assert_eq!(grid.cell_of(90, 60, 30, 30), Some((1, 1)));
    /// assert_eq!(grid.cell_of(90, 60, 90, 0), None);
    /// ```
    pub fn cell_of(
        &self,
        width: usize,
        height: usize,
        x: usize,
        y: usize,
    ) -> Option<(usize, usize)> {
        if x >= width || y >= height {
            return None;
        }
        // x < width <= 4096 and cols <= 32 in practice; checked math keeps absurd inputs safe.
        let cx = x.checked_mul(self.cols)?.checked_div(width)?;
        let cy = y.checked_mul(self.rows)?.checked_div(height)?;
        Some((cx, cy))
    }

    /// Checks the number of columns and rows; a refusal names `"cols"` or `"rows"`.
    ///
    /// ```
    /// use kestrel::detect::Grid;
    /// use kestrel::{Bound, ConfigError};
    /// assert_eq!(Grid { cols: 8, rows: 6, per_cell: 3 }.validate(), Ok(()));
    /// let refused = Grid { cols: 0, rows: 6, per_cell: 3 }.validate().unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "cols", bound: Bound::Range { min: 1, max: 32 } });
    /// assert_eq!(refused.to_string(), "cols must be 1 to 32");
    /// ```
    pub fn validate(&self) -> Result<(), ConfigError> {
        let sides = 1..=MAX_CELLS_PER_SIDE;
        let bound = Bound::Range {
            min: 1,
            max: bound_number(MAX_CELLS_PER_SIDE),
        };
        if !sides.contains(&self.cols) {
            return Err(ConfigError::new("cols", bound));
        }
        if !sides.contains(&self.rows) {
            return Err(ConfigError::new("rows", bound));
        }
        Ok(())
    }

    /// Keeps at most `per_cell` corners per cell of a `width` x `height` frame, less one for each
    /// of `tracks` in that cell, preferring the strongest. The kept corners are moved to the
    /// front of `corners`, strongest first, and their number is returned. Corners and tracks off
    /// the frame are dropped and ignored. The per-cell counts take 1 KB of stack.
    ///
    /// ```
    /// use kestrel::detect::Grid;
    /// use kestrel::detect::Corner;
    /// use kestrel::Point;
    ///
    /// // Three corners in the left half, one in the right; one track already in the left half.
    /// let mut corners = [
    ///     Corner::new(10, 10, 50),
    ///     Corner::new(20, 30, 90),
    ///     Corner::new(30, 50, 70),
    ///     Corner::new(120, 40, 10),
    /// ];
    /// let tracks = [Point::from_f32(40.0, 40.0)];
    /// let grid = Grid { cols: 2, rows: 1, per_cell: 2 };
    /// let n = grid.select(160, 120, &mut corners, &tracks).unwrap();
    /// let scores: Vec<u32> = corners[..n].iter().map(|c| c.score).collect();
    /// assert_eq!(scores, [90, 10]);
    /// ```
    pub fn select(
        &self,
        width: usize,
        height: usize,
        corners: &mut [Corner],
        tracks: &[Point],
    ) -> Result<usize, ConfigError> {
        self.validate()?;
        let mut used = [0u8; MAX_CELLS_PER_SIDE * MAX_CELLS_PER_SIDE];
        let index = |x: usize, y: usize| {
            self.cell_of(width, height, x, y)
                .map(|(cx, cy)| cy.saturating_mul(self.cols).saturating_add(cx))
        };
        for track in tracks {
            if let Some(count) = point_pixel(track)
                .and_then(|(x, y)| index(x, y))
                .and_then(|i| used.get_mut(i))
            {
                *count = count.saturating_add(1);
            }
        }

        sort_strongest_first(corners);
        let mut kept = 0usize;
        for i in 0..corners.len() {
            let Some(&corner) = corners.get(i) else {
                break;
            };
            let (x, y) = corner.pixel();
            let Some(count) = point_pixel(&corner.position)
                .and_then(|_| index(x, y))
                .and_then(|i| used.get_mut(i))
            else {
                continue;
            };
            if *count >= self.per_cell {
                continue;
            }
            *count = count.saturating_add(1);
            if let Some(slot) = corners.get_mut(kept) {
                *slot = corner;
                kept = kept.saturating_add(1);
            }
        }
        Ok(kept)
    }
}

/// The pixel holding `p`, or `None` for negative coordinates (off the frame).
fn point_pixel(p: &Point) -> Option<(usize, usize)> {
    let x = usize::try_from(p.x.to_bits() >> 16).ok()?;
    let y = usize::try_from(p.y.to_bits() >> 16).ok()?;
    Some((x, y))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_grids_are_refused() {
        let mut corners = [Corner::new(1, 1, 1)];
        let bound = Bound::Range { min: 1, max: 32 };
        for (cols, rows, field) in [
            (0, 3, "cols"),
            (3, 0, "rows"),
            (33, 1, "cols"),
            (1, 33, "rows"),
        ] {
            let grid = Grid {
                cols,
                rows,
                per_cell: 1,
            };
            assert_eq!(
                grid.select(10, 10, &mut corners, &[]),
                Err(ConfigError::new(field, bound))
            );
        }
    }

    #[test]
    fn off_frame_corners_and_tracks_are_dropped() {
        let mut corners = [
            Corner::new(200, 5, 9),
            Corner {
                position: Point::from_f32(-1.0, 5.0),
                score: 8,
            },
            Corner::new(5, 5, 1),
        ];
        let tracks = [Point::from_f32(-5.0, 5.0), Point::from_f32(500.0, 5.0)];
        let grid = Grid {
            cols: 1,
            rows: 1,
            per_cell: 5,
        };
        assert_eq!(grid.select(100, 100, &mut corners, &tracks), Ok(1));
        assert_eq!(corners[0].pixel(), (5, 5));
    }

    #[test]
    fn per_cell_zero_and_empty_frames_keep_nothing() {
        let mut corners = [Corner::new(1, 1, 1)];
        let grid = Grid {
            cols: 2,
            rows: 2,
            per_cell: 0,
        };
        assert_eq!(grid.select(10, 10, &mut corners, &[]), Ok(0));
        let grid = Grid {
            per_cell: 3,
            ..grid
        };
        assert_eq!(grid.select(0, 0, &mut corners, &[]), Ok(0));
    }
}
