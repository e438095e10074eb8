//! `Tracker`: the library's KLT track manager over a sequence of numpy frames.

use std::collections::HashSet;

use host_sim::tracking::{
    config_for, tracks_aimed_for, HostBuffers, LkSettings, Preset, TrackerSettings, MAX_TRACKS,
};
use kestrel::detect::Corner;
use kestrel::track::{
    FrameReport as Report, Tracker as LibraryTracker, TrackerBuffers, TrackerConfig,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{self, Pixels};
use crate::settings::{self, value_error};

/// A tracker's buffers, owned here and lent to the library (its tracker, or its flow sensor)
/// for the borrower's whole life.
pub struct Buffers {
    storage: *mut [u8],
    lk_scratch: *mut [i16],
    detect_scratch: *mut [i32],
    candidates: *mut [Corner],
}

// SAFETY: the pointers are only dereferenced to lend the buffers (`lend`) and to free them
// (`drop`); the buffers are plain data, so moving or sharing the owner between threads is as
// safe as for a `Box`.
unsafe impl Send for Buffers {}
// SAFETY: as above; `&Buffers` gives no access to the buffers.
unsafe impl Sync for Buffers {}

impl Buffers {
    /// Buffers for a tracker of `config` on `width` x `height` frames (host-sim's sizes).
    pub fn new(config: &TrackerConfig, width: usize, height: usize) -> Self {
        let host = HostBuffers::new(config, width, height);
        Buffers {
            storage: Box::into_raw(host.storage.into_boxed_slice()),
            lk_scratch: Box::into_raw(host.lk_scratch.into_boxed_slice()),
            detect_scratch: Box::into_raw(host.detect_scratch.into_boxed_slice()),
            candidates: Box::into_raw(host.candidates.into_boxed_slice()),
        }
    }

    /// The buffers, lent for as long as the borrower wants.
    ///
    /// # Safety
    ///
    /// Call once, and drop the borrower (everything holding the returned references) before
    /// these buffers: a struct holding both declares the borrower first and clears it in its
    /// `Drop`.
    pub unsafe fn lend(&mut self) -> TrackerBuffers<'static> {
        // SAFETY: each pointer comes from `Box::into_raw` in `new` and stays valid until
        // `drop`; the caller guarantees one borrower that is gone by then.
        unsafe {
            TrackerBuffers {
                storage: &mut *self.storage,
                lk_scratch: &mut *self.lk_scratch,
                detect_scratch: &mut *self.detect_scratch,
                candidates: &mut *self.candidates,
            }
        }
    }
}

impl Drop for Buffers {
    fn drop(&mut self) {
        // SAFETY: the pointers came from `Box::into_raw` in `new` and are freed once, here;
        // the borrower was dropped before (see `lend`).
        unsafe {
            drop(Box::from_raw(self.storage));
            drop(Box::from_raw(self.lk_scratch));
            drop(Box::from_raw(self.detect_scratch));
            drop(Box::from_raw(self.candidates));
        }
    }
}

/// A library tracker with its buffers and the previous frame it needs again at each step.
pub struct Live {
    /// Borrows `buffers`; cleared first (see `Drop`), and declared first.
    tracker: Option<LibraryTracker<'static, MAX_TRACKS>>,
    buffers: Buffers,
    /// The last frame given, packed: the library's `process` takes it again with the next.
    prev: Vec<u8>,
    width: usize,
    height: usize,
}

impl Live {
    /// A tracker of `config` for `width` x `height` frames, or the library's refusal.
    pub fn new(config: TrackerConfig, width: usize, height: usize) -> Result<Self, String> {
        let mut live = Live {
            tracker: None,
            buffers: Buffers::new(&config, width, height),
            prev: Vec::new(),
            width,
            height,
        };
        // SAFETY: lent once; the tracker is dropped before the buffers (`Drop for Live`).
        let lent = unsafe { live.buffers.lend() };
        let tracker =
            LibraryTracker::new(config, width, height, lent).map_err(|e| e.to_string())?;
        live.tracker = Some(tracker);
        Ok(live)
    }

    /// Starts on `next` (`restart`, or no frame yet) or follows the tracks from the previous
    /// frame into it; keeps a packed copy of it for the next step.
    pub fn step(&mut self, next: Pixels<'_>, restart: bool) -> Result<Report, String> {
        let tracker = self.tracker.as_mut().ok_or("tracker is not made")?;
        let view = next.view()?;
        let report = if restart || self.prev.is_empty() {
            tracker.start(view)
        } else {
            let prev = kestrel::ImageView::packed(&self.prev, self.width, self.height)
                .map_err(|e| e.to_string())?;
            tracker.process(prev, view, None)
        }
        .map_err(|e| e.to_string())?;
        self.prev = next.to_packed();
        Ok(report)
    }

    /// True before the first frame.
    pub fn is_new(&self) -> bool {
        self.prev.is_empty()
    }

    /// The live tracks.
    pub fn tracks(&self) -> &[kestrel::track::Track] {
        self.tracker.as_ref().map(|t| t.tracks()).unwrap_or(&[])
    }
}

impl Drop for Live {
    fn drop(&mut self) {
        // The tracker's borrows end here, before the buffers are freed.
        self.tracker = None;
    }
}

/// What the tracker did on one frame: counts of live, followed, dropped (by gate) and new
/// tracks, and the ids of the tracks that ended.
#[pyclass(module = "kestrel", frozen, get_all)]
#[derive(Clone)]
pub struct FrameReport {
    /// The frame's index, from 0 at the first frame of a start.
    frame: u32,
    /// Tracks live after the frame.
    live: usize,
    /// Tracks followed from the previous frame and kept.
    tracked: usize,
    /// Tracks started on this frame.
    added: usize,
    /// Corners not started on this frame: their step from the frame before already failed
    /// the residual gate, as their track would have on its first step.
    refused: usize,
    /// Tracks revived on this frame: dropped by a gate on a still camera (and counted there),
    /// then found again at their place with their ids.
    revived: usize,
    /// True when corners were detected on this frame.
    detected: bool,
    /// Tracks dropped on this frame, all reasons.
    dropped: usize,
    /// Dropped by the forward-backward check.
    dropped_fb: usize,
    /// Dropped by the residual gates (absolute, or relative to the frame's median and the
    /// track's own usual residual).
    dropped_residual: usize,
    /// Dropped because the window no longer matched the track's birth patch.
    dropped_appearance: usize,
    /// Dropped because the birth patch was not found near the track when relocated.
    dropped_relocation: usize,
    /// Dropped because the track left the frame.
    dropped_out_of_frame: usize,
    /// Dropped because LK lost it (low texture, no convergence).
    dropped_lost: usize,
    /// Ids of the tracks that ended on this frame (a track dropped on a still camera may be
    /// revived later with its id: see `revived`).
    dropped_ids: Vec<u32>,
}

impl FrameReport {
    fn new(frame: u32, r: &Report, dropped_ids: Vec<u32>) -> Self {
        Self {
            frame,
            live: r.live,
            tracked: r.tracked,
            added: r.added,
            refused: r.refused,
            revived: r.revived,
            detected: r.detected,
            dropped: r.dropped(),
            dropped_fb: r.dropped_fb,
            dropped_residual: r.dropped_residual,
            dropped_appearance: r.dropped_appearance,
            dropped_relocation: r.dropped_relocation,
            dropped_out_of_frame: r.dropped_out_of_frame,
            dropped_lost: r.dropped_lost,
            dropped_ids,
        }
    }
}

#[pymethods]
impl FrameReport {
    /// The report as a dict.
    fn as_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("frame", self.frame)?;
        d.set_item("live", self.live)?;
        d.set_item("tracked", self.tracked)?;
        d.set_item("added", self.added)?;
        d.set_item("refused", self.refused)?;
        d.set_item("revived", self.revived)?;
        d.set_item("detected", self.detected)?;
        d.set_item("dropped", self.dropped)?;
        d.set_item("dropped_fb", self.dropped_fb)?;
        d.set_item("dropped_residual", self.dropped_residual)?;
        d.set_item("dropped_appearance", self.dropped_appearance)?;
        d.set_item("dropped_relocation", self.dropped_relocation)?;
        d.set_item("dropped_out_of_frame", self.dropped_out_of_frame)?;
        d.set_item("dropped_lost", self.dropped_lost)?;
        d.set_item("dropped_ids", self.dropped_ids.clone())?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "FrameReport(frame={}, live={}, tracked={}, added={}, refused={}, revived={}, \
             dropped={} (fb {}, residual {}, appearance {}, relocation {}, out of frame {}, lost \
             {}))",
            self.frame,
            self.live,
            self.tracked,
            self.added,
            self.refused,
            self.revived,
            self.dropped,
            self.dropped_fb,
            self.dropped_residual,
            self.dropped_appearance,
            self.dropped_relocation,
            self.dropped_out_of_frame,
            self.dropped_lost
        )
    }
}

/// The library's KLT track manager: detects corners, follows them from frame to frame with LK,
/// drops the tracks that fail its gates (forward-backward, residual, appearance against the
/// birth patch, relocation), refills, and keeps ids that are never reused.
///
/// Tracker(width=None, height=None, *, max_tracks=100, preset=None, window=None,
///         max_level=None, illumination=None, fb_threshold=None, max_residual=None,
///         min_correlation=None, least_correlation=None, residual_ratio=None,
///         max_relocation=None, relocate_every=None, refill_cooldown=None,
///         refill_below=None, leaving_within=None, revive_within=None)
///
/// width, height: the frame size; when None, the first frame's size is taken.
/// max_tracks: tracks kept at most, 1 to 1000.
/// refill_below: new corners are detected when fewer tracks than this are live after a frame,
///     0 to max_tracks (0: on the first frame only); None: 90 % of max_tracks, 80 % with the
///     preset.
/// preset: None (host-sim's tracking settings for the frame size: a 21 px window, levels
///     0-3, Shi-Tomasi corners on level 1 bucketed by a grid shaped like the frame), or
///     "flow_sensor" (TrackerConfig::flow_sensor(): 25 tracks, 7 px windows on two levels of
///     a box-mean pyramid, FAST corners).
/// The other keywords override the configuration's: LK window (odd, 3-63), coarsest level
/// (0-7), illumination ("gain_bias" or "plain"), forward-backward gate (px), residual gate
/// (grey levels), least correlation with the birth patch (-1 to 1), the floor that gate is
/// lowered to on a frame whose tracks' correlations spread widely (-1 to 1, from
/// min_correlation up the gate is fixed), relative residual gate,
/// relocation limit (px) and period (frames, 0 = never), the refill's cooldown (frames
/// during which no track starts near where a young one failed, 0-65535, 0 = none), the
/// frames within which a moving camera takes a corner out of the view for it to start no track
/// (0-65535, 0 = every corner starts), and the
/// revival window (frames a track dropped on a still camera is kept to be revived with its id
/// where its birth patch shows again, 0-65535, 0 = never).
///
/// `process(frame)` starts on the first frame and follows the tracks on every later one;
/// `start(frame)` restarts. Both return a FrameReport. The GIL is released while the tracker
/// works. The tracker keeps a packed copy of the last frame (the library takes the previous
/// frame again with the next one).
#[pyclass(module = "kestrel")]
pub struct Tracker {
    config: Option<TrackerConfig>,
    settings: TrackerSettings,
    preset: Option<Preset>,
    max_tracks: usize,
    size: Option<(usize, usize)>,
    live: Option<Live>,
    frames: u64,
    totals: Report,
    /// Tracks that ended and have not come back (a revived track ended once and is live again).
    ended: u64,
    /// The newest id seen: ids are never reused, so a live id at or below it that was not
    /// live a frame before is a revived track.
    newest_id: Option<u32>,
}

impl Tracker {
    fn configure(&self, width: usize, height: usize) -> TrackerConfig {
        let base = match self.preset {
            Some(preset) => preset.config(Some(self.max_tracks)),
            None => config_for(width, height, self.max_tracks),
        };
        self.settings.apply(base)
    }

    /// The tracker for `frame`'s size, made on the first frame.
    fn live_for(&mut self, pixels: &Pixels<'_>) -> PyResult<&mut Live> {
        let (w, h) = (pixels.width, pixels.height);
        if let Some((tw, th)) = self.size {
            if (tw, th) != (w, h) {
                return Err(value_error(format!(
                    "frame is {w}x{h} but the tracker was made for {tw}x{th} frames"
                )));
            }
        }
        if self.live.is_none() {
            let config = self.configure(w, h);
            let live = Live::new(config, w, h)
                .map_err(|e| value_error(format!("tracker settings refused: {e}")))?;
            self.config = Some(config);
            self.size = Some((w, h));
            self.live = Some(live);
        }
        self.live
            .as_mut()
            .ok_or_else(|| value_error("tracker could not be made"))
    }

    fn live_ids(&self) -> HashSet<u32> {
        self.tracks().iter().map(|t| t.id).collect()
    }

    fn step(
        &mut self,
        py: Python<'_>,
        frame: &Bound<'_, PyAny>,
        restart: bool,
    ) -> PyResult<FrameReport> {
        let frame = arrays::frame(frame, "frame")?;
        let pixels = frame.pixels();
        let before = self.live_ids();
        let live = self.live_for(&pixels)?;
        let starting = restart || live.is_new();
        let result = py.detach(|| live.step(pixels, restart));
        let report = result.map_err(value_error)?;
        let after = self.live_ids();
        let mut dropped_ids: Vec<u32> = if starting {
            Vec::new()
        } else {
            before.difference(&after).copied().collect()
        };
        dropped_ids.sort_unstable();
        let newest = self.newest_id;
        let revived = after
            .difference(&before)
            .filter(|&&id| newest.is_some_and(|n| id <= n))
            .count();
        self.newest_id = after.iter().copied().max().max(newest);
        self.frames += 1;
        self.ended = (self.ended + dropped_ids.len() as u64).saturating_sub(revived as u64);
        let t = &mut self.totals;
        t.tracked += report.tracked;
        t.added += report.added;
        t.refused += report.refused;
        t.revived += report.revived;
        t.dropped_fb += report.dropped_fb;
        t.dropped_residual += report.dropped_residual;
        t.dropped_appearance += report.dropped_appearance;
        t.dropped_relocation += report.dropped_relocation;
        t.dropped_out_of_frame += report.dropped_out_of_frame;
        t.dropped_lost += report.dropped_lost;
        let index = self
            .live
            .as_ref()
            .and_then(|l| l.tracker.as_ref())
            .and_then(|t| t.frame_index())
            .unwrap_or(0);
        Ok(FrameReport::new(index, &report, dropped_ids))
    }

    fn tracks(&self) -> &[kestrel::track::Track] {
        self.live.as_ref().map(|l| l.tracks()).unwrap_or(&[])
    }
}

#[pymethods]
impl Tracker {
    #[new]
    #[pyo3(signature = (width=None, height=None, *, max_tracks=None, preset=None, window=None,
        max_level=None, illumination=None, fb_threshold=None, max_residual=None,
        min_correlation=None, least_correlation=None, residual_ratio=None, max_relocation=None,
        relocate_every=None, refill_cooldown=None, refill_below=None, leaving_within=None,
        revive_within=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        width: Option<i64>,
        height: Option<i64>,
        max_tracks: Option<i64>,
        preset: Option<&str>,
        window: Option<i64>,
        max_level: Option<i64>,
        illumination: Option<&str>,
        fb_threshold: Option<f64>,
        max_residual: Option<f64>,
        min_correlation: Option<f64>,
        least_correlation: Option<f64>,
        residual_ratio: Option<f64>,
        max_relocation: Option<f64>,
        relocate_every: Option<i64>,
        refill_cooldown: Option<i64>,
        refill_below: Option<i64>,
        leaving_within: Option<i64>,
        revive_within: Option<i64>,
    ) -> PyResult<Self> {
        let size = settings::frame_size(width, height)?;
        let preset = match preset {
            None => None,
            Some("flow_sensor" | "flow-sensor") => Some(Preset::FlowSensor),
            Some(other) => {
                return Err(value_error(format!(
                    "preset must be None or 'flow_sensor': got {other:?}"
                )))
            }
        };
        let max_tracks = max_tracks.unwrap_or(tracks_aimed_for(preset, None) as i64);
        if !(1..=MAX_TRACKS as i64).contains(&max_tracks) {
            return Err(value_error(format!(
                "max_tracks must be 1 to {MAX_TRACKS}: got {max_tracks}"
            )));
        }
        let refill_below = match refill_below {
            Some(n) if !(0..=max_tracks).contains(&n) => {
                return Err(value_error(format!(
                    "refill_below must be 0 to max_tracks, {max_tracks}: got {n}"
                )))
            }
            other => other.map(|n| n as usize),
        };
        let min_correlation = min_correlation
            .map(|c| settings::correlation(c, "min_correlation"))
            .transpose()?;
        let least_correlation = least_correlation
            .map(|c| settings::correlation(c, "least_correlation"))
            .transpose()?;
        let relocate_every = match relocate_every {
            Some(n) if !(0..=1_000_000).contains(&n) => {
                return Err(value_error(format!(
                    "relocate_every must be 0 to 1000000 frames: got {n}"
                )))
            }
            other => other.map(|n| n as u32),
        };
        let frames = |n: Option<i64>, name: &str| {
            n.map(|n| {
                u16::try_from(n)
                    .map_err(|_| value_error(format!("{name} must be 0 to 65535 frames: got {n}")))
            })
            .transpose()
        };
        let refill_cooldown = frames(refill_cooldown, "refill_cooldown")?;
        let leaving_within = frames(leaving_within, "leaving_within")?;
        let revive_within = frames(revive_within, "revive_within")?;
        let settings = TrackerSettings {
            lk: LkSettings {
                window: window.map(|w| settings::side(w, "window")).transpose()?,
                levels: max_level.map(settings::max_level).transpose()?,
                illumination: illumination.map(settings::illumination).transpose()?,
                template: None,
            },
            fb_threshold: fb_threshold
                .map(|v| settings::non_negative(v, "fb_threshold"))
                .transpose()?,
            max_residual: max_residual
                .map(|v| settings::non_negative(v, "max_residual"))
                .transpose()?,
            min_correlation,
            least_correlation,
            residual_ratio: residual_ratio
                .map(|v| settings::non_negative(v, "residual_ratio"))
                .transpose()?,
            max_relocation: max_relocation
                .map(|v| settings::non_negative(v, "max_relocation"))
                .transpose()?,
            relocate_every,
            refill_cooldown,
            refill_below,
            leaving_within,
            revive_within,
        };
        let mut tracker = Tracker {
            config: None,
            settings,
            preset,
            max_tracks: max_tracks as usize,
            size,
            live: None,
            frames: 0,
            totals: Report::default(),
            ended: 0,
            newest_id: None,
        };
        if let Some((w, h)) = size {
            // Made now, so that settings the library refuses raise here.
            let config = tracker.configure(w, h);
            let live = Live::new(config, w, h)
                .map_err(|e| value_error(format!("tracker settings refused: {e}")))?;
            tracker.config = Some(config);
            tracker.live = Some(live);
        }
        Ok(tracker)
    }

    /// Takes the next frame (2-D uint8, the tracker's size): starts on the first frame (corners
    /// detected, tracks born), and on later frames follows every track from the previous
    /// frame, drops the ones that fail the gates and refills. Returns a FrameReport.
    fn process(&mut self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<FrameReport> {
        self.step(py, frame, false)
    }

    /// Restarts on `frame`: ends every track (not counted as dropped) and detects new ones.
    /// Returns a FrameReport.
    fn start(&mut self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<FrameReport> {
        self.step(py, frame, true)
    }

    /// Ids of the live tracks, uint32 (N,), never reused.
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> PyResult<Py<PyAny>> {
        let ids: Vec<u32> = self.tracks().iter().map(|t| t.id).collect();
        let n = ids.len();
        Ok(arrays::array(py, ids, &[n])?.into_any().unbind())
    }

    /// Positions of the live tracks in the last frame, float32 (N, 2), px.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Py<PyAny>> {
        let mut data = Vec::new();
        for t in self.tracks() {
            let (x, y) = t.position.to_f32();
            data.extend([x, y]);
        }
        let n = data.len() / 2;
        Ok(arrays::array(py, data, &[n, 2])?.into_any().unbind())
    }

    /// Frames each live track has been followed over, uint32 (N,) (0 on its first frame).
    #[getter]
    fn ages<'py>(&self, py: Python<'py>) -> PyResult<Py<PyAny>> {
        let ages: Vec<u32> = self.tracks().iter().map(|t| t.age).collect();
        let n = ages.len();
        Ok(arrays::array(py, ages, &[n])?.into_any().unbind())
    }

    /// Index of the frame each live track was born on, uint32 (N,).
    #[getter]
    fn born<'py>(&self, py: Python<'py>) -> PyResult<Py<PyAny>> {
        let born: Vec<u32> = self.tracks().iter().map(|t| t.born).collect();
        let n = born.len();
        Ok(arrays::array(py, born, &[n])?.into_any().unbind())
    }

    /// LK residual of each live track's last step, grey levels, float32 (N,).
    #[getter]
    fn residuals<'py>(&self, py: Python<'py>) -> PyResult<Py<PyAny>> {
        let r: Vec<f32> = self
            .tracks()
            .iter()
            .map(|t| t.residual.to_num::<f32>())
            .collect();
        let n = r.len();
        Ok(arrays::array(py, r, &[n])?.into_any().unbind())
    }

    /// Each live track's last displacement, px per frame, float32 (N, 2) (zero when new).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Py<PyAny>> {
        let mut data = Vec::new();
        for t in self.tracks() {
            let (x, y) = t.velocity.to_f32();
            data.extend([x, y]);
        }
        let n = data.len() / 2;
        Ok(arrays::array(py, data, &[n, 2])?.into_any().unbind())
    }

    /// The frame size `(width, height)`, or None before the first frame when not given.
    #[getter]
    fn size(&self) -> Option<(usize, usize)> {
        self.size
    }

    /// Frames processed (starts included).
    #[getter]
    fn frames(&self) -> u64 {
        self.frames
    }

    /// Totals over every frame processed: tracks followed and added, corners refused at
    /// birth, dropped tracks revived, tracks that ended and did not come back, and drops by
    /// gate (a revived track counts again each time it is dropped).
    #[getter]
    fn totals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = &self.totals;
        let d = PyDict::new(py);
        d.set_item("frames", self.frames)?;
        d.set_item("tracked", t.tracked)?;
        d.set_item("added", t.added)?;
        d.set_item("refused", t.refused)?;
        d.set_item("revived", t.revived)?;
        d.set_item("ended", self.ended)?;
        d.set_item("dropped", t.dropped())?;
        d.set_item("dropped_fb", t.dropped_fb)?;
        d.set_item("dropped_residual", t.dropped_residual)?;
        d.set_item("dropped_appearance", t.dropped_appearance)?;
        d.set_item("dropped_relocation", t.dropped_relocation)?;
        d.set_item("dropped_out_of_frame", t.dropped_out_of_frame)?;
        d.set_item("dropped_lost", t.dropped_lost)?;
        Ok(d)
    }

    /// The main settings in use (None before the first frame when the size was not given).
    #[getter]
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(c) = self.config else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("max_tracks", c.max_tracks)?;
        d.set_item("refill_below", c.refill.below)?;
        d.set_item("window", c.lk.window)?;
        d.set_item("max_level", c.lk.max_level)?;
        d.set_item(
            "illumination",
            match c.lk.illumination {
                kestrel::lk::Illumination::Plain => "plain",
                kestrel::lk::Illumination::GainBias => "gain_bias",
            },
        )?;
        d.set_item("detect_level", c.refill.level)?;
        d.set_item(
            "detector",
            match c.refill.detector {
                kestrel::track::Detector::Fast(_) => "fast",
                kestrel::track::Detector::ShiTomasi(_) => "shi_tomasi",
            },
        )?;
        d.set_item(
            "grid",
            (
                c.refill.grid.cols,
                c.refill.grid.rows,
                c.refill.grid.per_cell,
            ),
        )?;
        d.set_item("fb_threshold", c.gates.fb_threshold)?;
        d.set_item("max_residual", c.gates.max_residual)?;
        d.set_item("residual_ratio", c.gates.residual_ratio)?;
        d.set_item("min_correlation", c.gates.min_correlation)?;
        d.set_item("least_correlation", c.gates.least_correlation)?;
        d.set_item("relocate_every", c.relocation.every)?;
        d.set_item("max_relocation", c.relocation.max_distance)?;
        d.set_item("leaving_within", c.refill.leaving_within)?;
        d.set_item("revive_within", c.relocation.revive_within)?;
        Ok(Some(d))
    }

    fn __len__(&self) -> usize {
        self.tracks().len()
    }

    fn __repr__(&self) -> String {
        match self.size {
            Some((w, h)) => format!(
                "Tracker({w}x{h}, {} live tracks, {} frames)",
                self.tracks().len(),
                self.frames
            ),
            None => "Tracker(size from the first frame)".into(),
        }
    }
}
