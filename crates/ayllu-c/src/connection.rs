//! Connections from C (rules S6, S10): every kind, with its period, between endpoints that
//! are local `(behavior, port)`, remote `(node, behavior, port)` or a broadcast group
//! `(group, behavior, port)`; connections whose source is on another node are requested
//! from that node (N2).

use std::ffi::c_char;

use ayllu_core::{ConnectOptions, ConnectionId, ConnectionKind, Endpoint, NodeId, RequestId, RequestStatus};

use crate::cstr::{put, put_optional};
use crate::node::{ay_node, names, with_node};
use crate::seconds::required_secs;
use crate::status::{ay_status, boundary, Fail};

/// Endpoint scope: a port on this node.
pub const AY_LOCAL: u32 = 0;
/// Endpoint scope: a port on node `node` (the paper's `(host, behavior, port)`).
pub const AY_NODE: u32 = 1;
/// Endpoint scope: the port on every node of broadcast group `group` except the sender.
pub const AY_GROUP: u32 = 2;

/// Connection kind: write and propagate (no period).
pub const AY_NORMAL: u32 = 0;
/// Connection kind: do not write; no connection may write the destination for the period.
pub const AY_SUPPRESS: u32 = 1;
/// Connection kind: do not write; nothing propagates out of the destination for the period.
pub const AY_INHIBIT: u32 = 2;
/// Connection kind: write; only this connection may write the destination for the period
/// (classic Brooks suppression).
pub const AY_OVERRIDE_IN: u32 = 3;
/// Connection kind: write; only what arrives along this connection propagates out of the
/// destination for the period.
pub const AY_OVERRIDE_OUT: u32 = 4;
/// Connection kind: do not write; what the destination's own behavior writes is not
/// propagated for the period (what arrives through connections still is).
pub const AY_WRITE_INHIBIT: u32 = 5;

/// One end of a connection.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct ay_endpoint {
    /// `AY_LOCAL`, `AY_NODE` or `AY_GROUP`.
    pub scope: u32,
    /// The node, for `AY_NODE`.
    pub node: u32,
    /// The group's name, for `AY_GROUP` (NUL-terminated; NULL otherwise).
    pub group: *const c_char,
    /// The behavior's name (NUL-terminated).
    pub behavior: *const c_char,
    /// The port's name (NUL-terminated; `BLE_Local`, `BLE_Inhibit`, `BLE_Best` name the
    /// implicit BLE ports).
    pub port: *const c_char,
}

/// # Safety
/// `p` is NULL or points to an endpoint whose strings are NULL or NUL-terminated.
pub(crate) unsafe fn endpoint(p: *const ay_endpoint, what: &str) -> Result<Endpoint, Fail> {
    if p.is_null() {
        return Err(Fail::null(what));
    }
    // SAFETY: non-null, and valid by the caller's promise.
    let e = unsafe { &*p };
    // SAFETY: the caller's promise on the endpoint's strings.
    let (b, port) = unsafe { names(e.behavior, e.port) }.map_err(|f| f.context(what))?;
    Ok(match e.scope {
        AY_LOCAL => Endpoint::local(b, port),
        AY_NODE if e.node == 0 => return Err(Fail::invalid(format!("{what}: node 0 is reserved"))),
        AY_NODE => Endpoint::node(NodeId(e.node), b, port),
        AY_GROUP => {
            // SAFETY: the caller's promise on the group name.
            let g = unsafe { crate::cstr::text(e.group, "group") }.map_err(|f| f.context(what))?;
            if g.is_empty() {
                return Err(Fail::invalid(format!("{what}: a group needs a name")));
            }
            Endpoint::group(g, b, port)
        }
        other => return Err(Fail::invalid(format!("{what}: {other} is not a scope (AY_LOCAL, AY_NODE, AY_GROUP)"))),
    })
}

pub(crate) fn kind(kind: u32, period: f64) -> Result<ConnectionKind, Fail> {
    if kind == AY_NORMAL {
        // C has no "no period": 0 stands for it. Anything else is the core's PeriodOnNormal
        // (ConnectionKind::from_parts), as in Python.
        if period != 0.0 {
            return Err(ayllu_core::Error::PeriodOnNormal { seconds: period }.into());
        }
        return Ok(ConnectionKind::Normal);
    }
    let p = required_secs(period, "the connection's period")?;
    Ok(match kind {
        AY_SUPPRESS => ConnectionKind::Suppress(p),
        AY_INHIBIT => ConnectionKind::Inhibit(p),
        AY_OVERRIDE_IN => ConnectionKind::OverrideIn(p),
        AY_OVERRIDE_OUT => ConnectionKind::OverrideOut(p),
        AY_WRITE_INHIBIT => ConnectionKind::WriteInhibit(p),
        other => {
            return Err(Fail::invalid(format!("{other} is not a connection kind (AY_NORMAL .. AY_WRITE_INHIBIT)")))
        }
    })
}

/// The body of `ay_node_connect` and `ay_node_request_connect`: read the endpoints and the
/// kind from C, `make` the connection (or the request for it) with them, and put its id into
/// `*out` (may be NULL).
///
/// # Safety
/// The endpoints are NULL or valid with NULL-or-NUL-terminated strings; `out` is NULL or valid
/// for a write.
unsafe fn connect_from_c(
    source: *const ay_endpoint,
    destination: *const ay_endpoint,
    kind_: u32,
    period: f64,
    out: *mut u64,
    make: impl FnOnce(&Endpoint, &Endpoint, ConnectionKind) -> Result<u64, Fail>,
) -> Result<(), Fail> {
    // SAFETY: forwarded promises on the endpoints.
    let (s, d) = unsafe { (endpoint(source, "source")?, endpoint(destination, "destination")?) };
    let id = make(&s, &d, kind(kind_, period)?)?;
    // SAFETY: forwarded promise on `out`.
    unsafe { put_optional(out, id) };
    Ok(())
}

/// Connect `source` (a port of this node) to `destination` with `kind` (`AY_NORMAL` ..
/// `AY_WRITE_INHIBIT`) and `period` seconds (0 for `AY_NORMAL`, above zero for the others);
/// `priority` is the connection's priority at a Priority port. The new connection's id goes
/// to `*out` (may be NULL). A source on another node is refused: use
/// `ay_node_request_connect`.
///
/// Ownership: the endpoints' strings are copied. Thread-safety: the node's thread. Errors:
/// `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`, `AY_ERR_UNKNOWN` (a local behavior or port),
/// `AY_ERR_TYPE` (a writing kind between ports of different types), `AY_ERR_PERIOD` (zero,
/// negative, NaN or infinite period; a period on a Normal connection), `AY_ERR_INVALID`
/// (unknown kind or scope, a group or remote source, a slot).
///
/// # Safety
/// `node` is NULL or a pointer from this library; the endpoints are NULL or valid with
/// NULL-or-NUL-terminated strings; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_connect(
    node: *mut ay_node,
    source: *const ay_endpoint,
    destination: *const ay_endpoint,
    kind_: u32,
    period: f64,
    priority: i32,
    out: *mut u64,
) -> ay_status {
    boundary("ay_node_connect", || {
        // SAFETY: the C caller's promises on the endpoints and `out`.
        unsafe {
            connect_from_c(source, destination, kind_, period, out, |s, d, k| {
                with_node(node, |n| Ok(n.node.connect_with(s, d, k, ConnectOptions { priority })?.0))
            })
        }
    })
}

/// Ask node `source.node` to connect its port to `destination` (a local destination means a
/// port of this node), retried until answered (N2). The request's id goes to `*out`; follow
/// it with `ay_node_request_status`.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_PERIOD` (as `ay_node_connect`), `AY_ERR_INVALID` (the source is not `AY_NODE`).
///
/// # Safety
/// As [`ay_node_connect`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_request_connect(
    node: *mut ay_node,
    source: *const ay_endpoint,
    destination: *const ay_endpoint,
    kind_: u32,
    period: f64,
    priority: i32,
    out: *mut u64,
) -> ay_status {
    boundary("ay_node_request_connect", || {
        // SAFETY: the C caller's promises on the endpoints and `out`.
        unsafe {
            connect_from_c(source, destination, kind_, period, out, |s, d, k| {
                with_node(node, |n| Ok(n.node.core_mut().request_connect(s, d, k, ConnectOptions { priority })?.0))
            })
        }
    })
}

/// Where request `request` stands, into `*out`: 0 pending, 1 answered with success, -1 failed
/// (refused by the other node, or no answer after the retries; `ay_last_error` is not set).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (no such request from this node).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_request_status(node: *mut ay_node, request: u64, out: *mut i32) -> ay_status {
    boundary("ay_node_request_status", || {
        let status = with_node(node, |n| {
            n.node.core().request_status(RequestId(request)).ok_or_else(|| {
                Fail::new(ay_status::AY_ERR_UNKNOWN, format!("no request {request} was sent by this node"))
            })
        })?;
        let code = match status {
            RequestStatus::Pending { .. } => 0,
            RequestStatus::Done(_) => 1,
            RequestStatus::Failed(_) => -1,
        };
        // SAFETY: the C caller's promise on `out`.
        unsafe { put(out, code, "out") }
    })
}

/// Remove connection `id` (owned by this node); windows it holds here end at once.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (no such connection).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_node_disconnect(node: *mut ay_node, id: u64) -> ay_status {
    boundary("ay_node_disconnect", || with_node(node, |n| Ok(n.node.disconnect(ConnectionId(id))?)))
}
