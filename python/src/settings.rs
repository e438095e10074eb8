//! Python arguments checked and turned into the library's settings, with messages that name
//! the argument and the limit.

use kestrel::lk::{Illumination, MAX_WINDOW};
use kestrel::pyramid::{level_size, MAX_LEVEL};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// A `ValueError` with `message`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// A frame size given as `width` and `height` (both or neither), each 1 to the library's
/// largest side.
pub fn frame_size(width: Option<i64>, height: Option<i64>) -> PyResult<Option<(usize, usize)>> {
    match (width, height) {
        (None, None) => Ok(None),
        (Some(w), Some(h)) => {
            let max = kestrel::MAX_DIMENSION;
            let side = |v: i64| usize::try_from(v).ok().filter(|v| (1..=max).contains(v));
            match (side(w), side(h)) {
                (Some(w), Some(h)) => Ok(Some((w, h))),
                _ => Err(value_error(format!(
                    "width and height must be 1 to {max} px: got {w}x{h}"
                ))),
            }
        }
        _ => Err(value_error("give both width and height, or neither")),
    }
}

/// A window side from OpenCV's `winSize` (a `(width, height)` pair) or a single int: odd,
/// 3 to 63, and square.
pub fn window(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<usize> {
    let (w, h) = if let Ok(side) = obj.extract::<i64>() {
        (side, side)
    } else if let Ok(pair) = obj.extract::<(i64, i64)>() {
        pair
    } else {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a (width, height) pair of ints or an int"
        )));
    };
    if w != h {
        return Err(value_error(format!(
            "{name} must be square (the library's windows are square): got ({w}, {h})"
        )));
    }
    side(w, name)
}

/// An odd window side from 3 to 63.
pub fn side(w: i64, name: &str) -> PyResult<usize> {
    let max = MAX_WINDOW as i64;
    if !(3..=max).contains(&w) || w % 2 == 0 {
        return Err(value_error(format!(
            "{name} must be odd and from 3 to {max} px: got {w}"
        )));
    }
    Ok(w as usize)
}

/// A pyramid depth from 0 to 7.
pub fn max_level(level: i64) -> PyResult<usize> {
    let max = MAX_LEVEL as i64;
    if !(0..=max).contains(&level) {
        return Err(value_error(format!(
            "max_level must be from 0 to {max}: got {level}"
        )));
    }
    Ok(level as usize)
}

/// Refuses a pyramid whose coarsest level is no wider or higher than half the window (the
/// library's dense mode refuses the same), naming the deepest level that fits.
pub fn check_depth(width: usize, height: usize, window: usize, level: usize) -> PyResult<()> {
    let half = window / 2;
    let fits = |l: usize| level_size(width, l).min(level_size(height, l)) > half;
    if fits(level) {
        return Ok(());
    }
    if !fits(0) {
        return Err(value_error(format!(
            "a {window} px window is too large for a {width}x{height} frame: the frame's \
             smaller side must be more than half the window ({half} px)"
        )));
    }
    let deepest = (0..level).rev().find(|&l| fits(l)).unwrap_or(0);
    Err(value_error(format!(
        "max_level {level} is too deep for a {width}x{height} frame with a {window} px window: \
         level {level} is {}x{} px, and the coarsest level must be more than half the window \
         ({half} px) per side; use max_level <= {deepest}",
        level_size(width, level),
        level_size(height, level)
    )))
}

/// `"gain_bias"` (the library's default) or `"plain"` (classic LK, OpenCV's).
pub fn illumination(name: &str) -> PyResult<Illumination> {
    match name {
        "gain_bias" | "gain-bias" => Ok(Illumination::GainBias),
        "plain" => Ok(Illumination::Plain),
        other => Err(value_error(format!(
            "illumination must be 'gain_bias' or 'plain': got {other:?}"
        ))),
    }
}

/// A finite number >= 0.
pub fn non_negative(value: f64, name: &str) -> PyResult<f32> {
    if !value.is_finite() || value < 0.0 {
        return Err(value_error(format!(
            "{name} must be a finite number >= 0: got {value}"
        )));
    }
    Ok(value as f32)
}

/// A correlation, -1 to 1.
pub fn correlation(value: f64, name: &str) -> PyResult<f32> {
    if !(-1.0..=1.0).contains(&value) {
        return Err(value_error(format!(
            "{name} must be from -1 to 1: got {value}"
        )));
    }
    Ok(value as f32)
}
