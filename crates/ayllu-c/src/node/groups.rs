//! Broadcast groups and BLE from C: join and leave a group, make a behavior a BLE peer in one
//! call (rule S11) and ask whether it holds a claim.
//!
//! Promise: BLE's settings are the runtime's `BleConfig`, checked by it; only the paper's C
//! names for the implicit ports (`BLE_Local`, ...) are mapped here.

use std::ffi::c_char;

use ayllu::BleConfig;

use super::handle::{ay_node, with_node};
use crate::cstr::{put, text};
use crate::register::register_name;
use crate::seconds::optional_secs;
use crate::status::{ay_status, boundary, Fail};

/// Join broadcast group `group` (the node then receives what is sent to the group).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (empty name).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `group` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_join(node: *mut ay_node, group: *const c_char) -> ay_status {
    boundary("ay_node_join", || {
        // SAFETY: the C caller's promise on `group`.
        let g = unsafe { text(group, "group") }?;
        if g.is_empty() {
            return Err(Fail::invalid("a group needs a name"));
        }
        with_node(node, |s| {
            s.node.join(g);
            Ok(())
        })
    })
}

/// Leave broadcast group `group`. As [`ay_node_join`].
///
/// # Safety
/// As [`ay_node_join`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_leave(node: *mut ay_node, group: *const c_char) -> ay_status {
    boundary("ay_node_leave", || {
        // SAFETY: the C caller's promise on `group`.
        let g = unsafe { text(group, "group") }?;
        with_node(node, |s| {
            s.node.leave(g);
            Ok(())
        })
    })
}

/// BLE in one call (rule S11): make `behavior` a peer of group `group`. Its `Local` goes to
/// the peers' `Best` (Normal), its `Inhibit` write-inhibits the peers' `output` port for
/// `inhibit_seconds` (0: the recommended twice the claim period plus delay and margin), and
/// a select process claims at `claim_hz` when its eligibility is the best. A period shorter
/// than the claim cycle allows is accepted and warned about in the node's report.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (behavior or output port), `AY_ERR_RATE` (claim rate), `AY_ERR_PERIOD`
/// (negative, NaN or infinite inhibit period), `AY_ERR_INVALID` (empty group, already a peer).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the strings are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_ble_join(
    node: *mut ay_node,
    behavior: *const c_char,
    group: *const c_char,
    output: *const c_char,
    claim_hz: f64,
    inhibit_seconds: f64,
) -> ay_status {
    boundary("ay_node_ble_join", || {
        // SAFETY: the C caller's promises on the strings.
        let (b, g, o) = unsafe { (text(behavior, "behavior")?, text(group, "group")?, text(output, "output")?) };
        let mut config = BleConfig::new(g, register_name(o), claim_hz)?;
        if let Some(d) = optional_secs(inhibit_seconds, "the inhibit period")? {
            config = config.inhibit_period(d);
        }
        with_node(node, |s| Ok(s.node.ble_join(b, &config).map(|_| ())?))
    })
}

/// Whether `behavior` holds a BLE claim now (its last claim's inhibition has not lapsed), into
/// `*out`; false for a behavior in no BLE group.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `behavior` is NULL or NUL-terminated;
/// `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_ble_claiming(
    node: *mut ay_node,
    behavior: *const c_char,
    out: *mut bool,
) -> ay_status {
    boundary("ay_node_ble_claiming", || {
        // SAFETY: the C caller's promise on `behavior`.
        let b = unsafe { text(behavior, "behavior") }?;
        let claiming = with_node(node, |s| Ok(s.node.core().ble_status(b)?.is_some_and(|st| st.claiming)))?;
        // SAFETY: the C caller's promise on `out`.
        unsafe { put(out, claiming, "out") }
    })
}
