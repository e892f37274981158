//! The dataset file formats. Every error names the field and, where there is one, the row.
//!
//! - Transitions (JSON, also the REST upload body):
//!   `{"dt": 0.01, "q": [[…]], "qdot": [[…]], "u": [[…]], "q_next": [[…]], "qdot_next": [[…]]}`,
//!   one inner array per transition, n wide (m for "u").
//! - Trajectories (JSON): `{"dt": 0.01, "trajectories": [{"q": [[…]], "qdot": [[…]],
//!   "u": [[…]]}]}`, each with T+1 states and T inputs, giving T transitions.
//! - CSV: a header `q0..,qdot0..,u0..,q_next0..,qdot_next0..`, one transition per line; Δt
//!   given separately.
//!
//! Δt comes from the file or from the caller (`--dt`, `?dt=`); given both, they must agree.
//! Transitions of their own Δt each (a log kept on its samples' times): `"dt"` an array of one
//! step per transition, or each trajectory's `"t"`, its T + 1 states' times.

use serde::Deserialize;
use serde_json::Value;

use super::{Dataset, FIELDS};
use crate::error::{Error, Result};

mod export;

/// One trajectory: T+1 states and T inputs.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Trajectory {
    #[serde(default)]
    t: Option<Vec<f64>>,
    q: Vec<Vec<f64>>,
    qdot: Vec<Vec<f64>>,
    u: Vec<Vec<f64>>,
}

/// Every row of `rows` has `width` values (those of the first trajectory's first row), or an
/// error naming the first that does not.
fn same_widths(rows: &[Vec<f64>], width: usize, field: String) -> Result<()> {
    match rows.iter().position(|r| r.len() != width) {
        None => Ok(()),
        Some(t) => Err(Error::invalid(
            format!("{field}[{t}]"),
            format!(
                "has {} values; the rows before it have {width}",
                rows[t].len()
            ),
        )),
    }
}

impl Dataset {
    /// Parses either JSON form (transitions, or trajectories). `dt` is the caller's Δt, for a
    /// file without one (or to check against the file's).
    pub fn from_json(text: &str, dt: Option<f64>) -> Result<Self> {
        let value: Value = serde_json::from_str(text)
            .map_err(|e| Error::invalid("body", format!("malformed JSON: {e}")))?;
        Self::from_json_value(&value, dt)
    }

    /// Either JSON form, already parsed.
    pub fn from_json_value(value: &Value, dt: Option<f64>) -> Result<Self> {
        let obj = value
            .as_object()
            .ok_or_else(|| Error::invalid("body", "expected a JSON object"))?;
        let each = obj.get("dt").and_then(Value::as_array);
        let timed = (obj.get("trajectories").and_then(Value::as_array))
            .is_some_and(|t| t.iter().any(|t| t.get("t").is_some()));
        let (dt, each) = match (each, timed) {
            (Some(_), _) if dt.is_some() => {
                return Err(Error::invalid(
                    "dt",
                    "the data gives each transition's dt: leave out the one given separately",
                ));
            }
            (Some(_), _) if obj.contains_key("trajectories") => {
                return Err(Error::invalid(
                    "dt",
                    "is one number for trajectories; a trajectory's own times go in its \"t\"",
                ));
            }
            (Some(a), _) => (f64::NAN, Some(steps_of(a)?)),
            // Each trajectory's times give its steps (a dt besides is replaced by their
            // median).
            (None, true) => (f64::NAN, None),
            (None, false) => (resolve_dt(obj.get("dt"), dt)?, None),
        };
        if obj.contains_key("trajectories") {
            // One form per body: the other's arrays would be silently dropped.
            if let Some(flat) = FIELDS.iter().find(|f| obj.contains_key(**f)) {
                return Err(Error::invalid(
                    "trajectories",
                    format!(
                        "a body has either trajectories or the flat arrays (q, qdot, u, \
                         q_next, qdot_next), not both: this one has trajectories and {flat}"
                    ),
                ));
            }
            return Self::from_trajectories(value, dt, timed);
        }
        let first = each.as_ref().and_then(|s| s.first().copied());
        let data = Self::from_transitions(obj, first.unwrap_or(dt))?;
        match each {
            Some(steps) => data.with_steps(steps),
            None => Ok(data),
        }
    }

    fn from_transitions(obj: &serde_json::Map<String, Value>, dt: f64) -> Result<Self> {
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
        // q and q_next share nq, qdot and qdot_next nv (nq unless a joint's configuration is
        // not its velocity: docs/dynamics.md#configuration-space).
        let (nq, nv) = (widths[0], widths[1]);
        for (k, of, w) in [(3, "q", nq), (4, "qdot", nv)] {
            if widths[k] != w {
                return Err(Error::invalid(
                    FIELDS[k],
                    format!(
                        "rows have {} values but {of} rows have {w}; {} shares {of}'s width",
                        widths[k], FIELDS[k]
                    ),
                ));
            }
        }
        Self::new(dt, (nq, nv), widths[2], arrays)
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
        let (nq, nv, m) = (count_prefix("q"), count_prefix("qdot"), count_prefix("u"));
        let columns = |nq: usize, nv: usize, m: usize| -> Vec<String> {
            let mut out = vec![];
            for f in FIELDS {
                let w = match f {
                    "u" => m,
                    "q" | "q_next" => nq,
                    _ => nv,
                };
                out.extend((0..w).map(|i| format!("{f}{i}")));
            }
            out
        };
        let expected = columns(nq, nv, m);
        if nq == 0 || nv == 0 || m == 0 {
            return Err(Error::invalid(
                "csv.header",
                format!(
                    "found {nq} q columns, {nv} qdot columns and {m} u columns, got {}: the \
                     header names nq columns each of q and q_next, nv each of qdot and \
                     qdot_next and m of u, numbered from 0, in the order q, qdot, u, q_next, \
                     qdot_next (for nq = nv = 2, m = 1: {})",
                    cols.join(","),
                    columns(2, 2, 1).join(",")
                ),
            ));
        }
        if cols != expected {
            return Err(Error::invalid(
                "csv.header",
                format!(
                    "expected columns {} (nq = {nq}, nv = {nv}, m = {m} from the header), got {}",
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
        Self::new(dt, (nq, nv), m, arrays)
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
            Self::from_json(&text, dt)
        }
    }

    /// Trajectories → transitions (x_t, u_t, x_{t+1}).
    /// The trajectory form, read straight into the five arrays: each trajectory is read in
    /// place (no copy of its JSON) and its rows appended as numbers, so the body's parsed
    /// form is the one large thing alive beside the arrays.
    fn from_trajectories(value: &Value, dt: f64, timed: bool) -> Result<Self> {
        use serde::Deserialize;
        let trajs = value["trajectories"]
            .as_array()
            .ok_or_else(|| Error::invalid("trajectories", "must be an array of {q, qdot, u}"))?;
        let mut arrays: [Vec<f64>; 5] = Default::default();
        let mut widths = None;
        let mut lengths = Vec::with_capacity(trajs.len());
        let mut times: Vec<f64> = vec![];
        for (k, t) in trajs.iter().enumerate() {
            let tr = Trajectory::deserialize(t).map_err(|e| {
                Error::invalid(
                    format!("trajectories[{k}]"),
                    format!("expected {{q, qdot, u}} arrays of number rows: {e}"),
                )
            })?;
            let steps = tr.u.len();
            if tr.q.len() != steps + 1 || tr.qdot.len() != steps + 1 {
                return Err(Error::invalid(
                    format!("trajectories[{k}]"),
                    format!(
                        "needs T+1 states for T inputs: q has {}, qdot {}, u {}",
                        tr.q.len(),
                        tr.qdot.len(),
                        steps
                    ),
                ));
            }
            if steps == 0 {
                return Err(Error::Unprocessable {
                    field: format!("trajectories[{k}]"),
                    message: "is empty: a trajectory needs at least one input (and two states)"
                        .into(),
                });
            }
            match &tr.t {
                Some(t) => times.extend(trajectory_steps(t, tr.u.len(), k)?),
                None if timed => {
                    return Err(Error::invalid(
                        format!("trajectories[{k}].t"),
                        "is required: the other trajectories give their times (t)",
                    ));
                }
                None => {}
            }
            let first = (tr.q[0].len(), tr.qdot[0].len(), tr.u[0].len());
            let (nq, nv, m) = *widths.get_or_insert(first);
            let field = |f: &str| format!("trajectories[{k}].{f}");
            same_widths(&tr.q, nq, field("q"))?;
            same_widths(&tr.qdot, nv, field("qdot"))?;
            same_widths(&tr.u, m, field("u"))?;
            for t in 0..steps {
                arrays[0].extend_from_slice(&tr.q[t]);
                arrays[1].extend_from_slice(&tr.qdot[t]);
                arrays[2].extend_from_slice(&tr.u[t]);
                arrays[3].extend_from_slice(&tr.q[t + 1]);
                arrays[4].extend_from_slice(&tr.qdot[t + 1]);
            }
            lengths.push(steps);
        }
        let (nq, nv, m) = widths.unwrap_or((0, 0, 0));
        let nominal = times.first().copied().unwrap_or(dt);
        let data = Self::new(nominal, (nq, nv), m, arrays)?.with_trajectories(lengths)?;
        if times.is_empty() {
            return Ok(data);
        }
        data.with_steps(times)
    }
}

/// Δt from the file, the caller, or both when they agree.
fn resolve_dt(file: Option<&Value>, given: Option<f64>) -> Result<f64> {
    let file = file
        .map(|v| {
            v.as_f64()
                .ok_or_else(|| Error::invalid("dt", "must be a number of seconds"))
        })
        .transpose()?;
    match (file, given) {
        (Some(f), Some(g)) if (f - g).abs() > 1e-12 * f.abs().max(g.abs()) => Err(Error::invalid(
            "dt",
            format!(
                "the data says dt = {f} but dt = {g} was given separately; remove one or make them agree"
            ),
        )),
        (Some(f), _) => Ok(f),
        (None, Some(g)) => Ok(g),
        (None, None) => Err(Error::invalid(
            "dt",
            "is required: put \"dt\" (seconds) in the data, or give it separately \
             (--dt on the command line, ?dt= on REST)",
        )),
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

/// A transition array's `"dt"`: one number of seconds per transition.
fn steps_of(a: &[Value]) -> Result<Vec<f64>> {
    if a.is_empty() {
        return Err(Error::invalid(
            "dt",
            "an array of steps needs one per transition",
        ));
    }
    (a.iter().enumerate())
        .map(|(i, v)| {
            v.as_f64()
                .ok_or_else(|| Error::invalid(format!("dt[{i}]"), "must be a number of seconds"))
        })
        .collect()
}

/// The steps between a trajectory's T + 1 times `t`, which must increase.
fn trajectory_steps(t: &[f64], steps: usize, k: usize) -> Result<Vec<f64>> {
    let field = || format!("trajectories[{k}].t");
    if t.len() != steps + 1 {
        return Err(Error::invalid(
            field(),
            format!(
                "needs T+1 = {} times, one per state, got {}",
                steps + 1,
                t.len()
            ),
        ));
    }
    let d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    match d.iter().position(|s| s.is_nan() || *s <= 0.0) {
        Some(i) => Err(Error::invalid(
            field(),
            format!(
                "times must increase: t[{}] = {} after t[{i}] = {}",
                i + 1,
                t[i + 1],
                t[i]
            ),
        )),
        None => Ok(d),
    }
}
