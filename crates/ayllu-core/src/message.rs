//! What nodes say to each other, as values — separate from any byte encoding (the wire crate
//! encodes these; the `mem://` transport passes them as they are).
//!
//! Port messages are best effort and carry everything the receiver needs to apply the
//! connection's effect on *its own* clock (rule S8): the kind, its period, the priority, and
//! the sender's connection id and sequence number (N1). Control messages are requests with an
//! id, answered by a reply with the same id, and safe to repeat (N2).

use std::sync::Arc;

use crate::address::{ConnectionId, Endpoint, NodeId};
use crate::change::Change;
use crate::connection::ConnectionKind;
use crate::introspect::{NodeReport, PortReport};
use crate::time::Duration;
use crate::value::Value;

/// Where an outgoing message goes.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Destination {
    /// One node, by id; the transport sends it where that node was last heard from (D-S10.2).
    Node(NodeId),
    /// Every member of the group except the sender.
    Group(Arc<str>),
}

/// One value travelling along a connection to a port on another node.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PortMessage {
    /// The connection on the sending node; with the sender's id it names the pass holder.
    pub conn: ConnectionId,
    /// Increases by one per message on this connection (N1).
    pub seq: u64,
    /// The destination behavior on the receiver.
    pub behavior: Arc<str>,
    /// The destination port.
    pub port: Arc<str>,
    /// The connection's kind and period; the receiver applies it on its own clock (S8).
    pub kind: ConnectionKind,
    /// The connection's priority, for a Priority port (D3.3).
    pub priority: i32,
    /// The source port's value after its merge (S5).
    pub value: Value,
}

/// A reliable request or its reply.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ControlMessage {
    /// Chosen by the requester, unique among its requests; a reply repeats it.
    pub id: u64,
    /// The request, or the reply to request `id`.
    pub body: ControlBody,
}

/// What a control request asks of a node (N2), or the reply to one. Requests are retried
/// until answered, and a receiver answers a repeat from memory, so each is applied once.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ControlBody {
    /// Create a connection from a port of the receiver to `destination` (a `Node` or `Group`
    /// endpoint; never `Local`, which would be ambiguous across nodes).
    Connect {
        /// The receiver's behavior the connection starts from.
        source_behavior: Arc<str>,
        /// Its port.
        source_port: Arc<str>,
        /// Where the connection goes.
        destination: Endpoint,
        /// The connection's kind and period (rule S6).
        kind: ConnectionKind,
        /// The priority of its messages at a Priority port (D3.3).
        priority: i32,
    },
    /// Remove a connection owned by the receiver.
    Disconnect {
        /// The connection's id on the receiver (as CONNECT's reply gave it).
        conn: ConnectionId,
    },
    /// Describe the whole node (answered with [`ReplyBody::Node`]).
    List,
    /// Explain one port (answered with [`ReplyBody::Port`]).
    Why {
        /// The behavior on the receiver.
        behavior: Arc<str>,
        /// The port to explain.
        port: Arc<str>,
    },
    /// Read one port's value (answered with [`ReplyBody::Value`]).
    Read {
        /// The behavior on the receiver.
        behavior: Arc<str>,
        /// The port to read.
        port: Arc<str>,
    },
    /// Transaction `txn` (docs/semantics.md R8): validate `changes` against the receiver's
    /// structure and hold them, refusing other structure changes from the network, for
    /// `hold` after receipt; answered `prepared` or with the refusal.
    Prepare {
        /// Chosen by the coordinator, unique among its transactions.
        txn: u64,
        /// The receiver's part, in order. Endpoints on the receiver name its node.
        changes: Vec<Change>,
        /// How long the receiver holds them waiting for COMMIT or ABORT, on its clock from
        /// receipt; then it aborts by itself.
        hold: Duration,
    },
    /// Switch transaction `txn` in: apply its changes `delay` after receipt (on the
    /// receiver's clock). Repeats do not move the switch; answered `committed`.
    Commit {
        /// The transaction.
        txn: u64,
        /// How long after receipt the switch happens.
        delay: Duration,
    },
    /// Drop prepared transaction `txn`; answered `aborted`.
    Abort {
        /// The transaction.
        txn: u64,
    },
    /// The answer to request `id`, or why it could not be carried out.
    Reply {
        /// What the request returned, or the receiver's error text (e.g. the access rule that
        /// refused it, D9.2).
        result: Result<ReplyBody, String>,
    },
}

impl ControlBody {
    /// Whether this request changes the receiver's structure: the right a node's access rules
    /// (`Access::structure`) and an operator key guard. One list for both, so a new kind of
    /// request cannot be guarded by one and not the other.
    pub fn changes_structure(&self) -> bool {
        matches!(
            self,
            ControlBody::Connect { .. }
                | ControlBody::Disconnect { .. }
                | ControlBody::Prepare { .. }
                | ControlBody::Commit { .. }
                | ControlBody::Abort { .. }
        )
    }
}

/// What a successful request returns.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ReplyBody {
    /// CONNECT: the new connection; DISCONNECT: the removed one.
    Connection(ConnectionId),
    /// READ: the port's readable value (its default while an aggregating port is empty).
    Value(Value),
    /// LIST: the whole node.
    Node(Box<NodeReport>),
    /// WHY: the port explained.
    Port(Box<PortReport>),
    /// A report of a shape this implementation does not model, as its JSON text: an AylluLite
    /// node answers LIST with `{"node":N,"lite":true,"behaviors":[{"name":B,"ports":[P..]}]}`
    /// (spec/protocol.md), which the requester should show rather than refuse.
    OtherReport(String),
}

/// Everything one node says to another, before any byte encoding.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Message {
    /// A value along a connection: best effort, newest wins (N1).
    Port(PortMessage),
    /// A request or reply: retried until answered (N2).
    Control(ControlMessage),
}

/// A message the core wants sent; the runtime hands it to a transport.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Outgoing {
    /// Who should receive it.
    pub to: Destination,
    /// What to send.
    pub message: Message,
}
