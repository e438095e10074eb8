//! Pinhole camera with radial distortion, and gyro derotation.

use super::model::{to_point, Homography, MAX_COORDINATE};
use super::rotation::Rotation;
use crate::q16::Point;
use crate::{Bound, ConfigError};

/// The focal length range accepted, pixels.
///
/// ```
/// use kestrel::ego::FOCAL_RANGE;
/// assert!(FOCAL_RANGE.contains(&138.6) && !FOCAL_RANGE.contains(&0.0));
/// ```
pub const FOCAL_RANGE: core::ops::RangeInclusive<f32> = 1.0..=100_000.0;

/// The largest distortion coefficient magnitude accepted.
///
/// ```
/// use kestrel::ego::MAX_DISTORTION;
/// use kestrel::ego::{Camera, CameraParams};
/// use kestrel::{Bound, ConfigError};
/// let p = CameraParams { k2: -2.0 * MAX_DISTORTION, ..CameraParams::from_horizontal_fov(64, 48, 1.0) };
/// assert_eq!(Camera::new(p).unwrap_err(), ConfigError { field: "k2", bound: Bound::Within(10) });
/// ```
pub const MAX_DISTORTION: f32 = 10.0;

/// Fixed-point iterations allowed to undistort a point.
const UNDISTORT_ITERATIONS: usize = 30;
/// Undistortion converges when a step is below this, pixels; a round trip must land within
/// ten times this of the distorted point.
const UNDISTORT_TOLERANCE: f32 = 1e-4;
/// The distortion factor must stay above this: below it the lens model folds over.
const MIN_DISTORTION_FACTOR: f32 = 0.05;
/// Rays at less than this depth (per unit lateral offset) are treated as leaving the view.
const MIN_DEPTH: f32 = 1e-3;

/// Camera intrinsics, pixels.
///
/// ```
/// use kestrel::ego::CameraParams;
/// let p = CameraParams::from_horizontal_fov(320, 240, core::f32::consts::FRAC_PI_2);
/// assert!((p.focal_x - 160.0).abs() < 1e-3 && p.focal_x == p.focal_y);
/// assert_eq!((p.principal_x, p.principal_y), (159.5, 119.5));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CameraParams {
    /// Horizontal focal length, pixels, within [`FOCAL_RANGE`].
    pub focal_x: f32,
    /// Vertical focal length, pixels, within [`FOCAL_RANGE`].
    pub focal_y: f32,
    /// Principal point, pixels from the top-left pixel centre.
    pub principal_x: f32,
    /// Principal point, pixels from the top-left pixel centre.
    pub principal_y: f32,
    /// Second-order radial distortion (0 for none), magnitude at most [`MAX_DISTORTION`].
    pub k1: f32,
    /// Fourth-order radial distortion (0 for none), magnitude at most [`MAX_DISTORTION`].
    pub k2: f32,
}

impl CameraParams {
    /// An undistorted camera with square pixels, the principal point at the image centre and
    /// the given horizontal field of view (radians, between pixel edges).
    ///
    /// ```
    /// use kestrel::ego::CameraParams;
    /// // The host simulator's default: 60 degrees across 160 px.
    /// let p = CameraParams::from_horizontal_fov(160, 120, 60f32.to_radians());
    /// assert!((p.focal_x - 138.564).abs() < 1e-3);
    /// ```
    pub fn from_horizontal_fov(width: u16, height: u16, fov: f32) -> Self {
        let focal = f32::from(width) / 2.0 / libm::tanf(fov / 2.0);
        Self {
            focal_x: focal,
            focal_y: focal,
            principal_x: (f32::from(width) - 1.0) / 2.0,
            principal_y: (f32::from(height) - 1.0) / 2.0,
            k1: 0.0,
            k2: 0.0,
        }
    }
}

/// [`FOCAL_RANGE`], [`MAX_COORDINATE`] and [`MAX_DISTORTION`] as the bounds a refusal names
/// (checked against them in the tests).
const FOCAL_BOUND: Bound = Bound::Range {
    min: 1,
    max: 100_000,
};
const PRINCIPAL_BOUND: Bound = Bound::Within(65_536);
const DISTORTION_BOUND: Bound = Bound::Within(10);

/// Why a camera call could not run (refused parameters are [`Camera::new`]'s
/// [`ConfigError`]).
///
/// ```
/// use kestrel::ego::{Camera, CameraError, CameraParams, Rotation};
/// use kestrel::Point;
/// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 64, 1.0)).unwrap();
/// let r = Rotation::from_vector([0.0, 0.0, 0.01]).unwrap();
/// let refused = camera.predict_points(&r, &[Point::default(); 2], &mut [Point::default(); 1]);
/// assert_eq!(refused, Err(CameraError::LengthMismatch));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CameraError {
    /// Point and output slices differ in length.
    LengthMismatch,
}

impl core::fmt::Display for CameraError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CameraError::LengthMismatch => "points and outputs differ in length",
        })
    }
}

/// Pinhole camera with radial distortion, and gyro derotation.
///
/// Intrinsics follow OpenCV: focal lengths `fx`, `fy` and principal point `(cx, cy)` in
/// pixels, radial distortion `x_d = x_u (1 + k1 r² + k2 r⁴)` on normalised coordinates. Axes
/// and rotation signs are described in [`Rotation`](super::Rotation).
///
/// Pure rotation moves every pixel by the infinite homography `H = K Rᵀ K⁻¹`, whatever the
/// depth, so a gyro reading predicts where each point goes: a good initial guess for LK in fast
/// turns, and the rotational flow to remove before the remaining flow says how the camera
/// translated.
///
/// ```
/// use kestrel::ego::{Camera, CameraParams, Rotation};
/// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0472)).unwrap();
/// // 10 ms of pitching up at 3 rad/s: the scene slides down the image by about 4 px.
/// let r = Rotation::from_body_rates([0.0, 3.0, 0.0], 10_000).unwrap();
/// let (x, y) = camera.predict(&r, (79.5, 59.5)).unwrap();
/// assert!((x - 79.5).abs() < 1e-3 && (y - 63.66).abs() < 0.01);
/// ```
///
/// A validated pinhole camera.
///
/// ```
/// use kestrel::ego::{Camera, CameraParams};
/// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
/// assert_eq!(camera.undistort((12.0, 34.0)), Some((12.0, 34.0)));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Camera {
    params: CameraParams,
}

impl Camera {
    /// Validates `params`: focal lengths within [`FOCAL_RANGE`], a principal point within
    /// [`MAX_COORDINATE`] and distortion coefficients within [`MAX_DISTORTION`] of 0, NaN
    /// refused; a refusal names the field (`"focal_x"`, `"principal_y"`, `"k1"`, ...).
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams};
    /// use kestrel::{Bound, ConfigError};
    /// let good = CameraParams::from_horizontal_fov(160, 120, 1.0);
    /// assert!(Camera::new(good).is_ok());
    /// let nan = CameraParams { k1: f32::NAN, ..good };
    /// assert_eq!(Camera::new(nan).unwrap_err(), ConfigError { field: "k1", bound: Bound::Within(10) });
    /// let flat = CameraParams { focal_y: 0.0, ..good };
    /// assert_eq!(Camera::new(flat).unwrap_err().to_string(), "focal_y must be 1 to 100000");
    /// ```
    pub fn new(params: CameraParams) -> Result<Self, ConfigError> {
        let focal = [("focal_x", params.focal_x), ("focal_y", params.focal_y)];
        for (field, focal) in focal {
            if !FOCAL_RANGE.contains(&focal) {
                return Err(ConfigError::new(field, FOCAL_BOUND));
            }
        }
        let principal = [
            ("principal_x", params.principal_x),
            ("principal_y", params.principal_y),
        ];
        // NaN is within no limit.
        let within = |v: f32, limit: f32| v.abs() <= limit;
        for (field, v) in principal {
            if !within(v, MAX_COORDINATE) {
                return Err(ConfigError::new(field, PRINCIPAL_BOUND));
            }
        }
        for (field, k) in [("k1", params.k1), ("k2", params.k2)] {
            if !within(k, MAX_DISTORTION) {
                return Err(ConfigError::new(field, DISTORTION_BOUND));
            }
        }
        Ok(Self { params })
    }

    /// The parameters this camera was built with.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 48, 1.0)).unwrap();
    /// assert_eq!(camera.params().principal_x, 31.5);
    /// ```
    pub fn params(&self) -> &CameraParams {
        &self.params
    }

    /// The pixel an ideal (distortion-free) lens would have seen the point at. `None` when the
    /// iteration does not converge (beyond the lens model's fold) or leaves the coordinate range.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams};
    /// let p = CameraParams { k1: -0.2, k2: 0.05, ..CameraParams::from_horizontal_fov(160, 120, 1.0) };
    /// let camera = Camera::new(p).unwrap();
    /// let ideal = camera.undistort((10.0, 15.0)).unwrap();
    /// let (x, y) = camera.distort(ideal).unwrap();
    /// assert!((x - 10.0).abs() < 1e-3 && (y - 15.0).abs() < 1e-3);
    /// ```
    pub fn undistort(&self, pixel: (f32, f32)) -> Option<(f32, f32)> {
        if !self.has_distortion() {
            return in_range(pixel);
        }
        let distorted = self.normalised(pixel);
        let focal = self.params.focal_x.max(self.params.focal_y);
        let tolerance = UNDISTORT_TOLERANCE / focal;
        let mut ideal = distorted;
        for _ in 0..UNDISTORT_ITERATIONS {
            let factor = self.distortion_factor(ideal)?;
            let next = (distorted.0 / factor, distorted.1 / factor);
            let step = (next.0 - ideal.0).abs().max((next.1 - ideal.1).abs());
            ideal = next;
            if step <= tolerance {
                break;
            }
        }
        // A fixed point of the iteration, not just its last step.
        let factor = self.distortion_factor(ideal)?;
        let error = (ideal.0 * factor - distorted.0)
            .abs()
            .max((ideal.1 * factor - distorted.1).abs());
        let converged = error <= 10.0 * tolerance;
        if !converged {
            return None;
        }
        in_range(self.pixel(ideal))
    }

    /// The pixel the lens actually images an ideal pixel at (the inverse of
    /// [`Camera::undistort`]). `None` where the lens model folds over or out of range.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(64, 48, 1.0)).unwrap();
    /// assert_eq!(camera.distort((3.0, 4.0)), Some((3.0, 4.0)));
    /// ```
    pub fn distort(&self, pixel: (f32, f32)) -> Option<(f32, f32)> {
        if !self.has_distortion() {
            return in_range(pixel);
        }
        let ideal = self.normalised(pixel);
        let factor = self.distortion_factor(ideal)?;
        in_range(self.pixel((ideal.0 * factor, ideal.1 * factor)))
    }

    /// The homography `K Rᵀ K⁻¹` by which a rotation moves ideal (undistorted) pixels. `None`
    /// when it cannot be scaled to `h33 = 1` (the top-left pixel's ray turned onto the horizon).
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, Rotation};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
    /// let r = Rotation::from_vector([0.02, -0.01, 0.03]).unwrap();
    /// let h = camera.rotation_homography(&r).unwrap();
    /// let (a, b) = (h.apply((20.0, 30.0)).unwrap(), camera.predict(&r, (20.0, 30.0)).unwrap());
    /// assert!((a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3);
    /// ```
    pub fn rotation_homography(&self, rotation: &Rotation) -> Option<Homography> {
        let p = &self.params;
        let k = [
            p.focal_x,
            0.0,
            p.principal_x,
            0.0,
            p.focal_y,
            p.principal_y,
            0.0,
            0.0,
            1.0,
        ];
        let (ix, iy) = (1.0 / p.focal_x, 1.0 / p.focal_y);
        let k_inv = [
            ix,
            0.0,
            -p.principal_x * ix,
            0.0,
            iy,
            -p.principal_y * iy,
            0.0,
            0.0,
            1.0,
        ];
        let r = rotation.camera_matrix();
        let r_t = [r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8]];
        let product = super::linalg::mul3(&super::linalg::mul3(&k, &r_t), &k_inv);
        Homography::from_matrix(product)
    }

    /// Where a static point seen at `pixel` appears after the camera rotated by `rotation`,
    /// lens distortion included. `None` when the point leaves the field of view's hemisphere
    /// or the lens model.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, Rotation};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
    /// // Yaw turns the image about the principal point.
    /// let r = Rotation::from_vector([0.0, 0.0, 0.1]).unwrap();
    /// let (x, y) = camera.predict(&r, (79.5, 59.5)).unwrap();
    /// assert!((x - 79.5).abs() < 1e-4 && (y - 59.5).abs() < 1e-4);
    /// ```
    pub fn predict(&self, rotation: &Rotation, pixel: (f32, f32)) -> Option<(f32, f32)> {
        let (x, y) = self.normalised(self.undistort(pixel)?);
        let [u, v, w] = rotation.in_new_frame([x, y, 1.0]);
        // In front of the camera, and not so oblique that the projection blows up.
        let in_view = w > MIN_DEPTH * (1.0 + u.abs() + v.abs());
        if !in_view {
            return None;
        }
        self.distort(self.pixel((u / w, v / w)))
    }

    /// Predicted positions for a batch of points, for use as LK initial guesses
    /// ([`crate::lk::LucasKanade::track_points`]). A point whose prediction fails keeps its own
    /// position as the guess.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, Rotation};
    /// use kestrel::Point;
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
    /// let r = Rotation::from_vector([0.05, 0.0, 0.0]).unwrap();
    /// let points = [Point::from_f32(79.5, 59.5)];
    /// let mut guesses = [Point::default(); 1];
    /// camera.predict_points(&r, &points, &mut guesses).unwrap();
    /// assert!(guesses[0].to_f32().0 > 86.0);
    /// ```
    pub fn predict_points(
        &self,
        rotation: &Rotation,
        points: &[Point],
        guesses: &mut [Point],
    ) -> Result<(), CameraError> {
        if points.len() != guesses.len() {
            return Err(CameraError::LengthMismatch);
        }
        for (point, guess) in points.iter().zip(guesses.iter_mut()) {
            *guess = self
                .predict(rotation, point.to_f32())
                .and_then(to_point)
                .unwrap_or(*point);
        }
        Ok(())
    }

    /// The flow of a track with the rotation removed: `next` minus where rotation alone would
    /// have taken `prev`, pixels. It is what the camera's translation caused (plus noise).
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, Rotation};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
    /// let r = Rotation::from_vector([0.03, 0.0, 0.0]).unwrap();
    /// let next = camera.predict(&r, (40.0, 30.0)).unwrap();
    /// let (dx, dy) = camera.derotated_flow(&r, (40.0, 30.0), next).unwrap();
    /// assert!(dx.abs() < 1e-5 && dy.abs() < 1e-5);
    /// ```
    pub fn derotated_flow(
        &self,
        rotation: &Rotation,
        prev: (f32, f32),
        next: (f32, f32),
    ) -> Option<(f32, f32)> {
        let (px, py) = self.predict(rotation, prev)?;
        let flow = (next.0 - px, next.1 - py);
        (flow.0.is_finite() && flow.1.is_finite()).then_some(flow)
    }

    /// The angular flow (rad) that a frame-to-frame motion shows at the principal point, about
    /// the sensor X and Y axes with MAVLink's signs: the OPTICAL_FLOW_RAD `integrated_x` and
    /// `integrated_y` increments. Under pure rotation about X or Y it equals the rotation angle.
    ///
    /// ```
    /// use kestrel::ego::{Camera, CameraParams, Rotation};
    /// let camera = Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).unwrap();
    /// let r = Rotation::from_vector([0.02, 0.0, 0.0]).unwrap();
    /// let h = camera.rotation_homography(&r).unwrap();
    /// let (x, y) = camera.angular_flow(&h).unwrap();
    /// assert!((x - 0.02).abs() < 1e-6 && y.abs() < 1e-6);
    /// ```
    pub fn angular_flow(&self, motion: &Homography) -> Option<(f32, f32)> {
        let p = &self.params;
        let (x, y) = motion.apply((p.principal_x, p.principal_y))?;
        // Image x is sensor Y and image y is sensor -X: a shift to the right is a rotation
        // about +X, a shift down one about +Y.
        let about_x = libm::atanf((x - p.principal_x) / p.focal_x);
        let about_y = libm::atanf((y - p.principal_y) / p.focal_y);
        (about_x.is_finite() && about_y.is_finite()).then_some((about_x, about_y))
    }

    fn has_distortion(&self) -> bool {
        self.params.k1 != 0.0 || self.params.k2 != 0.0
    }

    /// `1 + k1 r² + k2 r⁴`, `None` where the lens model folds over.
    fn distortion_factor(&self, (x, y): (f32, f32)) -> Option<f32> {
        let r2 = x * x + y * y;
        let factor = 1.0 + self.params.k1 * r2 + self.params.k2 * r2 * r2;
        (factor > MIN_DISTORTION_FACTOR && factor.is_finite()).then_some(factor)
    }

    fn normalised(&self, (x, y): (f32, f32)) -> (f32, f32) {
        let p = &self.params;
        (
            (x - p.principal_x) / p.focal_x,
            (y - p.principal_y) / p.focal_y,
        )
    }

    fn pixel(&self, (x, y): (f32, f32)) -> (f32, f32) {
        let p = &self.params;
        (x * p.focal_x + p.principal_x, y * p.focal_y + p.principal_y)
    }
}

/// The pixel if it is within [`MAX_COORDINATE`] (false for NaN).
fn in_range(pixel: (f32, f32)) -> Option<(f32, f32)> {
    (pixel.0.abs() <= MAX_COORDINATE && pixel.1.abs() <= MAX_COORDINATE).then_some(pixel)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(k1: f32, k2: f32) -> Camera {
        let p = CameraParams::from_horizontal_fov(320, 240, 1.2);
        Camera::new(CameraParams { k1, k2, ..p }).unwrap()
    }

    #[test]
    fn refusals_name_the_limits_the_checks_use() {
        assert_eq!(
            FOCAL_BOUND,
            Bound::Range {
                min: *FOCAL_RANGE.start() as u32,
                max: *FOCAL_RANGE.end() as u32
            }
        );
        assert_eq!(PRINCIPAL_BOUND, Bound::Within(MAX_COORDINATE as u32));
        assert_eq!(DISTORTION_BOUND, Bound::Within(MAX_DISTORTION as u32));
        let good = CameraParams::from_horizontal_fov(64, 48, 1.0);
        let far = CameraParams {
            principal_y: f32::INFINITY,
            ..good
        };
        assert_eq!(
            Camera::new(far).unwrap_err(),
            ConfigError::new("principal_y", PRINCIPAL_BOUND)
        );
    }

    #[test]
    fn undistortion_inverts_distortion_across_the_frame() {
        for (k1, k2) in [(-0.3, 0.1), (0.2, 0.0), (-0.1, -0.02)] {
            let cam = camera(k1, k2);
            for (x, y) in [(0.0, 0.0), (319.0, 239.0), (160.0, 10.0), (5.0, 120.0)] {
                let ideal = cam.undistort((x, y)).unwrap();
                let (u, v) = cam.distort(ideal).unwrap();
                assert!(
                    (u - x).abs() < 2e-3 && (v - y).abs() < 2e-3,
                    "{k1} {k2} {x} {y}"
                );
            }
        }
    }

    #[test]
    fn prediction_follows_the_sign_conventions() {
        let cam = camera(0.0, 0.0);
        let centre = (cam.params.principal_x, cam.params.principal_y);
        let moved = |v| {
            cam.predict(&Rotation::from_vector(v).unwrap(), centre)
                .unwrap()
        };
        // Roll right: scene moves right. Pitch up: scene moves down.
        assert!(moved([0.05, 0.0, 0.0]).0 > centre.0 + 5.0);
        assert!(moved([0.0, 0.05, 0.0]).1 > centre.1 + 5.0);
        // Yaw right (clockwise seen from above, camera looking down): the image turns
        // counter-clockwise about the principal point, so a point right of it moves up.
        let r = Rotation::from_vector([0.0, 0.0, 0.1]).unwrap();
        let right = cam.predict(&r, (centre.0 + 50.0, centre.1)).unwrap();
        assert!(right.1 < centre.1 - 4.0, "{right:?}");
    }

    #[test]
    fn points_turned_behind_the_camera_have_no_prediction() {
        let cam = camera(0.0, 0.0);
        // Pitching down swings the optical axis backwards, away from the image top: a ray 63
        // degrees towards the image top ends 120 degrees off-axis.
        let r = Rotation::from_vector([0.0, -1.0, 0.0]).unwrap();
        let top = (
            cam.params.principal_x,
            cam.params.principal_y - 2.0 * cam.params.focal_y,
        );
        assert_eq!(cam.predict(&r, top), None);
    }
}
