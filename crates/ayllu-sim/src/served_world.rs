//! The server's side of the simulator's distributed mode: a [`ServedWorld`] hosts the world
//! and one body node per robot, while each robot's controller runs elsewhere — its own OS
//! process (`ayllu sim robot`, a C program with `ay_sim_body`, a Python `ayllu.Node` with
//! `install_served_body`), on another machine, or on a thread of this one — and reaches its
//! body over the network, as a team of real robots and their drivers would. `ayllu sim serve`
//! is this type plus argument parsing and printing; C (`ay_served_world_*`) and Python
//! (`ayllu.sim.ServedWorld`, `ayllu.sim.serve`) wrap it. The robot's side is
//! [`crate::served_robot`]; docs/cmommt.md, "The distributed mode", says what a run means.
//!
//! Node ids (docs/cli.md): the controller of robot K is node K (1..=N, as in-process); its body
//! here is node [`BODY_BASE`] + K. Each body sends its `VISION.Target{n}Angle/Bottom` and
//! `SONAR.Ranges` to the same ports of node K, and its [`LINK`] word (`Reach`, `Alive`); the
//! robot sends its `BASE.Rotate/Translate` and `LINK.Drive/Sent/Bytes` back. Neither side is
//! told the other's address: a body greets the addresses its URL names (`peer=`,
//! `broadcast=`), its controller greets back, and from then on each routes by node id.
//!
//! Using it: [`ServedWorld::open`] with a [`ServeConfig`] (a [`Scenario`]: its world, team,
//! seed, duration, kills and radio; the bodies' URLs), then either [`ServedWorld::run`], which
//! waits for the robots, serves to the end and hands every [`Event`] to a callback, or the
//! same in steps: [`ServedWorld::start`], [`ServedWorld::step`] until [`ServedWorld::done`],
//! [`ServedWorld::finish`]. [`ServedWorld::stop`] (or a [`Stopper`] from another thread, or a
//! check given to [`ServedWorld::stop_when`]) ends the run early; the final metrics still come.
//! The events serialize (serde) to the JSON lines `ayllu sim serve` prints, field for field.
//!
//! Promises:
//! * the world is the in-process one: the scenario's world, seed, tick and sensing rate
//!   (`Scenario::sized` for a sized world), stepped by [`World::step`] and paced on the real
//!   clock (a server that falls [`MAX_LAG`] behind keeps world time and restarts its pacing:
//!   counted in `resyncs`); coverage is measured on the world's ground truth with the same
//!   [`Meter`]; the scenario's kills are applied at their instants with the in-process code
//!   ([`apply_due_kills`]);
//! * a body whose motor commands stop arriving stops its robot after [`WATCHDOG`], as a
//!   Pioneer's firmware does;
//! * the metrics are the in-process ones: switches from the drive each robot reports
//!   (`LINK.Drive`), messages and bytes from the radio emissions each robot counts (`LINK.Sent`,
//!   `LINK.Bytes`, at most 250 ms old);
//! * nothing here reads a signal or prints: stopping and output are the caller's.
//!
//! Bodies elsewhere: a body need not reach its controller over an Ayllu URL. A [`BodyHost`]
//! given to [`ServedWorld::open_with`] opens each body's node on a URL of its choosing, makes it
//! reach its controller by its own means, and returns a [`BodyLink`] the loop calls every tick
//! (the ROS 2 fleet of `ayllu sim serve --ros2` publishes the true pose as odometry there, and
//! says a body is linked once its controller's commands arrive). The Ayllu URLs are the default
//! host.
//!
//! Not here: controllers that need the world's truth (`centralized`) or a base station
//! (`planner`); they exist only in-process.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ayllu::stdlib::{BASE, SONAR, VISION};
use ayllu::{ConnectionKind, Endpoint, MonotonicClock, Node, NodeId, PortRef, UdpConfig};
use serde::{Serialize, Serializer};

use crate::body::Body;
use crate::bounds::InvalidScenario;
use crate::metrics::{Meter, Metrics};
use crate::radio::Station;
use crate::scenario::{apply_due_kills, node_id, Scenario};
use crate::served_radio::reach_row;
use crate::served_robot::{body_node, install_body_link, BODY_BASE, LINK};
use crate::world::{Command, Pose, World, WorldConfig};

/// The most robots a world serves: their ids stay below [`BODY_BASE`].
pub const MAX_ROBOTS: usize = BODY_BASE as usize - 1;
/// A body whose `BASE` has not been written for this long stops (the controller is gone).
pub const WATCHDOG: ayllu::Duration = ayllu::Duration::from_secs(1);
/// If the server falls this far behind the real clock, it stops trying to catch up.
pub const MAX_LAG: Duration = Duration::from_millis(500);
/// "Until stopped": the world time a run served with [`ServeConfig::until_stopped`] lasts
/// (about 31 years), as its start reports it.
pub const UNTIL_STOPPED: f64 = 1e9;
/// How often the bodies are stepped while they wait for their controllers.
const POLL: Duration = Duration::from_millis(20);

/// What to serve, and how.
#[derive(Clone, Debug)]
pub struct ServeConfig {
    /// The run: world, team, seed, duration, kills, radio (the radio is applied by the robots
    /// given the same scenario; the server computes their reachability). Checked as
    /// [`Scenario::validate`] does, except for the duration, which only has to be positive.
    pub scenario: Scenario,
    /// The bodies' URLs: one per robot in order, or one for all in which `{i}` stands for the
    /// robot's number (one URL without `{i}` for several bodies must bind port 0). `udp://`, or
    /// any scheme registered with `ayllu::transport::register_scheme` (`zenoh://`). Unused by
    /// [`ServedWorld::open_with`].
    pub urls: Vec<String>,
    /// Serve until stopped rather than for the scenario's duration.
    pub until_stopped: bool,
    /// How long [`ServedWorld::start`] waits for every body to hear its controller (it starts
    /// anyway after that; late controllers join when they come). Default 10 s.
    pub wait: Duration,
    /// How often (world time) a [`Status`] is produced; at least one tick. Default 1 s.
    pub status_every: Duration,
}

impl ServeConfig {
    /// `scenario` served to bodies on `urls`, with the defaults: for its duration, waiting 10 s
    /// for the robots, a status every second.
    pub fn new(scenario: Scenario, urls: Vec<String>) -> ServeConfig {
        ServeConfig {
            scenario,
            urls,
            until_stopped: false,
            wait: Duration::from_secs(10),
            status_every: Duration::from_secs(1),
        }
    }
}

/// Why a world could not be served.
#[derive(Debug)]
pub enum ServeError {
    /// More robots than [`MAX_ROBOTS`].
    TooManyRobots {
        /// The scenario's team.
        robots: usize,
    },
    /// Neither one URL nor one per robot.
    UrlCount {
        /// URLs given.
        urls: usize,
        /// Robots served.
        robots: usize,
    },
    /// One URL for several bodies that binds a fixed port: they cannot share it.
    SharedFixedPort {
        /// The URL.
        url: String,
        /// Robots served.
        robots: usize,
    },
    /// The scenario is out of bounds (naming its field), or its duration is not positive.
    Scenario(InvalidScenario),
    /// A duration that is not a positive number of seconds.
    Duration(f64),
    /// The runtime refused: a URL that does not parse, a socket the system refused, a port.
    Runtime(ayllu::RuntimeError),
    /// A [`BodyHost`]'s own failure, in its words.
    Host(String),
}

impl std::fmt::Display for ServeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ServeError::TooManyRobots { robots } => {
                write!(f, "{robots} robots: distributed mode takes at most {MAX_ROBOTS}")
            }
            ServeError::UrlCount { urls, robots } => {
                write!(f, "{urls} body URLs for {robots} robots: give one per robot, or one")
            }
            ServeError::SharedFixedPort { url, robots } => {
                write!(f, "one body URL for {robots} bodies must use `{{i}}` or bind port 0 (got `{url}`)")
            }
            ServeError::Scenario(e) => e.fmt(f),
            ServeError::Duration(d) => write!(f, "the duration must be a positive number of seconds, got {d}"),
            ServeError::Runtime(e) => e.fmt(f),
            ServeError::Host(what) => f.write_str(what),
        }
    }
}

impl std::error::Error for ServeError {}

impl From<ayllu::RuntimeError> for ServeError {
    fn from(e: ayllu::RuntimeError) -> Self {
        ServeError::Runtime(e)
    }
}

impl From<ayllu_core::Error> for ServeError {
    fn from(e: ayllu_core::Error) -> Self {
        ServeError::Runtime(ayllu::RuntimeError::Core(e))
    }
}

/// Where the bodies' nodes live and how they reach their controllers, when not over the Ayllu
/// URLs of [`ServeConfig::urls`] (module docs, "Bodies elsewhere"). Used only while the world
/// opens.
pub trait BodyHost {
    /// The URL robot `robot`'s body node (id [`body_node`]`(robot)`) opens on.
    fn url(&self, robot: u32) -> Result<String, ServeError>;
    /// On robot `robot`'s body node, whose VISION, SONAR and BASE exist already: create
    /// [`LINK`] (class [`crate::served_robot::link_class`]) and whatever carries the body's
    /// ports to and from the controller; return what the loop asks each tick.
    fn install(
        &mut self,
        robot: u32,
        node: &mut Node,
        targets: usize,
        world: &WorldConfig,
    ) -> Result<Box<dyn BodyLink>, ServeError>;
}

/// What the loop asks of one body each tick (made by a [`BodyHost`]).
pub trait BodyLink: Send {
    /// Whether the body hears its controller (its sensors reach it, its commands arrive).
    fn linked(&self, node: &Node) -> bool;
    /// Each tick, before the body's node steps: the robot's true pose and its motor command.
    fn tick(&mut self, _node: &mut Node, _pose: &Pose, _command: &Command) -> Result<(), ServeError> {
        Ok(())
    }
}

/// The URL of each of `robots` bodies from `urls` (see [`ServeConfig::urls`]).
pub fn body_urls(urls: &[String], robots: usize) -> Result<Vec<String>, ServeError> {
    match urls {
        [one] => {
            if robots > 1 && !one.contains("{i}") {
                // zenoh:// (and other registered schemes) bind what `listen=` names.
                let fixed = match UdpConfig::parse(one) {
                    Ok(c) => c.bind.port() != 0,
                    Err(_) => ayllu::transport::url_setting(one, "listen").is_some_and(|l| !l.ends_with(":0")),
                };
                if fixed {
                    return Err(ServeError::SharedFixedPort { url: one.clone(), robots });
                }
            }
            Ok((1..=robots).map(|k| one.replace("{i}", &k.to_string())).collect())
        }
        many if many.len() == robots => Ok(many.to_vec()),
        many => Err(ServeError::UrlCount { urls: many.len(), robots }),
    }
}

/// The default host: every body on its Ayllu URL, its sensors connected to node K.
struct UrlHost(Vec<String>);

impl BodyHost for UrlHost {
    fn url(&self, robot: u32) -> Result<String, ServeError> {
        Ok(self.0[robot as usize - 1].clone())
    }
    fn install(
        &mut self,
        k: u32,
        node: &mut Node,
        targets: usize,
        _: &WorldConfig,
    ) -> Result<Box<dyn BodyLink>, ServeError> {
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
        install_body_link(node.core_mut(), k)?;
        Ok(Box::new(UrlLink(controller)))
    }
}

/// A body on an Ayllu URL is linked once its controller is a peer.
struct UrlLink(NodeId);

impl BodyLink for UrlLink {
    fn linked(&self, node: &Node) -> bool {
        node.peers().iter().any(|p| p.node == self.0)
    }
}

/// One robot's body on the server: its node, the body's ports, its link.
struct ServedBody {
    node: Node,
    body: Body,
    rotate: PortRef,
    translate: PortRef,
    controller: NodeId,
    /// `LINK.Reach`, `Alive`, `Drive`, `Sent`, `Bytes` (crate::served_robot).
    link: [PortRef; 5],
    /// `LINK.Pose`: the robot's true pose, sent with its reachability (odometry on a known map,
    /// which BLE-seek's robots use as they do in-process).
    pose: PortRef,
    plug: Box<dyn BodyLink>,
}

impl ServedBody {
    fn open(k: u32, host: &mut dyn BodyHost, targets: usize, world: &WorldConfig) -> Result<ServedBody, ServeError> {
        let id = body_node(k);
        let url = host.url(k)?;
        let mut node = Node::new(MonotonicClock::new(), ayllu::transport::open_named(&url, id, &format!("body-{k}"))?);
        let body = Body::install(node.core_mut(), targets, world)?;
        let plug = host.install(k, &mut node, targets, world)?;
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
        let pose = core.port(LINK, "Pose")?;
        Ok(ServedBody { node, body, rotate, translate, controller: NodeId(k), link, pose, plug })
    }

    /// An int the robot reports on `LINK` (0 until it has).
    fn reported(&self, port: usize) -> u64 {
        self.node.core().read(self.link[port]).ok().and_then(|v| v.as_int()).unwrap_or(0).max(0) as u64
    }

    /// Tell the robot who it hears now, whether it is alive, and where it is.
    fn tell(&mut self, reach: &[f64], alive: bool, pose: &Pose) -> Result<(), ServeError> {
        let now = self.node.now();
        let core = self.node.core_mut();
        core.write(now, self.link[0], ayllu::Value::vector(reach))?;
        core.write(now, self.link[1], i64::from(alive))?;
        if alive {
            core.write(now, self.pose, ayllu::Value::vector(&[pose.x, pose.y, pose.theta]))?;
        }
        Ok(())
    }

    fn linked(&self) -> bool {
        self.plug.linked(&self.node)
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

fn round3<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64((x * 1000.0).round() / 1000.0)
}

/// The world starts: who was heard, and what is served. Serialized: `ayllu sim serve`'s first
/// line.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Start {
    /// Always true: marks this line among the others.
    pub start: bool,
    /// Seconds waited for the controllers (serialized to the millisecond).
    #[serde(serialize_with = "round3")]
    pub waited: f64,
    /// The robots whose body had not heard its controller when the world started.
    pub missing: Vec<u32>,
    /// The arena's width and height (m).
    pub arena: [f64; 2],
    /// Robots served.
    pub robots: usize,
    /// Targets in the world.
    pub targets: usize,
    /// The world's seed.
    pub seed: u64,
    /// World seconds to serve ([`UNTIL_STOPPED`] for until stopped).
    pub duration: f64,
    /// Kills scheduled.
    pub kills: usize,
    /// The radio's loss (applied by the robots).
    pub loss: f64,
}

/// A robot killed by the scenario. Serialized: `{"t": .., "kill": K}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Kill {
    /// World seconds.
    #[serde(serialize_with = "round3")]
    pub t: f64,
    /// The robot's number.
    pub kill: u32,
}

/// One robot in a [`Status`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RobotStatus {
    /// The robot's number (its controller's node id).
    pub id: u32,
    /// True pose: x (m).
    #[serde(serialize_with = "round3")]
    pub x: f64,
    /// True pose: y (m).
    #[serde(serialize_with = "round3")]
    pub y: f64,
    /// True pose: heading (rad).
    #[serde(serialize_with = "round3")]
    pub theta: f64,
    /// The command applied this tick (m/s).
    #[serde(serialize_with = "round3")]
    pub translate: f64,
    /// The command applied this tick (rad/s).
    #[serde(serialize_with = "round3")]
    pub rotate: f64,
    /// Whether the body hears its controller.
    pub linked: bool,
    /// Whether the robot is alive (not killed).
    pub alive: bool,
    /// The target driving it, as it reports (0: none).
    pub drive: u64,
}

/// The world now. Serialized: a status line of `ayllu sim serve`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Status {
    /// World seconds.
    #[serde(serialize_with = "round3")]
    pub t: f64,
    /// Targets observed now.
    pub observed: u32,
    /// Weighted observation now (the priorities of the targets observed, over their sum).
    #[serde(serialize_with = "round3")]
    pub weighted: f64,
    /// Weighted observation averaged over the run so far (A_w).
    #[serde(serialize_with = "round3")]
    pub a_w: f64,
    /// Every robot, in order.
    pub robots: Vec<RobotStatus>,
}

/// The radio emissions the robots reported, in a [`Done`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RadioTotals {
    /// Messages.
    pub sent: u64,
    /// Their encoded bytes.
    pub bytes: u64,
}

/// The run is over. Serialized: `ayllu sim serve`'s last line.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Done {
    /// Always true: marks this line among the others.
    pub done: bool,
    /// World seconds served.
    #[serde(serialize_with = "round3")]
    pub t: f64,
    /// Whether it was stopped before its duration.
    pub stopped: bool,
    /// How often the pacing restarted after falling [`MAX_LAG`] behind the real clock.
    pub resyncs: u64,
    /// The in-process metrics of the run.
    pub metrics: Metrics,
    /// The radio emissions counted.
    pub radio: RadioTotals,
}

/// What a served world says, in order: one [`Start`], then kills and statuses, one [`Done`].
/// Serialized without a tag: each is one JSON line of `ayllu sim serve`.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Event {
    /// The world started.
    Start(Start),
    /// A robot was killed.
    Kill(Kill),
    /// A status.
    Status(Status),
    /// The end.
    Done(Done),
}

/// Stops a served world from any thread (from [`ServedWorld::stopper`]).
#[derive(Clone, Debug, Default)]
pub struct Stopper(Arc<AtomicBool>);

impl Stopper {
    /// Ask the world to stop: the wait ends, no further tick runs, [`ServedWorld::finish`]
    /// reports `stopped`.
    pub fn stop(&self) {
        self.0.store(true, Ordering::Release);
    }
    /// Whether a stop was asked.
    pub fn is_stopped(&self) -> bool {
        self.0.load(Ordering::Acquire)
    }
}

/// A world served to robots whose controllers run elsewhere (module docs).
pub struct ServedWorld {
    scenario: Scenario,
    arena: [f64; 2],
    wait: Duration,
    bodies: Vec<ServedBody>,
    world: World,
    meter: Option<Meter>,
    drives: Vec<u32>,
    commands: Vec<Command>,
    kills_done: Vec<bool>,
    reach: Vec<f64>,
    dt: f64,
    sense_every: u64,
    status_every: u64,
    ticks: u64,
    tick: u64,
    weighted_time: f64,
    resyncs: u64,
    waiting_since: Option<Instant>,
    /// The pacing's anchor (real instant, tick), once started.
    anchor: Option<(Instant, u64)>,
    start: Option<Start>,
    done: Option<Done>,
    stopper: Stopper,
    stop_when: Option<fn() -> bool>,
}

impl ServedWorld {
    /// Open the bodies on [`ServeConfig::urls`] (sockets bound now) and build the world.
    /// Errors: the scenario out of bounds, too many robots, URLs that do not fit the team, a
    /// URL or socket the runtime refuses.
    pub fn open(config: ServeConfig) -> Result<ServedWorld, ServeError> {
        check(&config)?;
        let urls = body_urls(&config.urls, config.scenario.robots)?;
        ServedWorld::open_with(config, &mut UrlHost(urls))
    }

    /// [`ServedWorld::open`] with the bodies where `host` puts them (module docs, "Bodies
    /// elsewhere"); [`ServeConfig::urls`] is not used.
    pub fn open_with(config: ServeConfig, host: &mut dyn BodyHost) -> Result<ServedWorld, ServeError> {
        check(&config)?;
        let mut scenario = config.scenario;
        if config.until_stopped {
            scenario.duration = UNTIL_STOPPED;
        }
        let robots = scenario.robots;
        let targets = scenario.world.targets.len();
        // Targets numbered by decreasing priority (OBSn follows TargetN), as `scenario::Sim`.
        let world_config = scenario.world.clone().by_priority();
        let prios: Vec<f64> = world_config.targets.iter().map(|t| t.priority).collect();
        let bodies = (1..=robots as u32)
            .map(|k| ServedBody::open(k, host, targets, &world_config))
            .collect::<Result<Vec<_>, _>>()?;
        let dt = scenario.dt;
        let world = World::new(world_config.clone(), robots, scenario.seed);
        let status_every = ((config.status_every.as_secs_f64() / dt).round() as u64).max(1);
        Ok(ServedWorld {
            arena: world_config.arena,
            wait: config.wait,
            bodies,
            world,
            meter: Some(Meter::new(&prios, robots)),
            drives: vec![0; robots],
            commands: vec![Command::default(); robots],
            kills_done: vec![false; scenario.kills.len()],
            reach: vec![0.0; robots],
            dt,
            sense_every: u64::from(scenario.sense_every.max(1)),
            status_every,
            ticks: (scenario.duration / dt).round().max(1.0) as u64,
            tick: 0,
            weighted_time: 0.0,
            resyncs: 0,
            waiting_since: None,
            anchor: None,
            start: None,
            done: None,
            stopper: Stopper::default(),
            stop_when: None,
            scenario,
        })
    }

    /// The scenario served (its duration [`UNTIL_STOPPED`] when served until stopped).
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// Where each body's node listens (`ip:port`; None where its transport has no address).
    pub fn body_addresses(&self) -> Vec<Option<String>> {
        self.bodies.iter().map(|b| b.node.address()).collect()
    }

    /// Whether each body hears its controller now.
    pub fn linked(&self) -> Vec<bool> {
        self.bodies.iter().map(ServedBody::linked).collect()
    }

    /// A handle that stops this world from any thread.
    pub fn stopper(&self) -> Stopper {
        self.stopper.clone()
    }

    /// Stop the world (as [`Stopper::stop`]).
    pub fn stop(&self) {
        self.stopper.stop();
    }

    /// Also stop once `check` says so (it is called between ticks and while waiting): how
    /// `ayllu sim serve` wires Ctrl-C and SIGTERM.
    pub fn stop_when(&mut self, check: fn() -> bool) {
        self.stop_when = Some(check);
    }

    /// Whether a stop was asked.
    pub fn stopped(&self) -> bool {
        self.stopper.is_stopped() || self.stop_when.is_some_and(|f| f())
    }

    /// The start, once [`ServedWorld::start`] has made it.
    pub fn started(&self) -> Option<&Start> {
        self.start.as_ref()
    }

    /// World seconds served so far.
    pub fn now(&self) -> f64 {
        self.tick as f64 * self.dt
    }

    /// Whether the run is over: its duration served, or stopped.
    pub fn done(&self) -> bool {
        self.done.is_some() || self.tick >= self.ticks || self.stopped()
    }

    /// Before the start: step every body's node once (greetings go out, replies come in) and
    /// say whether every body hears its controller. [`ServedWorld::start`] calls it until they
    /// all do; call it yourself to wait in your own loop.
    pub fn poll(&mut self) -> bool {
        self.waiting_since.get_or_insert_with(Instant::now);
        for b in &mut self.bodies {
            b.node.step();
        }
        self.bodies.iter().all(ServedBody::linked)
    }

    /// Wait until every body hears its controller, [`ServeConfig::wait`] has passed since the
    /// first [`ServedWorld::poll`], or a stop is asked; then start the world's clock. Called
    /// again, returns the same start.
    pub fn start(&mut self) -> Start {
        if let Some(s) = &self.start {
            return s.clone();
        }
        let since = *self.waiting_since.get_or_insert_with(Instant::now);
        while !self.poll() && since.elapsed() < self.wait && !self.stopped() {
            std::thread::sleep(POLL);
        }
        let missing = self.bodies.iter().filter(|b| !b.linked()).map(|b| b.controller.0).collect();
        let start = Start {
            start: true,
            waited: since.elapsed().as_secs_f64(),
            missing,
            arena: self.arena,
            robots: self.scenario.robots,
            targets: self.scenario.world.targets.len(),
            seed: self.scenario.seed,
            duration: self.scenario.duration,
            kills: self.scenario.kills.len(),
            loss: self.scenario.radio.loss,
        };
        self.anchor = Some((Instant::now(), 0));
        self.start = Some(start.clone());
        start
    }

    /// One tick of the world, paced on the real clock (it sleeps until the tick is due): kills
    /// due, sensing, the bodies' nodes stepped, the world moved, coverage measured. Returns the
    /// tick's kills, then its status when one is due. Starts the world first if
    /// [`ServedWorld::start`] was not called; once [`ServedWorld::done`], does nothing.
    pub fn step(&mut self) -> Result<Vec<Event>, ServeError> {
        if self.start.is_none() {
            self.start();
        }
        let mut events = Vec::new();
        if self.done() {
            return Ok(events);
        }
        let (anchor, anchor_tick) = self.anchor.unwrap_or((Instant::now(), 0));
        let dt = self.dt;
        let due = anchor + Duration::from_secs_f64((self.tick + 1 - anchor_tick) as f64 * dt);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        } else if now - due > MAX_LAG {
            // Stalled (machine overloaded): keep world time, restart the pacing from here.
            self.anchor = Some((now, self.tick));
            self.resyncs += 1;
        }
        self.tick += 1;
        let t = self.tick as f64 * dt;
        let Some(meter) = self.meter.as_mut() else { return Ok(events) };
        let killed = apply_due_kills(&self.scenario.kills, &mut self.kills_done, t, &mut self.world);
        if !killed.is_empty() {
            meter.killed_together(t, &self.world, &killed);
            events.extend(killed.iter().map(|&i| Event::Kill(Kill { t, kill: node_id(i).0 })));
        }
        let sense = self.tick.is_multiple_of(self.sense_every) || !killed.is_empty();
        if sense {
            self.world.index();
        }
        let stations: Vec<Station> = self
            .world
            .robots
            .iter()
            .enumerate()
            .map(|(i, r)| Station { node: node_id(i), x: r.pose.x, y: r.pose.y, alive: r.alive })
            .collect();
        for (i, b) in self.bodies.iter_mut().enumerate() {
            let alive = self.world.robots[i].alive;
            b.plug.tick(&mut b.node, &self.world.robots[i].pose, &self.commands[i])?;
            if sense {
                // Who robot i hears now: alive, in range, on its side of every partition.
                reach_row(&self.scenario.radio, t, &stations, i, &mut self.reach);
                b.tell(&self.reach, alive, &self.world.robots[i].pose)?;
                if alive {
                    let now = b.node.now();
                    b.body.sense(b.node.core_mut(), now, &mut self.world, i)?;
                }
            }
            // Sends this frame, then takes in what the controller wrote since the last tick.
            b.node.step();
            self.commands[i] = b.command();
            self.drives[i] = b.reported(2) as u32;
        }
        self.world.step(dt, &self.commands);
        let (observed, weighted) = meter.observe(t, dt, &self.world, &self.drives);
        self.weighted_time += dt * weighted;
        if self.tick.is_multiple_of(self.status_every) {
            events.push(Event::Status(self.status(t, observed, weighted)));
        }
        Ok(events)
    }

    fn status(&self, t: f64, observed: u32, weighted: f64) -> Status {
        let robots = (self.world.robots.iter().zip(&self.bodies).zip(&self.commands))
            .map(|((r, b), c)| RobotStatus {
                id: b.controller.0,
                x: r.pose.x,
                y: r.pose.y,
                theta: r.pose.theta,
                translate: c.translate,
                rotate: c.rotate,
                linked: b.linked(),
                alive: r.alive,
                drive: b.reported(2),
            })
            .collect();
        Status { t, observed, weighted, a_w: self.weighted_time / t, robots }
    }

    /// End the run (stopping it if it is not done) and compute its metrics. Called again,
    /// returns the same.
    pub fn finish(&mut self) -> Done {
        if let Some(d) = &self.done {
            return d.clone();
        }
        let t = self.now();
        let sent: u64 = self.bodies.iter().map(|b| b.reported(3)).sum();
        let bytes: u64 = self.bodies.iter().map(|b| b.reported(4)).sum();
        let robots = self.scenario.robots;
        let meter = self.meter.take().unwrap_or_else(|| Meter::new(&[], robots));
        let done = Done {
            done: true,
            t,
            stopped: self.tick < self.ticks,
            resyncs: self.resyncs,
            metrics: meter.finish(t, robots, sent, bytes),
            radio: RadioTotals { sent, bytes },
        };
        self.done = Some(done.clone());
        done
    }

    /// The whole run: [`ServedWorld::start`], [`ServedWorld::step`] until
    /// [`ServedWorld::done`], [`ServedWorld::finish`], each event handed to `on_event` as it
    /// comes (`ayllu sim serve` prints them). An error of `on_event` ends the run with it.
    pub fn run<E: From<ServeError>>(&mut self, mut on_event: impl FnMut(&Event) -> Result<(), E>) -> Result<Done, E> {
        on_event(&Event::Start(self.start()))?;
        while !self.done() {
            for e in self.step()? {
                on_event(&e)?;
            }
        }
        let done = self.finish();
        on_event(&Event::Done(done.clone()))?;
        Ok(done)
    }
}

/// The checks before anything is opened.
fn check(config: &ServeConfig) -> Result<(), ServeError> {
    let s = &config.scenario;
    if s.robots > MAX_ROBOTS {
        return Err(ServeError::TooManyRobots { robots: s.robots });
    }
    if !(s.duration.is_finite() && s.duration > 0.0) {
        return Err(ServeError::Duration(s.duration));
    }
    // The duration is checked above: served on the real clock, it may be longer than a run
    // in-process may hold frames for. Nothing is recorded.
    Scenario { duration: 1.0, record: false, ..s.clone() }.validate().map_err(ServeError::Scenario)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn body_urls_come_one_per_robot_or_from_a_template() {
        let one = ["udp://127.0.0.1:0?peer=10.0.0.{i}:7400".to_owned()];
        assert_eq!(body_urls(&one, 3).unwrap()[1], "udp://127.0.0.1:0?peer=10.0.0.2:7400");
        let shared = ["udp://0.0.0.0:0?broadcast=10.0.0.255:7400".to_owned()];
        assert_eq!(body_urls(&shared, 3).unwrap()[2], shared[0]);
        let fixed = ["udp://127.0.0.1:7500".to_owned()];
        assert!(matches!(body_urls(&fixed, 3), Err(ServeError::SharedFixedPort { robots: 3, .. })));
        assert!(body_urls(&fixed, 1).is_ok());
        let many: Vec<String> = (1..=3).map(|k| format!("udp://127.0.0.1:{}", 7500 + k)).collect();
        assert_eq!(body_urls(&many, 3).unwrap()[2], "udp://127.0.0.1:7503");
        assert!(matches!(body_urls(&many[..2], 3), Err(ServeError::UrlCount { urls: 2, robots: 3 })));
        let zenoh = ["zenoh://?listen=tcp/127.0.0.1:7447&team=1".to_owned()];
        assert!(body_urls(&zenoh, 2).is_err(), "two bodies cannot listen on one fixed port");
        let zenoh = ["zenoh://?listen=tcp/127.0.0.1:0&connect=tcp/127.0.0.1:7447".to_owned()];
        assert!(body_urls(&zenoh, 2).is_ok());
    }
}
