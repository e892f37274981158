//! The f64 [`Data`] each thread keeps for the one-call entry points, grown to the largest
//! model it has served, and the lending of a caller's own in its place for a call
//! (`infer::Workspace` carries one, so its calls allocate nothing on any thread).

use std::any::{Any, TypeId};
use std::cell::RefCell;

use super::Model;
use super::data::Data;
use crate::physics::scalar::Scalar;

/// A workspace of f64 that can change hands (between a thread and a caller's workspace:
/// [`lending`]) by moving a pointer.
pub type Lent = Option<Box<Data>>;

thread_local! {
    /// This thread's f64 workspace, made at its first use, unless one is lent to it.
    static WORKSPACE: RefCell<Lent> = const { RefCell::new(None) };
}

/// `f` with this thread's f64 workspace, grown to the largest model the thread has served (a
/// fresh one if the thread's is in use further up the stack).
pub fn with_data<R>(f: impl FnOnce(&mut Data) -> R) -> R {
    WORKSPACE.with(|d| match d.try_borrow_mut() {
        Ok(mut d) => f(d.get_or_insert_with(Box::default)),
        Err(_) => f(&mut Data::default()),
    })
}

/// `f` with `data` as this thread's workspace (what [`with_data`] hands out), the thread's
/// own given back after, even if `f` panics: a caller-owned workspace (`infer::Workspace`)
/// brings its multibody scratch to whichever thread runs its calls, so that a thread's first
/// call allocates nothing either. `data` then holds what the thread's calls left in it.
pub fn lending<R>(data: &mut Lent, f: impl FnOnce() -> R) -> R {
    /// Swaps back when dropped (a nested call, whose thread's workspace is in use, swaps
    /// neither way).
    struct Swapped<'d>(&'d mut Lent);
    impl Drop for Swapped<'_> {
        fn drop(&mut self) {
            swap_with_thread(self.0);
        }
    }
    fn swap_with_thread(data: &mut Lent) {
        WORKSPACE.with(|cell| {
            if let Ok(mut own) = cell.try_borrow_mut() {
                std::mem::swap(&mut *own, data);
            }
        });
    }
    swap_with_thread(data);
    let _back = Swapped(data);
    f()
}

/// `f` on a workspace for coordinates like `q`: this thread's for f64 (`with_data`: the
/// one-call entry points in `aba.rs` and `rnea.rs` allocate nothing after a thread's first),
/// a fresh one for any other scalar, whose values' kind (a batch column's length, a dual
/// number's directions) is the call's.
pub fn with_workspace<S: Scalar, R>(
    model: &Model,
    q: &[S],
    f: impl FnOnce(&mut Data<S>) -> R,
) -> R {
    if TypeId::of::<S>() == TypeId::of::<f64>() {
        return with_data(|d| {
            let d = (d as &mut dyn Any).downcast_mut::<Data<S>>();
            f(d.expect("S is f64"))
        });
    }
    f(&mut Data::for_state(model, q))
}
