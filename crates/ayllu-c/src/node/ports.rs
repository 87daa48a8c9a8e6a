//! Ports from outside the behaviors: write and read a behavior's port by name, or through an
//! [`ay_port_ref`] resolved once for loops that must not look names up, ask whether a value is
//! fresh (rule S4), and empty an aggregating port.
//!
//! Promise: a write here is the behavior's own write (it propagates at once), and a read says
//! by its status whether the value is fresh, exactly as a process's read does.

use std::ffi::c_char;

use ayllu::{PortRef, Value};

use super::handle::{ay_node, with_node, NodeState};
use crate::cstr::{put, slice, text};
use crate::process::{copy_items, deliver, freshness, scalar, Scalar};
use crate::register::register_name;
use crate::status::{ay_status, boundary, Fail};

/// A port of a behavior on a node, for repeated writes and reads without name lookups
/// (from `ay_node_port`). It stays valid while the behavior exists; after the behavior is
/// removed, calls with it return `AY_ERR_UNKNOWN`.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ay_port_ref {
    /// Index in the node's table of handles.
    pub index: u32,
}

/// (behavior, port) names from C, with the paper's BLE names mapped.
///
/// # Safety
/// Both are NULL or NUL-terminated strings that outlive `'a`.
pub(crate) unsafe fn names<'a>(behavior: *const c_char, port: *const c_char) -> Result<(&'a str, &'a str), Fail> {
    // SAFETY: forwarded promise.
    let (b, p) = unsafe { (text(behavior, "behavior")?, text(port, "port")?) };
    Ok((b, register_name(p)))
}

fn write_value(node: *mut ay_node, behavior: *const c_char, port: *const c_char, value: Value) -> Result<(), Fail> {
    // SAFETY: the exported callers forward the C caller's promises on the names.
    let (b, p) = unsafe { names(behavior, port) }?;
    with_node(node, |s| Ok(s.node.write(b, p, value)?))
}

fn read_value(node: *mut ay_node, behavior: *const c_char, port: *const c_char) -> Result<(Value, bool), Fail> {
    // SAFETY: the exported callers forward the C caller's promises on the names.
    let (b, p) = unsafe { names(behavior, port) }?;
    with_node(node, |s| Ok((s.node.read(b, p)?, s.node.fresh(b, p)?)))
}

fn port_ref(s: &NodeState, r: ay_port_ref) -> Result<PortRef, Fail> {
    s.refs.get(r.index as usize).copied().ok_or_else(|| {
        Fail::new(ay_status::AY_ERR_UNKNOWN, format!("port handle {} was not made by this node", r.index))
    })
}

/// Write through a port handle now (the `ay_node_write_*_ref`).
fn write_ref(node: *mut ay_node, port: ay_port_ref, value: Value) -> Result<(), Fail> {
    with_node(node, |s| {
        let r = port_ref(s, port)?;
        let core = s.node.core_mut();
        let now = core.now(); // core_mut told it the present
        Ok(core.write(now, r, value)?)
    })
}

/// Read through a port handle now, and whether the value is fresh (the `ay_node_read_*_ref`).
fn read_ref(node: *mut ay_node, port: ay_port_ref) -> Result<(Value, bool), Fail> {
    with_node(node, |s| {
        let r = port_ref(s, port)?;
        let now = s.node.now();
        let core = s.node.core();
        Ok((core.read_at(now, r)?, core.fresh_at(now, r)?))
    })
}

/// As [`ay_node_write_int`], for a bool port.
///
/// # Safety
/// As [`ay_node_write_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_bool(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    value: bool,
) -> ay_status {
    boundary("ay_node_write_bool", || write_value(node, behavior, port, value.into_value()))
}

/// As [`ay_node_read_int`], for a bool port.
///
/// # Safety
/// As [`ay_node_read_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_bool(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    out: *mut bool,
) -> ay_status {
    boundary("ay_node_read_bool", || {
        let (v, fresh) = read_value(node, behavior, port)?;
        deliver(out, scalar::<bool>(&v, "the port")?, fresh)
    })
}

/// As [`ay_node_write_int_ref`], for a bool port.
///
/// # Safety
/// As [`ay_node_write_int_ref`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_bool_ref(node: *mut ay_node, port: ay_port_ref, value: bool) -> ay_status {
    boundary("ay_node_write_bool_ref", || write_ref(node, port, value.into_value()))
}

/// As [`ay_node_read_int_ref`], for a bool port.
///
/// # Safety
/// As [`ay_node_read_int_ref`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_bool_ref(node: *mut ay_node, port: ay_port_ref, out: *mut bool) -> ay_status {
    boundary("ay_node_read_bool_ref", || {
        let (v, fresh) = read_ref(node, port)?;
        deliver(out, scalar::<bool>(&v, "the port")?, fresh)
    })
}

/// Write `behavior.port` as its behavior would, now (propagates at once; remote hops leave at
/// the next step).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (behavior or port), `AY_ERR_TYPE` (the port holds another type).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the names are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_int(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    value: i64,
) -> ay_status {
    boundary("ay_node_write_int", || write_value(node, behavior, port, value.into_value()))
}

/// Read `behavior.port` now into `*out` (its default while an aggregating port is empty);
/// `AY_OK` if the value is fresh, `AY_ERR_ABSENT` if not (rule S4).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN`, `AY_ERR_TYPE` (`*out` untouched), `AY_ERR_ABSENT`.
///
/// # Safety
/// As [`ay_node_write_int`]; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_int(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    out: *mut i64,
) -> ay_status {
    boundary("ay_node_read_int", || {
        let (v, fresh) = read_value(node, behavior, port)?;
        deliver(out, scalar::<i64>(&v, "the port")?, fresh)
    })
}

/// Write through a port handle from `ay_node_port` (no name lookups). As
/// [`ay_node_write_int`]; `AY_ERR_UNKNOWN` also for a handle whose behavior was removed.
///
/// Ownership: keeps nothing. Thread-safety: the node's thread.
///
/// # Safety
/// `node` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_int_ref(node: *mut ay_node, port: ay_port_ref, value: i64) -> ay_status {
    boundary("ay_node_write_int_ref", || write_ref(node, port, value.into_value()))
}

/// Read through a port handle from `ay_node_port`. As [`ay_node_read_int`].
///
/// # Safety
/// `node` is NULL or a pointer from this library; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_int_ref(node: *mut ay_node, port: ay_port_ref, out: *mut i64) -> ay_status {
    boundary("ay_node_read_int_ref", || {
        let (v, fresh) = read_ref(node, port)?;
        deliver(out, scalar::<i64>(&v, "the port")?, fresh)
    })
}

/// As [`ay_node_write_int`], for a float port.
///
/// # Safety
/// As [`ay_node_write_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_float(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    value: f64,
) -> ay_status {
    boundary("ay_node_write_float", || write_value(node, behavior, port, value.into_value()))
}

/// As [`ay_node_read_int`], for a float port.
///
/// # Safety
/// As [`ay_node_read_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_float(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    out: *mut f64,
) -> ay_status {
    boundary("ay_node_read_float", || {
        let (v, fresh) = read_value(node, behavior, port)?;
        deliver(out, scalar::<f64>(&v, "the port")?, fresh)
    })
}

/// As [`ay_node_write_int_ref`], for a float port.
///
/// # Safety
/// As [`ay_node_write_int_ref`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_float_ref(node: *mut ay_node, port: ay_port_ref, value: f64) -> ay_status {
    boundary("ay_node_write_float_ref", || write_ref(node, port, value.into_value()))
}

/// As [`ay_node_read_int_ref`], for a float port.
///
/// # Safety
/// As [`ay_node_read_int_ref`].
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_float_ref(node: *mut ay_node, port: ay_port_ref, out: *mut f64) -> ay_status {
    boundary("ay_node_read_float_ref", || {
        let (v, fresh) = read_ref(node, port)?;
        deliver(out, scalar::<f64>(&v, "the port")?, fresh)
    })
}

/// Write a text port (copied). As [`ay_node_write_int`]; `AY_ERR_INVALID` for text that is not
/// UTF-8.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the strings are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_text(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    value: *const c_char,
) -> ay_status {
    boundary("ay_node_write_text", || {
        // SAFETY: the C caller's promise on `value`.
        let v = unsafe { text(value, "value") }?;
        write_value(node, behavior, port, Value::text(v))
    })
}

/// Write a vector port (`length` doubles, copied). As [`ay_node_write_int`].
///
/// # Safety
/// As [`ay_node_write_int`]; `value` is NULL (length 0) or valid for `length` reads.
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_vector(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    value: *const f64,
    length: usize,
) -> ay_status {
    boundary("ay_node_write_vector", || {
        // SAFETY: the C caller's promise on value/length.
        let v = unsafe { slice(value, length, "value") }?;
        write_value(node, behavior, port, Value::vector(v))
    })
}

/// Write a bytes port (`length` bytes, copied). As [`ay_node_write_int`].
///
/// # Safety
/// As [`ay_node_write_int`]; `value` is NULL (length 0) or valid for `length` reads.
#[no_mangle]
pub unsafe extern "C" fn ay_node_write_bytes(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    value: *const u8,
    length: usize,
) -> ay_status {
    boundary("ay_node_write_bytes", || {
        // SAFETY: the C caller's promise on value/length.
        let v = unsafe { slice(value, length, "value") }?;
        write_value(node, behavior, port, Value::bytes(v))
    })
}

/// Read a text port into `buffer` (`capacity` bytes, NUL-terminated); `*length` (may be NULL)
/// gets the text's length. Fresh as [`ay_node_read_int`]; `AY_ERR_BUFFER` when too small.
///
/// # Safety
/// As [`ay_node_read_int`]; `buffer` is NULL or valid for `capacity` bytes.
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_text(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    buffer: *mut c_char,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_node_read_text", || {
        let (v, fresh) = read_value(node, behavior, port)?;
        // SAFETY: the C caller's promises on buffer/capacity/length.
        unsafe {
            copy_items(&v, |v| v.as_text().map(str::as_bytes), "text", true, buffer.cast::<u8>(), capacity, length)
        }?;
        freshness(fresh)
    })
}

/// Read a vector port into `buffer` (`capacity` doubles); `*length` (may be NULL) gets its
/// length. As [`ay_node_read_text`].
///
/// # Safety
/// As [`ay_node_read_int`]; `buffer` is NULL or valid for `capacity` doubles.
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_vector(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    buffer: *mut f64,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_node_read_vector", || {
        let (v, fresh) = read_value(node, behavior, port)?;
        // SAFETY: the C caller's promises on buffer/capacity/length.
        unsafe { copy_items(&v, Value::as_vector, "a vector", false, buffer, capacity, length) }?;
        freshness(fresh)
    })
}

/// Read a bytes port into `buffer` (`capacity` bytes); `*length` (may be NULL) gets its
/// length. As [`ay_node_read_text`].
///
/// # Safety
/// As [`ay_node_read_int`]; `buffer` is NULL or valid for `capacity` bytes.
#[no_mangle]
pub unsafe extern "C" fn ay_node_read_bytes(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    buffer: *mut u8,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_node_read_bytes", || {
        let (v, fresh) = read_value(node, behavior, port)?;
        // SAFETY: the C caller's promises on buffer/capacity/length.
        unsafe { copy_items(&v, Value::as_bytes, "bytes", false, buffer, capacity, length) }?;
        freshness(fresh)
    })
}

/// Whether `behavior.port` holds a fresh value now (rule S4), into `*out`.
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
pub unsafe extern "C" fn ay_node_fresh(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    out: *mut bool,
) -> ay_status {
    boundary("ay_node_fresh", || {
        // SAFETY: the C caller's promises on the names.
        let (b, p) = unsafe { names(behavior, port) }?;
        let fresh = with_node(node, |s| Ok(s.node.fresh(b, p)?))?;
        // SAFETY: the C caller's promise on `out`.
        unsafe { put(out, fresh, "out") }
    })
}

/// A handle to `behavior.port` for the `_ref` reads and writes, into `*out`.
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
pub unsafe extern "C" fn ay_node_port(
    node: *mut ay_node,
    behavior: *const c_char,
    port: *const c_char,
    out: *mut ay_port_ref,
) -> ay_status {
    boundary("ay_node_port", || {
        // SAFETY: the C caller's promises on the names.
        let (b, p) = unsafe { names(behavior, port) }?;
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        let index = with_node(node, |s| {
            let r = s.node.core().port(b, p)?;
            let index = match s.refs.iter().position(|x| *x == r) {
                Some(i) => i,
                None => {
                    s.refs.push(r);
                    s.refs.len() - 1
                }
            };
            u32::try_from(index).map_err(|_| Fail::invalid("too many port handles"))
        })?;
        // SAFETY: the C caller's promise on `out`.
        unsafe { put(out, ay_port_ref { index }, "out") }
    })
}

/// Empty aggregating port `behavior.port` now.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the names are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_reset(node: *mut ay_node, behavior: *const c_char, port: *const c_char) -> ay_status {
    boundary("ay_node_reset", || {
        // SAFETY: the C caller's promises on the names.
        let (b, p) = unsafe { names(behavior, port) }?;
        with_node(node, |s| {
            let r = s.node.core().port(b, p)?;
            Ok(s.node.core_mut().reset(r)?)
        })
    })
}
