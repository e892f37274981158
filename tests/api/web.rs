//! The dashboard's files: served at `/` and `/ui/…` with their content types and without a
//! token even when reads need one (the page must load to ask for it), while the API it reads
//! (the event stream too) keeps needing the token.

use graybox::app::settings::Settings;

use crate::helpers::*;

#[tokio::test]
async fn the_page_loads_without_a_token_and_the_api_still_needs_one() {
    let app = spawn_configured(Settings {
        api_token: Some("s3cret".into()),
        auth_reads: true,
        ..test_settings()
    })
    .await;
    for (path, content_type, holds) in [
        ("/", "text/html", "<script src=\"/ui/app.js\">"),
        ("/ui/app.js", "text/javascript", "/v1/events"),
        ("/ui/forms.js", "text/javascript", "/v1/jobs"),
        ("/ui/jobs.js", "text/javascript", "/v1/jobs"),
        ("/ui/models.js", "text/javascript", "/v1/models"),
        ("/ui/defaults.js", "text/javascript", "GRAYBOX_DEFAULTS"),
        ("/ui/style.css", "text/css", "--accent"),
        ("/ui/uPlot.iife.min.js", "text/javascript", "uPlot"),
        ("/ui/uPlot.min.css", "text/css", ".uplot"),
        ("/favicon.ico", "image/svg+xml", "<svg"),
    ] {
        let r = app.client.get(app.url(path)).send().await.unwrap();
        assert_eq!(r.status().as_u16(), 200, "{path}");
        let ct = r.headers()["content-type"].to_str().unwrap().to_string();
        assert!(ct.starts_with(content_type), "{path}: {ct}");
        assert!(r.text().await.unwrap().contains(holds), "{path}");
    }
    for path in ["/v1/jobs", "/v1/events", "/v1/datasets/ds_x/trajectories"] {
        let r = app.client.get(app.url(path)).send().await.unwrap();
        assert_eq!(r.status().as_u16(), 401, "{path}");
    }
    let r = app
        .client
        .get(app.url("/v1/jobs"))
        .header("Authorization", "Bearer s3cret")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 200);
    // Where the page's files are is where a person may look for the page: sent to it.
    let no_follow = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    for path in ["/ui", "/ui/"] {
        let r = no_follow.get(app.url(path)).send().await.unwrap();
        assert_eq!(r.status().as_u16(), 308, "{path}");
        assert_eq!(r.headers()["location"], "/", "{path}");
    }
    // Not a way around the token: only the page's own files are open.
    let r = app
        .client
        .get(app.url("/ui/../v1/jobs"))
        .send()
        .await
        .unwrap();
    assert_ne!(r.status().as_u16(), 200);
    app.stop().await;
}

/// Every answer of the REST port carries the page's policy and the two headers that keep a
/// browser from sniffing or framing it: the page and its files, the API, and the errors of
/// the layers in front of the handlers (401) and of the router (404).
#[tokio::test]
async fn every_answer_carries_the_security_headers() {
    let app = spawn_configured(Settings {
        api_token: Some("s3cret".into()),
        ..test_settings()
    })
    .await;
    let policy = graybox::api::web::CONTENT_SECURITY_POLICY;
    assert!(policy.contains("default-src 'self'") && policy.contains("frame-ancestors 'none'"));
    for (method, path, status) in [
        ("GET", "/", 200),
        ("GET", "/ui/app.js", 200),
        ("GET", "/v1/jobs", 200),
        ("GET", "/healthz", 200),
        ("POST", "/v1/jobs", 401),
        ("GET", "/v2/nothing", 404),
    ] {
        let req = match method {
            "POST" => app.client.post(app.url(path)).body("{}"),
            _ => app.client.get(app.url(path)),
        };
        let r = req.send().await.unwrap();
        assert_eq!(r.status().as_u16(), status, "{method} {path}");
        let h = r.headers();
        assert_eq!(h["content-security-policy"], policy, "{method} {path}");
        assert_eq!(h["x-content-type-options"], "nosniff", "{method} {path}");
        assert_eq!(h["x-frame-options"], "DENY", "{method} {path}");
    }
    app.stop().await;
}

/// The new-job form starts from the service's own defaults: the script it reads holds every
/// training field at `TrainConfig::default()` (the fields files leave out at their default
/// included), the paper's model names and the built-in templates.
#[tokio::test]
async fn the_job_form_starts_from_the_services_defaults() {
    use graybox::train::TrainConfig;
    let app = spawn_configured(test_settings()).await;
    let r = app
        .client
        .get(app.url("/ui/defaults.js"))
        .send()
        .await
        .unwrap();
    let text = r.text().await.unwrap();
    let json = text
        .split("const GRAYBOX_DEFAULTS = ")
        .nth(1)
        .and_then(|t| t.trim().strip_suffix(';'))
        .expect("one assignment");
    let d: serde_json::Value = serde_json::from_str(json).unwrap();
    let training: TrainConfig = serde_json::from_value(d["training"].clone()).unwrap();
    assert_eq!(training, TrainConfig::default());
    for field in [
        "horizon",
        "discount",
        "one_step_epochs",
        "window_lr",
        "patience",
        "epochs",
    ] {
        assert!(d["training"].get(field).is_some(), "{field} missing: {d}");
    }
    assert!(
        d["models"].as_array().unwrap().iter().any(|m| m == "MVF"),
        "{d}"
    );
    assert_eq!(
        d["templates"],
        serde_json::json!(["double_pendulum", "pendulum", "cartpole", "planar_body"])
    );
}

/// `graybox serve` says where the dashboard is as it starts, and that address serves it.
#[test]
fn serve_prints_the_dashboards_address() {
    let dir = tempfile::tempdir().unwrap();
    let db = crate::processes::fresh_db(dir.path());
    let mut server = crate::processes::Server::start(&db, 0);
    let line = (server.proc.logs().iter())
        .find(|l| l.starts_with("graybox: REST on "))
        .cloned()
        .unwrap();
    let url = line.rsplit("dashboard: ").next().unwrap();
    assert_eq!(url, format!("{}/", server.base), "{line}");
    let page = String::from_utf8(server.bytes(url)).unwrap();
    assert!(page.contains("<script src=\"/ui/app.js\">"), "{page}");
    server.sigterm();
}
