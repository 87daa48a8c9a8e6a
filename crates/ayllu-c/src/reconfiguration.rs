//! Reconfiguration from C (docs/semantics.md R1–R12): structure changes a C process asks for
//! (applied when it returns; their outcomes read on its next activation), requests to other
//! nodes from a process, and transactions across nodes from a plan (`ay_node_apply`).
//!
//! Every function wraps the Rust API (`ayllu_core::Ctx::change`, `ayllu::transaction::apply`);
//! nothing here decides anything about the semantics.

use std::ffi::c_char;

use ayllu::transaction::{apply, Outcome, Plan};
use ayllu_core::{Applied, Change, ConnectOptions, ConnectionId};

use crate::connection::{ay_endpoint, endpoint, kind};
use crate::cstr::{copy_out, put, put_optional, text};
use crate::node::{ay_node, with_node};
use crate::process::{ay_ctx, with_ctx};
use crate::status::{ay_status, boundary, core_status, Fail};

/// Ask for `change`; its position in this activation's list into `*index` (may be NULL).
fn ask(ctx: *mut ay_ctx, change: Change, index: *mut usize) -> Result<(), Fail> {
    let i = with_ctx(ctx, |c, _| Ok(c.change(change)?))?;
    // SAFETY: the exported callers forward the C caller's promise on `index`.
    unsafe { put_optional(index, i) };
    Ok(())
}

/// Ask to create behavior `name` of class `class` on this node when the process returns (R1).
/// Its position among this activation's changes goes to `*index` (may be NULL): the next
/// activation reads its outcome there with [`ay_ctx_change_outcome`].
///
/// Errors at the call (R2): `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_INVALID` (an empty name).
/// What depends on the node (an unknown class, a taken name) is the change's outcome.
///
/// Ownership: copies the strings. Thread-safety: only inside the process `ctx` was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; the strings are NULL or NUL-terminated;
/// `index` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_create(
    ctx: *mut ay_ctx,
    class: *const c_char,
    name: *const c_char,
    index: *mut usize,
) -> ay_status {
    boundary("ay_ctx_create", || {
        // SAFETY: the C caller's promises on the strings.
        let (class, name) = unsafe { (text(class, "class")?, text(name, "name")?) };
        ask(ctx, Change::Create { class: class.to_owned(), name: name.to_owned() }, index)
    })
}

/// Ask to remove behavior `name` (possibly the running one: R3) when the process returns.
/// As [`ay_ctx_create`] otherwise.
///
/// # Safety
/// As [`ay_ctx_create`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_remove(ctx: *mut ay_ctx, name: *const c_char, index: *mut usize) -> ay_status {
    boundary("ay_ctx_remove", || {
        // SAFETY: the C caller's promise on `name`.
        let name = unsafe { text(name, "name")? };
        ask(ctx, Change::Remove { name: name.to_owned() }, index)
    })
}

/// Ask to connect `source` (a port of this node) to `destination` with `kind` and `period`
/// (as `ay_node_connect`) when the process returns. The outcome holds the connection's id.
///
/// Errors at the call: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_PERIOD`, `AY_ERR_INVALID`
/// (an unknown kind or scope, a group as source, an empty name).
///
/// # Safety
/// `ctx` as [`ay_ctx_create`]; the endpoints are NULL or valid with NULL-or-NUL-terminated
/// strings; `index` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_connect(
    ctx: *mut ay_ctx,
    source: *const ay_endpoint,
    destination: *const ay_endpoint,
    kind_: u32,
    period: f64,
    priority: i32,
    index: *mut usize,
) -> ay_status {
    boundary("ay_ctx_connect", || {
        // SAFETY: the C caller's promises on the endpoints.
        let (source, destination) = unsafe { (endpoint(source, "source")?, endpoint(destination, "destination")?) };
        let kind = kind(kind_, period)?;
        ask(ctx, Change::Connect { source, destination, kind, priority }, index)
    })
}

/// Ask to remove connection `id` of this node when the process returns.
///
/// # Safety
/// As [`ay_ctx_create`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_disconnect(ctx: *mut ay_ctx, id: u64, index: *mut usize) -> ay_status {
    boundary("ay_ctx_disconnect", || ask(ctx, Change::Disconnect { conn: ConnectionId(id) }, index))
}

/// Ask to remove every connection of this node from `source` to `destination` when the
/// process returns (refused, as its outcome, if there is none).
///
/// # Safety
/// As [`ay_ctx_connect`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_disconnect_between(
    ctx: *mut ay_ctx,
    source: *const ay_endpoint,
    destination: *const ay_endpoint,
    index: *mut usize,
) -> ay_status {
    boundary("ay_ctx_disconnect_between", || {
        // SAFETY: the C caller's promises on the endpoints.
        let (source, destination) = unsafe { (endpoint(source, "source")?, endpoint(destination, "destination")?) };
        ask(ctx, Change::DisconnectBetween { source, destination }, index)
    })
}

/// Ask to join broadcast group `group` when the process returns.
///
/// # Safety
/// As [`ay_ctx_create`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_join(ctx: *mut ay_ctx, group: *const c_char, index: *mut usize) -> ay_status {
    boundary("ay_ctx_join", || {
        // SAFETY: the C caller's promise on `group`.
        let group = unsafe { text(group, "group")? };
        ask(ctx, Change::Join { group: group.to_owned() }, index)
    })
}

/// Ask to leave broadcast group `group` when the process returns.
///
/// # Safety
/// As [`ay_ctx_create`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_leave(ctx: *mut ay_ctx, group: *const c_char, index: *mut usize) -> ay_status {
    boundary("ay_ctx_leave", || {
        // SAFETY: the C caller's promise on `group`.
        let group = unsafe { text(group, "group")? };
        ask(ctx, Change::Leave { group: group.to_owned() }, index)
    })
}

/// How many changes this process's previous activation asked for (their outcomes), into
/// `*out`.
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_change_count(ctx: *mut ay_ctx, out: *mut usize) -> ay_status {
    boundary("ay_ctx_change_count", || {
        // SAFETY: the C caller's promise on `out`.
        with_ctx(ctx, |c, _| unsafe { put(out, c.changes().len(), "out") })
    })
}

/// The outcome of change `index` of this process's previous activation: `AY_OK` if it was
/// applied (a connection it made or removed goes to `*connection`, may be NULL; 0 when it
/// concerns none), else the status of the node's refusal with its message in
/// `ay_last_error` (`AY_ERR_UNKNOWN` for an unknown class, behavior or port, ...).
///
/// Errors besides the outcome's: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_ABSENT` (no change
/// `index`).
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `connection` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_change_outcome(ctx: *mut ay_ctx, index: usize, connection: *mut u64) -> ay_status {
    boundary("ay_ctx_change_outcome", || {
        let result = with_ctx(ctx, |c, _| {
            c.changes().get(index).map(|o| o.result.clone()).ok_or_else(|| {
                Fail::new(ay_status::AY_ERR_ABSENT, format!("the previous activation asked for no change {index}"))
            })
        })?;
        match result {
            Ok(applied) => {
                let id = match applied {
                    Applied::Connection(c) => c.0,
                    Applied::Done | Applied::Disconnected(_) => 0,
                };
                // SAFETY: the C caller's promise on `connection`.
                unsafe { put_optional(connection, id) };
                Ok(())
            }
            Err(e) => Err(Fail::new(core_status(&e), e.to_string())),
        }
    })
}

/// Ask node `source.node` to connect its port to `destination`, from a process: sent at once
/// (R6). The request's id goes to `*request` (follow it with `ay_node_request_status`).
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_PERIOD`, `AY_ERR_INVALID` (the source is
/// not `AY_NODE`).
///
/// # Safety
/// As [`ay_ctx_connect`]; `request` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_request_connect(
    ctx: *mut ay_ctx,
    source: *const ay_endpoint,
    destination: *const ay_endpoint,
    kind_: u32,
    period: f64,
    priority: i32,
    request: *mut u64,
) -> ay_status {
    boundary("ay_ctx_request_connect", || {
        // SAFETY: the C caller's promises on the endpoints.
        let (s, d) = unsafe { (endpoint(source, "source")?, endpoint(destination, "destination")?) };
        let k = kind(kind_, period)?;
        let id = with_ctx(ctx, |c, _| Ok(c.request_connect(&s, &d, k, ConnectOptions { priority })?))?;
        // SAFETY: the C caller's promise on `request`.
        unsafe { put_optional(request, id.0) };
        Ok(())
    })
}

/// Apply a plan (the TOML of `ayllu apply`, docs/cli.md) from this node to the nodes it
/// names, all at once or not at all (R8–R12), in real time: returns when it has ended (at most
/// the plan's hold). The report, as JSON (`ayllu apply --json`'s), goes to `buffer` as
/// `ay_ctx_read_text` copies text (`*length` gets its length even when it does not fit).
///
/// `AY_OK`: the team switched. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (a plan that does not parse or cannot run: the message says why),
/// `AY_ERR_ABSENT` (it aborted or is split: the report says which node refused and why),
/// `AY_ERR_BUFFER` (the report did not fit; the outcome is then in the message).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `plan` is NULL or NUL-terminated; `buffer`
/// is NULL or valid for `capacity` bytes; `length` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_apply(
    node: *mut ay_node,
    plan: *const c_char,
    buffer: *mut c_char,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_node_apply", || {
        // SAFETY: the C caller's promise on `plan`.
        let plan = unsafe { text(plan, "plan")? };
        let plan = Plan::from_toml(plan).map_err(|e| Fail::invalid(e.to_string()))?;
        let report = with_node(node, |n| apply(&mut n.node, &plan).map_err(|e| Fail::invalid(e.to_string())))?;
        let json = report.to_json().to_string();
        // SAFETY: the C caller's promises on buffer/capacity/length.
        unsafe { copy_out(json.as_bytes(), true, buffer.cast::<u8>(), capacity, length) }
            .map_err(|f| Fail::new(f.status, format!("{} (the transaction {})", f.message, report.outcome)))?;
        match report.outcome {
            Outcome::Switched => Ok(()),
            other => Err(Fail::new(ay_status::AY_ERR_ABSENT, format!("the transaction {other}: {report}"))),
        }
    })
}
