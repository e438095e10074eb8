//! The dense grid, its dominant motion and moving-object boxes on arbitrary frames, settings
//! and buffer lengths.
//!
//! Counts must agree with the nodes, nodes beyond the grid stay untouched, a measured node's
//! centre plus its flow lies inside the frame, a node without flow has zero flow, fill passes
//! stay within the limit; the dominant motion is finite; every box lies inside the frame, has
//! at least the minimum number of nodes and comes largest first, no more boxes than regions.

use super::picture::{Change, Picture};
use arbitrary::Arbitrary;
use kestrel::dense::{
    grid_len, mask_words, motion_scratch_len, smooth_scratch_len, smooth_tracked, BoxRules,
    DenseError, DenseFlow, DenseParams, DominantFitParams, DominantMotion, GridLayout, GridNode,
    MaskStructure, MotionBox, MotionDetector, MotionParams, NodeStatus,
};
use kestrel::lk::{scratch_len, LkParams};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::{Bound, ConfigError, Point};

#[derive(Arbitrary, Debug)]
struct Input {
    prev: Picture,
    change: Change,
    other: Option<Picture>,
    levels: u8,
    cell: u8,
    window: u8,
    max_level: u8,
    max_iterations: u8,
    min_eigen_threshold: f32,
    plain: bool,
    max_residual: f32,
    fill_passes: u8,
    nodes_delta: i8,
    scratch_delta: i8,
    fit: (f32, f32, u8),
    motion: MotionInput,
    /// The smoothing's gate and how far its rows are from the length it needs; last, so the
    /// corpus from before it decodes the same.
    smooth: Option<(f32, i8)>,
}

#[derive(Arbitrary, Debug)]
struct MotionInput {
    threshold: f32,
    include_filled: bool,
    close: Option<bool>,
    open: Option<bool>,
    min_nodes: u32,
    inset: u8,
    mask_delta: i8,
    scratch_delta: i8,
    boxes: u8,
}

/// The decoded input, for reading a crash.
pub fn show(data: &[u8]) -> String {
    super::show::<Input>(data)
}

pub fn run(data: &[u8]) {
    let Some(input) = super::decode::<Input>(data) else {
        return;
    };
    let prev_frame = input.prev.render();
    let next_frame = match &input.other {
        Some(other) => other.render(),
        None => Picture {
            change: input.change,
            ..input.prev.clone()
        }
        .render(),
    };
    let (Some(prev), Some(next)) = (prev_frame.view(), next_frame.view()) else {
        return;
    };
    let levels = usize::from(input.levels % 5);
    let mut prev_storage = vec![0; pyramid_storage_len(prev.width(), prev.height(), levels)];
    let mut next_storage = vec![0; pyramid_storage_len(next.width(), next.height(), levels)];
    let prev = Pyramid::build(prev, levels, &mut prev_storage).expect("pyramid");
    let next = Pyramid::build(next, levels, &mut next_storage).expect("pyramid");
    let params = DenseParams {
        cell: usize::from(input.cell % 40),
        lk: LkParams {
            window: usize::from(input.window % 24),
            max_level: usize::from(input.max_level % 5),
            max_iterations: u32::from(input.max_iterations % 20),
            epsilon: 0.01,
            min_eigen_threshold: input.min_eigen_threshold,
            illumination: super::illumination(input.plain),
            template: super::template_placement(input.max_iterations),
        },
        max_residual: input.max_residual,
        fill_passes: input.fill_passes % 6,
        // 0 (off) to 1.5 px: the last two are refused.
        camera_tolerance: f32::from(input.fill_passes % 7) * 0.25,
        search_flat: (input.levels / 10) % 2 == 0,
    };
    let Ok(dense) = DenseFlow::new(params) else {
        return;
    };
    let (w, h) = (prev.base().width(), prev.base().height());
    let len = grid_len(w, h, params.cell);
    let mut nodes = vec![
        GridNode::invalid(NodeStatus::Residual);
        len.saturating_add_signed(input.nodes_delta.into())
    ];
    let needed = scratch_len(params.lk.window);
    let mut scratch = vec![0i16; needed.saturating_add_signed(input.scratch_delta.into())];
    // The quotient the modulus above ignores picks the search from a prediction: a constant
    // shift from two of the fit's floats, so hostile ones (NaN, huge) reach it too.
    let shift = (input.fit.0, input.fit.1);
    let predict = move |p: Point| {
        let (x, y) = p.to_f32();
        Point::from_f32(x + shift.0, y + shift.1)
    };
    let outcome = if (input.levels / 5) % 2 == 1 {
        dense.compute_predicted(&prev, &next, &mut nodes, &mut scratch, &predict)
    } else {
        dense.compute(&prev, &next, &mut nodes, &mut scratch)
    };
    let summary = match outcome {
        Ok(summary) => summary,
        Err(e) => {
            check_refusal(
                e,
                &params,
                (w, h),
                &next.base(),
                nodes.len() < len,
                scratch.len() < needed,
            );
            return;
        }
    };
    let layout = summary.layout;
    assert_eq!(layout.len(), len);
    let grid = &nodes[..len];
    let count = |s: NodeStatus| grid.iter().filter(|n| n.status == s).count();
    assert_eq!(summary.tracked, count(NodeStatus::Tracked));
    assert_eq!(summary.filled, count(NodeStatus::Filled));
    assert!(
        nodes[len..]
            .iter()
            .all(|n| *n == GridNode::invalid(NodeStatus::Residual)),
        "a node beyond the grid was written"
    );
    for (i, node) in grid.iter().enumerate() {
        check_node(&layout, i, node, params.fill_passes);
    }
    if let Some((gate, rows_delta)) = input.smooth {
        check_smoothing(
            &layout,
            &mut nodes[..len],
            gate,
            rows_delta,
            params.fill_passes,
        );
    }
    let grid = &nodes[..len];
    let motion = check_dominant(&layout, grid, input.fit);
    check_motion(&layout, grid, &motion, &input.motion);
}

/// The smoothing keeps every status, moves only measured nodes and keeps them inside the
/// frame, or refuses a bad gate or short rows.
fn check_smoothing(layout: &GridLayout, nodes: &mut [GridNode], gate: f32, delta: i8, passes: u8) {
    let needed = smooth_scratch_len(layout.width(), layout.cell());
    let mut rows = vec![Point::default(); needed.saturating_add_signed(delta.into())];
    let before = nodes.to_vec();
    match smooth_tracked(layout, nodes, gate, &mut rows) {
        Ok(smoothed) => {
            let tracked = before.iter().filter(|n| n.is_valid()).count();
            assert!(smoothed <= tracked, "{smoothed} of {tracked}");
            for (i, (after, before)) in nodes.iter().zip(&before).enumerate() {
                assert_eq!(after.status, before.status);
                if !before.is_valid() {
                    assert_eq!(after, before);
                }
                check_node(layout, i, after, passes);
            }
        }
        Err(ConfigError {
            field: "gate",
            bound: Bound::NonNegativeBelow(32_768),
        }) => assert!(!(0.0..=32767.0).contains(&gate), "{gate}"),
        Err(ConfigError {
            field: "rows",
            bound: Bound::MinLen(len),
        }) => assert!(rows.len() < needed && len == needed),
        Err(other) => panic!("unexpected refusal {other:?}"),
    }
}

/// A refusal names a real problem.
fn check_refusal(
    e: DenseError,
    params: &DenseParams,
    (w, h): (usize, usize),
    next: &kestrel::ImageView<'_>,
    short_nodes: bool,
    short_scratch: bool,
) {
    let refused = |field| match e {
        DenseError::Config(ConfigError { field: f, bound }) if f == field => Some(bound),
        _ => None,
    };
    if e == DenseError::FrameSizeMismatch {
        assert!((w, h) != (next.width(), next.height()));
    } else if let Some(bound) = refused("cell") {
        assert!(params.cell > w || params.cell > h);
        let max = w.min(h) as u32;
        assert_eq!(bound, Bound::Range { min: 1, max });
    } else if let Some(bound) = refused("nodes") {
        assert!(short_nodes);
        assert_eq!(bound, Bound::MinLen(grid_len(w, h, params.cell)));
    } else if let Some(bound) = refused("scratch") {
        assert!(short_scratch);
        assert_eq!(bound, Bound::MinLen(scratch_len(params.lk.window)));
    } else if e != DenseError::FrameTooSmall {
        panic!("unexpected refusal {e:?}");
    }
}

fn check_node(layout: &GridLayout, index: usize, node: &GridNode, passes: u8) {
    let (col, row) = layout.node(index);
    let (x, y) = layout.centre(col, row);
    assert!(x < layout.width() && y < layout.height());
    match node.status {
        NodeStatus::Tracked => {
            let (dx, dy) = node.flow.to_f32();
            let (nx, ny) = (x as f32 + dx, y as f32 + dy);
            let (wm, hm) = ((layout.width() - 1) as f32, (layout.height() - 1) as f32);
            assert!(
                (0.0..=wm).contains(&nx) && (0.0..=hm).contains(&ny),
                "{node:?} at ({x}, {y})"
            );
            assert_eq!(node.fill_pass, 0);
        }
        NodeStatus::Filled => assert!((1..=passes).contains(&node.fill_pass), "{node:?}"),
        _ => assert_eq!(
            (node.flow, node.fill_pass),
            (Point::default(), 0),
            "{node:?}"
        ),
    }
}

fn check_dominant(layout: &GridLayout, nodes: &[GridNode], fit: (f32, f32, u8)) -> DominantMotion {
    let params = DominantFitParams {
        start_radius: fit.0,
        inlier_radius: fit.1,
        iterations: fit.2 % 16,
    };
    let positive = |r: f32| r.is_finite() && r > 0.0;
    let Ok(result) = DominantMotion::fit(layout, nodes, &params) else {
        assert!(!positive(params.start_radius) || !positive(params.inlier_radius));
        return DominantMotion::ZERO;
    };
    let measured = nodes.iter().filter(|n| n.is_valid()).count();
    assert_eq!(result.measured, measured);
    assert!(result.inliers <= measured);
    assert!(result.spread.is_finite() && result.spread >= 0.0);
    let m = result.motion;
    assert!(m.dx.iter().chain(&m.dy).all(|v| v.is_finite()), "{m:?}");
    m
}

fn check_motion(
    layout: &GridLayout,
    nodes: &[GridNode],
    camera: &DominantMotion,
    input: &MotionInput,
) {
    let structure = |square3: bool| {
        if square3 {
            MaskStructure::Square3
        } else {
            MaskStructure::Square2
        }
    };
    let params = MotionParams {
        threshold: input.threshold,
        include_filled: input.include_filled,
        close: input.close.map(structure),
        open: input.open.map(structure),
        boxes: BoxRules {
            min_nodes: input.min_nodes % 8,
            inset: usize::from(input.inset % 16),
        },
    };
    let Ok(detector) = MotionDetector::new(params) else {
        assert!(!(params.threshold.is_finite() && params.threshold >= 0.0));
        return;
    };
    let (w, h, cell) = (layout.width(), layout.height(), layout.cell());
    let mask_len = mask_words(w, h, cell).saturating_add_signed(input.mask_delta.into());
    let scratch_len =
        motion_scratch_len(w, h, cell).saturating_add_signed(input.scratch_delta.into());
    let mut mask = vec![0u32; mask_len];
    let mut scratch = vec![0u32; scratch_len];
    let mut boxes = vec![MotionBox::default(); usize::from(input.boxes % 8)];
    let Ok(summary) = detector.detect(layout, nodes, camera, &mut mask, &mut scratch, &mut boxes)
    else {
        assert!(
            input.mask_delta < 0 || input.scratch_delta < 0,
            "valid buffers refused"
        );
        return;
    };
    assert!(summary.moving <= layout.len());
    assert!(summary.boxes <= boxes.len() && summary.boxes <= summary.regions);
    for (i, b) in boxes[..summary.boxes].iter().enumerate() {
        assert!(b.w > 0 && b.h > 0, "{b:?}");
        assert!(usize::from(b.x) + usize::from(b.w) <= w, "{b:?}");
        assert!(usize::from(b.y) + usize::from(b.h) <= h, "{b:?}");
        assert!(b.nodes >= params.boxes.min_nodes.max(1), "{b:?}");
        if let Some(next) = boxes.get(i + 1).filter(|_| i + 1 < summary.boxes) {
            assert!(next.nodes <= b.nodes, "boxes not largest first");
        }
        let moved = b.in_next_frame(w, h);
        assert!(
            usize::from(moved.x) + usize::from(moved.w) <= w,
            "{moved:?}"
        );
        assert!(
            usize::from(moved.y) + usize::from(moved.h) <= h,
            "{moved:?}"
        );
    }
}
