//! The OpenAPI 3.1 document, generated with utoipa from the API's types and route table.

use utoipa::openapi::path::{
    HttpMethod, OperationBuilder, ParameterBuilder, ParameterIn, PathItem,
};
use utoipa::openapi::request_body::RequestBodyBuilder;
use utoipa::openapi::{
    ContentBuilder, InfoBuilder, OpenApi, OpenApiBuilder, PathsBuilder, Required, ResponseBuilder,
};
use utoipa::{OpenApi as _, ToSchema};

use crate::app::datasets::Uploaded;
use crate::app::inference::{
    EnergyReportRequest, EnergyRequest, EnergyView, EvaluateRequest, Evaluation, ForcePartView,
    InverseRequest, InverseView, PredictRequest, PredictView, SimulateRequest, SimulateView,
};
use crate::app::jobs::JobRequest;
use crate::infer::horizons::HorizonError;
use crate::model::report::{EnergyDrift, EnergyReport, Passivity};
use crate::records::{DatasetInfo, Job, JobState, Metric, Warning};

#[derive(utoipa::OpenApi)]
#[openapi(components(schemas(
    DatasetInfo,
    Job,
    JobState,
    Metric,
    JobRequest,
    Uploaded,
    Warning,
    EvaluateRequest,
    Evaluation,
    EnergyRequest,
    EnergyReportRequest,
    EnergyReport,
    EnergyDrift,
    Passivity,
    EnergyView,
    ForcePartView,
    InverseRequest,
    InverseView,
    PredictRequest,
    PredictView,
    SimulateRequest,
    SimulateView,
    HorizonError
)))]
struct Components;

/// One route: method, path, summary, request schema, parameters ("?name" for query ones).
struct Route(
    &'static str,
    &'static str,
    &'static str,
    Option<&'static str>,
    &'static [&'static str],
);

const ROUTES: &[Route] = &[
    Route(
        "post",
        "/v1/datasets",
        "Upload a dataset (JSON arrays, trajectories, or CSV with ?dt=), or a robot's log (CSV \
         or Parquet) with ?time= (docs/logs.md)",
        Some("object"),
        &[
            "?name",
            "?dt",
            "?resample",
            "?time",
            "?q",
            "?qdot",
            "?qddot",
            "?u",
            "?wrapped",
            "?gap",
            "?window",
            "?order",
            "?inputs",
        ],
    ),
    Route(
        "get",
        "/v1/datasets",
        "List datasets, newest first",
        None,
        &["?page_size", "?page_token"],
    ),
    Route(
        "get",
        "/v1/datasets/{id}",
        "Read a dataset's metadata",
        None,
        &["id"],
    ),
    Route(
        "delete",
        "/v1/datasets/{id}",
        "Delete a dataset no queued or running job uses",
        None,
        &["id"],
    ),
    Route(
        "get",
        "/v1/datasets/{id}/trajectories",
        "A dataset's trajectories (index, first row, length): the boundaries of a trajectory-form upload, else the chains of rows whose next state is the next row's state exactly",
        None,
        &["id", "?page_size", "?page_token"],
    ),
    Route(
        "post",
        "/v1/jobs",
        "Submit a training job (Idempotency-Key header supported)",
        Some("JobRequest"),
        &[],
    ),
    Route(
        "get",
        "/v1/jobs",
        "List jobs, newest first",
        None,
        &["?state", "?page_size", "?page_token"],
    ),
    Route("get", "/v1/jobs/{id}", "Read a job", None, &["id"]),
    Route(
        "post",
        "/v1/jobs/{id}/cancel",
        "Cancel a queued or running job",
        None,
        &["id"],
    ),
    Route(
        "get",
        "/v1/jobs/{id}/metrics",
        "Per-epoch losses",
        None,
        &["id"],
    ),
    Route(
        "get",
        "/v1/jobs/{id}/events",
        "Server-sent events: progress and state",
        None,
        &["id"],
    ),
    Route(
        "get",
        "/v1/events",
        "Server-sent events of every job: `job` (the job after each change of state, epoch or losses, and each new job), `resync` (fell behind: read the list again)",
        None,
        &[],
    ),
    Route(
        "post",
        "/v1/models",
        "Upload a model file (.gbx, as /checkpoint returns it); the same file again returns the stored model",
        Some("object"),
        &["?name"],
    ),
    Route(
        "get",
        "/v1/models",
        "List models, newest first",
        None,
        &["?page_size", "?page_token"],
    ),
    Route(
        "get",
        "/v1/models/{id}",
        "Read a model: spec, dimensions, losses, physical parameters",
        None,
        &["id"],
    ),
    Route(
        "get",
        "/v1/models/{id}/checkpoint",
        "Download the model file (.gbx)",
        None,
        &["id"],
    ),
    Route(
        "get",
        "/v1/models/{id}/urdf",
        "Download the identified robot as URDF (the template's document with the learned <inertial> and <dynamics>); 409 unless the model's template is a URDF robot",
        None,
        &["id"],
    ),
    Route(
        "get",
        "/v1/models/{id}/rollout",
        "Replay trajectory `index` of a dataset with the model: from its first state with its recorded inputs, the recorded and predicted q and q̇ (T + 1 rows each) and their times; with `particles` P (1–1024), also the replay as P particles (particle p on member p mod K, as Rollout's), their mean and standard deviation in `particles`",
        None,
        &["id", "?dataset_id", "?index", "?particles"],
    ),
    Route(
        "post",
        "/v1/models/{id}/evaluate",
        "Open-loop error against horizon on a trajectory dataset: from every window start, the model rolled out under the recorded inputs; per horizon the median and mean position and velocity errors (README \"Multi-step training\")",
        Some("EvaluateRequest"),
        &["id"],
    ),
    Route(
        "post",
        "/v1/models/{id}/predict",
        "x' for a batch of states (as gRPC Predict): at the model's step, or at the body's `dt` in seconds (the dynamics are continuous: a model trained at one rate predicts at another)",
        Some("PredictRequest"),
        &["id"],
    ),
    Route(
        "post",
        "/v1/models/{id}/simulate",
        "The states x_0..x_T from x0 under a sequence of inputs (as gRPC Rollout, joined into one answer; at most --max-rollout-steps), `dt` seconds apart (unset: the model's step); with `particles`, their mean and spread",
        Some("SimulateRequest"),
        &["id"],
    ),
    Route(
        "post",
        "/v1/models/{id}/energy",
        "Energy and work at a batch of states: kinetic T, potential V, total E, the power of F, and M q̈ + c + ∇V = F term by term with F's named parts (README \"Energy and power\"); 409 for a naive model, which has none",
        Some("EnergyRequest"),
        &["id"],
    ),
    Route(
        "post",
        "/v1/models/{id}/inverse-dynamics",
        "Inverse dynamics at a batch of states: the generalized force τ = M q̈ + c + ∇V − F(q, q̇, 0) that produces the given accelerations (a robot's feed-forward torque), with its terms and F(q, q̇, 0)'s named parts (docs/energy.md); 409 for a naive model",
        Some("InverseRequest"),
        &["id"],
    ),
    Route(
        "post",
        "/v1/models/{id}/energy-report",
        "The model's energy report on a stored dataset's states (drift of unforced rollouts after 100 and 1000 steps, passivity), stored with the model and shown as metrics.energy (README \"Energy and power\"); 409 for a naive model",
        Some("EnergyReportRequest"),
        &["id"],
    ),
    Route("delete", "/v1/models/{id}", "Delete a model", None, &["id"]),
    Route(
        "post",
        "/v1/templates",
        "Store a template document: a formula template or a URDF robot as JSON, or a raw URDF with Content-Type application/xml (README \"Your own mechanism\", \"Your own robot\"); the same document again returns the stored template",
        Some("object"),
        &[],
    ),
    Route(
        "get",
        "/v1/templates",
        "List stored templates, newest first",
        None,
        &["?page_size", "?page_token"],
    ),
    Route(
        "get",
        "/v1/templates/{id}",
        "Read a template: coordinates, inputs, parameters, the document",
        None,
        &["id"],
    ),
    Route(
        "delete",
        "/v1/templates/{id}",
        "Delete a template (409 while a queued or running job uses it)",
        None,
        &["id"],
    ),
    Route("get", "/healthz", "Liveness", None, &[]),
    Route(
        "get",
        "/readyz",
        "Readiness (the database and the object store answer, each within 2 s)",
        None,
        &[],
    ),
    Route("get", "/metrics", "Prometheus metrics", None, &[]),
    Route("get", "/openapi.json", "This document", None, &[]),
];

pub fn document() -> OpenApi {
    let _ = JobRequest::name();
    let mut paths = PathsBuilder::new();
    for Route(method, path, summary, body, params) in ROUTES {
        let method = match *method {
            "post" => HttpMethod::Post,
            "delete" => HttpMethod::Delete,
            _ => HttpMethod::Get,
        };
        let mut op = OperationBuilder::new()
            .summary(Some(*summary))
            .response("200", ResponseBuilder::new().description("success"))
            .response(
                "4XX",
                ResponseBuilder::new()
                    .description("{\"error\": {\"code\", \"message\", \"field\"?}}"),
            );
        for p in *params {
            let (name, location, required) = match p.strip_prefix('?') {
                Some(q) => (q, ParameterIn::Query, Required::False),
                None => (*p, ParameterIn::Path, Required::True),
            };
            op = op.parameter(
                ParameterBuilder::new()
                    .name(name)
                    .parameter_in(location)
                    .required(required),
            );
        }
        if let Some(schema) = body {
            let content = if *schema == "object" {
                ContentBuilder::new().build()
            } else {
                ContentBuilder::new()
                    .schema(Some(utoipa::openapi::Ref::from_schema_name(*schema)))
                    .build()
            };
            op = op.request_body(Some(
                RequestBodyBuilder::new()
                    .content("application/json", content)
                    .build(),
            ));
        }
        paths = paths.path(*path, PathItem::new(method, op.build()));
    }
    OpenApiBuilder::new()
        .info(
            InfoBuilder::new()
                .title("graybox")
                .version(env!("CARGO_PKG_VERSION"))
                .build(),
        )
        .paths(paths.build())
        .components(Components::openapi().components)
        .build()
}
