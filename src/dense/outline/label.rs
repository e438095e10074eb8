//! Each pixel of an area labelled with the motion that explains it: the camera's, or one of
//! the object flows.
//!
//! A pixel belongs to an object when one of its flows matches its 3 x 3 neighbourhood in the
//! next frame clearly better than the camera's flow does, and better than its own texture
//! would allow a misaligned match to. The rows of differences go through a ring of three rows
//! per hypothesis: each new row completes the 3 x 3 sums of the row above it, so each pixel's
//! differences are computed once per hypothesis.

use super::area::Area;
use super::differences::{camera_row, flow_row, sums3, texture_row, UNKNOWN};
use super::flows::Flows;
use super::scratch::OutlineScratch;
use super::Outliner;
use crate::dense::motion::CameraMotion;
use crate::frame::ImageView;

/// How many times a flow's 3 x 3 mismatch the texture of the previous frame there must be:
/// the sum of absolute differences to the right and below neighbours is what a one-pixel
/// misalignment costs, so a pixel whose match is not clearly better than that (flat ground,
/// which any flow matches) belongs to no object.
const TEXTURE_RATIO: u32 = 2;

/// Which row of sums [`Outliner::decide_row`] is filling.
#[derive(Clone, Copy)]
enum Sums {
    Camera,
    Texture,
    Flow(u16),
}

/// The 3 x 3 sums along the row being labelled, `area.w` each, in the scratch's stack (free
/// while labelling: the flood fill comes after).
struct RowSums<'s> {
    camera: &'s mut [u16],
    texture: &'s mut [u16],
    /// The best object flow's sum at each pixel, and beside it that flow's label.
    best: &'s mut [u16],
    chosen: &'s mut [u16],
}

impl<'s> RowSums<'s> {
    /// Cuts `stack` into four rows of `w`, which the caller has checked it holds.
    fn split(stack: &'s mut [u16], w: usize) -> Self {
        let (camera, rest) = stack.split_at_mut(w);
        let (texture, rest) = rest.split_at_mut(w);
        let (best, rest) = rest.split_at_mut(w);
        let (chosen, _) = rest.split_at_mut(w.min(rest.len()));
        Self {
            camera,
            texture,
            best,
            chosen,
        }
    }
}

impl Outliner {
    /// Writes each pixel's label into the scratch's labels (row by row, `area.w` a row): 0 for
    /// the camera or nothing, `k + 1` for object flow `k`.
    pub(super) fn label(
        &self,
        (prev, next): (&ImageView<'_>, &ImageView<'_>),
        camera: &impl CameraMotion,
        area: &Area,
        flows: &Flows,
        scratch: &mut OutlineScratch<'_>,
    ) {
        let OutlineScratch {
            labels,
            stack,
            ring,
            ..
        } = scratch;
        let hypotheses = flows.len.saturating_add(1);
        let row_len = area.w.saturating_add(2);
        // The ring holds three rows for each of the OUTLINE_MAX_FLOWS + 2 hypotheses at the scratch's
        // side, and the area is at most that side wide, so every row below fits. Checked once
        // here so that a broken scratch leaves no pixel labelled from an older labelling.
        let needed = (hypotheses + 1) * 3 * row_len;
        let fits =
            ring.len() >= needed && stack.len() >= 4 * area.w && labels.len() >= area.pixels();
        debug_assert!(fits, "labelling scratch too short for {area:?}");
        if !fits {
            labels.fill(0);
            return;
        }
        // One row of 3 x 3 sums needs rows y - 1, y and y + 1 of differences: each new row
        // of differences completes the sums of the row above it.
        for yy in area.y.saturating_sub(1)..=area.y.saturating_add(area.h) {
            let slot = yy % 3;
            for h in 0..=hypotheses {
                let start = (h * 3 + slot) * row_len;
                // Inside `needed`, checked above.
                let Some(row) = ring.get_mut(start..start.saturating_add(row_len)) else {
                    continue;
                };
                match h {
                    0 => camera_row(prev, next, camera, area, yy, row),
                    _ if h == hypotheses => texture_row(prev, area, yy, row),
                    _ => flow_row(prev, next, area, yy, flows.flows.get(h - 1), row),
                }
            }
            if yy > area.y {
                self.decide_row(area, yy - 1, hypotheses, ring, stack, labels);
            }
        }
    }

    /// Labels row `y` of the area from the three rows of differences around it: each
    /// hypothesis's 3 x 3 sums along the row from running column sums, the best object flow's
    /// kept in `stack` beside the camera's and the texture's.
    fn decide_row(
        &self,
        area: &Area,
        y: usize,
        hypotheses: usize,
        ring: &[u16],
        stack: &mut [u16],
        labels: &mut [u16],
    ) {
        let w = area.w;
        let sums = RowSums::split(stack, w);
        sums.best.iter_mut().for_each(|b| *b = u16::MAX);
        for h in 0..=hypotheses {
            let kind = match h {
                0 => Sums::Camera,
                _ if h == hypotheses => Sums::Texture,
                _ => Sums::Flow(h as u16),
            };
            // The ring's length was checked by `label`, the only caller.
            let rows = ring.get(h * 3 * (w + 2)..(h + 1) * 3 * (w + 2));
            debug_assert!(rows.is_some(), "ring rows of hypothesis {h}");
            sums3(rows.unwrap_or(&[]), w, |x, e| match kind {
                Sums::Camera => sums.camera[x] = e,
                Sums::Texture => sums.texture[x] = e,
                Sums::Flow(k) => {
                    if e < sums.best[x] {
                        sums.best[x] = e;
                        sums.chosen[x] = k;
                    }
                }
            });
        }
        let gain = self.gain();
        let base = (y - area.y) * w;
        for x in 0..w {
            let (cam, e, tex) = (
                u32::from(sums.camera[x]),
                u32::from(sums.best[x]),
                u32::from(sums.texture[x]),
            );
            // Better than the camera, and than a misalignment of half a pixel would match.
            let object = cam < u32::from(UNKNOWN)
                && e + gain < cam
                && 2 * e < cam
                && TEXTURE_RATIO * e < tex;
            if let Some(label) = labels.get_mut(base + x) {
                *label = if object { sums.chosen[x] } else { 0 };
            }
        }
    }
}
