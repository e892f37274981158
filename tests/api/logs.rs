//! A robot's log uploaded to POST /v1/datasets (`?time=…`): imported as `graybox import` does,
//! with the import's summary in the answer; each bad log a 400 naming the field and the
//! column or row, a log whose import would outgrow its body's memory a 413, and nothing stored
//! for any of them.

use serde_json::Value;

use crate::helpers::*;

/// POST the CSV `body` with the query `query`: the status and the JSON answer.
async fn post_log(app: &TestApp, query: &str, body: String) -> (u16, Value) {
    let r = (app.client.post(app.url(&format!("/v1/datasets?{query}"))))
        .header("content-type", "text/csv")
        .body(body)
        .send()
        .await
        .unwrap();
    (r.status().as_u16(), r.json().await.unwrap())
}

/// Positions of a joint moving as sin(2t), at 2 ms ± 10 %, its efforts, and a text column.
fn log() -> String {
    let mut text = String::from("t,mode,j1,tau\n");
    let mut t = 0.0f64;
    for k in 0..600 {
        text += &format!("{t},run,{},{}\n", (2.0 * t).sin(), (k % 7) as f64 * 0.1);
        t += 0.002 * (1.0 + 0.1 * ((k % 5) as f64 - 2.0) / 2.0);
    }
    text
}

#[tokio::test]
async fn a_log_uploads_as_trajectories_with_its_import_summary() {
    let app = spawn_app(0).await;
    let (s, d) = post_log(&app, "name=arm&time=t&q=j1&u=tau", log()).await;
    assert_eq!(s, 201, "{d}");
    assert_eq!(
        (d["nq"].as_i64(), d["m"].as_i64()),
        (Some(1), Some(1)),
        "{d}"
    );
    let import = &d["import"];
    assert_eq!(
        (import["rows"].as_u64(), import["trajectories"].as_u64()),
        (Some(600), Some(1))
    );
    assert_eq!(import["velocities"], "estimated");
    assert_eq!(d["count"].as_u64(), import["transitions"].as_u64(), "{d}");
    let (_, listed) = app.get("/v1/datasets").await;
    let stored = listed["items"].as_array().unwrap().len();

    // Each bad log names what is wrong; none is stored.
    let bad = [
        ("time=t&q=j9&u=tau", log(), "q", "no column 'j9'"),
        (
            "time=t&q=j1&u=tau",
            "t,j1,tau\n0,0,0\n0.01,0,0\n0.005,0,0\n".into(),
            "time",
            "row 2",
        ),
        (
            "time=t&q=j1&u=tau",
            "t,j1,tau\n0,0,0\n0.01,high,0\n".into(),
            "q",
            "'high'",
        ),
        (
            "time=t&q=j1&u=tau",
            "t,j1,tau\n0,0,\n0.01,0,nan\n".into(),
            "u",
            "no value",
        ),
        (
            "time=t&q=j1&u=tau",
            "t,j1,tau\n0,0,0\n".into(),
            "log",
            "1 complete row",
        ),
        ("time=t&q=j1&u=tau&window=2", log(), "window", "between"),
    ];
    for (query, body, field, says) in bad {
        let (s, e) = post_log(&app, query, body).await;
        assert_eq!(
            (s, e["error"]["field"].as_str()),
            (400, Some(field)),
            "{query}: {e}"
        );
        let message = e["error"]["message"].as_str().unwrap();
        assert!(message.contains(says), "{query}: {message}");
    }
    // Whole seconds of zeros: each 7-byte row becomes a transition of ~100 bytes, more than
    // the ten bytes per body byte an upload may hold.
    let tiny: String = std::iter::once("t,q,u\n".to_string())
        .chain((1..2000).map(|k| format!("{k},0,0\n")))
        .collect();
    let (s, e) = post_log(&app, "time=t&q=q&u=u", tiny).await;
    assert_eq!(s, 413, "{e}");
    assert!(
        e["error"]["message"]
            .as_str()
            .unwrap()
            .contains("graybox import"),
        "{e}"
    );
    // The widest, highest-order fit over a minute at 1 kHz is more work than an upload may ask
    // (2.9e9 operations): refused before any fit.
    let long: String = std::iter::once("t,q,u\n".to_string())
        .chain((0..60_000).map(|k| format!("{:.6},{:.6},{:.6}\n", k as f64 * 1e-3, 0.5, 0.25)))
        .collect();
    let (s, e) = post_log(&app, "time=t&q=q&u=u&window=1001&order=6", long).await;
    assert_eq!(s, 413, "{e}");
    assert!(
        e["error"]["message"]
            .as_str()
            .unwrap()
            .contains("narrower window"),
        "{e}"
    );
    let (_, listed) = app.get("/v1/datasets").await;
    assert_eq!(
        listed["items"].as_array().unwrap().len(),
        stored,
        "{listed}"
    );
    app.stop().await;
}

/// By default a log keeps its samples' times: the stored dataset's transitions each carry
/// their own Δt, and a model's replay of it steps them (its times are the log's); resampled,
/// the replay's times are the grid's.
#[tokio::test]
async fn a_log_keeps_its_samples_times_through_storage_and_replay() {
    use graybox::model::file::ModelFile;
    use graybox::physics::integrator::Integrator;
    use graybox::physics::templates::Template;

    let app = spawn_app(0).await;
    let times: Vec<f64> = (log().lines().skip(1))
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    let (s, own) = post_log(&app, "time=t&q=j1&u=tau", log()).await;
    assert_eq!(
        (s, &own["import"]["times"]),
        (201, &"samples".into()),
        "{own}"
    );
    let (s, grid) = post_log(&app, "time=t&q=j1&u=tau&resample=true", log()).await;
    assert_eq!(
        (s, &grid["import"]["times"]),
        (201, &"grid".into()),
        "{grid}"
    );
    assert_ne!(own["id"], grid["id"]);
    let dt = own["dt"].as_f64().unwrap();
    let t = Template::Pendulum;
    let file = ModelFile::from_template(&t, &t.defaults(), dt, Integrator::Rk4).unwrap();
    let model = app.upload_model(&file).await;
    let replay = |d: &Value| {
        format!(
            "/v1/models/{model}/rollout?dataset_id={}&index=0",
            d["id"].as_str().unwrap()
        )
    };
    let (s, r) = app.get(&replay(&own)).await;
    assert_eq!(s, 200, "{r}");
    let got: Vec<f64> = r["t"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(got.len(), times.len());
    for (k, (g, t)) in got.iter().zip(&times).enumerate() {
        // Sums of the stored steps against the log's times: rounding of 600 additions.
        assert!(
            (g - (t - times[0])).abs() < 1e-12,
            "t[{k}] = {g}, the log's {t}"
        );
    }
    let (s, r) = app.get(&replay(&grid)).await;
    assert_eq!(s, 200, "{r}");
    let step = grid["dt"].as_f64().unwrap();
    let got = r["t"].as_array().unwrap();
    assert!(
        (got[7].as_f64().unwrap() - 7.0 * step).abs() < 1e-15,
        "{:?}",
        &got[..8]
    );
    app.stop().await;
}

/// A Parquet log uploads like its CSV: the committed pendulum log in both forms makes one
/// dataset (the second upload finds the first's arrays), its summary naming the format; a
/// truncated Parquet file is a 400 naming the log, and stores nothing.
#[tokio::test]
async fn a_parquet_log_uploads_as_its_csv_does() {
    let app = spawn_app(0).await;
    let read = |name: &str| std::fs::read(format!("examples/logs/pendulum.{name}")).unwrap();
    let post = |body: Vec<u8>, ct: &'static str| {
        let url = app.url("/v1/datasets?time=time&q=theta&u=tau");
        let request = app.client.post(url).header("content-type", ct).body(body);
        async move {
            let r = request.send().await.unwrap();
            (r.status().as_u16(), r.json::<Value>().await.unwrap())
        }
    };
    let (s, csv) = post(read("csv"), "text/csv").await;
    assert_eq!(
        (s, csv["import"]["format"].as_str()),
        (201, Some("csv")),
        "{csv}"
    );
    let parquet = read("parquet");
    let (s, same) = post(parquet.clone(), "application/vnd.apache.parquet").await;
    assert_eq!((s, same["created"].as_bool()), (200, Some(false)), "{same}");
    assert_eq!(same["id"], csv["id"]);
    assert_eq!(same["import"]["format"], "parquet");
    let (s, e) = post(
        parquet[..parquet.len() / 2].to_vec(),
        "application/octet-stream",
    )
    .await;
    assert_eq!((s, e["error"]["field"].as_str()), (400, Some("log")), "{e}");
    let (_, listed) = app.get("/v1/datasets").await;
    assert_eq!(listed["items"].as_array().unwrap().len(), 1, "{listed}");
    app.stop().await;
}
