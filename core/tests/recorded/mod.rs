//! The recorded model files the core's tests load (tests/fixtures at the workspace's root).

use std::path::Path;

use graybox_core::infer::Evaluator;
use graybox_core::model::file::ModelFile;

/// The evaluator of `tests/fixtures/{name}.gbx`.
pub fn load(name: &str) -> Evaluator {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../tests/fixtures/{name}.gbx"));
    let bytes = std::fs::read(path).unwrap();
    Evaluator::from_file(&ModelFile::from_bytes(&bytes).unwrap()).unwrap()
}
