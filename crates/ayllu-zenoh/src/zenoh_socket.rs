//! A [`DatagramSocket`] over a Zenoh session: what lets [`ayllu::UdpTransport`] run on Zenoh.
//!
//! The UDP transport addresses peers by `SocketAddr`; here those are names, not places. A node's
//! address is `NODE_ID_AS_IPV4:NONCE` (the nonce, never 0, tells apart two nodes that
//! wrongly share an id, so the transport's duplicate-id warning still works), and
//! [`BROADCAST`] stands for "every node of the team". Addresses map to key expressions
//! (spec/zenoh.md):
//! * `ayllu/<team>/n/<node>/<nonce>`: one node's inbox (unicast datagrams);
//! * `ayllu/<team>/b`: every node of the team (HELLOs, group messages; the receiving
//!   transport keeps only the groups it joined).
//!
//! Each payload is one datagram's bytes, unchanged; the sender's address travels as the
//! sample's attachment (6 bytes: IPv4 then port, big-endian), since Zenoh has no source
//! address. Promises: `send_to` never blocks (congestion control Drop); `recv_from` never
//! blocks; `wait` blocks at most its timeout. Zenoh's own threads only push into a bounded
//! queue ([`INBOX_LIMIT`]); its async runtime never reaches the node's loop.

use std::collections::{HashMap, VecDeque};
use std::io;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration as StdDuration;

use ayllu::datagram::DatagramSocket;
use ayllu::{NodeId, RuntimeError};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::Locality;
use zenoh::{Config, Session, Wait};

use crate::zenoh_url::ZenohUrl;

/// The address that stands for every node of the team (`ayllu/<team>/b`).
pub const BROADCAST: SocketAddr = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::BROADCAST, 0));

/// Datagrams held between Zenoh's delivery and the node's next receive; beyond it arrivals are
/// dropped and counted ([`ZenohSocket::overflowed`]), so a flood cannot grow memory (N4).
pub const INBOX_LIMIT: usize = 4096;

/// Publishers kept (one per destination); beyond it the cache starts again, so addresses
/// learned from forged datagrams cannot grow it.
const MAX_PUBLISHERS: usize = 1024;

/// Publishers on the key expressions of the addresses sent to, declared on first use and held
/// for the next datagram; a node's socket and the bridge publish through one each, so both
/// send with the same settings. At most `cap` are held: beyond it the cache starts again, so
/// addresses learned from forged datagrams cannot grow it.
pub(crate) struct Publishers {
    held: HashMap<SocketAddr, Publisher<'static>>,
    cap: usize,
}

impl Publishers {
    pub(crate) fn new(cap: usize) -> Publishers {
        Publishers { held: HashMap::new(), cap }
    }

    /// Publish `bytes` on team `team`'s key for `to`, the sender's address as `attachment`.
    pub(crate) fn put(
        &mut self,
        session: &Session,
        team: u32,
        to: SocketAddr,
        bytes: &[u8],
        attachment: &[u8],
    ) -> Result<(), zenoh::Error> {
        if !self.held.contains_key(&to) {
            if self.held.len() >= self.cap {
                self.held.clear();
            }
            let publisher = session
                .declare_publisher(key_for(team, to))
                // Best effort (N1): a congested link drops, it never blocks the sender's loop.
                .congestion_control(CongestionControl::Drop)
                // Ayllu batches a loop turn's messages itself (N3).
                .express(true)
                .allowed_destination(Locality::Remote)
                .wait()?;
            self.held.insert(to, publisher);
        }
        self.held[&to].put(bytes.to_vec()).attachment(attachment.to_vec()).wait()
    }
}

#[derive(Default)]
struct Inbox {
    queue: VecDeque<(Vec<u8>, SocketAddr)>,
}

type Shared = Arc<(Mutex<Inbox>, Condvar)>;

/// A node's datagram socket on a Zenoh session (module docs).
pub struct ZenohSocket {
    session: Session,
    team: u32,
    addr: SocketAddr,
    /// The sender's address as every payload's attachment carries it.
    attachment: [u8; 6],
    inbox: Shared,
    publishers: Publishers,
    /// Kept alive: dropping a subscriber undeclares it.
    _subscribers: Vec<Subscriber<()>>,
    overflowed: Arc<AtomicU64>,
    unattributed: Arc<AtomicU64>,
}

/// The key expression an address stands for.
pub fn key_for(team: u32, addr: SocketAddr) -> String {
    if addr == BROADCAST {
        format!("ayllu/{team}/b")
    } else {
        let ip = match addr.ip() {
            std::net::IpAddr::V4(ip) => u32::from(ip),
            std::net::IpAddr::V6(_) => u32::MAX,
        };
        format!("ayllu/{team}/n/{ip}/{}", addr.port())
    }
}

fn io_error(e: impl std::fmt::Display) -> io::Error {
    io::Error::other(e.to_string())
}

/// The Zenoh configuration a URL asks for (also the bridge's, `crate::bridge`).
pub(crate) fn zenoh_config(url: &ZenohUrl) -> Result<Config, String> {
    let mut c = match &url.config_file {
        Some(path) => Config::from_file(path).map_err(|e| format!("reading Zenoh configuration {path}: {e}"))?,
        None => Config::default(),
    };
    let set = |c: &mut Config, key: &str, value: String| {
        c.insert_json5(key, &value).map_err(|e| format!("Zenoh setting {key}={value}: {e}"))
    };
    let list = |v: &[String]| format!("[{}]", v.iter().map(|e| format!("\"{e}\"")).collect::<Vec<_>>().join(","));
    set(&mut c, "mode", format!("\"{}\"", url.mode))?;
    if !url.connect.is_empty() {
        set(&mut c, "connect/endpoints", list(&url.connect))?;
    }
    if !url.listen.is_empty() || url.mode == "client" {
        set(&mut c, "listen/endpoints", list(&url.listen))?;
    }
    if let Some(on) = url.scouting {
        set(&mut c, "scouting/multicast/enabled", on.to_string())?;
    }
    Ok(c)
}

impl ZenohSocket {
    /// Open a Zenoh session as `url` says and subscribe to node `id`'s inbox and the team's
    /// broadcast key.
    pub fn open(id: NodeId, url: &ZenohUrl) -> Result<ZenohSocket, RuntimeError> {
        let fail = |what: &str, e: String| RuntimeError::Io { what: what.to_owned(), error: e };
        let config = zenoh_config(url).map_err(|e| fail("configuring Zenoh", e))?;
        let session = zenoh::open(config).wait().map_err(|e| fail("opening the Zenoh session", e.to_string()))?;
        // The nonce comes from the session's random id: two processes started with the same
        // node id get different addresses.
        let nonce = nonce_of(&session);
        let addr = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::from(id.0), nonce));
        let mut attachment = [0u8; 6];
        attachment[..4].copy_from_slice(&id.0.to_be_bytes());
        attachment[4..].copy_from_slice(&nonce.to_be_bytes());
        let team = url.config.team;
        let inbox: Shared = Arc::new((Mutex::new(Inbox::default()), Condvar::new()));
        let overflowed = Arc::new(AtomicU64::new(0));
        let unattributed = Arc::new(AtomicU64::new(0));
        let mut subscribers = Vec::new();
        for key in [key_for(team, addr), key_for(team, BROADCAST)] {
            let (inbox, overflowed, unattributed) = (inbox.clone(), overflowed.clone(), unattributed.clone());
            let sub = session
                .declare_subscriber(key.clone())
                .allowed_origin(Locality::Remote)
                .callback(move |sample| {
                    let Some(from) = sample.attachment().and_then(|a| sender(&a.to_bytes())) else {
                        unattributed.fetch_add(1, Ordering::Relaxed);
                        return;
                    };
                    let bytes = sample.payload().to_bytes().into_owned();
                    let (lock, ready) = &*inbox;
                    let mut inbox = lock.lock().unwrap_or_else(|p| p.into_inner());
                    if inbox.queue.len() >= INBOX_LIMIT {
                        overflowed.fetch_add(1, Ordering::Relaxed);
                        return;
                    }
                    inbox.queue.push_back((bytes, from));
                    ready.notify_one();
                })
                .wait()
                .map_err(|e| fail(&format!("subscribing to {key}"), e.to_string()))?;
            subscribers.push(sub);
        }
        Ok(ZenohSocket {
            session,
            team,
            addr,
            attachment,
            inbox,
            publishers: Publishers::new(MAX_PUBLISHERS),
            _subscribers: subscribers,
            overflowed,
            unattributed,
        })
    }

    /// The Zenoh session (its id, for diagnostics).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// Where the session listens, as bound ([`locators_of`]).
    pub fn locators(&self) -> Vec<String> {
        locators_of(&self.session)
    }

    /// Datagrams dropped because the inbox was full.
    pub fn overflowed(&self) -> u64 {
        self.overflowed.load(Ordering::Relaxed)
    }

    /// Samples dropped for carrying no sender address (not sent by an Ayllu node).
    pub fn unattributed(&self) -> u64 {
        self.unattributed.load(Ordering::Relaxed)
    }
}

/// Where `session` listens, as bound: its Zenoh locators (`tcp/127.0.0.1:45125`), port 0
/// resolved to the port the system chose and an unspecified address (`0.0.0.0`) expanded to the
/// host's non-loopback addresses. Empty for a session that listens nowhere (a client without
/// `listen=`). A listener Zenoh is still retrying in the background appears once it is bound.
pub fn locators_of(session: &Session) -> Vec<String> {
    session.info().locators().wait().iter().map(|l| l.as_str().to_owned()).collect()
}

/// A session's address nonce (1 to 65535), from its random Zenoh id.
pub(crate) fn nonce_of(session: &Session) -> u16 {
    session.zid().to_string().bytes().fold(0u16, |h, b| h.rotate_left(5) ^ u16::from(b)).max(1)
}

/// The sender address an attachment carries.
pub(crate) fn sender(a: &[u8]) -> Option<SocketAddr> {
    let a: [u8; 6] = a.try_into().ok()?;
    let ip = Ipv4Addr::new(a[0], a[1], a[2], a[3]);
    Some(SocketAddr::V4(SocketAddrV4::new(ip, u16::from_be_bytes([a[4], a[5]]))))
}

impl DatagramSocket for ZenohSocket {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
        self.publishers.put(&self.session, self.team, to, bytes, &self.attachment).map_err(io_error)
    }

    fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<Option<(usize, SocketAddr)>> {
        let (lock, _) = &*self.inbox;
        let next = lock.lock().unwrap_or_else(|p| p.into_inner()).queue.pop_front();
        Ok(next.map(|(bytes, from)| {
            // Longer than the buffer: copied cut, and reported as the buffer's length, as a
            // UDP socket does; the transport then counts it oversized.
            let n = bytes.len().min(buf.len());
            buf[..n].copy_from_slice(&bytes[..n]);
            (n, from)
        }))
    }

    fn wait(&mut self, timeout: StdDuration) {
        let (lock, ready) = &*self.inbox;
        let inbox = lock.lock().unwrap_or_else(|p| p.into_inner());
        if inbox.queue.is_empty() {
            let _ = ready.wait_timeout(inbox, timeout);
        }
    }

    fn local_addr(&self) -> io::Result<SocketAddr> {
        Ok(self.addr)
    }

    fn join_multicast(&mut self, _group: Ipv4Addr) -> io::Result<()> {
        // Groups travel on the team's broadcast key; there is nothing to join.
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_the_team_and_the_node() {
        assert_eq!(key_for(7, BROADCAST), "ayllu/7/b");
        assert_eq!(key_for(7, "0.0.0.3:99".parse().unwrap()), "ayllu/7/n/3/99");
        assert_eq!(sender(&[0, 0, 0, 3, 0, 99]), Some("0.0.0.3:99".parse().unwrap()));
        assert_eq!(sender(&[1, 2, 3]), None);
    }
}
