//! The loop's choices on the command line: the planner, an ensemble's plan cost, the models
//! (ensembles written `MVB×5`) and the learning rate, each checked with an error naming it.

use clap::ValueEnum;
use serde::Serialize;

use super::LR;
use crate::experiment::{models_arg, names_arg};
use graybox::control::plan::{EnsembleCost, Method};
use graybox::error::{Error, Result};

/// How a plan is made, on the learned model and on the true one alike.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Planner {
    /// Direct collocation (the paper's).
    Dircol,
    /// iLQR on the same cost.
    Ilqr,
}

impl Planner {
    pub(super) fn name(self) -> &'static str {
        match self {
            Planner::Dircol => "DIRCOL",
            Planner::Ilqr => "iLQR",
        }
    }

    pub(super) fn method(self) -> Method {
        match self {
            Planner::Dircol => Method::Dircol,
            Planner::Ilqr => Method::Ilqr,
        }
    }
}

/// What a plan on an ensemble minimizes (`control::ensemble`).
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlanCost {
    /// The cost on the members' mean dynamics.
    MeanDynamics,
    /// The members' average cost, each rolling out the same inputs.
    Mean,
}

impl PlanCost {
    pub(super) fn of(self) -> EnsembleCost {
        match self {
            PlanCost::MeanDynamics => EnsembleCost::MeanDynamics,
            PlanCost::Mean => EnsembleCost::Mean,
        }
    }
}

/// Most members an ensemble of the loop may have: each trains every epoch.
const MAX_MEMBERS: usize = 32;

/// A model of the loop, `MVB` or `MVB×5`: its spec's name and its members.
pub(super) fn loop_model(name: &str) -> Result<(&str, usize)> {
    let split = name
        .rsplit_once('×')
        .or_else(|| name.rsplit_once('x'))
        .and_then(|(base, k)| Some((base, k.parse::<usize>().ok()?)));
    match split {
        None => Ok((name, 1)),
        Some((_, k)) if !(2..=MAX_MEMBERS).contains(&k) => Err(Error::invalid(
            "models",
            format!("{name}: an ensemble has 2 to {MAX_MEMBERS} members"),
        )),
        Some(split) => Ok(split),
    }
}

/// `--models` for the loop: names checked as `models_arg` does, ensembles written `MVB×5`.
pub(super) fn loop_models(arg: Option<&str>, default: &[&str]) -> Result<Vec<String>> {
    let given = names_arg(arg, default);
    let mut out = vec![];
    for name in &given {
        let (base, k) = loop_model(name)?;
        let base = models_arg(Some(base), &[])?.remove(0);
        out.push(if k == 1 { base } else { format!("{base}×{k}") });
    }
    if out.is_empty() {
        return Err(Error::invalid("models", "name at least one model"));
    }
    Ok(out)
}

/// `--lr`, else the paper's: positive and finite.
pub(super) fn learning_rate(lr: Option<f64>) -> Result<f64> {
    match lr.unwrap_or(LR) {
        lr if lr.is_finite() && lr > 0.0 => Ok(lr),
        lr => Err(Error::invalid(
            "lr",
            format!("{lr} is not a positive learning rate"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_ensemble_is_written_with_its_members() {
        assert_eq!(loop_model("MVB×5").unwrap(), ("MVB", 5));
        assert_eq!(loop_model("MVBx5").unwrap(), ("MVB", 5));
        assert_eq!(loop_model("naive").unwrap(), ("naive", 1));
        for bad in ["MVBx1", "MVB×33"] {
            let e = loop_model(bad).unwrap_err().to_string();
            assert!(e.contains("models") && e.contains(bad), "{e}");
        }
        let models = loop_models(Some("naive, MVBx5,MVB×3"), &[]).unwrap();
        assert_eq!(models, ["naive", "MVB×5", "MVB×3"]);
        let e = loop_models(Some("XYZx3"), &[]).unwrap_err().to_string();
        assert!(e.contains("models") && e.contains("XYZ"), "{e}");
    }
}
