//! `good_features_to_track` (Shi-Tomasi) and `fast` (FAST-9): the library's detectors with
//! OpenCV's argument names.

use kestrel::detect::{
    fast_scratch_len, shi_tomasi_scratch_len, Corner, Fast, Region, ShiTomasi, MAX_BLOCK,
};
use numpy::{PyArrayDescrMethods, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

use crate::arrays::{self, Frame};
use crate::settings::value_error;

/// The detection region an OpenCV-style mask gives: the rectangle of its non-zero pixels.
/// Masks of other shapes are refused (the library detects in a rectangle).
fn mask_region(mask: &Bound<'_, PyAny>, frame: &Frame<'_>) -> PyResult<Option<Region>> {
    let array = mask
        .cast::<PyUntypedArray>()
        .map_err(|_| PyTypeError::new_err("mask must be a numpy array (uint8, 0 = excluded)"))?;
    if !array.dtype().is_equiv_to(&numpy::dtype::<u8>(mask.py())) {
        return Err(PyTypeError::new_err(
            "mask must be a uint8 array (0 = excluded)",
        ));
    }
    let shape = array.shape().to_vec();
    if shape != [frame.height, frame.width] {
        return Err(value_error(format!(
            "mask has shape {shape:?} but image is {}x{} (shape [{}, {}])",
            frame.width, frame.height, frame.height, frame.width
        )));
    }
    let typed = array
        .cast::<numpy::PyArray2<u8>>()
        .map_err(|_| PyTypeError::new_err("mask must be a 2-D uint8 array"))?;
    let readonly = typed.readonly();
    let view = readonly.as_array();
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    let mut set = 0usize;
    for ((y, x), &v) in view.indexed_iter() {
        if v != 0 {
            set += 1;
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
    }
    if set == 0 {
        return Ok(None);
    }
    let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
    if set != w * h {
        return Err(value_error(format!(
            "mask must select one rectangle of pixels (the library detects inside a \
             rectangle): its non-zero pixels span x {x0}..={x1}, y {y0}..={y1} but fill only \
             {set} of its {} pixels",
            w * h
        )));
    }
    Ok(Some(Region::new(x0, y0, w, h)))
}

/// Positions of `corners` as an `N x 1 x 2` float32 array.
fn corner_array<'py>(py: Python<'py>, corners: &[Corner], shape: &[usize]) -> PyResult<Py<PyAny>> {
    let mut data = Vec::with_capacity(2 * corners.len());
    for c in corners {
        let (x, y) = c.position.to_f32();
        data.extend([x, y]);
    }
    Ok(arrays::array(py, data, shape)?.into_any().unbind())
}

/// Finds the strongest Shi-Tomasi corners of `image`, as `cv2.goodFeaturesToTrack` does, and
/// returns them as an `N x 1 x 2` float32 array, strongest first (`N = 0` when there are none,
/// where OpenCV returns None).
///
/// image: 2-D uint8 frame (rows may be a stride apart).
/// max_corners: at most this many corners; 0 or less means no limit, as in OpenCV.
/// quality_level: corners scoring at most this share of the strongest one's score are
///     dropped, 0 to 1.
/// min_distance: corners closer than this (px, a whole number, 0 to 65535) to a stronger
///     kept corner are dropped.
/// mask: optional uint8 array of the image's shape; the library detects inside one
///     rectangle, so the mask's non-zero pixels must form a rectangle (ValueError otherwise).
/// block_size: side of the gradient sums, odd, 3 to 7.
/// use_harris_detector: must be False (the library has no Harris score).
/// k: Harris parameter, accepted for OpenCV compatibility and unused.
///
/// Corners are at pixel centres (whole coordinates); pixels within block_size // 2 + 1 of the
/// border are never corners. The GIL is released while detecting.
#[pyfunction]
#[pyo3(signature = (image, max_corners, quality_level, min_distance, mask=None, block_size=3,
    use_harris_detector=false, k=0.04))]
#[allow(clippy::too_many_arguments)]
pub fn good_features_to_track<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    max_corners: i64,
    quality_level: f64,
    min_distance: f64,
    mask: Option<&Bound<'py, PyAny>>,
    block_size: i64,
    use_harris_detector: bool,
    k: f64,
) -> PyResult<Py<PyAny>> {
    let _ = k;
    let frame = arrays::frame(image, "image")?;
    if use_harris_detector {
        return Err(value_error(
            "use_harris_detector=True is not supported: the library has no Harris score, only \
             the minimum eigenvalue (Shi-Tomasi)",
        ));
    }
    if !(0.0..=1.0).contains(&quality_level) {
        return Err(value_error(format!(
            "quality_level must be from 0 to 1: got {quality_level}"
        )));
    }
    if !min_distance.is_finite()
        || min_distance < 0.0
        || min_distance > f64::from(u16::MAX)
        || min_distance.fract() != 0.0
    {
        return Err(value_error(format!(
            "min_distance must be a whole number of pixels from 0 to 65535 (the library \
             spaces corners by whole pixels): got {min_distance}"
        )));
    }
    let max_block = MAX_BLOCK as i64;
    if !(3..=max_block).contains(&block_size) || block_size % 2 == 0 {
        return Err(value_error(format!(
            "block_size must be odd and from 3 to {max_block}: got {block_size}"
        )));
    }
    let region = match mask {
        Some(mask) => match mask_region(mask, &frame)? {
            Some(region) => region,
            None => return corner_array(py, &[], &[0, 1, 2]),
        },
        None => Region::new(0, 0, frame.width, frame.height),
    };
    let detector = ShiTomasi {
        block: block_size as usize,
        quality_level: quality_level as f32,
        min_distance: min_distance as u16,
    };
    let pixels = frame.pixels();
    // Room for every 3 x 3 local maximum (at most one pixel in four, ties aside): the quality
    // level and the spacing then see them all, as OpenCV's do, and the strongest `max_corners`
    // of the spaced corners are kept.
    let capacity = (pixels.width * pixels.height).div_ceil(4);
    let corners = py
        .detach(|| -> Result<Vec<Corner>, String> {
            let view = pixels.view()?;
            let mut scratch = vec![0i32; shi_tomasi_scratch_len(pixels.width, capacity)];
            let mut out = vec![Corner::default(); capacity];
            let n = detector
                .detect(&view, region, None, &mut scratch, &mut out)
                .map_err(|e| e.to_string())?;
            out.truncate(n);
            Ok(out)
        })
        .map_err(value_error)?;
    let keep = if max_corners > 0 {
        corners.len().min(max_corners as usize)
    } else {
        corners.len()
    };
    corner_array(py, &corners[..keep], &[keep, 1, 2])
}

/// Finds FAST-9 corners (Rosten and Drummond; OpenCV's `FastFeatureDetector` with
/// `TYPE_9_16`) and returns their positions as an `N x 2` float32 array of pixel centres
/// (x, y), strongest first, or with `return_scores=True` a pair `(points, scores)` where
/// `scores` is an `N` uint32 array of FAST scores (the largest threshold at which each is
/// still a corner).
///
/// image: 2-D uint8 frame (rows may be a stride apart).
/// threshold: brightness difference, grey levels, 0 to 255 (OpenCV's default 10).
/// nonmax_suppression: keep only the corners whose score is a strict 3 x 3 local maximum.
/// max_keypoints: keep at most this many, the strongest (None: all).
///
/// Pixels within 3 px of the border are never corners. The GIL is released while detecting.
#[pyfunction]
#[pyo3(signature = (image, threshold=10, nonmax_suppression=true, max_keypoints=None,
    return_scores=false))]
pub fn fast<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    threshold: i64,
    nonmax_suppression: bool,
    max_keypoints: Option<i64>,
    return_scores: bool,
) -> PyResult<Py<PyAny>> {
    let frame = arrays::frame(image, "image")?;
    let threshold = u8::try_from(threshold)
        .map_err(|_| value_error(format!("threshold must be from 0 to 255: got {threshold}")))?;
    let capacity = match max_keypoints {
        Some(n) if n < 1 => {
            return Err(value_error(format!(
                "max_keypoints must be at least 1 (or None for all): got {n}"
            )))
        }
        Some(n) => (n as usize).min(frame.width * frame.height),
        None => frame.width * frame.height,
    };
    let detector = Fast {
        threshold,
        nonmax: nonmax_suppression,
    };
    let pixels = frame.pixels();
    let corners = py
        .detach(|| -> Result<Vec<Corner>, String> {
            let view = pixels.view()?;
            let mut scratch = vec![0u8; fast_scratch_len(pixels.width)];
            let mut out = vec![Corner::default(); capacity];
            let region = Region::full(&view);
            let n = detector
                .detect(&view, region, None, &mut scratch, &mut out)
                .map_err(|e| e.to_string())?;
            out.truncate(n);
            Ok(out)
        })
        .map_err(value_error)?;
    let points = corner_array(py, &corners, &[corners.len(), 2])?;
    if !return_scores {
        return Ok(points);
    }
    let scores: Vec<u32> = corners.iter().map(|c| c.score).collect();
    let n = scores.len();
    let scores = arrays::array(py, scores, &[n])?;
    (points, scores).into_py_any(py)
}
