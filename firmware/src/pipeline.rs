//! The per-frame pipeline: build the new frame's pyramid, then track the points from the
//! previous frame into it.
//!
//! Two pyramid buffers alternate: one holds the previous frame's levels, the other receives the
//! new frame's, and they swap once the frame is done. Level 0 is the camera frame itself,
//! borrowed, never copied.

use kestrel::frame::{ImageError, ImageView};
use kestrel::lk::{scratch_len, LkError, LkParams, LucasKanade, PointTrack, TrackStatus};
use kestrel::pyramid::{pyramid_storage_len, Pyramid, PyramidError};
use kestrel::{Point, Q16};

use crate::meter::Meter;
use crate::scene::{HEIGHT, WIDTH};
use crate::stages::{Stage, StageTimes};

/// Coarsest pyramid level: three levels, 160x120, 80x60 and 40x30.
pub const MAX_LEVEL: usize = 2;
/// LK window side in pixels.
pub const WINDOW: usize = 9;
/// Points across and down the tracking grid.
pub const GRID_SIDE: usize = 10;
/// Points tracked per frame.
pub const POINTS: usize = GRID_SIDE * GRID_SIDE;
/// Bytes of one pyramid's levels 1..=MAX_LEVEL.
pub const PYRAMID_LEN: usize = pyramid_storage_len(WIDTH, HEIGHT, MAX_LEVEL);
/// `i16` values of LK scratch for the window.
pub const SCRATCH_LEN: usize = scratch_len(WINDOW);

/// A track result before any frame has been tracked.
pub const NO_TRACK: PointTrack = PointTrack {
    position: Point::from_bits(0, 0),
    status: TrackStatus::OutOfBounds,
    residual: Q16::ZERO,
};

/// The LK configuration of the budget run: OpenCV's defaults but for the window and depth.
pub fn budget_params() -> LkParams {
    LkParams {
        window: WINDOW,
        max_level: MAX_LEVEL,
        ..LkParams::default()
    }
}

/// The buffers the pipeline works in, all `'static` so that they land in `.bss`.
pub struct Buffers {
    pub pyramids: [&'static mut [u8]; 2],
    pub tracks: &'static mut [PointTrack; POINTS],
    pub scratch: &'static mut [i16],
}

/// Why a frame produced no flow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    Image(ImageError),
    Pyramid(PyramidError),
    Track(LkError),
}

/// The flow of one frame, summarised over the tracked points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Flow {
    /// Points whose status is [`TrackStatus::Tracked`].
    pub tracked: usize,
    /// Median displacement of the tracked points, Q16 raw bits; `None` when none was tracked.
    pub median: Option<(i32, i32)>,
}

impl Flow {
    /// PX4FLOW-style quality: the share of tracked points, 0 (invalid) to 255.
    pub fn quality(&self) -> u8 {
        (self.tracked * 255 / POINTS) as u8
    }
}

/// The pyramid of the previous frame and the buffer for the next one.
struct PingPong {
    previous: Option<ImageView<'static>>,
    previous_levels: &'static mut [u8],
    next_levels: &'static mut [u8],
}

impl PingPong {
    fn swap(&mut self, newest: ImageView<'static>) {
        core::mem::swap(&mut self.previous_levels, &mut self.next_levels);
        self.previous = Some(newest);
    }
}

/// Everything tracking needs besides the pyramids.
struct Tracker {
    lk: LucasKanade,
    points: [Point; POINTS],
    tracks: &'static mut [PointTrack; POINTS],
    scratch: &'static mut [i16],
}

/// The per-frame pipeline over frames of the scene's size.
pub struct Pipeline {
    pyramids: PingPong,
    tracker: Tracker,
    max_level: usize,
}

impl Pipeline {
    /// A pipeline that tracks the grid with `params`, in `buffers`.
    pub fn new(params: LkParams, buffers: Buffers) -> Result<Self, LkError> {
        let [previous_levels, next_levels] = buffers.pyramids;
        Ok(Self {
            pyramids: PingPong {
                previous: None,
                previous_levels,
                next_levels,
            },
            tracker: Tracker {
                lk: LucasKanade::new(params)?,
                points: grid(),
                tracks: buffers.tracks,
                scratch: buffers.scratch,
            },
            max_level: params.max_level,
        })
    }

    /// Runs the pipeline on a `width` x `height` frame, timing each stage into `times`.
    ///
    /// The first frame only primes the pyramid (`Ok(None)`). A refused frame leaves the previous
    /// pyramid in place, so the next good frame tracks from the last good one.
    pub fn process(
        &mut self,
        pixels: &'static [u8],
        (width, height): (usize, usize),
        meter: &Meter,
        times: &mut StageTimes,
    ) -> Result<Option<Flow>, FrameError> {
        let frame = ImageView::packed(pixels, width, height).map_err(FrameError::Image)?;
        let pyramids = &mut self.pyramids;
        let max_level = self.max_level;
        let next = times
            .run(meter, Stage::Pyramid, || {
                Pyramid::build(frame, max_level, pyramids.next_levels)
            })
            .map_err(FrameError::Pyramid)?;
        let flow = match pyramids.previous {
            Some(previous) => {
                let prev = Pyramid::from_storage(previous, max_level, pyramids.previous_levels)
                    .map_err(FrameError::Pyramid)?;
                let tracker = &mut self.tracker;
                times
                    .run(meter, Stage::Track, || tracker.track(&prev, &next))
                    .map_err(FrameError::Track)?;
                Some(tracker.flow())
            }
            None => None,
        };
        pyramids.swap(frame);
        Ok(flow)
    }

    /// Gives the buffers back, for a pipeline with other parameters.
    pub fn into_buffers(self) -> Buffers {
        Buffers {
            pyramids: [self.pyramids.previous_levels, self.pyramids.next_levels],
            tracks: self.tracker.tracks,
            scratch: self.tracker.scratch,
        }
    }
}

impl Tracker {
    fn track(&mut self, prev: &Pyramid<'_>, next: &Pyramid<'_>) -> Result<(), LkError> {
        self.lk
            .track_points(prev, next, &self.points, None, self.tracks, self.scratch)
    }

    /// Counts the tracked points and takes the median of their displacements.
    fn flow(&self) -> Flow {
        let mut dx = [0i32; POINTS];
        let mut dy = [0i32; POINTS];
        let mut tracked = 0;
        for (point, track) in self.points.iter().zip(self.tracks.iter()) {
            if track.is_tracked() {
                dx[tracked] = (track.position.x - point.x).to_bits();
                dy[tracked] = (track.position.y - point.y).to_bits();
                tracked += 1;
            }
        }
        let median = median(&mut dx[..tracked]).zip(median(&mut dy[..tracked]));
        Flow { tracked, median }
    }
}

/// A `GRID_SIDE` x `GRID_SIDE` grid of cell centres over the whole frame. The outer points sit
/// 6-8 px from the edges, so at the coarser levels their windows cross the border, as detected
/// corners' windows would.
fn grid() -> [Point; POINTS] {
    // Cell centres of an even split of the frame: 8 px from the side edges, 6 px from the top.
    let cell = |i: usize, size: usize| ((2 * i + 1) * size / (2 * GRID_SIDE)) as i32;
    core::array::from_fn(|k| {
        let (column, row) = (k % GRID_SIDE, k / GRID_SIDE);
        Point::from_bits(cell(column, WIDTH) << 16, cell(row, HEIGHT) << 16)
    })
}

/// The median of `values` (the mean of the middle two for an even count), reordering them.
fn median(values: &mut [i32]) -> Option<i32> {
    values.sort_unstable();
    let n = values.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(values[n / 2]),
        _ => Some(((i64::from(values[n / 2 - 1]) + i64::from(values[n / 2])) / 2) as i32),
    }
}
