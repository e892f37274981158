//! `graybox health`: is the service on this machine ready? A GET of `/readyz` on the REST
//! address the service itself reads (`GRAYBOX_HTTP`), over TLS when `GRAYBOX_TLS_CERT` is set
//! — so a container's health check follows a changed port or TLS without editing. Exit
//! status 0 when ready, 1 otherwise (with the reason on stderr).

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_rustls::TlsConnector;
use tokio_rustls::rustls::client::danger::{
    HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier,
};
use tokio_rustls::rustls::crypto::{self, CryptoProvider};
use tokio_rustls::rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use tokio_rustls::rustls::{self, ClientConfig, DigitallySignedStruct, SignatureScheme};

use crate::api::tls::certificates;
use crate::error::{Error, Result};

#[derive(Args, Debug)]
pub struct HealthArgs {
    /// The service's REST address, as `graybox serve` was given it (0.0.0.0 is asked on
    /// loopback).
    #[arg(long, env = "GRAYBOX_HTTP", default_value = "127.0.0.1:8080")]
    pub http: String,
    /// The service's TLS certificate: when set, the check speaks TLS and accepts exactly this
    /// certificate (pinned; no host-name check, the check talks to its own machine).
    #[arg(long, env = "GRAYBOX_TLS_CERT")]
    pub tls_cert: Option<PathBuf>,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 3.0)]
    pub timeout_secs: f64,
}

pub(super) fn health(a: HealthArgs) -> Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let timeout = Duration::from_secs_f64(a.timeout_secs.max(0.001));
    match rt.block_on(async { tokio::time::timeout(timeout, probe(&a)).await }) {
        Ok(result) => result,
        Err(_) => Err(Error::DeadlineExceeded(format!(
            "no answer from {} within {:.1} s",
            a.http, a.timeout_secs
        ))),
    }?;
    super::say("ready")?;
    Ok(())
}

/// GET /readyz; Ok when the answer is 200.
pub async fn probe(a: &HealthArgs) -> Result<()> {
    let addr = local_address(&a.http)?;
    let tcp = TcpStream::connect(addr).await?;
    let status = match &a.tls_cert {
        None => get_readyz(tcp).await?,
        Some(cert) => {
            let pinned = certificates(cert)?.swap_remove(0);
            let tls = TlsConnector::from(Arc::new(client_config(pinned)?))
                .connect(ServerName::IpAddress(addr.ip().into()), tcp)
                .await
                .map_err(|e| Error::Io(std::io::Error::other(format!("TLS: {e}"))))?;
            get_readyz(tls).await?
        }
    };
    if status == "200" {
        Ok(())
    } else {
        Err(Error::FailedPrecondition(format!(
            "{} answered /readyz with status {status}: not ready",
            a.http
        )))
    }
}

/// The address to dial for a listen address: an unspecified IP (0.0.0.0, ::) is loopback.
fn local_address(http: &str) -> Result<SocketAddr> {
    let mut addr: SocketAddr = http.parse().map_err(|_| {
        Error::invalid(
            "http",
            format!("'{http}' is not an address such as 127.0.0.1:8080"),
        )
    })?;
    if addr.ip().is_unspecified() {
        addr.set_ip(match addr.ip() {
            IpAddr::V4(_) => IpAddr::V4(Ipv4Addr::LOCALHOST),
            IpAddr::V6(_) => IpAddr::V6(Ipv6Addr::LOCALHOST),
        });
    }
    Ok(addr)
}

/// The status code of `GET /readyz` on an open connection.
async fn get_readyz<S: AsyncRead + AsyncWrite + Unpin>(mut s: S) -> Result<String> {
    s.write_all(b"GET /readyz HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")
        .await?;
    let mut head = [0u8; 64];
    let mut len = 0;
    while len < 12 {
        let k = s.read(&mut head[len..]).await?;
        if k == 0 {
            break;
        }
        len += k;
    }
    let text = String::from_utf8_lossy(&head[..len]);
    // "HTTP/1.1 200 OK"
    text.split_whitespace()
        .nth(1)
        .filter(|_| text.starts_with("HTTP/"))
        .map(str::to_string)
        .ok_or_else(|| Error::Io(std::io::Error::other("the answer is not HTTP")))
}

fn client_config(pinned: CertificateDer<'static>) -> Result<ClientConfig> {
    let provider = Arc::new(crypto::ring::default_provider());
    Ok(ClientConfig::builder_with_provider(provider.clone())
        .with_safe_default_protocol_versions()
        .map_err(|e| Error::Internal(format!("TLS setup: {e}")))?
        .dangerous()
        .with_custom_certificate_verifier(Arc::new(Pinned { pinned, provider }))
        .with_no_client_auth())
}

/// Accepts the server only if it presents the configured certificate (and proves it holds
/// its key: the handshake signatures are verified as usual).
#[derive(Debug)]
struct Pinned {
    pinned: CertificateDer<'static>,
    provider: Arc<CryptoProvider>,
}

impl ServerCertVerifier for Pinned {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp_response: &[u8],
        _now: UnixTime,
    ) -> std::result::Result<ServerCertVerified, rustls::Error> {
        if end_entity.as_ref() == self.pinned.as_ref() {
            Ok(ServerCertVerified::assertion())
        } else {
            Err(rustls::Error::General(
                "the server's certificate is not the one in GRAYBOX_TLS_CERT".into(),
            ))
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> std::result::Result<HandshakeSignatureValid, rustls::Error> {
        crypto::verify_tls12_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> std::result::Result<HandshakeSignatureValid, rustls::Error> {
        crypto::verify_tls13_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.provider
            .signature_verification_algorithms
            .supported_schemes()
    }
}
