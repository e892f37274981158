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
    // Every job that existed before the listing started appears, in order.
    assert_eq!(&seen[..7], &created[..7]);
    // Oldest first and nothing skipped: what was seen is a prefix of creation order.
    assert_eq!(seen, created[..seen.len()]);

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
