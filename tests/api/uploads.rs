//! Request bodies in flight share one memory budget: an upload past it gets 503 with
//! `Retry-After` before its body is read; one over its kind's limit gets 413 from its
//! declared length; a finished upload gives its share back.

use graybox::app::uploads::BodyKind;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;

use crate::helpers::*;

/// A `len`-byte dataset upload of spaces (a 400 once read), sent until `done` says its status
/// is the one awaited (for up to 2 s); that response.
async fn upload_until(
    app: &TestApp,
    len: usize,
    done: impl Fn(u16) -> bool,
) -> Option<reqwest::Response> {
    for _ in 0..100 {
        let r = app
            .client
            .post(app.url("/v1/datasets"))
            .header("content-type", "application/json")
            .body(vec![b' '; len])
            .send()
            .await
            .unwrap();
        if done(r.status().as_u16()) {
            return Some(r);
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    None
}

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
        max_inflight_body_mb: 60,
        ..test_settings()
    };
    let budget = settings.max_inflight_body_bytes();
    let dataset = 4 << 20;
    // Two 4 MB datasets reserve 80 MB of the 60: the second does not fit beside the first.
    assert!(
        2 * BodyKind::Dataset.cost(dataset) > budget && BodyKind::Dataset.cost(dataset) < budget
    );
    let app = spawn_configured(settings).await;
    let held = stalled_upload(&app, "/v1/datasets", dataset).await;
    // The stalled upload is admitted once the server reads its head: a second one is
    // refused from then on.
    let refused = upload_until(&app, dataset, |status| status == 503).await;
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
    let r = upload_until(&app, dataset, |status| status != 503).await;
    let status = r.expect("the budget comes back").status();
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
        err.contains("max-inflight-body-mb") && err.contains("1000"),
        "{err}"
    );
}

/// A list page ends at its byte limit before its count: three templates with ~3.5 MB
/// summaries (60 000 parameters each) come two to the first page of ten, with a token for
/// the third.
#[tokio::test]
async fn list_pages_end_at_their_byte_limit() {
    let app = spawn_app(0).await;
    for k in 0..3 {
        let parameters: serde_json::Map<String, serde_json::Value> = (0..60_000)
            .map(|i| (format!("p{k}_{i}"), serde_json::json!({"value": 1.0})))
            .collect();
        let doc = serde_json::json!({
            "kind": "formula", "name": format!("many{k}"), "coordinates": ["x"],
            "parameters": parameters, "mass": [["1"]], "potential": "0", "forces": ["0"],
        });
        let (status, body) = app.post("/v1/templates", &doc).await;
        assert_eq!(
            status,
            201,
            "{}",
            &body.to_string()[..200.min(body.to_string().len())]
        );
    }
    let (status, page) = app.get("/v1/templates?page_size=10").await;
    assert_eq!(status, 200);
    assert_eq!(page["items"].as_array().unwrap().len(), 2);
    let token = page["next_page_token"]
        .as_str()
        .expect("a token for the rest");
    let (_, rest) = app
        .get(&format!("/v1/templates?page_size=10&page_token={token}"))
        .await;
    assert_eq!(rest["items"].as_array().unwrap().len(), 1);
    assert!(
        rest["next_page_token"].is_null(),
        "{}",
        rest["next_page_token"]
    );
}

/// A chunked body (no declared length) of `len` bytes of spaces sent to `path`; the status
/// the server answers with. The server may answer and close before the body is all sent, so
/// write errors end the sending, not the test.
async fn chunked_status(app: &TestApp, path: &str, len: usize) -> u16 {
    use tokio::io::AsyncReadExt;
    let addr = app.running.as_ref().unwrap().http_addr;
    let mut s = TcpStream::connect(addr).await.unwrap();
    let head = format!(
        "POST {path} HTTP/1.1\r\nhost: x\r\ncontent-type: application/json\r\n\
         transfer-encoding: chunked\r\nconnection: close\r\n\r\n"
    );
    s.write_all(head.as_bytes()).await.unwrap();
    let chunk = vec![b' '; 16 << 10];
    let mut left = len;
    while left > 0 {
        let part = &chunk[..left.min(chunk.len())];
        let framed = [format!("{:x}\r\n", part.len()).as_bytes(), part, b"\r\n"].concat();
        if s.write_all(&framed).await.is_err() {
            break;
        }
        left -= part.len();
    }
    let _ = s.write_all(b"0\r\n\r\n").await;
    let mut answer = Vec::new();
    let _ = s.read_to_end(&mut answer).await;
    let answer = String::from_utf8_lossy(&answer);
    let status = answer.split(' ').nth(1).unwrap_or_default();
    status
        .parse()
        .unwrap_or_else(|_| panic!("{path}: no status in {answer:?}"))
}

/// Every route that reads a body cuts it off at its own limit whatever the transfer encoding:
/// a chunked body one byte over is 413, and one at the limit is read. The small routes under
/// the model upload's path once read chunked bodies up to the upload's 64 MiB while the
/// in-flight budget held 64 KiB for them (40 at once took the server past 2 GB).
#[tokio::test]
async fn chunked_bodies_stop_at_each_routes_limit() {
    let settings = graybox::app::Settings {
        max_body_mb: 2,
        max_model_mb: 3,
        max_template_mb: 1,
        ..test_settings()
    };
    let app = spawn_configured(settings.clone()).await;
    let routes = [
        ("/v1/datasets", 2 << 20),
        ("/v1/models", 3 << 20),
        ("/v1/templates", 1 << 20),
        ("/v1/jobs", 1 << 20),
        ("/v1/models/m/evaluate", 64 << 10),
        ("/v1/models/m/energy", 64 << 10),
        ("/v1/models/m/energy-report", 64 << 10),
    ];
    for (path, limit) in routes {
        let kind = BodyKind::of("POST", path).unwrap();
        assert_eq!(kind.limit(&settings), limit, "{path}");
        assert_eq!(chunked_status(&app, path, limit + 1).await, 413, "{path}");
        // At the limit the body is read: the handler answers for what it holds (spaces are
        // not a document), not for its size.
        let at_limit = chunked_status(&app, path, limit).await;
        assert!(![413, 503].contains(&at_limit), "{path}: {at_limit}");
    }
}
