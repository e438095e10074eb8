//! Independently moving objects drawn over a scene: the tracks a camera-motion estimate must
//! reject as outliers.
//!
//! An object is a rectangle of its own texture that glides back and forth across the frame
//! on a sinusoid, in frame coordinates: its motion has nothing to do with the camera's.

use super::rng::SplitMix64;
use super::texture::{Extent, Texture};

/// The random stream an object is drawn from (the scene's texture and noise use others).
const OBJECT_STREAM: u64 = 4 << 32;
/// The random stream of an object's sides when they are given in pixels.
const SIDES_STREAM: u64 = 5 << 32;

/// How large an object is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GliderSize {
    /// Covering this share of the frame, with an aspect ratio between 0.6 and 1.6, textured
    /// like the ground (nearly flat in places).
    Share(f64),
    /// Each side drawn between these two lengths, px, textured all over (no flat regions), so
    /// that a small object is never blank.
    Sides(f64, f64),
}

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
        Self::sized(width, height, GliderSize::Share(share), seed)
    }

    /// An object of `size` in a `width` x `height` frame, drawn from `seed`. Its path is the
    /// same whatever its size: only the size and the texture's kind depend on `size`.
    ///
    /// ```
    /// use host_sim::synth::{Glider, GliderSize};
    /// let small = Glider::sized(160, 120, GliderSize::Sides(10.0, 12.0), 5);
    /// let large = Glider::sized(160, 120, GliderSize::Share(0.12), 5);
    /// let (w, h) = small.sides();
    /// assert!((10.0..=12.0).contains(&w) && (10.0..=12.0).contains(&h));
    /// assert_eq!(small.position(7), large.position(7));
    /// ```
    pub fn sized(width: usize, height: usize, size: GliderSize, seed: u64) -> Self {
        let mut rng = SplitMix64::substream(seed, OBJECT_STREAM);
        let (w, h) = (width as f64, height as f64);
        let aspect = rng.uniform(0.6, 1.6);
        let half = match size {
            GliderSize::Share(share) => {
                let area = share * w * h;
                ((area * aspect).sqrt() / 2.0, (area / aspect).sqrt() / 2.0)
            }
            GliderSize::Sides(low, high) => {
                let mut sides = SplitMix64::substream(seed, SIDES_STREAM);
                (
                    sides.uniform(low, high) / 2.0,
                    sides.uniform(low, high) / 2.0,
                )
            }
        };
        let centre = (rng.uniform(0.3 * w, 0.7 * w), rng.uniform(0.3 * h, 0.7 * h));
        let extent = Extent {
            left: -half.0,
            top: -half.1,
            right: half.0,
            bottom: half.1,
        };
        let texture = match size {
            GliderSize::Share(_) => Texture::random(rng.next_u64(), extent),
            GliderSize::Sides(..) => Texture::without_flat_regions(rng.next_u64(), extent),
        };
        Self {
            texture,
            half,
            centre,
            swing: (rng.uniform(0.1, 0.25) * w, rng.uniform(0.1, 0.25) * h),
            rate: rng.uniform(0.08, 0.2),
            phase: rng.uniform(0.0, std::f64::consts::TAU),
        }
    }

    /// The object's centre in frame `k`, px.
    pub fn position(&self, k: usize) -> (f64, f64) {
        self.position_at(k as f64)
    }

    /// The object's centre at instant `t`, in frame intervals from frame 0, px.
    pub fn position_at(&self, t: f64) -> (f64, f64) {
        let angle = self.phase + self.rate * t;
        (
            self.centre.0 + self.swing.0 * angle.sin(),
            self.centre.1 + self.swing.1 * (1.3 * angle).cos(),
        )
    }

    /// Width and height, px.
    pub fn sides(&self) -> (f64, f64) {
        (2.0 * self.half.0, 2.0 * self.half.1)
    }

    /// The object's box in frame `k`: left and top pixel edges, width and height, px (pixel
    /// column `c` spans the edges `c` to `c + 1`, so the box compares directly with the
    /// whole-pixel boxes of `host-sim motion`). The object covers the pixel centres within
    /// half a side of its centre.
    ///
    /// ```
    /// use host_sim::synth::{Glider, GliderSize};
    /// let object = Glider::sized(160, 120, GliderSize::Sides(10.0, 10.0), 2);
    /// let (cx, cy) = object.position(3);
    /// assert_eq!(object.box_at(3), (cx - 4.5, cy - 4.5, 10.0, 10.0));
    /// ```
    pub fn box_at(&self, k: usize) -> (f64, f64, f64, f64) {
        let (cx, cy) = self.position(k);
        let (w, h) = self.sides();
        (cx - self.half.0 + 0.5, cy - self.half.1 + 0.5, w, h)
    }

    /// The object's grey level at (`x`, `y`) of frame `k`, or `None` where it is not.
    pub fn value(&self, k: usize, x: f64, y: f64) -> Option<f64> {
        self.value_at(k as f64, x, y)
    }

    /// The object's grey level at (`x`, `y`) at instant `t`, or `None` where it is not.
    pub fn value_at(&self, t: f64, x: f64, y: f64) -> Option<f64> {
        let (cx, cy) = self.position_at(t);
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
