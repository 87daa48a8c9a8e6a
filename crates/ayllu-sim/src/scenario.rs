//! A run of the task: the world, one Ayllu node per robot (body + controller), the radio
//! between them, and the metrics — all on virtual time, stepped by [`Sim::step`].
//!
//! Promise: [`run`] is a pure function of the [`Scenario`]: same scenario and seed, same
//! outcome bit for bit, on any machine and with any number of threads ([`Sim::set_threads`];
//! no clock, no hash-map iteration order; all randomness from seeded streams). The trace hash
//! is SHA-256 over every frame's exact state (f64 bits), so any divergence shows.
//!
//! One tick (`dt`, 50 ms = the observers' 20 Hz): kills due; the radio's deliveries due are set
//! aside; every `sense_every` ticks each live robot's body takes a camera frame and its sonar
//! sweep's noise draws, in robot order (one noise stream); then robot by robot (one visit each,
//! so its node stays in cache; shared out among threads if allowed): its deliveries, its sonar
//! sweep and its senses written to its ports, the oracle's word (Centralized only), its pose (Planner only), its node runs at
//! the tick's time, its motors are read; then every robot's outgoing messages enter the radio
//! in robot order; the Planner's base station (a node of its own, the radio's last station)
//! takes its deliveries, polls and sends; the world moves; metrics account the tick; every
//! `frame_dt` a frame is hashed (and recorded if asked). Robots meet only through the world
//! and the radio, and nothing sent in a tick is delivered before the next, so this equals
//! doing each stage for every robot in turn.

use ayllu_core::{Duration, Error, Instant, NodeCore, NodeId, Outgoing, PortRef, Value};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::Mutex;

use crate::body::Body;
use crate::bounds::{InvalidScenario, MAX_ROBOTS, MAX_TARGETS};
use crate::classes::SharedClasses;
use crate::controller::{build_planner, build_shared, chain_quiet, Brain, Controller, ControllerConfig, PLANNER_NODE};
use crate::metrics::{Meter, Metrics};
use crate::radio::{Radio, RadioConfig, Station};
use crate::recording::{CoverageSeries, Event, Frame, Recording, RecordingMeta, RobotFrame, RobotInfo, TargetInfo};
use crate::workers::Workers;
use crate::world::{wrap, Command, SonarScratch, World, WorldConfig};

/// A scheduled robot failure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Kill {
    /// Seconds into the run.
    #[serde(deserialize_with = "crate::bounds::number_de")]
    pub at: f64,
    /// The robot's node id; `None`: the robot observing the highest-priority observed target
    /// at that moment (lowest id on ties; robot 1 if none observes anything) — the failure
    /// that hurts most, so re-covering is tested where it matters.
    pub robot: Option<u32>,
}

/// Everything that defines a run: the world, the team, the controller, the radio, the kills,
/// the seed and the rates. Serializable: `scenario_file` reads it from TOML.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// The arena, sensors and targets.
    pub world: WorldConfig,
    /// Robots at the start (node ids 1..=robots).
    pub robots: usize,
    /// The controller every robot runs.
    pub controller: Controller,
    /// The controllers' tunables (claim rate, wander seed, eligibility policy).
    pub controllers: ControllerConfig,
    /// The radio medium.
    pub radio: RadioConfig,
    /// Run length (s of virtual time).
    #[serde(deserialize_with = "crate::bounds::number_de")]
    pub duration: f64,
    /// Seed of the placement, target-motion, sensor-noise and radio streams (the wander seed is
    /// `controllers.wander_seed`).
    pub seed: u64,
    /// Scheduled robot failures, any number, at any instants.
    pub kills: Vec<Kill>,
    /// Keep every frame for a replay (costs memory; the hash is computed either way).
    pub record: bool,
    /// Virtual seconds between frames (hashed, sampled for coverage, recorded if `record`),
    /// rounded to a whole number of ticks.
    #[serde(deserialize_with = "crate::bounds::number_de")]
    pub frame_dt: f64,
    /// Tick length (s of virtual time); 0.05 is the observers' 20 Hz.
    #[serde(deserialize_with = "crate::bounds::number_de")]
    pub dt: f64,
    /// Ticks between camera frames and sonar sweeps (2: 10 Hz at 50 ms ticks).
    pub sense_every: u32,
}

/// The paper's target priorities for m targets: m, m-1, ..., 1.
pub fn priorities(targets: usize) -> Vec<f64> {
    (1..=targets).rev().map(|p| p as f64).collect()
}

impl Scenario {
    /// The paper's setting (section 4.3): 3 robots, 4 targets with priorities 4, 3, 2, 1, in
    /// the 8 m x 8 m lab, 300 s, no loss.
    pub fn paper(controller: Controller, seed: u64) -> Scenario {
        Scenario::sized(controller, 3, 4, seed)
    }

    /// `robots` robots and `targets` targets in a room that grows with the larger of the two
    /// so that density stays that of the paper's setting (8 m x 8 m for 4).
    ///
    /// Nothing is checked here (that is [`Scenario::validate`]'s job, which every run does), but
    /// nothing beyond the bounds is allocated either: `targets` above [`MAX_TARGETS`] makes
    /// `MAX_TARGETS + 1` targets, and the room is sized from counts capped likewise, so
    /// `sized(.., usize::MAX, ..)` costs nothing and the scenario is refused by `validate`
    /// (naming `robots` or `world.targets`), never shrunk into a valid one. For counts a user
    /// typed, [`Scenario::try_sized`] refuses them with the count as given.
    pub fn sized(controller: Controller, robots: usize, targets: usize, seed: u64) -> Scenario {
        let mut world = WorldConfig::lab(&priorities(targets.min(MAX_TARGETS + 1)));
        let room_for = robots.min(MAX_ROBOTS + 1).max(targets.min(MAX_TARGETS + 1));
        let side = 8.0 * (room_for as f64 / 4.0).sqrt().max(1.0);
        world.arena = [side, side];
        Scenario {
            world,
            robots,
            controller,
            controllers: ControllerConfig { wander_seed: seed, ..ControllerConfig::default() },
            radio: RadioConfig::default(),
            duration: 300.0,
            seed,
            kills: Vec::new(),
            record: false,
            frame_dt: 0.2,
            dt: 0.05,
            sense_every: 2,
        }
    }

    /// [`Scenario::sized`], refusing first a team of other than 1 to [`MAX_ROBOTS`] robots or
    /// other than 1 to [`MAX_TARGETS`] targets, naming the count as given (`robots`,
    /// `targets`). The rest is checked by [`Scenario::validate`], as for any scenario.
    pub fn try_sized(
        controller: Controller,
        robots: usize,
        targets: usize,
        seed: u64,
    ) -> Result<Scenario, InvalidScenario> {
        crate::bounds::robots(u64::try_from(robots).ok(), robots)?;
        crate::bounds::targets("targets", u64::try_from(targets).ok(), targets)?;
        Ok(Scenario::sized(controller, robots, targets, seed))
    }

    /// The same scenario with radio loss probability `loss`.
    pub fn loss(mut self, loss: f64) -> Scenario {
        self.radio.loss = loss;
        self
    }

    /// The same scenario lasting `seconds` of virtual time.
    pub fn duration(mut self, seconds: f64) -> Scenario {
        self.duration = seconds;
        self
    }

    /// The same scenario keeping every frame for a replay.
    pub fn recorded(mut self) -> Scenario {
        self.record = true;
        self
    }

    /// Kill the most useful robot halfway through (see [`Kill::robot`]).
    pub fn kill_halfway(mut self) -> Scenario {
        self.kills.push(Kill { at: self.duration / 2.0, robot: None });
        self
    }
}

/// Carry out the kills of `kills` due at `t` (s) and not yet `done`: each, in order, marks
/// its robot dead in `world` ([`Kill::robot`]'s rule sees the robots this instant already
/// killed as dead). Returns the robot indexes killed now, for
/// [`crate::metrics::Meter::killed_together`] — all dead before their lost targets are judged.
/// Shared by the in-process [`Sim`] and the distributed server, so both kill the same robots.
pub fn apply_due_kills(kills: &[Kill], done: &mut [bool], t: f64, world: &mut World) -> Vec<usize> {
    let mut killed = Vec::new();
    for (k, kill) in kills.iter().enumerate() {
        if done[k] || kill.at > t {
            continue;
        }
        done[k] = true;
        let i = match kill.robot {
            Some(id) => (id as usize).checked_sub(1).filter(|&i| i < world.robots.len()),
            None => most_useful_robot(world),
        };
        let Some(i) = i else { continue };
        if !world.robots[i].alive {
            continue;
        }
        world.robots[i].alive = false;
        killed.push(i);
    }
    killed
}

/// The live robot observing the highest-priority observed target (lowest index on ties; the
/// first live robot if none observes anything).
pub fn most_useful_robot(world: &World) -> Option<usize> {
    let range = world.config.observe_range;
    let mut best: Option<(usize, usize)> = None; // (target index, robot)
    for (i, r) in world.robots.iter().enumerate() {
        if !r.alive {
            continue;
        }
        world.in_view(i, range, |j, _, _| {
            if best.is_none_or(|(bj, _)| j < bj) {
                best = Some((j, i));
            }
        });
    }
    best.map(|(_, i)| i).or_else(|| world.robots.iter().position(|r| r.alive))
}

/// Radio totals of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RadioStats {
    /// Radio emissions by all robots (a group message counts once).
    pub sent: u64,
    /// Deliveries made (one per receiver).
    pub delivered: u64,
    /// Deliveries dropped by the loss draw (one per receiver).
    pub lost: u64,
    /// Deliveries cut by the range limit or a partition (one per receiver).
    pub cut: u64,
    /// The emissions' encoded size in bytes ([`crate::radio::wire_len`]).
    #[serde(default)]
    pub bytes: u64,
}

/// Why a run could not be built or stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The scenario has a field out of bounds ([`Scenario::validate`]): nothing was built.
    Scenario(InvalidScenario),
    /// A node refused something while the run was built or stepped (a controller that cannot be
    /// built, a port written with a value of another type...).
    Node(Error),
}

impl From<InvalidScenario> for SimError {
    fn from(e: InvalidScenario) -> Self {
        SimError::Scenario(e)
    }
}

impl From<Error> for SimError {
    fn from(e: Error) -> Self {
        SimError::Node(e)
    }
}

impl std::fmt::Display for SimError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SimError::Scenario(e) => e.fmt(f),
            SimError::Node(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for SimError {}

/// What a run produced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// The run's figures of merit (docs/cmommt.md, "The metrics").
    pub metrics: Metrics,
    /// SHA-256 of every frame, hex.
    pub trace_hash: String,
    /// Coverage over time (one sample per frame).
    pub coverage: CoverageSeries,
    /// Every frame, if the scenario asked for it (`Scenario::record`).
    pub recording: Option<Recording>,
    /// Radio totals over the run.
    pub radio: RadioStats,
}

/// The smallest team whose robots' messages are loaded ahead of their visits (`Sim::step`),
/// the planner's base station not counted. Measured on a 2-vCPU EPYC (1 MiB L2 per core,
/// 32 MiB L3): the hints saved 19-23 % of the user time of a 1000-robot run, were even at
/// 300 robots and cost 7 % at 100, whose nodes stay in cache (docs/performance.md, issue
/// 13's fifth pass).
const LOOK_AHEAD_TEAM: usize = 300;

/// The first stage of loading robot `i`'s messages ahead of its visit (see `Sim::step`): the
/// sequence-table slots they look up. Hints only.
fn load_slots(radio: &Radio, robots: &[RobotNode], base: usize, k: usize) {
    if let Some(r) = robots.get(k) {
        radio.deliver_due(base + k, |from, m| r.core.prefetch_receive(from, m));
    }
}

/// The second stage, once the slots are in: the ports they name. Hints only.
fn load_ports(radio: &Radio, robots: &[RobotNode], base: usize, k: usize) {
    if let Some(r) = robots.get(k) {
        radio.deliver_due(base + k, |from, m| r.core.prefetch_target(from, m));
    }
}

/// Robots a thread takes at the least: below this a share's visits are a few microseconds,
/// no more than handing them to a worker and waiting for it (crate::workers), so a smaller
/// team runs on fewer threads, down to one. Measured: 100 robots on two threads ran 1.4-1.8x
/// faster than on one (docs/performance.md, eighth pass).
const ROBOTS_PER_THREAD: usize = 50;

/// Robots a thread visits in turn before it takes the next block of a tick ([`Sim::set_threads`]):
/// small enough that a thread slowed by the machine leaves most of its work to the others,
/// large enough that a block's first two robots, whose messages were not loaded ahead
/// ([`LOOK_AHEAD_TEAM`]), are few.
const BLOCK: usize = 25;

/// How many threads visit a team of `robots` when [`Sim::set_threads`] allows `allowed`.
fn visit_threads(allowed: usize, robots: usize) -> usize {
    allowed.min(robots / ROBOTS_PER_THREAD).max(1)
}

/// What every visit of one tick reads, shared by the threads that visit.
struct Tick<'a> {
    now: Instant,
    radio: &'a Radio,
    world: &'a World,
    /// Centralized: the oracle's assignment per robot.
    assignment: &'a [Option<usize>],
    /// Whether the bodies observed this tick (their senses are written in the visit).
    sense: bool,
    /// BLE and Local: a bare observer chain (see the drives below).
    chain_only: bool,
    centralized: bool,
    /// Load each robot's messages ahead of its visit ([`LOOK_AHEAD_TEAM`]).
    ahead: bool,
}

/// Visit robots `base..base + robots.len()` in turn: each one's deliveries, its sonar sweep
/// (`sweep` for room) and senses, the oracle's word (Centralized), pose (Planner), its node's run, then its motors. Its outgoing
/// messages go to `outbox` (robot index first) for the radio, in order. In a large team, what a
/// robot's messages will touch in its node loads ahead of its visit, in two stages, so that the
/// loads of each stage overlap one another and the visits between: two visits ahead, the
/// sequence-table slots its messages look up; one visit ahead, the ports those slots name (by
/// then the slots are in cache). A small team's nodes stay in cache from tick to tick: there
/// the hints would only cost.
fn visit(
    tick: &Tick<'_>,
    base: usize,
    robots: &mut [RobotNode],
    commands: &mut [Command],
    drives: &mut [u32],
    outbox: &mut Vec<(usize, Outgoing)>,
    sweep: &mut SonarScratch,
) -> Result<(), Error> {
    let (now, radio) = (tick.now, tick.radio);
    if tick.ahead {
        load_slots(radio, robots, base, 0);
        load_slots(radio, robots, base, 1);
        load_ports(radio, robots, base, 0);
    }
    for k in 0..robots.len() {
        if tick.ahead {
            load_slots(radio, robots, base, k + 2);
            load_ports(radio, robots, base, k + 1);
        }
        let i = base + k;
        let alive = tick.world.robots[i].alive;
        let r = &mut robots[k];
        // A broadcast reaches its receivers as one shared message: nothing copied. In a
        // small team the next message's slot loads while this one is applied.
        if alive && tick.ahead {
            radio.deliver_due(i, |from, msg| r.core.receive_shared(now, from, msg));
        } else if alive {
            radio.deliver_due_ahead(i, |(from, msg), next| {
                if let Some((f, m)) = next {
                    r.core.prefetch_receive(f, m);
                }
                r.core.receive_shared(now, from, msg);
            });
        }
        if !alive {
            continue;
        }
        if tick.sense {
            r.body.write_senses(&mut r.core, now, tick.world, i, sweep)?;
            if let Brain::Follow { pose, .. } = r.brain {
                // Localization: the robot knows where it is (as odometry on a map would).
                let p = tick.world.robots[i].pose;
                r.core.write(now, pose, Value::vector(&[p.x, p.y, p.theta]))?;
            }
        }
        if tick.centralized {
            steer(tick, i, r)?;
        }
        // The next tick comes at its time whatever is due: no `poll_at` scan.
        r.core.run_due(now);
        while let Some(out) = r.core.pop_outgoing() {
            outbox.push((i, out));
        }
        commands[k] = r.body.command(&r.core);
        // Ble and Local build a bare chain: a robot that saw no target lately has no driver,
        // and neither its brain nor its ports need reading.
        drives[k] = if tick.chain_only && chain_quiet(now, r.body.latest_seen()) {
            0
        } else {
            r.brain.drive_seen(&r.core, r.body.seen())
        };
    }
    Ok(())
}

/// The oracle's word to live robot `i` this tick (see [`Sim::plan`]).
fn steer(tick: &Tick<'_>, i: usize, r: &mut RobotNode) -> Result<(), Error> {
    let w = tick.world;
    let (Some(j), Brain::Oracle { angle, assigned }) = (tick.assignment[i], &r.brain) else { return Ok(()) };
    let p = w.robots[i].pose;
    let t = &w.targets[j];
    let bearing = wrap((t.y - p.y).atan2(t.x - p.x) - p.theta);
    let (angle, assigned): (PortRef, PortRef) = (*angle, *assigned);
    r.core.write(tick.now, angle, -bearing)?;
    r.core.write(tick.now, assigned, j as i64 + 1)?;
    Ok(())
}

struct RobotNode {
    core: NodeCore,
    body: Body,
    brain: Brain,
}

/// A run in progress.
pub struct Sim {
    scenario: Scenario,
    world: World,
    radio: Radio,
    robots: Vec<RobotNode>,
    meter: Meter,
    tick: u64,
    dt: Duration,
    frame_every: u64,
    kills_done: Vec<bool>,
    commands: Vec<Command>,
    drives: Vec<u32>,
    stations: Vec<Station>,
    hash: Sha256,
    /// Scratch of `frame`: the bytes it hashes.
    frame_bytes: Vec<u8>,
    coverage: CoverageSeries,
    frames: Vec<Frame>,
    events: Vec<Event>,
    /// Centralized: current assignment target index per robot, and the messages it costs.
    assignment: Vec<Option<usize>>,
    oracle_messages: u64,
    /// Planner: the base station's node and where it stands (the radio's station `robots`).
    planner: Option<(NodeCore, Station)>,
    /// The last tick's (targets observed, priority-weighted fraction observed), for traces.
    last_coverage: (u32, f64),
    /// Whether robots' messages are loaded ahead of their visits (a large team,
    /// [`LOOK_AHEAD_TEAM`]); a hint that changes no outcome.
    look_ahead: bool,
    /// The threads beside the caller's that visit the robots (`Sim::set_threads`).
    workers: Option<Workers>,
    /// Each block's outgoing messages of the tick, kept for their capacity.
    outboxes: Vec<Vec<(usize, Outgoing)>>,
    /// Each visiting thread's room for sonar sweeps.
    sweeps: Vec<Mutex<SonarScratch>>,
}

/// Builds one robot's controller on its node for [`Sim::with_controller`]: the node (body
/// installed), the targets' priorities, the controllers' tunables; returns how to read it.
pub type BuildController<'a> = dyn FnMut(&mut NodeCore, &[f64], &ControllerConfig) -> Result<Brain, Error> + 'a;

/// Node id of robot index `i`.
pub fn node_id(i: usize) -> NodeId {
    NodeId(i as u32 + 1)
}

impl Sim {
    /// A simulation of `scenario` at time 0: world, bodies and controllers built. Errors if the
    /// scenario has a field out of bounds ([`Scenario::validate`], checked before anything is
    /// built) or a controller cannot be built.
    pub fn new(scenario: &Scenario) -> Result<Sim, SimError> {
        let controller = scenario.controller;
        // One copy of each controller class for the whole team (crate::classes).
        let mut classes = SharedClasses::new();
        Sim::with_controller(scenario, &mut |core, prios, cfg| build_shared(core, controller, prios, cfg, &mut classes))
    }

    /// [`Sim::new`] with every robot's controller built by `build` instead of
    /// `scenario.controller`'s (which still names the run and, for `Centralized`, runs the
    /// planner). `build` gets each robot's node with its body (VISION, SONAR, BASE) installed,
    /// the targets' priorities in decreasing order, and `scenario.controllers`; it is how
    /// controllers written elsewhere (the Python package's) run beside the built-in ones. The
    /// scenario is validated first, so `build` is not called for one out of bounds.
    pub fn with_controller(scenario: &Scenario, build: &mut BuildController<'_>) -> Result<Sim, SimError> {
        scenario.validate()?;
        let mut scenario = scenario.clone();
        scenario.world = scenario.world.by_priority();
        let prios: Vec<f64> = scenario.world.targets.iter().map(|t| t.priority).collect();
        let dt = Duration::try_from_secs_f64(scenario.dt)?;
        let world = World::new(scenario.world.clone(), scenario.robots, scenario.seed);
        let planner = scenario.controller == Controller::Planner;
        let stations = scenario.robots + usize::from(planner);
        let mut radio = Radio::new(scenario.radio.clone(), stations, scenario.seed);
        let mut robots = Vec::with_capacity(scenario.robots);
        let mut body_classes = SharedClasses::new();
        for i in 0..scenario.robots {
            let mut core = NodeCore::new(node_id(i));
            let body = Body::install_shared(&mut core, prios.len(), &scenario.world, &mut body_classes)?;
            let brain = build(&mut core, &prios, &scenario.controllers)?;
            radio.set_groups(i, core.groups());
            robots.push(RobotNode { core, body, brain });
        }
        let planner = if planner {
            let mut core = NodeCore::new(PLANNER_NODE);
            build_planner(&mut core, scenario.robots, &scenario.world, &scenario.controllers)?;
            radio.set_groups(scenario.robots, core.groups());
            let [w, h] = scenario.world.arena;
            let [x, y] = scenario.controllers.base_station.unwrap_or([w / 2.0, h / 2.0]);
            Some((core, Station { node: PLANNER_NODE, x, y, alive: true }))
        } else {
            None
        };
        let frame_every = scenario.frame_every();
        let n = scenario.robots;
        let mut sim = Sim {
            meter: Meter::new(&prios, n),
            kills_done: vec![false; scenario.kills.len()],
            scenario,
            world,
            radio,
            robots,
            tick: 0,
            dt,
            frame_every,
            commands: vec![Command::default(); n],
            drives: vec![0; n],
            stations: Vec::with_capacity(n),
            hash: Sha256::new(),
            frame_bytes: Vec::new(),
            coverage: CoverageSeries::default(),
            frames: Vec::new(),
            events: Vec::new(),
            assignment: vec![None; n],
            oracle_messages: 0,
            planner,
            last_coverage: (0, 0.0),
            look_ahead: n >= LOOK_AHEAD_TEAM,
            workers: None,
            outboxes: Vec::new(),
            sweeps: Vec::new(),
        };
        for r in &mut sim.robots {
            r.core.poll(Instant::ZERO);
        }
        if let Some((core, _)) = &mut sim.planner {
            core.poll(Instant::ZERO);
        }
        sim.frame(0, 0.0);
        Ok(sim)
    }

    /// Virtual time now: ticks done times `dt` (never the wall clock).
    pub fn now(&self) -> Instant {
        Instant::from_nanos(self.tick * self.dt.as_nanos())
    }

    /// The world's ground truth now (true positions, no noise).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The node of robot index `i` (0-based; node id `i + 1`), to inspect its ports and
    /// connections, for reports and `why`.
    pub fn core(&self, i: usize) -> &NodeCore {
        &self.robots[i].core
    }

    /// The node of robot index `i`, to change it while the run goes on (a transaction's
    /// messages delivered from outside the radio: crate::redistribution).
    pub fn core_mut(&mut self, i: usize) -> &mut NodeCore {
        &mut self.robots[i].core
    }

    /// The target driving robot `i` now (0: none).
    pub fn drive(&self, i: usize) -> u32 {
        self.drives[i]
    }

    /// The last tick's coverage: (targets observed, priority-weighted fraction observed, 0..1).
    pub fn coverage_now(&self) -> (u32, f64) {
        self.last_coverage
    }

    /// Radio emissions so far, by all robots and the Planner's base station (and the omniscient
    /// planner's words), as `msgs_per_robot_s` counts them.
    pub fn messages_sent(&self) -> u64 {
        self.radio.sent.iter().sum::<u64>() + self.oracle_messages
    }

    /// The scenario being run (targets in decreasing priority).
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// Let up to `threads` threads visit the robots in each tick (1, the default, visits them
    /// on the caller's thread; 0 counts as 1). The outcome is the same bit for bit whatever
    /// the number: only the robots' visits (deliveries, sonar sweeps, senses written, node
    /// runs, motors) are shared out, in blocks of 25 robots taken by whichever thread is free,
    /// while the sensor noise draws, the radio and the world stay in robot order on the
    /// caller's. A thread
    /// takes at least 150 robots, so a smaller team uses fewer threads than allowed; the gain
    /// is for large teams (docs/performance.md). The threads live until the next call or the
    /// end of the run; between two steps each one spins for at most 2 ms, then sleeps.
    /// Errors if the system refuses a thread (the run then stays on the caller's thread).
    pub fn set_threads(&mut self, threads: usize) -> std::io::Result<()> {
        self.workers = None;
        let threads = visit_threads(threads, self.robots.len());
        if threads > 1 {
            self.workers = Some(Workers::new(threads - 1)?);
        }
        Ok(())
    }

    /// How many threads visit the robots in each tick (see [`Sim::set_threads`]).
    pub fn threads(&self) -> usize {
        self.workers.as_ref().map_or(1, Workers::shares)
    }

    /// True once the scenario's duration has been simulated.
    pub fn done(&self) -> bool {
        self.now().as_secs_f64() >= self.scenario.duration - 1e-9
    }

    /// Advance one tick.
    pub fn step(&mut self) -> Result<(), Error> {
        self.tick += 1;
        let now = self.now();
        let t = now.as_secs_f64();
        self.apply_kills(t);
        // Messages due now are set aside before anyone sends, so that what is sent this tick
        // arrives at a later tick whatever the delay (as if every robot ran at once).
        self.radio.take_due(now);
        let sense = self.tick.is_multiple_of(u64::from(self.scenario.sense_every.max(1)));
        if sense {
            self.world.index();
        }
        if self.scenario.controller == Controller::Centralized {
            self.plan();
        }
        self.stations.clear();
        self.stations.extend(self.world.robots.iter().enumerate().map(|(i, r)| Station {
            node: node_id(i),
            x: r.pose.x,
            y: r.pose.y,
            alive: r.alive,
        }));
        if let Some((_, station)) = &self.planner {
            self.stations.push(*station);
        }
        let all_alive = self.stations.iter().all(|s| s.alive);
        // What draws from the sensor noise stream first, robot by robot (the stream's order):
        // the camera frames and the sonar sweeps' draws. The sweeps themselves read only the
        // world, which does not move until every robot has been visited: they run in the
        // visits.
        if sense {
            for (i, r) in self.robots.iter_mut().enumerate() {
                if self.world.robots[i].alive {
                    r.body.observe(&mut self.world, i);
                }
            }
        }
        let tick = Tick {
            now,
            radio: &self.radio,
            world: &self.world,
            assignment: &self.assignment,
            sense,
            chain_only: matches!(self.scenario.controller, Controller::Ble | Controller::Local),
            centralized: self.scenario.controller == Controller::Centralized,
            ahead: self.look_ahead,
        };
        let blocks = match &self.workers {
            None => 1,
            Some(_) => self.robots.len().div_ceil(BLOCK),
        };
        if self.outboxes.len() < blocks {
            self.outboxes.resize_with(blocks, Vec::new);
        }
        let shares = self.workers.as_ref().map_or(1, Workers::shares);
        if self.sweeps.len() < shares {
            self.sweeps.resize_with(shares, || Mutex::new(SonarScratch::default()));
        }
        match &mut self.workers {
            None => {
                let sweep = self.sweeps[0].get_mut().expect("a thread's sweep room");
                visit(&tick, 0, &mut self.robots, &mut self.commands, &mut self.drives, &mut self.outboxes[0], sweep)?
            }
            Some(workers) => {
                // Blocks of robots in turn, each taken by whichever thread is free (this one
                // too), so that a thread slowed by the machine takes fewer: each robot's visit
                // reads only the tick's shared state and writes only its own node, command,
                // drive and its block's outbox, so the split changes nothing but the wall time.
                let parts: Vec<_> = self
                    .robots
                    .chunks_mut(BLOCK)
                    .zip(self.commands.chunks_mut(BLOCK))
                    .zip(self.drives.chunks_mut(BLOCK))
                    .zip(self.outboxes.iter_mut())
                    .map(|(((robots, commands), drives), outbox)| Mutex::new(Some((robots, commands, drives, outbox))))
                    .collect();
                let results: Vec<Mutex<Result<(), Error>>> = parts.iter().map(|_| Mutex::new(Ok(()))).collect();
                let next = AtomicUsize::new(0);
                let (tick, sweeps) = (&tick, &self.sweeps);
                workers.run(&|k| {
                    let mut sweep = sweeps[k].lock().expect("a thread's sweep room");
                    loop {
                        let b = next.fetch_add(1, Relaxed);
                        let Some(part) = parts.get(b) else { break };
                        if let Some((robots, commands, drives, outbox)) = part.lock().expect("a block").take() {
                            *results[b].lock().expect("a block's result") =
                                visit(tick, b * BLOCK, robots, commands, drives, outbox, &mut sweep);
                        }
                    }
                });
                // The first error in robot order, as one thread would have met it.
                for r in results {
                    r.into_inner().expect("a block's result")?;
                }
            }
        }
        // The messages enter the radio in robot order, as if each robot had sent at the end
        // of its visit: nothing sent this tick is delivered before the next one, so no visit
        // could have seen them, and the radio's draws (loss, jitter) keep their order.
        for outbox in &mut self.outboxes[..blocks] {
            for (i, out) in outbox.drain(..) {
                if all_alive {
                    self.radio.send_all_alive(now, i, out, &self.stations);
                } else {
                    self.radio.send(now, i, out, &self.stations);
                }
            }
        }
        if let Some((core, _)) = &mut self.planner {
            let station = self.robots.len();
            self.radio.deliver_due(station, |from, msg| core.receive_shared(now, from, msg));
            core.run_due(now);
            while let Some(out) = core.pop_outgoing() {
                if all_alive {
                    self.radio.send_all_alive(now, station, out, &self.stations);
                } else {
                    self.radio.send(now, station, out, &self.stations);
                }
            }
        }
        self.radio.release_due();
        self.world.step(self.scenario.dt, &self.commands);
        let (observed, weighted) = self.meter.observe(t, self.scenario.dt, &self.world, &self.drives);
        self.last_coverage = (observed, weighted);
        if self.tick.is_multiple_of(self.frame_every) {
            self.frame(observed, weighted);
        }
        Ok(())
    }

    fn apply_kills(&mut self, t: f64) {
        let killed = apply_due_kills(&self.scenario.kills, &mut self.kills_done, t, &mut self.world);
        for &i in &killed {
            self.events.push(Event { t, kind: "kill".into(), robot: node_id(i).0 });
        }
        if !killed.is_empty() {
            self.meter.killed_together(t, &self.world, &killed);
        }
    }

    /// The omniscient planner: every second, give each target in priority order the nearest
    /// free live robot (keeping the current holder unless another free robot is less than
    /// half as far — hysteresis so that it does not thrash); every tick, [`Sim::steer`] tells
    /// each assigned robot the exact bearing of its target.
    fn plan(&mut self) {
        let w = &self.world;
        if self.tick % 20 == 1 {
            let mut free: Vec<bool> = w.robots.iter().map(|r| r.alive).collect();
            let mut next = vec![None; w.robots.len()];
            for (j, t) in w.targets.iter().enumerate() {
                let dist = |i: usize| (w.robots[i].pose.x - t.x).hypot(w.robots[i].pose.y - t.y);
                let nearest = (0..free.len()).filter(|&i| free[i]).min_by(|&a, &b| dist(a).total_cmp(&dist(b)));
                let Some(nearest) = nearest else { break };
                let holder = (0..free.len()).find(|&i| free[i] && self.assignment[i] == Some(j));
                let pick = match holder {
                    Some(h) if dist(nearest) * 2.0 >= dist(h) => h,
                    _ => nearest,
                };
                free[pick] = false;
                next[pick] = Some(j);
            }
            self.oracle_messages += next.iter().filter(|a| a.is_some()).count() as u64;
            self.assignment = next;
        }
    }

    fn frame(&mut self, observed: u32, weighted: f64) {
        let t = self.now().as_secs_f64();
        // The frame's bytes gathered first and hashed in one update: the same bytes in the
        // same order (so the same hash) without the hasher's bookkeeping per field.
        let b = &mut self.frame_bytes;
        b.clear();
        b.extend_from_slice(&t.to_bits().to_le_bytes());
        for (r, drive) in self.world.robots.iter().zip(&self.drives) {
            for v in [r.pose.x, r.pose.y, r.pose.theta] {
                b.extend_from_slice(&v.to_bits().to_le_bytes());
            }
            b.push(r.alive as u8);
            b.extend_from_slice(&drive.to_le_bytes());
        }
        for tg in &self.world.targets {
            b.extend_from_slice(&tg.x.to_bits().to_le_bytes());
            b.extend_from_slice(&tg.y.to_bits().to_le_bytes());
        }
        b.extend_from_slice(&self.radio.sent.iter().sum::<u64>().to_le_bytes());
        self.hash.update(&*b);
        self.coverage.t.push(t);
        self.coverage.observed.push(observed);
        self.coverage.weighted.push(weighted);
        if self.scenario.record {
            let f = self.record_frame(t);
            self.frames.push(f);
        }
    }

    fn record_frame(&self, t: f64) -> Frame {
        let m = self.world.targets.len() as u32;
        let range = self.world.config.observe_range;
        let robots = self
            .world
            .robots
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let core = &self.robots[i].core;
                let mut claims = Vec::new();
                let mut inhibited = Vec::new();
                if self.scenario.controller == Controller::Ble {
                    for n in 1..=m {
                        if let Ok(Some(s)) = core.ble_status(&format!("OBS{n}")) {
                            if s.claiming && r.alive {
                                claims.push(n);
                            }
                            if !s.inhibited_by.is_empty() && r.alive {
                                inhibited.push(n);
                            }
                        }
                    }
                }
                let mut observing = Vec::new();
                if r.alive {
                    self.world.in_view(i, range, |j, _, _| observing.push(j as u32 + 1));
                }
                RobotFrame {
                    x: r.pose.x,
                    y: r.pose.y,
                    theta: r.pose.theta,
                    alive: r.alive,
                    drive: if r.alive { self.drives[i] } else { 0 },
                    claims,
                    inhibited,
                    observing,
                }
            })
            .collect();
        Frame { t, robots, targets: self.world.targets.iter().map(|tg| [tg.x, tg.y]).collect() }
    }

    /// End the run: metrics, hash, series, and the recording if asked.
    pub fn finish(self) -> Outcome {
        let s = &self.scenario;
        let end = self.now().as_secs_f64();
        let sent = self.radio.sent.iter().sum::<u64>() + self.oracle_messages;
        let bytes = self.radio.bytes.iter().sum::<u64>();
        let metrics = self.meter.finish(end, s.robots, sent, bytes);
        let recording = s.record.then(|| Recording {
            meta: RecordingMeta {
                controller: s.controller.name().to_owned(),
                seed: s.seed,
                arena: s.world.arena,
                camera_fov: s.world.camera_fov,
                camera_range: s.world.camera_range,
                observe_range: s.world.observe_range,
                frame_dt: s.frame_dt,
                duration: s.duration,
                loss: s.radio.loss,
            },
            robots: (0..s.robots).map(|i| RobotInfo { id: node_id(i).0, radius: s.world.robot_radius }).collect(),
            targets: s
                .world
                .targets
                .iter()
                .enumerate()
                .map(|(j, t)| TargetInfo { id: j as u32 + 1, priority: t.priority, radius: s.world.target_radius })
                .collect(),
            frames: self.frames,
            events: self.events,
        });
        let hash: String = self.hash.finalize().iter().map(|b| format!("{b:02x}")).collect();
        Outcome {
            metrics,
            trace_hash: hash,
            coverage: self.coverage,
            recording,
            radio: RadioStats {
                sent,
                delivered: self.radio.delivered,
                lost: self.radio.lost,
                cut: self.radio.cut,
                bytes,
            },
        }
    }
}

/// Run `scenario` to its end.
///
/// ```
/// use ayllu_sim::controller::Controller;
/// use ayllu_sim::scenario::{run, Scenario};
/// // The paper's team, 30 s, a robot killed at 15 s.
/// let mut s = Scenario::sized(Controller::Ble, 3, 4, 1).duration(30.0);
/// s.kills.push(ayllu_sim::scenario::Kill { at: 15.0, robot: Some(2) });
/// let out = run(&s).unwrap();
/// assert!((0.0..=1.0).contains(&out.metrics.a_w));
/// assert!(out.metrics.msgs_per_robot_s > 0.0, "BLE talks");
/// // Deterministic: the same scenario, the same run.
/// assert_eq!(run(&s).unwrap().trace_hash, out.trace_hash);
/// ```
pub fn run(scenario: &Scenario) -> Result<Outcome, SimError> {
    run_on(scenario, 1)
}

/// [`run`] with up to `threads` threads visiting the robots ([`Sim::set_threads`]): the same
/// outcome bit for bit, sooner for a large team. If the system refuses a thread, the run uses
/// fewer (the outcome does not depend on them). Errors as [`Sim::new`], or if a step fails.
pub fn run_on(scenario: &Scenario, threads: usize) -> Result<Outcome, SimError> {
    let mut sim = Sim::new(scenario)?;
    let _ = sim.set_threads(threads);
    while !sim.done() {
        sim.step()?;
    }
    Ok(sim.finish())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radio::Partition;

    /// `Sim::step` asks [`Brain::drive_seen`], which skips the layers whose target the body
    /// has not written lately; it must give [`Brain::drive`]'s answer, every robot, every
    /// tick, whatever the radio does to the BLE claims (loss, delay, range, partitions), after
    /// kills, with the planner's override above the chain, and when the senses run every few
    /// ticks.
    #[test]
    fn the_drive_from_what_the_body_saw_is_the_drive_from_the_ports() {
        let mut driven = 0u64;
        for (case, controller) in
            [Controller::Ble, Controller::Local, Controller::Planner, Controller::Ble].into_iter().enumerate()
        {
            for seed in [3, 11] {
                let mut s = Scenario::sized(controller, 12, 5, seed).loss(0.3).duration(40.0);
                s.radio.delay = 0.05;
                s.radio.jitter = 0.03;
                s.radio.range = Some(7.0);
                s.radio.partitions.push(Partition { start: 8.0, end: 18.0, island: vec![1, 2, 3, 4] });
                s.kills.push(Kill { at: 12.0, robot: None });
                s.kills.push(Kill { at: 25.0, robot: Some(5) });
                if case == 3 {
                    s.sense_every = 3;
                }
                let mut sim = Sim::new(&s).expect("builds");
                while !sim.done() {
                    sim.step().expect("steps");
                    for (i, r) in sim.robots.iter().enumerate() {
                        if !sim.world.robots[i].alive {
                            continue;
                        }
                        let old = r.brain.drive(&r.core);
                        assert_eq!(r.brain.drive_seen(&r.core, r.body.seen()), old, "{controller:?} {seed} robot {i}");
                        if matches!(r.brain, Brain::Chain(_)) && chain_quiet(r.core.now(), r.body.latest_seen()) {
                            assert_eq!(old, 0, "{controller:?} {seed} robot {i}");
                        }
                        assert_eq!(sim.drives[i], old);
                        driven += u64::from(old != 0);
                    }
                }
            }
        }
        // Not vacuous: observers drove often.
        assert!(driven > 10_000, "{driven}");
    }

    /// Loading messages ahead is a hint: a large team's run with it is the run without it,
    /// bit for bit, with loss, a range limit, a partition and kills (dead robots' messages
    /// are looked at but not delivered).
    #[test]
    fn loading_ahead_changes_nothing() {
        let mut s = Scenario::sized(Controller::Ble, LOOK_AHEAD_TEAM + 5, 5, 9).loss(0.2).duration(4.0);
        s.radio.range = Some(30.0);
        s.radio.partitions.push(Partition { start: 1.0, end: 2.0, island: (1..100).collect() });
        s.kills.push(Kill { at: 1.5, robot: None });
        s.kills.push(Kill { at: 2.5, robot: Some(7) });
        // Every node's report (each port's value, counts and drops) and the run's outcome.
        let outcome = |ahead: bool| {
            let mut sim = Sim::new(&s).expect("builds");
            assert!(sim.look_ahead, "the team is large enough");
            sim.look_ahead = ahead;
            while !sim.done() {
                sim.step().expect("steps");
            }
            let nodes: Vec<_> = sim.robots.iter().map(|r| r.core.report()).collect();
            (nodes, sim.finish())
        };
        let ((nodes_with, with), (nodes_without, without)) = (outcome(true), outcome(false));
        for (i, (a, b)) in nodes_with.iter().zip(&nodes_without).enumerate() {
            assert_eq!(a, b, "robot {i}");
        }
        assert_eq!(with.trace_hash, without.trace_hash);
        assert_eq!(with.radio, without.radio);
        assert_eq!(with.metrics, without.metrics);
        assert!(with.radio.delivered > 10_000, "messages flowed: {:?}", with.radio);
    }

    /// Sharing a tick's visits among threads (`Sim::set_threads`) must give the run of one
    /// thread bit for bit: every controller (the Centralized oracle's words and the Planner's
    /// base station included), with loss, jitter, a range limit, a partition and kills, split
    /// in two and in three unequal shares, and a team large enough to load its messages
    /// ahead of the visits.
    #[test]
    fn threads_change_nothing() {
        let mut cases: Vec<(Scenario, usize)> = Controller::ALL
            .iter()
            .map(|&c| {
                let mut s = Scenario::sized(c, 3 * ROBOTS_PER_THREAD + 7, 5, 4).loss(0.15).duration(5.0);
                s.radio.jitter = 0.03;
                s.radio.range = Some(25.0);
                s.radio.partitions.push(Partition { start: 1.0, end: 2.0, island: (1..40).collect() });
                s.kills.push(Kill { at: 1.5, robot: None });
                s.kills.push(Kill { at: 2.5, robot: Some(ROBOTS_PER_THREAD as u32 + 1) });
                (s, 3)
            })
            .collect();
        cases.push((Scenario::sized(Controller::Ble, LOOK_AHEAD_TEAM + 5, 5, 9).loss(0.1).duration(3.0), 2));
        for (s, threads) in cases {
            let outcome = |threads: usize| {
                let mut sim = Sim::new(&s).expect("builds");
                sim.set_threads(threads).expect("the threads start");
                assert_eq!(sim.threads(), threads);
                while !sim.done() {
                    sim.step().expect("steps");
                }
                let nodes: Vec<_> = sim.robots.iter().map(|r| r.core.report()).collect();
                (nodes, sim.finish())
            };
            let ((nodes_one, one), (nodes_more, more)) = (outcome(1), outcome(threads));
            let name = s.controller.name();
            for (i, (a, b)) in nodes_one.iter().zip(&nodes_more).enumerate() {
                assert_eq!(a, b, "{name}: robot {i}");
            }
            assert_eq!(one.trace_hash, more.trace_hash, "{name}");
            assert_eq!(one.radio, more.radio, "{name}");
            assert_eq!(one.metrics, more.metrics, "{name}");
            assert_eq!(one.coverage, more.coverage, "{name}");
            if matches!(s.controller, Controller::Ble | Controller::Planner) {
                assert!(one.radio.delivered > 1000, "{name}: messages flowed: {:?}", one.radio);
            }
        }
    }

    /// A team too small for two shares of [`ROBOTS_PER_THREAD`] runs on one thread whatever is
    /// allowed, and 0 counts as 1.
    #[test]
    fn small_teams_stay_on_one_thread() {
        let mut sim = Sim::new(&Scenario::sized(Controller::Ble, 2 * ROBOTS_PER_THREAD - 1, 4, 1)).unwrap();
        sim.set_threads(8).unwrap();
        assert_eq!(sim.threads(), 1);
        sim.set_threads(0).unwrap();
        assert_eq!(sim.threads(), 1);
        let mut sim = Sim::new(&Scenario::sized(Controller::Ble, 2 * ROBOTS_PER_THREAD, 4, 1)).unwrap();
        sim.set_threads(8).unwrap();
        assert_eq!(sim.threads(), 2);
    }

    /// `Sim::new` defines one copy of each class on every robot (crate::classes); each robot
    /// building its own classes (`controller::build`, as `with_controller` callers do) must
    /// give the same run bit for bit, for every controller: no class keeps per-robot state.
    #[test]
    fn sharing_classes_changes_nothing() {
        for controller in Controller::ALL {
            let mut s = Scenario::sized(controller, 12, 4, 5).loss(0.1).duration(6.0);
            s.kills.push(Kill { at: 3.0, robot: Some(2) });
            let run_with = |sim: Sim| {
                let mut sim = sim;
                while !sim.done() {
                    sim.step().expect("steps");
                }
                let nodes: Vec<_> = sim.robots.iter().map(|r| r.core.report()).collect();
                (nodes, sim.finish())
            };
            let (nodes_shared, shared) = run_with(Sim::new(&s).expect("builds"));
            let own = Sim::with_controller(&s, &mut |core, prios, cfg| {
                crate::controller::build(core, controller, prios, cfg)
            });
            let (nodes_own, own) = run_with(own.expect("builds"));
            for (i, (a, b)) in nodes_shared.iter().zip(&nodes_own).enumerate() {
                assert_eq!(a, b, "{} robot {i}", controller.name());
            }
            assert_eq!(shared.trace_hash, own.trace_hash, "{}", controller.name());
            assert_eq!(shared.metrics, own.metrics, "{}", controller.name());
        }
    }
}
