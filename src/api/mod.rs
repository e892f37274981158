//! Adapters: REST (axum) and gRPC (tonic) over the one core, `App`, and how both accept
//! connections (TCP or TLS) and check the bearer token.

pub mod echo;
pub mod grpc;
pub mod listen;
pub mod openapi;
pub mod rest;
pub mod tls;
pub mod web;
