//! The multi-step experiment's tables: held-out open-loop error per horizon and seed, the
//! paired ratios against H = 1, and what each horizon costs per epoch.

use plotters::prelude::*;

use super::{Cell, MultistepSettings, TABLE_SECONDS, eval_steps};
use crate::experiment::out::OutDir;
use crate::experiment::plot::{self, COLORS};
use crate::experiment::{csv_line, median};
use graybox::error::Result;

/// A cell's errors after `seconds` of prediction, if they were measured.
fn errors_at(c: &Cell, seconds: f64) -> Option<&graybox::infer::horizons::HorizonError> {
    c.errors.iter().find(|e| (e.seconds - seconds).abs() < 1e-9)
}

/// The median position error after `seconds` of a cell (∞ for none: diverged everywhere).
fn error_at(c: &Cell, seconds: f64) -> f64 {
    errors_at(c, seconds)
        .and_then(|e| e.position_median)
        .unwrap_or(f64::INFINITY)
}

/// The mean position error after `seconds` (∞ when a rollout diverged).
fn mean_error_at(c: &Cell, seconds: f64) -> f64 {
    errors_at(c, seconds)
        .and_then(|e| e.position_mean)
        .unwrap_or(f64::INFINITY)
}

/// What a cell trained, seeds aside: the rows the ratios and the plot are grouped by.
fn group(c: &Cell) -> String {
    if c.equal_time {
        "H = 1 for H = 10's time".to_string()
    } else {
        format!("H = {}", c.horizon)
    }
}

fn label(c: &Cell) -> String {
    if c.equal_time {
        format!("H = 1, {} epochs (H = 10's time)", c.epochs)
    } else {
        format!("H = {}", c.horizon)
    }
}

/// How the data were recorded, for the intro.
fn recording(s: &MultistepSettings) -> String {
    if s.substeps == 1 {
        return format!("Δt = {}, the model's own RK4 step", s.dt);
    }
    format!(
        "recorded every Δt = {} s of the true system integrated by RK4 at Δt / {} = {} s; the \
         model steps RK4 at Δt",
        s.dt,
        s.substeps,
        s.dt / s.substeps as f64
    )
}

fn curriculum(one_step_epochs: usize) -> String {
    if one_step_epochs == 0 {
        return String::new();
    }
    format!(
        " Curriculum: every H > 1 training spends its first {one_step_epochs} epochs on the \
         one-step loss, then trains on its windows."
    )
}

pub(super) fn write(s: &MultistepSettings, out: &OutDir, cells: &[Cell]) -> Result<()> {
    let mut md = format!(
        "# Multi-step training: open-loop error against training horizon\n\n\
         MVF on the double pendulum: {} training trajectories of {} steps ({}), {} for \
         validation, per seed; {} epochs, batch {} windows, lr {}. Errors: median (and mean) \
         ‖q̂ − q‖ (angles on the circle) over every window start of {} held-out trajectories \
         of {} steps, open loop under the recorded inputs.{}\n\n",
        s.train_trajectories,
        s.steps,
        recording(s),
        s.val_trajectories,
        s.epochs,
        s.batch_size,
        s.lr,
        s.test_trajectories,
        s.test_steps,
        curriculum(s.one_step_epochs),
    );
    if let Some([q, qdot]) = s.noise {
        let note = format!(
            "Training and validation states carry Gaussian noise (σ = {q} rad on q, {qdot} rad/s \
             on q̇), as sensors would record them; the held-out trajectories are exact.\n\n"
        );
        let at = md.rfind("\n\n").expect("the intro ends with a blank line");
        md.insert_str(at + 2, &note);
    }
    md.push_str(
        "| training | seed | 0.5 s | 1 s | 2 s | mean 0.5 s | mean 1 s | mean 2 s | s / epoch \
         | samples/s | best epoch |\n",
    );
    md.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    let header = [
        "training",
        "horizon",
        "seed",
        "epochs",
        "error_0.5s",
        "error_1s",
        "error_2s",
        "mean_error_0.5s",
        "mean_error_1s",
        "mean_error_2s",
        "seconds_per_epoch",
        "samples_per_second",
        "best_epoch",
    ];
    let mut csv = csv_line(&header.map(String::from));
    for c in cells {
        let e: Vec<f64> = TABLE_SECONDS.iter().map(|&t| error_at(c, t)).collect();
        let mean: Vec<f64> = TABLE_SECONDS.iter().map(|&t| mean_error_at(c, t)).collect();
        md.push_str(&format!(
            "| {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.0} | {} |\n",
            label(c),
            c.seed,
            e[0],
            e[1],
            e[2],
            mean[0],
            mean[1],
            mean[2],
            c.seconds_per_epoch,
            c.samples_per_second,
            c.best_epoch
        ));
        csv.push_str(&csv_line(&[
            label(c),
            c.horizon.to_string(),
            c.seed.to_string(),
            c.epochs.to_string(),
            e[0].to_string(),
            e[1].to_string(),
            e[2].to_string(),
            mean[0].to_string(),
            mean[1].to_string(),
            mean[2].to_string(),
            c.seconds_per_epoch.to_string(),
            c.samples_per_second.to_string(),
            c.best_epoch.to_string(),
        ]));
    }
    md.push_str(&ratios(cells));
    md.push_str("\n![median held-out error against prediction time](horizons.png)\n");
    plot_errors(out, cells, s.dt)?;
    out.write("results.md", md.as_bytes())?;
    out.write("results.csv", csv.as_bytes())
}

/// Per horizon: the median over seeds of H = 1's error divided by its error (paired by seed),
/// at each time, and its epoch time against H = 1's.
fn ratios(cells: &[Cell]) -> String {
    let one = |seed: u64| {
        cells
            .iter()
            .find(|c| c.horizon == 1 && !c.equal_time && c.seed == seed)
    };
    let mut md = String::from(
        "\n## Against H = 1, paired by seed\n\n\
         Error ratio: H = 1's median error over this training's (above 1: this training is \
         better), the median over seeds, and how many seeds it is better in.\n\n\
         | training | 0.5 s | 1 s | 2 s | better at 1 s and 2 s | epoch time / H = 1's |\n\
         |---|---:|---:|---:|---:|---:|\n",
    );
    for c in cells.iter().filter(|c| c.horizon != 1 || c.equal_time) {
        if md.contains(&format!("| {} |", group(c))) {
            continue;
        }
        let peers: Vec<(&Cell, &Cell)> = (cells.iter())
            .filter(|d| d.horizon == c.horizon && d.equal_time == c.equal_time)
            .filter_map(|d| one(d.seed).map(|o| (d, o)))
            .collect();
        let ratio = |t: f64| {
            median(
                &peers
                    .iter()
                    .map(|(d, o)| error_at(o, t) / error_at(d, t))
                    .collect::<Vec<_>>(),
            )
        };
        let better = (peers.iter())
            .filter(|(d, o)| {
                error_at(d, 1.0) < error_at(o, 1.0) && error_at(d, 2.0) < error_at(o, 2.0)
            })
            .count();
        let time = median(
            &peers
                .iter()
                .map(|(d, o)| d.seconds_per_epoch / o.seconds_per_epoch)
                .collect::<Vec<_>>(),
        );
        md.push_str(&format!(
            "| {} | {:.2}× | {:.2}× | {:.2}× | {better} of {} | {time:.1}× |\n",
            group(c),
            ratio(0.5),
            ratio(1.0),
            ratio(2.0),
            peers.len()
        ));
    }
    md
}

/// Each training's median held-out position error (median over seeds) against prediction
/// time, both axes logarithmic.
fn plot_errors(out: &OutDir, cells: &[Cell], dt: f64) -> Result<()> {
    let mut labels: Vec<String> = cells.iter().map(group).collect();
    labels.dedup();
    let (lo, hi) = (1e-5, 10.0);
    let curve = |l: &String| -> Vec<(f64, f64)> {
        let mine: Vec<&Cell> = cells.iter().filter(|c| &group(c) == l).collect();
        (eval_steps(dt).into_iter())
            .map(|k| {
                let t = k as f64 * dt;
                let e = median(&mine.iter().map(|c| error_at(c, t)).collect::<Vec<_>>());
                // A diverged median sits on the top edge, marked by the clamp.
                (t, if e.is_finite() { e.clamp(lo, hi) } else { hi })
            })
            .collect()
    };
    plot::png(&out.path("horizons.png"), (1000, 600), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Open-loop position error on held-out trajectories (median)",
                plot::font(20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((dt.max(0.01)..2.0).log_scale(), (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("prediction time (s)")
            .y_desc("|q_pred - q| (rad)")
            .label_style(plot::font(13))
            .axis_desc_style(plot::font(14))
            .draw()?;
        // The baseline (H = 1, blue) drawn last, on top: it stays visible where lines meet.
        for (i, l) in labels.iter().enumerate().rev() {
            let color = COLORS[i % COLORS.len()];
            chart
                .draw_series(LineSeries::new(curve(l), color.stroke_width(2)))?
                .label(l.clone())
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE)
            .border_style(BLACK)
            .label_font(plot::font(14))
            .draw()?;
        Ok(())
    })
}
