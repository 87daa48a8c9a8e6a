//! A deterministic 2-D multi-robot simulator for Ayllu, and the paper's multi-target
//! observation task (W-CMOMMT) on it.
//!
//! Promises: virtual time only (nothing reads a clock); the same [`scenario::Scenario`] and
//! seed give the same run bit for bit (positions, messages, metrics, trace hash); each robot's
//! body is a set of behaviors with ports on the robot's own node (VISION, BASE, SONAR), so a
//! controller written for a robot runs here unchanged; a scenario out of bounds is refused,
//! naming its field, before anything is built ([`bounds`]), never met by a panic.
//!
//! Non-goals: physical fidelity beyond unicycle kinematics and circle/segment contacts; 3-D;
//! real-time pacing (the distributed server paces itself).

#![warn(missing_docs)]

pub mod body;
pub mod bounds;
pub mod classes;
pub mod controller;
pub mod metrics;
mod numbers;
pub mod radio;
pub mod recording;
pub mod redistribution;
pub mod report;
pub mod scenario;
pub mod scenario_file;
mod scenario_spec;
pub mod served_radio;
pub mod served_robot;
pub mod served_world;
pub mod study;
pub mod sweep;
pub mod trace;
mod workers;
pub mod world;
