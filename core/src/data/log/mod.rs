//! A robot's log as a dataset (docs/logs.md): a CSV or Parquet file with a time column, joint positions,
//! optionally velocities, and the inputs (measured efforts), sampled with jitter, with dropped
//! samples and pauses. The import keeps the rows with every selected value, unwraps wrapped
//! angles, splits the log into trajectories at its pauses (a step longer than `gap` median
//! steps), estimates velocities from positions by a local polynomial fit on the samples' own
//! times (`fit`) when the log has none, and takes the states at the samples' own times (each
//! transition its own Δt: `Dataset::steps`), or on an even grid of `dt` when asked to
//! resample: the positions and velocities the fit's, each input its mean over the step (the
//! model holds u over a step).

mod fit;
mod grid;
mod options;
mod table;

use serde::Serialize;

pub use fit::{DEFAULT_FIT, Fit, Stencil};
pub use options::{ImportOptions, Inputs, LogColumns, column_list};

use self::grid::{Check, Piece};
use self::options::check_options;
use self::table::{Columns, Table};
use super::{DT_RANGE, Dataset, median};
use crate::error::{Error, Result};

/// The most fitting an upload may ask: window × (order + 1)² per grid time, summed. An hour
/// of a 1 kHz log with the default fit is 9e8; 1.5e9 (30 000 times at window 1001, order 6)
/// took 3.5 s of one core here, so the bound is seconds.
const MAX_FIT_WORK: f64 = 2e9;

/// What an import did, for the dataset's summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ImportSummary {
    /// "csv" or "parquet".
    pub format: String,
    /// Data rows in the log.
    pub rows: usize,
    /// Rows left out for a missing value in a selected column, and the first of them.
    pub dropped_rows: usize,
    pub first_dropped_row: Option<usize>,
    /// The log's median step and the relative spread of its steps (their standard deviation
    /// over the median), pauses left out.
    pub median_step: f64,
    pub jitter: f64,
    /// Pauses that split the log, and trajectories too short for one step (left out).
    pub pauses: usize,
    pub short_trajectories: usize,
    pub trajectories: usize,
    pub transitions: usize,
    /// The dataset's Δt: the grid's, or the median of its transitions' own.
    pub dt: f64,
    /// "samples" (each transition from one sample to the next, its own Δt) or "grid".
    pub times: String,
    /// How the inputs go between samples: "linear" or "held".
    pub inputs: String,
    /// Whether the inputs passed through the fit (`ImportOptions::smooth_inputs`).
    pub smooth_inputs: bool,
    /// "estimated" (by `fit`) or "given".
    pub velocities: String,
    pub fit: Fit,
    /// With velocities given: the root mean square of the fit's estimate minus the log's, over
    /// every grid state and joint (a check of either).
    pub velocity_check_rms: Option<f64>,
    /// With accelerations given (`qddot`): the root mean square of the fit's second derivative
    /// of the positions minus the log's (fitted alike), over every state and joint.
    pub acceleration_check_rms: Option<f64>,
    /// The fit's largest delay over the grid, seconds: the centre of its weights in time
    /// against the time it answers for (0 up to rounding: it reproduces a straight line).
    pub lag: f64,
}

/// The dataset of a log (CSV, or Parquet: `table`) and what the import did.
pub fn import_log(
    bytes: &[u8],
    cols: &LogColumns,
    opts: &ImportOptions,
) -> Result<(Dataset, ImportSummary)> {
    opts.fit.check()?;
    check_options(cols, opts)?;
    let table = Table::open(bytes)?;
    let names = table.names();
    let mut at = vec![(find(names, "time", &cols.time)?, "time")];
    let lists = [("q", &cols.q), ("qdot", &cols.qdot), ("qddot", &cols.qddot)];
    for (field, list) in lists.into_iter().chain([("u", &cols.u)]) {
        for c in list {
            at.push((find(names, field, c)?, field));
        }
    }
    let read = table.read(&at, opts.memory)?;
    let named: Vec<(&str, String)> = at.iter().map(|(i, f)| (*f, names[*i].clone())).collect();
    let log = Samples::keep_complete(read, &named)?;
    let (data, mut summary) = log.import(cols, opts)?;
    summary.format = table.format().into();
    Ok((data, summary))
}

/// The column named `name` for `field`, or an error listing the log's columns.
fn find(names: &[String], field: &str, name: &str) -> Result<usize> {
    names.iter().position(|n| n == name).ok_or_else(|| {
        Error::invalid(
            field,
            format!(
                "no column '{name}' in the log; its columns: {}",
                names.join(", ")
            ),
        )
    })
}

/// The log's complete rows: times, then each selected column, in the order asked.
struct Samples {
    rows: usize,
    /// Original row of each kept sample.
    row: Vec<usize>,
    time: Vec<f64>,
    columns: Vec<Vec<f64>>,
    dropped: usize,
    first_dropped: Option<usize>,
}

impl Samples {
    /// The rows with every selected value; a column with no value at all, time that does not
    /// increase and a log of fewer than two complete rows are errors naming the column or row.
    fn keep_complete(read: Columns, named: &[(&str, String)]) -> Result<Self> {
        for ((field, name), v) in named.iter().zip(&read.values) {
            if v.iter().all(|x| x.is_nan()) {
                return Err(Error::invalid(
                    *field,
                    format!(
                        "column '{name}' has no value in any of the {} rows",
                        read.rows
                    ),
                ));
            }
        }
        let complete: Vec<usize> = (0..read.rows)
            .filter(|&r| read.values.iter().all(|v| !v[r].is_nan()))
            .collect();
        let first_dropped = (0..read.rows).find(|r| complete.binary_search(r).is_err());
        let pick = |v: &Vec<f64>| complete.iter().map(|&r| v[r]).collect::<Vec<f64>>();
        let s = Samples {
            rows: read.rows,
            time: pick(&read.values[0]),
            columns: read.values[1..].iter().map(pick).collect(),
            dropped: read.rows - complete.len(),
            first_dropped,
            row: complete,
        };
        if s.time.len() < 2 {
            return Err(Error::invalid(
                "log",
                format!(
                    "{} complete row(s) of {} (a row missing a selected value is left out): a \
                     log needs at least two",
                    s.time.len(),
                    s.rows
                ),
            ));
        }
        if let Some(k) = (1..s.time.len()).find(|&k| s.time[k] <= s.time[k - 1]) {
            return Err(Error::invalid(
                "time",
                format!(
                    "time must increase from row to row: row {} has {} after row {}'s {}",
                    s.row[k],
                    s.time[k],
                    s.row[k - 1],
                    s.time[k - 1]
                ),
            ));
        }
        Ok(s)
    }

    fn import(
        mut self,
        cols: &LogColumns,
        opts: &ImportOptions,
    ) -> Result<(Dataset, ImportSummary)> {
        let (nq, m) = (cols.q.len(), cols.u.len());
        for w in &opts.wrapped {
            let k = cols.q.iter().position(|c| c == w).expect("checked");
            unwrap(&mut self.columns[k]);
        }
        let steps: Vec<f64> = self.time.windows(2).map(|w| w[1] - w[0]).collect();
        let median = median(&steps);
        let breaks: Vec<usize> = (0..steps.len())
            .filter(|&k| steps[k] > opts.gap * median)
            .map(|k| k + 1)
            .collect();
        let regular: Vec<f64> = steps
            .iter()
            .copied()
            .filter(|s| *s <= opts.gap * median)
            .collect();
        let jitter = std_dev(&regular) / median;
        let grid = (opts.dt.is_some() || opts.resample).then(|| opts.dt.unwrap_or(median));
        let dt = grid.unwrap_or(median);
        // A finer grid than the samples invents states between them, and its size would
        // follow the caller's dt rather than the log's rows.
        if dt < median / 2.0 {
            return Err(Error::invalid(
                "dt",
                format!("{dt} s is finer than half the log's median step ({median} s)"),
            ));
        }
        let (lo, hi) = DT_RANGE;
        if !(dt.is_finite() && (lo..=hi).contains(&dt)) {
            return Err(Error::invalid(
                if opts.dt.is_some() { "dt" } else { "time" },
                format!("the step must be in [{lo:e}, {hi}] s, got {dt} (is time in seconds?)"),
            ));
        }
        let mut bounds = vec![0];
        bounds.extend(&breaks);
        bounds.push(self.time.len());
        self.check_cost(&bounds, dt, (nq, m), opts)?;
        let mut arrays: [Vec<f64>; 5] = Default::default();
        let (mut lengths, mut short, mut check) = (vec![], 0, Check::default());
        let mut steps = vec![];
        for seg in bounds.windows(2) {
            let piece = self.piece(seg[0]..seg[1]);
            let times = piece.times(grid);
            match piece.states_at(cols, opts.fit, &times, &mut check) {
                Some(states) if states.len() >= 2 => {
                    lengths.push(states.len() - 1);
                    let smooth = opts.smooth_inputs.then_some(opts.fit);
                    piece.transitions(&states, (nq, m), &times, (opts.inputs, smooth), &mut arrays);
                    steps.extend(times.windows(2).map(|w| w[1] - w[0]));
                }
                _ => short += 1,
            }
        }
        if lengths.is_empty() {
            return Err(Error::invalid(
                "log",
                format!(
                    "no trajectory of the log spans a step of {dt} s with {} samples to fit",
                    opts.fit.order + 1
                ),
            ));
        }
        let transitions = lengths.iter().sum();
        let data = Dataset::new(dt, (nq, nq), m, arrays)?.with_trajectories(lengths.clone())?;
        let data = match grid {
            Some(_) => data,
            None => data.with_steps(steps)?,
        };
        let summary = ImportSummary {
            format: String::new(),
            rows: self.rows,
            dropped_rows: self.dropped,
            first_dropped_row: self.first_dropped,
            median_step: median,
            jitter,
            pauses: breaks.len(),
            short_trajectories: short,
            trajectories: lengths.len(),
            transitions,
            dt: data.dt,
            times: if grid.is_some() { "grid" } else { "samples" }.into(),
            velocities: if cols.qdot.is_empty() {
                "estimated"
            } else {
                "given"
            }
            .into(),
            fit: opts.fit,
            inputs: opts.inputs.name().into(),
            smooth_inputs: opts.smooth_inputs,
            velocity_check_rms: check.rms(),
            acceleration_check_rms: check.acceleration_rms(),
            lag: check.lag,
        };
        Ok((data, summary))
    }

    /// Refuses, before any fit, an import whose columns and dataset would take more than
    /// the options' `memory` bytes: the parsed columns, and per transition its values twice (the dataset's
    /// arrays and their stored encoding). A log of tiny cells ("0,0,0") makes far more of
    /// them per byte than a robot's log of measured values.
    ///
    /// With a bound on memory (the service) the fits' work is bounded too, to seconds: each grid
    /// time solves the fit's normal equations over its window.
    fn check_cost(
        &self,
        bounds: &[usize],
        dt: f64,
        (nq, m): (usize, usize),
        opts: &ImportOptions,
    ) -> Result<()> {
        let Some(memory) = opts.memory else {
            return Ok(());
        };
        let states: f64 = bounds
            .windows(2)
            .map(|b| ((self.time[b[1] - 1] - self.time[b[0]]) / dt).floor() + 1.0)
            .sum();
        let parsed = 8.0 * (self.time.len() * (1 + self.columns.len())) as f64;
        let needed = parsed + 16.0 * (4 * nq + m) as f64 * states;
        if needed > memory as f64 {
            return Err(Error::ResourceExhausted(format!(
                "log: importing it at dt = {dt} s would hold {:.0} MB ({states} states of {} \
                 values), over the {:.0} MB this upload may use; import it with a coarser dt or \
                 fewer columns, or with `graybox import` and upload the dataset",
                needed / 1e6,
                2 * nq + m,
                memory as f64 / 1e6
            )));
        }
        let Fit { window, order } = opts.fit;
        // Smoothed inputs take the fit at every state again.
        let fits = if opts.smooth_inputs { 2.0 } else { 1.0 };
        let work = fits * states * (window * (order + 1).pow(2)) as f64;
        if work > MAX_FIT_WORK {
            return Err(Error::ResourceExhausted(format!(
                "log: fitting {states} grid times with a window of {window} samples (order \
                 {order}) is {work:.1e} operations, over the {MAX_FIT_WORK:.0e} an upload may \
                 ask; use a narrower window or a coarser dt, or `graybox import` and upload the \
                 dataset"
            )));
        }
        Ok(())
    }

    /// The samples of rows `r` as one trajectory.
    fn piece(&self, r: std::ops::Range<usize>) -> Piece<'_> {
        Piece {
            time: &self.time[r.clone()],
            columns: self.columns.iter().map(|c| &c[r.clone()]).collect(),
        }
    }
}

/// Undoes wraps: a jump of more than π between two samples loses its whole turns.
fn unwrap(y: &mut [f64]) {
    let turn = 2.0 * std::f64::consts::PI;
    let mut offset = 0.0;
    for k in 1..y.len() {
        let raw = y[k];
        let d = raw + offset - y[k - 1];
        if d.abs() > std::f64::consts::PI {
            offset -= turn * (d / turn).round();
        }
        y[k] = raw + offset;
    }
}

fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

#[cfg(test)]
mod tests;
