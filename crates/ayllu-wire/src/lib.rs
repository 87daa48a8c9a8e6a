//! # ayllu-wire — the Ayllu wire protocol, version 1
//!
//! The byte contract between Ayllu nodes and AylluLite clients, exactly as `spec/protocol.md`
//! describes it. The specification is normative; this crate is its reference implementation
//! and generates the golden vectors (`spec/vectors/vectors.json`) that the C and Python
//! implementations are checked against.
//!
//! ## What it promises
//! * Message types stay separate from their encoding: the core's [`PortMessage`] and
//!   [`ControlBody`] travel inside a [`WireMessage`]; nothing here changes `ayllu-core`.
//! * [`decode()`] never panics, whatever the bytes; it allocates at most a constant factor of the
//!   datagram's size and runs in time linear in it. A datagram that is not applied is refused
//!   whole with exactly one [`DropReason`] (N4).
//! * The encoder ([`DatagramWriter`]) only produces what [`decode()`] accepts, and the two
//!   round-trip: decoding an encoded datagram gives back the same messages.
//! * Authentication (N5) is HMAC-SHA256 truncated to 16 bytes, checked in constant time before
//!   any message is read; [`ReplayWindow`] is the per-sender sequence window applied after.
//!
//! ## Non-goals
//! Sockets, clocks, peers, retries and per-sender state beyond the replay window: those are
//! the runtime's (`ayllu`). Fragmentation of port messages: a value travels in one datagram or
//! not at all (N1).
//!
//! ## Example
//! ```
//! use ayllu_core::{ConnectionId, ConnectionKind, NodeId, PortMessage, Value};
//! use ayllu_wire::*;
//!
//! let msg = WireMessage::Port(PortMessage {
//!     conn: ConnectionId(3),
//!     seq: 1,
//!     behavior: "OBS2".into(),
//!     port: "Rotate".into(),
//!     kind: ConnectionKind::Normal,
//!     priority: 0,
//!     value: Value::Float(-0.25),
//! });
//! let mut writer = DatagramWriter::new(7, NodeId(1), 1 << 32, None, DEFAULT_MTU);
//! writer.push(&msg).unwrap();
//! let bytes = writer.finish();
//!
//! let datagram = decode(&bytes, &ReceiverConfig { team: 7, key: None }).unwrap();
//! assert_eq!(datagram.sender, NodeId(1));
//! assert_eq!(datagram.messages, vec![msg]);
//! assert_eq!(decode(&bytes, &ReceiverConfig { team: 8, key: None }).unwrap_err(), DropReason::WrongTeam);
//! ```

#![warn(missing_docs)]

pub mod auth;
pub mod decode;
pub mod encode;
pub mod message;
pub mod operator;
pub mod reply;

pub use auth::{mac, parse_key_hex, verify_mac, Key, ReplayWindow};
pub use decode::{
    decode, decode_into, decode_with, Datagram, DropReason, Header, MessageSink, NameCache, ReceiverConfig,
};
pub use encode::{encode_datagram, encoded_len, DatagramWriter, EncodeError, PortTemplates};
pub use message::{ReplyPart, WireMessage};
pub use operator::{OperatorPublic, OperatorSecret, OperatorSignature, SignedRequest};
pub use reply::{reply_messages, report_slice_capacity, AssembleError, ReplyAssembler};

// Re-exported so users of the wire types need not name the core crate for them.
pub use ayllu_core::{ControlBody, PortMessage, ReplyBody};

/// The first two bytes of every datagram: "AY".
pub const MAGIC: [u8; 2] = [0x41, 0x59];
/// The protocol version this crate speaks.
pub const VERSION: u8 = 1;
/// Flags bit 0: a 16-byte MAC ends the datagram.
pub const FLAG_AUTH: u8 = 0x01;
/// magic, version, flags, team, sender, sequence.
pub const HEADER_LEN: usize = 20;
/// The truncated HMAC-SHA256 tag.
pub const MAC_LEN: usize = 16;
/// kind u8 + length u16 before every message body.
pub const MESSAGE_HEADER_LEN: usize = 3;
/// Receivers accept datagrams up to this size and drop larger ones as `oversized`.
pub const MAX_DATAGRAM_LEN: usize = 8192;
/// Default size limit for datagrams we send: the UDP payload of a 1500-byte Ethernet frame.
pub const DEFAULT_MTU: usize = 1472;
/// A report is cut into at most this many REPLY parts.
pub const MAX_REPLY_PARTS: u16 = 64;
/// Team keys are 32 bytes.
pub const KEY_LEN: usize = 32;
/// Bytes of a CHALLENGE / ECHO cookie.
pub const COOKIE_LEN: usize = 16;

/// Message kind codes (the `kind` byte before each message).
pub mod kind {
    /// A value along a connection (best effort, N1).
    pub const PORT: u8 = 0x01;
    /// A liveness announcement with the sender's groups (N6).
    pub const HELLO: u8 = 0x02;
    /// A control request (reliable, N2); its `op` byte is one of [`crate::op`].
    pub const REQUEST: u8 = 0x10;
    /// One part of the answer to a request.
    pub const REPLY: u8 = 0x11;
    /// "Echo this cookie": proves a requester's address before a large answer.
    pub const CHALLENGE: u8 = 0x12;
    /// A cookie sent back.
    pub const ECHO: u8 = 0x13;
}

/// REQUEST operation codes.
pub mod op {
    /// Make a connection from one of the receiver's ports (answered with its id).
    pub const CONNECT: u8 = 1;
    /// Remove a connection the receiver owns (answered with its id).
    pub const DISCONNECT: u8 = 2;
    /// Describe the whole node (answered with a `NodeReport`, as JSON in REPLY parts).
    pub const LIST: u8 = 3;
    /// Explain one port (answered with a `PortReport`, as JSON in REPLY parts).
    pub const WHY: u8 = 4;
    /// Read one port's value.
    pub const READ: u8 = 5;
    /// Validate and hold a transaction's part (answered with the text value `prepared`).
    pub const PREPARE: u8 = 6;
    /// Switch a prepared transaction in, after a delay from receipt (answered `committed`).
    pub const COMMIT: u8 = 7;
    /// Drop a prepared transaction (answered `aborted`).
    pub const ABORT: u8 = 8;
}

/// The tags of the structure changes a PREPARE carries.
pub mod change_tag {
    /// Create a behavior: class, name.
    pub const CREATE: u8 = 1;
    /// Remove a behavior: name.
    pub const REMOVE: u8 = 2;
    /// Connect: source and destination endpoints, kind, priority.
    pub const CONNECT: u8 = 3;
    /// Disconnect by id.
    pub const DISCONNECT: u8 = 4;
    /// Disconnect every connection between two endpoints.
    pub const DISCONNECT_BETWEEN: u8 = 5;
    /// Join a group.
    pub const JOIN: u8 = 6;
    /// Leave a group.
    pub const LEAVE: u8 = 7;
    /// Join a BLE peer group: behavior, group, output, claim rate, inhibit period, delay.
    pub const BLE_JOIN: u8 = 8;
}

/// The first datagram sequence number of a sender started at `boot_unix_seconds`: the
/// seconds in the upper 32 bits, so a restarted node numbers above its previous life (spec,
/// "sequence") without storing anything.
pub const fn first_sequence(boot_unix_seconds: u64) -> u64 {
    boot_unix_seconds << 32
}

/// The name under which a receiver counts skipped messages of an unknown kind (not a
/// [`DropReason`]: the rest of the datagram is still applied).
pub const UNKNOWN_KIND: &str = "unknown_kind";
/// The name under which a receiver counts datagrams refused by its [`ReplayWindow`].
pub const REPLAYED: &str = "replayed";
