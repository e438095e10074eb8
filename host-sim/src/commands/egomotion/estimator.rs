//! The camera's motion between consecutive frames, with the library end to end.
//!
//! Per frame pair: Shi-Tomasi corners in the previous frame, spread over the frame by a grid;
//! pyramidal LK to the new frame (seeded with the gyro's prediction when there is one); RANSAC
//! on the tracked points. The new frame's pyramid is kept for the next pair, so each frame's
//! pyramid is built once.

use kestrel::detect::{
    shi_tomasi_scratch_len, Corner, Grid, Region, ShiTomasi, MAX_CELLS_PER_SIDE,
};
use kestrel::ego::{Camera, CameraParams, EgoMotion, ModelKind, Ransac, RansacParams, Rotation};
use kestrel::lk::{scratch_len, LkParams, LucasKanade, PointTrack};
use kestrel::pyramid::{pyramid_storage_len, Pyramid, PyramidFilter};
use kestrel::Point;

use crate::Frame;

/// Points tracked per frame pair unless told otherwise.
pub const DEFAULT_MAX_POINTS: usize = 200;

/// RANSAC inlier threshold unless told otherwise, px. LK tracks sharp frames to about 0.1 px,
/// so half a pixel keeps the camera's tracks while rejecting objects that move only a pixel
/// relative to the ground, which a homography with a 1 px threshold can bend to absorb.
pub const DEFAULT_THRESHOLD: f32 = 0.5;

/// Horizontal field of view assumed when no focal length is given, radians.
const DEFAULT_FOV: f32 = std::f32::consts::FRAC_PI_3;
/// Columns of the bucketing grid; rows follow the frame's aspect ratio.
const GRID_COLUMNS: usize = 8;
/// Corners offered to the grid per point wanted: enough that sparse cells still get theirs.
const CANDIDATES_PER_POINT: usize = 4;

/// How the motion between frames is measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorSettings {
    /// The motion model fitted.
    pub model: ModelKind,
    /// Focal length in pixels; `None` for a 60 degree horizontal field of view.
    pub focal: Option<f32>,
    /// At most this many points are tracked per frame pair.
    pub max_points: usize,
    /// RANSAC inlier threshold on the transfer error, px.
    pub threshold: f32,
    /// How points are followed from frame to frame.
    pub lk: LkParams,
    /// How the pyramid levels are made.
    pub pyramid: PyramidFilter,
}

impl Default for EstimatorSettings {
    fn default() -> Self {
        Self {
            model: ModelKind::Homography,
            focal: None,
            max_points: DEFAULT_MAX_POINTS,
            threshold: DEFAULT_THRESHOLD,
            lk: LkParams::default(),
            pyramid: PyramidFilter::Gaussian,
        }
    }
}

/// The motion between one frame and the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairMotion {
    /// The fitted motion, previous-frame pixels to next-frame pixels.
    pub motion: EgoMotion,
    /// Corners detected in the previous frame (after bucketing).
    pub corners: usize,
    /// Of those, the points LK tracked: the correspondences the model was fitted to.
    pub tracked: usize,
}

/// Detection, tracking and fitting for a sequence of frames of one size, with every buffer
/// allocated up front.
#[derive(Debug)]
pub struct MotionEstimator {
    width: usize,
    height: usize,
    camera: Camera,
    detector: ShiTomasi,
    grid: Grid,
    max_points: usize,
    lk: LucasKanade,
    pyramid: PyramidFilter,
    ransac: Ransac,
    /// The previous frame and its pyramid levels, once a frame was pushed.
    prev: Option<Frame>,
    prev_levels: Vec<u8>,
    next_levels: Vec<u8>,
    detect_scratch: Vec<i32>,
    lk_scratch: Vec<i16>,
    corners: Vec<Corner>,
    points: Vec<Point>,
    guesses: Vec<Point>,
    tracks: Vec<PointTrack>,
    pairs: Vec<(Point, Point)>,
    inliers: Vec<bool>,
}

impl MotionEstimator {
    /// An estimator for `width` x `height` frames (sizes the library accepts).
    pub fn new(settings: &EstimatorSettings, width: usize, height: usize) -> Result<Self, String> {
        let camera = camera(settings.focal, width, height)?;
        let lk_params = settings.lk;
        let lk = LucasKanade::new(lk_params).map_err(|e| format!("tracker: {e}"))?;
        let ransac_params = RansacParams {
            model: settings.model,
            threshold: settings.threshold,
            ..RansacParams::default()
        };
        let ransac = Ransac::new(ransac_params).map_err(|e| format!("model fit: {e}"))?;
        let levels_len = pyramid_storage_len(width, height, lk_params.max_level);
        let candidates = settings.max_points * CANDIDATES_PER_POINT;
        Ok(Self {
            width,
            height,
            camera,
            detector: ShiTomasi {
                min_distance: min_distance(settings.max_points, width, height),
                ..ShiTomasi::default()
            },
            grid: grid(settings.max_points, width, height),
            max_points: settings.max_points,
            pyramid: settings.pyramid,
            lk,
            ransac,
            prev: None,
            prev_levels: vec![0; levels_len],
            next_levels: vec![0; levels_len],
            detect_scratch: vec![0; shi_tomasi_scratch_len(width, candidates)],
            lk_scratch: vec![0; scratch_len(lk_params.window)],
            corners: vec![Corner::default(); candidates],
            points: Vec::with_capacity(settings.max_points),
            guesses: Vec::with_capacity(settings.max_points),
            tracks: Vec::with_capacity(settings.max_points),
            pairs: Vec::with_capacity(settings.max_points),
            inliers: Vec::with_capacity(settings.max_points),
        })
    }

    /// The camera the gyro predictions and the autopilot's angular flow use.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Takes the next frame (of the estimator's size) and returns the motion from the frame
    /// before it; `None` for the first frame. `rotation` is the gyro's rotation over the frame
    /// interval, if known: it predicts where each point went, as LK's starting guess.
    pub fn push(
        &mut self,
        frame: Frame,
        rotation: Option<&Rotation>,
    ) -> Result<Option<PairMotion>, String> {
        if (frame.width, frame.height) != (self.width, self.height) {
            return Err(format!(
                "frame is {}x{} but the estimator was made for {}x{}",
                frame.width, frame.height, self.width, self.height
            ));
        }
        let levels = self.lk.params().max_level;
        let view = frame.view().map_err(|e| e.to_string())?;
        Pyramid::build_with(view, levels, self.pyramid, &mut self.next_levels)
            .map_err(|e| e.to_string())?;
        let motion = match self.prev.take() {
            Some(prev) => Some(self.measure(&prev, &frame, rotation)?),
            None => None,
        };
        std::mem::swap(&mut self.prev_levels, &mut self.next_levels);
        self.prev = Some(frame);
        Ok(motion)
    }

    /// Detects in `prev`, tracks into `next` and fits the model; both pyramids are built.
    fn measure(
        &mut self,
        prev: &Frame,
        next: &Frame,
        rotation: Option<&Rotation>,
    ) -> Result<PairMotion, String> {
        let corners = self.detect(prev)?;
        let levels = self.lk.params().max_level;
        let (prev_view, next_view) = (
            prev.view().map_err(|e| e.to_string())?,
            next.view().map_err(|e| e.to_string())?,
        );
        let prev_pyramid = Pyramid::from_storage(prev_view, levels, &self.prev_levels)
            .map_err(|e| e.to_string())?;
        let next_pyramid = Pyramid::from_storage(next_view, levels, &self.next_levels)
            .map_err(|e| e.to_string())?;

        self.points.clear();
        self.points
            .extend(self.corners[..corners].iter().map(|c| c.position));
        let guesses = match rotation {
            Some(rotation) => {
                self.guesses.resize(corners, Point::default());
                self.camera
                    .predict_points(rotation, &self.points, &mut self.guesses)
                    .map_err(|e| e.to_string())?;
                Some(&self.guesses[..])
            }
            None => None,
        };
        self.tracks.resize(corners, PointTrack::default());
        self.lk
            .track_points(
                &prev_pyramid,
                &next_pyramid,
                &self.points,
                guesses,
                &mut self.tracks,
                &mut self.lk_scratch,
            )
            .map_err(|e| format!("tracker: {e}"))?;

        self.pairs.clear();
        self.pairs.extend(
            self.points
                .iter()
                .zip(&self.tracks)
                .filter(|(_, track)| track.is_tracked())
                .map(|(&point, track)| (point, track.position)),
        );
        self.inliers.resize(self.pairs.len(), false);
        let motion = self
            .ransac
            .estimate(&self.pairs, &mut self.inliers)
            .map_err(|e| format!("model fit: {e}"))?;
        Ok(PairMotion {
            motion,
            corners,
            tracked: self.pairs.len(),
        })
    }

    /// Shi-Tomasi corners of `frame`, at most `max_points` after grid bucketing, at the front
    /// of `self.corners`; returns how many.
    fn detect(&mut self, frame: &Frame) -> Result<usize, String> {
        let view = frame.view().map_err(|e| e.to_string())?;
        let found = self
            .detector
            .detect(
                &view,
                Region::full(&view),
                None,
                &mut self.detect_scratch,
                &mut self.corners,
            )
            .map_err(|e| format!("detector: {e}"))?;
        let kept = self
            .grid
            .select(self.width, self.height, &mut self.corners[..found], &[])
            .map_err(|e| format!("detector: {e}"))?;
        Ok(kept.min(self.max_points))
    }
}

/// The pinhole camera for `width` x `height` frames: principal point at the centre, and the
/// focal length given or that of a 60 degree horizontal field of view.
pub(super) fn camera(focal: Option<f32>, width: usize, height: usize) -> Result<Camera, String> {
    let size = |v: usize| u16::try_from(v).map_err(|_| format!("frame side {v} px is too large"));
    let default = CameraParams::from_horizontal_fov(size(width)?, size(height)?, DEFAULT_FOV);
    let params = match focal {
        Some(f) => CameraParams {
            focal_x: f,
            focal_y: f,
            ..default
        },
        None => default,
    };
    Camera::new(params).map_err(|e| format!("camera: {e}"))
}

/// Spacing between corners that leaves room for about twice `max_points` over the frame, so
/// small frames still get their share; at most the detector's default of 10 px.
fn min_distance(max_points: usize, width: usize, height: usize) -> u16 {
    let spacing = ((width * height) as f64 / (2 * max_points.max(1)) as f64).sqrt();
    spacing.clamp(3.0, 10.0) as u16
}

/// A grid of [`GRID_COLUMNS`] columns and rows in the frame's aspect ratio, allowing enough
/// points per cell for `max_points` in all.
fn grid(max_points: usize, width: usize, height: usize) -> Grid {
    let cols = GRID_COLUMNS;
    let rows = (cols * height + width / 2) / width.max(1);
    let rows = rows.clamp(1, MAX_CELLS_PER_SIDE);
    let per_cell = max_points
        .div_ceil(cols * rows)
        .clamp(1, usize::from(u8::MAX));
    Grid {
        cols,
        rows,
        per_cell: per_cell as u8,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{CameraPath, Scene, SceneSpec, Sequence};
    use kestrel::ego::EgoStatus;

    #[test]
    fn grids_follow_the_aspect_ratio() {
        assert_eq!(
            grid(200, 160, 120),
            Grid {
                cols: 8,
                rows: 6,
                per_cell: 5
            }
        );
        assert_eq!(grid(10, 400, 20).rows, 1);
        assert_eq!(min_distance(200, 160, 120), 6);
        assert_eq!(min_distance(200, 640, 480), 10);
    }

    #[test]
    fn a_pan_is_measured_pair_by_pair() {
        let scene = Scene::new(SceneSpec::new(160, 120, 3).with_noise(1.0));
        let path = CameraPath {
            pan: (2.5, -1.25),
            ..CameraPath::still((79.5, 59.5))
        };
        let sequence = Sequence::new(scene, path, 3);
        let settings = EstimatorSettings {
            model: ModelKind::Translation,
            ..EstimatorSettings::default()
        };
        let mut estimator = MotionEstimator::new(&settings, 160, 120).unwrap();
        let mut frames = sequence.frames();
        assert_eq!(estimator.push(frames.next().unwrap(), None), Ok(None));
        for frame in frames {
            let pair = estimator.push(frame, None).unwrap().unwrap();
            assert_eq!(pair.motion.status, EgoStatus::Ok);
            assert!(
                pair.tracked > 100 && pair.corners <= DEFAULT_MAX_POINTS,
                "{pair:?}"
            );
            let (x, y) = pair.motion.model.apply((0.0, 0.0)).unwrap();
            assert!((x - 2.5).abs() < 0.05 && (y + 1.25).abs() < 0.05, "{x} {y}");
        }
        let wrong = Frame::filled(80, 60, 0);
        assert!(estimator.push(wrong, None).is_err());
    }
}
