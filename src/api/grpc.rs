//! The gRPC listener. It serves grpc.health.v1 now; the Dynamics service joins it with the
//! gRPC issue.

use std::net::SocketAddr;

use tokio::net::TcpListener;
use tokio_stream::wrappers::TcpListenerStream;

use crate::error::Result;

/// Serves gRPC on `listener` until `shutdown` resolves.
pub async fn serve(
    listener: TcpListener,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<()> {
    let (reporter, health) = tonic_health::server::health_reporter();
    reporter
        .set_service_status("", tonic_health::ServingStatus::Serving)
        .await;
    tonic::transport::Server::builder()
        .add_service(health)
        .serve_with_incoming_shutdown(TcpListenerStream::new(listener), shutdown)
        .await
        .map_err(|e| crate::error::Error::Storage(format!("gRPC server failed: {e}")))
}

pub fn describe(addr: SocketAddr) -> String {
    format!("grpc://{addr}")
}
