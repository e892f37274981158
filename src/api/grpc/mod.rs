//! The gRPC listener: `graybox.v1.Dynamics` for controllers, grpc.health.v1 and server
//! reflection. Handlers convert and call the core; compute runs off the async executor.

mod convert;
mod dynamics;

use std::sync::Arc;

use futures_util::StreamExt;
use tokio::net::TcpListener;
use tokio_rustls::TlsAcceptor;
use tokio_stream::wrappers::{ReceiverStream, TcpListenerStream};
use tonic::service::interceptor::InterceptedService;

use super::listen::{bearer_matches, tls_incoming};
use crate::app::App;
use crate::error::{Error, Result};

/// Generated from `proto/graybox/v1/dynamics.proto` at build time.
pub mod pb {
    tonic::include_proto!("graybox.v1");
    pub const FILE_DESCRIPTOR_SET: &[u8] =
        tonic::include_file_descriptor_set!("graybox_descriptor");
}

/// Accepted connections with Nagle's algorithm off: a controller's small request/response
/// pairs otherwise wait on delayed ACKs (measured: +40 ms on a 1024-state Predict).
fn incoming(
    listener: TcpListener,
) -> impl futures_util::Stream<Item = std::io::Result<tokio::net::TcpStream>> {
    TcpListenerStream::new(listener).map(|conn| {
        let conn = conn?;
        conn.set_nodelay(true)?;
        Ok(conn)
    })
}

/// With a token, every `graybox.v1.Dynamics` call needs `authorization: Bearer <token>`
/// metadata: inference costs compute, so it is not a free read. Health and reflection stay
/// open (load balancers and tools call them without credentials).
#[derive(Clone)]
struct Auth(Option<Arc<str>>);

impl tonic::service::Interceptor for Auth {
    fn call(&mut self, req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        let Some(token) = &self.0 else {
            return Ok(req);
        };
        let given = req
            .metadata()
            .get("authorization")
            .and_then(|v| v.to_str().ok());
        if bearer_matches(given, token) {
            Ok(req)
        } else {
            Err(tonic::Status::unauthenticated(
                "a valid 'authorization: Bearer <token>' metadata entry is required",
            ))
        }
    }
}

/// Serves gRPC on `listener` until `shutdown` resolves: over TLS when `tls` is given, with
/// the bearer token required when `token` is.
pub async fn serve(
    app: App,
    listener: TcpListener,
    token: Option<String>,
    tls: Option<TlsAcceptor>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<()> {
    let (reporter, health) = tonic_health::server::health_reporter();
    reporter
        .set_service_status("", tonic_health::ServingStatus::Serving)
        .await;
    reporter
        .set_serving::<pb::dynamics_server::DynamicsServer<dynamics::DynamicsService>>()
        .await;
    // Both reflection versions: grpcurl speaks v1, grpcio-reflection's Python client and
    // older tools only v1alpha.
    let reflection = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(pb::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
    };
    let reflect_err = |e| Error::Internal(format!("reflection: {e}"));
    let reflection_v1 = reflection().build_v1().map_err(reflect_err)?;
    let reflection_v1alpha = reflection().build_v1alpha().map_err(reflect_err)?;
    let limit = app.settings.grpc_max_message_bytes();
    let streams = app.settings.grpc_max_streams;
    let dynamics = pb::dynamics_server::DynamicsServer::new(dynamics::DynamicsService { app })
        .max_decoding_message_size(limit)
        .max_encoding_message_size(limit);
    let dynamics = InterceptedService::new(dynamics, Auth(token.map(Arc::from)));
    let router = tonic::transport::Server::builder()
        // A client's streams on one connection are capped (tonic's default is unlimited),
        // so one connection cannot park an unbounded number of calls.
        .max_concurrent_streams(streams)
        .add_service(health)
        .add_service(reflection_v1)
        .add_service(reflection_v1alpha)
        .add_service(dynamics);
    let served = match tls {
        None => {
            router
                .serve_with_incoming_shutdown(incoming(listener), shutdown)
                .await
        }
        Some(acceptor) => {
            let conns = ReceiverStream::new(tls_incoming(listener, acceptor))
                .map(|(conn, _)| Ok::<_, std::io::Error>(conn));
            router.serve_with_incoming_shutdown(conns, shutdown).await
        }
    };
    served.map_err(|e| Error::Internal(format!("gRPC server failed: {e}")))
}
