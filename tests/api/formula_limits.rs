//! Kilobyte inputs that used to abort the whole process (recursion on the input) and
//! documents whose checks ran for minutes on the async executor: each entry point refuses
//! them with a 422 naming the field and the limit, or takes them and keeps serving.

use std::time::{Duration, Instant};

use graybox::api::grpc::pb;
use graybox::model::file::ModelFile;
use graybox::physics::formula::{MAX_DEPTH, MAX_NODES};
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::physics::urdf::xml;
use graybox::sim::{SimConfig, simulate};
use serde_json::{Value, json};

use crate::helpers::*;

/// A pendulum document whose potential is `potential`.
fn pendulum(potential: &str) -> Value {
    json!({
        "kind": "formula", "name": "hostile", "coordinates": ["theta"], "inputs": ["u"],
        "parameters": {"m": {"value": 1.0, "positive": true}, "l": {"value": 1.0, "positive": true},
                       "g": {"value": 9.81, "positive": true}},
        "mass": [["m*l^2"]], "potential": potential, "forces": ["u"],
    })
}

/// −m g l cos θ as a flat sum of `terms` equal parts.
fn long_sum(terms: usize) -> String {
    let part = format!("{}*m*g*l*cos(theta)", 1.0 / terms as f64);
    vec![format!("-{part}"); terms].join(" ")
}

/// Expressions of a few kilobytes, nested or long past a limit, and the words of the limit.
fn hostile() -> Vec<(String, String)> {
    let n = 2000;
    let depth = format!("more than {MAX_DEPTH} levels");
    vec![
        (
            format!("{}theta{}", "(".repeat(n), ")".repeat(n)),
            depth.clone(),
        ),
        (
            format!("{}theta{}", "sin(".repeat(n), ")".repeat(n)),
            depth.clone(),
        ),
        (format!("{}theta", "-".repeat(n)), depth),
        (
            vec!["theta"; MAX_NODES].join("+"),
            format!("more than {MAX_NODES}"),
        ),
    ]
}

fn refused(status: u16, body: &Value, field: &str, words: &str) {
    assert_eq!(status, 422, "{body}");
    assert_eq!(body["error"]["field"], field, "{body}");
    let message = body["error"]["message"].as_str().unwrap();
    assert!(message.contains(words), "{message}");
    assert!(
        message.len() < 1000,
        "the message echoes the input: {} bytes",
        message.len()
    );
}

async fn post_raw(app: &TestApp, path: &str, body: Vec<u8>) -> (u16, Value) {
    let r = app
        .client
        .post(app.url(path))
        .body(body)
        .send()
        .await
        .unwrap();
    (r.status().as_u16(), r.json().await.unwrap())
}

/// POST /v1/templates, a job's inline template and a model file embedding the template: each
/// a 422 naming the field and the limit, and the service answers afterwards.
#[tokio::test]
async fn hostile_expressions_are_refused_on_every_entry_point() {
    let app = spawn_app(0).await;
    let good = Template::Formula(std::sync::Arc::new(
        graybox::physics::formula_template::FormulaTemplate::parse(
            &pendulum("-m*g*l*cos(theta)").to_string(),
        )
        .unwrap(),
    ));
    let file = ModelFile::from_template(&good, &good.defaults(), 0.05, Integrator::Rk4).unwrap();
    let file: Value = serde_json::from_slice(&file.to_bytes().unwrap()).unwrap();
    for (expr, words) in hostile() {
        let doc = pendulum(&expr);
        let (status, body) = app.post("/v1/templates", &doc).await;
        refused(status, &body, "potential", &words);

        let job = json!({"dataset_id": "ds_none", "model": "W-B", "template": doc});
        let (status, body) = app.post("/v1/jobs", &job).await;
        refused(status, &body, "template.potential", &words);

        let mut gbx = file.clone();
        let embedded = find_template(&mut gbx).expect("the model file embeds its template");
        embedded["potential"] = json!(expr);
        let (status, body) = post_raw(&app, "/v1/models", serde_json::to_vec(&gbx).unwrap()).await;
        assert_eq!(status, 422, "{body}");
        let message = body["error"]["message"].as_str().unwrap();
        assert!(message.contains(&words), "{message}");
    }
    let (status, _) = app.get("/healthz").await;
    assert_eq!(status, 200);
}

/// The embedded template document of a model file (an object with `"kind": "formula"`).
fn find_template(v: &mut Value) -> Option<&mut Value> {
    let mut stack = vec![v];
    while let Some(v) = stack.pop() {
        if v.get("kind").and_then(Value::as_str) == Some("formula") {
            return Some(v);
        }
        match v {
            Value::Object(o) => stack.extend(o.values_mut()),
            Value::Array(a) => stack.extend(a.iter_mut()),
            _ => {}
        }
    }
    None
}

/// A potential that is a flat sum of 3000 terms (what used to abort the process on its first
/// Linearize or training step) is a legitimate template: stored, trained by a worker, served.
#[tokio::test]
async fn a_long_potential_is_stored_trained_and_served() {
    let app = spawn_app(1).await;
    let doc = pendulum(&long_sum(3000));
    let (status, t) = app.post("/v1/templates", &doc).await;
    assert_eq!(status, 201, "{t}");
    let template = Template::from_json(&doc.to_string()).unwrap();
    let data = simulate(
        &template,
        template.defaults(),
        &SimConfig {
            count: 64,
            seed: 4,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let ds = app
        .upload(&serde_json::from_str(&data.to_json()).unwrap())
        .await;
    let job = json!({"dataset_id": ds, "model": "W-B", "template": t["id"],
                     "training": {"epochs": 2, "batch_size": 32}});
    let (status, job) = app.post("/v1/jobs", &job).await;
    assert_eq!(status, 201, "{job}");
    let done = app
        .wait_job(job["id"].as_str().unwrap(), 120, final_state)
        .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let model = done["model_id"].as_str().unwrap().to_string();
    let mut c = client(&app).await;
    let lin = c
        .linearize(pb::LinearizeRequest {
            id: String::new(),
            model_id: model.clone(),
            x: arr(&[1, 2], vec![0.3, -0.1]),
            u: arr(&[1, 1], vec![0.5]),
        })
        .await
        .unwrap()
        .into_inner();
    assert!(lin.a.unwrap().data.iter().all(|v| v.is_finite()));
    let p = c
        .predict(pb::PredictRequest {
            id: String::new(),
            model_id: model,
            x: arr(&[64, 2], vec![0.2; 128]),
            u: arr(&[64, 1], vec![0.1; 64]),
            want_accel: true,
            members: false,
            dt: None,
        })
        .await
        .unwrap()
        .into_inner();
    assert!(p.x_next.unwrap().data.iter().all(|v| v.is_finite()));
}

/// A robot of 1000 joints as a chain of links.
fn chain_urdf(links: usize, joint: &str) -> String {
    let mut s = String::from("<robot name=\"chain\">\n");
    for i in 0..=links {
        s.push_str(&format!(
            "<link name=\"l{i}\"><inertial><mass value=\"1\"/>\
             <inertia ixx=\"0.1\" ixy=\"0\" ixz=\"0\" iyy=\"0.1\" iyz=\"0\" izz=\"0.1\"/>\
             </inertial></link>\n"
        ));
    }
    for i in 0..links {
        let kind = if i + 1 == links { "revolute" } else { joint };
        s.push_str(&format!(
            "<joint name=\"j{i}\" type=\"{kind}\"><parent link=\"l{i}\"/><child link=\"l{}\"/>\
             <origin xyz=\"0 0 0.01\"/><axis xyz=\"0 1 0\"/>\
             <limit effort=\"1\" velocity=\"1\" lower=\"-1\" upper=\"1\"/></joint>\n",
            i + 1
        ));
    }
    s + "</robot>\n"
}

/// Documents over the size limits are refused before anything reads their expressions or
/// builds their tree (a 1000-coordinate document whose every entry is unparsable is refused
/// for its size), off the async executor: `/healthz` answers throughout. Deep XML and long
/// fixed chains do not recurse.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oversized_documents_are_refused_first_and_the_service_keeps_answering() {
    let app = spawn_app(0).await;
    let n = 1000;
    let names: Vec<String> = (0..n).map(|i| format!("q{i}")).collect();
    let big = json!({
        "kind": "formula", "name": "big", "coordinates": names,
        "mass": vec![vec!["(("; n]; n], "potential": "((", "forces": vec!["(("; n],
    });
    let big = serde_json::to_vec(&big).unwrap();
    let urdf = chain_urdf(n, "revolute").into_bytes();
    let probes = {
        let (client, url) = (app.client.clone(), app.url("/healthz"));
        tokio::spawn(async move {
            let mut worst = Duration::ZERO;
            for _ in 0..20 {
                let t = Instant::now();
                let r = client.get(&url).send().await.unwrap();
                assert_eq!(r.status(), 200);
                worst = worst.max(t.elapsed());
                tokio::time::sleep(Duration::from_millis(25)).await;
            }
            worst
        })
    };
    for _ in 0..2 {
        let (status, body) = post_raw(&app, "/v1/templates", big.clone()).await;
        refused(status, &body, "coordinates", "--max-dof");
        let (status, body) = post_raw(&app, "/v1/templates", urdf.clone()).await;
        refused(status, &body, "urdf", "--max-dof");
    }
    let worst = probes.await.unwrap();
    eprintln!("slowest /healthz while oversized documents were refused: {worst:?}");
    // Before, two such uploads held both executor threads for over 20 s; a probe that waits
    // whole seconds means a check is back on the executor.
    assert!(worst < Duration::from_secs(2), "{worst:?}");

    // 3000 fixed links before the one joint: a chain that used to recurse once per link.
    let (status, body) = post_raw(&app, "/v1/templates", chain_urdf(3000, "fixed").into()).await;
    assert_eq!(status, 201, "{body}");
    assert_eq!(body["n"], 1, "{body}");
    // 3000 nested unknown elements inside a link: refused at the depth limit with its line.
    let nested = format!(
        "<robot name=\"r\">\n<link name=\"a\">{}{}</link></robot>",
        "<x>".repeat(3000),
        "</x>".repeat(3000)
    );
    let (status, body) = post_raw(&app, "/v1/templates", nested.into()).await;
    refused(
        status,
        &body,
        "urdf",
        &format!("more than {} deep", xml::MAX_DEPTH),
    );
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("line 2"),
        "{body}"
    );
}
