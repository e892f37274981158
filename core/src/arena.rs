//! Per-call scratch. Every intermediate vector of an evaluation is allocated in an [`Arena`]
//! the caller owns (`infer::Workspace` holds one, emptied at the start of each call), never
//! on the heap: once a workspace has grown to its model's largest call, a call reaches the
//! system allocator no more, by construction (MuJoCo's `mjData` arena plays this part, and
//! Pinocchio's `Data`). Training, which allocates freely, gives each step an arena of its own.
//!
//! An arena's vectors run their elements' destructors but return no memory until the arena
//! is reset, so a type that owns heap memory of its own (a batch column) still frees it.

pub use bumpalo::Bump as Arena;
pub use bumpalo::collections::CollectIn;
pub use bumpalo::vec as avec;

/// A vector in an arena.
pub type AVec<'a, T> = bumpalo::collections::Vec<'a, T>;

/// `len` zeros in `a`, written in one fill (`avec![in a; 0.0; len]` pushes them one at a time,
/// which took a fifth of a small network's evaluation).
pub fn zeros(a: &Arena, len: usize) -> AVec<'_, f64> {
    let mut v = AVec::with_capacity_in(len, a);
    v.resize(len, 0.0);
    v
}
