//! Tracker settings, their defaults and their validation.

use super::appearance::AppearanceGate;
use crate::config_error::bound_number;
use crate::detect::{Fast, Grid, ShiTomasi};
use crate::lk::{Illumination, LkParams, LucasKanade, TemplatePlacement, LK_PATHS};
use crate::pyramid::{PyramidFilter, MAX_LEVEL};
use crate::q16::Q16;
use crate::{Bound, ConfigError};

/// The corner detector that starts new tracks.
///
/// ```
/// use kestrel::detect::{Corner, Fast};
/// use kestrel::lk::scratch_len;
/// use kestrel::track::{
///     detect_scratch_len, tracker_storage_len, Detector, Refill, Tracker, TrackerBuffers, TrackerConfig,
/// };
/// use kestrel::{Bound, ConfigError};
/// let config = TrackerConfig {
///     max_tracks: 4,
///     refill: Refill { below: 2, ..Refill::default() },
///     ..TrackerConfig::default()
/// };
/// let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
/// let mut lk_scratch = [0i16; scratch_len(21)];
/// let mut candidates = [Corner::default(); 4];
/// let mut make = |detector| {
///     let buffers = TrackerBuffers {
///         storage: &mut storage,
///         lk_scratch: &mut lk_scratch,
///         detect_scratch: &mut [],
///         candidates: &mut candidates,
///     };
///     let refill = Refill { detector, ..config.refill };
///     Tracker::<4>::new(TrackerConfig { refill, ..config }, 32, 32, buffers).map(|_| ())
/// };
/// // Shi-Tomasi, the default, needs detection scratch; FAST needs none.
/// let needed = Bound::MinLen(detect_scratch_len(32, 1, 4));
/// assert_eq!(make(Detector::default()), Err(ConfigError { field: "buffers.detect_scratch", bound: needed }));
/// assert_eq!(make(Detector::Fast(Fast::default())), Ok(()));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Detector {
    /// FAST-9: the cheapest, a handful of compares per pixel.
    Fast(Fast),
    /// Shi-Tomasi: the minimum eigenvalue of the structure tensor, the corners LK tracks best.
    ShiTomasi(ShiTomasi),
}

impl Default for Detector {
    /// Shi-Tomasi with OpenCV's block and quality level and no minimum distance of its own
    /// (the tracker spaces new corners with [`Refill::min_distance`]). On the
    /// half-resolution image detection runs on, FAST at its threshold of 10 finds too few
    /// corners in a 160 x 120 frame to keep 100 tracks.
    fn default() -> Self {
        Detector::ShiTomasi(ShiTomasi {
            min_distance: 0,
            ..ShiTomasi::default()
        })
    }
}

/// Everything a [`super::Tracker`] is told, in groups: LK, the number of tracks and the
/// pyramid, then where each search starts ([`Search`]), when a track is dropped ([`Gates`]),
/// when and where new tracks start ([`Refill`]) and how old tracks are brought back onto
/// their feature ([`Relocation`]).
///
/// The defaults suit 160 x 120 to 320 x 240 frames and 100 tracks:
///
/// ```
/// use kestrel::detect::Corner;
/// use kestrel::ImageView;
/// use kestrel::lk::scratch_len;
/// use kestrel::track::{
///     detect_scratch_len, tracker_storage_len, Tracker, TrackerBuffers, TrackerConfig,
/// };
/// use kestrel::{Bound, ConfigError};
///
/// const W: usize = 160;
/// const H: usize = 120;
/// let config = TrackerConfig::default();
/// let mut storage = vec![0u8; tracker_storage_len(W, H, config.pyramid_levels())];
/// let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
/// let mut detect_scratch = vec![0i32; detect_scratch_len(W, config.refill.level, 200)];
/// let mut candidates = vec![Corner::default(); 200];
/// let buffers = TrackerBuffers {
///     storage: &mut storage,
///     lk_scratch: &mut lk_scratch,
///     detect_scratch: &mut detect_scratch,
///     candidates: &mut candidates,
/// };
/// // A tracker of fewer tracks than the settings want refuses them at once.
/// let small = Tracker::<50>::new(config, W, H, buffers);
/// let fewer = ConfigError { field: "max_tracks", bound: Bound::Range { min: 1, max: 50 } };
/// assert_eq!(small.unwrap_err(), fewer);
/// let buffers = TrackerBuffers {
///     storage: &mut storage,
///     lk_scratch: &mut lk_scratch,
///     detect_scratch: &mut detect_scratch,
///     candidates: &mut candidates,
/// };
/// let mut tracker = Tracker::<100>::new(config, W, H, buffers).unwrap();
/// let texture: Vec<u8> = (0..W * H).map(|i| {
///     let (x, y) = (i % W, i / W);
///     ((x * 37 + y * 91 + (x * y) % 13 * 17) % 251) as u8
/// }).collect();
/// let frame = ImageView::packed(&texture, W, H).unwrap();
/// // Spread over the frame, the corners start most of the 100 tracks (88 on this texture),
/// // more than the 80 below which a frame detects new ones.
/// let started = tracker.start(frame).unwrap();
/// assert!(started.added >= config.refill.below);
/// let still = tracker.process(frame, frame, None).unwrap();
/// assert_eq!((still.tracked, still.detected), (started.added, false));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerConfig {
    /// Lucas-Kanade settings for following every track, forwards and backwards.
    pub lk: LkParams,
    /// The number of tracks the tracker aims for, `1..=N`.
    pub max_tracks: usize,
    /// How the tracker's pyramid levels are made (a dense grid that borrows them gets the
    /// same).
    pub pyramid: PyramidFilter,
    /// Where each track's search starts, and on which pyramid levels.
    pub search: Search,
    /// When a followed track is dropped.
    pub gates: Gates,
    /// When new corners are detected, and where new tracks may start.
    pub refill: Refill,
    /// How old tracks are moved back onto the feature they were born on.
    pub relocation: Relocation,
}

/// Where each track's search starts, and on which pyramid levels: a search that starts close
/// to its answer converges in fewer iterations and needs fewer levels.
///
/// ```
/// use kestrel::track::{Search, TrackerConfig};
/// # use kestrel::detect::Corner;
/// # use kestrel::ImageView;
/// # use kestrel::lk::scratch_len;
/// # use kestrel::track::{detect_scratch_len, tracker_storage_len, Track, Tracker, TrackerBuffers};
/// # const W: usize = 64;
/// # const H: usize = 48;
/// # // Smooth blobs, `shift` px to the right.
/// # let scene = |shift: f32| -> Vec<u8> {
/// #     (0..W * H).map(|i| {
/// #         let (x, y) = ((i % W) as f32 - shift, (i / W) as f32);
/// #         (128.0 + 50.0 * (0.45 * x).sin() * (0.38 * y).cos() + 30.0 * (0.21 * (x + y)).sin()) as u8
/// #     }).collect()
/// # };
/// # // The tracks after a tracker of `config` has followed them through `frames`.
/// # let run = |config: TrackerConfig, frames: &[Vec<u8>]| -> Vec<Track> {
/// #     let mut storage = vec![0u8; tracker_storage_len(W, H, config.pyramid_levels())];
/// #     let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
/// #     let mut detect_scratch = vec![0i32; detect_scratch_len(W, config.refill.level, 24)];
/// #     let mut candidates = vec![Corner::default(); 24];
/// #     let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #         detect_scratch: &mut detect_scratch, candidates: &mut candidates };
/// #     let mut tracker = Tracker::<12>::new(config, W, H, buffers).unwrap();
/// #     let views: Vec<_> = frames.iter().map(|f| ImageView::packed(f, W, H).unwrap()).collect();
/// #     tracker.start(views[0]).unwrap();
/// #     for pair in views.windows(2) {
/// #         tracker.process(pair[0], pair[1], None).unwrap();
/// #     }
/// #     tracker.tracks().to_vec()
/// # };
/// let mut config = TrackerConfig::default();
/// config.max_tracks = 12;
/// config.refill.below = 8;
/// // The scene moves 1.5 px to the right every frame.
/// let frames = [scene(0.0), scene(1.5), scene(3.0)];
/// // How far each track's second step landed from where its search started.
/// let misses = |search: Search| -> Vec<f32> {
///     let tracks = run(TrackerConfig { search, ..config }, &frames);
///     tracks.iter().filter(|t| t.age == 2).map(|t| t.prediction_error.to_num()).collect()
/// };
/// // The first step, repeated, predicts the second...
/// let predicted = misses(Search::default());
/// assert!(!predicted.is_empty() && predicted.iter().all(|&miss| miss < 0.1));
/// // ...which otherwise starts at the track's position, a whole step away.
/// let still = misses(Search { constant_velocity: false, ..Search::default() });
/// assert!(!still.is_empty() && still.iter().all(|&miss| (miss - 1.5).abs() < 0.1));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Search {
    /// Without a caller's prediction, each track's search starts where its latest step's
    /// displacement predicts (constant velocity) instead of at its position. It assumes the
    /// image's motion changes little from one frame to the next, as at a flight controller's
    /// frame rates; a track's first step, with no displacement yet, starts from the median of
    /// the other tracks' steps.
    pub constant_velocity: bool,
    /// Reach of the finest level, px: a track whose latest step landed within this distance
    /// of its prediction ([`super::Track::prediction_error`]) is searched on pyramid level 0
    /// only, within twice this from level 1, and so on up to `lk.max_level`; a track without
    /// a prediction on the whole pyramid. A search that fails, or lands more than twice its
    /// starting level's reach from its start, is repeated on the whole pyramid. Every level
    /// skipped saves a template and its iterations. A number >= 0; 0 always searches the
    /// whole pyramid, infinity starts every predicted track on level 0.
    pub fine_reach: f32,
}

impl Search {
    /// The default: constant velocity, and a reach of 1 px on the finest level.
    const DEFAULT: Self = Self {
        constant_velocity: true,
        fine_reach: 1.0,
    };
}

impl Default for Search {
    /// Constant velocity, and a reach of 1 px on the finest level.
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// When a followed track is dropped: the cheap gates on every step (its residual, absolute
/// and relative to the frame's, and its appearance against its birth patch), then the
/// forward-backward check on a schedule and on every doubtful step.
///
/// A forward-backward check alone passes a window stuck on a flat or occluded region (it
/// moves nowhere both ways); the residual gates catch that, and the appearance gate a window
/// that slides off its feature a little every frame.
///
/// ```
/// use kestrel::track::{Gates, TrackerConfig};
/// # use kestrel::detect::Corner;
/// # use kestrel::ImageView;
/// # use kestrel::lk::scratch_len;
/// # use kestrel::track::{detect_scratch_len, tracker_storage_len, FrameReport, Tracker, TrackerBuffers};
/// # const W: usize = 64;
/// # const H: usize = 48;
/// # // Smooth blobs, `shift` px to the right.
/// # let scene = |shift: f32| -> Vec<u8> {
/// #     (0..W * H).map(|i| {
/// #         let (x, y) = ((i % W) as f32 - shift, (i / W) as f32);
/// #         (128.0 + 50.0 * (0.45 * x).sin() * (0.38 * y).cos() + 30.0 * (0.21 * (x + y)).sin()) as u8
/// #     }).collect()
/// # };
/// # // The report of the second frame of a tracker of `config`.
/// # let run = |config: TrackerConfig, first: &[u8], second: &[u8]| -> FrameReport {
/// #     let mut storage = vec![0u8; tracker_storage_len(W, H, config.pyramid_levels())];
/// #     let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
/// #     let mut detect_scratch = vec![0i32; detect_scratch_len(W, config.refill.level, 24)];
/// #     let mut candidates = vec![Corner::default(); 24];
/// #     let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #         detect_scratch: &mut detect_scratch, candidates: &mut candidates };
/// #     let mut tracker = Tracker::<12>::new(config, W, H, buffers).unwrap();
/// #     let (first, second) = (ImageView::packed(first, W, H).unwrap(), ImageView::packed(second, W, H).unwrap());
/// #     tracker.start(first).unwrap();
/// #     tracker.process(first, second, None).unwrap()
/// # };
/// let mut config = TrackerConfig::default();
/// config.max_tracks = 12;
/// config.refill.below = 0;
/// // The scene moves 1.5 px to the right and a flat grey board covers its left half.
/// let first = scene(0.0);
/// let mut second = scene(1.5);
/// second.chunks_mut(W).for_each(|row| row[..W / 2].fill(128));
/// let report = |gates: Gates| run(TrackerConfig { gates, ..config }, &first, &second);
/// // The tracks under the board no longer look like their feature: the gates drop them.
/// let gated = report(Gates::default());
/// assert!(gated.dropped_residual + gated.dropped_appearance > 0);
/// // With every gate off, LK's answer on the board is kept.
/// let open = report(Gates {
///     fb_threshold: f32::INFINITY,
///     max_residual: f32::INFINITY,
///     residual_ratio: f32::INFINITY,
///     min_correlation: -1.0,
///     ..Gates::default()
/// });
/// assert_eq!(open.dropped_residual + open.dropped_appearance + open.dropped_fb, 0);
/// assert!(open.tracked > gated.tracked);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Gates {
    /// Forward-backward gate, px: a track whose way back from its new position misses its old
    /// position by more than this is dropped. A number >= 0; infinity turns the check, and
    /// the backward tracking it costs, off.
    pub fb_threshold: f32,
    /// Forward-backward schedule, frames, at least 1: the backward check runs on every track
    /// at least once in this many frames (tracks take turns by id), and on every step that
    /// looks doubtful: a track's first step, a step that lands more than
    /// [`Gates::fb_doubt`] from its prediction, and one whose search fell back on the whole
    /// pyramid (searched again from the caller's prediction, or from the track's position
    /// without one). It assumes a step that agrees with its track's own motion is rarely
    /// wrong: the way back costs as much as the way forth. 1 checks every step.
    pub fb_every: u32,
    /// Distance from its prediction, px, beyond which a step is doubtful and checked
    /// forward-backward (see [`Gates::fb_every`]). A number >= 0; infinity leaves only the
    /// first steps, the fallbacks and the schedule.
    pub fb_doubt: f32,
    /// Residual gate, grey levels: a track whose window, after the gain and bias correction,
    /// differs from the previous frame's by more than this on average is dropped. It catches
    /// what the forward-backward check cannot: a window stuck on an occluder moves nowhere in
    /// both directions. A number >= 0; infinity turns it off.
    pub max_residual: f32,
    /// Relative residual gate: a track whose residual is more than this many times the
    /// median residual of the frame's tracks (taken as at least one grey level) is dropped.
    /// The median measures what noise, blur and interpolation cost every track in this frame,
    /// so the gate follows the camera: an occluder edge entering a window stands out from it
    /// before it reaches [`Gates::max_residual`]. Tracks whose step goes more than 1 px from
    /// the frame's median step (on movers, before a still or steadily moving background) are
    /// also judged against their own median when at least five are, and held to the larger
    /// limit: a walker's body bends and blurs, and its tracks' residuals are not the ground's.
    /// A track that has made four steps is also allowed this many times its own usual residual
    /// ([`super::Track::usual_residual`]) when that is higher, up to [`Gates::max_residual`]:
    /// a window's texture decides what noise and blur cost it, and what the gate looks for is
    /// a jump above the track's own past. A number >= 0; infinity turns it off.
    pub residual_ratio: f32,
    /// Appearance gate: a track whose neighbourhood (7 x 7 samples, 2 px apart) correlates
    /// less than this with its neighbourhood in its first frame is dropped (zero-mean
    /// normalised cross-correlation, so lighting does not matter). It catches a window that
    /// slides off its feature a little every frame, as when an occluder's edge pushes it:
    /// each step matches its previous frame, so no other gate sees it. A fine texture (grass,
    /// gravel, a sensor's noise and aliasing) decorrelates from itself when sampled at another
    /// sub-pixel phase, as every step samples it: while the image has not turned since its
    /// birth, a track is held to this times what its own patch keeps half a pixel off (at
    /// least half of it), measured at birth. At most 1; -1 or less turns it off.
    pub min_correlation: f32,
    /// The appearance gate's floor: on a frame whose tracks' likeness to their birth patches
    /// spreads widely (leaves in the wind, a face that talks, a compressed clip's blocks), the
    /// gate drops only the tracks that stand out below the others, more than six median
    /// absolute deviations below the frame's median, and those below this correlation: what
    /// the frame's tracks look like says what it does to a correct track. A track that
    /// passes [`Gates::min_correlation`] always passes; while the tracks agree, as over still
    /// ground that a walker crosses, that threshold is the gate. Likeness is measured as the
    /// gate measures it, a squared correlation over what resampling leaves each track's
    /// texture. Tracks whose image has turned or zoomed since their birth are held to the
    /// threshold and left out of the frame's spread: there the gate is what stops LK's drift.
    /// At most 1; [`Gates::min_correlation`] or more keeps the gate fixed, -1 or less leaves
    /// only the frame's spread.
    ///
    /// ```
    /// use kestrel::track::{Gates, TrackerConfig};
    /// # use kestrel::detect::Corner;
    /// # use kestrel::ImageView;
    /// # use kestrel::lk::scratch_len;
    /// # use kestrel::track::{detect_scratch_len, tracker_storage_len, Tracker, TrackerBuffers};
    /// # const W: usize = 96;
    /// # const H: usize = 72;
    /// // Smooth blobs moving 0.5 px a frame to the right, which over ten frames turn into
    /// // stripes: not at all at the left edge, 80 % of the way at the right edge.
    /// let frame = |k: usize| -> Vec<u8> {
    ///     (0..W * H).map(|i| {
    ///         let (x, y) = ((i % W) as f32, (i / W) as f32);
    ///         let x = x - 0.5 * k as f32;
    ///         let blobs = 128.0 + 50.0 * (0.45 * x).sin() * (0.38 * y).cos() + 30.0 * (0.21 * (x + y)).sin();
    ///         let stripes = 128.0 + 40.0 * (0.9 * x + 0.5 * y).sin();
    ///         let turned = 0.8 * (k as f32 / 10.0) * (i % W) as f32 / W as f32;
    ///         ((1.0 - turned) * blobs + turned * stripes) as u8
    ///     }).collect()
    /// };
    /// // The appearance drops over the ten frames, and how far the live tracks are from where
    /// // the motion took them, with the gates `gates`.
    /// let run = |gates: Gates| -> (usize, f32) {
    ///     let mut config = TrackerConfig { max_tracks: 40, gates, ..TrackerConfig::default() };
    ///     config.refill.below = 0;
    /// #   let mut storage = vec![0u8; tracker_storage_len(W, H, config.pyramid_levels())];
    /// #   let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
    /// #   let mut detect_scratch = vec![0i32; detect_scratch_len(W, config.refill.level, 60)];
    /// #   let mut candidates = vec![Corner::default(); 60];
    /// #   let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #       detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// #   let mut tracker = Tracker::<40>::new(config, W, H, buffers).unwrap();
    ///     // ... a tracker of `config` started on frame 0 and given frames 1 to 10 ...
    /// #   let frames: Vec<Vec<u8>> = (0..=10).map(frame).collect();
    /// #   let view = |k: usize| ImageView::packed(&frames[k], W, H).unwrap();
    /// #   tracker.start(view(0)).unwrap();
    /// #   let born: Vec<_> = tracker.tracks().iter().map(|t| (t.id, t.position.to_f32())).collect();
    /// #   let mut dropped = 0;
    /// #   for k in 1..=10 {
    /// #       dropped += tracker.process(view(k - 1), view(k), None).unwrap().dropped_appearance;
    /// #   }
    /// #   let worst = tracker.tracks().iter().map(|t| {
    /// #       let (_, (x, y)) = born.iter().find(|(id, _)| *id == t.id).unwrap();
    /// #       let (nx, ny) = t.position.to_f32();
    /// #       ((nx - x - 5.0).powi(2) + (ny - y).powi(2)).sqrt()
    /// #   }).fold(0.0f32, f32::max);
    /// #   (dropped, worst)
    /// };
    /// // A fixed gate drops the tracks whose texture changed most, right as they are.
    /// let (fixed, fixed_worst) = run(Gates { least_correlation: 0.8, ..Gates::default() });
    /// // The frame's tracks spread from unchanged to much changed: the gate follows them down.
    /// let (adaptive, adaptive_worst) = run(Gates::default());
    /// assert!(fixed >= 10 && adaptive <= fixed / 2);
    /// // The tracks it keeps are where the motion took them, within 0.35 px (measured: 12
    /// // drops, worst 0.18 px, against 6 and 0.27 px).
    /// assert!(fixed_worst < 0.25 && adaptive_worst < 0.35);
    /// ```
    pub least_correlation: f32,
}

impl Gates {
    /// The default gates.
    const DEFAULT: Self = Self {
        fb_threshold: 1.0,
        fb_every: 8,
        fb_doubt: 0.25,
        max_residual: 12.0,
        residual_ratio: 3.0,
        min_correlation: 0.8,
        least_correlation: 0.6,
    };
}

impl Default for Gates {
    /// A forward-backward gate of 1 px, checked once in 8 frames and on steps more than
    /// 0.25 px from their prediction; residuals up to 12 grey levels and 3 times the frame's
    /// median; a correlation of 0.8 with the birth patch, lowered as far as 0.6 on a frame
    /// whose tracks spread widely.
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// When new corners are detected, and where new tracks may start: away from the frame's
/// edges, from the live tracks and from each other, spread over the frame by a grid.
///
/// ```
/// use kestrel::track::{Refill, TrackerConfig};
/// # use kestrel::detect::Corner;
/// # use kestrel::ImageView;
/// # use kestrel::lk::scratch_len;
/// # use kestrel::track::{detect_scratch_len, tracker_storage_len, FrameReport, Tracker, TrackerBuffers};
/// # const W: usize = 160;
/// # const H: usize = 120;
/// # let texture: Vec<u8> = (0..W * H).map(|i| {
/// #     let (x, y) = (i % W, i / W);
/// #     ((x * 37 + y * 91 + (x * y) % 13 * 17) % 251) as u8
/// # }).collect();
/// # let frame = ImageView::packed(&texture, W, H).unwrap();
/// # // The reports of a tracker of `config` started on the texture and shown it again.
/// # let run = |config: TrackerConfig| -> (FrameReport, FrameReport) {
/// #     let mut storage = vec![0u8; tracker_storage_len(W, H, config.pyramid_levels())];
/// #     let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
/// #     let mut detect_scratch = vec![0i32; detect_scratch_len(W, config.refill.level, 200)];
/// #     let mut candidates = vec![Corner::default(); 200];
/// #     let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #         detect_scratch: &mut detect_scratch, candidates: &mut candidates };
/// #     let mut tracker = Tracker::<100>::new(config, W, H, buffers).unwrap();
/// #     let started = tracker.start(frame).unwrap();
/// #     (started, tracker.process(frame, frame, None).unwrap())
/// # };
/// let refilled = |refill: Refill| run(TrackerConfig { refill, ..TrackerConfig::default() });
/// // The texture starts most of the 100 tracks, more than the 80 below which new corners are
/// // detected; a still frame keeps them all and detects none.
/// let (started, still) = refilled(Refill::default());
/// assert!(started.added >= 80 && started.added < 100);
/// assert!(!still.detected);
/// // Asked to keep all 100, the tracker detects again at once.
/// let (_, topped_up) = refilled(Refill { below: 100, ..Refill::default() });
/// assert!(topped_up.detected);
/// // One track at most in each of the grid's 8 x 6 cells.
/// let mut sparse = Refill::default();
/// sparse.grid.per_cell = 1;
/// assert!(refilled(sparse).0.added <= 48);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Refill {
    /// New corners are detected when fewer than this many tracks are live after a frame,
    /// `0..=max_tracks`; 0 detects only on [`super::Tracker::start`].
    pub below: usize,
    /// The detector that starts new tracks.
    pub detector: Detector,
    /// The pyramid level detection runs on (0 = full resolution), at most [`MAX_LEVEL`].
    /// Each level up divides the cost of detection by four, and corners found there start
    /// tracks at twice, four times... their coordinates; a level too small for the frame
    /// finds too few corners to fill the tracks.
    pub level: usize,
    /// Bucketing of new corners over the frame; live tracks count against their cell.
    pub grid: Grid,
    /// New corners keep this far from the frame's edges, px at full resolution.
    pub border: u16,
    /// New corners keep this far from live tracks and from each other, px at full resolution
    /// (a square of this radius, rounded out to the exclusion mask's cells).
    pub min_distance: u16,
    /// For this many frames no new track starts within twice `min_distance` of where a track
    /// failed a gate in its first four frames; 0 turns it off. Such a spot holds a
    /// feature that changes faster than a track can follow (a walker's limbs, a talking face,
    /// leaves in the wind): it is often the strongest corner around, so without a pause each
    /// refill starts a track there again, which fails again a frame or two later. When the
    /// cooldown is not 0, a new corner must also have arrived from the frame before as a track
    /// would have: its window, followed back into that frame, passes the residual gate the
    /// frame's tracks were held to ([`super::FrameReport::refused`] counts those that do not,
    /// whose spots are marked in turn). It costs one LK step per corner tried; without it,
    /// most of the tracks a still camera over a street starts after its first frame are on
    /// walkers and end on their first step.
    pub cooldown: u16,
    /// On a camera that moves, frames: a corner that the frame's median step would carry to
    /// within `border` of the frame's edge within this many frames starts no track, and takes
    /// no place in the grid (the step taken at most a quarter of the frame across, so that a
    /// fast pan still spreads its tracks). Such a track would live a few frames and its slot
    /// would be refilled soon after, while a corner deeper in the view is followed for as long
    /// as the view keeps it. Only when the median step is at least half a pixel: a still
    /// camera's median step is noise, and a corner by the edge lives as long as any. 0 turns
    /// it off.
    ///
    /// ```
    /// use kestrel::track::{Refill, TrackerConfig};
    /// # use kestrel::detect::Corner;
    /// # use kestrel::ImageView;
    /// # use kestrel::lk::scratch_len;
    /// # use kestrel::track::{detect_scratch_len, tracker_storage_len, Tracker, TrackerBuffers};
    /// # const W: usize = 160;
    /// # const H: usize = 120;
    /// # // Smooth texture moved `shift` px to the right.
    /// # let scene = |shift: f32| -> Vec<u8> {
    /// #     (0..W * H).map(|i| {
    /// #         let (x, y) = ((i % W) as f32 - shift, (i / W) as f32);
    /// #         (128.0 + 60.0 * (0.31 * x).sin() * (0.27 * y).cos() + 40.0 * (0.13 * (x - y)).sin()) as u8
    /// #     }).collect()
    /// # };
    /// // The x of every track started after the first frame of a scene moving 2 px a frame to
    /// // the right, with a tracker of `refill`.
    /// let started_at = |refill: Refill| -> Vec<f32> {
    ///     let refill = Refill { below: 54, ..refill };
    ///     let config = TrackerConfig { max_tracks: 60, refill, ..TrackerConfig::default() };
    /// #   let mut storage = vec![0u8; tracker_storage_len(W, H, config.pyramid_levels())];
    /// #   let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
    /// #   let mut detect_scratch = vec![0i32; detect_scratch_len(W, config.refill.level, 200)];
    /// #   let mut candidates = vec![Corner::default(); 200];
    /// #   let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #       detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// #   let mut tracker = Tracker::<60>::new(config, W, H, buffers).unwrap();
    ///     // ... a tracker of `config`, started on the first frame, then given 30 more ...
    /// #   let frames: Vec<Vec<u8>> = (0..31).map(|k| scene(2.0 * k as f32)).collect();
    /// #   let view = |k: usize| ImageView::packed(&frames[k], W, H).unwrap();
    /// #   tracker.start(view(0)).unwrap();
    /// #   let mut xs = Vec::new();
    /// #   for k in 1..31 {
    /// #       let report = tracker.process(view(k - 1), view(k), None).unwrap();
    /// #       let new = &tracker.tracks()[report.live - report.added..];
    /// #       xs.extend(new.iter().map(|t| t.position.to_f32().0));
    /// #   }
    /// #   xs
    /// };
    /// let every_corner = started_at(Refill { leaving_within: 0, ..Refill::default() });
    /// let staying = started_at(Refill::default());
    /// // 20 frames take a corner 40 px right: none starts within 48 px of the right edge.
    /// assert!(!staying.is_empty() && staying.iter().all(|&x| x <= 111.0));
    /// assert!(every_corner.iter().any(|&x| x > 111.0));
    /// ```
    pub leaving_within: u16,
}

/// A track that fails a gate younger than this many frames marks its spot for
/// [`Refill::cooldown`] frames; an older one failed from something that happened to it (an
/// occluder, the view turning), not from its place.
pub(super) const FAILED_YOUNG: u32 = 4;

impl Refill {
    /// The default refill with `detector`.
    const fn with(detector: Detector) -> Self {
        Self {
            below: 80,
            detector,
            level: 1,
            grid: Grid {
                cols: 8,
                rows: 6,
                per_cell: 3,
            },
            border: 8,
            min_distance: 5,
            cooldown: 32,
            leaving_within: 20,
        }
    }
}

impl Default for Refill {
    /// Below 80 tracks, [`Detector::default`] on pyramid level 1, at most 3 corners in each
    /// cell of an 8 x 6 grid, 8 px from the edges and 5 px apart, none for 32 frames near where
    /// a young track failed, none that a camera moving half a pixel a frame or more takes out
    /// of the view within 20 frames.
    fn default() -> Self {
        Self::with(Detector::default())
    }
}

/// How old tracks are moved back onto the feature they were born on. LK follows a window
/// from frame to frame, so its sub-pixel errors add up over hundreds of frames; relocation
/// moves a track to where its birth patch (the appearance gate's 7 x 7 samples) matches best
/// near its position, found by a few Gauss-Newton steps on the patch, and drops it when
/// that is too far.
///
/// ```
/// use kestrel::track::{Relocation, TrackerConfig};
/// # use kestrel::detect::Corner;
/// # use kestrel::ImageView;
/// # use kestrel::lk::scratch_len;
/// # use kestrel::track::{detect_scratch_len, tracker_storage_len, FrameReport, Tracker, TrackerBuffers};
/// # const W: usize = 64;
/// # const H: usize = 48;
/// # // Smooth blobs, `shift` px to the right.
/// # let scene = |shift: f32| -> Vec<u8> {
/// #     (0..W * H).map(|i| {
/// #         let (x, y) = ((i % W) as f32 - shift, (i / W) as f32);
/// #         (128.0 + 50.0 * (0.45 * x).sin() * (0.38 * y).cos() + 30.0 * (0.21 * (x + y)).sin()) as u8
/// #     }).collect()
/// # };
/// # // The reports of a tracker of `config` over `frames`.
/// # let run = |config: TrackerConfig, frames: &[Vec<u8>]| -> Vec<FrameReport> {
/// #     let mut storage = vec![0u8; tracker_storage_len(W, H, config.pyramid_levels())];
/// #     let mut lk_scratch = vec![0i16; scratch_len(config.lk.window)];
/// #     let mut detect_scratch = vec![0i32; detect_scratch_len(W, config.refill.level, 24)];
/// #     let mut candidates = vec![Corner::default(); 24];
/// #     let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #         detect_scratch: &mut detect_scratch, candidates: &mut candidates };
/// #     let mut tracker = Tracker::<12>::new(config, W, H, buffers).unwrap();
/// #     let views: Vec<_> = frames.iter().map(|f| ImageView::packed(f, W, H).unwrap()).collect();
/// #     let mut reports = vec![tracker.start(views[0]).unwrap()];
/// #     for pair in views.windows(2) {
/// #         reports.push(tracker.process(pair[0], pair[1], None).unwrap());
/// #     }
/// #     reports
/// # };
/// let mut config = TrackerConfig::default();
/// config.max_tracks = 12;
/// config.refill.below = 0;
/// // The scene moves 1.5 px to the right every frame.
/// let frames: Vec<_> = (0..5).map(|k| scene(1.5 * k as f32)).collect();
/// let dropped = |relocation: Relocation| -> usize {
///     let reports = run(TrackerConfig { relocation, ..config }, &frames);
///     reports.iter().map(|r| r.dropped_relocation).sum()
/// };
/// // Every track relocated on every frame: each birth patch is found where LK put its track.
/// let every_frame = Relocation { every: 1, from_age: 0, ..Relocation::default() };
/// assert_eq!(dropped(every_frame), 0);
/// // Asked to find it exactly there, not a fraction of a pixel off, relocation drops them.
/// assert!(dropped(Relocation { max_distance: 0.0, ..every_frame }) > 0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Relocation {
    /// Relocation period, frames: every this many frames, a track at least
    /// [`Relocation::from_age`] frames old is relocated; every twice this many once its image
    /// has turned or zoomed since its birth, since the turned patch brings an error of its own
    /// into each relocation. Tracks take turns (by id), so each frame relocates about one in
    /// this many. 0 turns relocation off.
    pub every: u32,
    /// Tracks younger than this many frames are not relocated: they have not drifted yet.
    pub from_age: u32,
    /// Relocation limit, px: a track whose birth patch is not found within this distance of
    /// its position (or found only along an edge, where the search does not settle) is
    /// dropped as no longer looking like its feature. A number >= 0; infinity sets no limit.
    pub max_distance: f32,
    /// Revival window, frames: on a still camera (the frame's median step at most 1/8 px), a
    /// track at least 8 frames old that a gate drops is kept aside for this many frames, and
    /// revived, with its id, its birth and its age, where its birth patch matches again at its
    /// place (the appearance gate, when on, then located within [`Relocation::max_distance`],
    /// whether relocation runs or not) and no live track is nearer than
    /// [`super::Refill::min_distance`], while fewer than [`super::TrackerConfig::max_tracks`]
    /// are live: a walker passing over it, a leaf swinging back. At most 16 are kept aside,
    /// the oldest forgotten first; all are forgotten in a frame whose camera moves, where too
    /// few tracks stepped to say, or where most tracks failed at once. 0 turns it off.
    pub revive_within: u16,
    /// While the camera moves (the frame's median step half a pixel or more), a track whose LK
    /// window the frame's edge cuts is relocated in every frame, whatever its age: the
    /// window's pixels past the edge repeat the edge pixels, which do not move with the scene,
    /// and each step is biased towards standing still; relocation compares the part of the
    /// birth patch inside the frame. On a still camera the edge tracks stay put, where the cut
    /// window does no harm. It costs one relocation per such track and frame (on the
    /// firmware's test flight, 1.95 M -> 2.05 M instructions a frame for 100 tracks on
    /// 160 x 120 frames).
    pub at_edge: bool,
}

impl Relocation {
    /// The default relocation.
    const DEFAULT: Self = Self {
        every: 8,
        from_age: 32,
        max_distance: 0.75,
        revive_within: 32,
        at_edge: true,
    };
}

impl Default for Relocation {
    /// Every 8 frames (16 on a turned image), tracks at least 32 frames old, within 0.75 px,
    /// and tracks by the edge of a moving camera's frame in every frame; dropped tracks
    /// revived within 32 frames on a still camera.
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The least minimum eigenvalue of a new track's window (gradients of about 1.4 grey levels
/// per pixel), whatever the threshold a followed track must keep: on a nearly flat window LK
/// follows the noise and slides by several pixels in a hundred frames, and a feature should
/// start well above the threshold at which it is let go.
///
/// ```
/// use kestrel::track::{TrackerConfig, BIRTH_MIN_EIGEN};
/// assert!(TrackerConfig::default().lk.min_eigen_threshold < BIRTH_MIN_EIGEN);
/// ```
pub const BIRTH_MIN_EIGEN: f32 = 2e-3;

impl Default for TrackerConfig {
    /// OpenCV's LK settings, except the minimum eigenvalue: 5e-4 instead of 1e-4 for a
    /// followed track, and [`BIRTH_MIN_EIGEN`] for a new one. A track whose texture fades (a
    /// climb magnifies the ground, and blurs it) is followed down to a quarter of the texture
    /// it needed to start; its anchor's relocation catches the drift that weak windows bring.
    /// 100 tracks on a Gaussian pyramid, and each group's defaults.
    fn default() -> Self {
        let lk = LkParams {
            min_eigen_threshold: 5e-4,
            ..LkParams::default()
        };
        TrackerConfig::with(lk, Detector::default())
    }
}

impl TrackerConfig {
    /// The flow-sensor preset: what a flight controller needs to feed the autopilot's
    /// OPTICAL_FLOW_RAD at 400 Hz from 160 x 120 frames on a Cortex-M4 at 168 MHz, all in:
    /// pyramid, tracking, refill and the motion fit (its instructions a frame are measured by
    /// `bench/target.sh`, figures in the README).
    ///
    /// 25 tracks spread by a 5 x 5 grid (as PX4FLOW's 25 blocks), 7 x 7 windows on two levels
    /// whose coarse level is a 2 x 2 box mean, FAST corners on the coarse level, the
    /// template on the nearest pixel, at most 10 iterations; the gates, the gain and bias
    /// model, the motion prediction and the forward-backward schedule as the defaults have
    /// them. At 400 Hz the image moves a few pixels a frame at most, which two levels of a 7 x 7
    /// window cover. No refill cooldown: with one track to a grid cell, a cell whose best
    /// corner cools down takes a weaker one, and the reading the 25 tracks make is worse for it
    /// (the firmware template's flight in `bench/mavlink_link.sh`: worst reading 0.041 px from
    /// the true flow without, 0.054-0.059 px with the default 32 frames). Every corner starts
    /// a track, however soon it leaves the view (no [`Refill::leaving_within`]), for the same
    /// reason: a cell whose corner is passed over takes a weaker one.
    ///
    /// ```
    /// use kestrel::track::TrackerConfig;
    /// const SENSOR: TrackerConfig = TrackerConfig::flow_sensor();
    /// assert_eq!((SENSOR.max_tracks, SENSOR.lk.window, SENSOR.pyramid_levels()), (25, 7, 1));
    /// assert_eq!((SENSOR.refill.below, SENSOR.refill.grid.cols), (20, 5));
    /// assert_eq!(SENSOR.refill.cooldown, 0);
    /// assert_eq!(SENSOR.refill.leaving_within, 0);
    /// assert_eq!(SENSOR.relocation.every, 16);
    /// assert!(!SENSOR.relocation.at_edge);
    /// ```
    pub const fn flow_sensor() -> Self {
        let lk = LkParams {
            window: 7,
            max_level: 1,
            max_iterations: 10,
            epsilon: 0.01,
            min_eigen_threshold: 2e-3,
            illumination: Illumination::GainBias,
            template: TemplatePlacement::NearestPixel,
        };
        let detector = Detector::Fast(Fast {
            threshold: 10,
            nonmax: true,
        });
        let defaults = Self::with(lk, detector);
        Self {
            max_tracks: 25,
            pyramid: PyramidFilter::Box,
            refill: Refill {
                below: 20,
                cooldown: 0,
                leaving_within: 0,
                grid: Grid {
                    cols: 5,
                    rows: 5,
                    per_cell: 1,
                },
                ..defaults.refill
            },
            // Every 16 frames: the reading is the similarity of 25 tracks, which a relocation's
            // sub-pixel correction moves little, and the frame is at 94 % of its budget.
            relocation: Relocation {
                every: 16,
                revive_within: 0,
                // A relocation costs about six of a track's LK steps, and at 400 Hz the image
                // moves a pixel or two a frame at most, the edge tracks little.
                at_edge: false,
                ..Relocation::DEFAULT
            },
            ..defaults
        }
    }

    /// The defaults with `lk` and `detector`: the one place the tracker's default count and
    /// pyramid are written, and each group's defaults taken, for [`Default`] and the presets.
    const fn with(lk: LkParams, detector: Detector) -> Self {
        Self {
            lk,
            max_tracks: 100,
            pyramid: PyramidFilter::Gaussian,
            search: Search::DEFAULT,
            gates: Gates::DEFAULT,
            refill: Refill::with(detector),
            relocation: Relocation::DEFAULT,
        }
    }

    /// The coarsest pyramid level the tracker builds: the deeper of the LK pyramid and the
    /// detection level. Size the storage with it (see [`super::tracker_storage_len`]).
    ///
    /// ```
    /// use kestrel::track::{Refill, TrackerConfig};
    /// let config = TrackerConfig {
    ///     refill: Refill { level: 4, ..Refill::default() },
    ///     ..TrackerConfig::default()
    /// };
    /// assert_eq!(config.pyramid_levels(), 4);
    /// ```
    pub const fn pyramid_levels(&self) -> usize {
        if self.refill.level > self.lk.max_level {
            self.refill.level
        } else {
            self.lk.max_level
        }
    }

    /// Checks every setting for a tracker of capacity `capacity`; a refusal names the field
    /// by its path, as the caller writes it (`"max_tracks"`, `"lk.window"`,
    /// `"refill.grid.cols"`, `"gates.fb_threshold"`).
    pub(super) fn validate(&self, capacity: usize) -> Result<Checked, ConfigError> {
        let Self {
            lk: lk_params,
            max_tracks,
            pyramid: _,
            search,
            gates,
            refill,
            relocation,
        } = *self;
        let lk_refused = |e: ConfigError| e.nested(&LK_PATHS);
        let lk = LucasKanade::new(lk_params).map_err(lk_refused)?;
        if max_tracks == 0 || max_tracks > capacity {
            let bound = Bound::Range {
                min: 1,
                max: bound_number(capacity),
            };
            return Err(ConfigError::new("max_tracks", bound));
        }
        if refill.below > max_tracks {
            let bound = Bound::AtMost(bound_number(max_tracks));
            return Err(ConfigError::new("refill.below", bound));
        }
        if refill.level > MAX_LEVEL {
            let bound = Bound::AtMost(bound_number(MAX_LEVEL));
            return Err(ConfigError::new("refill.level", bound));
        }
        refill
            .grid
            .validate()
            .map_err(|e| e.nested(&["refill.grid.cols", "refill.grid.rows"]))?;
        if let Detector::ShiTomasi(shi_tomasi) = &refill.detector {
            shi_tomasi.validate().map_err(|e| {
                e.nested(&["refill.detector.block", "refill.detector.quality_level"])
            })?;
        }
        // The gates: a number >= 0, infinity turning the gate off.
        let refused = |field| ConfigError::new(field, Bound::NonNegative);
        let fb_limit_sq = gate(gates.fb_threshold)
            .ok_or(refused("gates.fb_threshold"))?
            .map(squared_bits);
        let max_residual = gate(gates.max_residual).ok_or(refused("gates.max_residual"))?;
        let residual_ratio = gate(gates.residual_ratio).ok_or(refused("gates.residual_ratio"))?;
        let min_correlation = match gates.min_correlation {
            c if c.is_nan() || c > 1.0 => {
                return Err(ConfigError::new("gates.min_correlation", Bound::AtMost(1)))
            }
            c if c <= -1.0 => None,
            c => Some(c),
        };
        let appearance = match (min_correlation, gates.least_correlation) {
            (_, c) if c.is_nan() || c > 1.0 => {
                return Err(ConfigError::new(
                    "gates.least_correlation",
                    Bound::AtMost(1),
                ))
            }
            (None, _) => None,
            (Some(min), least) if least >= min => Some(AppearanceGate::new(min, None)),
            (Some(min), least) => Some(AppearanceGate::new(min, Some(least))),
        };
        let texture_check = LucasKanade::new(LkParams {
            max_level: 0,
            max_iterations: 1,
            min_eigen_threshold: lk_params.min_eigen_threshold.max(BIRTH_MIN_EIGEN),
            ..lk_params
        })
        .map_err(lk_refused)?;
        let max_shift_sq = gate(relocation.max_distance)
            .ok_or(refused("relocation.max_distance"))?
            .map_or(i64::MAX, squared_bits);
        let fine_search = match gate(search.fine_reach).ok_or(refused("search.fine_reach"))? {
            Some(reach) if reach == Q16::ZERO => None,
            Some(reach) => Some(reach),
            None => Some(Q16::MAX),
        };
        if gates.fb_every == 0 {
            return Err(ConfigError::new("gates.fb_every", Bound::AtLeast(1)));
        }
        let fb_doubt_sq = gate(gates.fb_doubt)
            .ok_or(refused("gates.fb_doubt"))?
            .map_or(i64::MAX, squared_bits);
        let relocate = (relocation.every > 0).then_some(Relocate {
            every: relocation.every,
            from_age: relocation.from_age,
            max_shift_sq,
            at_edge: relocation.at_edge,
        });
        Ok(Checked {
            relocate,
            lk,
            texture_check,
            fb_limit_sq,
            max_residual,
            residual_ratio,
            appearance,
            constant_velocity: search.constant_velocity,
            fine_search,
            fb_every: gates.fb_every,
            fb_doubt_sq,
            revive: (relocation.revive_within > 0).then_some(Revive {
                within: relocation.revive_within,
                max_shift_sq,
            }),
        })
    }
}

/// A Q16 distance squared, in squared Q16 units.
pub(super) fn squared_bits(limit: Q16) -> i64 {
    let bits = i64::from(limit.to_bits());
    bits.saturating_mul(bits)
}

/// A threshold as Q16: `Some(None)` for infinity (no gate), `None` for NaN or negative.
// Out of line: six gates share it, once per tracker.
#[inline(never)]
fn gate(threshold: f32) -> Option<Option<Q16>> {
    if threshold.is_nan() || threshold < 0.0 {
        None
    } else if threshold == f32::INFINITY {
        Some(None)
    } else {
        Some(Some(crate::q16::q16_from_f32(threshold)))
    }
}

/// A configuration's derived values, once checked.
#[derive(Debug, Clone, Copy)]
pub(super) struct Checked {
    /// The validated LK tracker.
    pub lk: LucasKanade,
    /// The same at full resolution only, with one iteration: tracking a frame onto itself
    /// with it tells whether LK accepts a window, at the cost of building its template.
    pub texture_check: LucasKanade,
    /// The forward-backward gate squared, in squared Q16 units; `None` when off.
    pub fb_limit_sq: Option<i64>,
    /// The residual gate; `None` when off.
    pub max_residual: Option<Q16>,
    /// The relative residual gate; `None` when off.
    pub residual_ratio: Option<Q16>,
    /// The appearance gate; `None` when off.
    pub appearance: Option<AppearanceGate>,
    /// Relocation; `None` when off.
    pub relocate: Option<Relocate>,
    /// Whether a track's latest displacement predicts its next.
    pub constant_velocity: bool,
    /// The finest level's reach; `None` when every search takes the whole pyramid.
    pub fine_search: Option<Q16>,
    /// The forward-backward schedule, frames (at least 1).
    pub fb_every: u32,
    /// The doubt distance squared, in squared Q16 units.
    pub fb_doubt_sq: i64,
    /// How dropped tracks are revived on a still camera; `None` when off.
    pub revive: Option<Revive>,
}

/// How long dropped tracks are kept aside on a still camera, and how far from its place a
/// track's birth patch may be found for it to be revived.
#[derive(Debug, Clone, Copy)]
pub(super) struct Revive {
    /// Frames, at least 1.
    pub within: u16,
    /// The relocation limit squared, in squared Q16 units, whether relocation runs or not.
    pub max_shift_sq: i64,
}

/// When tracks are relocated on their anchor, and how far they may move.
#[derive(Debug, Clone, Copy)]
pub(super) struct Relocate {
    /// The period, frames (at least 1).
    pub every: u32,
    /// The least age relocated.
    pub from_age: u32,
    /// The relocation limit squared, in squared Q16 units.
    pub max_shift_sq: i64,
    /// Whether tracks by the edge of a moving camera's frame are relocated in every frame.
    pub at_edge: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gates_read_infinity_as_off_and_refuse_nan() {
        assert_eq!(gate(f32::INFINITY), Some(None));
        assert_eq!(gate(1.5), Some(Some(Q16::from_num(1.5))));
        assert_eq!(gate(1e9), Some(Some(Q16::MAX)));
        assert_eq!(gate(f32::NAN), None);
        assert_eq!(gate(-0.5), None);
    }

    #[test]
    fn the_default_is_valid() {
        let checked = TrackerConfig::default().validate(100).unwrap();
        assert_eq!(checked.fb_limit_sq, Some(65536 * 65536));
        assert_eq!(checked.max_residual, Some(Q16::from_num(12)));
        let relocate = checked.relocate.unwrap();
        assert_eq!((relocate.every, relocate.from_age), (8, 32));
        assert_eq!(relocate.max_shift_sq, 49152 * 49152);
    }

    #[test]
    fn relocation_is_off_at_period_0_and_refuses_a_nan_limit() {
        let relocation = |every, max_distance| TrackerConfig {
            relocation: Relocation {
                every,
                max_distance,
                ..Relocation::default()
            },
            ..TrackerConfig::default()
        };
        assert!(relocation(0, 0.75)
            .validate(100)
            .unwrap()
            .relocate
            .is_none());
        let unlimited = relocation(16, f32::INFINITY).validate(100).unwrap();
        assert_eq!(unlimited.relocate.unwrap().max_shift_sq, i64::MAX);
        assert_eq!(
            relocation(16, f32::NAN).validate(100).unwrap_err(),
            ConfigError::new("relocation.max_distance", Bound::NonNegative)
        );
    }

    #[test]
    fn the_groups_defaults_are_the_trackers() {
        let config = TrackerConfig::default();
        assert_eq!(config.search, Search::default());
        assert_eq!(config.gates, Gates::default());
        assert_eq!(config.refill, Refill::default());
        assert_eq!(config.relocation, Relocation::default());
    }
}
