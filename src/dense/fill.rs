//! Filling invalid nodes from their valid neighbours: [`fill_invalid`].

use super::grid::{GridLayout, GridNode, NodeStatus, NEIGHBOURS};
use crate::q16::{Point, Q16};
use crate::ConfigError;

/// Known neighbours a node needs to be filled: one alone would copy a possibly wrong value.
pub const FILL_MIN_SOURCES: usize = 2;

/// Fills invalid nodes from their valid neighbours: runs `passes` fill passes over the first
/// [`GridLayout::len`] `nodes` and returns how many nodes were filled. Filled nodes get
/// [`NodeStatus::Filled`] and the pass number in [`GridNode::fill_pass`]; nodes already filled
/// count as earlier passes.
///
/// A flat patch of road or sky has no flow of its own, but pictures, interpolated flow fields
/// and the motion mask want a value there. Each pass gives every still-empty node the
/// component-wise median of the flows around it (its 3 x 3 neighbourhood), provided at least
/// [`FILL_MIN_SOURCES`] of them are known: measured, or filled by an *earlier* pass. Only
/// earlier passes count, so the result does not depend on the order the nodes are visited in,
/// and pass `k` reaches exactly `k` nodes away from the measurements. The median, unlike the
/// mean, does not blend an object's flow with the background's at its border.
///
/// # Errors
///
/// A [`ConfigError`] naming `"nodes"` when `nodes` is shorter than the layout; no node is
/// changed.
/// A shorter slice would lose the neighbours of its last row and fill it differently.
///
/// ```
/// use kestrel::dense::{fill_invalid, GridLayout, GridNode, NodeStatus};
/// use kestrel::{Bound, ConfigError};
/// use kestrel::Point;
///
/// // A 3 x 3 grid: the centre is unknown, its neighbours moved 2 px right.
/// let layout = GridLayout::new(24, 24, 8).unwrap();
/// let mut nodes = [GridNode::tracked(Point::from_f32(2.0, 0.0)); 9];
/// nodes[4] = GridNode::invalid(NodeStatus::LowTexture);
/// assert_eq!(fill_invalid(&layout, &mut nodes, 2), Ok(1));
/// assert_eq!(nodes[4].status, NodeStatus::Filled);
/// assert_eq!(nodes[4].flow.to_f32(), (2.0, 0.0));
/// // A slice shorter than the layout is refused, untouched.
/// let mut short = [GridNode::invalid(NodeStatus::LowTexture); 8];
/// let refused = fill_invalid(&layout, &mut short, 2).unwrap_err();
/// assert_eq!(refused, ConfigError { field: "nodes", bound: Bound::MinLen(9) });
/// assert_eq!(refused.to_string(), "nodes must hold at least 9 elements");
/// assert!(short.iter().all(|n| n.status == NodeStatus::LowTexture));
/// ```
pub fn fill_invalid(
    layout: &GridLayout,
    nodes: &mut [GridNode],
    passes: u8,
) -> Result<usize, ConfigError> {
    let nodes = nodes
        .get_mut(..layout.len())
        .ok_or(ConfigError::min_len("nodes", layout.len()))?;
    // Nodes filled by an earlier call count as earlier passes.
    let done = nodes.iter().map(|n| n.fill_pass).max().unwrap_or(0);
    let mut filled = 0usize;
    for pass in (1..=passes).map(|p| done.saturating_add(p)) {
        let mut filled_now = 0usize;
        for index in 0..nodes.len() {
            let empty = nodes.get(index).is_some_and(|n| !n.has_flow());
            if !empty {
                continue;
            }
            if let Some(flow) = neighbour_median(layout, nodes, index, pass) {
                if let Some(node) = nodes.get_mut(index) {
                    *node = GridNode {
                        flow,
                        status: NodeStatus::Filled,
                        fill_pass: pass,
                    };
                    filled_now = filled_now.saturating_add(1);
                }
            }
        }
        if filled_now == 0 {
            break;
        }
        filled = filled.saturating_add(filled_now);
    }
    Ok(filled)
}

/// The component-wise median of the known neighbours of node `index`, counting filled nodes
/// only from passes before `pass`; `None` with fewer than [`FILL_MIN_SOURCES`].
fn neighbour_median(
    layout: &GridLayout,
    nodes: &[GridNode],
    index: usize,
    pass: u8,
) -> Option<Point> {
    let mut xs = [0i32; 8];
    let mut ys = [0i32; 8];
    let mut count = 0usize;
    for offset in NEIGHBOURS {
        let neighbour = layout.neighbour(index, offset).and_then(|i| nodes.get(i));
        let Some(n) = neighbour else { continue };
        let known = n.status == NodeStatus::Tracked
            || (n.status == NodeStatus::Filled && n.fill_pass < pass);
        if let (true, Some(x), Some(y)) = (known, xs.get_mut(count), ys.get_mut(count)) {
            *x = n.flow.x.to_bits();
            *y = n.flow.y.to_bits();
            count = count.saturating_add(1);
        }
    }
    if count < FILL_MIN_SOURCES {
        return None;
    }
    let x = median(xs.get_mut(..count)?);
    let y = median(ys.get_mut(..count)?);
    Some(Point::new(Q16::from_bits(x), Q16::from_bits(y)))
}

/// The median of at most eight values (the mean of the middle two for an even count);
/// reorders `values`. Selection rather than a sort, the routine the tracker's medians use: one
/// copy in the firmware's flash.
fn median(values: &mut [i32]) -> i32 {
    let (middle, odd) = (values.len() / 2, values.len() % 2 == 1);
    if values.is_empty() {
        return 0;
    }
    let (below, &mut upper, _) = values.select_nth_unstable(middle);
    if odd {
        return upper;
    }
    let lower = below.iter().copied().max().unwrap_or(upper);
    // The mean of two i32 values is an i32.
    i32::try_from(i64::from(lower).saturating_add(i64::from(upper)) / 2).unwrap_or(upper)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(dx: f32, dy: f32) -> GridNode {
        GridNode::tracked(Point::from_f32(dx, dy))
    }

    #[test]
    fn passes_reach_one_node_further_each() {
        // A 5 x 2 grid of 4 px cells: only the first two columns are measured.
        let layout = GridLayout::new(20, 8, 4).unwrap();
        let mut nodes = [GridNode::EMPTY; 10];
        for i in [0, 1, 5, 6] {
            nodes[i] = node(1.0, 0.0);
        }
        assert_eq!(fill_invalid(&layout, &mut nodes, 1), Ok(2));
        assert_eq!((nodes[2].fill_pass, nodes[7].fill_pass), (1, 1));
        assert_eq!(nodes[3].status, NodeStatus::Lost);
        // A later call continues where the first stopped: pass 2, then pass 3.
        assert_eq!(fill_invalid(&layout, &mut nodes, 5), Ok(4));
        assert_eq!((nodes[3].fill_pass, nodes[9].fill_pass), (2, 3));
        assert_eq!(nodes[9].flow.to_f32(), (1.0, 0.0));
    }

    #[test]
    fn a_lone_neighbour_is_not_copied() {
        let layout = GridLayout::new(8, 4, 4).unwrap();
        let mut nodes = [node(1.0, 0.0), GridNode::EMPTY];
        assert_eq!(fill_invalid(&layout, &mut nodes, 3), Ok(0));
    }

    #[test]
    fn the_median_ignores_a_minority_of_other_flows() {
        let layout = GridLayout::new(24, 24, 8).unwrap();
        let mut nodes = [node(1.0, 1.0); 9];
        nodes[0] = node(9.0, -9.0);
        nodes[4] = GridNode::invalid(NodeStatus::Residual);
        assert_eq!(fill_invalid(&layout, &mut nodes, 1), Ok(1));
        assert_eq!(nodes[4].flow.to_f32(), (1.0, 1.0));
    }

    #[test]
    fn order_does_not_matter_within_a_pass() {
        // Two empty nodes side by side between measured columns: both see only measured nodes.
        let layout = GridLayout::new(32, 8, 8).unwrap();
        let mut nodes = [
            node(2.0, 0.0),
            GridNode::EMPTY,
            GridNode::EMPTY,
            node(4.0, 0.0),
        ];
        assert_eq!(fill_invalid(&layout, &mut nodes, 3), Ok(0));
        let layout = GridLayout::new(32, 16, 8).unwrap();
        let mut nodes = [
            node(2.0, 0.0),
            GridNode::EMPTY,
            GridNode::EMPTY,
            node(4.0, 0.0),
            node(2.0, 0.0),
            node(2.0, 0.0),
            node(4.0, 0.0),
            node(4.0, 0.0),
        ];
        assert_eq!(fill_invalid(&layout, &mut nodes, 1), Ok(2));
        assert_eq!(nodes[1].flow.to_f32(), (2.0, 0.0));
        assert_eq!(nodes[2].flow.to_f32(), (4.0, 0.0));
    }

    #[test]
    fn median_of_even_and_odd_counts() {
        assert_eq!(median(&mut [3, 1, 2]), 2);
        assert_eq!(median(&mut [4, 1, 3, 2]), 2);
        assert_eq!(median(&mut [i32::MAX, i32::MAX]), i32::MAX);
    }
}
