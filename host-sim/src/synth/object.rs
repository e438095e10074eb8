//! Objects moving in front of the background: occluders for the tracker, targets for motion
//! detection.

use super::texture::{Extent, Texture};

/// What an object looks like.
#[derive(Debug, Clone)]
pub enum Surface {
    /// One grey level all over: nothing to track on it.
    Flat(f64),
    /// A procedural texture fixed to the object, in the object's own coordinates (origin at its
    /// centre), so that it moves rigidly with the object.
    Textured(Box<Texture>),
}

impl Surface {
    /// A seeded texture for an object of half sides `half_size`, detailed all over.
    pub fn textured(seed: u64, half_size: (f64, f64)) -> Self {
        let extent = Extent {
            left: -half_size.0,
            top: -half_size.1,
            right: half_size.0,
            bottom: half_size.1,
        };
        Surface::Textured(Box::new(Texture::without_flat_regions(seed, extent)))
    }
}

/// An axis-aligned rectangle on the scene plane, in front of the background, moving at a
/// steady velocity. Positions are scene-plane coordinates (frame 0's pixels), so the camera's
/// warp applies to the object as to the background, and its own motion comes on top.
///
/// ```
/// use host_sim::synth::{MovingObject, Surface};
/// let object = MovingObject {
///     half_size: (10.0, 5.0),
///     start: (50.0, 40.0),
///     velocity: (2.0, 0.0),
///     surface: Surface::Flat(200.0),
/// };
/// assert_eq!(object.centre(3.0), (56.0, 40.0));
/// assert!(object.covers(3.0, 65.0, 44.0) && !object.covers(0.0, 65.0, 44.0));
/// assert_eq!(object.carry((51.0, 41.0), 1.0, 4.0), (57.0, 41.0));
/// ```
#[derive(Debug, Clone)]
pub struct MovingObject {
    /// Half width and half height, px.
    pub half_size: (f64, f64),
    /// Centre at frame 0.
    pub start: (f64, f64),
    /// Motion of the centre per frame, px.
    pub velocity: (f64, f64),
    /// Its looks.
    pub surface: Surface,
}

impl MovingObject {
    /// The centre at frame `frame`.
    pub fn centre(&self, frame: f64) -> (f64, f64) {
        (
            self.start.0 + self.velocity.0 * frame,
            self.start.1 + self.velocity.1 * frame,
        )
    }

    /// How much of the plane point (`u`, `v`) the object hides at frame `frame`: 1 inside, 0
    /// outside, a ramp one pixel wide across its edge (a sharp lens, as for the texture's
    /// shapes).
    pub fn coverage(&self, frame: f64, u: f64, v: f64) -> f64 {
        (0.5 + self.inside_by(frame, u, v)).clamp(0.0, 1.0)
    }

    /// How far the plane point (`u`, `v`) lies inside the object's edge at frame `frame`, px
    /// along the nearer axis; negative outside.
    pub fn inside_by(&self, frame: f64, u: f64, v: f64) -> f64 {
        let (a, b) = self.local(frame, u, v);
        (self.half_size.0 - a.abs()).min(self.half_size.1 - b.abs())
    }

    /// True when the plane point (`u`, `v`) lies inside the object's edge at frame `frame`.
    pub fn covers(&self, frame: f64, u: f64, v: f64) -> bool {
        self.coverage(frame, u, v) >= 0.5
    }

    /// The object's grey level at the plane point (`u`, `v`) at frame `frame` (as if it covered
    /// it).
    pub fn value(&self, frame: f64, u: f64, v: f64) -> f64 {
        match &self.surface {
            Surface::Flat(grey) => *grey,
            Surface::Textured(texture) => {
                let (a, b) = self.local(frame, u, v);
                texture.value(a, b)
            }
        }
    }

    /// Where the object's point at plane position `point` in frame `from` is in frame `to`.
    pub fn carry(&self, point: (f64, f64), from: f64, to: f64) -> (f64, f64) {
        let elapsed = to - from;
        (
            point.0 + self.velocity.0 * elapsed,
            point.1 + self.velocity.1 * elapsed,
        )
    }

    /// The plane point in the object's own coordinates at frame `frame`.
    fn local(&self, frame: f64, u: f64, v: f64) -> (f64, f64) {
        let (cx, cy) = self.centre(frame);
        (u - cx, v - cy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_edge_is_a_one_pixel_ramp() {
        let object = MovingObject {
            half_size: (4.0, 4.0),
            start: (0.0, 0.0),
            velocity: (0.0, 0.0),
            surface: Surface::Flat(0.0),
        };
        assert_eq!(object.coverage(0.0, 3.0, 0.0), 1.0);
        assert_eq!(object.coverage(0.0, 4.0, 0.0), 0.5);
        assert_eq!(object.coverage(0.0, 4.25, -1.0), 0.25);
        assert_eq!(object.coverage(0.0, 0.0, 5.0), 0.0);
        assert_eq!(object.inside_by(0.0, 1.0, -2.5), 1.5);
        assert_eq!(object.inside_by(0.0, 7.0, 0.0), -3.0);
    }

    #[test]
    fn a_textured_surface_moves_with_the_object() {
        let object = MovingObject {
            half_size: (20.0, 10.0),
            start: (30.0, 30.0),
            velocity: (1.5, -0.5),
            surface: Surface::textured(3, (20.0, 10.0)),
        };
        let (u, v) = (33.0, 27.5);
        let (u2, v2) = object.carry((u, v), 0.0, 4.0);
        assert_eq!(object.value(0.0, u, v), object.value(4.0, u2, v2));
        assert_ne!(object.value(0.0, u, v), object.value(4.0, u, v));
    }
}
