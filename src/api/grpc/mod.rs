//! The gRPC listener: `graybox.v1.Dynamics` for controllers, grpc.health.v1 and server
//! reflection. Handlers convert and call the core; compute runs off the async executor.

mod convert;
mod dynamics;

use tokio::net::TcpListener;
use tokio_stream::wrappers::TcpListenerStream;

use crate::app::App;
use crate::error::{Error, Result};

/// Generated from `proto/graybox/v1/dynamics.proto` at build time.
pub mod pb {
    tonic::include_proto!("graybox.v1");
    pub const FILE_DESCRIPTOR_SET: &[u8] =
        tonic::include_file_descriptor_set!("graybox_descriptor");
}

/// Serves gRPC on `listener` until `shutdown` resolves.
pub async fn serve(
    app: App,
    listener: TcpListener,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<()> {
    let (reporter, health) = tonic_health::server::health_reporter();
    reporter
        .set_service_status("", tonic_health::ServingStatus::Serving)
        .await;
    reporter
        .set_serving::<pb::dynamics_server::DynamicsServer<dynamics::DynamicsService>>()
        .await;
    let reflection = tonic_reflection::server::Builder::configure()
        .register_encoded_file_descriptor_set(pb::FILE_DESCRIPTOR_SET)
        .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        .build_v1()
        .map_err(|e| Error::Storage(format!("reflection: {e}")))?;
    let limit = app.settings.grpc_max_message_bytes;
    let dynamics = pb::dynamics_server::DynamicsServer::new(dynamics::DynamicsService { app })
        .max_decoding_message_size(limit)
        .max_encoding_message_size(limit);
    tonic::transport::Server::builder()
        .add_service(health)
        .add_service(reflection)
        .add_service(dynamics)
        .serve_with_incoming_shutdown(TcpListenerStream::new(listener), shutdown)
        .await
        .map_err(|e| Error::Storage(format!("gRPC server failed: {e}")))
}
