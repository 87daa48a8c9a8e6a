//! # ayllu-ros2 — the ROS 2 body
//!
//! Behaviors whose ports are ROS 2 topics, declared in a mapping file ([`Mapping`],
//! docs/ros2.md). It is to a ROS 2 robot what `ayllu_sim::served_robot` is to the simulator: a
//! controller connects to `SONAR.Ranges` and `BASE.Rotate` by name and cannot tell whether a
//! LaserScan on `/robot2/scan` or the simulator wrote them. Fig. 2 moves from the simulator to a
//! robot by changing one line (`ayInitSimBody` -> `ayInitRos2Body("robot.toml")`).
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mut node = ayllu::Node::open(ayllu::NodeId(2), "udp://0.0.0.0:0")?;
//! ayllu_ros2::install_file(&mut node, "robot2.toml")?;
//! // ... build the controller on SONAR, VISION, BASE as on any body ...
//! node.run_for(std::time::Duration::from_secs(60));
//! # Ok(()) }
//! ```
//!
//! Goals: speak ROS 2's conventions exactly (topic prefix `rt/`, type names
//! `pkg::msg::dds_::Type_`, CDR, the QoS profiles a ROS 2 node uses), so that ROS 2 tools and
//! nodes on the same network see and use the topics; treat every sample from the network as
//! untrusted (decoded without panics, bounded before allocation, dropped and counted by
//! cause); keep the node's semantics: a sample is a port write like any other.
//!
//! Non-goals: services and actions; message types beyond [`messages`] (each one added there is
//! a schema, not code); ROS time (`/clock`): stamps are the system clock, as a robot's are.
//!
//! Built on `ros2-client` (RustDDS): pure Rust, no C library to install; tested against Cyclone
//! DDS (the DDS under `rmw_cyclonedds_cpp`) from Python. Fast DDS, Jazzy's default, speaks the
//! same RTPS standard but is not tested here.

pub mod body;
pub mod fleet;
pub mod mapping;
pub mod messages;
mod spelling;

use std::fmt;
use std::path::Path;

pub use body::{participant, Ros2Body};
pub use mapping::{Direction, Mapping, MappingError, Qos, Topic};
pub use ros2_client::Context;

/// What can go wrong installing a ROS 2 body.
#[derive(Debug)]
pub enum Error {
    /// The mapping file could not be read.
    Read {
        /// The file.
        path: String,
        /// Why.
        error: String,
    },
    /// The mapping file is wrong (where, what, and the fix).
    Mapping {
        /// The file, or empty for text given directly.
        path: String,
        /// What is wrong.
        error: MappingError,
    },
    /// The mapping does not fit the node (a port missing, of the wrong type).
    Install(String),
    /// The DDS stack refused (a participant, topic, reader or writer could not be created).
    Ros2(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Read { path, error } => write!(f, "reading {path}: {error}"),
            Error::Mapping { path, error } if path.is_empty() => write!(f, "{error}"),
            Error::Mapping { path, error } => write!(f, "{path}: {error}"),
            Error::Install(e) => write!(f, "{e}"),
            Error::Ros2(e) => write!(f, "ROS 2: {e}"),
        }
    }
}

impl std::error::Error for Error {}

/// Install the ROS 2 body `mapping` describes on `node` and attach its driver: from the next
/// step on, samples write the ports and the ports are published.
pub fn install(node: &mut ayllu::Node, mapping: &Mapping) -> Result<(), Error> {
    let body = Ros2Body::install(node.core_mut(), mapping)?;
    node.attach(body);
    Ok(())
}

/// Read the mapping file at `path` for this node (`{id}` in it is the node's id) and
/// [`install`] it.
pub fn install_file(node: &mut ayllu::Node, path: impl AsRef<Path>) -> Result<(), Error> {
    let mapping = read_mapping(path, Some(node.id()))?;
    install(node, &mapping)
}

/// Read and check the mapping file at `path`; `{id}` in it stands for `node`'s number (one
/// file for a fleet: `namespace = "/robot{id}"`), and is refused without one.
pub fn read_mapping(path: impl AsRef<Path>, node: Option<ayllu::NodeId>) -> Result<Mapping, Error> {
    let path = path.as_ref();
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::Read { path: shown.clone(), error: e.to_string() })?;
    Mapping::parse_for(&text, node).map_err(|error| Error::Mapping { path: shown, error })
}
