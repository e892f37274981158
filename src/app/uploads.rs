//! What an upload costs: each route's body kind, its size limit and the memory handling a
//! body of it takes per byte, so that the REST adapter can admit bodies under one budget
//! before reading them (`api/rest/admission.rs`).

use super::Settings;

/// What kind of body a route takes, which sets its size limit and its cost per body byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodyKind {
    /// A dataset (JSON or CSV): `--max-body-mb`.
    Dataset,
    /// A model file: `--max-model-mb`.
    Model,
    /// A template document, or a job request that may embed one: `--max-template-mb`.
    Template,
    /// Anything else (cancelling a job, …): [`SMALL_BODY`].
    Small,
}

/// The largest body of a route that takes no document.
pub const SMALL_BODY: usize = 64 << 10;

impl BodyKind {
    /// The kind of a request's body (`method` as HTTP spells it); None for methods without
    /// one.
    pub fn of(method: &str, path: &str) -> Option<Self> {
        if matches!(method, "GET" | "HEAD" | "OPTIONS") {
            return None;
        }
        Some(match path {
            "/v1/datasets" => BodyKind::Dataset,
            "/v1/models" => BodyKind::Model,
            "/v1/templates" | "/v1/jobs" => BodyKind::Template,
            _ => BodyKind::Small,
        })
    }

    pub fn limit(self, s: &Settings) -> usize {
        match self {
            BodyKind::Dataset => s.max_body_bytes(),
            BodyKind::Model => s.max_model_bytes(),
            BodyKind::Template => s.max_template_bytes(),
            BodyKind::Small => SMALL_BODY,
        }
    }

    /// Peak memory of handling a body of `bytes`: the body, its parsed form and what is
    /// built and stored from it. Measured as the process's peak RSS over one upload, per body
    /// byte (`graybox-lab bench uploads` for datasets): a JSON dataset 6.9–8.9× in either
    /// form, its bytes in the rows or in an object store (the parsed JSON document dominates),
    /// so 10×; a CSV one 3.4×, a model file 5.3×, a template document 5.0×, so 6×; a
    /// template's checks also take up to ~30 MB whatever its size (a document of 10⁵ nodes
    /// is 0.2 MB).
    pub fn cost(self, bytes: usize) -> usize {
        let (per_byte, floor) = match self {
            BodyKind::Dataset => (10, 0),
            BodyKind::Template => (6, 32 << 20),
            BodyKind::Model | BodyKind::Small => (6, 0),
        };
        bytes.saturating_mul(per_byte).max(floor)
    }

    /// The most one body of this kind reserves.
    pub fn max_cost(self, s: &Settings) -> usize {
        self.cost(self.limit(s))
    }

    pub const ALL: [BodyKind; 4] = [
        BodyKind::Dataset,
        BodyKind::Model,
        BodyKind::Template,
        BodyKind::Small,
    ];
}
