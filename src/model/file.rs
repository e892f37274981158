//! The trained-model file (`.gbx`): config, parameters and the training report, as JSON.
//! f64 values print in shortest round-trip form, so loading gives back the exact weights.

use serde::{Deserialize, Serialize};
use std::path::Path;

use super::report::TrainReport;
use crate::error::{Error, Result};
use crate::model::params_io::{NamedArray, import};
use crate::model::{Model, ModelConfig};
use burn::tensor::Device;

pub const FORMAT: &str = "graybox.model/1";

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelFile {
    pub format: String,
    pub config: ModelConfig,
    pub params: Vec<NamedArray>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<TrainReport>,
}

impl ModelFile {
    pub fn new(config: ModelConfig, params: Vec<NamedArray>, report: Option<TrainReport>) -> Self {
        Self {
            format: FORMAT.to_string(),
            config,
            params,
            report,
        }
    }

    /// The file's bytes. A non-finite number (JSON would write it as null and the file would
    /// not load back) is an error naming where it is: such a model is never written.
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        if !self.config.scaling.is_finite() || !self.config.dt.is_finite() {
            return Err(Error::Training(
                "the model's scalings are not finite; the data's values are out of range".into(),
            ));
        }
        if let Some(a) = self
            .params
            .iter()
            .find(|a| a.values.iter().any(|v| !v.is_finite()))
        {
            return Err(Error::Training(format!(
                "the trained parameters '{}' are not finite; training diverged",
                a.name
            )));
        }
        Ok(serde_json::to_vec(self).expect("model files serialize"))
    }

    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        let f: ModelFile =
            serde_json::from_slice(bytes).map_err(|e| Error::corrupt("model file", e))?;
        if f.format != FORMAT {
            return Err(Error::corrupt(
                "model file",
                format!("format '{}' is not {FORMAT}", f.format),
            ));
        }
        Ok(f)
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        write_atomic(path, &self.to_bytes()?)
    }

    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path)
            .map_err(|e| Error::invalid("model", format!("cannot read {}: {e}", path.display())))?;
        Self::from_bytes(&bytes)
    }

    /// The model on `device` with these parameters.
    pub fn model(&self, device: &Device) -> Result<Model> {
        let skeleton = Model::init(self.config.clone(), None, 0, device)?;
        let params = import(skeleton.params, &self.params, device)?;
        Ok(Model::from_parts(self.config.clone(), params, device))
    }
}

/// Write to a temporary file beside the target, fsync, rename over the target: a crash leaves
/// the old file or the new one, never half of one; a failed write leaves no temporary file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut builder = tempfile::Builder::new();
    builder.prefix(".graybox-").suffix(".tmp");
    #[cfg(unix)]
    {
        // Readable like any file the user writes (a temporary file would be 0600).
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}
