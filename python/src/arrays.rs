//! numpy arrays in and out: grey frames as the library's stride-aware views, point lists, and
//! the arrays returned.

use kestrel::Point;
use kestrel::{ImageView, MAX_DIMENSION};
use numpy::ndarray::{Array, IxDyn};
use numpy::{
    IntoPyArray, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArray2, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// The largest coordinate a Q16.16 position holds, px.
pub const MAX_COORDINATE: f32 = 32_767.0;

/// A grey frame borrowed from a numpy array: rows of contiguous pixels `stride` bytes apart.
pub struct Frame<'py> {
    /// Keeps the array borrowed (and alive) while its pixels are viewed.
    array: PyReadonlyArray2<'py, u8>,
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Bytes from one row to the next.
    pub stride: usize,
}

impl Frame<'_> {
    /// The pixels from the first to the last of the frame, rows `stride` bytes apart.
    pub fn bytes(&self) -> &[u8] {
        let len = self.stride * (self.height - 1) + self.width;
        let data = self.array.data() as *const u8;
        // SAFETY: `frame` checked that the array is 2-D uint8 with unit column stride and a
        // row stride of at least the width, so the `len` bytes from the first pixel are inside
        // the array's buffer; the read-only borrow keeps the array alive and stops Rust code
        // from writing to it while the slice lives.
        unsafe { std::slice::from_raw_parts(data, len) }
    }

    /// The frame's size as `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

/// A borrowed frame's pixels and geometry, `Send` so that it can be used with the GIL released.
#[derive(Clone, Copy)]
pub struct Pixels<'a> {
    /// See [`Frame::bytes`].
    pub data: &'a [u8],
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Bytes from one row to the next.
    pub stride: usize,
}

impl<'a> Pixels<'a> {
    /// The library's view of the pixels (geometry already checked), with the library's
    /// message on a refusal (no Python exception is made while the GIL is released).
    pub fn view(&self) -> Result<ImageView<'a>, String> {
        ImageView::new(self.data, self.width, self.height, self.stride)
            .map_err(|e| format!("frame refused: {e}"))
    }

    /// The pixels packed row after row.
    pub fn to_packed(self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.width * self.height);
        for y in 0..self.height {
            let start = y * self.stride;
            out.extend_from_slice(&self.data[start..start + self.width]);
        }
        out
    }
}

impl<'py> Frame<'py> {
    /// The pixels, detached from Python.
    pub fn pixels(&self) -> Pixels<'_> {
        Pixels {
            data: self.bytes(),
            width: self.width,
            height: self.height,
            stride: self.stride,
        }
    }
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "object".into())
}

fn shape_text(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(|s| s.to_string()).collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// `obj` as a numpy array, or a `TypeError` naming the argument.
fn ndarray<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    obj.cast::<PyUntypedArray>().cloned().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a numpy array, got {}",
            type_name(obj)
        ))
    })
}

/// Checks `obj` is a grey frame the library can view without a copy, and borrows it.
///
/// Accepted: 2-D `uint8` arrays, 1 to 4096 px per side, whose pixels are contiguous within
/// each row (column stride 1) and whose rows are a whole, positive number of bytes apart at
/// least a row wide (C-contiguous arrays and row or column crops of them, `frame[y0:y1, x0:x1]`).
/// Anything else is refused rather than copied: a `TypeError` for another type, a `ValueError`
/// for another shape or layout.
pub fn frame<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Frame<'py>> {
    let array = ndarray(obj, name)?;
    let dtype = array.dtype();
    if !dtype.is_equiv_to(&numpy::dtype::<u8>(obj.py())) {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a uint8 array (8-bit grey), got dtype {}; convert it with \
             np.clip(a, 0, 255).astype(np.uint8)",
            dtype.str().map(|s| s.to_string()).unwrap_or_default()
        )));
    }
    let shape = array.shape().to_vec();
    if shape.len() != 2 {
        let hint = if shape.len() == 3 {
            " (a colour frame? convert it to grey first, e.g. cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))"
        } else {
            ""
        };
        return Err(PyValueError::new_err(format!(
            "{name} must be a 2-D array (height x width), got shape {}{hint}",
            shape_text(&shape)
        )));
    }
    let (height, width) = (shape[0], shape[1]);
    if width == 0 || height == 0 {
        return Err(PyValueError::new_err(format!(
            "{name} is empty: shape {}",
            shape_text(&shape)
        )));
    }
    if width > MAX_DIMENSION || height > MAX_DIMENSION {
        return Err(PyValueError::new_err(format!(
            "{name} is {width}x{height}: frames are at most {MAX_DIMENSION} px per side"
        )));
    }
    let strides = array.strides().to_vec();
    let layout_error = || {
        PyValueError::new_err(format!(
            "{name} has strides ({}, {}) (bytes): the library views rows of contiguous pixels \
             at a positive row stride of at least the width; pass np.ascontiguousarray({name})",
            strides[0], strides[1]
        ))
    };
    if width > 1 && strides[1] != 1 {
        return Err(layout_error());
    }
    let stride = if height == 1 {
        width
    } else {
        match usize::try_from(strides[0]) {
            Ok(s) if s >= width => s,
            _ => return Err(layout_error()),
        }
    };
    let typed = array
        .cast::<numpy::PyArray2<u8>>()
        .map_err(|_| PyTypeError::new_err(format!("{name} must be a 2-D uint8 array")))?;
    let array = typed
        .try_readonly()
        .map_err(|e| PyValueError::new_err(format!("{name} cannot be read: {e}")))?;
    Ok(Frame {
        array,
        width,
        height,
        stride,
    })
}

/// Checks two frames have one size.
pub fn same_size(a: &Frame<'_>, a_name: &str, b: &Frame<'_>, b_name: &str) -> PyResult<()> {
    if a.size() == b.size() {
        return Ok(());
    }
    Err(PyValueError::new_err(format!(
        "{a_name} is {}x{} but {b_name} is {}x{}: frames must have the same size",
        a.width, a.height, b.width, b.height
    )))
}

/// Reads a point list: `float32`, shape `(N, 1, 2)` or `(N, 2)` (OpenCV's layouts), any
/// strides, `N >= 1`, every coordinate finite and within +-32767 px.
pub fn points(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<(f32, f32)>> {
    let array = ndarray(obj, name)?;
    let dtype = array.dtype();
    if !dtype.is_equiv_to(&numpy::dtype::<f32>(obj.py())) {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a float32 array of shape (N, 1, 2) or (N, 2), got dtype {}; use \
             {name}.astype(np.float32)",
            dtype.str().map(|s| s.to_string()).unwrap_or_default()
        )));
    }
    let shape = array.shape().to_vec();
    let ok = matches!(shape.as_slice(), [_, 1, 2] | [_, 2]);
    if !ok {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (N, 1, 2) or (N, 2), got {}",
            shape_text(&shape)
        )));
    }
    if shape[0] == 0 {
        return Err(PyValueError::new_err(format!(
            "{name} is empty: give at least one point"
        )));
    }
    let typed = array
        .cast::<PyArrayDyn<f32>>()
        .map_err(|_| PyTypeError::new_err(format!("{name} must be a float32 array")))?;
    let readonly = typed
        .try_readonly()
        .map_err(|e| PyValueError::new_err(format!("{name} cannot be read: {e}")))?;
    let view = readonly.as_array();
    let flat: Vec<f32> = view.iter().copied().collect();
    let mut out = Vec::with_capacity(shape[0]);
    for (i, xy) in flat.chunks_exact(2).enumerate() {
        let (x, y) = (xy[0], xy[1]);
        if !x.is_finite() || !y.is_finite() {
            return Err(PyValueError::new_err(format!(
                "{name}[{i}] is ({x}, {y}): points must be finite (no NaN or infinity)"
            )));
        }
        if x.abs() > MAX_COORDINATE || y.abs() > MAX_COORDINATE {
            return Err(PyValueError::new_err(format!(
                "{name}[{i}] is ({x}, {y}): coordinates must be within +-{MAX_COORDINATE} px"
            )));
        }
        out.push((x, y));
    }
    Ok(out)
}

/// The library's Q16 point for a checked coordinate pair.
pub fn to_point((x, y): (f32, f32)) -> Point {
    Point::from_f32(x, y)
}

/// `data` as a numpy array of `shape` (whose product is `data.len()`).
pub fn array<'py, T: numpy::Element>(
    py: Python<'py>,
    data: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let array = Array::from_shape_vec(IxDyn(shape), data)
        .map_err(|e| PyValueError::new_err(format!("internal shape error: {e}")))?;
    Ok(array.into_pyarray(py))
}
