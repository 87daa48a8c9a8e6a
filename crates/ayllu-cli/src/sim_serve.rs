//! The simulator's distributed mode: `ayllu sim serve` hosts the world, `ayllu sim robot` runs
//! one robot's controller as its own OS process. They talk real UDP, as a team of real robots
//! and their drivers would; the controllers talk to each other (BLE group `Peers`) by the
//! udp:// transport's group delivery (subnet broadcast, or unicast to the peers that announced
//! the group). Over `zenoh://` (the `ayllu-zenoh` tool, docs/zenoh.md) the same run crosses
//! Zenoh instead: the URLs are the only difference.
//!
//! Node ids (docs/cli.md): controller of robot K = node K (1..=N, as in the in-process
//! simulator); its body on the server = node [`BODY_BASE`] + K. The server connects each body's
//! `VISION.Target{n}Angle/Bottom` and `SONAR.Ranges` to the same ports of node K; the robot
//! connects its `BASE.Rotate/Translate` to the same ports of node `BODY_BASE + K`. Neither side
//! is told the other's address: a body greets the addresses its URL names (`peer=`,
//! `broadcast=`) and its controller greets back, and from then on each routes by node id.
//!
//! With `--scenario FILE` (the same file for `sim serve` and every `sim robot`) the run is that
//! scenario's: its world, team, seed and duration; its kills, carried out by the server at their
//! instants (the world marks the robot dead, its body stops, and its process is told to stop
//! through `LINK.Alive` and exits); and its radio, applied to the controllers' real traffic by
//! each robot's [`ayllu_sim::served_radio::RadioLink`] (loss, delay and jitter drawn at the
//! receiver; range and partitions from the reachability the server computes on the world's true
//! positions and sends each robot every sensing tick). docs/cmommt.md, "The distributed mode".
//!
//! Promises:
//! * the world is the in-process one: the scenario's (`Scenario::sized(.., robots, targets,
//!   seed)` without a file), the same seed, a 50 ms tick (camera and sonar at 10 Hz) paced on the
//!   real clock; coverage is measured on the world's ground truth with the same [`Meter`];
//! * the controllers are built by [`ayllu_sim::controller::build`] unchanged, on a node whose
//!   VISION/SONAR/BASE are local behaviors of the same classes, fed and read over the network;
//! * a body whose motor commands stop arriving stops the robot ([`WATCHDOG`]), as a Pioneer's
//!   firmware does;
//! * stdout carries only JSON lines (a robot's first says where it listens, then one per
//!   `--status-ms`); both commands stop cleanly on
//!   Ctrl-C / SIGTERM (the server still prints its final metrics line).
//!
//! * the metrics are the in-process ones: switches from the drive each robot reports
//!   (`LINK.Drive`), messages and bytes per robot per second from the radio emissions each robot
//!   counts (`LINK.Sent`, `LINK.Bytes`: what it last reported, at most 250 ms old), kills judged
//!   together as in-process ([`ayllu_sim::scenario::apply_due_kills`]).
//!
//! `centralized` and `planner` are refused: the first needs the world's truth, the second a base
//! station, which only exist in-process.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::stdlib::{BASE, SONAR, VISION};
use ayllu::{ConnectionKind, Endpoint, MonotonicClock, Node, NodeId, PortRef, UdpConfig};
use ayllu_sim::body::Body;
use ayllu_sim::controller::{build, Brain, Controller, ControllerConfig};
use ayllu_sim::metrics::Meter;
use ayllu_sim::radio::{RadioConfig, Station};
use ayllu_sim::scenario::{apply_due_kills, node_id, priorities, Scenario};
use ayllu_sim::scenario_file;
use ayllu_sim::served_radio::{reach_row, LinkHandle, RadioLink};
use ayllu_sim::served_robot::LINK;
use ayllu_sim::world::{Command, World, WorldConfig};
use clap::Args;
use serde_json::{json, Value as Json};

use crate::fail::Fail;
use crate::text::{listening_json, round3};
use crate::{parse_node, positive_secs, signals};

/// The body of robot K is node `BODY_BASE + K` (the robot's side: `ayllu_sim::served_robot`).
pub use ayllu_sim::served_robot::BODY_BASE;
/// Robots are numbered 1..=N below the bodies' ids.
const MAX_ROBOTS: u64 = BODY_BASE as u64 - 1;
/// The world's tick and its camera/sonar divider (the in-process defaults).
/// A body whose `BASE` has not been written for this long stops (the controller is gone).
const WATCHDOG: ayllu::Duration = ayllu::Duration::from_secs(1);
/// How often a robot reports its radio counts to the server (`LINK.Sent`, `LINK.Bytes`).
const REPORT_PERIOD: StdDuration = StdDuration::from_millis(250);
/// The world's tick: a robot looks at its drive and the server's word this often.
const TICK: StdDuration = StdDuration::from_millis(50);
/// If the server falls this far behind the real clock, it stops trying to catch up.
const MAX_LAG: StdDuration = StdDuration::from_millis(500);
/// How long a ROS 2 body's sonar must stay stale before its robot takes the server for gone: a
/// scan or two lost on a lossy network (best-effort, 10 Hz) must not stop the robot. (A UDP
/// body's peer entry already outlives three silent HELLO periods.)
const ROS2_SILENCE: StdDuration = StdDuration::from_secs(2);

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// A scenario file (docs/cmommt.md, "Studies as files"): its world, team, seed and duration,
    /// its kills (carried out here) and its radio (applied by robots given the same file).
    /// Replaces --robots, --targets, --seed and --duration.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["robots", "targets", "seed", "duration"])]
    pub scenario: Option<PathBuf>,
    /// How many robots (their controllers are nodes 1..=N, their bodies nodes 1001..=1000+N).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=MAX_ROBOTS))]
    pub robots: u64,
    /// How many targets (priorities M, M-1, ..., 1).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u64).range(1..=64))]
    pub targets: u64,
    /// The world's seed (start poses, target motion, sensor noise), as in `sim cmommt`.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seconds of world time to run (paced on the real clock) [default: 300; with --ros2,
    /// until stopped].
    #[arg(long, value_name = "SECS", value_parser = positive_secs)]
    pub duration: Option<f64>,
    /// The bodies' udp:// URLs (or zenoh:// in ayllu-zenoh): one per robot in order, or a
    /// single one for all in which `{i}` stands for the robot's number (a single URL without
    /// `{i}` must bind, or listen on, port 0). Each body
    /// greets the addresses its URL names (peer=, broadcast=); its controller greets back.
    #[arg(long, value_name = "URL", required_unless_present = "ros2", conflicts_with = "ros2")]
    pub udp: Vec<String>,
    /// Serve every robot's body as ROS 2 topics under /robotK/ (scan, odom, targetN, cmd_vel;
    /// docs/ros2.md) instead of over Ayllu: controllers run with a ROS 2 body
    /// (`sim robot --ros2 examples/ros2/sim-robot.toml`). Needs the tool built with ROS 2.
    #[arg(long)]
    pub ros2: bool,
    /// --ros2: the ROS domain id [default: $ROS_DOMAIN_ID, else 0].
    #[arg(long, value_name = "ID", requires = "ros2", value_parser = clap::value_parser!(u16).range(0..=232))]
    pub domain: Option<u16>,
    /// Wait this long for every body to hear its controller before the world starts (it
    /// starts anyway after that, and late controllers join when they come).
    #[arg(long, value_name = "SECS", default_value_t = 10.0, value_parser = positive_secs)]
    pub wait: f64,
    /// Print a JSON status line this often (world time).
    #[arg(long, value_name = "MS", default_value_t = 1000, value_parser = clap::value_parser!(u64).range(50..))]
    pub status_ms: u64,
}

#[derive(Args, Debug)]
pub struct RobotArgs {
    /// This robot's number K: its controller is node K, its body node 1000+K.
    #[arg(long, value_parser = parse_node)]
    pub id: NodeId,
    /// The scenario file the server runs (the same file): its targets, controller tunables,
    /// seed, and the radio this robot applies to what it hears from its peers. Replaces
    /// --targets, --seed and --claim-hz.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["targets", "seed", "claim_hz"])]
    pub scenario: Option<PathBuf>,
    /// The controller: ble, local, random or forcefield (centralized and planner exist only
    /// in-process) [default: the scenario's, else ble].
    #[arg(long, value_name = "NAME", value_parser = parse_distributed_controller)]
    pub controller: Option<Controller>,
    /// How many targets (must match the server's).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u64).range(1..=64))]
    pub targets: u64,
    /// Seed of the wander behavior (the in-process simulator uses the world's seed).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// BLE claims per second.
    #[arg(long, value_name = "HZ", default_value_t = 1.0, value_parser = crate::positive_hz)]
    pub claim_hz: f64,
    /// The controller node's udp:// URL: its address, and how it finds its peers (peer=,
    /// broadcast=, discovery=); or a zenoh:// URL in ayllu-zenoh (docs/zenoh.md). Its body finds it (the server's URLs name it). Default:
    /// $AYLLU_URL, else discovery on this machine.
    #[arg(long, value_name = "URL", default_value_t = ayllu::default_url())]
    pub udp: String,
    /// Stop after this many seconds (default: until Ctrl-C or SIGTERM).
    #[arg(long, value_name = "SECS", value_parser = positive_secs)]
    pub duration: Option<f64>,
    /// Print a JSON status line this often.
    #[arg(long, value_name = "MS", default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..))]
    pub status_ms: u64,
    /// The body is behind ROS 2 topics, as this mapping file says (`sim serve --ros2`'s
    /// robots: examples/ros2/sim-robot.toml; docs/ros2.md). Needs the tool built with ROS 2.
    #[arg(long, value_name = "FILE")]
    pub ros2: Option<PathBuf>,
}

fn parse_distributed_controller(s: &str) -> Result<Controller, String> {
    match Controller::parse(s) {
        Some(c) => distributed(c),
        None => Err(format!("`{s}` is not a controller (ble, local, random, forcefield)")),
    }
}

fn distributed(c: Controller) -> Result<Controller, String> {
    match c {
        Controller::Centralized => Err("centralized is not available in distributed mode: its planner \
             reads the world's true state, which only `sim serve` has (use `sim cmommt` for it)"
            .into()),
        Controller::Planner => Err("planner is not available in distributed mode: its base station exists \
             only in-process (use `sim run` or `sim cmommt` for it)"
            .into()),
        c => Ok(c),
    }
}

/// The scenario in `path` (docs/cmommt.md, "Studies as files").
fn read_scenario(path: &PathBuf) -> Result<Scenario, Fail> {
    let text = std::fs::read_to_string(path).map_err(|e| Fail::error(format!("reading {}: {e}", path.display())))?;
    scenario_file::scenario(&text).map_err(|e| Fail::error(format!("{}: {e}", path.display())))
}

fn body_id(robot: u32) -> NodeId {
    ayllu_sim::served_robot::body_node(robot)
}

/// Node `id`'s transport on `url`, named `name` unless the URL names it: `udp://`, or any
/// scheme the tool knows (`zenoh://` in `ayllu-zenoh`, docs/zenoh.md).
fn open_transport(url: &str, id: NodeId, name: &str) -> Result<Box<dyn ayllu::Transport>, Fail> {
    crate::client::network_url(url)?;
    Ok(ayllu::transport::open_named(url, id, name)?)
}

/// The URL of robot `k`'s body (1-based) from the `--udp` list (see [`ServeArgs::udp`]).
fn body_url(urls: &[String], robots: usize, k: usize) -> Result<String, Fail> {
    match urls {
        [one] => {
            if robots > 1 && !one.contains("{i}") {
                // zenoh:// (and other registered schemes) bind what `listen=` names.
                let fixed = match UdpConfig::parse(one) {
                    Ok(c) => c.bind.port() != 0,
                    Err(_) => ayllu::transport::url_setting(one, "listen").is_some_and(|l| !l.ends_with(":0")),
                };
                if fixed {
                    return Err(Fail::usage(format!(
                        "one --udp URL for {robots} bodies must use `{{i}}` or bind port 0 (got `{one}`)"
                    )));
                }
            }
            Ok(one.replace("{i}", &k.to_string()))
        }
        many if many.len() == robots => Ok(many[k - 1].clone()),
        many => Err(Fail::usage(format!("{} --udp URLs for {robots} robots: give one per robot, or one", many.len()))),
    }
}

/// One robot's body on the server: a node of its own, the body's ports, the controller it
/// feeds.
struct BodyNode {
    node: Node,
    body: Body,
    rotate: PortRef,
    translate: PortRef,
    controller: NodeId,
    /// `LINK.Reach`, `Alive`, `Drive`, `Sent`, `Bytes` (ayllu_sim::served_robot).
    link: [PortRef; 5],
    /// With --ros2: `ODOM.X`, `Y`, `Yaw`, `Translate`, `Rotate`, and the counter that says
    /// whether the controller's `cmd_vel` samples arrive.
    ros2: Option<([PortRef; 5], String)>,
}

/// World seconds served when neither --duration nor a scenario says (the UDP mode).
const DEFAULT_DURATION: f64 = 300.0;
/// "Until stopped": a world time no run reaches (about 31 years).
const UNTIL_STOPPED: f64 = 1e9;

/// The DDS participant every ROS 2 body of the fleet shares.
#[cfg(feature = "ros2")]
struct Fleet(ayllu_ros2::Context);

#[cfg(feature = "ros2")]
impl Fleet {
    fn open(domain: Option<u16>) -> Result<Fleet, Fail> {
        let domain = match domain {
            Some(d) => d,
            None => match std::env::var("ROS_DOMAIN_ID") {
                Ok(s) if !s.trim().is_empty() => s
                    .trim()
                    .parse::<u16>()
                    .ok()
                    .filter(|d| *d <= 232)
                    .ok_or_else(|| Fail::usage(format!("ROS_DOMAIN_ID=`{s}` is not a ROS domain id (0 to 232)")))?,
                _ => 0,
            },
        };
        Ok(Fleet(ayllu_ros2::participant(domain).map_err(|e| Fail::error(e.to_string()))?))
    }
}

#[cfg(not(feature = "ros2"))]
struct Fleet;

#[cfg(not(feature = "ros2"))]
impl Fleet {
    fn open(_domain: Option<u16>) -> Result<Fleet, Fail> {
        Err(Fail::error(crate::controllers::ROS2_MISSING))
    }
}

impl BodyNode {
    fn open(k: u32, url: &str, targets: usize, world: &WorldConfig) -> Result<BodyNode, Fail> {
        let id = body_id(k);
        let mut node = Node::new(MonotonicClock::new(), open_transport(url, id, &format!("body-{k}"))?);
        let body = Body::install(node.core_mut(), targets, world)?;
        let controller = NodeId(k);
        let mut sensors: Vec<(&str, String)> = (1..=targets)
            .flat_map(|n| [(VISION, format!("Target{n}Angle")), (VISION, format!("Target{n}Bottom"))])
            .collect();
        sensors.push((SONAR, "Ranges".to_owned()));
        for (behavior, port) in &sensors {
            node.connect(
                &Endpoint::local(behavior, port),
                &Endpoint::node(controller, behavior, port),
                ConnectionKind::Normal,
            )?;
        }
        ayllu_sim::served_robot::install_body_link(node.core_mut(), k)?;
        BodyNode::assemble(node, body, controller, None)
    }

    /// The handles every served body keeps: BASE's motor ports and LINK's five.
    fn assemble(
        node: Node,
        body: Body,
        controller: NodeId,
        ros2: Option<([PortRef; 5], String)>,
    ) -> Result<BodyNode, Fail> {
        let core = node.core();
        let rotate = core.port(BASE, "Rotate")?;
        let translate = core.port(BASE, "Translate")?;
        let link = [
            core.port(LINK, "Reach")?,
            core.port(LINK, "Alive")?,
            core.port(LINK, "Drive")?,
            core.port(LINK, "Sent")?,
            core.port(LINK, "Bytes")?,
        ];
        Ok(BodyNode { node, body, rotate, translate, controller, link, ros2 })
    }

    /// Robot `k`'s body as ROS 2 topics (`ayllu_ros2::fleet`): a node of its own on an
    /// in-process transport (it talks to nobody over Ayllu), its body behind a ROS 2 body.
    #[cfg(feature = "ros2")]
    fn open_ros2(k: u32, fleet: &Fleet, targets: usize, world: &WorldConfig) -> Result<BodyNode, Fail> {
        let id = body_id(k);
        let mut node = Node::open(id, &format!("mem://ayllu-sim-ros2-{}", std::process::id()))?;
        let body = Body::install(node.core_mut(), targets, world)?;
        let driver = ayllu_ros2::fleet::install_served(node.core_mut(), k, targets, world, &fleet.0)
            .map_err(|e| Fail::error(e.to_string()))?;
        node.attach(driver);
        let core = node.core();
        let odom = ayllu_ros2::fleet::ODOM;
        let odom = [
            core.port(odom, "X")?,
            core.port(odom, "Y")?,
            core.port(odom, "Yaw")?,
            core.port(odom, "Translate")?,
            core.port(odom, "Rotate")?,
        ];
        // Samples taken, not publishers matched: the controller's commands arrive. (Matches were
        // once counted from the ROS 2 node's match events, which the fleet's bodies, sharing one
        // participant, drain from one channel: a body could miss its controller's.)
        let heard = format!("/robot{k}/cmd_vel taken");
        BodyNode::assemble(node, body, NodeId(k), Some((odom, heard)))
    }

    #[cfg(not(feature = "ros2"))]
    fn open_ros2(_k: u32, _fleet: &Fleet, _targets: usize, _world: &WorldConfig) -> Result<BodyNode, Fail> {
        Err(Fail::error(crate::controllers::ROS2_MISSING))
    }

    /// With --ros2: the pose and the command now, for `/robotK/odom`.
    fn odometry(&mut self, pose: &ayllu_sim::world::Pose, command: &Command) -> Result<(), Fail> {
        let Some((odom, _)) = &self.ros2 else { return Ok(()) };
        let odom = *odom;
        let now = self.node.now();
        let core = self.node.core_mut();
        for (port, x) in odom.iter().zip([pose.x, pose.y, pose.theta, command.translate, command.rotate]) {
            core.write(now, *port, x)?;
        }
        Ok(())
    }

    /// An int the robot reports on `LINK` (0 until it has).
    fn reported(&self, port: usize) -> u64 {
        self.node.core().read(self.link[port]).ok().and_then(|v| v.as_int()).unwrap_or(0).max(0) as u64
    }

    /// Tell the robot who it hears now and whether it is alive.
    fn tell(&mut self, reach: &[f64], alive: bool) -> Result<(), Fail> {
        let now = self.node.now();
        let core = self.node.core_mut();
        core.write(now, self.link[0], ayllu::Value::vector(reach))?;
        core.write(now, self.link[1], i64::from(alive))?;
        Ok(())
    }

    /// Whether the body has heard its controller (it can send it the sensors); with --ros2,
    /// whether its controller's `cmd_vel` samples have arrived.
    fn linked(&self) -> bool {
        match &self.ros2 {
            Some((_, heard)) => self.node.core().body_counters().iter().any(|(k, n)| k == heard && *n > 0),
            None => self.node.peers().iter().any(|p| p.node == self.controller),
        }
    }

    /// The motor command, or a stop if the controller has been silent for [`WATCHDOG`].
    fn command(&self) -> Command {
        let core = self.node.core();
        let now = self.node.now();
        let recent = |p| core.last_accepted(p).ok().flatten().is_some_and(|t| now < t + WATCHDOG);
        if recent(self.rotate) || recent(self.translate) {
            self.body.command(core)
        } else {
            Command::default()
        }
    }
}

/// `ayllu sim serve`.
pub fn serve(args: &ServeArgs) -> Result<(), Fail> {
    // The in-process world, targets numbered by decreasing priority (OBSn follows TargetN),
    // with the in-process tick and sensing rate, as `scenario::Sim` runs it.
    let scenario = match &args.scenario {
        Some(path) => read_scenario(path)?,
        // With --ros2 and no duration the world runs until stopped, as a robot's driver does.
        None => Scenario::sized(Controller::Random, args.robots as usize, args.targets as usize, args.seed)
            .duration(args.duration.unwrap_or(if args.ros2 { UNTIL_STOPPED } else { DEFAULT_DURATION })),
    };
    let robots = scenario.robots;
    let targets = scenario.world.targets.len();
    if robots as u64 > MAX_ROBOTS {
        return Err(Fail::usage(format!("{robots} robots: distributed mode takes at most {MAX_ROBOTS}")));
    }
    let (dt, sense_every) = (scenario.dt, u64::from(scenario.sense_every.max(1)));
    let config = scenario.world.by_priority();
    let prios: Vec<f64> = config.targets.iter().map(|t| t.priority).collect();
    let mut bodies = Vec::with_capacity(robots);
    if args.ros2 {
        let fleet = Fleet::open(args.domain)?;
        for k in 1..=robots {
            bodies.push(BodyNode::open_ros2(k as u32, &fleet, targets, &config)?);
        }
    } else {
        for k in 1..=robots {
            bodies.push(BodyNode::open(k as u32, &body_url(&args.udp, robots, k)?, targets, &config)?);
        }
    }
    let mut world = World::new(config.clone(), robots, scenario.seed);
    signals::install();
    let mut out = std::io::stdout().lock();

    // Let every body find its controller before the clock starts, so that the run measures
    // the team, not the time its processes took to start.
    let waited = StdInstant::now();
    let limit = StdDuration::from_secs_f64(args.wait);
    while !bodies.iter().all(BodyNode::linked) && waited.elapsed() < limit && !signals::stopped() {
        for b in &mut bodies {
            b.node.step();
        }
        std::thread::sleep(StdDuration::from_millis(20));
    }
    let missing: Vec<u32> = bodies.iter().filter(|b| !b.linked()).map(|b| b.controller.0).collect();
    if !missing.is_empty() {
        eprintln!(
            "ayllu: warning: no controller heard for robots {missing:?} after {:.1}s; starting anyway",
            args.wait
        );
    }
    let start_line = json!({
        "start": true,
        "waited": round3(waited.elapsed().as_secs_f64()),
        "missing": missing,
        "arena": config.arena,
        "robots": robots,
        "targets": targets,
        "seed": scenario.seed,
        "duration": scenario.duration,
        "kills": scenario.kills.len(),
        "loss": scenario.radio.loss,
    });
    writeln!(out, "{start_line}")?;
    out.flush()?;

    let mut meter = Meter::new(&prios, robots);
    // The brains are in the robot processes: each reports the target driving it.
    let mut drives = vec![0u32; robots];
    let mut commands = vec![Command::default(); robots];
    let mut kills_done = vec![false; scenario.kills.len()];
    let mut reach = vec![0.0; robots];
    let ticks = (scenario.duration / dt).round().max(1.0) as u64;
    let status_every = ((args.status_ms as f64 / 1000.0 / dt).round() as u64).max(1);
    let (mut weighted_time, mut resyncs) = (0.0, 0u64);
    let mut anchor = StdInstant::now();
    let mut anchor_tick = 0u64;
    let mut tick = 0u64;
    while tick < ticks && !signals::stopped() {
        let due = anchor + StdDuration::from_secs_f64((tick + 1 - anchor_tick) as f64 * dt);
        let now = StdInstant::now();
        if due > now {
            std::thread::sleep(due - now);
        } else if now - due > MAX_LAG {
            // Stalled (machine overloaded): keep world time, restart the pacing from here.
            anchor = now;
            anchor_tick = tick;
            resyncs += 1;
        }
        tick += 1;
        let t = tick as f64 * dt;
        let killed = apply_due_kills(&scenario.kills, &mut kills_done, t, &mut world);
        if !killed.is_empty() {
            meter.killed_together(t, &world, &killed);
            for &i in &killed {
                writeln!(out, "{}", json!({"t": round3(t), "kill": node_id(i).0}))?;
            }
            out.flush()?;
        }
        let sense = tick.is_multiple_of(sense_every) || !killed.is_empty();
        if sense {
            world.index();
        }
        let stations: Vec<Station> = world
            .robots
            .iter()
            .enumerate()
            .map(|(i, r)| Station { node: node_id(i), x: r.pose.x, y: r.pose.y, alive: r.alive })
            .collect();
        for (i, b) in bodies.iter_mut().enumerate() {
            let alive = world.robots[i].alive;
            b.odometry(&world.robots[i].pose, &commands[i])?;
            if sense {
                // Who robot i hears now: alive, in range, on its side of every partition.
                reach_row(&scenario.radio, t, &stations, i, &mut reach);
                b.tell(&reach, alive)?;
                if alive {
                    let now = b.node.now();
                    b.body.sense(b.node.core_mut(), now, &mut world, i)?;
                }
            }
            // Sends this frame, then takes in what the controller wrote since the last tick.
            b.node.step();
            commands[i] = b.command();
            drives[i] = b.reported(2) as u32;
        }
        world.step(dt, &commands);
        let (observed, weighted) = meter.observe(t, dt, &world, &drives);
        weighted_time += dt * weighted;
        if tick.is_multiple_of(status_every) {
            let robots: Vec<Json> = world
                .robots
                .iter()
                .zip(&bodies)
                .zip(&commands)
                .map(|((r, b), c)| {
                    json!({
                        "id": b.controller.0,
                        "x": round3(r.pose.x),
                        "y": round3(r.pose.y),
                        "theta": round3(r.pose.theta),
                        "translate": round3(c.translate),
                        "rotate": round3(c.rotate),
                        "linked": b.linked(),
                        "alive": r.alive,
                        "drive": b.reported(2),
                    })
                })
                .collect();
            let line = json!({
                "t": round3(t),
                "observed": observed,
                "weighted": round3(weighted),
                "a_w": round3(weighted_time / t),
                "robots": robots,
            });
            writeln!(out, "{line}")?;
            out.flush()?;
        }
    }
    let t = tick as f64 * dt;
    let sent: u64 = bodies.iter().map(|b| b.reported(3)).sum();
    let bytes: u64 = bodies.iter().map(|b| b.reported(4)).sum();
    let metrics = meter.finish(t, robots, sent, bytes);
    let done = json!({
        "done": true,
        "t": round3(t),
        "stopped": tick < ticks,
        "resyncs": resyncs,
        "metrics": serde_json::to_value(&metrics).map_err(|e| Fail::error(format!("metrics as JSON: {e}")))?,
        "radio": {"sent": sent, "bytes": bytes},
    });
    writeln!(out, "{done}")?;
    out.flush()?;
    Ok(())
}

/// `ayllu sim robot`.
pub fn robot(args: &RobotArgs) -> Result<(), Fail> {
    let k = args.id.0;
    if k == 0 || u64::from(k) > MAX_ROBOTS {
        return Err(Fail::usage(format!("--id must be a robot number from 1 to {MAX_ROBOTS}, got {k}")));
    }
    // Without a scenario: no radio model (real UDP as it is), the tunables from the arguments.
    let (targets, cfg, radio, seed, controller) = match &args.scenario {
        Some(path) => {
            let s = read_scenario(path)?;
            let controller = args.controller.unwrap_or(s.controller);
            (s.world.targets.len(), s.controllers, s.radio, s.seed, controller)
        }
        None => {
            let cfg =
                ControllerConfig { claim_hz: args.claim_hz, wander_seed: args.seed, ..ControllerConfig::default() };
            let radio = RadioConfig { loss: 0.0, delay: 0.0, jitter: 0.0, range: None, partitions: Vec::new() };
            (args.targets as usize, cfg, radio, args.seed, args.controller.unwrap_or(Controller::Ble))
        }
    };
    let controller = distributed(controller).map_err(Fail::usage)?;
    let prios = priorities(targets);
    let transport = open_transport(&args.udp, args.id, &format!("robot-{k}"))?;
    let (transport, link) = RadioLink::new(transport, &radio, seed);
    let mut node = Node::new(MonotonicClock::new(), transport);
    match &args.ros2 {
        // The same behaviors, written and read by a ROS 2 body instead of the server's node.
        Some(path) => {
            ayllu_sim::served_robot::install_unconnected(node.core_mut(), targets)?;
            install_ros2_body(&mut node, path)?;
        }
        // The body's ports, as local behaviors the server writes (sensors) and reads (motors),
        // the motors sent to the body on the server (as the C library's ayInitSimBody does).
        None => ayllu_sim::served_robot::install(node.core_mut(), targets)?,
    }
    let brain = build(node.core_mut(), controller, &prios, &cfg)?;
    let body = body_id(k);
    let vision: Vec<PortRef> =
        (1..=targets).map(|n| node.core().port(VISION, &format!("Target{n}Angle"))).collect::<Result<_, _>>()?;
    signals::install();

    let start = StdInstant::now();
    let end = args.duration.map(|s| start + StdDuration::from_secs_f64(s));
    let period = StdDuration::from_millis(args.status_ms);
    let mut next_status = start + period;
    let mut next_report = start;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", listening_json(&node))?;
    out.flush()?;
    let mut was_linked = false;
    let ros2 = args.ros2.is_some();
    let mut heard_at = start;
    let mut last_drive = None;
    loop {
        let now = StdInstant::now();
        if signals::stopped() || end.is_some_and(|e| now >= e) {
            return Ok(());
        }
        if ros2 && body_linked(&node, body, true) {
            heard_at = now;
        }
        // The server's word: whom this robot hears, and whether it is still alive.
        if let Ok(ayllu::Value::Vector(reach)) = node.read(LINK, "Reach") {
            link.set_reach(&reach);
        }
        if node.read(LINK, "Alive").ok().and_then(|v| v.as_int()) == Some(0) {
            let mut status = robot_status(&node, &brain, &vision, body_linked(&node, body, args.ros2.is_some()), &link);
            status["killed"] = json!(true);
            writeln!(out, "{status}")?;
            out.flush()?;
            eprintln!("ayllu: sim robot {k}: killed by the scenario; stopping");
            return Ok(());
        }
        // Our word to the server, for the metrics: the drive when it changes, the radio counts
        // four times a second.
        let drive = brain.drive(node.core());
        if last_drive != Some(drive) {
            node.write(LINK, "Drive", i64::from(drive))?;
            last_drive = Some(drive);
        }
        if now >= next_report {
            let c = link.counts();
            node.write(LINK, "Sent", c.sent as i64)?;
            node.write(LINK, "Bytes", c.bytes as i64)?;
            next_report = (next_report + REPORT_PERIOD).max(now);
        }
        if now >= next_status {
            // A robot whose server went away stops too (its body is forgotten after three
            // silent HELLO periods; a ROS 2 body's sonar stays stale for ROS2_SILENCE), instead of
            // outliving it.
            let linked = body_linked(&node, body, ros2);
            if linked {
                was_linked = true;
            } else if was_linked && (!ros2 || now.duration_since(heard_at) >= ROS2_SILENCE) {
                eprintln!("ayllu: sim robot {k}: its body ({body}) has gone silent: the server stopped; stopping");
                return Ok(());
            }
            writeln!(
                out,
                "{}",
                robot_status(&node, &brain, &vision, body_linked(&node, body, args.ros2.is_some()), &link)
            )?;
            out.flush()?;
            next_status = (next_status + period).max(now);
        }
        // Wake at least every tick of the world, to follow the drive and the server's word.
        let mut until = next_status.min(now + TICK);
        if let Some(e) = end {
            until = until.min(e);
        }
        node.run_for(until.saturating_duration_since(StdInstant::now()));
    }
}

/// Whether the robot's body is there: its server node is a peer, or (a ROS 2 body) its sonar
/// is fresh.
fn body_linked(node: &Node, body: NodeId, ros2: bool) -> bool {
    if ros2 {
        node.fresh(SONAR, "Ranges").unwrap_or(false)
    } else {
        node.peers().iter().any(|p| p.node == body)
    }
}

#[cfg(feature = "ros2")]
fn install_ros2_body(node: &mut Node, path: &std::path::Path) -> Result<(), Fail> {
    ayllu_ros2::install_file(node, path).map_err(|e| Fail::error(e.to_string()))
}

#[cfg(not(feature = "ros2"))]
fn install_ros2_body(_node: &mut Node, _path: &std::path::Path) -> Result<(), Fail> {
    Err(Fail::error(crate::controllers::ROS2_MISSING))
}

fn robot_status(node: &Node, brain: &Brain, vision: &[PortRef], linked: bool, link: &LinkHandle) -> Json {
    let core = node.core();
    let claims: Vec<u32> = core
        .ble_statuses()
        .iter()
        .filter(|s| s.claiming)
        .filter_map(|s| s.behavior.strip_prefix("OBS").and_then(|n| n.parse().ok()))
        .collect();
    let sees: Vec<usize> =
        vision.iter().enumerate().filter(|(_, p)| core.fresh(**p).unwrap_or(false)).map(|(n, _)| n + 1).collect();
    let peers = node.peers();
    let stats = node.stats();
    let c = link.counts();
    let body: serde_json::Map<String, Json> =
        core.body_counters().iter().filter(|(_, n)| *n > 0).map(|(k, n)| (k.clone(), json!(n))).collect();
    json!({
        "t": round3(node.now().as_secs_f64()),
        "id": node.id().0,
        "drive": brain.drive(core),
        "body_counters": body,
        "claims": claims,
        "sees": sees,
        "body": linked,
        "peers": peers.iter().map(|p| p.node.0).filter(|&n| n < BODY_BASE).collect::<Vec<_>>(),
        "sent": stats.sent,
        "received": stats.received,
        "radio": {
            "sent": c.sent,
            "bytes": c.bytes,
            "delivered": c.delivered,
            "lost": c.lost,
            "cut": c.cut,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn body_urls_come_one_per_robot_or_from_a_template() {
        let one = ["udp://127.0.0.1:0?peer=10.0.0.{i}:7400".to_owned()];
        assert_eq!(body_url(&one, 3, 2).unwrap(), "udp://127.0.0.1:0?peer=10.0.0.2:7400");
        let shared = ["udp://0.0.0.0:0?broadcast=10.0.0.255:7400".to_owned()];
        assert_eq!(body_url(&shared, 3, 3).unwrap(), shared[0]);
        let fixed = ["udp://127.0.0.1:7500".to_owned()];
        assert!(body_url(&fixed, 3, 1).is_err(), "three bodies cannot share one fixed port");
        assert!(body_url(&fixed, 1, 1).is_ok());
        let many: Vec<String> = (1..=3).map(|k| format!("udp://127.0.0.1:{}", 7500 + k)).collect();
        assert_eq!(body_url(&many, 3, 3).unwrap(), "udp://127.0.0.1:7503");
        assert!(body_url(&many[..2], 3, 1).is_err());
        let zenoh = ["zenoh://?listen=tcp/127.0.0.1:7447&team=1".to_owned()];
        assert!(body_url(&zenoh, 2, 1).is_err(), "two bodies cannot listen on one fixed port");
        let zenoh = ["zenoh://?listen=tcp/127.0.0.1:0&connect=tcp/127.0.0.1:7447".to_owned()];
        assert!(body_url(&zenoh, 2, 1).is_ok());
    }

    #[test]
    fn centralized_and_planner_are_refused_in_distributed_mode() {
        assert_eq!(parse_distributed_controller("BLE"), Ok(Controller::Ble));
        assert_eq!(parse_distributed_controller("forcefield"), Ok(Controller::ForceField));
        assert!(parse_distributed_controller("centralized").unwrap_err().contains("not available"));
        assert!(parse_distributed_controller("planner").unwrap_err().contains("not available"));
        assert!(parse_distributed_controller("oracle").is_err());
    }
}
