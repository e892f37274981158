//! The C boundary's plumbing: errors to a status and this thread's message, panics stopped
//! before they unwind into C, the caller's pointers checked, and its cancel flag read.

use std::cell::RefCell;
use std::ffi::{CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicI32, Ordering};

use graybox_core::array::finite;
use graybox_core::error::Error;

use crate::GbxStatus;

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn remember(message: String) {
    let c = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = c);
}

/// This thread's last message.
pub(crate) fn last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

fn status_of(e: &Error) -> GbxStatus {
    match e {
        Error::Invalid { .. } | Error::Unprocessable { .. } => GbxStatus::InvalidArgument,
        Error::Corrupt { .. } => GbxStatus::Corrupt,
        Error::Io(_) => GbxStatus::Io,
        Error::Cancelled => GbxStatus::Cancelled,
        _ => GbxStatus::Internal,
    }
}

/// Runs a call: its error becomes a status and this thread's last message; a panic (a bug)
/// stops at the boundary instead of unwinding into C.
pub(crate) fn guard(f: impl FnOnce() -> Result<(), Error>) -> GbxStatus {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => GbxStatus::Ok,
        Ok(Err(e)) => {
            match e {
                Error::Cancelled => remember("cancelled: the cancel flag was set".into()),
                _ => remember(e.to_string()),
            }
            status_of(&e)
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            remember(format!("internal error: {what}"));
            GbxStatus::Internal
        }
    }
}

/// `rows` rows of `width` finite values at `p`, or an invalid-argument error naming `field`
/// (and the row holding a NaN or infinity: the model would carry it into its states, and the
/// error would blame them).
///
/// # Safety
/// A non-null `p` points to at least `rows · width` readable values.
pub(crate) unsafe fn input<'a>(
    p: *const f64,
    rows: usize,
    width: usize,
    field: &str,
) -> Result<&'a [f64], Error> {
    let len = values(field, rows, width)?;
    if len == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(Error::invalid(field, "is a null pointer"));
    }
    // SAFETY: non-null, and the caller promises `len` values.
    let data = unsafe { std::slice::from_raw_parts(p, len) };
    finite(field, data, width)?;
    Ok(data)
}

/// `len` writable values at `p`, or an invalid-argument error naming `field` when null.
///
/// # Safety
/// A non-null `p` points to at least `len` writable values that nothing else reads or
/// writes during the call.
pub(crate) unsafe fn output<'a>(
    p: *mut f64,
    len: usize,
    field: &str,
) -> Result<&'a mut [f64], Error> {
    if p.is_null() {
        return Err(Error::invalid(field, "is a null pointer"));
    }
    // SAFETY: non-null, and the caller promises `len` exclusive values.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, len) })
}

pub(crate) fn batch_of(batch: usize) -> Result<usize, Error> {
    if batch == 0 {
        return Err(Error::invalid("batch", "must be at least 1"));
    }
    Ok(batch)
}

/// `rows × width` values, or an invalid-argument error naming `field` when no array of
/// doubles could be that long (a wrapped product would read or write the wrong length).
pub(crate) fn values(field: &str, rows: usize, width: usize) -> Result<usize, Error> {
    let bytes = rows.checked_mul(width).and_then(|v| v.checked_mul(8));
    match bytes {
        Some(b) if b <= isize::MAX as usize => Ok(rows * width),
        _ => Err(Error::invalid(
            field,
            format!("{rows} rows of {width} values are more than any array can hold"),
        )),
    }
}

/// The caller's cancel flag (null: none), read as the C11 atomic it may be: another thread
/// or a signal handler sets it while the call runs.
pub(crate) struct Cancel<'a>(Option<&'a AtomicI32>);

impl Cancel<'_> {
    /// # Safety
    /// A non-null `flag` points to an aligned `int32_t` that lives through the call and that
    /// others only read or store whole.
    pub(crate) unsafe fn new(flag: *const i32) -> Self {
        // SAFETY: aligned and alive, as the caller promises; it is only loaded here, never
        // written, and AtomicI32 has i32's layout.
        Cancel((!flag.is_null()).then(|| unsafe { AtomicI32::from_ptr(flag.cast_mut()) }))
    }

    /// Whether the flag is set (nonzero).
    pub(crate) fn set(&self) -> bool {
        self.0.is_some_and(|f| f.load(Ordering::Relaxed) != 0)
    }
}
