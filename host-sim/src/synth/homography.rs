//! Plane projective warps: the exact ground truth of a synthetic sequence.
//!
//! A warp maps a point of frame 0 to where the same scene point appears in frame k. Positions use
//! the library's convention: the origin is the centre of the top-left pixel.

/// A 3x3 homography acting on `(x, y, 1)`, in `f64`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography {
    /// Row-major matrix; `m[2]` is the projective row `[h31 h32 h33]`.
    pub m: [[f64; 3]; 3],
}

impl Default for Homography {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Homography {
    /// The warp that leaves every point in place.
    pub const IDENTITY: Self = Self {
        m: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };

    /// A shift by (`dx`, `dy`) px.
    ///
    /// ```
    /// use host_sim::synth::Homography;
    /// assert_eq!(Homography::translation(2.0, -1.0).apply(1.0, 1.0), (3.0, 0.0));
    /// ```
    pub fn translation(dx: f64, dy: f64) -> Self {
        Self {
            m: [[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]],
        }
    }

    /// A rotation by `angle` radians about `centre`; positive turns x towards y (clockwise on
    /// screen, since y points down).
    pub fn rotation(angle: f64, centre: (f64, f64)) -> Self {
        Self::similarity(1.0, angle, (0.0, 0.0), centre)
    }

    /// A zoom by `scale` about `centre` (`scale > 1` magnifies).
    pub fn zoom(scale: f64, centre: (f64, f64)) -> Self {
        Self::similarity(scale, 0.0, (0.0, 0.0), centre)
    }

    /// Zoom by `scale` and rotation by `angle` about `centre`, then a shift by `shift`:
    /// `p' = scale R(angle) (p - centre) + centre + shift`.
    ///
    /// ```
    /// use host_sim::synth::Homography;
    /// let h = Homography::similarity(2.0, 0.0, (1.0, 0.0), (10.0, 10.0));
    /// assert_eq!(h.apply(11.0, 10.0), (13.0, 10.0));
    /// ```
    pub fn similarity(scale: f64, angle: f64, shift: (f64, f64), centre: (f64, f64)) -> Self {
        let (sin, cos) = angle.sin_cos();
        let (a, b) = (scale * cos, scale * sin);
        let linear = Self {
            m: [[a, -b, 0.0], [b, a, 0.0], [0.0, 0.0, 1.0]],
        };
        Self::about(linear, centre).then(&Self::translation(shift.0, shift.1))
    }

    /// A pure perspective warp about `centre`: `h31`, `h32` are the projective terms per pixel
    /// from the centre (keep them small, around 1e-4, for a camera tilting a few degrees).
    pub fn perspective(h31: f64, h32: f64, centre: (f64, f64)) -> Self {
        let projective = Self {
            m: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [h31, h32, 1.0]],
        };
        Self::about(projective, centre)
    }

    /// `warp` conjugated so that it acts about `centre` instead of the origin.
    fn about(warp: Self, centre: (f64, f64)) -> Self {
        Self::translation(-centre.0, -centre.1)
            .then(&warp)
            .then(&Self::translation(centre.0, centre.1))
    }

    /// The image of (`x`, `y`).
    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        let m = &self.m;
        let w = m[2][0] * x + m[2][1] * y + m[2][2];
        (
            (m[0][0] * x + m[0][1] * y + m[0][2]) / w,
            (m[1][0] * x + m[1][1] * y + m[1][2]) / w,
        )
    }

    /// This warp followed by `next` (the matrix product `next * self`).
    ///
    /// ```
    /// use host_sim::synth::Homography;
    /// let h = Homography::translation(1.0, 0.0).then(&Homography::zoom(2.0, (0.0, 0.0)));
    /// assert_eq!(h.apply(1.0, 1.0), (4.0, 2.0));
    /// ```
    pub fn then(&self, next: &Self) -> Self {
        let (a, b) = (&next.m, &self.m);
        let mut m = [[0.0; 3]; 3];
        for (r, row) in m.iter_mut().enumerate() {
            for (c, value) in row.iter_mut().enumerate() {
                *value = (0..3).map(|k| a[r][k] * b[k][c]).sum();
            }
        }
        Self { m }
    }

    /// The inverse warp (adjugate over determinant); `None` when the matrix is singular.
    pub fn inverse(&self) -> Option<Self> {
        let m = &self.m;
        let cofactor = |r0: usize, r1: usize, c0: usize, c1: usize| {
            m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
        };
        // The adjugate is the transposed cofactor matrix.
        let adj = [
            [
                cofactor(1, 2, 1, 2),
                -cofactor(0, 2, 1, 2),
                cofactor(0, 1, 1, 2),
            ],
            [
                -cofactor(1, 2, 0, 2),
                cofactor(0, 2, 0, 2),
                -cofactor(0, 1, 0, 2),
            ],
            [
                cofactor(1, 2, 0, 1),
                -cofactor(0, 2, 0, 1),
                cofactor(0, 1, 0, 1),
            ],
        ];
        let det = m[0][0] * adj[0][0] + m[0][1] * adj[1][0] + m[0][2] * adj[2][0];
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        Some(Self {
            m: adj.map(|row| row.map(|v| v / det)),
        })
    }

    /// The largest distance between the images of the four corners of a `width` x `height`
    /// frame under the two warps: how far apart they are where it matters.
    pub fn distance(&self, other: &Self, width: f64, height: f64) -> f64 {
        let corners = [(0.0, 0.0), (width, 0.0), (0.0, height), (width, height)];
        corners
            .iter()
            .map(|&(x, y)| {
                let (a, b) = (self.apply(x, y), other.apply(x, y));
                (a.0 - b.0).hypot(a.1 - b.1)
            })
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::FRAC_PI_2;

    fn close(a: (f64, f64), b: (f64, f64)) -> bool {
        (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9
    }

    #[test]
    fn rotation_about_a_centre_keeps_the_centre() {
        let h = Homography::rotation(FRAC_PI_2, (10.0, 20.0));
        assert!(close(h.apply(10.0, 20.0), (10.0, 20.0)));
        // x turns towards y: one pixel right of the centre goes one pixel down.
        assert!(close(h.apply(11.0, 20.0), (10.0, 21.0)));
    }

    #[test]
    fn zoom_scales_distances_from_the_centre() {
        let h = Homography::zoom(1.5, (4.0, 4.0));
        assert!(close(h.apply(6.0, 2.0), (7.0, 1.0)));
    }

    #[test]
    fn composition_applies_in_order() {
        let shift = Homography::translation(3.0, -2.0);
        let turn = Homography::rotation(0.3, (50.0, 40.0));
        let both = shift.then(&turn);
        let (x, y) = shift.apply(17.0, 9.0);
        assert!(close(both.apply(17.0, 9.0), turn.apply(x, y)));
        let similarity = Homography::similarity(1.0, 0.3, (3.0, -2.0), (50.0, 40.0));
        assert!(similarity.distance(&turn.then(&shift), 100.0, 80.0) < 1e-9);
    }

    #[test]
    fn inverse_undoes_every_constructor() {
        let warps = [
            Homography::translation(7.5, -3.25),
            Homography::rotation(-0.1, (80.0, 60.0)),
            Homography::zoom(0.97, (80.0, 60.0)),
            Homography::similarity(1.04, 0.05, (2.0, 1.0), (80.0, 60.0)),
            Homography::perspective(2e-4, -1e-4, (80.0, 60.0)),
        ];
        for h in warps {
            let inverse = h.inverse().unwrap();
            assert!(
                h.then(&inverse)
                    .distance(&Homography::IDENTITY, 160.0, 120.0)
                    < 1e-9
            );
            assert!(
                inverse
                    .then(&h)
                    .distance(&Homography::IDENTITY, 160.0, 120.0)
                    < 1e-9
            );
            let (x, y) = h.apply(33.0, 44.0);
            assert!(close(inverse.apply(x, y), (33.0, 44.0)));
        }
        let singular = Homography {
            m: [[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]],
        };
        assert!(singular.inverse().is_none());
    }

    #[test]
    fn perspective_keeps_the_centre_and_bends_the_rest() {
        let h = Homography::perspective(1e-3, 0.0, (50.0, 50.0));
        assert!(close(h.apply(50.0, 50.0), (50.0, 50.0)));
        let (x, _) = h.apply(100.0, 50.0);
        // w = 1 + 1e-3 * 50: the point 50 px right of the centre comes 50 / 1.05 px from it.
        assert!((x - (50.0 + 50.0 / 1.05)).abs() < 1e-9);
    }
}
