//! The per-frame pipeline: the tracker (pyramid, tracking, refill), the camera's motion from the
//! tracks with its OPTICAL_FLOW_RAD reading, and the dense grid with its motion boxes.
//!
//! The tracker keeps both pyramids in its storage and lends them to the dense grid, so every
//! frame's pyramid is built once. Level 0 of each is the camera frame itself, borrowed in place,
//! never copied.

use kestrel::dense::{DenseError, DenseSummary, MotionSummary, ObjectsStage};
use kestrel::detect::Corner;
use kestrel::ego::mavlink::EncodeError;
use kestrel::ego::{EgoMotion, ModelKind, OpticalFlowRad, RansacError};
use kestrel::lk::{scratch_len, LkParams, TemplatePlacement};
use kestrel::pyramid::Pyramid;
use kestrel::track::{
    detect_scratch_len, tracker_storage_len, FrameReport, Refill, Relocation, Tracker,
    TrackerBuffers, TrackerConfig, TrackerError, TrackerStage,
};
use kestrel::{ConfigError, Point};
use kestrel::{ImageError, ImageView};

use crate::dense::{Dense, DenseMemory};
use crate::ego::Ego;
use crate::meter::{Meter, Stopwatch};
use crate::scene::{HEIGHT, WIDTH};
use crate::stages::{Stage, StageTimes};

/// Coarsest pyramid level: three levels, 160x120, 80x60 and 40x30.
pub const MAX_LEVEL: usize = 2;
/// LK window side in pixels, for the tracks and the dense grid.
pub const WINDOW: usize = 9;
/// Tracks the tracker keeps.
pub const MAX_TRACKS: usize = 100;
/// Corner candidates of one detection: three per track spread new tracks over the frame.
pub const CANDIDATES: usize = 3 * MAX_TRACKS;
/// Pyramid level corners are detected on (the tracker's default).
pub const DETECT_LEVEL: usize = 1;
/// Bytes of the tracker's storage: two pyramids and FAST's rows.
pub const STORAGE_LEN: usize = tracker_storage_len(WIDTH, HEIGHT, MAX_LEVEL);
/// `i16` values of LK scratch for the window.
pub const LK_SCRATCH_LEN: usize = scratch_len(WINDOW);
/// `i32` words of Shi-Tomasi scratch.
pub const DETECT_SCRATCH_LEN: usize = detect_scratch_len(WIDTH, DETECT_LEVEL, CANDIDATES);

/// The tracker of the budget configuration.
pub type FrameTracker = Tracker<'static, MAX_TRACKS>;

/// The tracker's settings: its defaults (100 tracks, refill below 80, Shi-Tomasi on level 1),
/// with a 9x9 LK window on three levels, and without relocating the tracks by the frame's edge
/// in every frame (`Relocation::at_edge`): on this flight that took the tracker from 1.95 M to
/// 2.05 M instructions a frame, over its 2.0 M budget.
pub fn tracker_config() -> TrackerConfig {
    let defaults = TrackerConfig::default();
    TrackerConfig {
        relocation: Relocation {
            at_edge: false,
            ..defaults.relocation
        },
        lk: LkParams {
            window: WINDOW,
            max_level: MAX_LEVEL,
            template: TemplatePlacement::NearestPixel,
            ..defaults.lk
        },
        max_tracks: MAX_TRACKS,
        refill: Refill {
            level: DETECT_LEVEL,
            ..defaults.refill
        },
        ..defaults
    }
}

/// A tracker's buffers, sized by the configuration they serve, in one `static` so that they
/// land in `.bss`: `STORAGE` bytes of pyramids, `SCRATCH` values of LK scratch, `DETECT` words
/// of Shi-Tomasi scratch (0 with FAST) and `CANDIDATES` corners.
pub struct TrackerMemory<
    const STORAGE: usize,
    const SCRATCH: usize,
    const DETECT: usize,
    const CANDIDATES: usize,
> {
    storage: [u8; STORAGE],
    lk_scratch: [i16; SCRATCH],
    detect_scratch: [i32; DETECT],
    candidates: [Corner; CANDIDATES],
}

impl<const STORAGE: usize, const SCRATCH: usize, const DETECT: usize, const CANDIDATES: usize>
    TrackerMemory<STORAGE, SCRATCH, DETECT, CANDIDATES>
{
    /// Zeroed buffers, for a `static` initialiser.
    pub const fn new() -> Self {
        // `Corner::default` is not `const`.
        const NO_CORNER: Corner = Corner {
            position: Point::from_bits(0, 0),
            score: 0,
        };
        Self {
            storage: [0; STORAGE],
            lk_scratch: [0; SCRATCH],
            detect_scratch: [0; DETECT],
            candidates: [NO_CORNER; CANDIDATES],
        }
    }

    /// The buffers, lent to a tracker.
    pub fn buffers(&mut self) -> TrackerBuffers<'_> {
        TrackerBuffers {
            storage: &mut self.storage,
            lk_scratch: &mut self.lk_scratch,
            detect_scratch: &mut self.detect_scratch,
            candidates: &mut self.candidates,
        }
    }
}

/// The budget configuration's buffers.
pub type BudgetMemory = TrackerMemory<STORAGE_LEN, LK_SCRATCH_LEN, DETECT_SCRATCH_LEN, CANDIDATES>;

/// Why a frame produced no flow, or the pipeline could not be made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// A setting or buffer refused when the pipeline is made.
    Config(ConfigError),
    Image(ImageError),
    Track(TrackerError),
    Ego(RansacError),
    Mavlink(EncodeError),
    Dense(DenseError),
}

/// What one frame pair produced.
#[derive(Debug, Clone, Copy)]
pub struct Tracked {
    /// What happened to the tracks.
    pub report: FrameReport,
    /// The camera's motion, fitted to the tracks followed into this frame.
    pub motion: EgoMotion,
    /// The OPTICAL_FLOW_RAD reading of this frame pair.
    pub flow: OpticalFlowRad,
    /// The dense grid's measured and filled nodes.
    pub grid: DenseSummary,
    /// The motion mask and its boxes.
    pub moving: MotionSummary,
}

/// What one frame produced.
#[derive(Debug, Clone, Copy)]
pub enum FrameOutput {
    /// The first frame: the tracker started, with this many tracks.
    Started(usize),
    /// Any later frame.
    Tracked(Tracked),
}

/// The per-frame pipeline over frames of the scene's size.
pub struct Pipeline {
    tracker: FrameTracker,
    /// The last frame the tracker accepted.
    previous: Option<ImageView<'static>>,
    ego: Ego,
    dense: Dense,
}

impl Pipeline {
    /// A pipeline in the given buffers, its settings checked.
    pub fn new(
        tracker: &'static mut BudgetMemory,
        dense: &'static mut DenseMemory,
    ) -> Result<Self, FrameError> {
        let buffers = tracker.buffers();
        let tracker =
            Tracker::new(tracker_config(), WIDTH, HEIGHT, buffers).map_err(FrameError::Config)?;
        Ok(Self {
            tracker,
            previous: None,
            ego: Ego::new(ModelKind::Homography)?,
            dense: Dense::new(dense)?,
        })
    }

    /// Runs the pipeline on a `width` x `height` frame, timing each stage into `times`.
    ///
    /// A refused frame leaves the tracker as it was, so the next good frame is tracked from the
    /// last good one; the flow reading of a refused frame has quality 0.
    pub fn process(
        &mut self,
        pixels: &'static [u8],
        size: (usize, usize),
        meter: &Meter,
        times: &mut StageTimes,
    ) -> Result<FrameOutput, FrameError> {
        let outcome = self.process_frame(pixels, size, meter, times);
        if outcome.is_err() {
            self.ego.refuse().map_err(FrameError::Mavlink)?;
        }
        outcome
    }

    fn process_frame(
        &mut self,
        pixels: &'static [u8],
        (width, height): (usize, usize),
        meter: &Meter,
        times: &mut StageTimes,
    ) -> Result<FrameOutput, FrameError> {
        let next = ImageView::packed(pixels, width, height).map_err(FrameError::Image)?;
        let Some(prev) = self.previous else {
            let report = self.start(next, meter, times)?;
            return Ok(FrameOutput::Started(report.live));
        };
        let report = self.track(prev, next, meter, times)?;
        self.previous = Some(next);
        let (motion, flow) = times.run(meter, Stage::Ego, || self.ego.estimate(&self.tracker))?;
        let (prev, next) = self
            .tracker
            .pyramids(prev, next)
            .map_err(FrameError::Track)?;
        // The grid is timed as the dense stage, the mask, regions and persistence as the boxes.
        let mut watch = Stopwatch::start(meter);
        let found = self.dense.process(&prev, &next, &motion, |stage| {
            if stage == ObjectsStage::Grid {
                times.add(Stage::Dense, watch.lap());
            }
        });
        times.add(Stage::Boxes, watch.lap());
        let found = found.map_err(FrameError::Dense)?;
        Ok(FrameOutput::Tracked(Tracked {
            report,
            motion,
            flow,
            grid: found.grid,
            moving: found.summary,
        }))
    }

    /// The first frame: its pyramid and the first detection, timed as one.
    fn start(
        &mut self,
        frame: ImageView<'static>,
        meter: &Meter,
        times: &mut StageTimes,
    ) -> Result<FrameReport, FrameError> {
        let tracker = &mut self.tracker;
        let report = times
            .run(meter, Stage::Refill, || tracker.start(frame))
            .map_err(FrameError::Track)?;
        self.previous = Some(frame);
        Ok(report)
    }

    /// Pyramid, tracking and refill, timed apart as the tracker reports each stage's end.
    fn track(
        &mut self,
        prev: ImageView<'static>,
        next: ImageView<'static>,
        meter: &Meter,
        times: &mut StageTimes,
    ) -> Result<FrameReport, FrameError> {
        let mut watch = Stopwatch::start(meter);
        let report = self.tracker.process_observed(prev, next, None, |stage| {
            let stage = match stage {
                TrackerStage::Pyramid => Stage::Pyramid,
                TrackerStage::Follow => Stage::Track,
                TrackerStage::Refill => Stage::Refill,
            };
            times.add(stage, watch.lap());
        });
        // What follows the last stage is the tracker's bookkeeping: counted as tracking.
        times.add(Stage::Track, watch.lap());
        report.map_err(FrameError::Track)
    }

    /// The tracks followed into the latest frame: (position before, position now).
    pub fn pairs(&self) -> &[(Point, Point)] {
        self.ego.pairs()
    }

    /// The latest OPTICAL_FLOW_RAD reading and its MAVLink frame.
    pub fn latest_flow(&self) -> (&OpticalFlowRad, &[u8]) {
        self.ego.latest()
    }

    /// The boxes of the latest frame, largest first, in the previous frame's pixels.
    pub fn boxes(&self) -> &[kestrel::dense::MotionBox] {
        self.dense.found()
    }

    /// The camera model the flow readings are in.
    pub fn focal_length(&self) -> f32 {
        self.ego.focal_length()
    }

    /// The pyramids of the latest frame pair (`prev` and `next` must be its frames) and an LK
    /// scratch, for measurements beside the pipeline.
    pub fn latest_pair(
        &mut self,
        prev: ImageView<'static>,
        next: ImageView<'static>,
    ) -> Result<(Pyramid<'_>, Pyramid<'_>, &mut [i16]), FrameError> {
        let (prev, next) = self
            .tracker
            .pyramids(prev, next)
            .map_err(FrameError::Track)?;
        Ok((prev, next, self.dense.lk_scratch()))
    }
}
