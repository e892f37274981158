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

/// Accepted connections with Nagle's algorithm off: a controller's small request/response
/// pairs otherwise wait on delayed ACKs (measured: +40 ms on a 1024-state Predict).
fn incoming(
    listener: TcpListener,
) -> impl futures_util::Stream<Item = std::io::Result<tokio::net::TcpStream>> {
    use futures_util::StreamExt;
    TcpListenerStream::new(listener).map(|conn| {
        let conn = conn?;
        conn.set_nodelay(true)?;
        Ok(conn)
    })
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
    // Both reflection versions: grpcurl speaks v1, grpcio-reflection's Python client and
    // older tools only v1alpha.
    let reflection = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(pb::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
    };
    let reflect_err = |e| Error::Storage(format!("reflection: {e}"));
    let reflection_v1 = reflection().build_v1().map_err(reflect_err)?;
    let reflection_v1alpha = reflection().build_v1alpha().map_err(reflect_err)?;
    let limit = app.settings.grpc_max_message_bytes;
    let dynamics = pb::dynamics_server::DynamicsServer::new(dynamics::DynamicsService { app })
        .max_decoding_message_size(limit)
        .max_encoding_message_size(limit);
    tonic::transport::Server::builder()
        .add_service(health)
        .add_service(reflection_v1)
        .add_service(reflection_v1alpha)
        .add_service(dynamics)
        .serve_with_incoming_shutdown(incoming(listener), shutdown)
        .await
        .map_err(|e| Error::Storage(format!("gRPC server failed: {e}")))
}
