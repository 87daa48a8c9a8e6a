//! Return routability (spec/protocol.md, "CHALLENGE and ECHO"): a node never makes its answers
//! a weapon against a third party.
//!
//! Source addresses can be forged, so a node does not trust that a requester receives at the
//! address its requests come from until it has *proven* so: it echoed a cookie only this node
//! can make for that (node id, address), or it authenticated with the team key. Until then
//! every answer and challenge sent to it is charged to a budget of three times the bytes
//! received from it; an answer that does not fit is replaced by a CHALLENGE.
//!
//! Promises: a cookie is valid for one (node id, address) and for one to two minutes of the
//! node's clock; it cannot be made without the node's secret, drawn from the operating system
//! at start; nothing here allocates per datagram.

use std::net::SocketAddr;

use ayllu_core::{Instant, NodeId};
use ayllu_wire::{mac, Key, COOKIE_LEN};

/// How many times the bytes received from an unproven address may be sent back to it (QUIC's
/// anti-amplification factor, RFC 9000 section 8).
pub const AMPLIFICATION_FACTOR: u64 = 3;

/// How long one cookie epoch lasts, in seconds; a cookie is accepted in its epoch and the next.
const EPOCH_SECS: u64 = 60;

/// Makes and checks cookies.
pub(crate) struct Cookies {
    secret: Key,
}

impl Cookies {
    /// Cookies under a fresh secret from the operating system (a fixed fallback secret would
    /// let anyone forge proofs, so a failure here is reported, see [`Cookies::new`]).
    pub(crate) fn new() -> Result<Cookies, String> {
        let mut secret = [0u8; 32];
        getrandom::getrandom(&mut secret).map_err(|e| format!("no randomness from the operating system: {e}"))?;
        Ok(Cookies { secret })
    }

    fn at(&self, epoch: u64, node: NodeId, addr: SocketAddr) -> [u8; COOKIE_LEN] {
        // Address as text: one form for IPv4 and IPv6, and a cookie is made once per challenge.
        let mut data = Vec::with_capacity(64);
        data.extend_from_slice(&epoch.to_le_bytes());
        data.extend_from_slice(&node.0.to_le_bytes());
        data.extend_from_slice(addr.to_string().as_bytes());
        mac(&self.secret, &data)
    }

    fn epoch(now: Instant) -> u64 {
        now.as_nanos() / 1_000_000_000 / EPOCH_SECS
    }

    /// The cookie for `node` at `addr` now.
    pub(crate) fn make(&self, now: Instant, node: NodeId, addr: SocketAddr) -> [u8; COOKIE_LEN] {
        self.at(Self::epoch(now), node, addr)
    }

    /// Whether `cookie` was made for `node` at `addr` in this epoch or the one before.
    pub(crate) fn check(&self, now: Instant, node: NodeId, addr: SocketAddr, cookie: &[u8; COOKIE_LEN]) -> bool {
        let e = Self::epoch(now);
        // Not secret-dependent timing that matters: the attacker does not know the cookie's
        // other bytes either way, but compare in constant time all the same.
        let same = |a: &[u8; COOKIE_LEN]| a.iter().zip(cookie).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0;
        same(&self.at(e, node, addr)) || (e > 0 && same(&self.at(e - 1, node, addr)))
    }
}

/// What may still be sent to one peer's address before it is proven.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Budget {
    /// The address proved it receives (echoed a cookie, or authenticated).
    pub(crate) proven: bool,
    /// Bytes of datagrams received from it since it was last unproven.
    pub(crate) received: u64,
    /// Bytes of answers and challenges sent to it since.
    pub(crate) sent: u64,
}

impl Budget {
    /// Whether `bytes` more may be sent; if so they are charged.
    pub(crate) fn spend(&mut self, bytes: u64) -> bool {
        if self.proven {
            return true;
        }
        if self.sent.saturating_add(bytes) > self.received.saturating_mul(AMPLIFICATION_FACTOR) {
            return false;
        }
        self.sent += bytes;
        true
    }

    /// The peer's address changed: nothing is proven about the new one.
    pub(crate) fn reset(&mut self) {
        *self = Budget::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::Duration;

    fn at(s: &str) -> SocketAddr {
        s.parse().unwrap()
    }

    #[test]
    fn a_cookie_is_for_one_node_one_address_and_two_epochs() {
        let c = Cookies::new().unwrap();
        let t0 = Instant::ZERO + Duration::from_secs(600);
        let k = c.make(t0, NodeId(1), at("127.0.0.1:5000"));
        assert!(c.check(t0, NodeId(1), at("127.0.0.1:5000"), &k));
        assert!(c.check(t0 + Duration::from_secs(60), NodeId(1), at("127.0.0.1:5000"), &k), "the next epoch");
        assert!(!c.check(t0 + Duration::from_secs(120), NodeId(1), at("127.0.0.1:5000"), &k), "too old");
        assert!(!c.check(t0, NodeId(2), at("127.0.0.1:5000"), &k), "another node id");
        assert!(!c.check(t0, NodeId(1), at("127.0.0.1:5001"), &k), "another address");
        let other = Cookies::new().unwrap();
        assert!(!other.check(t0, NodeId(1), at("127.0.0.1:5000"), &k), "another node's secret");
    }

    #[test]
    fn an_unproven_address_gets_three_times_what_it_sent() {
        let mut b = Budget { received: 40, ..Budget::default() };
        assert!(b.spend(100));
        assert!(!b.spend(21), "121 > 120");
        assert!(b.spend(20));
        assert_eq!(b.sent, 120);
        b.proven = true;
        assert!(b.spend(1_000_000), "a proven address is not limited");
        b.reset();
        assert!(!b.spend(1), "a new address starts with nothing");
    }
}
