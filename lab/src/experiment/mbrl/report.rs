//! The experiment's output: results.csv, results.md and the score plot. Written from the
//! episode records and the reference alone, so that a finished directory reports again
//! without planning or training.

use super::episode::Initial;
use super::plots::{self, seeds_png};
use super::{DT, Episode, HORIZON, MbrlSettings, QF_SCALE, R, Reference, SOLVED, U_MAX};
use crate::experiment::csv_line;
use crate::experiment::out::OutDir;
use graybox::error::Result;

pub(super) fn report(
    s: &MbrlSettings,
    out: &OutDir,
    reference: &Reference,
    eps: &[Episode],
) -> Result<()> {
    let mut csv = String::from(
        "model,seed,episode,score,data_size,plan_cost,converged,train_loss,seconds,\
         plan_seconds,train_seconds,model_error,true_defect,plan_defect,spread,error\n",
    );
    let opt = |v: Option<f64>| v.map_or_else(String::new, |v| format!("{v:.6e}"));
    for e in eps {
        let d = e.detail.as_ref();
        csv += &csv_line(&[
            e.model.clone(),
            e.seed.to_string(),
            e.episode.to_string(),
            format!("{:.6}", e.score),
            e.data_size.to_string(),
            e.plan_cost.map_or_else(String::new, |c| format!("{c:.6e}")),
            e.converged.to_string(),
            e.train_loss.map_or(String::new(), |l| format!("{l:.6e}")),
            format!("{:.1}", e.seconds),
            opt(e.plan_seconds),
            opt(e.train_seconds),
            opt(d.map(|d| d.model_error)),
            opt(d.map(|d| d.true_defect)),
            opt(d.map(|d| d.plan_defect)),
            opt(d.and_then(|d| d.spread)),
            e.error.clone().unwrap_or_default(),
        ]);
    }
    out.write("results.csv", csv.as_bytes())?;
    let target = SOLVED * reference.score;
    let mut md = String::from("# Model-based RL of the swing-up (paper §V-D)\n\n");
    md += &format!(
        "Score: mean distance (m) of the end effector to the upright point over the noise-free \
         evaluation rollout (lower is better). Planner on the learned models: {}. Reference, the \
         same pipeline planned on the true model (the better of DIRCOL and iLQR there: {}): \
         **{:.4} m**. Solved: score ≤ {SOLVED} × reference = {target:.4} m. Q = diag{:?}, \
         R = {R}·I, Q_f = {QF_SCALE}·Q, |u| ≤ {U_MAX}, horizon {HORIZON} × {DT} s, {} restarts.\n\n",
        s.planner.name(),
        reference.planner,
        reference.score,
        s.q,
        s.restarts
    );
    md += "| model | seed | first episode within 10% | best score | last score | last training loss |\n\
           |---|---|---|---|---|---|\n";
    for m in &s.models {
        for &seed in &s.seeds {
            let run: Vec<&Episode> = eps
                .iter()
                .filter(|e| &e.model == m && e.seed == seed)
                .collect();
            let first = run.iter().find(|e| e.score <= target).map_or_else(
                || format!("not within {}", s.episodes),
                |e| e.episode.to_string(),
            );
            let best = run.iter().map(|e| e.score).fold(f64::INFINITY, f64::min);
            let last = run.last().map_or(f64::NAN, |e| e.score);
            let loss = (run.iter().rev().find_map(|e| e.train_loss))
                .map_or_else(|| "–".to_string(), |l| format!("{l:.2e}"));
            md += &format!("| {m} | {seed} | {first} | {best:.4} | {last:.4} | {loss} |\n");
        }
    }
    md += "\n![score per episode](mbrl.png)\n\n";
    for m in &s.models {
        plots::seeds(s, out, reference, eps, m)?;
        md += &format!("![{m}: score per episode and seed]({})\n", seeds_png(m));
    }
    md += &why(eps, target, &s.models);
    md += &trajectories(out, eps, target)?;
    md += &time_shares(s, out, eps);
    out.write("results.md", md.as_bytes())?;
    plots::scores(s, out, reference, eps)
}

/// Why plans fail, measured: per model, the episodes that solved and those that did not, with
/// the means of the model's error along the plan and the plan's defects.
fn why(eps: &[Episode], target: f64, models: &[String]) -> String {
    if eps.iter().all(|e| e.detail.is_none()) {
        return String::new();
    }
    let mut md = String::from(
        "\n## Where the plans part from the system\n\nMeans over the episodes that planned: \
         the model's one-step error along the plan (RMS of ‖f_model − f_true‖ at the plan's \
         states and inputs), the plan's largest defect on the true system \
         (‖f_true(x̄_t, ū_t) − x̄_{t+1}‖), its constraint violation on the model, and an \
         ensemble's mean state spread along it.\n\n\
         | model | episodes | count | model error | defect on the system | defect on the model | spread |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for m in models {
        for solved in [true, false] {
            let d: Vec<_> = (eps.iter())
                .filter(|e| &e.model == m && (e.score <= target) == solved)
                .filter_map(|e| e.detail.as_ref())
                .collect();
            let mean = |f: &dyn Fn(&super::system::Detail) -> Option<f64>| {
                let v: Vec<f64> = d.iter().filter_map(|d| f(d)).collect();
                match v.is_empty() {
                    true => "–".to_string(),
                    false => format!("{:.3e}", v.iter().sum::<f64>() / v.len() as f64),
                }
            };
            md += &format!(
                "| {m} | {} | {} | {} | {} | {} | {} |\n",
                if solved { "solved" } else { "not solved" },
                d.len(),
                mean(&|d| Some(d.model_error)),
                mean(&|d| Some(d.true_defect)),
                mean(&|d| Some(d.plan_defect)),
                mean(&|d| d.spread),
            );
        }
    }
    md
}

/// The figure of one slow run's plans, before and when it first solved (the solved run that
/// took the most episodes), or, when no run solved, of the failed run that came closest.
fn trajectories(out: &OutDir, eps: &[Episode], target: f64) -> Result<String> {
    let runs = {
        let mut r: Vec<(&str, u64)> = eps.iter().map(|e| (e.model.as_str(), e.seed)).collect();
        r.dedup();
        r
    };
    let of = |(m, seed): (&str, u64)| -> Vec<&Episode> {
        (eps.iter())
            .filter(|e| e.model == m && e.seed == seed)
            .collect()
    };
    let first_solved = |run: &[&Episode]| run.iter().position(|e| e.score <= target);
    let slow = (runs.iter().map(|&r| of(r)))
        .filter_map(|run| Some((first_solved(&run)?, run)))
        .filter(|(k, _)| *k > 0)
        .max_by_key(|(k, _)| *k);
    let (title, shown) = match slow {
        Some((k, run)) => (
            format!(
                "{} seed {}: plans (orange) and the system under TVLQR (blue), first, \
                 before and when first solved",
                run[0].model, run[0].seed
            ),
            if k > 1 {
                vec![run[0], run[k - 1], run[k]]
            } else {
                vec![run[0], run[k]]
            },
        ),
        None => {
            let best = |run: &[&Episode]| run.iter().map(|e| e.score).fold(f64::INFINITY, f64::min);
            let Some(run) =
                (runs.iter().map(|&r| of(r))).min_by(|a, b| best(a).total_cmp(&best(b)))
            else {
                return Ok(String::new());
            };
            let k = (0..run.len())
                .min_by(|&a, &b| run[a].score.total_cmp(&run[b].score))
                .unwrap_or(0);
            let title = format!(
                "{} seed {} (not solved): plans (orange) and the system under TVLQR (blue), \
                 first, best and last",
                run[0].model, run[0].seed
            );
            let mut shown = vec![run[0], run[k], run[run.len() - 1]];
            shown.dedup_by_key(|e| e.episode);
            (title, shown)
        }
    };
    Ok(match plots::trajectories(out, &title, &shown)? {
        true => {
            format!("\n## Plans against the system\n\n{title}.\n\n![plans](trajectories.png)\n")
        }
        false => String::new(),
    })
}

/// Where the compute went: the runs' first trainings, then per episode the plans and the
/// trainings (the rest is tracking, exploring and the evaluator's setup).
fn time_shares(s: &MbrlSettings, out: &OutDir, eps: &[Episode]) -> String {
    let initial: f64 = (s.models.iter())
        .flat_map(|m| {
            s.seeds
                .iter()
                .map(move |seed| format!("{m}/seed{seed}/initial"))
        })
        .filter_map(|k| out.get::<Initial>(&k))
        .map(|i| i.seconds)
        .sum();
    let sum = |f: &dyn Fn(&Episode) -> Option<f64>| eps.iter().filter_map(f).sum::<f64>();
    let plan = sum(&|e| e.plan_seconds);
    let train = sum(&|e| e.train_seconds);
    let total = initial + sum(&|e| Some(e.seconds));
    if plan + train == 0.0 || total <= 0.0 {
        return String::new();
    }
    let pct = |v: f64| 100.0 * v / total;
    format!(
        "\n## Where the time went\n\n{total:.0} s of compute over the runs (summed over \
         threads): training {:.1} % (the first trainings {:.1} %, after the episodes {:.1} %), \
         planning {:.1} %, the rest (tracking, exploring, loading) {:.1} %.\n",
        pct(initial + train),
        pct(initial),
        pct(train),
        pct(plan),
        pct(total - initial - train - plan),
    )
}
