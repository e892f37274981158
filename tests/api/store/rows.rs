//! Datasets, templates and models: stored once by content, read back exactly, listed newest
//! first, deleted by id, and kept while a queued or running job uses them.

use graybox::error::Error;
use graybox::store::{NewModel, NewTemplate, Submitted};

use super::{TestStore, new_job, queued_job, small_dataset};

#[tokio::test]
async fn a_dataset_is_stored_once_read_back_exactly_and_listed_newest_first() {
    let s = TestStore::new().await;
    let ds = small_dataset(1);
    let (first, created) = s.insert_dataset(Some("arm"), &ds).await.unwrap();
    assert!(created);
    assert_eq!(
        (first.nq, first.nv, first.n, first.m, first.count),
        (2, 2, 2, 2, 16)
    );
    assert_eq!(first.name.as_deref(), Some("arm"));
    // The same content again: the first row, and its trajectory lengths filled in.
    let as_trajectories = ds.clone().with_trajectories(vec![8, 8]).unwrap();
    let (again, created) = s.insert_dataset(None, &as_trajectories).await.unwrap();
    assert!(!created);
    assert_eq!(again.id, first.id);
    assert_eq!(
        s.dataset_trajectories(&first.id).await.unwrap(),
        Some(Some(vec![8, 8]))
    );
    // f64 arrays survive the blob column bit for bit, and come back with their trajectories.
    assert_eq!(
        s.load_dataset(&first.id).await.unwrap(),
        Some(as_trajectories)
    );
    assert_eq!(
        s.get_dataset(&first.id).await.unwrap().unwrap().id,
        first.id
    );
    assert!(s.get_dataset("ds_missing").await.unwrap().is_none());
    assert!(s.load_dataset("ds_missing").await.unwrap().is_none());
    assert_eq!(s.dataset_trajectories("ds_missing").await.unwrap(), None);

    let (second, _) = s.insert_dataset(None, &small_dataset(2)).await.unwrap();
    let page = s.list_datasets(None, 1).await.unwrap();
    assert_eq!(ids(&page), [second.id.as_str()]);
    let rest = s.list_datasets(Some(page[0].seq), 10).await.unwrap();
    assert_eq!(ids(&rest), [first.id.as_str()]);

    s.delete_dataset(&first.id).await.unwrap();
    assert!(s.get_dataset(&first.id).await.unwrap().is_none());
    assert!(matches!(
        s.delete_dataset(&first.id).await,
        Err(Error::NotFound(_))
    ));
}

fn ids(rows: &[graybox::store::DatasetRow]) -> Vec<&str> {
    rows.iter().map(|r| r.id.as_str()).collect()
}

#[tokio::test]
async fn a_dataset_a_queued_job_uses_cannot_be_deleted_and_a_deleted_one_cannot_be_used() {
    let s = TestStore::new().await;
    let job = queued_job(&s, 3, None).await;
    let err = s.delete_dataset(&job.dataset_id).await.unwrap_err();
    assert!(matches!(err, Error::Conflict(_)), "{err}");
    s.cancel_job(&job.id).await.unwrap();
    s.delete_dataset(&job.dataset_id).await.unwrap();
    // Submitting on the deleted dataset names the field.
    match s.submit_job(new_job(&job.dataset_id, None)).await {
        Err(Error::Unprocessable { field, .. }) => assert_eq!(field, "dataset_id"),
        other => panic!("{other:?}"),
    }
}

fn template(name: &str) -> NewTemplate<'_> {
    NewTemplate {
        kind: "formula",
        name,
        n: 1,
        m: 1,
        document: name,
        summary: "{}",
    }
}

#[tokio::test]
async fn a_template_is_stored_once_by_content_and_kept_while_a_job_uses_it() {
    let s = TestStore::new().await;
    let (t, created) = s.insert_template(template("pendulum")).await.unwrap();
    assert!(created);
    let (again, created) = s.insert_template(template("pendulum")).await.unwrap();
    assert!((!created, again.id.as_str()) == (true, t.id.as_str()));
    let got = s.get_template(&t.id).await.unwrap().unwrap();
    assert_eq!(got.document.as_deref(), Some("pendulum"));
    let (other, _) = s.insert_template(template("cart")).await.unwrap();
    let (page, more) = s.list_templates(None, 1).await.unwrap();
    assert_eq!((page[0].id.as_str(), more), (other.id.as_str(), true));
    let (page, more) = s.list_templates(Some(page[0].seq), 10).await.unwrap();
    assert_eq!((page[0].id.as_str(), more), (t.id.as_str(), false));

    let (ds, _) = s.insert_dataset(None, &small_dataset(4)).await.unwrap();
    let mut job = new_job(&ds.id, None);
    job.template_id = Some(t.id.clone());
    let Submitted::Created(job) = s.submit_job(job).await.unwrap() else {
        panic!("a new request found a job")
    };
    let err = s.delete_template(&t.id).await.unwrap_err();
    assert!(matches!(err, Error::Conflict(_)), "{err}");
    s.cancel_job(&job.id).await.unwrap();
    s.delete_template(&t.id).await.unwrap();
    assert!(s.get_template(&t.id).await.unwrap().is_none());
    assert!(matches!(
        s.delete_template(&t.id).await,
        Err(Error::NotFound(_))
    ));
    let mut job = new_job(&ds.id, None);
    job.template_id = Some(t.id.clone());
    match s.submit_job(job).await {
        Err(Error::Unprocessable { field, .. }) => assert_eq!(field, "template"),
        other => panic!("{other:?}"),
    }
}

pub fn model(file: &[u8]) -> NewModel<'_> {
    NewModel {
        name: "MVF",
        // nq apart from n (nv), so that a read that swapped or dropped them shows.
        n: 2,
        nq: 4,
        m: 2,
        dt: 0.01,
        spec: "{}",
        report: "null",
        file,
    }
}

#[tokio::test]
async fn an_uploaded_model_is_stored_once_by_content_and_its_file_read_back_verified() {
    let s = TestStore::new().await;
    let bytes: Vec<u8> = (0..=255).collect();
    let (m, created) = s.insert_model(model(&bytes)).await.unwrap();
    assert!(created);
    assert_eq!((m.origin.as_str(), m.job_id.as_deref()), ("uploaded", None));
    let (again, created) = s.insert_model(model(&bytes)).await.unwrap();
    assert!((!created, again.id.as_str()) == (true, m.id.as_str()));
    assert_eq!(s.model_file(&m.id).await.unwrap(), Some(bytes.clone()));
    let read = s.get_model(&m.id).await.unwrap().unwrap();
    assert_eq!(
        (read.sha256.as_str(), read.n, read.nq),
        (m.sha256.as_str(), 2, Some(4))
    );
    let (other, _) = s.insert_model(model(b"other")).await.unwrap();
    let (page, more) = s.list_models(None, 1).await.unwrap();
    assert_eq!((page[0].id.as_str(), more), (other.id.as_str(), true));
    let (page, more) = s.list_models(Some(page[0].seq), 10).await.unwrap();
    assert_eq!((page[0].id.as_str(), more), (m.id.as_str(), false));
    let asked = [m.id.clone(), "mdl_missing".to_string()];
    let found = s.existing_models(&asked).await.unwrap();
    assert!(found.contains(&m.id) && found.len() == 1, "{found:?}");

    s.delete_model(&m.id).await.unwrap();
    assert!(s.get_model(&m.id).await.unwrap().is_none());
    assert!(s.model_file(&m.id).await.unwrap().is_none());
    assert!(matches!(
        s.delete_model(&m.id).await,
        Err(Error::NotFound(_))
    ));
}
