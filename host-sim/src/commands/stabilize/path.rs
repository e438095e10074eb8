//! The camera path as similarity parameters, which a moving average can smooth.

use crate::synth::Homography;

/// The similarity part of a camera motion about a centre: where the centre went, how far the
/// image turned and by what factor it scaled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    /// Displacement of the centre, px.
    pub shift: (f64, f64),
    /// Rotation, radians (positive turns x towards y), unwrapped along the path.
    pub angle: f64,
    /// Natural logarithm of the scale factor.
    pub log_scale: f64,
}

impl PathPoint {
    /// The parameters of `motion` about `centre`: the centre's displacement, and the rotation
    /// and scale of the motion's local linear map there. `previous_angle` unwraps the angle so
    /// that a path turning past half a turn stays continuous.
    ///
    /// ```
    /// use host_sim::stabilize::PathPoint;
    /// use host_sim::synth::Homography;
    /// let centre = (50.0, 40.0);
    /// let motion = Homography::similarity(1.1, 0.2, (3.0, -1.0), centre);
    /// let p = PathPoint::of(&motion, centre, None);
    /// assert!((p.angle - 0.2).abs() < 1e-9 && (p.log_scale - 1.1f64.ln()).abs() < 1e-9);
    /// assert!(p.similarity(centre).distance(&motion, 100.0, 80.0) < 1e-9);
    /// ```
    pub fn of(motion: &Homography, centre: (f64, f64), previous_angle: Option<f64>) -> Self {
        let (cx, cy) = centre;
        let at = motion.apply(cx, cy);
        let along_x = motion.apply(cx + 1.0, cy);
        let along_y = motion.apply(cx, cy + 1.0);
        // Columns of the local linear map, by finite differences over one pixel (exact for
        // affine motions, and close for the mild perspective of camera motion).
        let (j00, j10) = (along_x.0 - at.0, along_x.1 - at.1);
        let (j01, j11) = (along_y.0 - at.0, along_y.1 - at.1);
        let (a, b) = ((j00 + j11) / 2.0, (j10 - j01) / 2.0);
        let angle = b.atan2(a);
        let angle = match previous_angle {
            Some(previous) => previous + wrap(angle - previous),
            None => angle,
        };
        Self {
            shift: (at.0 - cx, at.1 - cy),
            angle,
            log_scale: a.hypot(b).ln(),
        }
    }

    /// The mean of `points` (of which there must be at least one).
    pub fn mean<'a>(points: impl Iterator<Item = &'a PathPoint>) -> Self {
        let mut sum = Self {
            shift: (0.0, 0.0),
            angle: 0.0,
            log_scale: 0.0,
        };
        let mut count = 0.0;
        for p in points {
            sum.shift.0 += p.shift.0;
            sum.shift.1 += p.shift.1;
            sum.angle += p.angle;
            sum.log_scale += p.log_scale;
            count += 1.0;
        }
        Self {
            shift: (sum.shift.0 / count, sum.shift.1 / count),
            angle: sum.angle / count,
            log_scale: sum.log_scale / count,
        }
    }

    /// The similarity with these parameters about `centre`.
    pub fn similarity(&self, centre: (f64, f64)) -> Homography {
        Homography::similarity(self.log_scale.exp(), self.angle, self.shift, centre)
    }
}

/// `angle` brought into `(-pi, pi]`.
fn wrap(angle: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let wrapped = angle.rem_euclid(TAU);
    if wrapped > PI {
        wrapped - TAU
    } else {
        wrapped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_are_unwrapped_along_the_path() {
        let centre = (10.0, 10.0);
        let turned = Homography::rotation(3.0, centre);
        let beyond = Homography::rotation(3.3, centre);
        let first = PathPoint::of(&turned, centre, None);
        let second = PathPoint::of(&beyond, centre, Some(first.angle));
        assert!((second.angle - 3.3).abs() < 1e-9, "{}", second.angle);
    }

    #[test]
    fn the_mean_of_a_linear_path_is_its_middle() {
        let points: Vec<PathPoint> = (0..5)
            .map(|k| PathPoint {
                shift: (k as f64, -2.0 * k as f64),
                angle: 0.01 * k as f64,
                log_scale: 0.0,
            })
            .collect();
        let mean = PathPoint::mean(points.iter());
        assert_eq!(mean.shift, (2.0, -4.0));
        assert!((mean.angle - 0.02).abs() < 1e-12);
    }
}
