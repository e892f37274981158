use std::convert::Infallible;
use std::time::Duration;

use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::IntoResponse;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::routing::{get, post};
use futures_util::Stream;
use serde_json::json;

use super::error::{ApiError, ApiResult};
use super::{Params, RestState, int_param, json_body, page};
use crate::app::App;
use crate::app::jobs::{JobRequest, parse_body};

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/jobs", get(list).post(submit))
        .route("/v1/jobs/{id}", get(read))
        .route("/v1/jobs/{id}/cancel", post(cancel))
        .route("/v1/jobs/{id}/metrics", get(metrics))
        .route("/v1/jobs/{id}/events", get(events))
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
    let req: JobRequest = parse_body(json_body(body, s.app.settings.max_body_bytes)?)?;
    let (job, created) = s.app.submit_job(req, key).await?;
    Ok((
        if created {
            StatusCode::CREATED
        } else {
            StatusCode::OK
        },
        axum::Json(job),
    ))
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
/// stream ends after the final state. Reads the store, so it follows jobs any worker runs.
async fn events(
    State(s): State<RestState>,
    Path(id): Path<String>,
) -> ApiResult<impl IntoResponse> {
    let job = s.app.job(&id).await?;
    let stream = event_stream(s.app.clone(), id, job.state);
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

struct Cursor {
    app: App,
    id: String,
    last_epoch: i64,
    last_state: Option<crate::store::JobState>,
    pending: std::collections::VecDeque<Event>,
    done: bool,
}

fn event_stream(
    app: App,
    id: String,
    _initial: crate::store::JobState,
) -> impl Stream<Item = Result<Event, Infallible>> {
    let cursor = Cursor {
        app,
        id,
        last_epoch: 0,
        last_state: None,
        pending: Default::default(),
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
            let (Ok(Some(job)), Ok(rows)) = (
                c.app.store.get_job(&c.id).await,
                c.app.store.metrics(&c.id, c.last_epoch).await,
            ) else {
                tokio::time::sleep(Duration::from_millis(250)).await;
                continue;
            };
            for r in rows {
                c.last_epoch = r.epoch;
                c.pending.push_back(
                    Event::default()
                        .event("progress")
                        .json_data(r)
                        .expect("json"),
                );
            }
            if c.last_state != Some(job.state) {
                c.last_state = Some(job.state);
                c.done = job.state.is_final();
                c.pending.push_back(
                    Event::default()
                        .event("state")
                        .json_data(&job)
                        .expect("json"),
                );
            }
            if c.pending.is_empty() {
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
        }
    })
}
