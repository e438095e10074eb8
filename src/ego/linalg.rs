//! Small dense linear algebra for the motion fits: `f32`, fixed sizes, no allocation.
//!
//! `core` has no float square root or transcendental functions on stable Rust; they come from
//! `libm` (a port of musl's, correctly rounded `sqrtf` and sub-ulp `atanf`, `sinf`, `logf`), so
//! results are the same bit for bit on the host and on the flight controller.

/// A pivot smaller than this fraction of the largest matrix entry makes the system singular.
const SINGULAR_PIVOT: f32 = 1e-6;

/// Square root, correctly rounded; NaN for negative input, so callers check their arguments.
pub(super) fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// Solves `a x = b` by Gaussian elimination with partial pivoting.
///
/// `None` when the matrix is singular at `f32` precision (a pivot below [`SINGULAR_PIVOT`] of
/// the largest entry) or the solution is not finite.
// Every index is a loop variable below the arrays' const size N.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
// Out of line: the four-point and least-squares homography fits share one copy.
#[inline(never)]
pub(super) fn solve<const N: usize>(mut a: [[f32; N]; N], mut b: [f32; N]) -> Option<[f32; N]> {
    let largest = a.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
    if !(largest > 0.0 && largest.is_finite()) {
        return None;
    }
    let tiny = largest * SINGULAR_PIVOT;
    for col in 0..N {
        let mut pivot_row = col;
        for row in col + 1..N {
            if a[row][col].abs() > a[pivot_row][col].abs() {
                pivot_row = row;
            }
        }
        // False for NaN too.
        let usable = a[pivot_row][col].abs() > tiny;
        if !usable {
            return None;
        }
        a.swap(col, pivot_row);
        b.swap(col, pivot_row);
        let pivot = a[col];
        for row in col + 1..N {
            let factor = a[row][col] / pivot[col];
            if factor == 0.0 {
                continue;
            }
            for (entry, p) in a[row].iter_mut().zip(pivot.iter()).skip(col) {
                *entry -= factor * p;
            }
            b[row] -= factor * b[col];
        }
    }
    let mut x = [0.0f32; N];
    for row in (0..N).rev() {
        let mut sum = b[row];
        for col in row + 1..N {
            sum -= a[row][col] * x[col];
        }
        x[row] = sum / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The product of two row-major 3 x 3 matrices.
// `i < 9` and `k < 3`: every index is below 9.
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
pub(super) fn mul3(a: &[f32; 9], b: &[f32; 9]) -> [f32; 9] {
    core::array::from_fn(|i| {
        let (row, col) = (i / 3, i % 3);
        (0..3).map(|k| a[row * 3 + k] * b[k * 3 + col]).sum()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_pivoting_system() {
        // The first pivot is zero: only partial pivoting gets through.
        let a = [[0.0, 2.0, 1.0], [1.0, 1.0, 0.0], [3.0, 0.0, 1.0]];
        let x = solve(a, [5.0, 3.0, 6.0]).unwrap();
        let expected = [1.4, 1.6, 1.8];
        for (v, e) in x.iter().zip(expected) {
            assert!((v - e).abs() < 1e-5, "{x:?}");
        }
    }

    #[test]
    fn rejects_singular_and_non_finite_systems() {
        let singular = [[1.0, 2.0], [2.0, 4.0]];
        assert_eq!(solve(singular, [1.0, 2.0]), None);
        assert_eq!(solve([[0.0; 2]; 2], [0.0; 2]), None);
        assert_eq!(solve([[f32::NAN, 0.0], [0.0, 1.0]], [1.0, 1.0]), None);
        assert_eq!(solve([[1.0, 0.0], [0.0, 1.0]], [f32::INFINITY, 1.0]), None);
    }

    #[test]
    fn multiplies_matrices() {
        let a = [1.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let b = [1.0, 0.0, 3.0, 0.0, 1.0, 4.0, 0.0, 0.0, 1.0];
        assert_eq!(mul3(&a, &b), [1.0, 2.0, 11.0, 0.0, 1.0, 4.0, 0.0, 0.0, 1.0]);
    }
}
