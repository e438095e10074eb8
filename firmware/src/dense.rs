//! The dense grid and its motion boxes: LK at every node of an 8 px grid, then the regions that
//! move unlike the camera.

use kestrel::dense::grid::{grid_len, DenseFlow, DenseParams, DenseSummary, GridLayout, GridNode};
use kestrel::dense::mask::mask_words;
use kestrel::dense::motion::{motion_scratch_len, MotionDetector, MotionParams, MotionSummary};
use kestrel::dense::persist::BoxPersistence;
use kestrel::dense::regions::MotionBox;
use kestrel::dense::DenseError;
use kestrel::ego::{EgoMotion, EgoStatus};
use kestrel::lk::LkParams;
use kestrel::pyramid::Pyramid;
use kestrel::Point;

use crate::pipeline::{FrameError, LK_SCRATCH_LEN, MAX_LEVEL};
use crate::scene::{HEIGHT, WIDTH};

/// Grid spacing, px.
pub const CELL: usize = 8;
/// Nodes of the grid: 20 x 15.
pub const NODES: usize = grid_len(WIDTH, HEIGHT, CELL);
/// Words of the motion mask.
pub const MASK_WORDS: usize = mask_words(WIDTH, HEIGHT, CELL);
/// Words of the motion detector's scratch.
pub const MOTION_SCRATCH_LEN: usize = motion_scratch_len(WIDTH, HEIGHT, CELL);
/// Boxes kept per frame, the largest first.
pub const MAX_BOXES: usize = 8;
/// Consecutive frame pairs a region must move in to be boxed.
const PERSIST_PAIRS: u8 = 2;

/// The dense stage's buffers, in one `static` so that they land in `.bss`.
pub struct DenseMemory {
    nodes: [GridNode; NODES],
    lk_scratch: [i16; LK_SCRATCH_LEN],
    mask: [u32; MASK_WORDS],
    motion_scratch: [u32; MOTION_SCRATCH_LEN],
}

impl DenseMemory {
    /// Zeroed buffers, for a `static` initialiser: all zeros, so that the static lands in
    /// `.bss` (`GridNode::EMPTY` is not zeros; the grid overwrites every node anyway).
    pub const fn new() -> Self {
        const ZERO_NODE: GridNode = GridNode::tracked(Point::from_bits(0, 0));
        Self {
            nodes: [ZERO_NODE; NODES],
            lk_scratch: [0; LK_SCRATCH_LEN],
            mask: [0; MASK_WORDS],
            motion_scratch: [0; MOTION_SCRATCH_LEN],
        }
    }
}

/// The grid, the detector and the boxes of the latest frame.
pub struct Dense {
    flow: DenseFlow,
    detector: MotionDetector,
    persistence: BoxPersistence<MAX_BOXES>,
    buffers: &'static mut DenseMemory,
    boxes: [MotionBox; MAX_BOXES],
    found: usize,
}

impl Dense {
    /// The library's motion-detection defaults (8 px cells, 9x9 windows) on the tracker's three
    /// levels.
    pub fn new(buffers: &'static mut DenseMemory) -> Result<Self, FrameError> {
        let defaults = DenseParams::for_motion();
        let params = DenseParams {
            cell: CELL,
            lk: LkParams {
                max_level: MAX_LEVEL,
                ..defaults.lk
            },
            // Windows too flat for the camera check are not searched: a quarter of the grid's
            // instructions here, the boxes unchanged.
            search_flat: false,
            ..defaults
        };
        Ok(Self {
            flow: DenseFlow::new(params).map_err(FrameError::Dense)?,
            detector: MotionDetector::new(MotionParams::default()).map_err(FrameError::Dense)?,
            persistence: BoxPersistence::new(PERSIST_PAIRS),
            buffers,
            boxes: [MotionBox::default(); MAX_BOXES],
            found: 0,
        })
    }

    /// Tracks every node from `prev` to `next` and fills the invalid ones. With the camera's
    /// motion fitted to the tracks (`camera`, when the fit succeeded), each node's search
    /// starts where it predicts, on the finest level; nodes that move otherwise are searched
    /// on the whole pyramid.
    pub fn grid(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: &EgoMotion,
    ) -> Result<DenseSummary, DenseError> {
        self.found = 0;
        let buffers = &mut self.buffers;
        let (nodes, scratch) = (&mut buffers.nodes[..], &mut buffers.lk_scratch[..]);
        if camera.status != EgoStatus::Ok {
            return self.flow.compute(prev, next, nodes, scratch);
        }
        let model = camera.model;
        let predict = move |p: Point| model.apply_point(p).unwrap_or(p);
        self.flow
            .compute_predicted(prev, next, nodes, scratch, &predict)
    }

    /// Marks what moves otherwise than the camera and boxes the regions that moved in two
    /// consecutive frame pairs, against the camera's motion fitted to the tracks. Without that
    /// fit (a scene cut, a blank frame) there is nothing reliable to tell motion from: no box,
    /// and the regions remembered are forgotten.
    pub fn boxes(
        &mut self,
        layout: &GridLayout,
        camera: &EgoMotion,
    ) -> Result<MotionSummary, DenseError> {
        self.found = 0;
        if camera.status != EgoStatus::Ok {
            self.persistence.reset();
            return Ok(MotionSummary::default());
        }
        let buffers = &mut self.buffers;
        let mut found = self.detector.detect(
            layout,
            &buffers.nodes[..],
            &camera.model,
            &mut buffers.mask[..],
            &mut buffers.motion_scratch[..],
            &mut self.boxes,
        )?;
        found.boxes = self
            .persistence
            .confirm(layout, &mut self.boxes, found.boxes);
        self.found = found.boxes;
        Ok(found)
    }

    /// The boxes of the latest frame, largest first.
    pub fn found(&self) -> &[MotionBox] {
        self.boxes.get(..self.found).unwrap_or(&[])
    }

    /// The grid's LK scratch.
    pub fn lk_scratch(&mut self) -> &mut [i16] {
        &mut self.buffers.lk_scratch[..]
    }
}
