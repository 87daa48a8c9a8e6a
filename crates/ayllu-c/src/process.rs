//! The process context: what a C process body sees while it runs (the paper's `ayLocalPort`,
//! `ayReadIntPort`, `ayWriteIntPort`, slots, monostables). A context is valid only during the
//! call it was passed to; a call with a context from elsewhere returns `AY_ERR_CONTEXT`.

use std::cell::Cell;
use std::ffi::{c_char, c_void};

use ayllu_core::{Ctx, DropCause, Duration, Mono, Port, Slot, Value};

use crate::cstr::{copy_out, put, slice, text};
use crate::register::{Register, Registers};
use crate::seconds::required_secs;
use crate::status::{ay_status, boundary, Fail};

/// A port of the running behavior, as its processes name it (index in its class: the
/// implicit BLE ports `Local`, `Inhibit`, `Best` are 0, 1, 2).
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ay_port {
    /// Index among the class's ports.
    pub index: u16,
}

/// A slot of the running behavior (index in its class).
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ay_slot {
    /// Index among the class's slots.
    pub index: u16,
}

/// A monostable of the running behavior (index in its class).
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ay_mono {
    /// Index among the class's monostables.
    pub index: u16,
}

/// The running process's context (opaque; valid only during the call it is passed to).
#[allow(non_camel_case_types)]
pub struct ay_ctx {
    ctx: *mut Ctx<'static>,
    registers: *const Registers,
}

/// A process body: called with the context of the running behavior and the `user` pointer
/// given when the process was declared. It must return normally and must not block.
#[allow(non_camel_case_types)]
pub type ay_process_fn = Option<unsafe extern "C" fn(ctx: *mut ay_ctx, user: *mut c_void)>;

thread_local! {
    /// The context of the C process running on this thread (NULL: none).
    static CURRENT: Cell<*const ay_ctx> = const { Cell::new(std::ptr::null()) };
}

/// Run one activation of a C process body.
pub(crate) fn run(
    ctx: &mut Ctx<'_>,
    body: unsafe extern "C" fn(*mut ay_ctx, *mut c_void),
    user: *mut c_void,
    registers: &Registers,
) {
    let mut frame = ay_ctx { ctx: (ctx as *mut Ctx<'_>).cast::<Ctx<'static>>(), registers };
    let frame_ptr: *mut ay_ctx = &mut frame;
    // Restored afterwards: a body that steps another node runs that node's processes inside
    // this one.
    let previous = CURRENT.with(|c| c.replace(frame_ptr));
    // SAFETY: `body` is a C function of this signature, given when the process was declared;
    // `frame` outlives the call and points to the live `ctx`, which nothing else touches
    // until the body returns.
    unsafe { body(frame_ptr, user) };
    CURRENT.with(|c| c.set(previous));
}

/// Run `f` with the context `p`, if it is the running process's.
pub(crate) fn with_ctx<T>(
    p: *mut ay_ctx,
    f: impl FnOnce(&mut Ctx<'_>, &Registers) -> Result<T, Fail>,
) -> Result<T, Fail> {
    if p.is_null() {
        return Err(Fail::null("ctx"));
    }
    if CURRENT.with(Cell::get) != p.cast_const() {
        return Err(Fail::new(
            ay_status::AY_ERR_CONTEXT,
            "this context is not the running process's: a context is valid only during the call it was passed to",
        ));
    }
    // SAFETY: `p` is the frame `run` made for the call in progress on this thread, so it and
    // the `Ctx` and `Registers` it points to are alive; the body that called us holds no
    // Rust reference to them.
    let frame = unsafe { &mut *p };
    // SAFETY: as above: valid for the duration of the current activation.
    let (ctx, registers) = unsafe { (&mut *frame.ctx, &*frame.registers) };
    f(ctx, registers)
}

fn port_of(registers: &Registers, port: ay_port) -> Result<Port, Fail> {
    if usize::from(port.index) < registers.ports {
        Ok(Port(port.index))
    } else {
        Err(Fail::new(ay_status::AY_ERR_UNKNOWN, format!("port handle {} is not one of this behavior's", port.index)))
    }
}

fn slot_of(registers: &Registers, slot: ay_slot) -> Result<Slot, Fail> {
    if usize::from(slot.index) < registers.slots {
        Ok(Slot(slot.index))
    } else {
        Err(Fail::new(ay_status::AY_ERR_UNKNOWN, format!("slot handle {} is not one of this behavior's", slot.index)))
    }
}

fn mono_of(registers: &Registers, mono: ay_mono) -> Result<Mono, Fail> {
    if usize::from(mono.index) < registers.monos {
        Ok(Mono(mono.index))
    } else {
        Err(Fail::new(
            ay_status::AY_ERR_UNKNOWN,
            format!("monostable handle {} is not one of this behavior's", mono.index),
        ))
    }
}

fn lookup(registers: &Registers, name: *const c_char) -> Result<(Register, &str), Fail> {
    // SAFETY: the exported callers forward the C caller's promise on `name`.
    let name = unsafe { text(name, "name") }?;
    registers
        .get(name)
        .map(|r| (r, name))
        .ok_or_else(|| Fail::new(ay_status::AY_ERR_UNKNOWN, format!("this behavior has no register `{name}`")))
}

/// The handle of the running behavior's port `name` (the paper's `ayLocalPort`; `BLE_Local`,
/// `BLE_Inhibit` and `BLE_Best` name the implicit BLE ports).
///
/// Ownership: borrows `name` for the call. Thread-safety: only inside the process `ctx` was
/// given to. Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN` (no such register, or it
/// is a slot or monostable).
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `name` is NULL or NUL-terminated; `out` is
/// NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_port(ctx: *mut ay_ctx, name: *const c_char, out: *mut ay_port) -> ay_status {
    boundary("ay_ctx_port", || {
        with_ctx(ctx, |_, regs| match lookup(regs, name)? {
            // SAFETY: the C caller's promise on `out`.
            (Register::Port(i), _) => unsafe { put(out, ay_port { index: i }, "out") },
            (_, n) => Err(Fail::new(ay_status::AY_ERR_UNKNOWN, format!("`{n}` is not a port of this behavior"))),
        })
    })
}

/// The handle of the running behavior's slot `name`. As [`ay_ctx_port`].
///
/// # Safety
/// As [`ay_ctx_port`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_slot(ctx: *mut ay_ctx, name: *const c_char, out: *mut ay_slot) -> ay_status {
    boundary("ay_ctx_slot", || {
        with_ctx(ctx, |_, regs| match lookup(regs, name)? {
            // SAFETY: the C caller's promise on `out`.
            (Register::Slot(i), _) => unsafe { put(out, ay_slot { index: i }, "out") },
            (_, n) => Err(Fail::new(ay_status::AY_ERR_UNKNOWN, format!("`{n}` is not a slot of this behavior"))),
        })
    })
}

/// The handle of the running behavior's monostable `name`. As [`ay_ctx_port`].
///
/// # Safety
/// As [`ay_ctx_port`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_monostable(ctx: *mut ay_ctx, name: *const c_char, out: *mut ay_mono) -> ay_status {
    boundary("ay_ctx_monostable", || {
        with_ctx(ctx, |_, regs| match lookup(regs, name)? {
            // SAFETY: the C caller's promise on `out`.
            (Register::Mono(i), _) => unsafe { put(out, ay_mono { index: i }, "out") },
            (_, n) => Err(Fail::new(ay_status::AY_ERR_UNKNOWN, format!("`{n}` is not a monostable of this behavior"))),
        })
    })
}

/// A scalar C type a port or slot can hold.
pub(crate) trait Scalar: Copy {
    const TYPE: &'static str;
    fn from_value(v: &Value) -> Option<Self>;
    fn into_value(self) -> Value;
}

impl Scalar for bool {
    const TYPE: &'static str = "bool";
    fn from_value(v: &Value) -> Option<bool> {
        v.as_bool()
    }
    fn into_value(self) -> Value {
        Value::Bool(self)
    }
}

impl Scalar for i64 {
    const TYPE: &'static str = "int";
    fn from_value(v: &Value) -> Option<i64> {
        v.as_int()
    }
    fn into_value(self) -> Value {
        Value::Int(self)
    }
}

impl Scalar for f64 {
    const TYPE: &'static str = "float";
    fn from_value(v: &Value) -> Option<f64> {
        v.as_float()
    }
    fn into_value(self) -> Value {
        Value::Float(self)
    }
}

/// `v` as a `T`, or `AY_ERR_TYPE` naming both types.
pub(crate) fn scalar<T: Scalar>(v: &Value, what: &str) -> Result<T, Fail> {
    T::from_value(v).ok_or_else(|| {
        Fail::new(ay_status::AY_ERR_TYPE, format!("{what} holds a {}, not a {} (rule S1)", v.ty().name(), T::TYPE))
    })
}

/// `AY_ERR_ABSENT` for a read value that is not fresh (rule S4).
pub(crate) fn freshness(fresh: bool) -> Result<(), Fail> {
    if fresh {
        Ok(())
    } else {
        Err(Fail::new(ay_status::AY_ERR_ABSENT, "the port holds no fresh value (the output has what it reads as)"))
    }
}

/// Store a read value, then say whether it was fresh.
pub(crate) fn deliver<T>(out: *mut T, value: T, fresh: bool) -> Result<(), Fail> {
    // SAFETY: the exported callers forward the C caller's promise on `out`.
    unsafe { put(out, value, "out") }?;
    freshness(fresh)
}

/// The result of a process's own write: refused values are errors; a value the port's merge
/// absorbed, or whose propagation a window stopped, was still written (rule S6).
pub(crate) fn written(r: Result<(), DropCause>) -> Result<(), Fail> {
    match r {
        Ok(()) => Ok(()),
        Err(DropCause::TypeMismatch | DropCause::ShapeMismatch) => {
            Err(Fail::new(ay_status::AY_ERR_TYPE, "the value's type or shape is not the port's (rule S1)"))
        }
        Err(DropCause::NotANumber) => Err(Fail::invalid("NaN cannot be written into an ordered port")),
        Err(DropCause::UnknownBehavior | DropCause::UnknownPort) => {
            Err(Fail::new(ay_status::AY_ERR_UNKNOWN, "the port no longer exists"))
        }
        Err(_) => Ok(()),
    }
}

/// Copy the items `get` finds in a read value into `buffer` (NUL-terminated if `terminate`;
/// `*length` gets their count, as [`copy_out`]); `AY_ERR_TYPE` naming `what` (e.g. "a
/// vector") when the value holds another type.
///
/// # Safety
/// As [`copy_out`]: `buffer` is NULL or valid for `capacity` items, `length` is NULL or valid
/// for a write.
pub(crate) unsafe fn copy_items<T: Copy + Default>(
    v: &Value,
    get: impl FnOnce(&Value) -> Option<&[T]>,
    what: &str,
    terminate: bool,
    buffer: *mut T,
    capacity: usize,
    length: *mut usize,
) -> Result<(), Fail> {
    let items = get(v)
        .ok_or_else(|| Fail::new(ay_status::AY_ERR_TYPE, format!("the port holds a {}, not {what}", v.ty().name())))?;
    // SAFETY: forwarded promises on buffer/capacity/length.
    unsafe { copy_out(items, terminate, buffer, capacity, length) }
}

/// Read the running behavior's `port` as a `T` into `*out` (the scalar `ay_ctx_read_*`).
fn read_scalar<T: Scalar>(ctx: *mut ay_ctx, port: ay_port, out: *mut T) -> Result<(), Fail> {
    with_ctx(ctx, |c, regs| {
        let p = port_of(regs, port)?;
        let v = scalar::<T>(&c.read(p), "the port")?;
        deliver(out, v, c.fresh(p))
    })
}

/// Write the running behavior's `port` with the value `value` makes once the context and the
/// port are known to be good (the `ay_ctx_write_*`).
fn write_port(ctx: *mut ay_ctx, port: ay_port, value: impl FnOnce() -> Result<Value, Fail>) -> Result<(), Fail> {
    with_ctx(ctx, |c, regs| {
        let p = port_of(regs, port)?;
        written(c.write(p, value()?))
    })
}

/// Read the running behavior's `slot` as a `T` into `*out` (the `ay_ctx_slot_get_*`).
fn get_slot<T: Scalar>(ctx: *mut ay_ctx, slot: ay_slot, out: *mut T) -> Result<(), Fail> {
    with_ctx(ctx, |c, regs| {
        let s = slot_of(regs, slot)?;
        let v = scalar::<T>(&c.slot(s), "the slot")?;
        // SAFETY: the exported callers forward the C caller's promise on `out`.
        unsafe { put(out, v, "out") }
    })
}

/// Set the running behavior's `slot` (the `ay_ctx_slot_set_*`).
fn set_slot(ctx: *mut ay_ctx, slot: ay_slot, value: Value) -> Result<(), Fail> {
    with_ctx(ctx, |c, regs| {
        let s = slot_of(regs, slot)?;
        Ok(c.set_slot(s, value)?)
    })
}

/// As [`ay_ctx_read_int`], for a bool port.
///
/// # Safety
/// As [`ay_ctx_read_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_read_bool(ctx: *mut ay_ctx, port: ay_port, out: *mut bool) -> ay_status {
    boundary("ay_ctx_read_bool", || read_scalar(ctx, port, out))
}

/// As [`ay_ctx_write_int`], for a bool port.
///
/// # Safety
/// As [`ay_ctx_write_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_write_bool(ctx: *mut ay_ctx, port: ay_port, value: bool) -> ay_status {
    boundary("ay_ctx_write_bool", || write_port(ctx, port, || Ok(value.into_value())))
}

/// As [`ay_ctx_slot_get_int`], for a bool slot.
///
/// # Safety
/// As [`ay_ctx_slot_get_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_slot_get_bool(ctx: *mut ay_ctx, slot: ay_slot, out: *mut bool) -> ay_status {
    boundary("ay_ctx_slot_get_bool", || get_slot(ctx, slot, out))
}

/// As [`ay_ctx_slot_set_int`], for a bool slot.
///
/// # Safety
/// As [`ay_ctx_slot_set_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_slot_set_bool(ctx: *mut ay_ctx, slot: ay_slot, value: bool) -> ay_status {
    boundary("ay_ctx_slot_set_bool", || set_slot(ctx, slot, value.into_value()))
}

/// Read the running behavior's port: `*out` receives what the port reads as (its default
/// while an aggregating port is empty); the status says whether that value is fresh (`AY_OK`)
/// or not (`AY_ERR_ABSENT`, rule S4).
///
/// Ownership: nothing kept. Thread-safety: only inside the process `ctx` was given to.
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN` (handle not of this behavior),
/// `AY_ERR_TYPE` (the port holds another type; `*out` untouched), `AY_ERR_ABSENT`.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_read_int(ctx: *mut ay_ctx, port: ay_port, out: *mut i64) -> ay_status {
    boundary("ay_ctx_read_int", || read_scalar(ctx, port, out))
}

/// Write the running behavior's own port (never blocked by suppression; inhibition, another's
/// OverrideOut or a WriteInhibit may stop its propagation, rule S6).
///
/// Ownership: nothing kept. Thread-safety: only inside the process `ctx` was given to.
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`, `AY_ERR_TYPE` (the port holds
/// another type), `AY_ERR_INVALID` (NaN into a Max/Min port).
///
/// # Safety
/// `ctx` is NULL or a context passed to a process.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_write_int(ctx: *mut ay_ctx, port: ay_port, value: i64) -> ay_status {
    boundary("ay_ctx_write_int", || write_port(ctx, port, || Ok(value.into_value())))
}

/// Read a slot of the running behavior into `*out`.
///
/// Ownership: nothing kept. Thread-safety: only inside the process `ctx` was given to.
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`, `AY_ERR_TYPE`.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_slot_get_int(ctx: *mut ay_ctx, slot: ay_slot, out: *mut i64) -> ay_status {
    boundary("ay_ctx_slot_get_int", || get_slot(ctx, slot, out))
}

/// Set a slot of the running behavior (never propagated: slots are not connectable).
///
/// Ownership: nothing kept. Thread-safety: only inside the process `ctx` was given to.
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`, `AY_ERR_TYPE`.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_slot_set_int(ctx: *mut ay_ctx, slot: ay_slot, value: i64) -> ay_status {
    boundary("ay_ctx_slot_set_int", || set_slot(ctx, slot, value.into_value()))
}

/// As [`ay_ctx_read_int`], for a float port.
///
/// # Safety
/// As [`ay_ctx_read_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_read_float(ctx: *mut ay_ctx, port: ay_port, out: *mut f64) -> ay_status {
    boundary("ay_ctx_read_float", || read_scalar(ctx, port, out))
}

/// As [`ay_ctx_write_int`], for a float port.
///
/// # Safety
/// As [`ay_ctx_write_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_write_float(ctx: *mut ay_ctx, port: ay_port, value: f64) -> ay_status {
    boundary("ay_ctx_write_float", || write_port(ctx, port, || Ok(value.into_value())))
}

/// As [`ay_ctx_slot_get_int`], for a float slot.
///
/// # Safety
/// As [`ay_ctx_slot_get_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_slot_get_float(ctx: *mut ay_ctx, slot: ay_slot, out: *mut f64) -> ay_status {
    boundary("ay_ctx_slot_get_float", || get_slot(ctx, slot, out))
}

/// As [`ay_ctx_slot_set_int`], for a float slot.
///
/// # Safety
/// As [`ay_ctx_slot_set_int`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_slot_set_float(ctx: *mut ay_ctx, slot: ay_slot, value: f64) -> ay_status {
    boundary("ay_ctx_slot_set_float", || set_slot(ctx, slot, value.into_value()))
}

/// Read a text port into `buffer` (`capacity` bytes, NUL-terminated); `*length` (may be NULL)
/// receives the text's length without the NUL even when the buffer is too small. Fresh as for
/// [`ay_ctx_read_int`].
///
/// Ownership: nothing kept. Thread-safety: only inside the process `ctx` was given to.
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`, `AY_ERR_TYPE`, `AY_ERR_BUFFER`
/// (nothing copied), `AY_ERR_ABSENT`.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `buffer` is NULL or valid for `capacity`
/// bytes; `length` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_read_text(
    ctx: *mut ay_ctx,
    port: ay_port,
    buffer: *mut c_char,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_ctx_read_text", || {
        with_ctx(ctx, |c, regs| {
            let p = port_of(regs, port)?;
            // SAFETY: the C caller's promises on buffer/capacity/length.
            unsafe {
                copy_items(
                    &c.read(p),
                    |v| v.as_text().map(str::as_bytes),
                    "text",
                    true,
                    buffer.cast::<u8>(),
                    capacity,
                    length,
                )
            }?;
            freshness(c.fresh(p))
        })
    })
}

/// Read a vector port into `buffer` (`capacity` doubles); `*length` (may be NULL) receives
/// the vector's length even when the buffer is too small. Fresh as for [`ay_ctx_read_int`].
///
/// Errors, ownership, threads: as [`ay_ctx_read_text`].
///
/// # Safety
/// As [`ay_ctx_read_text`], with `buffer` valid for `capacity` doubles.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_read_vector(
    ctx: *mut ay_ctx,
    port: ay_port,
    buffer: *mut f64,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_ctx_read_vector", || {
        with_ctx(ctx, |c, regs| {
            let p = port_of(regs, port)?;
            // SAFETY: the C caller's promises on buffer/capacity/length.
            unsafe { copy_items(&c.read(p), Value::as_vector, "a vector", false, buffer, capacity, length) }?;
            freshness(c.fresh(p))
        })
    })
}

/// Read a bytes port into `buffer` (`capacity` bytes); `*length` (may be NULL) receives the
/// length even when the buffer is too small. Fresh as for [`ay_ctx_read_int`].
///
/// Errors, ownership, threads: as [`ay_ctx_read_text`].
///
/// # Safety
/// As [`ay_ctx_read_text`], with `buffer` valid for `capacity` bytes.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_read_bytes(
    ctx: *mut ay_ctx,
    port: ay_port,
    buffer: *mut u8,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_ctx_read_bytes", || {
        with_ctx(ctx, |c, regs| {
            let p = port_of(regs, port)?;
            // SAFETY: the C caller's promises on buffer/capacity/length.
            unsafe { copy_items(&c.read(p), Value::as_bytes, "bytes", false, buffer, capacity, length) }?;
            freshness(c.fresh(p))
        })
    })
}

/// Write a bytes port of the running behavior (`length` bytes, copied). As
/// [`ay_ctx_write_int`].
///
/// Ownership: copies the value; keeps nothing. Thread-safety: only inside the process `ctx`
/// was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `value` is NULL (length 0) or valid for
/// `length` reads.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_write_bytes(
    ctx: *mut ay_ctx,
    port: ay_port,
    value: *const u8,
    length: usize,
) -> ay_status {
    boundary("ay_ctx_write_bytes", || {
        write_port(ctx, port, || {
            // SAFETY: the C caller's promise on value/length.
            let v = unsafe { slice(value, length, "value") }?;
            Ok(Value::bytes(v))
        })
    })
}

/// Write a text port of the running behavior (the text is copied). As [`ay_ctx_write_int`];
/// also `AY_ERR_INVALID` for text that is not UTF-8.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `value` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_write_text(ctx: *mut ay_ctx, port: ay_port, value: *const c_char) -> ay_status {
    boundary("ay_ctx_write_text", || {
        write_port(ctx, port, || {
            // SAFETY: the C caller's promise on `value`.
            let v = unsafe { text(value, "value") }?;
            Ok(Value::text(v))
        })
    })
}

/// Write a vector port of the running behavior (`length` doubles, copied). As
/// [`ay_ctx_write_int`]; a length other than the port's shape is `AY_ERR_TYPE`.
///
/// Ownership: copies the value; keeps nothing. Thread-safety: only inside the process `ctx`
/// was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `value` is NULL (length 0) or valid for
/// `length` reads.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_write_vector(
    ctx: *mut ay_ctx,
    port: ay_port,
    value: *const f64,
    length: usize,
) -> ay_status {
    boundary("ay_ctx_write_vector", || {
        write_port(ctx, port, || {
            // SAFETY: the C caller's promise on value/length.
            let v = unsafe { slice(value, length, "value") }?;
            Ok(Value::vector(v))
        })
    })
}

/// Whether the running behavior's port holds a fresh value (rule S4) into `*out`.
///
/// Ownership: nothing kept. Thread-safety: only inside the process `ctx` was given to.
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_fresh(ctx: *mut ay_ctx, port: ay_port, out: *mut bool) -> ay_status {
    boundary("ay_ctx_fresh", || {
        with_ctx(ctx, |c, regs| {
            let p = port_of(regs, port)?;
            // SAFETY: the C caller's promise on `out`.
            unsafe { put(out, c.fresh(p), "out") }
        })
    })
}

/// Empty an aggregating port of the running behavior now (the paper's end of "the current
/// cycle"). Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`.
///
/// Ownership: keeps nothing. Thread-safety: only inside the process `ctx` was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_reset(ctx: *mut ay_ctx, port: ay_port) -> ay_status {
    boundary("ay_ctx_reset", || {
        with_ctx(ctx, |c, regs| {
            c.reset(port_of(regs, port)?);
            Ok(())
        })
    })
}

/// Trigger a monostable of the running behavior for `seconds`: it is high until
/// `max(its end, now + seconds)` (rule S2).
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`, `AY_ERR_PERIOD` (zero, negative,
/// NaN or infinite seconds).
///
/// Ownership: keeps nothing. Thread-safety: only inside the process `ctx` was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_trigger(ctx: *mut ay_ctx, mono: ay_mono, seconds: f64) -> ay_status {
    boundary("ay_ctx_trigger", || {
        with_ctx(ctx, |c, regs| {
            let m = mono_of(regs, mono)?;
            let d: Duration = required_secs(seconds, "the period")?;
            c.trigger(m, d);
            Ok(())
        })
    })
}

/// Whether a monostable of the running behavior is high now, into `*out`.
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_UNKNOWN`.
///
/// Ownership: keeps nothing. Thread-safety: only inside the process `ctx` was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_is_high(ctx: *mut ay_ctx, mono: ay_mono, out: *mut bool) -> ay_status {
    boundary("ay_ctx_is_high", || {
        with_ctx(ctx, |c, regs| {
            let m = mono_of(regs, mono)?;
            // SAFETY: the C caller's promise on `out`.
            unsafe { put(out, c.is_high(m), "out") }
        })
    })
}

/// The node's time of this activation (seconds on the node's clock) into `*out`.
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`.
///
/// Ownership: keeps nothing. Thread-safety: only inside the process `ctx` was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_now(ctx: *mut ay_ctx, out: *mut f64) -> ay_status {
    boundary("ay_ctx_now", || {
        // SAFETY: the C caller's promise on `out`.
        with_ctx(ctx, |c, _| unsafe { put(out, c.now().as_secs_f64(), "out") })
    })
}

/// This node's id into `*out`.
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`.
///
/// Ownership: keeps nothing. Thread-safety: only inside the process `ctx` was given to.
///
/// # Safety
/// `ctx` is NULL or a context passed to a process; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_node(ctx: *mut ay_ctx, out: *mut u32) -> ay_status {
    boundary("ay_ctx_node", || {
        // SAFETY: the C caller's promise on `out`.
        with_ctx(ctx, |c, _| unsafe { put(out, c.node().0, "out") })
    })
}

/// The running behavior's instance name (`OBS1`) into `buffer`, as [`ay_ctx_read_text`]
/// copies text.
///
/// Errors: `AY_ERR_NULL`, `AY_ERR_CONTEXT`, `AY_ERR_BUFFER`.
///
/// # Safety
/// As [`ay_ctx_read_text`].
#[no_mangle]
pub unsafe extern "C" fn ay_ctx_behavior(
    ctx: *mut ay_ctx,
    buffer: *mut c_char,
    capacity: usize,
    length: *mut usize,
) -> ay_status {
    boundary("ay_ctx_behavior", || {
        with_ctx(ctx, |c, _| {
            // SAFETY: the C caller's promises on buffer/capacity/length.
            unsafe { copy_out(c.behavior().as_bytes(), true, buffer.cast::<u8>(), capacity, length) }
        })
    })
}
