//! Frame sequences along a camera path, with the warp from frame 0 to every frame.

use super::homography::Homography;
use super::render::Lighting;
use super::scene::Scene;
use crate::Frame;

/// A steady camera motion: per frame, a shift of the image by `pan` px, a rotation by `rotation`
/// radians and a zoom by the factor `zoom`, both about `centre`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPath {
    /// Image shift per frame, px.
    pub pan: (f64, f64),
    /// Image rotation per frame, radians (positive turns x towards y).
    pub rotation: f64,
    /// Image scale factor per frame (1 for none).
    pub zoom: f64,
    /// Centre of the rotation and zoom, frame coordinates.
    pub centre: (f64, f64),
}

impl CameraPath {
    /// A camera that does not move, rotating and zooming about `centre` once given a rate.
    pub fn still(centre: (f64, f64)) -> Self {
        Self {
            pan: (0.0, 0.0),
            rotation: 0.0,
            zoom: 1.0,
            centre,
        }
    }

    /// The warp from frame 0 to frame `k`: `k` frames' worth of zoom, rotation and pan.
    ///
    /// ```
    /// use host_sim::synth::CameraPath;
    /// let path = CameraPath { pan: (1.5, 0.0), ..CameraPath::still((0.0, 0.0)) };
    /// assert_eq!(path.homography(4).apply(10.0, 10.0), (16.0, 10.0));
    /// ```
    pub fn homography(&self, k: usize) -> Homography {
        let k = k as f64;
        Homography::similarity(
            self.zoom.powf(k),
            self.rotation * k,
            (self.pan.0 * k, self.pan.1 * k),
            self.centre,
        )
    }
}

/// The frames a camera moving along a path sees of a scene.
#[derive(Debug, Clone)]
pub struct Sequence {
    scene: Scene,
    path: CameraPath,
    len: usize,
}

impl Sequence {
    /// `len` frames of `scene` along `path`.
    pub fn new(scene: Scene, path: CameraPath, len: usize) -> Self {
        Self { scene, path, len }
    }

    /// The number of frames.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True for a sequence without frames.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The scene being filmed.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The camera path.
    pub fn path(&self) -> &CameraPath {
        &self.path
    }

    /// The warp from frame 0 to frame `k`: the ground truth of every point of frame 0.
    pub fn homography(&self, k: usize) -> Homography {
        self.path.homography(k)
    }

    /// The warp from frame `from` to frame `to`.
    pub fn homography_between(&self, from: usize, to: usize) -> Homography {
        let back = self
            .homography(from)
            .inverse()
            .expect("a similarity with a non-zero zoom is invertible");
        back.then(&self.homography(to))
    }

    /// The plane point seen at pixel position `pixel` of frame `k`.
    pub fn plane_point(&self, k: usize, pixel: (f64, f64)) -> (f64, f64) {
        self.homography(k)
            .inverse()
            .expect("a similarity with a non-zero zoom is invertible")
            .apply(pixel.0, pixel.1)
    }

    /// The index of the object seen at pixel position `pixel` of frame `k`, or `None` where
    /// the background shows.
    pub fn object_at(&self, k: usize, pixel: (f64, f64)) -> Option<usize> {
        let (u, v) = self.plane_point(k, pixel);
        self.scene.object_at(k as f64, u, v)
    }

    /// Where the scene point seen at pixel position `pixel` of frame `from` is seen in frame
    /// `to`: the background moves with the camera, a point of an object with the object too.
    ///
    /// ```
    /// use host_sim::synth::{CameraPath, MovingObject, Scene, SceneSpec, Sequence, Surface};
    /// let object = MovingObject {
    ///     half_size: (8.0, 8.0),
    ///     start: (20.0, 20.0),
    ///     velocity: (1.0, 0.0),
    ///     surface: Surface::Flat(250.0),
    /// };
    /// let scene = Scene::new(SceneSpec::new(64, 48, 1)).with_objects(vec![object]);
    /// let path = CameraPath { pan: (0.5, 0.0), ..CameraPath::still((32.0, 24.0)) };
    /// let sequence = Sequence::new(scene, path, 10);
    /// // On the object: its motion and the camera's.
    /// assert_eq!(sequence.true_position(0, (20.0, 20.0), 4), (26.0, 20.0));
    /// // On the background: the camera's only.
    /// assert_eq!(sequence.true_position(0, (50.0, 20.0), 4), (52.0, 20.0));
    /// ```
    pub fn true_position(&self, from: usize, pixel: (f64, f64), to: usize) -> (f64, f64) {
        self.true_position_on(self.object_at(from, pixel), from, pixel, to)
    }

    /// Like [`Sequence::true_position`] for a point of a given layer: the background (`None`)
    /// or object `i` (`Some(i)`), wherever it is seen. A corner on an object's outline belongs
    /// to no one layer: the object's edge moves with the object, the pixels beside it with the
    /// background.
    ///
    /// Panics if there is no object `i`.
    pub fn true_position_on(
        &self,
        layer: Option<usize>,
        from: usize,
        pixel: (f64, f64),
        to: usize,
    ) -> (f64, f64) {
        let point = self.plane_point(from, pixel);
        let (u, v) = match layer {
            Some(i) => self.scene.objects[i].carry(point, from as f64, to as f64),
            None => point,
        };
        self.homography(to).apply(u, v)
    }

    /// How far `position` in frame `to` is from where the scene point seen at `pixel` in frame
    /// `from` is then, on the nearest layer: the background or any object. A tracker is right
    /// to follow either, since a corner on an object's outline belongs to both.
    ///
    /// ```
    /// use host_sim::synth::{CameraPath, Scene, SceneSpec, Sequence};
    /// let path = CameraPath { pan: (1.0, 0.0), ..CameraPath::still((32.0, 24.0)) };
    /// let sequence = Sequence::new(Scene::new(SceneSpec::new(64, 48, 1)), path, 3);
    /// assert_eq!(sequence.distance_to_truth(0, (10.0, 10.0), 2, (12.0, 13.0)), 3.0);
    /// ```
    pub fn distance_to_truth(
        &self,
        from: usize,
        pixel: (f64, f64),
        to: usize,
        position: (f64, f64),
    ) -> f64 {
        std::iter::once(None)
            .chain((0..self.scene.objects.len()).map(Some))
            .map(|layer| {
                let (x, y) = self.true_position_on(layer, from, pixel, to);
                (position.0 - x).hypot(position.1 - y)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Frame `k` (rendered on demand; frame `k` always has the same noise).
    pub fn frame(&self, k: usize) -> Frame {
        self.scene
            .render(&self.homography(k), Lighting::UNCHANGED, k as u64)
    }

    /// Every frame in order.
    pub fn frames(&self) -> impl Iterator<Item = Frame> + '_ {
        (0..self.len).map(|k| self.frame(k))
    }

    /// Every frame, rendered on `threads` threads at once (the same frames as
    /// [`Sequence::frames`]).
    pub fn render_all(&self, threads: usize) -> Vec<Frame> {
        let threads = threads.clamp(1, self.len.max(1));
        let mut frames: Vec<Option<Frame>> = vec![None; self.len];
        std::thread::scope(|scope| {
            // Frame k goes to thread k % threads, so that each gets early and late frames.
            let workers: Vec<_> = (0..threads)
                .map(|t| {
                    scope.spawn(move || {
                        (t..self.len)
                            .step_by(threads)
                            .map(|k| (k, self.frame(k)))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            for worker in workers {
                let rendered = worker
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                for (k, frame) in rendered {
                    frames[k] = Some(frame);
                }
            }
        });
        frames.into_iter().flatten().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::SceneSpec;

    fn sequence() -> Sequence {
        let scene = Scene::new(SceneSpec::new(40, 30, 8).with_supersample(2));
        let path = CameraPath {
            pan: (0.7, -0.3),
            rotation: 0.01,
            zoom: 1.01,
            centre: (20.0, 15.0),
        };
        Sequence::new(scene, path, 4)
    }

    #[test]
    fn warps_between_frames_chain_up() {
        let s = sequence();
        let chained = s.homography_between(0, 2).then(&s.homography_between(2, 3));
        assert!(chained.distance(&s.homography(3), 40.0, 30.0) < 1e-9);
        assert!(s.homography(0).distance(&Homography::IDENTITY, 40.0, 30.0) < 1e-12);
    }

    #[test]
    fn threads_render_the_same_frames() {
        let s = sequence();
        let one: Vec<Frame> = s.frames().collect();
        assert_eq!(s.render_all(3), one);
        assert_eq!(s.render_all(0), one);
    }

    #[test]
    fn frames_repeat_and_frame_zero_is_the_unwarped_scene() {
        let s = sequence();
        let frames: Vec<Frame> = s.frames().collect();
        assert_eq!(frames.len(), 4);
        assert_eq!(frames[2], s.frame(2));
        assert_eq!(
            frames[0],
            s.scene()
                .render(&Homography::IDENTITY, Lighting::UNCHANGED, 0)
        );
        assert_ne!(frames[1], frames[0]);
    }
}
