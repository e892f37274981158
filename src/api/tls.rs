//! The files of `--tls-cert` and `--tls-key`: read with a bound (a path such as `/dev/zero`
//! or a mistaken multi-GB file would otherwise be read until memory runs out), parsed once at
//! start-up, and the certificate's validity period checked so that an expired certificate —
//! which clients that check it refuse — is said in the log instead of starting silently.

use std::path::{Path, PathBuf};

use chrono::{DateTime, NaiveDateTime, SecondsFormat, Utc};
use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer};
use tracing::warn;

use crate::error::{Error, Result};

pub use crate::pem::FILE_LIMIT;

/// The certificate chain and private key files (PEM) the service presents.
#[derive(Debug, Clone)]
pub struct TlsFiles {
    pub cert: PathBuf,
    pub key: PathBuf,
}

/// What the files hold, read once for both listeners.
#[derive(Debug)]
pub struct TlsIdentity {
    pub certs: Vec<CertificateDer<'static>>,
    pub key: PrivateKeyDer<'static>,
}

impl TlsFiles {
    /// Both files, read and parsed. A certificate outside its validity period is a warning,
    /// not an error: clients that pin it (`graybox health`) or skip the check still connect,
    /// and the operator decides; the warning keeps it from going unnoticed.
    pub fn load(&self) -> Result<TlsIdentity> {
        let certs = certificates(&self.cert)?;
        warn_outside_validity(&self.cert, &certs[0]);
        let pem = crate::pem::read_bounded(&self.key, "--tls-key", "tls_key")?;
        let key = PrivateKeyDer::from_pem_slice(&pem).map_err(|e| {
            Error::invalid(
                "tls_key",
                format!("cannot read {}: {e}", self.key.display()),
            )
        })?;
        Ok(TlsIdentity { certs, key })
    }
}

/// The certificate chain in a PEM file (at least one certificate), the leaf first.
pub fn certificates(path: &Path) -> Result<Vec<CertificateDer<'static>>> {
    crate::pem::certificates(path, "--tls-cert", "tls_cert")
}

fn warn_outside_validity(path: &Path, leaf: &CertificateDer<'_>) {
    let now = Utc::now();
    let show = |t: DateTime<Utc>| t.to_rfc3339_opts(SecondsFormat::Secs, true);
    let cert = path.display();
    match validity(leaf) {
        Some((_, not_after)) if not_after < now => warn!(
            "the TLS certificate {cert} expired at {} (notAfter): clients that check it refuse it",
            show(not_after)
        ),
        Some((not_before, _)) if now < not_before => warn!(
            "the TLS certificate {cert} is not valid before {} (notBefore): clients that \
             check it refuse it until then",
            show(not_before)
        ),
        Some(_) => {}
        None => warn!("cannot read the validity period of the TLS certificate {cert}"),
    }
}

/// (notBefore, notAfter) of a DER X.509 certificate, or None when it is not shaped like one.
/// RFC 5280 §4.1: Certificate ::= SEQUENCE { tbsCertificate SEQUENCE { [0] version OPTIONAL,
/// serialNumber, signature, issuer, validity SEQUENCE { notBefore, notAfter }, … }, … }.
/// A walk over five elements instead of an X.509 crate: only the period is needed, and no
/// crate in the build exposes it (rustls-webpki keeps its parsed field private).
pub fn validity(der: &[u8]) -> Option<(DateTime<Utc>, DateTime<Utc>)> {
    const SEQUENCE: u8 = 0x30;
    const VERSION: u8 = 0xa0;
    let (_, cert, _) = element(der).filter(|e| e.0 == SEQUENCE)?;
    let (_, mut tbs, _) = element(cert).filter(|e| e.0 == SEQUENCE)?;
    if tbs.first() == Some(&VERSION) {
        tbs = element(tbs)?.2;
    }
    for _ in 0..3 {
        tbs = element(tbs)?.2; // serialNumber, signature, issuer
    }
    let (_, period, _) = element(tbs).filter(|e| e.0 == SEQUENCE)?;
    let (tag, not_before, rest) = element(period)?;
    let not_before = time(tag, not_before)?;
    let (tag, not_after, _) = element(rest)?;
    Some((not_before, time(tag, not_after)?))
}

/// The DER element at the start of `input`: (tag, contents, what follows). Definite lengths
/// only, as DER requires; single-byte tags are all this walk meets.
fn element(input: &[u8]) -> Option<(u8, &[u8], &[u8])> {
    let (&tag, rest) = input.split_first()?;
    let (&first, rest) = rest.split_first()?;
    let (len, rest) = if first < 0x80 {
        (usize::from(first), rest)
    } else {
        let n = usize::from(first & 0x7f);
        if n == 0 || n > 4 || rest.len() < n {
            return None;
        }
        let (len, rest) = rest.split_at(n);
        (
            len.iter().fold(0usize, |a, &b| a << 8 | usize::from(b)),
            rest,
        )
    };
    (len <= rest.len()).then(|| (tag, &rest[..len], &rest[len..]))
}

/// An X.509 Time: UTCTime (YYMMDDHHMMSSZ; years 50–99 are 19xx, RFC 5280 §4.1.2.5.1) or
/// GeneralizedTime (YYYYMMDDHHMMSSZ, from 2050 on).
fn time(tag: u8, contents: &[u8]) -> Option<DateTime<Utc>> {
    const UTC_TIME: u8 = 0x17;
    const GENERALIZED_TIME: u8 = 0x18;
    let text = std::str::from_utf8(contents)
        .ok()
        .filter(|t| t.is_ascii())?;
    let full = match tag {
        UTC_TIME if text.len() == 13 => {
            let century = if text[..2].parse::<u8>().ok()? >= 50 {
                "19"
            } else {
                "20"
            };
            format!("{century}{text}")
        }
        GENERALIZED_TIME if text.len() == 15 => text.to_string(),
        _ => return None,
    };
    NaiveDateTime::parse_from_str(&full, "%Y%m%d%H%M%SZ")
        .ok()
        .map(|t| t.and_utc())
}
