//! Shaped f64 data as a request carries it and a response returns it: row-major values and
//! their shape. The one array type of the core's seams (inference calls, their gRPC
//! conversion, the controllers' inputs); `control::linalg::Mat` is the matrix that math runs on.

use crate::error::{Error, Result};

/// Row-major values and their shape. A request's shape is the caller's claim, checked
/// (`rows`) before anything trusts it; a response's is built with its values (`new`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Array {
    pub data: Vec<f64>,
    pub shape: Vec<u64>,
}

impl Array {
    /// Values with the shape they fill.
    pub fn new(shape: &[usize], data: Vec<f64>) -> Self {
        debug_assert_eq!(shape.iter().product::<usize>(), data.len());
        Self {
            data,
            shape: shape.iter().map(|&s| s as u64).collect(),
        }
    }

    /// Dimension `i` (0 past the last).
    pub fn dim(&self, i: usize) -> usize {
        self.shape.get(i).map_or(0, |&d| d as usize)
    }

    /// The number of rows of a `[rows ≥ 1, width]` array of finite values; `field` names it in
    /// errors.
    pub fn rows(&self, field: &str, width: usize) -> Result<usize> {
        let (shape, data) = (&self.shape, &self.data);
        let [r, w] = shape[..] else {
            return Err(Error::invalid(
                field,
                format!("shape must be [rows, {width}], got {shape:?}"),
            ));
        };
        // Checked: a client-supplied shape such as [2⁶³ + 1, 4] must not wrap around to match.
        let expected = usize::try_from(r)
            .ok()
            .zip(usize::try_from(w).ok())
            .and_then(|(r, w)| r.checked_mul(w));
        if w != width as u64 || r == 0 || expected != Some(data.len()) {
            return Err(Error::invalid(
                field,
                format!(
                    "expected [rows ≥ 1, {width}] with rows·{width} values{}, got shape {shape:?} \
                     and {} values",
                    meaning(field),
                    data.len()
                ),
            ));
        }
        finite(field, data, width)?;
        Ok(r as usize)
    }
}

/// Rows of `width` values all finite, else an error naming `field` and the first row that is
/// not: checked before computing, so that a NaN in the inputs is not blamed on the states it
/// would have made non-finite.
pub fn finite(field: &str, data: &[f64], width: usize) -> Result<()> {
    match data.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::invalid(
            field,
            format!("row {} has a non-finite value", i / width.max(1)),
        )),
    }
}

/// What a request's array holds per row, by the last part of its field's name: said in shape
/// errors, so that a client learns what a row is rather than only its width.
fn meaning(field: &str) -> &'static str {
    match field.rsplit('.').next().unwrap_or(field) {
        "x" | "x_bar" | "x0" => " (each row a state x = [q, v]: nq + nv values)",
        "u" | "u_bar" => " (each row the inputs u: m values)",
        _ => "",
    }
}
