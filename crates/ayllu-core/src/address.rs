//! Who and where (rule S10): node ids, the three kinds of endpoint a connection can name, and
//! the [`Source`] that supplied a value.
//!
//! Node ids are numbers because BLE breaks ties by them; behaviors, ports and groups are
//! named, as in the paper (`OBS1`, `Rotate`, `Peers`).

use core::fmt;
use std::sync::Arc;

/// A node: one process running Ayllu. Lower ids win ties (rule S3, S11).
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NodeId(pub u32);

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "n{}", self.0)
    }
}

/// A connection id, unique on the node that owns the connection and never reused.
/// Zero is reserved for "a process of the port's own behavior" in [`Source`].
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ConnectionId(pub u64);

impl fmt::Display for ConnectionId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "c{}", self.0)
    }
}

/// Who supplied a value or holds a window: a connection on some node, or (`conn == 0`) a
/// process of the port's own behavior on that node.
///
/// The derived order — node first, then connection — is the deterministic tie-break: when two
/// sources offer equal values to a Max or Min port, the *smaller* source is kept.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Source {
    pub node: NodeId,
    pub conn: u64,
}

impl Source {
    pub const fn internal(node: NodeId) -> Source {
        Source { node, conn: 0 }
    }
    pub const fn connection(node: NodeId, id: ConnectionId) -> Source {
        Source { node, conn: id.0 }
    }
    pub const fn is_internal(&self) -> bool {
        self.conn == 0
    }
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_internal() {
            write!(f, "{}/process", self.node)
        } else {
            write!(f, "{}/c{}", self.node, self.conn)
        }
    }
}

/// One end of a connection.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Endpoint {
    /// `(behavior, port)` on this node.
    Local { behavior: Arc<str>, port: Arc<str> },
    /// `(node, behavior, port)` on a named node (possibly this one).
    Node { node: NodeId, behavior: Arc<str>, port: Arc<str> },
    /// `(group, behavior, port)` on every node of a broadcast group except the sender.
    Group { group: Arc<str>, behavior: Arc<str>, port: Arc<str> },
}

impl Endpoint {
    pub fn local(behavior: &str, port: &str) -> Endpoint {
        Endpoint::Local { behavior: behavior.into(), port: port.into() }
    }
    pub fn node(node: NodeId, behavior: &str, port: &str) -> Endpoint {
        Endpoint::Node { node, behavior: behavior.into(), port: port.into() }
    }
    pub fn group(group: &str, behavior: &str, port: &str) -> Endpoint {
        Endpoint::Group { group: group.into(), behavior: behavior.into(), port: port.into() }
    }
    pub fn behavior(&self) -> &str {
        match self {
            Endpoint::Local { behavior, .. } | Endpoint::Node { behavior, .. } | Endpoint::Group { behavior, .. } => {
                behavior
            }
        }
    }
    pub fn port(&self) -> &str {
        match self {
            Endpoint::Local { port, .. } | Endpoint::Node { port, .. } | Endpoint::Group { port, .. } => port,
        }
    }
}

impl fmt::Display for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Endpoint::Local { behavior, port } => write!(f, "{behavior}.{port}"),
            Endpoint::Node { node, behavior, port } => write!(f, "{node}:{behavior}.{port}"),
            Endpoint::Group { group, behavior, port } => write!(f, "*{group}:{behavior}.{port}"),
        }
    }
}
