//! Scenes and frame pairs with exact ground truth.

use super::homography::Homography;
use super::object::MovingObject;
use super::photo::Photo;
use super::render::{area_sample, Exposure, Lighting};
use super::rng::SplitMix64;
use super::texture::{Extent, Texture};
use crate::Frame;

/// Everything that fixes a synthetic scene and its camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneSpec {
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Seed of the texture and of the noise.
    pub seed: u64,
    /// Standard deviation of the sensor noise, grey levels.
    pub noise_sigma: f64,
    /// Samples per pixel and axis when rendering (2 gives 4 samples per pixel).
    pub supersample: usize,
}

impl SceneSpec {
    /// A noise-free scene of `width` x `height` px rendered with 2 x 2 samples per pixel (the
    /// texture's edges are a pixel wide, so that is enough to keep them from aliasing).
    pub fn new(width: usize, height: usize, seed: u64) -> Self {
        Self {
            width,
            height,
            seed,
            noise_sigma: 0.0,
            supersample: 2,
        }
    }

    /// The same scene with sensor noise of `sigma` grey levels.
    pub fn with_noise(self, sigma: f64) -> Self {
        Self {
            noise_sigma: sigma,
            ..self
        }
    }

    /// The same scene rendered with `n` x `n` samples per pixel.
    pub fn with_supersample(self, n: usize) -> Self {
        Self {
            supersample: n,
            ..self
        }
    }
}

/// A textured plane seen by a camera, with objects moving over it. Frame 0 sees plane point
/// (`u`, `v`) at pixel position (`u`, `v`); a frame warped by `H` sees it at `H(u, v)`.
#[derive(Debug, Clone)]
pub struct Scene {
    /// How the scene was made.
    pub spec: SceneSpec,
    /// The plane's texture.
    pub texture: Texture,
    /// Objects in front of the plane, each drawn over the ones before it.
    pub objects: Vec<MovingObject>,
    /// A photograph that covers the plane instead of the texture, when there is one.
    pub photo: Option<Photo>,
}

impl Scene {
    /// The scene of `spec`. The texture's shapes cover the frame and half its larger side
    /// around it, so that moderate camera motion keeps them in view.
    pub fn new(spec: SceneSpec) -> Self {
        let margin = spec.width.max(spec.height) as f64 / 2.0;
        let extent = Extent::around_frame(spec.width, spec.height, margin);
        Self {
            spec,
            texture: Texture::random(spec.seed, extent),
            objects: Vec::new(),
            photo: None,
        }
    }

    /// The same scene with `objects` in front of the plane, the last one on top.
    pub fn with_objects(self, objects: Vec<MovingObject>) -> Self {
        Self { objects, ..self }
    }

    /// The same scene with `photo` on the plane instead of the texture.
    pub fn with_photo(self, photo: Photo) -> Self {
        Self {
            photo: Some(photo),
            ..self
        }
    }

    /// The grey level of the plane itself at (`u`, `v`): the photograph, or the texture.
    pub fn ground(&self, u: f64, v: f64) -> f64 {
        match &self.photo {
            Some(photo) => photo.value(u, v),
            None => self.texture.value(u, v),
        }
    }

    /// The grey level of plane point (`u`, `v`) at frame `frame`: the ground, with the objects
    /// that cover it drawn over it.
    pub fn value(&self, frame: f64, u: f64, v: f64) -> f64 {
        self.objects
            .iter()
            .fold(self.ground(u, v), |below, object| {
                let alpha = object.coverage(frame, u, v);
                if alpha > 0.0 {
                    alpha * object.value(frame, u, v) + (1.0 - alpha) * below
                } else {
                    below
                }
            })
    }

    /// The index of the topmost object covering plane point (`u`, `v`) at frame `frame`, or
    /// `None` where the background shows.
    pub fn object_at(&self, frame: f64, u: f64, v: f64) -> Option<usize> {
        self.objects
            .iter()
            .rposition(|object| object.covers(frame, u, v))
    }

    /// The frame seen through `warp` under `lighting`. `frame_index` places the objects and
    /// selects the noise, so that two frames of one scene have independent noise and
    /// re-rendering a frame repeats it.
    ///
    /// Panics if `warp` is singular.
    pub fn render(&self, warp: &Homography, lighting: Lighting, frame_index: u64) -> Frame {
        self.render_with_overlay(warp, lighting, frame_index, |_, _| None)
    }

    /// Like [`Scene::render`], with `overlay(x, y)` drawn over the scene wherever it gives a
    /// grey level (moving objects, in frame coordinates).
    pub fn render_with_overlay(
        &self,
        warp: &Homography,
        lighting: Lighting,
        frame_index: u64,
        overlay: impl Fn(f64, f64) -> Option<f64>,
    ) -> Frame {
        let (w, h) = (self.spec.width, self.spec.height);
        let inverse = warp.inverse().expect("a camera warp is invertible");
        let radiance = area_sample(w, h, self.spec.supersample, |x, y| {
            overlay(x, y).unwrap_or_else(|| {
                let (u, v) = inverse.apply(x, y);
                self.value(frame_index as f64, u, v)
            })
        });
        let exposure = Exposure {
            lighting,
            noise_sigma: self.spec.noise_sigma,
            noise_seed: self.noise_seed(frame_index),
        };
        exposure.develop(w, h, &radiance)
    }

    /// The seed of the sensor noise of frame `frame_index`.
    pub fn noise_seed(&self, frame_index: u64) -> u64 {
        SplitMix64::substream(self.spec.seed, 1 << 32 | frame_index).next_u64()
    }
}

/// Two frames of the scene of `spec`: the reference view and the view through `warp`, lit alike.
///
/// ```
/// use host_sim::synth::{pair, true_position, Homography, SceneSpec};
/// let spec = SceneSpec::new(64, 48, 1).with_supersample(2);
/// let shift = Homography::translation(2.5, -1.0);
/// let (a, b) = pair(&spec, &shift);
/// assert_eq!((b.width, b.height), (64, 48));
/// assert_eq!(true_position(&shift, 10.0, 10.0), (12.5, 9.0));
/// ```
pub fn pair(spec: &SceneSpec, warp: &Homography) -> (Frame, Frame) {
    pair_with_lighting(spec, warp, Lighting::UNCHANGED)
}

/// Like [`pair`], with the second frame under `lighting` (the first is unchanged).
pub fn pair_with_lighting(
    spec: &SceneSpec,
    warp: &Homography,
    lighting: Lighting,
) -> (Frame, Frame) {
    let scene = Scene::new(*spec);
    let first = scene.render(&Homography::IDENTITY, Lighting::UNCHANGED, 0);
    let second = scene.render(warp, lighting, 1);
    (first, second)
}

/// Where the point at (`x`, `y`) in the first frame of a pair appears in the second.
pub fn true_position(warp: &Homography, x: f32, y: f32) -> (f32, f32) {
    let (u, v) = warp.apply(f64::from(x), f64::from(y));
    (u as f32, v as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_identical_frames() {
        let spec = SceneSpec::new(48, 40, 9).with_noise(1.5);
        let warp = Homography::similarity(1.02, 0.05, (1.5, -0.5), (24.0, 20.0));
        assert_eq!(pair(&spec, &warp), pair(&spec, &warp));
        let other = SceneSpec { seed: 10, ..spec };
        assert_ne!(pair(&spec, &warp).0, pair(&other, &warp).0);
    }

    #[test]
    fn noise_differs_between_the_frames_of_a_pair() {
        let spec = SceneSpec::new(32, 32, 2).with_noise(2.0);
        let (a, b) = pair(&spec, &Homography::IDENTITY);
        let differing = a.data.iter().zip(&b.data).filter(|(p, q)| p != q).count();
        assert!(differing > a.data.len() / 2);
    }

    #[test]
    fn an_integer_translation_shifts_the_frame() {
        let spec = SceneSpec::new(80, 60, 4);
        let (dx, dy) = (3, -2);
        let (a, b) = pair(&spec, &Homography::translation(dx as f64, dy as f64));
        for y in 5..55 {
            for x in 5..75 {
                let (sx, sy) = ((x - dx) as usize, (y - dy) as usize);
                let diff = i32::from(b.at(x as usize, y as usize)) - i32::from(a.at(sx, sy));
                assert!(diff.abs() <= 1, "({x}, {y}): {diff}");
            }
        }
    }

    #[test]
    fn lighting_applies_to_the_second_frame_only() {
        let spec = SceneSpec::new(32, 24, 6).with_supersample(2);
        let lighting = Lighting {
            gain: 1.25,
            bias: 15.0,
        };
        let (a, b) = pair_with_lighting(&spec, &Homography::IDENTITY, lighting);
        let (plain, _) = pair(&spec, &Homography::IDENTITY);
        assert_eq!(a, plain);
        for (&p, &q) in a.data.iter().zip(&b.data) {
            // Both frames are rounded: 0.5 from q, 1.25 x 0.5 from p.
            let expected = (1.25 * f64::from(p) + 15.0).min(255.0);
            assert!((f64::from(q) - expected).abs() <= 1.125);
        }
    }
}
