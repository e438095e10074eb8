//! Independently moving objects drawn over a scene: the tracks a camera-motion estimate must
//! reject as outliers.
//!
//! An object is a rectangle of its own texture that glides back and forth across the frame
//! on a sinusoid, in frame coordinates: its motion has nothing to do with the camera's.
//!
//! A [`Mover`] makes it more like what real footage has: a walker (a head and a torso gliding,
//! arms and legs swinging about the shoulder and the hip), a blob that stretches and squashes,
//! stops and starts, a shadow on the ground. Each is drawn from the object's seed on a stream
//! of its own, so the default mover (a rigid block gliding without a stop, casting no shadow)
//! draws and renders exactly what objects did before movers existed.

use super::rng::SplitMix64;
use super::texture::{Extent, Texture};

/// The random stream an object is drawn from (the scene's texture and noise use others).
const OBJECT_STREAM: u64 = 4 << 32;
/// The random stream of an object's sides when they are given in pixels.
const SIDES_STREAM: u64 = 5 << 32;
/// The random stream of a mover's gait, stops, deformation and shadow.
const MOVER_STREAM: u64 = 6 << 32;

/// What an object's body is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Body {
    /// A rigid textured rectangle.
    #[default]
    Block,
    /// An articulated figure seen from the side, as tall as the object and 0.4 times as wide
    /// standing: a head and a torso gliding, two arms swinging about the shoulder and two legs
    /// about the hip in opposition, one stride every 16 to 32 frames of its path.
    Walker,
    /// An ellipse that stretches along one axis as it squashes along the other (its area kept),
    /// by 20 to 35% every 12 to 30 frames, its texture stretched with it.
    Blob,
}

impl Body {
    /// Every body, in the order of their names.
    pub const ALL: [Body; 3] = [Body::Block, Body::Walker, Body::Blob];

    /// The body's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Body::Block => "block",
            Body::Walker => "walker",
            Body::Blob => "blob",
        }
    }

    /// The body called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|body| body.name() == name)
    }
}

/// What an object is and how it moves besides its glide.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mover {
    /// Its body.
    pub body: Body,
    /// It stops and starts: it goes for 12 to 40 frames, stands for 8 to 24, and again (its
    /// limbs stand with it; a blob goes on deforming).
    pub stop_go: bool,
    /// It casts a shadow on the ground: its silhouette, shifted by 0.3 to 0.5 times its height
    /// in a direction drawn per object, darkening the ground to 45 to 65% of its brightness.
    pub shadow: bool,
    /// Its pace along its glide, times the usual (1; the usual pace reaches several pixels a
    /// frame, a distant walker's is a tenth of it): the glide, the stride and the stops slow
    /// down or speed up together.
    pub pace: f64,
}

impl Default for Mover {
    /// A rigid block at the usual pace, never stopping, casting no shadow.
    fn default() -> Self {
        Self {
            body: Body::Block,
            stop_go: false,
            shadow: false,
            pace: 1.0,
        }
    }
}

/// A walker's height per width, standing.
const WALKER_ASPECT: f64 = 2.5;

/// What a mover draws from its seed: when and how its parts move, and its shadow.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Gait {
    /// Frames of path time per stride, and the stride's phase at path time 0.
    stride: f64,
    stride_phase: f64,
    /// Largest leg swing either side of hanging straight, rad.
    swing: f64,
    /// Frames going and frames standing, and where in that cycle frame 0 is.
    go: f64,
    stop: f64,
    cycle_offset: f64,
    /// Frames per deformation cycle, its share and its phase.
    deform_period: f64,
    deform: f64,
    deform_phase: f64,
    /// The shadow's shift, px, and the share of the ground's light it takes away.
    shadow_shift: (f64, f64),
    shadow_darkness: f64,
}

impl Gait {
    fn draw(seed: u64, height: f64) -> Self {
        let mut rng = SplitMix64::substream(seed, MOVER_STREAM);
        let tau = std::f64::consts::TAU;
        let stride = rng.uniform(16.0, 32.0);
        let stride_phase = rng.uniform(0.0, tau);
        let swing = rng.uniform(0.35, 0.5);
        let (go, stop) = (rng.uniform(12.0, 40.0), rng.uniform(8.0, 24.0));
        let cycle_offset = rng.uniform(0.0, go + stop);
        let deform_period = rng.uniform(12.0, 30.0);
        let deform = rng.uniform(0.2, 0.35);
        let deform_phase = rng.uniform(0.0, tau);
        let (length, angle) = (rng.uniform(0.3, 0.5) * height, rng.uniform(0.0, tau));
        Self {
            stride,
            stride_phase,
            swing,
            go,
            stop,
            cycle_offset,
            deform_period,
            deform,
            deform_phase,
            shadow_shift: (length * angle.cos(), length * angle.sin()),
            shadow_darkness: rng.uniform(0.35, 0.55),
        }
    }

    /// Path time gone by at instant `t` for a mover that stops and starts: frames spent going.
    fn path_time(&self, t: f64) -> f64 {
        let cycle = self.go + self.stop;
        let gone = |s: f64| (s / cycle).floor() * self.go + s.rem_euclid(cycle).min(self.go);
        gone(t + self.cycle_offset) - gone(self.cycle_offset)
    }
}

/// A walker's parts, relative to its centre.
struct Figure {
    /// The head's centre height and radius (centred on x = 0).
    head: (f64, f64),
    /// The torso: left, top, right, bottom.
    torso: (f64, f64, f64, f64),
    /// Arms, then legs.
    limbs: [Limb; 4],
}

/// A limb: a bar hanging from `pivot`, turned by `angle` (rad, 0 straight down, positive
/// towards +x), `length` long and `half_width` either side of its axis.
#[derive(Debug, Clone, Copy)]
struct Limb {
    pivot: (f64, f64),
    angle: f64,
    length: f64,
    half_width: f64,
}

impl Limb {
    /// The limb's own coordinates of object point (`u`, `v`): across and along its axis.
    fn local(&self, u: f64, v: f64) -> (f64, f64) {
        let (sin, cos) = self.angle.sin_cos();
        let (du, dv) = (u - self.pivot.0, v - self.pivot.1);
        (du * cos - dv * sin, du * sin + dv * cos)
    }

    fn covers(&self, u: f64, v: f64) -> bool {
        let (across, along) = self.local(u, v);
        across.abs() <= self.half_width && (0.0..=self.length).contains(&along)
    }

    /// Its four corners.
    fn corners(&self) -> [(f64, f64); 4] {
        let (sin, cos) = self.angle.sin_cos();
        let (p, l, w) = (self.pivot, self.length, self.half_width);
        [(-w, 0.0), (w, 0.0), (-w, l), (w, l)].map(|(across, along)| {
            (
                p.0 + across * cos + along * sin,
                p.1 - across * sin + along * cos,
            )
        })
    }
}

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
    /// What it is, and what it drew for its parts, stops and shadow.
    mover: Mover,
    gait: Gait,
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
        Self::mover(width, height, size, Mover::default(), seed)
    }

    /// An object of `size` in a `width` x `height` frame, drawn from `seed`, that moves as
    /// `mover` says. Its glide is the same whatever the mover; a walker is as tall as the
    /// object's height (for [`GliderSize::Share`], as tall as a walker covering that share of
    /// the frame standing) and 0.4 times as wide.
    ///
    /// ```
    /// use host_sim::synth::{Body, Glider, GliderSize, Mover};
    /// let size = GliderSize::Sides(10.0, 12.0);
    /// let walker = Mover { body: Body::Walker, ..Mover::default() };
    /// let figure = Glider::mover(160, 120, size, walker, 5);
    /// let block = Glider::sized(160, 120, size, 5);
    /// assert_eq!(figure.position(7), block.position(7));
    /// assert_eq!(figure.sides().1, block.sides().1);
    /// assert!((figure.sides().0 - block.sides().1 / 2.5).abs() < 1e-12);
    /// ```
    pub fn mover(width: usize, height: usize, size: GliderSize, mover: Mover, seed: u64) -> Self {
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
        let half = match (mover.body, size) {
            (Body::Walker, GliderSize::Share(share)) => {
                let tall = (share * w * h * WALKER_ASPECT).sqrt();
                (tall / WALKER_ASPECT / 2.0, tall / 2.0)
            }
            (Body::Walker, GliderSize::Sides(..)) => (half.1 / WALKER_ASPECT, half.1),
            _ => half,
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
            mover,
            gait: Gait::draw(seed, 2.0 * half.1),
        }
    }

    /// What the object is.
    pub fn kind(&self) -> Mover {
        self.mover
    }

    /// The object's centre in frame `k`, px.
    pub fn position(&self, k: usize) -> (f64, f64) {
        self.position_at(k as f64)
    }

    /// The object's centre at instant `t`, in frame intervals from frame 0, px.
    pub fn position_at(&self, t: f64) -> (f64, f64) {
        let t = self.path_time(t);
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
        if self.mover.body == Body::Block {
            let (w, h) = self.sides();
            return (cx - self.half.0 + 0.5, cy - self.half.1 + 0.5, w, h);
        }
        // Pixel centres within the parts' extent, seen as pixel edges.
        let (left, top, right, bottom) = self.extent_at(k as f64);
        (cx + left + 0.5, cy + top + 0.5, right - left, bottom - top)
    }

    /// The box around every part at instant `t`, relative to the centre: left, top, right,
    /// bottom, px.
    fn extent_at(&self, t: f64) -> (f64, f64, f64, f64) {
        match self.mover.body {
            Body::Block => (-self.half.0, -self.half.1, self.half.0, self.half.1),
            Body::Blob => {
                let (a, b) = self.blob_axes(t);
                (-a, -b, a, b)
            }
            Body::Walker => {
                let Figure { head, torso, limbs } = self.figure(t);
                let mut extent = (
                    torso.0.min(-head.1),
                    torso.1.min(head.0 - head.1),
                    torso.2.max(head.1),
                    torso.3,
                );
                for (x, y) in limbs.iter().flat_map(Limb::corners) {
                    extent = (
                        extent.0.min(x),
                        extent.1.min(y),
                        extent.2.max(x),
                        extent.3.max(y),
                    );
                }
                extent
            }
        }
    }

    /// Path time at instant `t`: `t` itself at the usual pace unless the object stops and
    /// starts.
    fn path_time(&self, t: f64) -> f64 {
        let t = t * self.mover.pace;
        match self.mover.stop_go {
            true => self.gait.path_time(t),
            false => t,
        }
    }

    /// A walker's parts at instant `t`, relative to its centre: the limbs swing with its
    /// stride, which advances with its path time.
    fn figure(&self, t: f64) -> Figure {
        let tall = 2.0 * self.half.1;
        let g = &self.gait;
        let stride = g.stride_phase + std::f64::consts::TAU * self.path_time(t) / g.stride;
        let swing = g.swing * stride.sin();
        let limb = |pivot: f64, angle: f64, length: f64, half_width: f64| Limb {
            pivot: (0.0, pivot * tall),
            angle,
            length: length * tall,
            half_width: half_width * tall,
        };
        let half_torso = 0.13 * tall;
        Figure {
            head: (-0.41 * tall, 0.09 * tall),
            torso: (-half_torso, -0.32 * tall, half_torso, 0.06 * tall),
            limbs: [
                limb(-0.29, -0.8 * swing, 0.32, 0.04),
                limb(-0.29, 0.8 * swing, 0.32, 0.04),
                limb(0.04, swing, 0.46, 0.055),
                limb(0.04, -swing, 0.46, 0.055),
            ],
        }
    }

    /// A blob's half axes at instant `t`: one stretched as the other squashes.
    fn blob_axes(&self, t: f64) -> (f64, f64) {
        let g = &self.gait;
        let angle = g.deform_phase + std::f64::consts::TAU * t / g.deform_period;
        let stretch = 1.0 + g.deform * angle.sin();
        (self.half.0 * stretch, self.half.1 / stretch)
    }

    /// The object's grey level at (`u`, `v`) from its centre at instant `t`, if it is there.
    fn body_value(&self, t: f64, u: f64, v: f64) -> Option<f64> {
        match self.mover.body {
            Body::Block => {
                let inside = u.abs() <= self.half.0 && v.abs() <= self.half.1;
                inside.then(|| self.texture.value(u, v))
            }
            Body::Blob => {
                let (a, b) = self.blob_axes(t);
                let inside = (u / a).powi(2) + (v / b).powi(2) <= 1.0;
                inside.then(|| self.texture.value(u * self.half.0 / a, v * self.half.1 / b))
            }
            Body::Walker => {
                // A foot reaches 0.27 heights from the axis at most.
                if v.abs() > self.half.1 + 1.0 || u.abs() > 0.6 * self.half.1 + 1.0 {
                    return None;
                }
                let Figure { head, torso, limbs } = self.figure(t);
                let in_head = u.hypot(v - head.0) <= head.1;
                let in_torso = (torso.0..=torso.2).contains(&u) && (torso.1..=torso.3).contains(&v);
                if in_head || in_torso {
                    return Some(self.texture.value(u, v));
                }
                // Each limb carries its own part of the texture, as if hanging straight.
                limbs
                    .iter()
                    .enumerate()
                    .find(|(_, l)| l.covers(u, v))
                    .map(|(i, l)| {
                        let (across, along) = l.local(u, v);
                        let side = if i % 2 == 0 { -0.5 } else { 0.5 };
                        let darker = if i >= 2 { 25.0 } else { 0.0 };
                        self.texture
                            .value(across + side * self.half.0, l.pivot.1 + along)
                            - darker
                    })
            }
        }
    }

    /// The share of the ground's light left at (`x`, `y`) at instant `t` by the object's
    /// shadow: 1 where it casts none.
    pub fn light_at(&self, t: f64, x: f64, y: f64) -> f64 {
        if !self.mover.shadow {
            return 1.0;
        }
        let (cx, cy) = self.position_at(t);
        let (sx, sy) = self.gait.shadow_shift;
        match self.body_value(t, x - sx - cx, y - sy - cy) {
            Some(_) => 1.0 - self.gait.shadow_darkness,
            None => 1.0,
        }
    }

    /// How far, at most, any point of the object moves from instant `t0` to `t1`, px: its
    /// centre's travel, and its parts' own motion.
    pub fn travel(&self, t0: f64, t1: f64) -> f64 {
        let (a, b) = (self.position_at(t0), self.position_at(t1));
        let centre = (a.0 - b.0).hypot(a.1 - b.1);
        let tau = std::f64::consts::TAU;
        let g = &self.gait;
        let parts = match self.mover.body {
            Body::Block => return centre,
            // A foot swings 0.51 heights from the hip at most `swing` rad either side.
            Body::Walker => {
                let turn = tau * (self.path_time(t1) - self.path_time(t0)).abs() / g.stride;
                2.0 * self.half.1 * 0.51 * g.swing * turn
            }
            Body::Blob => {
                let turn = tau * (t1 - t0).abs() / g.deform_period;
                2.0 * self.half.0.max(self.half.1) * g.deform * turn
            }
        };
        centre + parts
    }

    /// The object's grey level at (`x`, `y`) of frame `k`, or `None` where it is not.
    pub fn value(&self, k: usize, x: f64, y: f64) -> Option<f64> {
        self.value_at(k as f64, x, y)
    }

    /// The object's grey level at (`x`, `y`) at instant `t`, or `None` where it is not.
    pub fn value_at(&self, t: f64, x: f64, y: f64) -> Option<f64> {
        let (cx, cy) = self.position_at(t);
        self.body_value(t, x - cx, y - cy)
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
