//! Numbers as the report prints them.

use core::fmt;

/// A Q16 length printed in pixels with three decimals, sign always shown.
#[derive(Debug, Clone, Copy)]
pub struct Px(pub i32);

impl fmt::Display for Px {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let bits = i64::from(self.0);
        let sign = if bits < 0 { '-' } else { '+' };
        let millipx = (bits.abs() * 1000 + 32768) >> 16;
        write!(f, "{sign}{}.{:03}", millipx / 1000, millipx % 1000)
    }
}

/// Thousandths of a pixel as Q16 raw bits, rounded.
pub const fn millipx_to_q16(millipx: i32) -> i32 {
    let scaled = millipx as i64 * 65536;
    let rounded = if scaled < 0 {
        (scaled - 500) / 1000
    } else {
        (scaled + 500) / 1000
    };
    rounded as i32
}

/// A number printed with three decimals.
pub struct Milli(pub f32);

impl fmt::Display for Milli {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.3}", self.0)
    }
}

/// A number printed with six decimals (radians).
pub struct Micro(pub f32);

impl fmt::Display for Micro {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6}", self.0)
    }
}
