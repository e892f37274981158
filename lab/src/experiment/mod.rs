//! `graybox-lab experiment …`: the paper's experiments (§V, appendix C), one command each. Every
//! experiment writes `results.md`, `results.csv`, PNG plots and `run.json` to `--out`, trains
//! independent cells on all cores, and saves each finished cell as it completes, so that the
//! same command run again continues where it stopped (`out.rs`).

mod data_efficiency;
mod ensemble;
mod mbrl;
mod multistep;
mod out;
mod plot;
mod pool;
mod resumable;
mod rollout;

use clap::Subcommand;

use graybox::data::Dataset;
use graybox::error::{Error, Result};
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::{SimConfig, simulate};

pub use data_efficiency::DataEfficiencyArgs;
pub use ensemble::EnsembleArgs;
pub use mbrl::MbrlArgs;
pub use multistep::MultistepArgs;
pub use rollout::RolloutArgs;

#[derive(Subcommand, Debug)]
pub enum ExperimentCommand {
    /// §V-B: the smallest training set with which each model (W-B … MVF, naive) reaches the
    /// paper's validation loss, per seed.
    DataEfficiency(DataEfficiencyArgs),
    /// §V-C: 5-second open-loop predictions of MVF and naive against the true system.
    Rollout(RolloutArgs),
    /// §V-D: model-based RL of the swing-up (plan on the model, track with TVLQR on the
    /// system, learn from the episode), per model and seed.
    Mbrl(MbrlArgs),
    /// Multi-step (shooting) training: MVF trained on windows of H steps of trajectories
    /// against its open-loop error on held-out trajectories, paired by seed across H.
    Multistep(MultistepArgs),
    /// Ensembles: calibration of MVF ×5's spread against its true error in and out of the
    /// training distribution, and W-B ×5's bootstrap error bars against the true parameters.
    Ensemble(EnsembleArgs),
}

pub fn run(cmd: ExperimentCommand) -> Result<()> {
    match cmd {
        ExperimentCommand::DataEfficiency(a) => data_efficiency::run(a),
        ExperimentCommand::Rollout(a) => rollout::run(a),
        ExperimentCommand::Mbrl(a) => mbrl::run(a),
        ExperimentCommand::Multistep(a) => multistep::run(a),
        ExperimentCommand::Ensemble(a) => ensemble::run(a),
    }
}

/// `count` transitions of the paper's double pendulum with the paper's sampling (Δt = 0.01,
/// RK4), from stream `stream` of `seed` (streams keep a seed's training and validation
/// samples apart).
fn paper_double_pendulum(count: usize, seed: u64, stream: u64) -> Result<Dataset> {
    let t = Template::DoublePendulum;
    let cfg = SimConfig {
        count,
        seed: Rng::derive(seed, 0xDA7A_0000 + stream).next_u64(),
        ..SimConfig::default()
    };
    simulate(&t, t.defaults(), &cfg)
}

/// `--models`, comma-separated (else `default`): at least one, each a model the paper's
/// double pendulum takes.
fn models_arg(arg: Option<&str>, default: &[&str]) -> Result<Vec<String>> {
    let models = names_arg(arg, default);
    if models.is_empty() {
        return Err(Error::invalid("models", "name at least one model"));
    }
    for m in &models {
        ModelSpec::named(m, Some(Template::DoublePendulum))
            .map_err(|e| Error::invalid("models", e.to_string()))?;
    }
    Ok(models)
}

/// A comma-separated list's names, trimmed, empty ones dropped (else `default`).
fn names_arg(arg: Option<&str>, default: &[&str]) -> Vec<String> {
    match arg {
        Some(m) => (m.split(',').map(str::trim))
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect(),
        None => default.iter().map(|m| m.to_string()).collect(),
    }
}

/// `--seeds` (else `default`): that many seeds from 0, at least one.
fn seeds_arg(arg: Option<u64>, default: u64) -> Result<Vec<u64>> {
    match arg.unwrap_or(default) {
        0 => Err(Error::invalid("seeds", "must be at least 1")),
        k => Ok((0..k).collect()),
    }
}

/// Every model with every seed, model by model.
fn model_seeds(models: &[String], seeds: &[u64]) -> Vec<(String, u64)> {
    (models.iter())
        .flat_map(|m| seeds.iter().map(move |&seed| (m.clone(), seed)))
        .collect()
}

/// The median of `v` (NaN when empty); infinities count as large values.
fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let k = s.len() / 2;
    // Odd length, or equal middles (two infinities would average to NaN).
    if s.len() % 2 == 1 || s[k - 1] == s[k] {
        s[k]
    } else {
        (s[k - 1] + s[k]) / 2.0
    }
}

/// One CSV row (RFC 4180: fields with commas, quotes or newlines quoted).
fn csv_line(fields: &[String]) -> String {
    let quoted: Vec<String> = fields
        .iter()
        .map(|f| {
            if f.contains([',', '"', '\n', '\r']) {
                format!("\"{}\"", f.replace('"', "\"\""))
            } else {
                f.clone()
            }
        })
        .collect();
    quoted.join(",") + "\n"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_even_and_infinite() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(&[1.0, f64::INFINITY, f64::INFINITY]), f64::INFINITY);
        // Two equal infinities in the middle: their mean would be NaN.
        assert_eq!(
            median(&[1.0, f64::INFINITY, f64::INFINITY, 2.0]),
            f64::INFINITY
        );
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn csv_quotes_what_needs_it() {
        let line = csv_line(&["a".into(), "b,c".into(), "say \"hi\"".into()]);
        assert_eq!(line, "a,\"b,c\",\"say \"\"hi\"\"\"\n");
    }
}
