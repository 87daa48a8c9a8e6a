//! Behavior classes declared in Python, and the context their processes run with.
//!
//! Promise: a Python class's ports, slots and monostables become a Rust
//! [`ayllu_core::BehaviorClass`] declared in the same order; its processes are Rust process
//! bodies that call the Python method, so *when* they run, what their writes do and every rule
//! of docs/semantics.md stay the core's. A Python exception raised in a process is caught,
//! counted per process and kept with its traceback ([`Processes::errors`]); the first one of
//! each process is also printed to `sys.stderr`. It never unwinds into the node.
//!
//! A process sees its behavior through a [`Context`], valid only while the process runs: it
//! points at the core's `Ctx` for the duration of the call and is cleared right after.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicPtr, AtomicU32, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use ayllu_core::{
    Applied, BehaviorClass, Change, ConnectOptions, ConnectionId, Ctx, DropCause, Mono, NodeCore, Port, PortKind,
    PortSpec, Slot, Trigger,
};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::connection;
use crate::errors::{self, ValueTypeError};
use crate::value::{duration, secs, to_py, to_value};

const UNASSIGNED: u32 = u32::MAX;

/// A port declared as a class attribute: `speed = Port(0.0, kind="max", window=1.0)`.
#[pyclass(frozen, module = "ayllu._native")]
pub struct PortDecl {
    name: OnceLock<String>,
    default: Py<PyAny>,
    kind: PortKind,
    lifespan: Option<f64>,
    window: Option<f64>,
    index: AtomicU32,
}

/// A declaration's name: `name=` if given, else the attribute's, from `__set_name__`.
fn name_cell(name: Option<String>) -> OnceLock<String> {
    name.map_or_else(OnceLock::new, OnceLock::from)
}

/// `__set_name__`: the attribute's name, unless the declaration has one already.
fn set_name(cell: &OnceLock<String>, name: String) {
    if cell.get().is_none() {
        let _ = cell.set(name);
    }
}

/// A declaration's name in reprs and messages (`?` while it has none).
fn shown(cell: &OnceLock<String>) -> &str {
    cell.get().map_or("?", |s| s)
}

fn kind_from_name(kind: &str) -> PyResult<PortKind> {
    Ok(match kind {
        "normal" => PortKind::Normal,
        "max" => PortKind::Max,
        "min" => PortKind::Min,
        "sum" => PortKind::Sum,
        "priority" => PortKind::Priority,
        other => {
            return Err(errors::value_error(format!("port kind `{other}` is none of normal, max, min, sum, priority")))
        }
    })
}

#[pymethods]
impl PortDecl {
    #[new]
    #[pyo3(signature = (default, *, kind = "normal", lifespan = None, window = None, name = None))]
    fn new(
        default: Py<PyAny>,
        kind: &str,
        lifespan: Option<f64>,
        window: Option<f64>,
        name: Option<String>,
    ) -> PyResult<Self> {
        Ok(PortDecl {
            name: name_cell(name),
            default,
            kind: kind_from_name(kind)?,
            lifespan,
            window,
            index: AtomicU32::new(UNASSIGNED),
        })
    }
    fn __set_name__(&self, _owner: &Bound<'_, PyAny>, name: String) -> PyResult<()> {
        set_name(&self.name, name);
        Ok(())
    }
    /// The port's name on the node (the attribute's name unless `name=` was given).
    #[getter]
    fn name(&self) -> Option<String> {
        self.name.get().cloned()
    }
    /// The port's kind (`normal`, `max`, `min`, `sum`, `priority`).
    #[getter]
    fn kind(&self) -> &'static str {
        self.kind.name()
    }
    /// The port's default value (its type is the port's type).
    #[getter]
    fn default(&self, py: Python<'_>) -> Py<PyAny> {
        self.default.clone_ref(py)
    }
    /// The handle its processes use (assigned when the class is first defined on a node).
    #[getter]
    fn index(&self) -> Option<u32> {
        let i = self.index.load(Ordering::Relaxed);
        (i != UNASSIGNED).then_some(i)
    }
    fn __repr__(&self) -> String {
        format!("Port({}, kind={})", shown(&self.name), self.kind.name())
    }
}

/// A slot declared as a class attribute: `count = Slot(0)`.
#[pyclass(frozen, module = "ayllu._native")]
pub struct SlotDecl {
    name: OnceLock<String>,
    default: Py<PyAny>,
    index: AtomicU32,
}

#[pymethods]
impl SlotDecl {
    #[new]
    #[pyo3(signature = (default, *, name = None))]
    fn new(default: Py<PyAny>, name: Option<String>) -> Self {
        SlotDecl { name: name_cell(name), default, index: AtomicU32::new(UNASSIGNED) }
    }
    fn __set_name__(&self, _owner: &Bound<'_, PyAny>, name: String) -> PyResult<()> {
        set_name(&self.name, name);
        Ok(())
    }
    /// The slot's name.
    #[getter]
    fn name(&self) -> Option<String> {
        self.name.get().cloned()
    }
    fn __repr__(&self) -> String {
        format!("Slot({})", shown(&self.name))
    }
}

/// A monostable declared as a class attribute: `backing = Monostable()`.
#[pyclass(frozen, module = "ayllu._native")]
pub struct MonoDecl {
    name: OnceLock<String>,
    index: AtomicU32,
}

#[pymethods]
impl MonoDecl {
    #[new]
    #[pyo3(signature = (*, name = None))]
    fn new(name: Option<String>) -> Self {
        MonoDecl { name: name_cell(name), index: AtomicU32::new(UNASSIGNED) }
    }
    fn __set_name__(&self, _owner: &Bound<'_, PyAny>, name: String) -> PyResult<()> {
        set_name(&self.name, name);
        Ok(())
    }
    /// The monostable's name.
    #[getter]
    fn name(&self) -> Option<String> {
        self.name.get().cloned()
    }
    fn __repr__(&self) -> String {
        format!("Monostable({})", shown(&self.name))
    }
}

/// Give a declaration its handle. A declaration shared by classes (a base and its subclasses)
/// must have the same handle in each, since processes find registers by it.
fn claim(index: &AtomicU32, handle: u16, class: &str, name: &str) -> PyResult<()> {
    let old = index.swap(u32::from(handle), Ordering::Relaxed);
    if old != UNASSIGNED && old != u32::from(handle) {
        index.store(old, Ordering::Relaxed);
        return Err(errors::InvalidError::new_err(format!(
            "{class}.{name} is a declaration another class has at another position: declare a new one in each class"
        )));
    }
    Ok(())
}

/// The handle of `decl`, which a process of class `class` names (its trigger or its guard):
/// refused unless it is one of that class's ports (`ports`).
fn own_port(ports: &[Py<PyAny>], decl: &Bound<'_, PortDecl>, class: &str, process: &str) -> PyResult<Port> {
    if !ports.iter().any(|p| p.is(decl)) {
        return Err(errors::InvalidError::new_err(format!("process {class}.{process} names a port of another class")));
    }
    let d = decl.get();
    Ok(Port(assigned(&d.index, "port", &d.name)?))
}

fn assigned(index: &AtomicU32, what: &str, name: &OnceLock<String>) -> PyResult<u16> {
    let i = index.load(Ordering::Relaxed);
    if i == UNASSIGNED {
        return Err(errors::InvalidError::new_err(format!(
            "{what} `{}` belongs to no class defined on a node yet",
            shown(name)
        )));
    }
    Ok(i as u16)
}

/// One Python exception raised in a process.
#[derive(Clone)]
pub struct ProcessError {
    /// The behavior instance.
    pub behavior: String,
    /// The process.
    pub process: String,
    /// Node time (s) when it was raised.
    pub time: f64,
    /// The formatted traceback.
    pub traceback: String,
}

/// How many recent exceptions a node keeps (all are counted).
const KEPT_ERRORS: usize = 100;

#[derive(Default)]
struct ErrorLog {
    counts: HashMap<(String, String), u64>,
    recent: VecDeque<ProcessError>,
}

/// What a node's Python processes share: the Python object of each behavior instance, the
/// context object, the classes' factories and the exception log.
pub struct Processes {
    instances: Mutex<HashMap<String, Py<PyAny>>>,
    factories: Mutex<HashMap<String, Py<PyAny>>>,
    context: Py<Context>,
    log: Mutex<ErrorLog>,
}

impl Processes {
    /// An empty set for a new node.
    pub fn new(py: Python<'_>) -> PyResult<Arc<Processes>> {
        Ok(Arc::new(Processes {
            instances: Mutex::default(),
            factories: Mutex::default(),
            context: Py::new(py, Context { ptr: AtomicPtr::new(std::ptr::null_mut()) })?,
            log: Mutex::default(),
        }))
    }

    /// Every exception kept (the last 100), oldest first.
    pub fn errors(&self) -> Vec<ProcessError> {
        self.log.lock().map(|l| l.recent.iter().cloned().collect()).unwrap_or_default()
    }

    /// Exceptions per `(behavior, process)`, all of them.
    pub fn error_counts(&self) -> Vec<((String, String), u64)> {
        let mut v: Vec<_> =
            self.log.lock().map(|l| l.counts.iter().map(|(k, n)| (k.clone(), *n)).collect()).unwrap_or_default();
        v.sort();
        v
    }

    fn record(&self, py: Python<'_>, behavior: &str, process: &str, time: f64, err: PyErr) {
        let traceback = format_traceback(py, &err);
        let first = {
            let Ok(mut log) = self.log.lock() else { return };
            let n = log.counts.entry((behavior.to_owned(), process.to_owned())).or_insert(0);
            *n += 1;
            let first = *n == 1;
            if log.recent.len() == KEPT_ERRORS {
                log.recent.pop_front();
            }
            log.recent.push_back(ProcessError {
                behavior: behavior.to_owned(),
                process: process.to_owned(),
                time,
                traceback: traceback.clone(),
            });
            first
        };
        if first {
            let msg = format!(
                "ayllu: process {behavior}.{process} raised at t={time:.3} s (counted; the node goes on; \
                 later ones are only counted, see Node.process_errors()):\n{traceback}"
            );
            if let Ok(stderr) = py.import("sys").and_then(|s| s.getattr("stderr")) {
                let _ = stderr.call_method1("write", (msg,));
            }
        }
    }

    /// Make the Python object for behavior `name` of a Python class (None for a Rust class).
    pub fn instantiate(&self, py: Python<'_>, class: &str, name: &str) -> PyResult<Option<Py<PyAny>>> {
        let factory = self.factories.lock().ok().and_then(|f| f.get(class).map(|o| o.clone_ref(py)));
        let Some(factory) = factory else { return Ok(None) };
        let obj = factory.call0(py)?;
        if let Ok(mut m) = self.instances.lock() {
            m.insert(name.to_owned(), obj.clone_ref(py));
        }
        Ok(Some(obj))
    }

    /// Forget the Python object of a removed behavior.
    pub fn forget(&self, name: &str) {
        if let Ok(mut m) = self.instances.lock() {
            m.remove(name);
        }
    }

    /// The Python object of behavior `name`, if it is of a Python class.
    pub fn instance(&self, py: Python<'_>, name: &str) -> Option<Py<PyAny>> {
        self.instances.lock().ok().and_then(|m| m.get(name).map(|o| o.clone_ref(py)))
    }
}

fn format_traceback(py: Python<'_>, err: &PyErr) -> String {
    let formatted = py.import("traceback").and_then(|tb| {
        let lines = tb.call_method1("format_exception", (err.get_type(py), err.value(py), err.traceback(py)))?;
        let s: String = pyo3::types::PyString::new(py, "").call_method1("join", (lines,))?.extract()?;
        Ok::<_, PyErr>(s)
    });
    formatted.unwrap_or_else(|_| err.to_string())
}

/// The declaration a subclass of `ayllu.Behavior` carries (`__ayllu__`, made by its
/// `__init_subclass__`).
pub struct Declaration<'py> {
    /// The Ayllu class name.
    pub name: String,
    ports: Bound<'py, PyAny>,
    slots: Bound<'py, PyAny>,
    monos: Bound<'py, PyAny>,
    processes: Bound<'py, PyAny>,
}

impl<'py> Declaration<'py> {
    /// The declaration of `cls`; `TypeError` if it is no `ayllu.Behavior` subclass.
    pub fn of(cls: &Bound<'py, PyAny>) -> PyResult<Declaration<'py>> {
        let decl = cls
            .getattr("__ayllu__")
            .map_err(|_| errors::type_error(format!("{cls} is not a subclass of ayllu.Behavior")))?;
        let t = decl.cast::<PyTuple>().map_err(|_| errors::type_error(format!("{cls} has a damaged __ayllu__")))?;
        Ok(Declaration {
            name: t.get_item(0)?.extract()?,
            ports: t.get_item(1)?,
            slots: t.get_item(2)?,
            monos: t.get_item(3)?,
            processes: t.get_item(4)?,
        })
    }
}

/// Build the class `cls` declares and define it on `core`. Its processes are
/// `(name, trigger, arg, function)`: trigger `"every"` with a period in seconds, `"on_write"`
/// with a port declaration, `"on_monostable"` with a monostable one.
pub fn define(py: Python<'_>, core: &mut NodeCore, procs: &Arc<Processes>, cls: &Bound<'_, PyAny>) -> PyResult<()> {
    let d = Declaration::of(cls)?;
    let (name, ports, slots, monos, processes) = (d.name.as_str(), &d.ports, &d.slots, &d.monos, &d.processes);
    let factory = cls.clone().unbind();
    let mut class = BehaviorClass::new(name);
    let mut port_decls = Vec::new();
    for p in ports.try_iter()? {
        let p = p?;
        let decl = p.cast::<PortDecl>()?.get();
        let pname = decl.name.get().cloned().ok_or_else(|| errors::InvalidError::new_err("a port without a name"))?;
        let mut spec = PortSpec::new(&pname, to_value(decl.default.bind(py))?).kind(decl.kind);
        if let Some(l) = decl.lifespan {
            spec = spec.lifespan(duration("lifespan", l)?);
        }
        if let Some(w) = decl.window {
            spec = spec.window(duration("window", w)?);
        }
        let h = class.port(spec).map_err(errors::core)?;
        claim(&decl.index, h.0, name, &pname)?;
        port_decls.push(p.unbind());
    }
    for s in slots.try_iter()? {
        let s = s?;
        let decl = s.cast::<SlotDecl>()?.get();
        let sname = decl.name.get().cloned().ok_or_else(|| errors::InvalidError::new_err("a slot without a name"))?;
        let h = class.slot(&sname, to_value(decl.default.bind(py))?).map_err(errors::core)?;
        claim(&decl.index, h.0, name, &sname)?;
    }
    for m in monos.try_iter()? {
        let m = m?;
        let decl = m.cast::<MonoDecl>()?.get();
        let mname =
            decl.name.get().cloned().ok_or_else(|| errors::InvalidError::new_err("a monostable without a name"))?;
        let h = class.monostable(&mname).map_err(errors::core)?;
        claim(&decl.index, h.0, name, &mname)?;
    }
    for item in processes.try_iter()? {
        let item = item?;
        let t = item.cast::<PyTuple>()?;
        let pname: String = t.get_item(0)?.extract()?;
        let trigger: String = t.get_item(1)?.extract()?;
        let arg = t.get_item(2)?;
        let func: Py<PyAny> = t.get_item(3)?.unbind();
        let trig = match trigger.as_str() {
            "every" => Trigger::Periodic(duration("period", arg.extract()?)?),
            "every_while_fresh" => {
                let pair = arg.cast::<PyTuple>()?;
                let period = duration("period", pair.get_item(0)?.extract()?)?;
                let guard = pair.get_item(1)?;
                Trigger::PeriodicWhileFresh(period, own_port(&port_decls, guard.cast::<PortDecl>()?, name, &pname)?)
            }
            "on_write" => Trigger::OnWrite(own_port(&port_decls, arg.cast::<PortDecl>()?, name, &pname)?),
            "on_monostable" => {
                let d = arg.cast::<MonoDecl>()?.get();
                Trigger::OnMonostable(Mono(assigned(&d.index, "monostable", &d.name)?))
            }
            other => return Err(errors::value_error(format!("unknown trigger `{other}`"))),
        };
        let shared = Arc::clone(procs);
        let proc_name = pname.clone();
        let body = move |ctx: &mut Ctx<'_>| {
            Python::attach(|py| run_process(py, &shared, &proc_name, &func, ctx));
        };
        class.process(&pname, trig, body).map_err(errors::core)?;
    }
    core.define(class).map_err(errors::core)?;
    if let Ok(mut f) = procs.factories.lock() {
        f.insert(name.to_owned(), factory);
    }
    Ok(())
}

fn run_process(py: Python<'_>, shared: &Processes, process: &str, func: &Py<PyAny>, ctx: &mut Ctx<'_>) {
    // A behavior a process created (R1) has no Python object yet: made at its first run.
    let inst = match shared.instance(py, ctx.behavior()) {
        Some(inst) => inst,
        None => match shared.instantiate(py, ctx.class_name(), ctx.behavior()) {
            Ok(Some(inst)) => inst,
            _ => return,
        },
    };
    let c = shared.context.get();
    let ptr: *mut Ctx<'_> = ctx;
    c.ptr.store(ptr.cast(), Ordering::Release);
    let result = func.call1(py, (inst, shared.context.clone_ref(py)));
    c.ptr.store(std::ptr::null_mut(), Ordering::Release);
    if let Err(e) = result {
        let (b, t) = (ctx.behavior().to_owned(), secs(ctx.now()));
        shared.record(py, &b, process, t, e);
    }
}

/// What a running process can see and do (rule S7): its behavior's ports, slots and
/// monostables by their declarations, and the node's time. Valid only during the call.
#[pyclass(frozen, module = "ayllu._native")]
pub struct Context {
    ptr: AtomicPtr<()>,
}

fn port_of(obj: &Bound<'_, PyAny>) -> PyResult<Port> {
    if let Ok(d) = obj.cast::<PortDecl>() {
        let d = d.get();
        return Ok(Port(assigned(&d.index, "port", &d.name)?));
    }
    if let Ok(i) = obj.extract::<u16>() {
        // A raw handle: the implicit BLE ports are 0, 1, 2 (`Behavior.LOCAL`, ...).
        return Ok(Port(i));
    }
    Err(errors::type_error(format!("expected a Port declared on the behavior's class, got {obj}")))
}

fn slot_of(obj: &Bound<'_, PyAny>) -> PyResult<Slot> {
    let d = obj.cast::<SlotDecl>().map_err(|_| errors::type_error(format!("expected a Slot, got {obj}")))?.get();
    Ok(Slot(assigned(&d.index, "slot", &d.name)?))
}

fn mono_of(obj: &Bound<'_, PyAny>) -> PyResult<Mono> {
    let d = obj.cast::<MonoDecl>().map_err(|_| errors::type_error(format!("expected a Monostable, got {obj}")))?.get();
    Ok(Mono(assigned(&d.index, "monostable", &d.name)?))
}

fn refused(port: &Bound<'_, PyAny>, cause: DropCause) -> PyErr {
    let name = port.getattr("name").map(|n| n.to_string()).unwrap_or_default();
    match cause {
        DropCause::TypeMismatch => {
            ValueTypeError::new_err(format!("port {name} refused the value: it is of another type (rule S1)"))
        }
        other => errors::InvalidError::new_err(format!("port {name} refused the value ({})", other.name())),
    }
}

impl Context {
    /// Run `f` on the live `Ctx`, or raise if the process has returned.
    fn with<R>(&self, f: impl FnOnce(&mut Ctx<'_>) -> R) -> PyResult<R> {
        let p = self.ptr.load(Ordering::Acquire);
        if p.is_null() {
            return Err(PyRuntimeError::new_err(
                "this ctx belongs to a process that has returned: use a ctx only inside the process it was given to",
            ));
        }
        // SAFETY: `ptr` is set by `run_process` to the `&mut Ctx` it was handed, only for the
        // duration of the Python call, and cleared before that borrow ends; the caller holds
        // the GIL for the whole of this method (nothing here releases it), and `run_process`
        // holds it too while the pointer is set, so no two `&mut` made from it ever coexist and
        // the original borrow is not used while this one lives.
        let ctx = unsafe { &mut *p.cast::<Ctx<'static>>() };
        Ok(f(ctx))
    }
}

#[pymethods]
impl Context {
    /// The node's time (s): the `now` of the poll running this process.
    #[getter]
    fn now(&self) -> PyResult<f64> {
        self.with(|c| secs(c.now()))
    }
    /// This node's id.
    #[getter]
    fn node(&self) -> PyResult<u32> {
        self.with(|c| c.node().0)
    }
    /// The running behavior's instance name.
    #[getter]
    fn behavior(&self) -> PyResult<String> {
        self.with(|c| c.behavior().to_owned())
    }
    /// The port's value; its default while empty (ignores freshness: see `get`).
    fn read(&self, py: Python<'_>, port: &Bound<'_, PyAny>) -> PyResult<Py<PyAny>> {
        let p = port_of(port)?;
        self.with(|c| to_py(py, &c.read(p)))
    }
    /// The port's value if fresh (rule S4), else None.
    fn get(&self, py: Python<'_>, port: &Bound<'_, PyAny>) -> PyResult<Option<Py<PyAny>>> {
        let p = port_of(port)?;
        self.with(|c| c.get(p).map(|v| to_py(py, &v)))
    }
    /// Whether the port holds a fresh value.
    fn fresh(&self, port: &Bound<'_, PyAny>) -> PyResult<bool> {
        let p = port_of(port)?;
        self.with(|c| c.fresh(p))
    }
    /// Who supplied the port's value: `(node, connection)` (connection 0: a process), or None.
    fn supplier(&self, port: &Bound<'_, PyAny>) -> PyResult<Option<(u32, u64)>> {
        let p = port_of(port)?;
        self.with(|c| c.supplier(p).map(|s| (s.node.0, s.conn)))
    }
    /// When the port last accepted a value (node time, s), or None.
    fn last_accepted(&self, port: &Bound<'_, PyAny>) -> PyResult<Option<f64>> {
        let p = port_of(port)?;
        self.with(|c| c.last_accepted(p).map(secs))
    }
    /// Write the behavior's own port (rule S6). Raises `ValueTypeError` for a value of another
    /// type, `InvalidError` for one the port refuses (NaN into Max/Min/Sum, a vector of another
    /// length into a Sum).
    fn write(&self, port: &Bound<'_, PyAny>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let p = port_of(port)?;
        let v = to_value(value)?;
        self.with(|c| c.write(p, v))?.map_err(|cause| refused(port, cause))
    }
    /// Empty an aggregating port now.
    fn reset(&self, port: &Bound<'_, PyAny>) -> PyResult<()> {
        let p = port_of(port)?;
        self.with(|c| c.reset(p))
    }
    /// The slot's value.
    fn slot(&self, py: Python<'_>, slot: &Bound<'_, PyAny>) -> PyResult<Py<PyAny>> {
        let s = slot_of(slot)?;
        self.with(|c| to_py(py, &c.slot(s)))
    }
    /// Set a slot (same type as its default, rule S1).
    fn set_slot(&self, slot: &Bound<'_, PyAny>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let s = slot_of(slot)?;
        let v = to_value(value)?;
        self.with(|c| c.set_slot(s, v))?.map_err(errors::core)
    }
    /// Make the monostable true until at least now + `seconds` (rule S2).
    fn trigger(&self, mono: &Bound<'_, PyAny>, seconds: f64) -> PyResult<()> {
        let m = mono_of(mono)?;
        let d = duration("seconds", seconds)?;
        self.with(|c| c.trigger(m, d))
    }
    /// Whether the monostable is true now.
    fn is_high(&self, mono: &Bound<'_, PyAny>) -> PyResult<bool> {
        let m = mono_of(mono)?;
        self.with(|c| c.is_high(m))
    }

    // ----- structure (docs/semantics.md R1-R7) ---------------------------------------------

    /// Ask to create behavior `name` of class `class_name` when the process returns (R1).
    /// Returns its position among this activation's changes: the next activation finds its
    /// outcome there in `changes()`. Raises at once only for what is wrong whatever the node
    /// holds (an empty name: R2).
    fn create(&self, class_name: &str, name: &str) -> PyResult<usize> {
        self.ask(Change::Create { class: class_name.to_owned(), name: name.to_owned() })
    }
    /// Ask to remove behavior `name` (possibly this one: R3) when the process returns.
    fn remove(&self, name: &str) -> PyResult<usize> {
        self.ask(Change::Remove { name: name.to_owned() })
    }
    /// Ask to connect `source` (a port of this node) to `destination` when the process
    /// returns; endpoints and kinds as `Node.connect`.
    #[pyo3(signature = (source, destination, kind = None, *, priority = 0))]
    fn connect(
        &self,
        source: &Bound<'_, PyAny>,
        destination: &Bound<'_, PyAny>,
        kind: Option<&Bound<'_, PyAny>>,
        priority: i32,
    ) -> PyResult<usize> {
        let (s, d, k) = connection::connect_args(source, destination, kind)?;
        self.ask(Change::Connect {
            source: connection::endpoint(&s)?,
            destination: connection::endpoint(&d)?,
            kind: k,
            priority,
        })
    }
    /// Ask to remove connection `id` of this node when the process returns.
    fn disconnect(&self, id: u64) -> PyResult<usize> {
        self.ask(Change::Disconnect { conn: ConnectionId(id) })
    }
    /// Ask to remove every connection from `source` to `destination` when the process returns.
    fn disconnect_between(&self, source: &Bound<'_, PyAny>, destination: &Bound<'_, PyAny>) -> PyResult<usize> {
        let (s, d) = (connection::endpoint_arg(source)?, connection::endpoint_arg(destination)?);
        self.ask(Change::DisconnectBetween {
            source: connection::endpoint(&s)?,
            destination: connection::endpoint(&d)?,
        })
    }
    /// Ask to join broadcast group `group` when the process returns.
    fn join(&self, group: &str) -> PyResult<usize> {
        self.ask(Change::Join { group: group.to_owned() })
    }
    /// Ask to leave broadcast group `group` when the process returns.
    fn leave(&self, group: &str) -> PyResult<usize> {
        self.ask(Change::Leave { group: group.to_owned() })
    }
    /// What became of the changes this process's previous activation asked for, in order:
    /// `(change, error, connection)` — `error` None if applied (else the node's reason),
    /// `connection` the id of a connection made or removed (else None).
    fn changes(&self) -> PyResult<Vec<ChangeOutcomeTuple>> {
        self.with(|c| {
            c.changes()
                .iter()
                .map(|o| {
                    let (error, conn) = match &o.result {
                        Ok(Applied::Connection(id)) => (None, Some(id.0)),
                        Ok(_) => (None, None),
                        Err(e) => (Some(e.to_string()), None),
                    };
                    (o.change.describe(), error, conn)
                })
                .collect()
        })
    }
    /// Ask `source`'s node (`ayllu.remote(node, b, p)`) to connect that port to `destination`,
    /// at once (R6). Returns the request's id (`Node.request_status` follows it).
    #[pyo3(signature = (source, destination, kind = None, *, priority = 0))]
    fn request_connect(
        &self,
        source: &Bound<'_, PyAny>,
        destination: &Bound<'_, PyAny>,
        kind: Option<&Bound<'_, PyAny>>,
        priority: i32,
    ) -> PyResult<u64> {
        let (s, d, k) = connection::connect_args(source, destination, kind)?;
        let (s, d) = (connection::endpoint(&s)?, connection::endpoint(&d)?);
        self.with(|c| c.request_connect(&s, &d, k, ConnectOptions { priority }))?.map(|r| r.0).map_err(errors::core)
    }
}

/// One outcome as Python sees it: `(change, error, connection)`.
type ChangeOutcomeTuple = (String, Option<String>, Option<u64>);

impl Context {
    fn ask(&self, change: Change) -> PyResult<usize> {
        self.with(|c| c.change(change))?.map_err(errors::core)
    }
}
