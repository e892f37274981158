//! Transition datasets (q, q̇, u → q', q̇'): the file formats, validation, and splits.
//!
//! JSON (also the REST upload body):
//!   {"dt": 0.01, "q": [[…]], "qdot": [[…]], "u": [[…]], "q_next": [[…]], "qdot_next": [[…]]}
//! one inner array per transition, n wide (m for "u"). CSV: a header
//! `q0..,qdot0..,u0..,q_next0..,qdot_next0..` and Δt given separately.
//! Every error names the field and, where there is one, the row.

use serde::Serialize;
use serde_json::Value;

use crate::error::{Error, Result};
use crate::rng::Rng;

/// Row-major arrays of `count` transitions.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    pub dt: f64,
    pub n: usize,
    pub m: usize,
    pub q: Vec<f64>,
    pub qdot: Vec<f64>,
    pub u: Vec<f64>,
    pub q_next: Vec<f64>,
    pub qdot_next: Vec<f64>,
}

pub const FIELDS: [&str; 5] = ["q", "qdot", "u", "q_next", "qdot_next"];

#[derive(Serialize)]
struct DatasetJson<'a> {
    dt: f64,
    q: Vec<&'a [f64]>,
    qdot: Vec<&'a [f64]>,
    u: Vec<&'a [f64]>,
    q_next: Vec<&'a [f64]>,
    qdot_next: Vec<&'a [f64]>,
}

/// The sampling intervals graybox accepts, in seconds. Below 10 µs the one-step differences
/// q' − q drown in f32 rounding during training; above 10 s one RK4 step of a mechanical
/// system says nothing about its dynamics. A Δt outside this range has always been a unit or
/// export error (a reported 1e-320 produced a model with NaN scalings).
pub const DT_RANGE: (f64, f64) = (1e-5, 10.0);

impl Dataset {
    pub fn count(&self) -> usize {
        self.q.len().checked_div(self.n).unwrap_or(0)
    }

    /// Builds a dataset from row-major arrays, checking every invariant.
    pub fn new(dt: f64, n: usize, m: usize, arrays: [Vec<f64>; 5]) -> Result<Self> {
        let [q, qdot, u, q_next, qdot_next] = arrays;
        let d = Dataset {
            dt,
            n,
            m,
            q,
            qdot,
            u,
            q_next,
            qdot_next,
        };
        d.validate()?;
        Ok(d)
    }

    fn validate(&self) -> Result<()> {
        let (lo, hi) = DT_RANGE;
        if !(self.dt.is_finite() && (lo..=hi).contains(&self.dt)) {
            return Err(Error::invalid(
                "dt",
                format!(
                    "must be a number of seconds in [{lo:e}, {hi}], got {}",
                    self.dt
                ),
            ));
        }
        if self.n == 0 {
            return Err(Error::invalid(
                "q",
                "rows must have at least one coordinate",
            ));
        }
        if self.m == 0 {
            return Err(Error::invalid(
                "u",
                "rows must have at least one input (use a column of zeros for an unforced system)",
            ));
        }
        let count = self.count();
        if count == 0 {
            return Err(Error::invalid("q", "the dataset has no transitions"));
        }
        for (name, arr, width) in self.fields() {
            if arr.len() != count * width {
                return Err(Error::invalid(
                    name,
                    format!("expected {count} rows of {width}"),
                ));
            }
            if let Some(i) = arr.iter().position(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    format!("{name}[{}]", i / width),
                    format!("row {} has a non-finite value ({})", i / width, arr[i]),
                ));
            }
        }
        Ok(())
    }

    fn fields(&self) -> [(&'static str, &Vec<f64>, usize); 5] {
        [
            ("q", &self.q, self.n),
            ("qdot", &self.qdot, self.n),
            ("u", &self.u, self.m),
            ("q_next", &self.q_next, self.n),
            ("qdot_next", &self.qdot_next, self.n),
        ]
    }

    /// Parses the JSON form. `dt` may be supplied by the caller when the file has none.
    pub fn from_json(text: &str) -> Result<Self> {
        let value: Value = serde_json::from_str(text)
            .map_err(|e| Error::invalid("body", format!("malformed JSON: {e}")))?;
        Self::from_json_value(&value)
    }

    pub fn from_json_value(value: &Value) -> Result<Self> {
        let obj = value
            .as_object()
            .ok_or_else(|| Error::invalid("body", "expected a JSON object"))?;
        let dt = match obj.get("dt") {
            Some(v) => v
                .as_f64()
                .ok_or_else(|| Error::invalid("dt", "must be a number"))?,
            None => return Err(Error::invalid("dt", "is required")),
        };
        let mut widths = [0usize; 5];
        let mut arrays: [Vec<f64>; 5] = Default::default();
        let mut count = None;
        for (k, name) in FIELDS.iter().enumerate() {
            let (rows, width, flat) = parse_rows(obj.get(*name), name)?;
            match count {
                None => count = Some(rows),
                Some(c) if c != rows => {
                    return Err(Error::invalid(
                        *name,
                        format!(
                            "has {rows} rows but q has {c}; every field needs one row per transition"
                        ),
                    ));
                }
                _ => {}
            }
            widths[k] = width;
            arrays[k] = flat;
        }
        let n = widths[0];
        for k in [1, 3, 4] {
            if widths[k] != n {
                return Err(Error::invalid(
                    FIELDS[k],
                    format!(
                        "rows have {} values but q rows have {n}; q, qdot, q_next and qdot_next share n",
                        widths[k]
                    ),
                ));
            }
        }
        Self::new(dt, n, widths[2], arrays)
    }

    /// Parses the CSV form (header `q0..,qdot0..,u0..,q_next0..,qdot_next0..`).
    pub fn from_csv(text: &str, dt: f64) -> Result<Self> {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines
            .next()
            .ok_or_else(|| Error::invalid("csv", "empty file: expected a header row"))?;
        let cols: Vec<&str> = header.split(',').map(str::trim).collect();
        let count_prefix = |p: &str| cols.iter().filter(|c| strip_index(c, p).is_some()).count();
        let n = count_prefix("q");
        let m = count_prefix("u");
        let expected: Vec<String> = FIELDS
            .iter()
            .flat_map(|f| {
                let w = if *f == "u" { m } else { n };
                (0..w).map(move |i| format!("{f}{i}"))
            })
            .collect();
        if cols != expected {
            return Err(Error::invalid(
                "csv.header",
                format!(
                    "expected columns {} (n = {n}, m = {m} from the header), got {}",
                    expected.join(","),
                    cols.join(",")
                ),
            ));
        }
        let mut arrays: [Vec<f64>; 5] = Default::default();
        for (row, (lineno, line)) in lines.enumerate() {
            let vals: Vec<&str> = line.split(',').map(str::trim).collect();
            if vals.len() != cols.len() {
                return Err(Error::invalid(
                    format!("csv.row[{row}]"),
                    format!(
                        "line {} has {} values, the header has {}",
                        lineno + 1,
                        vals.len(),
                        cols.len()
                    ),
                ));
            }
            for (c, v) in vals.iter().enumerate() {
                let x: f64 = v.parse().map_err(|_| {
                    Error::invalid(
                        format!("{}[{row}]", field_of(cols[c])),
                        format!("'{v}' is not a number (line {})", lineno + 1),
                    )
                })?;
                let field = FIELDS
                    .iter()
                    .position(|f| *f == field_of(cols[c]))
                    .expect("header checked");
                arrays[field].push(x);
            }
        }
        Self::new(dt, n, m, arrays)
    }

    pub fn to_json(&self) -> String {
        fn rows(a: &[f64], w: usize) -> Vec<&[f64]> {
            a.chunks(w).collect()
        }
        serde_json::to_string(&DatasetJson {
            dt: self.dt,
            q: rows(&self.q, self.n),
            qdot: rows(&self.qdot, self.n),
            u: rows(&self.u, self.m),
            q_next: rows(&self.q_next, self.n),
            qdot_next: rows(&self.qdot_next, self.n),
        })
        .expect("plain arrays serialize")
    }

    /// Reads a file by extension: `.csv` needs `dt`, anything else is JSON.
    pub fn load(path: &std::path::Path, dt: Option<f64>) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::invalid("data", format!("cannot read {}: {e}", path.display())))?;
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
        {
            let dt = dt.ok_or_else(|| Error::invalid("dt", "a CSV dataset needs --dt"))?;
            Self::from_csv(&text, dt)
        } else {
            Self::from_json(&text)
        }
    }

    /// The transitions at `idx`, in that order.
    pub fn subset(&self, idx: &[usize]) -> Dataset {
        let take = |a: &[f64], w: usize| -> Vec<f64> {
            idx.iter()
                .flat_map(|&i| a[i * w..(i + 1) * w].iter().copied())
                .collect()
        };
        Dataset {
            dt: self.dt,
            n: self.n,
            m: self.m,
            q: take(&self.q, self.n),
            qdot: take(&self.qdot, self.n),
            u: take(&self.u, self.m),
            q_next: take(&self.q_next, self.n),
            qdot_next: take(&self.qdot_next, self.n),
        }
    }

    /// A seeded random split into (train, validation); validation gets round(fraction·count)
    /// transitions, at least one when fraction > 0 and count > 1.
    pub fn split(&self, fraction: f64, seed: u64) -> (Dataset, Dataset) {
        let count = self.count();
        let mut idx: Vec<usize> = (0..count).collect();
        Rng::derive(seed, 0x5_9117).shuffle(&mut idx);
        let mut n_val = (fraction * count as f64).round() as usize;
        if fraction > 0.0 && count > 1 {
            n_val = n_val.clamp(1, count - 1);
        }
        let (val, train) = idx.split_at(n_val.min(count));
        (self.subset(train), self.subset(val))
    }

    /// State rows x = [q, q̇] (count × 2n) and targets x' = [q', q̇'].
    pub fn states(&self) -> (Vec<f64>, Vec<f64>) {
        let join = |a: &[f64], b: &[f64]| -> Vec<f64> {
            a.chunks(self.n)
                .zip(b.chunks(self.n))
                .flat_map(|(x, y)| x.iter().chain(y).copied())
                .collect()
        };
        (
            join(&self.q, &self.qdot),
            join(&self.q_next, &self.qdot_next),
        )
    }
}

/// "q_next3" → Some(3) for prefix "q_next"; "q3" is not "qdot3".
fn strip_index(col: &str, prefix: &str) -> Option<usize> {
    col.strip_prefix(prefix)?.parse().ok()
}

fn field_of(col: &str) -> &str {
    col.trim_end_matches(|c: char| c.is_ascii_digit())
}

/// A field's rows → (row count, width, flattened values), checking that it is an array of
/// equally long arrays of numbers.
fn parse_rows(v: Option<&Value>, name: &str) -> Result<(usize, usize, Vec<f64>)> {
    let rows = v
        .ok_or_else(|| Error::invalid(name, "is required"))?
        .as_array()
        .ok_or_else(|| Error::invalid(name, "must be an array of rows (arrays of numbers)"))?;
    let mut width = None;
    let mut flat = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        let field = || format!("{name}[{i}]");
        let row = row
            .as_array()
            .ok_or_else(|| Error::invalid(field(), "must be an array of numbers"))?;
        match width {
            None => width = Some(row.len()),
            Some(w) if w != row.len() => {
                return Err(Error::invalid(
                    field(),
                    format!(
                        "has {} values but row 0 has {w}; every row of a field has the same width",
                        row.len()
                    ),
                ));
            }
            _ => {}
        }
        for (j, x) in row.iter().enumerate() {
            let x = x.as_f64().ok_or_else(|| {
                Error::invalid(field(), format!("value {j} is not a number: {x}"))
            })?;
            flat.push(x);
        }
    }
    Ok((rows.len(), width.unwrap_or(0), flat))
}
