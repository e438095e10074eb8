//! One frame's step for every live track: LK forwards, then the gates, cheapest first.

use super::anchor::Anchor;
use super::config::Checked;
use super::{FrameReport, Track};
use crate::lk::{LkError, PointTrack};
use crate::pyramid::Pyramid;
use crate::q16::{Point, Q16};
use heapless::Vec;

/// Why a track was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rejection {
    /// LK lost it: out of the frame, too little texture, or not converged.
    Lost,
    /// Its residual is above the gate.
    Residual,
    /// It no longer looks like the feature it was born on.
    Appearance,
    /// The way back misses its start.
    ForwardBackward,
}

/// The two frames of one step and how to judge the tracks between them.
pub(super) struct Follow<'p, 'f> {
    pub checked: &'p Checked,
    pub prev: &'p Pyramid<'f>,
    pub next: &'p Pyramid<'f>,
    pub predict: Option<&'p dyn Fn(Point) -> Point>,
}

impl Follow<'_, '_> {
    /// Moves every track that passes the gates into the next frame and drops the others (with
    /// their anchors), keeping the order.
    pub(super) fn all<const N: usize>(
        &self,
        tracks: &mut Vec<Track, N>,
        anchors: &mut Vec<Anchor, N>,
        scratch: &mut [i16],
        report: &mut FrameReport,
    ) -> Result<(), LkError> {
        // Forwards first, for every track: the residual gate needs the frame's median.
        let mut forward: Vec<PointTrack, N> = Vec::new();
        for track in tracks.iter() {
            let guess = self.predict.map(|predict| predict(track.position));
            let step = self.checked.lk.track_point(
                self.prev,
                self.next,
                track.position,
                guess,
                scratch,
            )?;
            // Cannot fail: one step per track, and both hold at most N.
            let _ = forward.push(step);
        }
        let max_residual = self.residual_limit::<N>(&forward);

        let mut kept = 0;
        for i in 0..tracks.len() {
            let (Some(&track), Some(&step), Some(&anchor)) =
                (tracks.get(i), forward.get(i), anchors.get(i))
            else {
                break;
            };
            match self.judge(&track, &anchor, step, max_residual, scratch)? {
                Ok(position) => {
                    let moved = Track {
                        position,
                        residual: step.residual,
                        age: track.age.saturating_add(1),
                        ..track
                    };
                    if let (Some(t), Some(a)) = (tracks.get_mut(kept), anchors.get_mut(kept)) {
                        *t = moved;
                        *a = anchor;
                        kept = kept.saturating_add(1);
                    }
                    report.tracked = report.tracked.saturating_add(1);
                }
                Err(Rejection::Lost) => report.dropped_lost = report.dropped_lost.saturating_add(1),
                Err(Rejection::Residual) => {
                    report.dropped_residual = report.dropped_residual.saturating_add(1)
                }
                Err(Rejection::Appearance) => {
                    report.dropped_appearance = report.dropped_appearance.saturating_add(1)
                }
                Err(Rejection::ForwardBackward) => {
                    report.dropped_fb = report.dropped_fb.saturating_add(1)
                }
            }
        }
        tracks.truncate(kept);
        anchors.truncate(kept);
        Ok(())
    }

    /// The residual gate of this frame: the absolute limit, or the ratio times the median
    /// residual of the tracked steps (at least one grey level) when that is lower.
    fn residual_limit<const N: usize>(&self, steps: &[PointTrack]) -> Option<Q16> {
        let relative = self.checked.residual_ratio.and_then(|ratio| {
            let mut residuals: Vec<Q16, N> = steps
                .iter()
                .filter(|s| s.is_tracked())
                .map(|s| s.residual)
                .collect();
            let middle = residuals.len() / 2;
            if residuals.is_empty() {
                return None;
            }
            let (_, &mut median, _) = residuals.select_nth_unstable(middle);
            Some(ratio.saturating_mul(median.max(Q16::ONE)))
        });
        match (self.checked.max_residual, relative) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Whether `track`, whose forward step is `step`, passes every gate, and if so its position
    /// in the next frame: the step's, or where its anchor was found when it was due for
    /// relocation.
    fn judge(
        &self,
        track: &Track,
        anchor: &Anchor,
        step: PointTrack,
        max_residual: Option<Q16>,
        scratch: &mut [i16],
    ) -> Result<Result<Point, Rejection>, LkError> {
        if !step.is_tracked() {
            return Ok(Err(Rejection::Lost));
        }
        if max_residual.is_some_and(|max| step.residual > max) {
            return Ok(Err(Rejection::Residual));
        }
        let mut position = step.position;
        if let Some(relocate) = self.checked.relocate {
            let age = track.age.saturating_add(1);
            let due = age >= relocate.from_age
                && age.wrapping_add(track.id).checked_rem(relocate.every) == Some(0);
            let frame = self.next.base();
            if due && anchor.inside(&frame, position) {
                match anchor.locate(&frame, position, relocate.max_shift_sq) {
                    Some(found) if anchor.inside(&frame, found) => position = found,
                    _ => return Ok(Err(Rejection::Appearance)),
                }
            }
        }
        if let Some(min) = self.checked.min_correlation {
            if !anchor.matches(&self.next.base(), position, min) {
                return Ok(Err(Rejection::Appearance));
            }
        }
        // The way back costs as much as the way forth, so it comes last.
        let Some(limit_sq) = self.checked.fb_limit_sq else {
            return Ok(Ok(position));
        };
        // Undo the predicted displacement too, so that the way back starts as close to the
        // answer as the way forth did.
        let start = track.position;
        let back_guess = self
            .predict
            .map(|predict| offset(step.position, start, predict(start)));
        let lk = &self.checked.lk;
        let back = lk.track_point(self.next, self.prev, step.position, back_guess, scratch)?;
        if !back.is_tracked() || distance_sq(back.position, start) > limit_sq {
            return Ok(Err(Rejection::ForwardBackward));
        }
        Ok(Ok(position))
    }
}

/// `p + (a - b)`, saturating.
fn offset(p: Point, a: Point, b: Point) -> Point {
    let shift = |p: Q16, a: Q16, b: Q16| p.saturating_add(a.saturating_sub(b));
    Point::new(shift(p.x, a.x, b.x), shift(p.y, a.y, b.y))
}

/// Squared distance in squared Q16 units, saturating.
pub(super) fn distance_sq(a: Point, b: Point) -> i64 {
    // Differences of two i32 values always fit an i64.
    let dx = i64::from(a.x.to_bits()).saturating_sub(i64::from(b.x.to_bits()));
    let dy = i64::from(a.y.to_bits()).saturating_sub(i64::from(b.y.to_bits()));
    dx.saturating_mul(dx).saturating_add(dy.saturating_mul(dy))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_and_distances_saturate() {
        let p = Point::from_f32(10.0, 10.0);
        let moved = offset(p, Point::from_f32(1.0, 2.0), Point::from_f32(3.0, 1.0));
        assert_eq!(moved, Point::from_f32(8.0, 11.0));
        let far = offset(
            p,
            Point::from_f32(32000.0, 0.0),
            Point::from_f32(-32000.0, 0.0),
        );
        assert_eq!(far.x, Q16::MAX);
        let corner = Point::from_bits(i32::MIN, i32::MIN);
        let other = Point::from_bits(i32::MAX, i32::MAX);
        assert_eq!(distance_sq(corner, other), i64::MAX);
        assert_eq!(distance_sq(p, Point::from_f32(13.0, 14.0)), 25 << 32);
    }
}
