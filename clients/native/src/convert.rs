//! Between Python and the core: array-likes in (as float64, shape checked with the field
//! named), NumPy arrays out, and the core's errors as `graybox_native.GrayboxError` with the
//! gRPC code and field the service would have answered with.

use numpy::{AllowTypeChange, PyArray1, PyArrayLikeDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyType;

use graybox_core::array::Array;
use graybox_core::control::linalg::Mat;
use graybox_core::error::Error;

/// `graybox_native.GrayboxError`, looked up once.
static GRAYBOX_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// The core's error as the package's exception: code (a gRPC status name), message, field.
pub fn py_error(py: Python<'_>, e: Error) -> PyErr {
    let field = e.field().map(str::to_string);
    raise(py, e, field)
}

/// [`py_error`] naming `field` when the error names none (RESOURCE_EXHAUSTED's do not: the
/// argument whose size is at fault is the caller's to know).
pub fn py_error_at(py: Python<'_>, e: Error, field: &str) -> PyErr {
    let field = e.field().unwrap_or(field).to_string();
    raise(py, e, Some(field))
}

fn raise(py: Python<'_>, e: Error, field: Option<String>) -> PyErr {
    let class = GRAYBOX_ERROR.import(py, "graybox_native", "GrayboxError");
    let code = e.code().1;
    match class {
        Ok(class) => match class.call1((code, e.to_string(), field)) {
            Ok(instance) => PyErr::from_value(instance),
            Err(err) => err,
        },
        Err(err) => err,
    }
}

pub trait OrPy<T> {
    /// The error as the package's exception.
    fn or_py(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> OrPy<T> for Result<T, Error> {
    fn or_py(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| py_error(py, e))
    }
}

/// A float64 array from anything NumPy reads as one.
pub type ArrayIn<'py> = PyArrayLikeDyn<'py, f64, AllowTypeChange>;

/// Its values in logical row-major order (what its C-ordered copy holds) and shape.
pub fn values(a: &ArrayIn<'_>) -> (Vec<f64>, Vec<usize>) {
    let shape = a.shape().to_vec();
    // `as_slice` also succeeds for a Fortran-ordered array, whose memory holds the values
    // column by column: read as rows, they were scrambled.
    let data = if a.is_c_contiguous() {
        a.as_slice().expect("C-contiguous").to_vec()
    } else {
        // Fortran-ordered, strided or reversed: in logical order.
        a.as_array().iter().copied().collect()
    };
    (data, shape)
}

/// A whole-number argument in `0..=max`, taken as a signed Python int so that a negative
/// one is refused naming it (as an unsigned parameter it was a bare OverflowError).
pub fn whole(field: &str, v: i128, max: u64) -> Result<u64, Error> {
    match u64::try_from(v) {
        Ok(v) if v <= max => Ok(v),
        Ok(_) => Err(Error::invalid(
            field,
            format!("must be at most {max}, got {v}"),
        )),
        Err(_) => Err(Error::invalid(field, format!("must be ≥ 0, got {v}"))),
    }
}

/// Rows of `width` values: `[width]` is one row (`single`), `[B, width]` is B of them.
pub struct Rows {
    pub data: Vec<f64>,
    pub rows: usize,
    pub single: bool,
}

pub fn rows(field: &str, a: Option<&ArrayIn<'_>>, width: usize) -> Result<Rows, Error> {
    let Some(a) = a else {
        return match width {
            0 => Ok(Rows {
                data: vec![],
                rows: 0,
                single: true,
            }),
            _ => Err(Error::invalid(
                field,
                format!("is required ({width} values a row)"),
            )),
        };
    };
    let (data, shape) = values(a);
    let (rows, single) = match shape[..] {
        [w] if w == width => (1, true),
        [b, w] if w == width && b > 0 => (b, false),
        // A model with no inputs takes any empty array for them.
        _ if width == 0 && data.is_empty() => (0, shape.len() < 2),
        _ => {
            return Err(Error::invalid(
                field,
                format!("expected shape [{width}] or [B, {width}] with B ≥ 1, got {shape:?}"),
            ));
        }
    };
    // The service's checks of a request's rows (non-finite values among them).
    let checked = Array::new(&[rows, width], data);
    if rows > 0 {
        checked.rows(field, width)?;
    }
    Ok(Rows {
        data: checked.data,
        rows,
        single,
    })
}

/// The inputs of `x`'s rows: u's rows must match them (none for a model with no inputs).
pub fn inputs(x: &Rows, u: Rows, m: usize) -> Result<Vec<f64>, Error> {
    if m == 0 {
        return Ok(vec![]);
    }
    if u.rows != x.rows || u.single != x.single {
        return Err(Error::invalid(
            "u",
            format!("has {} rows for x's {}", u.rows, x.rows),
        ));
    }
    Ok(u.data)
}

/// A square or rectangular matrix of the expected shape, named for the error.
pub fn matrix(name: &str, a: &ArrayIn<'_>, rows: usize, cols: usize) -> Result<Mat, Error> {
    let (data, shape) = values(a);
    if shape != [rows, cols] {
        return Err(Error::invalid(
            name,
            format!("expected shape [{rows}, {cols}], got {shape:?}"),
        ));
    }
    Ok(Mat { rows, cols, data })
}

/// A NumPy array of `shape` holding `data`.
pub fn array<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    let flat = PyArray1::from_vec(py, data);
    if shape.len() == 1 {
        return Ok(flat.into_any());
    }
    Ok(flat.reshape(shape)?.into_any())
}

/// `shape` with its first dimension dropped when the call was for one row.
pub fn shaped(single: bool, rows: usize, rest: &[usize]) -> Vec<usize> {
    let mut shape = if single { vec![] } else { vec![rows] };
    shape.extend_from_slice(rest);
    shape
}
