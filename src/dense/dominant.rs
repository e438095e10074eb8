//! The camera's motion, as the dominant affine motion of the grid flow: [`DominantMotion`]
//! and its fit.
//!
//! Everything is `f32`, in coordinates centred on the frame and scaled to about ±1 so the
//! normal equations stay well conditioned; the iteration count is bounded and the result is a
//! pure function of the nodes.

use super::grid::{GridLayout, GridNode};
use super::motion::CameraMotion;
use crate::{Bound, ConfigError};

/// An affine flow field: the motion the camera gives every pixel.
///
/// When the camera moves, every pixel moves; an object is what moves *differently*. The
/// camera's share is estimated from the measured nodes ([`DominantMotion::fit`]) as an affine
/// flow field
///
/// ```text
/// dx = a0 + a1·x + a2·y        dy = b0 + b1·x + b2·y
/// ```
///
/// which holds pan, roll and zoom exactly and small tilts approximately.
///
/// ```
/// use kestrel::dense::DominantMotion;
/// let pan = DominantMotion::translation(2.0, -1.0);
/// assert_eq!(pan.flow_at(50.0, 80.0), (2.0, -1.0));
/// // A 1% zoom about the origin moves (100, 0) by 1 px to the right.
/// let zoom = DominantMotion { dx: [0.0, 0.01, 0.0], dy: [0.0, 0.0, 0.01] };
/// assert_eq!(zoom.flow_at(100.0, 0.0), (1.0, 0.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DominantMotion {
    /// `dx = dx[0] + dx[1]·x + dx[2]·y`, pixels.
    pub dx: [f32; 3],
    /// `dy = dy[0] + dy[1]·x + dy[2]·y`, pixels.
    pub dy: [f32; 3],
}

impl DominantMotion {
    /// No motion: a still camera.
    pub const ZERO: Self = Self {
        dx: [0.0; 3],
        dy: [0.0; 3],
    };

    /// The same shift everywhere.
    ///
    /// ```
    /// use kestrel::dense::DominantMotion;
    /// assert_eq!(DominantMotion::translation(0.0, 0.0), DominantMotion::ZERO);
    /// ```
    pub const fn translation(dx: f32, dy: f32) -> Self {
        Self {
            dx: [dx, 0.0, 0.0],
            dy: [dy, 0.0, 0.0],
        }
    }

    /// The flow `(dx, dy)`, px, this motion gives pixel (`x`, `y`) of the previous frame: a
    /// displacement, not a position (the pixel is at (`x + dx`, `y + dy`) in the next frame).
    /// The same as its [`CameraMotion::flow_at`].
    ///
    /// ```
    /// use kestrel::dense::DominantMotion;
    /// assert_eq!(DominantMotion::ZERO.flow_at(3.0, 4.0), (0.0, 0.0));
    /// ```
    pub fn flow_at(&self, x: f32, y: f32) -> (f32, f32) {
        let [a0, a1, a2] = self.dx;
        let [b0, b1, b2] = self.dy;
        (a0 + a1 * x + a2 * y, b0 + b1 * x + b2 * y)
    }

    /// Fits the dominant motion to the measured nodes of `nodes`. Filled and invalid nodes
    /// are ignored; without any measured node the result is [`DominantMotion::ZERO`]. A node
    /// slice shorter than the layout is refused (as `"nodes"`): its missing rows would read as
    /// unmeasured; so are radii that are not finite numbers above 0 (`"start_radius"`,
    /// `"inlier_radius"`).
    ///
    /// Moving objects are outliers to the camera's motion, so it is fitted robustly, by
    /// iteratively reweighted least squares with Tukey's biweight ([`DominantFitParams`]):
    ///
    /// 1. Start from the median flow (exact, by bisection over the Q16 values: no buffer, no
    ///    sort).
    /// 2. Each iteration weighs every measured node by `(1 - (r/c)²)²` for a residual `r` below
    ///    the radius `c` (0 beyond) and solves the weighted normal equations, two 3 x 3
    ///    systems.
    /// 3. The radius starts wide (rotation and zoom put far nodes pixels away from the median)
    ///    and halves each iteration down to the inlier radius.
    ///
    /// A degenerate fit (nodes on a line, no weight left) falls back to a translation, then to
    /// the previous estimate, so the result is always finite.
    ///
    /// ```
    /// use kestrel::dense::{DominantFitParams, DominantMotion, GridLayout, GridNode};
    /// use kestrel::Point;
    ///
    /// // The camera pans 1.5 px right; two nodes of an object move 5 px down.
    /// let layout = GridLayout::new(64, 64, 8).unwrap();
    /// let mut nodes = [GridNode::tracked(Point::from_f32(1.5, 0.0)); 64];
    /// nodes[9] = GridNode::tracked(Point::from_f32(1.5, 5.0));
    /// nodes[10] = GridNode::tracked(Point::from_f32(1.5, 5.0));
    /// let fit = DominantMotion::fit(&layout, &nodes, &DominantFitParams::default()).unwrap();
    /// assert_eq!((fit.measured, fit.inliers), (64, 62));
    /// let (dx, dy) = fit.motion.flow_at(20.0, 12.0);
    /// assert!((dx - 1.5).abs() < 1e-3 && dy.abs() < 1e-3);
    /// let short = DominantMotion::fit(&layout, &nodes[..63], &DominantFitParams::default());
    /// assert_eq!(short.unwrap_err().to_string(), "nodes must hold at least 64 elements");
    /// ```
    pub fn fit(
        layout: &GridLayout,
        nodes: &[GridNode],
        params: &DominantFitParams,
    ) -> Result<DominantFit, ConfigError> {
        params.check()?;
        if nodes.len() < layout.len() {
            return Err(ConfigError::min_len("nodes", layout.len()));
        }
        let nodes = Measured::new(layout, nodes);
        let measured = nodes.iter().count();
        if measured == 0 {
            return Ok(DominantFit {
                motion: Self::ZERO,
                measured,
                inliers: 0,
                spread: 0.0,
            });
        }
        let mut model = Affine::translation(nodes.median(|f| f.0), nodes.median(|f| f.1));
        let mut radius = params.start_radius.max(params.inlier_radius);
        for _ in 0..params.iterations {
            let Some(next) = model.refit(&nodes, radius) else {
                break;
            };
            let settled = radius <= params.inlier_radius && next.close_to(&model);
            model = next;
            if settled {
                break;
            }
            radius = (radius * 0.5).max(params.inlier_radius);
        }
        let (inliers, sum_sq) = nodes
            .iter()
            .map(|(u, v, flow)| model.residual_sq(u, v, flow))
            .filter(|&r2| r2 < params.inlier_radius_sq())
            .fold((0usize, 0.0f32), |(n, sum), r2| {
                (n.saturating_add(1), sum + r2)
            });
        let spread = if inliers > 0 {
            sqrt(sum_sq / inliers as f32)
        } else {
            0.0
        };
        Ok(DominantFit {
            motion: model.in_pixels(&nodes.frame),
            measured,
            inliers,
            spread,
        })
    }
}

impl CameraMotion for DominantMotion {
    fn flow_at(&self, x: f32, y: f32) -> (f32, f32) {
        DominantMotion::flow_at(self, x, y)
    }
}

/// How the dominant motion is fitted.
///
/// ```
/// use kestrel::dense::{DominantFitParams, DominantMotion, GridLayout, GridNode};
/// use kestrel::{Bound, ConfigError, Point};
///
/// // The camera pans 1 px right; four nodes measured 1.5 px more.
/// let layout = GridLayout::new(64, 64, 8).unwrap();
/// let mut nodes = [GridNode::tracked(Point::from_f32(1.0, 0.0)); 64];
/// for i in [9, 18, 27, 36] {
///     nodes[i] = GridNode::tracked(Point::from_f32(2.5, 0.0));
/// }
/// let fit = |inlier_radius| {
///     let params = DominantFitParams { inlier_radius, ..DominantFitParams::default() };
///     DominantMotion::fit(&layout, &nodes, &params)
/// };
/// // Within the default radius of 1 px, only the pan's nodes are inliers; 2 px takes all.
/// assert_eq!(fit(1.0).unwrap().inliers, 60);
/// assert_eq!(fit(2.0).unwrap().inliers, 64);
/// let refused = fit(0.0).unwrap_err();
/// assert_eq!(refused, ConfigError { field: "inlier_radius", bound: Bound::Positive });
/// assert_eq!(refused.to_string(), "inlier_radius must be a finite number above 0");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DominantFitParams {
    /// Tukey radius of the first iteration, px: wide enough to hold the background's spread of
    /// flows around the median under rotation and zoom.
    pub start_radius: f32,
    /// Final Tukey radius, px; nodes nearer than it to the model are inliers.
    pub inlier_radius: f32,
    /// Most reweighting iterations.
    pub iterations: u8,
}

impl Default for DominantFitParams {
    fn default() -> Self {
        Self {
            start_radius: 8.0,
            inlier_radius: 1.0,
            iterations: 10,
        }
    }
}

impl DominantFitParams {
    /// Refuses a radius that is not a finite number above 0, by name.
    pub(crate) fn check(&self) -> Result<(), ConfigError> {
        let positive = |r: f32| r.is_finite() && r > 0.0;
        if !positive(self.start_radius) {
            return Err(ConfigError::new("start_radius", Bound::Positive));
        }
        if !positive(self.inlier_radius) {
            return Err(ConfigError::new("inlier_radius", Bound::Positive));
        }
        Ok(())
    }

    fn inlier_radius_sq(&self) -> f32 {
        self.inlier_radius * self.inlier_radius
    }
}

/// A fitted dominant motion and how well the nodes agree with it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DominantFit {
    /// The camera's motion.
    pub motion: DominantMotion,
    /// Measured nodes the fit used.
    pub measured: usize,
    /// Measured nodes within [`DominantFitParams::inlier_radius`] of the motion.
    pub inliers: usize,
    /// Root-mean-square distance of the inliers' flow from the motion, px: how precisely the
    /// static scene was measured.
    pub spread: f32,
}

/// Square root by Newton's method from the float's halved exponent: `core` has no `sqrt`, and
/// five steps reach `f32` precision for the spreads used here.
fn sqrt(x: f32) -> f32 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    // A positive finite float's bits are below 2^31: the sum stays below 2^32.
    let mut r = f32::from_bits((x.to_bits() >> 1).wrapping_add(0x1fc0_0000));
    for _ in 0..5 {
        r = 0.5 * (r + x / r);
    }
    r
}

/// The map from pixels to the fit's centred, scaled coordinates.
#[derive(Debug, Clone, Copy)]
struct Normalisation {
    origin: (f32, f32),
    /// Pixels per unit.
    scale: f32,
}

/// The measured nodes of a grid, in normalised coordinates.
struct Measured<'a> {
    layout: &'a GridLayout,
    nodes: &'a [GridNode],
    frame: Normalisation,
}

impl<'a> Measured<'a> {
    fn new(layout: &'a GridLayout, nodes: &'a [GridNode]) -> Self {
        let (w, h) = (layout.width() as f32, layout.height() as f32);
        let frame = Normalisation {
            origin: ((w - 1.0) * 0.5, (h - 1.0) * 0.5),
            scale: (w.max(h) * 0.5).max(1.0),
        };
        // The shorter of the two lengths: the range is always inside `nodes`.
        let len = layout.len().min(nodes.len());
        Self {
            layout,
            nodes: nodes.get(..len).unwrap_or(&[]),
            frame,
        }
    }

    /// `(u, v, (dx, dy))` of every measured node: its normalised position and its flow, px.
    fn iter(&self) -> impl Iterator<Item = (f32, f32, (f32, f32))> + '_ {
        self.nodes
            .iter()
            .enumerate()
            .filter(|(_, n)| n.is_valid())
            .map(|(i, n)| {
                let (col, row) = self.layout.node(i);
                let (x, y) = self.layout.centre(col, row);
                let Normalisation { origin, scale } = self.frame;
                let u = (x as f32 - origin.0) / scale;
                let v = (y as f32 - origin.1) / scale;
                (u, v, n.flow.to_f32())
            })
    }

    /// The lower median of one flow component of the measured nodes, found by bisection on
    /// the exact Q16 values; `part` picks the component from `(dx, dy)` raw bits.
    fn median(&self, part: fn((i32, i32)) -> i32) -> f32 {
        let values = || {
            self.nodes
                .iter()
                .filter(|n| n.is_valid())
                .map(|n| i64::from(part((n.flow.x.to_bits(), n.flow.y.to_bits()))))
        };
        let count = values().count();
        let (Some(mut lo), Some(mut hi)) = (values().min(), values().max()) else {
            return 0.0;
        };
        // The smallest value with at least half the values at or below it.
        let wanted = count.div_ceil(2);
        while lo < hi {
            // lo < hi, both i32 values widened to i64: no overflow.
            let mid = lo.saturating_add(hi.saturating_sub(lo) / 2);
            if values().filter(|&v| v <= mid).count() >= wanted {
                hi = mid;
            } else {
                lo = mid.saturating_add(1);
            }
        }
        lo as f32 / 65536.0
    }
}

/// An affine flow in normalised coordinates: `dx = c·(1, u, v)`, `dy = d·(1, u, v)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Affine {
    c: [f32; 3],
    d: [f32; 3],
}

/// Two fits closer than this in every coefficient (px per unit) have converged.
const SETTLED: f32 = 1e-3;

impl Affine {
    fn translation(dx: f32, dy: f32) -> Self {
        Self {
            c: [dx, 0.0, 0.0],
            d: [dy, 0.0, 0.0],
        }
    }

    fn flow_at(&self, u: f32, v: f32) -> (f32, f32) {
        let [c0, c1, c2] = self.c;
        let [d0, d1, d2] = self.d;
        (c0 + c1 * u + c2 * v, d0 + d1 * u + d2 * v)
    }

    fn residual_sq(&self, u: f32, v: f32, (dx, dy): (f32, f32)) -> f32 {
        let (px, py) = self.flow_at(u, v);
        (dx - px) * (dx - px) + (dy - py) * (dy - py)
    }

    fn close_to(&self, other: &Self) -> bool {
        let near =
            |a: &[f32; 3], b: &[f32; 3]| a.iter().zip(b).all(|(p, q)| (p - q).abs() < SETTLED);
        near(&self.c, &other.c) && near(&self.d, &other.d)
    }

    /// One reweighted least-squares step: Tukey weights of radius `radius` around `self`.
    /// `None` when no node is left with weight, or the solution is not finite.
    fn refit(&self, nodes: &Measured<'_>, radius: f32) -> Option<Self> {
        let radius_sq = radius * radius;
        let mut normal = NormalEquations::default();
        for (u, v, flow) in nodes.iter() {
            let r2 = self.residual_sq(u, v, flow);
            if r2 < radius_sq {
                let t = 1.0 - r2 / radius_sq;
                normal.add(u, v, flow, t * t);
            }
        }
        let fitted = normal.solve()?;
        let finite = fitted.c.iter().chain(&fitted.d).all(|k| k.is_finite());
        finite.then_some(fitted)
    }

    /// The same field in pixel coordinates.
    fn in_pixels(&self, frame: &Normalisation) -> DominantMotion {
        let Normalisation { origin, scale } = *frame;
        let to_pixels = |k: [f32; 3]| {
            let (kx, ky) = (k[1] / scale, k[2] / scale);
            [k[0] - kx * origin.0 - ky * origin.1, kx, ky]
        };
        DominantMotion {
            dx: to_pixels(self.c),
            dy: to_pixels(self.d),
        }
    }
}

/// Weighted sums of the least-squares problem: `A = Σ w p pᵀ`, `bx = Σ w dx p`, `by = Σ w dy p`
/// with `p = (1, u, v)`.
#[derive(Debug, Default)]
struct NormalEquations {
    /// `[Σw, Σwu, Σwv, Σwu², Σwuv, Σwv²]`.
    a: [f32; 6],
    bx: [f32; 3],
    by: [f32; 3],
}

/// Below this determinant, relative to `(Σw)³`, the nodes are too close to a line for an
/// affine fit.
const DEGENERATE: f32 = 1e-6;

impl NormalEquations {
    fn add(&mut self, u: f32, v: f32, (dx, dy): (f32, f32), w: f32) {
        let terms = [1.0, u, v, u * u, u * v, v * v];
        for (sum, t) in self.a.iter_mut().zip(terms) {
            *sum += w * t;
        }
        for (k, p) in [1.0, u, v].into_iter().enumerate() {
            if let (Some(bx), Some(by)) = (self.bx.get_mut(k), self.by.get_mut(k)) {
                *bx += w * dx * p;
                *by += w * dy * p;
            }
        }
    }

    /// Solves both systems by the adjugate; a translation (weighted mean) when the matrix is
    /// nearly singular; `None` without weight.
    fn solve(&self) -> Option<Affine> {
        let [s, su, sv, suu, suv, svv] = self.a;
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        // Cofactors of the symmetric matrix [[s, su, sv], [su, suu, suv], [sv, suv, svv]].
        let adj = [
            [
                suu * svv - suv * suv,
                sv * suv - su * svv,
                su * suv - sv * suu,
            ],
            [sv * suv - su * svv, s * svv - sv * sv, su * sv - s * suv],
            [su * suv - sv * suu, su * sv - s * suv, s * suu - su * su],
        ];
        let det = s * adj[0][0] + su * adj[0][1] + sv * adj[0][2];
        if det.is_nan() || det <= DEGENERATE * s * s * s {
            return Some(Affine::translation(self.bx[0] / s, self.by[0] / s));
        }
        let apply =
            |b: &[f32; 3]| adj.map(|row| (row[0] * b[0] + row[1] * b[1] + row[2] * b[2]) / det);
        Some(Affine {
            c: apply(&self.bx),
            d: apply(&self.by),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::q16::Point;

    /// Nodes of a 160 x 120 grid with 8 px cells moving by `flow(x, y)`.
    fn nodes_with(flow: impl Fn(f32, f32) -> (f32, f32)) -> (GridLayout, [GridNode; 300]) {
        let layout = GridLayout::new(160, 120, 8).unwrap();
        let nodes = core::array::from_fn(|i| {
            let (col, row) = layout.node(i);
            let (x, y) = layout.centre(col, row);
            let (dx, dy) = flow(x as f32, y as f32);
            GridNode::tracked(Point::from_f32(dx, dy))
        });
        (layout, nodes)
    }

    fn assert_close(motion: &DominantMotion, truth: impl Fn(f32, f32) -> (f32, f32), tol: f32) {
        for (x, y) in [
            (0.0, 0.0),
            (159.0, 0.0),
            (0.0, 119.0),
            (80.0, 60.0),
            (159.0, 119.0),
        ] {
            let (px, py) = motion.flow_at(x, y);
            let (tx, ty) = truth(x, y);
            assert!(
                (px - tx).abs() < tol && (py - ty).abs() < tol,
                "({x}, {y}): {:?} vs {:?}",
                (px, py),
                (tx, ty)
            );
        }
    }

    /// A similarity about the frame centre: zoom 2%, roll 1 degree, pan (2, -1) px.
    fn camera(x: f32, y: f32) -> (f32, f32) {
        let (s, a) = (1.02f32, 1f32.to_radians());
        let (u, v) = (x - 79.5, y - 59.5);
        let (c, n) = (s * a.cos(), s * a.sin());
        (
            c * u - n * v + 79.5 + 2.0 - x,
            n * u + c * v + 59.5 - 1.0 - y,
        )
    }

    #[test]
    fn recovers_a_similarity_exactly() {
        let (layout, nodes) = nodes_with(camera);
        let fit = DominantMotion::fit(&layout, &nodes, &DominantFitParams::default()).unwrap();
        assert_eq!(fit.inliers, 300);
        assert_close(&fit.motion, camera, 1e-3);
    }

    #[test]
    fn ignores_a_quarter_of_outliers() {
        let (layout, mut nodes) = nodes_with(camera);
        for (i, node) in nodes.iter_mut().enumerate() {
            let (col, row) = layout.node(i);
            // A block of 9 x 8 nodes moving 4 px left of the camera, plus scattered junk.
            if (3..12).contains(&col) && (2..10).contains(&row) {
                node.flow.x -= crate::q16::Q16::from_num(4);
            } else if i % 17 == 0 {
                *node = GridNode::tracked(Point::from_f32(-30.0, 25.0));
            }
        }
        let fit = DominantMotion::fit(&layout, &nodes, &DominantFitParams::default()).unwrap();
        assert_close(&fit.motion, camera, 0.01);
        assert!(
            fit.inliers < 300 - 72 && fit.inliers > 200,
            "{}",
            fit.inliers
        );
    }

    #[test]
    fn degenerate_inputs_stay_finite() {
        let layout = GridLayout::new(160, 120, 8).unwrap();
        let none = [GridNode::EMPTY; 300];
        let fit = DominantMotion::fit(&layout, &none, &DominantFitParams::default()).unwrap();
        assert_eq!((fit.motion, fit.measured), (DominantMotion::ZERO, 0));
        // One measured row: collinear nodes fall back to a translation.
        let mut row = [GridNode::EMPTY; 300];
        for node in row.iter_mut().take(20) {
            *node = GridNode::tracked(Point::from_f32(0.5, 1.5));
        }
        let fit = DominantMotion::fit(&layout, &row, &DominantFitParams::default()).unwrap();
        assert_close(&fit.motion, |_, _| (0.5, 1.5), 1e-4);
        let bad = DominantFitParams {
            inlier_radius: f32::NAN,
            ..DominantFitParams::default()
        };
        assert_eq!(
            DominantMotion::fit(&layout, &row, &bad),
            Err(ConfigError::new("inlier_radius", Bound::Positive))
        );
    }

    #[test]
    fn spread_is_the_rms_of_the_inliers() {
        // Alternate nodes 0.3 px left and right of a pan; one far outlier.
        let (layout, mut nodes) =
            nodes_with(|x, _| (1.0 + if x % 16.0 < 8.0 { 0.3 } else { -0.3 }, 0.0));
        nodes[7] = GridNode::tracked(Point::from_f32(9.0, 9.0));
        let fit = DominantMotion::fit(&layout, &nodes, &DominantFitParams::default()).unwrap();
        assert_eq!(fit.inliers, 299);
        assert!((fit.spread - 0.3).abs() < 1e-3, "{}", fit.spread);
    }

    #[test]
    fn square_roots_are_accurate() {
        for x in [1e-6f32, 0.09, 2.25, 1.0, 3.0, 1e6] {
            let r = sqrt(x);
            assert!((r * r - x).abs() <= 1e-5 * x, "{x}: {r}");
        }
        assert_eq!((sqrt(0.0), sqrt(-1.0), sqrt(f32::NAN)), (0.0, 0.0, 0.0));
    }

    #[test]
    fn median_is_exact_on_q16_values() {
        let layout = GridLayout::new(24, 8, 8).unwrap();
        let nodes = [
            GridNode::tracked(Point::from_f32(-3.25, 0.0)),
            GridNode::tracked(Point::from_f32(7.5, 0.0)),
            GridNode::tracked(Point::from_f32(0.125, 0.0)),
        ];
        let measured = Measured::new(&layout, &nodes);
        assert_eq!(measured.median(|f| f.0), 0.125);
    }
}
