//! Behavior classes built from C: ports of every kind and value type (with lifespans and
//! windows), slots, monostables, and processes whose bodies are C functions (periodic,
//! triggered by a port, triggered by a monostable). A class is a builder owned by C until
//! [`crate::node::ay_node_define`] hands it to a node.

use std::ffi::{c_char, c_void};
use std::sync::{Arc, OnceLock};

use ayllu_core::{BehaviorClass, Duration, PortKind, PortSpec, Trigger, Value};

use crate::cstr::{put_optional, slice, text};
use crate::process::{self, ay_mono, ay_port, ay_process_fn, ay_slot};
use crate::register::{register_name, Registers};
use crate::registry::{self, Kind};
use crate::seconds::optional_secs;
use crate::status::{ay_status, boundary, Fail};

/// Port kind: the last value written (rule S3).
pub const AY_PORT_NORMAL: u32 = 0;
/// Port kind: the greatest value offered in the current window.
pub const AY_PORT_MAX: u32 = 1;
/// Port kind: the smallest value offered in the current window.
pub const AY_PORT_MIN: u32 = 2;
/// Port kind: the sum of the values offered in the current window.
pub const AY_PORT_SUM: u32 = 3;
/// Port kind: the value of the highest-priority connection.
pub const AY_PORT_PRIORITY: u32 = 4;

/// A behavior class under construction (opaque). Made by [`ay_class_new`] (or by the node
/// for [`crate::node::ay_node_define_with`]); consumed by [`crate::node::ay_node_define`] or
/// freed by [`ay_class_free`].
#[allow(non_camel_case_types)]
pub struct ay_class {
    pub(crate) class: BehaviorClass,
    pub(crate) registers: Arc<OnceLock<Registers>>,
}

impl ay_class {
    pub(crate) fn new(name: &str) -> ay_class {
        ay_class { class: BehaviorClass::new(name), registers: Arc::new(OnceLock::new()) }
    }
    /// Fix the register names for the processes; returns the class for the node.
    pub(crate) fn finish(self) -> BehaviorClass {
        let _ = self.registers.set(Registers::of(&self.class));
        self.class
    }
}

/// Run `f` on a live class.
pub(crate) fn with_class<T>(p: *mut ay_class, f: impl FnOnce(&mut ay_class) -> Result<T, Fail>) -> Result<T, Fail> {
    registry::check(p, Kind::Class, "class")?;
    // SAFETY: registered class pointers come from Box::into_raw and are unregistered before
    // they are freed, so `p` points to a live ay_class; a class is used by one thread at a
    // time (documented), so this is the only reference.
    f(unsafe { &mut *p })
}

/// Register a class built on the Rust side of the boundary (the builder of
/// `ay_node_define_with`) so that C can fill it.
pub(crate) fn lend(class: &mut ay_class) {
    registry::add(class as *const ay_class, Kind::Class);
}

/// End a [`lend`].
pub(crate) fn unlend(class: &mut ay_class) {
    let _ = registry::remove(class as *const ay_class, Kind::Class, "class");
}

/// A new, empty behavior class named `name` (it has only the implicit BLE ports `Local`,
/// `Inhibit`, `Best`).
///
/// Ownership: `*out` belongs to the caller until passed to `ay_node_define` (which consumes
/// it) or `ay_class_free`. Thread-safety: a class is used by one thread at a time.
/// Errors: `AY_ERR_NULL` (name or out), `AY_ERR_INVALID` (name not UTF-8 or empty).
///
/// # Safety
/// `name` is NULL or a NUL-terminated string; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_class_new(name: *const c_char, out: *mut *mut ay_class) -> ay_status {
    boundary("ay_class_new", || {
        // SAFETY: the caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        if name.is_empty() {
            return Err(Fail::invalid("a class needs a name"));
        }
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        let p = Box::into_raw(Box::new(ay_class::new(name)));
        registry::add(p, Kind::Class);
        // SAFETY: `out` is non-null and valid for a write (caller's promise).
        unsafe { out.write(p) };
        Ok(())
    })
}

/// Free a class that was not given to a node.
///
/// Ownership: takes the class; the handle is invalid afterwards. Thread-safety: not while
/// another thread uses the class. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE` (freed already or
/// consumed by `ay_node_define`).
///
/// # Safety
/// `cls` is NULL or a pointer this library returned (checked against the live handles).
#[no_mangle]
pub unsafe extern "C" fn ay_class_free(cls: *mut ay_class) -> ay_status {
    boundary("ay_class_free", || {
        registry::remove(cls, Kind::Class, "class")?;
        // SAFETY: registered class pointers come from Box::into_raw in ay_class_new and were
        // just unregistered, so this is the only release.
        drop(unsafe { Box::from_raw(cls) });
        Ok(())
    })
}

fn port_kind(kind: u32) -> Result<PortKind, Fail> {
    Ok(match kind {
        AY_PORT_NORMAL => PortKind::Normal,
        AY_PORT_MAX => PortKind::Max,
        AY_PORT_MIN => PortKind::Min,
        AY_PORT_SUM => PortKind::Sum,
        AY_PORT_PRIORITY => PortKind::Priority,
        other => return Err(Fail::invalid(format!("{other} is not a port kind (AY_PORT_NORMAL .. AY_PORT_PRIORITY)"))),
    })
}

fn declare_port(
    cls: *mut ay_class,
    name: *const c_char,
    default: Value,
    kind: u32,
    lifespan: f64,
    window: f64,
    out: *mut ay_port,
) -> Result<(), Fail> {
    with_class(cls, |c| {
        // SAFETY: the exported callers forward the C caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        let mut spec = PortSpec::new(name, default).kind(port_kind(kind)?);
        if let Some(l) = optional_secs(lifespan, "lifespan")? {
            spec = spec.lifespan(l);
        }
        if let Some(w) = optional_secs(window, "window")? {
            spec = spec.window(w);
        }
        let port = c.class.port(spec)?;
        // SAFETY: the exported callers forward the C caller's promise on `out`.
        unsafe { put_optional(out, ay_port { index: port.0 }) };
        Ok(())
    })
}

/// Declare a bool port `name` with default `initial`. Kinds, lifespan, window, ownership, threads and
/// errors as [`ay_class_port_int`].
///
/// # Safety
/// As [`ay_class_port_int`]; nothing more.
#[no_mangle]
pub unsafe extern "C" fn ay_class_port_bool(
    cls: *mut ay_class,
    name: *const c_char,
    initial: bool,
    kind: u32,
    lifespan: f64,
    window: f64,
    out: *mut ay_port,
) -> ay_status {
    boundary("ay_class_port_bool", || declare_port(cls, name, Value::Bool(initial), kind, lifespan, window, out))
}

/// Declare an integer (int64) port `name` with default `initial`.
///
/// `kind` is one of `AY_PORT_NORMAL`, `AY_PORT_MAX`, `AY_PORT_MIN`, `AY_PORT_SUM`,
/// `AY_PORT_PRIORITY`; `lifespan` (seconds, 0 = none) makes the port read as absent that long
/// after its last accepted value (rule S4); `window` (seconds, 0 = none; aggregating kinds
/// only) empties the port that long after the first value of a window. The new port's handle
/// goes to `*out` (may be NULL).
///
/// Ownership: borrows `cls` and `name` for the call. Thread-safety: one thread at a time per
/// class. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE` (class not live), `AY_ERR_INVALID` (empty,
/// reserved or taken name, unknown kind), `AY_ERR_TYPE` (a kind this type cannot have, e.g. a
/// Max text port), `AY_ERR_PERIOD` (negative/NaN lifespan or window), `AY_ERR_INVALID` also
/// for a window on a Normal port.
///
/// # Safety
/// `cls` is NULL or a pointer from this library; `name` is NULL or NUL-terminated; `out` is
/// NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_class_port_int(
    cls: *mut ay_class,
    name: *const c_char,
    initial: i64,
    kind: u32,
    lifespan: f64,
    window: f64,
    out: *mut ay_port,
) -> ay_status {
    boundary("ay_class_port_int", || declare_port(cls, name, Value::Int(initial), kind, lifespan, window, out))
}

/// Declare a float (double) port `name` with default `initial`. Kinds, lifespan, window, ownership, threads and
/// errors as [`ay_class_port_int`].
///
/// # Safety
/// As [`ay_class_port_int`]; nothing more.
#[no_mangle]
pub unsafe extern "C" fn ay_class_port_float(
    cls: *mut ay_class,
    name: *const c_char,
    initial: f64,
    kind: u32,
    lifespan: f64,
    window: f64,
    out: *mut ay_port,
) -> ay_status {
    boundary("ay_class_port_float", || declare_port(cls, name, Value::Float(initial), kind, lifespan, window, out))
}

/// Declare a text port `name` with default `initial` (NUL-terminated UTF-8, copied). Kinds, lifespan, window, ownership, threads and
/// errors as [`ay_class_port_int`].
///
/// # Safety
/// As [`ay_class_port_int`]; `initial` is NULL or NUL-terminated;
#[no_mangle]
pub unsafe extern "C" fn ay_class_port_text(
    cls: *mut ay_class,
    name: *const c_char,
    initial: *const c_char,
    kind: u32,
    lifespan: f64,
    window: f64,
    out: *mut ay_port,
) -> ay_status {
    boundary("ay_class_port_text", || {
        // SAFETY: the C caller promises `initial` is NULL or NUL-terminated.
        let initial = Value::text(unsafe { text(initial, "initial") }?);
        declare_port(cls, name, initial, kind, lifespan, window, out)
    })
}

/// Declare a vector port `name` whose default is the `length` doubles at `initial` (copied;
/// its length is the port's shape, D3.5). Kinds, lifespan and window as for
/// [`ay_class_port_float`]; Max and Min are refused for vectors (`AY_ERR_TYPE`).
///
/// Ownership: borrows everything for the call. Thread-safety: one thread at a time per class.
/// Errors: as [`ay_class_port_float`], and `AY_ERR_NULL` for a NULL `initial` with a length.
///
/// # Safety
/// `initial` is NULL (with `length` 0) or valid for `length` reads; the rest as for
/// [`ay_class_port_float`].
#[no_mangle]
pub unsafe extern "C" fn ay_class_port_vector(
    cls: *mut ay_class,
    name: *const c_char,
    initial: *const f64,
    length: usize,
    kind: u32,
    lifespan: f64,
    window: f64,
    out: *mut ay_port,
) -> ay_status {
    boundary("ay_class_port_vector", || {
        // SAFETY: forwarded promise on `initial`/`length`.
        let v = unsafe { slice(initial, length, "initial") }?;
        declare_port(cls, name, Value::vector(v), kind, lifespan, window, out)
    })
}

/// Declare a bytes port `name` whose default is the `length` bytes at `initial` (copied).
/// Bytes ports may be Normal or Priority. Lifespan and window as for [`ay_class_port_float`].
///
/// Ownership: borrows everything for the call. Thread-safety: one thread at a time per class.
/// Errors: as [`ay_class_port_vector`].
///
/// # Safety
/// As [`ay_class_port_vector`].
#[no_mangle]
pub unsafe extern "C" fn ay_class_port_bytes(
    cls: *mut ay_class,
    name: *const c_char,
    initial: *const u8,
    length: usize,
    kind: u32,
    lifespan: f64,
    window: f64,
    out: *mut ay_port,
) -> ay_status {
    boundary("ay_class_port_bytes", || {
        // SAFETY: forwarded promise on `initial`/`length`.
        let v = unsafe { slice(initial, length, "initial") }?;
        declare_port(cls, name, Value::bytes(v), kind, lifespan, window, out)
    })
}

fn declare_slot(cls: *mut ay_class, name: *const c_char, default: Value, out: *mut ay_slot) -> Result<(), Fail> {
    with_class(cls, |c| {
        // SAFETY: the exported callers forward the C caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        let slot = c.class.slot(name, default)?;
        // SAFETY: forwarded promise on `out`.
        unsafe { put_optional(out, ay_slot { index: slot.0 }) };
        Ok(())
    })
}

/// Declare a bool slot. As [`ay_class_slot_int`].
///
/// # Safety
/// As [`ay_class_slot_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_class_slot_bool(
    cls: *mut ay_class,
    name: *const c_char,
    initial: bool,
    out: *mut ay_slot,
) -> ay_status {
    boundary("ay_class_slot_bool", || declare_slot(cls, name, Value::Bool(initial), out))
}

/// Declare an integer slot `name` with default `initial`. A slot is a register only the
/// behavior's own processes see (rule S2); its type is `initial`'s for good. The handle goes
/// to `*out` (may be NULL).
///
/// Ownership: borrows everything for the call. Thread-safety: one thread at a time per class.
/// Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_INVALID` (empty, reserved or taken name).
///
/// # Safety
/// `cls` is NULL or a pointer from this library; `name` is NULL or NUL-terminated; `out` is
/// NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_class_slot_int(
    cls: *mut ay_class,
    name: *const c_char,
    initial: i64,
    out: *mut ay_slot,
) -> ay_status {
    boundary("ay_class_slot_int", || declare_slot(cls, name, Value::Int(initial), out))
}

/// Declare a float slot. As [`ay_class_slot_int`].
///
/// # Safety
/// As [`ay_class_slot_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_class_slot_float(
    cls: *mut ay_class,
    name: *const c_char,
    initial: f64,
    out: *mut ay_slot,
) -> ay_status {
    boundary("ay_class_slot_float", || declare_slot(cls, name, Value::Float(initial), out))
}

/// Declare a text slot (`initial` is copied). As [`ay_class_slot_int`].
///
/// # Safety
/// As [`ay_class_slot_int`]; `initial` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_class_slot_text(
    cls: *mut ay_class,
    name: *const c_char,
    initial: *const c_char,
    out: *mut ay_slot,
) -> ay_status {
    boundary("ay_class_slot_text", || {
        // SAFETY: the C caller promises `initial` is NULL or NUL-terminated.
        let initial = Value::text(unsafe { text(initial, "initial") }?);
        declare_slot(cls, name, initial, out)
    })
}

/// Declare a monostable `name`: true for a while after it is triggered (rule S2). The handle
/// goes to `*out` (may be NULL).
///
/// Ownership: borrows everything for the call. Thread-safety: one thread at a time per class.
/// Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_INVALID` (empty, reserved or taken name).
///
/// # Safety
/// `cls` is NULL or a pointer from this library; `name` is NULL or NUL-terminated; `out`
/// is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_class_monostable(cls: *mut ay_class, name: *const c_char, out: *mut ay_mono) -> ay_status {
    boundary("ay_class_monostable", || {
        with_class(cls, |c| {
            // SAFETY: the C caller's promise on `name`.
            let name = unsafe { text(name, "name") }?;
            let m = c.class.monostable(name)?;
            // SAFETY: the C caller's promise on `out`.
            unsafe { put_optional(out, ay_mono { index: m.0 }) };
            Ok(())
        })
    })
}

fn declare_process(
    cls: *mut ay_class,
    name: *const c_char,
    trigger: impl FnOnce(&ay_class) -> Result<Trigger, Fail>,
    body: ay_process_fn,
    user: *mut c_void,
) -> Result<(), Fail> {
    with_class(cls, |c| {
        // SAFETY: the exported callers forward the C caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        let Some(body) = body else { return Err(Fail::null("process function")) };
        let trigger = trigger(c)?;
        let registers = c.registers.clone();
        let user = user as usize;
        c.class.process(name, trigger, move |ctx| {
            let empty = Registers::default();
            process::run(ctx, body, user as *mut c_void, registers.get().unwrap_or(&empty));
        })?;
        Ok(())
    })
}

/// Declare a periodic process `name` running `body(ctx, user)` `hz` times a second (the
/// paper's `ayInitProcess(name, ratepersecond(hz))`), phase-locked to the behavior's creation;
/// late activations are skipped, never run in a burst (rule S7).
///
/// Ownership: `user` is passed through untouched to every activation of every behavior of
/// this class; it must stay valid as long as they exist. Thread-safety: one thread at a time
/// per class; `body` runs on the thread that steps the node. `body` must return normally (no
/// `longjmp` out of it, no C++ exception through it). Errors: `AY_ERR_NULL` (class, name or
/// body), `AY_ERR_HANDLE`, `AY_ERR_RATE` (zero, negative, NaN or infinite `hz`),
/// `AY_ERR_INVALID` (empty or taken name).
///
/// # Safety
/// `cls` is NULL or a pointer from this library; `name` is NULL or NUL-terminated; `body`
/// is NULL or a function with this signature.
#[no_mangle]
pub unsafe extern "C" fn ay_class_every_hz(
    cls: *mut ay_class,
    name: *const c_char,
    hz: f64,
    body: ay_process_fn,
    user: *mut c_void,
) -> ay_status {
    boundary("ay_class_every_hz", || {
        declare_process(cls, name, |_| Ok(Trigger::Periodic(Duration::try_from_hz(hz)?)), body, user)
    })
}

/// Declare a periodic process `name` at `hz` activations per second that is activated only
/// while port `port` of its behavior holds a fresh value (rule S7, D7.5): the due times of
/// [`ay_class_every_hz`], without the runs that would find `port` stale (no run, not counted).
/// Ownership and threads as [`ay_class_every_hz`].
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_RATE` (zero, negative, NaN or infinite
/// `hz`), `AY_ERR_UNKNOWN` (the class has no port `port`; declare the port first),
/// `AY_ERR_INVALID` (empty or taken name).
///
/// # Safety
/// As [`ay_class_every_hz`]; `port` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_class_every_hz_while_fresh(
    cls: *mut ay_class,
    name: *const c_char,
    hz: f64,
    port: *const c_char,
    body: ay_process_fn,
    user: *mut c_void,
) -> ay_status {
    boundary("ay_class_every_hz_while_fresh", || {
        let trigger = |c: &ay_class| {
            let period = Duration::try_from_hz(hz)?;
            // SAFETY: the C caller's promise on `port`.
            let p = unsafe { text(port, "port") }?;
            let handle = c.class.port_handle(register_name(p)).ok_or_else(|| {
                Fail::new(ay_status::AY_ERR_UNKNOWN, format!("class {} has no port `{p}`", c.class.name()))
            })?;
            Ok(Trigger::PeriodicWhileFresh(period, handle))
        };
        declare_process(cls, name, trigger, body, user)
    })
}

/// Declare a process `name` that runs whenever port `port` of its behavior accepts a value
/// (from a connection or a process; rule S7). Ownership and threads as [`ay_class_every_hz`].
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_UNKNOWN` (the class has no port `port`;
/// declare the port first), `AY_ERR_INVALID` (empty or taken name).
///
/// # Safety
/// As [`ay_class_every_hz`]; `port` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_class_on_write(
    cls: *mut ay_class,
    name: *const c_char,
    port: *const c_char,
    body: ay_process_fn,
    user: *mut c_void,
) -> ay_status {
    boundary("ay_class_on_write", || {
        let trigger = |c: &ay_class| {
            // SAFETY: the C caller's promise on `port`.
            let p = unsafe { text(port, "port") }?;
            c.class.port_handle(register_name(p)).map(Trigger::OnWrite).ok_or_else(|| {
                Fail::new(ay_status::AY_ERR_UNKNOWN, format!("class {} has no port `{p}`", c.class.name()))
            })
        };
        declare_process(cls, name, trigger, body, user)
    })
}

/// Declare a process `name` that runs whenever monostable `mono` of its behavior rises or
/// falls (rule S7). Ownership and threads as [`ay_class_every_hz`].
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_UNKNOWN` (no monostable `mono`; declare it
/// first), `AY_ERR_INVALID` (empty or taken name).
///
/// # Safety
/// As [`ay_class_every_hz`]; `mono` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_class_on_monostable(
    cls: *mut ay_class,
    name: *const c_char,
    mono: *const c_char,
    body: ay_process_fn,
    user: *mut c_void,
) -> ay_status {
    boundary("ay_class_on_monostable", || {
        let trigger = |c: &ay_class| {
            // SAFETY: the C caller's promise on `mono`.
            let m = unsafe { text(mono, "monostable") }?;
            c.class.mono_handle(m).map(Trigger::OnMonostable).ok_or_else(|| {
                Fail::new(ay_status::AY_ERR_UNKNOWN, format!("class {} has no monostable `{m}`", c.class.name()))
            })
        };
        declare_process(cls, name, trigger, body, user)
    })
}
