//! `calc_optical_flow_pyr_lk`: the library's pyramidal LK with OpenCV's arguments and results.

use kestrel::lk::{scratch_len, LkParams, LucasKanade, PointTrack, TrackStatus};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::Point;
use numpy::PyArrayDyn;
use pyo3::prelude::*;

use crate::arrays::{self, Pixels};
use crate::settings::{self, value_error};

/// OpenCV's `OPTFLOW_USE_INITIAL_FLOW`: `next_pts` holds the starting guesses.
pub const OPTFLOW_USE_INITIAL_FLOW: i64 = 4;
/// OpenCV's `OPTFLOW_LK_GET_MIN_EIGENVALS`: `err` holds minimum eigenvalues (not supported).
pub const OPTFLOW_LK_GET_MIN_EIGENVALS: i64 = 8;
/// OpenCV's `TERM_CRITERIA_COUNT` and `TERM_CRITERIA_EPS`.
const CRITERIA_COUNT: i64 = 1;
const CRITERIA_EPS: i64 = 2;

/// Iterations and epsilon from OpenCV's `(type, max_count, epsilon)` criteria.
fn criteria(obj: &Bound<'_, PyAny>) -> PyResult<(u32, f32)> {
    let (kind, count, epsilon) = obj.extract::<(i64, i64, f64)>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "criteria must be a (type, max_count, epsilon) tuple, e.g. \
             (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01)",
        )
    })?;
    if !(1..=3).contains(&kind) {
        return Err(value_error(format!(
            "criteria type must be TERM_CRITERIA_COUNT (1), TERM_CRITERIA_EPS (2) or both (3): \
             got {kind}"
        )));
    }
    // As OpenCV: a criterion not selected by `type` takes its default.
    let iterations = if kind & CRITERIA_COUNT != 0 {
        if !(1..=i64::from(u32::MAX)).contains(&count) {
            return Err(value_error(format!(
                "criteria max_count must be at least 1: got {count}"
            )));
        }
        count as u32
    } else {
        30
    };
    let epsilon = if kind & CRITERIA_EPS != 0 {
        settings::non_negative(epsilon, "criteria epsilon")?
    } else {
        0.01
    };
    Ok((iterations, epsilon))
}

/// Builds both pyramids and tracks every point, with the GIL released by the caller.
pub fn track(
    prev: Pixels<'_>,
    next: Pixels<'_>,
    params: LkParams,
    points: &[Point],
    guesses: Option<&[Point]>,
) -> Result<Vec<PointTrack>, String> {
    let lk = LucasKanade::new(params).map_err(|e| e.to_string())?;
    let levels = params.max_level;
    let len = pyramid_storage_len(prev.width, prev.height, levels);
    let (mut prev_storage, mut next_storage) = (vec![0u8; len], vec![0u8; len]);
    let prev_pyramid =
        Pyramid::build(prev.view()?, levels, &mut prev_storage).map_err(|e| e.to_string())?;
    let next_pyramid =
        Pyramid::build(next.view()?, levels, &mut next_storage).map_err(|e| e.to_string())?;
    let mut scratch = vec![0i16; scratch_len(params.window)];
    let mut out = vec![PointTrack::default(); points.len()];
    lk.track_points(
        &prev_pyramid,
        &next_pyramid,
        points,
        guesses,
        &mut out,
        &mut scratch,
    )
    .map_err(|e| e.to_string())?;
    Ok(out)
}

/// The name of a point's status, as the library gives it.
pub fn status_name(status: TrackStatus) -> &'static str {
    match status {
        TrackStatus::Tracked => "tracked",
        TrackStatus::OutOfBounds => "out_of_bounds",
        TrackStatus::LowTexture => "low_texture",
        TrackStatus::NotConverged => "not_converged",
    }
}

/// Tracks points from `prev` to `next` with pyramidal Lucas-Kanade, as
/// `cv2.calcOpticalFlowPyrLK` does, and returns `(next_pts, status, err)` in OpenCV's shapes
/// and dtypes: `N x 1 x 2 float32`, `N x 1 uint8` (1 = tracked) and `N x 1 float32` (the mean
/// absolute residual over the window, grey levels, after the gain and bias correction; 0 for
/// points not tracked).
///
/// prev, next: 2-D uint8 frames of one size. Rows may be a stride apart (crops of a larger
///     array are viewed, not copied); pixels must be contiguous within a row.
/// prev_pts: float32 points, shape (N, 1, 2) or (N, 2), N >= 1, finite.
/// next_pts: starting guesses of the same shape, used when `flags` has
///     OPTFLOW_USE_INITIAL_FLOW (4); ignored otherwise, as in OpenCV.
/// win_size: (w, h) window, default (21, 21) (None too); the library's windows are square,
///     odd, 3 to 63 px.
/// max_level: coarsest pyramid level, 0 to 7, and the coarsest level must be more than half
///     a window wide and high (OpenCV silently uses fewer levels; this raises ValueError).
/// criteria: (type, max_count, epsilon) as in OpenCV, default (3, 30, 0.01) (None too):
///     iterations per level (>= 1) and the step below which iteration stops, px (>= 0).
/// flags: 0 or OPTFLOW_USE_INITIAL_FLOW (4); OPTFLOW_LK_GET_MIN_EIGENVALS (8) is not supported.
/// min_eig_threshold: minimum eigenvalue of the gradient matrix / window area, OpenCV's
///     scale (>= 0); weaker windows are not tracked.
/// illumination: "gain_bias" (default: fits a brightness gain and bias between the windows,
///     robust to auto-exposure) or "plain" (classic LK, as OpenCV).
/// return_reasons: also return an N-element list of why each point was or was not tracked
///     ("tracked", "out_of_bounds", "low_texture", "not_converged").
///
/// Raises TypeError for arrays of another type or dtype, ValueError for other shapes,
/// layouts, sizes and settings out of the library's range. The GIL is released while the
/// pyramids are built and the points tracked.
#[pyfunction]
#[pyo3(signature = (prev, next, prev_pts, next_pts=None, win_size=None, max_level=3,
    criteria=None, flags=0, min_eig_threshold=1e-4, illumination="gain_bias",
    return_reasons=false),
    text_signature = "(prev, next, prev_pts, next_pts=None, win_size=(21, 21), max_level=3, \
    criteria=(3, 30, 0.01), flags=0, min_eig_threshold=1e-4, illumination='gain_bias', \
    return_reasons=False)")]
#[allow(clippy::too_many_arguments)]
pub fn calc_optical_flow_pyr_lk<'py>(
    py: Python<'py>,
    prev: &Bound<'py, PyAny>,
    next: &Bound<'py, PyAny>,
    prev_pts: &Bound<'py, PyAny>,
    next_pts: Option<&Bound<'py, PyAny>>,
    win_size: Option<&Bound<'py, PyAny>>,
    max_level: i64,
    criteria: Option<&Bound<'py, PyAny>>,
    flags: i64,
    min_eig_threshold: f64,
    illumination: &str,
    return_reasons: bool,
) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
    let prev = arrays::frame(prev, "prev")?;
    let next = arrays::frame(next, "next")?;
    arrays::same_size(&prev, "prev", &next, "next")?;
    let window = match win_size {
        Some(w) => settings::window(w, "win_size")?,
        None => 21,
    };
    let max_level = settings::max_level(max_level)?;
    settings::check_depth(prev.width, prev.height, window, max_level)?;
    let (max_iterations, epsilon) = match criteria {
        Some(c) => self::criteria(c)?,
        None => (30, 0.01),
    };
    if flags & OPTFLOW_LK_GET_MIN_EIGENVALS != 0 {
        return Err(value_error(
            "flags: OPTFLOW_LK_GET_MIN_EIGENVALS (8) is not supported: err is always the mean \
             absolute residual",
        ));
    }
    if flags & !OPTFLOW_USE_INITIAL_FLOW != 0 {
        return Err(value_error(format!(
            "flags must be 0 or OPTFLOW_USE_INITIAL_FLOW (4): got {flags}"
        )));
    }
    let min_eigen_threshold = settings::non_negative(min_eig_threshold, "min_eig_threshold")?;
    let params = LkParams {
        window,
        max_level,
        max_iterations,
        epsilon,
        min_eigen_threshold,
        illumination: settings::illumination(illumination)?,
        ..LkParams::default()
    };
    let starts = arrays::points(prev_pts, "prev_pts")?;
    let guesses = if flags & OPTFLOW_USE_INITIAL_FLOW != 0 {
        let Some(next_pts) = next_pts else {
            return Err(value_error(
                "flags has OPTFLOW_USE_INITIAL_FLOW but next_pts is None: give the starting \
                 guesses",
            ));
        };
        let guesses = arrays::points(next_pts, "next_pts")?;
        if guesses.len() != starts.len() {
            return Err(value_error(format!(
                "next_pts has {} points but prev_pts has {}",
                guesses.len(),
                starts.len()
            )));
        }
        Some(
            guesses
                .into_iter()
                .map(arrays::to_point)
                .collect::<Vec<_>>(),
        )
    } else {
        None
    };
    let points: Vec<Point> = starts.into_iter().map(arrays::to_point).collect();
    let (prev_pixels, next_pixels) = (prev.pixels(), next.pixels());
    let tracks = py
        .detach(|| {
            track(
                prev_pixels,
                next_pixels,
                params,
                &points,
                guesses.as_deref(),
            )
        })
        .map_err(value_error)?;

    let n = tracks.len();
    let mut positions = Vec::with_capacity(2 * n);
    let mut status = Vec::with_capacity(n);
    let mut err = Vec::with_capacity(n);
    for t in &tracks {
        let (x, y) = t.position.to_f32();
        positions.extend([x, y]);
        status.push(u8::from(t.is_tracked()));
        err.push(t.residual.to_num::<f32>());
    }
    let positions: Bound<'py, PyArrayDyn<f32>> = arrays::array(py, positions, &[n, 1, 2])?;
    let status = arrays::array(py, status, &[n, 1])?;
    let err = arrays::array(py, err, &[n, 1])?;
    if return_reasons {
        let reasons: Vec<&str> = tracks.iter().map(|t| status_name(t.status)).collect();
        pyo3::types::PyTuple::new(
            py,
            [
                positions.into_any(),
                status.into_any(),
                err.into_any(),
                reasons.into_pyobject(py)?.into_any(),
            ],
        )
    } else {
        pyo3::types::PyTuple::new(
            py,
            [positions.into_any(), status.into_any(), err.into_any()],
        )
    }
}
