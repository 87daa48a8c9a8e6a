//! Nodes from Python: [`Node`] (one node of the runtime, on the real clock or a manual one),
//! [`Team`] (several nodes on one manual clock and an in-process network, stepped in order,
//! like `ayllu::Lockstep`) and [`PortHandle`] (a port resolved once, for fast writes).
//!
//! Promises:
//! * Manual clock: nothing moves unless Python calls `step`/`advance`; the same calls give
//!   the same run.
//! * Real clock: `start()` runs the node on a background thread that sleeps on the transport
//!   between deadlines *without the GIL*; it takes the GIL only to run Python processes.
//!   Python calls from other threads wait for the node (with the GIL released) and so never
//!   deadlock with it. The thread sleeps on the transport holding the node (its wait needs
//!   it), until the next deadline but at most [`IDLE_SLICE`]; once another thread has asked
//!   for the node, at most [`BUSY_SLICE`] for a while ([`BUSY_SPELL`]): an idle node wakes
//!   rarely, a node Python talks to answers within a millisecond.
//! * A node called from inside one of its own processes raises `NodeBusyError` (use `ctx`).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::thread::JoinHandle;

use ayllu::{ManualClock, MemNetwork};
use ayllu_core::{Access, Allow, ConnectionId, ControlBody, Instant, NodeId, PortRef};
use pyo3::prelude::*;
use pyo3::sync::MutexExt;
use pyo3::types::{PyDict, PyList};

use crate::behavior::Processes;
use crate::connection;
use crate::errors::{self, NodeBusyError};
use crate::stdlib::StdlibOptions;
use crate::value::{duration, instant, secs, to_py, to_value};
use crate::wiring;

/// The longest a real-clock node's thread sleeps on its transport while nobody else asks for
/// the node (it holds the node while it sleeps: the transport's wait needs it).
pub const IDLE_SLICE: std::time::Duration = std::time::Duration::from_millis(50);
/// The longest it sleeps at a time while other threads are asking for the node.
pub const BUSY_SLICE: std::time::Duration = std::time::Duration::from_millis(1);
/// How long after another thread last waited for the node the short slice is kept.
pub const BUSY_SPELL: std::time::Duration = std::time::Duration::from_millis(500);

/// Milliseconds since the first call: a cheap shared clock for `Shared::wanted_at`.
fn millis() -> u64 {
    static ORIGIN: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    ORIGIN.get_or_init(std::time::Instant::now).elapsed().as_millis() as u64
}

thread_local! {
    static TOKEN: u8 = const { 0 };
}

/// A number unique to the calling thread while it lives.
fn thread_token() -> usize {
    TOKEN.with(|t| t as *const u8 as usize)
}

/// The node and who is stepping it.
struct Shared {
    node: Mutex<Option<ayllu::Node>>,
    /// The thread stepping the node (running its processes), 0 when none.
    stepping: AtomicUsize,
    /// When (see [`millis`]) another thread last had to wait for the node; `u64::MAX`: never.
    wanted_at: std::sync::atomic::AtomicU64,
    procs: Arc<Processes>,
}

impl Shared {
    /// Lock the node: at once if free; from a process of this node, `NodeBusyError`; else wait
    /// for it with the GIL released (the thread holding it may need the GIL to finish).
    fn lock<'a>(&'a self, py: Python<'_>) -> PyResult<MutexGuard<'a, Option<ayllu::Node>>> {
        match self.node.try_lock() {
            Ok(g) => Ok(g),
            Err(TryLockError::Poisoned(p)) => Ok(p.into_inner()),
            Err(TryLockError::WouldBlock) => {
                if self.stepping.load(Ordering::Acquire) == thread_token() {
                    return Err(NodeBusyError::new_err(
                        "the node is running one of its processes: inside a process, use its ctx (ctx.write, ctx.read)",
                    ));
                }
                self.wanted_at.store(millis(), Ordering::Release);
                Ok(self.node.lock_py_attached(py).unwrap_or_else(|p| p.into_inner()))
            }
        }
    }

    fn with<R>(&self, py: Python<'_>, f: impl FnOnce(&mut ayllu::Node) -> PyResult<R>) -> PyResult<R> {
        let mut g = self.lock(py)?;
        match g.as_mut() {
            Some(n) => f(n),
            None => Err(errors::closed("this node")),
        }
    }

    /// How long the node may sleep on its transport now, holding it (see the module docs).
    fn slice(&self) -> std::time::Duration {
        let at = self.wanted_at.load(Ordering::Acquire);
        if at != u64::MAX && millis().saturating_sub(at) < BUSY_SPELL.as_millis() as u64 {
            BUSY_SLICE
        } else {
            IDLE_SLICE
        }
    }

    /// Sleep on the node's transport until `next` (node time), for at most `limit` and one
    /// slice.
    fn wait(&self, node: &mut ayllu::Node, next: Option<Instant>, limit: std::time::Duration) {
        let now = node.now();
        let until =
            next.map_or(limit, |t| std::time::Duration::from_nanos(t.as_nanos().saturating_sub(now.as_nanos())));
        let wait = until.min(limit).min(self.slice());
        if !wait.is_zero() {
            node.wait(wait);
        }
    }

    /// One step of the node, marking this thread as the one running its processes.
    fn step(node: &mut ayllu::Node, stepping: &AtomicUsize) -> Option<Instant> {
        stepping.store(thread_token(), Ordering::Release);
        let next = node.step();
        stepping.store(0, Ordering::Release);
        next
    }
}

/// An Ayllu node (see the module docs). Python's `ayllu.Node` adds the friendly signatures.
#[pyclass(frozen, module = "ayllu._native")]
pub struct Node {
    id: u32,
    shared: Arc<Shared>,
    /// The manual clock, or None on the real clock.
    clock: Option<ManualClock>,
    thread: Arc<Runner>,
}

/// A node's background thread and its stop flag (shared with [`RUNNERS`]).
#[derive(Default)]
struct Runner {
    handle: Mutex<Option<JoinHandle<()>>>,
    stop: AtomicBool,
}

impl Runner {
    /// Ask the thread to stop and wait for it, with the GIL released.
    fn stop(&self, py: Python<'_>) {
        self.stop.store(true, Ordering::Release);
        let handle = self.handle.lock().ok().and_then(|mut t| t.take());
        if let Some(h) = handle {
            py.detach(|| {
                let _ = h.join();
            });
        }
    }
}

/// Every started node's runner, so that [`stop_all`] can stop them before the interpreter
/// shuts down (a thread must not run Python code then).
static RUNNERS: Mutex<Vec<std::sync::Weak<Runner>>> = Mutex::new(Vec::new());

/// The `udp://` URL every Ayllu program uses when told nothing else: `AYLLU_URL` from the
/// environment, else the machine-local default (multicast discovery with TTL 0; docs/cli.md).
/// `Node(id, ayllu.default_url())` is how a robot's program joins the team its machine is
/// configured for.
#[pyfunction]
pub fn default_url() -> String {
    ayllu::default_url()
}

/// Stop every running node's background thread (called by `atexit`, see `ayllu/__init__.py`).
#[pyfunction]
pub fn stop_all(py: Python<'_>) {
    let runners: Vec<Arc<Runner>> = RUNNERS
        .lock()
        .map(|mut r| {
            r.retain(|w| w.strong_count() > 0);
            r.iter().filter_map(std::sync::Weak::upgrade).collect()
        })
        .unwrap_or_default();
    for r in runners {
        r.stop(py);
    }
}

impl Node {
    fn build(py: Python<'_>, id: u32, node: ayllu::Node, clock: Option<ManualClock>) -> PyResult<Node> {
        Ok(Node {
            id,
            shared: Arc::new(Shared {
                node: Mutex::new(Some(node)),
                stepping: AtomicUsize::new(0),
                wanted_at: std::sync::atomic::AtomicU64::new(u64::MAX),
                procs: Processes::new(py)?,
            }),
            clock,
            thread: Arc::new(Runner::default()),
        })
    }

    fn manual(&self) -> PyResult<&ManualClock> {
        self.clock.as_ref().ok_or_else(|| {
            errors::InvalidError::new_err("this node runs on the real clock: only a manual-clock node can be advanced")
        })
    }

    fn step_now(&self, py: Python<'_>) -> PyResult<Option<f64>> {
        let stepping = &self.shared.stepping;
        self.shared.with(py, |n| Ok(Shared::step(n, stepping).map(secs)))
    }

    fn stop_thread(&self, py: Python<'_>) {
        self.thread.stop(py);
    }
}

#[pymethods]
impl Node {
    /// A node with id `id`. `url`: its transport (`udp://...`, `mem://name`); None: an
    /// in-process network of its own. `manual=True`: a manual clock at 0 s that only
    /// `advance`/`set_time` move; else the real monotonic clock.
    #[new]
    #[pyo3(signature = (id, url = None, *, manual = false))]
    fn new(py: Python<'_>, id: u32, url: Option<&str>, manual: bool) -> PyResult<Node> {
        let nid = NodeId(id);
        let clock = manual.then(ManualClock::new);
        let node = match (url, &clock) {
            (None, Some(c)) => ayllu::Node::new(c.clone(), MemNetwork::new().attach(nid).map_err(errors::runtime)?),
            (None, None) => {
                ayllu::Node::new(ayllu::MonotonicClock::new(), MemNetwork::new().attach(nid).map_err(errors::runtime)?)
            }
            (Some(u), Some(c)) => ayllu::Node::open_with_clock(nid, u, c.clone()).map_err(errors::runtime)?,
            (Some(u), None) => ayllu::Node::open(nid, u).map_err(errors::runtime)?,
        };
        Node::build(py, id, node, clock)
    }

    /// This node's id.
    #[getter]
    fn id(&self) -> u32 {
        self.id
    }
    /// Whether the node runs on a manual clock.
    #[getter]
    fn is_manual(&self) -> bool {
        self.clock.is_some()
    }
    /// The node's clock now (s).
    #[getter]
    fn now(&self, py: Python<'_>) -> PyResult<f64> {
        self.shared.with(py, |n| Ok(secs(n.now())))
    }

    /// Define a behavior class (a subclass of `ayllu.Behavior`) on this node (rule S2).
    fn define(&self, py: Python<'_>, cls: &Bound<'_, PyAny>) -> PyResult<()> {
        let procs = Arc::clone(&self.shared.procs);
        self.shared.with(py, |n| wiring::define(py, n.core_mut(), &procs, cls))
    }

    /// Define one of the standard library's classes (the paper's `ayllustd.h`): `SafeVelocity`,
    /// `RandomWander` (`hz`, `seed`), `Wander` (`hz`), `Observer`, `Vision` (`targets`), `Base`,
    /// `Sonar` (`beams`, `max_range`).
    #[pyo3(signature = (name, *, hz = 10.0, seed = 1, targets = 4, beams = 16, max_range = 5.0))]
    #[allow(clippy::too_many_arguments)]
    fn define_stdlib(
        &self,
        py: Python<'_>,
        name: &str,
        hz: f64,
        seed: u64,
        targets: u32,
        beams: usize,
        max_range: f64,
    ) -> PyResult<()> {
        self.shared.with(py, |n| {
            wiring::define_stdlib(n.core_mut(), name, &StdlibOptions { hz, seed, targets, beams, max_range })
        })
    }

    /// Make this node robot `id`'s controller node for a world served by `ayllu sim serve`:
    /// its body (VISION, SONAR, BASE) as local behaviors the server writes and reads
    /// (`ayllu_sim::served_robot`). Then build the controller on it as in the simulator.
    ///
    /// It also creates `LINK` and attaches its driver, so the robot reports to the server what
    /// its metrics need with no code of the program's: every turn of the node, `LINK.Drive`
    /// (the target driving it, read from the observer layers `OBS1`..`OBS{targets}` by name)
    /// when it changes, and four times a second `LINK.Sent` and `LINK.Bytes` (the messages the
    /// node sent to anyone but its body during its turns, and their encoded size). The
    /// server's word is the program's to act on: `node.read("LINK", "Alive")` turns 0 when the
    /// scenario kills the robot.
    #[pyo3(signature = (targets = 4))]
    fn install_served_body(&self, py: Python<'_>, targets: usize) -> PyResult<()> {
        self.shared.with(py, |n| ayllu_sim::served_robot::attach(n, targets).map_err(errors::core))
    }

    /// Make this node's body a ROS 2 robot's: the behaviors the mapping file at `path` names
    /// (VISION, SONAR, BASE for Fig. 2) are created if the node lacks them, and from its next
    /// step on, samples of the file's "in" topics write their ports and its "out" topics
    /// publish their ports' values (docs/ros2.md; `{id}` in the file stands for this node's
    /// id). In place of `install_served_body`: the controller built on the body is the same.
    ///
    /// Raises `ayllu.InvalidError` (a `ValueError`) for a wrong mapping file, with the file,
    /// the field and the fix in the message, and for one that does not fit the node (a mapped
    /// port it has with another type); `FileNotFoundError` (or another `OSError`) for a file
    /// that cannot be read; `ayllu.NetworkError` when the DDS stack refuses; `ayllu.AylluError`
    /// when the module was built without the ROS 2 body (the default wheel: build one with it
    /// with `make ros2-python`).
    fn install_ros2_body(&self, py: Python<'_>, path: std::path::PathBuf) -> PyResult<()> {
        self.shared.with(py, |n| crate::ros2::install(n, &path))
    }

    /// Whether a class of this name is defined here.
    fn has_class(&self, py: Python<'_>, name: &str) -> PyResult<bool> {
        self.shared.with(py, |n| Ok(n.core().has_class(name)))
    }

    /// Create behavior `name` of `cls` (an `ayllu.Behavior` subclass, defined here first if it
    /// is not yet, or the name of a defined class). Returns the behavior's Python object.
    fn create(&self, py: Python<'_>, cls: &Bound<'_, PyAny>, name: &str) -> PyResult<Option<Py<PyAny>>> {
        let procs = Arc::clone(&self.shared.procs);
        self.shared.with(py, |n| wiring::create(py, n.core_mut(), &procs, cls, name))
    }

    /// Remove behavior `name` and its connections (rule S9).
    fn remove(&self, py: Python<'_>, name: &str) -> PyResult<()> {
        self.shared.with(py, |n| n.remove(name).map_err(errors::runtime))?;
        self.shared.procs.forget(name);
        Ok(())
    }

    /// The Python object of behavior `name` (None for a behavior of a Rust class).
    fn behavior(&self, py: Python<'_>, name: &str) -> Option<Py<PyAny>> {
        self.shared.procs.instance(py, name)
    }

    /// Connect `source` (a port of this node) to `destination` (`ayllu.local`, `ayllu.remote`,
    /// `ayllu.broadcast`, or a `(behavior, port)` tuple) with `kind` (default `ayllu.NORMAL`)
    /// and `priority` (for Priority ports). Returns the connection's id.
    #[pyo3(signature = (source, destination, kind = None, *, priority = 0))]
    fn connect(
        &self,
        py: Python<'_>,
        source: &Bound<'_, PyAny>,
        destination: &Bound<'_, PyAny>,
        kind: Option<&Bound<'_, PyAny>>,
        priority: i32,
    ) -> PyResult<u64> {
        let args = connection::connect_args(source, destination, kind)?;
        self.shared.with(py, |n| wiring::connect(n.core_mut(), &args, priority))
    }

    /// Remove connection `id` (owned by this node).
    fn disconnect(&self, py: Python<'_>, id: u64) -> PyResult<()> {
        self.shared.with(py, |n| n.disconnect(ayllu_core::ConnectionId(id)).map_err(errors::runtime))
    }

    /// Ask `source`'s node (`ayllu.remote(node, behavior, port)`) to connect that port to
    /// `destination` (`ayllu.local` is a port of this node, or `ayllu.remote`,
    /// `ayllu.broadcast`) with `kind` and `priority` (N2: resent until answered). Returns the
    /// request's id for `request_status`; the connection belongs to the source's node.
    #[pyo3(signature = (source, destination, kind = None, *, priority = 0))]
    fn request_connect(
        &self,
        py: Python<'_>,
        source: &Bound<'_, PyAny>,
        destination: &Bound<'_, PyAny>,
        kind: Option<&Bound<'_, PyAny>>,
        priority: i32,
    ) -> PyResult<u64> {
        let args = connection::connect_args(source, destination, kind)?;
        self.shared.with(py, |n| wiring::request_connect(n.core_mut(), &args, priority))
    }

    /// Ask node `node` to remove its connection `connection` (as `request_connect`'s result
    /// gave it). Returns the request's id.
    fn request_disconnect(&self, py: Python<'_>, node: u32, connection: u64) -> PyResult<u64> {
        self.shared.with(py, |n| Ok(n.core_mut().request_disconnect(NodeId(node), ConnectionId(connection)).0))
    }

    /// Ask node `node` to describe itself (LIST; the result is a report like `report()`'s).
    fn request_list(&self, py: Python<'_>, node: u32) -> PyResult<u64> {
        self.shared.with(py, |n| wiring::request(n.core_mut(), node, ControlBody::List))
    }

    /// Ask node `node` to explain `behavior.port` (WHY; the result is a report like `why()`'s).
    fn request_why(&self, py: Python<'_>, node: u32, behavior: &str, port: &str) -> PyResult<u64> {
        let body = ControlBody::Why { behavior: behavior.into(), port: port.into() };
        self.shared.with(py, |n| wiring::request(n.core_mut(), node, body))
    }

    /// Ask node `node` for the value of `behavior.port` (READ; the result is the value).
    fn request_read(&self, py: Python<'_>, node: u32, behavior: &str, port: &str) -> PyResult<u64> {
        let body = ControlBody::Read { behavior: behavior.into(), port: port.into() };
        self.shared.with(py, |n| wiring::request(n.core_mut(), node, body))
    }

    /// Apply a plan (the TOML text of `ayllu apply`, docs/cli.md) from this node to the nodes
    /// it names, all at once or not at all (docs/semantics.md R8-R12). Blocks until the
    /// transaction has ended and the switch is past; returns the report as a dict (`outcome`
    /// is "switched", "aborted" or "split"; `nodes` says which refused and why). Raises
    /// `ValueError` for a plan that does not parse or names this node.
    fn apply(&self, py: Python<'_>, plan: &str) -> PyResult<Py<PyAny>> {
        let plan = ayllu::transaction::Plan::from_toml(plan).map_err(|e| errors::value_error(e.to_string()))?;
        // Without the GIL while it waits: the team's other nodes in this process (started in
        // the background) take it to run their Python processes.
        let report = self.shared.with(py, |n| {
            py.detach(|| ayllu::transaction::apply(n, &plan)).map_err(|e| errors::value_error(e.to_string()))
        })?;
        let json = py.import("json")?;
        Ok(json.call_method1("loads", (report.to_json().to_string(),))?.unbind())
    }

    /// Where request `request_id` stands: an `ayllu.RequestStatus` (`pending` with `sends`,
    /// `done` with `result`, `failed` with `error`).
    fn request_status(&self, py: Python<'_>, request_id: u64) -> PyResult<Py<PyAny>> {
        self.shared.with(py, |n| wiring::request_status(py, n.core(), request_id))
    }

    /// Who may write this node's ports along connections (`ports`) and change its structure by
    /// request (`structure`): `"all"`, `"none"` or a list of node ids (D9.2). This node's own
    /// calls are never restricted.
    #[pyo3(signature = (ports = None, structure = None))]
    fn set_access(
        &self,
        py: Python<'_>,
        ports: Option<&Bound<'_, PyAny>>,
        structure: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let allow = |what, o: Option<&Bound<'_, PyAny>>| o.map_or(Ok(Allow::Everyone), |o| wiring::allow(what, o));
        let access = Access { ports: allow("ports", ports)?, structure: allow("structure", structure)? };
        self.shared.with(py, |n| {
            n.core_mut().set_access(access);
            Ok(())
        })
    }

    /// Bound what the network can make this node hold (D9.3); each limit left out keeps its
    /// default (256 connections by request, 32 per node, windows up to 600 s, 50 requests a
    /// second per node with bursts of 100).
    #[pyo3(signature = (
        *,
        remote_connections = None,
        remote_connections_per_node = None,
        max_remote_period = None,
        requests_per_second = None,
        requests_burst = None
    ))]
    fn set_limits(
        &self,
        py: Python<'_>,
        remote_connections: Option<usize>,
        remote_connections_per_node: Option<usize>,
        max_remote_period: Option<f64>,
        requests_per_second: Option<u32>,
        requests_burst: Option<u32>,
    ) -> PyResult<()> {
        let limits = wiring::limits(
            remote_connections,
            remote_connections_per_node,
            max_remote_period,
            requests_per_second,
            requests_burst,
        )?;
        self.shared.with(py, |n| {
            n.core_mut().set_limits(limits);
            Ok(())
        })
    }

    /// Join broadcast group `group`.
    fn join(&self, py: Python<'_>, group: &str) -> PyResult<()> {
        self.shared.with(py, |n| {
            n.join(group);
            Ok(())
        })
    }

    /// Leave broadcast group `group`.
    fn leave(&self, py: Python<'_>, group: &str) -> PyResult<()> {
        self.shared.with(py, |n| {
            n.leave(group);
            Ok(())
        })
    }

    /// Make `behavior` a BLE peer in `group` (rule S11): its eligibility goes to the peers'
    /// `Best`, its claims write-inhibit their `output`. One call; returns what was made.
    #[pyo3(signature = (behavior, group, output, claim_hz = 1.0, *, inhibit_period = None, network_delay = None))]
    #[allow(clippy::too_many_arguments)]
    fn ble_join<'py>(
        &self,
        py: Python<'py>,
        behavior: &str,
        group: &str,
        output: &str,
        claim_hz: f64,
        inhibit_period: Option<f64>,
        network_delay: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = self.shared.with(py, |n| {
            wiring::ble_join(py, n.core_mut(), behavior, group, output, claim_hz, inhibit_period, network_delay)
        })?;
        // The transport joins the group too (the node syncs its groups on every step).
        self.shared.with(py, |n| {
            n.join(group);
            Ok(())
        })?;
        Ok(d)
    }

    /// Write `behavior.port` as its behavior would, now (rule S6).
    fn write(&self, py: Python<'_>, behavior: &str, port: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = to_value(value)?;
        self.shared.with(py, |n| n.write(behavior, port, v).map_err(errors::runtime))
    }

    /// The port's value now (its default while empty).
    fn read(&self, py: Python<'_>, behavior: &str, port: &str) -> PyResult<Py<PyAny>> {
        self.shared.with(py, |n| n.read(behavior, port).map(|v| to_py(py, &v)).map_err(errors::runtime))
    }

    /// The port's value if fresh now (rule S4), else None.
    fn get(&self, py: Python<'_>, behavior: &str, port: &str) -> PyResult<Option<Py<PyAny>>> {
        self.shared.with(py, |n| n.get(behavior, port).map(|v| v.map(|v| to_py(py, &v))).map_err(errors::runtime))
    }

    /// Whether the port holds a fresh value now.
    fn fresh(&self, py: Python<'_>, behavior: &str, port: &str) -> PyResult<bool> {
        self.shared.with(py, |n| n.fresh(behavior, port).map_err(errors::runtime))
    }

    /// Whether monostable `mono` of `behavior` is high now.
    fn monostable(&self, py: Python<'_>, behavior: &str, mono: &str) -> PyResult<bool> {
        self.shared.with(py, |n| n.monostable(behavior, mono).map_err(errors::runtime))
    }

    /// Trigger monostable `mono` of `behavior` for `seconds` (rule S2).
    fn trigger(&self, py: Python<'_>, behavior: &str, mono: &str, seconds: f64) -> PyResult<()> {
        let d = duration("seconds", seconds)?;
        self.shared.with(py, |n| {
            let core = n.core_mut();
            let now = core.now(); // core_mut told it the present
            core.trigger(now, behavior, mono, d).map_err(errors::core)
        })
    }

    /// Empty an aggregating port (a Normal one returns to its default).
    fn reset(&self, py: Python<'_>, behavior: &str, port: &str) -> PyResult<()> {
        self.shared.with(py, |n| {
            let r = n.core().port(behavior, port).map_err(errors::core)?;
            n.core_mut().reset(r).map_err(errors::core)
        })
    }

    /// A handle to `behavior.port`, resolved once: its `write` and `read` skip the name lookups.
    fn port(slf: &Bound<'_, Self>, behavior: &str, port: &str) -> PyResult<PortHandle> {
        let py = slf.py();
        let r = slf.get().shared.with(py, |n| n.core().port(behavior, port).map_err(errors::core))?;
        Ok(PortHandle { node: slf.clone().unbind(), port: r, name: format!("{behavior}.{port}") })
    }

    /// Why `behavior.port` holds what it holds and passes what it passes, now: an
    /// `ayllu.Report` (attributes as in Rust's `PortReport`; `str()` is what `ayllu why` prints).
    fn why(&self, py: Python<'_>, behavior: &str, port: &str) -> PyResult<Py<PyAny>> {
        let (json, text) = self.shared.with(py, |n| {
            let r = n.why(behavior, port).map_err(errors::runtime)?;
            Ok((ayllu::report_json::port_report_json(&r).to_string(), r.to_string()))
        })?;
        wiring::report(py, &json, Some(text))
    }

    /// The whole node (behaviors, connections, counters, warnings) as an `ayllu.Report`.
    fn report(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let json =
            self.shared.with(py, |n| Ok(ayllu::report_json::node_report_json(&n.core().report()).to_string()))?;
        wiring::report(py, &json, None)
    }

    /// A BLE member's standing (claiming, claims, local, best, inhibited_by) as an
    /// `ayllu.Report`, or None if `behavior` is in no BLE group.
    fn ble_status(&self, py: Python<'_>, behavior: &str) -> PyResult<Option<Py<PyAny>>> {
        let json = self.shared.with(py, |n| match n.core().ble_status(behavior).map_err(errors::core)? {
            Some(s) => Ok(Some(wiring::json(&s)?)),
            None => Ok(None),
        })?;
        json.map(|j| wiring::report(py, &j, None)).transpose()
    }

    /// The warnings the node raised (e.g. a BLE inhibit period too short).
    fn warnings(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        self.shared.with(py, |n| Ok(n.core().warnings().to_vec()))
    }

    /// Traffic figures: steps, sent, held, dropped, received.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.shared.with(py, |n| Ok(n.stats()))?;
        let d = PyDict::new(py);
        d.set_item("steps", s.steps)?;
        d.set_item("sent", s.sent)?;
        d.set_item("held", s.held)?;
        d.set_item("dropped", s.dropped)?;
        d.set_item("received", s.received)?;
        Ok(d)
    }

    /// Record everything that enters this node's core, and the values its ports accept, into
    /// the MCAP file `path` (Foxglove opens it; `ayllu replay` and `ayllu.check_recording`
    /// play it back). Call it before defining classes. `max_bytes`: cap on all segments
    /// together (default 1 GiB; at least 65536). `keep_last`: keep only about the last that
    /// many seconds (a rolling recording, checkpointed every quarter of it; replayed from its
    /// oldest checkpoint kept).
    #[pyo3(signature = (path, *, max_bytes = None, keep_last = None))]
    fn record(
        &self,
        py: Python<'_>,
        path: std::path::PathBuf,
        max_bytes: Option<u64>,
        keep_last: Option<f64>,
    ) -> PyResult<()> {
        self.shared.with(py, |n| crate::recording::record(n, &path, max_bytes, keep_last))
    }

    /// Stop recording and close the file; what was written (a dict), or None if the node was
    /// not recording.
    fn stop_recording<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let stats = self.shared.with(py, |n| Ok(n.stop_recording()))?;
        stats.map(|s| crate::recording::stats_dict(py, &s)).transpose()
    }

    /// Where peers reach this node (`udp://` transports), or None.
    fn address(&self, py: Python<'_>) -> PyResult<Option<String>> {
        self.shared.with(py, |n| Ok(n.address()))
    }

    /// The Python exceptions raised in processes (the last 100): `(behavior, process, time,
    /// traceback)`.
    fn process_errors(&self, py: Python<'_>) -> PyResult<Vec<Py<PyAny>>> {
        let cls = py.import("ayllu.report")?.getattr("ProcessError")?;
        self.shared
            .procs
            .errors()
            .into_iter()
            .map(|e| Ok(cls.call1((e.behavior, e.process, e.time, e.traceback))?.unbind()))
            .collect()
    }

    /// Exceptions raised per `(behavior, process)`, every one counted.
    fn process_error_counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for ((b, p), n) in self.shared.procs.error_counts() {
            d.set_item((b, p), n)?;
        }
        Ok(d)
    }

    /// One turn: send, receive, run what is due. Returns when the node next has work (s).
    fn step(&self, py: Python<'_>) -> PyResult<Option<f64>> {
        self.step_now(py)
    }

    /// Manual clock only: move time forward by `seconds` (in steps of `tick` seconds, stepping
    /// after each; one step at the end if `tick` is None).
    #[pyo3(signature = (seconds, tick = None))]
    fn advance(&self, py: Python<'_>, seconds: f64, tick: Option<f64>) -> PyResult<()> {
        let clock = self.manual()?.clone();
        advance(py, &clock, seconds, tick, |py| self.step_now(py).map(|_| ()))
    }

    /// Manual clock only: set the time to `seconds` (never backwards) and step once.
    fn set_time(&self, py: Python<'_>, seconds: f64) -> PyResult<()> {
        let clock = self.manual()?;
        clock.set(instant(seconds)?);
        self.step_now(py).map(|_| ())
    }

    /// Real clock: step and sleep for `seconds`, here, releasing the GIL while asleep.
    /// `seconds` below 0 or NaN are refused (they used to run nothing, in silence).
    fn run_for(&self, py: Python<'_>, seconds: f64) -> PyResult<()> {
        if seconds.is_nan() || seconds < 0.0 {
            return Err(errors::value_error(format!("run_for takes seconds of at least 0, not {seconds}")));
        }
        let span = duration("seconds", seconds)?;
        if self.clock.is_some() {
            return self.advance(py, seconds, None);
        }
        let end = std::time::Instant::now() + std::time::Duration::from_nanos(span.as_nanos());
        let shared = Arc::clone(&self.shared);
        loop {
            let stepping = &self.shared.stepping;
            let next = self.shared.with(py, |n| Ok(Shared::step(n, stepping)))?;
            let left = end.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                return Ok(());
            }
            // Asleep without the GIL (other Python threads run), then Ctrl-C is honoured.
            py.detach(|| {
                let mut g = shared.node.lock().unwrap_or_else(|p| p.into_inner());
                if let Some(n) = g.as_mut() {
                    shared.wait(n, next, left);
                }
            });
            py.check_signals()?;
        }
    }

    /// Real clock: run the node on a background thread until `stop()` (or `close()`).
    fn start(&self, py: Python<'_>) -> PyResult<()> {
        if self.clock.is_some() {
            return Err(errors::InvalidError::new_err(
                "a manual-clock node moves only with advance(); only a real-clock node can start()",
            ));
        }
        // A closed node has nothing to run: its thread would end at once, and `running` say
        // True, where every other method raises.
        self.shared.with(py, |_| Ok(()))?;
        let mut t = self.thread.handle.lock().map_err(|_| errors::closed("this node"))?;
        if t.is_some() {
            return Err(errors::InvalidError::new_err("this node is already running"));
        }
        self.thread.stop.store(false, Ordering::Release);
        let (shared, runner) = (Arc::clone(&self.shared), Arc::clone(&self.thread));
        // Attached once and detached at once: the thread keeps its Python thread state, so each
        // Python process it runs only re-takes the GIL instead of making a thread state anew.
        *t = Some(std::thread::spawn(move || {
            Python::attach(|py| py.detach(|| run_in_background(&shared, &runner.stop)));
        }));
        if let Ok(mut r) = RUNNERS.lock() {
            r.push(Arc::downgrade(&self.thread));
        }
        Ok(())
    }

    /// Stop the background thread (the node keeps its state; `start()` runs it again).
    fn stop(&self, py: Python<'_>) {
        self.stop_thread(py);
    }

    /// Whether the background thread runs.
    #[getter]
    fn running(&self) -> bool {
        self.thread.handle.lock().map(|t| t.is_some()).unwrap_or(false) && !self.thread.stop.load(Ordering::Acquire)
    }

    fn __repr__(&self) -> String {
        let clock = if self.clock.is_some() { "manual clock" } else { "real clock" };
        format!("Node({}, {clock}{})", self.id, if self.running() { ", running" } else { "" })
    }

    /// Stop and drop the node: its transport closes; later calls raise.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        self.stop_thread(py);
        let mut g = self.shared.lock(py)?;
        *g = None;
        Ok(())
    }
}

impl Drop for Node {
    fn drop(&mut self) {
        self.thread.stop.store(true, Ordering::Release);
    }
}

fn run_in_background(shared: &Shared, stop: &AtomicBool) {
    while !stop.load(Ordering::Acquire) {
        let mut g = shared.node.lock().unwrap_or_else(|p| p.into_inner());
        let Some(n) = g.as_mut() else { return };
        let next = Shared::step(n, &shared.stepping);
        shared.wait(n, next, IDLE_SLICE);
        drop(g);
    }
}

fn advance(
    py: Python<'_>,
    clock: &ManualClock,
    seconds: f64,
    tick: Option<f64>,
    mut step: impl FnMut(Python<'_>) -> PyResult<()>,
) -> PyResult<()> {
    let total = duration("seconds", seconds)?;
    let Some(tick) = tick else {
        clock.advance(total);
        return step(py);
    };
    // A tick is counted in whole nanoseconds: one that rounds to none would never move time.
    if tick.is_nan() || tick < 0.5e-9 {
        return Err(errors::value_error(format!("tick must be at least 1 ns (1e-9 s), not {tick:e} s")));
    }
    let tick = duration("tick", tick)?;
    use ayllu::Clock;
    let end = clock.now() + total;
    while clock.now() < end {
        let left = end - clock.now();
        clock.advance(tick.min(left));
        step(py)?;
    }
    Ok(())
}

/// A port resolved once (see `Node.port`).
#[pyclass(frozen, module = "ayllu._native")]
pub struct PortHandle {
    node: Py<Node>,
    port: PortRef,
    name: String,
}

#[pymethods]
impl PortHandle {
    /// Write the port as its behavior would, now.
    fn write(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = to_value(value)?;
        self.node.get().shared.with(py, |n| {
            let core = n.core_mut();
            let now = core.now(); // core_mut told it the present
            core.write(now, self.port, v).map_err(errors::core)
        })
    }
    /// The port's value now.
    fn read(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.node.get().shared.with(py, |n| {
            let now = n.now();
            n.core().read_at(now, self.port).map(|v| to_py(py, &v)).map_err(errors::core)
        })
    }
    /// The port's value if fresh now, else None.
    fn get(&self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        self.node.get().shared.with(py, |n| {
            let now = n.now();
            n.core().get_at(now, self.port).map(|v| v.map(|v| to_py(py, &v))).map_err(errors::core)
        })
    }
    fn __repr__(&self) -> String {
        format!("PortHandle({})", self.name)
    }
}

/// Several manual-clock nodes on one clock and one in-process network, stepped in the order
/// they were added (like `ayllu::Lockstep`).
#[pyclass(frozen, module = "ayllu._native")]
pub struct Team {
    clock: ManualClock,
    network: MemNetwork,
    nodes: Mutex<Vec<Py<Node>>>,
}

#[pymethods]
impl Team {
    #[new]
    fn new() -> Team {
        Team { clock: ManualClock::new(), network: MemNetwork::new(), nodes: Mutex::new(Vec::new()) }
    }

    /// Add a node with id `id` on the team's clock and network.
    fn add(&self, py: Python<'_>, id: u32) -> PyResult<Py<Node>> {
        let transport = self.network.attach(NodeId(id)).map_err(errors::runtime)?;
        let node = ayllu::Node::new(self.clock.clone(), transport);
        let obj = Py::new(py, Node::build(py, id, node, Some(self.clock.clone()))?)?;
        self.nodes.lock().map_err(|_| errors::closed("this team"))?.push(obj.clone_ref(py));
        Ok(obj)
    }

    /// The live nodes, in the order they were added.
    #[getter]
    fn nodes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let v: Vec<Py<Node>> =
            self.nodes.lock().map(|n| n.iter().map(|x| x.clone_ref(py)).collect()).unwrap_or_default();
        PyList::new(py, v)
    }

    /// The team's time (s).
    #[getter]
    fn now(&self) -> f64 {
        use ayllu::Clock;
        secs(self.clock.now())
    }

    /// Step every node once at the current time.
    fn step(&self, py: Python<'_>) -> PyResult<()> {
        let nodes: Vec<Py<Node>> =
            self.nodes.lock().map(|n| n.iter().map(|x| x.clone_ref(py)).collect()).unwrap_or_default();
        for n in nodes {
            n.get().step_now(py)?;
        }
        Ok(())
    }

    /// Move time forward by `seconds` in ticks of `tick` (default 10 ms), stepping every
    /// node each tick.
    #[pyo3(signature = (seconds, tick = 0.01))]
    fn advance(&self, py: Python<'_>, seconds: f64, tick: f64) -> PyResult<()> {
        advance(py, &self.clock, seconds, Some(tick), |py| self.step(py))
    }

    /// Remove node `id` as if its robot died: it steps no more and its transport detaches.
    /// Returns whether it was in the team.
    fn kill(&self, py: Python<'_>, id: u32) -> PyResult<bool> {
        let victim = {
            let mut nodes = self.nodes.lock().map_err(|_| errors::closed("this team"))?;
            let i = nodes.iter().position(|n| n.get().id == id);
            i.map(|i| nodes.remove(i))
        };
        match victim {
            Some(n) => {
                n.get().close(py)?;
                Ok(true)
            }
            None => Ok(false),
        }
    }
}
