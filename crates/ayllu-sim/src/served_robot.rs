//! The robot's side of a world served by `ayllu sim serve`: the body (VISION, SONAR, BASE)
//! as local behaviors of the robot's node, written by the server (sensors) and read by it
//! (motors) over the network — the stand-in for the paper's `ayInitPioControl` when the
//! controller runs as its own OS process (`ayllu sim robot`, the C library's
//! `ayInitSimBody`).
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

use ayllu::stdlib::BASE;
use ayllu_core::{BehaviorClass, ConnectOptions, ConnectionKind, Endpoint, Error, NodeCore, NodeId, PortSpec, Value};

use crate::body::Body;
use crate::scenario::priorities;
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
/// 1 until killed), `Drive`, `Sent`, `Bytes` (ints). Both ends create it; it has no process.
pub fn link_class() -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Link");
    c.port(PortSpec::new("Reach", Value::vector(&[])))?;
    c.port(PortSpec::new("Alive", 1i64))?;
    for p in ["Drive", "Sent", "Bytes"] {
        c.port(PortSpec::new(p, 0i64))?;
    }
    Ok(c)
}

/// On a body node (the server's, node `BODY_BASE + K`): create [`LINK`] and send its `Reach`
/// and `Alive` to robot K's controller node.
pub fn install_body_link(core: &mut NodeCore, robot: u32) -> Result<(), Error> {
    core.define(link_class()?)?;
    core.create("Link", LINK)?;
    for port in ["Reach", "Alive"] {
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
