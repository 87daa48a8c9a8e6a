//! # ayllu-core — port-arbitrated behavior semantics, sans IO
//!
//! The heart of Ayllu (Werger, "Ayllu: Distributed Port-Arbitrated Behavior-Based Control"):
//! behaviors made of processes, whose ports are wired by connections that pass, suppress,
//! inhibit, override or write-inhibit messages, plus the aggregating ports and the Broadcast
//! of Local Eligibility that make teams scale.
//!
//! ## Goals
//! * The rules S1–S11 of `docs/semantics.md`, exactly, and nothing that contradicts them.
//! * Deterministic: no clock, no sockets, no threads, no randomness. Time is passed in
//!   (`poll(now)`), messages for other nodes come out of [`NodeCore::pop_outgoing`] and are
//!   fed in with [`NodeCore::receive`]. The same inputs give the same run.
//! * Fast: a write crossing a Normal connection is a few loads and stores, and propagating a
//!   scalar allocates nothing.
//! * Robust: misuse returns an [`Error`]; bad input from peers is dropped and counted by cause
//!   ([`DropCause`]); nothing panics on input.
//!
//! ## Non-goals
//! * Byte encodings (see `ayllu-wire`), sockets and clocks (see the `ayllu` runtime).
//! * Threads: a node is driven by one thread at a time (`NodeCore` is `Send`, not shared).
//!
//! ## A minimal example
//! ```
//! use ayllu_core::*;
//! let mut node = NodeCore::new(NodeId(1));
//! let mut sensor = BehaviorClass::new("Sensor");
//! sensor.port(PortSpec::new("Out", 0i64)).unwrap();
//! let mut motor = BehaviorClass::new("Motor");
//! motor.port(PortSpec::new("In", 0i64)).unwrap();
//! node.define(sensor).unwrap();
//! node.define(motor).unwrap();
//! node.create("Sensor", "S").unwrap();
//! node.create("Motor", "M").unwrap();
//! node.connect(&Endpoint::local("S", "Out"), &Endpoint::local("M", "In"),
//!              ConnectionKind::Normal, ConnectOptions::default()).unwrap();
//! let out = node.port("S", "Out").unwrap();
//! node.write(Instant::ZERO, out, 42i64).unwrap();
//! assert_eq!(node.read(node.port("M", "In").unwrap()).unwrap(), Value::Int(42));
//! ```

#![warn(missing_docs)]

pub mod access;
pub mod address;
pub mod arbitration;
pub mod behavior;
pub mod ble;
pub mod change;
pub mod connection;
pub mod counters;
pub mod error;
pub mod introspect;
pub mod journal;
pub mod message;
pub mod node;
mod plain;
pub mod port;
mod prefetch;
pub mod process;
mod schedule;
mod sequence;
pub mod time;
pub mod transaction;
pub mod value;

pub use access::{Access, Allow, Limits};
pub use address::{ConnectionId, Endpoint, NodeId, Source};
pub use arbitration::{Origin, Window, WindowKind};
pub use behavior::{BehaviorClass, Mono, Port, ProcessFn, Slot, Trigger, BEST, INHIBIT, LOCAL};
pub use ble::{check_inhibit_period, minimum_inhibit_period, BleConfig, BleGroup, BleStatus, BLE_SELECT};
pub use change::{Applied, Change, ChangeOutcome};
pub use connection::{ConnectOptions, ConnectionInfo, ConnectionKind};
pub use counters::{Counters, DropCause};
pub use error::{Error, ErrorKind};
pub use introspect::{BehaviorReport, NodeReport, PortReport, ProcessReport, RegisterReport, WindowReport};
pub use journal::{Entry, Event, JournalBatch, JournalItem};
pub use message::{ControlBody, ControlMessage, Destination, Message, Outgoing, PortMessage, ReplyBody};
pub use node::{BehaviorRef, NodeCore, PortRef, RequestId, RequestStatus, RETRIGGER_INTERVAL};
#[cfg(feature = "serde")]
pub use node::{Snapshot, SNAPSHOT_VERSION};
pub use port::{PortCell, PortKind, PortSpec};
pub use process::Ctx;
pub use time::{Compact, Duration, Instant};
pub use transaction::{TransactionState, TransactionStatus};
pub use value::{Value, ValueType, MAX_NETWORK_VECTOR};
