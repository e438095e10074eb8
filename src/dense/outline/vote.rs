//! The objects' flows in an area, by a vote on pyramid level 1.
//!
//! Each pixel there that the camera's flow does not explain votes for the whole-pixel shift
//! (within the reach of the camera's flow at the area's centre) whose 3 x 3 neighbourhood
//! matches best; the [`OUTLINE_VOTED_FLOWS`] shifts with the most votes, each at least a quarter of
//! [`super::OutlineParams::min_pixels`] (a level-1 pixel is four), are the flows, doubled to
//! level 0. Level 1 has a quarter of the pixels and half the shifts on each axis, so the search
//! costs a sixteenth of level 0's, and its whole pixels are two at level 0, which the
//! refinement then resolves.

use super::area::Area;
use super::differences::{camera_row, flow_bits, sad3, sums3, UNKNOWN};
use super::flows::Flows;
use super::scratch::{OutlineScratch, VoteScratch};
use super::{Outliner, OUTLINE_MAX_FLOWS, OUTLINE_VOTED_FLOWS};
use crate::dense::motion::CameraMotion;
use crate::frame::ImageView;
use crate::q16::{Point, Q16};

/// A level-1 pixel that voted for nothing (the camera explains it).
const NO_BIN: u16 = u16::MAX;

/// A camera's flow on pyramid level 1: half its flow at twice the coordinates.
struct Scaled<'a, C>(&'a C);

impl<C: CameraMotion> CameraMotion for Scaled<'_, C> {
    fn flow_at(&self, x: f32, y: f32) -> (f32, f32) {
        let (dx, dy) = self.0.flow_at(2.0 * x, 2.0 * y);
        (0.5 * dx, 0.5 * dy)
    }
}

/// The whole-pixel shifts searched on level 1: `reach` on each side of the camera's shift at
/// the area's centre, a bin each, row by row.
struct Shifts {
    reach: i32,
    side: usize,
    centre: (i32, i32),
}

impl Shifts {
    /// The bins of all shifts.
    fn bins(&self) -> usize {
        self.side * self.side
    }

    /// The bin of shift (`dx`, `dy`) from the centre, each within the reach.
    fn bin(&self, dx: i32, dy: i32) -> u16 {
        ((dy + self.reach) as usize * self.side + (dx + self.reach) as usize) as u16
    }

    /// The level-0 flow of bin `bin`, Q16: its level-1 shift doubled.
    fn flow(&self, bin: usize) -> Point {
        let (bx, by) = ((bin % self.side) as i32, (bin / self.side) as i32);
        let level0 = |c: i32, d: i32| Q16::from_bits((c + d - self.reach) << 17);
        Point::new(level0(self.centre.0, bx), level0(self.centre.1, by))
    }

    /// True when bins `a` and `b` are the same shift or neighbours.
    fn near(&self, a: u16, b: u16) -> bool {
        let (a, b, side) = (i32::from(a), i32::from(b), self.side as i32);
        (a % side - b % side).abs() <= 1 && (a / side - b / side).abs() <= 1
    }
}

impl Outliner {
    /// The objects' flows in `area` by the vote on level 1 (`prev` and `next`), and the
    /// level-1 area that voted. Each voter's flow (its shift's, or a chosen one beside it) is
    /// left in the scratch's [`OutlineScratch::voters`], for the first refinement.
    pub(super) fn vote(
        &self,
        (prev, next): (&ImageView<'_>, &ImageView<'_>),
        camera: &impl CameraMotion,
        area: &Area,
        scratch: &mut OutlineScratch<'_>,
    ) -> (Flows, Area) {
        let half = area.halved(prev);
        let reach = (self.params.reach / 2) as i32;
        let side = 2 * reach as usize + 1;
        let (cx, cy) = camera.flow_at((area.x + area.w / 2) as f32, (area.y + area.h / 2) as f32);
        let shifts = Shifts {
            reach,
            side,
            centre: (round_half(cx), round_half(cy)),
        };
        let mut parts = scratch.for_vote(half.pixels());
        parts
            .votes
            .iter_mut()
            .take(shifts.bins())
            .for_each(|v| *v = 0);
        // The camera's costs first: a pixel it explains votes for nothing.
        camera_sums(prev, next, &half, &Scaled(camera), &mut parts);
        self.cast_votes((prev, next), &half, &shifts, &mut parts);
        let (flows, chosen) = self.count_votes(&shifts, parts.votes);
        label_voters(&shifts, &chosen, parts.voters);
        (flows, half)
    }

    /// Each level-1 pixel's vote: the bin of its best shift into `voters` and a vote into its
    /// bin, or [`NO_BIN`] where the camera's flow explains it.
    fn cast_votes(
        &self,
        (prev, next): (&ImageView<'_>, &ImageView<'_>),
        half: &Area,
        shifts: &Shifts,
        parts: &mut VoteScratch<'_>,
    ) {
        let gain = self.gain();
        let VoteScratch {
            camera_sums,
            voters,
            votes,
            ..
        } = parts;
        for (i, (cam, shift)) in camera_sums.iter().zip(voters.iter_mut()).enumerate() {
            let cam = u32::from(*cam);
            *shift = NO_BIN;
            // A pixel whose camera match is within the gain cannot vote: skip its search.
            if cam >= u32::from(UNKNOWN) || cam <= gain {
                continue;
            }
            let (x, y) = (half.x + i % half.w, half.y + i / half.w);
            let best = best_shift((prev, next), (x, y), shifts);
            if best.0 + gain < cam && 2 * best.0 < cam {
                if let Some(v) = votes.get_mut(usize::from(best.1)) {
                    *v = v.saturating_add(1);
                    *shift = best.1;
                }
            }
        }
    }

    /// The flows of the bins with the most votes, at most [`OUTLINE_VOTED_FLOWS`] and each with at
    /// least a quarter of [`super::OutlineParams::min_pixels`]; beside them, the bin each
    /// flow came from ([`NO_BIN`] past the last).
    fn count_votes(&self, shifts: &Shifts, votes: &mut [u16]) -> (Flows, [u16; OUTLINE_MAX_FLOWS]) {
        let mut flows = Flows::EMPTY;
        let mut chosen = [NO_BIN; OUTLINE_MAX_FLOWS];
        let floor = (self.params.min_pixels / 4).max(1);
        // The shifts with the most votes, without suppressing their neighbours: two objects
        // a pixel apart in flow vote for neighbouring shifts.
        while flows.len < OUTLINE_VOTED_FLOWS {
            let Some((bin, count)) = votes
                .iter_mut()
                .take(shifts.bins())
                .enumerate()
                .max_by_key(|(_, v)| **v)
            else {
                break;
            };
            if usize::from(*count) < floor {
                break;
            }
            *count = 0;
            let before = flows.len;
            flows.add(shifts.flow(bin));
            if let Some(slot) = chosen.get_mut(before).filter(|_| flows.len > before) {
                *slot = bin as u16;
            }
        }
        (flows, chosen)
    }
}

/// The 3 x 3 sums of the camera's differences at each pixel of the level-1 area `half`, into
/// the vote's camera sums.
fn camera_sums(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    half: &Area,
    camera: &dyn CameraMotion,
    parts: &mut VoteScratch<'_>,
) {
    camera_differences(prev, next, half, camera, parts.camera_differences);
    let row_len = half.w + 2;
    for (row, sums) in parts.camera_sums.chunks_mut(half.w.max(1)).enumerate() {
        // Rows below half.h + 2, all written above (see there for why they fit).
        let rows = parts
            .camera_differences
            .get(row * row_len..(row + 3) * row_len);
        debug_assert!(rows.is_some(), "vote: row {row} of the camera's costs");
        sums3(rows.unwrap_or(&[]), half.w, |x, e| sums[x] = e);
    }
}

/// Differences between `prev` and `next` sampled at the camera's flow, over the area and a
/// pixel around it, into `rows` (`area.w + 2` a row); [`UNKNOWN`] where the camera's sample
/// leaves `next`.
fn camera_differences(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    area: &Area,
    camera: &dyn CameraMotion,
    rows: &mut [u16],
) {
    let row_len = area.w + 2;
    // The vote's area is at most (side / 2 + 1) px on a side, so its rows and the pixel around
    // them, (side / 2 + 3)^2 <= side^2 for a side of at least OUTLINE_MIN_SIDE, fit in the labels'
    // side x side. Checked once, before any row is written.
    let needed = (area.h + 2) * row_len;
    debug_assert!(
        rows.len() >= needed,
        "camera costs: {} < {needed}",
        rows.len()
    );
    let Some(rows) = rows.get_mut(..needed) else {
        return;
    };
    for (r, out) in rows.chunks_exact_mut(row_len).enumerate() {
        camera_row(prev, next, camera, area, area.y + r - 1, out);
    }
}

/// The best whole-pixel shift of level-1 pixel (`x`, `y`): its 3 x 3 sum and bin, the first
/// of the smallest sums in raster order of the bins.
fn best_shift(
    (prev, next): (&ImageView<'_>, &ImageView<'_>),
    (x, y): (usize, usize),
    shifts: &Shifts,
) -> (u32, u16) {
    let (reach, centre) = (shifts.reach, shifts.centre);
    let mut best = (u32::MAX, NO_BIN);
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let e = sad3(prev, next, (x, y), (centre.0 + dx, centre.1 + dy));
            if e < best.0 {
                best = (e, shifts.bin(dx, dy));
            }
        }
    }
    best
}

/// Turns each voter's bin into the label of its flow: `k + 1` for chosen bin `k`, or for a
/// chosen bin beside its own (one object's pixels split between neighbouring shifts), else 0.
fn label_voters(shifts: &Shifts, chosen: &[u16; OUTLINE_MAX_FLOWS], voters: &mut [u16]) {
    for s in voters.iter_mut() {
        let own = chosen.iter().position(|&c| c == *s);
        let beside = || {
            chosen
                .iter()
                .position(|&c| c != NO_BIN && *s != NO_BIN && shifts.near(c, *s))
        };
        *s = own.or_else(beside).map_or(0, |k| k as u16 + 1);
    }
}

/// Half of a level-0 flow, rounded to a whole level-1 pixel; 0 for NaN or out of reach.
fn round_half(v: f32) -> i32 {
    (flow_bits(v) + (1 << 16)) >> 17
}
