use std::collections::VecDeque;
use std::convert::Infallible;

use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::IntoResponse;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::routing::{get, post};
use futures_util::Stream;
use serde_json::json;

use super::error::{ApiError, ApiResult};
use super::{Params, RestState, int_param, json_body, page, stored};
use crate::app::events::JobProgress;
use crate::app::jobs::JobRequest;
use crate::app::requests::parse_body;
use crate::app::uploads::BodyKind;
use crate::records::JobState;
use tokio::sync::{broadcast, watch};

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/jobs", get(list).post(submit))
        .route("/v1/jobs/{id}", get(read))
        .route("/v1/jobs/{id}/cancel", post(cancel))
        .route("/v1/jobs/{id}/metrics", get(metrics))
        .route("/v1/jobs/{id}/events", get(events))
        .route("/v1/events", get(all_events))
}

/// Server-sent events of every job: `job` with the job as it is after each change (state,
/// epoch, losses) and for each new job; `resync` when this subscriber fell behind and should
/// read the list again. One store poller serves every subscriber.
async fn all_events(State(s): State<RestState>) -> ApiResult<impl IntoResponse> {
    let rx = s.app.follow_all_jobs().await?;
    let stream = futures_util::stream::unfold(rx, |mut rx| async move {
        let event = match rx.recv().await {
            Ok(job) => Event::default().event("job").json_data(&job).expect("json"),
            Err(broadcast::error::RecvError::Lagged(_)) => {
                Event::default().event("resync").data("{}")
            }
            Err(broadcast::error::RecvError::Closed) => return None,
        };
        Some((Ok::<_, Infallible>(event), rx))
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

async fn submit(
    State(s): State<RestState>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let key = match headers.get("idempotency-key") {
        None => None,
        Some(v) => {
            let k = v.to_str().ok().filter(|k| !k.is_empty() && k.len() <= 200);
            Some(
                k.ok_or_else(|| {
                    ApiError::bad_request(
                        "Idempotency-Key",
                        "must be 1–200 visible ASCII characters",
                    )
                })?
                .to_string(),
            )
        }
    };
    let req: JobRequest = parse_body(json_body(body, s.limit(BodyKind::Template))?)?;
    Ok(stored(s.app.submit_job(req, key).await?))
}

async fn list(State(s): State<RestState>, p: Params) -> ApiResult<impl IntoResponse> {
    let (items, next) = s
        .app
        .list_jobs(
            p.get("state").map(String::as_str),
            int_param(&p, "page_size")?,
            p.get("page_token").map(String::as_str),
        )
        .await?;
    Ok(page(items, next))
}

async fn read(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(s.app.job(&id).await?))
}

async fn cancel(
    State(s): State<RestState>,
    Path(id): Path<String>,
) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(s.app.cancel_job(&id).await?))
}

async fn metrics(
    State(s): State<RestState>,
    Path(id): Path<String>,
) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(
        json!({ "items": s.app.job_metrics(&id).await? }),
    ))
}

/// Server-sent events: `progress` per epoch with the metrics row, `state` on each change; the
/// stream ends after the final state. Every subscriber of a job shares one store poller.
async fn events(
    State(s): State<RestState>,
    Path(id): Path<String>,
) -> ApiResult<impl IntoResponse> {
    let rx = s.app.follow_job(&id).await?;
    Ok(Sse::new(event_stream(rx)).keep_alive(KeepAlive::default()))
}

struct Cursor {
    rx: watch::Receiver<JobProgress>,
    last_epoch: i64,
    last_state: Option<JobState>,
    pending: VecDeque<Event>,
    done: bool,
}

impl Cursor {
    /// Queues the events `p` adds to what this subscriber has seen.
    fn catch_up(&mut self, p: &JobProgress) {
        let seen = self.last_epoch;
        for r in p.metrics.iter().filter(|r| r.epoch > seen) {
            self.last_epoch = r.epoch;
            self.pending.push_back(
                Event::default()
                    .event("progress")
                    .json_data(r)
                    .expect("json"),
            );
        }
        if self.last_state != Some(p.job.state) {
            self.last_state = Some(p.job.state);
            self.done = p.job.state.is_final();
            self.pending.push_back(
                Event::default()
                    .event("state")
                    .json_data(&p.job)
                    .expect("json"),
            );
        }
    }
}

fn event_stream(rx: watch::Receiver<JobProgress>) -> impl Stream<Item = Result<Event, Infallible>> {
    let cursor = Cursor {
        rx,
        last_epoch: 0,
        last_state: None,
        pending: VecDeque::new(),
        done: false,
    };
    futures_util::stream::unfold(cursor, |mut c| async move {
        loop {
            if let Some(e) = c.pending.pop_front() {
                return Some((Ok(e), c));
            }
            if c.done {
                return None;
            }
            let p = c.rx.borrow_and_update().clone();
            c.catch_up(&p);
            if c.pending.is_empty() && c.rx.changed().await.is_err() {
                // The poller stopped (the job ended): its last value is all there is.
                let p = c.rx.borrow().clone();
                c.catch_up(&p);
                c.done = true;
            }
        }
    })
}
