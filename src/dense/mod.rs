//! Dense grid flow and moving-object detection.
//!
//! Corners say how the camera moves; they say little about *what else* moves. This module
//! measures flow everywhere, on a coarse regular grid, and finds the parts of the frame whose
//! motion differs from the camera's:
//!
//! 1. [`DenseFlow`]: LK flow at every node of a [`GridLayout`] (node centres at
//!    `cell/2 + k·cell`), one [`GridNode`] each, with a [`NodeStatus`] from texture,
//!    convergence and the intensity residual.
//! 2. [`fill_invalid`]: invalid nodes filled from their valid neighbours, marked as filled.
//!    [`smooth_tracked`] can then average each measured node with the neighbours that move
//!    alike.
//! 3. [`DominantMotion`]: the camera's motion as a robust global affine model of the grid flow
//!    ([`DominantMotion::fit`]).
//! 4. [`MotionDetector::mark`]: nodes whose flow differs from that model, in a node mask
//!    ([`mask_words`]), cleaned by morphology on the grid ([`mask_close`], [`mask_open`]).
//! 5. [`find_boxes`]: connected regions of the mask as bounding boxes in pixels
//!    ([`MotionBox`]).
//! 6. [`Outliner`]: each region outlined at pixel level, one box per object it holds (none
//!    for a region of mismeasured nodes).
//! 7. [`BoxPersistence`]: the boxes whose objects moved in consecutive frame pairs.
//! 8. [`join_bodies`]: the persisting boxes that are parts of one body (a walker's legs and
//!    torso from regions of their own) joined.
//! 9. [`grow_over_change`]: on a still camera, each box grown over the pixels connected to it
//!    that changed between the frames (a walker's flat coat and trousers), the boxes that
//!    then overlap joined, and so are the feet standing below a body.
//!
//! [`MovingObjects`] runs them in that order, one frame pair at a time: the motion detector as
//! one type, the one the firmware and host-sim run.
//!
//! [`MotionDetector`] runs steps 4 and 5 given a camera model, so a better model (a
//! homography from the ego-motion estimator) can replace [`DominantMotion`] through the
//! [`CameraMotion`] trait, whose [`CameraMotion::flow_at`] gives the camera's flow at a pixel
//! (a displacement, not a position).
//!
//! Nothing allocates: nodes, masks and boxes live in caller-owned slices sized by `const fn`s.
//! A refused setting or slice is a [`ConfigError`] naming it (`"cell"`, `"lk.window"`,
//! `"nodes"`, `"mask"`, ...); what a frame pair can meet is a [`DenseError`].
//!
//! # Memory
//!
//! With 8 px cells, a 9 px window and pyramids to level 3, flow and motion detection need,
//! besides the two frames themselves (level 0 of each pyramid is the frame):
//!
//! | buffer | sized by | 160 x 120 | 320 x 240 |
//! |---|---|---|---|
//! | two pyramids, levels 1 to 3 | [`crate::pyramid::pyramid_storage_len`] | 12 600 B | 50 400 B |
//! | nodes, 12 B each | [`grid_len`] | 3 600 B | 14 400 B |
//! | LK scratch | [`crate::lk::scratch_len`] | 1 422 B | 1 422 B |
//! | mask | [`mask_words`] | 40 B | 152 B |
//! | motion scratch | [`motion_scratch_len`] | 1 240 B | 4 952 B |
//! | 16 boxes, 20 B each | | 320 B | 320 B |
//! | total | | 19 222 B | 71 646 B |
//!
//! ```
//! use core::mem::size_of;
//! use kestrel::dense::{grid_len, mask_words, motion_scratch_len, GridNode, MotionBox};
//! use kestrel::{lk, pyramid};
//! const fn bytes(w: usize, h: usize) -> usize {
//!     2 * pyramid::pyramid_storage_len(w, h, 3)
//!         + grid_len(w, h, 8) * size_of::<GridNode>()
//!         + lk::scratch_len(9) * size_of::<i16>()
//!         + (mask_words(w, h, 8) + motion_scratch_len(w, h, 8)) * size_of::<u32>()
//!         + 16 * size_of::<MotionBox>()
//! }
//! assert_eq!((size_of::<GridNode>(), size_of::<MotionBox>()), (12, 20));
//! assert_eq!((bytes(160, 120), bytes(320, 240)), (19_222, 71_646));
//! ```
//!
//! The outline ([`Outliner`]) needs [`outline_scratch_len`] words of `u16` besides: 11 778 B
//! for regions up to 48 px and motions up to 8 px. The smoothing ([`smooth_tracked`]) needs
//! [`smooth_scratch_len`] points: two rows of nodes, 320 B at 160 x 120 and 640 B at
//! 320 x 240.
//!
//! On the stack, this module's largest buffer is the 64 B of a fill median (LK's use comes on
//! top).

// The camera check's sums are bounded by its 12 px window (`agreement::MAX_CHECKED_WINDOW`):
// at most 12 * 12 * 255 < 2^16, and its 16-bit lanes below 2^16 (proved beside them). Its
// indices are loop variables below the const sizes of the arrays they index.
#[cfg_attr(
    not(test),
    allow(
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation,
        clippy::indexing_slicing
    )
)]
mod agreement;
mod bodies;
mod dominant;
mod fill;
mod grid;
mod mask;
mod motion;
mod objects;
// Per-pixel loops over a candidate's area: indices are below the area's pixels, bounded by the
// checked scratch side (at most 255, so `u16` pixel indices), and sums of nine differences of
// grey x 16 stay below 2^16 (9 x 4080 = 36 720).
#[cfg_attr(
    not(test),
    allow(
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation,
        clippy::indexing_slicing
    )
)]
mod outline;
mod persist;
mod regions;
mod silhouette;
mod smooth;

pub use bodies::{join_bodies, BODY_GAP};
pub use dominant::{DominantFit, DominantFitParams, DominantMotion};
pub use fill::{fill_invalid, FILL_MIN_SOURCES};
pub use grid::{
    grid_len, grid_side, DenseFlow, DenseParams, DenseSummary, GridLayout, GridNode, NodeStatus,
};
pub use mask::{
    mask_close, mask_contains, mask_count, mask_open, mask_set, mask_words, MaskStructure,
};
pub use motion::{motion_scratch_len, CameraMotion, MotionDetector, MotionParams, MotionSummary};
pub use objects::{
    MovingObjects, MovingObjectsBuffers, MovingObjectsConfig, ObjectsStage, ObjectsStep,
};
pub use outline::{
    outline_scratch_len, OutlineParams, Outliner, OUTLINE_MAX_FLOWS, OUTLINE_MAX_REACH,
    OUTLINE_MAX_SIDE, OUTLINE_MIN_SIDE, OUTLINE_VOTED_FLOWS,
};
pub use persist::BoxPersistence;
pub use regions::{find_boxes, BoxRules, MotionBox, RegionCount};
pub use silhouette::grow_over_change;
pub use smooth::{
    smooth_scratch_len, smooth_tracked, SMOOTH_GATE, SMOOTH_MIN_AFFINE, SMOOTH_PASSES,
};

use crate::lk::LkError;
use crate::ConfigError;

/// Why a frame pair could not be taken: by [`DenseFlow::compute`], [`Outliner::outline`] or
/// [`MovingObjects::process`].
///
/// Refused settings and buffers are [`ConfigError`]s: the constructors and the functions
/// that take only buffers return one, and a frame pair's functions, which also take buffers,
/// wrap it as [`DenseError::Config`].
///
/// ```
/// use kestrel::dense::{grid_len, DenseError, DenseFlow, DenseParams, GridNode};
/// use kestrel::ImageView;
/// use kestrel::lk::scratch_len;
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
/// use kestrel::{Bound, ConfigError};
/// let pixels = [100u8; 64 * 48];
/// let mut storage = [0u8; pyramid_storage_len(64, 48, 3)];
/// let frame = Pyramid::build(ImageView::packed(&pixels, 64, 48).unwrap(), 3, &mut storage).unwrap();
/// let dense = DenseFlow::new(DenseParams::default()).unwrap();
/// let mut scratch = [0i16; scratch_len(9)];
/// let mut nodes = [GridNode::EMPTY; 10];
/// let short = dense.compute(&frame, &frame, &mut nodes, &mut scratch).unwrap_err();
/// let needed = ConfigError { field: "nodes", bound: Bound::MinLen(grid_len(64, 48, 8)) };
/// assert_eq!(short, DenseError::Config(needed));
/// assert_eq!(short.to_string(), "nodes must hold at least 48 elements");
/// // Level 3 of 64 x 48 is 8 x 6: narrower than half a 21 px window.
/// let wide = DenseParams { lk: kestrel::lk::LkParams { window: 21, ..DenseParams::default().lk }, ..DenseParams::default() };
/// let mut nodes = [GridNode::EMPTY; grid_len(64, 48, 8)];
/// let mut scratch = [0i16; scratch_len(21)];
/// let small = DenseFlow::new(wide).unwrap().compute(&frame, &frame, &mut nodes, &mut scratch);
/// assert_eq!(small, Err(DenseError::FrameTooSmall));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DenseError {
    /// The two pyramids were built from frames of different sizes, or not of the size the
    /// grid or pipeline was made for.
    FrameSizeMismatch,
    /// The coarsest pyramid level used is smaller than half an LK window per side.
    FrameTooSmall,
    /// A buffer was refused, or the grid's cell for these frames.
    Config(ConfigError),
}

impl From<ConfigError> for DenseError {
    fn from(e: ConfigError) -> Self {
        DenseError::Config(e)
    }
}

/// A per-node LK refusal: never expected, since [`DenseFlow::compute`] checks the frames and
/// the scratch first; a point at a time has no slices to differ in length.
pub(crate) fn lk_refusal(e: LkError) -> DenseError {
    match e {
        LkError::Config(e) => DenseError::Config(e),
        LkError::FrameSizeMismatch | LkError::LengthMismatch => DenseError::FrameSizeMismatch,
    }
}

impl core::fmt::Display for DenseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DenseError::FrameSizeMismatch => f.write_str("previous and next frames differ in size"),
            DenseError::FrameTooSmall => {
                f.write_str("frame is too small for the pyramid: the coarsest level is narrower than half a window")
            }
            DenseError::Config(e) => e.fmt(f),
        }
    }
}
