//! Adapters: REST (axum) and gRPC (tonic) over the one core, `App`.

pub mod grpc;
pub mod openapi;
pub mod rest;
