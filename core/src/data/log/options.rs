//! What an import is asked: which columns are what, and how to import them, checked before
//! the log is read.

use super::DEFAULT_FIT;
use super::Fit;
use crate::error::{Error, Result};

/// Which columns are what; `qdot` empty: estimated from `q`; `qddot`: accelerations the log
/// has, checked against the fit's (none: nothing to check).
#[derive(Debug, Clone, Default)]
pub struct LogColumns {
    pub time: String,
    pub q: Vec<String>,
    pub qdot: Vec<String>,
    pub qddot: Vec<String>,
    pub u: Vec<String>,
}

/// How to import.
#[derive(Debug, Clone)]
pub struct ImportOptions {
    /// Resample on an even grid of this step (at least half the median step); `None`: the
    /// samples' own times, unless `resample`.
    pub dt: Option<f64>,
    /// Resample on an even grid of the median step (`dt` unset).
    pub resample: bool,
    /// A step longer than this many median steps is a pause: the trajectory ends there.
    pub gap: f64,
    pub fit: Fit,
    /// q columns holding an angle wrapped into a turn (a jump of more than π between two
    /// samples is a wrap, undone).
    pub wrapped: Vec<String>,
    pub inputs: Inputs,
    /// Pass the inputs through the positions' fit as the accelerations pass
    /// (`Piece::through_the_fit`): for noisy positions, whose wide fit would otherwise leave
    /// in the efforts what it takes out of q̈ and bias the inertias and damping (parallel
    /// filtering).
    pub smooth_inputs: bool,
    /// The most memory the import may hold, in bytes (the service's share for the upload);
    /// `None`: no bound (the command line, on the caller's own file).
    pub memory: Option<usize>,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            dt: None,
            resample: false,
            gap: 5.0,
            fit: DEFAULT_FIT,
            wrapped: vec![],
            inputs: Inputs::Linear,
            smooth_inputs: false,
            memory: None,
        }
    }
}

/// How the log's inputs go between its samples, which decides a transition's input (the mean
/// over its step: the model holds u over a step).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Inputs {
    /// A measured signal: a straight line from sample to sample.
    Linear,
    /// A command held from its sample to the next (a controller's output, zero-order hold):
    /// on the samples' own times each transition's input is its first sample's.
    Held,
}

impl Inputs {
    pub fn parse(s: &str) -> Result<Self> {
        match s.trim() {
            "linear" => Ok(Inputs::Linear),
            "held" => Ok(Inputs::Held),
            other => Err(Error::invalid(
                "inputs",
                format!(
                    "'{other}' is neither 'linear' (a measured signal) nor 'held' (a command \
                     held until the next sample)"
                ),
            )),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Inputs::Linear => "linear",
            Inputs::Held => "held",
        }
    }
}

/// Comma-separated column names, as the command line and REST take them (empty: none).
pub fn column_list(list: &str) -> Vec<String> {
    (list.split(','))
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect()
}

pub(super) fn check_options(cols: &LogColumns, opts: &ImportOptions) -> Result<()> {
    if cols.q.is_empty() {
        return Err(Error::invalid("q", "name at least one position column"));
    }
    if cols.u.is_empty() {
        return Err(Error::invalid("u", "name at least one input column"));
    }
    for (field, list, what) in [
        ("qdot", &cols.qdot, "velocity"),
        ("qddot", &cols.qddot, "acceleration"),
    ] {
        if !list.is_empty() && list.len() != cols.q.len() {
            return Err(Error::invalid(
                field,
                format!(
                    "names {} columns for {} positions: one {what} per position, or none",
                    list.len(),
                    cols.q.len()
                ),
            ));
        }
    }
    if !cols.qddot.is_empty() && opts.fit.order < 2 {
        return Err(Error::invalid(
            "order",
            "must be at least 2 to check accelerations (a line has none)",
        ));
    }
    if let Some(w) = opts.wrapped.iter().find(|w| !cols.q.contains(w)) {
        return Err(Error::invalid(
            "wrapped",
            format!(
                "'{w}' is not one of the position columns ({})",
                cols.q.join(", ")
            ),
        ));
    }
    if !(opts.gap.is_finite() && opts.gap > 1.0) {
        return Err(Error::invalid(
            "gap",
            format!("must be a number of median steps above 1, got {}", opts.gap),
        ));
    }
    Ok(())
}
