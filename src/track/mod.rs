//! The KLT track manager: corners found, followed, checked, dropped and replaced, frame after
//! frame, with ids that are never reused.
//!
//! Every frame, [`Tracker::process`]
//! 1. builds the new frame's pyramid next to the previous one (the previous frame's pixels are
//!    the caller's buffer, passed again: nothing is copied);
//! 2. follows every live track with LK from where it should be: the caller's prediction when
//!    there is one (a gyro), else its own last displacement repeated (new tracks: the median
//!    of the others'), on the finest pyramid level its last prediction error calls for
//!    ([`Search::fine_reach`]), again on the whole pyramid when that search fails;
//! 3. drops a track that LK lost, whose residual stands out (above
//!    [`Gates::max_residual`], or [`Gates::residual_ratio`] times the frame's median, or
//!    the movers' median for a track on a mover), that no longer looks like the feature it
//!    was born on ([`Gates::min_correlation`]; on a frame whose tracks' looks spread widely,
//!    only the tracks that stand out below the others, down to [`Gates::least_correlation`]),
//!    or whose way back misses its start by more
//!    than [`Gates::fb_threshold`]: the cheap gates first, the backward LK last, run on
//!    every track once in [`Gates::fb_every`] frames and on every doubtful step; every
//!    [`Relocation::every`] frames (twice as many once its image has turned), a track that
//!    is old enough is first moved to where its birth appearance matches best nearby,
//!    undoing LK's slow drift, or dropped when that is farther than
//!    [`Relocation::max_distance`];
//! 4. on a still camera, sets the dropped tracks at least 8 frames old aside, and revives
//!    those set aside whose birth patch shows again at their place (a walker has passed over
//!    them), with their ids, for [`Relocation::revive_within`] frames;
//! 5. when fewer than [`Refill::below`] tracks are left, detects corners on
//!    pyramid level [`Refill::level`] away from the live tracks, spreads them
//!    with a [`Grid`](crate::detect::Grid), and starts new tracks up to
//!    [`TrackerConfig::max_tracks`] where LK accepts the window.
//!
//! Memory: the caller's [`TrackerBuffers`] (two pyramids, scratch, candidates), and inside the
//! tracker 48 bytes per track plus 120 for its anchor (its birth appearance, 49 samples plain and
//! 49 smoothed, their sums and how the image turned since), 16.8 KB for 100 tracks, 2.75 KB for
//! the 16 tracks set aside to be revived, and 12 bytes for each spot the refill keeps away from.
//!
//! ```
//! use kestrel::detect::Corner;
//! use kestrel::ImageView;
//! use kestrel::lk::scratch_len;
//! use kestrel::track::{
//!     detect_scratch_len, tracker_storage_len, Refill, Tracker, TrackerBuffers, TrackerConfig,
//! };
//!
//! const W: usize = 64;
//! const H: usize = 48;
//! let config = TrackerConfig {
//!     max_tracks: 12,
//!     refill: Refill { below: 8, ..Refill::default() },
//!     ..TrackerConfig::default()
//! };
//!
//! // Firmware would make these `static`.
//! let mut storage = [0u8; tracker_storage_len(W, H, 3)];
//! let mut lk_scratch = [0i16; scratch_len(21)];
//! let mut detect_scratch = [0i32; detect_scratch_len(W, 1, 24)];
//! let mut candidates = [Corner::default(); 24];
//! let buffers = TrackerBuffers {
//!     storage: &mut storage,
//!     lk_scratch: &mut lk_scratch,
//!     detect_scratch: &mut detect_scratch,
//!     candidates: &mut candidates,
//! };
//! let mut tracker = Tracker::<12>::new(config, W, H, buffers).unwrap();
//!
//! // Smooth blobs, then the same blobs 1.5 px further right: two camera buffers.
//! let scene = |shift: f32| -> [u8; W * H] {
//!     core::array::from_fn(|i| {
//!         let (x, y) = ((i % W) as f32 - shift, (i / W) as f32);
//!         (128.0 + 50.0 * (0.45 * x).sin() * (0.38 * y).cos() + 30.0 * (0.21 * (x + y)).sin()) as u8
//!     })
//! };
//! let (a, b) = (scene(0.0), scene(1.5));
//! let (first, second) = (ImageView::packed(&a, W, H).unwrap(), ImageView::packed(&b, W, H).unwrap());
//!
//! let report = tracker.start(first).unwrap();
//! assert!(report.added > 0);
//! let born: heapless::Vec<_, 12> = tracker.tracks().iter().map(|t| (t.id, t.position)).collect();
//!
//! let report = tracker.process(first, second, None).unwrap();
//! assert!(report.tracked > 0);
//! for track in tracker.tracks().iter().filter(|t| t.age == 1) {
//!     let (_, start) = born.iter().find(|(id, _)| *id == track.id).unwrap();
//!     let (dx, dy) = (track.position.x - start.x, track.position.y - start.y);
//!     assert!((dx.to_num::<f32>() - 1.5).abs() < 0.1 && dy.to_num::<f32>().abs() < 0.1);
//! }
//! ```

mod anchor;
mod appearance;
mod buffers;
mod config;
mod fingerprint;
mod follow;
mod refill;
mod revive;
mod turn;

pub use buffers::{detect_scratch_len, tracker_storage_len, TrackerBuffers};
pub use config::{Detector, Gates, Refill, Relocation, Search, TrackerConfig, BIRTH_MIN_EIGEN};

use crate::config_error::bound_number;
use crate::frame::{ImageView, MAX_DIMENSION};
use crate::lk::{scratch_len, LkError};
use crate::pyramid::{pyramid_storage_len, Pyramid};
use crate::q16::{Point, Q16};
use crate::{Bound, ConfigError};
use anchor::{likeness_limit, Anchor};
use buffers::StorageParts;
use config::Checked;
use fingerprint::Fingerprint;
use follow::{distance_sq, Follow, StepLimits};
use heapless::Vec;
use refill::{Cooling, DetectBuffers, FailedSpots};
use revive::{SetAside, Welcome};

/// One tracked feature.
///
/// ```
/// use kestrel::track::{Tracker, Refill, TrackerConfig};
/// use kestrel::Point;
/// # use kestrel::track::{tracker_storage_len, detect_scratch_len, TrackerBuffers};
/// # use kestrel::{detect::Corner, ImageView, lk::scratch_len};
/// # const W: usize = 64;
/// # const H: usize = 48;
/// # let mut storage = [0u8; tracker_storage_len(W, H, 3)];
/// # let mut lk_scratch = [0i16; scratch_len(21)];
/// # let mut detect_scratch = [0i32; detect_scratch_len(W, 1, 24)];
/// # let mut candidates = [Corner::default(); 24];
/// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
/// # let scene = |shift: f32| -> [u8; W * H] {
/// #     core::array::from_fn(|i| {
/// #         let (x, y) = ((i % W) as f32 - shift, (i / W) as f32);
/// #         (128.0 + 50.0 * (0.45 * x).sin() * (0.38 * y).cos() + 30.0 * (0.21 * (x + y)).sin()) as u8
/// #     })
/// # };
/// let config = TrackerConfig {
///     max_tracks: 12,
///     refill: Refill { below: 8, ..Refill::default() },
///     ..TrackerConfig::default()
/// };
/// let mut tracker = Tracker::<12>::new(config, W, H, buffers).unwrap();
/// // Smooth blobs, then the same blobs 1.5 px further right.
/// let (a, b) = (scene(0.0), scene(1.5));
/// let (first, second) = (ImageView::packed(&a, W, H).unwrap(), ImageView::packed(&b, W, H).unwrap());
/// tracker.start(first).unwrap();
/// tracker.process(first, second, None).unwrap();
/// assert!(tracker.tracks().iter().any(|t| t.born == 0));
/// for t in tracker.tracks() {
///     if t.born == 0 {
///         // Detected in frame 0 and followed one step of 1.5 px.
///         let (dx, dy) = t.velocity.to_f32();
///         assert!(t.age == 1 && (dx - 1.5).abs() < 0.1 && dy.abs() < 0.1, "{t:?}");
///     } else {
///         // Detected in frame 1: no step yet.
///         assert_eq!((t.born, t.age, t.velocity), (1, 0, Point::default()));
///     }
/// }
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Track {
    /// Identity, unique among the tracks of a tracker (see [`Tracker::process`] on wrapping).
    pub id: u32,
    /// Position in the latest frame, px.
    pub position: Point,
    /// Position in the frame before, px (its position, on its first frame and on the frame it
    /// was revived in): with [`Track::position`], the track's correspondence between the two
    /// frames.
    pub previous: Point,
    /// Frames the track has been followed through since it was detected (0 on its first frame).
    pub age: u32,
    /// Mean absolute residual of the latest step, grey levels (0 on its first frame).
    pub residual: Q16,
    /// The residual this track's steps usually leave, grey levels: the mean of its steps'
    /// residuals, each new step weighing 1/8 (its first step's own residual after one step; 0
    /// on its first frame). A window's texture decides how much noise, blur and resampling
    /// cost it, so once a track has made four steps the relative residual gate also allows it
    /// this times [`Gates::residual_ratio`] when that is higher than the frame's limit, up to
    /// [`Gates::max_residual`].
    pub usual_residual: Q16,
    /// Index of the frame it was detected in.
    pub born: u32,
    /// Displacement of the latest step, px (zero on its first frame). Without a caller's
    /// prediction, the next step's search starts this far from the track's position
    /// ([`Search::constant_velocity`]).
    pub velocity: Point,
    /// How far the latest step landed from where its search started (its prediction, or its
    /// old position without one), px; [`Q16::MAX`] on its first frame. It decides how coarse
    /// a pyramid level the next search needs ([`Search::fine_reach`]).
    pub prediction_error: Q16,
}

/// What happened to the tracks in one frame.
///
/// ```
/// use kestrel::track::FrameReport;
/// let r = FrameReport { live: 90, tracked: 85, added: 5, ..FrameReport::default() };
/// assert_eq!(r.dropped(), 0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameReport {
    /// Tracks alive after the frame.
    pub live: usize,
    /// Tracks followed into this frame from the previous one.
    pub tracked: usize,
    /// Tracks dropped by the forward-backward check.
    pub dropped_fb: usize,
    /// Tracks dropped by the residual gate.
    pub dropped_residual: usize,
    /// Tracks dropped because they no longer correlate with their birth patch
    /// ([`Gates::min_correlation`], lowered towards [`Gates::least_correlation`] on a frame
    /// whose tracks spread widely).
    pub dropped_appearance: usize,
    /// Tracks dropped because their birth patch was not found near them when they were due
    /// for relocation ([`Relocation::max_distance`]).
    pub dropped_relocation: usize,
    /// Tracks that left the frame.
    pub dropped_out_of_frame: usize,
    /// Tracks LK lost in the frame: too little texture, or not converged.
    pub dropped_lost: usize,
    /// New tracks started in this frame.
    pub added: usize,
    /// Corners not started in this frame because their window, followed back into the
    /// previous frame, failed the residual gate the frame's tracks were held to: a track there
    /// would fail its first step (see [`Refill::cooldown`]).
    pub refused: usize,
    /// Tracks revived: dropped by a gate on a still camera (and counted there), then found
    /// again at their place with their ids ([`Relocation::revive_within`]).
    pub revived: usize,
    /// True when detection ran in this frame.
    pub detected: bool,
}

impl FrameReport {
    /// Tracks dropped for any reason.
    ///
    /// ```
    /// use kestrel::track::FrameReport;
    /// let r = FrameReport { dropped_fb: 1, dropped_residual: 2, dropped_lost: 3, ..FrameReport::default() };
    /// assert_eq!(r.dropped(), 6);
    /// ```
    pub fn dropped(&self) -> usize {
        self.dropped_fb
            .saturating_add(self.dropped_residual)
            .saturating_add(self.dropped_appearance)
            .saturating_add(self.dropped_relocation)
            .saturating_add(self.dropped_out_of_frame)
            .saturating_add(self.dropped_lost)
    }
}

/// Why a tracker could not take a frame (a tracker that could not be made is a
/// [`ConfigError`] of [`Tracker::new`]).
///
/// ```
/// use kestrel::ImageView;
/// use kestrel::track::{Tracker, Refill, TrackerConfig, TrackerError};
/// # use kestrel::track::{tracker_storage_len, detect_scratch_len, TrackerBuffers};
/// # use kestrel::{detect::Corner, lk::scratch_len};
/// # let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
/// # let mut lk_scratch = [0i16; scratch_len(21)];
/// # let mut detect_scratch = [0i32; detect_scratch_len(32, 1, 4)];
/// # let mut candidates = [Corner::default(); 4];
/// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
/// let config = TrackerConfig {
///     max_tracks: 4,
///     refill: Refill { below: 4, ..Refill::default() },
///     ..TrackerConfig::default()
/// };
/// let mut tracker = Tracker::<4>::new(config, 32, 32, buffers).unwrap();
/// let (small, large) = ([0u8; 16 * 16], [0u8; 32 * 32]);
/// let (small, frame) = (ImageView::packed(&small, 16, 16).unwrap(), ImageView::packed(&large, 32, 32).unwrap());
/// assert_eq!(tracker.process(frame, frame, None), Err(TrackerError::NotStarted));
/// let refused = tracker.start(small).unwrap_err();
/// assert_eq!(refused, TrackerError::FrameSizeMismatch);
/// assert_eq!(refused.to_string(), "frame size differs from the tracker's frame size");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrackerError {
    /// A frame is not the size the tracker was made for.
    FrameSizeMismatch,
    /// [`Tracker::process`] was called before [`Tracker::start`].
    NotStarted,
    /// The previous frame given is not the frame given last: its size or pixels differ.
    NotThePreviousFrame,
    /// A buffer refused while taking a frame: never expected, since [`Tracker::new`] checked
    /// every buffer against the settings.
    Config(ConfigError),
}

impl From<ConfigError> for TrackerError {
    fn from(e: ConfigError) -> Self {
        TrackerError::Config(e)
    }
}

impl core::fmt::Display for TrackerError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TrackerError::FrameSizeMismatch => {
                f.write_str("frame size differs from the tracker's frame size")
            }
            TrackerError::NotStarted => f.write_str("no previous frame: call start first"),
            TrackerError::NotThePreviousFrame => {
                f.write_str("previous frame is not the frame given last")
            }
            TrackerError::Config(e) => e.fmt(f),
        }
    }
}

/// The previous frame, as far as the tracker remembers it.
#[derive(Debug, Clone, Copy)]
struct Previous {
    fingerprint: Fingerprint,
    /// Which half of the storage holds its pyramid.
    half: usize,
    /// The frame before it, when the other half still holds that frame's pyramid (after
    /// [`Tracker::process`], not after [`Tracker::start`]).
    earlier: Option<Fingerprint>,
}

/// A step of [`Tracker::process_observed`], reported as it ends.
///
/// ```
/// use kestrel::track::{TrackerStage, Tracker, Refill, TrackerConfig};
/// # use kestrel::track::{tracker_storage_len, detect_scratch_len, TrackerBuffers};
/// # use kestrel::{detect::Corner, ImageView, lk::scratch_len};
/// # let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
/// # let mut lk_scratch = [0i16; scratch_len(21)];
/// # let mut detect_scratch = [0i32; detect_scratch_len(32, 1, 4)];
/// # let mut candidates = [Corner::default(); 4];
/// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
/// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
/// // A tracker that detects corners only when it starts: its frames never refill.
/// let config = TrackerConfig {
///     max_tracks: 4,
///     refill: Refill { below: 0, ..Refill::default() },
///     ..TrackerConfig::default()
/// };
/// let mut tracker = Tracker::<4>::new(config, 32, 32, buffers).unwrap();
/// let flat = [100u8; 32 * 32];
/// let frame = ImageView::packed(&flat, 32, 32).unwrap();
/// tracker.start(frame).unwrap();
/// let mut stages = heapless::Vec::<TrackerStage, 3>::new();
/// tracker.process_observed(frame, frame, None, |s| stages.push(s).unwrap()).unwrap();
/// assert_eq!(stages, [TrackerStage::Pyramid, TrackerStage::Follow]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrackerStage {
    /// The new frame's pyramid is built (after the frame checks).
    Pyramid,
    /// Every live track was followed (and checked back where due), and the gates applied.
    Follow,
    /// New corners were detected and new tracks started; only in frames that refill.
    Refill,
}

/// A KLT tracker of at most `N` tracks over `width` x `height` frames, working in the caller's
/// [`TrackerBuffers`]. See the [module documentation](self) for a whole example.
#[derive(Debug)]
pub struct Tracker<'a, const N: usize> {
    config: TrackerConfig,
    checked: Checked,
    width: usize,
    height: usize,
    buffers: TrackerBuffers<'a>,
    set: TrackSet<N>,
    /// Where young tracks failed lately, which refill keeps away from.
    failed: FailedSpots<N>,
    /// Index the next frame will get.
    next_frame: u32,
    previous: Option<Previous>,
}

impl<'a, const N: usize> Tracker<'a, N> {
    /// A tracker for `width` x `height` frames, once `config` and the sizes of `buffers` are
    /// checked: all the validation happens here, so that firmware finds a mistake at start-up.
    ///
    /// A refusal names the setting as the caller writes it: a field of `config`
    /// (`"max_tracks"`, `"fb_threshold"`; a nested one by its path, `"lk.window"`,
    /// `"grid.cols"`, `"detector.quality_level"`), `"width"` or `"height"` (1 to
    /// [`MAX_DIMENSION`]), or a buffer (`"buffers.storage"`, `"buffers.lk_scratch"`,
    /// `"buffers.detect_scratch"`, `"buffers.candidates"`) with the length it needs.
    ///
    /// ```
    /// use kestrel::track::{tracker_storage_len, Tracker, TrackerBuffers, TrackerConfig};
    /// use kestrel::{Bound, ConfigError};
    /// let buffers = || TrackerBuffers {
    ///     storage: &mut [],
    ///     lk_scratch: &mut [],
    ///     detect_scratch: &mut [],
    ///     candidates: &mut [],
    /// };
    /// let config = TrackerConfig::default();
    /// // No tracks at all.
    /// let none = TrackerConfig { max_tracks: 0, ..config };
    /// let refused = Tracker::<4>::new(none, 160, 120, buffers()).unwrap_err();
    /// assert_eq!(refused, ConfigError { field: "max_tracks", bound: Bound::Range { min: 1, max: 4 } });
    /// assert_eq!(refused.to_string(), "max_tracks must be 1 to 4");
    /// // The default wants 100 tracks; this tracker holds 50.
    /// let small = Tracker::<50>::new(config, 160, 120, buffers()).unwrap_err();
    /// assert_eq!(small.to_string(), "max_tracks must be 1 to 50");
    /// // Nested settings are named by their path.
    /// let mut even = config;
    /// even.lk.window = 20;
    /// let refused = Tracker::<100>::new(even, 160, 120, buffers()).unwrap_err();
    /// assert_eq!(refused.to_string(), "lk.window must be odd, 3 to 63");
    /// // Buffers by their field, with the length they need.
    /// let empty = Tracker::<100>::new(config, 160, 120, buffers()).unwrap_err();
    /// let needed = tracker_storage_len(160, 120, config.pyramid_levels());
    /// assert_eq!(empty, ConfigError { field: "buffers.storage", bound: Bound::MinLen(needed) });
    /// assert_eq!(empty.to_string(), "buffers.storage must hold at least 13080 elements");
    /// ```
    pub fn new(
        config: TrackerConfig,
        width: usize,
        height: usize,
        buffers: TrackerBuffers<'a>,
    ) -> Result<Self, ConfigError> {
        let checked = config.validate(N)?;
        let sides = 1..=MAX_DIMENSION;
        let side_bound = Bound::Range {
            min: 1,
            max: bound_number(MAX_DIMENSION),
        };
        if !sides.contains(&width) {
            return Err(ConfigError::new("width", side_bound));
        }
        if !sides.contains(&height) {
            return Err(ConfigError::new("height", side_bound));
        }
        check_buffers(&config, width, height, &buffers)?;
        Ok(Self {
            config,
            checked,
            width,
            height,
            buffers,
            set: TrackSet {
                tracks: Vec::new(),
                anchors: Vec::new(),
                set_aside: SetAside::default(),
                next_id: 0,
            },
            failed: FailedSpots::new(),
            next_frame: 0,
            previous: None,
        })
    }

    /// Starts over on `frame`: drops every track, builds the frame's pyramid and detects new
    /// tracks in it. Use it on the first frame, and to resynchronise after a lost frame. Ids
    /// keep counting up and frames keep their indices.
    ///
    /// See the [module documentation](self).
    pub fn start(&mut self, frame: ImageView<'_>) -> Result<FrameReport, TrackerError> {
        self.check_size(&frame)?;
        let levels = self.config.pyramid_levels();
        // Keep the previous pyramid intact until this one is built, in case it fails.
        let half = self.previous.map_or(0, |p| other_half(p.half));
        let StorageParts {
            halves: [first, second],
            ..
        } = buffers::split_storage(self.buffers.storage, self.width, self.height, levels);
        let storage = if half == 0 { first } else { second };
        Pyramid::build_with(frame, levels, self.config.pyramid, storage)
            .map_err(TrackerError::Config)?;

        // A restart ends the previous frame's tracks; they are not counted as dropped.
        self.set.clear();
        self.failed.clear();
        let mut report = FrameReport::default();
        self.refill((frame, half), (None, None), &mut report)?;
        Ok(self.finish_frame(&frame, half, report))
    }

    /// Follows the tracks from `prev` to `next`, drops the bad ones and refills.
    ///
    /// `prev` must be the frame given last (to [`Tracker::start`] or as `next`): the tracker
    /// kept its pyramid but not its pixels. A cheap fingerprint of it is checked, and a
    /// mismatch is [`TrackerError::NotThePreviousFrame`], with the tracks left as they were.
    ///
    /// `predict`, when given, maps a position in `prev` to its expected position in `next`
    /// (from a gyro, or a motion model), where LK starts its search; the backward check starts
    /// from the same displacement reversed.
    ///
    /// Ids count up from 0 and wrap after 2^32 new tracks; at 1000 new tracks per second that
    /// is 49 days.
    pub fn process(
        &mut self,
        prev: ImageView<'_>,
        next: ImageView<'_>,
        predict: Option<&dyn Fn(Point) -> Point>,
    ) -> Result<FrameReport, TrackerError> {
        self.process_observed(prev, next, predict, |_| {})
    }

    /// [`Tracker::process`], calling `stage_ended` as each [`TrackerStage`] ends: firmware
    /// reads a cycle counter there to time the pyramid, the tracking and the refill apart.
    /// What comes after the last stage (remembering the frame) is a few hundred instructions.
    ///
    /// ```
    /// use kestrel::track::{TrackerStage, Tracker, Refill, TrackerConfig};
    /// # use kestrel::track::{tracker_storage_len, detect_scratch_len, TrackerBuffers};
    /// # use kestrel::{detect::Corner, ImageView, lk::scratch_len};
    /// # let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
    /// # let mut lk_scratch = [0i16; scratch_len(21)];
    /// # let mut detect_scratch = [0i32; detect_scratch_len(32, 1, 4)];
    /// # let mut candidates = [Corner::default(); 4];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// let config = TrackerConfig {
    ///     max_tracks: 4,
    ///     refill: Refill { below: 4, ..Refill::default() },
    ///     ..TrackerConfig::default()
    /// };
    /// let mut tracker = Tracker::<4>::new(config, 32, 32, buffers).unwrap();
    /// let flat = [100u8; 32 * 32];
    /// let frame = ImageView::packed(&flat, 32, 32).unwrap();
    /// tracker.start(frame).unwrap();
    /// let mut stages = heapless::Vec::<TrackerStage, 3>::new();
    /// tracker.process_observed(frame, frame, None, |s| stages.push(s).unwrap()).unwrap();
    /// // A flat frame has no corners, so the tracker stays below its refill threshold.
    /// assert_eq!(stages, [TrackerStage::Pyramid, TrackerStage::Follow, TrackerStage::Refill]);
    /// ```
    pub fn process_observed(
        &mut self,
        prev: ImageView<'_>,
        next: ImageView<'_>,
        predict: Option<&dyn Fn(Point) -> Point>,
        mut stage_ended: impl FnMut(TrackerStage),
    ) -> Result<FrameReport, TrackerError> {
        self.check_size(&prev)?;
        self.check_size(&next)?;
        let previous = self.previous.ok_or(TrackerError::NotStarted)?;
        if Fingerprint::of(&prev) != previous.fingerprint {
            return Err(TrackerError::NotThePreviousFrame);
        }
        // The other half is overwritten now: it no longer holds the frame before `prev`.
        self.previous = Some(Previous {
            earlier: None,
            ..previous
        });
        let levels = self.config.pyramid_levels();
        let StorageParts {
            halves: [first, second],
            ..
        } = buffers::split_storage(self.buffers.storage, self.width, self.height, levels);
        let (old, new) = if previous.half == 0 {
            (first, second)
        } else {
            (second, first)
        };
        let prev_pyramid =
            Pyramid::from_storage(prev, levels, old).map_err(TrackerError::Config)?;
        let next_pyramid = Pyramid::build_with(next, levels, self.config.pyramid, new)
            .map_err(TrackerError::Config)?;
        stage_ended(TrackerStage::Pyramid);

        let mut report = FrameReport::default();
        let follow = Follow {
            checked: &self.checked,
            prev: &prev_pyramid,
            next: &next_pyramid,
            predict,
        };
        let TrackSet {
            tracks,
            anchors,
            set_aside,
            ..
        } = &mut self.set;
        let failed = &mut self.failed;
        let (frame, cooldown) = (self.next_frame, self.config.refill.cooldown);
        failed.expire(frame, cooldown);
        let before = tracks.len();
        let mut mark = |at| {
            if cooldown > 0 {
                failed.mark(at, frame);
            }
        };
        let mut keep = |track, anchor: &Anchor| set_aside.keep(track, anchor, frame);
        let limits = follow
            .all(
                tracks,
                anchors,
                self.buffers.lk_scratch,
                &mut report,
                &mut mark,
                &mut keep,
            )
            .map_err(lk_refusal)?;
        // Most tracks failing at once is the frame's doing (a scene cut, a flat or saturated
        // frame), not their places': the spots marked so far no longer mean anything either.
        let most_failed = before.saturating_sub(tracks.len()).saturating_mul(2) > before;
        if most_failed {
            failed.clear();
        }
        let now = (&next_pyramid.base(), self.next_frame);
        let still = limits.is_still() && !most_failed;
        let settings = (&self.checked, &self.config);
        report.revived = revive(&mut self.set, settings, now, still);
        stage_ended(TrackerStage::Follow);
        let half = other_half(previous.half);
        if self.set.tracks.len() < self.config.refill.below {
            // New corners are held to this step as well when spots cool down: one that
            // would fail its first step is such a spot already. Not after a step most tracks
            // failed: it says nothing of the corners' places either.
            let earlier = (cooldown > 0 && !most_failed).then_some(Earlier {
                frame: prev,
                limits,
                predict,
            });
            // Nor does its median step say where the camera goes.
            let motion = limits.frame_motion().filter(|_| !most_failed);
            self.refill((next, half), (earlier, motion), &mut report)?;
            stage_ended(TrackerStage::Refill);
        }
        let report = self.finish_frame(&next, half, report);
        if let Some(latest) = self.previous.as_mut() {
            latest.earlier = Some(previous.fingerprint);
        }
        Ok(report)
    }

    /// The pyramids of the latest [`Tracker::process`]: `prev`'s and `next`'s, which must be
    /// the frames given to it. Other per-frame work (a dense flow grid, say) can then use them
    /// instead of building its own, which saves their memory and time. They stay valid until
    /// the next `process` or `start`, and do not exist after [`Tracker::start`]
    /// ([`TrackerError::NotStarted`]). Frames other than those given are
    /// [`TrackerError::NotThePreviousFrame`].
    ///
    /// ```
    /// use kestrel::track::{Tracker, Refill, TrackerConfig, TrackerError};
    /// # use kestrel::track::{tracker_storage_len, detect_scratch_len, TrackerBuffers};
    /// # use kestrel::{detect::Corner, ImageView, lk::scratch_len};
    /// # let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
    /// # let mut lk_scratch = [0i16; scratch_len(21)];
    /// # let mut detect_scratch = [0i32; detect_scratch_len(32, 1, 4)];
    /// # let mut candidates = [Corner::default(); 4];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// let config = TrackerConfig {
    ///     max_tracks: 4,
    ///     refill: Refill { below: 4, ..Refill::default() },
    ///     ..TrackerConfig::default()
    /// };
    /// let mut tracker = Tracker::<4>::new(config, 32, 32, buffers).unwrap();
    /// let (dark, bright) = ([90u8; 32 * 32], [110u8; 32 * 32]);
    /// let a = ImageView::packed(&dark, 32, 32).unwrap();
    /// let b = ImageView::packed(&bright, 32, 32).unwrap();
    /// tracker.start(a).unwrap();
    /// assert_eq!(tracker.pyramids(a, a).unwrap_err(), TrackerError::NotStarted);
    /// tracker.process(a, b, None).unwrap();
    /// let (prev, next) = tracker.pyramids(a, b).unwrap();
    /// assert_eq!(prev.level(2).unwrap().get(3, 3), Some(90));
    /// assert_eq!(next.level(2).unwrap().get(3, 3), Some(110));
    /// assert_eq!(tracker.pyramids(b, a).unwrap_err(), TrackerError::NotThePreviousFrame);
    /// ```
    pub fn pyramids<'f>(
        &'f self,
        prev: ImageView<'f>,
        next: ImageView<'f>,
    ) -> Result<(Pyramid<'f>, Pyramid<'f>), TrackerError> {
        self.check_size(&prev)?;
        self.check_size(&next)?;
        let latest = self.previous.ok_or(TrackerError::NotStarted)?;
        let earlier = latest.earlier.ok_or(TrackerError::NotStarted)?;
        if Fingerprint::of(&prev) != earlier || Fingerprint::of(&next) != latest.fingerprint {
            return Err(TrackerError::NotThePreviousFrame);
        }
        let levels = self.config.pyramid_levels();
        let len = pyramid_storage_len(self.width, self.height, levels);
        let storage: &'f [u8] = self.buffers.storage;
        let (first, rest) = storage.split_at(len.min(storage.len()));
        let second = rest.get(..len).unwrap_or(rest);
        let (old, new) = if latest.half == 0 {
            (second, first)
        } else {
            (first, second)
        };
        let prev = Pyramid::from_storage(prev, levels, old).map_err(TrackerError::Config)?;
        let next = Pyramid::from_storage(next, levels, new).map_err(TrackerError::Config)?;
        Ok((prev, next))
    }

    /// The live tracks, oldest first.
    ///
    /// ```
    /// use kestrel::track::{Tracker, Refill, TrackerConfig};
    /// # use kestrel::track::{tracker_storage_len, detect_scratch_len, TrackerBuffers};
    /// # use kestrel::{detect::Corner, lk::scratch_len};
    /// # let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
    /// # let mut lk_scratch = [0i16; scratch_len(21)];
    /// # let mut detect_scratch = [0i32; detect_scratch_len(32, 1, 4)];
    /// # let mut candidates = [Corner::default(); 4];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// let config = TrackerConfig {
    ///     max_tracks: 4,
    ///     refill: Refill { below: 4, ..Refill::default() },
    ///     ..TrackerConfig::default()
    /// };
    /// let tracker = Tracker::<4>::new(config, 32, 32, buffers).unwrap();
    /// assert!(tracker.tracks().is_empty());
    /// ```
    pub fn tracks(&self) -> &[Track] {
        &self.set.tracks
    }

    /// The correspondences of the latest frame pair, into `pairs` (cleared first): each track
    /// followed into the latest frame, as (where it was in the frame before, where it is now).
    /// Tracks born in the latest frame have no step and give none; a track revived in it
    /// ([`Relocation::revive_within`], a still camera) gives its place twice. This is what ego-motion
    /// ([`crate::ego::Ransac::estimate`]) fits the camera's motion to.
    ///
    /// ```
    /// use heapless::Vec;
    /// use kestrel::track::{Tracker, Refill, TrackerConfig};
    /// # use kestrel::track::{tracker_storage_len, detect_scratch_len, TrackerBuffers};
    /// # use kestrel::{detect::Corner, lk::scratch_len};
    /// # let mut storage = [0u8; tracker_storage_len(64, 64, 3)];
    /// # let mut lk_scratch = [0i16; scratch_len(21)];
    /// # let mut detect_scratch = [0i32; detect_scratch_len(64, 1, 24)];
    /// # let mut candidates = [Corner::default(); 24];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// use kestrel::ImageView;
    /// use kestrel::Point;
    /// // Smooth blobs on a 66 x 64 canvas; the second frame is the first moved 2 px left.
    /// let canvas: [u8; 66 * 64] = core::array::from_fn(|i| {
    ///     let (x, y) = ((i % 66) as f32, (i / 66) as f32);
    ///     (128.0 + 60.0 * (x * 0.45).sin() * (y * 0.38).cos() + 40.0 * (x * 0.21 + y * 0.3).sin()) as u8
    /// });
    /// let first = ImageView::new(&canvas, 64, 64, 66).unwrap();
    /// let second = ImageView::new(&canvas[2..], 64, 64, 66).unwrap();
    /// let config = TrackerConfig {
    ///     max_tracks: 8,
    ///     refill: Refill { below: 8, ..Refill::default() },
    ///     ..TrackerConfig::default()
    /// };
    /// let mut tracker = Tracker::<8>::new(config, 64, 64, buffers).unwrap();
    /// tracker.start(first).unwrap();
    /// let mut pairs: Vec<(Point, Point), 8> = Vec::new();
    /// tracker.correspondences(&mut pairs);
    /// assert!(pairs.is_empty(), "no step yet");
    /// tracker.process(first, second, None).unwrap();
    /// tracker.correspondences(&mut pairs);
    /// assert!(pairs.len() >= 4);
    /// for (before, now) in &pairs {
    ///     let (dx, dy) = (now.x - before.x, now.y - before.y);
    ///     assert!((dx.to_num::<f32>() + 2.0).abs() < 0.1 && dy.to_num::<f32>().abs() < 0.1);
    /// }
    /// ```
    pub fn correspondences(&self, pairs: &mut Vec<(Point, Point), N>) {
        pairs.clear();
        for track in self.set.tracks.iter().filter(|t| t.age > 0) {
            // At most N tracks, so at most N pairs.
            let pushed = pairs.push((track.previous, track.position));
            debug_assert!(pushed.is_ok(), "more tracks than the tracker's capacity");
        }
    }

    /// The index of the latest frame (counted from 0, wrapping after 2^32 frames), or `None`
    /// before the first.
    ///
    /// ```
    /// # use kestrel::track::{tracker_storage_len, detect_scratch_len, Refill, Tracker, TrackerBuffers, TrackerConfig};
    /// # use kestrel::{detect::Corner, ImageView, lk::scratch_len};
    /// # let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
    /// # let mut lk_scratch = [0i16; scratch_len(21)];
    /// # let mut detect_scratch = [0i32; detect_scratch_len(32, 1, 4)];
    /// # let mut candidates = [Corner::default(); 4];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// # let config = TrackerConfig {
    /// #     max_tracks: 4,
    /// #     refill: Refill { below: 4, ..Refill::default() },
    /// #     ..TrackerConfig::default()
    /// # };
    /// let mut tracker = Tracker::<4>::new(config, 32, 32, buffers).unwrap();
    /// assert_eq!(tracker.frame_index(), None);
    /// let flat = [100u8; 32 * 32];
    /// let frame = ImageView::packed(&flat, 32, 32).unwrap();
    /// tracker.start(frame).unwrap();
    /// tracker.process(frame, frame, None).unwrap();
    /// assert_eq!(tracker.frame_index(), Some(1));
    /// ```
    pub fn frame_index(&self) -> Option<u32> {
        self.previous.map(|_| self.next_frame.wrapping_sub(1))
    }

    /// The configuration the tracker was made with.
    ///
    /// ```
    /// # use kestrel::track::{tracker_storage_len, detect_scratch_len, Refill, Tracker, TrackerBuffers, TrackerConfig};
    /// # use kestrel::{detect::Corner, lk::scratch_len};
    /// # let mut storage = [0u8; tracker_storage_len(32, 32, 3)];
    /// # let mut lk_scratch = [0i16; scratch_len(21)];
    /// # let mut detect_scratch = [0i32; detect_scratch_len(32, 1, 4)];
    /// # let mut candidates = [Corner::default(); 4];
    /// # let buffers = TrackerBuffers { storage: &mut storage, lk_scratch: &mut lk_scratch,
    /// #     detect_scratch: &mut detect_scratch, candidates: &mut candidates };
    /// let config = TrackerConfig {
    ///     max_tracks: 4,
    ///     refill: Refill { below: 2, ..Refill::default() },
    ///     ..TrackerConfig::default()
    /// };
    /// let tracker = Tracker::<4>::new(config, 32, 32, buffers).unwrap();
    /// assert_eq!(tracker.config().refill.below, 2);
    /// ```
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    fn check_size(&self, frame: &ImageView<'_>) -> Result<(), TrackerError> {
        if (frame.width(), frame.height()) == (self.width, self.height) {
            Ok(())
        } else {
            Err(TrackerError::FrameSizeMismatch)
        }
    }

    /// Detects new tracks in `frame`, whose pyramid was just built into `half` of the storage;
    /// with `earlier`, each must have arrived from that frame as a track would have, or its
    /// spot cools down; with the frame's median step `motion`, none starts where the camera's
    /// motion soon takes it out of the view.
    fn refill(
        &mut self,
        (frame, half): (ImageView<'_>, usize),
        (earlier, motion): (Option<Earlier<'_>>, Option<Point>),
        report: &mut FrameReport,
    ) -> Result<(), TrackerError> {
        let set = &mut self.set;
        let failed = &mut self.failed;
        let live: Vec<Point, N> = set.tracks.iter().map(|t| t.position).collect();
        let room = self.config.max_tracks.saturating_sub(set.tracks.len());
        let born = self.next_frame;
        let birth = Birth {
            config: &self.config,
            checked: &self.checked,
            size: (self.width, self.height),
            live: &live,
            room,
            earlier,
            motion,
        };
        let mut adopt = |position, anchor| set.adopt(position, anchor, born);
        start_tracks(
            birth,
            (frame, half),
            &mut self.buffers,
            (&mut adopt, failed, born),
            report,
        )
    }

    /// Remembers `frame` as the previous frame, its pyramid in `half`, and counts it.
    fn finish_frame(
        &mut self,
        frame: &ImageView<'_>,
        half: usize,
        mut report: FrameReport,
    ) -> FrameReport {
        self.previous = Some(Previous {
            fingerprint: Fingerprint::of(frame),
            half,
            earlier: None,
        });
        self.next_frame = self.next_frame.wrapping_add(1);
        report.live = self.set.tracks.len();
        report
    }
}

/// Revives into `set` the tracks set aside whose feature shows again at their place in `frame`
/// (the base of frame `now`) while there is room, or forgets them all when the camera is not
/// `still`; how many were revived.
fn revive<const N: usize>(
    set: &mut TrackSet<N>,
    (checked, config): (&Checked, &TrackerConfig),
    (frame, now): (&ImageView<'_>, u32),
    still: bool,
) -> usize {
    let TrackSet {
        tracks,
        anchors,
        set_aside,
        ..
    } = set;
    let Some(revive) = checked.revive.filter(|_| still) else {
        set_aside.clear();
        return 0;
    };
    // The appearance gate's threshold, whatever the frame's spread: a revived track must look
    // like its birth patch again. Without the gate, any patch with contrast.
    let least_likeness = checked
        .appearance
        .map_or(likeness_limit(-1.0), |gate| gate.strict());
    let spacing = i64::from(config.refill.min_distance) << 16;
    let mut welcome = |track: Track, anchor: &Anchor| {
        let near =
            |t: &Track| distance_sq(t.position, track.position) < spacing.saturating_mul(spacing);
        if tracks.iter().any(near) {
            return Welcome::Taken;
        }
        if tracks.len() < config.max_tracks && push_track(tracks, anchors, track, anchor) {
            Welcome::Revived
        } else {
            Welcome::Full
        }
    };
    set_aside.revive(
        frame,
        (now, revive.within),
        (least_likeness, revive.max_shift_sq),
        &mut welcome,
    )
}

/// The half of the ping-pong storage that is not `half` (0 or 1).
fn other_half(half: usize) -> usize {
    usize::from(half == 0)
}

/// The live tracks, their anchors (in the same order) and the id the next new one gets.
#[derive(Debug)]
struct TrackSet<const N: usize> {
    tracks: Vec<Track, N>,
    anchors: Vec<Anchor, N>,
    next_id: u32,
    /// Tracks dropped on a still camera, kept to be revived.
    set_aside: SetAside,
}

impl<const N: usize> TrackSet<N> {
    /// Ends every track.
    fn clear(&mut self) {
        self.tracks.clear();
        self.anchors.clear();
        self.set_aside.clear();
    }

    /// Starts a track at `position` with its anchor; false when the set is full.
    fn adopt(&mut self, position: Point, anchor: Anchor, born: u32) -> bool {
        let track = Track {
            id: self.next_id,
            position,
            previous: position,
            age: 0,
            residual: Q16::ZERO,
            usual_residual: Q16::ZERO,
            born,
            velocity: Point::default(),
            prediction_error: Q16::MAX,
        };
        if !push_track(&mut self.tracks, &mut self.anchors, track, &anchor) {
            return false;
        }
        self.next_id = self.next_id.wrapping_add(1);
        true
    }
}

/// Appends `track` and its `anchor` to the live tracks; false, and neither appended, when
/// they are full.
fn push_track<const N: usize>(
    tracks: &mut Vec<Track, N>,
    anchors: &mut Vec<Anchor, N>,
    track: Track,
    anchor: &Anchor,
) -> bool {
    if tracks.is_full() || anchors.is_full() {
        return false;
    }
    let pushed = tracks.push(track).is_ok() && anchors.push(*anchor).is_ok();
    debug_assert!(pushed, "room was checked");
    pushed
}

/// Detects corners away from the live tracks in `frame`, whose pyramid is in `half` of the
/// storage, and starts up to `birth.room` new tracks, each handed to `adopt`. A corner becomes
/// a track only where LK accepts its window: otherwise it would be dropped on its first step
/// and found again by the next refill, frame after frame. With `birth.earlier`, whose pyramid
/// is in the other half, a corner must also have arrived from that frame as a track would
/// have; one that did not is marked in `cooling` in frame `now`.
// Not generic over the tracker's capacity: one copy serves every tracker size.
fn start_tracks(
    birth: Birth<'_>,
    (frame, half): (ImageView<'_>, usize),
    buffers: &mut TrackerBuffers<'_>,
    (adopt, cooling, now): (&mut dyn FnMut(Point, Anchor) -> bool, &mut dyn Cooling, u32),
    report: &mut FrameReport,
) -> Result<(), TrackerError> {
    let Birth {
        config,
        checked,
        size,
        live,
        room,
        earlier,
        motion,
    } = birth;
    let levels = config.pyramid_levels();
    let StorageParts {
        halves: [first, second],
        fast_rows,
    } = buffers::split_storage(buffers.storage, size.0, size.1, levels);
    let (storage, other) = if half == 0 {
        (first, second)
    } else {
        (second, first)
    };
    let pyramid = Pyramid::from_storage(frame, levels, storage).map_err(TrackerError::Config)?;
    let Some(level_image) = pyramid.level(config.refill.level) else {
        return Ok(());
    };
    let before = match earlier {
        Some(e) => Some((
            Pyramid::from_storage(e.frame, levels, other).map_err(TrackerError::Config)?,
            e,
        )),
        None => None,
    };
    let detect = DetectBuffers {
        fast_rows,
        scratch: buffers.detect_scratch,
        candidates: buffers.candidates,
    };
    let corners = refill::new_corners(
        &config.refill,
        &level_image,
        size,
        (live, cooling.spots(), motion),
        detect,
    )
    .map_err(TrackerError::Config)?;
    report.detected = true;
    let mut started = 0;
    for corner in corners {
        if started >= room {
            break;
        }
        let anchor = newborn(checked, &pyramid, corner.position, buffers.lk_scratch)?;
        let Some(anchor) = anchor else {
            continue;
        };
        if let Some((prev, earlier)) = &before {
            let step = Follow {
                checked,
                prev,
                next: &pyramid,
                predict: earlier.predict,
            };
            let arrived = step
                .arrived(corner.position, &earlier.limits, buffers.lk_scratch)
                .map_err(lk_refusal)?;
            if !arrived {
                cooling.mark(corner.position, now);
                report.refused = report.refused.saturating_add(1);
                continue;
            }
        }
        if !adopt(corner.position, anchor) {
            break;
        }
        started = started.saturating_add(1);
        report.added = report.added.saturating_add(1);
    }
    Ok(())
}

/// The anchor of a track born at `position`, or `None` where LK rejects the corner's window.
// Not generic over the capacity, and out of line: one copy serves every tracker size.
#[inline(never)]
fn newborn(
    checked: &Checked,
    pyramid: &Pyramid<'_>,
    position: Point,
    lk_scratch: &mut [i16],
) -> Result<Option<Anchor>, TrackerError> {
    let still = checked
        .texture_check
        .track_point(pyramid, pyramid, position, None, lk_scratch)
        .map_err(lk_refusal)?;
    Ok(still
        .is_tracked()
        .then(|| Anchor::capture(&pyramid.base(), position)))
}

/// An LK refusal while following or starting tracks: never expected, since [`Tracker::new`]
/// checked the LK scratch and every pyramid is of the tracker's frame size.
fn lk_refusal(e: LkError) -> TrackerError {
    match e {
        LkError::Config(e) => TrackerError::Config(ConfigError {
            field: "buffers.lk_scratch",
            ..e
        }),
        LkError::FrameSizeMismatch | LkError::LengthMismatch => TrackerError::FrameSizeMismatch,
    }
}

/// Where new tracks may be born, how many, and by which rules.
struct Birth<'c> {
    config: &'c TrackerConfig,
    checked: &'c Checked,
    size: (usize, usize),
    /// Where the live tracks are: new ones keep their distance.
    live: &'c [Point],
    /// How many tracks may start.
    room: usize,
    /// The frame before, when new tracks must have arrived from it.
    earlier: Option<Earlier<'c>>,
    /// The frame's median step, when the tracks said it: where the view is going.
    motion: Option<Point>,
}

/// The frame before the one new tracks start in, the residual limits its step held the
/// frame's tracks to, and the caller's prediction of that step.
struct Earlier<'f> {
    frame: ImageView<'f>,
    limits: StepLimits,
    predict: Option<&'f dyn Fn(Point) -> Point>,
}

/// Checks each buffer against the size the configuration needs.
fn check_buffers(
    config: &TrackerConfig,
    width: usize,
    height: usize,
    buffers: &TrackerBuffers<'_>,
) -> Result<(), ConfigError> {
    let levels = config.pyramid_levels();
    let storage = tracker_storage_len(width, height, levels);
    if buffers.storage.len() < storage {
        return Err(ConfigError::min_len("buffers.storage", storage));
    }
    let lk_scratch = scratch_len(config.lk.window);
    if buffers.lk_scratch.len() < lk_scratch {
        return Err(ConfigError::min_len("buffers.lk_scratch", lk_scratch));
    }
    let candidates = buffers.candidates.len();
    if candidates < config.max_tracks {
        return Err(ConfigError::min_len(
            "buffers.candidates",
            config.max_tracks,
        ));
    }
    let needs_scratch = matches!(config.refill.detector, Detector::ShiTomasi(_));
    let scratch = detect_scratch_len(width, config.refill.level, candidates);
    if needs_scratch && buffers.detect_scratch.len() < scratch {
        return Err(ConfigError::min_len("buffers.detect_scratch", scratch));
    }
    Ok(())
}
