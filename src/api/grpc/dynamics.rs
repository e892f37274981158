//! `graybox.v1.Dynamics`: thin handlers over the core's inference.

use std::pin::Pin;
use std::time::{Duration, Instant};

use futures_util::{Stream, StreamExt};
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

use super::convert::{OrStatus, model_info, plan_request, take};
use super::pb::{self, dynamics_server::Dynamics};
use crate::app::App;
use crate::app::inference::{Energy, RolloutInputs, RolloutShape, Want};
use crate::array::Array;
use crate::control::linalg::Mat;

pub struct DynamicsService {
    pub app: App,
}

/// How long before the caller's deadline the service gives up: a twentieth of the time the
/// caller allows, between 10 ms and 100 ms. tonic's timeout layers (the server's, and the
/// caller's own channel, whose clock started before the request left) answer a bare
/// CANCELLED ("Timeout expired") at the deadline; stopping earlier sends the service's
/// DEADLINE_EXCEEDED, with its message, first. 10 ms covers tokio's 1 ms timer resolution and
/// the handler starting after the layer's clock did; on a loaded machine the answer's way
/// back to the caller takes longer, which the proportional part covers (a 2 s call stops
/// 100 ms early, a 100 ms call 10 ms early).
fn deadline_margin(allowed: Duration) -> Duration {
    (allowed / 20).clamp(Duration::from_millis(10), Duration::from_millis(100))
}

/// The caller's deadline from the `grpc-timeout` header ("100m", "5S", …), less
/// [`deadline_margin`].
fn deadline<T>(req: &Request<T>) -> Option<Instant> {
    let v = req.metadata().get("grpc-timeout")?.to_str().ok()?;
    let (num, unit) = v.split_at(v.len().checked_sub(1)?);
    let n: u64 = num.parse().ok()?;
    // Checked throughout: a client may send any number (18446744073709551615S once panicked
    // here); a deadline too far to represent is no deadline.
    let d = match unit {
        "H" => Duration::from_secs(n.checked_mul(3600)?),
        "M" => Duration::from_secs(n.checked_mul(60)?),
        "S" => Duration::from_secs(n),
        "m" => Duration::from_millis(n),
        "u" => Duration::from_micros(n),
        "n" => Duration::from_nanos(n),
        _ => return None,
    };
    Instant::now().checked_add(d.saturating_sub(deadline_margin(d)))
}

#[tonic::async_trait]
impl Dynamics for DynamicsService {
    async fn predict(
        &self,
        req: Request<pb::PredictRequest>,
    ) -> Result<Response<pb::PredictResponse>, Status> {
        let until = deadline(&req);
        let r = req.into_inner();
        let (x, u) = (take("x", r.x)?, take("u", r.u)?);
        let want = Want {
            accel: r.want_accel,
            members: r.members,
            dt: r.dt,
        };
        let p = self
            .app
            .predict(&r.model_id, x, u, want, until)
            .await
            .or_status()?;
        Ok(Response::new(pb::PredictResponse {
            id: r.id,
            x_next: Some(p.next.into()),
            accel: p.accel.map(Into::into),
            max_abs_z: p.max_abs_z,
            x_next_std: p.std.map(Into::into),
            members: p.members.map(Into::into),
            member_count: p.member_count as u32,
        }))
    }

    async fn energy(
        &self,
        req: Request<pb::EnergyRequest>,
    ) -> Result<Response<pb::EnergyResponse>, Status> {
        let until = deadline(&req);
        let r = req.into_inner();
        let (x, u) = (take("x", r.x)?, take("u", r.u)?);
        let Energy { n, energies: e } = self
            .app
            .energy(&r.model_id, x, u, until)
            .await
            .or_status()?;
        let b = e.kinetic.len();
        let array = |v: Vec<f64>| Some(Array::new(&[b, n], v).into());
        Ok(Response::new(pb::EnergyResponse {
            id: r.id,
            kinetic: e.kinetic,
            potential: e.potential,
            total: e.total,
            power: e.power,
            inertial: array(e.inertial),
            coriolis: array(e.coriolis),
            gravity: array(e.gravity),
            applied: array(e.applied),
            parts: (e.parts.into_iter())
                .map(|p| pb::ForcePart {
                    name: p.name.into(),
                    damping: p.dissipation,
                    values: array(p.values),
                })
                .collect(),
        }))
    }

    async fn inverse_dynamics(
        &self,
        req: Request<pb::InverseDynamicsRequest>,
    ) -> Result<Response<pb::InverseDynamicsResponse>, Status> {
        let until = deadline(&req);
        let r = req.into_inner();
        let (x, qdd) = (take("x", r.x)?, take("qdd", r.qdd)?);
        let (n, inv) = self
            .app
            .inverse_dynamics(&r.model_id, x, qdd, until)
            .await
            .or_status()?;
        let b = inv.tau.len() / n;
        let array = |v: Vec<f64>| Some(Array::new(&[b, n], v).into());
        let e = inv.terms;
        Ok(Response::new(pb::InverseDynamicsResponse {
            id: r.id,
            tau: array(inv.tau),
            inertial: array(e.inertial),
            coriolis: array(e.coriolis),
            gravity: array(e.gravity),
            passive: array(e.applied),
            parts: (e.parts.into_iter())
                .map(|p| pb::ForcePart {
                    name: p.name.into(),
                    damping: p.dissipation,
                    values: array(p.values),
                })
                .collect(),
        }))
    }

    type RolloutStream = Pin<Box<dyn Stream<Item = Result<pb::RolloutChunk, Status>> + Send>>;

    async fn rollout(
        &self,
        req: Request<pb::RolloutRequest>,
    ) -> Result<Response<Self::RolloutStream>, Status> {
        let until = deadline(&req);
        let r = req.into_inner();
        let inputs = match r.inputs {
            Some(pb::rollout_request::Inputs::U(u)) => RolloutInputs::U(u.into()),
            Some(pb::rollout_request::Inputs::Policy(p)) => RolloutInputs::Policy {
                x_bar: take("policy.x_bar", p.x_bar)?,
                u_bar: take("policy.u_bar", p.u_bar)?,
                k: take("policy.k", p.k)?,
            },
            None => return Err(Status::invalid_argument("inputs: give u or policy")),
        };
        let shape = RolloutShape {
            chunk: usize::try_from(r.chunk).unwrap_or(usize::MAX),
            particles: r.particles.map(|p| p as usize),
            dt: r.dt,
        };
        let rx = self
            .app
            .rollout(&r.model_id, r.x0, inputs, shape, until)
            .await
            .or_status()?;
        let id = r.id;
        let stream = ReceiverStream::new(rx).map(move |c| {
            let c = c.or_status()?;
            Ok(pb::RolloutChunk {
                id: id.clone(),
                start: c.start as u64,
                x: Some(c.x.into()),
                u: Some(c.u.into()),
                max_abs_z: c.max_abs_z,
                x_std: c.x_std.map(Into::into),
            })
        });
        Ok(Response::new(Box::pin(stream)))
    }

    async fn linearize(
        &self,
        req: Request<pb::LinearizeRequest>,
    ) -> Result<Response<pb::LinearizeResponse>, Status> {
        let until = deadline(&req);
        let r = req.into_inner();
        let (x, u) = (take("x", r.x)?, take("u", r.u)?);
        let l = self
            .app
            .linearize(&r.model_id, x, u, until)
            .await
            .or_status()?;
        Ok(Response::new(pb::LinearizeResponse {
            id: r.id,
            a: Some(l.a.into()),
            b: Some(l.b.into()),
            max_abs_z: l.max_abs_z,
        }))
    }

    async fn tvlqr(
        &self,
        req: Request<pb::TvlqrRequest>,
    ) -> Result<Response<pb::TvlqrResponse>, Status> {
        let until = deadline(&req);
        let r = req.into_inner();
        let (xbar, ubar) = (take("x_bar", r.x_bar)?, take("u_bar", r.u_bar)?);
        let weights = [take("q", r.q)?, take("r", r.r)?, take("qf", r.qf)?];
        let g = self
            .app
            .tvlqr(&r.model_id, xbar, ubar, weights, until)
            .await
            .or_status()?;
        Ok(Response::new(pb::TvlqrResponse {
            id: r.id,
            k: Some(g.k.into()),
            s: Some(g.s.into()),
        }))
    }

    async fn plan(
        &self,
        req: Request<pb::PlanRequest>,
    ) -> Result<Response<pb::PlanResponse>, Status> {
        let until = deadline(&req);
        let mut r = req.into_inner();
        let id = std::mem::take(&mut r.id);
        let model_id = std::mem::take(&mut r.model_id);
        let p = self
            .app
            .plan(&model_id, plan_request(r)?, until)
            .await
            .or_status()?;
        let (t, nx) = (p.gains.k.len(), p.x.len() / (p.gains.k.len() + 1));
        let m = p.u.len() / t.max(1);
        Ok(Response::new(pb::PlanResponse {
            id,
            x: Some(Array::new(&[t + 1, nx], p.x).into()),
            u: Some(Array::new(&[t, m], p.u).into()),
            k: Some(Mat::stack(p.gains.k).into()),
            cost: p.cost,
            costs: p.costs,
            iterations: p.iterations as u32,
            converged: p.converged,
            goal_error: p.goal_error,
            method: p.method.name().to_string(),
            constraint_violation: p.constraint_violation,
            rollout_deviation: p.rollout_deviation,
            x_std: p.x_std.map(|s| Array::new(&[t + 1, nx], s).into()),
        }))
    }

    async fn get_model(
        &self,
        req: Request<pb::GetModelRequest>,
    ) -> Result<Response<pb::ModelInfo>, Status> {
        let row = self
            .app
            .resolve_model(&req.into_inner().model_id)
            .await
            .or_status()?;
        Ok(Response::new(model_info(&row)))
    }

    async fn list_models(
        &self,
        req: Request<pb::ListModelsRequest>,
    ) -> Result<Response<pb::ListModelsResponse>, Status> {
        let r = req.into_inner();
        let size = (r.page_size != 0).then_some(r.page_size as i64);
        let token = (!r.page_token.is_empty()).then_some(r.page_token.as_str());
        let (items, next) = self.app.list_models(size, token).await.or_status()?;
        Ok(Response::new(pb::ListModelsResponse {
            models: items.iter().map(model_info).collect(),
            next_page_token: next.unwrap_or_default(),
        }))
    }
}
