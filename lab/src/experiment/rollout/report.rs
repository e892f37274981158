//! The rollout experiment's table (errors at 0.5, 1, 2 and 5 s per row) and its plot.

use plotters::prelude::*;

use super::{DT, RolloutSettings, STEPS, Trained, Trajectory};
use crate::experiment::out::OutDir;
use crate::experiment::plot::{self, COLORS};
use crate::experiment::{csv_line, median};
use graybox::error::Result;
use graybox::model::file::ModelFile;
use graybox::physics::templates::Template;

/// Where the error table looks, in seconds.
const TIMES: [f64; 4] = [0.5, 1.0, 2.0, 5.0];
const PLOTTED: usize = 4;
/// `COLORS` by name, for the plot's title.
const COLOR_NAMES: [&str; 5] = ["blue", "orange", "green", "red", "purple"];

/// ‖q̂_k − q_k‖₂ (angles not wrapped); a prediction that left the finite numbers is ∞.
fn error_at(truth: &[f64], pred: &[f64], k: usize, n: usize) -> f64 {
    let d: f64 = (0..n)
        .map(|i| (pred[k * n + i] - truth[k * n + i]).powi(2))
        .sum::<f64>()
        .sqrt();
    if d.is_finite() { d } else { f64::INFINITY }
}

fn step_of(seconds: f64) -> usize {
    (seconds / DT).round() as usize
}

pub(super) fn write(
    s: &RolloutSettings,
    out: &OutDir,
    trained: &[(Trained, ModelFile)],
    truth: &[Trajectory],
    predicted: &[Vec<Vec<f64>>],
) -> Result<()> {
    let n = Template::DoublePendulum.n();
    let mut csv = String::from("trajectory,model,seconds,position_error\n");
    let mut md = String::from("# 5-second rollouts (paper §V-C)\n\n");
    md += &format!(
        "{} true trajectories; position error ‖q̂ − q‖₂ in rad (angles not wrapped) of open-loop \
         predictions from the same x₀ under the same inputs. Models trained on {} samples for \
         {} epochs (best validation loss kept).{}\n\n",
        s.count,
        s.train_size,
        s.epochs,
        trajectory_note(s)
    );
    md += "| model | best val loss |";
    for t in TIMES {
        md += &format!(" {t} s mean | {t} s median |");
    }
    md += " diverged |\n|---|---|";
    md += &"---|---|".repeat(TIMES.len());
    md += "---|\n";
    for ((t, _), preds) in trained.iter().zip(predicted) {
        md += &format!(
            "| {} | {} |",
            t.model,
            t.best_val_loss
                .map_or_else(|| "–".into(), |l| format!("{l:.2e}"))
        );
        for sec in TIMES {
            let k = step_of(sec);
            let errors: Vec<f64> = truth
                .iter()
                .zip(preds)
                .map(|(tr, p)| error_at(&tr.q, p, k, n))
                .collect();
            for (i, e) in errors.iter().enumerate() {
                csv += &csv_line(&[
                    i.to_string(),
                    t.model.clone(),
                    sec.to_string(),
                    format!("{e:.6e}"),
                ]);
            }
            let mean = errors.iter().sum::<f64>() / errors.len() as f64;
            md += &format!(" {} | {} |", fmt_err(mean), fmt_err(median(&errors)));
        }
        let diverged = preds
            .iter()
            .filter(|p| p.iter().any(|v| !v.is_finite()))
            .count();
        md += &format!(" {diverged} |\n");
    }
    md += "\n![rollouts](rollouts.png)\n";
    out.write("results.csv", csv.as_bytes())?;
    out.write("results.md", md.as_bytes())?;
    plot_rollouts(out, trained, truth, predicted)
}

fn trajectory_note(s: &RolloutSettings) -> String {
    let Some(t) = &s.trajectories else {
        return String::new();
    };
    let curriculum = if t.one_step_epochs > 0 {
        format!(" (its first {} on the one-step loss)", t.one_step_epochs)
    } else {
        String::new()
    };
    format!(
        " The trajectory rows trained on {} trajectories of {} steps (Δt = 0.01; {} more \
         validate, their one-step loss shown) for {} epochs, with the one-step loss (H = 1) \
         and on windows of H = {}{curriculum}.",
        t.train_trajectories, t.steps, t.val_trajectories, t.epochs, t.horizon
    )
}

fn fmt_err(e: f64) -> String {
    if e.is_finite() {
        format!("{e:.3}")
    } else {
        "∞".into()
    }
}

/// q₁ and q₂ over time for the first trajectories: truth and every row's model.
fn plot_rollouts(
    out: &OutDir,
    trained: &[(Trained, ModelFile)],
    truth: &[Trajectory],
    predicted: &[Vec<Vec<f64>>],
) -> Result<()> {
    let n = Template::DoublePendulum.n();
    let shown = truth.len().min(PLOTTED);
    plot::png(
        &out.path("rollouts.png"),
        (1200, 260 * shown as u32 + 40),
        |root| {
            let (title, body) = root.split_vertically(40);
            let names = (trained.iter().enumerate())
                .map(|(m, (t, _))| format!("{} ({})", t.model, COLOR_NAMES[1 + m]));
            let names: Vec<String> = names.collect();
            let caption = format!(
                "5 s open-loop predictions (× where one leaves the plot): truth (blue), {}",
                names.join(", ")
            );
            title.titled(&caption, plot::font(16))?;
            let panels = body.split_evenly((shown, n));
            for (p, area) in panels.iter().enumerate() {
                let (j, i) = (p / n, p % n);
                let series =
                    |q: &[f64]| -> Vec<f64> { (0..=STEPS).map(|k| q[k * n + i]).collect() };
                let tq = series(&truth[j].q);
                let (lo, hi) = tq
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                let pad = 0.5 * (hi - lo).max(1.0);
                let (lo, hi) = (lo - pad, hi + pad);
                let caption = format!("trajectory {j}, q{}", i + 1);
                let mut chart = plot::angle_panel(area, &caption, STEPS as f64 * DT, (lo, hi))?;
                // A prediction is drawn until it leaves the plot (or the finite numbers),
                // and marked with an × where it does, rather than run along the edge.
                let draw = |chart: &mut ChartContext<'_, _, _>, v: Vec<f64>, color: RGBColor| {
                    let exit = v.iter().position(|y| !(lo..=hi).contains(y));
                    let kept = v[..exit.unwrap_or(v.len())].iter().enumerate();
                    let points = kept.map(|(k, &y)| (k as f64 * DT, y));
                    chart.draw_series(LineSeries::new(points, color.stroke_width(2)))?;
                    if let Some(k) = exit {
                        let y = if v[k] < lo { lo } else { hi };
                        let mark = Cross::new((k as f64 * DT, y), 7, color.stroke_width(3));
                        chart.draw_series(std::iter::once(mark))?;
                    }
                    Ok::<(), Box<dyn std::error::Error>>(())
                };
                draw(&mut chart, tq, COLORS[0])?;
                for (m, preds) in predicted.iter().enumerate().take(trained.len()) {
                    draw(&mut chart, series(&preds[j]), COLORS[1 + m])?;
                }
            }
            Ok(())
        },
    )
}
