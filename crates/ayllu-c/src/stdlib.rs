//! The standard behaviors (the paper's `ayllustd.h`, from `ayllu::stdlib`) and the
//! simulator's robot body, for C: safe velocity, wander, the Fig. 2 observer, and the body of
//! a robot in a world served by `ayllu sim serve` (in place of `ayInitPioControl`).

use std::ffi::c_char;

use ayllu::stdlib::{self, SafeVelocity, BASE, SONAR, VISION};
use ayllu_core::{BleConfig, ConnectOptions, ConnectionKind, Endpoint, NodeCore};

use crate::cstr::text;
use crate::node::{ay_node, with_node};
use crate::status::{ay_status, boundary, Fail};

fn exists(core: &NodeCore, behavior: &str) -> bool {
    core.behavior_ref(behavior).is_ok()
}

fn wire(core: &mut NodeCore, from: (&str, &str), to: (&str, &str)) -> Result<(), Fail> {
    core.connect(
        &Endpoint::local(from.0, from.1),
        &Endpoint::local(to.0, to.1),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )?;
    Ok(())
}

/// `MakeSafeVelBeh(name)`: create behavior `name` of class `SafeVelocity` (defined on first
/// use: 10 Hz, 0.4 m/s with a clear way, stopping 0.3 m from what is ahead, stopping when its
/// sonar is stale), wired `SONAR.Ranges -> name.Ranges` and `name.Translate ->
/// BASE.Translate` when the body's SONAR and BASE exist.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (empty or taken name).
///
/// Ownership: borrows the names for the call (they are copied).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `name` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_std_safe_velocity(node: *mut ay_node, name: *const c_char) -> ay_status {
    boundary("ay_std_safe_velocity", || {
        // SAFETY: the C caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        with_node(node, |s| {
            let core = s.node.core_mut();
            if !core.has_class("SafeVelocity") {
                core.define(stdlib::safe_velocity_class(SafeVelocity::default())?)?;
            }
            core.create("SafeVelocity", name)?;
            if exists(core, SONAR) {
                wire(core, (SONAR, "Ranges"), (name, "Ranges"))?;
            }
            if exists(core, BASE) {
                wire(core, (name, "Translate"), (BASE, "Translate"))?;
            }
            Ok(())
        })
    })
}

/// `MakeWanderBeh(name)`: create behavior `name` of class `RandomWander` (defined on first use
/// with `seed`: at 10 Hz a turn rate of 0.15 to 0.6 rad/s either way, changing every 1 to 4 s;
/// the same seed and node id give the same walk), wired `name.Rotate -> BASE.Rotate` when the
/// body's BASE exists. The Rust controllers' wander, so a C team and a Rust team differ only
/// in their language.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (empty or taken name).
///
/// Ownership: borrows the names for the call (they are copied).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `name` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_std_wander(node: *mut ay_node, name: *const c_char, seed: u64) -> ay_status {
    boundary("ay_std_wander", || {
        // SAFETY: the C caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        with_node(node, |s| {
            let core = s.node.core_mut();
            if !core.has_class("RandomWander") {
                core.define(stdlib::random_wander_class(10.0, seed)?)?;
            }
            core.create("RandomWander", name)?;
            if exists(core, BASE) {
                wire(core, (name, "Rotate"), (BASE, "Rotate"))?;
            }
            Ok(())
        })
    })
}

/// The standard library's Fig. 2 observer as one call (`ayllu::stdlib::make_observer`):
/// create `OBS{num}` of class `Observer` (defined on first use), fed from
/// `VISION.Target{num}Angle/Bottom`, overriding `next.Rotate` for 0.2 s (subsumption), and —
/// unless `group` is NULL — a BLE peer of `group` claiming at `claim_hz` with the
/// recommended inhibit period. The C example writes the same observer with the macros.
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL` (node, next), `AY_ERR_HANDLE`,
/// `AY_ERR_BUSY`, `AY_ERR_UNKNOWN` (no VISION or `next`), `AY_ERR_RATE`, `AY_ERR_INVALID`.
///
/// Ownership: borrows the names for the call (they are copied).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `next` and `group` are NULL or
/// NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_std_observer(
    node: *mut ay_node,
    num: u32,
    next: *const c_char,
    group: *const c_char,
    claim_hz: f64,
) -> ay_status {
    boundary("ay_std_observer", || {
        // SAFETY: the C caller's promise on `next`.
        let next = unsafe { text(next, "next") }?;
        let group = if group.is_null() {
            None
        } else {
            // SAFETY: the C caller's promise on `group`.
            Some(unsafe { text(group, "group") }?)
        };
        if num == 0 {
            return Err(Fail::invalid("targets are numbered from 1"));
        }
        with_node(node, |s| {
            let core = s.node.core_mut();
            if !exists(core, VISION) {
                return Err(Fail::new(
                    ay_status::AY_ERR_UNKNOWN,
                    "no VISION behavior on this node (install a body first)",
                ));
            }
            if !core.has_class("Observer") {
                core.define(stdlib::observer_class()?)?;
            }
            match group {
                Some(g) => {
                    stdlib::make_observer(core, num, next, &BleConfig::new(g, "Rotate", claim_hz)?).map(|_| ())?
                }
                None => stdlib::make_observer_layer(core, num, next).map(|_| ())?,
            }
            Ok(())
        })
    })
}

/// The simulator's robot body in place of the paper's `ayInitPioControl`: on the node of
/// robot K (its id must be K, 1 to 999), create VISION (`Target{n}Angle`, `Target{n}Bottom`
/// for n = 1..`targets`), SONAR (`Ranges`) and BASE (`Rotate`, `Translate`), and send BASE to
/// the body the server `ayllu sim serve` runs for robot K (node 1000+K). The server feeds
/// VISION and SONAR once its body hears this node (its `--udp` URL names this node's address).
///
/// It also creates `LINK` and attaches its driver (`ayllu_sim::served_robot::attach`), so the
/// robot reports to the server what its metrics need with no code of the program's: every
/// turn of the node, `LINK.Drive` (the target driving it, read from the observer layers
/// `OBS1`..`OBS{targets}` by name, as `MakeObserver` names them) when it changes, and four
/// times a second `LINK.Sent` and `LINK.Bytes` (the messages the node sent to anyone but its
/// body during its turns, and their encoded size). The server's word is the program's to
/// act on: `LINK.Alive` (int) turns 0 when the scenario kills the robot
/// (`ay_node_read_int(node, "LINK", "Alive", &alive)`).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (a node id that is no robot number, `targets` 0 or above 64, a body
/// already installed).
///
/// Ownership: borrows the names for the call (they are copied).
///
/// # Safety
/// `node` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_sim_body(node: *mut ay_node, targets: u32) -> ay_status {
    boundary("ay_sim_body", || {
        if targets == 0 || targets > 64 {
            return Err(Fail::invalid(format!("targets must be 1 to 64, got {targets}")));
        }
        with_node(node, |s| install_sim_body(&mut s.node, targets as usize))
    })
}

#[cfg(feature = "sim")]
fn install_sim_body(node: &mut ayllu::Node, targets: usize) -> Result<(), Fail> {
    Ok(ayllu_sim::served_robot::attach(node, targets)?)
}

/// Without the simulator the call exists (the header and a program are the same in both
/// builds) and says how to get it.
#[cfg(not(feature = "sim"))]
fn install_sim_body(_node: &mut ayllu::Node, _targets: usize) -> Result<(), Fail> {
    Err(Fail::invalid(
        "libayllu was built without the simulator's robot body: build it with the `sim` feature (the default)",
    ))
}
