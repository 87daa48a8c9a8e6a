//! The simulator's distributed mode from the command line: `ayllu sim serve` hosts the world,
//! `ayllu sim robot` runs one robot's controller as its own OS process. They talk real UDP, as a
//! team of real robots and their drivers would; the controllers talk to each other (BLE group
//! `Peers`) by the udp:// transport's group delivery (subnet broadcast, or unicast to the peers
//! that announced the group). Over `zenoh://` (the `ayllu-zenoh` tool, docs/zenoh.md) the same
//! run crosses Zenoh instead: the URLs are the only difference.
//!
//! `sim serve` is [`ayllu_sim::served_world::ServedWorld`] (what the world, its bodies, kills,
//! radio and metrics promise is said there, and docs/cmommt.md, "The distributed mode") plus
//! argument parsing, printing its events as JSON lines, and Ctrl-C / SIGTERM wired to its stop
//! (the final metrics line is still printed). The one thing it adds is the ROS 2 fleet (`--ros2`):
//! a [`BodyHost`] that puts every body behind ROS 2 topics, here because `ayllu_ros2` depends on
//! `ayllu_sim`. `sim robot` is the robot's side ([`ayllu_sim::served_robot`], the robot's
//! [`ayllu_sim::served_radio::RadioLink`] applying the scenario's radio), its controller built by
//! [`ayllu_sim::controller::build_in`] unchanged (BLE-seek's pose fed from the body link,
//! [`ayllu_sim::served_robot::connect_pose`]).
//!
//! Node ids (docs/cli.md): controller of robot K = node K (1..=N, as in the in-process
//! simulator); its body on the server = node [`BODY_BASE`] + K.
//!
//! Promises: stdout carries only JSON lines (a robot's first says where it listens, then one per
//! `--status-ms`; the server's are [`ayllu_sim::served_world::Event`]s, serialized); both
//! commands stop cleanly on Ctrl-C / SIGTERM. `centralized` and `planner` are refused: the first
//! needs the world's truth, the second a base station, which only exist in-process.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::stdlib::{SONAR, VISION};
use ayllu::{MonotonicClock, Node, NodeId, PortRef};
use ayllu_sim::classes::SharedClasses;
use ayllu_sim::controller::{build_in, Brain, Controller, ControllerConfig};
use ayllu_sim::radio::RadioConfig;
use ayllu_sim::scenario::{priorities, Scenario};
use ayllu_sim::scenario_file;
use ayllu_sim::served_radio::{LinkHandle, RadioLink};
use ayllu_sim::served_robot::{LinkDriver, LINK};
use ayllu_sim::served_world::{self, BodyHost, BodyLink, Event, ServeConfig, ServeError, ServedWorld};
use ayllu_sim::world::WorldConfig;
#[cfg(feature = "ros2")]
use ayllu_sim::world::{Command, Pose};
use clap::Args;
use serde_json::{json, Value as Json};

use crate::fail::Fail;
use crate::text::{listening_json, round3};
use crate::{parse_node, positive_secs, signals};

/// The body of robot K is node `BODY_BASE + K` (the robot's side: `ayllu_sim::served_robot`).
pub use ayllu_sim::served_robot::BODY_BASE;
/// Robots are numbered 1..=N below the bodies' ids.
const MAX_ROBOTS: u64 = BODY_BASE as u64 - 1;
/// The world's tick: a robot looks at the server's word this often (its drive: its
/// `LinkDriver`, every `ayllu_sim::served_robot::DRIVE_PERIOD`, the same).
const TICK: StdDuration = StdDuration::from_millis(50);
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
        None => Err(format!("`{s}` is not a controller (ble, ble-lean, ble-seek, local, random, forcefield)")),
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

/// World seconds served when neither --duration nor a scenario says (the UDP mode).
const DEFAULT_DURATION: f64 = 300.0;

/// A served world's refusal as the tool says it: in `--udp`'s words, exit code 2 for the
/// arguments' shape; the library's message otherwise.
impl From<ServeError> for Fail {
    fn from(e: ServeError) -> Fail {
        match e {
            ServeError::TooManyRobots { robots } => {
                Fail::usage(format!("{robots} robots: distributed mode takes at most {MAX_ROBOTS}"))
            }
            ServeError::UrlCount { urls, robots } => {
                Fail::usage(format!("{urls} --udp URLs for {robots} robots: give one per robot, or one"))
            }
            ServeError::SharedFixedPort { url, robots } => {
                Fail::usage(format!("one --udp URL for {robots} bodies must use `{{i}}` or bind port 0 (got `{url}`)"))
            }
            other => Fail::error(other.to_string()),
        }
    }
}

/// The DDS participant every ROS 2 body of the fleet shares: the [`BodyHost`] of `sim serve
/// --ros2`, which puts each body on an in-process node (it talks to nobody over Ayllu) behind a
/// ROS 2 body (`ayllu_ros2::fleet`). It lives here, not in `ayllu_sim`, because `ayllu_ros2`
/// depends on `ayllu_sim`.
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

#[cfg(feature = "ros2")]
impl BodyHost for Fleet {
    fn url(&self, _robot: u32) -> Result<String, ServeError> {
        Ok(format!("mem://ayllu-sim-ros2-{}", std::process::id()))
    }

    fn install(
        &mut self,
        k: u32,
        node: &mut Node,
        targets: usize,
        world: &WorldConfig,
    ) -> Result<Box<dyn BodyLink>, ServeError> {
        let driver = ayllu_ros2::fleet::install_served(node.core_mut(), k, targets, world, &self.0)
            .map_err(|e| ServeError::Host(e.to_string()))?;
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
        Ok(Box::new(Ros2Link { odom, heard }))
    }
}

/// A ROS 2 body of the fleet: `ODOM.X`, `Y`, `Yaw`, `Translate`, `Rotate` (published as
/// `/robotK/odom`), and the counter that says whether the controller's `cmd_vel` samples arrive.
#[cfg(feature = "ros2")]
struct Ros2Link {
    odom: [PortRef; 5],
    heard: String,
}

#[cfg(feature = "ros2")]
impl BodyLink for Ros2Link {
    fn linked(&self, node: &Node) -> bool {
        node.core().body_counters().iter().any(|(k, n)| *k == self.heard && *n > 0)
    }

    /// The pose and the command now, for `/robotK/odom`.
    fn tick(&mut self, node: &mut Node, pose: &Pose, command: &Command) -> Result<(), ServeError> {
        let now = node.now();
        let core = node.core_mut();
        for (port, x) in self.odom.iter().zip([pose.x, pose.y, pose.theta, command.translate, command.rotate]) {
            core.write(now, *port, x)?;
        }
        Ok(())
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

/// Never made ([`Fleet::open`] refuses without ROS 2): the call site is the same in both builds.
#[cfg(not(feature = "ros2"))]
impl BodyHost for Fleet {
    fn url(&self, _robot: u32) -> Result<String, ServeError> {
        Err(ServeError::Host(crate::controllers::ROS2_MISSING.to_owned()))
    }

    fn install(&mut self, _: u32, _: &mut Node, _: usize, _: &WorldConfig) -> Result<Box<dyn BodyLink>, ServeError> {
        Err(ServeError::Host(crate::controllers::ROS2_MISSING.to_owned()))
    }
}

/// `ayllu sim serve`: the arguments made into a [`ServeConfig`], the [`ServedWorld`]'s events
/// printed as JSON lines, Ctrl-C and SIGTERM wired to its stop.
pub fn serve(args: &ServeArgs) -> Result<(), Fail> {
    let (scenario, until_stopped) = match &args.scenario {
        Some(path) => (read_scenario(path)?, false),
        // With --ros2 and no duration the world runs until stopped, as a robot's driver does.
        None => (
            Scenario::sized(Controller::Random, args.robots as usize, args.targets as usize, args.seed)
                .duration(args.duration.unwrap_or(DEFAULT_DURATION)),
            args.ros2 && args.duration.is_none(),
        ),
    };
    let robots = scenario.robots;
    if robots > served_world::MAX_ROBOTS {
        return Err(ServeError::TooManyRobots { robots }.into());
    }
    let mut config = ServeConfig::new(scenario, Vec::new());
    config.until_stopped = until_stopped;
    config.wait = StdDuration::from_secs_f64(args.wait);
    config.status_every = StdDuration::from_millis(args.status_ms);
    let mut world = if args.ros2 {
        ServedWorld::open_with(config, &mut Fleet::open(args.domain)?)?
    } else {
        // The URLs' shape, then their scheme (`udp://`, or one the tool registered).
        config.urls = served_world::body_urls(&args.udp, robots)?;
        for url in &config.urls {
            crate::client::network_url(url)?;
        }
        ServedWorld::open(config)?
    };
    world.stop_when(signals::stopped);
    signals::install();
    let mut out = std::io::stdout().lock();
    world.run(|event| -> Result<(), Fail> {
        if let Event::Start(start) = event {
            if !start.missing.is_empty() {
                eprintln!(
                    "ayllu: warning: no controller heard for robots {:?} after {:.1}s; starting anyway",
                    start.missing, args.wait
                );
            }
        }
        // An event is plain data (numbers, strings, lists): writing it fails only as its
        // output does, so that is the error it returns.
        serde_json::to_writer(&mut out, event).map_err(std::io::Error::from)?;
        writeln!(out)?;
        out.flush()?;
        Ok(())
    })?;
    Ok(())
}

/// `ayllu sim robot`.
pub fn robot(args: &RobotArgs) -> Result<(), Fail> {
    let k = args.id.0;
    if k == 0 || u64::from(k) > MAX_ROBOTS {
        return Err(Fail::usage(format!("--id must be a robot number from 1 to {MAX_ROBOTS}, got {k}")));
    }
    // Without a scenario: no radio model (real UDP as it is), the tunables from the arguments.
    // The camera's size constant (focal x target height): how BLE-seek turns a sighting into a
    // place, as in-process (`controller::build_in`); the lab's without a scenario.
    let (targets, cfg, radio, seed, controller, target_size) = match &args.scenario {
        Some(path) => {
            let s = read_scenario(path)?;
            let controller = args.controller.unwrap_or(s.controller);
            let size = s.world.focal * s.world.target_height;
            (s.world.targets.len(), s.controllers, s.radio, s.seed, controller, size)
        }
        None => {
            let cfg =
                ControllerConfig { claim_hz: args.claim_hz, wander_seed: args.seed, ..ControllerConfig::default() };
            let radio = RadioConfig { loss: 0.0, delay: 0.0, jitter: 0.0, range: None, partitions: Vec::new() };
            let lab = WorldConfig::lab(&[]);
            let size = lab.focal * lab.target_height;
            (args.targets as usize, cfg, radio, args.seed, args.controller.unwrap_or(Controller::Ble), size)
        }
    };
    let controller = distributed(controller).map_err(Fail::usage)?;
    if controller == Controller::BleSeek && args.ros2.is_some() {
        // The ROS 2 body publishes odometry to its own topics, not the body link's pose.
        return Err(Fail::usage(
            "BLE-seek needs the body link's pose, which a ROS 2 body does not carry: run it without --ros2",
        ));
    }
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
    let brain = build_in(node.core_mut(), controller, &prios, target_size, &cfg, &mut SharedClasses::new())?;
    // BLE-seek's robots localize: the server's pose on the body link, as in-process.
    ayllu_sim::served_robot::connect_pose(node.core_mut(), &brain)?;
    // Our word to the server, for the metrics (the drive when it changes, the radio counts four
    // times a second), and its word on whom this robot hears: written and read by the node's
    // own loop, as for a C or Python robot (ayllu_sim::served_robot, "What a robot reports").
    node.attach(LinkDriver::new(targets).with_brain(brain.clone()).with_radio(link.clone()));
    let body = body_id(k);
    let vision: Vec<PortRef> =
        (1..=targets).map(|n| node.core().port(VISION, &format!("Target{n}Angle"))).collect::<Result<_, _>>()?;
    signals::install();

    let start = StdInstant::now();
    let end = args.duration.map(|s| start + StdDuration::from_secs_f64(s));
    let period = StdDuration::from_millis(args.status_ms);
    let mut next_status = start + period;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", listening_json(&node))?;
    out.flush()?;
    let mut was_linked = false;
    let ros2 = args.ros2.is_some();
    let mut heard_at = start;
    loop {
        let now = StdInstant::now();
        if signals::stopped() || end.is_some_and(|e| now >= e) {
            return Ok(());
        }
        if ros2 && body_linked(&node, body, true) {
            heard_at = now;
        }
        // The server's word: whether this robot is still alive (whom it hears: the driver).
        if node.read(LINK, "Alive").ok().and_then(|v| v.as_int()) == Some(0) {
            let mut status = robot_status(&node, &brain, &vision, body_linked(&node, body, args.ros2.is_some()), &link);
            status["killed"] = json!(true);
            writeln!(out, "{status}")?;
            out.flush()?;
            eprintln!("ayllu: sim robot {k}: killed by the scenario; stopping");
            return Ok(());
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
        // Wake at least every tick of the world, to follow the server's word.
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
    fn centralized_and_planner_are_refused_in_distributed_mode() {
        assert_eq!(parse_distributed_controller("BLE"), Ok(Controller::Ble));
        assert_eq!(parse_distributed_controller("forcefield"), Ok(Controller::ForceField));
        assert!(parse_distributed_controller("centralized").unwrap_err().contains("not available"));
        assert!(parse_distributed_controller("planner").unwrap_err().contains("not available"));
        assert!(parse_distributed_controller("oracle").is_err());
    }
}
