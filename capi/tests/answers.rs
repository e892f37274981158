//! The C library answers as the service does, bit for bit: every Predict, Linearize and
//! Rollout the service answered in tests/fixtures/inference/answers.json (recorded by
//! scripts/inference_fixtures.sh before the inference core moved out of the service),
//! replayed through the C ABI, and through the `_z` calls with the max_abs_z the service
//! answered. And its errors: a status and this thread's message.

use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::null_mut;

use graybox_c::*;
use serde_json::Value;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn floats(v: &Value) -> Vec<f64> {
    match v {
        Value::Array(a) => a.iter().flat_map(floats).collect(),
        v => vec![v.as_f64().expect("a number")],
    }
}

fn load(path: &Path) -> (*mut GbxModel, GbxStatus) {
    let c = CString::new(path.to_str().unwrap()).unwrap();
    let mut model = null_mut();
    // SAFETY: a NUL-terminated path and a place for the pointer.
    let status = unsafe { gbx_model_load(c.as_ptr(), &mut model) };
    (model, status)
}

fn last_error() -> String {
    // SAFETY: the library keeps the message alive until this thread's next failure.
    unsafe { CStr::from_ptr(gbx_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// Equal bits, value by value (so −0.0 is not 0.0), naming the first that differs.
fn same(got: &[f64], want: &[f64], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    if let Some(i) = (0..got.len()).find(|&i| got[i].to_bits() != want[i].to_bits()) {
        panic!("{what}[{i}]: {:e} != {:e}", got[i], want[i]);
    }
}

/// One recorded call through the ABI; false for the calls the C library does not offer.
fn replay(model: *const GbxModel, n: usize, m: usize, call: &Value, what: &str) -> bool {
    let nx = 2 * n;
    let answer = &call["answer"];
    if let Some(z) = answer.get("max_abs_z") {
        replay_z(model, n, m, call, &floats(z), what);
    }
    // SAFETY (every call below): the buffers have the sizes the header documents.
    match call["rpc"].as_str().unwrap() {
        "predict" => {
            let (x, u) = (floats(&call["x"]), floats(&call["u"]));
            let batch = x.len() / nx;
            let (mut next, mut acc) = (vec![0.0; batch * nx], vec![0.0; batch * n]);
            let s = unsafe {
                gbx_predict(
                    model,
                    x.as_ptr(),
                    u.as_ptr(),
                    batch,
                    next.as_mut_ptr(),
                    acc.as_mut_ptr(),
                )
            };
            assert_eq!(s, GbxStatus::Ok, "{what}: {}", last_error());
            same(&next, &floats(&answer["x_next"]), &format!("{what} x_next"));
            same(&acc, &floats(&answer["accel"]), &format!("{what} accel"));
        }
        "linearize" => {
            let (x, u) = (floats(&call["x"]), floats(&call["u"]));
            let batch = x.len() / nx;
            let (mut a, mut b) = (vec![0.0; batch * nx * nx], vec![0.0; batch * nx * m]);
            let s = unsafe {
                gbx_linearize(
                    model,
                    x.as_ptr(),
                    u.as_ptr(),
                    batch,
                    a.as_mut_ptr(),
                    b.as_mut_ptr(),
                )
            };
            assert_eq!(s, GbxStatus::Ok, "{what}: {}", last_error());
            same(&a, &floats(&answer["A"]), &format!("{what} A"));
            same(&b, &floats(&answer["B"]), &format!("{what} B"));
        }
        "rollout" => {
            let (x0, u) = (floats(&call["x0"]), floats(&call["u"]));
            let steps = u.len() / m;
            let mut xs = vec![0.0; (steps + 1) * nx];
            let s = unsafe { gbx_rollout(model, x0.as_ptr(), u.as_ptr(), steps, xs.as_mut_ptr()) };
            assert_eq!(s, GbxStatus::Ok, "{what}: {}", last_error());
            same(&xs, &floats(&answer["xs"]), &format!("{what} xs"));
        }
        _ => return false,
    }
    true
}

/// One recorded call through its `_z` entry point: the same answer, and the service's z.
fn replay_z(model: *const GbxModel, n: usize, m: usize, call: &Value, want: &[f64], what: &str) {
    let (nx, answer) = (2 * n, &call["answer"]);
    let mut z = vec![f64::NAN; want.len()];
    // SAFETY (every call below): the buffers have the sizes the header documents.
    match call["rpc"].as_str().unwrap() {
        "predict" => {
            let (x, u) = (floats(&call["x"]), floats(&call["u"]));
            let batch = x.len() / nx;
            let (mut next, mut acc) = (vec![0.0; batch * nx], vec![0.0; batch * n]);
            let s = unsafe {
                gbx_predict_z(
                    model,
                    x.as_ptr(),
                    u.as_ptr(),
                    batch,
                    next.as_mut_ptr(),
                    acc.as_mut_ptr(),
                    z.as_mut_ptr(),
                )
            };
            assert_eq!(s, GbxStatus::Ok, "{what}: {}", last_error());
            same(
                &next,
                &floats(&answer["x_next"]),
                &format!("{what} x_next (z)"),
            );
            same(
                &acc,
                &floats(&answer["accel"]),
                &format!("{what} accel (z)"),
            );
        }
        "linearize" => {
            let (x, u) = (floats(&call["x"]), floats(&call["u"]));
            let batch = x.len() / nx;
            let (mut a, mut b) = (vec![0.0; batch * nx * nx], vec![0.0; batch * nx * m]);
            let s = unsafe {
                gbx_linearize_z(
                    model,
                    x.as_ptr(),
                    u.as_ptr(),
                    batch,
                    a.as_mut_ptr(),
                    b.as_mut_ptr(),
                    z.as_mut_ptr(),
                )
            };
            assert_eq!(s, GbxStatus::Ok, "{what}: {}", last_error());
            same(&a, &floats(&answer["A"]), &format!("{what} A (z)"));
            same(&b, &floats(&answer["B"]), &format!("{what} B (z)"));
        }
        "rollout" => {
            let (x0, u) = (floats(&call["x0"]), floats(&call["u"]));
            let steps = u.len() / m;
            let mut xs = vec![0.0; (steps + 1) * nx];
            let s = unsafe {
                gbx_rollout_z(
                    model,
                    x0.as_ptr(),
                    u.as_ptr(),
                    steps,
                    xs.as_mut_ptr(),
                    z.as_mut_ptr(),
                )
            };
            assert_eq!(s, GbxStatus::Ok, "{what}: {}", last_error());
            same(&xs, &floats(&answer["xs"]), &format!("{what} xs (z)"));
        }
        rpc => panic!("{what}: the record has z for {rpc}"),
    }
    same(&z, want, &format!("{what} max_abs_z"));
}

#[test]
fn the_c_library_gives_the_services_recorded_answers_bit_for_bit() {
    let text = std::fs::read_to_string(root().join("tests/fixtures/inference/answers.json"));
    let record: Value = serde_json::from_str(&text.unwrap()).unwrap();
    let (mut replayed, mut with_z) = (0, 0);
    for (name, entry) in record.as_object().unwrap() {
        let (model, status) = load(&root().join(entry["file"].as_str().unwrap()));
        assert_eq!(status, GbxStatus::Ok, "{name}: {}", last_error());
        let (n, m) = unsafe { (gbx_model_n(model), gbx_model_m(model)) };
        assert_eq!(
            (n as u64, m as u64),
            (entry["n"].as_u64().unwrap(), entry["m"].as_u64().unwrap())
        );
        for (k, call) in entry["calls"].as_array().unwrap().iter().enumerate() {
            replayed += replay(model, n, m, call, &format!("{name} call {k}")) as usize;
            with_z += call["answer"].get("max_abs_z").is_some() as usize;
        }
        unsafe { gbx_model_free(model) };
    }
    // Six models, each with two Predicts, two Linearizes and a Rollout, each with its z.
    assert_eq!(replayed, 30);
    assert_eq!(with_z, 30, "every replayed answer has the service's z");
}

#[test]
fn failures_return_a_status_and_a_message() {
    let (model, status) = load(&root().join("no/such/model.gbx"));
    assert_eq!(status, GbxStatus::Io);
    assert!(model.is_null());
    assert!(
        last_error().contains("no/such/model.gbx"),
        "{}",
        last_error()
    );

    let urdf = root().join("tests/fixtures/urdf/robots/ur5.urdf");
    assert_eq!(load(&urdf).1, GbxStatus::Corrupt);
    assert!(last_error().contains("URDF"), "{}", last_error());

    let (model, status) = load(&root().join("tests/fixtures/inference/dp-mvf.gbx"));
    assert_eq!(status, GbxStatus::Ok);
    let mut next = [0.0; 4];
    let x = [0.1, 0.2, 0.3, 0.4];
    // SAFETY: a loaded model; `u` is null on purpose, x and x_next hold one state.
    let s = unsafe {
        gbx_predict(
            model,
            x.as_ptr(),
            std::ptr::null(),
            1,
            next.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("u:"), "{}", last_error());
    let s = unsafe {
        gbx_predict(
            model,
            x.as_ptr(),
            x.as_ptr(),
            0,
            next.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("batch:"), "{}", last_error());
    // A batch whose arrays no memory could hold is refused before any pointer is read (its
    // product of sizes would wrap around to a small length).
    let huge = usize::MAX / 2 + 1;
    let s = unsafe {
        gbx_predict(
            model,
            x.as_ptr(),
            x.as_ptr(),
            huge,
            next.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("x:"), "{}", last_error());
    let mut xs = [0.0; 8];
    let s = unsafe { gbx_rollout(model, x.as_ptr(), x.as_ptr(), usize::MAX, xs.as_mut_ptr()) };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("u:"), "{}", last_error());
    unsafe { gbx_model_free(model) };
}

/// A NaN or infinity among the inputs is blamed on its argument and row, before computing
/// (it once came back as a non-finite state of "x0" a step later, or as "x").
#[test]
fn non_finite_inputs_are_blamed_on_their_argument() {
    let (model, status) = load(&root().join("tests/fixtures/inference/dp-mvf.gbx"));
    assert_eq!(status, GbxStatus::Ok);
    let x0 = [0.1, 0.2, 0.0, 0.0];
    let mut u = [0.0; 2 * 10];
    u[2 * 5 + 1] = f64::NAN;
    let mut xs = [0.0; 4 * 11];
    // SAFETY (every call): a loaded model and buffers of the documented sizes.
    let s = unsafe { gbx_rollout(model, x0.as_ptr(), u.as_ptr(), 10, xs.as_mut_ptr()) };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("u: row 5 "), "{}", last_error());
    let x = [x0, x0].concat();
    let mut next = [0.0; 8];
    let s = unsafe {
        gbx_predict(
            model,
            x.as_ptr(),
            u.as_ptr().add(8),
            2,
            next.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("u: row 1 "), "{}", last_error());
    let (mut a, mut b) = ([0.0; 32], [0.0; 16]);
    let s = unsafe {
        gbx_linearize(
            model,
            x.as_ptr(),
            u.as_ptr().add(8),
            2,
            a.as_mut_ptr(),
            b.as_mut_ptr(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("u: row 1 "), "{}", last_error());
    let mut bad = x0;
    bad[2] = f64::INFINITY;
    let s = unsafe { gbx_rollout(model, bad.as_ptr(), u.as_ptr(), 5, xs.as_mut_ptr()) };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("x0: row 0 "), "{}", last_error());
    unsafe { gbx_model_free(model) };
}
