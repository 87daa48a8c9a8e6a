//! [`Driver`]: what joins a node's body to the world that is not an Ayllu team — a robot's
//! sensors and motors behind a middleware (the ROS 2 body, `crates/ayllu-ros2`), a serial
//! port, a camera library.
//!
//! A body is behaviors with ports, like any other (`ayllu::stdlib`'s VISION, SONAR, BASE); a
//! driver writes the sensor ports and reads the motor ports. The simulator's bodies are driven
//! by the simulator's loop; a [`Driver`] lets a body be driven by the node's own loop, so a
//! controller written for one body runs on another unchanged — the C API's `ayInitRos2Body`
//! and `ayllu node --ros2` attach one and nothing else changes.
//!
//! Promises:
//! * a driver runs on the node's thread, inside [`crate::Node::step`]: [`Driver::input`]
//!   after the turn's messages were received and before the core runs what is due, so a value
//!   that arrived from outside is seen by the processes it triggers in the same turn;
//!   [`Driver::output`] after, so what the processes wrote leaves in the same turn;
//! * what a driver writes goes through [`NodeCore::write`], the behavior's own write: it is
//!   journaled and recorded like [`crate::Node::write`] (a recording replays it), it
//!   propagates and is arbitrated like any other write, and `why` explains it;
//! * the node sleeps no longer than the driver asks ([`Driver::output`]'s answer), which is how
//!   a driver whose inputs arrive on threads of their own bounds their latency.

use ayllu_core::{Instant, NodeCore};

/// A body's link to the outside world, run by the node's loop (module docs).
///
/// Thread-safety: a driver is moved into its node and called only from the thread that steps
/// the node; what it shares with threads of its own (a middleware's) it guards itself.
pub trait Driver: Send {
    /// Write what arrived from outside since the last turn into the body's ports, at `now`.
    fn input(&mut self, core: &mut NodeCore, now: Instant);
    /// Send out what the body's ports hold now. Returns when the driver next needs a turn
    /// even if nothing else happens (its polling period), or `None`.
    fn output(&mut self, core: &mut NodeCore, now: Instant) -> Option<Instant>;
}
