//! Certificate files read with a bound: a path such as `/dev/zero` or a mistaken multi-GB file
//! would otherwise be read until memory runs out. The service's own TLS files (`api/tls.rs`)
//! and the CA certificates it checks PostgreSQL's certificate against (`store/postgres.rs`)
//! are read here.

use std::io::Read;
use std::path::Path;

use rustls_pki_types::CertificateDer;
use rustls_pki_types::pem::PemObject;

use crate::error::{Error, Result};

/// The most a certificate or key file may hold: a PEM chain of a dozen 4096-bit certificates
/// is ~25 KB.
pub const FILE_LIMIT: u64 = 1 << 20;

/// A whole file of at most [`FILE_LIMIT`] bytes; one byte more is read to tell a file at the
/// limit from a larger one without reading the rest. Errors name `flag` (where the path came
/// from) and the request `field`.
pub fn read_bounded(path: &Path, flag: &str, field: &str) -> Result<Vec<u8>> {
    let cannot = |e: std::io::Error| {
        Error::invalid(
            field,
            format!("cannot read {} ({flag}): {e}", path.display()),
        )
    };
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .map_err(cannot)?
        .take(FILE_LIMIT + 1)
        .read_to_end(&mut bytes)
        .map_err(cannot)?;
    if bytes.len() as u64 > FILE_LIMIT {
        return Err(Error::invalid(
            field,
            format!(
                "{} is larger than the limit of 1 MiB ({FILE_LIMIT} bytes) for {flag}",
                path.display()
            ),
        ));
    }
    Ok(bytes)
}

/// The certificates of a PEM file (at least one), read as [`read_bounded`] does.
pub fn certificates(path: &Path, flag: &str, field: &str) -> Result<Vec<CertificateDer<'static>>> {
    parse_certificates(&read_bounded(path, flag, field)?, path, flag, field)
}

/// The certificates in `pem`, the contents of `path` (at least one).
pub fn parse_certificates(
    pem: &[u8],
    path: &Path,
    flag: &str,
    field: &str,
) -> Result<Vec<CertificateDer<'static>>> {
    let certs = CertificateDer::pem_slice_iter(pem)
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(|e| {
            Error::invalid(
                field,
                format!("cannot read {} ({flag}): {e}", path.display()),
            )
        })?;
    if certs.is_empty() {
        return Err(Error::invalid(
            field,
            format!("{} ({flag}) has no PEM certificate", path.display()),
        ));
    }
    Ok(certs)
}
