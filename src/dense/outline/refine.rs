//! Each object flow refined on the pixels that chose it.
//!
//! A flow from the vote is a whole level-1 pixel, two at level 0, and a node's flow is
//! measured over a window that also sees the ground: the object's own pixels give its flow
//! more exactly, and more of them then match.

use super::area::Area;
use super::differences::{sample, SUB_BITS};
use super::flows::Flows;
use super::OUTLINE_MAX_FLOWS;
use crate::frame::ImageView;
use crate::q16::{q16_from_f32, Point};

/// One Gauss-Newton step of each flow on the pixels labelled with it: the shift that best
/// explains, to first order, the differences between the previous frame and the next sampled
/// at the flow, by the previous frame's gradient (central differences). A flow with too few
/// pixels or a singular system is kept.
pub(super) fn refine(
    (prev, next): (&ImageView<'_>, &ImageView<'_>),
    area: &Area,
    flows: &mut Flows,
    label_of: impl Fn(usize, usize) -> u16,
) {
    let sums = normal_sums(prev, next, area, flows, label_of);
    for (flow, sums) in flows.flows.iter_mut().zip(sums).take(flows.len) {
        if let Some((dx, dy)) = step(sums) {
            *flow = Point::new(
                flow.x.saturating_add(q16_from_f32(dx)),
                flow.y.saturating_add(q16_from_f32(dy)),
            );
        }
    }
}

/// The sums of the normal equations of each flow over the pixels `label_of` (column and row
/// in the area) gives it: gxx, gxy, gyy, gx e, gy e.
fn normal_sums(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    area: &Area,
    flows: &Flows,
    label_of: impl Fn(usize, usize) -> u16,
) -> [[i64; 5]; OUTLINE_MAX_FLOWS] {
    // Per flow: gxx, gxy, gyy, gx e, gy e; gradients and differences grey x 16 (|g| < 2^12,
    // |e| < 2^12), so each product is below 2^24 and 2^16 pixels of them below 2^40.
    let mut sums = [[0i64; 5]; OUTLINE_MAX_FLOWS];
    for row in 0..area.h {
        let y = area.y + row;
        let (up, here, down) = (prev.row(y - 1), prev.row(y), prev.row(y + 1));
        for col in 0..area.w {
            let label = usize::from(label_of(col, row));
            let (Some(flow), Some(sum)) = (
                label.checked_sub(1).and_then(|k| flows.flows.get(k)),
                label.checked_sub(1).and_then(|k| sums.get_mut(k)),
            ) else {
                continue;
            };
            let x = area.x + col;
            let at = |r: &[u8], x: usize| i64::from(r.get(x).copied().unwrap_or(0));
            let gx = (at(here, x + 1) - at(here, x - 1)) << (SUB_BITS - 1);
            let gy = (at(down, x) - at(up, x)) << (SUB_BITS - 1);
            let Some(q) = sample(next, x, y, (flow.x.to_bits(), flow.y.to_bits())) else {
                continue;
            };
            let e = i64::from(q) - (at(here, x) << SUB_BITS);
            for (s, v) in sum
                .iter_mut()
                .zip([gx * gx, gx * gy, gy * gy, gx * e, gy * e])
            {
                *s += v;
            }
        }
    }
    sums
}

/// The step, px, that solves one flow's normal equations `sums`; `None` for a singular
/// system or a step of two pixels or more (too few pixels, or pixels of another motion).
fn step([gxx, gxy, gyy, bx, by]: [i64; 5]) -> Option<(f32, f32)> {
    let det = (gxx as f32) * (gyy as f32) - (gxy as f32) * (gxy as f32);
    if det <= 0.0 || !det.is_finite() {
        return None;
    }
    // delta = -G^-1 b, px.
    let dx = -((gyy as f32) * (bx as f32) - (gxy as f32) * (by as f32)) / det;
    let dy = -((gxx as f32) * (by as f32) - (gxy as f32) * (bx as f32)) / det;
    (dx.abs() < 2.0 && dy.abs() < 2.0).then_some((dx, dy))
}
