//! Measured nodes averaged with the neighbours that move alike: [`smooth_tracked`].

use super::grid::{grid_side, GridLayout, GridNode, NodeStatus, NEIGHBOURS};
use crate::q16::{Point, Q16};
use crate::{Bound, ConfigError};

/// The `rows` [`smooth_tracked`] needs for a `width` px frame and `cell` px cells: two rows of
/// nodes.
///
/// ```
/// use kestrel::dense::smooth_scratch_len;
/// assert_eq!(smooth_scratch_len(160, 8), 40);
/// ```
pub const fn smooth_scratch_len(width: usize, cell: usize) -> usize {
    grid_side(width, cell).saturating_mul(2)
}

/// The gate host-sim uses, px: about five times a node's measurement noise with sensor noise of
/// 1.5 grey levels. Per component, so a neighbour let in differs by at most 0.71 px, under the
/// 0.8 px at which the motion mask calls a node moving ([`MotionParams::threshold`]): a fit
/// never averages in a neighbour the mask would set apart.
///
/// [`MotionParams::threshold`]: super::MotionParams::threshold
pub const SMOOTH_GATE: f32 = 0.5;

/// The passes host-sim runs: the second fit, over nodes already smoothed, reaches the 5 x 5
/// neighbourhood (40 px at 8 px cells), which takes a further sixth to a fifth off the median
/// error on textured scenes and photographs while the affine fit still follows rotation and
/// zoom exactly.
pub const SMOOTH_PASSES: u8 = 2;

/// Members (the node included) an affine fit needs; with fewer the node takes their mean.
/// Three would fit the plane exactly through noisy points, extrapolating their noise.
pub const SMOOTH_MIN_AFFINE: usize = 4;

/// Averages measured nodes with the neighbours that move alike: replaces the flow of every
/// measured node among the first [`GridLayout::len`] `nodes` by the affine fit of its 3 x 3
/// neighbourhood's measured flows within `gate` px of its own, and returns how many nodes had
/// a neighbour within the gate. Statuses and every other node are left alone. `rows` holds at
/// least [`smooth_scratch_len`] points.
///
/// LK measures each node from its own window alone: 81 pixels for the default 9 x 9, so
/// sensor noise of 1.5 grey levels moves a node by about a tenth of a pixel
/// (tests/dense_grid.rs measures a median of 0.09 px without the smoothing). Neighbouring
/// nodes on the same surface see independent pixels of the same smooth motion, so a fit over
/// the 3 x 3 neighbourhood averages up to nine windows' noise. The fit is affine (flow = a +
/// b·col + c·row, per component) so that rotation and zoom, which make the flow vary by a few
/// tenths of a pixel from node to node, do not bias it; its value at the node is the smoothed
/// flow. Fewer than [`SMOOTH_MIN_AFFINE`] members, or members on one line, take their mean
/// instead.
///
/// Only measured ([`NodeStatus::Tracked`]) nodes take part, and only neighbours whose flow is
/// within the gate of the node's own in both components: a neighbour beyond it sees another
/// surface (an object's edge, a mismeasured window), so an object moving more than the gate
/// against its background keeps its own flow, even on a single node.
///
/// The smoothing runs in place, row by row; `rows` keeps the measured flows of the row above
/// and of the current one while they are replaced. A second pass over the smoothed nodes
/// reaches a node further ([`SMOOTH_PASSES`]): a wider average where the surface goes on,
/// still bounded by the gate where it ends.
///
/// Errors: a [`ConfigError`] naming `"gate"` for a gate that is negative, NaN or beyond a Q16
/// flow (32,768 px), `"nodes"` or `"rows"` for short buffers. Nothing is changed then.
///
/// ```
/// use kestrel::dense::{smooth_scratch_len, smooth_tracked, GridLayout, GridNode};
/// use kestrel::Point;
///
/// // A 3 x 3 grid moving 2 px right, the centre measured 0.3 px off, a corner on an object.
/// let layout = GridLayout::new(24, 24, 8).unwrap();
/// let mut nodes = [GridNode::tracked(Point::from_f32(2.0, 0.0)); 9];
/// nodes[4] = GridNode::tracked(Point::from_f32(2.3, 0.0));
/// nodes[0] = GridNode::tracked(Point::from_f32(5.0, 1.0));
/// let mut rows = [Point::default(); smooth_scratch_len(24, 8)];
/// assert_eq!(smooth_tracked(&layout, &mut nodes, 0.5, &mut rows), Ok(8));
/// let (dx, dy) = nodes[4].flow.to_f32();
/// assert!((dx - 2.0).abs() < 0.05 && dy == 0.0, "{dx}");
/// // The object's node has no neighbour within the gate: it keeps its flow.
/// assert_eq!(nodes[0].flow.to_f32(), (5.0, 1.0));
/// let refused = smooth_tracked(&layout, &mut nodes, -1.0, &mut rows).unwrap_err();
/// assert_eq!(refused.to_string(), "gate must be a number >= 0 and below 32768");
/// ```
pub fn smooth_tracked(
    layout: &GridLayout,
    nodes: &mut [GridNode],
    gate: f32,
    rows: &mut [Point],
) -> Result<usize, ConfigError> {
    let gate = match Q16::checked_from_num(gate) {
        Some(g) if gate >= 0.0 => g.to_bits(),
        _ => return Err(ConfigError::new("gate", Bound::NonNegativeBelow(32_768))),
    };
    let cols = layout.cols();
    let nodes = nodes
        .get_mut(..layout.len())
        .ok_or(ConfigError::min_len("nodes", layout.len()))?;
    let needed = smooth_scratch_len(layout.width(), layout.cell());
    let rows = rows
        .get_mut(..needed)
        .ok_or(ConfigError::min_len("rows", needed))?;
    let (mut above, mut current) = rows.split_at_mut(cols);
    let mut smoothed = 0usize;
    for row in 0..layout.rows() {
        let start = row.saturating_mul(cols);
        // `nodes` was cut to the layout's rows x cols above: every row is inside it.
        let measured = nodes.get(start..start.saturating_add(cols));
        debug_assert!(measured.is_some(), "row {row} of {}", layout.rows());
        let measured = measured.unwrap_or(&[]);
        for (kept, node) in current.iter_mut().zip(measured) {
            *kept = node.flow;
        }
        let neighbourhood = Neighbourhood {
            layout,
            above,
            current,
            row,
            gate,
        };
        for col in 0..cols {
            let index = start.saturating_add(col);
            let Some(fit) = neighbourhood.fit(nodes, col) else {
                continue;
            };
            if let Some(node) = nodes.get_mut(index) {
                node.flow = fit;
                smoothed = smoothed.saturating_add(1);
            }
        }
        core::mem::swap(&mut above, &mut current);
    }
    Ok(smoothed)
}

/// The measured flows around one row of nodes while it is smoothed: the row above and this one
/// from `rows`, the row below still in the nodes.
struct Neighbourhood<'a> {
    layout: &'a GridLayout,
    above: &'a [Point],
    current: &'a [Point],
    row: usize,
    gate: i32,
}

impl Neighbourhood<'_> {
    /// The measured flow of the node `offset` (columns, rows) from (`col`, this row), if it
    /// was tracked.
    fn measured(&self, nodes: &[GridNode], col: usize, (dc, dr): (isize, isize)) -> Option<Point> {
        let (c, r) = (
            col.checked_add_signed(dc)?,
            self.row.checked_add_signed(dr)?,
        );
        let node = nodes.get(self.layout.index(c, r)?)?;
        if node.status != NodeStatus::Tracked {
            return None;
        }
        match dr {
            -1 => self.above.get(c).copied(),
            0 => self.current.get(c).copied(),
            _ => Some(node.flow),
        }
    }

    /// The smoothed flow of the node at `col` of this row; `None` when it is not measured or
    /// no neighbour is within the gate.
    fn fit(&self, nodes: &[GridNode], col: usize) -> Option<Point> {
        let centre = self.measured(nodes, col, (0, 0))?;
        let mut sums = FitSums::default();
        // The node itself, at offset 0 and 0 from its own flow.
        sums.add(0, 0, (0, 0));
        for (dc, dr) in NEIGHBOURS {
            let Some(flow) = self.measured(nodes, col, (dc, dr)) else {
                continue;
            };
            // Differences of two i32 values: exact in i64.
            let x = i64::from(flow.x.to_bits()).saturating_sub(centre.x.to_bits().into());
            let y = i64::from(flow.y.to_bits()).saturating_sub(centre.y.to_bits().into());
            let gate = i64::from(self.gate);
            if x.abs() <= gate && y.abs() <= gate {
                sums.add(dc as i64, dr as i64, (x, y));
            }
        }
        if sums.n < 2 {
            return None;
        }
        let (x, y) = sums.intercept();
        let (px, py) = self.layout.centre(col, self.row);
        Some(Point::new(
            kept_inside(centre.x, x, px, self.layout.width())?,
            kept_inside(centre.y, y, py, self.layout.height())?,
        ))
    }
}

/// The flow `flow + change` (Q16 bits) of a node centred at pixel `centre` along an axis of
/// `size` pixels, held so that the node lands inside the frame as LK left it: the fit of
/// its neighbours may not carry a border node out. `None` when it does not fit a Q16 flow.
fn kept_inside(flow: Q16, change: i64, centre: usize, size: usize) -> Option<Q16> {
    let q16 = |v: usize| i64::try_from(v).map_or(i64::MAX, |v| v.saturating_mul(1 << 16));
    let (lowest, highest) = (
        q16(centre).saturating_neg(),
        q16(size.saturating_sub(1)).saturating_sub(q16(centre)),
    );
    // `max` then `min`, not `clamp`: bounds that crossed (a frame beyond Q16's reach) cannot
    // panic.
    let bits = i64::from(flow.to_bits())
        .saturating_add(change)
        .max(lowest)
        .min(highest);
    i32::try_from(bits).ok().map(Q16::from_bits)
}

/// Least-squares sums of an affine fit over offsets `(u, v)` in -1..=1 with values relative to
/// the node's own flow, Q16 bits. Nine members of at most a gate of 2^31 each: no overflow in
/// `i64`.
#[derive(Default)]
struct FitSums {
    n: i64,
    u: i64,
    v: i64,
    uu: i64,
    vv: i64,
    uv: i64,
    /// Sums of the values, and of the values times `u` and times `v`, for x and for y.
    x: [i64; 3],
    y: [i64; 3],
}

// Sums of at most nine members below 2^31 times offsets of at most 1, and adjugate entries of
// at most 81 times them: below 2^46 in i64.
#[allow(clippy::arithmetic_side_effects)]
impl FitSums {
    fn add(&mut self, u: i64, v: i64, (x, y): (i64, i64)) {
        self.n += 1;
        self.u += u;
        self.v += v;
        self.uu += u * u;
        self.vv += v * v;
        self.uv += u * v;
        for (sums, value) in [(&mut self.x, x), (&mut self.y, y)] {
            sums[0] += value;
            sums[1] += u * value;
            sums[2] += v * value;
        }
    }

    /// The fitted value at offset (0, 0), x and y: the first row of the normal matrix's
    /// adjugate over its determinant, or the mean when the fit is underdetermined.
    fn intercept(&self) -> (i64, i64) {
        let adjugate = [
            self.uu * self.vv - self.uv * self.uv,
            self.uv * self.v - self.u * self.vv,
            self.u * self.uv - self.uu * self.v,
        ];
        let det = self.n * adjugate[0] + self.u * adjugate[1] + self.v * adjugate[2];
        let solve = |sums: &[i64; 3]| {
            if self.n >= SMOOTH_MIN_AFFINE as i64 && det > 0 {
                let num: i64 = adjugate.iter().zip(sums).map(|(a, s)| a * s).sum();
                div_round(num, det)
            } else {
                div_round(sums[0], self.n)
            }
        };
        (solve(&self.x), solve(&self.y))
    }
}

/// `num / den` rounded to the nearest, halves away from zero; `den` > 0.
// `num` below 2^46 and `den` positive (the callers' sums).
#[allow(clippy::arithmetic_side_effects)]
fn div_round(num: i64, den: i64) -> i64 {
    let half = den / 2;
    if num >= 0 {
        (num + half) / den
    } else {
        -((-num + half) / den)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(dx: f32, dy: f32) -> GridNode {
        GridNode::tracked(Point::from_f32(dx, dy))
    }

    /// Seeded values spread uniformly over `width` px around 0.
    fn uniform_noise(seed: u32, width: f32) -> impl FnMut() -> f32 {
        let mut state = seed;
        move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((state >> 8) as f32 / (1u32 << 24) as f32 - 0.5) * width
        }
    }

    fn smooth(layout: &GridLayout, nodes: &mut [GridNode], gate: f32) -> usize {
        let mut rows = [Point::default(); 40];
        smooth_tracked(layout, nodes, gate, &mut rows).unwrap()
    }

    #[test]
    fn an_affine_field_is_kept_exactly() {
        // Zoom and rotation: flow = (0.5 + 0.02·x - 0.01·y, -0.25 + 0.01·x + 0.02·y) at the
        // node centres, with holes that make the neighbourhoods lopsided (each node keeps at least
        // SMOOTH_MIN_AFFINE members off one line: the corners four, the edges five or six).
        let layout = GridLayout::new(64, 48, 8).unwrap();
        let field = |i: usize| {
            let (c, r) = layout.centre(i % 8, i / 8);
            let (x, y) = (c as f32, r as f32);
            node(0.5 + 0.02 * x - 0.01 * y, -0.25 + 0.01 * x + 0.02 * y)
        };
        let mut nodes: [GridNode; 48] = core::array::from_fn(field);
        for hole in [10, 21, 36] {
            nodes[hole] = GridNode::invalid(NodeStatus::LowTexture);
        }
        let before = nodes;
        for _ in 0..SMOOTH_PASSES {
            smooth(&layout, &mut nodes, 0.5);
        }
        for (a, b) in nodes.iter().zip(&before) {
            assert_eq!(a.status, b.status);
            let (dx, dy) = (
                (a.flow.x - b.flow.x).to_num::<f32>(),
                (a.flow.y - b.flow.y).to_num::<f32>(),
            );
            assert!(dx.abs() < 1e-4 && dy.abs() < 1e-4, "{dx} {dy}");
        }
    }

    #[test]
    fn in_place_equals_every_node_fitted_from_the_measurements() {
        // A noisy field with holes and a moving patch, smoothed in place, against each node
        // fitted from an untouched copy: bit for bit.
        let layout = GridLayout::new(56, 48, 8).unwrap();
        let mut noise = uniform_noise(99, 0.6);
        let mut nodes: [GridNode; 42] = core::array::from_fn(|i| {
            let moving = [16, 17, 23].contains(&i);
            let base = if moving { 1.8 } else { 1.0 };
            node(base + noise(), -0.5 + noise())
        });
        for hole in [3, 11, 30, 41] {
            nodes[hole] = GridNode::invalid(NodeStatus::LowTexture);
        }
        let measured = nodes;
        let gate = Q16::from_num(0.5).to_bits();
        let flows: [Point; 42] = core::array::from_fn(|i| measured[i].flow);
        let cols = layout.cols();
        let expected: [Point; 42] = core::array::from_fn(|i| {
            let row = i / cols;
            let above = if row == 0 {
                &flows[..0]
            } else {
                &flows[(row - 1) * cols..row * cols]
            };
            let current = &flows[row * cols..(row + 1) * cols];
            let around = Neighbourhood {
                layout: &layout,
                above,
                current,
                row,
                gate,
            };
            around.fit(&measured, i % cols).unwrap_or(measured[i].flow)
        });
        let count = smooth(&layout, &mut nodes, 0.5);
        assert!(count > 30, "{count}");
        for (i, (n, e)) in nodes.iter().zip(&expected).enumerate() {
            assert_eq!(n.flow, *e, "node {i}");
        }
    }

    #[test]
    fn noise_shrinks_on_a_smooth_field() {
        // A uniform 1.5 px flow with seeded noise of about 0.1 px per node.
        let layout = GridLayout::new(160, 120, 8).unwrap();
        let mut noise = uniform_noise(12345, 0.35);
        let mut nodes: [GridNode; 300] = core::array::from_fn(|_| node(1.5 + noise(), noise()));
        let error = |nodes: &[GridNode]| {
            let sum: f32 = nodes
                .iter()
                .map(|n| {
                    let (dx, dy) = n.flow.to_f32();
                    (dx - 1.5).powi(2) + dy.powi(2)
                })
                .sum();
            (sum / nodes.len() as f32).sqrt()
        };
        let before = error(&nodes);
        assert_eq!(smooth(&layout, &mut nodes, 0.5), layout.len());
        let after = error(&nodes);
        assert!(after < 0.5 * before, "{before} -> {after}");
    }

    #[test]
    fn an_object_beyond_the_gate_keeps_its_flow() {
        // One node moving 1 px against a still background, through every default pass; the
        // background around it stays at zero too.
        let layout = GridLayout::new(40, 40, 8).unwrap();
        let mut nodes = [node(0.0, 0.0); 25];
        nodes[12] = node(1.0, 0.0);
        for _ in 0..SMOOTH_PASSES {
            smooth(&layout, &mut nodes, SMOOTH_GATE);
        }
        assert_eq!(nodes[12].flow.to_f32(), (1.0, 0.0));
        assert!(nodes
            .iter()
            .enumerate()
            .all(|(i, n)| i == 12 || n.flow.to_f32() == (0.0, 0.0)));
    }

    #[test]
    fn unmeasured_nodes_neither_change_nor_count() {
        let layout = GridLayout::new(24, 8, 8).unwrap();
        // Two measured nodes two columns apart, a filled one between them within the gate of
        // both: it would move them if it counted.
        let filled = GridNode {
            flow: Point::from_f32(1.1, 0.0),
            status: NodeStatus::Filled,
            fill_pass: 1,
        };
        let mut nodes = [node(1.0, 0.0), filled, node(1.2, 0.0)];
        let before = nodes;
        assert_eq!(smooth(&layout, &mut nodes, 0.5), 0);
        assert_eq!(nodes, before);
    }

    #[test]
    fn bad_gates_and_short_buffers_are_refused() {
        let layout = GridLayout::new(24, 24, 8).unwrap();
        let mut nodes = [node(0.0, 0.0); 9];
        let mut rows = [Point::default(); 6];
        for gate in [f32::NAN, -0.1, f32::INFINITY, 1e9] {
            assert_eq!(
                smooth_tracked(&layout, &mut nodes, gate, &mut rows),
                Err(ConfigError::new("gate", Bound::NonNegativeBelow(32_768)))
            );
        }
        assert_eq!(
            smooth_tracked(&layout, &mut nodes[..8], 0.5, &mut rows),
            Err(ConfigError::min_len("nodes", 9))
        );
        assert_eq!(
            smooth_tracked(&layout, &mut nodes, 0.5, &mut rows[..5]),
            Err(ConfigError::min_len("rows", 6))
        );
    }

    #[test]
    fn smoothed_nodes_stay_inside_the_frame() {
        // One row of three nodes: the first (centre x = 4) moved 4 px left onto the frame's
        // first pixel, its neighbour 4.4 px. Two members take their mean, -4.2 px, which would
        // carry the first node off the frame: it stops at the edge.
        let layout = GridLayout::new(24, 8, 8).unwrap();
        let mut nodes = [node(-4.0, 0.0), node(-4.4, 0.0), node(-4.4, 0.0)];
        smooth(&layout, &mut nodes, 0.5);
        assert_eq!(nodes[0].flow.to_f32(), (-4.0, 0.0));
        let (dx, _) = nodes[1].flow.to_f32();
        assert!(dx < -4.2 && dx > -4.4, "{dx}");
    }

    #[test]
    fn rounding_is_symmetric() {
        assert_eq!(
            (
                div_round(5, 2),
                div_round(-5, 2),
                div_round(4, 3),
                div_round(-4, 3)
            ),
            (3, -3, 1, -1)
        );
    }
}
