//! The experiment's figures: the scores of every model (mean and range over seeds), each
//! model's seeds with the solved band, and one run's plans against what TVLQR achieved on the
//! system (the paper's "nominal trajectories eventually start looking more realistic").

use plotters::prelude::*;

use super::{DT, Episode, HORIZON, MbrlSettings, Reference, SOLVED};
use crate::experiment::out::OutDir;
use crate::experiment::plot::{self, COLORS, Chart};
use graybox::error::Result;

/// Light green: the band of scores that count as solved.
const SOLVED_BAND: RGBColor = RGBColor(0xc7, 0xe9, 0xc0);

/// The file of `model`'s per-seed plot.
pub(super) fn seeds_png(model: &str) -> String {
    format!("scores-{}.png", model.replace('×', "x"))
}

/// Scores drawn above this are clipped to it (∞ included): 10% over the largest finite one.
fn top(reference: &Reference, eps: &[Episode]) -> f64 {
    let finite = eps.iter().map(|e| e.score).filter(|v| v.is_finite());
    1.1 * finite.fold(reference.score, f64::max)
}

/// Axes of score against episode, with the reference line.
fn score_axes<'a, 'b>(
    root: &plot::Area<'b>,
    caption: &str,
    episodes: usize,
    top: f64,
) -> std::result::Result<Chart<'a, 'b>, Box<dyn std::error::Error>>
where
    'b: 'a,
{
    let mut chart = ChartBuilder::on(root)
        .caption(caption, plot::font(20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5f64..(episodes as f64 + 0.5), 0f64..top)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("episode (interactions after the random one)")
        .x_labels(episodes.min(15))
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc("mean end-effector distance to upright (m)")
        .label_style(plot::font(14))
        .axis_desc_style(plot::font(15))
        .draw()?;
    Ok(chart)
}

fn legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>) -> plot::DrawResult {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(plot::font(14))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

fn reference_line<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    reference: &Reference,
    episodes: usize,
) -> plot::DrawResult {
    let ends = [
        (0.5, reference.score),
        (episodes as f64 + 0.5, reference.score),
    ];
    chart
        .draw_series(LineSeries::new(ends, BLACK.stroke_width(1)))?
        .label("reference (true model)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(1)));
    Ok(())
}

/// Score per episode: per model the mean over seeds (line) and the range (band).
pub(super) fn scores(
    s: &MbrlSettings,
    out: &OutDir,
    reference: &Reference,
    eps: &[Episode],
) -> Result<()> {
    let top = top(reference, eps);
    plot::png(&out.path("mbrl.png"), (900, 520), |root| {
        let caption = "Model-based RL: score per episode (mean over seeds, band: range)";
        let mut chart = score_axes(root, caption, s.episodes, top)?;
        for (i, m) in s.models.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let (mut mean, mut lo, mut hi) = (vec![], vec![], vec![]);
            for e in 1..=s.episodes {
                let v: Vec<f64> = (eps.iter())
                    .filter(|x| &x.model == m && x.episode == e)
                    .map(|x| x.score.min(top))
                    .collect();
                if v.is_empty() {
                    continue;
                }
                let x = e as f64;
                mean.push((x, v.iter().sum::<f64>() / v.len() as f64));
                lo.push((x, v.iter().copied().fold(f64::INFINITY, f64::min)));
                hi.push((x, v.iter().copied().fold(0.0, f64::max)));
            }
            let band: Vec<(f64, f64)> = hi.iter().copied().chain(lo.into_iter().rev()).collect();
            chart.draw_series([Polygon::new(band, color.mix(0.2).filled())])?;
            chart
                .draw_series(LineSeries::new(mean, color.stroke_width(2)))?
                .label(m.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        reference_line(&mut chart, reference, s.episodes)?;
        legend(&mut chart)
    })
}

/// One model's score per episode, a line per seed, over the band of solved scores.
pub(super) fn seeds(
    s: &MbrlSettings,
    out: &OutDir,
    reference: &Reference,
    eps: &[Episode],
    model: &str,
) -> Result<()> {
    let top = top(reference, eps);
    let target = SOLVED * reference.score;
    plot::png(&out.path(&seeds_png(model)), (900, 520), |root| {
        let caption = format!("{model}: score per episode, one line per seed");
        let mut chart = score_axes(root, &caption, s.episodes, top)?;
        let band = Rectangle::new(
            [(0.5, 0.0), (s.episodes as f64 + 0.5, target)],
            SOLVED_BAND.filled(),
        );
        chart
            .draw_series([band])?
            .label(format!("solved (≤ {SOLVED} × reference)"))
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], SOLVED_BAND.filled()));
        for (i, &seed) in s.seeds.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let line = (eps.iter())
                .filter(|e| e.model == model && e.seed == seed)
                .map(|e| (e.episode as f64, e.score.min(top)));
            chart
                .draw_series(LineSeries::new(line, color.stroke_width(2)))?
                .label(format!("seed {seed}"))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        reference_line(&mut chart, reference, s.episodes)?;
        legend(&mut chart)
    })
}

/// q₁ and q₂ of the plans of `shown` episodes (columns) against the system's states under
/// TVLQR. Episodes without a plan's detail are skipped; none: no figure.
pub(super) fn trajectories(out: &OutDir, title: &str, shown: &[&Episode]) -> Result<bool> {
    let shown: Vec<(&Episode, &super::system::Detail)> = (shown.iter())
        .filter_map(|e| Some((*e, e.detail.as_ref()?)))
        .collect();
    if shown.is_empty() {
        return Ok(false);
    }
    let width = 420 * shown.len() as u32 + 40;
    plot::png(&out.path("trajectories.png"), (width, 640), |root| {
        let (head, body) = root.split_vertically(40);
        head.titled(title, plot::font(16))?;
        let panels = body.split_evenly((2, shown.len()));
        for (p, area) in panels.iter().enumerate() {
            let (i, (ep, d)) = (p / shown.len(), shown[p % shown.len()]);
            let series = |x: &[f32]| -> Vec<(f64, f64)> {
                let at = |k: usize| x.get(4 * k + i).map_or(f64::NAN, |&v| f64::from(v));
                (0..=HORIZON).map(|k| (k as f64 * DT, at(k))).collect()
            };
            let (nominal, achieved) = (series(&d.nominal), series(&d.achieved));
            let values = nominal.iter().chain(&achieved).map(|p| p.1);
            let finite: Vec<f64> = values.filter(|v| v.is_finite()).collect();
            let lo = finite.iter().copied().fold(-1.0, f64::min) - 0.3;
            let hi = finite.iter().copied().fold(4.0, f64::max) + 0.3;
            let caption = format!(
                "episode {}, q{} (score {:.2} m)",
                ep.episode,
                i + 1,
                ep.score
            );
            let mut chart = plot::angle_panel(area, &caption, HORIZON as f64 * DT, (lo, hi))?;
            let goal = if i == 0 { std::f64::consts::PI } else { 0.0 };
            let ends = [(0.0, goal), (HORIZON as f64 * DT, goal)];
            chart.draw_series(LineSeries::new(ends, BLACK.stroke_width(1)))?;
            let clip = |v: Vec<(f64, f64)>| v.into_iter().filter(|p| (lo..=hi).contains(&p.1));
            chart.draw_series(LineSeries::new(clip(nominal), COLORS[1].stroke_width(2)))?;
            chart.draw_series(LineSeries::new(clip(achieved), COLORS[0].stroke_width(2)))?;
        }
        Ok(())
    })?;
    Ok(true)
}
