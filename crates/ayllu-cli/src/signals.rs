//! Ctrl-C and SIGTERM as a flag, so that commands that run until stopped (`echo`, `write
//! --repeat-hz`, `node`) finish cleanly — `echo` disconnects what it connected — instead of
//! dying mid-way.
//!
//! The handler only stores to an atomic (async-signal-safe). A blocked `poll` returns early on
//! a signal, so loops notice within one slice.

use std::sync::atomic::{AtomicBool, Ordering};

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// Route SIGINT and SIGTERM to the flag.
pub fn install() {
    for sig in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: a zeroed sigaction is a valid "no flags, empty mask" value; the handler is an
        // `extern "C"` function that only touches an atomic, which is async-signal-safe.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(sig, &action, std::ptr::null_mut());
        }
    }
}

/// Whether the user asked the tool to stop.
pub fn stopped() -> bool {
    STOP.load(Ordering::SeqCst)
}
