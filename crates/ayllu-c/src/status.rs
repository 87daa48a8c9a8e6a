//! What every call returns: an [`ay_status`] code, and on failure a readable message kept per
//! thread for [`ay_last_error`]. Every exported function runs its body inside [`boundary`],
//! which turns errors into codes and catches panics, so nothing unwinds into C and nothing
//! aborts.

use std::cell::RefCell;
use std::ffi::{c_char, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// The result of every call. `AY_OK` is zero; every failure also sets the thread's message
/// ([`ay_last_error`]).
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ay_status {
    /// Done.
    AY_OK = 0,
    /// A required pointer (handle, name, output) was NULL.
    AY_ERR_NULL = 1,
    /// The handle is not live: freed already, or never made by this library.
    AY_ERR_HANDLE = 2,
    /// No class, behavior, port, slot, monostable, process or connection of that name or id.
    AY_ERR_UNKNOWN = 3,
    /// A value, port or register of the wrong type (rule S1), or a kind the type cannot have.
    AY_ERR_TYPE = 4,
    /// A period, lifespan, window or duration that is zero (where one is required), negative,
    /// NaN or infinite.
    AY_ERR_PERIOD = 5,
    /// A rate (`ratepersecond`) that is zero, negative, NaN or infinite.
    AY_ERR_RATE = 6,
    /// Any other argument the runtime refused: an empty, reserved or taken name, an unknown
    /// kind constant, text that is not UTF-8, a group as a source.
    AY_ERR_INVALID = 7,
    /// The transport: a URL that does not parse, a socket the system refused.
    AY_ERR_TRANSPORT = 8,
    /// The node is running its processes (a process called a node function on its own node;
    /// use the process context instead), or another call on it has not returned.
    AY_ERR_BUSY = 9,
    /// A process-context call made outside the process it was given to.
    AY_ERR_CONTEXT = 10,
    /// The port holds no fresh value (stale past its lifespan, or an empty aggregating port);
    /// the output still receives what the port reads as (its default while empty).
    AY_ERR_ABSENT = 11,
    /// The caller's buffer is too small; the length needed is reported where the call says.
    AY_ERR_BUFFER = 12,
    /// An internal error was caught at the boundary (a bug in the library: please report it).
    AY_ERR_PANIC = 13,
}

/// A failed call on its way to C: the code and the message.
#[derive(Debug)]
pub(crate) struct Fail {
    pub(crate) status: ay_status,
    pub(crate) message: String,
}

impl Fail {
    pub(crate) fn new(status: ay_status, message: impl Into<String>) -> Fail {
        Fail { status, message: message.into() }
    }
    pub(crate) fn null(what: &str) -> Fail {
        Fail::new(ay_status::AY_ERR_NULL, format!("{what} is NULL"))
    }
    pub(crate) fn invalid(message: impl Into<String>) -> Fail {
        Fail::new(ay_status::AY_ERR_INVALID, message)
    }
    pub(crate) fn context(mut self, what: &str) -> Fail {
        self.message = format!("{what}: {}", self.message);
        self
    }
}

/// The code for each refusal of the core: its [`ayllu_core::ErrorKind`], the classification
/// Python's exceptions come from too (its `Display` is the message).
pub(crate) fn core_status(e: &ayllu_core::Error) -> ay_status {
    use ayllu_core::ErrorKind as K;
    match e.kind() {
        K::Unknown => ay_status::AY_ERR_UNKNOWN,
        K::Type => ay_status::AY_ERR_TYPE,
        K::Period => ay_status::AY_ERR_PERIOD,
        K::Rate => ay_status::AY_ERR_RATE,
        K::Invalid => ay_status::AY_ERR_INVALID,
    }
}

impl From<ayllu_core::Error> for Fail {
    fn from(e: ayllu_core::Error) -> Fail {
        Fail::new(core_status(&e), e.to_string())
    }
}

impl From<ayllu::RuntimeError> for Fail {
    fn from(e: ayllu::RuntimeError) -> Fail {
        match e {
            ayllu::RuntimeError::Core(c) => c.into(),
            other => Fail::new(ay_status::AY_ERR_TRANSPORT, other.to_string()),
        }
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: String) {
    // Interior NULs cannot be shown by C: replace them.
    let text = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    LAST_ERROR.with(|l| *l.borrow_mut() = text);
}

/// Run an exported function's body: `Ok` is `AY_OK`; an error sets the thread's message
/// (prefixed with `what`, the C function's name) and returns its code; a panic is caught and
/// returned as `AY_ERR_PANIC`, never unwound into C.
pub(crate) fn boundary(what: &str, body: impl FnOnce() -> Result<(), Fail>) -> ay_status {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => ay_status::AY_OK,
        Ok(Err(fail)) => {
            set_last_error(format!("{what}: {}", fail.message));
            fail.status
        }
        Err(panic) => {
            let reason = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_owned());
            set_last_error(format!("{what}: internal error (caught at the C boundary): {reason}"));
            ay_status::AY_ERR_PANIC
        }
    }
}

/// The message of the last failed call on this thread ("" if none failed yet): which function,
/// and what to fix.
///
/// Ownership: the string belongs to the library; it stays valid until the next failing call
/// on this thread. Copy it to keep it. Thread-safety: each thread has its own message.
/// Errors: none; never NULL.
#[no_mangle]
pub extern "C" fn ay_last_error() -> *const c_char {
    LAST_ERROR.with(|l| l.borrow().as_ptr())
}

/// A short constant name for a status code (`"AY_ERR_UNKNOWN"`), for logs.
///
/// Ownership: a static string; never freed. Thread-safety: any thread. Errors: a number that
/// is no status gives `"AY_ERR_?"`.
#[no_mangle]
pub extern "C" fn ay_status_name(status: i32) -> *const c_char {
    const NAMES: [&[u8]; 14] = [
        b"AY_OK\0",
        b"AY_ERR_NULL\0",
        b"AY_ERR_HANDLE\0",
        b"AY_ERR_UNKNOWN\0",
        b"AY_ERR_TYPE\0",
        b"AY_ERR_PERIOD\0",
        b"AY_ERR_RATE\0",
        b"AY_ERR_INVALID\0",
        b"AY_ERR_TRANSPORT\0",
        b"AY_ERR_BUSY\0",
        b"AY_ERR_CONTEXT\0",
        b"AY_ERR_ABSENT\0",
        b"AY_ERR_BUFFER\0",
        b"AY_ERR_PANIC\0",
    ];
    let s: &'static [u8] = usize::try_from(status).ok().and_then(|i| NAMES.get(i).copied()).unwrap_or(b"AY_ERR_?\0");
    s.as_ptr().cast()
}

/// What `ayllu.h`'s macros call when a call they make fails: the status (an `ay_status`
/// value), what was being done (`ayIntPort(TargetX)`), and where (`file`, `line`); the
/// message is in [`ay_last_error`].
#[allow(non_camel_case_types)]
pub type ay_error_handler =
    Option<unsafe extern "C" fn(status: i32, what: *const c_char, file: *const c_char, line: i32)>;

static HANDLER: std::sync::Mutex<ay_error_handler> = std::sync::Mutex::new(None);

/// Install the handler `ayllu.h`'s macros call on failure (NULL: the default, which prints
/// `ayllu: FILE:LINE: WHAT: MESSAGE` on stderr and exits with status 70 — the paper's macros
/// have no error returns, so a failed declaration or connection is a program error). Returns
/// the previous handler.
///
/// Ownership: the function pointer is kept. Thread-safety: any thread (process-wide).
/// Errors: none.
#[no_mangle]
pub extern "C" fn ay_set_error_handler(handler: ay_error_handler) -> ay_error_handler {
    let mut h = HANDLER.lock().unwrap_or_else(|e| e.into_inner());
    std::mem::replace(&mut *h, handler)
}

/// Report a failed call the way the macros do: call the installed handler, or print and exit
/// with status 70 (see [`ay_set_error_handler`]).
///
/// Ownership: borrows the strings for the call. Thread-safety: any thread. Errors: none.
///
/// # Safety
/// `what` and `file` are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_report_error(status: i32, what: *const c_char, file: *const c_char, line: i32) {
    let handler = *HANDLER.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(h) = handler {
        // SAFETY: a C function of this signature, installed by the program; the strings are
        // passed on as received.
        unsafe { h(status, what, file, line) };
        return;
    }
    let show = |p: *const c_char| {
        if p.is_null() {
            "?".to_owned()
        } else {
            // SAFETY: non-null and NUL-terminated (caller's promise).
            unsafe { std::ffi::CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    let message = LAST_ERROR.with(|l| l.borrow().to_string_lossy().into_owned());
    use std::io::Write as _;
    let _ = writeln!(std::io::stderr(), "ayllu: {}:{line}: {}: {message}", show(file), show(what));
    std::process::exit(70);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn last() -> String {
        // SAFETY: ay_last_error always returns a valid NUL-terminated string.
        unsafe { std::ffi::CStr::from_ptr(ay_last_error()) }.to_string_lossy().into_owned()
    }

    #[test]
    fn a_panic_is_caught_at_the_boundary_and_reported() {
        let status = boundary("ay_example", || panic!("a bug inside"));
        assert_eq!(status, ay_status::AY_ERR_PANIC);
        assert!(last().contains("ay_example: internal error") && last().contains("a bug inside"), "{}", last());
        // The boundary still works afterwards, and success leaves the message alone.
        assert_eq!(boundary("ay_example", || Ok(())), ay_status::AY_OK);
        assert_eq!(boundary("ay_other", || Err(Fail::invalid("why"))), ay_status::AY_ERR_INVALID);
        assert_eq!(last(), "ay_other: why");
    }

    #[test]
    fn every_status_has_its_name() {
        for (code, name) in
            [(0, "AY_OK"), (5, "AY_ERR_PERIOD"), (13, "AY_ERR_PANIC"), (14, "AY_ERR_?"), (-1, "AY_ERR_?")]
        {
            // SAFETY: ay_status_name returns a static NUL-terminated string.
            let got = unsafe { std::ffi::CStr::from_ptr(ay_status_name(code)) };
            assert_eq!(got.to_str().unwrap(), name);
        }
    }
}
