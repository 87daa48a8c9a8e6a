//! Monostables from outside the behaviors: trigger one for a span of time and ask whether it is
//! high (rule S2), as a test or a driver does without a process of its own.

use std::ffi::c_char;

use super::handle::{ay_node, with_node};
use crate::cstr::{put, text};
use crate::seconds::required_secs;
use crate::status::{ay_status, boundary};

/// Trigger monostable `behavior.mono` for `seconds` from now (rule S2).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN`, `AY_ERR_PERIOD` (zero, negative, NaN, infinite).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the names are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_trigger(
    node: *mut ay_node,
    behavior: *const c_char,
    mono: *const c_char,
    seconds: f64,
) -> ay_status {
    boundary("ay_node_trigger", || {
        // SAFETY: the C caller's promises on the names.
        let (b, m) = unsafe { (text(behavior, "behavior")?, text(mono, "monostable")?) };
        let d = required_secs(seconds, "the period")?;
        with_node(node, |s| {
            let core = s.node.core_mut();
            let now = core.now(); // core_mut told it the present
            Ok(core.trigger(now, b, m, d)?)
        })
    })
}

/// Whether monostable `behavior.mono` is high now, into `*out`.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the names are NULL or NUL-terminated;
/// `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_monostable(
    node: *mut ay_node,
    behavior: *const c_char,
    mono: *const c_char,
    out: *mut bool,
) -> ay_status {
    boundary("ay_node_monostable", || {
        // SAFETY: the C caller's promises on the names.
        let (b, m) = unsafe { (text(behavior, "behavior")?, text(mono, "monostable")?) };
        let high = with_node(node, |s| Ok(s.node.monostable(b, m)?))?;
        // SAFETY: the C caller's promise on `out`.
        unsafe { put(out, high, "out") }
    })
}
