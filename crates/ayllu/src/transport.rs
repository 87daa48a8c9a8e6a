//! The transport boundary: how a node's outgoing messages leave and incoming ones arrive.
//!
//! A transport moves [`Message`] values between nodes. It is chosen by URL:
//! `mem://NAME` (in-process), `udp://...` (real networks, see [`crate::udp_config`]) and
//! `sim://` (the simulator's radio, later). The contract every transport keeps:
//! * `send` never blocks and never fails loudly: port messages are best effort (N1);
//! * a message to a group reaches every member except the sender;
//! * `recv` never blocks; `wait` blocks at most until its timeout.

use std::collections::VecDeque;

use ayllu_core::{Instant, Message, NodeId, Outgoing};

use crate::error::Error;
use crate::mem::MemNetwork;
use crate::udp::UdpTransport;
use crate::udp_config::UdpConfig;

/// Moves messages between nodes. See the module docs for the contract.
pub trait Transport: Send {
    /// This node's id on the transport.
    fn local(&self) -> NodeId;
    /// Hand a message over for delivery (best effort), and say what became of it: a message
    /// is only reported [`Sent::Now`] when it really leaves (N1 stays best effort after that).
    fn send(&mut self, out: Outgoing) -> Sent;
    /// Hand over every message of `outbox`, oldest first, leaving it empty, and count what
    /// became of each in `tally`: what [`Transport::send`] on each does (the default). A
    /// transport that can send a borrowed message overrides it to send the messages where they
    /// lie, sparing each its moves out of the queue and into `send`.
    fn send_all(&mut self, outbox: &mut VecDeque<Outgoing>, tally: &mut SendTally) {
        while let Some(out) = outbox.pop_front() {
            tally.add(self.send(out));
        }
    }
    /// The next message that has arrived, if any. Never blocks.
    fn recv(&mut self) -> Option<(NodeId, Message)>;
    /// Hand `deliver` every message that has arrived, in order, until [`Transport::recv`] would
    /// return `None`: what calling `recv` until then does (the default). A transport that
    /// queues what it decoded overrides it to hand the messages over where they lie, sparing
    /// each its move out of the queue. Never blocks.
    fn recv_all(&mut self, deliver: &mut dyn FnMut(NodeId, &Message)) {
        while let Some((from, message)) = self.recv() {
            deliver(from, &message);
        }
    }
    /// Block until a message may be available or `timeout` passes.
    fn wait(&mut self, timeout: std::time::Duration);
    /// Start receiving messages sent to `group`.
    fn join(&mut self, group: &str);
    /// Stop receiving messages sent to `group`.
    fn leave(&mut self, group: &str);
    /// End of a loop turn: send what `send` batched (N3).
    fn flush(&mut self) {}
    /// Let the transport do timed work (liveness announcements, forgetting silent peers).
    /// Returns when it next needs a tick.
    fn tick(&mut self, now: Instant) -> Option<Instant> {
        let _ = now;
        None
    }
    /// Counters by cause: traffic, and everything dropped before reaching the core (N4).
    fn counters(&self) -> Vec<(String, u64)> {
        Vec::new()
    }
    /// Whether the node's clock is real time (told once, when the node is made). A transport
    /// may then trade exactness at the microsecond for system calls: the UDP transport lets a
    /// receive that found nothing stand for [`crate::datagram::RECHECK`]. On a manual clock
    /// (lockstep teams, simulated time) every step must hear what has arrived.
    fn set_real_time(&mut self, real_time: bool) {
        let _ = real_time;
    }
    /// Write what `counters` returns into `out`. A node calls this after every loop turn in
    /// which the counters changed, so transports that count per datagram should override it to
    /// reuse `out`'s strings instead of allocating them again.
    fn counters_into(&self, out: &mut Vec<(String, u64)>) {
        *out = self.counters();
    }
    /// Changes whenever `counters` would return something new.
    fn counters_generation(&self) -> u64 {
        0
    }
    /// The peers this transport knows of.
    fn peers(&self) -> Vec<PeerInfo> {
        Vec::new()
    }
    /// Move what happened on the network since the last call into `out`, in the order it
    /// happened (see [`TransportEvent`]). No default: a transport says what it has to tell,
    /// even if that is nothing, and a wrapper ([`TransportWrapper`]) passes its inner
    /// transport's events on unless it overrides this.
    fn take_events(&mut self, out: &mut Vec<TransportEvent>);
    /// Where peers reach this node, as a peer's URL would name it (`127.0.0.1:45125` for
    /// `udp://`), once bound: a node bound to port 0 learns its real port here. `None` for
    /// transports without addresses (`mem://`).
    fn address(&self) -> Option<String> {
        None
    }
}

/// What a transport tells its node besides the messages it delivers. The node acts on each
/// as it takes them, after receiving ([`Transport::take_events`]).
#[derive(Clone, Debug, PartialEq)]
pub enum TransportEvent {
    /// A peer forgotten: silent for its liveness period (N6), or gone from an in-process
    /// network. The node releases what it held on our ports (D3.7).
    PeerLost(NodeId),
    /// Something about the network the node's report should warn of (another node using this
    /// node's id, a discovery address that cannot be joined, ...).
    Warning(String),
    /// A control request this transport cannot send at all, e.g. larger than one datagram.
    /// The node fails it at once ([`ayllu_core::NodeCore::fail_request`]) rather than
    /// retrying it for 5 s.
    RequestFailed {
        /// The node it was for.
        to: NodeId,
        /// The request's id.
        id: u64,
        /// Why it cannot be sent, and what to do.
        why: String,
    },
}

/// A transport built around another one, changing part of what it does: the recording tap,
/// the simulator's radio link, the zenoh transport. Implementing this rather than
/// [`Transport`] gives every method the wrapper does not override to the inner transport, so
/// a wrapper cannot drop what it does not know of (the events of [`Transport::take_events`]
/// above all: three wrappers that forwarded methods by hand once lost failed requests, and an
/// oversized request retried for 5 s through them).
///
/// The batch methods (`send_all`, `recv_all`, `counters_into`) default to the wrapper's own
/// `send`, `recv` and `counters`, so a wrapper that changes one of those is seen on the batch
/// paths too; a wrapper that changes none of them may override the batch methods to reach the
/// inner transport's faster ones. A method added to [`Transport`] is added here, with a default
/// that reaches the inner transport, and to the blanket implementation below (and to the box's
/// forwarding). It is not re-exported at the crate root, so `use ayllu::*` does not bring it
/// into scope: where both traits are, call a wrapper's methods as [`Transport`]'s
/// (`Transport::recv(&mut tap)`).
pub trait TransportWrapper: Send {
    /// The transport wrapped.
    type Inner: Transport + ?Sized;
    /// The transport wrapped.
    fn inner(&self) -> &Self::Inner;
    /// The transport wrapped.
    fn inner_mut(&mut self) -> &mut Self::Inner;
    /// [`Transport::local`].
    fn local(&self) -> NodeId {
        self.inner().local()
    }
    /// [`Transport::send`].
    fn send(&mut self, out: Outgoing) -> Sent {
        self.inner_mut().send(out)
    }
    /// [`Transport::send_all`]: through this wrapper's `send`.
    fn send_all(&mut self, outbox: &mut VecDeque<Outgoing>, tally: &mut SendTally) {
        while let Some(out) = outbox.pop_front() {
            tally.add(TransportWrapper::send(self, out));
        }
    }
    /// [`Transport::recv`].
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        self.inner_mut().recv()
    }
    /// [`Transport::recv_all`]: through this wrapper's `recv`.
    fn recv_all(&mut self, deliver: &mut dyn FnMut(NodeId, &Message)) {
        while let Some((from, message)) = TransportWrapper::recv(self) {
            deliver(from, &message);
        }
    }
    /// [`Transport::wait`].
    fn wait(&mut self, timeout: std::time::Duration) {
        self.inner_mut().wait(timeout)
    }
    /// [`Transport::join`].
    fn join(&mut self, group: &str) {
        self.inner_mut().join(group)
    }
    /// [`Transport::leave`].
    fn leave(&mut self, group: &str) {
        self.inner_mut().leave(group)
    }
    /// [`Transport::flush`].
    fn flush(&mut self) {
        self.inner_mut().flush()
    }
    /// [`Transport::tick`].
    fn tick(&mut self, now: Instant) -> Option<Instant> {
        self.inner_mut().tick(now)
    }
    /// [`Transport::counters`].
    fn counters(&self) -> Vec<(String, u64)> {
        self.inner().counters()
    }
    /// [`Transport::set_real_time`].
    fn set_real_time(&mut self, real_time: bool) {
        self.inner_mut().set_real_time(real_time)
    }
    /// [`Transport::counters_into`]: this wrapper's `counters`.
    fn counters_into(&self, out: &mut Vec<(String, u64)>) {
        *out = TransportWrapper::counters(self);
    }
    /// [`Transport::counters_generation`].
    fn counters_generation(&self) -> u64 {
        self.inner().counters_generation()
    }
    /// [`Transport::peers`].
    fn peers(&self) -> Vec<PeerInfo> {
        self.inner().peers()
    }
    /// [`Transport::take_events`].
    fn take_events(&mut self, out: &mut Vec<TransportEvent>) {
        self.inner_mut().take_events(out)
    }
    /// [`Transport::address`].
    fn address(&self) -> Option<String> {
        self.inner().address()
    }
}

/// Every method of a wrapper is its [`TransportWrapper`] method: overridden there, or reaching
/// the inner transport.
impl<W: TransportWrapper> Transport for W {
    fn local(&self) -> NodeId {
        TransportWrapper::local(self)
    }
    fn send(&mut self, out: Outgoing) -> Sent {
        TransportWrapper::send(self, out)
    }
    fn send_all(&mut self, outbox: &mut VecDeque<Outgoing>, tally: &mut SendTally) {
        TransportWrapper::send_all(self, outbox, tally)
    }
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        TransportWrapper::recv(self)
    }
    fn recv_all(&mut self, deliver: &mut dyn FnMut(NodeId, &Message)) {
        TransportWrapper::recv_all(self, deliver)
    }
    fn wait(&mut self, timeout: std::time::Duration) {
        TransportWrapper::wait(self, timeout)
    }
    fn join(&mut self, group: &str) {
        TransportWrapper::join(self, group)
    }
    fn leave(&mut self, group: &str) {
        TransportWrapper::leave(self, group)
    }
    fn flush(&mut self) {
        TransportWrapper::flush(self)
    }
    fn tick(&mut self, now: Instant) -> Option<Instant> {
        TransportWrapper::tick(self, now)
    }
    fn counters(&self) -> Vec<(String, u64)> {
        TransportWrapper::counters(self)
    }
    fn set_real_time(&mut self, real_time: bool) {
        TransportWrapper::set_real_time(self, real_time)
    }
    fn counters_into(&self, out: &mut Vec<(String, u64)>) {
        TransportWrapper::counters_into(self, out)
    }
    fn counters_generation(&self) -> u64 {
        TransportWrapper::counters_generation(self)
    }
    fn peers(&self) -> Vec<PeerInfo> {
        TransportWrapper::peers(self)
    }
    fn take_events(&mut self, out: &mut Vec<TransportEvent>) {
        TransportWrapper::take_events(self, out)
    }
    fn address(&self) -> Option<String> {
        TransportWrapper::address(self)
    }
}

/// A boxed transport is a transport: commands that open whatever URL they are given
/// ([`open`], [`open_named`]) can still wrap the result (a recording tap, the simulator's
/// radio link) or hand it to `Node::new`. The box is the transport itself, not a wrapper that
/// changes it: every method forwards, the defaulted ones too, so the box changes nothing a
/// node can observe.
impl Transport for Box<dyn Transport> {
    fn local(&self) -> NodeId {
        (**self).local()
    }
    fn send(&mut self, out: Outgoing) -> Sent {
        (**self).send(out)
    }
    fn send_all(&mut self, outbox: &mut VecDeque<Outgoing>, tally: &mut SendTally) {
        (**self).send_all(outbox, tally)
    }
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        (**self).recv()
    }
    fn recv_all(&mut self, deliver: &mut dyn FnMut(NodeId, &Message)) {
        (**self).recv_all(deliver)
    }
    fn wait(&mut self, timeout: std::time::Duration) {
        (**self).wait(timeout)
    }
    fn join(&mut self, group: &str) {
        (**self).join(group)
    }
    fn leave(&mut self, group: &str) {
        (**self).leave(group)
    }
    fn flush(&mut self) {
        (**self).flush()
    }
    fn tick(&mut self, now: Instant) -> Option<Instant> {
        (**self).tick(now)
    }
    fn counters(&self) -> Vec<(String, u64)> {
        (**self).counters()
    }
    fn set_real_time(&mut self, real_time: bool) {
        (**self).set_real_time(real_time)
    }
    fn counters_into(&self, out: &mut Vec<(String, u64)>) {
        (**self).counters_into(out)
    }
    fn counters_generation(&self) -> u64 {
        (**self).counters_generation()
    }
    fn peers(&self) -> Vec<PeerInfo> {
        (**self).peers()
    }
    fn take_events(&mut self, out: &mut Vec<TransportEvent>) {
        (**self).take_events(out)
    }
    fn address(&self) -> Option<String> {
        (**self).address()
    }
}

/// What became of a message handed to [`Transport::send`].
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Sent {
    /// It left, or is in a datagram that leaves at the end of this loop turn.
    Now,
    /// Its destination node has not been heard from yet: held until that node greets, for a
    /// bounded time (`udp://`: three HELLO periods), then dropped and counted.
    Held,
    /// It cannot be delivered (no route, destination gone, unencodable); counted by cause in
    /// the transport's counters.
    Dropped,
}

/// How many of the messages handed to [`Transport::send_all`] became each [`Sent`].
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct SendTally {
    /// [`Sent::Now`].
    pub sent: u64,
    /// [`Sent::Held`].
    pub held: u64,
    /// [`Sent::Dropped`].
    pub dropped: u64,
}

impl SendTally {
    /// Count one message's fate.
    pub fn add(&mut self, sent: Sent) {
        match sent {
            Sent::Now => self.sent += 1,
            Sent::Held => self.held += 1,
            Sent::Dropped => self.dropped += 1,
        }
    }
}

/// A peer as a transport knows it.
#[derive(Clone, Debug, PartialEq)]
pub struct PeerInfo {
    /// The peer's node id.
    pub node: NodeId,
    /// Where it was last heard from (`IP:PORT` for `udp://`).
    pub addr: String,
    /// The name it announces (may be empty).
    pub name: String,
    /// The broadcast groups it announced in its HELLO.
    pub groups: Vec<String>,
    /// When it was last heard, on this node's clock.
    pub last_heard: Instant,
}

/// Opens a transport for a URL of a registered scheme, for node `id` (see [`register_scheme`]).
pub type SchemeFactory = fn(url: &str, id: NodeId) -> Result<Box<dyn Transport>, Error>;

/// Schemes added by other crates. A registry rather than a dependency: transports with heavy
/// dependencies (`zenoh://`, crates/ayllu-zenoh) live in their own projects and plug in here,
/// so the default build never compiles them.
static SCHEMES: std::sync::RwLock<Vec<(String, SchemeFactory)>> = std::sync::RwLock::new(Vec::new());

/// Make [`open`] (and so [`crate::Node::open`]) hand URLs of `scheme` (without `://`) to
/// `factory`. Registering a scheme again replaces its factory. Built-in schemes (`mem`,
/// `udp`) cannot be replaced: they are matched first.
pub fn register_scheme(scheme: &str, factory: SchemeFactory) {
    let mut schemes = SCHEMES.write().unwrap_or_else(|poisoned| poisoned.into_inner());
    schemes.retain(|(s, _)| s != scheme);
    schemes.push((scheme.to_owned(), factory));
}

/// Open the transport a URL names, for node `id`.
pub fn open(url: &str, id: NodeId) -> Result<Box<dyn Transport>, Error> {
    let (scheme, rest) = url.split_once("://").ok_or_else(|| Error::BadUrl {
        url: url.to_owned(),
        reason: "expected SCHEME://..., e.g. mem://team".into(),
    })?;
    if !matches!(scheme, "mem" | "udp") {
        let registered = SCHEMES
            .read()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .iter()
            .find(|(s, _)| s == scheme)
            .map(|(_, factory)| *factory);
        if let Some(factory) = registered {
            return factory(url, id);
        }
    }
    match scheme {
        "mem" => {
            if rest.is_empty() {
                return Err(Error::BadUrl { url: url.to_owned(), reason: "mem:// needs a network name".into() });
            }
            Ok(Box::new(MemNetwork::named(rest).attach(id)?))
        }
        "udp" => Ok(Box::new(UdpTransport::bind(id, UdpConfig::parse(url)?)?)),
        "zenoh" => Err(Error::Unsupported {
            what: "the zenoh:// transport is not in this build: use the `ayllu-zenoh` tool (`make zenoh`), or \
                   call ayllu_zenoh::register() in a Rust program (crates/ayllu-zenoh); see docs/zenoh.md"
                .into(),
        }),
        "sim" => Err(Error::Unsupported { what: format!("the {scheme}:// transport (not yet supported)") }),
        _ => Err(Error::BadUrl { url: url.to_owned(), reason: format!("unknown transport `{scheme}`") }),
    }
}

/// The value of setting `key` in a URL's query (`team` in `udp://0.0.0.0:0?team=7`), as
/// written (not decoded). The settings Ayllu reads (`team=`, `key=`, `name=`) mean the same in
/// every scheme that has them, so a tool can learn them without knowing the scheme.
pub fn url_setting<'a>(url: &'a str, key: &str) -> Option<&'a str> {
    let (_, query) = url.split_once('?')?;
    query.split('&').find_map(|part| part.strip_prefix(key)?.strip_prefix('='))
}

/// [`open`], with the node named `name` unless the URL names it (a `name=` that is not
/// empty): what the tools do
/// for every node they start (`node-3`, `body-2`, `ayllu-cli`), whatever the scheme. `mem://`
/// has no names and ignores it.
pub fn open_named(url: &str, id: NodeId, name: &str) -> Result<Box<dyn Transport>, Error> {
    let scheme = url.split_once("://").map_or("", |(scheme, _)| scheme);
    if scheme == "mem" || name.is_empty() || url_setting(url, "name").is_some_and(|n| !n.is_empty()) {
        return open(url, id);
    }
    if scheme == "udp" {
        // Parsed, not rewritten: the name needs no escaping this way.
        let mut config = UdpConfig::parse(url)?;
        config.name = name.to_owned();
        return Ok(Box::new(UdpTransport::bind(id, config)?));
    }
    let separator = if url.contains('?') { '&' } else { '?' };
    open(&format!("{url}{separator}name={name}"), id)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fake(url: &str, id: NodeId) -> Result<Box<dyn Transport>, Error> {
        // A registered scheme gets the whole URL: prove it by opening an in-process network
        // named after it.
        let name = url.split_once("://").map(|(_, rest)| rest).unwrap_or_default();
        Ok(Box::new(MemNetwork::named(&format!("registered-{name}")).attach(id)?))
    }

    #[test]
    fn a_registered_scheme_is_opened_by_its_factory() {
        assert!(matches!(open("registrytest://x", NodeId(1)), Err(Error::BadUrl { .. })));
        register_scheme("registrytest", fake);
        let t = open("registrytest://x", NodeId(1)).expect("registered scheme opens");
        assert_eq!(t.local(), NodeId(1));
        // Built-in schemes stay built in.
        register_scheme("mem", fake);
        assert!(matches!(open("mem://", NodeId(1)), Err(Error::BadUrl { .. })));
    }

    #[test]
    fn settings_are_read_from_any_scheme_and_names_added_once() {
        assert_eq!(url_setting("zenoh://?connect=tcp/h:1&team=7&key=ab", "team"), Some("7"));
        assert_eq!(url_setting("udp://0.0.0.0:0?teamx=1&team=3", "team"), Some("3"));
        assert_eq!(url_setting("udp://0.0.0.0:0", "team"), None);
        static SEEN: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
        fn seen(url: &str, id: NodeId) -> Result<Box<dyn Transport>, Error> {
            SEEN.lock().unwrap().push(url.to_owned());
            fake(url, id)
        }
        register_scheme("namedtest", seen);
        open_named("namedtest://x", NodeId(1), "robot-1").expect("opens");
        open_named("namedtest://x?team=2", NodeId(1), "robot-1").expect("opens");
        open_named("namedtest://x?name=mine", NodeId(1), "robot-1").expect("opens");
        assert_eq!(
            *SEEN.lock().unwrap(),
            ["namedtest://x?name=robot-1", "namedtest://x?team=2&name=robot-1", "namedtest://x?name=mine"]
        );
        let t = open_named("udp://127.0.0.1:0", NodeId(1), "robot-1").expect("udp opens");
        assert_eq!(t.local(), NodeId(1));
    }

    #[test]
    fn zenoh_without_the_crate_says_where_it_is() {
        match open("zenoh://?team=1", NodeId(1)) {
            Err(Error::Unsupported { what }) => assert!(what.contains("ayllu-zenoh"), "{what}"),
            Err(other) => panic!("unexpected error: {other}"),
            Ok(_) => panic!("zenoh:// opened without the crate"),
        }
    }
}
