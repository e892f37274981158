//! Uploaded model files are the models their specs describe and within the service's
//! limits: a network whose weights are not the spec's widths, or a model over
//! `--max-model-params`, is a 422 and is not stored; a file as training wrote it is taken. A
//! file proves it is whole: an edited one is a 422 naming `checksum` or `members`.

use graybox::app::Settings;
use serde_json::{Value, json};

use crate::helpers::*;

async fn post_file(app: &TestApp, file: &Value) -> (u16, Value) {
    let r = app
        .client
        .post(app.url("/v1/models"))
        .body(serde_json::to_vec(file).unwrap())
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    (status, r.json().await.unwrap_or(Value::Null))
}

/// A 422 whose message holds every one of `words`.
fn refused(status: u16, body: &Value, words: &[&str]) {
    assert_eq!(status, 422, "{body}");
    let message = body["error"]["message"].as_str().unwrap();
    for w in words {
        assert!(message.contains(w), "'{w}' not in: {message}");
    }
}

/// The stored models' ids.
async fn listed(app: &TestApp) -> Vec<String> {
    let (status, list) = app.get("/v1/models").await;
    assert_eq!(status, 200, "{list}");
    list["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["id"].as_str().unwrap().to_string())
        .collect()
}

/// An MVF model of the double pendulum as training wrote it (hidden widths 32, 32, 32), with
/// the checksum the worker writes.
async fn mvf_file(app: &TestApp) -> (String, Value) {
    let id = trained(app, "MVF").await;
    let file: Value = serde_json::from_slice(&app.model_file(&id).await).unwrap();
    assert!(file["checksum"].is_string(), "{}", file["checksum"]);
    (id, file)
}

/// The file without its checksum, as a file from before checksums is: the checks of what it
/// holds are all that stand between such a file and serving (an edit of a file that has one
/// is refused on its checksum first).
fn unchecked(mut file: Value) -> Value {
    file.as_object_mut().unwrap().remove("checksum");
    file
}

/// The file's arrays whose names start with `prefix`.
fn arrays<'a>(file: &'a mut Value, prefix: &str) -> Vec<&'a mut Value> {
    file["params"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .filter(|a| a["name"].as_str().unwrap().starts_with(prefix))
        .collect()
}

/// Specs that say other widths than the weights have (the issue's: hidden 16 × 4096 over
/// weights of 32s), a layer more than the file has, or a weight whose shape is not two
/// numbers: each a 422 naming the network and the shapes, nothing stored. Before, the first
/// two were stored and listed with the spec's widths, the third was a panic (500).
#[tokio::test]
async fn weights_unlike_their_spec_are_refused() {
    let app = spawn_app(1).await;
    let (id, file) = mvf_file(&app).await;
    let file = unchecked(file);
    let before = listed(&app).await;
    assert_eq!(before, [id]);

    let mut wider = file.clone();
    wider["config"]["spec"]["mass"]["hidden"] = json!([16, 4096]);
    let (status, body) = post_file(&app, &wider).await;
    refused(status, &body, &["mass_net", "layers where the spec has 3"]);

    let mut narrower = file.clone();
    narrower["config"]["spec"]["potential"]["hidden"] = json!([32, 16, 32]);
    let (status, body) = post_file(&app, &narrower).await;
    refused(
        status,
        &body,
        &["potential_net", "layer 1's weight is 32×32, expected 32×16"],
    );

    let mut deeper = file.clone();
    deeper["config"]["spec"]["forces"]["hidden"] = json!([32, 32, 32, 32]);
    let (status, body) = post_file(&app, &deeper).await;
    refused(
        status,
        &body,
        &["force_net", "has 4 layers where the spec has 5"],
    );

    let mut flat = file.clone();
    let weight = "mass_net.layers.1.weight";
    for a in arrays(&mut flat, weight) {
        a["shape"] = json!([32 * 32]);
    }
    let (status, body) = post_file(&app, &flat).await;
    refused(
        status,
        &body,
        &["mass_net layer 1", "[1024]", "not two numbers"],
    );

    assert_eq!(listed(&app).await, before);
    app.stop().await;
}

/// The trained file's values, counted from the file itself (every array's length), set the
/// limit: a service whose `--max-model-params` is one less refuses the upload naming the
/// flag; one whose limit is exactly that takes it (201), and serves it. Before, uploads were
/// never counted.
#[tokio::test]
async fn uploads_count_against_max_model_params() {
    let trainer = spawn_app(1).await;
    let (_, file) = mvf_file(&trainer).await;
    trainer.stop().await;
    let count: usize = file["params"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["values"].as_array().unwrap().len())
        .sum();
    assert!(count > 5_000, "an MVF of three 32-wide networks: {count}");

    let tight = spawn_configured(Settings {
        max_model_params: count - 1,
        ..test_settings()
    })
    .await;
    let (status, body) = post_file(&tight, &file).await;
    refused(status, &body, &[&count.to_string(), "--max-model-params"]);
    assert!(listed(&tight).await.is_empty());
    tight.stop().await;

    let exact = spawn_configured(Settings {
        max_model_params: count,
        ..test_settings()
    })
    .await;
    let (status, body) = post_file(&exact, &file).await;
    assert_eq!(status, 201, "{body}");
    let id = body["id"].as_str().unwrap().to_string();
    assert_eq!(listed(&exact).await, std::slice::from_ref(&id));
    let answer = client(&exact)
        .await
        .predict(predict_req(&id, 3))
        .await
        .expect("the uploaded model is served")
        .into_inner();
    assert_eq!(answer.x_next.unwrap().data.len(), 3 * 4);
    exact.stop().await;
}

/// An ensemble of three as graybox writes it (with its checksum) with one weight changed, a
/// member removed, its `members` deleted (one model that would answer with no spread), or 200
/// members more than training allows: each a 422 naming `checksum` or `members`, nothing
/// stored. Before, each was stored and served. The file as written is taken without a
/// warning; one from before checksums is taken with the warning in its metrics.
#[tokio::test]
async fn an_edited_model_file_is_refused_naming_the_field() {
    use graybox::model::file::ModelFile;
    let app = spawn_app(0).await;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/compat");
    let old = std::fs::read(dir.join("wb-x3.gbx")).unwrap();
    let written = ModelFile::from_bytes(&old).unwrap().to_bytes().unwrap();
    let file: Value = serde_json::from_slice(&written).unwrap();

    let mut weight = file.clone();
    let w = &mut weight["params"][0]["values"][0];
    *w = json!(w.as_f64().unwrap() * 1.001);
    let mut fewer = file.clone();
    fewer["members"].as_array_mut().unwrap().pop();
    let mut gone = file.clone();
    gone.as_object_mut().unwrap().remove("members");
    let mut many = file.clone();
    many["members"] = json!(vec![file["params"].clone(); 200]);
    for (edited, field, words) in [
        (weight, "checksum", &["edited"][..]),
        (fewer, "members", &["2 member(s)", "lists 3"]),
        (gone, "members", &["1 member(s)", "lists 3"]),
        (many, "members", &["201 members", "at most 32"]),
    ] {
        let (status, body) = post_file(&app, &edited).await;
        refused(status, &body, words);
        assert_eq!(body["error"]["field"], field, "{body}");
    }
    assert!(listed(&app).await.is_empty());

    let (status, body) = post_file(&app, &file).await;
    assert_eq!(status, 201, "{body}");
    assert_eq!(body["metrics"]["warnings"], json!([]), "{body}");
    let (status, body) = post_file(&app, &serde_json::from_slice(&old).unwrap()).await;
    assert_eq!(status, 201, "{body}");
    let (status, body) = app
        .get(&format!("/v1/models/{}", body["id"].as_str().unwrap()))
        .await;
    assert_eq!(status, 200, "{body}");
    let warnings = body["metrics"]["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{body}");
    assert_eq!(
        (&warnings[0]["code"], &warnings[0]["field"]),
        (&json!("model_file_unchecked"), &json!("checksum"))
    );
    app.stop().await;
}
