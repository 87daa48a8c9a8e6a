//! Serving a world from C: an [`ay_served_world`] is `ayllu_sim::served_world::ServedWorld`,
//! the server of the simulator's distributed mode (what `ayllu sim serve` runs), so a C program
//! hosts the world and its robots' bodies while their controllers run elsewhere (C programs
//! with `ay_sim_body`, `ayllu sim robot` processes, Python nodes). The run is the Rust type's,
//! unchanged: the in-process world paced on the real clock, the same kills, radio reachability
//! and metrics; its events cross as the JSON lines `ayllu sim serve` prints.
//!
//! With the cargo feature `sim` (the default). Without it the functions exist (the header and
//! a program are the same in both builds) and `ay_served_world_open` says how to get them.
//!
//! Thread-safety: a world is driven by one thread at a time (a second thread's call waits for
//! the first's), except `ay_served_world_stop`, which any thread may call at any time, also
//! while another thread is inside `ay_served_world_run`.

use std::ffi::c_char;

use crate::cstr::{owned, put, slice, text};
use crate::registry::{self, Kind};
use crate::status::{ay_status, boundary, Fail};

/// What to serve (`ay_served_world_open`). Zero-initialize it and set what you need.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct ay_serve_config {
    /// A scenario file (TOML, docs/cmommt.md, "Studies as files"): its world, team, seed,
    /// duration, kills and radio. NULL: a sized world of `robots` robots and `targets` targets
    /// from `seed` (`ayllu sim serve --robots --targets --seed`).
    pub scenario: *const c_char,
    /// Robots of a sized world (1 to 999); 0 with a scenario file.
    pub robots: u32,
    /// Targets of a sized world (1 to 64); 0 with a scenario file.
    pub targets: u32,
    /// The sized world's seed.
    pub seed: u64,
    /// World seconds to serve; 0: the scenario's (300 for a sized world).
    pub duration: f64,
    /// Serve until `ay_served_world_stop` rather than for the duration.
    pub until_stopped: bool,
    /// The bodies' URLs: `urls_len` of them, one per robot, or one for all in which `{i}` stands
    /// for the robot's number (one URL without `{i}` for several bodies must bind port 0).
    pub urls: *const *const c_char,
    /// How many URLs `urls` holds.
    pub urls_len: usize,
    /// Seconds `ay_served_world_start` waits for every body to hear its controller; 0: 10.
    pub wait: f64,
    /// World seconds between status lines; 0: 1.
    pub status_every: f64,
}

/// A world served to robots whose controllers run elsewhere (opaque; module docs).
#[allow(non_camel_case_types)]
pub struct ay_served_world {
    #[cfg(feature = "sim")]
    world: std::sync::Mutex<ayllu_sim::served_world::ServedWorld>,
    #[cfg(feature = "sim")]
    stopper: ayllu_sim::served_world::Stopper,
}

fn handle<'a>(p: *mut ay_served_world) -> Result<&'a ay_served_world, Fail> {
    registry::check(p, Kind::ServedWorld, "world")?;
    // SAFETY: registered pointers come from Box::into_raw in `ay_served_world_open` and are
    // unregistered before they are freed; only a shared reference is made (the world is
    // behind a mutex).
    Ok(unsafe { &*p })
}

/// Open the bodies (their sockets are bound now) and build the world that `config` describes.
/// Nothing runs until `ay_served_world_poll`, `_start` or `_run`.
///
/// Ownership: borrows `config` and its strings for the call; `*out` belongs to the caller:
/// free it with `ay_served_world_free`. Thread-safety: any thread. Errors: `AY_ERR_NULL`
/// (config, out, urls, a URL), `AY_ERR_INVALID` (a scenario file that cannot be read or is out
/// of bounds, a sized world out of bounds, more than 999 robots, URLs that do not fit the team,
/// a library built without `sim`), `AY_ERR_PERIOD` (duration, wait or status_every negative or
/// not finite), `AY_ERR_TRANSPORT` (a URL that does not parse, a socket the system refused).
///
/// # Safety
/// `config` is NULL or valid, its strings NULL or NUL-terminated, `urls` NULL or valid for
/// `urls_len` pointers; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_open(
    config: *const ay_serve_config,
    out: *mut *mut ay_served_world,
) -> ay_status {
    boundary("ay_served_world_open", || {
        if config.is_null() {
            return Err(Fail::null("config"));
        }
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        // SAFETY: non-null, and the C caller's promise.
        let c = unsafe { *config };
        // SAFETY: the C caller's promise on `urls` and `urls_len`.
        let pointers = unsafe { slice(c.urls, c.urls_len, "urls") }?;
        let urls = pointers
            .iter()
            // SAFETY: the C caller's promise on each URL.
            .map(|&u| unsafe { text(u, "a URL") }.map(str::to_owned))
            .collect::<Result<Vec<_>, _>>()?;
        let scenario = if c.scenario.is_null() {
            None
        } else {
            // SAFETY: the C caller's promise on `scenario`.
            Some(unsafe { text(c.scenario, "scenario") }?)
        };
        for (value, what) in [(c.duration, "duration"), (c.wait, "wait"), (c.status_every, "status_every")] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(Fail::new(
                    ay_status::AY_ERR_PERIOD,
                    format!("{what} must be 0 (the default) or a positive number of seconds, got {value}"),
                ));
            }
        }
        let h = Box::into_raw(Box::new(imp::open(&c, scenario, urls)?));
        registry::add(h, Kind::ServedWorld);
        // SAFETY: checked non-null; the C caller's promise that it is valid for a write.
        unsafe { out.write(h) };
        Ok(())
    })
}

/// Before the start: step every body's node once (greetings go out, replies come in) and store
/// in `*linked` (if not NULL) whether every body hears its controller now. Lets a program that
/// also steps its robots' nodes on this thread wait for them (`ay_served_world_start` waits
/// without stepping anything else).
///
/// Thread-safety: module docs. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`.
///
/// # Safety
/// `world` is NULL or a pointer from this library; `linked` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_poll(world: *mut ay_served_world, linked: *mut bool) -> ay_status {
    boundary("ay_served_world_poll", || {
        let all = imp::poll(handle(world)?)?;
        if !linked.is_null() {
            // SAFETY: non-null, and the C caller's promise.
            unsafe { put(linked, all, "linked") }?;
        }
        Ok(())
    })
}

/// Wait until every body hears its controller, `wait` seconds have passed since the first poll,
/// or the world is stopped; then start its clock. `*start` (if not NULL) gets the start line's
/// JSON (`{"start":true,"waited":..,"missing":[..],...}`). Called again, gives the same line.
///
/// Ownership: `*start` belongs to the caller: free it with `ay_string_free`. Thread-safety:
/// module docs. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`.
///
/// # Safety
/// `world` is NULL or a pointer from this library; `start` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_start(world: *mut ay_served_world, start: *mut *mut c_char) -> ay_status {
    boundary("ay_served_world_start", || {
        let line = imp::start(handle(world)?)?;
        if !start.is_null() {
            // SAFETY: non-null, and the C caller's promise.
            unsafe { put(start, owned(line), "start") }?;
        }
        Ok(())
    })
}

/// Serve `seconds` of world time (at least one 50 ms tick), or to the end if `seconds` is 0,
/// paced on the real clock (the call sleeps between ticks); starts the world first if
/// `ay_served_world_start` was not called. `*events` (if not NULL) gets a JSON array of the
/// kill and status lines of that stretch. Once the run is done, serves nothing (`[]`).
///
/// Ownership: `*events` belongs to the caller: free it with `ay_string_free`. Thread-safety:
/// module docs. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_PERIOD` (seconds negative or not
/// finite), `AY_ERR_TRANSPORT` or another code for a port a body could not write (the run is
/// then stopped where it was).
///
/// # Safety
/// `world` is NULL or a pointer from this library; `events` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_run(
    world: *mut ay_served_world,
    seconds: f64,
    events: *mut *mut c_char,
) -> ay_status {
    boundary("ay_served_world_run", || {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(Fail::new(ay_status::AY_ERR_PERIOD, format!("seconds must be 0 or positive, got {seconds}")));
        }
        let lines = imp::run(handle(world)?, seconds)?;
        if !events.is_null() {
            // SAFETY: non-null, and the C caller's promise.
            unsafe { put(events, owned(lines), "events") }?;
        }
        Ok(())
    })
}

/// Whether the run is over (its duration served, or stopped) into `*done`.
///
/// Thread-safety: module docs. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`.
///
/// # Safety
/// `world` is NULL or a pointer from this library; `done` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_done(world: *mut ay_served_world, done: *mut bool) -> ay_status {
    boundary("ay_served_world_done", || {
        let d = imp::done(handle(world)?)?;
        // SAFETY: the C caller's promise on `done` (NULL is refused).
        unsafe { put(done, d, "done") }
    })
}

/// Ask the world to stop: a wait ends, no further tick runs, the done line says `"stopped":true`.
///
/// Thread-safety: any thread, any time, also while another thread is in `ay_served_world_run`
/// (not while the world is being freed). Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`.
///
/// # Safety
/// `world` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_stop(world: *mut ay_served_world) -> ay_status {
    boundary("ay_served_world_stop", || imp::stop(handle(world)?))
}

/// End the run (stopping it if it is not done) and compute its metrics: `*done` (if not NULL)
/// gets the done line's JSON (`{"done":true,"t":..,"stopped":..,"resyncs":..,"metrics":{..},
/// "radio":{..}}`). Called again, gives the same line.
///
/// Ownership: `*done` belongs to the caller: free it with `ay_string_free`. Thread-safety:
/// module docs. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`.
///
/// # Safety
/// `world` is NULL or a pointer from this library; `done` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_finish(world: *mut ay_served_world, done: *mut *mut c_char) -> ay_status {
    boundary("ay_served_world_finish", || {
        let line = imp::finish(handle(world)?)?;
        if !done.is_null() {
            // SAFETY: non-null, and the C caller's promise.
            unsafe { put(done, owned(line), "done") }?;
        }
        Ok(())
    })
}

/// Close a served world: its bodies' sockets go (their robots see their bodies go silent).
///
/// Ownership: takes the world; the handle is invalid afterwards, and later calls with it return
/// `AY_ERR_HANDLE`. Thread-safety: not while another thread uses it. Errors: `AY_ERR_NULL`,
/// `AY_ERR_HANDLE` (freed already).
///
/// # Safety
/// `world` is NULL or a pointer from this library (checked against the live handles).
#[no_mangle]
pub unsafe extern "C" fn ay_served_world_free(world: *mut ay_served_world) -> ay_status {
    boundary("ay_served_world_free", || {
        registry::remove(world, Kind::ServedWorld, "world")?;
        // SAFETY: came from Box::into_raw in `ay_served_world_open` and was just unregistered.
        drop(unsafe { Box::from_raw(world) });
        Ok(())
    })
}

#[cfg(feature = "sim")]
mod imp {
    use std::sync::MutexGuard;
    use std::time::Duration;

    use ayllu_sim::controller::Controller;
    use ayllu_sim::scenario::Scenario;
    use ayllu_sim::served_world::{ServeConfig, ServeError, ServedWorld};

    use super::{ay_serve_config, ay_served_world};
    use crate::status::{ay_status, Fail};

    fn fail(e: ServeError) -> Fail {
        match e {
            ServeError::Runtime(e) => e.into(),
            other => Fail::invalid(other.to_string()),
        }
    }

    fn json(line: serde_json::Result<String>) -> Result<String, Fail> {
        line.map_err(|e| Fail::new(ay_status::AY_ERR_PANIC, format!("a line as JSON: {e}")))
    }

    fn world(h: &ay_served_world) -> MutexGuard<'_, ServedWorld> {
        h.world.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(super) fn open(
        c: &ay_serve_config,
        scenario: Option<&str>,
        urls: Vec<String>,
    ) -> Result<ay_served_world, Fail> {
        let mut scenario = match scenario {
            Some(path) => {
                if c.robots != 0 || c.targets != 0 {
                    return Err(Fail::invalid("robots and targets must be 0 with a scenario file (the file says)"));
                }
                let text = std::fs::read_to_string(path).map_err(|e| Fail::invalid(format!("reading {path}: {e}")))?;
                ayllu_sim::scenario_file::scenario(&text).map_err(|e| Fail::invalid(format!("{path}: {e}")))?
            }
            None => {
                if !(1..=64).contains(&c.targets) {
                    return Err(Fail::invalid(format!("targets must be 1 to 64, got {}", c.targets)));
                }
                Scenario::sized(Controller::Random, c.robots as usize, c.targets as usize, c.seed).duration(300.0)
            }
        };
        if c.duration > 0.0 {
            scenario.duration = c.duration;
        }
        let mut config = ServeConfig::new(scenario, urls);
        config.until_stopped = c.until_stopped;
        if c.wait > 0.0 {
            config.wait = Duration::from_secs_f64(c.wait);
        }
        if c.status_every > 0.0 {
            config.status_every = Duration::from_secs_f64(c.status_every);
        }
        let world = ServedWorld::open(config).map_err(fail)?;
        Ok(ay_served_world { stopper: world.stopper(), world: std::sync::Mutex::new(world) })
    }

    pub(super) fn poll(h: &ay_served_world) -> Result<bool, Fail> {
        let mut w = world(h);
        Ok(w.started().is_some() || w.poll())
    }

    pub(super) fn start(h: &ay_served_world) -> Result<String, Fail> {
        json(serde_json::to_string(&world(h).start()))
    }

    pub(super) fn run(h: &ay_served_world, seconds: f64) -> Result<String, Fail> {
        let mut w = world(h);
        let end = if seconds > 0.0 { w.now() + seconds } else { f64::INFINITY };
        let mut events = Vec::new();
        w.start();
        loop {
            events.extend(w.step().map_err(|e| {
                w.stop();
                fail(e)
            })?);
            // Half a tick of slack: world time is a whole number of ticks.
            if w.done() || w.now() + 0.025 >= end {
                break;
            }
        }
        json(serde_json::to_string(&events))
    }

    pub(super) fn done(h: &ay_served_world) -> Result<bool, Fail> {
        Ok(world(h).done())
    }

    pub(super) fn stop(h: &ay_served_world) -> Result<(), Fail> {
        h.stopper.stop();
        Ok(())
    }

    pub(super) fn finish(h: &ay_served_world) -> Result<String, Fail> {
        json(serde_json::to_string(&world(h).finish()))
    }
}

/// Without the simulator: `open` says how to get it; no handle is ever made, so the others
/// are refused by the handle check before they get here.
#[cfg(not(feature = "sim"))]
mod imp {
    use super::{ay_serve_config, ay_served_world};
    use crate::status::Fail;

    fn missing() -> Fail {
        Fail::invalid("libayllu was built without the simulator: build it with the `sim` feature (the default)")
    }

    pub(super) fn open(_: &ay_serve_config, _: Option<&str>, _: Vec<String>) -> Result<ay_served_world, Fail> {
        Err(missing())
    }
    pub(super) fn poll(_: &ay_served_world) -> Result<bool, Fail> {
        Err(missing())
    }
    pub(super) fn start(_: &ay_served_world) -> Result<String, Fail> {
        Err(missing())
    }
    pub(super) fn run(_: &ay_served_world, _: f64) -> Result<String, Fail> {
        Err(missing())
    }
    pub(super) fn done(_: &ay_served_world) -> Result<bool, Fail> {
        Err(missing())
    }
    pub(super) fn stop(_: &ay_served_world) -> Result<(), Fail> {
        Err(missing())
    }
    pub(super) fn finish(_: &ay_served_world) -> Result<String, Fail> {
        Err(missing())
    }
}
