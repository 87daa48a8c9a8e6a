//! The robot's side of a world served by `ayllu sim serve`: the body (VISION, SONAR, BASE)
//! as local behaviors of the robot's node, written by the server (sensors) and read by it
//! (motors) over the network — the stand-in for the paper's `ayInitPioControl` when the
//! controller runs as its own OS process (`ayllu sim robot`, the C library's
//! `ayInitSimBody`).
//!
//! Node ids (docs/cli.md): the controller of robot K is node K; its body on the server is
//! node [`BODY_BASE`] + K. The server connects the body's sensor ports to the same ports of
//! node K; [`install`] connects node K's `BASE.Rotate` and `BASE.Translate` to the body's.

use ayllu::stdlib::BASE;
use ayllu_core::{ConnectOptions, ConnectionKind, Endpoint, Error, NodeCore, NodeId};

use crate::body::Body;
use crate::scenario::priorities;
use crate::world::WorldConfig;

/// The body of robot K is node `BODY_BASE + K` on the server.
pub const BODY_BASE: u32 = 1000;

/// The server's node for robot `robot`'s body.
pub fn body_node(robot: u32) -> NodeId {
    NodeId(BODY_BASE + robot)
}

/// On the controller node of robot K (node id K, 1..[`BODY_BASE`]): define and create the
/// body's behaviors for `targets` targets and send the motor ports to the served body (node
/// `BODY_BASE + K`). The controller then connects to VISION, SONAR and BASE by name, as on a
/// robot. Refused ([`Error::NotAllowed`]): a node id that is no robot number.
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
    Ok(())
}
