//! The robot's side of a world served by `ayllu sim serve`: the body (VISION, SONAR, BASE)
//! as local behaviors of the robot's node, written by the server (sensors) and read by it
//! (motors) over the network — the stand-in for the paper's `ayInitPioControl` when the
//! controller runs as its own OS process (`ayllu sim robot`, the C library's
//! `ayInitSimBody`, Python's `Node.install_served_body`).
//!
//! Node ids (docs/cli.md): the controller of robot K is node K; its body on the server is
//! node [`BODY_BASE`] + K. The server connects the body's sensor ports to the same ports of
//! node K; [`install`] connects node K's `BASE.Rotate` and `BASE.Translate` to the body's.
//!
//! Beside the body, both ends have a [`LINK`] behavior (class [`link_class`]): the server's word
//! to the robot — `Reach` (which robots' messages reach it now: the scenario's range and
//! partitions on the world's true positions, and who is alive; see [`crate::served_radio`]) and
//! `Alive` (0 once the scenario kills the robot: its process stops) — and the robot's word to
//! the server, for the metrics: `Drive` (the target driving it, for switches), `Sent` and
//! `Bytes` (its radio emissions so far and their encoded size).
//!
//! # What a robot reports, and how
//!
//! The robot's word is written by a [`LinkDriver`], an [`ayllu::Driver`] run by the node's own
//! loop (inside `Node::step`, on the node's thread), so every robot reports the same way
//! whatever language its controller is in: `ayllu sim robot` attaches one (with its [`Brain`]
//! and its [`RadioLink`](crate::served_radio::RadioLink)'s handle), and [`attach`] — what the
//! C library's `ay_sim_body` (`ayInitSimBody`) and Python's `Node.install_served_body` call —
//! installs the body and attaches one that finds the controller by its behaviors' names. Each
//! turn of the node, the driver:
//! * `Drive`: looks at the target driving the robot every [`DRIVE_PERIOD`] (the world's tick)
//!   and writes it when it changed. With a [`Brain`] ([`LinkDriver::with_brain`]) it is
//!   [`Brain::drive`]; otherwise it is read from the Fig. 2 observer layers by name, `OBS1` to
//!   `OBS{targets}` ([`crate::controller::named_chain_drive`]): the highest layer whose `Rotate`
//!   was written within the override period drives, and a controller without such layers
//!   reports 0 (none) once;
//! * `Sent`, `Bytes`: writes the robot's radio emissions so far and their encoded size (wire
//!   format, message headers included, datagram headers not: [`crate::radio::wire_len`]) every
//!   [`REPORT_PERIOD`], starting with its first turn. A radio emission is a message to anyone
//!   but the robot's body (a group message counts once), as in-process. With a radio link's
//!   handle ([`LinkDriver::with_radio`]) these are the link's counts
//!   ([`LinkHandle::counts`]); without one, the driver counts the messages the node queues for
//!   sending during its turns (what processes, BLE and the core's answers produce), before the
//!   turn hands them to the transport. Not counted then: messages a program writes between
//!   turns (from its own thread, outside any process), which leave at the start of the next
//!   turn. The transport's own counters (`messages_sent` of `NodeCore::transport_counters`)
//!   are no substitute: they count the body's traffic too (the motors, these reports) and no
//!   bytes;
//! * `Reach`: with a radio link's handle, hands the reachability the server sent to the link
//!   ([`LinkHandle::set_reach`]) before the turn's processes run.
//!
//! Whether a robot the scenario killed (`LINK.Alive` 0) stops is its program's business:
//! `ayllu sim robot` exits; a C program reads it with
//! `ay_node_read_int(node, "LINK", "Alive", &alive)`, a Python one with `node.read("LINK", "Alive")`,
//! and may stop its loop (the examples do not: the server has stopped their body, and their
//! messages no longer reach anyone — every peer's `Reach` cuts a dead robot).

use ayllu::stdlib::BASE;
use ayllu_core::{
    BehaviorClass, ConnectOptions, ConnectionKind, Destination, Duration, Endpoint, Error, Instant, NodeCore, NodeId,
    PortRef, PortSpec, Value,
};

use crate::body::Body;
use crate::controller::{named_chain_drive, Brain, SEEK};
use crate::radio::wire_len;
use crate::scenario::priorities;
use crate::served_radio::LinkHandle;
use crate::world::WorldConfig;

/// The body of robot K is node `BODY_BASE + K` on the server.
pub const BODY_BASE: u32 = 1000;

/// The server's node for robot `robot`'s body.
pub fn body_node(robot: u32) -> NodeId {
    NodeId(BODY_BASE + robot)
}

/// The behavior between a served robot and its body on the server (module docs).
pub const LINK: &str = "LINK";

/// The class of [`LINK`]: `Reach` (vector, one entry per robot, 1.0 reachable), `Alive` (int,
/// 1 until killed), `Pose` (vector `[x, y, theta]`, the robot's pose: its odometry on a known
/// map, as the in-process simulator writes it to the controllers that localize), `Drive`,
/// `Sent`, `Bytes` (ints). Both ends create it; it has no process.
pub fn link_class() -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Link");
    c.port(PortSpec::new("Reach", Value::vector(&[])))?;
    c.port(PortSpec::new("Alive", 1i64))?;
    c.port(PortSpec::new("Pose", Value::vector(&[])))?;
    for p in ["Drive", "Sent", "Bytes"] {
        c.port(PortSpec::new(p, 0i64))?;
    }
    Ok(c)
}

/// On a body node (the server's, node `BODY_BASE + K`): create [`LINK`] and send its `Reach`,
/// `Alive` and `Pose` to robot K's controller node.
pub fn install_body_link(core: &mut NodeCore, robot: u32) -> Result<(), Error> {
    core.define(link_class()?)?;
    core.create("Link", LINK)?;
    for port in ["Reach", "Alive", "Pose"] {
        core.connect(
            &Endpoint::local(LINK, port),
            &Endpoint::node(NodeId(robot), LINK, port),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
    }
    Ok(())
}

/// On the controller node of a robot whose body is driven by something other than the
/// server's Ayllu node (a ROS 2 body: `ayllu sim robot --ros2`): the body's behaviors for
/// `targets` targets and [`LINK`], of the same classes as [`install`]'s, connected to nothing.
pub fn install_unconnected(core: &mut NodeCore, targets: usize) -> Result<(), Error> {
    let world = WorldConfig::lab(&priorities(targets));
    Body::install(core, targets, &world)?;
    core.define(link_class()?)?;
    core.create("Link", LINK)?;
    Ok(())
}

/// On the controller node of robot K (node id K, 1..[`BODY_BASE`]): define and create the
/// body's behaviors for `targets` targets and send the motor ports to the served body (node
/// `BODY_BASE + K`); create [`LINK`] and send its `Drive`, `Sent` and `Bytes` to the body. The
/// controller then connects to VISION, SONAR and BASE by name, as on a robot. Refused ([`Error::NotAllowed`]): a node id that is no robot number.
pub fn install(core: &mut NodeCore, targets: usize) -> Result<(), Error> {
    let robot = core.id().0;
    if robot == 0 || robot >= BODY_BASE {
        return Err(Error::NotAllowed {
            what: format!("a served robot's node id is its robot number, 1 to {}; node {robot} is none", BODY_BASE - 1),
        });
    }
    // Only the sensor classes' shapes matter (beams, range); they do not depend on the room.
    let world = WorldConfig::lab(&priorities(targets));
    Body::install(core, targets, &world)?;
    for port in ["Rotate", "Translate"] {
        core.connect(
            &Endpoint::local(BASE, port),
            &Endpoint::node(body_node(robot), BASE, port),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
    }
    core.define(link_class()?)?;
    core.create("Link", LINK)?;
    for port in ["Drive", "Sent", "Bytes"] {
        core.connect(
            &Endpoint::local(LINK, port),
            &Endpoint::node(body_node(robot), LINK, port),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
    }
    Ok(())
}

/// On a served robot's controller node whose controller localizes (`BleSeek`: [`Brain::Seek`]):
/// feed the pose the server sends on the body link (`LINK.Pose`, every sensing tick) to the
/// port the in-process simulator writes it to (`SEEK.Pose`). Nothing for other brains.
pub fn connect_pose(core: &mut NodeCore, brain: &Brain) -> Result<(), Error> {
    if let Brain::Seek { .. } = brain {
        core.connect(
            &Endpoint::local(LINK, "Pose"),
            &Endpoint::local(SEEK, "Pose"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
    }
    Ok(())
}

/// On robot K's controller node: [`install`] the body, then attach a [`LinkDriver`] for
/// `targets` targets that reads the drive from the observer layers by name and counts the
/// node's own emissions (module docs) — what the C library's `ay_sim_body` and Python's
/// `Node.install_served_body` do, so that a controller written in either reports to the server
/// without a line of its own. Refused as [`install`] (nothing is attached then).
pub fn attach(node: &mut ayllu::Node, targets: usize) -> Result<(), Error> {
    install(node.core_mut(), targets)?;
    node.attach(LinkDriver::new(targets));
    Ok(())
}

/// How often a [`LinkDriver`] looks at the target driving the robot: the world's tick, at
/// which the server samples it too.
pub const DRIVE_PERIOD: Duration = Duration::from_millis(50);
/// How often a [`LinkDriver`] reports the radio counts (`LINK.Sent`, `LINK.Bytes`).
pub const REPORT_PERIOD: Duration = Duration::from_millis(250);

/// Where a [`LinkDriver`] reads the drive.
#[derive(Debug)]
enum DriveFrom {
    /// The Fig. 2 observer layers by name, layer n first.
    Layers(Vec<String>),
    /// A controller built by [`crate::controller::build`].
    Brain(Brain),
}

/// `LINK`'s ports on the robot's node: `Reach`, `Drive`, `Sent`, `Bytes`.
#[derive(Clone, Copy, Debug)]
struct LinkPorts {
    reach: PortRef,
    drive: PortRef,
    sent: PortRef,
    bytes: PortRef,
}

impl LinkPorts {
    fn find(core: &NodeCore) -> Option<LinkPorts> {
        let port = |p: &str| core.port(LINK, p).ok();
        Some(LinkPorts { reach: port("Reach")?, drive: port("Drive")?, sent: port("Sent")?, bytes: port("Bytes")? })
    }
}

/// The robot's side of [`LINK`], run by the node's loop (module docs, "What a robot reports,
/// and how"): writes `Drive` when the driving target changes (looked at every
/// [`DRIVE_PERIOD`]), `Sent` and `Bytes` every [`REPORT_PERIOD`], and with a radio link's
/// handle feeds it `Reach`. A node without [`LINK`] (not installed, or removed) is left alone.
///
/// Thread-safety: moved into its node and called on the node's thread only (the radio link's
/// handle guards itself).
pub struct LinkDriver {
    drive_from: DriveFrom,
    radio: Option<LinkHandle>,
    ports: Option<LinkPorts>,
    /// Without a radio link: the emissions counted so far, and their bytes.
    counted: (u64, u64),
    last_drive: Option<u32>,
    next_drive: Option<Instant>,
    next_report: Option<Instant>,
}

impl LinkDriver {
    /// For a controller of `targets` targets built by the program: the drive from its observer
    /// layers `OBS1`..`OBS{targets}` by name; the emissions counted from the node's turns.
    pub fn new(targets: usize) -> LinkDriver {
        LinkDriver {
            drive_from: DriveFrom::Layers((1..=targets).map(|n| format!("OBS{n}")).collect()),
            radio: None,
            ports: None,
            counted: (0, 0),
            last_drive: None,
            next_drive: None,
            next_report: None,
        }
    }

    /// The drive from `brain` ([`Brain::drive`]), the controller [`crate::controller::build`]
    /// made on this node.
    pub fn with_brain(mut self, brain: Brain) -> LinkDriver {
        self.drive_from = DriveFrom::Brain(brain);
        self
    }

    /// The node's transport is wrapped in the [`RadioLink`](crate::served_radio::RadioLink)
    /// `radio` is the handle of: report its counts, and hand it `LINK.Reach`.
    pub fn with_radio(mut self, radio: LinkHandle) -> LinkDriver {
        self.radio = Some(radio);
        self
    }

    /// `LINK`'s ports, found again if the behavior was made (or remade) since.
    fn ports(&mut self, core: &NodeCore) -> Option<LinkPorts> {
        if self.ports.is_none_or(|p| core.last_accepted(p.drive).is_err()) {
            self.ports = LinkPorts::find(core);
        }
        self.ports
    }

    /// Count the radio emissions the node queued this turn (without a radio link).
    fn count(&mut self, core: &mut NodeCore) {
        let body = body_node(core.id().0);
        for out in core.outgoing_mut().iter() {
            if !matches!(out.to, Destination::Node(id) if id == body) {
                self.counted.0 += 1;
                self.counted.1 += wire_len(&out.message);
            }
        }
    }
}

impl ayllu::Driver for LinkDriver {
    fn input(&mut self, core: &mut NodeCore, _now: Instant) {
        if self.radio.is_none() {
            return;
        }
        let Some(ports) = self.ports(core) else { return };
        if let (Some(radio), Ok(Value::Vector(reach))) = (&self.radio, core.read(ports.reach)) {
            radio.set_reach(&reach);
        }
    }

    fn output(&mut self, core: &mut NodeCore, now: Instant) -> Option<Instant> {
        // Before anything this driver writes (to the body: not radio), after the processes.
        if self.radio.is_none() {
            self.count(core);
        }
        let ports = self.ports(core)?;
        if self.next_drive.is_none_or(|t| now >= t) {
            let drive = match &self.drive_from {
                DriveFrom::Layers(layers) => named_chain_drive(core, layers),
                DriveFrom::Brain(brain) => brain.drive(core),
            };
            if self.last_drive != Some(drive) && core.write(now, ports.drive, i64::from(drive)).is_ok() {
                self.last_drive = Some(drive);
            }
            self.next_drive = Some(now + DRIVE_PERIOD);
        }
        if self.next_report.is_none_or(|t| now >= t) {
            let (sent, bytes) = match &self.radio {
                Some(radio) => {
                    let c = radio.counts();
                    (c.sent, c.bytes)
                }
                None => self.counted,
            };
            let _ = core.write(now, ports.sent, sent as i64);
            let _ = core.write(now, ports.bytes, bytes as i64);
            // On the period's grid from the first report; a node that fell behind skips the
            // reports it missed rather than sending them in a burst: at most 4 a second.
            let next = self.next_report.map_or(now, |t| t) + REPORT_PERIOD;
            self.next_report = Some(if next <= now { now + REPORT_PERIOD } else { next });
        }
        match (self.next_drive, self.next_report) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radio::RadioConfig;
    use crate::served_radio::RadioLink;
    use ayllu::{Lockstep, Node};

    const TICK: Duration = Duration::from_millis(10);

    /// A team on a manual clock: robot 1 (its transport wrapped in a [`RadioLink`], whose
    /// handle is returned), its body (node 1001, `LINK` only) and peer robot 2. Robot 1 has the
    /// body for 2 targets, two observer layers `OBS1`, `OBS2` (a `Rotate` port, written by the
    /// test) and a talker that sends peer 2 a message 10 times a second from a process; peer 2
    /// talks back the same way.
    fn team(name: &str) -> (Lockstep, LinkHandle) {
        let mut team = Lockstep::new(name);
        let transport = team.network().attach(NodeId(1)).unwrap();
        let (transport, handle) = RadioLink::new(transport, &RadioConfig::default(), 1);
        team.add_node(Node::new(team.clock().clone(), transport));
        let body = team.add(body_node(1)).unwrap();
        install_body_link(team.node(body).core_mut(), 1).unwrap();
        let peer = team.add(NodeId(2)).unwrap();
        for (i, to) in [(0, NodeId(2)), (peer, NodeId(1))] {
            let node = team.node(i);
            let mut talker = BehaviorClass::new("Talker");
            let out = talker.port(PortSpec::new("Out", 0.0)).unwrap();
            talker.port(PortSpec::new("In", 0.0)).unwrap();
            talker
                .every_hz("Talk", 10.0, move |ctx| {
                    let now = ctx.now().as_secs_f64();
                    let _ = ctx.write(out, now);
                })
                .unwrap();
            node.define(talker).unwrap();
            node.create("Talker", "TALK").unwrap();
            node.connect(&Endpoint::local("TALK", "Out"), &Endpoint::node(to, "TALK", "In"), ConnectionKind::Normal)
                .unwrap();
        }
        (team, handle)
    }

    fn layers(node: &mut Node) {
        let mut layer = BehaviorClass::new("Layer");
        layer.port(PortSpec::new("Rotate", 0.0)).unwrap();
        node.define(layer).unwrap();
        node.create("Layer", "OBS1").unwrap();
        node.create("Layer", "OBS2").unwrap();
    }

    fn link(team: &mut Lockstep, port: &str) -> Value {
        team.node_by_id(body_node(1)).unwrap().read(LINK, port).unwrap()
    }

    fn accepted(team: &mut Lockstep, port: &str) -> Option<Instant> {
        let core = team.node_by_id(body_node(1)).unwrap().core();
        core.last_accepted(core.port(LINK, port).unwrap()).unwrap()
    }

    #[test]
    fn a_program_built_robot_reports_its_drive_by_layer_name_and_its_emissions() {
        let (mut team, handle) = team("link-driver-names");
        // What `ay_sim_body` and Python's `install_served_body` do; the driver is given no
        // radio link: it counts the node's emissions itself, which must come to the link's.
        attach(team.node(0), 2).unwrap();
        layers(team.node(0));
        let mut reports: Vec<(Instant, i64, i64)> = Vec::new();
        let mut drives: Vec<(Duration, i64)> = Vec::new();
        let start = team.now();
        while team.now() < start + Duration::from_secs(3) {
            let t = team.now() - start;
            // OBS2 drives for a while; then OBS1 (higher) overrides it; then nothing does.
            if t >= Duration::from_millis(500) && t < Duration::from_millis(1200) {
                team.node(0).write("OBS2", "Rotate", 0.3).unwrap();
            }
            if t >= Duration::from_millis(900) && t < Duration::from_millis(1500) {
                team.node(0).write("OBS1", "Rotate", -0.3).unwrap();
            }
            team.advance(TICK, TICK);
            let now = team.now();
            if accepted(&mut team, "Sent") == Some(now) {
                let (sent, bytes) =
                    (link(&mut team, "Sent").as_int().unwrap(), link(&mut team, "Bytes").as_int().unwrap());
                let c = handle.counts();
                assert_eq!((sent, bytes), (c.sent as i64, c.bytes as i64), "at {now:?}: the link's counts");
                reports.push((now, sent, bytes));
            }
            if accepted(&mut team, "Drive") == Some(now) {
                drives.push((now - start, link(&mut team, "Drive").as_int().unwrap()));
            }
        }
        // Four reports a second, on a 250 ms grid from the first turn; the emissions grow.
        assert_eq!(reports.len(), 12, "{reports:?}");
        assert!(reports.windows(2).all(|w| w[1].0 - w[0].0 == REPORT_PERIOD), "{reports:?}");
        let (_, sent, bytes) = *reports.last().unwrap();
        assert!((25..=31).contains(&sent), "about 10 a second for 3 s: {sent}");
        assert!(bytes > 10 * sent, "{bytes} bytes for {sent} messages");
        // The drive: none, then target 2, then 1 (the higher layer), then none again; each
        // change written once, within a drive period of its cause.
        let values: Vec<i64> = drives.iter().map(|d| d.1).collect();
        assert_eq!(values, [0, 2, 1, 0], "{drives:?}");
        let at = |i: usize| drives[i].0;
        assert!(at(1) >= Duration::from_millis(500) && at(1) <= Duration::from_millis(500) + DRIVE_PERIOD + TICK);
        assert!(at(2) >= Duration::from_millis(900) && at(2) <= Duration::from_millis(900) + DRIVE_PERIOD + TICK);
        let quiet = Duration::from_millis(1500) + ayllu::stdlib::OVERRIDE_PERIOD;
        assert!(at(3) >= quiet && at(3) <= quiet + DRIVE_PERIOD + TICK, "{drives:?}");
    }

    #[test]
    fn with_a_brain_and_a_radio_link_it_reports_the_links_counts_and_feeds_it_reach() {
        let (mut team, handle) = team("link-driver-brain");
        install(team.node(0).core_mut(), 2).unwrap();
        layers(team.node(0));
        let core = team.node(0).core();
        let brain = Brain::Chain(vec![core.port("OBS1", "Rotate").unwrap(), core.port("OBS2", "Rotate").unwrap()]);
        team.node(0).attach(LinkDriver::new(2).with_brain(brain).with_radio(handle.clone()));
        team.node(0).write("OBS2", "Rotate", 0.1).unwrap();
        team.advance(Duration::from_millis(100), TICK);
        assert_eq!(link(&mut team, "Drive"), Value::Int(2));
        team.advance(Duration::from_millis(900), TICK);
        let before = handle.counts();
        assert!(before.delivered >= 8 && before.cut == 0, "peer 2 is heard: {before:?}");
        // The link's counts as of the last report, at most 250 ms (3 emissions) old.
        let sent = link(&mut team, "Sent").as_int().unwrap() as u64;
        assert!(sent > 0 && sent <= before.sent && sent + 3 >= before.sent, "{sent} reported, {before:?}");
        // The server says peer 2 is out of reach: from then on its messages are cut.
        team.node_by_id(body_node(1)).unwrap().write(LINK, "Reach", Value::vector(&[0.0, 0.0])).unwrap();
        team.advance(Duration::from_secs(1), TICK);
        let after = handle.counts();
        assert!(after.cut >= 8, "{after:?}");
        assert!(after.delivered <= before.delivered + 1, "{before:?} then {after:?}");
        assert_eq!(link(&mut team, "Drive"), Value::Int(0));
    }
}
