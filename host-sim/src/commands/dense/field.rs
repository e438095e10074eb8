//! Full-resolution flow fields interpolated from the grid, and Middlebury `.flo` files.
//!
//! A pixel's flow is the bilinear interpolation of the four grid nodes around it, over those
//! that have a flow (measured or filled); the weights of the others are dropped and the rest
//! renormalised. Pixels before the first node centre or after the last take the nearest
//! nodes' values. A pixel none of whose four nodes has a flow is unknown.
//!
//! A `.flo` file (Baker et al., "A Database and Evaluation Methodology for Optical Flow") is the
//! float 202021.25 (the bytes `PIEH`), the width and height as 32-bit integers, then the
//! (u, v) pairs of every pixel row by row as 32-bit floats, all little-endian. Unknown flow is
//! written as 1e10; any component above 1e9 reads as unknown.

use kestrel::dense::{GridLayout, GridNode};

/// The float that starts every `.flo` file.
pub const FLO_MAGIC: f32 = 202_021.25;
/// The value written for unknown flow.
pub const UNKNOWN_FLOW: f32 = 1e10;
/// Components above this read as unknown.
pub const UNKNOWN_THRESHOLD: f32 = 1e9;

/// A flow vector per pixel, `None` where unknown.
#[derive(Debug, Clone, PartialEq)]
pub struct FlowField {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// `width * height` flows, row by row, px.
    pub flow: Vec<Option<(f32, f32)>>,
}

impl FlowField {
    /// The field of a grid at the full resolution of its frames.
    pub fn from_grid(layout: &GridLayout, nodes: &[GridNode]) -> Self {
        let (width, height) = (layout.width(), layout.height());
        let cols: Vec<Axis> = (0..width)
            .map(|x| Axis::at(x, layout.cell(), layout.cols()))
            .collect();
        let mut flow = Vec::with_capacity(width * height);
        for y in 0..height {
            let row = Axis::at(y, layout.cell(), layout.rows());
            flow.extend(cols.iter().map(|col| interpolate(layout, nodes, col, &row)));
        }
        Self {
            width,
            height,
            flow,
        }
    }

    /// The flow at (`x`, `y`); `None` where unknown or outside.
    pub fn at(&self, x: usize, y: usize) -> Option<(f32, f32)> {
        if x >= self.width {
            return None;
        }
        self.flow.get(y * self.width + x).copied().flatten()
    }

    /// The largest speed over the known pixels, px; 0 without any.
    pub fn max_speed(&self) -> f32 {
        self.flow
            .iter()
            .flatten()
            .map(|&(u, v)| u.hypot(v))
            .fold(0.0, f32::max)
    }

    /// The field as the bytes of a `.flo` file.
    pub fn to_flo(&self) -> Vec<u8> {
        let mut bytes = Vec::with_capacity(12 + 8 * self.flow.len());
        bytes.extend_from_slice(&FLO_MAGIC.to_le_bytes());
        // Frame sides are at most 4096, far inside an i32.
        bytes.extend_from_slice(&(self.width as i32).to_le_bytes());
        bytes.extend_from_slice(&(self.height as i32).to_le_bytes());
        for flow in &self.flow {
            let (u, v) = flow.unwrap_or((UNKNOWN_FLOW, UNKNOWN_FLOW));
            bytes.extend_from_slice(&u.to_le_bytes());
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes
    }

    /// Reads the bytes of a `.flo` file; the error says what is wrong.
    pub fn from_flo(bytes: &[u8]) -> Result<Self, String> {
        let word = |i: usize| -> Option<[u8; 4]> { bytes.get(4 * i..4 * i + 4)?.try_into().ok() };
        let header = (word(0), word(1), word(2));
        let (Some(magic), Some(w), Some(h)) = header else {
            return Err("too short for a .flo header".to_owned());
        };
        if f32::from_le_bytes(magic) != FLO_MAGIC {
            return Err("not a .flo file (no PIEH tag)".to_owned());
        }
        let (width, height) = (i32::from_le_bytes(w), i32::from_le_bytes(h));
        let (Ok(width), Ok(height)) = (usize::try_from(width), usize::try_from(height)) else {
            return Err(format!("negative size {width}x{height}"));
        };
        let expected = width
            .checked_mul(height)
            .and_then(|n| n.checked_mul(8))
            .and_then(|n| n.checked_add(12));
        if expected != Some(bytes.len()) {
            return Err(format!(
                "{} bytes do not hold a {width}x{height} field",
                bytes.len()
            ));
        }
        let flow = (0..width * height)
            .map(|p| {
                let u = f32::from_le_bytes(word(3 + 2 * p)?);
                let v = f32::from_le_bytes(word(4 + 2 * p)?);
                let unknown = |c: f32| c.is_nan() || c.abs() > UNKNOWN_THRESHOLD;
                (!unknown(u) && !unknown(v)).then_some((u, v))
            })
            .collect();
        Ok(Self {
            width,
            height,
            flow,
        })
    }
}

/// Where a pixel lies between the node centres of one axis: nodes `k0` and `k1` with the
/// weight `t` of `k1`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Axis {
    k0: usize,
    k1: usize,
    t: f32,
}

impl Axis {
    /// Pixel `p` on an axis of `count` nodes `cell` px apart, centred at `cell/2 + k·cell`.
    fn at(p: usize, cell: usize, count: usize) -> Self {
        let last = count.saturating_sub(1);
        let f = (p as f32 - (cell / 2) as f32) / cell as f32;
        if f <= 0.0 {
            return Self {
                k0: 0,
                k1: 0,
                t: 0.0,
            };
        }
        let k0 = f as usize;
        if k0 >= last {
            return Self {
                k0: last,
                k1: last,
                t: 0.0,
            };
        }
        Self {
            k0,
            k1: k0 + 1,
            t: f - k0 as f32,
        }
    }
}

/// The bilinear flow between the nodes `col` x `row` that have one.
fn interpolate(
    layout: &GridLayout,
    nodes: &[GridNode],
    col: &Axis,
    row: &Axis,
) -> Option<(f32, f32)> {
    let corners = [
        (col.k0, row.k0, (1.0 - col.t) * (1.0 - row.t)),
        (col.k1, row.k0, col.t * (1.0 - row.t)),
        (col.k0, row.k1, (1.0 - col.t) * row.t),
        (col.k1, row.k1, col.t * row.t),
    ];
    let (mut u, mut v, mut total) = (0.0, 0.0, 0.0);
    for (c, r, weight) in corners {
        let node = layout.index(c, r).and_then(|i| nodes.get(i));
        if let Some(node) = node.filter(|n| n.has_flow() && weight > 0.0) {
            let (du, dv) = node.flow.to_f32();
            u += weight * du;
            v += weight * dv;
            total += weight;
        }
    }
    (total > 0.0).then(|| (u / total, v / total))
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::dense::NodeStatus;
    use kestrel::Point;

    #[test]
    fn interpolation_is_bilinear_between_centres_and_flat_beyond() {
        // A 3 x 2 grid of 8 px cells: flow u = column index, v = row index.
        let layout = GridLayout::new(24, 16, 8).unwrap();
        let nodes: Vec<GridNode> = (0..6)
            .map(|i| GridNode::tracked(Point::from_f32((i % 3) as f32, (i / 3) as f32)))
            .collect();
        let field = FlowField::from_grid(&layout, &nodes);
        assert_eq!(field.at(4, 4), Some((0.0, 0.0)));
        assert_eq!(field.at(8, 4), Some((0.5, 0.0)));
        assert_eq!(field.at(14, 10), Some((1.25, 0.75)));
        assert_eq!(field.at(0, 0), Some((0.0, 0.0)));
        assert_eq!(field.at(23, 15), Some((2.0, 1.0)));
        assert_eq!(field.at(24, 0), None);
    }

    #[test]
    fn unknown_nodes_drop_out_and_alone_leave_pixels_unknown() {
        let layout = GridLayout::new(16, 8, 8).unwrap();
        let nodes = [
            GridNode::invalid(NodeStatus::LowTexture),
            GridNode {
                flow: Point::from_f32(2.0, 0.0),
                status: NodeStatus::Filled,
                fill_pass: 1,
            },
        ];
        let field = FlowField::from_grid(&layout, &nodes);
        assert_eq!(field.at(4, 4), None);
        assert_eq!(field.at(6, 4), Some((2.0, 0.0)));
        assert_eq!(field.max_speed(), 2.0);
    }

    #[test]
    fn flo_files_round_trip() {
        let field = FlowField {
            width: 3,
            height: 2,
            flow: vec![
                Some((0.5, -1.25)),
                None,
                Some((3.0, 4.0)),
                None,
                None,
                Some((0.0, 0.0)),
            ],
        };
        let bytes = field.to_flo();
        assert_eq!(&bytes[..4], b"PIEH");
        assert_eq!(bytes.len(), 12 + 6 * 8);
        assert_eq!(FlowField::from_flo(&bytes), Ok(field));
        assert!(FlowField::from_flo(&bytes[..20]).is_err());
        assert!(FlowField::from_flo(b"PIEX\0\0\0\0\0\0\0\0").is_err());
    }
}
