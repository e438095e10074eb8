//! A candidate's outlines written as boxes: the largest first, specks left out, and an
//! object's outline seen from two candidates written once.

use super::area::Area;
use super::flood::{flood, Outline, VISITED};
use super::flows::Flows;
use super::scratch::OutlineScratch;
use super::Outliner;
use crate::dense::regions::MotionBox;

/// An outline with fewer than one in this many of the pixels of its candidate's largest is a
/// speck of chance matches at that object's edge, where it covers or uncovers ground; two
/// objects in one region are rarely that unequal.
const SPECK_RATIO: usize = 8;

/// The largest outlines of a candidate, with their pixels, the largest first.
type Ranked = heapless::Vec<(usize, MotionBox), 16>;

impl Outliner {
    /// Joins the labelled pixels into outlines and writes those of at least
    /// [`super::OutlineParams::min_pixels`] into `boxes` after the `written` there; returns the
    /// new number written.
    pub(super) fn gather(
        &self,
        area: &Area,
        flows: &Flows,
        candidate: &MotionBox,
        scratch: &mut OutlineScratch<'_>,
        boxes: &mut [MotionBox],
        mut written: usize,
    ) -> usize {
        let joined = flows.joined();
        let mut found = Ranked::new();
        for seed in 0..area.pixels() {
            let Some(&label) = scratch.labels.get(seed) else {
                break;
            };
            if label == 0 || label & VISITED != 0 {
                continue;
            }
            let outline = flood(area, &joined, scratch.labels, scratch.stack, seed);
            if outline.pixels >= self.params.min_pixels {
                let b = outline_box(area, flows, candidate, &outline);
                rank(&mut found, outline.pixels, b);
            }
        }
        // The largest first: a speck of chance matches on an object is covered by it, and one
        // beside it (where it uncovers or covers the ground) is far smaller than it.
        let largest = found.first().map_or(0, |(pixels, _)| *pixels);
        for (pixels, b) in found {
            if pixels.saturating_mul(SPECK_RATIO) >= largest {
                written = push_new(boxes, written, b);
            }
        }
        written
    }
}

/// The box of `outline` in the frame, with its candidate's nodes and the flow most of its
/// pixels chose.
fn outline_box(area: &Area, flows: &Flows, candidate: &MotionBox, outline: &Outline) -> MotionBox {
    let chosen = (0..flows.len)
        .max_by_key(|&k| outline.votes.get(k).copied().unwrap_or(0))
        .unwrap_or(0);
    MotionBox {
        x: to_u16(area.x + outline.cols.0),
        y: to_u16(area.y + outline.rows.0),
        w: to_u16(outline.cols.1 + 1 - outline.cols.0),
        h: to_u16(outline.rows.1 + 1 - outline.rows.0),
        nodes: candidate.nodes,
        mean_flow: flows.flows.get(chosen).copied().unwrap_or_default(),
    }
}

/// Inserts box `b` of `pixels` pixels into `found` by size, after those of as many pixels.
fn rank(found: &mut Ranked, pixels: usize, b: MotionBox) {
    // A full list keeps the largest outlines: it drops its smallest to make room, so the
    // insertion below always has a free slot at a position <= its length.
    let at = found.iter().position(|(p, _)| *p < pixels);
    let at = match (found.is_full(), at) {
        (true, None) => return,
        (true, Some(at)) => {
            found.pop();
            at
        }
        (false, at) => at.unwrap_or(found.len()),
    };
    let inserted = found.insert(at, (pixels, b));
    debug_assert!(inserted.is_ok(), "a free slot was made above");
}

/// Writes `b` at `written` unless it and a box written before mostly cover each other, in which
/// case the larger of the two is kept there; returns the new count (unchanged when `boxes` is
/// full).
pub(super) fn push_new(boxes: &mut [MotionBox], written: usize, b: MotionBox) -> usize {
    let (kept, room) = boxes.split_at_mut(written.min(boxes.len()));
    match kept.iter_mut().find(|a| covers(a, &b)) {
        // One object's two outlines (a speck of it seen from another candidate): the larger
        // stays.
        Some(a) => {
            if b.area() > a.area() {
                *a = b;
            }
            written
        }
        None => match room.first_mut() {
            Some(slot) => {
                *slot = b;
                written + 1
            }
            None => written,
        },
    }
}

/// True when the two boxes share at least half the smaller one's area.
fn covers(a: &MotionBox, b: &MotionBox) -> bool {
    2 * a.overlap_area(b) >= a.area().min(b.area()).max(1)
}

fn to_u16(v: usize) -> u16 {
    u16::try_from(v).unwrap_or(u16::MAX)
}
