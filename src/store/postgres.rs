//! Opening a PostgreSQL database: its URL's TLS settings honoured (`sslmode`, `sslrootcert`)
//! and a failed connection explained, then the pool and the migrations.

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use sqlx::Connection;
use sqlx::postgres::{PgConnectOptions, PgPoolOptions};

use super::dialect::Db;
use super::redacted;
use crate::error::{Error, Result};

/// The query keys sqlx reads a CA file from (`sslrootcert` is libpq's name).
const ROOT_CERT_KEYS: [&str; 3] = ["sslrootcert", "ssl-root-cert", "ssl-ca"];

/// Several processes may start at once on an empty database: sqlx's migrator holds a
/// Postgres advisory lock while it migrates, so the others wait and find it done.
pub(super) async fn open(url: &str) -> Result<Db> {
    let opts = options(url)?;
    // One connection first: the pool's own attempts would end in "pool timed out" 30 s
    // later, without the reason (refused, authentication, TLS, no such database).
    let first = sqlx::PgConnection::connect_with(&opts)
        .await
        .map_err(|e| Error::Storage(connect_error(url, &e)))?;
    first.close().await?;
    let pool = PgPoolOptions::new()
        .max_connections(8)
        .acquire_timeout(Duration::from_secs(30))
        .connect_with(opts)
        .await?;
    sqlx::migrate!("./migrations/postgres").run(&pool).await?;
    Ok(Db::Postgres(pool))
}

/// The URL's options, with the CA file of `sslrootcert` (or `PGSSLROOTCERT`) read here, with
/// a bound and its certificates checked, so that a wrong path stops the start-up naming it
/// instead of failing each connection with a bare "No such file".
fn options(url: &str) -> Result<PgConnectOptions> {
    let opts = PgConnectOptions::from_str(url)
        .map_err(|e| Error::invalid("db", format!("not a usable PostgreSQL URL: {e}")))?;
    let from_url = url.split_once('?').and_then(|(_, query)| {
        form_urlencoded::parse(query.as_bytes())
            .find(|(k, _)| ROOT_CERT_KEYS.contains(&k.as_ref()))
            .map(|(_, v)| (v.into_owned(), "sslrootcert in --db"))
    });
    let from_env = || {
        std::env::var("PGSSLROOTCERT")
            .ok()
            .map(|v| (v, "PGSSLROOTCERT"))
    };
    let Some((path, source)) = from_url.or_else(from_env) else {
        return Ok(opts);
    };
    let path = Path::new(&path);
    let pem = crate::pem::read_bounded(path, source, "db")?;
    crate::pem::parse_certificates(&pem, path, source, "db")?;
    Ok(opts.ssl_root_cert_from_pem(pem))
}

/// Why connecting to PostgreSQL at `url` failed, and for a TLS failure what the URL's
/// `sslmode` asks for: a refused certificate is a setting to change, not an outage.
fn connect_error(url: &str, e: &sqlx::Error) -> String {
    let head = format!("cannot connect to {}: {e}", redacted(url));
    // rustls's refusal of a certificate reaches sqlx as an I/O error of the handshake.
    let tls = match e {
        sqlx::Error::Tls(_) => true,
        sqlx::Error::Io(io) => io
            .get_ref()
            .is_some_and(|inner| inner.is::<tokio_rustls::rustls::Error>()),
        _ => false,
    };
    if !tls {
        return head;
    }
    format!(
        "{head} (TLS: sslmode=require encrypts without checking the server's certificate; \
         verify-ca checks it against the CA certificates of sslrootcert=FILE (PEM; without it, \
         the system's trust store), verify-full also that it names the URL's host; \
         sslmode=disable does not use TLS)"
    )
}
