//! TLS to PostgreSQL as a URL asks for it (`sslmode`, `sslrootcert`), against the throwaway
//! cluster `scripts/services.sh` starts with `ssl=on` and a certificate made for the run
//! (signed by the CA of `GRAYBOX_TEST_POSTGRES_CA`, for the host `localhost` only). On SQLite
//! (no `GRAYBOX_TEST_POSTGRES_CA`) there is no cluster to talk to, and the tests return.

use graybox::store::Store;
use sqlx::Connection;

use crate::processes::Proc;

/// The cluster's URL and CA files, when the run has them.
fn cluster() -> Option<(String, String, String)> {
    let env = |k: &str| std::env::var(k).ok();
    Some((
        env("GRAYBOX_TEST_POSTGRES")?,
        env("GRAYBOX_TEST_POSTGRES_CA")?,
        env("GRAYBOX_TEST_POSTGRES_WRONG_CA")?,
    ))
}

/// A new database on the cluster: its name, and the URL of the server at `host`.
async fn database(server: &str, host: &str) -> (String, String) {
    let url = crate::helpers::fresh_db(std::path::Path::new("unused")).await;
    let name = url.rsplit('/').next().unwrap().to_string();
    (
        name.clone(),
        format!("{}/{name}", server.replace("127.0.0.1", host)),
    )
}

/// How many of the database's open connections use TLS, and how many do not.
async fn connections(server: &str, name: &str) -> (i64, i64) {
    let mut admin = sqlx::PgConnection::connect(&format!("{server}/postgres?sslmode=disable"))
        .await
        .unwrap();
    sqlx::query_as(
        "SELECT count(*) FILTER (WHERE s.ssl), count(*) FILTER (WHERE NOT s.ssl)
         FROM pg_stat_activity a JOIN pg_stat_ssl s USING (pid) WHERE a.datname = $1",
    )
    .bind(name)
    .fetch_one(&mut admin)
    .await
    .unwrap()
}

#[tokio::test]
async fn tls_as_the_url_asks_for_it() {
    let Some((server, ca, _)) = cluster() else {
        return;
    };
    // require: encrypted, the certificate not checked (the host 127.0.0.1 is not in it).
    // verify-ca: checked against the CA, the host name not. verify-full via `localhost`, the
    // name the certificate is for: both checked.
    for (mode, host) in [
        ("require", "127.0.0.1"),
        ("verify-ca", "127.0.0.1"),
        ("verify-full", "localhost"),
    ] {
        let (name, url) = database(&server, host).await;
        let url = format!("{url}?sslmode={mode}&sslrootcert={ca}");
        let store = Store::open(&url)
            .await
            .unwrap_or_else(|e| panic!("{mode}: {e}"));
        store.ping().await.unwrap();
        let (tls, plain) = connections(&server, &name).await;
        assert!(
            tls >= 1 && plain == 0,
            "{mode}: {tls} over TLS, {plain} not"
        );
        drop(store);
    }
    // disable: no TLS even though the server offers it.
    let (name, url) = database(&server, "127.0.0.1").await;
    let store = Store::open(&format!("{url}?sslmode=disable"))
        .await
        .unwrap();
    let (tls, plain) = connections(&server, &name).await;
    assert!(
        tls == 0 && plain >= 1,
        "disable: {tls} over TLS, {plain} not"
    );
    drop(store);
}

/// Why opening `url` fails (it must).
async fn refused(url: &str) -> String {
    match Store::open(url).await {
        Ok(_) => panic!("{url} opened"),
        Err(e) => e.to_string(),
    }
}

#[tokio::test]
async fn a_certificate_the_url_does_not_trust_is_refused_saying_why() {
    let Some((server, ca, wrong)) = cluster() else {
        return;
    };
    let (_, at_ip) = database(&server, "127.0.0.1").await;
    let (_, at_name) = database(&server, "localhost").await;
    let untrusted = [
        // Signed by another CA.
        format!("{at_name}?sslmode=verify-full&sslrootcert={wrong}"),
        format!("{at_ip}?sslmode=verify-ca&sslrootcert={wrong}"),
        // The right CA, but the certificate does not name 127.0.0.1.
        format!("{at_ip}?sslmode=verify-full&sslrootcert={ca}"),
    ];
    for url in untrusted {
        let err = refused(&url).await;
        assert!(
            err.contains("cannot connect to") && err.contains("verify-full also"),
            "{url}: {err}"
        );
        assert!(
            err.contains("UnknownIssuer") || err.contains("not valid for name"),
            "{url}: the reason rustls gave: {err}"
        );
    }
    // A CA file that is not there, or holds no certificate: named before any connection.
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.pem");
    std::fs::write(&empty, "not a certificate\n").unwrap();
    for (file, says) in [
        ("/no/such/ca.pem", "cannot read"),
        (empty.to_str().unwrap(), "has no PEM certificate"),
    ] {
        let url = format!("{at_name}?sslmode=verify-full&sslrootcert={file}");
        let err = refused(&url).await;
        assert!(
            err.contains(file) && err.contains(says) && err.contains("sslrootcert"),
            "{err}"
        );
    }
}

/// The user's case: the service's processes start on a URL with `sslmode=require`.
#[test]
fn a_worker_starts_on_a_url_that_requires_tls() {
    let Some((server, _, _)) = cluster() else {
        return;
    };
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let (name, url) = rt.block_on(database(&server, "127.0.0.1"));
    let worker = Proc::worker(&format!("{url}?sslmode=require")).ready_worker();
    let (tls, plain) = rt.block_on(connections(&server, &name));
    assert!(tls >= 1 && plain == 0, "{tls} over TLS, {plain} not");
    worker.sigterm();
}
