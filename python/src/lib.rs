//! Python bindings of Kestrel (`import kestrel`): numpy arrays in and out, OpenCV's argument
//! names and result shapes, the GIL released while the library computes.
//!
//! Every function checks its arguments and raises `TypeError` or `ValueError` with a message
//! naming the argument and the limit; nothing in the library panics on bad input, and nothing
//! here indexes unchecked input.

use pyo3::prelude::*;

mod arrays;
mod dense;
mod detect;
mod ego;
mod lk;
mod settings;
mod tracker;

/// The compiled part of the `kestrel` package; `kestrel/__init__.py` re-exports it.
#[pymodule]
fn _kestrel(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(lk::calc_optical_flow_pyr_lk, m)?)?;
    m.add_function(wrap_pyfunction!(detect::good_features_to_track, m)?)?;
    m.add_function(wrap_pyfunction!(detect::fast, m)?)?;
    m.add_function(wrap_pyfunction!(dense::dense_flow, m)?)?;
    m.add_function(wrap_pyfunction!(dense::flow_to_color, m)?)?;
    m.add_class::<dense::MotionDetector>()?;
    m.add_class::<dense::MotionResult>()?;
    m.add_class::<tracker::Tracker>()?;
    m.add_class::<tracker::FrameReport>()?;
    m.add_function(wrap_pyfunction!(ego::estimate_motion, m)?)?;
    m.add_function(wrap_pyfunction!(ego::heartbeat_mavlink, m)?)?;
    m.add_class::<ego::EgoMotion>()?;
    m.add_class::<ego::FlowReading>()?;
    m.add_class::<ego::FlowSensor>()?;
    m.add("OPTFLOW_USE_INITIAL_FLOW", lk::OPTFLOW_USE_INITIAL_FLOW)?;
    m.add(
        "OPTFLOW_LK_GET_MIN_EIGENVALS",
        lk::OPTFLOW_LK_GET_MIN_EIGENVALS,
    )?;
    Ok(())
}
