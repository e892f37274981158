//! Trained models: listing, reading, the model file, deletion.

use super::App;
use super::views::{Dataset, Model};
use crate::error::{Error, Result};
use crate::store::{JobState, ModelRow};

impl App {
    async fn model_row(&self, id: &str) -> Result<ModelRow> {
        self.store
            .get_model(id)
            .await?
            .ok_or_else(|| Error::NotFound(format!("model {id}")))
    }

    pub async fn model(&self, id: &str) -> Result<Model> {
        self.model_row(id).await.map(Model::from)
    }

    /// A model by its id, or by the id of the job that trained it (gRPC callers may name
    /// either); a job that has not succeeded is a failed precondition.
    pub async fn resolve_model(&self, id: &str) -> Result<Model> {
        self.resolve_model_row(id).await.map(Model::from)
    }

    pub(super) async fn resolve_model_row(&self, id: &str) -> Result<ModelRow> {
        if id.is_empty() {
            return Err(Error::invalid("model_id", "is required"));
        }
        if let Some(m) = self.store.get_model(id).await? {
            return Ok(m);
        }
        match self.store.get_job(id).await? {
            Some(job) if job.state == JobState::Succeeded => match job.info.model_id {
                Some(mid) => self.model_row(&mid).await,
                None => Err(Error::NotFound(format!("model of job {id}"))),
            },
            Some(job) => Err(Error::FailedPrecondition(format!(
                "job {id} is {}; it has no model until it succeeds",
                job.state.as_str()
            ))),
            None => Err(Error::NotFound(format!("model {id}"))),
        }
    }

    pub async fn model_file(&self, id: &str) -> Result<Vec<u8>> {
        self.store
            .model_file(id)
            .await?
            .ok_or_else(|| Error::NotFound(format!("model {id}")))
    }

    pub async fn list_models(
        &self,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<Model>, Option<String>)> {
        let size = super::paging::size(size)?;
        let before = super::paging::decode("models", token)?;
        let items = self.store.list_models(before, size).await?;
        let next = super::paging::next("models", &items, size, |m| m.seq);
        Ok((items.into_iter().map(Model::from).collect(), next))
    }

    pub async fn list_datasets(
        &self,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<Dataset>, Option<String>)> {
        let size = super::paging::size(size)?;
        let before = super::paging::decode("datasets", token)?;
        let items = self.store.list_datasets(before, size).await?;
        let next = super::paging::next("datasets", &items, size, |d| d.seq);
        Ok((items.into_iter().map(Dataset::from).collect(), next))
    }
}
