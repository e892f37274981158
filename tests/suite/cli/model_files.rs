//! The CLI reads a model file as every reader does: an edited one is refused naming its
//! checksum, and one written before files carried a checksum is read with a warning on stderr.

use serde_json::{Value, json};

use super::{graybox, json, pendulum_model, tmp};

fn compat(name: &str) -> String {
    format!(
        "{}/tests/fixtures/compat/{name}.gbx",
        env!("CARGO_MANIFEST_DIR")
    )
}

#[test]
fn a_file_from_before_checksums_is_read_with_a_warning_on_stderr() {
    let out = graybox(&["inspect", "--model", &compat("wb-x3")]);
    json(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning:") && err.contains("no checksum"),
        "{err}"
    );

    let written = pendulum_model("written.gbx");
    let out = graybox(&["inspect", "--model", &written]);
    json(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("checksum"), "{err}");
}

#[test]
fn an_edited_file_is_refused_naming_its_checksum() {
    let written = pendulum_model("to-edit.gbx");
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&written).unwrap()).unwrap();
    assert!(doc["checksum"].is_string(), "{}", doc["checksum"]);
    let value = &mut doc["params"][0]["values"][0];
    *value = json!(value.as_f64().unwrap() * 1.001);
    let edited = tmp("edited.gbx");
    std::fs::write(&edited, serde_json::to_vec(&doc).unwrap()).unwrap();
    let unused = tmp("unused");
    for args in [
        vec!["inspect", "--model", &edited],
        vec!["energy", "--model", &edited, "--data", &unused],
        vec!["export-urdf", "--model", &edited, "--out", &unused],
    ] {
        let out = graybox(&args);
        assert!(!out.status.success(), "{args:?} read an edited file");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("checksum") && err.contains("edited"),
            "{args:?}: {err}"
        );
    }
}
