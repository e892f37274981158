//! The experiment's output: results.csv, results.md and the score plot. Written from the
//! episode records and the reference alone, so that a finished directory reports again
//! without planning or training.

use plotters::prelude::*;

use super::{DT, Episode, HORIZON, MbrlSettings, QF_SCALE, R, Reference, SOLVED, U_MAX};
use crate::experiment::csv_line;
use crate::experiment::out::OutDir;
use crate::experiment::plot::{self, COLORS};
use graybox::error::Result;

pub(super) fn report(
    s: &MbrlSettings,
    out: &OutDir,
    reference: &Reference,
    eps: &[Episode],
) -> Result<()> {
    let mut csv = String::from(
        "model,seed,episode,score,data_size,plan_cost,converged,train_loss,seconds,error\n",
    );
    for e in eps {
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
    md += "| model | seed | first episode within 10% | best score | last score |\n|---|---|---|---|---|\n";
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
            md += &format!("| {m} | {seed} | {first} | {best:.4} | {last:.4} |\n");
        }
    }
    md += "\n![score per episode](mbrl.png)\n";
    out.write("results.md", md.as_bytes())?;
    plot_scores(s, out, reference, eps)
}

/// Score per episode: per model the mean over seeds (line) and the range (band), with the
/// reference line.
fn plot_scores(
    s: &MbrlSettings,
    out: &OutDir,
    reference: &Reference,
    eps: &[Episode],
) -> Result<()> {
    let finite_max = eps
        .iter()
        .map(|e| e.score)
        .filter(|v| v.is_finite())
        .fold(reference.score, f64::max);
    let top = finite_max * 1.1;
    plot::png(&out.path("mbrl.png"), (900, 520), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Model-based RL: score per episode (mean over seeds, band: range)",
                plot::font(20),
            )
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(0.5f64..(s.episodes as f64 + 0.5), 0f64..top)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_desc("episode")
            .x_labels(s.episodes.min(15))
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_desc("mean end-effector distance to upright (m)")
            .label_style(plot::font(14))
            .axis_desc_style(plot::font(15))
            .draw()?;
        for (i, m) in s.models.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let mut mean = vec![];
            let mut band_lo = vec![];
            let mut band_hi = vec![];
            for e in 1..=s.episodes {
                let v: Vec<f64> = eps
                    .iter()
                    .filter(|x| &x.model == m && x.episode == e)
                    .map(|x| x.score.min(top))
                    .collect();
                if v.is_empty() {
                    continue;
                }
                let x = e as f64;
                mean.push((x, v.iter().sum::<f64>() / v.len() as f64));
                band_lo.push((x, v.iter().copied().fold(f64::INFINITY, f64::min)));
                band_hi.push((x, v.iter().copied().fold(0.0, f64::max)));
            }
            let band: Vec<(f64, f64)> = band_hi
                .iter()
                .copied()
                .chain(band_lo.iter().rev().copied())
                .collect();
            chart.draw_series([Polygon::new(band, color.mix(0.2).filled())])?;
            chart
                .draw_series(LineSeries::new(mean, color.stroke_width(2)))?
                .label(m.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        chart
            .draw_series(LineSeries::new(
                [
                    (0.5, reference.score),
                    (s.episodes as f64 + 0.5, reference.score),
                ],
                BLACK.stroke_width(1),
            ))?
            .label("reference (true model)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(1)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(plot::font(14))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .draw()?;
        Ok(())
    })
}
