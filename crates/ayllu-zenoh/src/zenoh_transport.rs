//! [`ZenohTransport`]: the `udp://` transport's protocol engine on a [`ZenohSocket`], with the
//! socket's own drops in its counters.
//!
//! Promises: every [`Transport`] method is the UDP transport's, unchanged, except the address
//! (below) and the counters, which add what the Zenoh socket dropped before the engine saw it
//! (N4: nothing is dropped uncounted), so `ayllu list` shows them beside the engine's:
//! * `zenoh_overflowed`: datagrams dropped because the socket's inbox was full
//!   ([`ZenohSocket::overflowed`]);
//! * `zenoh_unattributed`: samples without a valid sender attachment, so not from an Ayllu
//!   node ([`ZenohSocket::unattributed`]).
//!
//! Like the engine's causes, each appears once it is not zero.
//!
//! [`Transport::address`] is where peers reach the node, as a peer's `connect=` names it: the
//! session's listening locators, as bound ([`ZenohSocket::locators`]), comma-separated
//! (`tcp/127.0.0.1:45125`; `listen=tcp/127.0.0.1:0` comes back with the port the system
//! chose), or `None` for a node that listens nowhere (a client without `listen=`). The engine's
//! own address (`NODE_ID_AS_IPV4:NONCE`, the node's name on the team's key expressions) stays
//! [`ZenohTransport::zenoh_name`].

use std::collections::VecDeque;

use ayllu::transport::TransportWrapper;
use std::net::SocketAddr;

use ayllu::{Message, NodeId, Outgoing, SendTally, Transport, UdpTransport};

use crate::zenoh_socket::ZenohSocket;

/// The socket's counter names, in the order they are reported.
pub const SOCKET_COUNTERS: [&str; 2] = ["zenoh_overflowed", "zenoh_unattributed"];

/// The `zenoh://` transport (module docs).
pub struct ZenohTransport {
    inner: UdpTransport<ZenohSocket>,
}

impl ZenohTransport {
    /// The UDP protocol engine `inner`, counted with its socket's drops.
    pub fn new(inner: UdpTransport<ZenohSocket>) -> ZenohTransport {
        ZenohTransport { inner }
    }

    /// The protocol engine (peer list, local address, ...).
    pub fn engine(&self) -> &UdpTransport<ZenohSocket> {
        &self.inner
    }

    /// The Zenoh socket under the engine.
    pub fn socket(&self) -> &ZenohSocket {
        self.inner.socket()
    }

    /// The node's name on Zenoh: `NODE_ID_AS_IPV4:NONCE`, whose key expression
    /// (`ayllu/<team>/n/<node>/<nonce>`) is its inbox (spec/zenoh.md); what the engine calls its
    /// local address and puts in every sample's attachment.
    pub fn zenoh_name(&self) -> Option<SocketAddr> {
        self.inner.local_addr()
    }

    fn socket_counts(&self) -> [u64; 2] {
        [self.socket().overflowed(), self.socket().unattributed()]
    }
}

/// Sending and receiving go straight to the engine (its batch paths too); only the counters
/// change.
impl TransportWrapper for ZenohTransport {
    type Inner = UdpTransport<ZenohSocket>;
    fn inner(&self) -> &Self::Inner {
        &self.inner
    }
    fn inner_mut(&mut self) -> &mut Self::Inner {
        &mut self.inner
    }
    fn send_all(&mut self, outbox: &mut VecDeque<Outgoing>, tally: &mut SendTally) {
        self.inner.send_all(outbox, tally)
    }
    fn recv_all(&mut self, deliver: &mut dyn FnMut(NodeId, &Message)) {
        self.inner.recv_all(deliver)
    }
    fn counters(&self) -> Vec<(String, u64)> {
        let mut out = self.inner.counters();
        for (name, n) in SOCKET_COUNTERS.iter().zip(self.socket_counts()) {
            if n > 0 {
                out.push(((*name).to_owned(), n));
            }
        }
        out
    }
    fn counters_into(&self, out: &mut Vec<(String, u64)>) {
        // The engine's part first, on the list as the engine last wrote it (its fast path
        // copies numbers only when the list is the one it wrote), then the socket's.
        while out.last().is_some_and(|(name, _)| SOCKET_COUNTERS.contains(&name.as_str())) {
            out.pop();
        }
        self.inner.counters_into(out);
        for (name, n) in SOCKET_COUNTERS.iter().zip(self.socket_counts()) {
            if n > 0 {
                out.push(((*name).to_owned(), n));
            }
        }
    }
    fn address(&self) -> Option<String> {
        let locators = self.socket().locators();
        (!locators.is_empty()).then(|| locators.join(","))
    }
    fn counters_generation(&self) -> u64 {
        // Every part only grows, so the sum changes whenever any of them does.
        let [a, b] = self.socket_counts();
        self.inner.counters_generation().wrapping_add(a).wrapping_add(b)
    }
}
