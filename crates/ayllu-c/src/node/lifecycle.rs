//! A node's life from C: open it (real clock or manual), ask what it is (id, address, time),
//! step it or run its loop until a stop is requested, and close it. The process-wide default
//! node is set and read here too, beside `ay_node_free` which clears it; opening it the paper's
//! way (`ayInitIPComms`) is in `default_node.rs`, which the header lists last.
//!
//! Promise: a stop request reaches every running loop within [`STOP_CHECK`], and is safe to
//! make from a signal handler.

use std::ffi::c_char;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use ayllu::{Node, NodeId};

use super::handle::{ay_node, open, with_node, NodeState};
use crate::clock::with_clock;
use crate::cstr::{copy_out, put, text};
use crate::registry::{self, Kind};
use crate::status::{ay_status, boundary, Fail};

pub(super) static DEFAULT: AtomicUsize = AtomicUsize::new(0);
static STOP: AtomicBool = AtomicBool::new(false);

fn node_id(id: u32) -> Result<NodeId, Fail> {
    if id == 0 {
        return Err(Fail::invalid("node id 0 is reserved; use 1 or more"));
    }
    Ok(NodeId(id))
}

/// Open node `id` on the transport `url` names (`udp://127.0.0.1:0`, `mem://team`; NULL: the
/// default, `$AYLLU_URL` or discovery on this machine), on the real monotonic clock.
///
/// Ownership: `*out` belongs to the caller; free it with `ay_node_free`. Thread-safety: a node
/// is driven by one thread at a time (different nodes may run on different threads).
/// Errors: `AY_ERR_NULL` (out), `AY_ERR_INVALID` (id 0, URL not UTF-8), `AY_ERR_TRANSPORT`
/// (a URL that does not parse, a socket the system refused, an id taken on a `mem://` network).
///
/// # Safety
/// `url` is NULL or NUL-terminated; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_open(id: u32, url: *const c_char, out: *mut *mut ay_node) -> ay_status {
    boundary("ay_node_open", || {
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        let url = if url.is_null() {
            ayllu::default_url()
        } else {
            // SAFETY: the C caller's promise on `url`.
            unsafe { text(url, "url") }?.to_owned()
        };
        open(Node::open(node_id(id)?, &url)?, out)
    })
}

/// Open node `id` on `url` (as [`ay_node_open`]) with the manual clock `clock`: time moves
/// only when the clock is advanced, and stepping never sleeps.
///
/// Ownership: `*out` belongs to the caller; the node shares the clock's time and does not keep
/// the handle (the clock may be freed first). Thread-safety and errors: as [`ay_node_open`],
/// plus `AY_ERR_NULL`/`AY_ERR_HANDLE` for the clock.
///
/// # Safety
/// As [`ay_node_open`]; `clock` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_node_open_manual(
    id: u32,
    url: *const c_char,
    clock: *const crate::clock::ay_clock,
    out: *mut *mut ay_node,
) -> ay_status {
    boundary("ay_node_open_manual", || {
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        // SAFETY: the C caller's promise on `url`.
        let url = unsafe { text(url, "url") }?;
        let clock = with_clock(clock, |c| Ok(c.clock.clone()))?;
        open(Node::open_with_clock(node_id(id)?, url, clock)?, out)
    })
}

/// Close a node: its socket, its behaviors and their processes go (a process's `user`
/// pointer is not touched). If it was the default node (`ay_default_node`), there is none
/// afterwards.
///
/// Ownership: takes the node; the handle is invalid afterwards, and later calls with it
/// return `AY_ERR_HANDLE`. Thread-safety: not while another thread uses it. Errors:
/// `AY_ERR_NULL`, `AY_ERR_HANDLE` (freed already), `AY_ERR_BUSY` (called from one of its own
/// processes).
///
/// # Safety
/// `node` is NULL or a pointer from this library (checked against the live handles).
#[no_mangle]
pub unsafe extern "C" fn ay_node_free(node: *mut ay_node) -> ay_status {
    boundary("ay_node_free", || {
        with_node(node, |_| Ok(()))?;
        registry::remove(node, Kind::Node, "node")?;
        let _ = DEFAULT.compare_exchange(node as usize, 0, Ordering::SeqCst, Ordering::SeqCst);
        // SAFETY: came from Box::into_raw in `open`, was just unregistered, and is not busy.
        drop(unsafe { Box::from_raw(node) });
        Ok(())
    })
}

/// Make `node` the process's default node (the one `ayllu.h`'s macros use; NULL: none).
///
/// Ownership: the caller still owns the node. Thread-safety: any thread (the setting is
/// process-wide). Errors: `AY_ERR_HANDLE` (not a live node).
///
/// # Safety
/// `node` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_set_default_node(node: *mut ay_node) -> ay_status {
    boundary("ay_set_default_node", || {
        if !node.is_null() {
            registry::check(node, Kind::Node, "node")?;
        }
        DEFAULT.store(node as usize, Ordering::SeqCst);
        Ok(())
    })
}

/// The default node (NULL if none). Ownership: the caller does not own it. Thread-safety: any
/// thread. Errors: none.
#[no_mangle]
pub extern "C" fn ay_default_node() -> *mut ay_node {
    DEFAULT.load(Ordering::SeqCst) as *mut ay_node
}

/// Ask every running loop (`ay_node_run`, `ay_node_run_for`) to return soon (within 50 ms).
///
/// Ownership: nothing. Thread-safety: any thread, and async-signal-safe: call it from a
/// SIGINT/SIGTERM handler. Errors: none.
#[no_mangle]
pub extern "C" fn ay_request_stop() {
    STOP.store(true, Ordering::SeqCst);
}

/// Whether a stop was requested (and not cleared). Thread-safety: any thread.
///
/// Ownership: nothing. Errors: none.
#[no_mangle]
pub extern "C" fn ay_stop_requested() -> bool {
    STOP.load(Ordering::SeqCst)
}

/// Forget a stop request, so that loops run again. Thread-safety: any thread.
///
/// Ownership: nothing. Errors: none.
#[no_mangle]
pub extern "C" fn ay_clear_stop() {
    STOP.store(false, Ordering::SeqCst);
}

/// The node's id into `*out`.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_id(node: *mut ay_node, out: *mut u32) -> ay_status {
    boundary("ay_node_id", || {
        // SAFETY: the C caller's promise on `out`.
        with_node(node, |s| unsafe { put(out, s.node.id().0, "out") })
    })
}

/// Where peers reach this node (`127.0.0.1:40123` after binding port 0; empty for `mem://`)
/// into `buffer` (`capacity` bytes, NUL-terminated); `*length` (may be NULL) gets the length.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_BUFFER` (nothing copied; `*length` says how much is needed).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `buffer` is NULL or valid for `capacity`
/// bytes; `length` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_address(
    node: *mut ay_node,
    buffer: *mut c_char,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_node_address", || {
        with_node(node, |s| {
            let a = s.node.address().unwrap_or_default();
            // SAFETY: the C caller's promises on buffer/capacity/length.
            unsafe { copy_out(a.as_bytes(), true, buffer.cast::<u8>(), capacity, length) }
        })
    })
}

/// The node's clock now (seconds since the clock's origin) into `*out`.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_now(node: *mut ay_node, out: *mut f64) -> ay_status {
    boundary("ay_node_now", || {
        // SAFETY: the C caller's promise on `out`.
        with_node(node, |s| unsafe { put(out, s.node.now().as_secs_f64(), "out") })
    })
}

/// One turn of the loop: send what was written, receive what arrived, run the processes that
/// are due, send what they produced. `*next` (may be NULL) gets the seconds until the node
/// next has work, or -1 if it has none.
///
/// Thread-safety: the node's thread; the node's C processes run inside this call. Errors:
/// `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY` (called from one of its own processes).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `next` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_step(node: *mut ay_node, next: *mut f64) -> ay_status {
    boundary("ay_node_step", || {
        with_node(node, |s| {
            let due = s.node.step();
            let now = s.node.now();
            let secs = due.map_or(-1.0, |d| if d > now { (d - now).as_secs_f64() } else { 0.0 });
            // SAFETY: the C caller's promise on `next`.
            unsafe { crate::cstr::put_optional(next, secs) };
            Ok(())
        })
    })
}

/// The slice a run loop sleeps at most between checks of `ay_request_stop`.
const STOP_CHECK: std::time::Duration = std::time::Duration::from_millis(50);

fn run(s: &mut NodeState, seconds: Option<f64>) {
    let end = seconds.map(|secs| std::time::Instant::now() + std::time::Duration::from_secs_f64(secs));
    loop {
        if STOP.load(Ordering::SeqCst) {
            return;
        }
        let slice = match end {
            Some(e) => {
                let left = e.saturating_duration_since(std::time::Instant::now());
                if left.is_zero() {
                    return;
                }
                left.min(STOP_CHECK)
            }
            None => STOP_CHECK,
        };
        s.node.run_for(slice);
    }
}

/// Run the node's loop in real time for `seconds` (sleeping on the transport between
/// deadlines), or until `ay_request_stop`. With a manual clock: one step (time is not the
/// node's to move).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_PERIOD` (negative, NaN or infinite seconds).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_node_run_for(node: *mut ay_node, seconds: f64) -> ay_status {
    boundary("ay_node_run_for", || {
        let d = ayllu_core::Duration::try_from_secs_f64(seconds)?;
        with_node(node, |s| {
            run(s, Some(d.as_secs_f64()));
            Ok(())
        })
    })
}

/// Run the node's loop until `ay_request_stop` is called (from a process, another thread or
/// a signal handler); the paper's `ayRunBehaviors`. Returns `AY_OK` then (the request stays
/// set: `ay_clear_stop` to run again).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_node_run(node: *mut ay_node) -> ay_status {
    boundary("ay_node_run", || {
        with_node(node, |s| {
            run(s, None);
            Ok(())
        })
    })
}
