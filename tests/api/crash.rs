//! Durability with the real binary: `kill -9` mid-training and SIGTERM. A job resumes from
//! its last checkpoint and ends with exactly the parameters of an uninterrupted run (on
//! SQLite, whichever backend the crashed runs use). The job trains on windows of 3 steps of
//! trajectory data: what a multi-step job adds to a checkpoint (its windows, their order,
//! the horizon loss) must survive too; one-step jobs are killed in `chaos.rs` and
//! `cluster.rs`.

use serde_json::{Value, json};

use crate::helpers::final_state;
use crate::multistep::trajectories;
use crate::processes::{Server, fresh_db};

fn setup(s: &Server) -> String {
    let d = s.post("/v1/datasets", &trajectories(8, 64, 21));
    let v = s.post("/v1/datasets", &trajectories(2, 64, 22));
    let body = json!({"dataset_id": d["id"], "validation_dataset_id": v["id"], "model": "MVF",
                      "training": {"epochs": 24, "batch_size": 64, "lr": 0.003, "horizon": 3}});
    s.post("/v1/jobs", &body)["id"]
        .as_str()
        .unwrap()
        .to_string()
}

#[test]
fn kill_and_sigterm_resume_from_checkpoints_and_match_an_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();

    // Reference: one uninterrupted run.
    let reference = dir.path().join("ref.db");
    let reference = Server::start(reference.to_str().unwrap(), 1);
    let rid = setup(&reference);
    let rjob = reference.wait(&rid, 300, final_state);
    assert_eq!(rjob["state"], "succeeded", "{rjob}");
    let want = reference.model_file(&rjob);
    reference.sigterm();

    // kill -9 after the first checkpoints, then restart on the same database.
    let db = fresh_db(&dir.path().join("crash"));
    let first = Server::start(&db, 1);
    let id = setup(&first);
    let before = first.wait(&id, 120, |j| j["checkpoint_epoch"].as_i64() >= Some(2));
    assert_ne!(
        before["state"], "succeeded",
        "killed too late to test anything"
    );
    first.proc.kill();
    let mut second = Server::start(&db, 1);
    let done = second.wait(&id, 300, final_state);
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["attempt"], 2, "reclaimed once after the lease expired");
    let resumed: Vec<&String> = (second.proc.logs().iter())
        .filter(|l| l.contains("resuming from checkpoint"))
        .collect();
    assert_eq!(resumed.len(), 1, "{resumed:?}");
    assert!(
        !resumed[0].contains("epoch=0"),
        "resumed at a checkpoint, not epoch 0: {}",
        resumed[0]
    );
    let horizon: Vec<Value> = (second.get(&format!("/v1/jobs/{id}/metrics"))["items"].as_array())
        .unwrap()
        .iter()
        .map(|m| m["val_horizon_loss"].clone())
        .collect();
    assert!(horizon.iter().all(Value::is_f64), "{horizon:?}");
    let got = second.model_file(&done);
    assert_eq!(
        got.params, want.params,
        "final parameters equal the uninterrupted run's"
    );
    assert_eq!(
        got.report.as_ref().unwrap().best_epoch,
        want.report.as_ref().unwrap().best_epoch
    );
    assert_eq!(
        second.metric_epochs(&id),
        (1..=24).collect::<Vec<_>>(),
        "one metrics row per epoch"
    );
    assert_eq!(
        second.get("/v1/datasets")["items"]
            .as_array()
            .unwrap()
            .len(),
        2,
        "no row lost"
    );
    assert_eq!(second.get("/v1/jobs")["items"].as_array().unwrap().len(), 1);
    second.sigterm();

    // SIGTERM: the running job is checkpointed at its next epoch end and released as queued.
    let db = fresh_db(&dir.path().join("term"));
    let third = Server::start(&db, 1);
    let id = setup(&third);
    third.wait(&id, 120, |j| j["epoch"].as_i64() >= Some(3));
    third.sigterm();
    let idle = Server::start(&db, 0);
    let released = idle.get(&format!("/v1/jobs/{id}"));
    assert_eq!(released["state"], "queued", "{released}");
    let ck = released["checkpoint_epoch"].as_i64().unwrap();
    assert!(
        ck >= 3 && ck == released["epoch"].as_i64().unwrap(),
        "checkpointed at the epoch it stopped: {released}"
    );
    idle.sigterm();
    let last = Server::start(&db, 1);
    let done = last.wait(&id, 300, final_state);
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(last.model_file(&done).params, want.params);
    assert_eq!(last.metric_epochs(&id), (1..=24).collect::<Vec<_>>());
    last.sigterm();
}

/// An ensemble of 3, killed after its first checkpoints, resumes with every member where it
/// was: the finished file's members equal an uninterrupted run's, and its metrics carry the
/// members' spread.
#[test]
fn a_killed_ensemble_resumes_every_member_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let setup = |s: &Server| -> String {
        let d = s.post("/v1/datasets", &trajectories(8, 64, 31));
        let body = json!({"dataset_id": d["id"], "model": "MVF",
                          "training": {"epochs": 16, "batch_size": 64, "ensemble": 3}});
        let job = s.post("/v1/jobs", &body);
        job["id"].as_str().unwrap().to_string()
    };
    let reference = Server::start(dir.path().join("ref.db").to_str().unwrap(), 1);
    let rid = setup(&reference);
    let rjob = reference.wait(&rid, 300, final_state);
    assert_eq!(rjob["state"], "succeeded", "{rjob}");
    let want = reference.model_file(&rjob);
    assert_eq!(want.member_count(), 3);
    reference.sigterm();

    let db = fresh_db(&dir.path().join("crash"));
    let first = Server::start(&db, 1);
    let id = setup(&first);
    let before = first.wait(&id, 120, |j| j["checkpoint_epoch"].as_i64() >= Some(2));
    assert_ne!(before["state"], "succeeded", "killed too late");
    first.proc.kill();
    let second = Server::start(&db, 1);
    let done = second.wait(&id, 300, final_state);
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["attempt"], 2);
    let got = second.model_file(&done);
    assert_eq!(got.params, want.params, "member 0");
    assert_eq!(got.members, want.members, "members 1 and 2");
    let metrics = second.get(&format!("/v1/jobs/{id}/metrics"));
    let spread: Vec<&Value> = (metrics["items"].as_array().unwrap().iter())
        .map(|m| &m["train_loss_std"])
        .collect();
    assert!(
        spread.iter().all(|s| s.as_f64().is_some_and(|s| s > 0.0)),
        "{spread:?}"
    );
    assert_eq!(second.metric_epochs(&id), (1..=16).collect::<Vec<_>>());
    second.sigterm();
}
