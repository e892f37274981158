//! The queue: idempotent submission, claims in order and never twice, leases on the
//! database's clock, fencing of every worker write, worker deaths counted and capped,
//! cancellation, giving jobs back, and the ends of a job.

use std::collections::HashSet;
use std::time::Duration;

use graybox::backoff::Backoff;
use graybox::error::Error;
use graybox::records::{JobState, Metric, Warning};
use graybox::store::{Claimed, Lease, Submitted};

use super::rows::model;
use super::{TestStore, new_job, queued_job, small_dataset};

/// Long enough that no test outlives it.
const LEASE_MS: i64 = 600_000;
/// A lease that has expired by the time the next statement runs (after [`expire`]).
const SHORT_MS: i64 = 1;
const MAX_ATTEMPTS: i64 = 3;

/// Waits past a [`SHORT_MS`] lease. The lease is on the database's clock, which moves with
/// this machine's: 50 ms is 50 times the lease, and only a lower bound matters.
async fn expire() {
    tokio::time::sleep(Duration::from_millis(50)).await;
}

fn metric(epoch: i64) -> Metric {
    Metric {
        epoch,
        train_loss: 1.0 / epoch as f64,
        val_loss: Some(2.0 / epoch as f64),
        val_horizon_loss: None,
        seconds: 0.5,
        // An ensemble's spread, so that its columns are read back too.
        train_loss_std: Some(0.1 / epoch as f64),
        val_loss_std: None,
    }
}

/// A claim that no longer holds: the same job under an older attempt.
fn stale(c: &Claimed) -> Claimed {
    Claimed {
        attempt: c.attempt - 1,
        ..c.clone()
    }
}

#[tokio::test]
async fn submission_is_idempotent_by_key_and_a_reused_key_with_another_request_is_refused() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 1, Some("key-1")).await;
    assert_eq!(
        (job.state, job.attempt, job.epoch),
        (JobState::Queued, 0, 0)
    );
    match s.submit_job(new_job(&job.dataset_id, Some("key-1"))).await {
        Ok(Submitted::Existing(again)) => assert_eq!(again.id, job.id),
        other => panic!("{other:?}"),
    }
    let mut other = new_job(&job.dataset_id, Some("key-1"));
    other.epochs = 5;
    other.request.push(' ');
    match s.submit_job(other).await {
        Err(Error::Unprocessable { field, .. }) => assert_eq!(field, "Idempotency-Key"),
        other => panic!("{other:?}"),
    }
    assert_eq!(s.list_jobs(None, None, 10).await.unwrap().len(), 1);
}

#[tokio::test]
async fn jobs_are_listed_counted_and_watched() {
    let s = TestStore::new().await;
    let a = queued_job(&s, 1, None).await;
    let b = queued_job(&s, 2, None).await;
    assert_eq!(s.max_job_seq().await.unwrap(), b.seq);
    let claimed = s
        .claim_job("w", LEASE_MS, MAX_ATTEMPTS)
        .await
        .unwrap()
        .unwrap();
    assert_eq!(claimed.job.id, a.id);
    let running = s
        .list_jobs(Some(JobState::Running), None, 10)
        .await
        .unwrap();
    assert_eq!(running.iter().map(|j| &j.id).collect::<Vec<_>>(), [&a.id]);
    // Newest first; a page continues before the last job it showed.
    let all = s.list_jobs(None, None, 10).await.unwrap();
    assert_eq!(
        all.iter().map(|j| &j.id).collect::<Vec<_>>(),
        [&b.id, &a.id]
    );
    let before_b = s.list_jobs(None, Some(b.seq), 10).await.unwrap();
    assert_eq!(before_b.iter().map(|j| &j.id).collect::<Vec<_>>(), [&a.id]);
    let counts = s.job_counts().await.unwrap();
    let count = |st| counts.iter().find(|(s, _)| *s == st).unwrap().1;
    assert_eq!((count(JobState::Queued), count(JobState::Running)), (1, 1));
    assert_eq!(count(JobState::Succeeded), 0);
    // A watcher sees everything newer than its mark and everything still active.
    assert!(
        s.end_job(&claimed, JobState::Succeeded, None)
            .await
            .unwrap()
    );
    let watched = s.watched_jobs(b.seq).await.unwrap();
    assert_eq!(watched.iter().map(|j| &j.id).collect::<Vec<_>>(), [&b.id]);
    assert_eq!(s.watched_jobs(0).await.unwrap().len(), 2);
}

#[tokio::test]
async fn a_claim_takes_the_oldest_job_and_concurrent_claims_never_share_one() {
    let s = TestStore::new().await;
    for seed in 0..6 {
        queued_job(&s, seed, None).await;
    }
    // Two pools, as two processes: 12 claimers race for 6 jobs.
    let other = s.reopen().await;
    let claims = (0..12).map(|i| {
        let store = if i % 2 == 0 {
            s.store.clone()
        } else {
            other.clone()
        };
        tokio::spawn(async move {
            store
                .claim_job(&format!("w{i}"), LEASE_MS, MAX_ATTEMPTS)
                .await
                .unwrap()
        })
    });
    let mut got = Vec::new();
    for c in claims {
        if let Some(c) = c.await.unwrap() {
            assert_eq!((c.attempt, c.job.state), (1, JobState::Running));
            got.push(c.job.id.clone());
        }
    }
    let distinct: HashSet<_> = got.iter().collect();
    assert_eq!((got.len(), distinct.len()), (6, 6), "{got:?}");
    assert!(s.claim_job("late", LEASE_MS, 3).await.unwrap().is_none());
    // One claimer alone takes them in submission order.
    let s = TestStore::new().await;
    let first = queued_job(&s, 1, None).await;
    let second = queued_job(&s, 2, None).await;
    let c1 = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    let c2 = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    assert_eq!((&c1.job.id, &c2.job.id), (&first.id, &second.id));
}

#[tokio::test]
async fn a_held_job_records_epochs_checkpoints_and_finishes_into_a_model() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 1, None).await;
    let c = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    assert_eq!(
        s.heartbeat(&c, LEASE_MS).await.unwrap(),
        Lease::Held {
            cancel_requested: false
        }
    );
    for epoch in 1..=2 {
        assert!(s.record_epoch(&c, &metric(epoch), Some(0.5)).await.unwrap());
    }
    // Recording an epoch again (a resumed job repeats the epochs after its checkpoint)
    // replaces its row.
    assert!(s.record_epoch(&c, &metric(2), Some(0.25)).await.unwrap());
    assert_eq!(s.metrics(&job.id, 0).await.unwrap(), [metric(1), metric(2)]);
    assert_eq!(s.metrics(&job.id, 1).await.unwrap(), [metric(2)]);
    let got = s.get_job(&job.id).await.unwrap().unwrap();
    assert_eq!((got.epoch, got.best_val_loss), (2, Some(0.25)));

    let state: Vec<u8> = (0..100_000u32).map(|i| (i * 7) as u8).collect();
    assert!(s.save_checkpoint(&c, 2, &state).await.unwrap());
    assert!(s.save_checkpoint(&c, 2, &state[..10]).await.unwrap());
    assert_eq!(
        s.load_checkpoint(&job.id).await.unwrap(),
        Some((2, state[..10].to_vec()))
    );
    assert_eq!(
        s.get_job(&job.id).await.unwrap().unwrap().checkpoint_epoch,
        2
    );

    let warnings = [Warning {
        code: "stiff".into(),
        field: Some("q[0]".into()),
        message: "a warning survives the JSON column".into(),
    }];
    let file = b"model bytes";
    let id = s.finish_job(&c, model(file), &warnings).await.unwrap();
    let id = id.expect("the holder finishes its job");
    let done = s.get_job(&job.id).await.unwrap().unwrap();
    assert_eq!(done.state, JobState::Succeeded);
    assert_eq!(done.model_id.as_deref(), Some(id.as_str()));
    assert_eq!(done.warnings, warnings);
    let m = s.get_model(&id).await.unwrap().unwrap();
    assert_eq!(
        (m.origin.as_str(), m.job_id.as_deref()),
        ("trained", Some(job.id.as_str()))
    );
    assert_eq!(s.model_file(&id).await.unwrap().as_deref(), Some(&file[..]));
    // Ended: the lease is gone and nothing more is written.
    assert_eq!(s.heartbeat(&c, LEASE_MS).await.unwrap(), Lease::Lost);
    assert!(!s.record_epoch(&c, &metric(3), None).await.unwrap());
}

#[tokio::test]
async fn an_expired_lease_is_reclaimed_counted_and_its_old_holder_fenced_out() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 1, None).await;
    let old = s.claim_job("a", SHORT_MS, 3).await.unwrap().unwrap();
    assert!(s.save_checkpoint(&old, 1, b"epoch 1").await.unwrap());
    expire().await;
    let new = s.claim_job("b", LEASE_MS, 3).await.unwrap().unwrap();
    assert_eq!((new.job.id.as_str(), new.attempt), (job.id.as_str(), 2));
    // The old holder's every write is refused; the new holder's go through.
    assert_eq!(s.heartbeat(&old, LEASE_MS).await.unwrap(), Lease::Lost);
    assert!(!s.record_epoch(&old, &metric(1), None).await.unwrap());
    assert!(!s.save_checkpoint(&old, 2, b"stale").await.unwrap());
    assert_eq!(
        s.finish_job(&old, model(b"stale"), &[]).await.unwrap(),
        None
    );
    assert!(!s.release_job(&old).await.unwrap());
    assert!(
        !s.end_job(&old, JobState::Failed, Some("stale"))
            .await
            .unwrap()
    );
    // Same attempt, another owner: refused as well.
    let thief = Claimed {
        owner: "a".into(),
        ..new.clone()
    };
    assert!(!s.record_epoch(&thief, &metric(1), None).await.unwrap());
    assert_eq!(
        s.load_checkpoint(&job.id).await.unwrap().unwrap().1,
        b"epoch 1"
    );
    assert!(s.record_epoch(&new, &metric(1), None).await.unwrap());
    assert!(
        !s.record_epoch(&stale(&new), &metric(1), None)
            .await
            .unwrap()
    );
    assert!(s.end_job(&new, JobState::Succeeded, None).await.unwrap());
}

#[tokio::test]
async fn a_job_whose_workers_keep_dying_fails_at_the_cap() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 1, None).await;
    for attempt in 1..=2 {
        let c = s.claim_job("w", SHORT_MS, 3).await.unwrap().unwrap();
        assert_eq!(c.attempt, attempt);
        expire().await;
    }
    // A graceful release is no death: the count stays at one.
    let c = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    assert!(s.release_job(&c).await.unwrap());
    let c = s.claim_job("w", SHORT_MS, 3).await.unwrap().unwrap();
    assert_eq!(c.attempt, 4);
    expire().await;
    // The third death reaches --max-attempts 3: failed, not claimed again.
    assert!(s.claim_job("w", LEASE_MS, 3).await.unwrap().is_none());
    let failed = s.get_job(&job.id).await.unwrap().unwrap();
    assert_eq!(failed.state, JobState::Failed);
    let error = failed.error.clone().unwrap();
    assert!(error.contains("died 3 times"), "{error}");
}

#[tokio::test]
async fn cancelling_ends_a_queued_job_and_asks_a_running_one() {
    let s = TestStore::new().await;
    let queued = queued_job(&s, 1, None).await;
    assert_eq!(
        s.cancel_job(&queued.id).await.unwrap().state,
        JobState::Cancelled
    );
    assert!(s.claim_job("w", LEASE_MS, 3).await.unwrap().is_none());

    let running = queued_job(&s, 2, None).await;
    let c = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    let asked = s.cancel_job(&running.id).await.unwrap();
    assert_eq!(
        (asked.state, asked.cancel_requested),
        (JobState::Running, true)
    );
    assert_eq!(
        s.heartbeat(&c, LEASE_MS).await.unwrap(),
        Lease::Held {
            cancel_requested: true
        }
    );
    assert!(s.end_job(&c, JobState::Cancelled, None).await.unwrap());
    assert!(matches!(
        s.cancel_job("job_missing").await,
        Err(Error::NotFound(_))
    ));

    // Asked while its worker is dead: cancelled by the next claim, not run again.
    let orphan = queued_job(&s, 3, None).await;
    let c = s.claim_job("w", SHORT_MS, 3).await.unwrap().unwrap();
    assert_eq!(c.job.id, orphan.id);
    s.cancel_job(&orphan.id).await.unwrap();
    expire().await;
    assert!(s.claim_job("w", LEASE_MS, 3).await.unwrap().is_none());
    let got = s.get_job(&orphan.id).await.unwrap().unwrap();
    assert_eq!(got.state, JobState::Cancelled);
}

#[tokio::test]
async fn jobs_given_back_are_claimed_again() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 1, None).await;
    let c = s.claim_job("proc-w0", LEASE_MS, 3).await.unwrap().unwrap();
    assert!(s.release_job(&c).await.unwrap());
    let c = s.claim_job("proc-w0", LEASE_MS, 3).await.unwrap().unwrap();
    assert_eq!(c.attempt, 2);
    // A forced shutdown gives back what an owner holds without naming the attempt.
    assert_eq!(s.release_owned("proc-w1").await.unwrap(), 0);
    assert_eq!(s.release_owned("proc-w0").await.unwrap(), 1);
    assert_eq!(
        s.get_job(&job.id).await.unwrap().unwrap().state,
        JobState::Queued
    );
    assert!(!s.record_epoch(&c, &metric(1), None).await.unwrap());
}

/// A storage failure gives the job back to be claimed after a backoff wait, not at once;
/// the job fails only once its storage has been failing for the patience, counted from the
/// first failure since its last stored checkpoint.
#[tokio::test]
async fn storage_failures_are_waited_out_and_counted_over_time() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 1, None).await;
    let hour = Duration::from_secs(3600);
    // Waits of 1 to 2 s: long beside a claim's round trip, so "not yet" is not a race.
    let wait = Backoff::new(Duration::from_secs(2), Duration::from_secs(2));
    let c = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    let state = s.retry_later(&c, wait, hour, "down").await.unwrap();
    assert_eq!(state, Some(JobState::Queued));
    assert!(
        s.claim_job("w", LEASE_MS, 3).await.unwrap().is_none(),
        "claimed during its wait"
    );
    assert_eq!(
        s.retry_later(&c, wait, hour, "down").await.unwrap(),
        None,
        "fenced"
    );
    tokio::time::sleep(Duration::from_millis(2100)).await;
    let c = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    assert_eq!((c.job.id.as_str(), c.attempt), (job.id.as_str(), 2));

    // Patience 1 s: a stored checkpoint ends the run of failures, so the next one starts a
    // new run; a run longer than the patience fails the job, saying so.
    let now = Backoff::new(Duration::from_millis(1), Duration::from_millis(1));
    let second = Duration::from_secs(1);
    tokio::time::sleep(Duration::from_millis(1100)).await;
    assert!(s.save_checkpoint(&c, 1, &[1; 16]).await.unwrap());
    let state = s.retry_later(&c, now, second, "down").await.unwrap();
    assert_eq!(
        state,
        Some(JobState::Queued),
        "the checkpoint began a new run"
    );
    tokio::time::sleep(Duration::from_millis(1100)).await;
    let c = s.claim_job("w", LEASE_MS, 3).await.unwrap().unwrap();
    let state = s.retry_later(&c, now, second, "still down").await.unwrap();
    assert_eq!(state, Some(JobState::Failed));
    let failed = s.get_job(&job.id).await.unwrap().unwrap();
    let error = failed.error.clone().unwrap_or_default();
    assert!(
        error.contains("storage failed for ") && error.contains("still down"),
        "{error}"
    );
}

#[tokio::test]
async fn a_validation_dataset_is_checked_and_kept_like_the_training_one() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 1, None).await;
    let (val, _) = s.insert_dataset(None, &small_dataset(9)).await.unwrap();
    let mut with_val = new_job(&job.dataset_id, None);
    with_val.validation_dataset_id = Some(val.id.clone());
    s.submit_job(with_val).await.unwrap();
    let err = s.delete_dataset(&val.id).await.unwrap_err();
    assert!(matches!(err, Error::Conflict(_)), "{err}");
    let mut missing = new_job(&job.dataset_id, None);
    missing.validation_dataset_id = Some("ds_missing".into());
    match s.submit_job(missing).await {
        Err(Error::Unprocessable { field, .. }) => assert_eq!(field, "validation_dataset_id"),
        other => panic!("{other:?}"),
    }
}
