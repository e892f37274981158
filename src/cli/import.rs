//! `graybox import`: a robot's log (CSV or Parquet: a time column, positions, optionally velocities, the
//! inputs) as a dataset file in the trajectory form (docs/logs.md).

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use crate::data::log::{
    DEFAULT_FIT, Fit, ImportOptions, Inputs, LogColumns, column_list, import_log,
};
use crate::error::{Error, Result};
use crate::model::file::write_atomic;

#[derive(Args, Debug)]
pub struct ImportArgs {
    /// The log: a CSV file whose header names its columns, or a Parquet file.
    pub log: PathBuf,
    /// The time column, in seconds.
    #[arg(long)]
    pub time: String,
    /// The position columns, comma-separated (q, in the model's coordinate order).
    #[arg(long)]
    pub q: String,
    /// The velocity columns, one per position (default: estimated from the positions).
    #[arg(long)]
    pub qdot: Option<String>,
    /// Acceleration columns the log has, one per position: checked against the fit's
    /// (`acceleration_check_rms` in the summary).
    #[arg(long)]
    pub qddot: Option<String>,
    /// The input columns (measured efforts or commands), comma-separated.
    #[arg(long)]
    pub u: String,
    /// Position columns holding an angle wrapped into one turn (unwrapped on import).
    #[arg(long, default_value = "")]
    pub wrapped: String,
    /// How the inputs go between samples: linear (a measured signal, joined by straight
    /// lines) or held (a command held until the next sample, as a controller's output is).
    #[arg(long, default_value = "linear")]
    pub inputs: String,
    /// Resample on an even grid of this step, seconds (default: keep the samples' own times,
    /// each transition its own Δt).
    #[arg(long)]
    pub dt: Option<f64>,
    /// Resample on an even grid of the log's median step.
    #[arg(long)]
    pub resample: bool,
    /// A step longer than this many median steps is a pause: the trajectory ends there.
    #[arg(long, default_value_t = 5.0)]
    pub gap: f64,
    /// Pass the inputs through the positions' fit as the accelerations pass (parallel
    /// filtering): for noisy positions and a wide `--window`, which would otherwise bias the
    /// identified inertias and damping.
    #[arg(long)]
    pub smooth_inputs: bool,
    /// Samples in the local polynomial fit of each time (Savitzky–Golay on the samples' own
    /// times).
    #[arg(long, default_value_t = DEFAULT_FIT.window)]
    pub window: usize,
    /// The fit's polynomial order.
    #[arg(long, default_value_t = DEFAULT_FIT.order)]
    pub order: usize,
    /// Where to write the dataset (JSON; a summary goes to stdout).
    #[arg(long)]
    pub out: PathBuf,
}

pub(super) fn import(a: ImportArgs) -> Result<()> {
    let bytes = std::fs::read(&a.log)
        .map_err(|e| Error::invalid("log", format!("cannot read {}: {e}", a.log.display())))?;
    let cols = LogColumns {
        time: a.time.trim().to_string(),
        q: column_list(&a.q),
        qdot: a.qdot.as_deref().map(column_list).unwrap_or_default(),
        qddot: a.qddot.as_deref().map(column_list).unwrap_or_default(),
        u: column_list(&a.u),
    };
    let opts = ImportOptions {
        dt: a.dt,
        resample: a.resample,
        gap: a.gap,
        fit: Fit {
            window: a.window,
            order: a.order,
        },
        wrapped: column_list(&a.wrapped),
        inputs: Inputs::parse(&a.inputs)?,
        smooth_inputs: a.smooth_inputs,
        // The caller's own file: no service shares its memory.
        memory: None,
    };
    let (data, summary) = import_log(&bytes, &cols, &opts)?;
    write_atomic(&a.out, data.to_json().as_bytes())?;
    let mut out = json!({"out": a.out, "nq": data.nq, "nv": data.nv, "m": data.m});
    out["import"] = serde_json::to_value(&summary).map_err(|e| Error::Internal(e.to_string()))?;
    super::say(&out)
}
