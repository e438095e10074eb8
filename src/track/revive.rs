//! Tracks set aside on a still camera when a gate drops them, and revived where their feature
//! shows again: [`SetAside`].
//!
//! On a still camera a feature does not move: a walker that passes over a track on the ground
//! ends it (its window's residual jumps, its patch no longer matches), and once the walker has
//! gone the feature is back where it was. A leaf that swings in the wind comes back to its
//! place too. Rather than start a new track there, with a new id, the tracker keeps the dropped
//! track and its anchor aside for [`super::Relocation::revive_within`] frames, and revives it
//! when its birth patch passes the appearance gate at its place again and relocation finds it
//! there: its id, its age and its history go on. Only where the camera is still: a moving
//! camera leaves no place to look at, and everything set aside is forgotten when it moves.

use super::anchor::{Anchor, Located};
use super::Track;
use crate::frame::ImageView;
use crate::q16::{Point, Q16};
use heapless::Vec;

/// Tracks kept aside at most: the oldest is forgotten first.
pub(super) const SET_ASIDE: usize = 16;

/// A track at least this many frames old may be set aside: a younger one more often failed
/// from its place (a feature that changes faster than it can follow) than from an occluder.
pub(super) const SET_ASIDE_FROM_AGE: u32 = 8;

/// The tracks set aside, with their anchors and the frame each was dropped in.
#[derive(Debug, Default)]
pub(super) struct SetAside {
    kept: Vec<(Track, Anchor, u32), SET_ASIDE>,
}

impl SetAside {
    /// Keeps `track`, dropped in frame `now`, and its anchor; forgets the oldest when full.
    pub(super) fn keep(&mut self, track: Track, anchor: &Anchor, now: u32) {
        if self.kept.is_full() {
            self.kept.remove(0);
        }
        let kept = self.kept.push((track, *anchor, now));
        debug_assert!(kept.is_ok(), "room was made");
    }

    /// Forgets every track set aside.
    pub(super) fn clear(&mut self) {
        self.kept.clear();
    }

    /// Offers `revive` the tracks set aside before frame `now` whose anchor matches `frame`
    /// at their place again (a likeness of at least `least_likeness`, the appearance gate's
    /// threshold: [`Anchor::likeness`]) and is located
    /// there within `max_shift_sq` (squared Q16 units), each moved to where it was found;
    /// forgets those set aside more than `within` frames ago, and those `revive` revived or
    /// whose place another track took. Returns how many were revived.
    pub(super) fn revive(
        &mut self,
        frame: &ImageView<'_>,
        (now, within): (u32, u16),
        (least_likeness, max_shift_sq): (Q16, i64),
        revive: &mut dyn FnMut(Track, &Anchor) -> Welcome,
    ) -> usize {
        let mut revived = 0usize;
        let mut i = 0;
        while let Some(&(track, anchor, since)) = self.kept.get(i) {
            let waited = now.wrapping_sub(since);
            if waited > u32::from(within) {
                self.kept.remove(i);
                continue;
            }
            let found = || match anchor.locate(frame, track.position, max_shift_sq) {
                Located::At(found) => Some(found),
                Located::Lost | Located::OutOfView => None,
            };
            let looks_alike = || anchor.likeness(frame, track.position) >= least_likeness;
            let back = (waited > 0 && looks_alike()).then(found).flatten();
            let revive_at = |at: Point| Track {
                position: at,
                previous: at,
                velocity: Point::default(),
                prediction_error: Q16::MAX,
                ..track
            };
            let welcome = back.map(|at| revive(revive_at(at), &anchor));
            match welcome {
                Some(Welcome::Revived) => {
                    revived = revived.saturating_add(1);
                    self.kept.remove(i);
                }
                Some(Welcome::Taken) => {
                    self.kept.remove(i);
                }
                Some(Welcome::Full) | None => i = i.saturating_add(1),
            }
        }
        revived
    }
}

/// What became of a track offered for revival.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Welcome {
    /// Live again.
    Revived,
    /// Another live track is at its place: it is forgotten.
    Taken,
    /// No room now: it stays aside.
    Full,
}
