//! Deterministic, bounded-time robust estimation of the dominant motion (RANSAC).

use super::linalg::sqrt;
use super::model::{self, Correspondence, FitError, Homography, ModelKind, Pair, Pairs, Pick};
use crate::{Bound, ConfigError};

/// The generator seed used unless the parameters say otherwise: the seed decides which
/// samples are drawn.
///
/// ```
/// use kestrel::ego::{EgoStatus, ModelKind, Ransac, RansacParams, DEFAULT_SEED};
/// // 24 tracks shifted by (2, 1), and 16 scattered ones.
/// let tracks: [((f32, f32), (f32, f32)); 40] = core::array::from_fn(|i| {
///     let (x, y) = ((i % 8) as f32 * 20.0, (i / 8) as f32 * 20.0);
///     let off = if i % 5 < 3 { (2.0, 1.0) } else { ((i * 7 % 11) as f32 - 5.0, (i * 3 % 13) as f32) };
///     ((x, y), (x + off.0, y + off.1))
/// });
/// // One draw: it finds the consensus only when it picks one of the shifted tracks.
/// let one_draw = RansacParams { model: ModelKind::Translation, max_iterations: 1, ..Default::default() };
/// let run = |params| Ransac::new(params).unwrap().estimate(&tracks, &mut [false; 40]).unwrap();
/// let seeds: Vec<EgoStatus> = (0..16).map(|seed| run(RansacParams { seed, ..one_draw }).status).collect();
/// assert!(seeds.contains(&EgoStatus::Ok) && seeds.contains(&EgoStatus::NoConsensus));
/// assert_eq!(run(one_draw), run(RansacParams { seed: DEFAULT_SEED, ..one_draw }));
/// ```
pub const DEFAULT_SEED: u64 = 0x4B45_5354_5245_4C21;

/// Inliers from which the count no longer limits [`EgoMotion::quality`].
///
/// ```
/// use kestrel::ego::FULL_SUPPORT;
/// use kestrel::ego::{ModelKind, Ransac, RansacParams};
/// let ransac = Ransac::new(RansacParams { model: ModelKind::Translation, ..Default::default() })
///     .unwrap();
/// // Exact tracks, every one an inlier: only their count limits the quality.
/// let tracks: [((f32, f32), (f32, f32)); 40] = core::array::from_fn(|i| {
///     let (x, y) = ((i % 8) as f32 * 10.0, (i / 8) as f32 * 10.0);
///     ((x, y), (x + 1.0, y))
/// });
/// let quality = |n: usize| ransac.estimate(&tracks[..n], &mut [false; 40][..n]).unwrap().quality;
/// // A quarter of the full support: 255 / 4, rounded.
/// assert_eq!(quality(usize::from(FULL_SUPPORT) / 4), 64);
/// assert_eq!(quality(usize::from(FULL_SUPPORT)), 255);
/// assert_eq!(quality(40), 255);
/// ```
pub const FULL_SUPPORT: u16 = 32;

/// Least-squares refits after the sampling, at most: each one moves the inlier set towards the
/// consensus of the whole frame, and the set usually stops changing after two or three.
///
/// ```
/// use kestrel::ego::MAX_REFITS;
/// assert!(MAX_REFITS >= 2);
/// ```
pub const MAX_REFITS: usize = 8;

/// How a motion estimate came out.
///
/// ```
/// use kestrel::ego::{EgoMotion, EgoStatus, ModelKind};
/// let failed = EgoMotion::failed(ModelKind::Homography, EgoStatus::TooFewTracks);
/// assert_eq!(failed.quality, 0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EgoStatus {
    /// A model with enough support was found.
    Ok,
    /// Fewer tracks than the consensus minimum ([`RansacParams::min_inliers`], and at least one
    /// more than the model's minimal sample).
    TooFewTracks,
    /// The tracks cannot determine the model: they coincide (similarity and up), or lie on a
    /// line (affine and homography), all of them or those of the consensus.
    Degenerate,
    /// No model drawn gathered the consensus minimum of inliers.
    NoConsensus,
    /// Invalid input: a NaN, infinite or out-of-range coordinate or gyro value, or a zero or
    /// absurd frame interval.
    BadInput,
}

/// The dominant camera motion between two frames.
///
/// `model` maps pixel positions in the previous frame to the next one. When `status` is not
/// [`EgoStatus::Ok`], `model` is the identity and `inliers`, `rms_residual` and `quality` are 0.
/// Every field is finite.
///
/// `quality` (0..=255, as MAVLink's) is, for an `Ok` estimate with `k` inliers out of `n`
/// tracks, RMS inlier residual `r` and inlier threshold `t`:
///
/// `max(1, round(255 x (k / n) x min(1, k / FULL_SUPPORT) x (1 - (r / t)²)))`
///
/// The share says how dominant the motion is, the count how well it is determined, and the
/// residual how well it fits; an `Ok` estimate never scores 0, which MAVLink reserves for
/// invalid flow.
///
/// ```
/// use kestrel::ego::{EgoMotion, EgoStatus, Homography, ModelKind};
/// let m = EgoMotion::failed(ModelKind::Affine, EgoStatus::NoConsensus);
/// assert_eq!(m.model, Homography::IDENTITY);
/// assert!(!m.is_ok());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EgoMotion {
    /// Previous-frame pixels to next-frame pixels.
    pub model: Homography,
    /// The model that was fitted.
    pub kind: ModelKind,
    /// Tracks within the threshold of the final model.
    pub inliers: u16,
    /// RMS transfer error of the inliers, pixels.
    pub rms_residual: f32,
    /// Confidence 0..=255 (formula above); 0 unless `status` is `Ok`.
    pub quality: u8,
    /// Whether the estimate is usable, and why not.
    pub status: EgoStatus,
    /// Samples drawn, at most [`RansacParams::max_iterations`].
    pub iterations: u16,
}

impl EgoMotion {
    /// An unusable estimate: identity model, zero support and quality.
    ///
    /// ```
    /// use kestrel::ego::{EgoMotion, EgoStatus, ModelKind};
    /// let m = EgoMotion::failed(ModelKind::Translation, EgoStatus::BadInput);
    /// assert_eq!((m.inliers, m.rms_residual, m.quality), (0, 0.0, 0));
    /// ```
    pub fn failed(kind: ModelKind, status: EgoStatus) -> Self {
        Self {
            model: Homography::IDENTITY,
            kind,
            inliers: 0,
            rms_residual: 0.0,
            quality: 0,
            status,
            iterations: 0,
        }
    }

    /// True for [`EgoStatus::Ok`].
    ///
    /// ```
    /// use kestrel::ego::{EgoMotion, EgoStatus, ModelKind};
    /// assert!(!EgoMotion::failed(ModelKind::Homography, EgoStatus::Degenerate).is_ok());
    /// ```
    pub fn is_ok(&self) -> bool {
        self.status == EgoStatus::Ok
    }
}

/// Robust estimation parameters.
///
/// The threshold decides which tracks count as moving with the camera:
///
/// ```
/// use kestrel::ego::{ModelKind, Ransac, RansacParams};
/// // 20 tracks shifted by 1 px, and 6 shifted by 3 px.
/// let tracks: [((f32, f32), (f32, f32)); 26] = core::array::from_fn(|i| {
///     let (x, y) = ((i % 6) as f32 * 20.0, (i / 6) as f32 * 20.0);
///     ((x, y), (x + if i < 20 { 1.0 } else { 3.0 }, y))
/// });
/// let inliers = |threshold| {
///     let params = RansacParams { model: ModelKind::Translation, threshold, ..Default::default() };
///     Ransac::new(params).unwrap().estimate(&tracks, &mut [false; 26]).unwrap().inliers
/// };
/// assert_eq!(inliers(1.0), 20);
/// assert_eq!(inliers(3.0), 26);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RansacParams {
    /// The motion model.
    pub model: ModelKind,
    /// Inlier threshold on the transfer error, pixels: finite, in `(0, 1000]`.
    pub threshold: f32,
    /// Upper bound on the samples drawn, at least 1.
    pub max_iterations: u16,
    /// Probability of drawing at least one all-inlier sample before stopping early, in `(0, 1)`.
    pub confidence: f32,
    /// Inliers needed for a consensus (raised to the model's minimal sample plus one).
    pub min_inliers: u16,
    /// Seed of the sample generator.
    pub seed: u64,
}

impl Default for RansacParams {
    fn default() -> Self {
        Self {
            model: ModelKind::Homography,
            threshold: 1.0,
            max_iterations: 200,
            confidence: 0.995,
            min_inliers: 8,
            seed: DEFAULT_SEED,
        }
    }
}

/// Why an estimation could not run at all (problems with the data are an [`EgoStatus`]
/// instead; refused parameters are [`Ransac::new`]'s [`ConfigError`]).
///
/// ```
/// use kestrel::ego::{Ransac, RansacError, RansacParams};
/// let ransac = Ransac::new(RansacParams::default()).unwrap();
/// let tracks = [((1.0, 1.0), (2.0, 2.0)); 3];
/// assert_eq!(ransac.estimate(&tracks, &mut [false; 2]).unwrap_err(), RansacError::LengthMismatch);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RansacError {
    /// The inlier flags do not have one entry per track.
    LengthMismatch,
    /// More than 65535 tracks.
    TooManyTracks,
}

impl core::fmt::Display for RansacError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            RansacError::LengthMismatch => "inlier flags and tracks differ in length",
            RansacError::TooManyTracks => "at most 65535 tracks",
        })
    }
}

/// The largest inlier threshold accepted, pixels.
const MAX_THRESHOLD: f32 = 1000.0;
/// [`MAX_THRESHOLD`] as the bound a refusal names.
const THRESHOLD_BOUND: Bound = Bound::PositiveAtMost(1000);

/// Deterministic, bounded-time robust estimation of the dominant motion (RANSAC).
///
/// Each iteration draws a minimal sample with a seeded SplitMix64 generator, fits it exactly,
/// drops implausible models (mirrored, or folding a sample point over the horizon) and scores
/// the model by MSAC: the sum over all tracks of the squared transfer error, truncated at the
/// squared threshold. The lowest cost wins. After each improvement the iteration budget shrinks
/// to the usual `log(1 - confidence) / log(1 - w^s)` for inlier share `w` and sample size `s`,
/// never beyond [`RansacParams::max_iterations`]; every draw counts, degenerate ones too, so the
/// work is at most `max_iterations x tracks` transfer errors, plus [`MAX_REFITS`] refits of
/// four passes each.
///
/// The best model is then refined: a least-squares fit on its inliers, a new inlier pass, and
/// so on until the inlier set stops changing (at most [`MAX_REFITS`] fits), each fit kept only
/// if it does not raise the cost. The generator restarts from the seed on every call, so the
/// same tracks always give the same result, bit for bit, on the host and on the target alike.
///
/// ```
/// use kestrel::ego::{EgoStatus, ModelKind, Ransac, RansacParams};
/// // A 6 x 5 grid shifted by (1.5, -0.5), and two tracks on a moving object.
/// let mut tracks = [((0.0f32, 0.0f32), (0.0f32, 0.0f32)); 32];
/// for (i, t) in tracks.iter_mut().enumerate() {
///     let (x, y) = ((i % 6) as f32 * 20.0 + 10.0, (i / 6) as f32 * 20.0 + 10.0);
///     *t = ((x, y), (x + 1.5, y - 0.5));
/// }
/// tracks[30] = ((50.0, 50.0), (58.0, 50.0));
/// tracks[31] = ((60.0, 50.0), (68.0, 50.0));
///
/// let ransac = Ransac::new(RansacParams { model: ModelKind::Translation, ..Default::default() })
///     .unwrap();
/// let mut inliers = [false; 32];
/// let motion = ransac.estimate(&tracks, &mut inliers).unwrap();
/// assert_eq!(motion.status, EgoStatus::Ok);
/// assert_eq!(motion.inliers, 30);
/// assert!(!inliers[30] && !inliers[31]);
/// assert_eq!(motion.model.apply((0.0, 0.0)), Some((1.5, -0.5)));
/// ```
///
/// A validated robust estimator: parameters checked once, reused for every frame.
///
/// ```
/// use kestrel::ego::{ModelKind, Ransac, RansacParams};
/// let params = RansacParams { model: ModelKind::Similarity, threshold: 0.8, ..Default::default() };
/// let ransac = Ransac::new(params).unwrap();
/// assert_eq!(ransac.params().model, ModelKind::Similarity);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Ransac {
    params: RansacParams,
    threshold_sq: f32,
    /// `ln(1 - confidence)`, negative.
    log_miss: f32,
}

impl Ransac {
    /// Validates `params`; a refusal names `"threshold"`, `"max_iterations"` or
    /// `"confidence"`.
    ///
    /// ```
    /// use kestrel::ego::{Ransac, RansacParams};
    /// use kestrel::{Bound, ConfigError};
    /// assert!(Ransac::new(RansacParams::default()).is_ok());
    /// let p = RansacParams { confidence: 1.0, ..Default::default() };
    /// let refused = Ransac::new(p).unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "confidence", bound: Bound::Fraction });
    /// assert_eq!(refused.to_string(), "confidence must be a number above 0 and below 1");
    /// let bad = RansacParams { threshold: -1.0, ..Default::default() };
    /// let refused = Ransac::new(bad).unwrap_err();
    /// assert_eq!(refused.to_string(), "threshold must be a number above 0 and at most 1000");
    /// ```
    pub fn new(params: RansacParams) -> Result<Self, ConfigError> {
        let t = params.threshold;
        if !(t > 0.0 && t <= MAX_THRESHOLD) {
            return Err(ConfigError::new("threshold", THRESHOLD_BOUND));
        }
        if params.max_iterations == 0 {
            return Err(ConfigError::new("max_iterations", Bound::AtLeast(1)));
        }
        let c = params.confidence;
        if !(c > 0.0 && c < 1.0) {
            return Err(ConfigError::new("confidence", Bound::Fraction));
        }
        Ok(Self {
            params,
            threshold_sq: t * t,
            log_miss: libm::logf(1.0 - c),
        })
    }

    /// The parameters this estimator was built with.
    ///
    /// They are kept as given: a consensus still needs one track more than the model's minimal
    /// sample, whatever [`RansacParams::min_inliers`] says.
    ///
    /// ```
    /// use kestrel::ego::{EgoStatus, Ransac, RansacParams};
    /// let ransac = Ransac::new(RansacParams { min_inliers: 2, ..Default::default() }).unwrap();
    /// assert_eq!(ransac.params().min_inliers, 2);
    /// // Four exact tracks determine a homography but are no consensus for one.
    /// let four = [(0.0, 0.0), (50.0, 0.0), (0.0, 50.0), (50.0, 50.0)].map(|(x, y)| ((x, y), (x + 1.0, y)));
    /// let motion = ransac.estimate(&four, &mut [false; 4]).unwrap();
    /// assert_eq!(motion.status, EgoStatus::TooFewTracks);
    /// ```
    pub fn params(&self) -> &RansacParams {
        &self.params
    }

    /// Estimates the dominant motion of `pairs`, marking its inliers in `inliers` (all false
    /// unless the status is `Ok`). See the module example.
    ///
    /// ```
    /// use kestrel::ego::{EgoStatus, Ransac, RansacParams};
    /// let ransac = Ransac::new(RansacParams::default()).unwrap();
    /// let tracks = [((1.0, 1.0), (2.0, 2.0)); 3];
    /// let motion = ransac.estimate(&tracks, &mut [false; 3]).unwrap();
    /// assert_eq!((motion.status, motion.quality), (EgoStatus::TooFewTracks, 0));
    /// ```
    pub fn estimate<C: Correspondence>(
        &self,
        pairs: &[C],
        inliers: &mut [bool],
    ) -> Result<EgoMotion, RansacError> {
        if inliers.len() != pairs.len() {
            return Err(RansacError::LengthMismatch);
        }
        if pairs.len() > usize::from(u16::MAX) {
            return Err(RansacError::TooManyTracks);
        }
        inliers.fill(false);
        let motion = self.run(pairs, inliers);
        if !motion.is_ok() {
            inliers.fill(false);
        }
        Ok(motion)
    }

    /// The inliers a consensus needs.
    fn min_consensus(&self) -> usize {
        usize::from(self.params.min_inliers).max(self.params.model.min_samples().saturating_add(1))
    }

    fn run<C: Correspondence>(&self, pairs: &[C], flags: &mut [bool]) -> EgoMotion {
        let kind = self.params.model;
        let failed = |status, iterations| EgoMotion {
            iterations,
            ..EgoMotion::failed(kind, status)
        };
        if !pairs.iter().all(|c| Pair::of(c).is_valid()) {
            return failed(EgoStatus::BadInput, 0);
        }
        if pairs.len() < self.min_consensus() {
            return failed(EgoStatus::TooFewTracks, 0);
        }
        if model::is_degenerate(kind, Pairs::new(pairs, Pick::All)) {
            return failed(EgoStatus::Degenerate, 0);
        }
        let (best, iterations) = self.search(pairs);
        // No sample gave a plausible model: bad luck or no structure, not singular data.
        let Some(best) = best else {
            return failed(EgoStatus::NoConsensus, iterations);
        };
        if best.inliers < self.min_consensus() {
            return failed(EgoStatus::NoConsensus, iterations);
        }
        let model = match self.refine(pairs, flags, best.model) {
            Ok(model) => model,
            Err(status) => return failed(status, iterations),
        };
        let score = self.mark(pairs, &model, flags);
        if score.inliers < self.min_consensus() {
            return failed(EgoStatus::NoConsensus, iterations);
        }
        let rms = sqrt(score.inlier_error_sq / score.inliers as f32);
        EgoMotion {
            model,
            kind,
            inliers: u16::try_from(score.inliers).unwrap_or(u16::MAX),
            rms_residual: rms,
            quality: self.quality(score.inliers, pairs.len(), rms),
            status: EgoStatus::Ok,
            iterations,
        }
    }

    /// The sampling loop: the lowest-cost minimal-sample model, and the draws it took.
    fn search<C: Correspondence>(&self, pairs: &[C]) -> (Option<Candidate>, u16) {
        let kind = self.params.model;
        let size = kind.min_samples();
        let mut rng = SplitMix64::new(self.params.seed);
        let mut best: Option<Candidate> = None;
        let mut budget = self.params.max_iterations;
        let mut iterations = 0;
        while iterations < budget {
            iterations = iterations.saturating_add(1);
            let mut sample = [Pair::default(); 4];
            let indices = rng.sample(pairs.len(), size);
            for (slot, &index) in sample.iter_mut().zip(&indices) {
                if let Some(c) = pairs.get(index) {
                    *slot = Pair::of(c);
                }
            }
            // A model needs at most four pairs (`min_samples`), the sample's length.
            debug_assert!(size <= sample.len(), "{size} samples in {}", sample.len());
            let sample = sample.get(..size).unwrap_or(&[]);
            let chosen = indices.get(..size).unwrap_or(&[]);
            let Ok(model) = model::fit_pairs(kind, Pairs::new(pairs, Pick::Indices(chosen))) else {
                continue;
            };
            if !is_plausible(&model, sample) {
                continue;
            }
            let bound = best.as_ref().map_or(f32::INFINITY, |b| b.cost);
            if let Some((inliers, cost)) = self.score(pairs, &model, bound) {
                best = Some(Candidate {
                    model,
                    inliers,
                    cost,
                });
                budget = budget.min(self.iterations_needed(inliers, pairs.len()));
            }
        }
        (best, iterations)
    }

    /// Least-squares refits on the inliers, repeated while the inlier set changes (at most
    /// [`MAX_REFITS`] times) and kept only when they do not raise the cost; `flags` ends
    /// marking the inliers of the returned model.
    fn refine<C: Correspondence>(
        &self,
        pairs: &[C],
        flags: &mut [bool],
        mut model: Homography,
    ) -> Result<Homography, EgoStatus> {
        let mut cost = self.mark(pairs, &model, flags).cost;
        for _ in 0..MAX_REFITS {
            let selected = Pairs::new(pairs, Pick::Flagged(flags));
            let refit = match model::fit_pairs(self.params.model, selected) {
                Ok(refit) => refit,
                // The consensus set lies on a line: the data do not determine the model.
                Err(FitError::Degenerate) => return Err(EgoStatus::Degenerate),
                Err(_) => break,
            };
            match self.score(pairs, &refit, f32::INFINITY) {
                Some((_, refit_cost)) if refit_cost <= cost => {
                    model = refit;
                    let score = self.mark(pairs, &model, flags);
                    cost = score.cost;
                    if !score.changed {
                        break;
                    }
                }
                _ => break,
            }
        }
        Ok(model)
    }

    /// MSAC cost and inlier count of `model`; `None` as soon as the cost reaches `bound`.
    fn score<C: Correspondence>(
        &self,
        pairs: &[C],
        model: &Homography,
        bound: f32,
    ) -> Option<(usize, f32)> {
        let mut cost = 0.0f32;
        let mut inliers = 0usize;
        for c in pairs {
            let error_sq = model.transfer_error_sq(&Pair::of(c));
            if error_sq < self.threshold_sq {
                inliers = inliers.saturating_add(1);
                cost += error_sq;
            } else {
                cost += self.threshold_sq;
            }
            if cost >= bound {
                return None;
            }
        }
        Some((inliers, cost))
    }

    /// Writes the inlier flags of `model` and returns its score.
    fn mark<C: Correspondence>(
        &self,
        pairs: &[C],
        model: &Homography,
        flags: &mut [bool],
    ) -> Score {
        let mut score = Score::default();
        for (c, flag) in pairs.iter().zip(flags.iter_mut()) {
            let error_sq = model.transfer_error_sq(&Pair::of(c));
            let inlier = error_sq < self.threshold_sq;
            score.changed |= inlier != *flag;
            *flag = inlier;
            if inlier {
                score.inliers = score.inliers.saturating_add(1);
                score.inlier_error_sq += error_sq;
                score.cost += error_sq;
            } else {
                score.cost += self.threshold_sq;
            }
        }
        score
    }

    /// Samples needed to draw an all-inlier one with the configured confidence.
    fn iterations_needed(&self, inliers: usize, total: usize) -> u16 {
        let max = self.params.max_iterations;
        let share = inliers as f32 / total as f32;
        let all_inliers = (0..self.params.model.min_samples()).fold(1.0f32, |p, _| p * share);
        if all_inliers >= 1.0 {
            return 1;
        }
        let log_fail = libm::logf(1.0 - all_inliers);
        // Both logarithms are negative; a zero inlier share gives ln(1) = 0.
        let needed = libm::ceilf(self.log_miss / log_fail);
        if log_fail < 0.0 && needed < f32::from(max) {
            // Below u16::MAX here, and `as` saturates anyway.
            #[allow(clippy::cast_possible_truncation)]
            let needed = needed as u16;
            needed
        } else {
            max
        }
    }

    /// The quality figure documented on [`EgoMotion`].
    fn quality(&self, inliers: usize, total: usize, rms: f32) -> u8 {
        let share = inliers as f32 / total as f32;
        let support = (inliers as f32 / f32::from(FULL_SUPPORT)).min(1.0);
        let relative = rms / self.params.threshold;
        let fit = (1.0 - relative * relative).max(0.0);
        // `as` saturates, and maps NaN to 0.
        #[allow(clippy::cast_possible_truncation)]
        let quality = (255.0 * share * support * fit + 0.5) as u8;
        quality.max(1)
    }
}

/// True when the model keeps the image's orientation and every sample point in front of the
/// horizon: camera motion never mirrors the scene.
fn is_plausible(model: &Homography, sample: &[Pair]) -> bool {
    model.determinant() > 0.0 && sample.iter().all(|p| model.apply(p.prev).is_some())
}

/// The best model so far.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    model: Homography,
    inliers: usize,
    cost: f32,
}

#[derive(Debug, Clone, Copy, Default)]
struct Score {
    inliers: usize,
    cost: f32,
    inlier_error_sq: f32,
    /// Whether marking changed any flag.
    changed: bool,
}

/// SplitMix64 (Steele, Lea and Flood): tiny, fast and statistically sound for sampling.
#[derive(Debug, Clone, Copy)]
struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (Lemire's multiply-shift; the bias is below `n / 2³²`).
    fn below(&mut self, n: usize) -> usize {
        // Exact for every n below 2^32 (tracks are at most 65535).
        (((self.next_u64() >> 32).saturating_mul(n as u64)) >> 32) as usize
    }

    /// `size` (at most 4) distinct indices below `n`, ascending; `n >= size`.
    fn sample(&mut self, n: usize, size: usize) -> [usize; 4] {
        let mut chosen = [usize::MAX; 4];
        for k in 0..size.min(4) {
            // A rank among the indices not chosen yet, mapped to the index itself.
            let mut index = self.below(n.saturating_sub(k));
            for &c in chosen.iter().take(k) {
                if c <= index {
                    index = index.saturating_add(1);
                }
            }
            // Keep the chosen indices ascending (the rank mapping above relies on it): insert
            // the new one where it belongs, a step of insertion sort (k < 4).
            if let Some(slot) = chosen.get_mut(k) {
                *slot = index;
            }
            for (i, j) in (0..k).rev().zip((1..=k).rev()) {
                if chosen.get(i) <= chosen.get(j) {
                    break;
                }
                chosen.swap(i, j);
            }
        }
        chosen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_refusal_names_the_limit_the_check_uses() {
        assert_eq!(THRESHOLD_BOUND, Bound::PositiveAtMost(MAX_THRESHOLD as u32));
        let params = RansacParams {
            max_iterations: 0,
            ..RansacParams::default()
        };
        assert_eq!(
            Ransac::new(params).unwrap_err(),
            ConfigError::new("max_iterations", Bound::AtLeast(1))
        );
    }

    #[test]
    fn samples_are_distinct_and_in_range() {
        let mut rng = SplitMix64::new(7);
        let mut counts = [0u32; 6];
        for _ in 0..6000 {
            let s = rng.sample(6, 4);
            assert!(s.windows(2).all(|w| w[0] < w[1]), "{s:?}");
            for &i in &s {
                counts[i] += 1;
            }
        }
        // Each index is in 4 of 6 positions: 4000 expected.
        assert!(
            counts.iter().all(|&c| (3800..4200).contains(&c)),
            "{counts:?}"
        );
        assert_eq!(rng.sample(5, 1)[1..], [usize::MAX; 3]);
    }

    #[test]
    fn splitmix_matches_the_reference_sequence() {
        // First outputs of the reference implementation seeded with 1234567.
        let mut rng = SplitMix64::new(1_234_567);
        assert_eq!(rng.next_u64(), 6_457_827_717_110_365_317);
        assert_eq!(rng.next_u64(), 3_203_168_211_198_807_973);
    }

    #[test]
    fn adaptive_budget() {
        let ransac = Ransac::new(RansacParams::default()).unwrap();
        assert_eq!(ransac.iterations_needed(100, 100), 1);
        assert_eq!(ransac.iterations_needed(0, 100), 200);
        // w = 0.5, s = 4: ln(0.005) / ln(15/16) = 82.1.
        assert_eq!(ransac.iterations_needed(50, 100), 83);
    }

    #[test]
    fn quality_formula() {
        let ransac = Ransac::new(RansacParams::default()).unwrap();
        assert_eq!(ransac.quality(100, 100, 0.0), 255);
        assert_eq!(ransac.quality(16, 16, 0.0), 128);
        assert_eq!(ransac.quality(75, 100, 0.5), 143);
        assert_eq!(ransac.quality(10, 10_000, 0.99), 1);
    }
}
