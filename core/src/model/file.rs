//! The model file (`.gbx`, docs/model-file.md): config, parameters and the training report (or
//! how the model was made, for one that was not trained), as JSON, with a checksum over what
//! defines its answers (`checksum.rs`) that every write adds and every read checks.
//! f64 values print in shortest round-trip form, so loading gives back the exact weights.

use serde::{Deserialize, Serialize};
use std::path::Path;

use std::collections::BTreeMap;

use super::report::TrainReport;
use super::spec::ModelSpec;
use super::{ModelConfig, NamedArray, names};
use crate::error::{Error, Result};
use crate::physics::integrator::Integrator;
use crate::physics::params::Part;
use crate::physics::scaling::Scaling;
use crate::physics::templates::Template;
use crate::records::Warning;

mod checksum;
mod integrity;
#[cfg(test)]
mod tests;

pub use integrity::{MAX_MEMBERS, UNCHECKED};

/// The format of files whose template is a built-in one (older graybox versions read them).
pub const FORMAT: &str = "graybox.model/1";
/// The format of files that embed a template's document (a formula template or a URDF).
pub const FORMAT_EMBEDDED_TEMPLATE: &str = "graybox.model/2";

/// The format of an ensemble's files (any template): its members' parameters in `members`.
pub const FORMAT_ENSEMBLE: &str = "graybox.model/3";

/// The format of a model whose configuration space has a joint of nq ≠ nv (`joints` in its
/// config), single or an ensemble. A version that predates nq and nv would read such a file's
/// `n` (its nv) as n numbers and answer for another space; this format makes it refuse the
/// file by name instead.
pub const FORMAT_JOINTS: &str = "graybox.model/4";

/// The format a file with this configuration is written in.
fn format_of(config: &ModelConfig) -> &'static str {
    if !config.space.is_flat() {
        return FORMAT_JOINTS;
    }
    match config.template() {
        Some(Template::Formula(_) | Template::Urdf(_)) => FORMAT_EMBEDDED_TEMPLATE,
        _ => FORMAT,
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelFile {
    pub format: String,
    pub config: ModelConfig,
    pub params: Vec<NamedArray>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<TrainReport>,
    /// Set for a model made from a template's equations instead of trained (`graybox model`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub made: Option<Made>,
    /// An ensemble's members after the first (`params` is member 0's), in member order;
    /// empty for a single model ([`FORMAT_ENSEMBLE`] files only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<Vec<NamedArray>>,
    /// Read from a file without a checksum: nothing proved it whole ([`Self::unchecked_warning`]).
    /// Never written: `to_bytes` writes a fresh checksum instead.
    #[serde(skip)]
    unchecked: bool,
}

/// How a model that was not trained was made: a template's equations with these values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Made {
    pub template: String,
    pub physical_parameters: BTreeMap<String, f64>,
    pub note: String,
}

impl ModelFile {
    pub fn new(config: ModelConfig, params: Vec<NamedArray>, report: Option<TrainReport>) -> Self {
        Self {
            format: format_of(&config).to_string(),
            config,
            params,
            report,
            made: None,
            members: vec![],
            unchecked: false,
        }
    }

    /// The ensemble of these single-model files (one configuration, trained together) with
    /// the ensemble's report; one file stays what it is.
    pub fn ensemble(mut files: Vec<ModelFile>, report: Option<TrainReport>) -> Self {
        assert!(!files.is_empty(), "an ensemble has a member");
        let mut first = files.remove(0);
        if files.is_empty() {
            return first;
        }
        if first.format != FORMAT_JOINTS {
            first.format = FORMAT_ENSEMBLE.to_string();
        }
        first.members = files.into_iter().map(|f| f.params).collect();
        first.report = report;
        first
    }

    /// Members: 1 for a single model.
    pub fn member_count(&self) -> usize {
        1 + self.members.len()
    }

    /// Member `k` as a single model's file (without the ensemble's report).
    pub fn member(&self, k: usize) -> ModelFile {
        let mut file = Self::new(self.config.clone(), self.params.clone(), None);
        if k > 0 {
            file.params = self.members[k - 1].clone();
        } else {
            file.report = self.report.clone().filter(|_| self.members.is_empty());
        }
        file.made = self.made.clone();
        file.unchecked = self.unchecked;
        file
    }

    /// The white-box model of a template with the given physical values: "the true system"
    /// as a model, with no data and no training. Its scalings are the identity (a template's
    /// equations read no network and no data statistics). Nothing trains, so the values are
    /// stored as they are (`names::PHYSICAL_VALUES`), not in the trainable form: a URDF's
    /// massless link or point mass is the file's exactly, without the floors training needs.
    pub fn from_template(
        t: &Template,
        values: &[f64],
        dt: f64,
        integrator: Integrator,
    ) -> Result<Self> {
        let (lo, hi) = crate::data::DT_RANGE;
        if !(dt.is_finite() && (lo..=hi).contains(&dt)) {
            return Err(Error::invalid(
                "dt",
                format!("must be a number of seconds in [{lo:e}, {hi}], got {dt}"),
            ));
        }
        // Values the trainable form refuses (a body that is not physical) are refused here too.
        t.raw_from_physical(values)?;
        // Continuous joints and a formula's angles stay angles: a row that wraps across π must
        // cost its true difference, not (2π)². None marked is stored empty, as training does.
        let config = ModelConfig {
            spec: ModelSpec::named("W-B", Some(t.clone()))?,
            space: t.space(),
            m: t.m(),
            dt,
            integrator,
            lambda: 1.0,
            scaling: Scaling::identity(t.nq(), t.n(), t.m()),
        };
        let params = vec![NamedArray {
            name: names::PHYSICAL_VALUES.to_string(),
            shape: vec![1, values.len()],
            values: values.to_vec(),
        }];
        let mut file = Self::new(config, params, None);
        file.made = Some(Made {
            template: t.name().to_string(),
            physical_parameters: t
                .params()
                .iter()
                .zip(values)
                .map(|(p, v)| (p.name.to_string(), *v))
                .collect(),
            note: "made from the template's equations with these values; not trained".into(),
        });
        Ok(file)
    }

    /// The file's bytes. A non-finite number (JSON would write it as null and the file would
    /// not load back) is an error naming where it is: such a model is never written.
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        if !self.config.scaling.is_finite() || !self.config.dt.is_finite() {
            return Err(Error::Training(
                "the model's scalings are not finite; the data's values are out of range".into(),
            ));
        }
        if let Some(a) = (self.params.iter())
            .chain(self.members.iter().flatten())
            .find(|a| a.values.iter().any(|v| !v.is_finite()))
        {
            return Err(Error::Training(format!(
                "the trained parameters '{}' are not finite; training diverged",
                a.name
            )));
        }
        self.check_members()?;
        Ok(self.sealed())
    }

    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        // XML where a model file's JSON should be: most likely a robot's URDF, which is a
        // template, not a model.
        if bytes.trim_ascii_start().starts_with(b"<") {
            return Err(Error::corrupt(
                "model file",
                "this is XML (a URDF?), not a graybox model file (JSON, .gbx): a URDF is a \
                 template, given as --template robot.urdf to `graybox model` (a model of it \
                 with its values), `train`, `simulate`; or POST /v1/templates",
            ));
        }
        let mut f: ModelFile =
            serde_json::from_slice(bytes).map_err(|e| Error::corrupt("model file", e))?;
        let known = [
            FORMAT,
            FORMAT_EMBEDDED_TEMPLATE,
            FORMAT_ENSEMBLE,
            FORMAT_JOINTS,
        ];
        if !known.contains(&f.format.as_str()) {
            return Err(Error::corrupt(
                "model file",
                format!("format '{}' is not one of {}", f.format, known.join(", ")),
            ));
        }
        if !f.members.is_empty() && ![FORMAT_ENSEMBLE, FORMAT_JOINTS].contains(&f.format.as_str()) {
            return Err(Error::corrupt(
                "model file",
                format!(
                    "format '{}' has no members (an ensemble is {FORMAT_ENSEMBLE}, or \
                     {FORMAT_JOINTS} on a space of nq ≠ nv)",
                    f.format
                ),
            ));
        }
        f.check_members()?;
        f.check_seal(bytes)?;
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

    /// The physical values of the template's parameters (the template's own when no part is
    /// white-box); None without a template.
    pub fn physical_values(&self) -> Option<Vec<f64>> {
        let t = self.config.template()?;
        let array = |name: &str| self.params.iter().find(|a| a.name == name);
        Some(
            match (array(names::PHYSICAL_VALUES), array(names::PHYSICAL)) {
                (Some(a), _) => a.values.clone(),
                (None, Some(a)) => t.physical_from_raw(&a.values),
                (None, None) => t.defaults(),
            },
        )
    }

    /// Whether this model's template forces are too stiff for its step (`sim::stiffness_warning`,
    /// at q = 0 and `configurations`).
    pub fn stiffness_warning(&self, configurations: &[Vec<f64>]) -> Option<Warning> {
        stiffness_of(&self.config, &self.physical_values()?, configurations)
    }

    /// The identified robot as URDF (`urdf::export`): a model whose template is not a URDF
    /// robot has none (failed precondition).
    pub fn urdf(&self) -> Result<String> {
        let Some(Template::Urdf(u)) = self.config.template() else {
            return Err(Error::FailedPrecondition(
                "this model's template is not a URDF robot, so it has no URDF".into(),
            ));
        };
        let physical = self.physical_values().expect("a template model");
        // Files trained before damping and friction were kept ≥ 0 can hold negative ones,
        // which the URDF reader refuses (and Pinocchio's, for friction): no file rather than
        // a silently different robot.
        for (info, v) in u.params().iter().zip(&physical) {
            if let Some(why) = info.out_of_bounds(*v) {
                return Err(Error::FailedPrecondition(format!(
                    "{} {why}: this model was trained by a graybox that did not keep it \
                     there; train it again to export it",
                    info.name
                )));
            }
        }
        crate::physics::urdf::export::export(u, &physical)
    }
}

/// The stiffness warning of a model with this configuration at these physical values: only
/// when its forces are the template's (a network's stiffness is not the template's to judge).
pub fn stiffness_of(
    config: &ModelConfig,
    physical: &[f64],
    configurations: &[Vec<f64>],
) -> Option<Warning> {
    let t = config.template()?;
    if !config.spec.white_box_parts().contains(&Part::Forces) {
        return None;
    }
    crate::sim::stiffness_warning(t, physical, config.dt, config.integrator, configurations)
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
