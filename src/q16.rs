//! Q16.16 fixed-point positions.
//!
//! Pixel coordinates follow OpenCV: the origin is the centre of the top-left pixel, x to the right,
//! y down. A Q16.16 number resolves 1/65536 px, far below the 0.01 px that LK can deliver, and
//! holds every position of a frame up to [`crate::frame::MAX_DIMENSION`].

/// A signed Q16.16 fixed-point number (16 integer bits, 16 fractional bits).
pub type Q16 = fixed::types::I16F16;

/// A position or displacement in pixels.
///
/// ```
/// use kestrel::{Point, Q16};
/// let p = Point::from_f32(12.25, -3.5);
/// assert_eq!(p.x, Q16::from_num(12.25));
/// assert_eq!(p.to_f32(), (12.25, -3.5));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Point {
    /// Horizontal coordinate, pixels to the right of the top-left pixel centre.
    pub x: Q16,
    /// Vertical coordinate, pixels below the top-left pixel centre.
    pub y: Q16,
}

impl Point {
    /// A point from Q16 coordinates.
    ///
    /// ```
    /// use kestrel::{Point, Q16};
    /// let p = Point::new(Q16::from_num(1), Q16::from_num(2));
    /// assert_eq!(p.to_f32(), (1.0, 2.0));
    /// ```
    pub const fn new(x: Q16, y: Q16) -> Self {
        Self { x, y }
    }

    /// A point from raw Q16.16 bits (`value * 65536`).
    ///
    /// ```
    /// use kestrel::Point;
    /// assert_eq!(Point::from_bits(65536, -32768).to_f32(), (1.0, -0.5));
    /// ```
    pub const fn from_bits(x: i32, y: i32) -> Self {
        Self {
            x: Q16::from_bits(x),
            y: Q16::from_bits(y),
        }
    }

    /// A point from `f32` coordinates, saturating at the Q16 range; NaN becomes 0.
    ///
    /// ```
    /// use kestrel::Point;
    /// assert_eq!(Point::from_f32(f32::NAN, 1e9).to_f32(), (0.0, 32767.99998));
    /// ```
    pub fn from_f32(x: f32, y: f32) -> Self {
        Self {
            x: q16_from_f32(x),
            y: q16_from_f32(y),
        }
    }

    /// The coordinates as `f32`.
    ///
    /// ```
    /// use kestrel::Point;
    /// assert_eq!(Point::from_f32(0.75, 2.0).to_f32(), (0.75, 2.0));
    /// ```
    pub fn to_f32(self) -> (f32, f32) {
        (q16_to_f32(self.x), q16_to_f32(self.y))
    }
}

/// `v` as `f32`: one rounding of the raw bits to f32 (a single instruction on an FPU), then an
/// exact scaling by 2^-16; the nearest f32, as `to_num` gives it, without its software path.
#[allow(clippy::cast_precision_loss)]
pub(crate) fn q16_to_f32(v: Q16) -> f32 {
    v.to_bits() as f32 * (1.0 / 65536.0)
}

/// `v` as Q16, to the nearest step (halves away from zero), saturating at the Q16 range; NaN
/// becomes 0. A multiply, an add and one conversion on an FPU (Rust's `as` saturates and takes
/// NaN to 0), where `fixed`'s conversion from a float is a software routine.
#[allow(clippy::cast_possible_truncation)]
pub(crate) fn q16_from_f32(v: f32) -> Q16 {
    let scaled = v * 65536.0;
    let half = if scaled < 0.0 { -0.5 } else { 0.5 };
    Q16::from_bits((scaled + half) as i32)
}

#[cfg(test)]
mod tests {
    #[test]
    fn to_f32_rounds_as_fixed_does() {
        let mut bits = 0x1234_5678u32;
        for _ in 0..200_000 {
            bits ^= bits << 13;
            bits ^= bits >> 17;
            bits ^= bits << 5;
            for v in [
                bits as i32,
                (bits >> 8) as i32,
                -((bits >> 12) as i32),
                i32::MIN,
                i32::MAX,
            ] {
                let p = super::Point::from_bits(v, v);
                assert_eq!(p.to_f32().0, p.x.to_num::<f32>(), "{v}");
            }
        }
    }
}
