//! How the image turns and zooms between frames, as one complex number.
//!
//! A camera that yaws or climbs turns and scales every feature it sees. A track's birth patch
//! ([`super::anchor::Anchor`]) compared without that would stop matching its own feature after
//! a few degrees or a few percent, and a good track would die for it. The frame's similarity,
//! measured robustly from the tracks' own steps, and accumulated per track since its birth,
//! lets the patch be sampled the way the feature now lies.
//!
//! A similarity without its translation is `z = s e^{iθ}`: a point `p` (relative to any
//! centre) moves to `z p`. Each tracked step gives one estimate, the ratio of its offsets from
//! the frame's median position before and from where the median step takes that position
//! after; the median of their real and imaginary parts leaves out the tracks on moving objects
//! and the failed steps, as long as they are fewer than half.

use super::follow::median;
use crate::q16::Point;

/// Rotation and scale, `z = re + i im`: a point `(x, y)` goes to `(re x - im y, im x + re y)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Turn {
    re: f32,
    im: f32,
}

/// Steps a turn is measured from, at most (the rest are not looked at): enough for its
/// medians, and one buffer size for every tracker.
pub(super) const STEPS: usize = 32;

/// Offsets shorter than this from the frame's median position, px, give no estimate: their
/// ratio is mostly the step's noise.
const MIN_RADIUS: f32 = 8.0;

/// Estimates needed for a frame's turn; with fewer, the frame is taken not to turn.
const MIN_ESTIMATES: usize = 8;

/// A turn this close to none (`|z - 1|`) moves a patch's corner samples, 8.5 px out, by less
/// than a quarter of a pixel: patches are sampled on their plain grid.
const NEGLIGIBLE: f32 = 0.03;

/// How close to where a frame's turn takes it a step must land to agree with it, px; six in
/// ten steps must.
const AGREE: f32 = 0.5;

/// A frame's turn beyond this (`|z - 1|`: 0.6 degrees, or 1 % of zoom, in one frame) is fast:
/// a translation's residual grows with it.
const FAST: f32 = 0.01;

/// A frame's turn outside `|z - 1| <= MAX_CHANGE` is not believed (a scene cut, a frame of
/// failed steps): the frame is taken not to turn.
const MAX_CHANGE: f32 = 0.25;

impl Turn {
    /// No rotation, no scale.
    pub const NONE: Self = Self { re: 1.0, im: 0.0 };

    /// A rotation by `radians`, for tests.
    #[cfg(test)]
    pub fn rotation(radians: f32) -> Self {
        Self {
            re: radians.cos(),
            im: radians.sin(),
        }
    }

    /// The frame's turn from the steps `from -> to` of its tracked points (the first
    /// [`STEPS`]); [`Turn::NONE`] when too few lie far enough from the middle to say.
    pub fn of(steps: &[(Point, Point)]) -> Self {
        // The first STEPS: the medians below gather at most that many values.
        let steps = steps.chunks(STEPS).next().unwrap_or(&[]);
        // The middle of the points before, and where the median step takes it: both robust
        // to the steps of anything that moves its own way.
        let (Some(from), Some(shift)) = (
            median_point(steps.iter().map(|&(a, _)| a)),
            median_point(
                steps
                    .iter()
                    .map(|&(a, b)| Point::new(b.x.saturating_sub(a.x), b.y.saturating_sub(a.y))),
            ),
        ) else {
            return Self::NONE;
        };
        let centre = (from.0 + shift.0, from.1 + shift.1);
        let first = Self::about(steps, from, centre);
        if first.is_negligible() {
            // Its bias is smaller still.
            return first.agreed(steps, from, centre);
        }
        // The median step is the step of the middle point only approximately (under a turn,
        // steps vary across the frame): where the first estimate puts the middle, robustly,
        // gives the estimate again without that bias.
        let to = median_point(steps.iter().map(|&(a, b)| {
            let (pa, pb) = (a.to_f32(), b.to_f32());
            let (x, y) = first.apply((pa.0 - from.0, pa.1 - from.1));
            Point::from_f32(pb.0 - x, pb.1 - y)
        }));
        match to {
            Some(to) if first != Self::NONE => Self::about(steps, from, to).agreed(steps, from, to),
            _ => first.agreed(steps, from, centre),
        }
    }

    /// This turn about `from -> to` when most `steps` agree with it (within [`AGREE`] px);
    /// else [`Turn::NONE`]: a frame whose steps are mostly wrong (a blank or saturated frame,
    /// a scene cut) says nothing of how the image turned.
    // Out of line: called from three places, once a frame.
    #[inline(never)]
    fn agreed(self, steps: &[(Point, Point)], from: (f32, f32), to: (f32, f32)) -> Self {
        let agrees = |&&(a, b): &&(Point, Point)| {
            let (pa, pb) = (a.to_f32(), b.to_f32());
            let (x, y) = self.apply((pa.0 - from.0, pa.1 - from.1));
            let (ex, ey) = (pb.0 - to.0 - x, pb.1 - to.1 - y);
            ex * ex + ey * ey <= AGREE * AGREE
        };
        let agreeing = steps.iter().filter(agrees).count();
        if agreeing.saturating_mul(10) >= steps.len().saturating_mul(6) && agreeing >= MIN_ESTIMATES
        {
            self
        } else {
            Self::NONE
        }
    }

    /// The turn that takes offsets from `from` before to offsets from `to` after, from the
    /// median of each step's ratio; [`Turn::NONE`] when too few steps say.
    #[inline(never)]
    fn about(steps: &[(Point, Point)], from: (f32, f32), to: (f32, f32)) -> Self {
        // Q16 bits: the medians are of integers, as the tracker's other medians.
        let mut re: heapless::Vec<i32, STEPS> = heapless::Vec::new();
        let mut im: heapless::Vec<i32, STEPS> = heapless::Vec::new();
        for &(a, b) in steps {
            let (pa, pb) = (a.to_f32(), b.to_f32());
            let (px, py) = (pa.0 - from.0, pa.1 - from.1);
            let (qx, qy) = (pb.0 - to.0, pb.1 - to.1);
            let norm = px * px + py * py;
            if norm < MIN_RADIUS * MIN_RADIUS {
                continue;
            }
            // q / p = q conj(p) / |p|^2.
            // At most STEPS steps (cut in `of`, the only caller): both have room.
            let pushed = (
                re.push(q16((qx * px + qy * py) / norm)),
                im.push(q16((qy * px - qx * py) / norm)),
            );
            debug_assert!(pushed.0.is_ok() && pushed.1.is_ok(), "over {STEPS} steps");
        }
        if re.len() < MIN_ESTIMATES {
            return Self::NONE;
        }
        let (Some(re), Some(im)) = (median(&mut re), median(&mut im)) else {
            return Self::NONE;
        };
        let turn = Self {
            re: from_q16(re),
            im: from_q16(im),
        };
        if turn.change_sq() > MAX_CHANGE * MAX_CHANGE {
            return Self::NONE;
        }
        turn
    }

    /// This turn followed by `then`.
    pub fn then(self, then: Self) -> Self {
        Self {
            re: self.re * then.re - self.im * then.im,
            im: self.re * then.im + self.im * then.re,
        }
    }

    /// Where the offset `(x, y)` goes.
    pub fn apply(self, (x, y): (f32, f32)) -> (f32, f32) {
        (self.re * x - self.im * y, self.im * x + self.re * y)
    }

    /// True when the turn moves a patch's samples by less than a quarter of a pixel.
    pub fn is_negligible(self) -> bool {
        self.change_sq() <= NEGLIGIBLE * NEGLIGIBLE
    }

    /// True when one frame turns or zooms beyond [`FAST`].
    pub fn is_fast(self) -> bool {
        self.change_sq() > FAST * FAST
    }

    /// True when the turn scales by less than `limit` (`||z| - 1| < limit`).
    pub fn zooms_less_than(self, limit: f32) -> bool {
        let scale_sq = self.re * self.re + self.im * self.im;
        let (low, high) = (1.0 - limit, 1.0 + limit);
        low * low < scale_sq && scale_sq < high * high
    }

    /// `|z - 1|^2`.
    fn change_sq(self) -> f32 {
        let (dr, di) = (self.re - 1.0, self.im);
        dr * dr + di * di
    }
}

/// The coordinate-wise median of `points` (at most [`STEPS`]), px; `None` when there are none.
fn median_point(points: impl Iterator<Item = Point>) -> Option<(f32, f32)> {
    let mut xs: heapless::Vec<i32, STEPS> = heapless::Vec::new();
    let mut ys: heapless::Vec<i32, STEPS> = heapless::Vec::new();
    for p in points {
        // One point per step, and `of` keeps at most STEPS steps: both have room.
        let pushed = (xs.push(p.x.to_bits()), ys.push(p.y.to_bits()));
        debug_assert!(pushed.0.is_ok() && pushed.1.is_ok(), "over {STEPS} points");
    }
    Some((from_q16(median(&mut xs)?), from_q16(median(&mut ys)?)))
}

/// `v` as Q16 bits, saturating (NaN to 0).
fn q16(v: f32) -> i32 {
    crate::q16::q16_from_f32(v).to_bits()
}

/// Q16 bits as a number.
fn from_q16(bits: i32) -> f32 {
    crate::q16::q16_to_f32(crate::q16::Q16::from_bits(bits))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a ring, and where a turn of `degrees` and a scale of `scale` about (60, 40)
    /// plus a shift of (3, -2) takes them.
    fn steps(degrees: f32, scale: f32) -> [(Point, Point); 24] {
        let (c, s) = (
            degrees.to_radians().cos() * scale,
            degrees.to_radians().sin() * scale,
        );
        core::array::from_fn(|k| {
            let a = k as f32 * 0.7;
            let r = 10.0 + (k % 5) as f32 * 6.0;
            let (x, y) = (r * a.cos(), r * a.sin());
            let from = Point::from_f32(60.0 + x, 40.0 + y);
            let to = Point::from_f32(63.0 + c * x - s * y, 38.0 + s * x + c * y);
            (from, to)
        })
    }

    #[test]
    fn recovers_rotation_and_scale_despite_outliers() {
        let mut moved = steps(2.0, 1.01);
        // A quarter of the points on something that moves its own way.
        for (k, step) in moved.iter_mut().enumerate().filter(|(k, _)| k % 4 == 0) {
            step.1 = Point::from_f32(10.0 + k as f32, 90.0);
        }
        let turn = Turn::of(&moved);
        let want = (
            2.0f32.to_radians().cos() * 1.01,
            2.0f32.to_radians().sin() * 1.01,
        );
        assert!(
            (turn.re - want.0).abs() < 2e-3 && (turn.im - want.1).abs() < 2e-3,
            "{turn:?}"
        );
        assert!(!turn.is_negligible());
    }

    #[test]
    fn a_translation_does_not_turn_and_turns_compose() {
        let turn = Turn::of(&steps(0.0, 1.0));
        assert!(
            turn.is_negligible() && (turn.re - 1.0).abs() < 1e-3,
            "{turn:?}"
        );
        let quarter = Turn { re: 0.0, im: 1.0 };
        let half = quarter.then(quarter);
        assert!((half.re + 1.0).abs() < 1e-6 && half.im.abs() < 1e-6);
        assert_eq!(quarter.apply((1.0, 0.0)), (0.0, 1.0));
    }

    #[test]
    fn too_few_or_unbelievable_steps_do_not_turn() {
        let few = steps(5.0, 1.0);
        assert_eq!(Turn::of(&few[..4]), Turn::NONE);
        assert_eq!(Turn::of(&steps(40.0, 1.0)), Turn::NONE);
        assert_eq!(Turn::of(&[]), Turn::NONE);
    }
}
