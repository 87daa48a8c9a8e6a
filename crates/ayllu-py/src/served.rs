//! Serving a world from Python: [`ServedWorld`] wraps `ayllu_sim::served_world::ServedWorld`
//! (the server of the simulator's distributed mode, what `ayllu sim serve` runs), so a Python
//! program hosts the world and its robots' bodies while the controllers run elsewhere — other
//! processes (`ayllu sim robot`, a Python `ayllu.Node` with `install_served_body`), other
//! machines, or threads of this one. `ayllu.sim.ServedWorld` and `ayllu.sim.serve` are the
//! friendly Python side.
//!
//! Promises: the run is the Rust type's, unchanged (the in-process world, paced on the real
//! clock, the same metrics); its events cross as the JSON lines `ayllu sim serve` prints. Waiting
//! and stepping release the GIL (other Python threads run, a robot's among them), and the wait
//! for the robots returns to Python every 20 ms so Ctrl-C interrupts it; `stop` may be called
//! from any thread, also while another one steps. Refusals: a scenario out of bounds, URLs that
//! do not fit the team, too many robots raise `ayllu.InvalidError` (a `ValueError`); a URL the
//! runtime refuses `ayllu.InvalidError`, a socket the system refuses `ayllu.NetworkError`.

use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

use ayllu_sim::scenario::Scenario;
use ayllu_sim::served_world::{self as served, ServeConfig, ServeError, Stopper};
use pyo3::prelude::*;

use crate::errors;
use crate::wiring;

/// Register the class on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<ServedWorld>()
}

fn serve_error(e: ServeError) -> PyErr {
    match e {
        ServeError::Runtime(e) => errors::runtime(e),
        other => errors::InvalidError::new_err(other.to_string()),
    }
}

/// A world served to robots whose controllers run elsewhere (see the module docs).
#[pyclass(frozen, module = "ayllu._native")]
pub struct ServedWorld {
    world: Mutex<served::ServedWorld>,
    stopper: Stopper,
    wait: Duration,
}

impl ServedWorld {
    fn world(&self) -> MutexGuard<'_, served::ServedWorld> {
        // A panic while stepping leaves the world as it was between two ticks at worst.
        self.world.lock().unwrap_or_else(|e| e.into_inner())
    }
}

fn seconds(s: f64, what: &str) -> PyResult<Duration> {
    Duration::try_from_secs_f64(s)
        .map_err(|_| errors::value_error(format!("{what} must be a non-negative number of seconds, got {s}")))
}

#[pymethods]
impl ServedWorld {
    /// Open the bodies on `urls` (one per robot, or one with `{i}` for the robot's number) for
    /// `scenario` (its serde JSON), and build the world.
    #[new]
    #[pyo3(signature = (scenario, urls, *, until_stopped = false, wait = 10.0, status_every = 1.0))]
    fn new(
        py: Python<'_>,
        scenario: &str,
        urls: Vec<String>,
        until_stopped: bool,
        wait: f64,
        status_every: f64,
    ) -> PyResult<ServedWorld> {
        let scenario: Scenario =
            serde_json::from_str(scenario).map_err(|e| errors::value_error(format!("not a scenario: {e}")))?;
        let mut config = ServeConfig::new(scenario, urls);
        config.until_stopped = until_stopped;
        config.wait = seconds(wait, "wait")?;
        config.status_every = seconds(status_every, "status_every")?;
        let wait = config.wait;
        let world = py.detach(|| served::ServedWorld::open(config)).map_err(serve_error)?;
        Ok(ServedWorld { stopper: world.stopper(), world: Mutex::new(world), wait })
    }

    /// Where each body's node listens (`ip:port`).
    fn body_addresses(&self) -> Vec<Option<String>> {
        self.world().body_addresses()
    }

    /// Whether each body hears its controller now.
    fn linked(&self) -> Vec<bool> {
        self.world().linked()
    }

    /// Wait for the robots (at most `wait` seconds, or until stopped), start the clock; the
    /// start line's JSON.
    fn start(&self, py: Python<'_>) -> PyResult<String> {
        let since = std::time::Instant::now();
        loop {
            let ready = py.detach(|| {
                let mut w = self.world();
                w.started().is_some() || w.poll() || w.stopped()
            });
            if ready || since.elapsed() >= self.wait {
                break;
            }
            py.check_signals()?;
            py.detach(|| std::thread::sleep(Duration::from_millis(20)));
        }
        let start = py.detach(|| self.world().start());
        wiring::json(&start)
    }

    /// One tick, paced on the real clock; its kill and status lines' JSON (none once done).
    fn step(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        let events = py.detach(|| self.world().step()).map_err(serve_error)?;
        events.iter().map(wiring::json).collect()
    }

    /// Whether the run is over (its duration served, or stopped).
    #[getter]
    fn done(&self) -> bool {
        self.world().done()
    }

    /// World seconds served so far.
    #[getter]
    fn now(&self) -> f64 {
        self.world().now()
    }

    /// End the run (stopping it if needed); the done line's JSON, with the metrics.
    fn finish(&self, py: Python<'_>) -> PyResult<String> {
        let done = py.detach(|| self.world().finish());
        wiring::json(&done)
    }

    /// Ask the world to stop (any thread): no further tick runs.
    fn stop(&self) {
        self.stopper.stop();
    }
}
