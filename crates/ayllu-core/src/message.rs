//! What nodes say to each other, as values — separate from any byte encoding (the wire crate
//! encodes these; the `mem://` transport passes them as they are).
//!
//! Port messages are best effort and carry everything the receiver needs to apply the
//! connection's effect on *its own* clock (rule S8): the kind, its period, the priority, and
//! the sender's connection id and sequence number (N1). Control messages are requests with an
//! id, answered by a reply with the same id, and safe to repeat (N2).

use std::sync::Arc;

use crate::address::{ConnectionId, Endpoint, NodeId};
use crate::connection::ConnectionKind;
use crate::introspect::{NodeReport, PortReport};
use crate::value::Value;

/// Where an outgoing message goes.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Destination {
    Node(NodeId),
    /// Every member of the group except the sender.
    Group(Arc<str>),
}

/// One value travelling along a connection to a port on another node.
#[derive(Clone, Debug, PartialEq)]
pub struct PortMessage {
    /// The connection on the sending node; with the sender's id it names the pass holder.
    pub conn: ConnectionId,
    /// Increases by one per message on this connection (N1).
    pub seq: u64,
    pub behavior: Arc<str>,
    pub port: Arc<str>,
    pub kind: ConnectionKind,
    pub priority: i32,
    pub value: Value,
}

/// A reliable request or its reply.
#[derive(Clone, Debug, PartialEq)]
pub struct ControlMessage {
    /// Chosen by the requester, unique among its requests; a reply repeats it.
    pub id: u64,
    pub body: ControlBody,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ControlBody {
    /// Create a connection from a port of the receiver to `destination` (a `Node` or `Group`
    /// endpoint; never `Local`, which would be ambiguous across nodes).
    Connect {
        source_behavior: Arc<str>,
        source_port: Arc<str>,
        destination: Endpoint,
        kind: ConnectionKind,
        priority: i32,
    },
    /// Remove a connection owned by the receiver.
    Disconnect { conn: ConnectionId },
    /// Describe the whole node (answered with [`ReplyBody::Node`]).
    List,
    /// Explain one port (answered with [`ReplyBody::Port`]).
    Why { behavior: Arc<str>, port: Arc<str> },
    /// Read one port's value (answered with [`ReplyBody::Value`]).
    Read { behavior: Arc<str>, port: Arc<str> },
    /// The answer to request `id`, or why it could not be carried out.
    Reply { result: Result<ReplyBody, String> },
}

/// What a successful request returns.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ReplyBody {
    /// CONNECT: the new connection; DISCONNECT: the removed one.
    Connection(ConnectionId),
    Value(Value),
    Node(Box<NodeReport>),
    Port(Box<PortReport>),
    /// A report of a shape this implementation does not model, as its JSON text: an AylluLite
    /// node answers LIST with `{"node":N,"lite":true,"behaviors":[{"name":B,"ports":[P..]}]}`
    /// (spec/protocol.md), which the requester should show rather than refuse.
    OtherReport(String),
}

#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    Port(PortMessage),
    Control(ControlMessage),
}

/// A message the core wants sent; the runtime hands it to a transport.
#[derive(Clone, Debug, PartialEq)]
pub struct Outgoing {
    pub to: Destination,
    pub message: Message,
}
