//! Borrowed 8-bit grey frames.
//!
//! A camera driver hands the tracker a DMA buffer; Kestrel never copies it. [`ImageView`] is a
//! checked, borrowed window onto such a buffer: width, height and a row stride that may be larger
//! than the width (padded rows, or a region of a larger frame).

/// The largest width or height Kestrel accepts.
///
/// Positions are Q16.16 numbers (`I16F16`), whose integer part holds ±32767; limiting frames to
/// 4096 px keeps every position, window and pyramid sum far inside that range.
pub const MAX_DIMENSION: usize = 4096;

/// Why a frame buffer was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImageError {
    /// Width or height is zero.
    ZeroSize,
    /// Width or height exceeds [`MAX_DIMENSION`].
    TooLarge,
    /// The stride is smaller than the width.
    StrideTooSmall,
    /// The buffer is shorter than `stride * (height - 1) + width` bytes.
    BufferTooSmall,
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ImageError::ZeroSize => "frame has zero width or height",
            ImageError::TooLarge => "frame is larger than 4096 px",
            ImageError::StrideTooSmall => "stride is smaller than the width",
            ImageError::BufferTooSmall => "buffer is too short for width, height and stride",
        })
    }
}

/// Checks a frame geometry against a buffer length and returns the bytes it spans.
const fn check_geometry(
    len: usize,
    width: usize,
    height: usize,
    stride: usize,
) -> Result<usize, ImageError> {
    if width == 0 || height == 0 {
        return Err(ImageError::ZeroSize);
    }
    if width > MAX_DIMENSION || height > MAX_DIMENSION {
        return Err(ImageError::TooLarge);
    }
    if stride < width {
        return Err(ImageError::StrideTooSmall);
    }
    if stride > len {
        // A stride longer than the whole buffer only fits a single row.
        if height == 1 && width <= len {
            return Ok(width);
        }
        return Err(ImageError::BufferTooSmall);
    }
    let needed = match stride.checked_mul(height.saturating_sub(1)) {
        Some(rows) => rows.checked_add(width),
        None => None,
    };
    match needed {
        Some(needed) if needed <= len => Ok(needed),
        _ => Err(ImageError::BufferTooSmall),
    }
}

/// A borrowed 8-bit grey image: `height` rows of `width` pixels, rows `stride` bytes apart.
///
/// ```
/// use kestrel::ImageView;
/// let pixels = [0u8; 8 * 6];
/// let frame = ImageView::new(&pixels, 8, 6, 8).unwrap();
/// assert_eq!((frame.width(), frame.height()), (8, 6));
/// assert_eq!(frame.row(5).len(), 8);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a> {
    data: &'a [u8],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a> ImageView<'a> {
    /// Wraps `data` as a `width` x `height` image whose rows start `stride` bytes apart.
    ///
    /// ```
    /// use kestrel::{ImageError, ImageView};
    /// let pixels = [0u8; 10];
    /// assert_eq!(ImageView::new(&pixels, 4, 3, 4).unwrap_err(), ImageError::BufferTooSmall);
    /// assert_eq!(ImageView::new(&pixels, 0, 3, 4).unwrap_err(), ImageError::ZeroSize);
    /// ```
    pub const fn new(
        data: &'a [u8],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, ImageError> {
        match check_geometry(data.len(), width, height, stride) {
            Ok(_) => Ok(Self {
                data,
                width,
                height,
                stride,
            }),
            Err(e) => Err(e),
        }
    }

    /// Wraps a tightly packed buffer (`stride == width`).
    ///
    /// ```
    /// use kestrel::ImageView;
    /// let pixels = [7u8; 12];
    /// assert_eq!(ImageView::packed(&pixels, 4, 3).unwrap().get(3, 2), Some(7));
    /// ```
    pub const fn packed(data: &'a [u8], width: usize, height: usize) -> Result<Self, ImageError> {
        Self::new(data, width, height, width)
    }

    /// Width in pixels.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// assert_eq!(ImageView::packed(&[0; 6], 3, 2).unwrap().width(), 3);
    /// ```
    pub const fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// assert_eq!(ImageView::packed(&[0; 6], 3, 2).unwrap().height(), 2);
    /// ```
    pub const fn height(&self) -> usize {
        self.height
    }

    /// Distance between the starts of two rows, in bytes.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// assert_eq!(ImageView::new(&[0; 8], 3, 2, 5).unwrap().stride(), 5);
    /// ```
    pub const fn stride(&self) -> usize {
        self.stride
    }

    /// Row `y` as a slice of exactly `width` pixels; an empty slice when `y` is outside the image.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// let frame = ImageView::new(&[1, 2, 3, 0, 4, 5, 6], 3, 2, 4).unwrap();
    /// assert_eq!(frame.row(1), &[4, 5, 6]);
    /// assert!(frame.row(2).is_empty());
    /// ```
    pub fn row(&self, y: usize) -> &'a [u8] {
        if y >= self.height {
            return &[];
        }
        // y < height and the geometry was checked when the view was made (the data holds
        // height - 1 strides and a width): neither operation can overflow and the range is
        // inside the data. A failure would give the empty row rather than a panic.
        let start = y.saturating_mul(self.stride);
        let end = start.saturating_add(self.width);
        let row = self.data.get(start..end);
        debug_assert!(row.is_some(), "row {y} outside {} bytes", self.data.len());
        row.unwrap_or(&[])
    }

    /// The pixels of the `cols` x `rows` block whose top-left pixel is (`x`, `y`), from that
    /// pixel to the block's last, rows [`ImageView::stride`] apart; `None` unless the block lies
    /// wholly in the image.
    #[inline]
    pub(crate) fn block(&self, x: isize, y: isize, cols: usize, rows: usize) -> Option<&'a [u8]> {
        let (x, y) = (usize::try_from(x).ok()?, usize::try_from(y).ok()?);
        if x.checked_add(cols)? > self.width || y.checked_add(rows)? > self.height || rows == 0 {
            return None;
        }
        // Inside the checked geometry: these cannot overflow.
        let start = y.checked_mul(self.stride)?.checked_add(x)?;
        let span = rows
            .checked_sub(1)?
            .checked_mul(self.stride)?
            .checked_add(cols)?;
        self.data.get(start..start.checked_add(span)?)
    }

    /// The pixel at (`x`, `y`), or `None` outside the image.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// let frame = ImageView::packed(&[1, 2, 3, 4], 2, 2).unwrap();
    /// assert_eq!(frame.get(1, 1), Some(4));
    /// assert_eq!(frame.get(2, 0), None);
    /// ```
    pub fn get(&self, x: usize, y: usize) -> Option<u8> {
        self.row(y).get(x).copied()
    }

    /// True when both views have the same width and height.
    ///
    /// ```
    /// # use kestrel::ImageView;
    /// let a = ImageView::packed(&[0; 6], 3, 2).unwrap();
    /// let b = ImageView::new(&[0; 8], 3, 2, 4).unwrap();
    /// assert!(a.same_size(&b));
    /// ```
    pub const fn same_size(&self, other: &ImageView<'_>) -> bool {
        self.width == other.width && self.height == other.height
    }
}

/// Logs the geometry only: the pixels would flood the log.
#[cfg(feature = "defmt")]
impl defmt::Format for ImageView<'_> {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(
            f,
            "ImageView {{ width: {=usize}, height: {=usize}, stride: {=usize} }}",
            self.width,
            self.height,
            self.stride
        );
    }
}

/// Bytes needed for a tightly packed `width` x `height` frame.
///
/// ```
/// const BYTES: usize = kestrel::frame_len(160, 120);
/// static FRAME: [u8; BYTES] = [0; BYTES];
/// assert_eq!(FRAME.len(), 19_200);
/// ```
pub const fn frame_len(width: usize, height: usize) -> usize {
    width.saturating_mul(height)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stride_longer_than_width_is_respected() {
        let data = [1, 2, 9, 3, 4, 9, 5, 6];
        let view = ImageView::new(&data, 2, 3, 3).unwrap();
        assert_eq!(view.row(0), &[1, 2]);
        assert_eq!(view.row(2), &[5, 6]);
    }

    #[test]
    fn bad_geometry_is_rejected() {
        let data = [0u8; 16];
        assert_eq!(
            ImageView::new(&data, 4, 4, 3).unwrap_err(),
            ImageError::StrideTooSmall
        );
        assert_eq!(
            ImageView::new(&data, 4, 5, 4).unwrap_err(),
            ImageError::BufferTooSmall
        );
        assert_eq!(
            ImageView::new(&data, 4097, 1, 4097).unwrap_err(),
            ImageError::TooLarge
        );
        assert_eq!(
            ImageView::new(&data, 4, 0, 4).unwrap_err(),
            ImageError::ZeroSize
        );
        assert_eq!(
            ImageView::new(&data, 2, 3, 100).unwrap_err(),
            ImageError::BufferTooSmall
        );
    }

    #[test]
    fn last_row_needs_only_width_bytes() {
        let data = [0u8; 7];
        assert!(ImageView::new(&data, 3, 2, 4).is_ok());
    }
}
