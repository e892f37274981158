use serde_json::{Value, json};

use crate::helpers::*;

#[tokio::test]
async fn uploads_in_three_forms_with_dedup() {
    let app = spawn_app(0).await;
    let body = dataset(16, 1);
    let (s1, a) = app.post("/v1/datasets?name=first", &body).await;
    assert_eq!(s1, 201, "{a}");
    assert_eq!(
        (a["n"].as_i64(), a["m"].as_i64(), a["count"].as_i64()),
        (Some(2), Some(2), Some(16))
    );
    assert_eq!(a["name"], "first");
    let (s2, b) = app.post("/v1/datasets", &body).await;
    assert_eq!(s2, 200, "the same arrays again return the stored dataset");
    assert_eq!(a["id"], b["id"]);

    // CSV with ?dt=
    let csv = "q0,qdot0,u0,q_next0,qdot_next0\n0.1,0.2,1.0,0.102,0.19\n0.3,0.0,-1.0,0.3,-0.01\n";
    let r = app
        .client
        .post(app.url("/v1/datasets?dt=0.01"))
        .header("content-type", "text/csv")
        .body(csv)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 201);
    let c: Value = r.json().await.unwrap();
    assert_eq!(
        (c["n"].as_i64(), c["m"].as_i64(), c["count"].as_i64()),
        (Some(1), Some(1), Some(2))
    );

    // Trajectories: T+1 states and T inputs each → T transitions each.
    let traj = json!({"dt": 0.01, "name": "rollouts", "trajectories": [
        {"q": [[0.0], [0.1], [0.2]], "qdot": [[1.0], [1.0], [1.1]], "u": [[0.5], [0.4]]},
        {"q": [[1.0], [1.1]], "qdot": [[0.0], [0.2]], "u": [[2.0]]}
    ]});
    let (s, t) = app.post("/v1/datasets", &traj).await;
    assert_eq!(s, 201, "{t}");
    assert_eq!(t["count"], 3);
    assert_eq!(t["name"], "rollouts");
    // The trajectory form equals the same transitions uploaded as arrays.
    let arrays = json!({"dt": 0.01, "q": [[0.0], [0.1], [1.0]], "qdot": [[1.0], [1.0], [0.0]], "u": [[0.5], [0.4], [2.0]],
                        "q_next": [[0.1], [0.2], [1.1]], "qdot_next": [[1.0], [1.1], [0.2]]});
    let (s, same) = app.post("/v1/datasets", &arrays).await;
    assert_eq!((s, &same["sha256"]), (200, &t["sha256"]));

    let (s, got) = app
        .get(&format!("/v1/datasets/{}", a["id"].as_str().unwrap()))
        .await;
    assert_eq!((s, &got["sha256"]), (200, &a["sha256"]));
    app.stop().await;
}

/// Keyset pagination: inserting between page reads never repeats or skips a row.
#[tokio::test]
async fn pagination_never_repeats_or_skips() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(8, 2)).await;
    let mut created = vec![];
    for _ in 0..7 {
        let (_, j) = app.post("/v1/jobs", &job_body(&ds, "W-B", 1)).await;
        created.push(j["id"].as_str().unwrap().to_string());
    }
    let mut seen: Vec<String> = vec![];
    let mut token: Option<String> = None;
    let mut pages = 0;
    loop {
        let path = match &token {
            Some(t) => format!("/v1/jobs?page_size=3&page_token={t}"),
            None => "/v1/jobs?page_size=3".to_string(),
        };
        let (s, page) = app.get(&path).await;
        assert_eq!(s, 200, "{page}");
        pages += 1;
        seen.extend(
            page["items"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| j["id"].as_str().unwrap().to_string()),
        );
        // Insert between pages.
        let (_, j) = app.post("/v1/jobs", &job_body(&ds, "W-B", 1)).await;
        created.push(j["id"].as_str().unwrap().to_string());
        match page["next_page_token"].as_str() {
            Some(t) => token = Some(t.to_string()),
            None => break,
        }
        assert!(pages < 20, "pagination does not end");
    }
    assert!(pages >= 3, "{pages} pages");
    let mut dedup = seen.clone();
    dedup.dedup();
    assert_eq!(dedup, seen, "no repeats");
    // Newest first: exactly the jobs that existed when the listing started, newest to
    // oldest (jobs submitted meanwhile are newer than its first page, so never appear).
    let before: Vec<String> = created[..7].iter().rev().cloned().collect();
    assert_eq!(seen, before);

    // Datasets page newest first, also without repeats.
    for i in 0..5 {
        app.upload(&dataset(4, 100 + i)).await;
    }
    let (_, p1) = app.get("/v1/datasets?page_size=2").await;
    let t = p1["next_page_token"].as_str().unwrap();
    app.upload(&dataset(4, 200)).await;
    let (_, p2) = app
        .get(&format!("/v1/datasets?page_size=2&page_token={t}"))
        .await;
    let ids: Vec<&Value> = p1["items"]
        .as_array()
        .unwrap()
        .iter()
        .chain(p2["items"].as_array().unwrap())
        .map(|d| &d["id"])
        .collect();
    assert_eq!(ids.len(), 4);
    assert!(ids.windows(2).all(|w| w[0] != w[1]));
    app.stop().await;
}

#[tokio::test]
async fn dataset_in_use_cannot_be_deleted() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(8, 3)).await;
    let (_, job) = app.post("/v1/jobs", &job_body(&ds, "W-B", 1)).await;
    let r = app
        .client
        .delete(app.url(&format!("/v1/datasets/{ds}")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 409);
    app.post(
        &format!("/v1/jobs/{}/cancel", job["id"].as_str().unwrap()),
        &json!({}),
    )
    .await;
    let r = app
        .client
        .delete(app.url(&format!("/v1/datasets/{ds}")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 204);
    assert_eq!(app.get(&format!("/v1/datasets/{ds}")).await.0, 404);
    app.stop().await;
}

/// What a person gets from an upload: CSV recognised without its content type, ?dt= for a
/// JSON body without one (and a contradiction refused), a note when a name is not applied,
/// and the sanity warnings with the dataset.
#[tokio::test]
async fn uploads_say_what_happened() {
    let app = spawn_app(0).await;
    let csv = "q0,qdot0,u0,q_next0,qdot_next0\n0.1,0.2,1.0,0.102,0.19\n0.3,0.0,-1.0,0.3,-0.01\n";
    // curl --data-binary sends application/x-www-form-urlencoded.
    let r = app
        .client
        .post(app.url("/v1/datasets?dt=0.01"))
        .header("content-type", "application/x-www-form-urlencoded")
        .body(csv)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 201);
    // Declared JSON but CSV inside: the error says how to send CSV.
    let r = app
        .client
        .post(app.url("/v1/datasets?dt=0.01"))
        .header("content-type", "application/json")
        .body(csv)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 400);
    let e: Value = r.json().await.unwrap();
    assert!(
        e["error"]["message"].as_str().unwrap().contains("text/csv"),
        "{e}"
    );

    let mut body = dataset(16, 3);
    body.as_object_mut().unwrap().remove("dt");
    let (s, e) = app.post("/v1/datasets", &body).await;
    assert_eq!((s, e["error"]["field"].as_str()), (400, Some("dt")), "{e}");
    let (s, d) = app.post("/v1/datasets?name=first&dt=0.01", &body).await;
    assert_eq!(
        (s, &d["dt"], &d["created"]),
        (201, &json!(0.01), &json!(true)),
        "{d}"
    );
    assert!(d.get("note").is_none(), "{d}");
    let (s, e) = app.post("/v1/datasets?dt=0.02", &dataset(16, 3)).await;
    assert_eq!((s, e["error"]["field"].as_str()), (400, Some("dt")), "{e}");

    // The same arrays under another name: the stored record, and a note saying so.
    let (s, again) = app.post("/v1/datasets?name=second&dt=0.01", &body).await;
    assert_eq!(
        (s, &again["id"], &again["name"]),
        (200, &d["id"], &json!("first"))
    );
    assert_eq!(again["created"], false);
    let note = again["note"].as_str().unwrap();
    assert!(
        note.contains("'second'") && note.contains("'first'"),
        "{note}"
    );
    // The same name again: nothing to say.
    let (_, same) = app.post("/v1/datasets?name=first&dt=0.01", &body).await;
    assert!(same.get("note").is_none(), "{same}");

    // Angles in degrees: stored, with a warning naming the coordinate (also on GET).
    let deg = json!({"dt": 0.01, "q": [[0.0], [90.0], [-170.0]], "qdot": [[0.0], [5.0], [1.0]],
                     "u": [[0.0], [0.0], [0.0]], "q_next": [[0.0], [90.05], [-169.99]],
                     "qdot_next": [[0.0], [5.0], [1.0]]});
    let (s, d) = app.post("/v1/datasets", &deg).await;
    assert_eq!(s, 201, "{d}");
    assert_eq!(d["warnings"][0]["code"], "coordinate_span", "{d}");
    assert_eq!(d["warnings"][0]["field"], "q[0]", "{d}");
    let (_, got) = app
        .get(&format!("/v1/datasets/{}", d["id"].as_str().unwrap()))
        .await;
    assert_eq!(got["warnings"], d["warnings"]);
    app.stop().await;
}
