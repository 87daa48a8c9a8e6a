//! The simulator from Python: scenarios in, outcomes (and per-tick traces) out, with the
//! controllers of `ayllu-sim` or one written in Python running on every robot's node.
//!
//! Promises:
//! * A run is `ayllu_sim`'s own ([`Sim`]): the same scenario gives the same outcome, bit for
//!   bit, as the Rust simulator (same trace hash). Scenarios cross as the serde JSON of
//!   `ayllu_sim::scenario::Scenario`, so every field of the Rust type is settable from Python.
//! * Runs with Rust controllers release the GIL, so Python threads run beside them.
//! * A Python controller is a callable given a [`RobotBuilder`] per robot (valid only during
//!   that call); its processes run inside the simulator's step like any other process, and
//!   exceptions they raise are counted per process and returned with the outcome.

use std::sync::atomic::{AtomicPtr, Ordering};
use std::sync::Arc;

use ayllu_core::{Error as CoreError, NodeCore};
use ayllu_sim::bounds::show;
use ayllu_sim::controller::{Brain, Controller, ControllerConfig};
use ayllu_sim::scenario::{node_id, Scenario, Sim, SimError};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::behavior::Processes;
use crate::connection;
use crate::errors;
use crate::stdlib::StdlibOptions;
use crate::wiring;

/// Register the simulator's functions and classes on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(scenario_json, m)?)?;
    m.add_function(wrap_pyfunction!(controller_names, m)?)?;
    m.add_function(wrap_pyfunction!(run_scenario, m)?)?;
    m.add("MAX_TRACE_VALUES", MAX_TRACE_VALUES)?;
    m.add_class::<RobotBuilder>()?;
    Ok(())
}

/// The JSON of `Scenario::sized(controller, robots, targets, seed)`: `robots` robots and
/// `targets` targets with priorities targets..1 in a room scaled to keep the paper's density.
#[pyfunction]
fn scenario_json(controller: &str, robots: usize, targets: usize, seed: u64) -> PyResult<String> {
    let c = parse_controller(controller)?;
    // The targets' list is made here: its bound is asked first (the team's is asked by a run).
    ayllu_sim::bounds::targets("targets", Some(targets as u64), targets).map_err(sim_error)?;
    wiring::json(&Scenario::sized(c, robots, targets, seed))
}

/// Every built-in controller's name: the study's six in the tables' order, then the ones a
/// study adds on request (BLE-lean, BLE-seek: docs/cmommt.md).
#[pyfunction]
fn controller_names() -> Vec<&'static str> {
    Controller::EVERY.iter().map(|c| c.name()).collect()
}

fn parse_controller(name: &str) -> PyResult<Controller> {
    Controller::parse(name).ok_or_else(|| {
        errors::value_error(format!("unknown controller `{name}`: one of {}", controller_names().join(", ")))
    })
}

/// A scenario out of bounds is a `ValueError` naming its field (its message is the library's:
/// `ayllu_sim::bounds`); a node's refusal is the core error's exception.
fn sim_error(e: impl Into<SimError>) -> PyErr {
    match e.into() {
        SimError::Scenario(e) => errors::value_error(e.to_string()),
        SimError::Node(e) => errors::core(e),
    }
}

/// One robot's node while a Python controller builds on it: the same building methods as
/// `ayllu.Node` (`define`, `create`, `connect`, `join`, `leave`, `ble_join`,
/// `define_stdlib`), plus the robot's `id`, the targets' `priorities` and the controllers'
/// tunables (`claim_hz`, `wander_seed`).
#[pyclass(frozen, module = "ayllu._native")]
pub struct RobotBuilder {
    core: AtomicPtr<NodeCore>,
    procs: Arc<Processes>,
    #[pyo3(get)]
    id: u32,
    #[pyo3(get)]
    priorities: Vec<f64>,
    #[pyo3(get)]
    claim_hz: f64,
    #[pyo3(get)]
    wander_seed: u64,
}

impl RobotBuilder {
    fn with<R>(&self, f: impl FnOnce(&mut NodeCore) -> PyResult<R>) -> PyResult<R> {
        let p = self.core.load(Ordering::Acquire);
        if p.is_null() {
            return Err(PyRuntimeError::new_err(
                "this robot builder belongs to a controller call that has returned: build only inside it",
            ));
        }
        // SAFETY: `p` is the `&mut NodeCore` that `run_scenario`'s build closure holds for the
        // duration of the Python controller call; it is stored right before that call and cleared
        // right after, and nothing else touches the core meanwhile. Every method runs with the
        // GIL held and does not release it, so no two `&mut` made from it coexist.
        let core = unsafe { &mut *p };
        f(core)
    }
}

#[pymethods]
impl RobotBuilder {
    /// Define an `ayllu.Behavior` subclass on the robot's node.
    fn define(&self, py: Python<'_>, cls: &Bound<'_, PyAny>) -> PyResult<()> {
        self.with(|c| wiring::define(py, c, &self.procs, cls))
    }
    /// Create behavior `name` of `cls` (a class or the name of a defined one).
    fn create(&self, py: Python<'_>, cls: &Bound<'_, PyAny>, name: &str) -> PyResult<Option<Py<PyAny>>> {
        self.with(|c| wiring::create(py, c, &self.procs, cls, name))
    }
    /// Define one of the standard library's classes (see `ayllu.Node.define_stdlib`).
    #[pyo3(signature = (name, *, hz = 10.0, seed = 1, targets = 4, beams = 16, max_range = 5.0))]
    fn define_stdlib(
        &self,
        name: &str,
        hz: f64,
        seed: u64,
        targets: u32,
        beams: usize,
        max_range: f64,
    ) -> PyResult<()> {
        self.with(|c| wiring::define_stdlib(c, name, &StdlibOptions { hz, seed, targets, beams, max_range }))
    }
    /// Whether a class of this name is defined on the robot's node.
    fn has_class(&self, name: &str) -> PyResult<bool> {
        self.with(|c| Ok(c.has_class(name)))
    }
    /// Connect two ports (see `ayllu.Node.connect`); the connection's id.
    #[pyo3(signature = (source, destination, kind = None, *, priority = 0))]
    fn connect(
        &self,
        source: &Bound<'_, PyAny>,
        destination: &Bound<'_, PyAny>,
        kind: Option<&Bound<'_, PyAny>>,
        priority: i32,
    ) -> PyResult<u64> {
        let args = connection::connect_args(source, destination, kind)?;
        self.with(|c| wiring::connect(c, &args, priority))
    }
    /// Join broadcast group `group`.
    fn join(&self, group: &str) -> PyResult<()> {
        self.with(|c| {
            c.join(group);
            Ok(())
        })
    }
    /// Leave broadcast group `group`.
    fn leave(&self, group: &str) -> PyResult<()> {
        self.with(|c| {
            c.leave(group);
            Ok(())
        })
    }
    /// Make `behavior` a BLE peer (see `ayllu.Node.ble_join`).
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
        self.with(|c| wiring::ble_join(py, c, behavior, group, output, claim_hz, inhibit_period, network_delay))
    }
}

/// What a Python controller returned: None (wander: nothing drives), `("drive", (b, p))` (an
/// int port holding the target driving, 0 none) or `("chain", [(b, p), ...])` (observer layers
/// from the highest: the highest that wrote its port within the override period drives).
fn brain(core: &NodeCore, spec: &Bound<'_, PyAny>) -> PyResult<Brain> {
    if spec.is_none() {
        return Ok(Brain::Wander);
    }
    let bad = || {
        errors::type_error(
            "a controller returns None, ayllu.sim.drive(behavior, port) or ayllu.sim.chain([(behavior, port), ...])",
        )
    };
    let t = spec.cast::<PyTuple>().map_err(|_| bad())?;
    let what: String = t.get_item(0)?.extract().map_err(|_| bad())?;
    match what.as_str() {
        "drive" => {
            let (b, p): (String, String) = t.get_item(1)?.extract().map_err(|_| bad())?;
            Ok(Brain::Drive(core.port(&b, &p).map_err(errors::core)?))
        }
        "chain" => {
            let layers: Vec<(String, String)> = t.get_item(1)?.extract().map_err(|_| bad())?;
            let refs = layers.iter().map(|(b, p)| core.port(b, p)).collect::<Result<_, _>>().map_err(errors::core)?;
            Ok(Brain::Chain(refs))
        }
        _ => Err(bad()),
    }
}

/// The most values a trace (`run(..., trace=True)`) keeps: ticks x (1 + 5 x robots + 2 x
/// targets). The trace is held whole, twice for a moment (Rust vectors, then Python lists of
/// about 32 bytes a value), so 2e7 values is about 800 MB at its peak, less than the largest
/// recording ([`ayllu_sim::bounds::MAX_RECORDED`] poses, 2 GB). A run whose trace would hold
/// more is refused before it starts (not cut short, nor thinned, in silence): a recording
/// keeps every frame within its own bound, and the `ayllu` tool streams a per-tick trace to a
/// file. docs/python.md says why.
pub const MAX_TRACE_VALUES: f64 = 2e7;

/// Refuse `trace=True` on a scenario whose trace would hold more than [`MAX_TRACE_VALUES`].
fn check_trace(s: &Scenario) -> PyResult<()> {
    let ticks = (s.duration / s.dt).ceil() + 1.0; // the state before the first step, then one a step
    let per_tick = 1 + 5 * s.robots + 2 * s.world.targets.len();
    let values = ticks * per_tick as f64;
    if values > MAX_TRACE_VALUES {
        let shown = if values < 1e6 { format!("{values:.0}") } else { format!("{values:.1e}") };
        return Err(errors::value_error(format!(
            "trace=True would keep {shown} values ({ticks:.0} ticks x {per_tick} values: the time, 5 per robot, 2 per target), \
             more than {} (sim.MAX_TRACE_VALUES, about 800 MB): shorten the run, record it instead (the scenario's \
             record=True keeps every frame_dt's poses), or stream the trace to a file with `ayllu sim run FILE \
             --trace T.csv`",
            show(MAX_TRACE_VALUES)
        )));
    }
    Ok(())
}

/// Per-tick state: time, and per robot and tick x, y, theta, alive, drive; per target x, y.
#[derive(Default)]
struct Trace {
    t: Vec<f64>,
    robot: [Vec<f64>; 3],
    alive: Vec<bool>,
    drive: Vec<u32>,
    target: [Vec<f64>; 2],
}

impl Trace {
    fn sample(&mut self, sim: &Sim) {
        let w = sim.world();
        self.t.push(sim.now().as_secs_f64());
        for (i, r) in w.robots.iter().enumerate() {
            self.robot[0].push(r.pose.x);
            self.robot[1].push(r.pose.y);
            self.robot[2].push(r.pose.theta);
            self.alive.push(r.alive);
            self.drive.push(if r.alive { sim.drive(i) } else { 0 });
        }
        for tg in &w.targets {
            self.target[0].push(tg.x);
            self.target[1].push(tg.y);
        }
    }

    fn to_py<'py>(&self, py: Python<'py>, robots: usize, targets: usize) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("t", &self.t)?;
        d.set_item("robots", robots)?;
        d.set_item("targets", targets)?;
        d.set_item("x", &self.robot[0])?;
        d.set_item("y", &self.robot[1])?;
        d.set_item("theta", &self.robot[2])?;
        d.set_item("alive", &self.alive)?;
        d.set_item("drive", &self.drive)?;
        d.set_item("target_x", &self.target[0])?;
        d.set_item("target_y", &self.target[1])?;
        Ok(d)
    }
}

fn simulate(mut sim: Sim, trace: Option<&mut Trace>) -> Result<ayllu_sim::scenario::Outcome, CoreError> {
    match trace {
        Some(tr) => {
            tr.sample(&sim);
            while !sim.done() {
                sim.step()?;
                tr.sample(&sim);
            }
        }
        None => {
            while !sim.done() {
                sim.step()?;
            }
        }
    }
    Ok(sim.finish())
}

/// Run the scenario (its serde JSON) to its end. `controller`: None for the scenario's
/// built-in one, else a Python callable building each robot's controller. `trace`: also return
/// the per-tick state. Returns `(outcome JSON, trace dict or None, process errors)`.
#[pyfunction]
#[pyo3(signature = (scenario, controller = None, trace = false, threads = 1))]
#[allow(clippy::type_complexity)]
fn run_scenario<'py>(
    py: Python<'py>,
    scenario: &str,
    controller: Option<Py<PyAny>>,
    trace: bool,
    threads: usize,
) -> PyResult<(String, Option<Bound<'py, PyDict>>, Vec<(u32, String, String, f64, String)>)> {
    let scenario: Scenario =
        serde_json::from_str(scenario).map_err(|e| errors::value_error(format!("not a scenario: {e}")))?;
    if threads == 0 {
        return Err(errors::value_error("threads must be at least 1"));
    }
    if threads > 1 && controller.is_some() {
        return Err(errors::value_error(
            "threads > 1 needs a built-in controller: a Python controller's processes run one at a time (the GIL)",
        ));
    }
    if trace {
        // The scenario's own bounds first: they name its fields.
        scenario.validate().map_err(sim_error)?;
        check_trace(&scenario)?;
    }
    let (robots, targets) = (scenario.robots, scenario.world.targets.len());
    let mut tr = trace.then(Trace::default);
    let mut all_procs: Vec<(u32, Arc<Processes>)> = Vec::new();
    let outcome = match controller {
        None => {
            let mut sim = py.detach(|| Sim::new(&scenario)).map_err(sim_error)?;
            sim.set_threads(threads)
                .map_err(|e| pyo3::exceptions::PyOSError::new_err(format!("starting the simulator's threads: {e}")))?;
            py.detach(|| simulate(sim, tr.as_mut())).map_err(sim_error)?
        }
        Some(ctrl) => {
            let mut failure: Option<PyErr> = None;
            let mut index = 0usize;
            let mut build = |core: &mut NodeCore, prios: &[f64], cfg: &ControllerConfig| -> Result<Brain, CoreError> {
                let id = node_id(index).0;
                index += 1;
                let built = (|| -> PyResult<Brain> {
                    let procs = Processes::new(py)?;
                    let builder = Py::new(
                        py,
                        RobotBuilder {
                            core: AtomicPtr::new(std::ptr::null_mut()),
                            procs: Arc::clone(&procs),
                            id,
                            priorities: prios.to_vec(),
                            claim_hz: cfg.claim_hz,
                            wander_seed: cfg.wander_seed,
                        },
                    )?;
                    builder.get().core.store(core as *mut NodeCore, Ordering::Release);
                    let result = ctrl.call1(py, (builder.clone_ref(py),));
                    builder.get().core.store(std::ptr::null_mut(), Ordering::Release);
                    all_procs.push((id, procs));
                    brain(core, result?.bind(py))
                })();
                built.map_err(|e| {
                    failure = Some(e);
                    CoreError::NotAllowed { what: "the Python controller raised".into() }
                })
            };
            let sim = Sim::with_controller(&scenario, &mut build);
            if let Some(e) = failure {
                return Err(e);
            }
            simulate(sim.map_err(sim_error)?, tr.as_mut()).map_err(sim_error)?
        }
    };
    let json = wiring::json(&outcome)?;
    let trace = tr.map(|t| t.to_py(py, robots, targets)).transpose()?;
    let errs = all_procs
        .iter()
        .flat_map(|(id, p)| p.errors().into_iter().map(move |e| (*id, e.behavior, e.process, e.time, e.traceback)))
        .collect();
    Ok((json, trace, errs))
}
