//! 3x3 matrices for camera geometry: rotations from axis-angle vectors and the products that
//! turn them into homographies (applied by [`super::Homography`]), in `f64` so that ground
//! truth is exact to far below a pixel.
//!
//! ```
//! use host_sim::synth::rotation::{mul, rotation, transpose, IDENTITY};
//! let r = rotation([0.0, 0.0, std::f64::consts::FRAC_PI_2]);
//! // A quarter turn about z takes x to y (its first column is y), and its transpose undoes it.
//! assert!(r[0][0].abs() < 1e-12 && (r[1][0] - 1.0).abs() < 1e-12);
//! let back = mul(&transpose(&r), &r);
//! assert!((0..3).all(|i| (0..3).all(|j| (back[i][j] - IDENTITY[i][j]).abs() < 1e-12)));
//! ```

/// A 3x3 matrix, row by row.
pub type Mat3 = [[f64; 3]; 3];

/// The identity matrix.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The product `a b`.
pub fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// The transpose of `a`: the inverse of a rotation.
pub fn transpose(a: &Mat3) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// `exp([w]x)`: the right-handed rotation by `|w|` radians about `w` (Rodrigues' formula).
pub fn rotation(w: [f64; 3]) -> Mat3 {
    let angle = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    if angle == 0.0 {
        return IDENTITY;
    }
    let axis = w.map(|v| v / angle);
    let (s, c) = angle.sin_cos();
    let cross = [
        [0.0, -axis[2], axis[1]],
        [axis[2], 0.0, -axis[0]],
        [-axis[1], axis[0], 0.0],
    ];
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            c * f64::from(u8::from(i == j)) + s * cross[i][j] + (1.0 - c) * axis[i] * axis[j]
        })
    })
}
