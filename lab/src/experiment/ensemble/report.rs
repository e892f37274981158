//! The ensemble experiment's results: results.md (tables), results.json (every figure),
//! results.csv (the buckets) and sigma_vs_error.png.

use plotters::prelude::*;
use serde_json::json;

use super::calibration::{COORDS, Calibration, Points, SetResult};
use super::errorbars::{ErrorBars, Row};
use super::{EnsembleSettings, Trained};
use crate::experiment::csv_line;
use crate::experiment::out::OutDir;
use crate::experiment::plot::{self, COLORS, GRAY};
use graybox::error::Result;

pub(super) fn write(
    s: &EnsembleSettings,
    out: &OutDir,
    trained: &[Trained],
    cal: &Calibration,
    bars: &ErrorBars,
) -> Result<()> {
    let (c, e) = (&s.calibration, &s.error_bars);
    let mut md = format!(
        "# Ensembles: calibration of the spread, and bootstrap error bars\n\n\
         {} members, each on its own bootstrap resample of the training rows (seed {}); the \
         double pendulum with the paper's values (Δt = 0.01, RK4, u ~ N(0, 120²)).\n\n\
         ## Calibration: {} ×{}\n\n\
         {} training samples (q ~ U(−π, π), q̇ ~ U(−{}, {})), {} validation samples, {} epochs \
         (batch {}, lr {}; each member keeps its best-validation epoch). Held out: {} samples \
         of the same distribution, and {} out of it with q̇ ~ U(−{}, {}). Error: the members' \
         mean next state against the true system's; σ: the members' sample standard deviation \
         (divisor K − 1), per coordinate; norms over (q1, q2, q̇1, q̇2).\n\n",
        s.members,
        s.seed,
        c.model,
        s.members,
        c.train_size,
        c.qdot_range,
        c.qdot_range,
        c.val_size,
        c.epochs,
        c.batch_size,
        c.lr,
        c.test_size,
        c.test_size,
        c.ood_qdot_range,
        c.ood_qdot_range,
    );
    md.push_str(&trained_table(trained));
    md.push_str(&findings(&cal.sets));
    md.push_str(&coverage_table(&cal.sets));
    md.push_str(&summary_table(&cal.sets));
    for set in &cal.sets[..2] {
        md.push_str(&bucket_table(set));
    }
    md.push_str(
        "\n![‖σ‖ against the true error ‖mean − truth‖, per held-out sample](sigma_vs_error.png)\n",
    );
    md.push_str(&format!(
        "\n## Error bars: {} ×{}\n\n\
         {} training samples and {} validation samples of the same distribution, Gaussian noise \
         of σ = {} added to q̇' (seeded); every parameter starts 20% off its true value (the \
         init column); {} epochs, batch {}, lr {}. Mean and σ across the members \
         (`ensemble.physical_parameters` of the model file).\n\n",
        e.model,
        s.members,
        e.train_size,
        e.val_size,
        e.qdot_next_noise,
        e.epochs,
        e.batch_size,
        e.lr
    ));
    md.push_str(&bars_table(&bars.parameters));
    md.push_str(
        "\nm1, m2, l1, l2 and g enter M and V only through the products m·l² and m·g·l: m → m/s², \
         l → s·l, g → s·g leaves the dynamics unchanged for every s, so the data fixes these \
         five only up to s. The forces b·u + eta·q̇ are not part of that symmetry, so b1, b2, \
         eta1 and eta2 are determined. Every member starts from the same values and lands at \
         about the same s, so the bootstrap spread, which measures what resampling the data \
         does to the fit, does not see that direction: the identifiable combinations below are \
         the fair test of the error bars.\n",
    );
    md.push_str(
        "\nThe identifiable combinations (the model report's), each member's value from its \
         own parameters:\n\n",
    );
    md.push_str(&bars_table(&bars.combinations));
    plot_points(out, &cal.in_dist, &cal.ood)?;
    let results = json!({
        "settings": s,
        "trained": trained,
        "calibration": cal.sets,
        "error_bars": bars,
        "wall_seconds": out.wall_seconds(),
    });
    let json = serde_json::to_vec_pretty(&results).expect("results serialize");
    out.write("results.json", &json)?;
    out.write("results.csv", buckets_csv(&cal.sets).as_bytes())?;
    out.write("results.md", md.as_bytes())
}

fn trained_table(trained: &[Trained]) -> String {
    let mut md = String::from(
        "| ensemble | epochs | best epochs | best val loss (members' mean) | training s (members summed) | wall s |\n\
         |---|---:|---|---:|---:|---:|\n",
    );
    for t in trained {
        let best: Vec<String> = t.best_epochs.iter().map(|e| e.to_string()).collect();
        md.push_str(&format!(
            "| {} | {} | {} | {:.3e} | {:.0} | {:.0} |\n",
            t.model,
            t.epochs,
            best.join(", "),
            t.best_val_loss.unwrap_or(f64::NAN),
            t.member_seconds,
            t.wall_seconds
        ));
    }
    md
}

/// What the calibration tables say, in numbers: σ's scale, how it follows the error out of
/// distribution, and the rank correlations against the goal.
fn findings(sets: &[SetResult]) -> String {
    let (id, ood) = (&sets[0], &sets[1]);
    let range = |v: &[f64; 4]| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    };
    let (clo, chi) = range(&id.coverage_2sigma);
    let (flo, fhi) = range(&id.factor_for_95);
    let goal = |r: f64| if r >= 0.6 { "met" } else { "not met" };
    let worst = ood
        .buckets
        .last()
        .map_or(f64::NAN, |b| b.mean_error / b.mean_sigma);
    format!(
        "\n**Findings.** In distribution mean ± 2σ holds {:.1}–{:.1}% of the true values per \
         coordinate (ideal ≈ 95%); 95% would need {:.1}–{:.1}σ instead of 2σ. Out of \
         distribution the mean error grows {:.1}× and the mean ‖σ‖ {:.1}×; coverage there is \
         {:.1}–{:.1}%. In the out-of-distribution decile of largest errors the error is {:.1}× \
         the spread. Spearman's ρ(‖σ‖, ‖error‖): {:.2} in distribution, {:.2} out of it, {:.2} \
         outside the training range alone (goal ≥ 0.6: {} in distribution, {} out of it). The \
         one-step errors of q and q̇ are one error in q̈ seen through the step, so q1 and q̇1 \
         (q2 and q̇2) rank alike.\n\n",
        100.0 * clo,
        100.0 * chi,
        flo,
        fhi,
        ood.mean_error / id.mean_error,
        ood.mean_sigma / id.mean_sigma,
        100.0 * range(&ood.coverage_2sigma).0,
        100.0 * range(&ood.coverage_2sigma).1,
        worst,
        id.spearman,
        ood.spearman,
        sets.get(2).map_or(f64::NAN, |s| s.spearman),
        goal(id.spearman),
        goal(ood.spearman),
    )
}

fn coverage_table(sets: &[SetResult]) -> String {
    let mut md = String::from(
        "\n### Coverage of mean ± 2σ per coordinate (ideal ≈ 95%)\n\n\
         In brackets: the factor σ would need for 95% coverage (the 95th percentile of \
         |error| / σ; 2 when calibrated).\n\n| set | samples |",
    );
    COORDS.iter().for_each(|c| md.push_str(&format!(" {c} |")));
    md.push_str("\n|---|---:|---:|---:|---:|---:|\n");
    for s in sets {
        md.push_str(&format!("| {} | {} |", s.name, s.samples));
        for j in 0..4 {
            md.push_str(&format!(
                " {:.1}% ({:.1}) |",
                100.0 * s.coverage_2sigma[j],
                s.factor_for_95[j]
            ));
        }
        md.push('\n');
    }
    md
}

fn summary_table(sets: &[SetResult]) -> String {
    let mut md = String::from(
        "\n### Spread against error, and Spearman's ρ (goal ≥ 0.6)\n\n\
         | set | mean ‖error‖ | median ‖error‖ | mean ‖σ‖ | median ‖σ‖ | ρ(‖σ‖, ‖error‖) |",
    );
    COORDS
        .iter()
        .for_each(|c| md.push_str(&format!(" ρ {c} |")));
    md.push_str("\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for s in sets {
        md.push_str(&format!(
            "| {} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3} |",
            s.name, s.mean_error, s.median_error, s.mean_sigma, s.median_sigma, s.spearman
        ));
        s.spearman_coord
            .iter()
            .for_each(|r| md.push_str(&format!(" {r:.3} |")));
        md.push('\n');
    }
    md
}

fn bucket_table(s: &SetResult) -> String {
    let mut md = format!(
        "\n### By decile of the true error: {}\n\n\
         | decile | ‖error‖ from | to | mean ‖error‖ | mean ‖σ‖ | mean ‖error‖ / mean ‖σ‖ | all 4 inside 2σ |\n\
         |---|---:|---:|---:|---:|---:|---:|\n",
        s.name
    );
    for b in &s.buckets {
        md.push_str(&format!(
            "| {:.0}–{:.0}% | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.2} | {:.1}% |\n",
            100.0 * b.from_quantile,
            100.0 * b.to_quantile,
            b.error_min,
            b.error_max,
            b.mean_error,
            b.mean_sigma,
            b.mean_error / b.mean_sigma,
            100.0 * b.coverage_all
        ));
    }
    md
}

fn bars_table(rows: &[Row]) -> String {
    let mut md = String::from(
        "| parameter | true | init | mean | σ | abs. error | abs. error / σ | inside ±3σ |\n\
         |---|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for r in rows {
        md.push_str(&format!(
            "| {} | {:.4} | {:.4} | {:.4} | {:.2e} | {:.2e} | {:.1} | {} |\n",
            r.name.replace('*', "·"),
            r.truth,
            r.init,
            r.mean,
            r.std,
            r.error,
            r.z,
            if r.inside_3sigma { "yes" } else { "no" }
        ));
    }
    let inside = rows.iter().filter(|r| r.inside_3sigma).count();
    md.push_str(&format!("\n{inside} of {} inside ±3σ.\n", rows.len()));
    md
}

fn buckets_csv(sets: &[SetResult]) -> String {
    let header = [
        "set",
        "from_quantile",
        "to_quantile",
        "samples",
        "error_min",
        "error_max",
        "mean_error",
        "mean_sigma",
        "coverage_all_2sigma",
    ];
    let mut csv = csv_line(&header.map(String::from));
    for s in sets {
        for b in &s.buckets {
            csv.push_str(&csv_line(&[
                s.name.clone(),
                b.from_quantile.to_string(),
                b.to_quantile.to_string(),
                b.samples.to_string(),
                b.error_min.to_string(),
                b.error_max.to_string(),
                b.mean_error.to_string(),
                b.mean_sigma.to_string(),
                b.coverage_all.to_string(),
            ]));
        }
    }
    csv
}

/// ‖σ‖ against ‖error‖ per sample, both axes logarithmic, with the line error = σ.
fn plot_points(out: &OutDir, in_dist: &Points, ood: &Points) -> Result<()> {
    let all =
        || (in_dist.sigma.iter().chain(&ood.sigma)).chain(in_dist.error.iter().chain(&ood.error));
    let positive = || all().copied().filter(|v| v.is_finite() && *v > 0.0);
    let lo = positive().fold(f64::INFINITY, f64::min).max(1e-12) / 1.5;
    let hi = positive().fold(0.0, f64::max).max(lo * 10.0) * 1.5;
    let (lo, hi) = if lo.is_finite() {
        (lo, hi)
    } else {
        (1e-6, 1.0)
    };
    let clamp = |v: f64| v.clamp(lo, hi);
    plot::png(&out.path("sigma_vs_error.png"), (900, 800), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Ensemble spread against true one-step error (MVF ×5)",
                plot::font(20),
            )
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d((lo..hi).log_scale(), (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("members' spread ‖sigma‖")
            .y_desc("true error ‖mean − truth‖")
            .label_style(plot::font(13))
            .axis_desc_style(plot::font(14))
            .draw()?;
        chart
            .draw_series(LineSeries::new([(lo, lo), (hi, hi)], GRAY.stroke_width(2)))?
            .label("error = sigma")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], GRAY.stroke_width(2)));
        // Out of distribution first, see-through: the in-distribution cloud is drawn over it,
        // solid.
        let sets = [
            (
                ood,
                COLORS[1],
                0.5,
                "out of distribution (qdot ~ U(-20, 20))",
            ),
            (
                in_dist,
                COLORS[0],
                1.0,
                "in distribution (qdot ~ U(-10, 10))",
            ),
        ];
        for (p, color, opacity, label) in sets {
            let dots = (p.sigma.iter().zip(&p.error)).map(move |(&s, &e)| {
                Circle::new((clamp(s), clamp(e)), 2, color.mix(opacity).filled())
            });
            chart
                .draw_series(dots)?
                .label(label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE)
            .border_style(BLACK)
            .label_font(plot::font(14))
            .draw()?;
        Ok(())
    })
}
