//! Moving objects in front of a scene: textured rectangles with a position per frame.
//!
//! A [`MovingObject`] is a rectangle carrying its own texture (so LK can track it), moving on
//! the scene's plane: a car on the ground seen from a drone, a person seen from a mast. Its
//! path bounces between the edges of a rectangle of the plane, so it stays near the view for
//! any number of frames. The camera sees the plane, objects included, through its warp: the image motion
//! of an object is the camera's plus its own. [`ObjectScene`] renders a [`Scene`] with the
//! objects, area-sampled like the scene so their edges do not alias; [`ObjectSequence`] does so
//! along a [`CameraPath`] and knows every object's true box in every frame.
//!
//! ```
//! use host_sim::synth::objects::{BoxPx, MovingObject, ObjectSequence};
//! use host_sim::synth::{CameraPath, Scene, SceneSpec};
//! let scene = Scene::new(SceneSpec::new(64, 48, 3));
//! let view = BoxPx { x: 0.0, y: 0.0, w: 64.0, h: 48.0 };
//! let ball = MovingObject::new(7, (12.0, 10.0), (20.0, 20.0), (2.0, -1.0), view);
//! let sequence = ObjectSequence::new(scene, vec![ball], CameraPath::still((32.0, 24.0)), 3);
//! assert_eq!(sequence.frame(2).data.len(), 64 * 48);
//! assert_eq!(sequence.boxes(2)[0].x, 24.0);
//! // Seen by a camera panning 1 px right per frame, the object moves 3 px right per frame.
//! let pan = CameraPath { pan: (1.0, 0.0), ..CameraPath::still((32.0, 24.0)) };
//! let ball = sequence.objects()[0].clone();
//! let panned = ObjectSequence::new(Scene::new(SceneSpec::new(64, 48, 3)), vec![ball], pan, 3);
//! assert!((panned.boxes(2)[0].x - 26.0).abs() < 1e-9);
//! ```

use super::homography::Homography;
use super::render::{area_sample, Exposure, Lighting};
use super::rng::SplitMix64;
use super::scene::{Scene, SceneSpec};
use super::sequence::CameraPath;
use super::texture::value_noise;
use crate::Frame;
use kestrel::dense::MotionBox;

/// An axis-aligned box in pixels: `x..x + w` by `y..y + h` (pixel edges, so a box from 0 to
/// 10 covers pixels 0 to 9).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxPx {
    /// Left edge.
    pub x: f64,
    /// Top edge.
    pub y: f64,
    /// Width.
    pub w: f64,
    /// Height.
    pub h: f64,
}

impl From<&MotionBox> for BoxPx {
    /// A detector's box in pixels.
    ///
    /// ```
    /// use host_sim::synth::objects::BoxPx;
    /// use kestrel::dense::MotionBox;
    /// let found = MotionBox { x: 8, y: 16, w: 24, h: 12, ..MotionBox::default() };
    /// assert_eq!(BoxPx::from(&found), BoxPx { x: 8.0, y: 16.0, w: 24.0, h: 12.0 });
    /// ```
    fn from(b: &MotionBox) -> Self {
        BoxPx {
            x: f64::from(b.x),
            y: f64::from(b.y),
            w: f64::from(b.w),
            h: f64::from(b.h),
        }
    }
}

/// Matches `found` boxes to `truth` boxes overlapping by at least `min_iou`, best overlaps
/// first, each at most once: which truth boxes and which found boxes were matched.
///
/// ```
/// use host_sim::synth::objects::{match_boxes, BoxPx};
/// let b = |x: f64| BoxPx { x, y: 0.0, w: 10.0, h: 10.0 };
/// // Two found boxes on the first object: the closer one takes it, the other is false.
/// let (truth_hit, found_hit) = match_boxes(&[b(0.0), b(50.0)], &[b(4.0), b(1.0)], 0.3);
/// assert_eq!((truth_hit, found_hit), (vec![true, false], vec![false, true]));
/// ```
pub fn match_boxes(truth: &[BoxPx], found: &[BoxPx], min_iou: f64) -> (Vec<bool>, Vec<bool>) {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (t, object) in truth.iter().enumerate() {
        for (d, b) in found.iter().enumerate() {
            let iou = b.iou(object);
            if iou >= min_iou {
                pairs.push((iou, t, d));
            }
        }
    }
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
    let (mut truth_hit, mut found_hit) = (vec![false; truth.len()], vec![false; found.len()]);
    for (_, t, d) in pairs {
        if !truth_hit[t] && !found_hit[d] {
            (truth_hit[t], found_hit[d]) = (true, true);
        }
    }
    (truth_hit, found_hit)
}

impl BoxPx {
    /// The part inside a `width` x `height` frame (possibly empty).
    pub fn clip(&self, width: usize, height: usize) -> BoxPx {
        let x0 = self.x.clamp(0.0, width as f64);
        let y0 = self.y.clamp(0.0, height as f64);
        let x1 = (self.x + self.w).clamp(x0, width as f64);
        let y1 = (self.y + self.h).clamp(y0, height as f64);
        BoxPx {
            x: x0,
            y: y0,
            w: x1 - x0,
            h: y1 - y0,
        }
    }

    /// Area, px².
    pub fn area(&self) -> f64 {
        self.w.max(0.0) * self.h.max(0.0)
    }

    /// Intersection over union with `other`; 0 when both are empty.
    ///
    /// ```
    /// use host_sim::synth::objects::BoxPx;
    /// let a = BoxPx { x: 0.0, y: 0.0, w: 10.0, h: 10.0 };
    /// let b = BoxPx { x: 5.0, y: 0.0, w: 10.0, h: 10.0 };
    /// assert!((a.iou(&b) - 50.0 / 150.0).abs() < 1e-12);
    /// ```
    pub fn iou(&self, other: &BoxPx) -> f64 {
        let w = (self.x + self.w).min(other.x + other.w) - self.x.max(other.x);
        let h = (self.y + self.h).min(other.y + other.h) - self.y.max(other.y);
        let overlap = w.max(0.0) * h.max(0.0);
        let union = self.area() + other.area() - overlap;
        if union > 0.0 {
            overlap / union
        } else {
            0.0
        }
    }

    fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.x && x < self.x + self.w && y >= self.y && y < self.y + self.h
    }
}

/// A textured rectangle moving at a constant speed on the scene's plane, bouncing off the edges
/// of a rectangle of it. Plane coordinates are frame 0's pixel coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct MovingObject {
    /// Seed of the object's texture.
    pub seed: u64,
    /// Width and height, px.
    pub size: (f64, f64),
    /// Top-left corner on the plane in frame 0, px (pixel edges).
    pub start: (f64, f64),
    /// Displacement on the plane per frame, px; (0, 0) for an object that stands still.
    pub velocity: (f64, f64),
    /// The rectangle of the plane the object bounces in.
    pub area: BoxPx,
    /// Mean grey level of the texture.
    pub base: f64,
}

/// Value-noise octaves of an object's texture: (wavelength px, amplitude grey levels).
const OBJECT_OCTAVES: [(f64, f64); 2] = [(6.0, 55.0), (2.5, 25.0)];

impl MovingObject {
    /// An object of `size` px starting at `start` (top-left) and moving `velocity` px per
    /// frame inside `area`, textured by `seed`.
    pub fn new(
        seed: u64,
        size: (f64, f64),
        start: (f64, f64),
        velocity: (f64, f64),
        area: BoxPx,
    ) -> Self {
        let base = SplitMix64::new(seed).uniform(70.0, 180.0);
        Self {
            seed,
            size,
            start,
            velocity,
            area,
            base,
        }
    }

    /// True when the object moves.
    pub fn moves(&self) -> bool {
        self.velocity != (0.0, 0.0)
    }

    /// Its rectangle on the plane at frame `k`: the straight path folded back at the edges of
    /// its area, so the rectangle stays inside the area when it starts inside.
    pub fn box_at(&self, k: usize) -> BoxPx {
        let fold = |start: f64, step: f64, size: f64, low: f64, room: f64| {
            low + bounce(start - low + step * k as f64, (room - size).max(0.0))
        };
        let a = &self.area;
        BoxPx {
            x: fold(self.start.0, self.velocity.0, self.size.0, a.x, a.w),
            y: fold(self.start.1, self.velocity.1, self.size.1, a.y, a.h),
            w: self.size.0,
            h: self.size.1,
        }
    }

    /// The texture's grey level at (`u`, `v`) px from the object's top-left corner.
    fn value(&self, u: f64, v: f64) -> f64 {
        let detail: f64 = OBJECT_OCTAVES
            .iter()
            .enumerate()
            .map(|(i, &(wavelength, amplitude))| {
                let seed = self.seed.wrapping_add(i as u64);
                amplitude * (2.0 * value_noise(seed, u / wavelength, v / wavelength) - 1.0)
            })
            .sum();
        self.base + detail
    }
}

/// `p` reflected into `[0, limit]`, as a ball bouncing between two walls.
fn bounce(p: f64, limit: f64) -> f64 {
    if limit <= 0.0 {
        return 0.0;
    }
    let period = 2.0 * limit;
    let t = p.rem_euclid(period);
    if t <= limit {
        t
    } else {
        period - t
    }
}

/// How [`scatter_objects`] draws objects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectSpec {
    /// Moving objects.
    pub moving: usize,
    /// Objects that stand still (they must not be reported as moving).
    pub still: usize,
    /// Smallest and largest side, px.
    pub sizes: (f64, f64),
    /// Smallest and largest speed, px per frame.
    pub speeds: (f64, f64),
    /// Least distance between any two objects in every frame, px.
    pub gap: f64,
}

/// Objects drawn from `seed`, bouncing inside `area`, that never come closer than `spec.gap`
/// to each other during `frames` frames; moving ones first. Gives up on an object after a
/// thousand draws, so a crowded spec returns fewer objects rather than never returning.
pub fn scatter_objects(
    seed: u64,
    spec: &ObjectSpec,
    area: BoxPx,
    frames: usize,
) -> Vec<MovingObject> {
    let mut rng = SplitMix64::substream(seed, 7);
    let mut objects: Vec<MovingObject> = Vec::new();
    for index in 0..spec.moving + spec.still {
        for _ in 0..1000 {
            let size = (
                rng.uniform(spec.sizes.0, spec.sizes.1),
                rng.uniform(spec.sizes.0, spec.sizes.1),
            );
            let start = (
                area.x + rng.uniform(0.0, (area.w - size.0).max(0.0)),
                area.y + rng.uniform(0.0, (area.h - size.1).max(0.0)),
            );
            let (speed, angle) = (
                rng.uniform(spec.speeds.0, spec.speeds.1),
                rng.uniform(0.0, core::f64::consts::TAU),
            );
            let velocity = if index < spec.moving {
                (speed * angle.cos(), speed * angle.sin())
            } else {
                (0.0, 0.0)
            };
            let candidate = MovingObject::new(rng.next_u64(), size, start, velocity, area);
            let apart = (0..frames).all(|k| {
                let b = grown(candidate.box_at(k), spec.gap);
                objects.iter().all(|o| b.iou(&o.box_at(k)) == 0.0)
            });
            if apart {
                objects.push(candidate);
                break;
            }
        }
    }
    objects
}

/// The scenes the motion tests and benchmarks use, so that both measure the same thing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scenario {
    /// A still camera over four objects of 10 to 40 px moving 1 to 3 px per frame anywhere in
    /// the frame, and one object standing still (which must not be reported).
    StillCamera,
    /// A camera panning (1.5, -0.8) px, rolling 0.4 degrees and zooming 0.6% per frame over
    /// eight targets of 10 to 25 px moving 1.5 to 3 px per frame on the ground, inside frame
    /// 0's view less 24 px on every side.
    MovingCamera,
    /// The camera of [`Scenario::MovingCamera`] over three targets of 10 to 12 px at 160 px of
    /// width (sizes and speeds grow with the width: 20 to 24 px at 320), moving 1.5 to 3 px
    /// per frame at 160 px.
    SmallTargets,
    /// The camera of [`Scenario::SmallTargets`] over the ground alone: nothing moves but the
    /// camera, so every box is false.
    StillGround,
}

impl Scenario {
    /// The scenario's `frames` frames of `width` x `height` drawn from `seed`, with sensor
    /// noise of 1.5 grey levels; objects stay at least 24 px (three 8 px grid cells) apart.
    pub fn sequence(self, width: usize, height: usize, frames: usize, seed: u64) -> ObjectSequence {
        let centre = (width as f64 / 2.0, height as f64 / 2.0);
        let (spec, camera, margin) = match self {
            Scenario::StillCamera => {
                let spec = ObjectSpec {
                    moving: 4,
                    still: 1,
                    sizes: (10.0, 40.0),
                    speeds: (1.0, 3.0),
                    gap: 24.0,
                };
                (spec, CameraPath::still(centre), 0.0)
            }
            Scenario::MovingCamera => {
                let spec = ObjectSpec {
                    moving: 8,
                    still: 0,
                    sizes: (10.0, 25.0),
                    speeds: (1.5, 3.0),
                    gap: 24.0,
                };
                let camera = CameraPath {
                    pan: (1.5, -0.8),
                    rotation: 0.4f64.to_radians(),
                    zoom: 1.006,
                    centre,
                };
                (spec, camera, 24.0)
            }
            Scenario::SmallTargets | Scenario::StillGround => {
                let scale = width as f64 / 160.0;
                let spec = ObjectSpec {
                    moving: if self == Scenario::StillGround { 0 } else { 3 },
                    still: 0,
                    sizes: (10.0 * scale, 12.0 * scale),
                    speeds: (1.5 * scale, 3.0 * scale),
                    gap: 24.0 * scale,
                };
                let camera = CameraPath {
                    pan: (1.5 * scale, -0.8 * scale),
                    rotation: 0.4f64.to_radians(),
                    zoom: 1.006,
                    centre,
                };
                (spec, camera, 24.0 * scale)
            }
        };
        let area = BoxPx {
            x: margin,
            y: margin,
            w: width as f64 - 2.0 * margin,
            h: height as f64 - 2.0 * margin,
        };
        let objects = scatter_objects(seed, &spec, area, frames);
        let scene = Scene::new(SceneSpec::new(width, height, seed).with_noise(1.5));
        ObjectSequence::new(scene, objects, camera, frames)
    }
}

/// The bounding box of plane rectangle `b` seen through `warp`.
fn seen_through(warp: &Homography, b: &BoxPx) -> BoxPx {
    // Edges to pixel-centre coordinates and back: the warp acts on the latter.
    let corners = [
        (b.x, b.y),
        (b.x + b.w, b.y),
        (b.x, b.y + b.h),
        (b.x + b.w, b.y + b.h),
    ]
    .map(|(ex, ey)| warp.apply(ex - 0.5, ey - 0.5))
    .map(|(x, y)| (x + 0.5, y + 0.5));
    let (mut x0, mut y0) = (f64::INFINITY, f64::INFINITY);
    let (mut x1, mut y1) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (x, y) in corners {
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    BoxPx {
        x: x0,
        y: y0,
        w: x1 - x0,
        h: y1 - y0,
    }
}

/// `b` grown by `margin` on every side.
fn grown(b: BoxPx, margin: f64) -> BoxPx {
    BoxPx {
        x: b.x - margin,
        y: b.y - margin,
        w: b.w + 2.0 * margin,
        h: b.h + 2.0 * margin,
    }
}

/// A scene with objects in front of it.
#[derive(Debug, Clone)]
pub struct ObjectScene {
    /// The background.
    pub scene: Scene,
    /// The objects, back to front.
    pub objects: Vec<MovingObject>,
}

impl ObjectScene {
    /// Frame `k`: the background through `warp`, the objects where they are in frame `k`,
    /// lit by `lighting`, with the scene's sensor noise for frame `k`.
    ///
    /// Panics if `warp` is singular.
    pub fn render(&self, warp: &Homography, lighting: Lighting, k: usize) -> Frame {
        let spec = &self.scene.spec;
        let (w, h) = (spec.width, spec.height);
        let inverse = warp.inverse().expect("a camera warp is invertible");
        let boxes: Vec<BoxPx> = self.objects.iter().map(|o| o.box_at(k)).collect();
        let radiance = area_sample(w, h, spec.supersample, |x, y| {
            let (u, v) = inverse.apply(x, y);
            // Pixel centres are integers, so pixel edges sit at half-integers.
            let (eu, ev) = (u + 0.5, v + 0.5);
            let front = self
                .objects
                .iter()
                .zip(&boxes)
                .rev()
                .find(|(_, b)| b.contains(eu, ev));
            match front {
                Some((object, b)) => object.value(eu - b.x, ev - b.y),
                None => self.scene.ground(u, v),
            }
        });
        let exposure = Exposure {
            lighting,
            noise_sigma: spec.noise_sigma,
            noise_seed: SplitMix64::substream(spec.seed, 1 << 33 | k as u64).next_u64(),
        };
        exposure.develop(w, h, &radiance)
    }
}

/// A camera moving along a path over a scene with moving objects.
#[derive(Debug, Clone)]
pub struct ObjectSequence {
    scene: ObjectScene,
    path: CameraPath,
    len: usize,
}

impl ObjectSequence {
    /// `len` frames of `scene` with `objects`, the camera along `path`.
    pub fn new(scene: Scene, objects: Vec<MovingObject>, path: CameraPath, len: usize) -> Self {
        Self {
            scene: ObjectScene { scene, objects },
            path,
            len,
        }
    }

    /// The number of frames.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True for a sequence without frames.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The objects.
    pub fn objects(&self) -> &[MovingObject] {
        &self.scene.objects
    }

    /// Frame width and height, px.
    pub fn size(&self) -> (usize, usize) {
        (self.scene.scene.spec.width, self.scene.scene.spec.height)
    }

    /// The camera's warp from frame 0 to frame `k` (of the background).
    pub fn homography(&self, k: usize) -> Homography {
        self.path.homography(k)
    }

    /// Frame `k`.
    pub fn frame(&self, k: usize) -> Frame {
        self.scene
            .render(&self.homography(k), Lighting::UNCHANGED, k)
    }

    /// Every object's box in frame `k`, in object order: the bounding box of its rectangle as
    /// the camera sees it, not clipped to the frame.
    pub fn boxes(&self, k: usize) -> Vec<BoxPx> {
        let warp = self.homography(k);
        self.scene
            .objects
            .iter()
            .map(|o| seen_through(&warp, &o.box_at(k)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_bounce_inside_the_frame() {
        let area = BoxPx {
            x: 2.0,
            y: 0.0,
            w: 62.0,
            h: 120.0,
        };
        let object = MovingObject::new(1, (10.0, 20.0), (5.0, 90.0), (7.0, 3.0), area);
        for k in 0..200 {
            let b = object.box_at(k);
            assert!(b.x >= 2.0 && b.x + b.w <= 64.0, "{k}: {b:?}");
            assert!(b.y >= 0.0 && b.y + b.h <= 120.0, "{k}: {b:?}");
        }
        assert_eq!(object.box_at(1).x, 12.0);
        // x: 5 + 7 k reaches the limit 54 between frames 7 and 8 and comes back.
        assert_eq!(object.box_at(8).x, 108.0 - 61.0);
    }

    #[test]
    fn a_turning_camera_sees_a_larger_bounding_box() {
        let turn = Homography::rotation(0.1, (0.0, 0.0));
        let b = seen_through(
            &turn,
            &BoxPx {
                x: 10.5,
                y: 10.5,
                w: 10.0,
                h: 10.0,
            },
        );
        let (sin, cos) = 0.1f64.sin_cos();
        assert!((b.w - 10.0 * (sin + cos)).abs() < 1e-9);
    }

    #[test]
    fn objects_cover_the_background_and_move() {
        let scene = Scene::new(SceneSpec::new(48, 32, 5));
        let view = BoxPx {
            x: 0.0,
            y: 0.0,
            w: 48.0,
            h: 32.0,
        };
        let object = MovingObject::new(9, (10.0, 8.0), (4.0, 4.0), (3.0, 0.0), view);
        let still = CameraPath::still((24.0, 16.0));
        let with = ObjectSequence::new(scene.clone(), vec![object], still, 2);
        let without = ObjectSequence::new(scene, vec![], still, 2);
        let (a, b) = (with.frame(0), without.frame(0));
        // Inside the object the frames differ; far from it they are the same.
        let differ = (5..13).filter(|&x| a.at(x, 8) != b.at(x, 8)).count();
        assert!(differ >= 6);
        assert_eq!(a.at(40, 28), b.at(40, 28));
        // The object carries its texture: frame 1 at x + 3 is frame 0 at x.
        let c = with.frame(1);
        for x in 5..13 {
            assert_eq!(a.at(x, 8), c.at(x + 3, 8));
        }
    }
}
