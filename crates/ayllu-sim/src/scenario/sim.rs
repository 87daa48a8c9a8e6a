//! The run itself: [`Sim`] builds a scenario's world, robots' nodes and radio, then steps them
//! tick by tick (a tick's order is told in [`crate::scenario`]); [`run`] and [`run_on`] take a
//! scenario to its end.
//!
//! Promise: the outcome is a pure function of the scenario, bit for bit, whatever the number
//! of threads; nothing is built for a scenario out of bounds.

use ayllu_core::{Duration, Error, Instant, NodeCore, NodeId, Outgoing};
use sha2::{Digest, Sha256};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::Mutex;

use super::kills::apply_due_kills;
use super::outcome::{Outcome, RadioStats, SimError};
use super::visit::{visit, visit_threads, RobotNode, Tick, BLOCK, LOOK_AHEAD_TEAM};
use crate::body::Body;
use crate::classes::SharedClasses;
use crate::controller::{build_in, build_planner, Brain, Controller, ControllerConfig, PLANNER_NODE};
use crate::metrics::Meter;
use crate::radio::{Partition, Radio, Station};
use crate::recording::{CoverageSeries, Event, Frame, Recording, RecordingMeta, RobotFrame, RobotInfo, TargetInfo};
use crate::scenario_spec::{BaseStationLoss, Scenario};
use crate::workers::Workers;
use crate::world::{Command, SonarScratch, World};

/// A run in progress.
pub struct Sim {
    scenario: Scenario,
    pub(super) world: World,
    radio: Radio,
    pub(super) robots: Vec<RobotNode>,
    meter: Meter,
    tick: u64,
    dt: Duration,
    frame_every: u64,
    kills_done: Vec<bool>,
    /// Whether the base station's failure has happened.
    base_station_failed: bool,
    commands: Vec<Command>,
    pub(super) drives: Vec<u32>,
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
    pub(super) look_ahead: bool,
    /// Whether any robot's brain takes its pose (Planner, BLE-seek): the visits of the others
    /// need not read their brains on a sensing tick.
    localize: bool,
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
        let size = scenario.world.focal * scenario.world.target_height;
        Sim::with_controller(scenario, &mut |core, prios, cfg| {
            build_in(core, controller, prios, size, cfg, &mut classes)
        })
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
        let mut radio_config = scenario.radio.clone();
        if let Some(f) =
            scenario.base_station_failure.as_ref().filter(|f| planner && f.how == BaseStationLoss::Partitioned)
        {
            // The base station alone on its side of a partition: it hears no robot, no robot hears it.
            radio_config.partitions.push(Partition {
                start: f.at,
                end: f.until.unwrap_or(f64::INFINITY),
                island: vec![PLANNER_NODE.0],
            });
        }
        let mut radio = Radio::new(radio_config, stations, scenario.seed);
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
        let localize = robots.iter().any(|r| matches!(r.brain, Brain::Follow { .. } | Brain::Seek { .. }));
        let mut sim = Sim {
            meter: Meter::new(&prios, n),
            kills_done: vec![false; scenario.kills.len()],
            base_station_failed: false,
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
            localize,
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
        self.apply_base_station_failure(t);
        // Messages due now are set aside before anyone sends, so that what is sent this tick
        // arrives at a later tick whatever the delay (as if every robot ran at once).
        self.radio.take_due(now);
        let sense_every = u64::from(self.scenario.sense_every.max(1));
        let sense = self.tick.is_multiple_of(sense_every);
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
            chain_only: matches!(self.scenario.controller, Controller::Ble | Controller::BleLean | Controller::Local),
            centralized: self.scenario.controller == Controller::Centralized,
            localize: self.localize,
            ahead: self.look_ahead,
            // One thread walks the team forth and back in turn: a tick starts with the nodes
            // the last one ended with, still in the cache, where a walk in the same order
            // each tick would find the least recently used ones first, evicted whenever the
            // team's nodes outgrow the cache (a 1000-robot team: docs/performance.md). The
            // turn comes every `sense_every` ticks, not every tick, so that the ticks that
            // sense (and the stdlib's 10 Hz processes, which run on the same ticks at the
            // default 2) alternate too: what only those ticks touch (ranges, sightings, the
            // motor processes' ports) is then found again before a whole team's worth of
            // every-tick state has passed through the cache, where flipping every tick sent
            // every sensing tick the same way. The visits are independent
            // (crate::scenario::visit), so their order changes no outcome; the threads keep
            // the blocks' order.
            backward: self.workers.is_none() && (self.tick / sense_every) % 2 == 1,
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
        if let Some((core, s)) = &mut self.planner {
            let station = self.robots.len();
            if !s.alive {
                // A killed base station hears nothing and does nothing.
                self.radio.deliver_due(station, |_, _| {});
                self.radio.release_due();
                return self.finish_tick(t);
            }
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
        self.finish_tick(t)
    }

    /// The end of a tick: the world moves, the metrics count it, a frame every `frame_dt`.
    fn finish_tick(&mut self, t: f64) -> Result<(), Error> {
        self.world.step(self.scenario.dt, &self.commands);
        let (observed, weighted) = self.meter.observe(t, self.scenario.dt, &self.world, &self.drives);
        self.last_coverage = (observed, weighted);
        if self.tick.is_multiple_of(self.frame_every) {
            self.frame(observed, weighted);
        }
        Ok(())
    }

    /// The base station's failure when due (Planner runs): killed, it stops; cut off, the
    /// radio's partition (made with the radio) does the rest. Either is an event of the run.
    fn apply_base_station_failure(&mut self, t: f64) {
        let (Some(f), Some((_, station))) = (&self.scenario.base_station_failure, &mut self.planner) else { return };
        if self.base_station_failed || t < f.at {
            return;
        }
        self.base_station_failed = true;
        let kind = match f.how {
            BaseStationLoss::Killed => {
                station.alive = false;
                "base station killed"
            }
            BaseStationLoss::Partitioned => "base station cut off",
        };
        self.events.push(Event { t, kind: kind.into(), robot: PLANNER_NODE.0 });
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
                if matches!(self.scenario.controller, Controller::Ble | Controller::BleLean | Controller::BleSeek) {
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
