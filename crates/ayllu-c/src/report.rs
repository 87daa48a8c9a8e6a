//! Introspection from C: `why` a port holds and passes what it does, and the whole node
//! (`list`), as JSON strings in the shapes `ayllu why --json` and `ayllu list --json` print
//! ([`ayllu::report_json`]: times in seconds, `counted` beside the counters).

use std::ffi::c_char;

use crate::cstr::{owned, put};
use crate::node::{ay_node, names, with_node};
use crate::status::{ay_status, boundary, Fail};

/// Why `behavior.port` holds what it holds and passes what it passes, now: value, freshness,
/// supplier, active windows and their holders, connections in and out. `*out` receives a
/// JSON object.
///
/// Ownership: `*out` belongs to the caller; free it with `ay_string_free`. Thread-safety: the
/// node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`, `AY_ERR_UNKNOWN`
/// (`*out` is then untouched).
///
/// # Safety
/// `node` is NULL or a pointer from this library; the names are NULL or NUL-terminated; `out`
/// is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_why_json(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    out: *mut *mut c_char,
) -> ay_status {
    boundary("ay_node_why_json", || {
        // SAFETY: the C caller's promises on the names.
        let (b, p) = unsafe { names(behavior, port) }?;
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        let text = with_node(node, |s| Ok(ayllu::report_json::port_report_json(&s.node.why(b, p)?).to_string()))?;
        // SAFETY: the C caller's promise on `out`.
        unsafe { put(out, owned(text), "out") }
    })
}

/// The whole node now (the `list` report): its behaviors with their ports, slots,
/// monostables and processes, its connections, groups, counters and warnings (e.g. a BLE
/// inhibit period too short). `*out` receives a JSON object.
///
/// Ownership: `*out` belongs to the caller; free it with `ay_string_free`. Thread-safety: the
/// node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_report_json(node: *mut ay_node, out: *mut *mut c_char) -> ay_status {
    boundary("ay_node_report_json", || {
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        let text = with_node(node, |s| Ok(ayllu::report_json::node_report_json(&s.node.core().report()).to_string()))?;
        // SAFETY: the C caller's promise on `out`.
        unsafe { put(out, owned(text), "out") }
    })
}
