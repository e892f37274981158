//! `graybox-lab experiment rollout`: the paper's §V-C. MVF and naive trained on the same data
//! predict 5-second trajectories open loop from the true system's initial states and inputs.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::Args;
use plotters::prelude::*;
use serde::{Deserialize, Serialize};

use super::out::OutDir;
use super::plot::{self, COLORS};
use super::pool::{self, Progress};
use super::{csv_line, median, paper_double_pendulum};
use graybox::backend::{self, Backend, Precision};
use graybox::error::Result;
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::TemplateSystem;
use graybox::sim::true_step;
use graybox::train::{TrainConfig, Trainer};

const MODELS: [&str; 2] = ["MVF", "naive"];
const DT: f64 = 0.01;
/// 5 s at Δt = 0.01.
const STEPS: usize = 500;
/// Inputs are held for 0.1 s.
const HOLD: usize = 10;
const U_STD: f64 = 30.0;
const QDOT0: f64 = 2.0;
/// Where the error table looks, in seconds.
const TIMES: [f64; 4] = [0.5, 1.0, 2.0, 5.0];
const PLOTTED: usize = 4;

#[derive(Args, Debug)]
pub struct RolloutArgs {
    /// Directory for results.md, results.csv, rollouts.png, the two models and run.json;
    /// running again with the same settings reuses the trained models.
    #[arg(long)]
    pub out: PathBuf,
    /// True trajectories [default: 100; 4 with --quick].
    #[arg(long)]
    pub count: Option<usize>,
    /// Training samples [default: 4096; 256 with --quick].
    #[arg(long)]
    pub train_size: Option<usize>,
    /// Validation samples [default: 1024; 64 with --quick].
    #[arg(long)]
    pub val_size: Option<usize>,
    /// Training epochs (the best-validation parameters are kept) [default: 3000; 30 with
    /// --quick].
    #[arg(long)]
    pub epochs: Option<usize>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub run: pool::RunArgs,
}

#[derive(Debug, Clone, Serialize)]
struct RolloutSettings {
    system: &'static str,
    models: [&'static str; 2],
    seed: u64,
    train_size: usize,
    val_size: usize,
    epochs: usize,
    batch_size: usize,
    lr: f64,
    count: usize,
    trajectory: &'static str,
    backend: &'static str,
    precision: &'static str,
}

/// A trained model, saved as `<model>.gbx` in the directory.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Trained {
    model: String,
    best_val_loss: Option<f64>,
    best_epoch: usize,
    seconds: f64,
    file: String,
}

/// One true trajectory: x₀, inputs `[STEPS, m]` and positions `[STEPS + 1, n]`.
struct Trajectory {
    x0: Vec<f64>,
    u: Vec<f64>,
    q: Vec<f64>,
}

pub fn run(a: RolloutArgs) -> Result<()> {
    let q = a.run.quick;
    let s = RolloutSettings {
        system: "double_pendulum (paper values), dt 0.01, RK4; training data as in data-efficiency",
        models: MODELS,
        seed: a.seed,
        train_size: a.train_size.unwrap_or(if q { 256 } else { 4096 }).max(1),
        val_size: a.val_size.unwrap_or(if q { 64 } else { 1024 }).max(1),
        epochs: a.epochs.unwrap_or(if q { 30 } else { 3000 }),
        batch_size: 256,
        lr: 1e-3,
        count: a.count.unwrap_or(if q { 4 } else { 100 }).max(1),
        trajectory: "5 s (500 steps): q0 ~ U(-pi, pi), qdot0 ~ U(-2, 2), inputs held 0.1 s, ~ N(0, 30^2)",
        backend: "flex",
        precision: "f32",
    };
    let out = OutDir::open(&a.out, "rollout", &s)?;
    let progress = Progress::new(MODELS.len(), 0);
    let trained = pool::parallel(
        &MODELS,
        pool::threads(a.run.jobs),
        &progress,
        |m, status| {
            if let Some(t) = out.get::<Trained>(&format!("train/{m}"))
                && let Ok(file) = ModelFile::load(&out.path(&t.file))
            {
                progress.cells_done(1, &format!("{m}: trained earlier"));
                return Ok((t, file));
            }
            let (t, file) = train(&s, m, &|e, best| {
                status.show(&format!("{m}: epoch {e}/{} best val {best:.3e}", s.epochs))
            })?;
            file.save(&out.path(&t.file))?;
            out.put(&format!("train/{m}"), &t)?;
            progress.cells_done(
                1,
                &format!(
                    "{m}: best val {:.3e} ({:.0} s)",
                    t.best_val_loss.unwrap_or(f64::NAN),
                    t.seconds
                ),
            );
            Ok((t, file))
        },
    );
    progress.finish();
    let trained: Vec<(Trained, ModelFile)> = trained.into_iter().collect::<Result<_>>()?;
    let evaluators: Vec<Evaluator> = trained
        .iter()
        .map(|(_, f)| Evaluator::from_file(f))
        .collect::<Result<_>>()?;
    let truth = true_trajectories(&s);
    let predicted: Vec<Vec<Vec<f64>>> = evaluators
        .iter()
        .map(|e| truth.iter().map(|t| predict(e, t)).collect())
        .collect();
    report(&s, &out, &trained, &truth, &predicted)?;
    out.finish()
}

fn train(
    s: &RolloutSettings,
    model: &str,
    show: &dyn Fn(usize, f64),
) -> Result<(Trained, ModelFile)> {
    let start = Instant::now();
    let data = paper_double_pendulum(s.train_size, s.seed, 0)?;
    let val = paper_double_pendulum(s.val_size, s.seed, 1)?;
    let cfg = TrainConfig {
        epochs: s.epochs,
        batch_size: s.batch_size,
        lr: s.lr,
        val_fraction: 0.0,
        seed: s.seed,
        ..TrainConfig::default()
    };
    let spec = ModelSpec::named(model, Some(Template::DoublePendulum))?;
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let mut trainer = Trainer::new(model, spec, &[], &data, Some(&val), cfg, &device)?;
    trainer.run(&AtomicBool::new(false), |m, t| {
        show(m.epoch, t.best_val_loss().unwrap_or(f64::NAN))
    })?;
    let report = trainer.report();
    Ok((
        Trained {
            model: model.to_string(),
            best_val_loss: report.best_val_loss,
            best_epoch: report.best_epoch,
            seconds: start.elapsed().as_secs_f64(),
            file: format!("{model}.gbx"),
        },
        trainer.model_file(),
    ))
}

/// The true system's trajectories (RK4 at Δt = 0.01 on the template, as the training data).
fn true_trajectories(s: &RolloutSettings) -> Vec<Trajectory> {
    let t = Template::DoublePendulum;
    let (n, m) = (t.n(), t.m());
    let sys = TemplateSystem::new(t.clone(), t.defaults());
    let mut rng = Rng::derive(s.seed, 0x0707_0001);
    (0..s.count)
        .map(|_| {
            let q0 = (0..n).map(|_| rng.uniform_in(-std::f64::consts::PI, std::f64::consts::PI));
            let q0: Vec<f64> = q0.collect();
            let qd0: Vec<f64> = (0..n).map(|_| rng.uniform_in(-QDOT0, QDOT0)).collect();
            let x0: Vec<f64> = q0.iter().chain(&qd0).copied().collect();
            let mut u = Vec::with_capacity(STEPS * m);
            for k in 0..STEPS {
                if k % HOLD == 0 {
                    u.extend((0..m).map(|_| U_STD * rng.normal()));
                } else {
                    u.extend_from_within(u.len() - m..);
                }
            }
            let mut x = x0.clone();
            let mut q = q0;
            for k in 0..STEPS {
                x = true_step(&sys, &x, &u[k * m..(k + 1) * m], DT, Integrator::Rk4);
                q.extend_from_slice(&x[..n]);
            }
            Trajectory { x0, u, q }
        })
        .collect()
}

/// A model's positions `[STEPS + 1, n]` from the trajectory's x₀ under its inputs.
fn predict(e: &Evaluator, t: &Trajectory) -> Vec<f64> {
    let (n, m) = (e.config.n, e.config.m);
    let mut q = t.x0[..n].to_vec();
    e.rollout(
        &t.x0,
        STEPS,
        |k, _| t.u[k * m..(k + 1) * m].to_vec(),
        |x, _| {
            q.extend_from_slice(&x[..n]);
            true
        },
    );
    q
}

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

fn report(
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
         {} epochs (best validation loss kept).\n\n",
        s.count, s.train_size, s.epochs
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

fn fmt_err(e: f64) -> String {
    if e.is_finite() {
        format!("{e:.3}")
    } else {
        "∞".into()
    }
}

/// q₁ and q₂ over time for the first trajectories: truth, MVF, naive. Predictions that leave
/// the plot are clipped to its edge.
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
            title.titled(
                "5 s open-loop predictions: truth (blue), MVF (orange), naive (green)",
                plot::font(20),
            )?;
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
                let mut chart = ChartBuilder::on(area)
                    .caption(format!("trajectory {j}, q{}", i + 1), plot::font(15))
                    .margin(6)
                    .x_label_area_size(28)
                    .y_label_area_size(48)
                    .build_cartesian_2d(0f64..STEPS as f64 * DT, lo..hi)?;
                chart
                    .configure_mesh()
                    .light_line_style(WHITE)
                    .x_desc("s")
                    .y_desc("rad")
                    .label_style(plot::font(12))
                    .axis_desc_style(plot::font(12))
                    .draw()?;
                let line = |v: Vec<f64>, color: RGBColor| {
                    LineSeries::new(
                        v.into_iter().enumerate().map(move |(k, y)| {
                            let y = if y.is_finite() { y.clamp(lo, hi) } else { hi };
                            (k as f64 * DT, y)
                        }),
                        color.stroke_width(2),
                    )
                };
                chart.draw_series(line(tq, COLORS[0]))?;
                for (m, preds) in predicted.iter().enumerate().take(trained.len()) {
                    chart.draw_series(line(series(&preds[j]), COLORS[1 + m]))?;
                }
            }
            Ok(())
        },
    )
}
