//! Ayllu in Foxglove: a live team served over Foxglove's WebSocket protocol, and simulator
//! runs written as MCAP files with a 3-D scene — both through the Foxglove SDK, so recordings
//! and the live team open in Foxglove with no conversion (docs/cli.md, "ayllu foxglove" and
//! "sim run --mcap").
//!
//! * [`team_bridge`]: a node's reports as channels — port values on the team channel layout
//!   (`ayllu::team_channels`), windows and BLE claims on channels of their own;
//! * [`team_watch`]: the live team, asked by LIST and WHY from a small node of its own (the
//!   polling strategy and what it misses are in its docs);
//! * [`live_server`]: the WebSocket server (and optional MCAP file) a watch feeds;
//! * [`sim_scene`] and [`sim_mcap`]: a simulator run as a scene (robots, fields of view,
//!   targets coloured by priority, claims) and its ports, in an MCAP file.
//!
//! This crate is the only one that depends on the SDK (and through it on tokio), so the rest
//! of the workspace builds without it.

pub mod live_server;
pub mod sim_mcap;
pub mod sim_scene;
pub mod team_bridge;
pub mod team_watch;

pub use live_server::{LiveError, LiveServer};
pub use sim_mcap::{run_to_mcap, McapSummary, SimMcapError};
pub use team_bridge::TeamBridge;
pub use team_watch::{TeamWatch, WatchConfig};
