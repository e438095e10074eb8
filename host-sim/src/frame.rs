//! Owned grey frames on the host.

use kestrel::{ImageError, ImageView};

/// An owned, tightly packed 8-bit grey frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` pixels, row by row.
    pub data: Vec<u8>,
}

impl Frame {
    /// A frame of `width` x `height` pixels, all `value`.
    pub fn filled(width: usize, height: usize, value: u8) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }

    /// The pixel at (`x`, `y`); panics outside the frame (host-side test and tooling code).
    pub fn at(&self, x: usize, y: usize) -> u8 {
        self.data[y * self.width + x]
    }

    /// A borrowed view for the library.
    pub fn view(&self) -> Result<ImageView<'_>, ImageError> {
        ImageView::packed(&self.data, self.width, self.height)
    }
}
