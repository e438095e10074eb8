//! The object flows tried at one candidate.

use super::area::Area;
use super::OUTLINE_MAX_FLOWS;
use crate::dense::grid::{GridLayout, GridNode};
use crate::dense::mask::mask_contains;
use crate::q16::{Point, Q16};

/// Flows closer than this on both axes are tried once, Q16 (half a pixel).
const SAME_FLOW: i32 = 1 << 15;

/// Neighbouring object pixels join one outline when their flows differ by at most this on
/// both axes, Q16 (one pixel).
const JOINED_FLOW: i32 = 1 << 16;

/// The flows tried at one candidate, Q16: pixel label `k + 1` stands for `flows[k]`.
pub(super) struct Flows {
    pub flows: [Point; OUTLINE_MAX_FLOWS],
    pub len: usize,
}

impl Flows {
    pub const EMPTY: Self = Self {
        flows: [Point::from_bits(0, 0); OUTLINE_MAX_FLOWS],
        len: 0,
    };

    /// The flows held, in the order they were added.
    pub fn iter(&self) -> impl Iterator<Item = &Point> {
        self.flows.iter().take(self.len)
    }

    /// Adds `flow` unless it is full or a flow within [`SAME_FLOW`] is there.
    pub fn add(&mut self, flow: Point) {
        let known = self.iter().any(|f| close(f, &flow, SAME_FLOW));
        if let Some(slot) = self.flows.get_mut(self.len).filter(|_| !known) {
            *slot = flow;
            self.len += 1;
        }
    }

    /// The distinct flows of the moving measured nodes whose centres lie in `area`, the first
    /// [`OUTLINE_MAX_FLOWS`] in raster order.
    pub fn of_nodes(layout: &GridLayout, nodes: &[GridNode], mask: &[u32], area: &Area) -> Self {
        let mut flows = Self::EMPTY;
        for (index, node) in nodes.iter().take(layout.len()).enumerate() {
            let (col, row) = layout.node(index);
            let (x, y) = layout.centre(col, row);
            if area.contains(x, y) && mask_contains(mask, index) && node.is_valid() {
                flows.add(node.flow);
            }
        }
        flows
    }

    /// For each flow, the flows (bit `j` for flow `j`) within [`JOINED_FLOW`] of it: the
    /// flows whose pixels one outline may hold.
    pub fn joined(&self) -> [u8; OUTLINE_MAX_FLOWS] {
        core::array::from_fn(|i| {
            let Some(a) = self.flows.get(i).filter(|_| i < self.len) else {
                return 0;
            };
            self.iter()
                .enumerate()
                .filter(|(_, b)| close(a, b, JOINED_FLOW))
                .fold(0u8, |bits, (j, _)| bits | (1 << j))
        })
    }
}

fn close(a: &Point, b: &Point, within: i32) -> bool {
    let d = |p: Q16, q: Q16| p.to_bits().abs_diff(q.to_bits());
    d(a.x, b.x) <= within.unsigned_abs() && d(a.y, b.y) <= within.unsigned_abs()
}
