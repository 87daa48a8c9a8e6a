//! Who may change a node from the network, and how much one peer may cost it (N4, open teams).
//!
//! In the paper's open team anyone who can reach a node may write its ports and rewire it. A
//! node can narrow that: [`Access`] says which nodes may write its ports along connections and
//! which may change its structure by request (CONNECT, DISCONNECT); reads (LIST, WHY, READ)
//! stay open. [`Limits`] bound what the network can make a node hold: connections created by
//! request (in all and per requesting node), the period of any window a message opens,
//! and the rate of control requests per requesting node. What is refused is counted
//! (`not_allowed`, `too_long`, `rate_limited`, `bad_request`) and never applied;
//! requests get an error that says which rule refused them.
//!
//! Connections created by request are *leased* to their requester: they are removed when the
//! requester's node is lost (`NodeCore::node_lost`), so a killed tool's connections do not
//! stay for good (docs/semantics.md D9.1).

use crate::address::NodeId;
use crate::time::Duration;

/// Which nodes a right is given to.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Allow {
    /// Every node that can reach this one (the paper's open team; the default).
    #[default]
    Everyone,
    /// No other node.
    Nobody,
    /// Only these nodes.
    Only(Vec<NodeId>),
}

impl Allow {
    /// Whether node `n` has the right.
    pub fn admits(&self, n: NodeId) -> bool {
        match self {
            Allow::Everyone => true,
            Allow::Nobody => false,
            Allow::Only(ids) => ids.contains(&n),
        }
    }
}

/// The rights other nodes have on this one. The node's own code is never restricted.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Access {
    /// Who may write this node's ports along connections (port messages of every kind).
    pub ports: Allow,
    /// Who may change this node's structure by request (CONNECT, DISCONNECT).
    pub structure: Allow,
}

/// Bounds on what the network can make a node hold. The defaults are far above the paper's use
/// (a BLE team holds one connection per layer and peer; windows of a few seconds).
#[derive(Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Limits {
    /// Connections created by request, from all nodes together.
    pub remote_connections: usize,
    /// Connections created by request, from any one node.
    pub remote_connections_per_node: usize,
    /// The longest window a message from the network may open; a longer one is refused and
    /// counted as `too_long` (not clamped in silence).
    pub max_remote_period: Duration,
    /// Control requests (CONNECT, DISCONNECT, LIST, WHY, READ) answered per second from any
    /// one node, on average; more are dropped unanswered and counted `rate_limited`. Replies can
    /// be much larger than requests (a LIST), so this bounds what one requester can make a node
    /// send.
    pub requests_per_second: u32,
    /// How many requests one node may send at once above that rate.
    pub requests_burst: u32,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            remote_connections: 256,
            remote_connections_per_node: 32,
            max_remote_period: Duration::from_secs(600),
            requests_per_second: 50,
            requests_burst: 100,
        }
    }
}
