//! Nodes from C: open one on a `udp://` or `mem://` URL with the real clock or a manual one,
//! define classes, create and remove behaviors, write and read ports from outside, step and
//! run the loop, join groups and BLE. A node is driven by one thread at a time; a process may
//! not call node functions on its own node (it gets `AY_ERR_BUSY`: it has its context).

use std::cell::{Cell, UnsafeCell};
use std::ffi::{c_char, c_void};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use ayllu::{BleConfig, Node, NodeId, PortRef, Value};

use crate::class::{self, ay_class, optional_secs, required_secs};
use crate::clock::with_clock;
use crate::cstr::{copy_out, put, text};
use crate::process::{copy_items, deliver, freshness, scalar, slice, Scalar};
use crate::registry::{self, Kind};
use crate::status::{ay_status, boundary, Fail};

/// A running node (opaque): the runtime's `Node` with its clock and transport.
#[allow(non_camel_case_types)]
pub struct ay_node {
    state: UnsafeCell<NodeState>,
    busy: Cell<bool>,
}

/// What a node handle owns.
pub(crate) struct NodeState {
    pub(crate) node: Node,
    /// Port handles given out by `ay_node_port`, by index.
    refs: Vec<PortRef>,
}

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

/// A signature for class builders (`ay_node_define_with`): declare the class's ports, slots,
/// monostables and processes on `class`.
#[allow(non_camel_case_types)]
pub type ay_class_fn = Option<unsafe extern "C" fn(cls: *mut ay_class, user: *mut c_void)>;

struct Unbusy<'a>(&'a Cell<bool>);

impl Drop for Unbusy<'_> {
    fn drop(&mut self) {
        self.0.set(false);
    }
}

/// Run `f` on a live node that no other call is using.
pub(crate) fn with_node<T>(p: *mut ay_node, f: impl FnOnce(&mut NodeState) -> Result<T, Fail>) -> Result<T, Fail> {
    registry::check(p, Kind::Node, "node")?;
    // SAFETY: registered node pointers come from Box::into_raw in `open` and are unregistered
    // before they are freed, so `p` points to a live ay_node. Only a shared reference is made
    // here: the mutable parts are behind Cell and UnsafeCell.
    let h = unsafe { &*p };
    if h.busy.get() {
        return Err(Fail::new(
            ay_status::AY_ERR_BUSY,
            "the node is running its processes (a process reaches its own node through its context), \
             or another call on it has not returned",
        ));
    }
    h.busy.set(true);
    let _unbusy = Unbusy(&h.busy);
    // SAFETY: `busy` was false and is now true until `_unbusy` drops, so no other reference
    // to the state exists (a node is driven by one thread at a time, as documented, and
    // re-entrant calls are refused above).
    f(unsafe { &mut *h.state.get() })
}

static DEFAULT: AtomicUsize = AtomicUsize::new(0);
static STOP: AtomicBool = AtomicBool::new(false);

fn open(node: Node, out: *mut *mut ay_node) -> Result<(), Fail> {
    let p = Box::into_raw(Box::new(ay_node {
        state: UnsafeCell::new(NodeState { node, refs: Vec::new() }),
        busy: Cell::new(false),
    }));
    registry::add(p, Kind::Node);
    // SAFETY: `out` was checked non-null by the callers and is valid for a write (the C
    // caller's promise).
    unsafe { out.write(p) };
    Ok(())
}

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

/// Define class `cls` on the node (rule S2), consuming it whether or not this succeeds.
///
/// Ownership: takes `cls` (the handle is invalid afterwards). Thread-safety: the node's
/// thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE` (node or class), `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (a class of that name is already defined here).
///
/// # Safety
/// `node` and `cls` are NULL or pointers from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_node_define(node: *mut ay_node, cls: *mut ay_class) -> ay_status {
    boundary("ay_node_define", || {
        registry::check(node, Kind::Node, "node")?;
        registry::remove(cls, Kind::Class, "class")?;
        // SAFETY: came from Box::into_raw in ay_class_new and was just unregistered.
        let class = unsafe { Box::from_raw(cls) };
        with_node(node, |s| Ok(s.node.define(class.finish())?))
    })
}

fn define_with(s: &mut NodeState, name: &str, build: ay_class_fn, user: *mut c_void) -> Result<(), Fail> {
    let Some(build) = build else { return Err(Fail::null("builder")) };
    let mut class = ay_class::new(name);
    class::lend(&mut class);
    // SAFETY: `build` is a C function of this signature; the class is registered for the
    // call, so the builder's ay_class_* calls on it are checked like any other.
    unsafe { build(&mut class, user) };
    class::unlend(&mut class);
    Ok(s.node.define(class.finish())?)
}

/// Define class `name` on the node by calling `build(class, user)` to declare its interface
/// and processes (what `ayDefBehaviorClass` generates). Errors from inside `build` are its
/// own calls' to handle; the class is defined with whatever they declared.
///
/// Ownership: `user` is passed to `build` and stored by the processes it declares with it.
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL` (name, build), `AY_ERR_HANDLE`,
/// `AY_ERR_BUSY`, `AY_ERR_INVALID` (empty name, class already defined here).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `name` is NULL or NUL-terminated; `build`
/// is NULL or a function of this signature.
#[no_mangle]
pub unsafe extern "C" fn ay_node_define_with(
    node: *mut ay_node,
    name: *const c_char,
    build: ay_class_fn,
    user: *mut c_void,
) -> ay_status {
    boundary("ay_node_define_with", || {
        // SAFETY: the C caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        if name.is_empty() {
            return Err(Fail::invalid("a class needs a name"));
        }
        with_node(node, |s| define_with(s, name, build, user))
    })
}

/// Create behavior `name` of class `class` (the paper's `ayInitBehavior`), first defining
/// the class with `build(class, user)` if the node does not have it yet (`build` may be NULL
/// when the class is known to be defined).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (class not defined and no builder), `AY_ERR_INVALID` (empty or taken
/// behavior name).
///
/// # Safety
/// As [`ay_node_define_with`]; `behavior` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_init_behavior(
    node: *mut ay_node,
    class_name: *const c_char,
    build: ay_class_fn,
    user: *mut c_void,
    behavior: *const c_char,
) -> ay_status {
    boundary("ay_node_init_behavior", || {
        // SAFETY: the C caller's promises on `class` and `behavior`.
        let (class, behavior) = unsafe { (text(class_name, "class")?, text(behavior, "behavior")?) };
        with_node(node, |s| {
            if !s.node.core().has_class(class) && build.is_some() {
                define_with(s, class, build, user)?;
            }
            s.node.create(class, behavior)?;
            Ok(())
        })
    })
}

/// Create behavior `behavior` of a defined class `class` (rule S9: also while running).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (no such class), `AY_ERR_INVALID` (empty or taken name).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the names are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_create(
    node: *mut ay_node,
    class_name: *const c_char,
    behavior: *const c_char,
) -> ay_status {
    boundary("ay_node_create", || {
        // SAFETY: the C caller's promises on the names.
        let (class, behavior) = unsafe { (text(class_name, "class")?, text(behavior, "behavior")?) };
        with_node(node, |s| Ok(s.node.create(class, behavior).map(|_| ())?))
    })
}

/// Remove behavior `behavior` and every connection into or out of it (rule S9).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `behavior` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_remove(node: *mut ay_node, behavior: *const c_char) -> ay_status {
    boundary("ay_node_remove", || {
        // SAFETY: the C caller's promise on `behavior`.
        let behavior = unsafe { text(behavior, "behavior") }?;
        with_node(node, |s| Ok(s.node.remove(behavior)?))
    })
}

/// (behavior, port) names from C, with the paper's BLE names mapped.
///
/// # Safety
/// Both are NULL or NUL-terminated strings that outlive `'a`.
pub(crate) unsafe fn names<'a>(behavior: *const c_char, port: *const c_char) -> Result<(&'a str, &'a str), Fail> {
    // SAFETY: forwarded promise.
    let (b, p) = unsafe { (text(behavior, "behavior")?, text(port, "port")?) };
    Ok((b, class::register_name(p)))
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
        let mut config = BleConfig::new(g, class::register_name(o), claim_hz)?;
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
