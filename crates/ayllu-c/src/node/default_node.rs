//! The paper's one-call setup and shutdown: `ayInitIPComms` opens the process's default node
//! (id and URL from the environment when not given) and `ayShutdown` closes it. Setting and
//! reading the default node directly (`ay_set_default_node`, `ay_default_node`) stay in
//! `lifecycle.rs`, beside `ay_node_free`, which clears it.
//!
//! Promise: at most one default node is open at a time.

use std::ffi::c_char;
use std::sync::atomic::Ordering;

use super::handle::ay_node;
use super::lifecycle::{ay_node_free, ay_node_open, DEFAULT};
use crate::status::{ay_status, boundary, Fail};

/// Open the process's default node (the paper's `ayInitIPComms`): node `id` (0: the number in
/// `$AYLLU_NODE`) on `url` (NULL: `$AYLLU_URL`, else discovery on this machine), real clock.
///
/// Ownership: the library owns the default node until `ay_close_default`. Thread-safety: call
/// once, from the thread that will drive it. Errors: as [`ay_node_open`], plus
/// `AY_ERR_INVALID` (a default node is open already; id 0 without a numeric `$AYLLU_NODE`).
///
/// # Safety
/// `url` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_open_default(id: u32, url: *const c_char) -> ay_status {
    boundary("ay_open_default", || {
        if DEFAULT.load(Ordering::SeqCst) != 0 {
            return Err(Fail::invalid("the default node is open already (ayInitIPComms runs once)"));
        }
        let id = match id {
            0 => std::env::var("AYLLU_NODE").ok().and_then(|s| s.trim().parse::<u32>().ok()).ok_or_else(|| {
                Fail::invalid("no node id: pass one (ayInitIPCommsAs) or set AYLLU_NODE to a number from 1")
            })?,
            id => id,
        };
        let mut p: *mut ay_node = std::ptr::null_mut();
        // SAFETY: `url` as promised by the caller; `p` is a valid place for the handle.
        let status = unsafe { ay_node_open(id, url, &mut p) };
        if status != ay_status::AY_OK {
            return Err(Fail::new(status, last_message()));
        }
        DEFAULT.store(p as usize, Ordering::SeqCst);
        Ok(())
    })
}

fn last_message() -> String {
    // SAFETY: ay_last_error always returns a valid NUL-terminated string.
    unsafe { std::ffi::CStr::from_ptr(crate::status::ay_last_error()) }.to_string_lossy().into_owned()
}

/// Close the default node (if any) and forget it: what `ayShutdown` does before a program
/// that used `ayInitIPComms` returns.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_BUSY` (from one of its processes).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
#[no_mangle]
pub extern "C" fn ay_close_default() -> ay_status {
    let p = DEFAULT.load(Ordering::SeqCst) as *mut ay_node;
    if p.is_null() {
        return ay_status::AY_OK;
    }
    // SAFETY: the default node is a live handle (ay_node_free clears it when it goes).
    unsafe { ay_node_free(p) }
}
