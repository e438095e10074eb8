//! Flow at every node of a regular grid: [`DenseFlow`], and the [`GridLayout`] of its nodes.

use super::agreement::agreement;
use super::fill::fill_invalid;
use super::{lk_refusal, DenseError};
use crate::config_error::bound_number;
use crate::lk::{scratch_len, LkParams, LucasKanade, TrackStatus, LK_PATHS};
use crate::pyramid::{level_size, Pyramid};
use crate::q16::Point;
use crate::{Bound, ConfigError};

/// Nodes along one side of `size` px with `cell` px cells: the centres `cell/2 + k·cell` that lie
/// inside `0..size`. Zero when `cell` is zero.
///
/// ```
/// use kestrel::dense::grid_side;
/// assert_eq!(grid_side(160, 8), 20);
/// assert_eq!(grid_side(101, 8), 13); // the 13th centre, 100, is the last pixel
/// assert_eq!(grid_side(100, 8), 12);
/// assert_eq!(grid_side(5, 0), 0);
/// ```
pub const fn grid_side(size: usize, cell: usize) -> usize {
    if cell == 0 || size <= cell / 2 {
        return 0;
    }
    // cell >= 1 and size > cell / 2: no underflow, no division by zero.
    match size
        .saturating_sub(1)
        .saturating_sub(cell / 2)
        .checked_div(cell)
    {
        Some(before_last) => before_last.saturating_add(1),
        None => 0,
    }
}

/// Nodes of the grid over a `width` x `height` frame with `cell` px cells: the length of the
/// node slice [`DenseFlow::compute`] fills.
///
/// ```
/// use kestrel::dense::{grid_len, GridNode};
/// static mut NODES: [GridNode; grid_len(160, 120, 8)] = [GridNode::EMPTY; grid_len(160, 120, 8)];
/// assert_eq!(grid_len(160, 120, 8), 300);
/// assert_eq!(grid_len(320, 240, 8), 1200);
/// ```
pub const fn grid_len(width: usize, height: usize, cell: usize) -> usize {
    grid_side(width, cell).saturating_mul(grid_side(height, cell))
}

/// The geometry of a grid: frame size, cell size, and the nodes' columns and rows.
///
/// ```
/// use kestrel::dense::GridLayout;
/// let layout = GridLayout::new(160, 120, 8).unwrap();
/// assert_eq!((layout.cols(), layout.rows(), layout.len()), (20, 15, 300));
/// assert_eq!(layout.centre(0, 0), (4, 4));
/// assert_eq!(layout.centre(19, 14), (156, 116));
/// assert_eq!(layout.index(1, 2), Some(41));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridLayout {
    width: usize,
    height: usize,
    cell: usize,
    cols: usize,
    rows: usize,
}

impl GridLayout {
    /// The grid of `cell` px cells over a `width` x `height` frame: `cell` is at least 1 and
    /// at most the frame's smaller side.
    ///
    /// ```
    /// use kestrel::dense::GridLayout;
    /// use kestrel::{Bound, ConfigError};
    /// let cells = Bound::Range { min: 1, max: 120 };
    /// assert_eq!(GridLayout::new(160, 120, 0), Err(ConfigError { field: "cell", bound: cells }));
    /// let refused = GridLayout::new(160, 120, 121).unwrap_err();
    /// assert_eq!(refused.to_string(), "cell must be 1 to 120");
    /// assert!(GridLayout::new(160, 120, 120).is_ok());
    /// ```
    pub const fn new(width: usize, height: usize, cell: usize) -> Result<Self, ConfigError> {
        if cell == 0 || cell > width || cell > height {
            let side = if width < height { width } else { height };
            let bound = Bound::Range {
                min: 1,
                max: bound_number(side),
            };
            return Err(ConfigError::new("cell", bound));
        }
        Ok(Self {
            width,
            height,
            cell,
            cols: grid_side(width, cell),
            rows: grid_side(height, cell),
        })
    }

    /// Frame width, px.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(160, 120, 8).unwrap().width(), 160);
    /// ```
    pub const fn width(&self) -> usize {
        self.width
    }

    /// Frame height, px.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(160, 120, 8).unwrap().height(), 120);
    /// ```
    pub const fn height(&self) -> usize {
        self.height
    }

    /// Cell side, px: the distance between neighbouring nodes.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(160, 120, 8).unwrap().cell(), 8);
    /// ```
    pub const fn cell(&self) -> usize {
        self.cell
    }

    /// Node columns.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(100, 50, 8).unwrap().cols(), 12);
    /// ```
    pub const fn cols(&self) -> usize {
        self.cols
    }

    /// Node rows.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(100, 50, 8).unwrap().rows(), 6);
    /// ```
    pub const fn rows(&self) -> usize {
        self.rows
    }

    /// Number of nodes, [`grid_len`] of the frame and cell.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(100, 50, 8).unwrap().len(), 72);
    /// ```
    pub const fn len(&self) -> usize {
        self.cols.saturating_mul(self.rows)
    }

    /// True when the grid has no node (never, for a layout [`GridLayout::new`] accepted).
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert!(!GridLayout::new(8, 8, 8).unwrap().is_empty());
    /// ```
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The pixel at the centre of node (`col`, `row`).
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(64, 64, 16).unwrap().centre(1, 3), (24, 56));
    /// ```
    pub const fn centre(&self, col: usize, row: usize) -> (usize, usize) {
        (
            (self.cell / 2).saturating_add(col.saturating_mul(self.cell)),
            (self.cell / 2).saturating_add(row.saturating_mul(self.cell)),
        )
    }

    /// The index of node (`col`, `row`) in a node slice (row by row), `None` off the grid.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// let layout = GridLayout::new(64, 64, 16).unwrap();
    /// assert_eq!(layout.index(3, 3), Some(15));
    /// assert_eq!(layout.index(4, 0), None);
    /// ```
    pub const fn index(&self, col: usize, row: usize) -> Option<usize> {
        if col < self.cols && row < self.rows {
            // Below cols x rows, the grid's length.
            Some(row.saturating_mul(self.cols).saturating_add(col))
        } else {
            None
        }
    }

    /// The column and row of the node at `index`.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// assert_eq!(GridLayout::new(64, 64, 16).unwrap().node(6), (2, 1));
    /// ```
    pub const fn node(&self, index: usize) -> (usize, usize) {
        // `cols` is at least 1 for an accepted layout; the guard keeps the division panic-free.
        match (index.checked_rem(self.cols), index.checked_div(self.cols)) {
            (Some(col), Some(row)) => (col, row),
            _ => (0, 0),
        }
    }

    /// The index of the node `offset` (columns, rows) away from node `index`; `None` off the
    /// grid.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// let layout = GridLayout::new(64, 64, 16).unwrap();
    /// assert_eq!(layout.neighbour(5, (1, 1)), Some(10));
    /// assert_eq!(layout.neighbour(4, (-1, 0)), None);
    /// ```
    pub fn neighbour(&self, index: usize, (dc, dr): (isize, isize)) -> Option<usize> {
        let (col, row) = self.node(index);
        self.index(col.checked_add_signed(dc)?, row.checked_add_signed(dr)?)
    }

    /// The pixels of node (`col`, `row`)'s cell, clipped to the frame: `(x, y, width, height)`.
    ///
    /// ```
    /// # use kestrel::dense::GridLayout;
    /// let layout = GridLayout::new(100, 50, 8).unwrap();
    /// assert_eq!(layout.cell_rect(0, 0), (0, 0, 8, 8));
    /// assert_eq!(layout.cell_rect(11, 5), (88, 40, 8, 8));
    /// ```
    pub fn cell_rect(&self, col: usize, row: usize) -> (usize, usize, usize, usize) {
        self.span_rect(col, row, col, row)
    }

    /// The pixels covered by the cells of columns `c0..=c1` and rows `r0..=r1`, clipped to the
    /// frame: `(x, y, width, height)`.
    pub(crate) fn span_rect(
        &self,
        c0: usize,
        r0: usize,
        c1: usize,
        r1: usize,
    ) -> (usize, usize, usize, usize) {
        let edge = |k: usize, size: usize| k.saturating_mul(self.cell).min(size);
        let x = edge(c0, self.width);
        let y = edge(r0, self.height);
        let right = edge(c1.saturating_add(1), self.width);
        let bottom = edge(r1.saturating_add(1), self.height);
        (x, y, right.saturating_sub(x), bottom.saturating_sub(y))
    }
}

/// The camera check's verdict on one node.
enum CameraCheck {
    /// The node moves as predicted: it takes the prediction.
    Confirmed,
    /// The window is too flat for the check, and [`DenseParams::search_flat`] is off.
    Flat,
    /// LK decides.
    Search,
}

/// The eight neighbours of a node, as (column, row) offsets.
pub(crate) const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// What is known about one node's flow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NodeStatus {
    /// Measured: LK converged inside the frame with a residual under the gate.
    Tracked,
    /// The window is too flat to measure flow.
    LowTexture,
    /// LK converged, but the window's residual is above the gate.
    Residual,
    /// LK did not converge, or the node or its estimate left the frame.
    #[default]
    Lost,
    /// Invalid, then filled from valid neighbours: usable for pictures and masks, not a
    /// measurement.
    Filled,
}

/// The flow at one grid node.
///
/// ```
/// use kestrel::dense::{GridNode, NodeStatus};
/// use kestrel::Point;
/// let node = GridNode::tracked(Point::from_f32(1.5, -0.25));
/// assert!(node.is_valid() && node.has_flow());
/// assert!(!GridNode::EMPTY.has_flow());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridNode {
    /// Displacement of the node's centre from the previous frame to the next, px. Zero for
    /// nodes that are neither tracked nor filled.
    pub flow: Point,
    /// Whether the flow was measured, filled, or is unknown and why.
    pub status: NodeStatus,
    /// For a filled node, the fill pass that filled it: 1 next to a measured node, 2 one node
    /// further, and so on. 0 for every other node.
    pub fill_pass: u8,
}

impl GridNode {
    /// A node without flow ([`NodeStatus::Lost`]), for initialising static buffers.
    pub const EMPTY: Self = Self {
        flow: Point::from_bits(0, 0),
        status: NodeStatus::Lost,
        fill_pass: 0,
    };

    /// A measured node.
    ///
    /// ```
    /// use kestrel::dense::{GridNode, NodeStatus};
    /// assert_eq!(GridNode::tracked(Default::default()).status, NodeStatus::Tracked);
    /// ```
    pub const fn tracked(flow: Point) -> Self {
        Self {
            flow,
            status: NodeStatus::Tracked,
            fill_pass: 0,
        }
    }

    /// A node whose flow is unknown for `status`'s reason.
    ///
    /// ```
    /// use kestrel::dense::{GridNode, NodeStatus};
    /// assert!(!GridNode::invalid(NodeStatus::LowTexture).is_valid());
    /// ```
    pub const fn invalid(status: NodeStatus) -> Self {
        Self {
            status,
            ..Self::EMPTY
        }
    }

    /// True when the flow was measured ([`NodeStatus::Tracked`]).
    ///
    /// ```
    /// use kestrel::dense::{GridNode, NodeStatus};
    /// assert!(!GridNode { status: NodeStatus::Filled, ..GridNode::EMPTY }.is_valid());
    /// ```
    pub fn is_valid(&self) -> bool {
        self.status == NodeStatus::Tracked
    }

    /// True when the node has a flow, measured or filled.
    ///
    /// ```
    /// use kestrel::dense::{GridNode, NodeStatus};
    /// assert!(GridNode { status: NodeStatus::Filled, ..GridNode::EMPTY }.has_flow());
    /// ```
    pub fn has_flow(&self) -> bool {
        matches!(self.status, NodeStatus::Tracked | NodeStatus::Filled)
    }
}

/// Dense-mode parameters.
///
/// ```
/// use kestrel::dense::{DenseFlow, DenseParams};
/// use kestrel::{Bound, ConfigError};
/// // A node every `cell` px: over a 64 x 48 frame, 8 x 6 nodes for 8 px, 4 x 3 for 16 px.
/// let nodes = |cell| {
///     let dense = DenseFlow::new(DenseParams { cell, ..DenseParams::default() }).unwrap();
///     let layout = dense.layout(64, 48).unwrap();
///     (layout.cols(), layout.rows())
/// };
/// assert_eq!(nodes(8), (8, 6));
/// assert_eq!(nodes(16), (4, 3));
/// // The camera check's tolerance is at most a pixel.
/// let loose = DenseParams { camera_tolerance: 1.5, ..DenseParams::default() };
/// let refused = DenseFlow::new(loose).unwrap_err();
/// assert_eq!(refused, ConfigError { field: "camera_tolerance", bound: Bound::Range { min: 0, max: 1 } });
/// assert_eq!(refused.to_string(), "camera_tolerance must be 0 to 1");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DenseParams {
    /// Grid spacing, px (at least 1, at most the frame's smaller side).
    pub cell: usize,
    /// The LK tracker's parameters; dense mode defaults to a 9 x 9 window and a minimum
    /// eigenvalue of [`DenseParams::DEFAULT_MIN_EIGEN`].
    pub lk: LkParams,
    /// Residual gate, grey levels: a converged node whose mean absolute residual (after the
    /// gain and bias correction) is above it is [`NodeStatus::Residual`].
    pub max_residual: f32,
    /// Passes of [`fill_invalid`] after tracking; 0 leaves invalid nodes empty.
    pub fill_passes: u8,
    /// With a prediction ([`DenseFlow::compute_predicted`]), the camera check's tolerance, px:
    /// a node whose window, moved as predicted, mismatches the next frame by at most this share
    /// of its own texture (the mismatch of a one-pixel shift) takes the predicted flow without
    /// an LK search. 0 searches every node; so do windows wider than 12 px.
    pub camera_tolerance: f32,
    /// With the camera check on, whether a window too flat for it (its neighbouring pixels
    /// differ by less than 2 grey levels on average along its weaker direction) is still
    /// searched by LK (`true`), or marked [`NodeStatus::LowTexture`] at once (`false`). LK
    /// measures some of those windows; skipping them saves LK searches where a grid is mostly
    /// flat (README, Dense grid and moving objects).
    pub search_flat: bool,
}

impl DenseParams {
    /// The default LK window in dense mode, px.
    pub const DEFAULT_WINDOW: usize = 9;
    /// The default LK minimum eigenvalue in dense mode, in OpenCV's scale (see
    /// [`LkParams::min_eigen_threshold`]): gradients of about 0.85 grey levels per pixel. Weaker
    /// windows measure within a few tenths of a pixel, which [`smooth_tracked`] brings down
    /// where their neighbours move alike; below it, three quarters of a textured frame's
    /// nodes are measured.
    ///
    /// [`smooth_tracked`]: super::smooth_tracked
    pub const DEFAULT_MIN_EIGEN: f32 = 7e-4;
    /// The minimum eigenvalue for motion detection: gradients of about 1.7 grey levels per
    /// pixel. A weak window's error looks like motion of its own to the mask, so motion
    /// detection measures only the nodes it can trust.
    pub const MOTION_MIN_EIGEN: f32 = 3e-3;

    /// The defaults with [`DenseParams::MOTION_MIN_EIGEN`]: what
    /// [`MotionDetector`](super::MotionDetector)'s callers track the grid with.
    ///
    /// ```
    /// use kestrel::dense::DenseParams;
    /// let (grid, motion) = (DenseParams::default(), DenseParams::for_motion());
    /// assert!(motion.lk.min_eigen_threshold > grid.lk.min_eigen_threshold);
    /// assert_eq!(DenseParams { lk: grid.lk, ..motion }, grid);
    /// ```
    pub fn for_motion() -> Self {
        let defaults = Self::default();
        Self {
            lk: LkParams {
                min_eigen_threshold: Self::MOTION_MIN_EIGEN,
                ..defaults.lk
            },
            ..defaults
        }
    }
}

impl Default for DenseParams {
    fn default() -> Self {
        Self {
            cell: 8,
            lk: LkParams {
                window: Self::DEFAULT_WINDOW,
                min_eigen_threshold: Self::DEFAULT_MIN_EIGEN,
                ..LkParams::default()
            },
            max_residual: 12.0,
            fill_passes: 2,
            camera_tolerance: 0.25,
            search_flat: true,
        }
    }
}

/// What one [`DenseFlow::compute`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DenseSummary {
    /// The grid the nodes were written for.
    pub layout: GridLayout,
    /// Nodes measured ([`NodeStatus::Tracked`]).
    pub tracked: usize,
    /// Nodes filled from their neighbours ([`NodeStatus::Filled`]).
    pub filled: usize,
}

/// Flow at every node of a regular grid: a validated dense-flow configuration.
///
/// A `cell` x `cell` grid covers the frame; its nodes sit at the cell centres,
/// `(cell/2 + i·cell, cell/2 + j·cell)`, for every centre inside the frame (so a partial last
/// cell still has a node when its centre fits): see [`GridLayout`]. Each node is tracked from
/// the previous frame to the next by the core pyramidal LK ([`LucasKanade::track_point`]) and
/// classified:
///
/// - [`NodeStatus::Tracked`]: converged, inside the frame, residual under the gate;
/// - [`NodeStatus::LowTexture`]: the window is too flat to say anything;
/// - [`NodeStatus::Residual`]: converged, but the window does not match (occlusion, a moving
///   edge, a reflection): the flow is not trusted;
/// - [`NodeStatus::Lost`]: the iterations did not converge, or the node left the frame;
/// - [`NodeStatus::Filled`]: was invalid, then filled from valid neighbours ([`fill_invalid`]).
///
/// Dense mode wants smaller windows than sparse tracking: a node's window should see one
/// surface, not the object and the background around it. The default is 9 x 9 on an 8 px grid
/// ([`DenseParams`]).
///
/// ```
/// use kestrel::dense::{grid_len, DenseFlow, DenseParams, GridNode};
/// use kestrel::ImageView;
/// use kestrel::lk::scratch_len;
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
///
/// const W: usize = 64;
/// const H: usize = 48;
/// // A textured frame and the same texture 1 px to the right.
/// let texture = |x: usize, y: usize| ((x * 37 + y * 91 + (x * y) % 13 * 17) % 251) as u8;
/// let a: [u8; W * H] = core::array::from_fn(|i| texture(i % W + 1, i / W));
/// let b: [u8; W * H] = core::array::from_fn(|i| texture(i % W, i / W));
/// let mut storage_a = [0u8; pyramid_storage_len(W, H, 1)];
/// let mut storage_b = [0u8; pyramid_storage_len(W, H, 1)];
/// let prev = Pyramid::build(ImageView::packed(&a, W, H).unwrap(), 1, &mut storage_a).unwrap();
/// let next = Pyramid::build(ImageView::packed(&b, W, H).unwrap(), 1, &mut storage_b).unwrap();
///
/// let dense = DenseFlow::new(DenseParams { cell: 16, ..DenseParams::default() }).unwrap();
/// let mut nodes = [GridNode::default(); grid_len(W, H, 16)];
/// let mut scratch = [0i16; scratch_len(DenseParams::DEFAULT_WINDOW)];
/// let summary = dense.compute(&prev, &next, &mut nodes, &mut scratch).unwrap();
/// assert_eq!((summary.layout.cols(), summary.layout.rows()), (4, 3));
/// ```
#[derive(Debug, Clone, Copy)]
pub struct DenseFlow {
    params: DenseParams,
    /// [`DenseParams::camera_tolerance`], Q8; 0 when off.
    camera_tolerance: u32,
    lk: LucasKanade,
    /// The same on the finest level only, for searches from a prediction.
    fine: LucasKanade,
}

impl DenseFlow {
    /// Validates `params`; a refusal names `"cell"`, `"max_residual"`, `"camera_tolerance"` or
    /// the LK setting (`"lk.window"`, ...).
    ///
    /// ```
    /// use kestrel::dense::{DenseFlow, DenseParams};
    /// use kestrel::{Bound, ConfigError};
    /// assert!(DenseFlow::new(DenseParams::default()).is_ok());
    /// let zero = DenseParams { cell: 0, ..DenseParams::default() };
    /// assert_eq!(DenseFlow::new(zero).unwrap_err(), ConfigError { field: "cell", bound: Bound::AtLeast(1) });
    /// let gate = DenseParams { max_residual: f32::NAN, ..DenseParams::default() };
    /// assert_eq!(DenseFlow::new(gate).unwrap_err().to_string(), "max_residual must be a finite number >= 0");
    /// let mut even = DenseParams::default();
    /// even.lk.window = 8;
    /// assert_eq!(DenseFlow::new(even).unwrap_err().to_string(), "lk.window must be odd, 3 to 63");
    /// ```
    pub fn new(params: DenseParams) -> Result<Self, ConfigError> {
        if params.cell == 0 {
            return Err(ConfigError::new("cell", Bound::AtLeast(1)));
        }
        if !params.max_residual.is_finite() || params.max_residual < 0.0 {
            return Err(ConfigError::new("max_residual", Bound::FiniteNonNegative));
        }
        // Above one pixel the check would confirm nodes that move on their own.
        if !(0.0..=1.0).contains(&params.camera_tolerance) {
            let bound = Bound::Range { min: 0, max: 1 };
            return Err(ConfigError::new("camera_tolerance", bound));
        }
        let lk = LucasKanade::new(params.lk).map_err(|e| e.nested(&LK_PATHS))?;
        let fine = lk.with_max_level(0);
        // In 0..=256 after the check above: the cast neither truncates nor saturates.
        #[allow(clippy::cast_possible_truncation)]
        let camera_tolerance = (params.camera_tolerance * 256.0) as u32;
        Ok(Self {
            params,
            camera_tolerance,
            lk,
            fine,
        })
    }

    /// The parameters this configuration was built with.
    ///
    /// ```
    /// use kestrel::dense::{DenseFlow, DenseParams};
    /// let params = DenseParams { cell: 16, fill_passes: 0, ..DenseParams::for_motion() };
    /// assert_eq!(*DenseFlow::new(params).unwrap().params(), params);
    /// ```
    pub fn params(&self) -> &DenseParams {
        &self.params
    }

    /// The grid this configuration lays over `width` x `height` frames.
    ///
    /// ```
    /// use kestrel::dense::{DenseFlow, DenseParams};
    /// let dense = DenseFlow::new(DenseParams::default()).unwrap();
    /// assert_eq!(dense.layout(320, 240).unwrap().len(), 1200);
    /// ```
    ///
    /// A cell larger than the frame's smaller side is refused as `"cell"`.
    pub fn layout(&self, width: usize, height: usize) -> Result<GridLayout, ConfigError> {
        GridLayout::new(width, height, self.params.cell)
    }

    /// Tracks every node from `prev` to `next` into `nodes` (row by row, at least
    /// [`grid_len`] long; entries beyond it are left alone), then fills invalid nodes.
    ///
    /// `scratch` is LK's, [`scratch_len`]`(params.lk.window)` values. See [`DenseFlow`]'s
    /// example. Every refusal comes before the first node is written, so an error leaves
    /// `nodes` as they were.
    pub fn compute(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        nodes: &mut [GridNode],
        scratch: &mut [i16],
    ) -> Result<DenseSummary, DenseError> {
        self.compute_with(prev, next, nodes, scratch, None)
    }

    /// [`DenseFlow::compute`] with each node's search started where `predict` takes its centre
    /// (the camera's motion, from a tracker's ego-motion or a gyro), on the finest level only.
    /// Most of a frame moves with the camera, and a search that starts within a pixel of the
    /// answer needs no coarse level; a node whose fine search fails, or lands more than
    /// [`DenseFlow::FINE_REACH`] px from the prediction (it moves on its own, or the
    /// prediction is off), is searched again as [`DenseFlow::compute`] would, on the whole
    /// pyramid from its centre; one too flat to track stays [`NodeStatus::LowTexture`], which
    /// the whole pyramid would find again at the same finest-level window.
    ///
    /// `predict` gives a position, as the tracker's `predict` does: where a node's centre in
    /// `prev` is expected in `next` (a still camera is `|p| p`), not its flow. The flow a
    /// node takes from it is that position less its centre.
    ///
    /// Before any search, the camera check ([`DenseParams::camera_tolerance`]) compares each
    /// node's window with the next frame at the prediction: where they agree to within the
    /// noise and a fraction of the window's own texture, the node takes the predicted flow
    /// (the prediction less its centre) without LK. That fraction bounds its error, in pixels along the window's weaker
    /// direction, besides the prediction's own.
    ///
    /// ```
    /// use kestrel::dense::{grid_len, DenseFlow, DenseParams, GridNode};
    /// use kestrel::ImageView;
    /// use kestrel::lk::scratch_len;
    /// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
    /// use kestrel::Point;
    /// const W: usize = 48;
    /// const H: usize = 40;
    /// let scene = |dx: f32| -> [u8; W * H] {
    ///     core::array::from_fn(|i| {
    ///         let (x, y) = ((i % W) as f32 - dx, (i / W) as f32);
    ///         (128.0 + 60.0 * (0.5 * x).sin() * (0.4 * y).cos() + 30.0 * (0.23 * (x + y)).sin()) as u8
    ///     })
    /// };
    /// let (a, b) = (scene(0.0), scene(2.5));
    /// let (mut sa, mut sb) = ([0u8; pyramid_storage_len(W, H, 2)], [0u8; pyramid_storage_len(W, H, 2)]);
    /// let prev = Pyramid::build(ImageView::packed(&a, W, H).unwrap(), 2, &mut sa).unwrap();
    /// let next = Pyramid::build(ImageView::packed(&b, W, H).unwrap(), 2, &mut sb).unwrap();
    /// let params = DenseParams { cell: 8, fill_passes: 0, ..DenseParams::default() };
    /// let searched = DenseFlow::new(DenseParams { camera_tolerance: 0.0, ..params }).unwrap();
    /// let mut nodes = [GridNode::default(); grid_len(W, H, 8)];
    /// let mut scratch = [0i16; scratch_len(9)];
    /// // The camera moved 2.5 px right; the prediction is a tenth of a pixel off.
    /// let camera = |p: Point| Point::from_f32(p.to_f32().0 + 2.4, p.to_f32().1);
    /// searched.compute_predicted(&prev, &next, &mut nodes, &mut scratch, &camera).unwrap();
    /// // Without the camera check: the same flow as the search on the whole pyramid, at a
    /// // fraction of its cost.
    /// let mut whole = nodes;
    /// searched.compute(&prev, &next, &mut whole, &mut scratch).unwrap();
    /// for (n, w) in nodes.iter().zip(&whole) {
    ///     assert_eq!(n.status, w.status);
    ///     let (dx, dy) = (n.flow.x - w.flow.x, n.flow.y - w.flow.y);
    ///     assert!(dx.abs().to_num::<f32>() < 0.02 && dy.abs().to_num::<f32>() < 0.02);
    /// }
    /// // With it (the default, a quarter of a pixel), cheaper still, and within a quarter of a
    /// // pixel of the true 2.5 px wherever it measured.
    /// let checked = DenseFlow::new(params).unwrap();
    /// checked.compute_predicted(&prev, &next, &mut nodes, &mut scratch, &camera).unwrap();
    /// for n in nodes.iter().filter(|n| n.is_valid()) {
    ///     let (dx, dy) = n.flow.to_f32();
    ///     assert!((dx - 2.5).abs() < 0.25 && dy.abs() < 0.25, "{dx} {dy}");
    /// }
    /// ```
    pub fn compute_predicted(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        nodes: &mut [GridNode],
        scratch: &mut [i16],
        predict: &dyn Fn(Point) -> Point,
    ) -> Result<DenseSummary, DenseError> {
        self.compute_with(prev, next, nodes, scratch, Some(predict))
    }

    /// How far from its prediction, px, a node's search on the finest level may land before it
    /// is searched again on the whole pyramid ([`DenseFlow::compute_predicted`]): about what LK
    /// on one level of a 9 x 9 window can follow.
    pub const FINE_REACH: f32 = 2.0;

    /// The nodes, searched from `predict` when given.
    fn compute_with(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        nodes: &mut [GridNode],
        scratch: &mut [i16],
        predict: Option<&dyn Fn(Point) -> Point>,
    ) -> Result<DenseSummary, DenseError> {
        let layout = self.check(prev, next, nodes.len(), scratch.len())?;
        let mut tracked = 0usize;
        for (index, node) in nodes.iter_mut().take(layout.len()).enumerate() {
            let (col, row) = layout.node(index);
            let centre = layout.centre(col, row);
            // LK refuses only frames of two sizes and a short scratch, both refused by `check`
            // above: no node is written before an error.
            let tracked_node = self.track_node(prev, next, centre, predict, scratch);
            debug_assert!(tracked_node.is_ok(), "LK refused what check() let through");
            *node = tracked_node?;
            tracked = tracked.saturating_add(usize::from(node.is_valid()));
        }
        // `check` refused a node slice shorter than the layout.
        let filled =
            fill_invalid(&layout, nodes, self.params.fill_passes).map_err(DenseError::Config)?;
        Ok(DenseSummary {
            layout,
            tracked,
            filled,
        })
    }

    /// Checks the inputs of [`DenseFlow::compute`] and returns the grid.
    fn check(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        nodes: usize,
        scratch: usize,
    ) -> Result<GridLayout, DenseError> {
        let base = prev.base();
        if !base.same_size(&next.base()) {
            return Err(DenseError::FrameSizeMismatch);
        }
        let layout = self
            .layout(base.width(), base.height())
            .map_err(DenseError::Config)?;
        let top = self
            .params
            .lk
            .max_level
            .min(prev.max_level())
            .min(next.max_level());
        let smallest = level_size(base.width(), top).min(level_size(base.height(), top));
        if smallest <= self.params.lk.window / 2 {
            return Err(DenseError::FrameTooSmall);
        }
        if nodes < layout.len() {
            return Err(DenseError::Config(ConfigError::min_len(
                "nodes",
                layout.len(),
            )));
        }
        let needed = scratch_len(self.params.lk.window);
        if scratch < needed {
            return Err(DenseError::Config(ConfigError::min_len("scratch", needed)));
        }
        Ok(layout)
    }

    /// What the camera check says of the node at pixel `centre` landing at `guess`.
    fn camera_check(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        centre: (usize, usize),
        guess: Point,
    ) -> CameraCheck {
        let (prev, next) = (prev.base(), next.base());
        // A prediction off the frame is LK's to refuse: a measured node lands inside it.
        let landing = (guess.x.to_bits(), guess.y.to_bits());
        if self.camera_tolerance == 0 || !crate::lk::inside(&next, landing) {
            return CameraCheck::Search;
        }
        let win = self.params.lk.window;
        match agreement(&prev, &next, centre, guess, win) {
            Some(a) if a.confirms(self.camera_tolerance) => CameraCheck::Confirmed,
            Some(a) if a.is_flat() && !self.params.search_flat => CameraCheck::Flat,
            _ => CameraCheck::Search,
        }
    }

    /// Tracks the node centred at pixel `centre` and classifies it.
    fn track_node(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        (x, y): (usize, usize),
        predict: Option<&dyn Fn(Point) -> Point>,
        scratch: &mut [i16],
    ) -> Result<GridNode, DenseError> {
        // Centres are below MAX_DIMENSION = 4096, so the Q16 conversion is exact.
        let q16 = |v: usize| i32::try_from(v).map_or(i32::MAX, |v| v.saturating_mul(1 << 16));
        let start = Point::from_bits(q16(x), q16(y));
        let fine = match predict {
            Some(predict) => {
                let guess = predict(start);
                match self.camera_check(prev, next, (x, y), guess) {
                    CameraCheck::Confirmed => {
                        let flow = Point::new(
                            guess.x.saturating_sub(start.x),
                            guess.y.saturating_sub(start.y),
                        );
                        return Ok(GridNode::tracked(flow));
                    }
                    CameraCheck::Flat => return Ok(GridNode::invalid(NodeStatus::LowTexture)),
                    CameraCheck::Search => {}
                }
                let step = self
                    .fine
                    .track_point(prev, next, start, Some(guess), scratch)
                    .map_err(lk_refusal)?;
                let (px, py) = step.position.to_f32();
                let (gx, gy) = guess.to_f32();
                let near =
                    (px - gx).abs() <= Self::FINE_REACH && (py - gy).abs() <= Self::FINE_REACH;
                // The finest level's template is the same whatever the search starts from:
                // a window too flat here is too flat for the search on the whole pyramid.
                let flat = step.status == TrackStatus::LowTexture;
                ((step.is_tracked() && near) || flat).then_some(step)
            }
            None => None,
        };
        let track = match fine {
            Some(step) => step,
            None => self
                .lk
                .track_point(prev, next, start, None, scratch)
                .map_err(lk_refusal)?,
        };
        Ok(match track.status {
            TrackStatus::Tracked if track.residual.to_num::<f32>() > self.params.max_residual => {
                GridNode::invalid(NodeStatus::Residual)
            }
            TrackStatus::Tracked => GridNode::tracked(Point::new(
                track.position.x.saturating_sub(start.x),
                track.position.y.saturating_sub(start.y),
            )),
            TrackStatus::LowTexture => GridNode::invalid(NodeStatus::LowTexture),
            TrackStatus::NotConverged | TrackStatus::OutOfBounds => {
                GridNode::invalid(NodeStatus::Lost)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::ImageView;
    use crate::lk::LkParams;
    use crate::pyramid::pyramid_storage_len;

    #[test]
    fn sides_cover_every_centre_inside_the_frame() {
        for size in 1..40 {
            for cell in 1..=size {
                let n = grid_side(size, cell);
                assert!(n >= 1, "{size} {cell}");
                assert!(cell / 2 + (n - 1) * cell < size);
                assert!(cell / 2 + n * cell >= size);
            }
        }
    }

    #[test]
    fn cell_rects_clip_to_the_frame() {
        let layout = GridLayout::new(20, 10, 6).unwrap();
        assert_eq!((layout.cols(), layout.rows()), (3, 2));
        assert_eq!(layout.cell_rect(2, 1), (12, 6, 6, 4));
        assert_eq!(layout.span_rect(0, 0, 2, 1), (0, 0, 18, 10));
    }

    fn flat_pyramids<'a>(
        pixels: &'a [u8],
        width: usize,
        height: usize,
        levels: usize,
        storage: &'a mut [u8],
    ) -> Pyramid<'a> {
        let frame = ImageView::packed(pixels, width, height).unwrap();
        Pyramid::build(frame, levels, storage).unwrap()
    }

    #[test]
    fn bad_inputs_are_errors() {
        let pixels = [100u8; 64 * 48];
        let mut storage = [0u8; pyramid_storage_len(64, 48, 3)];
        let p = flat_pyramids(&pixels, 64, 48, 3, &mut storage);
        let mut nodes = [GridNode::EMPTY; grid_len(64, 48, 8)];
        let mut scratch = [0i16; scratch_len(9)];
        let dense = |cell, window, max_level| {
            DenseFlow::new(DenseParams {
                cell,
                lk: LkParams {
                    window,
                    max_level,
                    ..LkParams::default()
                },
                ..DenseParams::default()
            })
        };
        let ok = dense(8, 9, 2).unwrap();
        assert!(ok.compute(&p, &p, &mut nodes, &mut scratch).is_ok());
        // Level 3 of 64 x 48 is 8 x 6, narrower than half a 21 px window.
        let wide = dense(8, 21, 3).unwrap();
        let mut big_scratch = [0i16; scratch_len(21)];
        assert_eq!(
            wide.compute(&p, &p, &mut nodes, &mut big_scratch),
            Err(DenseError::FrameTooSmall)
        );
        assert_eq!(
            dense(49, 9, 0)
                .unwrap()
                .compute(&p, &p, &mut nodes, &mut scratch),
            Err(DenseError::Config(ConfigError::new(
                "cell",
                Bound::Range { min: 1, max: 48 }
            )))
        );
        assert_eq!(
            dense(0, 9, 0).unwrap_err(),
            ConfigError::new("cell", Bound::AtLeast(1))
        );
        assert_eq!(
            dense(8, 10, 0).unwrap_err(),
            ConfigError::new("lk.window", Bound::OddRange { min: 3, max: 63 })
        );
        assert_eq!(
            ok.compute(&p, &p, &mut nodes[..10], &mut scratch),
            Err(DenseError::Config(ConfigError::min_len("nodes", 48)))
        );
        assert_eq!(
            ok.compute(&p, &p, &mut nodes, &mut scratch[..10]),
            Err(DenseError::Config(ConfigError::min_len(
                "scratch",
                scratch_len(9)
            )))
        );
        let other = [100u8; 48 * 48];
        let mut other_storage = [0u8; pyramid_storage_len(48, 48, 3)];
        let q = flat_pyramids(&other, 48, 48, 3, &mut other_storage);
        assert_eq!(
            ok.compute(&p, &q, &mut nodes, &mut scratch),
            Err(DenseError::FrameSizeMismatch)
        );
    }

    #[test]
    fn flat_frames_give_low_texture_nodes() {
        let pixels = [100u8; 32 * 32];
        let mut storage = [0u8; pyramid_storage_len(32, 32, 1)];
        let p = flat_pyramids(&pixels, 32, 32, 1, &mut storage);
        let dense = DenseFlow::new(DenseParams {
            fill_passes: 0,
            ..DenseParams::default()
        })
        .unwrap();
        let mut nodes = [GridNode::EMPTY; grid_len(32, 32, 8)];
        let mut scratch = [0i16; scratch_len(9)];
        let summary = dense.compute(&p, &p, &mut nodes, &mut scratch).unwrap();
        assert_eq!((summary.tracked, summary.filled), (0, 0));
        assert!(nodes.iter().all(|n| n.status == NodeStatus::LowTexture));
    }
}
