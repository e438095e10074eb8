//! Q16 pyramidal Lucas-Kanade (Bouguet's method).
//!
//! For each point, from the coarsest pyramid level to the finest: sample the window around the
//! point in the previous frame, build and invert its gradient matrix once, then iterate: sample
//! the next frame at the current estimate, compute the mismatch and step by `-G^-1 b`, until the
//! step is below `epsilon`, the steps start to oscillate, or `max_iterations` is reached. The
//! estimate, doubled, seeds the next finer level.
//!
//! Positions are Q16.16; window samples are grey x 32 with 14-bit bilinear weights; window sums
//! are exact integers (see the widths in `template.rs`). The defaults are OpenCV's:
//! 21 x 21 window, coarsest level 3, 30 iterations, epsilon 0.01 px, minimum eigenvalue 1e-4.
//!
//! ```
//! use kestrel::ImageView;
//! use kestrel::lk::{scratch_len, LkParams, LucasKanade, TrackStatus};
//! use kestrel::pyramid::{pyramid_storage_len, Pyramid};
//! use kestrel::Point;
//!
//! // A smooth blob, and the same blob 1.5 px to the right.
//! let blob = |cx: f32| -> [u8; 64 * 64] {
//!     core::array::from_fn(|i| {
//!         let (x, y) = ((i % 64) as f32 - cx, (i / 64) as f32 - 32.0);
//!         (250.0 / (1.0 + (x * x + y * y) / 40.0)) as u8
//!     })
//! };
//! let (a, b) = (blob(30.0), blob(31.5));
//! let mut storage_a = [0u8; pyramid_storage_len(64, 64, 2)];
//! let mut storage_b = [0u8; pyramid_storage_len(64, 64, 2)];
//! let prev = Pyramid::build(ImageView::packed(&a, 64, 64).unwrap(), 2, &mut storage_a).unwrap();
//! let next = Pyramid::build(ImageView::packed(&b, 64, 64).unwrap(), 2, &mut storage_b).unwrap();
//!
//! let lk = LucasKanade::new(LkParams { max_level: 2, ..LkParams::default() }).unwrap();
//! let mut scratch = [0i16; scratch_len(21)];
//! let track = lk.track_point(&prev, &next, Point::from_f32(27.0, 30.0), None, &mut scratch).unwrap();
//! assert_eq!(track.status, TrackStatus::Tracked);
//! let (x, y) = track.position.to_f32();
//! assert!((x - 28.5).abs() < 0.05 && (y - 30.0).abs() < 0.05);
//! ```

mod correlation;
// The padded loops LLVM vectorised for SIMD hosts before the row loops' innermost operations
// had SSE2 kernels (`crate::dsp`): kept in the tests as an independent reference that the
// row loops must match bit for bit.
#[cfg(test)]
mod flat;
mod rows;
mod template;
mod wide;
mod window;

use crate::config_error::bound_number;
use crate::frame::ImageView;
use crate::pyramid::Pyramid;
use crate::q16::{Point, Q16};
use crate::{Bound, ConfigError};
use correlation::Correlations;
use template::{Step, Template, TemplateError};
use window::{Loops, TemplateBuffers, TemplateOut, WindowOrigin};

/// The window loops of every target: one set, whose innermost operations (`crate::dsp::runs`)
/// are SSE2 on x86-64, SMLAD on the Cortex-M4 and portable Rust elsewhere.
type NativeLoops = rows::Rows;

/// The largest window side accepted.
pub const MAX_WINDOW: usize = 63;

/// The fields [`LucasKanade::new`] checks, as paths from settings that hold an [`LkParams`] in
/// a field named `lk` (the tracker's and the dense grid's): their refusals are named so.
pub(crate) const LK_PATHS: [&str; 5] = [
    "lk.window",
    "lk.max_level",
    "lk.max_iterations",
    "lk.epsilon",
    "lk.min_eigen_threshold",
];

/// `i16` scratch values one point needs for a `window` x `window` window.
///
/// The scratch holds the source pixels under a window, the template patch with its derivative
/// border, the template, its two gradients and the resampled next-frame window (the figure
/// allows rows padded to `window + 3` values, more than the window loops use); size it for the
/// largest window the application uses:
///
/// ```
/// use kestrel::lk::scratch_len;
/// static mut SCRATCH: [i16; scratch_len(21)] = [0; scratch_len(21)];
/// assert_eq!(scratch_len(21), 3_147);
/// ```
pub const fn scratch_len(window: usize) -> usize {
    // Rows padded to `window + 3`, as the tests' reference loops pad them: more than the window
    // loops need for every window, and the figure applications already size their scratch by.
    let pitch = window + 3;
    let source = (window + 3) * pitch + 1;
    let patch = (window + 2) * pitch + 2;
    source + patch + 4 * window * pitch
}

/// How brightness differences between the two frames are treated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Illumination {
    /// Classic LK: the next window must match the previous one grey level for grey level.
    Plain,
    /// Fit a gain and a bias per window and iteration (`J = a I + b`, `a` in `[1/4, 4]`): robust
    /// to auto-exposure and outdoor light changes. The residual is reported after the correction.
    #[default]
    GainBias,
}

/// Where the template window sits in the previous frame at each pyramid level.
///
/// ```
/// use kestrel::ImageView;
/// use kestrel::lk::{scratch_len, LkParams, LucasKanade, TemplatePlacement, TrackStatus};
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
/// use kestrel::Point;
///
/// // A smooth blob moving 1.5 px right, tracked from a point between pixels.
/// let blob = |cx: f32| -> [u8; 64 * 64] {
///     core::array::from_fn(|i| {
///         let (x, y) = ((i % 64) as f32 - cx, (i / 64) as f32 - 32.0);
///         (250.0 / (1.0 + (x * x + y * y) / 40.0)) as u8
///     })
/// };
/// let (a, b) = (blob(30.0), blob(31.5));
/// let mut storage = [[0u8; pyramid_storage_len(64, 64, 2)]; 2];
/// let [sa, sb] = &mut storage;
/// let prev = Pyramid::build(ImageView::packed(&a, 64, 64).unwrap(), 2, sa).unwrap();
/// let next = Pyramid::build(ImageView::packed(&b, 64, 64).unwrap(), 2, sb).unwrap();
/// let mut scratch = [0i16; scratch_len(21)];
/// let start = Point::from_f32(27.3, 30.6);
/// let mut track = |template| {
///     let params = LkParams { max_level: 2, template, ..LkParams::default() };
///     let lk = LucasKanade::new(params).unwrap();
///     let t = lk.track_point(&prev, &next, start, None, &mut scratch).unwrap();
///     assert_eq!(t.status, TrackStatus::Tracked);
///     t.position.to_f32()
/// };
/// // Under a translation both placements find the point 1.5 px further right.
/// for (x, y) in [track(TemplatePlacement::AtPoint), track(TemplatePlacement::NearestPixel)] {
///     assert!((x - 28.8).abs() < 0.05 && (y - 30.6).abs() < 0.05, "{x} {y}");
/// }
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TemplatePlacement {
    /// Centred on the point itself, interpolated between pixels (OpenCV's choice).
    #[default]
    AtPoint,
    /// Centred on the pixel nearest the point, and the displacement of that window is taken as
    /// the point's. Under locally rigid motion the flow is the same (the window moves by at most
    /// half a pixel), and the template needs no interpolation: its intensities and derivatives
    /// come straight from the pyramid level's pixels, which makes each template several times
    /// cheaper to prepare. Under rotation or zoom the flow half a pixel away differs slightly
    /// (by 0.01 px for a 2 % zoom), and the window holds other pixels, hence other noise: a
    /// little less accurate than [`TemplatePlacement::AtPoint`] (README, How the tracker
    /// works).
    NearestPixel,
}

/// Tracking parameters, with OpenCV's defaults.
///
/// A point is followed only where its window has the texture
/// [`LkParams::min_eigen_threshold`] asks for:
///
/// ```
/// use kestrel::ImageView;
/// use kestrel::lk::{scratch_len, LkParams, LucasKanade, TrackStatus};
/// use kestrel::pyramid::{pyramid_storage_len, Pyramid};
/// use kestrel::Point;
///
/// // A faint blob, 30 grey levels over its ground, moving 1 px right.
/// let blob = |cx: f32| -> [u8; 32 * 32] {
///     core::array::from_fn(|i| {
///         let (x, y) = ((i % 32) as f32 - cx, (i / 32) as f32 - 16.0);
///         (100.0 + 30.0 / (1.0 + (x * x + y * y) / 20.0)) as u8
///     })
/// };
/// let (a, b) = (blob(16.0), blob(17.0));
/// let mut storage = [[0u8; pyramid_storage_len(32, 32, 0)]; 2];
/// let [sa, sb] = &mut storage;
/// let prev = Pyramid::build(ImageView::packed(&a, 32, 32).unwrap(), 0, sa).unwrap();
/// let next = Pyramid::build(ImageView::packed(&b, 32, 32).unwrap(), 0, sb).unwrap();
/// let mut scratch = [0i16; scratch_len(21)];
/// let mut track = |min_eigen_threshold| {
///     let lk = LucasKanade::new(LkParams { min_eigen_threshold, ..LkParams::default() }).unwrap();
///     lk.track_point(&prev, &next, Point::from_f32(16.0, 16.0), None, &mut scratch).unwrap()
/// };
/// let t = track(LkParams::default().min_eigen_threshold);
/// assert_eq!(t.status, TrackStatus::Tracked);
/// assert!((t.position.to_f32().0 - 17.0).abs() < 0.1);
/// // Gradients of 5 grey levels per pixel are more than this blob has.
/// assert_eq!(track(25.0 / 1024.0).status, TrackStatus::LowTexture);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LkParams {
    /// Window side in pixels: odd, 3..=63.
    pub window: usize,
    /// Coarsest pyramid level used (0 = no pyramid). Clamped to the pyramids' depth.
    pub max_level: usize,
    /// Iterations per level, at least 1.
    pub max_iterations: u32,
    /// Stop when a step is shorter than this, in pixels (>= 0).
    pub epsilon: f32,
    /// Minimum eigenvalue of the gradient matrix divided by the window area, in OpenCV's scale
    /// (gradients of 1 grey level per pixel give 0.0009765625 = 1/1024); below it a point is
    /// [`TrackStatus::LowTexture`].
    pub min_eigen_threshold: f32,
    /// Brightness model between the frames.
    pub illumination: Illumination,
    /// Where the template is taken around the point.
    pub template: TemplatePlacement,
}

impl Default for LkParams {
    fn default() -> Self {
        Self {
            window: 21,
            max_level: 3,
            max_iterations: 30,
            epsilon: 0.01,
            min_eigen_threshold: 1e-4,
            illumination: Illumination::GainBias,
            template: TemplatePlacement::AtPoint,
        }
    }
}

/// Why a tracking call could not run at all (per-point problems are a [`TrackStatus`]
/// instead; refused settings are [`LucasKanade::new`]'s [`ConfigError`]).
///
/// ```
/// use kestrel::ImageView;
/// use kestrel::lk::{scratch_len, LkError, LkParams, LucasKanade};
/// use kestrel::pyramid::Pyramid;
/// use kestrel::{Bound, ConfigError, Point};
/// let (small, large) = ([0u8; 16 * 16], [0u8; 32 * 32]);
/// let a = Pyramid::build(ImageView::packed(&small, 16, 16).unwrap(), 0, &mut []).unwrap();
/// let b = Pyramid::build(ImageView::packed(&large, 32, 32).unwrap(), 0, &mut []).unwrap();
/// let lk = LucasKanade::new(LkParams { window: 7, ..LkParams::default() }).unwrap();
/// let p = Point::from_f32(8.0, 8.0);
/// let mut scratch = [0i16; scratch_len(7)];
/// assert_eq!(lk.track_point(&a, &b, p, None, &mut scratch), Err(LkError::FrameSizeMismatch));
/// // The scratch is sized once for the window, like a setting.
/// let short = lk.track_point(&a, &a, p, None, &mut scratch[..10]).unwrap_err();
/// let needed = ConfigError { field: "scratch", bound: Bound::MinLen(scratch_len(7)) };
/// assert_eq!(short, LkError::Config(needed));
/// assert_eq!(short.to_string(), "scratch must hold at least 473 elements");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LkError {
    /// The scratch buffer is shorter than [`scratch_len`] for the window (`"scratch"`).
    Config(ConfigError),
    /// The two pyramids were built from frames of different sizes.
    FrameSizeMismatch,
    /// Output or guess slices do not have one entry per point.
    LengthMismatch,
}

impl From<ConfigError> for LkError {
    fn from(e: ConfigError) -> Self {
        LkError::Config(e)
    }
}

impl core::fmt::Display for LkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LkError::Config(e) => e.fmt(f),
            LkError::FrameSizeMismatch => f.write_str("previous and next frames differ in size"),
            LkError::LengthMismatch => f.write_str("points, guesses and outputs differ in length"),
        }
    }
}

/// What happened to one point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrackStatus {
    /// Tracked: the position is the converged estimate inside the next frame.
    Tracked,
    /// The point, or its estimate in the next frame, is outside the frame.
    #[default]
    OutOfBounds,
    /// The window has too little texture (gradient matrix eigenvalue below the threshold).
    LowTexture,
    /// The iterations at full resolution ran out while the steps were still above epsilon.
    NotConverged,
}

/// The result for one point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PointTrack {
    /// Estimated position in the next frame (the last estimate when not tracked).
    pub position: Point,
    /// Whether the position can be trusted, and why not.
    pub status: TrackStatus,
    /// Mean absolute intensity residual over the window, grey levels (after the gain and bias
    /// correction in [`Illumination::GainBias`]); zero when the point was not tracked.
    pub residual: Q16,
}

impl PointTrack {
    /// True for [`TrackStatus::Tracked`].
    ///
    /// ```
    /// use kestrel::lk::{PointTrack, TrackStatus};
    /// assert!(!PointTrack::default().is_tracked());
    /// ```
    pub fn is_tracked(&self) -> bool {
        self.status == TrackStatus::Tracked
    }
}

/// One step shorter than this (0.01 px) cancelling the previous one is an oscillation.
const OSCILLATION: i64 = 655;

/// A validated Lucas-Kanade tracker configuration.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LucasKanade {
    params: LkParams,
    /// `epsilon²` in Q32 (squared Q16 raw units).
    epsilon_sq: i64,
    /// Minimum eigenvalue of the integer gradient matrix.
    min_eigen: u64,
}

impl LucasKanade {
    /// Validates `params`; a refusal names the field (`"window"`, `"max_level"`,
    /// `"max_iterations"`, `"epsilon"`, `"min_eigen_threshold"`) and its bound.
    ///
    /// ```
    /// use kestrel::lk::{LkParams, LucasKanade};
    /// use kestrel::{Bound, ConfigError};
    /// assert!(LucasKanade::new(LkParams::default()).is_ok());
    /// let even = LkParams { window: 20, ..LkParams::default() };
    /// let refused = LucasKanade::new(even).unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "window", bound: Bound::OddRange { min: 3, max: 63 } });
    /// assert_eq!(refused.to_string(), "window must be odd, 3 to 63");
    /// let nan = LkParams { epsilon: f32::NAN, ..LkParams::default() };
    /// assert_eq!(LucasKanade::new(nan).unwrap_err().to_string(), "epsilon must be a finite number >= 0");
    /// ```
    pub fn new(params: LkParams) -> Result<Self, ConfigError> {
        if params.window < 3 || params.window > MAX_WINDOW || params.window % 2 == 0 {
            let bound = Bound::OddRange {
                min: 3,
                max: bound_number(MAX_WINDOW),
            };
            return Err(ConfigError::new("window", bound));
        }
        if params.max_level > crate::pyramid::MAX_LEVEL {
            let bound = Bound::AtMost(bound_number(crate::pyramid::MAX_LEVEL));
            return Err(ConfigError::new("max_level", bound));
        }
        if params.max_iterations == 0 {
            return Err(ConfigError::new("max_iterations", Bound::AtLeast(1)));
        }
        if !params.epsilon.is_finite() || params.epsilon < 0.0 {
            return Err(ConfigError::new("epsilon", Bound::FiniteNonNegative));
        }
        let threshold = params.min_eigen_threshold;
        if !threshold.is_finite() || threshold < 0.0 {
            let bound = Bound::FiniteNonNegative;
            return Err(ConfigError::new("min_eigen_threshold", bound));
        }
        let epsilon = (params.epsilon.min(1000.0) * 65536.0) as i64;
        // OpenCV's threshold applies to λ_min(G) / (2^20 * area) with G in our integer scale.
        let area = (params.window * params.window) as f32;
        let min_eigen = (threshold * 1_048_576.0 * area).min(1e18) as u64;
        Ok(Self {
            params,
            epsilon_sq: epsilon * epsilon,
            min_eigen,
        })
    }

    /// The parameters this tracker was built with.
    ///
    /// ```
    /// use kestrel::lk::{Illumination, LkParams, LucasKanade};
    /// let params = LkParams { window: 9, illumination: Illumination::Plain, ..LkParams::default() };
    /// assert_eq!(*LucasKanade::new(params).unwrap().params(), params);
    /// ```
    pub fn params(&self) -> &LkParams {
        &self.params
    }

    /// The same tracker with its search starting at pyramid level `level` at the coarsest
    /// (and never coarser than its own `max_level`). When a point's motion is already known to
    /// within a pixel or so (predicted from its last step, or from a gyro), the coarse levels
    /// have nothing left to find and each one skipped saves a template and its iterations.
    ///
    /// ```
    /// use kestrel::lk::{LkParams, LucasKanade};
    /// let lk = LucasKanade::new(LkParams { max_level: 2, ..LkParams::default() }).unwrap();
    /// assert_eq!(lk.with_max_level(0).params().max_level, 0);
    /// assert_eq!(lk.with_max_level(5).params().max_level, 2);
    /// ```
    pub fn with_max_level(&self, level: usize) -> Self {
        let mut lk = *self;
        lk.params.max_level = level.min(self.params.max_level);
        lk
    }

    /// Tracks one point from `prev` to `next`.
    ///
    /// `guess` is an optional estimate of the point's position in `next` (for example predicted
    /// from a gyro); without one the search starts at the point itself. See the module example.
    pub fn track_point(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        point: Point,
        guess: Option<Point>,
        scratch: &mut [i16],
    ) -> Result<PointTrack, LkError> {
        self.check_inputs(prev, next, scratch)?;
        Ok(self.track::<NativeLoops>(prev, next, point, guess, scratch))
    }

    /// What both entry points require: scratch for the window, and frames of one size.
    fn check_inputs(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        scratch: &[i16],
    ) -> Result<(), LkError> {
        let needed = scratch_len(self.params.window);
        if scratch.len() < needed {
            return Err(LkError::Config(ConfigError::min_len("scratch", needed)));
        }
        if !prev.base().same_size(&next.base()) {
            return Err(LkError::FrameSizeMismatch);
        }
        Ok(())
    }

    /// Tracks every point of `points`, writing one result per point into `out`.
    ///
    /// `guesses`, when given, holds one predicted position per point.
    ///
    /// ```
    /// use kestrel::ImageView;
    /// use kestrel::lk::{scratch_len, LkParams, LucasKanade, PointTrack, TrackStatus};
    /// use kestrel::pyramid::Pyramid;
    /// use kestrel::Point;
    /// let flat = [90u8; 32 * 32];
    /// let frame = ImageView::packed(&flat, 32, 32).unwrap();
    /// let pyramid = Pyramid::build(frame, 0, &mut []).unwrap();
    /// let lk = LucasKanade::new(LkParams { max_level: 0, ..LkParams::default() }).unwrap();
    /// let points = [Point::from_f32(16.0, 16.0), Point::from_f32(-3.0, 5.0)];
    /// let mut out = [PointTrack::default(); 2];
    /// let mut scratch = [0i16; scratch_len(21)];
    /// lk.track_points(&pyramid, &pyramid, &points, None, &mut out, &mut scratch).unwrap();
    /// assert_eq!(out[0].status, TrackStatus::LowTexture);
    /// assert_eq!(out[1].status, TrackStatus::OutOfBounds);
    /// ```
    pub fn track_points(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        points: &[Point],
        guesses: Option<&[Point]>,
        out: &mut [PointTrack],
        scratch: &mut [i16],
    ) -> Result<(), LkError> {
        if out.len() != points.len() || guesses.is_some_and(|g| g.len() != points.len()) {
            return Err(LkError::LengthMismatch);
        }
        self.check_inputs(prev, next, scratch)?;
        for (i, (point, result)) in points.iter().zip(out.iter_mut()).enumerate() {
            let guess = guesses.and_then(|g| g.get(i)).copied();
            *result = self.track::<NativeLoops>(prev, next, *point, guess, scratch);
        }
        Ok(())
    }

    /// The per-point driver over the pyramid levels; arguments are already validated.
    fn track<L: Loops>(
        &self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        point: Point,
        guess: Option<Point>,
        scratch: &mut [i16],
    ) -> PointTrack {
        let base = prev.base();
        let start = (point.x.to_bits(), point.y.to_bits());
        let lost = |status, position| PointTrack {
            position,
            status,
            residual: Q16::ZERO,
        };
        if !inside(&base, start) {
            return lost(TrackStatus::OutOfBounds, point);
        }
        let top = self
            .params
            .max_level
            .min(prev.max_level())
            .min(next.max_level());
        let target = guess.unwrap_or(point);
        // The estimate lives in the current level's coordinates, Q16 raw bits.
        let mut estimate = (target.x.to_bits() >> top, target.y.to_bits() >> top);
        let mut outcome = LevelOutcome::Converged;
        let mut residual = 0;
        for level in (0..=top).rev() {
            let (Some(prev_level), Some(next_level)) = (prev.level(level), next.level(level))
            else {
                continue;
            };
            let centre = (start.0 >> level, start.1 >> level);
            let scale = Scale {
                centre,
                finest: level == 0,
            };
            (outcome, residual) =
                self.refine::<L>(&prev_level, &next_level, scale, &mut estimate, scratch);
            if level > 0 {
                estimate = (estimate.0.saturating_mul(2), estimate.1.saturating_mul(2));
            }
        }
        let position = Point::from_bits(estimate.0, estimate.1);
        let status = match outcome {
            LevelOutcome::LowTexture => TrackStatus::LowTexture,
            LevelOutcome::LeftFrame => TrackStatus::OutOfBounds,
            LevelOutcome::IterationsExhausted => TrackStatus::NotConverged,
            LevelOutcome::Converged if !inside(&next.base(), estimate) => TrackStatus::OutOfBounds,
            LevelOutcome::Converged => TrackStatus::Tracked,
        };
        if status != TrackStatus::Tracked {
            return lost(status, position);
        }
        PointTrack {
            position,
            status,
            residual: Q16::from_bits(residual),
        }
    }

    /// Iterates LK at one level, moving `estimate`; at the finest level also returns the mean
    /// absolute residual at the final estimate (Q16 grey levels) when it converged.
    #[inline(never)]
    fn refine<L: Loops>(
        &self,
        prev: &ImageView<'_>,
        next: &ImageView<'_>,
        scale: Scale,
        estimate: &mut (i32, i32),
        scratch: &mut [i16],
    ) -> (LevelOutcome, i32) {
        let (centre, offset) = match self.params.template {
            TemplatePlacement::AtPoint => (scale.centre, (0, 0)),
            TemplatePlacement::NearestPixel => {
                // The centre lies in the frame, far from the ends of the i32 range.
                let nearest = |v: i32| v.saturating_add(1 << 15) & !0xFFFF;
                let (x, y) = (nearest(scale.centre.0), nearest(scale.centre.1));
                ((x, y), (x - scale.centre.0, y - scale.centre.1))
            }
        };
        let Some((template, mut j)) = self.template::<L>(prev, centre, scratch) else {
            return (LevelOutcome::LowTexture, 0);
        };
        // The iterations move the template's window; the point moves with it.
        let mut window = (
            estimate.0.saturating_add(offset.0),
            estimate.1.saturating_add(offset.1),
        );
        let outcome = self.iterate(&template, next, &mut window, &mut j);
        *estimate = (
            window.0.saturating_sub(offset.0),
            window.1.saturating_sub(offset.1),
        );
        if outcome != LevelOutcome::Converged || !scale.finest {
            return (outcome, 0);
        }
        let origin = WindowOrigin::new(window.0, window.1, self.params.window / 2);
        let c = *j.correlations(&template, next, origin);
        (
            outcome,
            template.residual(next, &origin, &c, (j.source, j.values)),
        )
    }

    /// The LK iterations of one level.
    fn iterate<L: Loops>(
        &self,
        template: &Template<'_, L>,
        next: &ImageView<'_>,
        estimate: &mut (i32, i32),
        j: &mut NextWindow<'_>,
    ) -> LevelOutcome {
        let win = self.params.window;
        let mut previous: Option<Step> = None;
        for _ in 0..self.params.max_iterations {
            let origin = WindowOrigin::new(estimate.0, estimate.1, win / 2);
            if origin.misses(next, win) {
                return LevelOutcome::LeftFrame;
            }
            let step = template.step(j.correlations(template, next, origin), origin.w);
            estimate.0 = estimate.0.saturating_add(step.dx);
            estimate.1 = estimate.1.saturating_add(step.dy);
            let (sx, sy) = (i64::from(step.dx), i64::from(step.dy));
            if sx * sx + sy * sy <= self.epsilon_sq {
                return LevelOutcome::Converged;
            }
            if let Some(p) = previous {
                // Two steps that cancel: the estimate bounces around the optimum; settle midway.
                if (sx + i64::from(p.dx)).abs() < OSCILLATION
                    && (sy + i64::from(p.dy)).abs() < OSCILLATION
                {
                    estimate.0 = estimate.0.saturating_sub(step.dx / 2);
                    estimate.1 = estimate.1.saturating_sub(step.dy / 2);
                    return LevelOutcome::Converged;
                }
            }
            previous = Some(step);
        }
        LevelOutcome::IterationsExhausted
    }

    /// Samples the template around `centre` and prepares its solve; the rest of the scratch is
    /// returned for the next-frame window. `None` when the window lacks texture.
    fn template<'s, L: Loops>(
        &self,
        prev: &ImageView<'_>,
        centre: (i32, i32),
        scratch: &'s mut [i16],
    ) -> Option<(Template<'s, L>, NextWindow<'s>)> {
        let win = self.params.window;
        let layout = L::layout(win);
        let (source, rest) = scratch.split_at_mut(layout.source_len);
        let (patch, rest) = rest.split_at_mut(layout.patch_len);
        let (intensity, rest) = rest.split_at_mut(layout.window_len());
        let (dx, rest) = rest.split_at_mut(layout.window_len());
        let (dy, rest) = rest.split_at_mut(layout.window_len());
        let values = rest.get_mut(..layout.window_len())?;
        // The patch adds a one-pixel border for the derivatives.
        let origin = WindowOrigin::new(centre.0, centre.1, win / 2 + 1);
        let out = TemplateOut { intensity, dx, dy };
        let sums = L::template(prev, &origin, &layout, (source, patch), out);
        let buffers = TemplateBuffers { intensity, dx, dy };
        let illumination = self.params.illumination;
        match Template::new(buffers, sums, layout, illumination, self.min_eigen) {
            Ok(t) => Some((
                t,
                NextWindow {
                    source,
                    values,
                    at: None,
                    correlations: Correlations::default(),
                },
            )),
            Err(TemplateError::LowTexture) => None,
        }
    }
}

/// Scratch for the next frame's window at one level: its samples, the buffer its source pixels
/// may go through, and the correlations of the integer position last visited.
struct NextWindow<'s> {
    source: &'s mut [i16],
    values: &'s mut [i16],
    /// The integer position `correlations` belong to, if any.
    at: Option<(isize, isize)>,
    correlations: Correlations,
}

impl NextWindow<'_> {
    /// The correlations of the window at `origin` with the template: those of the last visit
    /// when the integer position is the same (they do not depend on the sub-pixel offset).
    ///
    /// The origin comes by value: on the usual path, a visit to the same position, it then
    /// stays in registers (read back from memory, its weights' four 2-byte stores would stall
    /// an x86-64 load of all four).
    fn correlations<L: Loops>(
        &mut self,
        template: &Template<'_, L>,
        frame: &ImageView<'_>,
        origin: WindowOrigin,
    ) -> &Correlations {
        let position = (origin.x, origin.y);
        if self.at != Some(position) {
            let (layout, t) = (template.layout(), template.buffers());
            self.correlations = L::correlate(frame, &origin, layout, self.source, t);
            self.at = Some(position);
        }
        &self.correlations
    }
}

/// The point's position at one pyramid level.
#[derive(Debug, Clone, Copy)]
struct Scale {
    /// The point in the previous frame, this level's coordinates, Q16 raw bits.
    centre: (i32, i32),
    /// True at full resolution.
    finest: bool,
}

/// How the iterations at one level ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LevelOutcome {
    Converged,
    LowTexture,
    LeftFrame,
    IterationsExhausted,
}

/// True when the Q16 position (raw bits) lies within the frame's pixel centres.
pub(crate) fn inside(frame: &ImageView<'_>, (x, y): (i32, i32)) -> bool {
    let max_x = ((frame.width() - 1) as i64) << 16;
    let max_y = ((frame.height() - 1) as i64) << 16;
    (0..=max_x).contains(&i64::from(x)) && (0..=max_y).contains(&i64::from(y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pyramid::pyramid_storage_len;

    const W: usize = 96;
    const H: usize = 72;

    /// Smooth texture with sharp features, shifted by `(dx, dy)` and brightened by `gain`.
    fn scene(dx: f32, dy: f32, gain: f32) -> [u8; W * H] {
        core::array::from_fn(|i| {
            let (x, y) = ((i % W) as f32 - dx, (i / W) as f32 - dy);
            let smooth = 60.0 * micromath::F32Ext::sin(0.31 * x + 0.17 * y)
                + 40.0 * micromath::F32Ext::cos(0.23 * y - 0.11 * x);
            let sharp = if (x * 0.25) as i32 % 3 == 0 && (y * 0.2) as i32 % 2 == 0 {
                50.0
            } else {
                0.0
            };
            ((110.0 + smooth + sharp) * gain).clamp(0.0, 255.0) as u8
        })
    }

    /// Every point of a grid that reaches past each border, tracked with both sets of window
    /// loops: the results agree bit for bit.
    /// Trackers for `window` and `max_level` in every illumination model and template
    /// placement.
    fn every_mode(window: usize, max_level: usize) -> impl Iterator<Item = LucasKanade> {
        let placements = [TemplatePlacement::AtPoint, TemplatePlacement::NearestPixel];
        [Illumination::GainBias, Illumination::Plain]
            .into_iter()
            .flat_map(move |illumination| placements.map(|template| (illumination, template)))
            .map(move |(illumination, template)| {
                LucasKanade::new(LkParams {
                    window,
                    max_level,
                    illumination,
                    template,
                    ..LkParams::default()
                })
                .unwrap()
            })
    }

    #[test]
    fn flat_and_row_loops_track_alike() {
        let (a, b) = (scene(0.0, 0.0, 1.0), scene(1.7, -0.8, 1.1));
        let mut storage_a = [0u8; pyramid_storage_len(W, H, 3)];
        let mut storage_b = [0u8; pyramid_storage_len(W, H, 3)];
        let frame = |px| ImageView::packed(px, W, H).unwrap();
        let prev = Pyramid::build(frame(&a), 3, &mut storage_a).unwrap();
        let next = Pyramid::build(frame(&b), 3, &mut storage_b).unwrap();
        let mut scratch = [0i16; scratch_len(21)];
        let mut tracked = 0;
        for (window, max_level) in [(3, 0), (7, 1), (9, 2), (9, 3), (21, 3)] {
            for lk in every_mode(window, max_level) {
                for y in (-2..H as i32 + 2).step_by(5) {
                    for x in (-2..W as i32 + 2).step_by(7) {
                        let p = Point::from_bits(x << 16 | 0x2a3b, y << 16 | 0x9c1);
                        let flat = lk.track::<flat::Flat>(&prev, &next, p, None, &mut scratch);
                        let rows = lk.track::<rows::Rows>(&prev, &next, p, None, &mut scratch);
                        assert_eq!(flat, rows, "window {window} level {max_level} at {p:?}");
                        tracked += usize::from(flat.is_tracked());
                    }
                }
            }
        }
        assert!(tracked > 2000, "only {tracked} tracked");
    }

    /// `scratch_len` covers the buffers of both sets of window loops for every window.
    #[test]
    fn scratch_len_fits_both_layouts() {
        for win in (3..=MAX_WINDOW).step_by(2) {
            for layout in [flat::Flat::layout(win), rows::Rows::layout(win)] {
                let needed = layout.source_len + layout.patch_len + 4 * layout.window_len();
                assert!(needed <= scratch_len(win), "window {win}: {layout:?}");
            }
        }
    }

    /// Full-contrast checks, the largest sums the window loops can meet, in the largest
    /// windows: both sets of loops give the same tracks (and neither overflows, which tests
    /// built with overflow checks would report).
    #[test]
    fn flat_and_row_loops_agree_at_full_contrast_in_large_windows() {
        const SIDE: usize = 160;
        let stripes = |shift: usize| -> [u8; SIDE * SIDE] {
            core::array::from_fn(|i| {
                let (x, y) = (i % SIDE + shift, i / SIDE);
                if (x / 2 + y / 2) % 2 == 0 {
                    255
                } else {
                    0
                }
            })
        };
        let (a, b) = (stripes(0), stripes(1));
        let frame = |px| ImageView::packed(px, SIDE, SIDE).unwrap();
        let prev = Pyramid::build(frame(&a), 0, &mut []).unwrap();
        let next = Pyramid::build(frame(&b), 0, &mut []).unwrap();
        let mut scratch = [0i16; scratch_len(MAX_WINDOW)];
        for window in [31, MAX_WINDOW] {
            for lk in every_mode(window, 0) {
                // On a pixel (the largest samples) and between pixels.
                for p in [Point::from_f32(80.0, 80.0), Point::from_f32(80.3, 79.6)] {
                    let flat = lk.track::<flat::Flat>(&prev, &next, p, None, &mut scratch);
                    let rows = lk.track::<rows::Rows>(&prev, &next, p, None, &mut scratch);
                    assert_eq!(flat, rows, "window {window} at {p:?}");
                    assert!(flat.is_tracked(), "{flat:?}");
                }
            }
        }
    }
}
