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
//! * `Planner` — the honest centralized baseline: a planner node on a base station
//!   ([`build_planner`]) assigns robots to targets from what the robots report, and the reports
//!   and assignments travel through the same radio as every other message (loss, delay, range,
//!   partitions). Each robot (a `FOLLOW` behavior) reports its pose and sightings, follows its
//!   last assignment while it is fresh, and falls back to the observer chain (as `Local`) when
//!   it is not.
//! * `BleSeek` — the BLE family without a base station, closer to the `Planner`
//!   (docs/cmommt.md, "BLE-seek"): the same observer layers and the same BLE (eligibility
//!   broadcast plus cross-inhibition, no negotiation, no central node), but eligibility is
//!   what the robot would gain (none offered for a target while a higher one holds the robot,
//!   or while a peer is more eligible; a bonus on the target it claims), a target lost from
//!   view is turned to where it was for a moment, and a robot shares where the targets it sees
//!   but nobody takes are, so that another seeks one worth leaving its own for (`SEEK`, beside
//!   the layers: it tells a layer where to turn, the layer competes as for a sight).
//! * `BleLean` — `Ble` offering its eligibility by `Eligibility::LEAN`: the study's row for
//!   the cheaper policy (docs/cmommt.md, "A cheaper BLE").
//!
//! Each build returns a [`Brain`]: how the harness reads which target drives the robot (for
//! switch counting and the replay) and, for `Centralized`, where the oracle writes.

use std::f64::consts::TAU;

use ayllu::stdlib::{
    make_observer, make_observer_layer, observer_class_with, random_wander_class, safe_velocity_class, Eligibility,
    SafeVelocity, BASE, OVERRIDE_PERIOD, SONAR, VEL, VISION, VISION_LIFESPAN, WANDER,
};
use ayllu_core::{
    BehaviorClass, BleConfig, ConnectOptions, ConnectionKind, Duration, Endpoint, Error, Instant, NodeCore, NodeId,
    Port, PortRef, PortSpec, Value,
};
use serde::{Deserialize, Serialize};

use crate::classes::SharedClasses;
use crate::world::{wrap, WorldConfig};

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
    /// A central planner on a base station that knows only what the robots report over the
    /// radio, and whose assignments reach them over the radio: the honest centralized baseline.
    Planner,
    /// The BLE family without a base station (docs/cmommt.md, "BLE-seek"): Fig. 2's observer
    /// layers and BLE, with eligibility that counts what the robot would gain by taking the
    /// target, a bonus for the claim it holds, and sightings of targets nobody claims shared
    /// with the peers, which a robot with nothing in view seeks.
    BleSeek,
    /// The paper's BLE offering its eligibility by [`Eligibility::LEAN`] (a 10 % change or
    /// every 500 ms, not at every activation), whatever `controllers.eligibility` says: the
    /// study's row that shows BLE's message cost with the lean policy beside the paper's.
    BleLean,
}

impl Controller {
    /// The study's six controllers, in the tables' order: the first six of [`Controller::EVERY`].
    pub const ALL: [Controller; 6] = {
        let mut all = [Controller::Ble; 6];
        let mut i = 0;
        while i < all.len() {
            all[i] = Controller::EVERY[i];
            i += 1;
        }
        all
    };

    /// Every controller, [`Controller::ALL`] and then the controllers added after the study's
    /// six, which the study runs only when asked (so that its tables and runs stay as they
    /// were): what names parse to and what a sweep file may list.
    pub const EVERY: [Controller; 8] = [
        Controller::Ble,
        Controller::Random,
        Controller::Local,
        Controller::ForceField,
        Controller::Centralized,
        Controller::Planner,
        Controller::BleLean,
        Controller::BleSeek,
    ];

    /// The name used in tables, reports and files ("BLE", "ForceField", ...).
    pub fn name(self) -> &'static str {
        match self {
            Controller::Ble => "BLE",
            Controller::Random => "Random",
            Controller::Local => "Local",
            Controller::ForceField => "ForceField",
            Controller::Centralized => "Centralized",
            Controller::Planner => "Planner",
            Controller::BleSeek => "BLE-seek",
            Controller::BleLean => "BLE-lean",
        }
    }

    /// Case-insensitive, by [`Controller::name`].
    pub fn parse(s: &str) -> Option<Controller> {
        Controller::EVERY.into_iter().find(|c| c.name().eq_ignore_ascii_case(s))
    }
}

/// Tunables of the controllers that the paper leaves open.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControllerConfig {
    /// BLE claims per second (the paper: 1).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub claim_hz: f64,
    /// Seed of the wander behaviors (mixed with each node id).
    pub wander_seed: u64,
    /// How BLE observers offer their eligibility (the paper: every 20 Hz activation).
    #[serde(default = "paper_eligibility")]
    pub eligibility: Eligibility,
    /// `Planner`: reports and plans per second (each robot reports, then the planner assigns,
    /// this often; an assignment older than [`GOAL_PERIODS`] periods is stale).
    #[serde(default = "plan_hz", deserialize_with = "crate::numbers::number_de")]
    pub plan_hz: f64,
    /// `Planner`: where its base station stands (m, arena frame); `None`: the arena's centre.
    #[serde(default, deserialize_with = "crate::numbers::optional_pair_de")]
    pub base_station: Option<[f64; 2]>,
}

fn paper_eligibility() -> Eligibility {
    Eligibility::EveryActivation
}

fn plan_hz() -> f64 {
    2.0
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig {
            claim_hz: 1.0,
            wander_seed: 1,
            eligibility: Eligibility::EveryActivation,
            plan_hz: plan_hz(),
            base_station: None,
        }
    }
}

/// How the harness reads a robot's controller.
#[derive(Clone, Debug)]
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
    /// `Planner`: `FOLLOW.Rotate` overrides the observer chain while the robot follows a fresh
    /// assignment, and `FOLLOW.Drive` then says which target; otherwise the chain drives.
    Follow {
        /// `FOLLOW.Pose`: the robot's pose [x, y, theta], written by the harness (localization).
        pose: PortRef,
        /// `FOLLOW.Rotate`.
        rotate: PortRef,
        /// `FOLLOW.Drive`: the assigned target's id (0: none).
        drive: PortRef,
        /// The fallback observer chain, as [`Brain::Chain`].
        chain: Vec<PortRef>,
    },
    /// `BleSeek`: the observer chain drives as in [`Brain::Chain`], a layer seeking its target
    /// from a peer's report too (so [`Brain::drive_seen`] reads every layer); the harness
    /// writes the robot's pose to `SEEK.Pose`.
    Seek {
        /// `SEEK.Pose`: the robot's pose [x, y, theta], written by the harness (localization,
        /// as the Planner's robots have it).
        pose: PortRef,
        /// The observer chain, as [`Brain::Chain`].
        chain: Vec<PortRef>,
    },
    /// Wander only.
    Wander,
}

impl Brain {
    /// The target id driving the robot now (0: none).
    pub fn drive(&self, core: &NodeCore) -> u32 {
        match self {
            Brain::Chain(layers) | Brain::Seek { chain: layers, .. } => chain_drive(core, layers),
            Brain::Follow { rotate, drive, chain, .. } => {
                let now = core.now();
                if core.last_accepted(*rotate).ok().flatten().is_some_and(|t| now < t + OVERRIDE_PERIOD) {
                    core.read(*drive).ok().and_then(|v| v.as_int()).unwrap_or(0) as u32
                } else {
                    chain_drive(core, chain)
                }
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

/// How long after its target was last written to VISION an observer layer can still drive:
/// an observer writes `Rotate` only while its `TargetX` is fresh (`VISION_LIFESPAN` after
/// the write), and its layer drives for `OVERRIDE_PERIOD` after that. Doubled, as a margin
/// that costs nothing.
pub const SEEN_WINDOW: Duration =
    Duration::from_micros(2 * (VISION_LIFESPAN.as_nanos() + OVERRIDE_PERIOD.as_nanos()) / 1000);

impl Brain {
    /// [`Brain::drive`] for a robot whose VISION ports only its body writes, `seen[n - 1]`
    /// being when it last wrote target n's ([`crate::body::Body::seen`]). Same answer: a
    /// layer's `Rotate` is accepted only when that layer's observer writes it (while its
    /// target's port is fresh) or a higher layer's (or FOLLOW's) write overrides it, which
    /// the scan meets first. So a layer whose target was not written within [`SEEN_WINDOW`]
    /// cannot be the highest that drives, and its port — cold: most layers see nothing — is
    /// not read. (A test compares both answers every tick, with kills, loss and partitions.)
    pub fn drive_seen(&self, core: &NodeCore, seen: &[Option<Instant>]) -> u32 {
        match self {
            Brain::Chain(layers) => chain_drive_seen(core, layers, seen),
            Brain::Follow { rotate, drive, chain, .. } => {
                let now = core.now();
                if core.last_accepted(*rotate).ok().flatten().is_some_and(|t| now < t + OVERRIDE_PERIOD) {
                    core.read(*drive).ok().and_then(|v| v.as_int()).unwrap_or(0) as u32
                } else {
                    chain_drive_seen(core, chain, seen)
                }
            }
            _ => self.drive(core),
        }
    }
}

/// True if a robot whose body last wrote a target to VISION at `latest` (`None`: never) has
/// no observer layer that can drive at `now`: a [`Brain::Chain`] then drives nothing
/// ([`Brain::drive_seen`] says 0), which the harness can tell without reading the brain.
pub fn chain_quiet(now: Instant, latest: Option<Instant>) -> bool {
    latest.is_none_or(|s| now >= s + SEEN_WINDOW)
}

/// [`chain_drive`] reading only the layers whose target was written within [`SEEN_WINDOW`].
fn chain_drive_seen(core: &NodeCore, layers: &[PortRef], seen: &[Option<Instant>]) -> u32 {
    let now = core.now();
    for (n, p) in layers.iter().enumerate() {
        if seen.get(n).copied().flatten().is_none_or(|s| now >= s + SEEN_WINDOW) {
            continue;
        }
        if let Ok(Some(t)) = core.last_accepted(*p) {
            if now < t + OVERRIDE_PERIOD {
                return n as u32 + 1;
            }
        }
    }
    0
}

/// The highest observer layer that wrote within the override period (0: none).
fn chain_drive(core: &NodeCore, layers: &[PortRef]) -> u32 {
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

/// [`Brain::drive`] of a Fig. 2 controller built by anyone (a C or Python program), read from
/// its observer layers by name: `layers[n - 1]` names layer n, the behavior watching target n
/// (`OBS1`..`OBSm`, as [`build`], examples/cmommt/c/cmommt.c and examples/cmommt/python/fig2.py
/// name them), whose `Rotate` drives while it wrote within the override period. The highest
/// such layer drives (its target's number); a layer missing, or without `Rotate`, never
/// drives; 0: none does. The same answer as [`Brain::Chain`] on the same node.
pub fn named_chain_drive(core: &NodeCore, layers: &[String]) -> u32 {
    let now = core.now();
    for (n, name) in layers.iter().enumerate() {
        let Ok(p) = core.port(name, "Rotate") else { continue };
        if let Ok(Some(t)) = core.last_accepted(p) {
            if now < t + OVERRIDE_PERIOD {
                return n as u32 + 1;
            }
        }
    }
    0
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
    build_shared(node, controller, priorities, cfg, &mut SharedClasses::new())
}

/// [`build`] with the controller's classes taken from (or built into) `classes`, so that the
/// robots of one scenario share them (crate::classes). The Planner's `Follower` class knows
/// its robot and is built for each node. `BleSeek` places sightings as in the lab's camera
/// ([`WorldConfig::lab`]); [`build_in`] tells it the world's.
pub fn build_shared(
    node: &mut NodeCore,
    controller: Controller,
    priorities: &[f64],
    cfg: &ControllerConfig,
    classes: &mut SharedClasses,
) -> Result<Brain, Error> {
    let lab = WorldConfig::lab(&[]);
    build_in(node, controller, priorities, lab.focal * lab.target_height, cfg, classes)
}

/// [`build_shared`] in a world whose camera sees a target at distance `d` with apparent height
/// `target_size / d` (`focal * target_height`, [`WorldConfig`]): how `BleSeek` turns a
/// sighting into a place it can share. The other controllers do not use it.
pub fn build_in(
    node: &mut NodeCore,
    controller: Controller,
    priorities: &[f64],
    target_size: f64,
    cfg: &ControllerConfig,
    classes: &mut SharedClasses,
) -> Result<Brain, Error> {
    let m = priorities.len() as u32;
    classes.define(node, "SafeVelocity", || safe_velocity_class(SafeVelocity::default()))?;
    classes.define(node, "RandomWander", || random_wander_class(10.0, cfg.wander_seed))?;
    node.create("SafeVelocity", VEL)?;
    node.create("RandomWander", WANDER)?;
    local(node, (SONAR, "Ranges"), (VEL, "Ranges"), ConnectionKind::Normal)?;
    local(node, (VEL, "Translate"), (BASE, "Translate"), ConnectionKind::Normal)?;
    local(node, (WANDER, "Rotate"), (BASE, "Rotate"), ConnectionKind::Normal)?;
    match controller {
        Controller::Random => Ok(Brain::Wander),
        Controller::Ble | Controller::BleLean | Controller::Local | Controller::Planner => {
            // BLE-lean is Fig. 2 with the lean policy, whatever the tunables say.
            let policy = if controller == Controller::BleLean { Eligibility::LEAN } else { cfg.eligibility };
            classes.define(node, "Observer", || observer_class_with(policy))?;
            let ble = BleConfig::new(GROUP, "Rotate", cfg.claim_hz)?;
            // Lowest layer first, so that each layer's `next` exists when it is made.
            for num in (1..=m).rev() {
                let next = if num == m { WANDER.to_owned() } else { format!("OBS{}", num + 1) };
                if matches!(controller, Controller::Ble | Controller::BleLean) {
                    make_observer(node, num, &next, &ble)?;
                } else {
                    make_observer_layer(node, num, &next)?;
                }
            }
            let layers = (1..=m).map(|n| node.port(&format!("OBS{n}"), "Rotate")).collect::<Result<_, _>>()?;
            if controller != Controller::Planner {
                return Ok(Brain::Chain(layers));
            }
            build_follower(node, m, cfg)?;
            Ok(Brain::Follow {
                pose: node.port("FOLLOW", "Pose")?,
                rotate: node.port("FOLLOW", "Rotate")?,
                drive: node.port("FOLLOW", "Drive")?,
                chain: layers,
            })
        }
        Controller::BleSeek => build_ble_seek(node, priorities, target_size, cfg, classes),
        Controller::ForceField => {
            classes.define(node, "Force", || force_class(priorities))?;
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
            classes.define(node, "Oracle", oracle_class)?;
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

/// The `Planner`'s node id: its base station is a node of its own on the radio, after the
/// robots (1..=N). Partitions name it by this id.
pub const PLANNER_NODE: NodeId = NodeId(65_535);
/// An assignment (robot side) or a report (planner side) older than this many plan periods is
/// stale: the robot falls back to its observer chain, the planner stops counting on the robot.
pub const GOAL_PERIODS: f64 = 3.0;
/// How long the planner keeps a target's last reported position when nobody reports it.
const TARGET_MEMORY: f64 = 5.0;

fn plan_lifespan(cfg: &ControllerConfig) -> Result<Duration, Error> {
    Duration::try_from_secs_f64(GOAL_PERIODS / cfg.plan_hz)
}

/// `Follower` (behavior `FOLLOW`) on a `Planner` robot: reports `[x, y, theta, angle1,
/// height1, ..., angleM, heightM]` (height 0: not seen) to the planner `plan_hz` times a second,
/// and steers towards its assignment `Goal = [target id, x, y]` while it is fresh — along the
/// camera's bearing when it sees the target, else from its pose to the planner's estimate —
/// overriding the observer chain; with no fresh assignment (or target 0) it is silent and the
/// chain drives.
fn build_follower(node: &mut NodeCore, m: u32, cfg: &ControllerConfig) -> Result<(), Error> {
    let robot = node.id().0;
    let mut c = BehaviorClass::new("Follower");
    let pose = c.port(PortSpec::new("Pose", Value::vector(&[])).lifespan(VISION_LIFESPAN))?;
    let goal = c.port(PortSpec::new("Goal", Value::vector(&[])).lifespan(plan_lifespan(cfg)?))?;
    let obs = c.port(PortSpec::new("Obs", Value::vector(&[])))?;
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    let drive = c.port(PortSpec::new("Drive", 0i64))?;
    let mut sights = Vec::new();
    for n in 1..=m {
        let a = c.port(PortSpec::new(&format!("T{n}Angle"), 0.0).lifespan(VISION_LIFESPAN))?;
        let h = c.port(PortSpec::new(&format!("T{n}Bottom"), 0.0).lifespan(VISION_LIFESPAN))?;
        sights.push((a, h));
    }
    let report_sights = sights.clone();
    c.every_hz("Report", cfg.plan_hz, move |ctx| {
        let Some(Value::Vector(p)) = ctx.get(pose) else { return };
        let mut v = p.to_vec();
        for &(a, h) in &report_sights {
            match (ctx.float(a), ctx.float(h)) {
                (Some(a), Some(h)) => v.extend([a, h]),
                _ => v.extend([0.0, 0.0]),
            }
        }
        let _ = ctx.write(obs, Value::vector(&v));
    })?;
    c.every_hz("Steer", 20.0, move |ctx| {
        let target = match ctx.get(goal) {
            Some(Value::Vector(g)) if g.len() == 3 && g[0] >= 1.0 => Some((g[0] as usize, g[1], g[2])),
            _ => None,
        };
        let Some((id, tx, ty)) = target else {
            let _ = ctx.write(drive, 0i64);
            return; // no fresh assignment: the observer chain drives
        };
        let seen = sights.get(id - 1).and_then(|&(a, _)| ctx.float(a));
        let turn = match (seen, ctx.get(pose)) {
            // Angles are right-positive; Rotate is counter-clockwise-positive.
            (Some(a), _) => -a,
            (None, Some(Value::Vector(p))) if p.len() == 3 => wrap((ty - p[1]).atan2(tx - p[0]) - p[2]),
            _ => return,
        };
        let _ = ctx.write(rotate, turn);
        let _ = ctx.write(drive, id as i64);
    })?;
    node.define(c)?;
    node.create("Follower", "FOLLOW")?;
    for n in 1..=m {
        for (from, to) in [("Angle", "Angle"), ("Bottom", "Bottom")] {
            local(
                node,
                (VISION, &format!("Target{n}{from}")),
                ("FOLLOW", &format!("T{n}{to}")),
                ConnectionKind::Normal,
            )?;
        }
    }
    // Above the whole observer chain: a fresh assignment outranks what the robot sees.
    local(node, ("FOLLOW", "Rotate"), ("OBS1", "Rotate"), ConnectionKind::OverrideOut(OVERRIDE_PERIOD))?;
    node.connect(
        &Endpoint::local("FOLLOW", "Obs"),
        &Endpoint::node(PLANNER_NODE, "PLAN", &format!("Obs{robot}")),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )?;
    Ok(())
}

/// The `Planner`'s node: behavior `PLAN` (class `Planner`) on node [`PLANNER_NODE`], for
/// `robots` robots (nodes 1..=robots) and the targets of `world` (in decreasing priority).
///
/// `plan_hz` times a second it turns each fresh report into robot poses and target positions
/// (a sighting's distance from its apparent height: `focal * target_height / height`; the
/// closest sighting of a target wins; a target nobody reports is remembered for 5 s), then
/// gives each known target, in priority order, the nearest free robot that reported (keeping
/// the current holder unless another is less than half as far, as the omniscient planner does),
/// and sends every robot that reported its assignment (`[id, x, y]`, or `[0, 0, 0]`: none).
pub fn build_planner(
    node: &mut NodeCore,
    robots: usize,
    world: &WorldConfig,
    cfg: &ControllerConfig,
) -> Result<(), Error> {
    let m = world.targets.len();
    let size = world.focal * world.target_height;
    let mut c = BehaviorClass::new("Planner");
    let life = plan_lifespan(cfg)?;
    let mut links = Vec::with_capacity(robots);
    for k in 1..=robots {
        let obs = c.port(PortSpec::new(&format!("Obs{k}"), Value::vector(&[])).lifespan(life))?;
        let assign = c.port(PortSpec::new(&format!("Assign{k}"), Value::vector(&[])))?;
        links.push((obs, assign));
    }
    // Per target: x, y, when last reported (s; negative: never).
    let known = c.slot("Known", Value::vector(&vec![-1.0; 3 * m]))?;
    // Per robot: the target it holds (id; 0 none).
    let held = c.slot("Held", Value::vector(&vec![0.0; robots]))?;
    c.every_hz("Plan", cfg.plan_hz, move |ctx| {
        let now = ctx.now().as_secs_f64();
        let mut mem = ctx.slot(known).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        let mut hold = ctx.slot(held).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        if mem.len() != 3 * m || hold.len() != robots {
            return;
        }
        // Fresh reports: robot index -> pose; the closest sighting of each target this round.
        let mut poses: Vec<Option<(f64, f64)>> = vec![None; robots];
        let mut best: Vec<Option<(f64, f64, f64)>> = vec![None; m];
        for (i, &(obs, _)) in links.iter().enumerate() {
            let Some(Value::Vector(r)) = ctx.get(obs) else { continue };
            if r.len() != 3 + 2 * m {
                continue;
            }
            let (x, y, theta) = (r[0], r[1], r[2]);
            poses[i] = Some((x, y));
            for j in 0..m {
                let (angle, height) = (r[3 + 2 * j], r[4 + 2 * j]);
                if height <= 0.0 || best[j].is_some_and(|(_, _, h)| h >= height) {
                    continue;
                }
                let d = size / height;
                let heading = theta - angle; // right-positive bearing
                best[j] = Some((x + d * heading.cos(), y + d * heading.sin(), height));
            }
        }
        for (j, b) in best.iter().enumerate() {
            if let Some((x, y, _)) = *b {
                mem[3 * j..3 * j + 3].copy_from_slice(&[x, y, now]);
            }
        }
        let mut free: Vec<bool> = poses.iter().map(Option::is_some).collect();
        let mut next = vec![0.0; robots];
        let mut goal = vec![None; robots];
        for j in 0..m {
            let (tx, ty, seen) = (mem[3 * j], mem[3 * j + 1], mem[3 * j + 2]);
            if seen < 0.0 || now - seen > TARGET_MEMORY {
                continue;
            }
            let dist = |i: usize| poses[i].map_or(f64::INFINITY, |(x, y)| (x - tx).hypot(y - ty));
            let nearest = (0..robots).filter(|&i| free[i]).min_by(|&a, &b| dist(a).total_cmp(&dist(b)));
            let Some(nearest) = nearest else { break };
            let holder = (0..robots).find(|&i| free[i] && hold[i] == (j + 1) as f64);
            let pick = match holder {
                Some(h) if dist(nearest) * 2.0 >= dist(h) => h,
                _ => nearest,
            };
            free[pick] = false;
            next[pick] = (j + 1) as f64;
            goal[pick] = Some((tx, ty));
        }
        for (i, &(_, assign)) in links.iter().enumerate() {
            if poses[i].is_none() {
                continue; // no fresh report: nothing to tell it from
            }
            let v = match goal[i] {
                Some((x, y)) => [next[i], x, y],
                None => [0.0; 3],
            };
            let _ = ctx.write(assign, Value::vector(&v));
        }
        hold.copy_from_slice(&next);
        let _ = ctx.set_slot(known, Value::vector(&mem));
        let _ = ctx.set_slot(held, Value::vector(&hold));
    })?;
    node.define(c)?;
    node.create("Planner", "PLAN")?;
    for k in 1..=robots {
        node.connect(
            &Endpoint::local("PLAN", &format!("Assign{k}")),
            &Endpoint::node(NodeId(k as u32), "FOLLOW", "Goal"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
    }
    Ok(())
}

/// `BleSeek`: how much more eligible a robot is for the target it already claims. A peer must
/// see the target 1.1 times as large (about nine tenths of the distance) to take it: a claim
/// is not given up for a marginal trade, but a clearly closer robot takes over. Measured (20
/// seeds x 600 s of issue 37's room): 1.5 cost up to 0.02 of A_w against 1.1 (likely because a
/// holder that sees its target from 4 m does not observe it, 2 m, and kept a peer at 2.5 m
/// away); 1.0 (no bonus) was level with 1.1 within noise, 2.0 worse by 0.03.
pub const HOLD_BONUS: f64 = 1.1;
/// `BleSeek`: how much better another reported target must score (priority / (1 m +
/// distance)) to replace the search under way: a search is not dropped for a marginally better
/// one, which would turn the robot back and forth between two places. (Separate from
/// [`HOLD_BONUS`], which compares robots for one target, not targets for one robot.)
pub const SEARCH_BONUS: f64 = 1.5;
/// `BleSeek`: a robot seeking a target it does not see is this eligible for it, as a share of
/// the apparent height the target would have at the distance it was told: a report counts as
/// a sight from where the robot is. Measured: 0.5 (a report half as sure) up to 0.01 lower as
/// is, under loss and at a 4 m range; 1.0 kept: a robot told of a target is as able to reach it.
pub const SEEK_WEIGHT: f64 = 1.0;
/// `BleSeek`: eligibility offers per claim period while nobody competes for the target: one
/// lost broadcast does not lose the claim (the select needs an offer within the cycle).
pub const OFFERS: f64 = 2.0;
/// `BleSeek`: eligibility offers per claim period while a peer competes (offered within
/// [`QUIET_PERIODS`]): a competitor that missed every offer of a cycle claims too, and both
/// robots then keep away from the target. Measured: 0.01-0.02 more A_w under 20 % loss than
/// two offers, for 0.2-0.3 more messages per robot per second.
pub const CHALLENGED_OFFERS: f64 = 4.0;
/// `BleSeek`: a robot that holds a target it sees leaves it for a reported one only if that
/// one is worth this many times more (priority): a small gain is not worth the trip.
pub const LEAVE_FOR: f64 = 1.5;
/// `BleSeek`: how long (claim periods) a layer that heard a peer offer more stays quiet: the
/// peer's claim inhibits it that long anyway ([`BleConfig::new`]'s lease, 2.25 periods and
/// the delay), and a beaten robot that spoke up again after one period would claim whenever
/// both of the peer's offers of a cycle were lost (4 % of cycles at 20 % loss).
pub const QUIET_PERIODS: f64 = 2.25;
/// `BleSeek`: how long an observer layer's word "I hold the robot" (`Engaged`) counts for the
/// layers below it and for `SEEK`: three 20 Hz activations, so that one late activation does
/// not free them.
const ENGAGED_LIFESPAN: Duration = Duration::from_millis(150);
/// `BleSeek`: how long a peer's eligibility for a target keeps it "covered" in a robot's
/// eyes (`Covered`): longer than the half claim period between two offers.
const COVERED_LIFESPAN: Duration = Duration::from_millis(1500);
/// `BleSeek`: how often a robot shares the targets it sees but nobody takes (one message
/// each time it has any).
const SHARE_HZ: f64 = 1.0;
/// `BleSeek`: how long (s) a shared sighting may start a search: a little over two sharing
/// periods, so that one lost message does not drop it. A search the robot's layer holds goes
/// on until it arrives (or [`SEEK_AT_MOST`]).
const SOUGHT_FOR: f64 = 2.5;
/// `BleSeek`: how long (s) a robot keeps turning to where it last saw a target it lost from
/// view (a miss, a turn, the target stepping aside), as the Planner's robots steer to the
/// planner's estimate: the observer layer keeps its target instead of handing the robot to
/// the layers below for a moment.
const TRACK_FOR: f64 = 3.0;
/// `BleSeek`: the longest search (s) for one report.
const SEEK_AT_MOST: f64 = 30.0;
/// `BleSeek`: a robot this close (m) to where a reported target was, and not seeing it, gives
/// up that report (the target moved on).
const ARRIVED: f64 = 1.0;
/// `BleSeek`: a search its layer does not hold this long after it began (s) lost to a peer's
/// better eligibility; that target is not sought again for [`SOUGHT_FOR`].
const REFUSED_AFTER: f64 = 0.3;

/// `BleSeek`'s observer (class `SeekObserver`): Fig. 2's `ObserveTarget`, whose target is the
/// one it sees or, when it sees none, the one `SEEK` asks it to turn to (`Sought = [turn,
/// eligibility]`: where it lost the target, or a peer's report), and whose eligibility counts
/// what the robot would gain. At 20 Hz: turn towards the target (`Rotate`, as the paper's); a
/// peer's eligibility heard this cycle (`Best`) for a target it sees tells `SEEK` the target is
/// covered (`Covered`). Then, unless a higher layer holds the robot (`Above` fresh: the robot
/// would not go there, and a claim would only keep a free peer away): its eligibility is the
/// apparent height (or `Sought`'s), times [`HOLD_BONUS`] while this robot claims the target;
/// the layer holds the robot (`Engaged`, to the layers below and `SEEK`) unless a peer offered
/// more this cycle; and it offers its eligibility (`Local`) [`OFFERS`] times per claim period
/// (at once on a first sight; [`CHALLENGED_OFFERS`] while a peer competes) unless a peer
/// offered more within [`QUIET_PERIODS`]: a robot that would lose
/// the comparison gains nothing by broadcasting, and BLE's claims are unchanged (the select is
/// the core's, [`NodeCore::ble_join`]).
fn seek_observer_class(claim_hz: f64) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("SeekObserver");
    let x = c.port(PortSpec::new("TargetX", 0.0).lifespan(VISION_LIFESPAN))?;
    let y = c.port(PortSpec::new("TargetY", 0.0).lifespan(VISION_LIFESPAN))?;
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    let above = c.port(PortSpec::new("Above", 0.0).lifespan(ENGAGED_LIFESPAN))?;
    let sought = c.port(PortSpec::new("Sought", Value::vector(&[])).lifespan(ENGAGED_LIFESPAN))?;
    let engaged = c.port(PortSpec::new("Engaged", 0.0))?;
    let covered = c.port(PortSpec::new("Covered", 0.0))?;
    let offered_at = c.slot("OfferedAt", -1.0)?;
    // The best peer eligibility heard lately, and when (s; negative: never).
    let heard = c.slot("Heard", Value::vector(&[0.0, -1.0]))?;
    let period = 1.0 / claim_hz;
    c.every_hz("TurnToTarget", 20.0, move |ctx| {
        let seen = ctx.float(x).and_then(|b| ctx.float(y).map(|h| (b, h)));
        let (turn, eligibility) = match seen {
            Some((bearing, height)) => (-bearing, height),
            None => match ctx.get_ref(sought) {
                Some(Value::Vector(v)) if v.len() == 2 => (v[0], v[1]),
                _ => return,
            },
        };
        let _ = ctx.write(rotate, turn);
        let now = ctx.now().as_secs_f64();
        let peer = ctx.float(Port::BEST);
        if seen.is_some() && peer.is_some() {
            let _ = ctx.write(covered, 1.0);
        }
        if ctx.fresh(above) {
            return;
        }
        // A claim is renewed every period: one within 1.5 periods is held.
        let holding = ctx.last_accepted(Port::INHIBIT).is_some_and(|t| now - t.as_secs_f64() < 1.5 * period);
        let mine = if holding { eligibility * HOLD_BONUS } else { eligibility };
        if holding || peer.is_none_or(|p| p <= mine) {
            let _ = ctx.write(engaged, 1.0);
        }
        // `Best` empties at every select: what was heard within a claim's lease still counts.
        let last = ctx.slot(heard).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        if let Some(p) = peer {
            let _ = ctx.set_slot(heard, Value::vector(&[p, now]));
        }
        let beaten = match peer {
            Some(p) => p > mine,
            None => last.len() == 2 && last[1] >= 0.0 && now - last[1] < QUIET_PERIODS * period && last[0] > mine,
        };
        if beaten {
            return; // a peer is more eligible: offering would gain nothing
        }
        let at = ctx.slot(offered_at).as_float().unwrap_or(-1.0);
        // Unchallenged, two offers per claim cycle: one lost broadcast does not lose the claim.
        // Challenged (a peer offered within the lease), four: a peer that missed both offers
        // of a cycle would claim too, and under loss that cost more than the messages.
        let challenged =
            peer.is_some() || (last.len() == 2 && last[1] >= 0.0 && now - last[1] < QUIET_PERIODS * period);
        let every = period / if challenged { CHALLENGED_OFFERS } else { OFFERS };
        if at < 0.0 || now - at >= every - 1e-9 {
            let _ = ctx.write(Port::LOCAL, mine);
            let _ = ctx.set_slot(offered_at, now);
        }
    })?;
    Ok(c)
}

/// `BleSeek`'s `SEEK` (class `Seeker`): what the robot shares and hears, where its targets
/// were, and which reported target it seeks. It never drives the robot itself: it tells an
/// observer layer where to turn (`Sought{n}`), and subsumption and BLE decide as for a sight.
///
/// Places: at 20 Hz, each target it sees is placed from the pose, the bearing and the apparent
/// height (`target_size / height` m away). Tracks: a target lost from view while its layer held
/// the robot is sought where it was for [`TRACK_FOR`] s, with the eligibility of the apparent
/// height it would have there. Shares: once a second, the targets it sees that none of its
/// layers holds and no peer offered for (not `Engaged{n}`, not `Covered{n}`) go to the peers as
/// `Wanted = [n, x, y, ...]`, one broadcast. Hears: the peers' `Wanted` into `Heard`, each
/// target's place remembered with the time heard. Seeks: among the targets heard within
/// [`SOUGHT_FOR`] s that it neither sees nor tracks, above the layer holding the robot and worth
/// [`LEAVE_FOR`] times its target, the one with the best priority / (1 m + distance); that layer
/// gets `Sought{n} = [turn, eligibility]` ([`SEEK_WEIGHT`] times the apparent height the target
/// would have there). A search its layer holds goes on until the robot is within [`ARRIVED`]
/// of the place (it then gives the report up), sees the target, or [`SEEK_AT_MOST`]; one its
/// layer does not hold [`REFUSED_AFTER`] s after it began (a peer is more eligible) is given up,
/// and that target not sought again for [`SOUGHT_FOR`] s.
fn seeker_class(priorities: &[f64], target_size: f64) -> Result<BehaviorClass, Error> {
    let m = priorities.len();
    let prios = priorities.to_vec();
    let mut c = BehaviorClass::new("Seeker");
    let pose = c.port(PortSpec::new("Pose", Value::vector(&[])).lifespan(VISION_LIFESPAN))?;
    let wanted = c.port(PortSpec::new("Wanted", Value::vector(&[])))?;
    let heard = c.port(PortSpec::new("Heard", Value::vector(&[])))?;
    let mut layers = Vec::with_capacity(m);
    for n in 1..=m {
        let a = c.port(PortSpec::new(&format!("T{n}Angle"), 0.0).lifespan(VISION_LIFESPAN))?;
        let h = c.port(PortSpec::new(&format!("T{n}Bottom"), 0.0).lifespan(VISION_LIFESPAN))?;
        let e = c.port(PortSpec::new(&format!("Engaged{n}"), 0.0).lifespan(ENGAGED_LIFESPAN))?;
        let k = c.port(PortSpec::new(&format!("Covered{n}"), 0.0).lifespan(COVERED_LIFESPAN))?;
        let s = c.port(PortSpec::new(&format!("Sought{n}"), Value::vector(&[])))?;
        layers.push((a, h, e, k, s));
    }
    // Per target: x, y, when heard (s; negative: not sought), when a search for it was refused.
    let known = c.slot("Known", Value::vector(&vec![-1.0; 4 * m]))?;
    // The search under way: target index + 1 (0: none), when it began.
    let search = c.slot("Search", Value::vector(&[0.0, 0.0]))?;
    // Per target: where this robot last saw it, and when (s; negative: never).
    let own = c.slot("Own", Value::vector(&vec![-1.0; 4 * m]))?;
    let share_layers = layers.clone();
    c.every_hz("Share", SHARE_HZ, move |ctx| {
        let mine = ctx.slot(own).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        if mine.len() != 4 * m {
            return;
        }
        let now = ctx.now().as_secs_f64();
        let mut v = Vec::new();
        for (n, &(a, _, e, k, _)) in share_layers.iter().enumerate() {
            if ctx.fresh(e) || ctx.fresh(k) {
                continue;
            }
            // Seen now (placed by `Seek` at its last activation, at most 50 ms ago).
            let at = mine[4 * n + 2];
            if ctx.fresh(a) && at >= 0.0 && now - at < 0.2 {
                v.extend([(n + 1) as f64, mine[4 * n], mine[4 * n + 1]]);
            }
        }
        if !v.is_empty() {
            let _ = ctx.write(wanted, Value::vector(&v));
        }
    })?;
    c.on_write("Hear", heard, move |ctx| {
        let Some(Value::Vector(h)) = ctx.get(heard) else { return };
        let mut mem = ctx.slot(known).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        if mem.len() != 4 * m {
            return;
        }
        let now = ctx.now().as_secs_f64();
        for e in h.chunks_exact(3) {
            let n = e[0] as usize;
            if (1..=m).contains(&n) {
                mem[4 * (n - 1)..4 * (n - 1) + 3].copy_from_slice(&[e[1], e[2], now]);
            }
        }
        let _ = ctx.set_slot(known, Value::vector(&mem));
    })?;
    c.every_hz("Seek", 20.0, move |ctx| {
        let Some(Value::Vector(p)) = ctx.get(pose) else { return };
        let (px, py, theta) = (p[0], p[1], p[2]);
        let mut mem = ctx.slot(known).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        let s = ctx.slot(search).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        if mem.len() != 4 * m || s.len() != 2 {
            return;
        }
        let now = ctx.now().as_secs_f64();
        // What it sees now, placed; what it lost lately, sought where it was.
        let mut mine = ctx.slot(own).as_vector().map(<[f64]>::to_vec).unwrap_or_default();
        if mine.len() == 4 * m {
            for (j, &(a, h, e, ..)) in layers.iter().enumerate() {
                match (ctx.float(a), ctx.float(h)) {
                    (Some(angle), Some(height)) if height > 0.0 => {
                        let d = target_size / height;
                        let heading = theta - angle;
                        let held = if ctx.fresh(e) { now } else { mine[4 * j + 3] };
                        mine[4 * j..4 * j + 4].copy_from_slice(&[
                            px + d * heading.cos(),
                            py + d * heading.sin(),
                            now,
                            held,
                        ]);
                    }
                    // Lost from view while its layer held the robot: turn to where it was.
                    _ if mine[4 * j + 2] >= 0.0
                        && now - mine[4 * j + 2] <= TRACK_FOR
                        && now - mine[4 * j + 3] <= TRACK_FOR =>
                    {
                        let (tx, ty) = (mine[4 * j], mine[4 * j + 1]);
                        let d = (tx - px).hypot(ty - py).max(ARRIVED);
                        let turn = wrap((ty - py).atan2(tx - px) - theta);
                        let _ = ctx.write(layers[j].4, Value::vector(&[turn, target_size / d]));
                    }
                    _ => {}
                }
            }
            let _ = ctx.set_slot(own, Value::vector(&mine));
        }
        let lost = |j: usize| mine.get(4 * j + 2).is_some_and(|&t| t >= 0.0 && now - t <= TRACK_FOR);
        let (mut current, began) = (s[0] as usize, s[1]);
        // The search under way: held by its layer, lost to a peer, or over.
        if current > 0 {
            let j = current - 1;
            let held = ctx.fresh(layers[j].2);
            let d = (mem[4 * j] - px).hypot(mem[4 * j + 1] - py);
            if !held && now - began > REFUSED_AFTER {
                mem[4 * j + 3] = now;
                current = 0;
            } else if ctx.fresh(layers[j].0) || d < ARRIVED || now - began > SEEK_AT_MOST {
                if !ctx.fresh(layers[j].0) {
                    mem[4 * j + 2] = -1.0;
                }
                current = 0;
            }
        }
        // The layer that holds the robot by sight (the search's own layer aside).
        let holder = (0..m).find(|&j| j + 1 != current && ctx.fresh(layers[j].2));
        let mut best: Option<(f64, usize, f64)> = None;
        for (j, &(a, ..)) in layers.iter().enumerate() {
            let (tx, ty, at, refused) = (mem[4 * j], mem[4 * j + 1], mem[4 * j + 2], mem[4 * j + 3]);
            let ongoing = j + 1 == current;
            if at < 0.0
                || (!ongoing && (now - at > SOUGHT_FOR || now - refused < SOUGHT_FOR))
                || ctx.fresh(a)
                || lost(j)
            {
                continue;
            }
            if holder.is_some_and(|h| j >= h || prios[j] < LEAVE_FOR * prios[h]) {
                continue;
            }
            let d = (tx - px).hypot(ty - py);
            if d < ARRIVED {
                mem[4 * j + 2] = -1.0;
                continue;
            }
            // The search under way keeps its place unless another is clearly better.
            let score = prios[j] / (1.0 + d) * if ongoing { SEARCH_BONUS } else { 1.0 };
            if best.is_none_or(|(b, _, _)| score > b) {
                best = Some((score, j, d));
            }
        }
        let next = match best {
            Some((_, j, d)) => {
                let (tx, ty) = (mem[4 * j], mem[4 * j + 1]);
                let turn = wrap((ty - py).atan2(tx - px) - theta);
                let _ = ctx.write(layers[j].4, Value::vector(&[turn, SEEK_WEIGHT * target_size / d.max(ARRIVED)]));
                j + 1
            }
            None => 0,
        };
        let began = if next == current { began } else { now };
        let _ = ctx.set_slot(known, Value::vector(&mem));
        let _ = ctx.set_slot(search, Value::vector(&[next as f64, began]));
    })?;
    Ok(c)
}

/// Build [`Controller::BleSeek`] on `node` (see the module docs and docs/cmommt.md,
/// "BLE-seek"): `OBS1..OBSm` (class `SeekObserver`) in a subsumption chain over `WANDER`, each
/// layer in its BLE group as in Fig. 2, and `SEEK` beside them; `OBSk.Engaged` feeds every
/// lower layer's `Above` and `SEEK`.
fn build_ble_seek(
    node: &mut NodeCore,
    priorities: &[f64],
    target_size: f64,
    cfg: &ControllerConfig,
    classes: &mut SharedClasses,
) -> Result<Brain, Error> {
    let m = priorities.len() as u32;
    classes.define(node, "SeekObserver", || seek_observer_class(cfg.claim_hz))?;
    classes.define(node, "Seeker", || seeker_class(priorities, target_size))?;
    node.create("Seeker", SEEK)?;
    let ble = BleConfig::new(GROUP, "Rotate", cfg.claim_hz)?;
    for num in (1..=m).rev() {
        let name = format!("OBS{num}");
        let next = if num == m { WANDER.to_owned() } else { format!("OBS{}", num + 1) };
        node.create("SeekObserver", &name)?;
        for (from, to) in [("Angle", "TargetX"), ("Bottom", "TargetY")] {
            local(node, (VISION, &format!("Target{num}{from}")), (&name, to), ConnectionKind::Normal)?;
            local(
                node,
                (VISION, &format!("Target{num}{from}")),
                (SEEK, &format!("T{num}{from}")),
                ConnectionKind::Normal,
            )?;
        }
        local(node, (&name, "Rotate"), (&next, "Rotate"), ConnectionKind::OverrideOut(OVERRIDE_PERIOD))?;
        local(node, (&name, "Engaged"), (SEEK, &format!("Engaged{num}")), ConnectionKind::Normal)?;
        local(node, (&name, "Covered"), (SEEK, &format!("Covered{num}")), ConnectionKind::Normal)?;
        local(node, (SEEK, &format!("Sought{num}")), (&name, "Sought"), ConnectionKind::Normal)?;
        for lower in num + 1..=m {
            local(node, (&name, "Engaged"), (&format!("OBS{lower}"), "Above"), ConnectionKind::Normal)?;
        }
        node.ble_join(&name, &ble)?;
    }
    node.connect(
        &Endpoint::local(SEEK, "Wanted"),
        &Endpoint::group(GROUP, SEEK, "Heard"),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )?;
    let layers = (1..=m).map(|n| node.port(&format!("OBS{n}"), "Rotate")).collect::<Result<_, _>>()?;
    Ok(Brain::Seek { pose: node.port(SEEK, "Pose")?, chain: layers })
}

/// `BleSeek`'s sharing and seeking behavior.
pub const SEEK: &str = "SEEK";
