//! Frames resampled through a homography.

use crate::synth::Homography;
use crate::Frame;

/// The frame whose pixel `(x, y)` is `frame` at `source_of(x, y)`, bilinearly interpolated and
/// rounded; pixels whose source lies outside `frame` are black.
///
/// ```
/// use host_sim::stabilize::warp_bilinear;
/// use host_sim::synth::Homography;
/// use host_sim::Frame;
/// let ramp = Frame { width: 4, height: 1, data: vec![0, 100, 200, 250] };
/// let shifted = warp_bilinear(&ramp, &Homography::translation(0.5, 0.0));
/// assert_eq!(shifted.data, vec![50, 150, 225, 0]);
/// ```
pub fn warp_bilinear(frame: &Frame, source_of: &Homography) -> Frame {
    let (w, h) = (frame.width, frame.height);
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (sx, sy) = source_of.apply(x as f64, y as f64);
            data.push(sample(frame, sx, sy).unwrap_or(0));
        }
    }
    Frame {
        width: w,
        height: h,
        data,
    }
}

/// Bilinear sample at (`x`, `y`), `None` outside the pixel centres' hull (or for NaN).
fn sample(frame: &Frame, x: f64, y: f64) -> Option<u8> {
    let (w, h) = (frame.width as f64, frame.height as f64);
    let inside = (0.0..=w - 1.0).contains(&x) && (0.0..=h - 1.0).contains(&y);
    if !inside {
        return None;
    }
    // On the last row or column the second neighbour is the pixel itself, with weight 0.
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = (
        (x0 + 1).min(frame.width - 1),
        (y0 + 1).min(frame.height - 1),
    );
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |px: usize, py: usize| f64::from(frame.data[py * frame.width + px]);
    let top = at(x0, y0) + fx * (at(x1, y0) - at(x0, y0));
    let bottom = at(x0, y1) + fx * (at(x1, y1) - at(x0, y1));
    Some((top + fy * (bottom - top)).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_identity_keeps_every_pixel() {
        let frame = Frame {
            width: 5,
            height: 3,
            data: (0..15).map(|i| i * 17).collect(),
        };
        assert_eq!(warp_bilinear(&frame, &Homography::IDENTITY), frame);
    }

    #[test]
    fn sources_outside_the_frame_are_black() {
        let frame = Frame::filled(4, 4, 200);
        let moved = warp_bilinear(&frame, &Homography::translation(-1.5, 0.0));
        assert_eq!(&moved.data[..4], &[0, 0, 200, 200]);
    }
}
