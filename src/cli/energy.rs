//! `graybox energy`: a model file's energies at a dataset's states, or its energy report.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use crate::data::Dataset;
use crate::error::Result;
use crate::infer::Evaluator;
use crate::infer::energy_report::REPORT_SEED;

#[derive(Args, Debug)]
pub struct EnergyArgs {
    /// A model file (.gbx) that `train` or `model` wrote, or the service served.
    #[arg(long)]
    pub model: PathBuf,
    /// Dataset whose states (q, q̇) and inputs u are evaluated (README, "Dataset files").
    #[arg(long)]
    pub data: PathBuf,
    /// Δt in seconds, for data files without one.
    #[arg(long)]
    pub dt: Option<f64>,
    /// Instead of each state's figures: the energy report on the data's states (unforced
    /// drift after 100 and 1000 steps, passivity), as a trained model's report holds it.
    #[arg(long)]
    pub report: bool,
    /// Which states the report draws (by default those a trained model's report drew, so
    /// that the two agree on its training data).
    #[arg(long, default_value_t = REPORT_SEED)]
    pub seed: u64,
}

pub(super) fn energy(a: EnergyArgs) -> Result<()> {
    let eval = Evaluator::from_file(&super::model::read(&a.model)?)?;
    eval.check_energy()?;
    let data = Dataset::load(&a.data, a.dt)?;
    let c = &eval.config;
    c.check_data("data", (data.nq(), data.nv(), data.m))?;
    let (x, _) = data.states();
    if a.report {
        let report = eval.energy_report(&x, a.seed, &|| false)?;
        let report = report.expect("never stopped");
        super::say(serde_json::to_string_pretty(&report).expect("json"))?;
        return Ok(());
    }
    let e = eval
        .energy_until(&x, &data.u, &|| false)?
        .expect("never stopped");
    let n = c.nv();
    // As the service refuses them: the rows are the data's transitions.
    e.check_finite("data", n)?;
    let row = |v: &[f64], k: usize| v[k * n..(k + 1) * n].to_vec();
    for k in 0..data.count() {
        let parts: serde_json::Map<String, serde_json::Value> = (e.parts.iter())
            .map(|p| (p.name.to_string(), json!(row(&p.values, k))))
            .collect();
        let line = json!({
            "kinetic": e.kinetic[k], "potential": e.potential[k], "total": e.total[k],
            "power": e.power[k], "inertial": row(&e.inertial, k), "coriolis": row(&e.coriolis, k),
            "gravity": row(&e.gravity, k), "applied": row(&e.applied, k), "parts": parts,
        });
        super::say(&line)?;
    }
    Ok(())
}
