//! Motion models fitted to point correspondences, all reported as a [`Homography`].

use super::linalg::{mul3, solve, sqrt};
use crate::q16::Point;

/// The largest coordinate magnitude accepted, in pixels (twice the Q16 range).
///
/// ```
/// use kestrel::ego::{fit, FitError, ModelKind, MAX_COORDINATE};
/// let far = [((MAX_COORDINATE * 2.0, 0.0), (0.0, 0.0))];
/// assert_eq!(fit(ModelKind::Translation, &far), Err(FitError::BadInput));
/// ```
pub const MAX_COORDINATE: f32 = 65_536.0;

/// Points closer than this to their centroid (RMS, pixels) determine no rotation or scale.
const MIN_SPREAD: f32 = 1e-2;
/// `4 det(S) / trace(S)²` of the points' scatter matrix `S` (1 for an isotropic cloud, 0 for a
/// line) below which the points count as collinear: a strip thinner than about 1% of its length.
const MIN_ISOTROPY: f32 = 4e-4;
/// A triangle whose height is below this fraction of its longest side counts as a line.
const MIN_TRIANGLE_HEIGHT: f32 = 1e-2;
/// A determinant smaller than this fraction of the terms it is summed from is lost in
/// cancellation: the matrix is singular at `f32` precision.
const MIN_DETERMINANT: f32 = 1e-5;
/// Homogeneous scale below which a point is taken to be on the horizon line.
const MIN_W: f32 = 1e-6;

/// A feature's position in the previous frame and in the next one, in pixels.
///
/// Implemented for `(Point, Point)` (tracker output) and `((f32, f32), (f32, f32))`.
///
/// ```
/// use kestrel::ego::Correspondence;
/// use kestrel::Point;
/// let track = (Point::from_f32(1.5, 2.0), Point::from_f32(3.0, 4.25));
/// assert_eq!(track.positions(), ((1.5, 2.0), (3.0, 4.25)));
/// assert_eq!(((1.0, 2.0), (3.0, 4.0)).positions(), ((1.0, 2.0), (3.0, 4.0)));
/// ```
pub trait Correspondence {
    /// `(previous, next)` positions as `(x, y)` pixels.
    fn positions(&self) -> ((f32, f32), (f32, f32));
}

impl Correspondence for (Point, Point) {
    fn positions(&self) -> ((f32, f32), (f32, f32)) {
        (self.0.to_f32(), self.1.to_f32())
    }
}

impl Correspondence for ((f32, f32), (f32, f32)) {
    fn positions(&self) -> ((f32, f32), (f32, f32)) {
        *self
    }
}

/// Which motion model to fit.
///
/// A model fits only the motions it can express: a shift cannot turn.
///
/// ```
/// use kestrel::ego::{fit, ModelKind};
/// // Four corners of a square turned by 0.1 rad about the origin.
/// let turn = |(x, y): (f32, f32)| {
///     let (s, c) = (0.1f32.sin(), 0.1f32.cos());
///     (c * x - s * y, s * x + c * y)
/// };
/// let pairs = [(0.0, 0.0), (40.0, 0.0), (0.0, 40.0), (40.0, 40.0)].map(|p| (p, turn(p)));
/// // How far each fitted model puts the far corner from where it went, px.
/// let miss = |kind| {
///     let (x, y) = fit(kind, &pairs).unwrap().apply((40.0, 40.0)).unwrap();
///     let (tx, ty) = turn((40.0, 40.0));
///     ((x - tx).powi(2) + (y - ty).powi(2)).sqrt()
/// };
/// assert!(miss(ModelKind::Translation) > 2.0);
/// assert!(miss(ModelKind::Similarity) < 1e-3);
/// assert!(miss(ModelKind::Homography) < 1e-3);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ModelKind {
    /// Image shift (2 degrees of freedom): a downward camera translating at constant height.
    Translation,
    /// Shift, rotation and uniform scale (4): adds yaw and climb.
    Similarity,
    /// General linear map and shift (6): adds shear, a first-order tilt.
    Affine,
    /// Full projective map of a plane (8): any camera motion over flat ground, or pure rotation.
    #[default]
    Homography,
}

impl ModelKind {
    /// The number of correspondences that determine the model exactly.
    ///
    /// ```
    /// use kestrel::ego::ModelKind;
    /// assert_eq!(ModelKind::Homography.min_samples(), 4);
    /// ```
    pub const fn min_samples(self) -> usize {
        match self {
            ModelKind::Translation => 1,
            ModelKind::Similarity => 2,
            ModelKind::Affine => 3,
            ModelKind::Homography => 4,
        }
    }

    /// Degrees of freedom: twice [`ModelKind::min_samples`].
    ///
    /// ```
    /// use kestrel::ego::ModelKind;
    /// assert_eq!(ModelKind::Similarity.degrees_of_freedom(), 4);
    /// ```
    pub const fn degrees_of_freedom(self) -> usize {
        self.min_samples().saturating_mul(2)
    }
}

/// Why a model could not be fitted.
///
/// ```
/// use kestrel::ego::{fit, FitError, ModelKind};
/// let one = [((0.0, 0.0), (1.0, 1.0))];
/// assert_eq!(fit(ModelKind::Affine, &one), Err(FitError::TooFewPoints));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FitError {
    /// Fewer correspondences than [`ModelKind::min_samples`].
    TooFewPoints,
    /// The points do not determine the model: coincident, collinear, or a singular system.
    Degenerate,
    /// A coordinate is NaN, infinite or beyond [`MAX_COORDINATE`].
    BadInput,
}

impl core::fmt::Display for FitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FitError::TooFewPoints => "too few correspondences for the model",
            FitError::Degenerate => "correspondences do not determine the model",
            FitError::BadInput => "a coordinate is not finite or out of range",
        })
    }
}

/// A plane projective map `p' ~ H p`, row-major 3 x 3 with `h33 = 1`, always finite.
///
/// Every motion model is reported in this form. Points are `(x, y)` pixels with the origin at
/// the centre of the top-left pixel. A homography maps the side of its horizon line that holds
/// the origin; points on or beyond the horizon have no image (`apply` returns `None`).
///
/// ```
/// use kestrel::ego::Homography;
/// let shift = Homography::translation(3.0, -2.0).unwrap();
/// assert_eq!(shift.apply((1.0, 1.0)), Some((4.0, -1.0)));
/// let back = shift.inverse().unwrap();
/// assert_eq!(back.compose(&shift).unwrap(), Homography::IDENTITY);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Homography {
    m: [f32; 9],
}

impl Default for Homography {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Homography {
    /// The identity map.
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// assert_eq!(Homography::IDENTITY.apply((5.0, 7.0)), Some((5.0, 7.0)));
    /// ```
    pub const IDENTITY: Self = Self {
        m: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    };

    /// A homography from a row-major 3 x 3 matrix, scaled so that `h33 = 1`.
    ///
    /// `None` when an entry is not finite or `h33` is zero (relative to the largest entry).
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// let h = Homography::from_matrix([2.0, 0.0, 4.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0]).unwrap();
    /// assert_eq!(h.matrix(), [1.0, 0.0, 2.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    /// assert!(Homography::from_matrix([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0]).is_none());
    /// assert!(Homography::from_matrix([f32::NAN; 9]).is_none());
    /// ```
    pub fn from_matrix(m: [f32; 9]) -> Option<Self> {
        let largest = m.iter().fold(0.0f32, |a, v| a.max(v.abs()));
        let h33 = m[8];
        let scalable = h33.abs() > largest * f32::EPSILON;
        if !largest.is_finite() || !scalable {
            return None;
        }
        let mut scaled = m.map(|v| v / h33);
        scaled[8] = 1.0;
        scaled
            .iter()
            .all(|v| v.is_finite())
            .then_some(Self { m: scaled })
    }

    /// A pure image shift by `(dx, dy)` pixels; `None` unless both are finite.
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// assert_eq!(Homography::translation(1.0, 2.0).unwrap().apply((0.0, 0.0)), Some((1.0, 2.0)));
    /// assert!(Homography::translation(f32::INFINITY, 0.0).is_none());
    /// ```
    pub fn translation(dx: f32, dy: f32) -> Option<Self> {
        Self::from_matrix([1.0, 0.0, dx, 0.0, 1.0, dy, 0.0, 0.0, 1.0])
    }

    /// The row-major matrix, `h33 = 1`.
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// assert_eq!(Homography::IDENTITY.matrix()[4], 1.0);
    /// ```
    pub fn matrix(&self) -> [f32; 9] {
        self.m
    }

    /// Maps a point. `None` when it lies on or beyond the horizon line, or its image is not a
    /// finite `f32`.
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// // Perspective: the line x = -1000 is the horizon.
    /// let h = Homography::from_matrix([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.001, 0.0, 1.0]).unwrap();
    /// assert_eq!(h.apply((1000.0, 0.0)), Some((500.0, 0.0)));
    /// assert_eq!(h.apply((-1000.0, 0.0)), None);
    /// ```
    pub fn apply(&self, (x, y): (f32, f32)) -> Option<(f32, f32)> {
        let m = &self.m;
        let w = m[6] * x + m[7] * y + m[8];
        let in_front = w > MIN_W;
        if !in_front {
            return None;
        }
        let u = (m[0] * x + m[1] * y + m[2]) / w;
        let v = (m[3] * x + m[4] * y + m[5]) / w;
        (u.is_finite() && v.is_finite()).then_some((u, v))
    }

    /// Maps a Q16 point; `None` as for [`Homography::apply`] or when the image is outside the
    /// Q16 range.
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// use kestrel::Point;
    /// let h = Homography::translation(0.5, 0.0).unwrap();
    /// assert_eq!(h.apply_point(Point::from_f32(1.0, 2.0)), Some(Point::from_f32(1.5, 2.0)));
    /// ```
    pub fn apply_point(&self, p: Point) -> Option<Point> {
        to_point(self.apply(p.to_f32())?)
    }

    /// The inverse map; `None` when the matrix is singular at `f32` precision or the inverse
    /// cannot be scaled to `h33 = 1`.
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// let h = Homography::from_matrix([1.1, 0.1, 5.0, -0.1, 0.9, 2.0, 1e-4, 0.0, 1.0]).unwrap();
    /// let (x, y) = h.inverse().unwrap().apply(h.apply((40.0, 30.0)).unwrap()).unwrap();
    /// assert!((x - 40.0).abs() < 1e-4 && (y - 30.0).abs() < 1e-4);
    /// let flat = Homography::from_matrix([1.0, 2.0, 0.0, 2.0, 4.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
    /// assert!(flat.inverse().is_none());
    /// ```
    pub fn inverse(&self) -> Option<Self> {
        let [a, b, c, d, e, f, g, h, i] = self.m;
        let cofactors = [e * i - f * h, f * g - d * i, d * h - e * g];
        let terms = [a * cofactors[0], b * cofactors[1], c * cofactors[2]];
        let det: f32 = terms.iter().sum();
        let magnitude: f32 = terms.iter().map(|t| t.abs()).sum();
        let invertible = det.abs() > MIN_DETERMINANT * magnitude;
        if !invertible {
            return None;
        }
        // The adjugate is the inverse up to scale; `from_matrix` fixes the scale.
        Self::from_matrix([
            cofactors[0],
            c * h - b * i,
            b * f - c * e,
            cofactors[1],
            a * i - c * g,
            c * d - a * f,
            cofactors[2],
            b * g - a * h,
            a * e - b * d,
        ])
    }

    /// `self ∘ first`: the map that applies `first`, then `self`. `None` when the product cannot
    /// be scaled to `h33 = 1`.
    ///
    /// ```
    /// use kestrel::ego::Homography;
    /// let a = Homography::translation(1.0, 0.0).unwrap();
    /// let b = Homography::from_matrix([2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
    /// // Scale first, then shift.
    /// assert_eq!(a.compose(&b).unwrap().apply((1.0, 1.0)), Some((3.0, 2.0)));
    /// ```
    pub fn compose(&self, first: &Homography) -> Option<Self> {
        Self::from_matrix(mul3(&self.m, &first.m))
    }

    /// The determinant (positive for maps that keep the image's orientation).
    pub(super) fn determinant(&self) -> f32 {
        let [a, b, c, d, e, f, g, h, i] = self.m;
        a * (e * i - f * h) + b * (f * g - d * i) + c * (d * h - e * g)
    }

    /// Squared distance between the mapped previous position and the next one; infinite when
    /// the previous position has no image.
    pub(super) fn transfer_error_sq(&self, pair: &Pair) -> f32 {
        match self.apply(pair.prev) {
            Some((x, y)) => {
                let (dx, dy) = (x - pair.next.0, y - pair.next.1);
                dx * dx + dy * dy
            }
            None => f32::INFINITY,
        }
    }
}

/// Fits a model to all `pairs` by least squares: motion models fitted to point
/// correspondences, all reported as a [`Homography`].
///
/// | Model | Degrees of freedom | Minimal sample | Least-squares fit |
/// |---|---|---|---|
/// | [`ModelKind::Translation`] | 2 | 1 | mean displacement |
/// | [`ModelKind::Similarity`] | 4 | 2 | closed form on centred points (rotation and scale, no reflection) |
/// | [`ModelKind::Affine`] | 6 | 3 | closed form on centred points |
/// | [`ModelKind::Homography`] | 8 | 4 | normalised DLT |
///
/// The homography fit is Hartley's normalised DLT with `h33 = 1`: both point sets are moved to
/// their centroid and scaled to an RMS distance of √2, the 8 x 8 normal equations are
/// accumulated in `f32` and solved by Gaussian elimination with partial pivoting, and the result
/// is mapped back to pixels. Normalisation keeps the normal equations well conditioned, so `f32`
/// loses well under 0.001 px at the image corners. Four points are solved exactly instead (the
/// RANSAC samples), after checking that no three of them are collinear.
///
/// A fit fails with [`FitError::Degenerate`] rather than returning a meaningless model: points
/// that coincide, points on one line (affine and homography), a singular system, or a result that
/// is not invertible. Non-finite or out-of-range coordinates are [`FitError::BadInput`].
///
/// ```
/// use kestrel::ego::{fit, Homography, ModelKind};
/// // Four tracks shifted by (2, -1) and a fifth one too.
/// let tracks = [
///     ((10.0, 10.0), (12.0, 9.0)),
///     ((90.0, 12.0), (92.0, 11.0)),
///     ((85.0, 70.0), (87.0, 69.0)),
///     ((15.0, 75.0), (17.0, 74.0)),
///     ((50.0, 40.0), (52.0, 39.0)),
/// ];
/// let h = fit(ModelKind::Homography, &tracks).unwrap();
/// let (x, y) = h.apply((30.0, 30.0)).unwrap();
/// assert!((x - 32.0).abs() < 1e-3 && (y - 29.0).abs() < 1e-3);
/// ```
///
/// Two correspondences fit a similarity exactly, three an affine map, four a homography.
///
/// ```
/// use kestrel::ego::{fit, FitError, ModelKind};
/// // Rotated by 90 degrees about (0, 0) and scaled by 2.
/// let tracks = [((1.0, 0.0), (0.0, 2.0)), ((0.0, 1.0), (-2.0, 0.0))];
/// let h = fit(ModelKind::Similarity, &tracks).unwrap();
/// let (x, y) = h.apply((1.0, 1.0)).unwrap();
/// assert!((x + 2.0).abs() < 1e-5 && (y - 2.0).abs() < 1e-5);
///
/// let collinear = [((0.0, 0.0), (1.0, 0.0)), ((1.0, 1.0), (2.0, 1.0)), ((2.0, 2.0), (3.0, 2.0))];
/// assert_eq!(fit(ModelKind::Affine, &collinear), Err(FitError::Degenerate));
/// let nan = [((f32::NAN, 0.0), (0.0, 0.0))];
/// assert_eq!(fit(ModelKind::Translation, &nan), Err(FitError::BadInput));
/// ```
pub fn fit<C: Correspondence>(kind: ModelKind, pairs: &[C]) -> Result<Homography, FitError> {
    if !pairs.iter().all(|c| Pair::of(c).is_valid()) {
        return Err(FitError::BadInput);
    }
    fit_pairs(kind, Pairs::new(pairs, Pick::All))
}

/// A correspondence as `f32` pixels.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Pair {
    pub prev: (f32, f32),
    pub next: (f32, f32),
}

impl Pair {
    pub fn of<C: Correspondence>(c: &C) -> Self {
        let (prev, next) = c.positions();
        Self { prev, next }
    }

    /// Finite and within [`MAX_COORDINATE`] (the comparison is false for NaN).
    pub fn is_valid(&self) -> bool {
        [self.prev.0, self.prev.1, self.next.0, self.next.1]
            .iter()
            .all(|v| v.abs() <= MAX_COORDINATE)
    }
}

/// The pairs a fit reads, several times over: `pairs` as `pick` selects them, in order. One
/// type for every selection (a sample, the inliers, all), so that each fit is built once for a
/// type of correspondence: on the Cortex-M4 each iterator type a fit took was another copy of
/// the fits in flash.
pub(super) struct Pairs<'a, C> {
    pairs: &'a [C],
    pick: Pick<'a>,
    next: usize,
}

/// Which of a slice's correspondences [`Pairs`] yields.
#[derive(Clone, Copy)]
pub(super) enum Pick<'a> {
    All,
    /// These indices, in their order.
    Indices(&'a [usize]),
    /// Those whose flag is set.
    Flagged(&'a [bool]),
}

// By hand: a derive would ask `C: Clone` of the borrowed slice's items.
impl<C> Clone for Pairs<'_, C> {
    fn clone(&self) -> Self {
        Self { ..*self }
    }
}

impl<'a, C> Pairs<'a, C> {
    pub fn new(pairs: &'a [C], pick: Pick<'a>) -> Self {
        Self {
            pairs,
            pick,
            next: 0,
        }
    }
}

impl<C: Correspondence> Iterator for Pairs<'_, C> {
    type Item = Pair;

    fn next(&mut self) -> Option<Pair> {
        loop {
            let i = self.next;
            self.next = i.saturating_add(1);
            let index = match self.pick {
                Pick::All => i,
                Pick::Indices(indices) => *indices.get(i)?,
                Pick::Flagged(flags) => match flags.get(i)? {
                    true => i,
                    false => continue,
                },
            };
            return self.pairs.get(index).map(Pair::of);
        }
    }
}

/// Least-squares fit over already validated pairs; they are walked several times.
pub(super) fn fit_pairs<C: Correspondence>(
    kind: ModelKind,
    pairs: Pairs<'_, C>,
) -> Result<Homography, FitError> {
    let (prev, next, count) = Moments::of_pairs(pairs.clone()).ok_or(FitError::TooFewPoints)?;
    if count < kind.min_samples() {
        return Err(FitError::TooFewPoints);
    }
    let model = match kind {
        ModelKind::Translation => translation(pairs, count),
        ModelKind::Similarity => similarity(pairs, &prev, next.mean),
        ModelKind::Affine => affine(pairs, &prev, next.mean),
        ModelKind::Homography if count == 4 => {
            let mut four = [Pair::default(); 4];
            for (slot, pair) in four.iter_mut().zip(pairs) {
                *slot = pair;
            }
            homography_from_four(&four, &prev, &next)
        }
        ModelKind::Homography => homography_least_squares(pairs, &prev, &next),
    }?;
    // A model that collapses the image (zero scale) fits but explains nothing.
    model.inverse().ok_or(FitError::Degenerate)?;
    Ok(model)
}

/// True when the points cannot determine a model of `kind` whatever the sample: all coincident
/// (similarity and up) or collinear in either frame (affine and homography).
pub(super) fn is_degenerate<C: Correspondence>(kind: ModelKind, pairs: Pairs<'_, C>) -> bool {
    let Some((prev, next, _)) = Moments::of_pairs(pairs) else {
        return true;
    };
    match kind {
        ModelKind::Translation => false,
        ModelKind::Similarity => !prev.is_spread() || !next.is_spread(),
        ModelKind::Affine | ModelKind::Homography => !prev.is_planar() || !next.is_planar(),
    }
}

fn translation<I: Iterator<Item = Pair>>(pairs: I, count: usize) -> Result<Homography, FitError> {
    let (sx, sy) = pairs.fold((0.0f32, 0.0f32), |(sx, sy), p| {
        (sx + (p.next.0 - p.prev.0), sy + (p.next.1 - p.prev.1))
    });
    let n = count as f32;
    Homography::translation(sx / n, sy / n).ok_or(FitError::Degenerate)
}

/// The similarity fit, from the pairs' moments in the previous frame and their mean in the next.
fn similarity<I>(pairs: I, prev: &Moments, m_next: (f32, f32)) -> Result<Homography, FitError>
where
    I: Iterator<Item = Pair>,
{
    if !prev.is_spread() {
        return Err(FitError::Degenerate);
    }
    let m = prev.mean;
    let (mut dot, mut cross) = (0.0f32, 0.0f32);
    for pair in pairs {
        let (x, y) = sub(pair.prev, m);
        let (u, v) = sub(pair.next, m_next);
        dot += x * u + y * v;
        cross += x * v - y * u;
    }
    // [a -b; b a] = scale x rotation minimises the squared residuals.
    let norm = prev.sxx + prev.syy;
    let (a, b) = (dot / norm, cross / norm);
    let tx = m_next.0 - (a * m.0 - b * m.1);
    let ty = m_next.1 - (b * m.0 + a * m.1);
    Homography::from_matrix([a, -b, tx, b, a, ty, 0.0, 0.0, 1.0]).ok_or(FitError::Degenerate)
}

/// The affine fit, from the pairs' moments in the previous frame and their mean in the next.
fn affine<I>(pairs: I, prev: &Moments, m_next: (f32, f32)) -> Result<Homography, FitError>
where
    I: Iterator<Item = Pair>,
{
    if !prev.is_planar() {
        return Err(FitError::Degenerate);
    }
    let m = prev.mean;
    // Cross moments between next and previous centred coordinates.
    let (mut uxx, mut uxy, mut vxx, mut vxy) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for pair in pairs {
        let (x, y) = sub(pair.prev, m);
        let (u, v) = sub(pair.next, m_next);
        uxx += u * x;
        uxy += u * y;
        vxx += v * x;
        vxy += v * y;
    }
    // A = C S⁻¹ with S the previous scatter matrix.
    let (sxx, sxy, syy) = (prev.sxx, prev.sxy, prev.syy);
    let det = sxx * syy - sxy * sxy;
    let a11 = (uxx * syy - uxy * sxy) / det;
    let a12 = (uxy * sxx - uxx * sxy) / det;
    let a21 = (vxx * syy - vxy * sxy) / det;
    let a22 = (vxy * sxx - vxx * sxy) / det;
    let tx = m_next.0 - (a11 * m.0 + a12 * m.1);
    let ty = m_next.1 - (a21 * m.0 + a22 * m.1);
    Homography::from_matrix([a11, a12, tx, a21, a22, ty, 0.0, 0.0, 1.0]).ok_or(FitError::Degenerate)
}

/// The homography's least-squares (DLT) fit, from the pairs' moments in both frames.
fn homography_least_squares<I>(
    pairs: I,
    prev: &Moments,
    next: &Moments,
) -> Result<Homography, FitError>
where
    I: Iterator<Item = Pair>,
{
    if !prev.is_planar() || !next.is_planar() {
        return Err(FitError::Degenerate);
    }
    let (from, to) = (prev.normalisation(), next.normalisation());
    let mut ata = [[0.0f32; 8]; 8];
    let mut atb = [0.0f32; 8];
    for pair in pairs {
        for (row, rhs) in dlt_rows(from.apply(pair.prev), to.apply(pair.next)) {
            let rows = ata.iter_mut().zip(atb.iter_mut()).zip(row.iter());
            for (i, ((ata_row, atb_i), &ri)) in rows.enumerate() {
                if ri == 0.0 {
                    continue;
                }
                for (entry, &rj) in ata_row.iter_mut().zip(row.iter()).skip(i) {
                    *entry += ri * rj;
                }
                *atb_i += ri * rhs;
            }
        }
    }
    let upper = ata;
    for (i, row) in ata.iter_mut().enumerate() {
        for (j, entry) in row.iter_mut().enumerate().take(i) {
            *entry = upper.get(j).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
        }
    }
    let h = solve(ata, atb).ok_or(FitError::Degenerate)?;
    denormalise(h, &from, &to)
}

/// The homography through four pairs, whose moments in both frames `prev` and `next` are.
fn homography_from_four(
    four: &[Pair; 4],
    prev: &Moments,
    next: &Moments,
) -> Result<Homography, FitError> {
    const TRIPLES: [[usize; 3]; 4] = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
    for [i, j, k] in TRIPLES {
        let (Some(&a), Some(&b), Some(&c)) = (four.get(i), four.get(j), four.get(k)) else {
            return Err(FitError::TooFewPoints);
        };
        if is_thin_triangle(a.prev, b.prev, c.prev) || is_thin_triangle(a.next, b.next, c.next) {
            return Err(FitError::Degenerate);
        }
    }
    let (from, to) = (prev.normalisation(), next.normalisation());
    let mut a = [[0.0f32; 8]; 8];
    let mut b = [0.0f32; 8];
    let rows = four
        .iter()
        .flat_map(|p| dlt_rows(from.apply(p.prev), to.apply(p.next)));
    for ((a_row, b_row), (row, rhs)) in a.iter_mut().zip(b.iter_mut()).zip(rows) {
        *a_row = row;
        *b_row = rhs;
    }
    let h = solve(a, b).ok_or(FitError::Degenerate)?;
    denormalise(h, &from, &to)
}

/// The two DLT equations of one normalised correspondence `(x, y) -> (u, v)` with `h33 = 1`:
/// `h11 x + h12 y + h13 - h31 x u - h32 y u = u`, and the same for `v`.
fn dlt_rows((x, y): (f32, f32), (u, v): (f32, f32)) -> [([f32; 8], f32); 2] {
    [
        ([x, y, 1.0, 0.0, 0.0, 0.0, -x * u, -y * u], u),
        ([0.0, 0.0, 0.0, x, y, 1.0, -x * v, -y * v], v),
    ]
}

/// `H = T_next⁻¹ H_n T_prev`: the normalised solution back in pixels.
fn denormalise(
    h: [f32; 8],
    from: &Normalisation,
    to: &Normalisation,
) -> Result<Homography, FitError> {
    let normalised = [h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0];
    let m = mul3(&mul3(&to.inverse_matrix(), &normalised), &from.matrix());
    Homography::from_matrix(m).ok_or(FitError::Degenerate)
}

/// True when the triangle's height is below [`MIN_TRIANGLE_HEIGHT`] of its longest side.
fn is_thin_triangle(a: (f32, f32), b: (f32, f32), c: (f32, f32)) -> bool {
    let (ab, ac, bc) = (sub(b, a), sub(c, a), sub(c, b));
    let cross = ab.0 * ac.1 - ab.1 * ac.0;
    let longest_sq = norm_sq(ab).max(norm_sq(ac)).max(norm_sq(bc));
    // |cross| = longest side x height.
    let thick = cross.abs() > MIN_TRIANGLE_HEIGHT * longest_sq;
    !thick
}

/// Centroid and centred second moments of a point set.
#[derive(Debug, Clone, Copy)]
struct Moments {
    count: f32,
    mean: (f32, f32),
    sxx: f32,
    sxy: f32,
    syy: f32,
}

impl Moments {
    /// The moments of the pairs' previous and next points and their count; `None` for an empty
    /// set. Two passes over both: centring first keeps the sums accurate.
    fn of_pairs<I: Iterator<Item = Pair> + Clone>(pairs: I) -> Option<(Self, Self, usize)> {
        let zero = (0.0f32, 0.0f32);
        let (sum_prev, sum_next, n) =
            pairs.clone().fold((zero, zero, 0usize), |(p, q, n), pair| {
                let add = |a: (f32, f32), b: (f32, f32)| (a.0 + b.0, a.1 + b.1);
                (add(p, pair.prev), add(q, pair.next), n.saturating_add(1))
            });
        // Counts of a slice's items are exact in f32 up to 2^24, far beyond any frame's tracks.
        #[allow(clippy::cast_precision_loss)]
        let count = n as f32;
        let means = (n > 0).then(|| {
            let mean = |s: (f32, f32)| (s.0 / count, s.1 / count);
            (mean(sum_prev), mean(sum_next))
        });
        let (mean_prev, mean_next) = means?;
        let (mut prev, mut next) = (Self::empty(mean_prev), Self::empty(mean_next));
        for pair in pairs {
            prev.add(pair.prev);
            next.add(pair.next);
        }
        Some((prev, next, n))
    }

    fn empty(mean: (f32, f32)) -> Self {
        Self {
            count: 0.0,
            mean,
            sxx: 0.0,
            sxy: 0.0,
            syy: 0.0,
        }
    }

    /// Adds `p`'s centred products.
    fn add(&mut self, p: (f32, f32)) {
        let (x, y) = sub(p, self.mean);
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
        self.count += 1.0;
    }

    /// Mean squared distance from the centroid.
    fn spread_sq(&self) -> f32 {
        (self.sxx + self.syy) / self.count
    }

    fn is_spread(&self) -> bool {
        self.spread_sq() >= MIN_SPREAD * MIN_SPREAD
    }

    /// Spread out and not along one line.
    fn is_planar(&self) -> bool {
        let trace = self.sxx + self.syy;
        let det = self.sxx * self.syy - self.sxy * self.sxy;
        self.is_spread() && 4.0 * det >= MIN_ISOTROPY * trace * trace
    }

    /// Hartley's normalisation: centroid to the origin, RMS distance √2.
    fn normalisation(&self) -> Normalisation {
        Normalisation {
            centre: self.mean,
            scale: sqrt(2.0 / self.spread_sq()),
        }
    }
}

/// The similarity `p -> (p - centre) * scale`.
#[derive(Debug, Clone, Copy)]
struct Normalisation {
    centre: (f32, f32),
    scale: f32,
}

impl Normalisation {
    fn apply(&self, p: (f32, f32)) -> (f32, f32) {
        let (x, y) = sub(p, self.centre);
        (x * self.scale, y * self.scale)
    }

    fn matrix(&self) -> [f32; 9] {
        let (s, (cx, cy)) = (self.scale, self.centre);
        [s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0]
    }

    fn inverse_matrix(&self) -> [f32; 9] {
        let (s, (cx, cy)) = (1.0 / self.scale, self.centre);
        [s, 0.0, cx, 0.0, s, cy, 0.0, 0.0, 1.0]
    }
}

/// The position as a Q16 point, `None` outside the Q16 range.
pub(super) fn to_point((x, y): (f32, f32)) -> Option<Point> {
    const LIMIT: f32 = 32_767.0;
    (x.abs() < LIMIT && y.abs() < LIMIT).then(|| Point::from_f32(x, y))
}

fn sub(a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
    (a.0 - b.0, a.1 - b.1)
}

fn norm_sq(v: (f32, f32)) -> f32 {
    v.0 * v.0 + v.1 * v.1
}

#[cfg(test)]
mod tests {
    use super::*;

    type Track = ((f32, f32), (f32, f32));

    fn grid(h: &[f64; 9]) -> [Track; 30] {
        core::array::from_fn(|i| {
            let (x, y) = ((i % 6) as f64 * 30.0 + 5.0, (i / 6) as f64 * 25.0 + 3.0);
            let w = h[6] * x + h[7] * y + h[8];
            let u = (h[0] * x + h[1] * y + h[2]) / w;
            let v = (h[3] * x + h[4] * y + h[5]) / w;
            ((x as f32, y as f32), (u as f32, v as f32))
        })
    }

    fn max_error(h: &Homography, pairs: &[Track]) -> f32 {
        pairs
            .iter()
            .map(|&(p, q)| {
                let (x, y) = h.apply(p).unwrap();
                sqrt(norm_sq(sub((x, y), q)))
            })
            .fold(0.0, f32::max)
    }

    #[test]
    fn each_model_recovers_its_own_motion() {
        let (c, s) = (0.1f64.cos() * 1.05, 0.1f64.sin() * 1.05);
        let motions = [
            (
                ModelKind::Translation,
                [1.0, 0.0, 3.5, 0.0, 1.0, -2.25, 0.0, 0.0, 1.0],
            ),
            (
                ModelKind::Similarity,
                [c, -s, 4.0, s, c, -3.0, 0.0, 0.0, 1.0],
            ),
            (
                ModelKind::Affine,
                [1.02, 0.05, 2.0, -0.03, 0.97, 1.0, 0.0, 0.0, 1.0],
            ),
            (
                ModelKind::Homography,
                [1.01, 0.02, 3.0, -0.01, 0.99, 1.5, 2e-4, -1e-4, 1.0],
            ),
        ];
        for (kind, h) in motions {
            let pairs = grid(&h);
            let fitted = fit(kind, &pairs).unwrap();
            assert!(max_error(&fitted, &pairs) < 2e-3, "{kind:?}");
            // Spread over the grid, no three on a line.
            let sample = [pairs[0], pairs[9], pairs[29], pairs[20]];
            let minimal = fit(kind, &sample[..kind.min_samples()]).unwrap();
            assert!(max_error(&minimal, &pairs) < 5e-3, "{kind:?} minimal");
        }
    }

    #[test]
    fn rejects_coincident_and_collinear_points() {
        let same = [((5.0, 5.0), (6.0, 5.0)); 6];
        assert_eq!(fit(ModelKind::Similarity, &same), Err(FitError::Degenerate));
        let line: [Track; 6] =
            core::array::from_fn(|i| ((i as f32 * 10.0, i as f32 * 3.7 + 1.0), (i as f32, 0.0)));
        assert_eq!(fit(ModelKind::Affine, &line), Err(FitError::Degenerate));
        assert_eq!(fit(ModelKind::Homography, &line), Err(FitError::Degenerate));
        assert_eq!(
            fit(ModelKind::Homography, &line[..4]),
            Err(FitError::Degenerate)
        );
        assert!(fit(ModelKind::Translation, &line).is_ok());
    }

    #[test]
    fn a_collapsing_fit_is_degenerate() {
        let to_one_point: [Track; 5] =
            core::array::from_fn(|i| (((i * i) as f32, (i * 7 % 5) as f32), (3.0, 3.0)));
        assert_eq!(
            fit(ModelKind::Affine, &to_one_point),
            Err(FitError::Degenerate)
        );
    }

    #[test]
    fn rejects_out_of_range_input() {
        let far = [((1e6, 0.0), (0.0, 0.0))];
        assert_eq!(fit(ModelKind::Translation, &far), Err(FitError::BadInput));
        let inf = [((0.0, 0.0), (0.0, f32::NEG_INFINITY))];
        assert_eq!(fit(ModelKind::Translation, &inf), Err(FitError::BadInput));
    }

    #[test]
    fn inverse_and_compose_round_trip() {
        let h =
            Homography::from_matrix([1.2, 0.1, -7.0, 0.05, 0.8, 3.0, 3e-4, -2e-4, 1.0]).unwrap();
        let identity = h.compose(&h.inverse().unwrap()).unwrap().matrix();
        for (v, e) in identity.iter().zip(Homography::IDENTITY.matrix()) {
            assert!((v - e).abs() < 1e-5, "{identity:?}");
        }
    }
}
