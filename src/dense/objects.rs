//! The motion detector as one type: [`MovingObjects`].

use super::bodies::join_bodies;
use super::dominant::{DominantFit, DominantFitParams, DominantMotion};
use super::grid::{DenseFlow, DenseParams, DenseSummary, GridLayout, GridNode};
use super::motion::{CameraMotion, MotionDetector, MotionParams, MotionSummary};
use super::outline::{OutlineParams, Outliner};
use super::persist::BoxPersistence;
use super::regions::{BoxRules, MotionBox};
use super::silhouette::grow_over_change;
use super::DenseError;
use crate::ego::{EgoMotion, EgoStatus};
use crate::pyramid::Pyramid;
use crate::q16::Point;
use crate::{Bound, ConfigError};

/// The settings [`MovingObjects::new`] checks, as paths from its [`MovingObjectsConfig`], one
/// list per part.
const GRID_PATHS: [&str; 8] = [
    "grid.cell",
    "grid.max_residual",
    "grid.camera_tolerance",
    "grid.lk.window",
    "grid.lk.max_level",
    "grid.lk.max_iterations",
    "grid.lk.epsilon",
    "grid.lk.min_eigen_threshold",
];
const FIT_PATHS: [&str; 2] = ["fit.start_radius", "fit.inlier_radius"];
const MOTION_PATHS: [&str; 1] = ["motion.threshold"];
const OUTLINE_PATHS: [&str; 2] = ["outline.side", "outline.reach"];

/// How a [`MovingObjects`] is made.
///
/// ```
/// use kestrel::dense::{DenseParams, MovingObjectsConfig};
/// let config = MovingObjectsConfig::default();
/// // The grid keeps only the windows it can trust for motion, every region is outlined
/// // (even a node alone may be a small object's), and a box needs two frame pairs.
/// assert_eq!(config.grid, DenseParams::for_motion());
/// assert_eq!(config.motion.boxes.min_nodes, 1);
/// assert!(config.outline.is_some());
/// assert_eq!(config.persist_pairs, 2);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MovingObjectsConfig {
    /// The grid's flow.
    pub grid: DenseParams,
    /// The grid's own fit of the camera's motion, used when the caller gives none.
    pub fit: DominantFitParams,
    /// The motion mask, its morphology and its regions.
    pub motion: MotionParams,
    /// Each region outlined at pixel level; `None` reports the regions' own boxes.
    pub outline: Option<OutlineParams>,
    /// Consecutive frame pairs a region must move in to be reported ([`BoxPersistence`]);
    /// 0 and 1 report every pair's boxes.
    pub persist_pairs: u8,
}

impl MovingObjectsConfig {
    /// The defaults without the outline: each region of the mask boxed as it is, from three
    /// nodes up ([`BoxRules::default`]).
    ///
    /// ```
    /// use kestrel::dense::MovingObjectsConfig;
    /// let config = MovingObjectsConfig::grid_regions();
    /// assert_eq!((config.outline, config.motion.boxes.min_nodes), (None, 3));
    /// ```
    pub fn grid_regions() -> Self {
        Self {
            motion: MotionParams::default(),
            outline: None,
            ..Self::default()
        }
    }
}

impl Default for MovingObjectsConfig {
    /// The grid of [`DenseParams::for_motion`], the default fit, every region of one node or
    /// more outlined with [`OutlineParams::default`], and two pairs to report a box.
    fn default() -> Self {
        Self {
            grid: DenseParams::for_motion(),
            fit: DominantFitParams::default(),
            motion: MotionParams {
                boxes: BoxRules {
                    min_nodes: 1,
                    ..BoxRules::default()
                },
                ..MotionParams::default()
            },
            outline: Some(OutlineParams::default()),
            persist_pairs: 2,
        }
    }
}

/// The buffers a frame pair needs, the caller's, lent to each [`MovingObjects::process`].
///
/// Each is at least as long as the `const fn` named beside it, for the frame size and the
/// [`MovingObjectsConfig`]; longer is fine. See the [`MovingObjects`] documentation for a whole
/// example.
///
/// ```
/// use kestrel::dense::{grid_len, mask_words, motion_scratch_len, GridNode, MovingObjectsBuffers};
/// use kestrel::lk::scratch_len;
/// // 160 x 120 frames, 8 px cells, 9 px windows, no outline (firmware keeps them in statics).
/// let mut nodes = [GridNode::EMPTY; grid_len(160, 120, 8)];
/// let mut lk_scratch = [0i16; scratch_len(9)];
/// let mut mask = [0u32; mask_words(160, 120, 8)];
/// let mut motion_scratch = [0u32; motion_scratch_len(160, 120, 8)];
/// let buffers = MovingObjectsBuffers {
///     nodes: &mut nodes,
///     lk_scratch: &mut lk_scratch,
///     mask: &mut mask,
///     motion_scratch: &mut motion_scratch,
///     outline_scratch: &mut [],
/// };
/// assert_eq!((buffers.nodes.len(), buffers.mask.len()), (300, 10));
/// ```
#[derive(Debug)]
pub struct MovingObjectsBuffers<'a> {
    /// The grid's nodes, row by row: [`grid_len`](super::grid_len). After a pair, its flow.
    pub nodes: &'a mut [GridNode],
    /// LK's scratch: [`crate::lk::scratch_len`] of the grid's window.
    pub lk_scratch: &'a mut [i16],
    /// The motion mask: [`mask_words`](super::mask_words). After a pair, its cleaned mask.
    pub mask: &'a mut [u32],
    /// The mask's morphology and region search: [`motion_scratch_len`].
    ///
    /// [`motion_scratch_len`]: super::motion_scratch_len
    pub motion_scratch: &'a mut [u32],
    /// The outline's: [`outline_scratch_len`] of [`OutlineParams::side`] and
    /// [`OutlineParams::reach`]; may be empty without an outline.
    ///
    /// [`outline_scratch_len`]: super::outline_scratch_len
    pub outline_scratch: &'a mut [u16],
}

/// What one frame pair gave.
///
/// See the [`MovingObjects`] documentation.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ObjectsStep {
    /// The grid: its layout, and how many nodes were measured and filled.
    pub grid: DenseSummary,
    /// The grid's own fit of the camera's motion, when the caller gave none.
    pub fit: Option<DominantFit>,
    /// The mask's moving nodes and regions; `boxes` counts the boxes reported, after the
    /// persistence and the join of one body's parts ([`MovingObjects::boxes`]). All zero when
    /// the caller's camera motion was unknown.
    pub summary: MotionSummary,
    /// The pair's boxes before the persistence: the outlines of its regions (a region may give
    /// several, or none) and of the boxes expected from the pair before, or the regions' own
    /// boxes without the outline.
    pub candidates: usize,
}

/// A stage of [`MovingObjects::process_observed`], in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ObjectsStage {
    /// The grid's flow, measured and filled.
    Grid,
    /// The camera's motion: the grid's own fit, or the caller's taken as it is.
    Camera,
    /// The motion mask and its regions' boxes.
    Regions,
    /// The regions outlined at pixel level (with an outline only).
    Outline,
    /// The boxes that persisted, the parts of one body joined, and on a still camera grown
    /// over the changed pixels.
    Persist,
}

/// The motion detector as one type: frame pairs in, boxes of what moves unlike the camera out.
///
/// [`MovingObjects`] runs the dense stages in their order for each frame pair: the grid
/// ([`DenseFlow`], searched from the camera's motion when the caller knows it), the camera's
/// motion (the caller's, fitted to the tracks, or else the grid's own dominant fit,
/// [`DominantMotion::fit`]), the motion mask and its regions ([`MotionDetector`]), optionally
/// each region outlined at pixel level ([`Outliner`]), the persistence over frame pairs
/// ([`BoxPersistence`]), the persisting boxes that are parts of one body joined
/// ([`join_bodies`]), and on a still camera each box grown over the pixels connected to it
/// that changed between the frames, and the feet standing below a body joined to it
/// ([`grow_over_change`]: a walker's flat coat and trousers, its planted foot).
/// The firmware, `host-sim motion` and `host-sim demo` all run this type.
///
/// Memory: the frames' pyramids are the caller's (a tracker lends its own, so each frame's
/// pyramid is built once), and so are the per-frame buffers ([`MovingObjectsBuffers`], each
/// sized by a `const fn`), lent to every [`MovingObjects::process`]: the caller reads the grid
/// and the mask there afterwards. The type itself holds the settings, the persistence's memory
/// and `2 * N` boxes, so a `static` of it is its whole footprint.
///
/// ```
/// use kestrel::dense::{
///     grid_len, mask_words, motion_scratch_len, outline_scratch_len, GridNode, MovingObjects,
///     MovingObjectsBuffers, MovingObjectsConfig, OutlineParams,
/// };
/// use kestrel::ImageView;
/// use kestrel::lk::scratch_len;
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
///
/// const W: usize = 96;
/// const H: usize = 64;
/// const LEVELS: usize = 3;
/// // A still camera over textured ground; a 16 x 16 patch of another texture moves 3 px to
/// // the right a frame, from x = 24.
/// let frame = |k: usize| -> [u8; W * H] {
///     core::array::from_fn(|i| {
///         let (x, y) = (i % W, i / W);
///         let left = 24 + 3 * k;
///         let (u, v) = (x as f32, y as f32);
///         if (left..left + 16).contains(&x) && (24..40).contains(&y) {
///             let (u, v) = ((x - left) as f32, (y - 24) as f32);
///             (128.0 + 90.0 * (1.3 * u).sin() * (1.1 * v).cos()) as u8
///         } else {
///             (128.0 + 50.0 * (0.45 * u).sin() * (0.38 * v).cos() + 35.0 * (0.21 * u + 0.3 * v).sin()) as u8
///         }
///     })
/// };
/// fn pyramid<'a>(pixels: &'a [u8], storage: &'a mut [u8]) -> Pyramid<'a> {
///     Pyramid::build(ImageView::packed(pixels, W, H).unwrap(), LEVELS, storage).unwrap()
/// }
///
/// // The defaults: 8 px cells, the grid's own fit of the camera, outlines up to 48 px.
/// let config = MovingObjectsConfig::default();
/// assert_eq!((config.grid.cell, config.outline.map(|o| o.side)), (8, Some(48)));
/// let mut objects = MovingObjects::<8>::new(config, W, H).unwrap();
/// let mut nodes = [GridNode::EMPTY; grid_len(W, H, 8)];
/// let mut lk_scratch = [0i16; scratch_len(9)];
/// let mut mask = [0u32; mask_words(W, H, 8)];
/// let mut motion_scratch = [0u32; motion_scratch_len(W, H, 8)];
/// let mut outline_scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
/// let mut buffers = MovingObjectsBuffers {
///     nodes: &mut nodes,
///     lk_scratch: &mut lk_scratch,
///     mask: &mut mask,
///     motion_scratch: &mut motion_scratch,
///     outline_scratch: &mut outline_scratch,
/// };
///
/// let frames = [frame(0), frame(1), frame(2)];
/// let mut storage = [[0u8; pyramid_storage_len(W, H, LEVELS)]; 3];
/// let [s0, s1, s2] = &mut storage;
/// let (p0, p1, p2) = (pyramid(&frames[0], s0), pyramid(&frames[1], s1), pyramid(&frames[2], s2));
///
/// // The first pair: the patch moved, but a box needs two pairs.
/// let step = objects.process(&p0, &p1, None, &mut buffers).unwrap();
/// assert!(step.summary.moving > 0 && step.candidates == 1);
/// assert!(objects.boxes().is_empty());
/// // The second pair: the patch moved on, and is boxed where it was in frame 1 (27, 24,
/// // 16 x 16) within a few pixels, with its flow, 3 px to the right.
/// let step = objects.process(&p1, &p2, None, &mut buffers).unwrap();
/// assert_eq!(step.summary.boxes, 1);
/// let b = objects.boxes()[0];
/// assert!(b.x.abs_diff(27) <= 1 && b.y.abs_diff(24) <= 1, "{b:?}");
/// assert!(b.w.abs_diff(16) <= 3 && b.h.abs_diff(16) <= 3, "{b:?}");
/// let (dx, dy) = b.mean_flow.to_f32();
/// assert!((dx - 3.0).abs() < 0.2 && dy.abs() < 0.2);
/// // The camera stood still, as the grid's own fit says.
/// let fit = step.fit.unwrap();
/// let (cx, cy) = fit.motion.flow_at(48.0, 32.0);
/// assert!(cx.abs() < 0.05 && cy.abs() < 0.05);
/// ```
///
/// `N` is the most boxes a frame pair gives and the persistence remembers.
///
/// `OUTLINE` says whether the pipeline may outline: `false` refuses a configuration with an
/// outline (`"outline"` must be `None`) and compiles the outline out, so a program that has
/// no use for it does not link its code (9 KB of Cortex-M4 flash).
///
/// ```
/// use kestrel::dense::{MovingObjects, MovingObjectsConfig};
/// use kestrel::{Bound, ConfigError};
/// let regions = MovingObjects::<8, false>::new(MovingObjectsConfig::grid_regions(), 160, 120);
/// assert!(regions.is_ok());
/// let outlined = MovingObjects::<8, false>::new(MovingObjectsConfig::default(), 160, 120);
/// let refused = outlined.err().unwrap();
/// assert_eq!(refused, ConfigError { field: "outline", bound: Bound::Absent });
/// assert_eq!(refused.to_string(), "outline must be None");
/// ```
#[derive(Debug, Clone)]
pub struct MovingObjects<const N: usize, const OUTLINE: bool = true> {
    config: MovingObjectsConfig,
    layout: GridLayout,
    flow: DenseFlow,
    detector: MotionDetector,
    outliner: Option<Outliner>,
    persistence: BoxPersistence<N>,
    /// The regions' boxes, then the pair's candidates, then the reported boxes first.
    boxes: [MotionBox; N],
    /// The outlines of the candidates.
    outlines: [MotionBox; N],
    /// Boxes reported for the latest pair, at the start of `boxes`.
    reported: usize,
}

impl<const N: usize, const OUTLINE: bool> MovingObjects<N, OUTLINE> {
    /// A pipeline for `width` x `height` frames, its settings checked: a refusal names the
    /// setting by its path in `config` (`"grid.cell"`, `"grid.lk.window"`,
    /// `"fit.inlier_radius"`, `"motion.threshold"`, `"outline.side"`, ...).
    ///
    /// ```
    /// use kestrel::dense::{DenseParams, MovingObjects, MovingObjectsConfig};
    /// use kestrel::{Bound, ConfigError};
    /// let config = MovingObjectsConfig::default();
    /// let objects = MovingObjects::<16>::new(config, 160, 120).unwrap();
    /// assert_eq!((objects.layout().cols(), objects.layout().rows()), (20, 15));
    /// let zero = MovingObjectsConfig { grid: DenseParams { cell: 0, ..config.grid }, ..config };
    /// let refused = MovingObjects::<16>::new(zero, 160, 120).err().unwrap();
    /// assert_eq!(refused, ConfigError { field: "grid.cell", bound: Bound::AtLeast(1) });
    /// let large = MovingObjectsConfig { grid: DenseParams { cell: 200, ..config.grid }, ..config };
    /// let refused = MovingObjects::<16>::new(large, 160, 120).err().unwrap();
    /// assert_eq!(refused.to_string(), "grid.cell must be 1 to 120");
    /// let bad_fit = MovingObjectsConfig { fit: kestrel::dense::DominantFitParams {
    ///     inlier_radius: f32::NAN, ..config.fit }, ..config };
    /// let refused = MovingObjects::<16>::new(bad_fit, 160, 120).err().unwrap();
    /// assert_eq!(refused.to_string(), "fit.inlier_radius must be a finite number above 0");
    /// ```
    pub fn new(
        config: MovingObjectsConfig,
        width: usize,
        height: usize,
    ) -> Result<Self, ConfigError> {
        let grid = |e: ConfigError| e.nested(&GRID_PATHS);
        let flow = DenseFlow::new(config.grid).map_err(grid)?;
        let layout = flow.layout(width, height).map_err(grid)?;
        let detector = MotionDetector::new(config.motion).map_err(|e| e.nested(&MOTION_PATHS))?;
        if !OUTLINE && config.outline.is_some() {
            return Err(ConfigError::new("outline", Bound::Absent));
        }
        let outliner = config
            .outline
            .map(Outliner::new)
            .transpose()
            .map_err(|e| e.nested(&OUTLINE_PATHS))?;
        config.fit.check().map_err(|e| e.nested(&FIT_PATHS))?;
        Ok(Self {
            config,
            layout,
            flow,
            detector,
            outliner,
            persistence: BoxPersistence::new(config.persist_pairs),
            boxes: [MotionBox::default(); N],
            outlines: [MotionBox::default(); N],
            reported: 0,
        })
    }

    /// Finds what moved from `prev` to `next` (the pyramids of two consecutive frames of the
    /// pipeline's size, to the grid's levels), in the caller's `buffers`, and reports the boxes
    /// whose objects have moved in enough consecutive pairs ([`MovingObjects::boxes`]).
    ///
    /// `camera` is the camera's motion from `prev` to `next` when the caller knows it, such as
    /// the ego-motion fitted to a tracker's tracks: each node's search then starts where it
    /// predicts ([`DenseFlow::compute_predicted`]), and the mask compares the nodes' flow with
    /// it. When that fit failed (a status other than [`EgoStatus::Ok`]: a scene cut, a blank
    /// frame) nothing can tell an object from the camera: no box, an empty mask, and the boxes
    /// remembered are forgotten. With `None`, the camera's motion is the grid's own dominant
    /// fit ([`ObjectsStep::fit`]).
    ///
    /// An error (pyramids of another size, or a buffer too short, named by its field in
    /// [`MovingObjectsBuffers`]: `"buffers.nodes"`, `"buffers.lk_scratch"`, ...) leaves no box
    /// reported and the persistence as it was.
    ///
    /// ```
    /// # use kestrel::dense::{
    /// #     grid_len, mask_words, motion_scratch_len, DenseError, GridNode, MovingObjects,
    /// #     MovingObjectsBuffers, MovingObjectsConfig,
    /// # };
    /// # use kestrel::ImageView;
    /// # use kestrel::lk::scratch_len;
    /// # use kestrel::pyramid::{pyramid_storage_len, Pyramid};
    /// use kestrel::ego::{EgoMotion, EgoStatus, Homography, ModelKind};
    /// const W: usize = 64;
    /// const H: usize = 48;
    /// let pixels: [u8; W * H] = core::array::from_fn(|i| {
    ///     let (x, y) = ((i % W) as f32, (i / W) as f32);
    ///     (128.0 + 60.0 * (0.45 * x).sin() * (0.38 * y).cos() + 40.0 * (0.21 * x + 0.3 * y).sin()) as u8
    /// });
    /// let mut storage = [0u8; pyramid_storage_len(W, H, 3)];
    /// let still = Pyramid::build(ImageView::packed(&pixels, W, H).unwrap(), 3, &mut storage).unwrap();
    /// # let mut nodes = [GridNode::EMPTY; grid_len(W, H, 8)];
    /// # let mut lk_scratch = [0i16; scratch_len(9)];
    /// # let mut mask = [0u32; mask_words(W, H, 8)];
    /// # let mut motion_scratch = [0u32; motion_scratch_len(W, H, 8)];
    /// # let mut buffers = MovingObjectsBuffers { nodes: &mut nodes, lk_scratch: &mut lk_scratch,
    /// #     mask: &mut mask, motion_scratch: &mut motion_scratch, outline_scratch: &mut [] };
    /// let mut objects = MovingObjects::<8>::new(MovingObjectsConfig::grid_regions(), W, H).unwrap();
    /// // The tracks say the camera stood still: nothing moves, and no fit of the grid's own.
    /// let tracks = EgoMotion {
    ///     status: EgoStatus::Ok,
    ///     ..EgoMotion::failed(ModelKind::Homography, EgoStatus::Ok)
    /// };
    /// let step = objects.process(&still, &still, Some(&tracks), &mut buffers).unwrap();
    /// assert_eq!((step.summary.moving, step.fit), (0, None));
    /// assert_eq!(step.grid.tracked + step.grid.filled, 48);
    /// // Had they said the camera moved 2 px to the right, the whole ground would move
    /// // against it: too much to tell an object from, so still no box.
    /// let pan = EgoMotion { model: Homography::translation(2.0, 0.0).unwrap(), ..tracks };
    /// let step = objects.process(&still, &still, Some(&pan), &mut buffers).unwrap();
    /// assert_eq!(step.summary.boxes, 0);
    /// // A failed fit: the camera's motion is unknown and nothing is looked for.
    /// let failed = EgoMotion::failed(ModelKind::Homography, EgoStatus::NoConsensus);
    /// let step = objects.process(&still, &still, Some(&failed), &mut buffers).unwrap();
    /// assert_eq!((step.summary.moving, step.candidates), (0, 0));
    /// // Pyramids of another size are refused.
    /// let mut other = MovingObjects::<8>::new(MovingObjectsConfig::grid_regions(), 80, 48).unwrap();
    /// let refused = other.process(&still, &still, None, &mut buffers);
    /// assert_eq!(refused.err(), Some(DenseError::FrameSizeMismatch));
    /// // A short buffer is named as the caller's field.
    /// buffers.lk_scratch = &mut [];
    /// let short = objects.process(&still, &still, None, &mut buffers).unwrap_err();
    /// assert_eq!(short.to_string(), "buffers.lk_scratch must hold at least 711 elements");
    /// ```
    pub fn process(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: Option<&EgoMotion>,
        buffers: &mut MovingObjectsBuffers<'_>,
    ) -> Result<ObjectsStep, DenseError> {
        self.process_observed(prev, next, camera, buffers, |_| {})
    }

    /// [`MovingObjects::process`], calling `stage_ended` as each [`ObjectsStage`] ends:
    /// firmware reads a cycle counter there to time the grid and the boxes apart.
    ///
    /// ```
    /// # use kestrel::dense::{
    /// #     grid_len, mask_words, motion_scratch_len, outline_scratch_len, GridNode,
    /// #     MovingObjects, MovingObjectsBuffers, MovingObjectsConfig, ObjectsStage, OutlineParams,
    /// # };
    /// # use kestrel::ImageView;
    /// # use kestrel::lk::scratch_len;
    /// # use kestrel::pyramid::{pyramid_storage_len, Pyramid};
    /// # const W: usize = 64;
    /// # const H: usize = 48;
    /// # let pixels: [u8; W * H] = core::array::from_fn(|i| ((i % W) * 7 + (i / W) * 13) as u8);
    /// # let mut storage = [0u8; pyramid_storage_len(W, H, 3)];
    /// # let frame = Pyramid::build(ImageView::packed(&pixels, W, H).unwrap(), 3, &mut storage).unwrap();
    /// # let mut nodes = [GridNode::EMPTY; grid_len(W, H, 8)];
    /// # let mut lk_scratch = [0i16; scratch_len(9)];
    /// # let mut mask = [0u32; mask_words(W, H, 8)];
    /// # let mut motion_scratch = [0u32; motion_scratch_len(W, H, 8)];
    /// # let mut outline_scratch = [0u16; outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8)];
    /// # let mut buffers = MovingObjectsBuffers { nodes: &mut nodes, lk_scratch: &mut lk_scratch,
    /// #     mask: &mut mask, motion_scratch: &mut motion_scratch, outline_scratch: &mut outline_scratch };
    /// let mut objects = MovingObjects::<8>::new(MovingObjectsConfig::default(), W, H).unwrap();
    /// let mut stages = heapless::Vec::<ObjectsStage, 5>::new();
    /// objects.process_observed(&frame, &frame, None, &mut buffers, |s| stages.push(s).unwrap()).unwrap();
    /// assert_eq!(stages, [
    ///     ObjectsStage::Grid,
    ///     ObjectsStage::Camera,
    ///     ObjectsStage::Regions,
    ///     ObjectsStage::Outline,
    ///     ObjectsStage::Persist,
    /// ]);
    /// ```
    pub fn process_observed(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: Option<&EgoMotion>,
        buffers: &mut MovingObjectsBuffers<'_>,
        mut stage_ended: impl FnMut(ObjectsStage),
    ) -> Result<ObjectsStep, DenseError> {
        self.reported = 0;
        for pyramid in [prev, next] {
            let base = pyramid.base();
            if (base.width(), base.height()) != (self.layout.width(), self.layout.height()) {
                return Err(DenseError::FrameSizeMismatch);
            }
        }
        let known = camera.filter(|c| c.status == EgoStatus::Ok);
        let (nodes, scratch) = (&mut *buffers.nodes, &mut *buffers.lk_scratch);
        let grid = match known {
            Some(camera) => {
                let model = camera.model;
                let predict = move |p: Point| model.apply_point(p).unwrap_or(p);
                self.flow
                    .compute_predicted(prev, next, nodes, scratch, &predict)
            }
            None => self.flow.compute(prev, next, nodes, scratch),
        }
        .map_err(|e| named(e, "buffers.lk_scratch"))?;
        debug_assert_eq!(grid.layout, self.layout, "the grid of the checked frames");
        stage_ended(ObjectsStage::Grid);
        let (fit, found) = match (camera, known) {
            (None, _) => {
                let fit = DominantMotion::fit(&self.layout, buffers.nodes, &self.config.fit)
                    .map_err(|e| named(DenseError::Config(e), "buffers.nodes"))?;
                stage_ended(ObjectsStage::Camera);
                let found = self.detect(prev, next, &fit.motion, buffers, &mut stage_ended)?;
                (Some(fit), found)
            }
            (Some(_), Some(camera)) => {
                stage_ended(ObjectsStage::Camera);
                let found = self.detect(prev, next, &camera.model, buffers, &mut stage_ended)?;
                (None, found)
            }
            (Some(_), None) => {
                self.persistence.reset();
                buffers.mask.iter_mut().for_each(|w| *w = 0);
                (None, (MotionSummary::default(), 0))
            }
        };
        let (summary, candidates) = found;
        Ok(ObjectsStep {
            grid,
            fit,
            summary,
            candidates,
        })
    }

    /// Mask, regions, outline and persistence of the nodes in `buffers` against `camera`:
    /// the summary (with the boxes reported) and the count of candidates.
    fn detect(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: &impl CameraMotion,
        buffers: &mut MovingObjectsBuffers<'_>,
        stage_ended: &mut impl FnMut(ObjectsStage),
    ) -> Result<(MotionSummary, usize), DenseError> {
        let layout = &self.layout;
        let mut summary = self
            .detector
            .detect(
                layout,
                buffers.nodes,
                camera,
                buffers.mask,
                buffers.motion_scratch,
                &mut self.boxes,
            )
            .map_err(|e| named(DenseError::Config(e), "buffers.motion_scratch"))?;
        stage_ended(ObjectsStage::Regions);
        let mut candidates = summary.boxes;
        // Without OUTLINE, the branch and the outline's code are compiled out.
        let outliner = if OUTLINE {
            self.outliner.as_ref()
        } else {
            None
        };
        if let Some(outliner) = outliner {
            candidates = self
                .persistence
                .append_expected(&mut self.boxes, candidates);
            let regions = self.boxes.get(..candidates);
            debug_assert!(regions.is_some(), "more candidates than boxes");
            candidates = outliner
                .outline(
                    prev,
                    next,
                    camera,
                    layout,
                    buffers.nodes,
                    buffers.mask,
                    regions.unwrap_or(&[]),
                    buffers.outline_scratch,
                    &mut self.outlines,
                )
                .map_err(|e| named(e, "buffers.outline_scratch"))?;
            core::mem::swap(&mut self.boxes, &mut self.outlines);
            stage_ended(ObjectsStage::Outline);
        }
        summary.boxes = self
            .persistence
            .confirm(layout, &mut self.boxes, candidates);
        summary.boxes = join_bodies(&mut self.boxes, summary.boxes, camera);
        summary.boxes = grow_over_change(prev, next, &mut self.boxes, summary.boxes, camera);
        self.reported = summary.boxes;
        stage_ended(ObjectsStage::Persist);
        Ok((summary, candidates))
    }

    /// The boxes reported for the latest frame pair, largest first, in the earlier frame of
    /// the pair ([`MotionBox::in_next_frame`] moves one into the later); none after an error.
    ///
    /// See the [`MovingObjects`] documentation.
    pub fn boxes(&self) -> &[MotionBox] {
        let reported = self.boxes.get(..self.reported);
        debug_assert!(reported.is_some(), "more boxes reported than kept");
        reported.unwrap_or(&[])
    }

    /// Forgets the boxes remembered from the pairs before: the next pair starts a new
    /// sequence.
    ///
    /// ```
    /// use kestrel::dense::{MovingObjects, MovingObjectsConfig};
    /// let mut objects = MovingObjects::<8>::new(MovingObjectsConfig::default(), 64, 48).unwrap();
    /// objects.reset();
    /// assert!(objects.boxes().is_empty());
    /// ```
    pub fn reset(&mut self) {
        self.persistence.reset();
        self.reported = 0;
    }

    /// The grid over the pipeline's frames: which node of [`MovingObjectsBuffers::nodes`]
    /// and of the mask is where.
    ///
    /// See [`MovingObjects::new`].
    pub fn layout(&self) -> &GridLayout {
        &self.layout
    }

    /// The settings this pipeline was made with.
    ///
    /// ```
    /// use kestrel::dense::{MovingObjects, MovingObjectsConfig};
    /// let config = MovingObjectsConfig::grid_regions();
    /// assert_eq!(*MovingObjects::<8>::new(config, 64, 48).unwrap().config(), config);
    /// ```
    pub fn config(&self) -> &MovingObjectsConfig {
        &self.config
    }
}

/// `e` with a refused buffer named as the caller's field in [`MovingObjectsBuffers`]; the
/// stage's own scratch (its `"scratch"`, and the parts the motion detector cuts from it) is
/// `scratch`.
fn named(e: DenseError, scratch: &'static str) -> DenseError {
    match e {
        DenseError::Config(e) => DenseError::Config(e.renamed(&[
            ("nodes", "buffers.nodes"),
            ("mask", "buffers.mask"),
            ("scratch", scratch),
            ("temp", scratch),
            ("unvisited", scratch),
            ("stack", scratch),
        ])),
        other => other,
    }
}
