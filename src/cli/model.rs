//! `graybox model`: the white-box model of a template with given physical values, written as
//! a model file without data or training ("the true system" as a model).

use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::json;

use crate::error::Result;
use crate::model::file::ModelFile;
use crate::physics::integrator::Integrator;
use crate::sim::parse_assignments;

#[derive(Args, Debug)]
pub struct ModelArgs {
    /// Template: double_pendulum, pendulum, cartpole, planar_body, a template document's JSON file, or a
    /// URDF file.
    #[arg(long)]
    pub template: String,
    /// Physical values, e.g. m1=10,l2=0.8 (others keep the template's defaults).
    #[arg(long)]
    pub set: Option<String>,
    /// The model's time step, seconds.
    #[arg(long)]
    pub dt: f64,
    /// rk4, euler or midpoint.
    #[arg(long, default_value = "rk4")]
    pub integrator: String,
    /// Where to write the model file (.gbx).
    #[arg(long)]
    pub out: PathBuf,
}

pub(super) fn model(a: ModelArgs) -> Result<()> {
    let t = super::template_arg(&a.template)?;
    let values = parse_assignments(&t, a.set.as_deref(), "set")?;
    let integrator = Integrator::parse(&a.integrator)?;
    let file = ModelFile::from_template(&t, &values, a.dt, integrator)?;
    file.save(&a.out)?;
    let warnings: Vec<_> = file.stiffness_warning(&[]).into_iter().collect();
    for w in &warnings {
        eprintln!("warning: {}", w.message);
    }
    let c = &file.config;
    let mut out = json!({"out": a.out, "template": t.name(), "nq": c.nq(), "nv": c.nv(),
        "m": file.config.m, "dt": a.dt, "integrator": a.integrator,
        "physical_parameters": file.made.as_ref().map(|m| &m.physical_parameters)});
    if !warnings.is_empty() {
        out["warnings"] = json!(warnings);
    }
    super::say(&out)?;
    Ok(())
}

/// A model file for a command, as `ModelFile::load` reads it (refused when it does not prove
/// it is whole), with the warning of a file from before checksums on stderr, where every
/// command's warnings go.
pub(super) fn read(path: &Path) -> Result<ModelFile> {
    let file = ModelFile::load(path)?;
    if let Some(w) = file.unchecked_warning() {
        eprintln!("warning: {}: {}", path.display(), w.message);
    }
    Ok(file)
}

#[derive(Args, Debug)]
pub struct ExportUrdfArgs {
    /// A model file whose template is a URDF robot.
    #[arg(long)]
    pub model: PathBuf,
    /// Where to write the URDF.
    #[arg(long)]
    pub out: PathBuf,
}

/// The identified robot: the template's URDF with the model's `<inertial>` and `<dynamics>`.
pub(super) fn export_urdf(a: ExportUrdfArgs) -> Result<()> {
    let file = read(&a.model)?;
    let text = file.urdf()?;
    crate::model::file::write_atomic(&a.out, text.as_bytes())?;
    super::say(json!({"out": a.out, "bytes": text.len()}))?;
    Ok(())
}
