//! The library's allocator: what a controller's real-time loop needs from `gbx_predict` and
//! `gbx_linearize` is that they never call into the system allocator (which may lock, fault
//! pages in or take unbounded time) once warmed up. The inference core builds small vectors
//! as it goes (the generic math returns them), so during those calls every block comes from a
//! free list of the calling thread, by power-of-two size class, and goes back to one when
//! freed: a pop and a push, no lock, no system call. The lists fill during the warm-up call
//! and keep what the calls' peak needed; outside those calls (loading a model, the host's own
//! Rust code) blocks come from the system allocator as usual.
//!
//! Every block carries its origin in the word before it, so a block is returned where it came
//! from whichever thread frees it and whenever. A thread's lists go back to the system when
//! the thread ends.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ptr::null_mut;

/// The smallest and largest pooled block, header included (32 B and 1 MiB): larger blocks
/// belong to batches far beyond one controller step, which come from the system.
const MIN_CLASS: u32 = 5;
const MAX_CLASS: u32 = 20;
const CLASSES: usize = MAX_CLASS as usize + 1;
/// Room before every block for its origin (and, in a free pooled block, the list's link).
const HEADER: usize = 16;
/// The origin of a block from the system allocator; pooled blocks carry their class.
const SYSTEM: usize = 0;

/// What a thread's lists are doing: empty and never used, in use, or gone with the thread.
const FRESH: u8 = 0;
const REGISTERING: u8 = 1;
const LIVE: u8 = 2;
const DEAD: u8 = 3;

thread_local! {
    // Const-initialised and without destructors, so they stay usable while the thread's
    // other destructors run (which free blocks too).
    static HOT: Cell<bool> = const { Cell::new(false) };
    static STATE: Cell<u8> = const { Cell::new(FRESH) };
    static FREE: [Cell<*mut u8>; CLASSES] = const { [const { Cell::new(null_mut()) }; CLASSES] };
    static COUNTS: Cell<Counts> = const { Cell::new(Counts { served: 0, system: 0 }) };
    static DRAIN: Drain = const { Drain };
}

/// This thread's allocations inside pooled calls: all of them, and those the system served
/// (a list was empty: the warm-up, or a larger call than before).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Counts {
    pub served: u64,
    pub system: u64,
}

/// This thread's counts so far.
pub fn counts() -> Counts {
    COUNTS.with(Cell::get)
}

/// Runs `f` with its allocations served from this thread's lists.
pub fn pooled<T>(f: impl FnOnce() -> T) -> T {
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            HOT.with(|h| h.set(self.0));
        }
    }
    let _restore = Restore(HOT.with(|h| h.replace(true)));
    f()
}

/// The allocator the library installs.
pub struct Pool;

/// The class of a block that holds `size` bytes after its header, if it is pooled.
fn class_of(layout: Layout) -> Option<usize> {
    if layout.align() > HEADER {
        return None;
    }
    let total = layout.size().checked_add(HEADER)?.next_power_of_two();
    let class = total.trailing_zeros().max(MIN_CLASS);
    (class <= MAX_CLASS).then_some(class as usize)
}

fn block_layout(class: usize) -> Layout {
    // A power of two no larger than 1 MiB with the header's alignment: always valid.
    Layout::from_size_align(1 << class, HEADER).expect("a pooled block's layout")
}

/// The system block behind a block from the system allocator: its header is `align` bytes
/// (at least HEADER) so that what follows keeps the alignment asked for.
fn system_layout(layout: Layout) -> Option<(Layout, usize)> {
    let prefix = layout.align().max(HEADER);
    let size = layout.size().checked_add(prefix)?;
    Some((Layout::from_size_align(size, prefix).ok()?, prefix))
}

/// # Safety
/// `p` is a block this allocator gave.
unsafe fn origin(p: *mut u8) -> usize {
    // SAFETY: every block has its origin in the word before it.
    unsafe { p.sub(size_of::<usize>()).cast::<usize>().read() }
}

/// # Safety
/// `base` is the start of a system block with room for the header and `size` more bytes.
unsafe fn tag(base: *mut u8, prefix: usize, class: usize) -> *mut u8 {
    // SAFETY: the header lies within the block and is aligned for a usize.
    unsafe {
        let p = base.add(prefix);
        p.sub(size_of::<usize>()).cast::<usize>().write(class);
        p
    }
}

fn count(system: bool) {
    COUNTS.with(|c| {
        let mut k = c.get();
        k.served += 1;
        k.system += u64::from(system);
        c.set(k);
    });
}

/// A pooled block of `class` from this thread's list, or a new one from the system.
///
/// # Safety
/// As [`GlobalAlloc::alloc`].
unsafe fn take(class: usize) -> *mut u8 {
    let popped = FREE.with(|lists| {
        let head = lists[class].get();
        if !head.is_null() {
            // SAFETY: a free block's first word links the next one.
            lists[class].set(unsafe { head.cast::<*mut u8>().read() });
        }
        head
    });
    count(popped.is_null());
    let base = if popped.is_null() {
        // SAFETY: a non-zero size.
        unsafe { System.alloc(block_layout(class)) }
    } else {
        popped
    };
    if base.is_null() {
        return base;
    }
    // SAFETY: the block holds 2^class ≥ HEADER bytes.
    unsafe { tag(base, HEADER, class) }
}

/// Returns a pooled block to this thread's list (to the system once the thread is ending).
///
/// # Safety
/// `base` is the start of a pooled block of `class` that nothing uses any more.
unsafe fn give_back(base: *mut u8, class: usize) {
    if STATE.with(Cell::get) == FRESH {
        // Registering the destructor may allocate and free: those frees see REGISTERING and
        // do not register again. A thread already ending cannot register one any more.
        STATE.with(|s| s.set(REGISTERING));
        let registered = DRAIN.try_with(|_| ()).is_ok();
        STATE.with(|s| s.set(if registered { LIVE } else { DEAD }));
    }
    if STATE.with(Cell::get) == DEAD {
        // SAFETY: the system gave this block with this layout.
        return unsafe { System.dealloc(base, block_layout(class)) };
    }
    FREE.with(|lists| {
        // SAFETY: the block is ours again; its first word becomes the link.
        unsafe { base.cast::<*mut u8>().write(lists[class].get()) };
        lists[class].set(base);
    });
}

/// Hands a thread's lists back to the system when the thread ends.
struct Drain;

impl Drop for Drain {
    fn drop(&mut self) {
        STATE.with(|s| s.set(DEAD));
        FREE.with(|lists| {
            for (class, list) in lists.iter().enumerate() {
                let mut p = list.replace(null_mut());
                while !p.is_null() {
                    // SAFETY: every listed block is a free pooled block of this class.
                    let next = unsafe { p.cast::<*mut u8>().read() };
                    unsafe { System.dealloc(p, block_layout(class)) };
                    p = next;
                }
            }
        });
    }
}

// SAFETY: blocks are aligned as asked (the header keeps the alignment, pooled blocks are
// only for alignments up to HEADER), and each is freed exactly as it was made, by its origin.
unsafe impl GlobalAlloc for Pool {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if HOT.with(Cell::get)
            && let Some(class) = class_of(layout)
        {
            // SAFETY: as the caller of alloc promises.
            return unsafe { take(class) };
        }
        let Some((outer, prefix)) = system_layout(layout) else {
            return null_mut();
        };
        if HOT.with(Cell::get) {
            count(true);
        }
        // SAFETY: a non-zero size.
        let base = unsafe { System.alloc(outer) };
        if base.is_null() {
            return base;
        }
        // SAFETY: the block holds the prefix and the size asked for.
        unsafe { tag(base, prefix, SYSTEM) }
    }

    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        // SAFETY: `p` is a block this allocator gave, so its origin precedes it.
        match unsafe { origin(p) } {
            SYSTEM => {
                let (outer, prefix) = system_layout(layout).expect("its layout was valid");
                // SAFETY: the system gave the block at `p - prefix` with this layout.
                unsafe { System.dealloc(p.sub(prefix), outer) }
            }
            // SAFETY: a pooled block starts its header's length before `p`.
            class => unsafe { give_back(p.sub(HEADER), class) },
        }
    }

    unsafe fn realloc(&self, p: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `p` is a block this allocator gave.
        let class = unsafe { origin(p) };
        if class != SYSTEM && new_size <= (1 << class) - HEADER {
            return p;
        }
        let Ok(new) = Layout::from_size_align(new_size, layout.align()) else {
            return null_mut();
        };
        // SAFETY: a valid layout; the old block holds `layout.size()` bytes, the new one at
        // least `new_size`.
        unsafe {
            let q = self.alloc(new);
            if !q.is_null() {
                std::ptr::copy_nonoverlapping(p, q, layout.size().min(new_size));
                self.dealloc(p, layout);
            }
            q
        }
    }
}
