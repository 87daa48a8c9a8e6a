//! # ayllu — the runtime
//!
//! Wraps the sans-IO [`ayllu_core`] in what a program needs to run it: a [`Node`] with a
//! [`Clock`] (real monotonic or [`ManualClock`]) and a [`Transport`] chosen by URL
//! (`mem://` in-process, `udp://` on IP networks), and [`Lockstep`] for deterministic teams on
//! virtual time. [`faults`] puts seeded network faults between nodes for tests (the userspace
//! shaper between network namespaces, a tool, lives in `ayllu-cli`). Everything in the core is
//! re-exported, so `use ayllu::*` is enough.

#![warn(missing_docs)]

mod admission;
pub mod ask;
pub mod clock;
pub mod datagram;
pub mod driver;
pub mod error;
pub mod faults;
pub mod lockstep;
mod mcap_records;
pub mod mem;
pub mod node;
pub mod operator;
pub mod plan_file;
pub mod recording;
pub mod recording_cdr;
pub mod recording_format;
pub mod replay;
pub mod report_json;
pub mod routability;
pub mod stdlib;
pub mod team_channels;
pub mod team_recording;
pub mod team_replay;
pub mod transaction;
pub mod transport;
pub mod udp;
pub mod udp_config;

pub use ask::AskError;
pub use ayllu_core::*;
pub use clock::{Clock, ManualClock, MonotonicClock};
pub use driver::Driver;
pub use error::Error as RuntimeError;
pub use lockstep::Lockstep;
pub use mem::{MemNetwork, MemTransport};
pub use node::{Node, NodeStats};
pub use recording::{RecordOptions, RecordStats, Recorder};
pub use replay::{Recording, Replay};
pub use transport::{register_scheme, PeerInfo, SchemeFactory, SendTally, Sent, Transport, TransportEvent};
pub use udp::UdpTransport;
pub use udp_config::{default_url, UdpConfig, DEFAULT_URL, URL_ENV};

/// The README's Rust examples, compiled and run by `cargo test`.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
