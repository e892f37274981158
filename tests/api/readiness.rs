//! Probes during faults: `/readyz` and `/metrics` answer within a couple of seconds while the
//! database hangs (through the tests' fault proxy), and a store that lost its readiness marker
//! gets it back instead of staying unready until a restart.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use crate::faults::{FaultProxy, Mode};
use crate::helpers::{TestApp, fresh_db, spawn_configured, spawn_on, test_settings};

/// Far beyond the probes' own bounds (2 s for readiness, 1 s for the job counts), far below
/// the 30 s a probe took when it waited for the database's pool.
const ANSWERED_WITHIN: Duration = Duration::from_secs(10);

async fn probe(app: &TestApp, path: &str) -> (u16, String) {
    let r = (app.client.get(app.url(path)))
        .timeout(ANSWERED_WITHIN)
        .send()
        .await
        .unwrap_or_else(|e| panic!("{path} did not answer within {ANSWERED_WITHIN:?}: {e}"));
    (r.status().as_u16(), r.text().await.unwrap())
}

/// The value of the sample named `series` in exposition text.
fn sample(text: &str, series: &str) -> Option<f64> {
    (text.lines()).find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

#[tokio::test(flavor = "multi_thread")]
async fn probes_answer_while_the_database_hangs() {
    if std::env::var("GRAYBOX_TEST_POSTGRES").is_err() {
        return; // SQLite is a file: nothing between the service and it can hang.
    }
    let dir = tempfile::tempdir().unwrap();
    let db = fresh_db(dir.path()).await;
    let (head, rest) = db.rsplit_once(':').unwrap();
    let (port, name) = rest.split_once('/').unwrap();
    let upstream: SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
    let proxy = FaultProxy::start(upstream).await;
    let proxied = format!("{head}:{}/{name}", proxy.addr.port());
    let mut settings = test_settings();
    settings.worker.workers = 0;
    let app = spawn_on(proxied, settings, dir).await;
    assert_eq!(probe(&app, "/readyz").await.0, 200);
    let (_, text) = probe(&app, "/metrics").await;
    assert_eq!(
        sample(&text, "graybox_jobs{state=\"queued\"}"),
        Some(0.0),
        "{text}"
    );

    proxy.set(Mode::Hang);
    let (status, body) = probe(&app, "/readyz").await;
    assert_eq!(status, 503, "{body}");
    assert!(body.contains("database"), "{body}");
    let (status, text) = probe(&app, "/metrics").await;
    assert_eq!(status, 200, "{text}");
    // The last counts read, with their age.
    assert_eq!(
        sample(&text, "graybox_jobs{state=\"queued\"}"),
        Some(0.0),
        "{text}"
    );
    let age = sample(&text, "graybox_jobs_age_seconds").unwrap();
    assert!(age.is_finite() && age > 0.0, "{text}");

    proxy.set(Mode::Pass);
    let t0 = Instant::now();
    while probe(&app, "/readyz").await.0 != 200 {
        assert!(t0.elapsed() < Duration::from_secs(60), "never ready again");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    app.stop().await;
}

#[tokio::test]
async fn a_store_that_lost_its_marker_gets_it_back_and_stays_ready() {
    let blobs = tempfile::tempdir().unwrap();
    let mut settings = test_settings();
    settings.worker.workers = 0;
    settings.worker.blobs = Some(format!("file://{}", blobs.path().display()));
    let app = spawn_configured(settings).await;
    let marker = blobs.path().join("graybox").join("ready");
    assert!(marker.exists());
    std::fs::remove_file(&marker).unwrap();
    let (status, body) = probe(&app, "/readyz").await;
    assert_eq!(status, 200, "{body}");
    assert!(marker.exists(), "the marker was written anew");
    app.stop().await;
}
