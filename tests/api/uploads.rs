//! Request bodies in flight share one memory budget: an upload past it gets 503 with
//! `Retry-After` before its body is read; one over its kind's limit gets 413 from its
//! declared length; a finished upload gives its share back.

use graybox::app::uploads::BodyKind;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;

use crate::helpers::*;

/// An upload that declares `len` bytes and sends only its first few: it holds its share of
/// the budget until the connection closes.
async fn stalled_upload(app: &TestApp, path: &str, len: usize) -> TcpStream {
    let addr = app.running.as_ref().unwrap().http_addr;
    let mut s = TcpStream::connect(addr).await.unwrap();
    let head = format!(
        "POST {path} HTTP/1.1\r\nhost: x\r\ncontent-type: application/json\r\n\
         content-length: {len}\r\n\r\n{{\"q\": ["
    );
    s.write_all(head.as_bytes()).await.unwrap();
    s.flush().await.unwrap();
    s
}

#[tokio::test]
async fn bodies_past_the_budget_are_refused_before_they_are_read() {
    let settings = graybox::app::Settings {
        max_body_mb: 4,
        max_model_mb: 4,
        max_template_mb: 1,
        max_inflight_body_mb: 40,
        ..test_settings()
    };
    let budget = settings.max_inflight_body_bytes();
    let dataset = 4 << 20;
    // Two 4 MB datasets reserve 48 MB of the 40: the second does not fit beside the first.
    assert!(
        2 * BodyKind::Dataset.cost(dataset) > budget && BodyKind::Dataset.cost(dataset) < budget
    );
    let app = spawn_configured(settings).await;
    let held = stalled_upload(&app, "/v1/datasets", dataset).await;
    // The stalled upload is admitted once the server reads its head: wait until a second
    // one is refused.
    let mut refused = None;
    for _ in 0..100 {
        let r = app
            .client
            .post(app.url("/v1/datasets"))
            .header("content-type", "application/json")
            .body(vec![b' '; dataset])
            .send()
            .await
            .unwrap();
        if r.status() == 503 {
            refused = Some(r);
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    let r = refused.expect("a second upload past the budget is refused");
    assert!(r.headers().get("retry-after").is_some(), "{r:?}");
    let body: serde_json::Value = r.json().await.unwrap();
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("--max-inflight-body-mb"),
        "{body}"
    );
    // Small requests and reads are not held up by uploads.
    let (status, _) = app.get("/v1/datasets").await;
    assert_eq!(status, 200);

    // Over the kind's limit by its declared length: 413 naming the limit, nothing reserved.
    let r = app
        .client
        .post(app.url("/v1/templates"))
        .body(vec![b' '; (1 << 20) + 1])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 413);

    // The stalled upload goes away: its share comes back and the next upload is read (a
    // 400 for its malformed body, not a 503).
    drop(held);
    let mut status = 503;
    for _ in 0..100 {
        let r = app
            .client
            .post(app.url("/v1/datasets"))
            .header("content-type", "application/json")
            .body(vec![b' '; dataset])
            .send()
            .await
            .unwrap();
        status = r.status().as_u16();
        if status != 503 {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    assert_eq!(status, 400);
}

#[test]
fn a_budget_smaller_than_one_body_is_refused_at_start() {
    let settings = graybox::app::Settings {
        max_body_mb: 100,
        max_inflight_body_mb: 200,
        ..graybox::app::Settings::default()
    };
    let err = settings.validate().unwrap_err().to_string();
    assert!(
        err.contains("max-inflight-body-mb") && err.contains("600"),
        "{err}"
    );
}
