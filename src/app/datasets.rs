//! Dataset uploads in the three accepted forms, validated and deduplicated by content.

use serde_json::Value;

use super::App;
use super::templates::off_executor;
use crate::data::Dataset;
use crate::data::log::{ImportOptions, ImportSummary, LogColumns, import_log};
use crate::error::{Error, Result};
use crate::names::check_name;
use crate::records::DatasetInfo;

/// What a POST /v1/datasets body was, with the Δt given beside it (`?dt=`), or a robot's log
/// with the columns and options of its import (`?time=…`, docs/logs.md).
pub enum Upload {
    Json {
        value: Value,
        dt: Option<f64>,
    },
    Csv {
        text: String,
        dt: Option<f64>,
    },
    Log {
        bytes: Vec<u8>,
        columns: LogColumns,
        options: ImportOptions,
    },
}

/// An upload's outcome: the stored dataset, whether this upload created it, and a note when
/// it did not do all it asked (the data was already stored under another name).
#[derive(Debug, Clone, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct Uploaded {
    #[serde(flatten)]
    pub dataset: DatasetInfo,
    pub created: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    /// A log's import: what it kept, dropped and estimated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub import: Option<ImportSummary>,
}

impl App {
    /// Validates and stores a dataset; the same arrays again return the stored one
    /// (`created = false`).
    pub async fn upload_dataset(&self, name: Option<String>, upload: Upload) -> Result<Uploaded> {
        let mut import = None;
        let (ds, body_name) = match upload {
            Upload::Csv { text, dt } => {
                let dt = dt.ok_or_else(|| Error::invalid("dt", "a CSV upload needs ?dt="))?;
                (Dataset::from_csv(&text, dt)?, None)
            }
            Upload::Log {
                bytes,
                columns,
                options,
            } => {
                // Fitting every grid time is seconds of work for a long log: off the executor.
                let (ds, summary) =
                    off_executor(move || import_log(&bytes, &columns, &options)).await?;
                import = Some(summary);
                (ds, None)
            }
            Upload::Json { value, dt } => {
                let body_name = match value.get("name") {
                    None | Some(Value::Null) => None,
                    Some(Value::String(s)) => Some(s.clone()),
                    Some(_) => return Err(Error::invalid("name", "must be a string")),
                };
                (Dataset::from_json_value(&value, dt)?, body_name)
            }
        };
        let name = name.or(body_name);
        if let Some(n) = &name {
            check_name(n)?;
        }
        let (store, asked) = (self.store.clone(), name.clone());
        let (row, created) =
            super::detached(async move { store.insert_dataset(asked.as_deref(), &ds).await })
                .await?;
        let dataset: DatasetInfo = row.into();
        let note = match (&name, &dataset.name) {
            (Some(asked), stored) if !created && stored.as_ref() != Some(asked) => Some(format!(
                "this data was already stored as {}{}; the name '{asked}' was not applied \
                 (a dataset is identified by its arrays)",
                dataset.id,
                stored
                    .as_ref()
                    .map_or(" without a name".to_string(), |s| format!(" named '{s}'"))
            )),
            _ => None,
        };
        Ok(Uploaded {
            dataset,
            created,
            note,
            import,
        })
    }

    pub async fn dataset(&self, id: &str) -> Result<DatasetInfo> {
        self.store
            .get_dataset(id)
            .await?
            .map(DatasetInfo::from)
            .ok_or_else(|| Error::NotFound(format!("dataset {id}")))
    }

    /// Deletes a dataset unless a queued or running job uses it (409).
    pub async fn delete_dataset(&self, id: &str) -> Result<()> {
        self.store.delete_dataset(id).await
    }
}
