//! A camera flying over textured ground: seeded camera paths with exact frame-to-frame
//! homographies and exact gyro rates.
//!
//! The camera looks straight down at a plane one unit away (frame 0's camera frame is the world
//! frame: x right, y down the image, z along the optical axis; the ground is `n·X = 1`). Frame
//! `k` has orientation `R_k` (its axes in the world) and centre `C_k`, and sees ground point
//! `X` at `K R_kᵀ (X - C_k)`, so frame 0 maps to frame `k` by the plane homography
//! `H_k = K R_kᵀ (I - C_k nᵀ) K⁻¹`. Every path but `shake` turns at a constant body rate and
//! moves at a constant velocity; `shake` hovers, drifting slowly, with a random tremor of the
//! orientation in every frame (the case video stabilization is for).
//!
//! The camera model is the library's default: square pixels, principal point at the frame
//! centre, a 60 degree horizontal field of view.

use super::camera::{Camera, Shot, Subject};
use super::glider::{Body, Glider, GliderSize, Mover};
use super::homography::Homography;
use super::photo::Photo;
use super::rng::SplitMix64;
use super::rotation::{mul, rotation, transpose, Mat3};
use super::scene::{Scene, SceneSpec};
use super::texture::Extent;
use crate::Frame;

/// The kinds of camera motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlightPath {
    /// Translation parallel to the ground: the image shifts.
    Pan,
    /// Turning about the optical axis while drifting: the image turns.
    Yaw,
    /// Moving towards or away from the ground while drifting: the image zooms.
    Climb,
    /// A tilted ground plane, turning and moving along every axis: a full homography.
    Perspective,
    /// Turning about every axis without moving: what a gyro alone predicts.
    Rotation,
    /// Hovering with a slow drift and a random tremor of the orientation in every frame.
    Shake,
    /// Not moving at all: a camera on a mast or a tripod.
    Still,
}

impl FlightPath {
    /// Every path, in the order of their names.
    pub const ALL: [FlightPath; 7] = [
        FlightPath::Pan,
        FlightPath::Yaw,
        FlightPath::Climb,
        FlightPath::Perspective,
        FlightPath::Rotation,
        FlightPath::Shake,
        FlightPath::Still,
    ];

    /// The path's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            FlightPath::Pan => "pan",
            FlightPath::Yaw => "yaw",
            FlightPath::Climb => "climb",
            FlightPath::Perspective => "perspective",
            FlightPath::Rotation => "rotation",
            FlightPath::Shake => "shake",
            FlightPath::Still => "still",
        }
    }

    /// The path called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|path| path.name() == name)
    }
}

/// Largest tremor of the `shake` path per axis and frame, rad.
const TREMOR: f64 = 0.01;
/// The random streams of the path's parameters and of the tremor in each frame (the scene's
/// texture and noise use others).
const PATH_STREAM: u64 = 2 << 32;
const TREMOR_STREAM: u64 = 3 << 32;

/// A seeded camera flight for `width` x `height` frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Flight {
    path: FlightPath,
    /// Intrinsics and their inverse.
    k: Mat3,
    k_inv: Mat3,
    /// Unit normal of the ground, world frame (the ground is `normal·X = 1`).
    normal: [f64; 3],
    /// Body rate, camera axes, rad per frame.
    rate: [f64; 3],
    /// Camera centre velocity, world frame, ground distances per frame.
    velocity: [f64; 3],
    /// Seed of the tremor (`shake` only).
    seed: u64,
}

impl Flight {
    /// The flight along `path` drawn from `seed`, for frames of `width` x `height` px.
    pub fn new(path: FlightPath, width: usize, height: usize, seed: u64) -> Self {
        let focal = width as f64 / 2.0 / (std::f64::consts::PI / 6.0).tan();
        let (cx, cy) = ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0);
        let k = [[focal, 0.0, cx], [0.0, focal, cy], [0.0, 0.0, 1.0]];
        let k_inv = [
            [1.0 / focal, 0.0, -cx / focal],
            [0.0, 1.0 / focal, -cy / focal],
            [0.0, 0.0, 1.0],
        ];
        let mut rng = SplitMix64::substream(seed, PATH_STREAM);
        let mut signed = |low: f64, high: f64| {
            let magnitude = rng.uniform(low, high);
            if rng.below(2) == 0 {
                magnitude
            } else {
                -magnitude
            }
        };
        let level = [0.0, 0.0, 1.0];
        let (normal, rate, velocity) = match path {
            FlightPath::Pan => {
                let v = [signed(0.005, 0.02), signed(0.005, 0.02), 0.0];
                (level, [0.0; 3], v)
            }
            FlightPath::Yaw => {
                let w = [0.0, 0.0, signed(0.015, 0.04)];
                (level, w, [signed(0.0, 0.005), signed(0.0, 0.005), 0.0])
            }
            FlightPath::Climb => {
                let v = [signed(0.0, 0.005), signed(0.0, 0.005), signed(0.005, 0.01)];
                (level, [0.0; 3], v)
            }
            FlightPath::Perspective => {
                let (nx, ny) = (signed(0.2, 0.4), signed(0.2, 0.4));
                let norm = (nx * nx + ny * ny + 1.0).sqrt();
                let w = [signed(0.0, 0.006), signed(0.0, 0.006), signed(0.0, 0.01)];
                let v = [signed(0.0, 0.01), signed(0.0, 0.01), signed(0.0, 0.005)];
                ([nx / norm, ny / norm, 1.0 / norm], w, v)
            }
            FlightPath::Rotation => {
                let w = [signed(0.01, 0.04), signed(0.01, 0.04), signed(0.01, 0.04)];
                (level, w, [0.0; 3])
            }
            FlightPath::Shake => {
                let v = [signed(0.0, 0.003), signed(0.0, 0.003), 0.0];
                (level, [0.0; 3], v)
            }
            FlightPath::Still => (level, [0.0; 3], [0.0; 3]),
        };
        Self {
            path,
            k,
            k_inv,
            normal,
            rate,
            velocity,
            seed,
        }
    }

    /// The principal point, px: the frame centre.
    ///
    /// ```
    /// use host_sim::synth::{Flight, FlightPath};
    /// assert_eq!(Flight::new(FlightPath::Pan, 160, 120, 1).principal_point(), (79.5, 59.5));
    /// ```
    pub fn principal_point(&self) -> (f64, f64) {
        (self.k[0][2], self.k[1][2])
    }

    /// The path flown.
    pub fn path(&self) -> FlightPath {
        self.path
    }

    /// The warp from frame 0 to frame `k`: where each pixel of frame 0 appears in frame `k`.
    pub fn homography(&self, k: usize) -> Homography {
        self.homography_at(k as f64)
    }

    /// The warp from frame 0 to the view at instant `t`, in frame intervals from frame 0 (frame
    /// `k` is seen at `t = k`): the flight is continuous, for a camera that exposes over an
    /// interval or reads its rows one after the other.
    pub fn homography_at(&self, t: f64) -> Homography {
        let (r, c) = (self.orientation(t), self.centre(t));
        let n = self.normal;
        let plane: Mat3 = std::array::from_fn(|i| {
            std::array::from_fn(|j| f64::from(u8::from(i == j)) - c[i] * n[j])
        });
        let m = mul(&mul(&self.k, &mul(&transpose(&r), &plane)), &self.k_inv);
        let scale = m[2][2];
        Homography {
            m: m.map(|row| row.map(|v| v / scale)),
        }
    }

    /// The warp from frame `k - 1` to frame `k` (`k >= 1`).
    pub fn pair_homography(&self, k: usize) -> Homography {
        let back = self.homography(k - 1).inverse().expect(INVERTIBLE);
        back.then(&self.homography(k))
    }

    /// The constant body rates in rad/s about the sensor axes of PX4's flow convention (X to
    /// the top of the image, Y to its right, Z along the optical axis) at `fps` frames per
    /// second; `None` for `shake`, whose rate changes every frame.
    pub fn body_rates(&self, fps: f64) -> Option<[f64; 3]> {
        if self.path == FlightPath::Shake {
            return None;
        }
        // Camera (x, y, z) = sensor (Y, -X, Z).
        let [x, y, z] = self.rate;
        Some([-y * fps, x * fps, z * fps])
    }

    /// The camera's axes in the world frame at instant `t`.
    fn orientation(&self, t: f64) -> Mat3 {
        match self.path {
            FlightPath::Shake => rotation(self.tremor_at(t)),
            _ => rotation(self.rate.map(|w| w * t)),
        }
    }

    /// The `shake` path's rotation vector at instant `t`: each frame's own tremor, and between
    /// two frames the straight blend of theirs.
    fn tremor_at(&self, t: f64) -> [f64; 3] {
        let (before, share) = (t.floor(), t - t.floor());
        let at_before = self.tremor(before);
        if share == 0.0 {
            return at_before;
        }
        let at_after = self.tremor(before + 1.0);
        std::array::from_fn(|i| at_before[i] + share * (at_after[i] - at_before[i]))
    }

    /// The rotation vector of the tremor in frame `k` (none in frame 0 and before it).
    fn tremor(&self, k: f64) -> [f64; 3] {
        if k <= 0.0 {
            return [0.0; 3];
        }
        let mut rng = SplitMix64::substream(self.seed, TREMOR_STREAM | k as u64);
        std::array::from_fn(|_| rng.uniform(-TREMOR, TREMOR))
    }

    /// The camera's centre in the world frame at instant `t`.
    fn centre(&self, t: f64) -> [f64; 3] {
        self.velocity.map(|v| v * t)
    }
}

/// Share of the frame each moving object covers: two objects make 20-30% of the tracks
/// outliers on the synthetic textures.
pub const OBJECT_SHARE: f64 = 0.12;

/// The frames a camera on a [`Flight`] sees of a scene, with moving objects drawn over it.
#[derive(Debug, Clone)]
pub struct FlightSequence {
    scene: Scene,
    flight: Flight,
    objects: Vec<Glider>,
    camera: Camera,
}

impl FlightSequence {
    /// The scene of `spec` seen along `path` (drawn from the scene's seed), with `objects`
    /// independently moving objects.
    pub fn new(spec: SceneSpec, path: FlightPath, objects: usize) -> Self {
        Self::with_object_size(spec, path, objects, GliderSize::Share(OBJECT_SHARE))
    }

    /// Like [`FlightSequence::new`], with objects of `size` (the same paths as the objects of
    /// [`FlightSequence::new`], which cover [`OBJECT_SHARE`] of the frame each).
    ///
    /// ```
    /// use host_sim::synth::{FlightPath, FlightSequence, GliderSize, SceneSpec};
    /// let spec = SceneSpec::new(160, 120, 3);
    /// let sequence =
    ///     FlightSequence::with_object_size(spec, FlightPath::Pan, 2, GliderSize::Sides(10.0, 12.0));
    /// let (_, _, w, h) = sequence.objects()[1].box_at(4);
    /// assert!((10.0..=12.0).contains(&w) && (10.0..=12.0).contains(&h));
    /// ```
    pub fn with_object_size(
        spec: SceneSpec,
        path: FlightPath,
        objects: usize,
        size: GliderSize,
    ) -> Self {
        Self::with_movers(spec, path, objects, size, Mover::default())
    }

    /// Like [`FlightSequence::with_object_size`], with objects that move as `mover` says (the
    /// same glides; [`Mover::default`] gives the same frames).
    pub fn with_movers(
        spec: SceneSpec,
        path: FlightPath,
        objects: usize,
        size: GliderSize,
        mover: Mover,
    ) -> Self {
        let (w, h) = (spec.width, spec.height);
        let objects = (0..objects)
            .map(|i| Glider::mover(w, h, size, mover, spec.seed ^ ((i as u64 + 1) << 40)))
            .collect();
        Self {
            scene: Scene::new(spec),
            flight: Flight::new(path, w, h, spec.seed),
            objects,
            camera: Camera::default(),
        }
    }

    /// A still camera over `spec`'s ground where `walkers` walkers of `size` cross, legs and
    /// arms swinging, stopping and starting: occluders and movers that bend, for the tests of
    /// the tracker and of the motion detector alike.
    ///
    /// ```
    /// use host_sim::synth::{Body, FlightSequence, GliderSize, SceneSpec};
    /// let spec = SceneSpec::new(160, 120, 5);
    /// let street = FlightSequence::still_walkers(spec, 6, GliderSize::Sides(20.0, 32.0));
    /// assert_eq!(street.objects().len(), 6);
    /// assert!(street.objects().iter().all(|w| w.kind().body == Body::Walker && w.kind().stop_go));
    /// ```
    pub fn still_walkers(spec: SceneSpec, walkers: usize, size: GliderSize) -> Self {
        let walker = Mover {
            body: Body::Walker,
            stop_go: true,
            ..Mover::default()
        };
        Self::with_movers(spec, FlightPath::Still, walkers, size, walker)
    }

    /// The same flight filmed by `camera` (the ideal [`Camera::default`] otherwise).
    pub fn with_camera(self, camera: Camera) -> Self {
        Self { camera, ..self }
    }

    /// The same flight over `photo` instead of the procedural texture: the photograph covers
    /// the ground the camera sees in frames 0 to `frames - 1`, a frame interval either side
    /// included for the exposures and the rolling shutter.
    pub fn with_photo(self, photo: &Frame, frames: usize) -> Self {
        let seen = self.ground_seen(-1.0, frames as f64);
        let photo = Photo::covering(photo, seen);
        Self {
            scene: self.scene.with_photo(photo),
            ..self
        }
    }

    /// The part of the ground plane seen from instant `first` to `last`: the box around the
    /// frame's outline seen back on the plane every tenth of a frame, grown by a pixel.
    pub fn ground_seen(&self, first: f64, last: f64) -> Extent {
        let (w, h) = (self.scene.spec.width as f64, self.scene.spec.height as f64);
        let corners = [
            (-0.5, -0.5),
            (w - 0.5, -0.5),
            (-0.5, h - 0.5),
            (w - 0.5, h - 0.5),
        ];
        let steps = ((last - first) * 10.0).ceil().max(1.0) as usize;
        let seen = (0..=steps).flat_map(|step| {
            let t = first + (last - first) * step as f64 / steps as f64;
            let back = self.flight.homography_at(t).inverse().expect(INVERTIBLE);
            corners.map(|(x, y)| back.apply(x, y))
        });
        Extent::enclosing(seen, 1.0)
    }

    /// The independently moving objects, back to front.
    pub fn objects(&self) -> &[Glider] {
        &self.objects
    }

    /// The camera's flight: the ground truth.
    pub fn flight(&self) -> &Flight {
        &self.flight
    }

    /// Frame `k` (rendered on demand; frame `k` always has the same noise).
    pub fn frame(&self, k: usize) -> Frame {
        let spec = &self.scene.spec;
        let shot = Shot {
            index: k,
            width: spec.width,
            height: spec.height,
            supersample: spec.supersample,
            noise_sigma: spec.noise_sigma,
            noise_seed: self.scene.noise_seed(k as u64),
        };
        self.camera.shoot(&shot, self)
    }
}

/// Why the flight's warps can be inverted.
const INVERTIBLE: &str = "a camera in front of the ground sees it through an invertible warp";

impl Subject for FlightSequence {
    /// The objects where they are at `t`, and elsewhere the ground seen through the flight's
    /// warp at `t`, darkened by the objects' shadows.
    fn view(&self, t: f64) -> impl Fn(f64, f64) -> f64 + '_ {
        let back = self.flight.homography_at(t).inverse().expect(INVERTIBLE);
        let shadows = self.objects.iter().any(|o| o.kind().shadow);
        move |x, y| {
            let object = self.objects.iter().rev().find_map(|o| o.value_at(t, x, y));
            object.unwrap_or_else(|| {
                let (u, v) = back.apply(x, y);
                let ground = self.scene.value(t, u, v);
                match shadows {
                    true => self
                        .objects
                        .iter()
                        .fold(ground, |g, o| g * o.light_at(t, x, y)),
                    false => ground,
                }
            })
        }
    }

    /// The larger of the frame corners' motion and the objects' motion.
    fn travel(&self, t0: f64, t1: f64) -> f64 {
        let (w, h) = (self.scene.spec.width as f64, self.scene.spec.height as f64);
        let (from, to) = (self.flight.homography_at(t0), self.flight.homography_at(t1));
        self.objects
            .iter()
            .map(|object| object.travel(t0, t1))
            .fold(from.distance(&to, w, h), f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every path but `still`.
    fn moving() -> impl Iterator<Item = FlightPath> {
        FlightPath::ALL
            .into_iter()
            .filter(|&p| p != FlightPath::Still)
    }

    #[test]
    fn frame_zero_is_unwarped_and_pairs_chain_up() {
        let still = Flight::new(FlightPath::Still, 160, 120, 4).pair_homography(3);
        assert_eq!(still.distance(&Homography::IDENTITY, 160.0, 120.0), 0.0);
        for path in moving() {
            let flight = Flight::new(path, 160, 120, 4);
            assert!(
                flight
                    .homography(0)
                    .distance(&Homography::IDENTITY, 160.0, 120.0)
                    < 1e-12
            );
            let chained = flight.pair_homography(1).then(&flight.pair_homography(2));
            assert!(chained.distance(&flight.homography(2), 160.0, 120.0) < 1e-9);
            // Every path moves the image, by a few pixels per frame at most.
            let step = flight
                .pair_homography(5)
                .distance(&Homography::IDENTITY, 160.0, 120.0);
            assert!((0.2..12.0).contains(&step), "{path:?}: {step}");
            assert_eq!(FlightPath::from_name(path.name()), Some(path));
        }
    }

    #[test]
    fn a_pan_shifts_and_a_yaw_turns_about_the_centre() {
        let pan = Flight::new(FlightPath::Pan, 160, 120, 1).pair_homography(3);
        assert!(pan.m[0][1].abs() < 1e-12 && (pan.m[0][0] - 1.0).abs() < 1e-12);
        let yaw = Flight::new(FlightPath::Yaw, 160, 120, 1);
        let turn = Homography::rotation(-yaw.rate[2], (79.5, 59.5));
        let drift = yaw.pair_homography(1);
        // The drift is a shift; apart from it the image turns against the yaw rate.
        let (x, y) = drift.apply(79.5, 59.5);
        let expected = turn.then(&Homography::translation(x - 79.5, y - 59.5));
        assert!(drift.distance(&expected, 160.0, 120.0) < 1e-9);
    }

    #[test]
    fn the_ideal_camera_renders_what_the_scene_renders() {
        // What frame() was before the camera model: the scene through the frame's warp, with
        // the objects over it, developed with additive noise.
        let spec = SceneSpec::new(64, 48, 3).with_noise(1.5);
        for path in FlightPath::ALL {
            let sequence = FlightSequence::new(spec, path, 2);
            for k in [0, 1, 4] {
                let overlay = |x, y| sequence.objects.iter().rev().find_map(|o| o.value(k, x, y));
                let warp = sequence.flight.homography(k);
                let lighting = crate::synth::Lighting::UNCHANGED;
                let direct = sequence
                    .scene
                    .render_with_overlay(&warp, lighting, k as u64, overlay);
                assert_eq!(sequence.frame(k), direct, "{path:?} frame {k}");
            }
        }
    }

    #[test]
    fn between_frames_the_flight_moves_continuously() {
        for path in moving() {
            let flight = Flight::new(path, 160, 120, 6);
            let (a, b) = (flight.homography(3), flight.homography(4));
            let middle = flight.homography_at(3.5);
            let (to_a, to_b) = (
                middle.distance(&a, 160.0, 120.0),
                middle.distance(&b, 160.0, 120.0),
            );
            let step = a.distance(&b, 160.0, 120.0);
            assert!(
                to_a < 0.6 * step && to_b < 0.6 * step,
                "{path:?}: {to_a} {to_b} {step}"
            );
            assert_eq!(flight.homography_at(4.0), b);
        }
    }

    #[test]
    fn rolling_right_moves_the_scene_right() {
        let mut flight = Flight::new(FlightPath::Rotation, 160, 120, 2);
        // Sensor X (roll right) is camera -y.
        flight.rate = [0.0, -0.02, 0.0];
        let rates = flight.body_rates(50.0).unwrap();
        assert!((rates[0] - 1.0).abs() < 1e-12 && rates[1] == 0.0);
        let (x, _) = flight.pair_homography(1).apply(79.5, 59.5);
        assert!(x > 79.5 + 2.0, "{x}");
        assert_eq!(
            Flight::new(FlightPath::Shake, 16, 16, 0).body_rates(30.0),
            None
        );
    }
}
