//! Dense grid flow, its Middlebury colour picture, and moving-object boxes.

use host_sim::dense::field::FlowField;
use host_sim::dense::wheel::{colour_wheel, flow_colour, flow_picture};
use host_sim::dense::{MotionFrame, MotionRunner, MotionSettings};
use host_sim::Frame as HostFrame;
use kestrel::dense::{
    smooth_scratch_len, smooth_tracked, DenseFlow, DenseParams, GridLayout, GridNode, SMOOTH_GATE,
    SMOOTH_PASSES,
};
use kestrel::lk::{scratch_len, LkParams};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::Point;
use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

use crate::arrays::{self, Pixels};
use crate::settings::{self, value_error};

/// The grid flow of a frame pair: builds both pyramids, tracks every node, fills and smooths.
fn grid_flow(
    prev: Pixels<'_>,
    next: Pixels<'_>,
    dense: &DenseFlow,
    layout: &GridLayout,
    smooth: bool,
) -> Result<Vec<GridNode>, String> {
    let params = dense.params();
    let levels = params.lk.max_level;
    let len = pyramid_storage_len(prev.width, prev.height, levels);
    let (mut a, mut b) = (vec![0u8; len], vec![0u8; len]);
    let prev = Pyramid::build(prev.view()?, levels, &mut a).map_err(|e| e.to_string())?;
    let next = Pyramid::build(next.view()?, levels, &mut b).map_err(|e| e.to_string())?;
    let mut nodes = vec![GridNode::EMPTY; layout.len()];
    let mut scratch = vec![0i16; scratch_len(params.lk.window)];
    dense
        .compute(&prev, &next, &mut nodes, &mut scratch)
        .map_err(|e| e.to_string())?;
    if smooth {
        let mut rows = vec![Point::default(); smooth_scratch_len(layout.width(), layout.cell())];
        for _ in 0..SMOOTH_PASSES {
            smooth_tracked(layout, &mut nodes, SMOOTH_GATE, &mut rows)
                .map_err(|e| e.to_string())?;
        }
    }
    Ok(nodes)
}

/// LK flow on a regular grid, the library's dense mode: a node every `cell` px (node (col, row)
/// at pixel (cell // 2 + col * cell, cell // 2 + row * cell)), each tracked with a small LK
/// window, gated by texture, convergence and residual; invalid nodes filled from valid
/// neighbours (fill_passes), then measured nodes smoothed with the neighbours that move alike
/// (smooth=True).
///
/// Returns `(flow, valid)`: flow is a float32 array (rows, cols, 2) of (dx, dy) in px, NaN where
/// a node has no flow; valid is a bool array (rows, cols), True where the flow was measured
/// (False for filled and unknown nodes). With full_resolution=True both are interpolated from
/// the grid to every pixel of the frame, (height, width, 2) and (height, width), valid then
/// saying where a flow is known.
///
/// prev, next: 2-D uint8 frames of one size (rows may be a stride apart).
/// cell: grid spacing, px, 1 to the frame's smaller side.
/// window: LK window side, odd, 3 to 63 (dense default 9).
/// max_level: coarsest pyramid level, 0 to 7; the coarsest level must be more than half a
///     window per side.
/// min_eig_threshold: texture threshold in OpenCV's scale (dense default 7e-4).
/// illumination: "gain_bias" or "plain".
/// max_residual: residual gate, grey levels (>= 0).
/// fill_passes: passes filling invalid nodes from their neighbours, 0 to 255.
///
/// The GIL is released while the flow is computed.
#[pyfunction]
#[pyo3(signature = (prev, next, cell=8, *, window=9, max_level=3, min_eig_threshold=7e-4,
    illumination="gain_bias", max_residual=12.0, fill_passes=2, smooth=true,
    full_resolution=false))]
#[allow(clippy::too_many_arguments)]
pub fn dense_flow<'py>(
    py: Python<'py>,
    prev: &Bound<'py, PyAny>,
    next: &Bound<'py, PyAny>,
    cell: i64,
    window: i64,
    max_level: i64,
    min_eig_threshold: f64,
    illumination: &str,
    max_residual: f64,
    fill_passes: i64,
    smooth: bool,
    full_resolution: bool,
) -> PyResult<Py<PyAny>> {
    let prev = arrays::frame(prev, "prev")?;
    let next = arrays::frame(next, "next")?;
    arrays::same_size(&prev, "prev", &next, "next")?;
    let (w, h) = prev.size();
    if cell < 1 || cell as usize > w.min(h) {
        return Err(value_error(format!(
            "cell must be from 1 px to the frame's smaller side ({} px for {w}x{h}): got {cell}",
            w.min(h)
        )));
    }
    let window = settings::side(window, "window")?;
    let max_level = settings::max_level(max_level)?;
    settings::check_depth(w, h, window, max_level)?;
    let fill_passes = u8::try_from(fill_passes)
        .map_err(|_| value_error(format!("fill_passes must be 0 to 255: got {fill_passes}")))?;
    let params = DenseParams {
        cell: cell as usize,
        lk: LkParams {
            window,
            max_level,
            min_eigen_threshold: settings::non_negative(min_eig_threshold, "min_eig_threshold")?,
            illumination: settings::illumination(illumination)?,
            ..DenseParams::default().lk
        },
        max_residual: settings::non_negative(max_residual, "max_residual")?,
        fill_passes,
        ..DenseParams::default()
    };
    let dense = DenseFlow::new(params).map_err(|e| value_error(e.to_string()))?;
    let layout = dense.layout(w, h).map_err(|e| value_error(e.to_string()))?;
    let (a, b) = (prev.pixels(), next.pixels());
    let nodes = py
        .detach(|| grid_flow(a, b, &dense, &layout, smooth))
        .map_err(value_error)?;

    if full_resolution {
        let field = FlowField::from_grid(&layout, &nodes);
        let mut flow = Vec::with_capacity(2 * w * h);
        let mut valid = Vec::with_capacity(w * h);
        for f in &field.flow {
            let (u, v) = f.unwrap_or((f32::NAN, f32::NAN));
            flow.extend([u, v]);
            valid.push(f.is_some());
        }
        let flow = arrays::array(py, flow, &[h, w, 2])?;
        let valid = arrays::array(py, valid, &[h, w])?;
        return (flow, valid).into_py_any(py);
    }
    let (cols, rows) = (layout.cols(), layout.rows());
    let mut flow = Vec::with_capacity(2 * nodes.len());
    for n in &nodes {
        let (u, v) = if n.has_flow() {
            n.flow.to_f32()
        } else {
            (f32::NAN, f32::NAN)
        };
        flow.extend([u, v]);
    }
    let valid: Vec<bool> = nodes.iter().map(|n| n.is_valid()).collect();
    let flow = arrays::array(py, flow, &[rows, cols, 2])?;
    let valid = arrays::array(py, valid, &[rows, cols])?;
    (flow, valid).into_py_any(py)
}

/// Reads an (H, W, 2) float32 flow field, NaN where unknown.
fn flow_field(obj: &Bound<'_, PyAny>) -> PyResult<FlowField> {
    let array = obj
        .cast::<PyUntypedArray>()
        .map_err(|_| PyTypeError::new_err("flow must be a numpy array (H, W, 2) float32"))?;
    if !array.dtype().is_equiv_to(&numpy::dtype::<f32>(obj.py())) {
        return Err(PyTypeError::new_err(
            "flow must be a float32 array (H, W, 2); use flow.astype(np.float32)",
        ));
    }
    let shape = array.shape().to_vec();
    if shape.len() != 3 || shape[2] != 2 || shape[0] == 0 || shape[1] == 0 {
        return Err(value_error(format!(
            "flow must have shape (H, W, 2) with H, W >= 1: got {shape:?}"
        )));
    }
    let typed = array
        .cast::<PyArrayDyn<f32>>()
        .map_err(|_| PyTypeError::new_err("flow must be a float32 array"))?;
    let readonly = typed.readonly();
    let values: Vec<f32> = readonly.as_array().iter().copied().collect();
    let flow = values
        .chunks_exact(2)
        .map(|uv| (uv[0].is_finite() && uv[1].is_finite()).then_some((uv[0], uv[1])))
        .collect();
    Ok(FlowField {
        width: shape[1],
        height: shape[0],
        flow,
    })
}

/// The Middlebury colour picture of a flow field (Baker et al. 2011, its colorcode.cpp): hue
/// is the direction (right red, down yellow-orange, left cyan-blue, up violet), saturation
/// grows with speed from white at rest to the full colour at `max_speed` (default: the
/// largest speed in the field), darker beyond it; unknown flow (NaN) is black.
///
/// flow: float32 array (H, W, 2), e.g. from dense_flow(..., full_resolution=True) or
///     cv2.calcOpticalFlowFarneback.
/// max_speed: speed, px, that gets the full colour (> 0); None for the field's largest.
/// legend: draw the colour wheel in the top-right corner (its rim is the largest speed;
///     max_speed must then be None).
/// bgr: return channels in OpenCV's BGR order (for cv2.imwrite / cv2.imshow) instead of RGB.
///
/// Returns an (H, W, 3) uint8 picture.
#[pyfunction]
#[pyo3(signature = (flow, max_speed=None, legend=false, bgr=false))]
pub fn flow_to_color<'py>(
    py: Python<'py>,
    flow: &Bound<'py, PyAny>,
    max_speed: Option<f64>,
    legend: bool,
    bgr: bool,
) -> PyResult<Py<PyAny>> {
    let field = flow_field(flow)?;
    if let Some(s) = max_speed {
        if !s.is_finite() || s <= 0.0 {
            return Err(value_error(format!(
                "max_speed must be a finite number > 0: got {s}"
            )));
        }
        if legend {
            return Err(value_error(
                "legend=True scales by the field's largest speed: give max_speed=None",
            ));
        }
    }
    let (w, h) = (field.width, field.height);
    let mut rgb: Vec<u8> = py.detach(|| {
        if legend {
            flow_picture(&field).into_raw()
        } else {
            let wheel = colour_wheel();
            let scale = max_speed
                .map(|s| s as f32)
                .unwrap_or_else(|| field.max_speed())
                .max(f32::EPSILON);
            let mut out = Vec::with_capacity(3 * w * h);
            for f in &field.flow {
                out.extend(f.map_or([0, 0, 0], |(u, v)| {
                    flow_colour(&wheel, u / scale, v / scale)
                }));
            }
            out
        }
    });
    if bgr {
        for px in rgb.chunks_exact_mut(3) {
            px.swap(0, 2);
        }
    }
    Ok(arrays::array(py, rgb, &[h, w, 3])?.into_any().unbind())
}

/// What moved between two frames besides the camera.
#[pyclass(module = "kestrel", frozen, get_all)]
pub struct MotionResult {
    /// Boxes in the earlier frame, int32 (K, 4): x, y, width, height, largest first.
    boxes: Py<PyAny>,
    /// The same boxes moved by their objects' flow into the later frame, int32 (K, 4).
    boxes_next: Py<PyAny>,
    /// Each box's mean flow, px, float32 (K, 2).
    box_flow: Py<PyAny>,
    /// The camera's motion as an affine flow, float32 (2, 3): dx = a0 + a1 x + a2 y (first
    /// row), dy likewise (second row).
    camera: Py<PyAny>,
    /// Grid nodes whose flow the camera model explains.
    camera_inliers: usize,
    /// Grid nodes that move unlike the camera (after cleaning).
    moving: usize,
    /// Connected moving regions before outlining and persistence.
    regions: usize,
}

#[pymethods]
impl MotionResult {
    fn __repr__(&self, py: Python<'_>) -> String {
        let k = self.boxes.bind(py).len().unwrap_or(0);
        format!(
            "MotionResult({k} boxes, {} moving nodes, {} regions)",
            self.moving, self.regions
        )
    }
}

fn motion_result(
    py: Python<'_>,
    found: &MotionFrame,
    width: usize,
    height: usize,
) -> PyResult<MotionResult> {
    let k = found.boxes.len();
    let rect = |b: &kestrel::dense::MotionBox| {
        [
            i32::from(b.x),
            i32::from(b.y),
            i32::from(b.w),
            i32::from(b.h),
        ]
    };
    let boxes: Vec<i32> = found.boxes.iter().flat_map(rect).collect();
    let next: Vec<i32> = found
        .boxes_in_later_frame(width, height)
        .iter()
        .flat_map(rect)
        .collect();
    let flow: Vec<f32> = found
        .boxes
        .iter()
        .flat_map(|b| {
            let (x, y) = b.mean_flow.to_f32();
            [x, y]
        })
        .collect();
    let m = found.camera.motion;
    let camera: Vec<f32> = m.dx.iter().chain(m.dy.iter()).copied().collect();
    Ok(MotionResult {
        boxes: arrays::array(py, boxes, &[k, 4])?.into_any().unbind(),
        boxes_next: arrays::array(py, next, &[k, 4])?.into_any().unbind(),
        box_flow: arrays::array(py, flow, &[k, 2])?.into_any().unbind(),
        camera: arrays::array(py, camera, &[2, 3])?.into_any().unbind(),
        camera_inliers: found.camera.inliers,
        moving: found.summary.moving,
        regions: found.summary.regions,
    })
}

/// The library's moving-object detector over a sequence (host-sim's motion pipeline): grid
/// flow between consecutive frames, the camera's dominant motion fitted to it, the nodes that
/// move otherwise as a cleaned mask, its connected regions outlined at pixel level into
/// object boxes, only the boxes whose objects moved in `persist_pairs` consecutive pairs
/// reported, those that are parts of one body (within 4 px, moving alike against the camera)
/// joined into one, and on a still camera each box grown over the pixels connected to it that
/// changed between the frames (a walker's flat coat and trousers), taking in the boxes it then
/// overlaps and the feet standing below it.
///
/// MotionDetector(width=None, height=None, *, cell=8, persist_pairs=2, outline=True)
///
/// width, height: the frame size; when None, the first frame's size is taken.
/// cell: grid spacing, px.
/// persist_pairs: consecutive frame pairs a region must move in to be reported, 1 to 255.
/// outline: outline regions at pixel level (False keeps the grid's boxes).
///
/// `push(frame)` returns None for the first frame and a MotionResult for every later one.
/// Each frame is copied (packed) into the detector, which keeps the previous one.
#[pyclass(module = "kestrel")]
pub struct MotionDetector {
    settings: MotionSettings,
    runner: Option<MotionRunner>,
    size: Option<(usize, usize)>,
}

#[pymethods]
impl MotionDetector {
    #[new]
    #[pyo3(signature = (width=None, height=None, *, cell=8, persist_pairs=2, outline=true))]
    fn new(
        width: Option<i64>,
        height: Option<i64>,
        cell: i64,
        persist_pairs: i64,
        outline: bool,
    ) -> PyResult<Self> {
        let defaults = MotionSettings::default();
        if cell < 1 {
            return Err(value_error(format!(
                "cell must be at least 1 px: got {cell}"
            )));
        }
        let persist_pairs = u8::try_from(persist_pairs)
            .ok()
            .filter(|&p| p >= 1)
            .ok_or_else(|| {
                value_error(format!(
                    "persist_pairs must be 1 to 255: got {persist_pairs}"
                ))
            })?;
        let settings = MotionSettings {
            dense: DenseParams {
                cell: cell as usize,
                ..defaults.dense
            },
            outline: if outline { defaults.outline } else { None },
            persist_pairs,
            ..defaults
        };
        let mut detector = MotionDetector {
            settings,
            runner: None,
            size: None,
        };
        if let Some((w, h)) = settings::frame_size(width, height)? {
            detector.make(w, h)?;
        }
        Ok(detector)
    }

    /// Takes the next frame (2-D uint8 of the detector's size). Returns None for the first
    /// frame, and for every later one a MotionResult for the pair it ends.
    fn push(&mut self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<Option<MotionResult>> {
        let frame = arrays::frame(frame, "frame")?;
        let (w, h) = frame.size();
        match self.size {
            Some((tw, th)) if (tw, th) != (w, h) => {
                return Err(value_error(format!(
                    "frame is {w}x{h} but the detector was made for {tw}x{th} frames"
                )))
            }
            Some(_) => {}
            None => self.make(w, h)?,
        }
        let pixels = frame.pixels();
        let runner = self
            .runner
            .as_mut()
            .ok_or_else(|| value_error("detector could not be made"))?;
        let found = py
            .detach(|| {
                let host = HostFrame {
                    width: w,
                    height: h,
                    data: pixels.to_packed(),
                };
                runner.push(host).map_err(|e| e.to_string())
            })
            .map_err(value_error)?;
        found.map(|f| motion_result(py, &f, w, h)).transpose()
    }

    /// The frame size `(width, height)`, or None before the first frame when not given.
    #[getter]
    fn size(&self) -> Option<(usize, usize)> {
        self.size
    }
}

impl MotionDetector {
    fn make(&mut self, w: usize, h: usize) -> PyResult<()> {
        let window = self.settings.dense.lk.window;
        settings::check_depth(w, h, window, self.settings.dense.lk.max_level)?;
        let runner = MotionRunner::new(self.settings, w, h)
            .map_err(|e| value_error(format!("motion detector refused {w}x{h} frames: {e}")))?;
        self.runner = Some(runner);
        self.size = Some((w, h));
        Ok(())
    }
}
