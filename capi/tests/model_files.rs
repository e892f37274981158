//! The C library serves only a model file that proves it is whole: an edited one (a weight, a
//! member removed, an ensemble's members deleted) is refused with a status and this thread's
//! message naming the field; one written before files carried a checksum loads, and
//! `gbx_model_warning` says so.

use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::null_mut;

use graybox_c::*;
use graybox_core::model::file::ModelFile;
use serde_json::{Value, json};

fn compat(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../tests/fixtures/compat/{name}.gbx"))
}

fn load_buffer(bytes: &[u8]) -> (*mut GbxModel, GbxStatus) {
    let mut model = null_mut();
    // SAFETY: `bytes` is readable for its length; a place for the pointer.
    let status = unsafe { gbx_model_load_buffer(bytes.as_ptr(), bytes.len(), &mut model) };
    (model, status)
}

fn last_error() -> String {
    // SAFETY: the library keeps the message alive until this thread's next failure.
    unsafe { CStr::from_ptr(gbx_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// The model's warning, freeing the model.
fn warning_of(model: *mut GbxModel) -> Option<String> {
    // SAFETY: a model a load gave; its text lives until it is freed, after the copy.
    let text = unsafe { gbx_model_warning(model) };
    let text = (!text.is_null()).then(|| unsafe { CStr::from_ptr(text) }.to_string_lossy());
    let text = text.map(|t| t.into_owned());
    unsafe { gbx_model_free(model) };
    text
}

/// `bytes` does not load: an invalid argument whose message holds `words`.
fn refused(bytes: &[u8], words: &[&str]) {
    let (model, status) = load_buffer(bytes);
    assert!(model.is_null());
    assert_eq!(status, GbxStatus::InvalidArgument, "{}", last_error());
    let message = last_error();
    for w in words {
        assert!(message.contains(w), "'{w}' not in: {message}");
    }
}

#[test]
fn an_edited_model_file_is_refused_with_a_status_and_a_message() {
    // The ensemble as graybox writes it today: with its checksum.
    let old = std::fs::read(compat("wb-x3")).unwrap();
    let written = ModelFile::from_bytes(&old).unwrap().to_bytes().unwrap();
    let (model, status) = load_buffer(&written);
    assert_eq!(status, GbxStatus::Ok, "{}", last_error());
    assert_eq!(warning_of(model), None);

    let doc: Value = serde_json::from_slice(&written).unwrap();
    let edit = |f: &dyn Fn(&mut Value)| {
        let mut v = doc.clone();
        f(&mut v);
        serde_json::to_vec(&v).unwrap()
    };
    let weight = edit(&|v| {
        let w = &mut v["params"][0]["values"][0];
        *w = json!(w.as_f64().unwrap() * 1.001);
    });
    refused(&weight, &["checksum", "edited"]);
    let fewer = edit(&|v| {
        v["members"].as_array_mut().unwrap().pop();
    });
    refused(&fewer, &["members", "lists 3"]);
    let gone = edit(&|v| {
        v.as_object_mut().unwrap().remove("members");
    });
    refused(&gone, &["members"]);
}

#[test]
fn a_file_from_before_checksums_loads_with_a_warning() {
    let path = CString::new(compat("wb-x3").to_str().unwrap()).unwrap();
    let mut model = null_mut();
    // SAFETY: a NUL-terminated path and a place for the pointer.
    let status = unsafe { gbx_model_load(path.as_ptr(), &mut model) };
    assert_eq!(status, GbxStatus::Ok, "{}", last_error());
    let warning = warning_of(model).expect("a warning");
    assert!(warning.contains("no checksum"), "{warning}");
}
