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
    /// The node the value came from, or whose connection holds the window.
    pub node: NodeId,
    /// The raw [`ConnectionId`] on `node`; 0 means a process of the port's own behavior (or the
    /// application writing on its behalf), which holds no pass.
    pub conn: u64,
}

impl Source {
    /// The source of a behavior's own writes on `node` (its processes, or
    /// [`NodeCore::write`](crate::NodeCore::write)): connection 0, so it wins Max/Min ties
    /// against every connection of the same node (D3.4).
    pub const fn internal(node: NodeId) -> Source {
        Source { node, conn: 0 }
    }
    /// The source of values arriving along connection `id` owned by `node`. With the node id it
    /// names a pass holder across nodes, so two nodes overriding one port hold separate passes
    /// (D10.3).
    pub const fn connection(node: NodeId, id: ConnectionId) -> Source {
        Source { node, conn: id.0 }
    }
    /// Whether this is a behavior's own write rather than a connection: own writes are never
    /// suppressed and never hold an override pass (D6.5).
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
    Local {
        /// Behavior instance name (`OBS1`).
        behavior: Arc<str>,
        /// Port name (`Rotate`).
        port: Arc<str>,
    },
    /// `(node, behavior, port)` on a named node (possibly this one).
    Node {
        /// The node that owns the port; messages reach it through the transport (D-S10.2).
        node: NodeId,
        /// Behavior instance name on that node.
        behavior: Arc<str>,
        /// Port name.
        port: Arc<str>,
    },
    /// `(group, behavior, port)` on every node of a broadcast group except the sender.
    Group {
        /// Broadcast group name (the paper's `Peers`); nodes join with
        /// [`NodeCore::join`](crate::NodeCore::join).
        group: Arc<str>,
        /// Behavior instance name, the same on every member (the same layer, S11).
        behavior: Arc<str>,
        /// Port name.
        port: Arc<str>,
    },
}

impl Endpoint {
    /// `(behavior, port)` on this node: the usual source of
    /// [`NodeCore::connect`](crate::NodeCore::connect), and a local destination.
    pub fn local(behavior: &str, port: &str) -> Endpoint {
        Endpoint::Local { behavior: behavior.into(), port: port.into() }
    }
    /// `(node, behavior, port)` on node `node` (S10); this node's own id is treated as local.
    /// As a source on another node it is only valid for
    /// [`NodeCore::request_connect`](crate::NodeCore::request_connect), which asks that node
    /// to make the connection (D10.1).
    pub fn node(node: NodeId, behavior: &str, port: &str) -> Endpoint {
        Endpoint::Node { node, behavior: behavior.into(), port: port.into() }
    }
    /// `(group, behavior, port)`: that port on every node that joined `group`, except the sender
    /// (the paper's broadcast connection). A destination only: as a source it is refused with
    /// [`Error::GroupSource`](crate::Error::GroupSource).
    pub fn group(group: &str, behavior: &str, port: &str) -> Endpoint {
        Endpoint::Group { group: group.into(), behavior: behavior.into(), port: port.into() }
    }
    /// The behavior name, whatever the kind of endpoint.
    pub fn behavior(&self) -> &str {
        match self {
            Endpoint::Local { behavior, .. } | Endpoint::Node { behavior, .. } | Endpoint::Group { behavior, .. } => {
                behavior
            }
        }
    }
    /// The port name, whatever the kind of endpoint.
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
