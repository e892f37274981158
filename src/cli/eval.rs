//! `graybox eval` and `graybox inspect`: a model file's loss on a dataset, and what it holds.

use std::collections::BTreeMap;
use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use crate::backend::{self, Backend, Precision};
use crate::data::Dataset;
use crate::error::Result;
use crate::infer::Evaluator;
use crate::infer::horizons::{check_horizons, horizon_errors};
use crate::model::Model;
use crate::model::file::ModelFile;
use crate::model::report::{Spread, identifiable, used_physical};
use crate::train::trainer::{evaluate, evaluate_members};

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// A model file (.gbx) that `train` or `model` wrote, or the service served.
    #[arg(long)]
    pub model: PathBuf,
    /// Dataset: JSON transitions or trajectories, or CSV (README, "Dataset files").
    #[arg(long)]
    pub data: PathBuf,
    /// Δt in seconds, for data files without one (CSV, or JSON without "dt"); a file's own dt
    /// that disagrees is an error.
    #[arg(long)]
    pub dt: Option<f64>,
    #[arg(long, value_enum, default_value_t = Backend::Flex)]
    pub backend: Backend,
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub precision: Precision,
    /// Instead of the loss: open-loop rollouts of this many steps (comma-separated, e.g.
    /// 1,10,50,100) from every window start of the data's trajectories, one JSON line per
    /// horizon with the median and mean position and velocity errors (README "Multi-step
    /// training").
    #[arg(long, value_delimiter = ',')]
    pub horizons: Option<Vec<usize>>,
}

#[derive(Args, Debug)]
pub struct InspectArgs {
    /// A model file (.gbx) that `train` or `model` wrote, or the service served.
    #[arg(long)]
    pub model: PathBuf,
}

pub(super) fn eval(a: EvalArgs) -> Result<()> {
    let file = super::model::read(&a.model)?;
    let data = Dataset::load(&a.data, a.dt)?;
    if let Some(horizons) = &a.horizons {
        return eval_horizons(&file, &data, horizons);
    }
    let device = backend::device(a.backend, a.precision)?;
    if file.member_count() > 1 {
        return eval_ensemble(&file, &data, &device);
    }
    let model = Model::from_file(&file, &device)?;
    let loss = evaluate(&model, &data)?;
    super::say(json!({"loss": loss, "count": data.count()}))?;
    Ok(())
}

/// An ensemble's loss is its members' mean prediction's (what the service answers), beside
/// each member's own and how far apart their predictions are.
fn eval_ensemble(file: &ModelFile, data: &Dataset, device: &burn::tensor::Device) -> Result<()> {
    let members = (0..file.member_count())
        .map(|k| Model::from_file(&file.member(k), device))
        .collect::<Result<Vec<_>>>()?;
    let e = evaluate_members(&members, data)?;
    super::say(json!({
        "loss": e.loss, "count": data.count(), "members": members.len(),
        "member_loss": Spread::of(&e.member_losses), "member_losses": e.member_losses,
        "prediction_std": e.prediction_std,
    }))?;
    Ok(())
}

fn eval_horizons(file: &ModelFile, data: &Dataset, horizons: &[usize]) -> Result<()> {
    let e = Evaluator::from_file(file)?;
    let c = &e.config;
    c.check_data("data", (data.nq(), data.nv(), data.m))?;
    let longest = data.segments().iter().map(|s| s.length).max().unwrap_or(0);
    let horizons = check_horizons(horizons, usize::MAX)?;
    let found = horizon_errors(&e, data, &horizons, &|| false).expect("never stopped");
    for h in found {
        super::say(serde_json::to_string(&h).expect("json"))?;
    }
    if longest < *horizons.last().expect("checked") {
        eprintln!(
            "note: the data's longest trajectory has {longest} transitions: longer horizons \
             have no windows"
        );
    }
    Ok(())
}

pub(super) fn inspect(a: InspectArgs) -> Result<()> {
    let file = super::model::read(&a.model)?;
    let c = &file.config;
    let members = file.member_count();
    let mut out = json!({
        "spec": c.spec,
        "nq": c.nq(),
        "nv": c.nv(),
        "n": c.nv(),
        "m": c.m,
        "dt": c.dt,
        "integrator": c.integrator,
        "lambda": c.lambda,
        "scaling": c.scaling,
        "members": members,
        "parameters": file.params.iter().map(|p| p.values.len()).sum::<usize>(),
    });
    if let Some(t) = c.template() {
        let device = backend::device(Backend::Flex, Precision::F32)?;
        let parts = c.spec.white_box_parts();
        // Every member's values: an ensemble's are their means (as its report and the
        // service give them), with their spread beside them.
        let mut physical = vec![];
        let mut ident = vec![];
        for k in 0..members {
            let values = Model::from_file(&file.member(k), &device)?
                .physical_values()
                .unwrap_or_default();
            physical.push(used_physical(t, &parts, &values));
            ident.push(identifiable(t, &parts, &values));
        }
        out["template"] = json!(t.name());
        // In the model's order, which is not Pinocchio's on a branching robot: how a user
        // maps the rows of q, q̇ and u to joints.
        out["coordinates"] = json!(t.coordinates());
        out["inputs"] = json!(t.inputs());
        out["periodic"] = json!(c.space.periodic());
        out["joints"] = json!(c.space.joints());
        let spread = |name: &String| -> Spread {
            Spread::of(&physical.iter().map(|p| p[name]).collect::<Vec<_>>())
        };
        let names = physical[0].keys();
        out["physical_parameters"] = json!(
            names
                .clone()
                .map(|n| (n, spread(n).mean))
                .collect::<BTreeMap<_, _>>()
        );
        if members > 1 {
            out["physical_parameters_std"] = json!(
                names
                    .map(|n| (n, spread(n).std))
                    .collect::<BTreeMap<_, _>>()
            );
        }
        let mut combos = ident[0].clone();
        for (i, c) in combos.iter_mut().enumerate() {
            let same: Option<Vec<f64>> = (ident.iter())
                .map(|m| m.get(i).filter(|o| o.name == c.name).map(|o| o.value))
                .collect();
            c.value = same.map_or(c.value, |v| Spread::of(&v).mean);
        }
        out["identifiable"] = json!(combos);
    }
    if let Some(made) = &file.made {
        out["made"] = json!(made);
    }
    if let Some(r) = &file.report {
        out["training"] = json!({
            "model": r.model, "epochs": r.epochs, "best_epoch": r.best_epoch,
            "train_loss": r.train_loss, "val_loss": r.val_loss, "best_val_loss": r.best_val_loss,
            "seconds": r.seconds,
        });
        if let Some(s) = r.ensemble.as_ref().and_then(|e| e.member_seconds) {
            out["training"]["member_seconds"] = json!(s);
        }
        if let Some(energy) = &r.energy {
            out["energy"] = json!(energy);
        }
    }
    super::say(serde_json::to_string_pretty(&out).expect("json"))?;
    Ok(())
}
