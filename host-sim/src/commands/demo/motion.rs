//! The demo's dense section: the grid flow of one frame pair as a Middlebury colour picture, and
//! the moving-object boxes over the whole sequence, scored against the ground truth.

use std::path::Path;
use std::time::Instant;

use kestrel::dense::{DenseParams, MotionBox};

use super::Scenario;
use crate::commands::CommandError;
use crate::dense::field::FlowField;
use crate::dense::picture::motion_overlay;
use crate::dense::wheel::flow_picture;
use crate::dense::{DenseRunner, MotionRunner, MotionSettings, RunError};
use crate::io::create_output_dir;
use crate::io::images::write_rgb_png;

/// The pair whose flow is pictured: the middle of the sequence, with the box in view.
const FLOW_PAIR: usize = 30;
/// Every how many frames a motion picture is written.
const PICTURE_STEP: usize = 5;
/// Overlap with the true outline that counts as finding the object.
const MIN_IOU: f64 = 0.3;

/// Runs dense flow and motion detection on the scenario and writes into `dir`: `flow.png`
/// (colour wheel: hue is direction, brightness speed) and `boxes/NNNNNN.png`.
pub fn run(scenario: &Scenario, dir: &Path) -> Result<Vec<String>, CommandError> {
    let frames = &scenario.frames;
    let (width, height) = (frames[0].width, frames[0].height);
    let settings = MotionSettings::default();
    let failed = |e: RunError| CommandError::Processing(format!("dense mode: {e:?}"));

    // The picture shows the grid mode's flow, as `host-sim dense` computes it.
    let mut dense = DenseRunner::new(DenseParams::default(), width, height).map_err(failed)?;
    let start = Instant::now();
    let grid = dense
        .compute(&frames[FLOW_PAIR - 1], &frames[FLOW_PAIR])
        .map_err(failed)?;
    let dense_ms = start.elapsed().as_secs_f64() * 1e3;
    let field = FlowField::from_grid(dense.layout(), dense.nodes());
    write_rgb_png(&dir.join("flow.png"), &flow_picture(&field))?;

    let boxes_dir = dir.join("boxes");
    create_output_dir(&boxes_dir)?;
    let mut motion = MotionRunner::new(settings, width, height).map_err(failed)?;
    let mut score = Score::default();
    for (index, frame) in frames.iter().enumerate() {
        let start = Instant::now();
        let Some(found) = motion.push(frame.clone()).map_err(failed)? else {
            continue;
        };
        score.seconds.push(start.elapsed().as_secs_f64());
        let boxes = found.boxes_in_later_frame(width, height);
        score.add(&truth_boxes(scenario, index, width, height), &boxes);
        if index % PICTURE_STEP == 0 {
            let picture =
                motion_overlay(frame, motion.layout(), motion.nodes(), &found.mask, &boxes);
            write_rgb_png(&boxes_dir.join(format!("{index:06}.png")), &picture)?;
        }
    }
    Ok(vec![
        format!(
            "grid flow, frames {}-{}: {} of {} nodes measured, in {dense_ms:.2} ms; flow.png",
            FLOW_PAIR - 1,
            FLOW_PAIR,
            grid.tracked,
            dense.nodes().len(),
        ),
        score.summary(),
        format!(
            "pictures: boxes/000005.png to boxes/{:06}.png, every {PICTURE_STEP}th frame",
            { (frames.len() - 1) / PICTURE_STEP * PICTURE_STEP }
        ),
    ])
}

/// A box as (left, top, right, bottom), px.
type Rect = (f64, f64, f64, f64);

/// The true outline of each object in frame `index`, clipped to the frame; none when out of view.
fn truth_boxes(scenario: &Scenario, index: usize, width: usize, height: usize) -> Vec<Rect> {
    let warp = scenario.sequence.homography(index);
    let (w, h) = (width as f64 - 1.0, height as f64 - 1.0);
    scenario
        .sequence
        .scene()
        .objects
        .iter()
        .filter_map(|object| {
            let (cx, cy) = object.centre(index as f64);
            let (hw, hh) = object.half_size;
            let corners = [(-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh)]
                .map(|(dx, dy)| warp.apply(cx + dx, cy + dy));
            let xs = corners.map(|c| c.0);
            let ys = corners.map(|c| c.1);
            let fold = |v: [f64; 4], f: fn(f64, f64) -> f64| v.into_iter().reduce(f).unwrap_or(0.0);
            let rect = (
                fold(xs, f64::min).max(0.0),
                fold(ys, f64::min).max(0.0),
                fold(xs, f64::max).min(w),
                fold(ys, f64::max).min(h),
            );
            // Count an object only while most of it is in view.
            let visible = area(rect) >= 0.5 * 4.0 * hw * hh;
            visible.then_some(rect)
        })
        .collect()
}

fn area((l, t, r, b): Rect) -> f64 {
    (r - l).max(0.0) * (b - t).max(0.0)
}

fn iou(a: Rect, b: Rect) -> f64 {
    let inter = area((a.0.max(b.0), a.1.max(b.1), a.2.min(b.2), a.3.min(b.3)));
    let union = area(a) + area(b) - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

/// How the boxes compare with the true outlines over the sequence.
#[derive(Debug, Default)]
struct Score {
    /// Frames where an object is in view, and those where a box overlaps it.
    visible: usize,
    found: usize,
    /// Boxes overlapping no object, of all boxes.
    false_boxes: usize,
    boxes: usize,
    seconds: Vec<f64>,
}

impl Score {
    fn add(&mut self, truth: &[Rect], boxes: &[MotionBox]) {
        let rects: Vec<Rect> = boxes
            .iter()
            .map(|b| {
                let (x, y) = (f64::from(b.x), f64::from(b.y));
                (x, y, x + f64::from(b.w), y + f64::from(b.h))
            })
            .collect();
        for &t in truth {
            self.visible += 1;
            if rects.iter().any(|&r| iou(r, t) >= MIN_IOU) {
                self.found += 1;
            }
        }
        self.boxes += rects.len();
        self.false_boxes += rects
            .iter()
            .filter(|&&r| truth.iter().all(|&t| iou(r, t) < MIN_IOU))
            .count();
    }

    fn summary(&self) -> String {
        let mean_ms = 1e3 * self.seconds.iter().sum::<f64>() / self.seconds.len().max(1) as f64;
        format!(
            "moving box found (IoU >= {MIN_IOU}) in {} of {} frames where it is in view; \
             {} of {} boxes false; {mean_ms:.2} ms per frame (camera motion removed)",
            self.found, self.visible, self.false_boxes, self.boxes
        )
    }
}
