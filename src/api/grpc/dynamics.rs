//! `graybox.v1.Dynamics`: thin handlers over the core's inference.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

use super::convert::{array, model_info, take};
use super::pb::{self, dynamics_server::Dynamics};
use crate::app::App;
use crate::app::inference::rows;

pub struct DynamicsService {
    pub app: App,
}

/// The caller's deadline from the `grpc-timeout` header ("100m", "5S", …).
fn deadline<T>(req: &Request<T>) -> Option<Instant> {
    let v = req.metadata().get("grpc-timeout")?.to_str().ok()?;
    let (num, unit) = v.split_at(v.len().checked_sub(1)?);
    let n: u64 = num.parse().ok()?;
    let d = match unit {
        "H" => Duration::from_secs(n * 3600),
        "M" => Duration::from_secs(n * 60),
        "S" => Duration::from_secs(n),
        "m" => Duration::from_millis(n),
        "u" => Duration::from_micros(n),
        "n" => Duration::from_nanos(n),
        _ => return None,
    };
    Some(Instant::now() + d)
}

#[tonic::async_trait]
impl Dynamics for DynamicsService {
    async fn predict(
        &self,
        req: Request<pb::PredictRequest>,
    ) -> Result<Response<pb::PredictResponse>, Status> {
        let r = req.into_inner();
        let (x, xs) = take("x", r.x)?;
        let (u, us) = take("u", r.u)?;
        let b = xs.first().copied().unwrap_or(0) as usize;
        let (next, acc) = self
            .app
            .predict(&r.model_id, x, xs.clone(), u, us, r.want_accel)
            .await?;
        let width = next.len() / b.max(1);
        let accel = acc.map(|a| {
            let n = a.len() / b.max(1);
            array(&[b, n], a)
        });
        Ok(Response::new(pb::PredictResponse {
            id: r.id,
            x_next: Some(array(&[b, width], next)),
            accel,
        }))
    }

    type RolloutStream = ReceiverStream<Result<pb::RolloutChunk, Status>>;

    async fn rollout(
        &self,
        req: Request<pb::RolloutRequest>,
    ) -> Result<Response<Self::RolloutStream>, Status> {
        let until = deadline(&req);
        let r = req.into_inner();
        let eval = self.app.evaluator(&r.model_id).await?;
        let (n, m) = (eval.config.n, eval.config.m);
        let nx = 2 * n;
        if r.x0.len() != nx || r.x0.iter().any(|v| !v.is_finite()) {
            return Err(Status::invalid_argument(format!(
                "x0: must be {nx} finite values"
            )));
        }
        enum Inputs {
            Open(Vec<f64>),
            Policy {
                xbar: Vec<f64>,
                ubar: Vec<f64>,
                k: Vec<f64>,
            },
        }
        let (inputs, steps) = match r.inputs {
            Some(pb::rollout_request::Inputs::U(u)) => {
                let t = rows("u", &u.shape, &u.data, m)?.rows;
                (Inputs::Open(u.data), t)
            }
            Some(pb::rollout_request::Inputs::Policy(p)) => {
                let (xbar, xs) = take("policy.x_bar", p.x_bar)?;
                let (ubar, us) = take("policy.u_bar", p.u_bar)?;
                let (k, ks) = take("policy.k", p.k)?;
                let t = rows("policy.u_bar", &us, &ubar, m)?.rows;
                let tx = rows("policy.x_bar", &xs, &xbar, nx)?.rows;
                if tx != t && tx != t + 1 {
                    return Err(Status::invalid_argument(format!(
                        "policy.x_bar: needs T or T+1 rows for T = {t}, got {tx}"
                    )));
                }
                if ks != [t as u64, m as u64, nx as u64]
                    || k.len() != t * m * nx
                    || k.iter().any(|v| !v.is_finite())
                {
                    return Err(Status::invalid_argument(format!(
                        "policy.k: must be [{t}, {m}, {nx}] finite values, got shape {ks:?}"
                    )));
                }
                (Inputs::Policy { xbar, ubar, k }, t)
            }
            None => return Err(Status::invalid_argument("inputs: give u or policy")),
        };
        let max = self.app.settings.max_rollout_steps;
        if steps > max {
            return Err(Status::resource_exhausted(format!(
                "{steps} steps is over the limit of {max}"
            )));
        }
        let chunk = if r.chunk == 0 { 1000 } else { r.chunk as usize }.min(100_000);
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        let telemetry = self.app.telemetry.clone();
        let id = r.id;
        let x0 = r.x0;
        tokio::task::spawn_blocking(move || {
            let input = |t: usize, x: &[f64]| -> Vec<f64> {
                match &inputs {
                    Inputs::Open(u) => u[t * m..(t + 1) * m].to_vec(),
                    Inputs::Policy { xbar, ubar, k } => (0..m)
                        .map(|i| {
                            let kx: f64 = (0..nx)
                                .map(|j| k[(t * m + i) * nx + j] * (x[j] - xbar[t * nx + j]))
                                .sum();
                            ubar[t * m + i] - kx
                        })
                        .collect(),
                }
            };
            let stopped = || {
                telemetry
                    .computations_stopped
                    .fetch_add(1, Ordering::Relaxed)
            };
            let (mut start, mut done) = (0usize, 0usize);
            let mut states = x0.clone();
            let mut applied: Vec<f64> = Vec::new();
            eval.rollout(&x0, steps, input, |x, u| {
                if until.is_some_and(|d| Instant::now() > d) || tx.is_closed() {
                    stopped();
                    let _ = tx.blocking_send(Err(Status::deadline_exceeded(
                        "the rollout passed its deadline",
                    )));
                    return false;
                }
                if x.iter().any(|v| !v.is_finite()) {
                    let _ = tx.blocking_send(Err(Status::invalid_argument(format!(
                        "the state became non-finite at step {}: the trajectory left what the model can evaluate",
                        done + 1
                    ))));
                    return false;
                }
                states.extend(x);
                applied.extend(u);
                done += 1;
                if states.len() / nx >= chunk || done == steps {
                    let c = states.len() / nx;
                    let cu = applied.len() / m;
                    let msg = pb::RolloutChunk {
                        id: id.clone(),
                        start: start as u64,
                        x: Some(array(&[c, nx], std::mem::take(&mut states))),
                        u: Some(array(&[cu, m], std::mem::take(&mut applied))),
                    };
                    if tx.blocking_send(Ok(msg)).is_err() {
                        stopped();
                        return false;
                    }
                    start += c;
                }
                true
            });
        });
        Ok(Response::new(ReceiverStream::new(rx)))
    }

    async fn linearize(
        &self,
        req: Request<pb::LinearizeRequest>,
    ) -> Result<Response<pb::LinearizeResponse>, Status> {
        let r = req.into_inner();
        let (x, xs) = take("x", r.x)?;
        let (u, us) = take("u", r.u)?;
        let (b, nx) = (
            xs.first().copied().unwrap_or(0) as usize,
            xs.get(1).copied().unwrap_or(0) as usize,
        );
        let m = us.get(1).copied().unwrap_or(0) as usize;
        let (a, bm) = self.app.linearize(&r.model_id, x, xs, u, us).await?;
        Ok(Response::new(pb::LinearizeResponse {
            id: r.id,
            a: Some(array(&[b, nx, nx], a)),
            b: Some(array(&[b, nx, m], bm)),
        }))
    }

    async fn tvlqr(
        &self,
        req: Request<pb::TvlqrRequest>,
    ) -> Result<Response<pb::TvlqrResponse>, Status> {
        let r = req.into_inner();
        let xbar = take("x_bar", r.x_bar)?;
        let ubar = take("u_bar", r.u_bar)?;
        let (t, m) = (
            ubar.1.first().copied().unwrap_or(0) as usize,
            ubar.1.get(1).copied().unwrap_or(0) as usize,
        );
        let nx = xbar.1.get(1).copied().unwrap_or(0) as usize;
        let (k, s) = self
            .app
            .tvlqr(
                &r.model_id,
                xbar,
                ubar,
                take("q", r.q)?,
                take("r", r.r)?,
                take("qf", r.qf)?,
            )
            .await?;
        Ok(Response::new(pb::TvlqrResponse {
            id: r.id,
            k: Some(array(&[t, m, nx], k)),
            s: Some(array(&[t + 1, nx, nx], s)),
        }))
    }

    async fn get_model(
        &self,
        req: Request<pb::GetModelRequest>,
    ) -> Result<Response<pb::ModelInfo>, Status> {
        let row = self.app.resolve_model(&req.into_inner().model_id).await?;
        Ok(Response::new(model_info(&row)))
    }

    async fn list_models(
        &self,
        req: Request<pb::ListModelsRequest>,
    ) -> Result<Response<pb::ListModelsResponse>, Status> {
        let r = req.into_inner();
        let size = (r.page_size != 0).then_some(r.page_size as i64);
        let token = (!r.page_token.is_empty()).then_some(r.page_token.as_str());
        let (items, next) = self.app.list_models(size, token).await?;
        Ok(Response::new(pb::ListModelsResponse {
            models: items.iter().map(model_info).collect(),
            next_page_token: next.unwrap_or_default(),
        }))
    }
}
