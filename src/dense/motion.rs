//! The motion mask and moving-object boxes: [`MotionDetector`].

use super::grid::{grid_len, GridLayout, GridNode, NodeStatus};
use super::mask::{
    mask_close, mask_count, mask_open, mask_set, mask_words, words_for, MaskStructure,
};
use super::regions::{find_boxes, BoxRules, MotionBox};
use crate::ego::Homography;
use crate::{Bound, ConfigError};

/// The flow the camera's own motion gives each pixel.
///
/// [`CameraMotion::flow_at`] is a displacement, not a position: the static scene at (`x`, `y`)
/// in the previous frame is at (`x + dx`, `y + dy`) in the next. Positions are what
/// [`Homography::apply`], [`Camera::predict`](crate::ego::Camera::predict) and the tracker's
/// `predict` give.
///
/// Implemented by [`DominantMotion`](super::DominantMotion), fitted to the grid, and
/// by [`Homography`], such as the ego-motion fitted to the tracks; implement it for another
/// model (a gyro-predicted rotation) to use that model for the mask instead.
///
/// ```
/// use kestrel::dense::CameraMotion;
/// struct Pan(f32);
/// impl CameraMotion for Pan {
///     fn flow_at(&self, _x: f32, _y: f32) -> (f32, f32) {
///         (self.0, 0.0)
///     }
/// }
/// assert_eq!(Pan(1.5).flow_at(10.0, 20.0), (1.5, 0.0));
/// ```
pub trait CameraMotion {
    /// The flow `(dx, dy)`, px, of the static scene at pixel (`x`, `y`) of the previous frame:
    /// how far that pixel moves to the next frame.
    fn flow_at(&self, x: f32, y: f32) -> (f32, f32);
}

/// The flow a homography of the camera's motion (previous frame to next) gives each pixel.
/// A pixel it cannot map (behind the camera: not the case of a fitted frame-to-frame model)
/// gets a zero flow: it is taken as still.
///
/// ```
/// use kestrel::dense::CameraMotion;
/// use kestrel::ego::Homography;
/// let pan = Homography::translation(1.5, -0.5).unwrap();
/// // The homography maps a pixel to its position; its flow is the difference.
/// assert_eq!(pan.apply((10.0, 20.0)), Some((11.5, 19.5)));
/// assert_eq!(pan.flow_at(10.0, 20.0), (1.5, -0.5));
/// ```
impl CameraMotion for Homography {
    fn flow_at(&self, x: f32, y: f32) -> (f32, f32) {
        self.apply((x, y))
            .map_or((0.0, 0.0), |(u, v)| (u - x, v - y))
    }
}

/// `u32` words of scratch [`MotionDetector::detect`] needs: a second mask for the morphology
/// and the region search, and a flood-fill stack of one word per node.
///
/// ```
/// use kestrel::dense::motion_scratch_len;
/// static mut SCRATCH: [u32; motion_scratch_len(160, 120, 8)] = [0; motion_scratch_len(160, 120, 8)];
/// assert_eq!(motion_scratch_len(160, 120, 8), 10 + 300);
/// ```
pub const fn motion_scratch_len(width: usize, height: usize, cell: usize) -> usize {
    mask_words(width, height, cell).saturating_add(grid_len(width, height, cell))
}

/// Motion-detection parameters.
///
/// ```
/// use kestrel::dense::{
///     DominantMotion, GridLayout, GridNode, MotionDetector, MotionParams, NodeStatus,
/// };
/// use kestrel::Point;
///
/// // A still camera: one node moves 0.5 px, another 1.5 px, and a filled one 1.5 px.
/// let layout = GridLayout::new(24, 8, 8).unwrap();
/// let filled = GridNode { status: NodeStatus::Filled, ..GridNode::tracked(Point::from_f32(1.5, 0.0)) };
/// let nodes = [
///     GridNode::tracked(Point::from_f32(0.5, 0.0)),
///     GridNode::tracked(Point::from_f32(0.0, 1.5)),
///     filled,
/// ];
/// let moving = |params| {
///     let detector = MotionDetector::new(params).unwrap();
///     detector.mark(&layout, &nodes, &DominantMotion::ZERO, &mut [0u32]).unwrap()
/// };
/// let default = MotionParams::default();
/// assert_eq!(moving(default), 1);
/// assert_eq!(moving(MotionParams { threshold: 0.4, ..default }), 2);
/// assert_eq!(moving(MotionParams { include_filled: true, ..default }), 2);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionParams {
    /// A node moves when its flow differs from the camera's by more than this, px. The
    /// default, 0.8, sits well above the scatter of the static scene's flow (about 0.2 px) and
    /// below the slowest motion worth reporting, a pixel per frame.
    pub threshold: f32,
    /// Whether filled nodes may move (their flow is their neighbours' median); measured nodes
    /// always may. Off by default: a filled node beside an object takes the object's flow and
    /// glues neighbouring regions together.
    pub include_filled: bool,
    /// Closing of the raw mask; `None` (the default) skips it. With 9 px windows on an 8 px
    /// grid the raw mask already overhangs each object by about a node, so a 3 x 3 closing
    /// merges objects less than about three cells apart.
    pub close: Option<MaskStructure>,
    /// Opening after the closing; `None` (the default) skips it: a 3 x 3 opening removes every
    /// region narrower than three nodes, which on an 8 px grid is every object under about
    /// 24 px. [`BoxRules::min_nodes`] removes specks instead.
    pub open: Option<MaskStructure>,
    /// Which regions give boxes, and how.
    pub boxes: BoxRules,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            threshold: 0.8,
            include_filled: false,
            close: None,
            open: None,
            boxes: BoxRules::default(),
        }
    }
}

/// What one [`MotionDetector::detect`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionSummary {
    /// Nodes in the cleaned mask.
    pub moving: usize,
    /// Regions of at least [`BoxRules::min_nodes`] nodes.
    pub regions: usize,
    /// Boxes written (the largest regions, at most the output's length).
    pub boxes: usize,
}

/// The motion mask and moving-object boxes: a validated motion detector.
///
/// A node moves on its own when its flow differs from the flow the camera gives it by more
/// than a threshold ([`MotionParams::threshold`]). The camera's flow comes from a
/// [`CameraMotion`]: for a still camera [`DominantMotion::ZERO`] (the test is then the flow's
/// magnitude), for a moving one the [`DominantMotion`] fitted to the same grid, or any better
/// model such as a homography from the ego-motion estimator. The raw mask is closed and opened
/// on the grid ([`mask_close`], [`mask_open`]), and its connected regions of at least a minimum
/// size become boxes ([`find_boxes`]).
///
/// [`DominantMotion`]: super::DominantMotion
/// [`DominantMotion::ZERO`]: super::DominantMotion::ZERO
///
/// ```
/// use kestrel::dense::{
///     grid_len, mask_words, motion_scratch_len, DominantFitParams, DominantMotion, GridLayout,
///     GridNode, MotionBox, MotionDetector, MotionParams,
/// };
/// use kestrel::Point;
///
/// // The camera pans 2 px left; a 3 x 2 block of nodes moves 3 px down besides.
/// let layout = GridLayout::new(96, 64, 8).unwrap();
/// let mut nodes = [GridNode::tracked(Point::from_f32(-2.0, 0.0)); grid_len(96, 64, 8)];
/// for (col, row) in [(4, 3), (5, 3), (6, 3), (4, 4), (5, 4), (6, 4)] {
///     nodes[layout.index(col, row).unwrap()] = GridNode::tracked(Point::from_f32(-2.0, 3.0));
/// }
/// let camera = DominantMotion::fit(&layout, &nodes, &DominantFitParams::default()).unwrap().motion;
///
/// let detector = MotionDetector::new(MotionParams::default()).unwrap();
/// let mut mask = [0u32; mask_words(96, 64, 8)];
/// let mut scratch = [0u32; motion_scratch_len(96, 64, 8)];
/// let mut boxes = [MotionBox::default(); 4];
/// let found = detector
///     .detect(&layout, &nodes, &camera, &mut mask, &mut scratch, &mut boxes)
///     .unwrap();
/// assert_eq!(found.boxes, 1);
/// // The block's cells, inset by 4 px on every side.
/// assert_eq!((boxes[0].x, boxes[0].y, boxes[0].w, boxes[0].h), (36, 28, 16, 8));
/// ```
#[derive(Debug, Clone, Copy)]
pub struct MotionDetector {
    params: MotionParams,
}

impl MotionDetector {
    /// Validates `params`: the threshold is a finite number >= 0.
    ///
    /// ```
    /// use kestrel::dense::{MotionDetector, MotionParams};
    /// use kestrel::{Bound, ConfigError};
    /// let bad = MotionParams { threshold: -1.0, ..MotionParams::default() };
    /// let refused = MotionDetector::new(bad).unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "threshold", bound: Bound::FiniteNonNegative });
    /// assert_eq!(refused.to_string(), "threshold must be a finite number >= 0");
    /// ```
    pub fn new(params: MotionParams) -> Result<Self, ConfigError> {
        if !params.threshold.is_finite() || params.threshold < 0.0 {
            return Err(ConfigError::new("threshold", Bound::FiniteNonNegative));
        }
        Ok(Self { params })
    }

    /// The parameters this detector was built with.
    ///
    /// ```
    /// use kestrel::dense::{MotionDetector, MotionParams};
    /// let params = MotionParams { threshold: 1.2, include_filled: true, ..MotionParams::default() };
    /// let detector = MotionDetector::new(params).unwrap();
    /// assert_eq!(*detector.params(), params);
    /// ```
    pub fn params(&self) -> &MotionParams {
        &self.params
    }

    /// Writes the raw motion mask of `nodes` into `mask` ([`mask_words`] words) and returns the
    /// number of moving nodes. A `mask` or `nodes` shorter than the layout is refused by
    /// name.
    ///
    /// ```
    /// use kestrel::dense::{DominantMotion, GridLayout, GridNode, MotionDetector, MotionParams};
    /// use kestrel::Point;
    /// let layout = GridLayout::new(16, 8, 8).unwrap();
    /// let nodes = [GridNode::tracked(Point::from_f32(0.5, 0.0)), GridNode::tracked(Point::from_f32(0.0, 1.5))];
    /// let detector = MotionDetector::new(MotionParams::default()).unwrap();
    /// let mut mask = [0u32];
    /// assert_eq!(detector.mark(&layout, &nodes, &DominantMotion::ZERO, &mut mask), Ok(1));
    /// assert_eq!(mask, [0b10]);
    /// ```
    pub fn mark(
        &self,
        layout: &GridLayout,
        nodes: &[GridNode],
        camera: &impl CameraMotion,
        mask: &mut [u32],
    ) -> Result<usize, ConfigError> {
        let words = words_for(layout.len());
        if mask.len() < words {
            return Err(ConfigError::min_len("mask", words));
        }
        if nodes.len() < layout.len() {
            return Err(ConfigError::min_len("nodes", layout.len()));
        }
        let limit = self.params.threshold * self.params.threshold;
        let mut moving = 0usize;
        for (index, node) in nodes.iter().take(layout.len()).enumerate() {
            let moves = self.counts(node) && self.residual_sq(layout, index, node, camera) > limit;
            mask_set(mask, index, moves);
            moving = moving.saturating_add(usize::from(moves));
        }
        Ok(moving)
    }

    /// Marks the moving nodes, cleans the mask, and writes the boxes of its regions into
    /// `boxes`, largest first. `mask` ([`mask_words`] words) holds the cleaned mask afterwards;
    /// `scratch` is [`motion_scratch_len`] words. A shorter `scratch`, `mask` or `nodes` is
    /// refused by name. See [`MotionDetector`]'s example.
    ///
    /// No box is reported, and the mask is cleared, when the nodes cannot tell an object from
    /// the camera: when fewer than a quarter of the grid's nodes take part (a dark, blown-out
    /// or featureless frame, where the few measured nodes are as likely mismeasured as moving),
    /// or when most of those that take part move (the camera motion describes nothing: the
    /// frames do not show one scene). A box says "this moves unlike the rest", and there is no
    /// rest to compare with.
    pub fn detect(
        &self,
        layout: &GridLayout,
        nodes: &[GridNode],
        camera: &impl CameraMotion,
        mask: &mut [u32],
        scratch: &mut [u32],
        boxes: &mut [MotionBox],
    ) -> Result<MotionSummary, ConfigError> {
        let words = words_for(layout.len());
        let needed = words.saturating_add(layout.len());
        if scratch.len() < needed {
            return Err(ConfigError::min_len("scratch", needed));
        }
        let (temp, stack) = scratch.split_at_mut(words);
        let moving = self.mark(layout, nodes, camera, mask)?;
        let taking_part = nodes
            .iter()
            .take(layout.len())
            .filter(|n| self.counts(n))
            .count();
        if taking_part < layout.len().div_ceil(4) || moving > taking_part / 2 {
            mask.iter_mut().for_each(|w| *w = 0);
            return Ok(MotionSummary::default());
        }
        if let Some(structure) = self.params.close {
            mask_close(layout, mask, temp, structure)?;
        }
        if let Some(structure) = self.params.open {
            mask_open(layout, mask, temp, structure)?;
        }
        let found = find_boxes(layout, nodes, mask, temp, stack, &self.params.boxes, boxes)?;
        Ok(MotionSummary {
            moving: mask_count(mask, layout.len()),
            regions: found.regions,
            boxes: found.boxes,
        })
    }

    /// Whether `node`'s flow takes part in the mask.
    fn counts(&self, node: &GridNode) -> bool {
        match node.status {
            NodeStatus::Tracked => true,
            NodeStatus::Filled => self.params.include_filled,
            _ => false,
        }
    }

    /// Squared distance between the node's flow and the camera's flow at its centre.
    fn residual_sq(
        &self,
        layout: &GridLayout,
        index: usize,
        node: &GridNode,
        camera: &impl CameraMotion,
    ) -> f32 {
        let (col, row) = layout.node(index);
        let (x, y) = layout.centre(col, row);
        let (cx, cy) = camera.flow_at(x as f32, y as f32);
        let (dx, dy) = node.flow.to_f32();
        let (rx, ry) = (dx - cx, dy - cy);
        let r2 = rx * rx + ry * ry;
        // A camera model whose flow is NaN says nothing: the node does not move.
        if r2.is_nan() {
            0.0
        } else {
            r2
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dense::dominant::DominantMotion;
    use crate::q16::Point;

    #[test]
    fn short_buffers_are_errors() {
        let layout = GridLayout::new(64, 64, 8).unwrap();
        let nodes = [GridNode::EMPTY; 64];
        let detector = MotionDetector::new(MotionParams::default()).unwrap();
        let camera = DominantMotion::ZERO;
        let mut boxes = [MotionBox::default(); 2];
        let mut scratch = [0u32; motion_scratch_len(64, 64, 8)];
        assert_eq!(
            detector.detect(
                &layout,
                &nodes,
                &camera,
                &mut [0; 1],
                &mut scratch,
                &mut boxes
            ),
            Err(ConfigError::min_len("mask", 2))
        );
        assert_eq!(
            detector.detect(
                &layout,
                &nodes,
                &camera,
                &mut [0; 2],
                &mut scratch[..65],
                &mut boxes
            ),
            Err(ConfigError::min_len("scratch", 66))
        );
        assert_eq!(
            detector.detect(
                &layout,
                &nodes[..63],
                &camera,
                &mut [0; 2],
                &mut scratch,
                &mut boxes
            ),
            Err(ConfigError::min_len("nodes", 64))
        );
    }

    #[test]
    fn no_boxes_without_a_static_majority_or_with_few_measured_nodes() {
        // An 8 x 8 grid of 64 nodes, a quarter of which is 16.
        let layout = GridLayout::new(64, 64, 8).unwrap();
        let detector = MotionDetector::new(MotionParams::default()).unwrap();
        let camera = DominantMotion::ZERO;
        let boxes = |moving: &dyn Fn(usize) -> bool, still: &dyn Fn(usize) -> bool| {
            let nodes: [GridNode; 64] = core::array::from_fn(|i| {
                if moving(i) {
                    GridNode::tracked(Point::from_f32(4.0, 0.0))
                } else if still(i) {
                    GridNode::tracked(Point::default())
                } else {
                    GridNode::EMPTY
                }
            });
            let mut mask = [0u32; 2];
            let mut scratch = [0u32; motion_scratch_len(64, 64, 8)];
            let mut boxes = [MotionBox::default(); 4];
            let summary = detector
                .detect(
                    &layout,
                    &nodes,
                    &camera,
                    &mut mask,
                    &mut scratch,
                    &mut boxes,
                )
                .unwrap();
            (summary.boxes, mask)
        };
        // A 3 x 3 block moves.
        let block = |i: usize| (2..5).contains(&(i % 8)) && (2..5).contains(&(i / 8));
        assert_eq!(boxes(&block, &|_| true).0, 1);
        // With 9 still nodes the block is half of what is measured: one box; with 8 the
        // moving nodes are the majority: none, and the mask is cleared.
        assert_eq!(boxes(&block, &|i| i < 9).0, 1);
        assert_eq!(boxes(&block, &|i| i < 8), (0, [0, 0]));
        // Three moving nodes in a row and 13 still ones: 16 measured, one box; with 12 still
        // ones, 15 measured are too few.
        let row = |i: usize| (18..21).contains(&i);
        assert_eq!(boxes(&row, &|i| i < 13).0, 1);
        assert_eq!(boxes(&row, &|i| i < 12).0, 0);
    }

    #[test]
    fn invalid_nodes_never_move_and_filled_ones_only_when_asked() {
        let layout = GridLayout::new(24, 8, 8).unwrap();
        let fast = Point::from_f32(5.0, 0.0);
        let nodes = [
            GridNode {
                flow: fast,
                status: NodeStatus::Filled,
                fill_pass: 1,
            },
            GridNode {
                flow: fast,
                status: NodeStatus::Residual,
                fill_pass: 0,
            },
            GridNode::tracked(fast),
        ];
        let camera = DominantMotion::ZERO;
        let mut mask = [0u32];
        let without = MotionDetector::new(MotionParams::default()).unwrap();
        assert_eq!(without.mark(&layout, &nodes, &camera, &mut mask), Ok(1));
        assert_eq!(mask, [0b100]);
        let with = MotionDetector::new(MotionParams {
            include_filled: true,
            ..MotionParams::default()
        })
        .unwrap();
        assert_eq!(with.mark(&layout, &nodes, &camera, &mut mask), Ok(2));
        assert_eq!(mask, [0b101]);
    }

    #[test]
    fn a_nan_camera_marks_nothing() {
        struct Broken;
        impl CameraMotion for Broken {
            fn flow_at(&self, _: f32, _: f32) -> (f32, f32) {
                (f32::NAN, 0.0)
            }
        }
        let layout = GridLayout::new(16, 8, 8).unwrap();
        let nodes = [GridNode::tracked(Point::from_f32(9.0, 9.0)); 2];
        let detector = MotionDetector::new(MotionParams::default()).unwrap();
        assert_eq!(detector.mark(&layout, &nodes, &Broken, &mut [0]), Ok(0));
    }
}
