//! What the C library's test binaries share: the recorded model files, loaded through the C
//! ABI, and this thread's last error. (Each binary uses some of them.)
#![allow(dead_code)]

use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::null_mut;

use graybox_c::*;

/// `tests/fixtures/{name}.gbx` at the workspace's root.
pub fn path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../tests/fixtures/{name}.gbx"))
}

/// The model file `name` (as `path`) loaded by `gbx_model_load`.
pub fn load(name: &str) -> *mut GbxModel {
    let c = CString::new(path(name).to_str().unwrap()).unwrap();
    let mut model = null_mut();
    // SAFETY: a NUL-terminated path and a place for the pointer.
    assert_eq!(
        unsafe { gbx_model_load(c.as_ptr(), &mut model) },
        GbxStatus::Ok
    );
    model
}

pub fn last_error() -> String {
    // SAFETY: the library keeps the message alive until this thread's next failure.
    unsafe { CStr::from_ptr(gbx_last_error()) }
        .to_string_lossy()
        .into_owned()
}
