//! Independently moving objects drawn over a scene: the tracks a camera-motion estimate must
//! reject as outliers.
//!
//! An object is a rectangle of its own texture that glides back and forth across the frame
//! on a sinusoid, in frame coordinates: its motion has nothing to do with the camera's.

use super::rng::SplitMix64;
use super::texture::{Extent, Texture};

/// The random stream an object is drawn from (the scene's texture and noise use others).
const OBJECT_STREAM: u64 = 4 << 32;

/// A textured rectangle moving across the frame.
#[derive(Debug, Clone)]
pub struct Glider {
    texture: Texture,
    /// Half width and half height, px.
    half: (f64, f64),
    /// Centre about which it moves, px.
    centre: (f64, f64),
    /// Largest excursion from the centre along x and y, px.
    swing: (f64, f64),
    /// Radians of the sinusoid per frame, and its phase at frame 0.
    rate: f64,
    phase: f64,
}

impl Glider {
    /// An object covering `share` of a `width` x `height` frame, drawn from `seed`.
    pub fn random(width: usize, height: usize, share: f64, seed: u64) -> Self {
        let mut rng = SplitMix64::substream(seed, OBJECT_STREAM);
        let (w, h) = (width as f64, height as f64);
        let aspect = rng.uniform(0.6, 1.6);
        let area = share * w * h;
        let half = ((area * aspect).sqrt() / 2.0, (area / aspect).sqrt() / 2.0);
        let centre = (rng.uniform(0.3 * w, 0.7 * w), rng.uniform(0.3 * h, 0.7 * h));
        let extent = Extent {
            left: -half.0,
            top: -half.1,
            right: half.0,
            bottom: half.1,
        };
        Self {
            texture: Texture::random(rng.next_u64(), extent),
            half,
            centre,
            swing: (rng.uniform(0.1, 0.25) * w, rng.uniform(0.1, 0.25) * h),
            rate: rng.uniform(0.08, 0.2),
            phase: rng.uniform(0.0, std::f64::consts::TAU),
        }
    }

    /// The object's centre in frame `k`, px.
    pub fn position(&self, k: usize) -> (f64, f64) {
        let angle = self.phase + self.rate * k as f64;
        (
            self.centre.0 + self.swing.0 * angle.sin(),
            self.centre.1 + self.swing.1 * (1.3 * angle).cos(),
        )
    }

    /// The object's grey level at (`x`, `y`) of frame `k`, or `None` where it is not.
    pub fn value(&self, k: usize, x: f64, y: f64) -> Option<f64> {
        let (cx, cy) = self.position(k);
        let (u, v) = (x - cx, y - cy);
        let inside = u.abs() <= self.half.0 && v.abs() <= self.half.1;
        inside.then(|| self.texture.value(u, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn objects_cover_their_share_and_move() {
        let object = Glider::random(160, 120, 0.1, 7);
        let covered = (0..120)
            .flat_map(|y| (0..160).map(move |x| (x, y)))
            .filter(|&(x, y)| object.value(0, f64::from(x), f64::from(y)).is_some())
            .count();
        let share = covered as f64 / (160.0 * 120.0);
        assert!((0.07..0.11).contains(&share), "{share}");
        let (a, b) = (object.position(0), object.position(1));
        assert!((a.0 - b.0).hypot(a.1 - b.1) > 1.0);
    }
}
