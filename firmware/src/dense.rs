//! The dense grid and its motion boxes: the library's motion detector
//! ([`kestrel::dense::MovingObjects`]) on an 8 px grid, against the camera's motion fitted to
//! the tracks, without the outline.

use kestrel::dense::{
    grid_len, mask_words, motion_scratch_len, DenseError, DenseParams, GridNode, MotionBox,
    MotionParams, MovingObjects, MovingObjectsBuffers, MovingObjectsConfig, ObjectsStage,
    ObjectsStep,
};
use kestrel::ego::EgoMotion;
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

    /// The buffers, lent to the motion detector (no outline).
    fn buffers(&mut self) -> MovingObjectsBuffers<'_> {
        MovingObjectsBuffers {
            nodes: &mut self.nodes,
            lk_scratch: &mut self.lk_scratch,
            mask: &mut self.mask,
            motion_scratch: &mut self.motion_scratch,
            outline_scratch: &mut [],
        }
    }
}

/// The motion detector (compiled without the outline) and its buffers.
pub struct Dense {
    objects: MovingObjects<MAX_BOXES, false>,
    buffers: MovingObjectsBuffers<'static>,
}

impl Dense {
    /// The library's motion-detection defaults (8 px cells, 9x9 windows) on the tracker's three
    /// levels, each region of three nodes or more boxed as it is (no outline).
    pub fn new(memory: &'static mut DenseMemory) -> Result<Self, FrameError> {
        let defaults = MovingObjectsConfig::grid_regions();
        let config = MovingObjectsConfig {
            grid: DenseParams {
                cell: CELL,
                lk: LkParams {
                    max_level: MAX_LEVEL,
                    ..defaults.grid.lk
                },
                // Windows too flat for the camera check are not searched: a quarter of the
                // grid's instructions here, the boxes unchanged.
                search_flat: false,
                ..defaults.grid
            },
            motion: MotionParams::default(),
            outline: None,
            persist_pairs: PERSIST_PAIRS,
            ..defaults
        };
        Ok(Self {
            objects: MovingObjects::new(config, WIDTH, HEIGHT).map_err(FrameError::Config)?,
            buffers: memory.buffers(),
        })
    }

    /// Tracks every node from `prev` to `next`, each searched from where the camera's motion
    /// fitted to the tracks (`camera`) takes it when that fit succeeded, and boxes what moves
    /// otherwise in two consecutive frame pairs. Without that fit (a scene cut, a blank frame)
    /// there is nothing reliable to tell motion from: no box, and the regions remembered are
    /// forgotten. `stage_ended` is called as the grid ends, then as each stage of the boxes
    /// does.
    pub fn process(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: &EgoMotion,
        stage_ended: impl FnMut(ObjectsStage),
    ) -> Result<ObjectsStep, DenseError> {
        self.objects
            .process_observed(prev, next, Some(camera), &mut self.buffers, stage_ended)
    }

    /// The boxes of the latest frame, largest first.
    pub fn found(&self) -> &[MotionBox] {
        self.objects.boxes()
    }

    /// The grid's LK scratch.
    pub fn lk_scratch(&mut self) -> &mut [i16] {
        self.buffers.lk_scratch
    }
}
