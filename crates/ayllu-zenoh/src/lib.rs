//! # ayllu-zenoh — the `zenoh://` transport
//!
//! Ayllu nodes over a Zenoh session, for teams that need routing, TLS and discovery beyond one
//! subnet (docs/zenoh.md). What it promises:
//! * the bytes are those of `udp://` (spec/protocol.md, the golden vectors): every datagram the
//!   UDP transport would send is one Zenoh payload, so the team key's MAC, sequence numbers,
//!   HELLO liveness, control requests and replies work unchanged, end to end through routers;
//! * the behaviour is that of `udp://`: this crate reuses [`ayllu::UdpTransport`] whole and
//!   only puts a [`ZenohSocket`] in place of its socket, so the [`ayllu::Transport`] contract
//!   (send never blocks, group delivery to every member but the sender, recv never blocks,
//!   wait bounded) holds for the same reasons;
//! * key expressions live under `ayllu/<team>/` (spec/zenoh.md).
//!
//! Zenoh is never in the default build: this is its own cargo project (`make zenoh`), and
//! [`register`] plugs the scheme into [`ayllu::transport::open`], so `Node::open(id,
//! "zenoh://...")` works once it has been called.

#![warn(missing_docs)]

pub mod bridge;
pub mod router;
pub mod zenoh_socket;
pub mod zenoh_transport;
pub mod zenoh_url;

use ayllu::{NodeId, RuntimeError, Transport, UdpTransport};

pub use bridge::Bridge;
pub use router::{Router, RouterOptions};
pub use zenoh_socket::ZenohSocket;
pub use zenoh_transport::ZenohTransport;
pub use zenoh_url::ZenohUrl;

/// Open a `zenoh://` URL (see [`zenoh_url`]) for node `id`.
pub fn open(url: &str, id: NodeId) -> Result<ZenohTransport, RuntimeError> {
    let parsed = ZenohUrl::parse(url)?;
    let socket = ZenohSocket::open(id, &parsed)?;
    let mut config = parsed.config;
    config.broadcast = Some(zenoh_socket::BROADCAST);
    Ok(ZenohTransport::new(UdpTransport::with_socket(id, config, socket)?))
}

fn open_boxed(url: &str, id: NodeId) -> Result<Box<dyn Transport>, RuntimeError> {
    Ok(Box::new(open(url, id)?))
}

/// Register the `zenoh` scheme with [`ayllu::transport::open`] (and so `Node::open`).
pub fn register() {
    ayllu::register_scheme("zenoh", open_boxed);
}
