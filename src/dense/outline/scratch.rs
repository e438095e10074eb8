//! The caller's scratch, cut once into the parts the stages of an outline use.
//!
//! The stages run one after the other on a candidate, so two parts serve more than one of
//! them: the vote runs before any pixel is labelled and borrows the labels and the stack, and
//! the labelling keeps its rows of sums in the stack, which the flood fill needs only after.
//! [`OutlineScratch`] names each part once, and each borrowing is a named view of its own.

use super::OUTLINE_MAX_FLOWS;

/// Scratch, in `u16`, for areas up to `side` x `side` pixels and motions up to `reach` px:
/// the pixel labels, a flood-fill stack, the three-row ring of differences of every flow
/// tried, and the vote's bins. The vote on level 1 borrows the labels and the stack.
///
/// ```
/// use kestrel::dense::{outline_scratch_len, OutlineParams};
/// // Labels and stack, 8 x 3 ring rows of 50, 9 x 9 vote bins.
/// assert_eq!(outline_scratch_len(48, 8), 2 * 48 * 48 + 24 * 50 + 81);
/// const LEN: usize = outline_scratch_len(OutlineParams::DEFAULT_SIDE, 8);
/// static mut SCRATCH: [u16; LEN] = [0; LEN];
/// ```
pub const fn outline_scratch_len(side: usize, reach: usize) -> usize {
    let pixels = side.saturating_mul(side);
    let ring = RING_ROWS * side.saturating_add(2);
    pixels
        .saturating_mul(2)
        .saturating_add(ring)
        .saturating_add(bins(reach))
}

/// Rows of the ring: three for the camera, each flow, and the texture.
const RING_ROWS: usize = (OUTLINE_MAX_FLOWS + 2) * 3;

/// Bins of the vote over shifts of up to `reach` px (`reach / 2` on the level searched).
const fn bins(reach: usize) -> usize {
    let side = (reach / 2).saturating_mul(2).saturating_add(1);
    side.saturating_mul(side)
}

/// The parts of one outliner's scratch.
pub(super) struct OutlineScratch<'a> {
    /// Each area pixel's label, `side` x `side`, row by row: 0 for the camera or nothing,
    /// `k + 1` for object flow `k`, and [`super::flood::VISITED`] once a flood fill took it.
    pub labels: &'a mut [u16],
    /// The flood fill's stack of pixel indices, `side` x `side`: no pixel is pushed twice.
    pub stack: &'a mut [u16],
    /// The labelling's ring: three rows of differences (`side + 2` each, the area's width and
    /// a pixel on each side) for the camera, each flow and the texture.
    pub ring: &'a mut [u16],
    /// The vote's bins, one count per whole-pixel shift within the reach.
    pub votes: &'a mut [u16],
}

/// What the vote on level 1 borrows: the labels and the stack, free until the labelling.
pub(super) struct VoteScratch<'s> {
    /// The camera's differences on the level-1 area's rows and a pixel around them (in the
    /// labels: see [`super::vote`] for why they fit).
    pub camera_differences: &'s mut [u16],
    /// Each level-1 pixel's 3 x 3 sum of the camera's differences (the stack's first part).
    pub camera_sums: &'s mut [u16],
    /// Each level-1 pixel's bin, then which flow it voted for (the rest of the stack): the
    /// first refinement reads it back through [`OutlineScratch::voters`].
    pub voters: &'s mut [u16],
    /// The bins, as in [`OutlineScratch::votes`].
    pub votes: &'s mut [u16],
}

impl<'a> OutlineScratch<'a> {
    /// Cuts `scratch` for areas up to `side` x `side` and motions up to `reach` px; `None`
    /// when it is shorter than [`outline_scratch_len`] of them.
    pub fn split(scratch: &'a mut [u16], side: usize, reach: usize) -> Option<Self> {
        if scratch.len() < outline_scratch_len(side, reach) {
            return None;
        }
        // Each cut is within the length checked above.
        let pixels = side.saturating_mul(side);
        let (labels, rest) = scratch.split_at_mut(pixels);
        let (stack, rest) = rest.split_at_mut(pixels);
        let (ring, votes) = rest.split_at_mut(RING_ROWS * (side + 2));
        Some(Self {
            labels,
            stack,
            ring,
            votes,
        })
    }

    /// The vote's view for a level-1 area of `level1_pixels` pixels.
    pub fn for_vote(&mut self, level1_pixels: usize) -> VoteScratch<'_> {
        // The level-1 area is at most (side / 2 + 1) px on a side: a quarter of the stack
        // and a little more, so the voters are never empty.
        debug_assert!(level1_pixels <= self.stack.len());
        let at = level1_pixels.min(self.stack.len());
        let (camera_sums, voters) = self.stack.split_at_mut(at);
        VoteScratch {
            camera_differences: self.labels,
            camera_sums,
            voters,
            votes: self.votes,
        }
    }

    /// Which flow each level-1 pixel voted for, as the vote of an area of `level1_pixels`
    /// pixels left it ([`VoteScratch::voters`]).
    pub fn voters(&self, level1_pixels: usize) -> &[u16] {
        debug_assert!(level1_pixels <= self.stack.len());
        self.stack.get(level1_pixels..).unwrap_or(&[])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_scratch_is_not_cut() {
        let mut scratch = [0u16; outline_scratch_len(16, 4)];
        let (short, _) = scratch.split_at_mut(outline_scratch_len(16, 4) - 1);
        assert!(OutlineScratch::split(short, 16, 4).is_none());
    }

    #[test]
    fn the_parts_are_their_sizes_and_the_votes_take_the_rest() {
        let mut scratch = [0u16; outline_scratch_len(16, 4) + 3];
        let parts = OutlineScratch::split(&mut scratch, 16, 4).unwrap();
        assert_eq!(parts.labels.len(), 256);
        assert_eq!(parts.stack.len(), 256);
        assert_eq!(parts.ring.len(), RING_ROWS * 18);
        assert_eq!(parts.votes.len(), 5 * 5 + 3);
    }

    #[test]
    fn the_vote_cuts_the_stack_after_the_level_1_pixels() {
        let mut scratch = [0u16; outline_scratch_len(16, 4)];
        let mut parts = OutlineScratch::split(&mut scratch, 16, 4).unwrap();
        let vote = parts.for_vote(81);
        assert_eq!(vote.camera_differences.len(), 256);
        assert_eq!((vote.camera_sums.len(), vote.voters.len()), (81, 175));
        vote.voters.fill(7);
        assert_eq!(parts.voters(81), &[7; 175]);
    }
}
