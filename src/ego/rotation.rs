//! Gyro rotations over a frame interval, and the axes they are expressed in.

use super::linalg::sqrt;

/// The largest body rate accepted, rad/s (above the 2000 °/s full scale of common MEMS gyros).
///
/// ```
/// use kestrel::ego::{Rotation, MAX_BODY_RATE};
/// assert!(Rotation::from_body_rates([MAX_BODY_RATE, 0.0, 0.0], 1_000).is_ok());
/// assert!(Rotation::from_body_rates([MAX_BODY_RATE * 1.01, 0.0, 0.0], 1_000).is_err());
/// ```
pub const MAX_BODY_RATE: f32 = 40.0;

/// The largest rotation over one frame interval accepted, rad. Beyond it the two frames hardly
/// overlap with a typical lens.
///
/// ```
/// use kestrel::ego::{Rotation, MAX_ROTATION};
/// assert!(Rotation::from_vector([0.0, 0.0, MAX_ROTATION]).is_ok());
/// assert!(Rotation::from_vector([0.0, 0.0, MAX_ROTATION + 0.01]).is_err());
/// ```
pub const MAX_ROTATION: f32 = 1.0;

/// Why a gyro reading was rejected.
///
/// ```
/// use kestrel::ego::{GyroError, Rotation};
/// assert_eq!(Rotation::from_vector([f32::NAN, 0.0, 0.0]).unwrap_err(), GyroError::NotFinite);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GyroError {
    /// A component is NaN or infinite.
    NotFinite,
    /// A rate above [`MAX_BODY_RATE`], a rotation above [`MAX_ROTATION`], or a zero interval
    /// for an integrated reading.
    OutOfRange,
}

impl core::fmt::Display for GyroError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            GyroError::NotFinite => "gyro value is not finite",
            GyroError::OutOfRange => "gyro rate or rotation out of range",
        })
    }
}

/// Gyro rotations over a frame interval, and the axes they are expressed in.
///
/// # Axes
///
/// - **Pixels**: origin at the centre of the top-left pixel, x to the right, y down.
/// - **Camera frame** (OpenCV): x to the right of the image, y down the image, z forward along
///   the optical axis.
/// - **Sensor frame**: PX4's optical flow sensor frame, in which the gyro rates and every
///   OPTICAL_FLOW_RAD field are expressed. X points to the top of the image, Y to the right of
///   the image, Z along the optical axis. Mounted looking down with the top of the image
///   towards the nose (PX4's `SENS_FLOW_ROT` = 0), these are the vehicle's forward-right-down
///   body axes; other mountings are a yaw rotation for `SENS_FLOW_ROT`.
///
/// So camera `(x, y, z)` = sensor `(Y, -X, Z)`. Rotations are right-handed: a positive rate
/// about sensor X (roll right) swings the optical axis towards the left of the vehicle, and the
/// scene moves right in the image. That is why, in MAVLink's convention, a right-hand rotation
/// about X gives positive `integrated_x` and, under pure rotation, the angular flow equals the
/// integrated gyro.
///
/// ```
/// use kestrel::ego::Rotation;
/// // 20 ms of roll at 2 rad/s.
/// let r = Rotation::from_body_rates([2.0, 0.0, 0.0], 20_000).unwrap();
/// assert!((r.vector()[0] - 0.04).abs() < 1e-6);
/// ```
///
/// The sensor's rotation over one frame interval, from the gyro.
///
/// Holds the rotation vector in the sensor frame (right-handed, radians: the integrated gyro)
/// and the matching rotation matrix in the camera frame.
///
/// ```
/// use kestrel::ego::Rotation;
/// let r = Rotation::from_vector([0.01, -0.02, 0.005]).unwrap();
/// assert_eq!(r.vector(), [0.01, -0.02, 0.005]);
/// assert_eq!(Rotation::IDENTITY.vector(), [0.0; 3]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rotation {
    vector: [f32; 3],
    /// Row-major camera-frame matrix: new camera axes expressed in the old camera frame.
    camera: [f32; 9],
}

impl Rotation {
    /// No rotation.
    ///
    /// ```
    /// use kestrel::ego::Rotation;
    /// assert_eq!(Rotation::IDENTITY, Rotation::from_vector([0.0; 3]).unwrap());
    /// ```
    pub const IDENTITY: Self = Self {
        vector: [0.0; 3],
        camera: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    };

    /// A rotation from its rotation vector in the sensor frame, radians (axis x angle).
    ///
    /// ```
    /// use kestrel::ego::{GyroError, Rotation};
    /// assert!(Rotation::from_vector([0.0, 0.3, 0.0]).is_ok());
    /// assert_eq!(Rotation::from_vector([0.0, 2.0, 0.0]).unwrap_err(), GyroError::OutOfRange);
    /// ```
    pub fn from_vector(vector: [f32; 3]) -> Result<Self, GyroError> {
        if !vector.iter().all(|v| v.is_finite()) {
            return Err(GyroError::NotFinite);
        }
        let [x, y, z] = vector;
        let angle_sq = x * x + y * y + z * z;
        let small = angle_sq <= MAX_ROTATION * MAX_ROTATION;
        if !small {
            return Err(GyroError::OutOfRange);
        }
        Ok(Self {
            vector,
            camera: rodrigues([y, -x, z], angle_sq),
        })
    }

    /// The rotation of body rates (rad/s, sensor frame) held for `interval_us` microseconds.
    ///
    /// ```
    /// use kestrel::ego::{GyroError, Rotation};
    /// let r = Rotation::from_body_rates([0.0, 0.0, 1.0], 10_000).unwrap();
    /// assert!((r.vector()[2] - 0.01).abs() < 1e-7);
    /// let absurd = Rotation::from_body_rates([500.0, 0.0, 0.0], 10_000);
    /// assert_eq!(absurd.unwrap_err(), GyroError::OutOfRange);
    /// ```
    pub fn from_body_rates(rates: [f32; 3], interval_us: u32) -> Result<Self, GyroError> {
        check_rates(rates)?;
        let dt = interval_us as f32 * 1e-6;
        Self::from_vector(rates.map(|r| r * dt))
    }

    /// A rotation from the gyro integrated over `interval_us` microseconds (rad, sensor
    /// frame), checking that the mean rate is plausible as well.
    ///
    /// ```
    /// use kestrel::ego::{GyroError, Rotation};
    /// assert!(Rotation::from_integrated_gyro([0.02, 0.0, 0.0], 10_000).is_ok());
    /// // 0.5 rad in 10 ms is 50 rad/s.
    /// let fast = Rotation::from_integrated_gyro([0.5, 0.0, 0.0], 10_000);
    /// assert_eq!(fast.unwrap_err(), GyroError::OutOfRange);
    /// ```
    pub fn from_integrated_gyro(vector: [f32; 3], interval_us: u32) -> Result<Self, GyroError> {
        if !vector.iter().all(|v| v.is_finite()) {
            return Err(GyroError::NotFinite);
        }
        if interval_us == 0 {
            return Err(GyroError::OutOfRange);
        }
        let dt = interval_us as f32 * 1e-6;
        check_rates(vector.map(|v| v / dt))?;
        Self::from_vector(vector)
    }

    /// The rotation vector in the sensor frame, radians.
    ///
    /// ```
    /// use kestrel::ego::Rotation;
    /// assert_eq!(Rotation::from_vector([0.1, 0.0, 0.0]).unwrap().vector(), [0.1, 0.0, 0.0]);
    /// ```
    pub fn vector(&self) -> [f32; 3] {
        self.vector
    }

    /// The camera-frame matrix `R`, row-major: a static point's coordinates in the new camera
    /// frame are `Rᵀ p`.
    pub(super) fn camera_matrix(&self) -> &[f32; 9] {
        &self.camera
    }

    /// `Rᵀ v`: a ray of the previous camera frame in the new one.
    pub(super) fn in_new_frame(&self, v: [f32; 3]) -> [f32; 3] {
        let r = &self.camera;
        [
            r[0] * v[0] + r[3] * v[1] + r[6] * v[2],
            r[1] * v[0] + r[4] * v[1] + r[7] * v[2],
            r[2] * v[0] + r[5] * v[1] + r[8] * v[2],
        ]
    }
}

fn check_rates(rates: [f32; 3]) -> Result<(), GyroError> {
    if !rates.iter().all(|r| r.is_finite()) {
        return Err(GyroError::NotFinite);
    }
    if !rates.iter().all(|r| r.abs() <= MAX_BODY_RATE) {
        return Err(GyroError::OutOfRange);
    }
    Ok(())
}

/// `exp([w]x) = I + a [w]x + b [w]x²` with `a = sin θ / θ`, `b = (1 - cos θ) / θ²`.
fn rodrigues(w: [f32; 3], angle_sq: f32) -> [f32; 9] {
    let angle = sqrt(angle_sq);
    let (a, b) = if angle < 1e-4 {
        // Series: the closed forms divide by θ; the next terms are below 1e-9.
        (1.0 - angle_sq / 6.0, 0.5 - angle_sq / 24.0)
    } else {
        let half = sin_small(angle / 2.0);
        (sin_small(angle) / angle, 2.0 * half * half / angle_sq)
    };
    let [x, y, z] = w;
    // [w]x² = w wᵀ - θ² I.
    [
        1.0 + b * (x * x - angle_sq),
        -a * z + b * x * y,
        a * y + b * x * z,
        a * z + b * x * y,
        1.0 + b * (y * y - angle_sq),
        -a * x + b * y * z,
        -a * y + b * x * z,
        a * x + b * y * z,
        1.0 + b * (z * z - angle_sq),
    ]
}

/// `sin x` for `|x| <= MAX_ROTATION` (1 rad) by its Taylor series to `x¹¹`: the first term
/// left out is below 2e-10. It spares `libm::sinf`'s argument reduction for huge angles, which
/// costs kilobytes of flash and a 760-byte stack frame on the Cortex-M4.
fn sin_small(x: f32) -> f32 {
    let x2 = x * x;
    x * (1.0
        - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0 * (1.0 - x2 / 110.0)))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_series_sine_matches_libm() {
        for i in -100..=100 {
            let x = i as f32 * MAX_ROTATION / 100.0;
            assert!((sin_small(x) - libm::sinf(x)).abs() <= 1.2e-7, "{x}");
        }
    }

    #[test]
    fn rotation_matrices_are_orthonormal() {
        for v in [[0.3, -0.2, 0.5], [1e-6, 0.0, -2e-6], [0.0, 0.0, 0.9]] {
            let r = Rotation::from_vector(v).unwrap();
            let m = r.camera_matrix();
            for i in 0..3 {
                for j in 0..3 {
                    let dot: f32 = (0..3).map(|k| m[i * 3 + k] * m[j * 3 + k]).sum();
                    let expected = if i == j { 1.0 } else { 0.0 };
                    assert!((dot - expected).abs() < 1e-6, "{v:?} {i} {j} {dot}");
                }
            }
        }
    }

    #[test]
    fn roll_swings_the_optical_axis_to_the_left() {
        // A right-hand roll (about sensor X = image up) moves the optical axis towards sensor
        // -Y = image left: the scene point ahead appears to the right.
        let r = Rotation::from_vector([0.1, 0.0, 0.0]).unwrap();
        let ahead = r.in_new_frame([0.0, 0.0, 1.0]);
        assert!(
            (ahead[0] / ahead[2] - libm::tanf(0.1)).abs() < 1e-6,
            "{ahead:?}"
        );
        assert!(ahead[1].abs() < 1e-7);
    }

    #[test]
    fn rejects_bad_readings() {
        assert_eq!(
            Rotation::from_body_rates([0.0, f32::INFINITY, 0.0], 1000),
            Err(GyroError::NotFinite)
        );
        assert_eq!(
            Rotation::from_integrated_gyro([0.0; 3], 0),
            Err(GyroError::OutOfRange)
        );
        assert_eq!(
            Rotation::from_body_rates([39.0, 39.0, 39.0], 100_000),
            Err(GyroError::OutOfRange)
        );
    }
}
