//! A candidate's outlines written as boxes: the largest first, specks left out, the parts of
//! one body joined, and an object's outline seen from two candidates written once.

use super::area::Area;
use super::flood::{flood, Outline, VISITED};
use super::flows::Flows;
use super::scratch::OutlineScratch;
use super::Outliner;
use crate::dense::bodies::join_pairs;
use crate::dense::regions::MotionBox;
use crate::q16::Point;

/// An outline with fewer than one in this many of the pixels of its candidate's largest is a
/// speck of chance matches at that object's edge, where it covers or uncovers ground; two
/// objects in one region are rarely that unequal.
const SPECK_RATIO: usize = 8;

/// Outlines of one candidate at most this far apart, px (the gap between their boxes), or half
/// the smaller one's longer side when that is more, may be parts of one body: a walker's legs
/// and arms leave a pixel or two of ground between them and the torso where their flows
/// disagree, and on a larger body plain clothes and blur leave gaps that grow with it.
const PART_GAP: u16 = 4;

/// Parts of one body move alike: two outlines join when their flows differ by at most this,
/// Q16 (one pixel), or by at most half the faster one's flow ([`PART_SHARE_SHIFT`]): a leg
/// swings at up to twice its torso's speed, while two bodies that pass each other rarely move
/// within half a speed of each other.
const PART_FLOW: i64 = 1 << 16;

/// Half, as a shift of a squared flow (a quarter).
const PART_SHARE_SHIFT: u32 = 2;

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
        let mut parts = Parts::new();
        for (pixels, b) in found {
            if pixels.saturating_mul(SPECK_RATIO) >= largest {
                // At most as many as `found` holds.
                let pushed = parts.push(b);
                debug_assert!(pushed.is_ok(), "more parts than ranked outlines");
            }
        }
        join_parts(&mut parts);
        for b in parts {
            written = push_new(boxes, written, b);
        }
        written
    }
}

/// A candidate's outlines after the specks are left out, the largest first.
type Parts = heapless::Vec<MotionBox, 16>;

/// Joins the outlines that are parts of one body ([`PART_GAP`], [`PART_FLOW`]) into one box,
/// with the flow of the larger (earlier) one, until no two are.
fn join_parts(parts: &mut Parts) {
    let count = parts.len();
    let left = join_pairs(parts, count, one_body, MotionBox::union);
    parts.truncate(left);
}

/// True when `a` and `b` lie within [`PART_GAP`] of each other, or half the smaller one's
/// longer side, and move alike.
fn one_body(a: &MotionBox, b: &MotionBox) -> bool {
    let side = |m: &MotionBox| m.w.max(m.h);
    let reach = PART_GAP.max(side(a).min(side(b)) / 2);
    a.gap_to(b) <= reach && moves_alike(a.mean_flow, b.mean_flow)
}

/// True when flows `a` and `b` differ by at most [`PART_FLOW`] or half the faster one.
pub(in crate::dense) fn moves_alike(a: Point, b: Point) -> bool {
    let sq = |x: i64, y: i64| x.saturating_mul(x).saturating_add(y.saturating_mul(y));
    let bits = |p: Point| (i64::from(p.x.to_bits()), i64::from(p.y.to_bits()));
    let ((ax, ay), (bx, by)) = (bits(a), bits(b));
    let apart = sq(ax.saturating_sub(bx), ay.saturating_sub(by));
    let faster = sq(ax, ay).max(sq(bx, by));
    apart <= (PART_FLOW * PART_FLOW).max(faster >> PART_SHARE_SHIFT)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn part(x: u16, y: u16, w: u16, h: u16, flow: (f32, f32)) -> MotionBox {
        let mean_flow = Point::from_f32(flow.0, flow.1);
        MotionBox {
            x,
            y,
            w,
            h,
            nodes: 1,
            mean_flow,
        }
    }

    #[test]
    fn a_bodys_parts_join_and_two_bodies_do_not() {
        // A walker's torso, and a leg 2 px below it swinging at 1.8 times its speed: 1.6 px
        // apart, within half the leg's speed.
        let torso = part(40, 20, 10, 16, (2.0, 0.0));
        let leg = part(41, 38, 5, 10, (3.6, 0.2));
        let mut parts = Parts::from_slice(&[torso, leg]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.as_slice(), [part(40, 20, 10, 28, (2.0, 0.0))]);
        // The same leg swinging at 2.5 times: 3 px apart, beyond half its speed.
        let kick = part(41, 38, 5, 10, (5.0, 0.0));
        let mut parts = Parts::from_slice(&[torso, kick]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.len(), 2);
        // Two walkers passing each other 2 px apart: opposite flows stay two boxes.
        let other = part(52, 20, 10, 16, (-2.0, 0.0));
        let mut parts = Parts::from_slice(&[torso, other]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.len(), 2);
        // Alike, 8 px apart: half the smaller one's 16 px side, joined; 9 px: two boxes.
        let near = part(58, 20, 10, 16, (2.0, 0.0));
        let mut parts = Parts::from_slice(&[torso, near]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.as_slice(), [part(40, 20, 28, 16, (2.0, 0.0))]);
        let apart = part(59, 20, 10, 16, (2.0, 0.0));
        let mut parts = Parts::from_slice(&[torso, apart]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.len(), 2);
        // Small parts reach 4 px at least: a 6 px hand 5 px from the torso stays apart.
        let hand = part(55, 24, 6, 6, (2.0, 0.0));
        let mut parts = Parts::from_slice(&[torso, hand]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.len(), 2);
        // Slow parts differ by up to a pixel (the outline's own flow step): joined.
        let slow = part(40, 37, 10, 6, (0.0, 0.9));
        let still = part(40, 20, 10, 16, (0.0, 0.0));
        let mut parts = Parts::from_slice(&[still, slow]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.len(), 1);
    }

    #[test]
    fn joining_goes_on_until_no_two_parts_are_one_body() {
        // A chain: head - torso - leg, each within reach of the next only.
        let head = part(42, 10, 6, 6, (1.0, 0.0));
        let torso = part(40, 18, 10, 16, (1.1, 0.0));
        let leg = part(41, 36, 5, 10, (1.6, 0.0));
        let mut parts = Parts::from_slice(&[torso, leg, head]).unwrap();
        join_parts(&mut parts);
        assert_eq!(parts.as_slice(), [part(40, 10, 10, 36, (1.1, 0.0))]);
    }
}
