//! From the trained cells to the answer: the smallest training set per model, seed and
//! threshold beside the paper's, as results.csv, cells.csv, results.md and the bar plot. It
//! reads the cells alone, so that a finished directory reports again without training.

use plotters::prelude::*;

use super::{Cell, DataEfficiencySettings, PAPER};
use crate::experiment::out::OutDir;
use crate::experiment::plot::{self, COLORS, GRAY};
use crate::experiment::{csv_line, median};
use graybox::error::Result;

/// The smallest size at which `model`/`seed` reaches `threshold`.
fn smallest(cells: &[Cell], model: &str, seed: u64, threshold: f64) -> Option<usize> {
    cells
        .iter()
        .filter(|c| c.model == model && c.seed == seed && c.reaches(threshold))
        .map(|c| c.size)
        .min()
}

fn paper_value(model: &str) -> Option<usize> {
    PAPER.iter().find(|(m, _)| *m == model).map(|&(_, v)| v)
}

pub(super) fn report(s: &DataEfficiencySettings, out: &OutDir, cells: &[Cell]) -> Result<()> {
    let names = ["10^-2.5", "2·10^-2.5"];
    // results.csv: per model, seed and threshold.
    let mut csv = String::from("model,seed,threshold,smallest_size,range_low,range_high\n");
    for m in &s.models {
        for &seed in &s.seeds {
            for &t in &s.thresholds {
                let v = smallest(cells, m, seed, t);
                let f = |x: Option<usize>| x.map_or_else(String::new, |x| x.to_string());
                csv += &csv_line(&[
                    m.clone(),
                    seed.to_string(),
                    format!("{t:.6e}"),
                    f(v),
                    f(v.map(|v| v / 2)),
                    f(v),
                ]);
            }
        }
    }
    out.write("results.csv", csv.as_bytes())?;
    let mut cells_csv =
        String::from("model,seed,size,best_val_loss,best_epoch,epochs,seconds,error\n");
    for c in cells {
        cells_csv += &csv_line(&[
            c.model.clone(),
            c.seed.to_string(),
            c.size.to_string(),
            c.best_val_loss
                .map_or_else(String::new, |l| format!("{l:.6e}")),
            c.best_epoch.to_string(),
            c.epochs.to_string(),
            format!("{:.1}", c.seconds),
            c.error.clone().unwrap_or_default(),
        ]);
    }
    out.write("cells.csv", cells_csv.as_bytes())?;

    let mut md = String::from("# Data efficiency (paper §V-B)\n\n");
    md += &format!(
        "Smallest training set reaching each validation-loss threshold, as the paper's range \
         [|D|/2, |D|]; \"n.r.\": not reached by {} samples. Seeds {}. Paper: lower end of its \
         range (threshold 10^-2.5 in its code's halved loss, i.e. 2·10^-2.5 here).\n\n",
        s.sizes.last().expect("sizes"),
        s.seeds.len()
    );
    md += "| model | paper | ≤ 10^-2.5: per seed | median | ≤ 2·10^-2.5: per seed | median |\n";
    md += "|---|---|---|---|---|---|\n";
    for m in &s.models {
        let mut row = format!(
            "| {m} | {} ",
            paper_value(m).map_or_else(|| "–".into(), |v| format!("[{v}, {}]", 2 * v))
        );
        for &t in &s.thresholds {
            let per: Vec<Option<usize>> = s
                .seeds
                .iter()
                .map(|&seed| smallest(cells, m, seed, t))
                .collect();
            let text: Vec<String> = per
                .iter()
                .map(|v| v.map_or_else(|| "n.r.".into(), |v| format!("[{}, {v}]", v / 2)))
                .collect();
            let med = median_size(&per, *s.sizes.last().expect("sizes"));
            row += &format!("| {} | {med} ", text.join(" "));
        }
        md += &row;
        md += "|\n";
    }
    md += "\n![data efficiency](data_efficiency.png)\n\nPer-cell best validation losses: \
           cells.csv. Thresholds: ";
    md += &names.join(", ");
    md += ".\n";
    out.write("results.md", md.as_bytes())?;
    plot(s, out, cells)
}

/// The median lower end over seeds ("n.r." counts as above every size).
fn median_size(per: &[Option<usize>], max: usize) -> String {
    let lows: Vec<f64> = per
        .iter()
        .map(|v| v.map_or(f64::INFINITY, |v| (v / 2) as f64))
        .collect();
    let m = median(&lows);
    if m.is_finite() {
        format!("{m}")
    } else {
        format!("> {}", max / 2)
    }
}

/// Bars on a log₂ axis: the paper's lower end beside graybox's median lower end (strict
/// threshold), with the range over seeds as a whisker; "not reached" reaches the top.
fn plot(s: &DataEfficiencySettings, out: &OutDir, cells: &[Cell]) -> Result<()> {
    let max = *s.sizes.last().expect("sizes");
    let top = (2 * max.max(4096)) as f64;
    let models = &s.models;
    plot::png(&out.path("data_efficiency.png"), (1000, 560), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Smallest training set reaching validation loss 10^-2.5 (lower end of [|D|/2, |D|])",
                plot::font(20),
            )
            .margin(12)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5f64..(models.len() as f64 - 0.5), (2f64..top).log_scale().base(2.0))?;
        let label = |x: &f64| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                models.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .disable_x_mesh()
            .x_labels(models.len())
            .x_label_formatter(&label)
            .y_desc("training samples (log2)")
            .y_label_formatter(&|v| format!("{}", v.round()))
            .label_style(plot::font(15))
            .axis_desc_style(plot::font(16))
            .draw()?;
        let bar = |x: f64, w: f64, v: f64, color: RGBColor| {
            Rectangle::new(
                [(x - w / 2.0, 2.0), (x + w / 2.0, v.min(top))],
                color.filled(),
            )
        };
        for (i, m) in models.iter().enumerate() {
            let x = i as f64;
            if let Some(p) = paper_value(m) {
                chart.draw_series([bar(x - 0.18, 0.34, p as f64, GRAY)])?;
            }
            let lows: Vec<f64> = s
                .seeds
                .iter()
                .map(|&seed| {
                    smallest(cells, m, seed, s.thresholds[0]).map_or(top, |v| (v / 2) as f64)
                })
                .collect();
            let med = median(&lows);
            let color = if med >= top { COLORS[3] } else { COLORS[0] };
            chart.draw_series([bar(x + 0.18, 0.34, med, color)])?;
            let (lo, hi) = lows
                .iter()
                .fold((f64::INFINITY, 0f64), |(a, b), &v| (a.min(v), b.max(v)));
            chart.draw_series([PathElement::new(
                vec![(x + 0.18, lo), (x + 0.18, hi)],
                BLACK.stroke_width(2),
            )])?;
        }
        let legend = [
            ("paper", GRAY),
            ("graybox, median over seeds (whisker: range)", COLORS[0]),
            ("graybox, not reached", COLORS[3]),
        ];
        for (name, color) in legend {
            chart
                .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())?
                .label(name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 14, y + 5)], color.filled())
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(plot::font(14))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .draw()?;
        Ok(())
    })
}
