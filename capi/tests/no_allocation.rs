//! Real-time use: once warmed up, gbx_predict and gbx_linearize (and their `_z` variants)
//! take every block they need from the calling thread's lists and none from the system
//! allocator (which may lock or page in). The library's allocator counts, per thread, the
//! allocations made inside those calls and how many of them reached the system.

use std::ffi::CString;
use std::ptr::{null, null_mut};

use graybox_c::pool::{Counts, counts};
use graybox_c::*;

const MODELS: [&str; 6] = [
    "inference/dp-mvf",
    "inference/cartpole-wb",
    "inference/formula-dp-wb",
    "inference/ur5-residual",
    "compat/mvf",
    "compat/wb-x3",
];

struct Loaded {
    model: *mut GbxModel,
    n: usize,
    m: usize,
}

fn load(name: &str) -> Loaded {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/fixtures");
    let path = CString::new(format!("{dir}/{name}.gbx")).unwrap();
    let mut model = null_mut();
    // SAFETY: a NUL-terminated path and a place for the pointer.
    let status = unsafe { gbx_model_load(path.as_ptr(), &mut model) };
    assert_eq!(status, GbxStatus::Ok, "{name}");
    // SAFETY: a loaded model.
    let (n, m) = unsafe { (gbx_model_n(model), gbx_model_m(model)) };
    Loaded { model, n, m }
}

/// One predict (with q̈ when asked) and one linearize of `batch` states near the origin, each
/// also with its z.
fn calls(l: &Loaded, batch: usize, accel: bool) {
    let nx = 2 * l.n;
    let x: Vec<f64> = (0..batch * nx).map(|i| 0.1 + 0.01 * i as f64).collect();
    let u = vec![0.2; batch * l.m];
    let (mut next, mut acc) = (vec![0.0; batch * nx], vec![0.0; batch * l.n]);
    let (mut a, mut b) = (vec![0.0; batch * nx * nx], vec![0.0; batch * nx * l.m]);
    let acc = if accel { acc.as_mut_ptr() } else { null_mut() };
    let mut z = vec![0.0; batch];
    let u = if l.m == 0 { null() } else { u.as_ptr() };
    // SAFETY: the buffers have the sizes the header documents.
    unsafe {
        let s = gbx_predict(l.model, x.as_ptr(), u, batch, next.as_mut_ptr(), acc);
        assert_eq!(s, GbxStatus::Ok);
        let s = gbx_linearize(
            l.model,
            x.as_ptr(),
            u,
            batch,
            a.as_mut_ptr(),
            b.as_mut_ptr(),
        );
        assert_eq!(s, GbxStatus::Ok);
        let (x, next) = (x.as_ptr(), next.as_mut_ptr());
        let s = gbx_predict_z(l.model, x, u, batch, next, acc, z.as_mut_ptr());
        assert_eq!(s, GbxStatus::Ok);
        let (a, b) = (a.as_mut_ptr(), b.as_mut_ptr());
        let s = gbx_linearize_z(l.model, x, u, batch, a, b, z.as_mut_ptr());
        assert_eq!(s, GbxStatus::Ok);
    }
}

fn since(before: Counts) -> Counts {
    let now = counts();
    Counts {
        served: now.served - before.served,
        system: now.system - before.system,
    }
}

#[test]
fn after_a_warm_up_call_predict_and_linearize_take_nothing_from_the_system() {
    for name in MODELS {
        let l = load(name);
        calls(&l, 1, true);
        calls(&l, 1, false);
        let before = counts();
        for k in 0..1000 {
            calls(&l, 1, k % 2 == 0);
        }
        let d = since(before);
        // The count sees the calls' allocations (the core's vectors), so zero below is the
        // lists' doing, not an allocator that was not asked.
        assert!(d.served > 0, "{name}: no allocation was counted");
        assert_eq!(
            d.system, 0,
            "{name}: {} system allocations after warm-up",
            d.system
        );
        // SAFETY: loaded above, freed once.
        unsafe { gbx_model_free(l.model) };
    }
}

#[test]
fn a_larger_batch_than_any_before_reaches_the_system_once() {
    let l = load("inference/cartpole-wb");
    calls(&l, 1, true);
    let before = counts();
    calls(&l, 8, true);
    assert!(since(before).system > 0, "larger blocks came from nowhere");
    let before = counts();
    calls(&l, 8, true);
    assert_eq!(since(before).system, 0);
    // SAFETY: loaded above, freed once.
    unsafe { gbx_model_free(l.model) };
}

#[test]
fn blocks_freed_on_other_threads_and_at_their_end_stay_sound() {
    let l = load("inference/ur5-residual");
    let kept: Vec<Vec<u8>> =
        graybox_c::pool::pooled(|| (0..64).map(|i| vec![i; 40 * i as usize + 1]).collect());
    let (model, n, m) = (l.model as usize, l.n, l.m);
    let workers: Vec<_> = (0..4)
        .map(|_| {
            std::thread::spawn(move || {
                let l = Loaded {
                    model: model as *mut GbxModel,
                    n,
                    m,
                };
                for k in 0..50 {
                    calls(&l, 1 + k % 3, k % 2 == 0);
                }
            })
        })
        .collect();
    // Pooled blocks of this thread, freed on another that then ends.
    std::thread::spawn(move || {
        for (i, v) in kept.iter().enumerate() {
            assert!(v.iter().all(|&b| b == i as u8));
        }
        drop(kept);
    })
    .join()
    .unwrap();
    workers.into_iter().for_each(|w| w.join().unwrap());
    calls(&l, 2, true);
    // SAFETY: every thread that used it has ended.
    unsafe { gbx_model_free(l.model) };
}

#[test]
fn over_aligned_grown_and_shrunk_blocks_keep_their_alignment_and_bytes() {
    #[repr(align(64))]
    struct Line([u8; 64]);
    graybox_c::pool::pooled(|| {
        let lines: Vec<Box<Line>> = (0..8).map(|i| Box::new(Line([i; 64]))).collect();
        for (i, l) in lines.iter().enumerate() {
            assert_eq!(&raw const **l as usize % 64, 0);
            assert!(l.0.iter().all(|&b| b == i as u8));
        }
        // Growing past a block's class moves it, past the largest class to the system;
        // shrinking stays in place.
        let mut v: Vec<u32> = Vec::new();
        for i in 0..1_000_000 {
            v.push(i);
        }
        v.truncate(10);
        v.shrink_to_fit();
        assert_eq!(v, (0..10).collect::<Vec<_>>());
    });
}
