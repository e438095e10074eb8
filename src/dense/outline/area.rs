//! The pixels of a candidate that are searched, at level 0 and on level 1.

use super::super::regions::MotionBox;
use crate::frame::ImageView;

/// The pixels of one candidate searched, in the previous frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Area {
    pub x: usize,
    pub y: usize,
    pub w: usize,
    pub h: usize,
}

impl Area {
    /// The candidate `b` grown by `margin`, clipped to the pixels whose 3 x 3 neighbourhood is
    /// inside `frame`; `None` when it is wider or higher than `side`, the scratch's.
    pub fn around(
        b: &MotionBox,
        frame: &ImageView<'_>,
        margin: usize,
        side: usize,
    ) -> Option<Self> {
        let span = |start: u16, len: u16, size: usize| {
            let lo = usize::from(start).saturating_sub(margin).max(1);
            let hi = usize::from(start)
                .saturating_add(usize::from(len))
                .saturating_add(margin)
                .min(size.saturating_sub(1));
            (lo, hi.saturating_sub(lo))
        };
        let (x, w) = span(b.x, b.w, frame.width());
        let (y, h) = span(b.y, b.h, frame.height());
        let fits = (1..=side).contains(&w) && (1..=side).contains(&h);
        fits.then_some(Self { x, y, w, h })
    }

    /// The area on pyramid level 1 (`level1`): half of it, clipped, like it, to the pixels
    /// whose 3 x 3 neighbourhood is inside.
    pub fn halved(&self, level1: &ImageView<'_>) -> Self {
        Self {
            x: (self.x / 2).max(1),
            y: (self.y / 2).max(1),
            w: self
                .w
                .div_ceil(2)
                .min(level1.width().saturating_sub(self.x / 2 + 1)),
            h: self
                .h
                .div_ceil(2)
                .min(level1.height().saturating_sub(self.y / 2 + 1)),
        }
    }

    /// Its pixels.
    pub fn pixels(&self) -> usize {
        self.w * self.h
    }

    /// True when pixel (`x`, `y`) lies in it.
    pub fn contains(&self, x: usize, y: usize) -> bool {
        (self.x..self.x + self.w).contains(&x) && (self.y..self.y + self.h).contains(&y)
    }
}
