//! Boxes that persist: [`BoxPersistence`].

use heapless::Vec;

use super::grid::GridLayout;
use super::regions::MotionBox;
use crate::q16::Q16;

/// Boxes that persist: a region is reported once it has moved in consecutive frame pairs.
///
/// A wrong LK estimate, a patch that clipped at 255 in one frame or a burst of noise moves a
/// few nodes in one frame pair; an object moves its nodes in every pair. A `BoxPersistence`
/// remembers each pair's boxes, moved by their own flow into the frame the next pair starts
/// from, and reports a box of the next pair only when it overlaps one of them: when its
/// region has moved in [`BoxPersistence::min_pairs`] pairs in a row. An object is then
/// reported from its second pair on (with two), and a region that moves in one pair alone
/// never is. Two rules keep runs honest at the edges of time and of the frame:
///
/// - a reported region that the mask misses in one pair keeps its run for the next pair, where
///   it is expected one more step of its flow further on: one miss costs one frame, not the
///   frames of a new run;
/// - a region that lies in the grid's outer ring of nodes alone (first or last column or row)
///   needs one pair more to start a run: there the camera carries part of a node's window
///   out of the next frame, and the wrong flow that gives lasts as long as the camera's
///   motion.
///
/// With two pairs, on 116 frame pairs of a camera panning, rolling and zooming over still
/// ground at 320 x 240 (`tests/dense_motion.rs`), boxes fell from 34 to 0.
///
/// The state is a fixed number of boxes (`N`, the most boxes a pair gives), with no heap: the
/// boxes of the last frame pair and how many pairs in a row each region has moved.
///
/// ```
/// use kestrel::dense::{BoxPersistence, GridLayout, MotionBox};
/// use kestrel::Point;
///
/// let layout = GridLayout::new(160, 120, 8).unwrap();
/// let object = |x| MotionBox { x, y: 40, w: 16, h: 16, nodes: 4, mean_flow: Point::from_f32(3.0, 0.0) };
/// let speck = MotionBox { x: 100, y: 8, w: 8, h: 8, nodes: 3, mean_flow: Point::from_f32(0.0, 2.0) };
/// let mut persistence = BoxPersistence::<8>::new(2);
///
/// // First pair: nothing has moved before, nothing is reported.
/// let mut boxes = [object(20), speck];
/// assert_eq!(persistence.confirm(&layout, &mut boxes, 2), 0);
/// // Second pair: the object moved on by 3 px and is reported; the speck is gone.
/// let mut boxes = [object(23)];
/// assert_eq!(persistence.confirm(&layout, &mut boxes, 1), 1);
/// assert_eq!(boxes[0].x, 23);
/// ```
#[derive(Debug, Clone)]
pub struct BoxPersistence<const N: usize> {
    min_pairs: u8,
    /// The last pair's boxes, moved into its later frame, with their runs of pairs, and the
    /// reported boxes of the pair before that no box of the last pair continued, moved on by
    /// their flow once more.
    last: Vec<Remembered, N>,
}

/// A box kept for the next pair.
#[derive(Debug, Clone, Copy)]
struct Remembered {
    /// Where the box is expected in the frame the next pair starts from.
    place: MotionBox,
    /// Consecutive pairs its region has moved in.
    run: u8,
    /// True when it was missing from the last pair (it waits one pair at most).
    missed: bool,
    /// True once a box of the current pair continues it.
    continued: bool,
}

impl Remembered {
    /// True when its box was reported in the last pair (a run of at least `min_pairs`, and
    /// at least two: with no persistence asked every box is reported, but none has a run to
    /// carry on): it is looked for again in the next pair.
    fn reported(&self, min_pairs: u8) -> bool {
        self.run >= min_pairs.max(2) && !self.missed
    }
}

impl<const N: usize> BoxPersistence<N> {
    /// Reports boxes whose regions moved in at least `min_pairs` consecutive pairs; 0 and 1
    /// report every box (no persistence asked).
    ///
    /// ```
    /// use kestrel::dense::BoxPersistence;
    /// assert_eq!(BoxPersistence::<16>::new(3).min_pairs(), 3);
    /// ```
    pub const fn new(min_pairs: u8) -> Self {
        Self {
            min_pairs,
            last: Vec::new(),
        }
    }

    /// The consecutive pairs a region must move in to be reported.
    pub const fn min_pairs(&self) -> u8 {
        self.min_pairs
    }

    /// Forgets every box (a new sequence, or a frame that could not be processed).
    ///
    /// ```
    /// use kestrel::dense::{BoxPersistence, GridLayout, MotionBox};
    /// let layout = GridLayout::new(64, 64, 8).unwrap();
    /// let b = MotionBox { x: 16, y: 16, w: 8, h: 8, ..MotionBox::default() };
    /// let mut persistence = BoxPersistence::<4>::new(2);
    /// assert_eq!(persistence.confirm(&layout, &mut [b], 1), 0);
    /// persistence.reset();
    /// assert_eq!(persistence.confirm(&layout, &mut [b], 1), 0);
    /// ```
    pub fn reset(&mut self) {
        self.last.clear();
    }

    /// Appends to the first `count` of `boxes` (a pair's candidates, before
    /// [`BoxPersistence::confirm`]) the boxes reported for the pair before, where their flow
    /// takes them in this pair's earlier frame, that overlap none of them; returns the new
    /// count. Looked at again by a pixel-level check ([`Outliner`](super::Outliner)), they keep an object
    /// that slows to the camera's motion, where the grid's mask loses it, for as long as its
    /// pixels still tell it from the ground.
    ///
    /// ```
    /// use kestrel::dense::{BoxPersistence, GridLayout, MotionBox};
    /// use kestrel::Point;
    /// let layout = GridLayout::new(64, 64, 8).unwrap();
    /// let b = MotionBox { x: 16, y: 16, w: 8, h: 8, nodes: 2, mean_flow: Point::from_f32(2.0, 0.0) };
    /// let mut persistence = BoxPersistence::<4>::new(2);
    /// let mut boxes = [b, MotionBox::default()];
    /// persistence.confirm(&layout, &mut boxes, 1);
    /// boxes[0] = MotionBox { x: 18, ..b };
    /// assert_eq!(persistence.confirm(&layout, &mut boxes, 1), 1);
    /// // The next pair's mask finds nothing: the reported box is looked at where it went.
    /// assert_eq!(persistence.append_expected(&mut boxes, 0), 1);
    /// assert_eq!(boxes[0].x, 20);
    /// ```
    pub fn append_expected(&self, boxes: &mut [MotionBox], count: usize) -> usize {
        let mut count = count.min(boxes.len());
        let reported = self.last.iter().filter(|r| r.reported(self.min_pairs));
        for expected in reported.map(|r| r.place) {
            let (found, room) = boxes.split_at_mut(count);
            let Some(slot) = room.first_mut() else {
                break;
            };
            if !found.iter().any(|b| overlap(b, &expected)) {
                *slot = expected;
                count = count.saturating_add(1);
            }
        }
        count
    }

    /// Takes the first `count` boxes of a frame pair on the grid `layout`, in the earlier
    /// frame of the pair (as `MotionDetector::detect` gives them), and keeps in
    /// `boxes`, in their order, those whose region has moved in enough consecutive pairs;
    /// returns how many it kept. A box continues a run when it overlaps a box of the pair
    /// before, moved by that box's mean flow. Boxes past the first `N` are judged but not
    /// remembered for the next pair; a reported region this pair missed is remembered after
    /// this pair's boxes while fewer than `N` are; `count` beyond `boxes.len()` counts as
    /// `boxes.len()`.
    pub fn confirm(&mut self, layout: &GridLayout, boxes: &mut [MotionBox], count: usize) -> usize {
        let (width, height) = (layout.width(), layout.height());
        let mut next: Vec<Remembered, N> = Vec::new();
        let mut kept = 0usize;
        for read in 0..count.min(boxes.len()) {
            let Some(&found) = boxes.get(read) else {
                break;
            };
            let mut before_run: Option<u8> = None;
            for before in self.last.iter_mut() {
                if overlap(&before.place, &found) && same_motion(&before.place, &found) {
                    before_run = Some(before_run.map_or(before.run, |r| r.max(before.run)));
                    before.continued = true;
                }
            }
            // A region of the frame's outer ring of nodes alone needs a pair more to start: it
            // is where the camera carries part of a node's window out of the next frame, and
            // wrong flow there lasts as long as the camera's motion.
            let run = match before_run {
                Some(run) => run.saturating_add(1),
                None if on_rim(layout, &found) => 0,
                None => 1,
            };
            // A full list drops the smallest boxes' runs: they come last. Only boxes past the
            // first N find it full, as documented.
            let remembered = next.push(Remembered {
                place: found.in_next_frame(width, height),
                run,
                missed: false,
                continued: false,
            });
            debug_assert!(
                remembered.is_ok() || read >= N,
                "box {read} of {N} not remembered"
            );
            if run >= self.min_pairs || self.min_pairs <= 1 {
                if let Some(slot) = boxes.get_mut(kept) {
                    *slot = found;
                }
                kept = kept.saturating_add(1);
            }
        }
        // A reported region missing from this pair alone (a miss of the mask) keeps its run
        // for the next pair, where it is expected one more step of its flow further on.
        for before in &self.last {
            if before.reported(self.min_pairs) && !before.continued {
                // Behind this pair's boxes, as room allows (see `confirm`'s documentation):
                // a full list has N of this pair's boxes, which come first.
                let carried = next.push(Remembered {
                    place: before.place.in_next_frame(width, height),
                    missed: true,
                    ..*before
                });
                if carried.is_err() {
                    break;
                }
            }
        }
        self.last = next;
        kept
    }
}

/// True when `b` lies in the cells of the grid's first or last column or row alone.
fn on_rim(layout: &GridLayout, b: &MotionBox) -> bool {
    let cell = layout.cell();
    let last = |n: usize| n.saturating_sub(1).saturating_mul(cell);
    let (x, y) = (usize::from(b.x), usize::from(b.y));
    let (right, bottom) = (x.saturating_add(b.w.into()), y.saturating_add(b.h.into()));
    right <= cell || bottom <= cell || x >= last(layout.cols()) || y >= last(layout.rows())
}

/// True when the two boxes' flows differ by at most 3 px and half the larger flow on each
/// axis: an object's flow changes little from one pair to the next (an object of 1 to 3 px a
/// frame turning round changes by up to 4), while a chance match beside it (a patch of ground
/// the object uncovers) has a flow of its own.
fn same_motion(a: &MotionBox, b: &MotionBox) -> bool {
    let within = |p: Q16, q: Q16| {
        let (p, q) = (p.to_bits(), q.to_bits());
        // Q16 bits of i32 values: sums and differences fit an i64.
        let slack =
            (3i64 << 16).saturating_add(i64::from(p.unsigned_abs().max(q.unsigned_abs())) / 2);
        i64::from(p).abs_diff(i64::from(q)) <= slack.unsigned_abs()
    };
    within(a.mean_flow.x, b.mean_flow.x) && within(a.mean_flow.y, b.mean_flow.y)
}

/// True when the two boxes share at least one pixel.
fn overlap(a: &MotionBox, b: &MotionBox) -> bool {
    a.overlap_area(b) > 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::q16::Point;

    fn b(x: u16, y: u16, flow: (f32, f32)) -> MotionBox {
        MotionBox {
            x,
            y,
            w: 16,
            h: 16,
            nodes: 4,
            mean_flow: Point::from_f32(flow.0, flow.1),
        }
    }

    #[test]
    fn runs_follow_the_flow_and_survive_one_missing_pair() {
        let layout = GridLayout::new(200, 100, 8).unwrap();
        let mut p = BoxPersistence::<4>::new(3);
        // Moving 10 px a pair: without the flow the boxes would not overlap.
        let run =
            |x, p: &mut BoxPersistence<4>| p.confirm(&layout, &mut [b(x, 20, (10.0, 0.0))], 1);
        assert_eq!(run(10, &mut p), 0);
        assert_eq!(run(20, &mut p), 0);
        assert_eq!(run(30, &mut p), 1);
        assert_eq!(run(40, &mut p), 1);
        // One pair without the object: it is expected 10 px further on, and its run goes on.
        assert_eq!(p.confirm(&layout, &mut [], 0), 0);
        assert_eq!(run(60, &mut p), 1);
        // Two pairs without it end the run.
        assert_eq!(p.confirm(&layout, &mut [], 0), 0);
        assert_eq!(p.confirm(&layout, &mut [], 0), 0);
        assert_eq!(run(90, &mut p), 0);
        // Beside the moved box, not on it: no run.
        let mut q = BoxPersistence::<4>::new(2);
        q.confirm(&layout, &mut [b(40, 20, (0.0, 0.0))], 1);
        assert_eq!(q.confirm(&layout, &mut [b(56, 20, (0.0, 0.0))], 1), 0);
    }

    #[test]
    fn a_region_on_the_rim_needs_a_pair_more() {
        let layout = GridLayout::new(200, 100, 8).unwrap();
        let mut p = BoxPersistence::<4>::new(2);
        // The last column's cells: x from 192.
        let rim = || MotionBox {
            w: 8,
            ..b(192, 40, (0.0, 0.0))
        };
        assert_eq!(p.confirm(&layout, &mut [rim()], 1), 0);
        assert_eq!(p.confirm(&layout, &mut [rim()], 1), 0);
        assert_eq!(p.confirm(&layout, &mut [rim()], 1), 1);
        // One column in from the rim: two pairs, as anywhere.
        let mut q = BoxPersistence::<4>::new(2);
        let inside = || MotionBox {
            w: 8,
            ..b(184, 40, (0.0, 0.0))
        };
        assert_eq!(q.confirm(&layout, &mut [inside()], 1), 0);
        assert_eq!(q.confirm(&layout, &mut [inside()], 1), 1);
    }

    #[test]
    fn kept_boxes_keep_their_order_and_one_pair_reports_all() {
        let layout = GridLayout::new(200, 100, 8).unwrap();
        let mut p = BoxPersistence::<4>::new(2);
        let mut first = [
            b(16, 16, (0.0, 0.0)),
            b(50, 50, (0.0, 0.0)),
            b(90, 10, (0.0, 0.0)),
        ];
        assert_eq!(p.confirm(&layout, &mut first, 3), 0);
        let mut second = [
            b(120, 60, (0.0, 0.0)),
            b(90, 12, (0.0, 0.0)),
            b(18, 18, (0.0, 0.0)),
        ];
        assert_eq!(p.confirm(&layout, &mut second, 3), 2);
        assert_eq!((second[0].x, second[1].x), (90, 18));
        let mut all = BoxPersistence::<4>::new(1);
        assert_eq!(all.confirm(&layout, &mut second, 9), 3);
    }
}
