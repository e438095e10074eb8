//! The library's dense mode on host frames: grid flow for a pair, moving-object boxes along a
//! sequence, and the pictures and files made from them.
//!
//! The runners own their buffers, allocated once for a frame size as firmware would place them
//! in statics, so that each call is exactly the library's work on one frame.

use kestrel::dense::{
    mask_words, motion_scratch_len, outline_scratch_len, smooth_scratch_len, smooth_tracked,
    BoxRules, DenseError, DenseFlow, DenseParams, DenseSummary, DominantFit, DominantFitParams,
    DominantMotion, GridLayout, GridNode, MotionBox, MotionParams, MotionSummary, MovingObjects,
    MovingObjectsBuffers, MovingObjectsConfig, OutlineParams, SMOOTH_GATE, SMOOTH_PASSES,
};
use kestrel::lk::scratch_len;
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::{ConfigError, Point};
use kestrel::{ImageError, ImageView};

use crate::Frame;

/// Why the library refused to run on host frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunError {
    /// Dense flow or motion detection refused its frames.
    Dense(DenseError),
    /// A setting or buffer was refused (a pyramid's storage, for a frame of another size than
    /// the runner's).
    Config(ConfigError),
    /// A frame could not be viewed.
    Image(ImageError),
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Dense(e) => e.fmt(f),
            RunError::Config(e) => e.fmt(f),
            RunError::Image(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for RunError {}

impl From<DenseError> for RunError {
    fn from(error: DenseError) -> Self {
        RunError::Dense(error)
    }
}

impl From<ConfigError> for RunError {
    fn from(error: ConfigError) -> Self {
        RunError::Config(error)
    }
}

/// Grid flow between two frames of one size.
#[derive(Debug, Clone)]
pub struct DenseRunner {
    dense: DenseFlow,
    layout: GridLayout,
    prev_storage: Vec<u8>,
    next_storage: Vec<u8>,
    scratch: Vec<i16>,
    nodes: Vec<GridNode>,
    /// The smoothing's gate, px, and passes, and its rows; `None` leaves the measured flows
    /// alone.
    smoothing: Option<Smoothing>,
    smooth_rows: Vec<Point>,
}

impl DenseRunner {
    /// A runner for `width` x `height` frames that smooths the measured nodes with
    /// [`Smoothing::default`].
    pub fn new(params: DenseParams, width: usize, height: usize) -> Result<Self, RunError> {
        let dense = DenseFlow::new(params)?;
        let layout = dense.layout(width, height)?;
        let storage = pyramid_storage_len(width, height, params.lk.max_level);
        Ok(Self {
            dense,
            layout,
            prev_storage: vec![0; storage],
            next_storage: vec![0; storage],
            scratch: vec![0; scratch_len(params.lk.window)],
            nodes: vec![GridNode::EMPTY; layout.len()],
            smoothing: Some(Smoothing::default()),
            smooth_rows: vec![Point::default(); smooth_scratch_len(width, params.cell)],
        })
    }

    /// The same runner smoothing as `smoothing` says, or not at all with `None`.
    pub fn with_smoothing(self, smoothing: Option<Smoothing>) -> Self {
        Self { smoothing, ..self }
    }

    /// The core: builds both pyramids, computes the grid flow from `prev` to `next` and
    /// smooths it.
    pub fn compute(&mut self, prev: &Frame, next: &Frame) -> Result<DenseSummary, RunError> {
        let levels = self.dense.params().lk.max_level;
        let prev = Pyramid::build(view(prev)?, levels, &mut self.prev_storage)?;
        let next = Pyramid::build(view(next)?, levels, &mut self.next_storage)?;
        let summary = self
            .dense
            .compute(&prev, &next, &mut self.nodes, &mut self.scratch)?;
        if let Some(Smoothing { gate, passes }) = self.smoothing {
            for _ in 0..passes {
                smooth_tracked(&self.layout, &mut self.nodes, gate, &mut self.smooth_rows)?;
            }
        }
        Ok(summary)
    }

    /// The grid.
    pub fn layout(&self) -> &GridLayout {
        &self.layout
    }

    /// The nodes of the last [`DenseRunner::compute`], row by row.
    pub fn nodes(&self) -> &[GridNode] {
        &self.nodes
    }
}

/// How [`DenseRunner`] smooths the measured nodes ([`smooth_tracked`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Smoothing {
    /// Neighbours further than this from a node's flow, px, are left out of its fit.
    pub gate: f32,
    /// Passes of the fit: each reaches one node further.
    pub passes: u8,
}

impl Default for Smoothing {
    /// [`SMOOTH_GATE`] and [`SMOOTH_PASSES`].
    fn default() -> Self {
        Self {
            gate: SMOOTH_GATE,
            passes: SMOOTH_PASSES,
        }
    }
}

fn view(frame: &Frame) -> Result<ImageView<'_>, RunError> {
    frame.view().map_err(RunError::Image)
}

/// Every setting of the motion pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionSettings {
    /// Grid flow.
    pub dense: DenseParams,
    /// The camera's dominant motion.
    pub fit: DominantFitParams,
    /// Mask, morphology and regions.
    pub motion: MotionParams,
    /// Regions outlined at pixel resolution; `None` keeps the grid's boxes.
    pub outline: Option<OutlineParams>,
    /// Consecutive frame pairs a region must move in to be reported
    /// ([`kestrel::dense::BoxPersistence`]); 1 reports every pair's boxes.
    pub persist_pairs: u8,
}

impl MotionSettings {
    /// The library pipeline's configuration with these settings.
    pub fn config(&self) -> MovingObjectsConfig {
        MovingObjectsConfig {
            grid: self.dense,
            fit: self.fit,
            motion: self.motion,
            outline: self.outline,
            persist_pairs: self.persist_pairs,
        }
    }
}

/// The default of [`MotionSettings::persist_pairs`].
pub const PERSIST_PAIRS: u8 = 2;

impl Default for MotionSettings {
    fn default() -> Self {
        Self {
            dense: DenseParams::for_motion(),
            fit: DominantFitParams::default(),
            motion: MotionParams {
                // The outline checks every region at pixel level: even a node alone may be a
                // small object's.
                boxes: BoxRules {
                    min_nodes: 1,
                    ..BoxRules::default()
                },
                ..MotionParams::default()
            },
            outline: Some(OutlineParams {
                side: OUTLINE_SIDE,
                reach: OUTLINE_REACH,
                ..OutlineParams::default()
            }),
            persist_pairs: PERSIST_PAIRS,
        }
    }
}

/// The widest region outlined on the host, px: larger ones keep their grid box.
pub const OUTLINE_SIDE: usize = 96;

/// The largest motion of an object beside the camera's searched on the host, px: the
/// fastest objects of host-sim's flights at 320 x 240 move about 12 px a frame.
pub const OUTLINE_REACH: usize = 16;

/// The most boxes reported per frame.
pub const MAX_BOXES: usize = 32;

/// What the motion pipeline found between a frame and the one before it.
#[derive(Debug, Clone)]
pub struct MotionFrame {
    /// The camera's motion between the two frames.
    pub camera: DominantFit,
    /// Mask and region counts; `boxes` counts the boxes reported, after persistence.
    pub summary: MotionSummary,
    /// Boxes of this pair before persistence: the outlines of its regions (a region may give
    /// several, or none) and of the boxes expected from the pair before, or the regions'
    /// own boxes without outlining.
    pub candidates: usize,
    /// Boxes in the earlier frame, largest first, of the regions that persisted.
    pub boxes: Vec<MotionBox>,
    /// The cleaned mask on the grid of the earlier frame.
    pub mask: Vec<u32>,
}

impl MotionFrame {
    /// The boxes moved by their flow into the later frame of a `width` x `height` sequence.
    pub fn boxes_in_later_frame(&self, width: usize, height: usize) -> Vec<MotionBox> {
        self.boxes
            .iter()
            .map(|b| b.in_next_frame(width, height))
            .collect()
    }
}

/// Moving-object detection along a sequence: the library's [`MovingObjects`] with the grid's
/// own fit of the camera's motion, over buffers this runner owns. Each frame's pyramid is built
/// once and kept as the next pair's previous one.
#[derive(Debug, Clone)]
pub struct MotionRunner {
    settings: MotionSettings,
    objects: MovingObjects<MAX_BOXES>,
    /// The previous frame, once one was pushed, and its pyramid levels in `prev_storage`.
    prev: Option<Frame>,
    prev_storage: Vec<u8>,
    next_storage: Vec<u8>,
    scratch: Vec<i16>,
    nodes: Vec<GridNode>,
    mask: Vec<u32>,
    motion_scratch: Vec<u32>,
    outline_scratch: Vec<u16>,
}

impl MotionRunner {
    /// A runner for `width` x `height` frames.
    pub fn new(settings: MotionSettings, width: usize, height: usize) -> Result<Self, RunError> {
        let objects = MovingObjects::new(settings.config(), width, height)?;
        let side = settings.outline.map_or(0, |o| o.side);
        let reach = settings.outline.map_or(0, |o| o.reach);
        let layout = *objects.layout();
        let cell = settings.dense.cell;
        let storage = pyramid_storage_len(width, height, settings.dense.lk.max_level);
        Ok(Self {
            settings,
            objects,
            prev: None,
            prev_storage: vec![0; storage],
            next_storage: vec![0; storage],
            scratch: vec![0; scratch_len(settings.dense.lk.window)],
            nodes: vec![GridNode::EMPTY; layout.len()],
            mask: vec![0; mask_words(width, height, cell)],
            motion_scratch: vec![0; motion_scratch_len(width, height, cell)],
            outline_scratch: vec![0; outline_scratch_len(side, reach)],
        })
    }

    /// The grid.
    pub fn layout(&self) -> &GridLayout {
        self.objects.layout()
    }

    /// The nodes of the last pair, row by row.
    pub fn nodes(&self) -> &[GridNode] {
        &self.nodes
    }

    /// Takes the next frame; from the second frame on, returns what moved between the frame
    /// before and this one.
    pub fn push(&mut self, frame: Frame) -> Result<Option<MotionFrame>, RunError> {
        let mut next_storage = std::mem::take(&mut self.next_storage);
        let prev_storage = std::mem::take(&mut self.prev_storage);
        let prev = self.prev.take();
        let found = self.pair(prev.as_ref(), &prev_storage, &frame, &mut next_storage);
        if found.is_err() {
            // A refused frame changes nothing: the pair before stays the last one.
            (self.prev, self.prev_storage, self.next_storage) = (prev, prev_storage, next_storage);
            return found;
        }
        // The later frame and its pyramid start the next pair.
        (self.prev, self.prev_storage, self.next_storage) =
            (Some(frame), next_storage, prev_storage);
        found
    }

    /// Builds `frame`'s pyramid into `next_storage` and, after a first frame, runs the pair.
    fn pair(
        &mut self,
        prev: Option<&Frame>,
        prev_storage: &[u8],
        frame: &Frame,
        next_storage: &mut [u8],
    ) -> Result<Option<MotionFrame>, RunError> {
        let levels = self.settings.dense.lk.max_level;
        let next = Pyramid::build(view(frame)?, levels, next_storage)?;
        let Some(prev) = prev else {
            return Ok(None);
        };
        let prev = Pyramid::from_storage(view(prev)?, levels, prev_storage)?;
        let mut buffers = MovingObjectsBuffers {
            nodes: &mut self.nodes,
            lk_scratch: &mut self.scratch,
            mask: &mut self.mask,
            motion_scratch: &mut self.motion_scratch,
            outline_scratch: &mut self.outline_scratch,
        };
        let step = self.objects.process(&prev, &next, None, &mut buffers)?;
        // Without a camera motion of the caller's, the pipeline always fits its own.
        debug_assert!(step.fit.is_some(), "no fit of the grid's own");
        let camera = step.fit.unwrap_or(DominantFit {
            motion: DominantMotion::ZERO,
            measured: 0,
            inliers: 0,
            spread: 0.0,
        });
        Ok(Some(MotionFrame {
            camera,
            summary: step.summary,
            candidates: step.candidates,
            boxes: self.objects.boxes().to_vec(),
            mask: self.mask.clone(),
        }))
    }
}
