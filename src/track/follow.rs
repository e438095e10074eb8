//! One frame's step for every live track: LK forwards, then the gates, cheapest first.

use super::anchor::{Anchor, Located};
use super::appearance::AppearanceGate;
use super::config::{squared_bits, Checked, Relocate, FAILED_YOUNG};
use super::revive::SET_ASIDE_FROM_AGE;
use super::turn::{self, Turn};
use super::{FrameReport, Track};
use crate::frame::ImageView;
use crate::lk::{inside, LkError, PointTrack, TrackStatus};
use crate::pyramid::Pyramid;
use crate::q16::{Point, Q16};
use heapless::Vec;

/// Every this many frames of a track's life, its birth patch's summed turn is checked against
/// the image ([`Anchor::settle_turn`]).
const TURN_CHECK_EVERY: u32 = 128;

/// How often, in frames, a track is relocated onto its birth patch (from that age on) while the
/// image turns or zooms fast and has turned since the track's birth.
const TURNED_RELOCATE: u32 = 2;

/// Whether a frame's median step `centre` says the camera moves: [`MOVING_STEP`] or more.
pub(super) fn moves(centre: Point) -> bool {
    distance_sq(centre, Point::default()) >= squared_bits(MOVING_STEP)
}

/// The age from which a track whose image has turned or zoomed since its birth is relocated
/// on the regular schedule, at the latest: LK's translation drifts on such a track (a zoom
/// biases it towards the window's stronger texture) long before the regular first age.
const TURNED_FROM_AGE: u32 = 8;

/// Why a track was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rejection {
    /// LK lost it in the frame: too little texture, or not converged.
    Lost,
    /// It left the frame.
    OutOfFrame,
    /// Its residual is above the gate.
    Residual,
    /// It no longer correlates with its birth patch.
    Appearance,
    /// Its birth patch was not found near it.
    Relocation,
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

/// One track's forward step and how it was searched.
#[derive(Debug, Clone, Copy, Default)]
struct Forward {
    step: PointTrack,
    /// Where the search started in the next frame, when anything predicted it.
    guess: Option<Point>,
    /// The coarsest pyramid level searched.
    top: usize,
    /// True when the search started on a finer level and had to be repeated on the whole
    /// pyramid.
    fell_back: bool,
}

/// A track's appearance gate in one frame.
#[derive(Debug, Clone, Copy)]
struct AppearanceCheck {
    /// The least likeness to its anchor it passes with.
    limit: Q16,
    /// Its likeness at its step, when the frame's limit needed it.
    at_step: Option<Q16>,
}

/// The appearance gate of one frame (see [`super::appearance`]).
struct FrameAppearance<const N: usize> {
    gate: AppearanceGate,
    /// The limit of a track whose image has not turned since its birth.
    unturned: Q16,
    /// Each track's likeness to its anchor at its step, in track order ([`Q16::MIN`] where LK
    /// lost it), when the limit followed the frame's tracks; empty otherwise.
    likeness: Vec<Q16, N>,
}

impl<const N: usize> FrameAppearance<N> {
    /// The check of the `i`-th track, whose anchor is `anchor`: a track whose image has turned
    /// since its birth is held to the threshold, since there the gate is what stops LK's drift.
    fn of_track(&self, i: usize, anchor: &Anchor) -> AppearanceCheck {
        AppearanceCheck {
            limit: match anchor.has_turned() {
                true => self.gate.strict(),
                false => self.unturned,
            },
            at_step: self.likeness.get(i).copied(),
        }
    }
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
        failed_young: &mut dyn FnMut(Point),
        set_aside: &mut dyn FnMut(Track, &Anchor),
    ) -> Result<StepLimits, LkError> {
        // Forwards first, for every track: the residual gate needs the frame's median.
        let forward = self.forward_all::<N>(tracks, scratch)?;
        let limits = self.residual_limits::<N>(tracks, &forward);
        // The birth patches turn and zoom with the image, so that a camera that yaws or climbs
        // does not make good tracks look unlike their features.
        let steps = tracks.iter().zip(forward.iter());
        // At most turn::STEPS steps, spread over the tracks, say enough.
        let every = tracks.len().div_ceil(turn::STEPS).max(1);
        let tracked = steps.step_by(every).filter(|(_, f)| f.step.is_tracked());
        let mut pairs: Vec<(Point, Point), { turn::STEPS }> = Vec::new();
        for (t, f) in tracked {
            // At most turn::STEPS by the stride above.
            let pushed = pairs.push((t.position, f.step.position));
            debug_assert!(
                pushed.is_ok(),
                "more steps than turn::STEPS at stride {every}"
            );
        }
        let turn = Turn::of(&pairs);
        // A frame's similarity is the image's turn only on average, and summed over a long
        // life its errors may turn a patch more than its own feature turned: now and then each
        // track's summed turn is checked against the image, in the frame it is in.
        let frame = self.prev.base();
        for (anchor, track) in anchors.iter_mut().zip(tracks.iter()) {
            let due = track.age > 0 && track.age.checked_rem(TURN_CHECK_EVERY) == Some(0);
            if due {
                anchor.settle_turn(&frame, track.position);
            }
            anchor.turn(turn);
        }
        // A translation's residual grows on an image that turns or zooms fast, though the
        // tracks are right: in such a frame the residual gate is twice as wide, and the birth
        // patches, turned with the image, judge the tracks besides.
        let fast = turn.is_fast();
        let widen = if fast { 2 } else { 1 };

        // A camera that is still leaves a dropped track's feature where it was: it may be
        // revived there.
        let set_aside_dropped = self.checked.revive.is_some() && limits.is_still();
        let moving = limits.centre.is_some_and(moves);
        let appearance = self.appearance::<N>(&forward, anchors);
        let mut kept = 0;
        for i in 0..tracks.len() {
            let (Some(&track), Some(fwd), Some(anchor)) =
                (tracks.get(i), forward.get(i), anchors.get(i))
            else {
                break;
            };
            let max_residual = limits.of_step(&track, &fwd.step, widen);
            let check = appearance.as_ref().map(|a| a.of_track(i, anchor));
            let context = (max_residual, turn, moving, check);
            let verdict = self.judge(&track, anchor, fwd, context, scratch)?;
            if let Err(rejection) = verdict {
                let revivable = set_aside_dropped
                    && rejection != Rejection::OutOfFrame
                    && track.age >= SET_ASIDE_FROM_AGE;
                if revivable {
                    set_aside(track, anchor);
                }
                if rejection != Rejection::OutOfFrame && track.age < FAILED_YOUNG {
                    // Where its feature is now, as far as LK saw it.
                    failed_young(match fwd.step.is_tracked() {
                        true => fwd.step.position,
                        false => track.position,
                    });
                }
            }
            match verdict {
                Ok(position) => {
                    let step = fwd.step.position;
                    let moved = Track {
                        position,
                        previous: track.position,
                        residual: fwd.step.residual,
                        usual_residual: usual_residual(&track, fwd.step.residual),
                        age: track.age.saturating_add(1),
                        velocity: offset(step, Point::default(), track.position),
                        prediction_error: distance(step, fwd.guess.unwrap_or(track.position)),
                        ..track
                    };
                    if let Some(t) = tracks.get_mut(kept) {
                        *t = moved;
                    }
                    // Anchors move down only once a track before them was dropped.
                    // One move, in place (`kept < i < len`: in bounds).
                    if kept != i {
                        anchors.copy_within(i..=i, kept);
                    }
                    kept = kept.saturating_add(1);
                    report.tracked = report.tracked.saturating_add(1);
                }
                Err(Rejection::Lost) => report.dropped_lost = report.dropped_lost.saturating_add(1),
                Err(Rejection::Residual) => {
                    report.dropped_residual = report.dropped_residual.saturating_add(1)
                }
                Err(Rejection::Appearance) => {
                    report.dropped_appearance = report.dropped_appearance.saturating_add(1)
                }
                Err(Rejection::Relocation) => {
                    report.dropped_relocation = report.dropped_relocation.saturating_add(1)
                }
                Err(Rejection::OutOfFrame) => {
                    report.dropped_out_of_frame = report.dropped_out_of_frame.saturating_add(1)
                }
                Err(Rejection::ForwardBackward) => {
                    report.dropped_fb = report.dropped_fb.saturating_add(1)
                }
            }
        }
        tracks.truncate(kept);
        anchors.truncate(kept);
        Ok(StepLimits {
            residual: limits,
            widen,
        })
    }

    /// Whether a corner at `position` in the next frame arrived there from the previous frame
    /// as a track would have: its window, followed back into the previous frame, passes the
    /// residual gate the frame's tracks were judged by (`limits`). The way back starts from
    /// the caller's prediction reversed, else from the frame's median step reversed. A window
    /// LK cannot follow back at all, or that reaches out of the previous frame there (a feature
    /// that just came into view: its window was partly outside), is given the benefit of the
    /// doubt: only a residual measured is held against a corner. A corner on a feature that
    /// changes faster than a track can follow (a walker's limbs, a face that talks) fails here
    /// as its track would fail the residual gate on its first step.
    pub(super) fn arrived(
        &self,
        position: Point,
        limits: &StepLimits,
        scratch: &mut [i16],
    ) -> Result<bool, LkError> {
        let guess = match self.predict {
            Some(predict) => Some(offset(position, position, predict(position))),
            None => limits
                .frame_motion()
                .map(|motion| offset(position, Point::default(), motion)),
        };
        let back = self
            .checked
            .lk
            .track_point(self.next, self.prev, position, guess, scratch)?;
        let half = self.checked.lk.params().window / 2;
        if !back.is_tracked() || !window_inside(&self.prev.base(), back.position, half) {
            return Ok(true);
        }
        let moved = offset(position, Point::default(), back.position);
        Ok(limits
            .of_displacement(moved)
            .is_none_or(|max| back.residual <= max))
    }

    /// The forward steps of every track, in order. Tracks with a history go first; the
    /// median of their displacements (the frame's motion) then seeds the search of the new
    /// tracks, which have none. In a frame of new tracks only, the first few are searched on
    /// the whole pyramid and seed the others.
    fn forward_all<const N: usize>(
        &self,
        tracks: &[Track],
        scratch: &mut [i16],
    ) -> Result<Vec<Forward, N>, LkError> {
        let mut forward: Vec<Forward, N> = Vec::new();
        let mut motion = FrameMotion::<N>::default();
        for track in tracks {
            let step = match self.guess(track) {
                Some(guess) => {
                    let step = self.forward(track, Some(guess), track.prediction_error, scratch)?;
                    motion.add(track, &step);
                    step
                }
                // Searched in the second pass.
                None => Forward::default(),
            };
            // Cannot fail: one step per track, and both hold at most N.
            let pushed = forward.push(step);
            debug_assert!(pushed.is_ok(), "more tracks than the tracker's capacity");
        }
        let seeds = self.checked.constant_velocity;
        let mut seed = motion.median().filter(|_| seeds);
        for (track, step) in tracks.iter().zip(forward.iter_mut()) {
            if self.predicted(track) {
                continue;
            }
            *step = match seed {
                Some(velocity) => {
                    let guess = offset(track.position, velocity, Point::default());
                    self.forward(track, Some(guess), Q16::ZERO, scratch)?
                }
                None => {
                    let step = self.forward(track, None, Q16::MAX, scratch)?;
                    motion.add(track, &step);
                    seed = motion.median().filter(|_| seeds);
                    step
                }
            };
        }
        Ok(forward)
    }

    /// Where `track`'s search starts: the caller's prediction, else its latest displacement
    /// repeated ([`super::Search::constant_velocity`]) once it has one.
    fn guess(&self, track: &Track) -> Option<Point> {
        match self.predict {
            Some(predict) => Some(predict(track.position)),
            None => self
                .predicted(track)
                .then(|| offset(track.position, track.velocity, Point::default())),
        }
    }

    /// Whether [`Follow::guess`] has a prediction for `track`, without making it.
    fn predicted(&self, track: &Track) -> bool {
        self.predict.is_some() || (self.checked.constant_velocity && track.age > 0)
    }

    /// The forward step of `track` from `guess`, whose expected error is `expected`: from the
    /// coarsest level that error calls for, and again on the whole pyramid when that search
    /// fails or lands beyond the reach of the level it started on.
    fn forward(
        &self,
        track: &Track,
        guess: Option<Point>,
        expected: Q16,
        scratch: &mut [i16],
    ) -> Result<Forward, LkError> {
        let lk = &self.checked.lk;
        let full = lk.params().max_level;
        let start = guess.and(self.checked.fine_search).map(|reach| {
            let mut level = 0;
            let mut reach = reach;
            while level < full && expected > reach {
                level = level.saturating_add(1);
                reach = reach.saturating_mul_int(2);
            }
            (level, reach)
        });
        if let Some((top, reach)) = start.filter(|&(top, _)| top < full) {
            let step = lk.with_max_level(top).track_point(
                self.prev,
                self.next,
                track.position,
                guess,
                scratch,
            )?;
            let landed_near = guess.is_some_and(|g| {
                let limit = i64::from(reach.saturating_mul_int(2).to_bits());
                distance_sq(step.position, g) <= limit.saturating_mul(limit)
            });
            if step.is_tracked() && landed_near {
                return Ok(Forward {
                    step,
                    guess,
                    top,
                    fell_back: false,
                });
            }
        }
        let fell_back = start.is_some_and(|(top, _)| top < full);
        // A prediction that failed on the fine levels is not trusted on the coarse ones: the
        // whole pyramid is searched from the caller's prediction, or else from the track's
        // position, as without any (a camera that stops, or a repeated frame).
        let guess = match (fell_back, self.predict) {
            (true, Some(predict)) => Some(predict(track.position)),
            (true, None) => None,
            (false, _) => guess,
        };
        let step = lk.track_point(self.prev, self.next, track.position, guess, scratch)?;
        Ok(Forward {
            step,
            guess,
            top: full,
            fell_back,
        })
    }

    /// The appearance gate of this frame (`None` when the gate is off). When its limit follows
    /// the frame's tracks, every tracked step's likeness is measured here, and the gate reuses
    /// it; a turned track's likeness, without the resampling allowance, says nothing of the
    /// others' ([`Anchor::likeness`]) and is left out of the frame's spread.
    fn appearance<const N: usize>(
        &self,
        steps: &[Forward],
        anchors: &[Anchor],
    ) -> Option<FrameAppearance<N>> {
        let gate = self.checked.appearance?;
        let mut likeness = Vec::new();
        if !gate.follows_frame() {
            let unturned = gate.strict();
            return Some(FrameAppearance {
                gate,
                unturned,
                likeness,
            });
        }
        let frame = self.next.base();
        let mut unturned: Vec<i32, N> = Vec::new();
        for (fwd, anchor) in steps.iter().zip(anchors) {
            let tracked = fwd.step.is_tracked();
            let value = match tracked {
                true => anchor.likeness(&frame, fwd.step.position),
                false => Q16::MIN,
            };
            // At most one a track, and both hold N.
            let pushed = likeness.push(value).is_ok()
                && (!tracked || anchor.has_turned() || unturned.push(value.to_bits()).is_ok());
            debug_assert!(pushed, "more tracks than the tracker holds");
        }
        let unturned = gate.limit(&mut unturned);
        Some(FrameAppearance {
            gate,
            unturned,
            likeness,
        })
    }

    /// The residual gates of this frame (see [`ResidualLimits`]).
    fn residual_limits<const N: usize>(
        &self,
        tracks: &[Track],
        steps: &[Forward],
    ) -> ResidualLimits {
        let tracked = tracks
            .iter()
            .zip(steps)
            .filter(|(_, f)| f.step.is_tracked())
            .map(|(t, f)| (displacement(t, &f.step), f.step.residual));
        ResidualLimits::of::<N>(
            self.checked.max_residual,
            self.checked.residual_ratio,
            tracked,
        )
    }

    /// Whether `track`, whose forward step is `fwd`, passes every gate, and if so its position
    /// in the next frame: the step's, or where its anchor was found when it was due for
    /// relocation (`moving`: the camera moves, see [`moves`]).
    fn judge(
        &self,
        track: &Track,
        anchor: &Anchor,
        fwd: &Forward,
        (max_residual, turn, moving, appearance): (
            Option<Q16>,
            Turn,
            bool,
            Option<AppearanceCheck>,
        ),
        scratch: &mut [i16],
    ) -> Result<Result<Point, Rejection>, LkError> {
        let step = fwd.step;
        if !step.is_tracked() {
            return Ok(Err(match step.status {
                TrackStatus::OutOfBounds => Rejection::OutOfFrame,
                _ => Rejection::Lost,
            }));
        }
        if max_residual.is_some_and(|max| step.residual > max) {
            return Ok(Err(Rejection::Residual));
        }
        let fast = turn.is_fast();
        let mut position = step.position;
        if let Some(relocate) = self.checked.relocate {
            let due = (relocate, fast, moving);
            position = match self.relocated(track, anchor, position, due) {
                Ok(found) => found,
                Err(rejection) => return Ok(Err(rejection)),
            };
        }
        if let Some(check) = appearance {
            // Measured at the step already, unless relocation moved the track.
            let likeness = match check.at_step {
                Some(likeness) if position == step.position => likeness,
                _ => anchor.likeness(&self.next.base(), position),
            };
            if likeness < check.limit {
                return Ok(Err(Rejection::Appearance));
            }
        }
        // The way back costs as much as the way forth, so it comes last, and only when due.
        let Some(limit_sq) = self.checked.fb_limit_sq else {
            return Ok(Ok(position));
        };
        if !self.backward_due(track, fwd) {
            return Ok(Ok(position));
        }
        // Undo the predicted displacement too, so that the way back starts as close to the
        // answer as the way forth did; and search as many levels as the way forth did.
        let start = track.position;
        let back_guess = fwd.guess.map(|guess| offset(step.position, start, guess));
        let lk = self.checked.lk.with_max_level(fwd.top);
        let back = lk.track_point(self.next, self.prev, step.position, back_guess, scratch)?;
        if !back.is_tracked() || distance_sq(back.position, start) > limit_sq {
            return Ok(Err(Rejection::ForwardBackward));
        }
        Ok(Ok(position))
    }

    /// Where `track`, stepped to `position`, is once relocated onto its anchor when it is due
    /// (`position` itself when not, or when too little of its patch lies in the frame to say);
    /// the rejection when the anchor is not found near it, or is found out of the frame. Due on
    /// its schedule, sooner while the image turns fast (`fast`), and in every frame near the
    /// frame's edge, where its LK window is cut, while the camera moves (`moving`, see
    /// [`super::Relocation::at_edge`]).
    fn relocated(
        &self,
        track: &Track,
        anchor: &Anchor,
        position: Point,
        (relocate, fast, moving): (Relocate, bool, bool),
    ) -> Result<Point, Rejection> {
        let age = track.age.saturating_add(1);
        let on_schedule = |from: u32, every: u32| {
            age >= from && age.wrapping_add(track.id).checked_rem(every) == Some(0)
        };
        let turned = anchor.has_turned();
        let from_age = if turned {
            relocate.from_age.min(TURNED_FROM_AGE)
        } else {
            relocate.from_age
        };
        // A turned patch carries an error of its own (the frame's turn is the image's only on
        // average), which each relocation brings into the track: on a turned image tracks are
        // relocated half as often.
        let every = if turned {
            relocate.every.saturating_mul(2)
        } else {
            relocate.every
        };
        let regular = on_schedule(from_age, every);
        // LK drifts faster on an image that turns or zooms fast: its tracks are brought back
        // onto their features sooner and more often.
        let quick = fast && turned && on_schedule(TURNED_RELOCATE, TURNED_RELOCATE);
        // A still camera's edge tracks stay put, where LK's cut window does no harm; relocated
        // every frame, the tracks at the edge of a face that talks failed sooner (carphone).
        let at_edge = relocate.at_edge
            && moving
            && !window_inside(
                &self.next.base(),
                position,
                self.checked.lk.params().window / 2,
            );
        if !(regular || quick || at_edge) {
            return Ok(position);
        }
        // Near the frame's edge the part of the patch inside it is compared: a window the
        // edge cuts drifts most, and its track needs the check most.
        let frame = self.next.base();
        match anchor.locate(&frame, position, relocate.max_shift_sq) {
            // Found beyond the outer pixel centres: the feature is leaving the frame.
            Located::At(found) if inside(&frame, (found.x.to_bits(), found.y.to_bits())) => {
                Ok(found)
            }
            Located::At(_) => Err(Rejection::OutOfFrame),
            Located::OutOfView => Ok(position),
            Located::Lost => Err(Rejection::Relocation),
        }
    }

    /// Whether the forward step `fwd` of `track` gets the backward check: when its turn comes
    /// (see [`super::Gates::fb_every`]), or when it looks doubtful.
    fn backward_due(&self, track: &Track, fwd: &Forward) -> bool {
        let checked = self.checked;
        let turn = track
            .age
            .wrapping_add(track.id)
            .checked_rem(checked.fb_every)
            == Some(0);
        let strays = fwd
            .guess
            .is_none_or(|g| distance_sq(fwd.step.position, g) > checked.fb_doubt_sq);
        // A new track's first step is always checked: agreeing with the frame's motion (its
        // seed) is not enough, since a window on an edge slides along with it
        // (tests/hostile_frames.rs: a repeated frame then loses it).
        turn || track.age == 0 || fwd.fell_back || strays
    }
}

/// How much farther than the frame's median step, px (squared, in squared Q16 units), a step
/// goes for its track to be judged among the movers: 1 px.
const MOVER_STEP_SQ: i64 = 1 << 32;

/// The residual gates of one frame: the absolute limit ([`super::Gates::max_residual`]), or
/// the ratio ([`super::Gates::residual_ratio`]) times the median residual of the tracked steps
/// (at least one grey level) when that is lower.
///
/// The median stands for what noise, blur and interpolation cost a correct track in this
/// frame, and it is the median of the scene most tracks are on. A still camera over a street
/// has most of its tracks on the still ground, whose residual is the sensor's noise alone; a
/// track on a walker has a residual of its own (the body bends, its edges blur) and would be
/// judged against the ground's. So the steps that go more than 1 px from the frame's median
/// step (the movers') get their own median, when there are at least five of them, and a
/// mover is held to the larger of the two limits. A track an occluder drags is judged so too,
/// but what stops it is the jump of its residual as the occluder's edge enters its window, far
/// above either median, and its birth patch, which no longer matches
/// (tests/track.rs: rigid occluders and walkers alike).
///
/// A median is still the median of many windows, and a window's own texture decides what a
/// correct step costs it: a high-contrast edge under blur, or a face that talks, leaves a
/// residual several times the frame's at every step. So a track is also held to the ratio
/// times its own usual residual ([`Track::usual_residual`], a slow running mean) when that is
/// higher, within the absolute limit: what stops it is a jump above its own past, as an
/// occluder's edge entering its window brings. On OpenCV's vtest clip (a still camera over a
/// street) this kept tracks 89.9 frames on average instead of 82.9, 70.1 % of the first
/// frame's at frame 100 instead of 64.9 % (`bench/real_footage.py`).
#[derive(Debug, Clone, Copy)]
struct ResidualLimits {
    /// The limit of the frame's tracks; `None` when both gates are off.
    frame: Option<Q16>,
    /// The frame's median step, once enough tracks stepped.
    centre: Option<Point>,
    /// The limit of the steps that go more than 1 px from the median step, when enough do.
    movers: Option<Q16>,
    /// The relative gate's ratio, which a track's own usual residual is multiplied by.
    ratio: Option<Q16>,
    /// The absolute limit, which no track's own limit exceeds.
    max: Option<Q16>,
}

impl ResidualLimits {
    /// The limits of the tracked steps `steps` (each track's displacement and residual), with
    /// the absolute limit `max` and the relative `ratio`.
    fn of<const N: usize>(
        max: Option<Q16>,
        ratio: Option<Q16>,
        steps: impl Iterator<Item = (Point, Q16)> + Clone,
    ) -> Self {
        let relative = |residuals: &mut [i32]| {
            let median = Q16::from_bits(median(residuals)?);
            let limit = ratio?.saturating_mul(median.max(Q16::ONE));
            Some(max.map_or(limit, |max| max.min(limit)))
        };
        let mut all: Vec<i32, N> = steps.clone().map(|(_, r)| r.to_bits()).collect();
        let frame = relative(&mut all).or(max);
        let mut motion = FrameMotion::<N>::default();
        steps.clone().for_each(|(d, _)| motion.push(d));
        let centre = motion.median();
        let movers = ratio.zip(centre).and_then(|(_, centre)| {
            let mut moving: Vec<i32, N> = steps
                .filter(|&(d, _)| distance_sq(d, centre) > MOVER_STEP_SQ)
                .map(|(_, r)| r.to_bits())
                .collect();
            if moving.len() < FrameMotion::<N>::ENOUGH {
                return None;
            }
            relative(&mut moving)
        });
        Self {
            frame,
            centre,
            movers,
            ratio,
            max,
        }
    }

    /// Whether the frame's median step is within [`STILL_STEP`] px of none: a still camera.
    fn is_still(&self) -> bool {
        self.centre
            .is_some_and(|c| distance_sq(c, Point::default()) <= squared_bits(STILL_STEP))
    }

    /// The limit of `track`, stepped by `step`: the frame's (or the movers'), `widen` times
    /// as wide, or the ratio times the track's own usual residual when that is higher, within
    /// the absolute limit. A fast turn widens the frame's limit only: widening the track's own
    /// as well let weak tracks on `bench/track_vs_opencv.py`'s 320 x 240 climb live on and
    /// crowd out better ones (mean life 33.4 -> 31.4 frames).
    fn of_step(&self, track: &Track, step: &PointTrack, widen: i32) -> Option<Q16> {
        let limit = self
            .of_displacement(displacement(track, step))?
            .saturating_mul_int(widen);
        let own = self
            .ratio
            .filter(|_| track.age >= USUAL_AFTER && track.usual_residual > Q16::ZERO)
            .map(|ratio| ratio.saturating_mul(track.usual_residual))
            .map(|own| self.max.map_or(own, |max| own.min(max)));
        Some(own.map_or(limit, |own| limit.max(own)))
    }

    /// The limit of a step that moves a point by `d`.
    fn of_displacement(&self, d: Point) -> Option<Q16> {
        match self.centre.zip(self.movers) {
            Some((centre, limit)) if distance_sq(d, centre) > MOVER_STEP_SQ => {
                self.frame.map(|frame| frame.max(limit))
            }
            _ => self.frame,
        }
    }
}

/// The residual limits the frame's tracks were judged by, which a corner about to become a
/// track is held to as well (see [`super::Refill::cooldown`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct StepLimits {
    residual: ResidualLimits,
    /// 2 in a frame whose image turns or zooms fast, else 1: the gate is that much wider.
    widen: i32,
}

impl StepLimits {
    /// The residual limit of a step that moves a point by `d`, `None` when the gates are off.
    pub(super) fn of_displacement(&self, d: Point) -> Option<Q16> {
        self.residual
            .of_displacement(d)
            .map(|max| max.saturating_mul_int(self.widen))
    }

    /// The frame's median step, where a point's search starts; `None` when too few tracks
    /// stepped to say.
    pub(super) fn frame_motion(&self) -> Option<Point> {
        self.residual.centre
    }

    /// Whether the frame's median step says the camera is still (within [`STILL_STEP`] px);
    /// false when too few tracks stepped to say.
    pub(super) fn is_still(&self) -> bool {
        self.residual.is_still()
    }
}

/// The usual residual of `track` once a step of `residual` is added to it: the step's own on
/// the track's first step, else a running mean in which the new step weighs
/// 1 / 2^[`USUAL_RESIDUAL_SHIFT`].
fn usual_residual(track: &Track, residual: Q16) -> Q16 {
    if track.age == 0 {
        return residual;
    }
    let usual = track.usual_residual.to_bits();
    let change = residual.to_bits().saturating_sub(usual) >> USUAL_RESIDUAL_SHIFT;
    Q16::from_bits(usual.saturating_add(change))
}

/// Steps a track has made (its age before the step judged) before its usual residual says
/// what its window costs it: its own limit applies from its fifth step on, so a track on a
/// feature that changes faster than it can follow (leaves in the wind, a patch of water) fails
/// within its first few, before that limit may let it live on.
const USUAL_AFTER: u32 = FAILED_YOUNG;

/// How slowly a track's usual residual follows its steps: each new one weighs 1/8, so that a
/// track's own limit rises over several frames, not with the jump of an occluder's edge
/// entering its window.
const USUAL_RESIDUAL_SHIFT: u32 = 3;

/// The longest median step of a frame whose camera is taken as still, px: well under what a
/// camera that pans or shakes moves in a frame, and above LK's noise on a still one.
const STILL_STEP: Q16 = Q16::from_bits(1 << 16 >> 3);

/// The shortest median step of a frame whose camera is taken as moving, px: half a pixel, under
/// which the median is as much LK's noise and a mover's steps as the camera's motion.
const MOVING_STEP: Q16 = Q16::from_bits(1 << 15);

/// How far `step` moves `track`.
fn displacement(track: &Track, step: &PointTrack) -> Point {
    offset(step.position, Point::default(), track.position)
}

/// The displacements of the steps tracked so far in a frame, whose median stands for the
/// frame's motion.
struct FrameMotion<const N: usize> {
    dx: Vec<i32, N>,
    dy: Vec<i32, N>,
}

impl<const N: usize> Default for FrameMotion<N> {
    fn default() -> Self {
        Self {
            dx: Vec::new(),
            dy: Vec::new(),
        }
    }
}

impl<const N: usize> FrameMotion<N> {
    /// Steps a median needs before it seeds other tracks.
    const ENOUGH: usize = 5;

    fn add(&mut self, track: &Track, step: &Forward) {
        if step.step.is_tracked() {
            self.push(displacement(track, &step.step));
        }
    }

    fn push(&mut self, d: Point) {
        // Both hold at most N, one entry per track.
        let pushed = (self.dx.push(d.x.to_bits()), self.dy.push(d.y.to_bits()));
        debug_assert!(
            pushed.0.is_ok() && pushed.1.is_ok(),
            "more tracks than the tracker's capacity"
        );
    }

    /// The median displacement, once [`Self::ENOUGH`] steps are in.
    fn median(&mut self) -> Option<Point> {
        if self.dx.len() < Self::ENOUGH {
            return None;
        }
        Some(Point::from_bits(
            median(&mut self.dx)?,
            median(&mut self.dy)?,
        ))
    }
}

/// The median of `values` (the upper one of an even count), reordering them; `None` when
/// there are none. Q16 values go in as their bits, which order alike: one selection routine in
/// the firmware's flash rather than one per type.
pub(super) fn median(values: &mut [i32]) -> Option<i32> {
    let middle = values.len() / 2;
    if values.is_empty() {
        return None;
    }
    let (_, &mut m, _) = values.select_nth_unstable(middle);
    Some(m)
}

/// Whether the window of `half` px either side of `p` lies wholly inside `frame`.
fn window_inside(frame: &ImageView<'_>, p: Point, half: usize) -> bool {
    let within = |v: Q16, size: usize| {
        let (low, high) = (half, size.saturating_sub(1).saturating_sub(half));
        // Frame sides are at most MAX_DIMENSION: the shifts stay far inside i64.
        let bits = i64::from(v.to_bits());
        low <= high && (low as i64) << 16 <= bits && bits <= (high as i64) << 16
    };
    within(p.x, frame.width()) && within(p.y, frame.height())
}

/// `p + (a - b)`, saturating.
fn offset(p: Point, a: Point, b: Point) -> Point {
    let shift = |p: Q16, a: Q16, b: Q16| p.saturating_add(a.saturating_sub(b));
    Point::new(shift(p.x, a.x, b.x), shift(p.y, a.y, b.y))
}

/// Distance in px, saturating.
fn distance(a: Point, b: Point) -> Q16 {
    // An f32 square root (one instruction on a Cortex-M4F) is within a Q16 step of the exact
    // root at any distance; saturated squares give Q16::MAX, as `as` saturates.
    #[allow(clippy::cast_possible_truncation, clippy::cast_precision_loss)]
    let root = libm::sqrtf(distance_sq(a, b) as f32) as i32;
    Q16::from_bits(root)
}

/// Squared distance in squared Q16 units, saturating.
pub(super) fn distance_sq(a: Point, b: Point) -> i64 {
    // The difference of two i32 values is below 2^32 in magnitude, so its square fits a u64
    // (one multiply); only the sum can pass the i64 range.
    let gap = |p: Q16, q: Q16| i64::from(p.to_bits()).abs_diff(i64::from(q.to_bits()));
    let (dx, dy) = (gap(a.x, b.x), gap(a.y, b.y));
    // (2^32 - 1)^2 < 2^64: the squares never wrap.
    let sum = dx.wrapping_mul(dx).saturating_add(dy.wrapping_mul(dy));
    i64::try_from(sum).unwrap_or(i64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_inside_keep_half_a_window_from_every_edge() {
        let pixels = [0u8; 40 * 30];
        let frame = ImageView::packed(&pixels, 40, 30).unwrap();
        let inside = |x: f32, y: f32| window_inside(&frame, Point::from_f32(x, y), 10);
        assert!(inside(10.0, 10.0) && inside(29.0, 19.0));
        assert!(!inside(9.9, 15.0) && !inside(29.1, 15.0) && !inside(20.0, 19.1));
        // A window wider than the frame is never inside.
        assert!(!window_inside(&frame, Point::from_f32(20.0, 15.0), 15));
    }

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

    /// A still ground's steps (residual 1 grey level) and `movers` walkers' steps of 3 px
    /// (residual 4: bodies bend and blur).
    fn street(movers: usize) -> Vec<(Point, Q16), 32> {
        let ground = (Point::default(), Q16::ONE);
        let walker = (Point::from_f32(3.0, 0.0), Q16::from_num(4));
        let ground = core::iter::repeat_n(ground, 20);
        ground.chain(core::iter::repeat_n(walker, movers)).collect()
    }

    #[test]
    fn movers_are_judged_against_the_movers_residual() {
        let (max, ratio) = (Some(Q16::from_num(12)), Some(Q16::from_num(3)));
        let steps = street(6);
        let limits = ResidualLimits::of::<32>(max, ratio, steps.iter().copied());
        let track = Track::default();
        let step = |x: f32| PointTrack {
            position: Point::from_f32(x, 0.0),
            ..PointTrack::default()
        };
        // The ground's tracks: 3 times its median of 1 grey level.
        assert_eq!(
            limits.of_step(&track, &step(0.0), 1),
            Some(Q16::from_num(3))
        );
        assert_eq!(
            limits.of_step(&track, &step(0.9), 1),
            Some(Q16::from_num(3))
        );
        // A walker's: 3 times the walkers' median of 4, within the absolute 12.
        assert_eq!(
            limits.of_step(&track, &step(3.0), 1),
            Some(Q16::from_num(12))
        );
        // Four movers are too few for a median of their own.
        let few = street(4);
        let limits = ResidualLimits::of::<32>(max, ratio, few.iter().copied());
        assert_eq!(
            limits.of_step(&track, &step(3.0), 1),
            Some(Q16::from_num(3))
        );
        // Without the relative gate, the absolute limit alone; with neither, none.
        let absolute = ResidualLimits::of::<32>(max, None, steps.iter().copied());
        assert_eq!(absolute.of_step(&track, &step(3.0), 1), max);
        let open = ResidualLimits::of::<32>(None, None, steps.iter().copied());
        assert_eq!(open.of_step(&track, &step(3.0), 1), None);
    }

    #[test]
    fn a_track_is_also_judged_against_its_own_usual_residual() {
        let (max, ratio) = (Some(Q16::from_num(12)), Some(Q16::from_num(3)));
        // The ground's tracks leave 1 grey level: the frame's limit is 3.
        let limits = ResidualLimits::of::<32>(max, ratio, street(0).iter().copied());
        let still = PointTrack::default();
        let usual = |grey: f32| Track {
            age: 10,
            usual_residual: Q16::from_num(grey),
            ..Track::default()
        };
        // A track on a high-contrast edge that usually leaves 2 is held to 6, not 3.
        assert_eq!(
            limits.of_step(&usual(2.0), &still, 1),
            Some(Q16::from_num(6))
        );
        // One that usually leaves less than the frame's median is held to the frame's limit,
        // and no track to more than the absolute limit.
        assert_eq!(
            limits.of_step(&usual(0.5), &still, 1),
            Some(Q16::from_num(3))
        );
        assert_eq!(limits.of_step(&usual(5.0), &still, 1), max);
        // A fast turn widens the frame's limit, not the track's own.
        assert_eq!(
            limits.of_step(&usual(2.5), &still, 2),
            Some(Q16::from_num(7.5))
        );
        // Before its fifth step a track is held to the frame's limit alone.
        let aged = |age: u32| Track { age, ..usual(2.0) };
        assert_eq!(limits.of_step(&aged(3), &still, 1), Some(Q16::from_num(3)));
        assert_eq!(limits.of_step(&aged(4), &still, 1), Some(Q16::from_num(6)));
        // Without the relative gate, the absolute limit alone.
        let absolute = ResidualLimits::of::<32>(max, None, street(0).iter().copied());
        assert_eq!(absolute.of_step(&usual(2.0), &still, 1), max);
    }

    #[test]
    fn the_usual_residual_follows_the_steps_slowly() {
        let newborn = Track::default();
        // The first step's residual is the track's usual one.
        assert_eq!(usual_residual(&newborn, Q16::from_num(2)), Q16::from_num(2));
        let track = Track {
            age: 5,
            usual_residual: Q16::from_num(2),
            ..Track::default()
        };
        // A jump from 2 to 10 raises it by an eighth of the jump.
        assert_eq!(usual_residual(&track, Q16::from_num(10)), Q16::from_num(3));
        assert_eq!(usual_residual(&track, Q16::ZERO), Q16::from_num(1.75));
    }
}
