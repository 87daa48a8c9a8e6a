//! The controllers compared on the task, each built from behaviors and connections on the
//! robot's own node, on top of the same body, safe-velocity and wander behaviors:
//!
//! * `Ble` — the paper's Fig. 2 (errata fixed, docs/semantics.md): observers OBS1..OBSm in a
//!   subsumption chain over WANDER, each layer cross-inhibited across robots with BLE.
//! * `Local` — the same chain without BLE: each robot follows the highest-priority target it
//!   sees; no communication.
//! * `Random` — wander only.
//! * `ForceField` — A-CMOMMT style (Parker): a FORCE behavior turns the robot along the sum of
//!   attractions to the targets it sees, weighted by priority and reduced (x0.2) for targets a
//!   peer sees from closer (peers broadcast apparent heights into Max ports), plus repulsion
//!   from close sonar echoes.
//! * `Centralized` — the omniscient upper bound: the harness assigns robots to targets from the
//!   true world state and writes each robot the exact bearing of its target, seen or not.
//!
//! Each build returns a [`Brain`]: how the harness reads which target drives the robot (for
//! switch counting and the replay) and, for `Centralized`, where the oracle writes.

use std::f64::consts::TAU;

use ayllu::stdlib::{
    make_observer, make_observer_layer, observer_class_with, random_wander_class, safe_velocity_class, Eligibility,
    SafeVelocity, BASE, OVERRIDE_PERIOD, SONAR, VEL, VISION, VISION_LIFESPAN, WANDER,
};
use ayllu_core::{
    BehaviorClass, BleConfig, ConnectOptions, ConnectionKind, Duration, Endpoint, Error, NodeCore, PortRef, PortSpec,
    Value,
};
use serde::{Deserialize, Serialize};

/// The BLE (and force-field) broadcast group.
pub const GROUP: &str = "Peers";

/// The controllers compared on CMOMMT (docs/cmommt.md, "The controllers").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Controller {
    /// The paper's Fig. 2: observer layers OBS1..OBSm over WANDER, each cross-inhibited across
    /// robots by BLE (with the fixes of docs/cmommt.md, "What we changed from Fig. 2").
    Ble,
    /// `WANDER` and `VEL` only, no observers, no communication: the floor.
    Random,
    /// The observer chain without BLE: each robot follows the best target it sees, no talking.
    Local,
    /// A-CMOMMT style (Parker): turns along priority-weighted attractions to the targets it sees
    /// (cut to 0.2 for a target a peer reports seeing from closer) plus repulsion from sonar
    /// echoes under 0.8 m.
    ForceField,
    /// An omniscient planner assigning targets from the world's ground truth every second and
    /// steering each robot to the exact bearing of its target: the upper bound.
    Centralized,
}

impl Controller {
    /// Every controller, in the tables' order.
    pub const ALL: [Controller; 5] =
        [Controller::Ble, Controller::Random, Controller::Local, Controller::ForceField, Controller::Centralized];

    /// The name used in tables, reports and files ("BLE", "ForceField", ...).
    pub fn name(self) -> &'static str {
        match self {
            Controller::Ble => "BLE",
            Controller::Random => "Random",
            Controller::Local => "Local",
            Controller::ForceField => "ForceField",
            Controller::Centralized => "Centralized",
        }
    }

    /// Case-insensitive, by [`Controller::name`].
    pub fn parse(s: &str) -> Option<Controller> {
        Controller::ALL.into_iter().find(|c| c.name().eq_ignore_ascii_case(s))
    }
}

/// Tunables of the controllers that the paper leaves open.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControllerConfig {
    /// BLE claims per second (the paper: 1).
    pub claim_hz: f64,
    /// Seed of the wander behaviors (mixed with each node id).
    pub wander_seed: u64,
    /// How BLE observers offer their eligibility (the paper: every 20 Hz activation).
    #[serde(default = "paper_eligibility")]
    pub eligibility: Eligibility,
}

fn paper_eligibility() -> Eligibility {
    Eligibility::EveryActivation
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig { claim_hz: 1.0, wander_seed: 1, eligibility: Eligibility::EveryActivation }
    }
}

/// How the harness reads a robot's controller.
pub enum Brain {
    /// Observer chain: `OBS{n}.Rotate` for n = 1..=m; the highest layer that wrote within the
    /// override period drives.
    Chain(Vec<PortRef>),
    /// A behavior's `Drive` port holds the target id driving (0 none).
    Drive(PortRef),
    /// Centralized: the oracle writes `ORACLE.Angle`/`Assigned`; `Drive` mirrors `Assigned`.
    Oracle {
        /// `ORACLE.Angle`: bearing (rad, right-positive) of the assigned target, written by the
        /// harness every tick while the robot has an assignment.
        angle: PortRef,
        /// `ORACLE.Assigned`: the assigned target's id (1-based; 0: none).
        assigned: PortRef,
    },
    /// Wander only.
    Wander,
}

impl Brain {
    /// The target id driving the robot now (0: none).
    pub fn drive(&self, core: &NodeCore) -> u32 {
        match self {
            Brain::Chain(layers) => {
                let now = core.now();
                for (n, p) in layers.iter().enumerate() {
                    if let Ok(Some(t)) = core.last_accepted(*p) {
                        if now < t + OVERRIDE_PERIOD {
                            return n as u32 + 1;
                        }
                    }
                }
                0
            }
            Brain::Drive(p) => core.read(*p).ok().and_then(|v| v.as_int()).unwrap_or(0) as u32,
            Brain::Oracle { assigned, angle } => {
                if core.fresh(*angle).unwrap_or(false) {
                    core.read(*assigned).ok().and_then(|v| v.as_int()).unwrap_or(0) as u32
                } else {
                    0
                }
            }
            Brain::Wander => 0,
        }
    }
}

fn local(node: &mut NodeCore, from: (&str, &str), to: (&str, &str), kind: ConnectionKind) -> Result<(), Error> {
    node.connect(&Endpoint::local(from.0, from.1), &Endpoint::local(to.0, to.1), kind, ConnectOptions::default())
        .map(|_| ())
}

/// Build `controller` on `node`, whose body (VISION, SONAR, BASE) already exists, for targets
/// with `priorities` (target n = index n-1, decreasing priority).
pub fn build(
    node: &mut NodeCore,
    controller: Controller,
    priorities: &[f64],
    cfg: &ControllerConfig,
) -> Result<Brain, Error> {
    let m = priorities.len() as u32;
    node.define(safe_velocity_class(SafeVelocity::default())?)?;
    node.define(random_wander_class(10.0, cfg.wander_seed)?)?;
    node.create("SafeVelocity", VEL)?;
    node.create("RandomWander", WANDER)?;
    local(node, (SONAR, "Ranges"), (VEL, "Ranges"), ConnectionKind::Normal)?;
    local(node, (VEL, "Translate"), (BASE, "Translate"), ConnectionKind::Normal)?;
    local(node, (WANDER, "Rotate"), (BASE, "Rotate"), ConnectionKind::Normal)?;
    match controller {
        Controller::Random => Ok(Brain::Wander),
        Controller::Ble | Controller::Local => {
            node.define(observer_class_with(cfg.eligibility)?)?;
            let ble = BleConfig::new(GROUP, "Rotate", cfg.claim_hz)?;
            // Lowest layer first, so that each layer's `next` exists when it is made.
            for num in (1..=m).rev() {
                let next = if num == m { WANDER.to_owned() } else { format!("OBS{}", num + 1) };
                if controller == Controller::Ble {
                    make_observer(node, num, &next, &ble)?;
                } else {
                    make_observer_layer(node, num, &next)?;
                }
            }
            let layers = (1..=m).map(|n| node.port(&format!("OBS{n}"), "Rotate")).collect::<Result<_, _>>()?;
            Ok(Brain::Chain(layers))
        }
        Controller::ForceField => {
            node.define(force_class(priorities)?)?;
            node.create("Force", "FORCE")?;
            for n in 1..=m {
                local(
                    node,
                    (VISION, &format!("Target{n}Angle")),
                    ("FORCE", &format!("T{n}Angle")),
                    ConnectionKind::Normal,
                )?;
                local(
                    node,
                    (VISION, &format!("Target{n}Bottom")),
                    ("FORCE", &format!("T{n}Bottom")),
                    ConnectionKind::Normal,
                )?;
                node.connect(
                    &Endpoint::local("FORCE", &format!("Seen{n}")),
                    &Endpoint::group(GROUP, "FORCE", &format!("Taken{n}")),
                    ConnectionKind::Normal,
                    ConnectOptions::default(),
                )?;
            }
            node.join(GROUP);
            local(node, (SONAR, "Ranges"), ("FORCE", "Ranges"), ConnectionKind::Normal)?;
            local(node, ("FORCE", "Rotate"), (WANDER, "Rotate"), ConnectionKind::OverrideOut(OVERRIDE_PERIOD))?;
            Ok(Brain::Drive(node.port("FORCE", "Drive")?))
        }
        Controller::Centralized => {
            node.define(oracle_class()?)?;
            node.create("Oracle", "ORACLE")?;
            local(node, ("ORACLE", "Rotate"), (WANDER, "Rotate"), ConnectionKind::OverrideOut(OVERRIDE_PERIOD))?;
            Ok(Brain::Oracle { angle: node.port("ORACLE", "Angle")?, assigned: node.port("ORACLE", "Assigned")? })
        }
    }
}

/// How long a peer's "I see target n from this close" counts for the force field.
const TAKEN_WINDOW: Duration = Duration::from_secs(1);
/// Weight kept for a target a peer sees from closer (Parker's reduced weight).
const SHARED_WEIGHT: f64 = 0.2;
/// Sonar echoes closer than this (m) push the robot away.
const REPULSION_RANGE: f64 = 0.8;

/// `Force`: the A-CMOMMT-style local force field (see the module docs).
fn force_class(priorities: &[f64]) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Force");
    let mut inputs = Vec::new();
    for n in 1..=priorities.len() {
        let a = c.port(PortSpec::new(&format!("T{n}Angle"), 0.0).lifespan(VISION_LIFESPAN))?;
        let h = c.port(PortSpec::new(&format!("T{n}Bottom"), 0.0).lifespan(VISION_LIFESPAN))?;
        let taken = c.port(PortSpec::new(&format!("Taken{n}"), 0.0).max().window(TAKEN_WINDOW))?;
        let seen = c.port(PortSpec::new(&format!("Seen{n}"), 0.0))?;
        inputs.push((a, h, taken, seen, priorities[n - 1]));
    }
    let ranges = c.port(PortSpec::new("Ranges", Vec::<f64>::new()).lifespan(VISION_LIFESPAN))?;
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    let drive = c.port(PortSpec::new("Drive", 0i64))?;
    let ticks = c.slot("Ticks", 0i64)?;
    c.every_hz("Field", 20.0, move |ctx| {
        let tick = ctx.slot(ticks).as_int().unwrap_or(0);
        let _ = ctx.set_slot(ticks, tick + 1);
        // Broadcast what we see twice a second: enough for a 1 s window, cheap on the radio.
        let announce = tick % 10 == 0;
        let (mut fx, mut fy, mut best, mut best_w, mut total) = (0.0, 0.0, 0i64, 0.0, 0.0);
        for (n, &(a, h, taken, seen, prio)) in inputs.iter().enumerate() {
            let (Some(angle), Some(height)) = (ctx.float(a), ctx.float(h)) else { continue };
            if announce {
                let _ = ctx.write(seen, height);
            }
            let closer_peer = ctx.float(taken).is_some_and(|t| t > height);
            let w = if closer_peer { prio * SHARED_WEIGHT } else { prio };
            // Angles are right-positive; the force is in the robot frame, x ahead, y right.
            fx += w * angle.cos();
            fy += w * angle.sin();
            total += w;
            if w > best_w {
                best_w = w;
                best = n as i64 + 1;
            }
        }
        if total == 0.0 {
            let _ = ctx.write(drive, 0i64);
            return; // nothing seen: no output, WANDER drives
        }
        if let Some(Value::Vector(r)) = ctx.get(ranges) {
            let step = TAU / r.len() as f64;
            for (k, d) in r.iter().enumerate() {
                if *d < REPULSION_RANGE {
                    // Beam k points k*step counter-clockwise = -k*step right-positive.
                    let push = total * (REPULSION_RANGE - d) / REPULSION_RANGE;
                    let beam = -(k as f64) * step;
                    fx -= push * beam.cos();
                    fy -= push * beam.sin();
                }
            }
        }
        let heading = fy.atan2(fx);
        let _ = ctx.write(rotate, -heading);
        let _ = ctx.write(drive, best);
    })?;
    Ok(c)
}

/// `Oracle`: turns towards the bearing the central planner writes to `Angle` (right-positive),
/// while it is fresh.
fn oracle_class() -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Oracle");
    let angle = c.port(PortSpec::new("Angle", 0.0).lifespan(VISION_LIFESPAN))?;
    c.port(PortSpec::new("Assigned", 0i64))?;
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    c.every_hz("Steer", 20.0, move |ctx| {
        if let Some(a) = ctx.float(angle) {
            let _ = ctx.write(rotate, -a);
        }
    })?;
    Ok(c)
}
