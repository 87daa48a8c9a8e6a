//! [`Node`]: the core driven by a clock and a transport — what a robot program runs.
//!
//! A node owns one [`NodeCore`], one [`Clock`] and one [`Transport`]. Each [`Node::step`]
//! reads the clock once, applies every message that has arrived, runs what is due, and hands
//! what the core wants sent to the transport. [`Node::run_for`] repeats that, sleeping on the
//! transport until the next deadline. With a [`crate::ManualClock`] nothing sleeps and a test
//! decides time (see [`crate::Lockstep`]).
//!
//! Thread-safety: a `Node` is `Send` and is driven by one thread at a time.

use ayllu_core::{
    BehaviorClass, BehaviorRef, BleConfig, BleGroup, ConnectOptions, ConnectionId, ConnectionKind, Endpoint, Instant,
    NodeCore, NodeId, PortReport, Value,
};

use crate::clock::{Clock, MonotonicClock};
use crate::driver::Driver;
use crate::error::Error;
use crate::transport::{self, SendTally, Transport, TransportEvent};

/// Traffic figures of one node.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// Loop turns ([`Node::step`] calls).
    pub steps: u64,
    /// Messages that left (handed to the network; best effort from there, N1).
    pub sent: u64,
    /// Messages held for a node not heard from yet ([`crate::Sent::Held`]): they leave when it
    /// greets, or are dropped after a bounded time (see the transport's counters).
    pub held: u64,
    /// Messages that could not be sent (no route, destination gone, unencodable).
    pub dropped: u64,
    /// Messages received and applied to the core.
    pub received: u64,
}

/// A running Ayllu node. See the module docs.
///
/// Two nodes in one program over `mem://`, on a clock the program moves: node 1 writes
/// node 2's port across the transport.
///
/// ```
/// use ayllu::*;
/// let clock = ManualClock::new();
/// let net = MemNetwork::new();
/// let mut nodes = Vec::new();
/// for id in [1, 2] {
///     let mut node = Node::new(clock.clone(), net.attach(NodeId(id))?);
///     let mut relay = BehaviorClass::new("Relay");
///     relay.port(PortSpec::new("Out", 0i64))?;
///     relay.port(PortSpec::new("In", 0i64))?;
///     node.define(relay)?;
///     node.create("Relay", "R")?;
///     nodes.push(node);
/// }
/// nodes[0].connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(2), "R", "In"),
///                  ConnectionKind::Normal)?;
/// nodes[0].write("R", "Out", 42i64)?;
/// nodes[0].step(); // sends
/// clock.advance(Duration::from_millis(1));
/// nodes[1].step(); // receives
/// assert_eq!(nodes[1].read("R", "In")?, Value::Int(42));
/// # Ok::<(), RuntimeError>(())
/// ```
pub struct Node {
    core: NodeCore,
    clock: Box<dyn Clock>,
    transport: Box<dyn Transport>,
    stats: NodeStats,
    /// The groups the transport has joined, and the core's generation they reflect.
    joined: Vec<String>,
    joined_generation: u64,
    counters_generation: u64,
    transport_due: Option<Instant>,
    /// Scratch list of the transport's events (reused).
    events: Vec<TransportEvent>,
    /// The flight recorder, drained every turn (see [`Node::record`]).
    recorder: Option<crate::recording::Recorder>,
    /// The drivers of the node's bodies (see [`Node::attach`]), in the order attached.
    drivers: Vec<Box<dyn Driver>>,
}

impl Node {
    /// A node with an explicit clock and transport.
    pub fn new(clock: impl Clock + 'static, transport: impl Transport + 'static) -> Node {
        let id = transport.local();
        Node::assemble(NodeCore::new(id), Box::new(clock), Box::new(transport))
    }

    /// A node on the real monotonic clock, on the transport `url` names (`mem://team`).
    pub fn open(id: NodeId, url: &str) -> Result<Node, Error> {
        Node::open_with_clock(id, url, MonotonicClock::new())
    }

    /// A node on the transport `url` names, with the given clock.
    pub fn open_with_clock(id: NodeId, url: &str, clock: impl Clock + 'static) -> Result<Node, Error> {
        let transport = transport::open(url, id)?;
        Ok(Node::assemble(NodeCore::new(id), Box::new(clock), transport))
    }

    fn assemble(mut core: NodeCore, clock: Box<dyn Clock>, mut transport: Box<dyn Transport>) -> Node {
        transport.set_real_time(clock.is_real_time());
        if clock.is_real_time() {
            // A restarted process may reuse its node id: number its messages and requests above
            // anything its previous life sent (like datagrams).
            core.set_sequence_base(crate::clock::boot_sequence_base());
        }
        Node {
            core,
            clock,
            transport,
            stats: NodeStats::default(),
            joined: Vec::new(),
            joined_generation: 0,
            counters_generation: 0,
            transport_due: None,
            events: Vec::new(),
            recorder: None,
            drivers: Vec::new(),
        }
    }

    /// Make the transport's group memberships match the core's (groups may be joined through
    /// `core_mut()`, e.g. by `ble_join`).
    fn sync_groups(&mut self) {
        if self.core.groups_generation() == self.joined_generation {
            return;
        }
        self.joined_generation = self.core.groups_generation();
        let wanted: Vec<String> = self.core.groups().iter().map(|g| g.to_string()).collect();
        for g in self.joined.iter().filter(|g| !wanted.contains(g)) {
            self.transport.leave(g);
        }
        for g in wanted.iter().filter(|g| !self.joined.contains(g)) {
            self.transport.join(g);
        }
        self.joined = wanted;
    }

    /// This node's id.
    pub fn id(&self) -> NodeId {
        self.core.id()
    }
    /// The node's clock now.
    pub fn now(&self) -> Instant {
        self.clock.now()
    }
    /// Whether the node's clock is real time (a [`ManualClock`](crate::ManualClock) is not:
    /// time moves only when its owner moves it).
    pub fn is_real_time(&self) -> bool {
        self.clock.is_real_time()
    }
    /// The sans-IO core, for reading everything this wrapper does not forward (reports, BLE
    /// status, warnings).
    pub fn core(&self) -> &NodeCore {
        &self.core
    }
    /// The core, for everything this wrapper does not forward, told the clock's present
    /// first ([`NodeCore::advance_to`]): a change made through it between steps is dated now,
    /// not at the last step (a node wired before it starts, or added to a running team, would
    /// otherwise date its behaviors' creation and its BLE joins in the past). Changes take
    /// effect (and messages leave) at the next step. `core_mut().now()` is then the present.
    pub fn core_mut(&mut self) -> &mut NodeCore {
        let now = self.clock.now();
        self.core.advance_to(now);
        &mut self.core
    }
    /// Traffic figures since the node started.
    pub fn stats(&self) -> NodeStats {
        self.stats
    }
    /// The transport's counters (traffic and drops by cause, N4).
    pub fn transport_counters(&self) -> Vec<(String, u64)> {
        self.transport.counters()
    }
    /// The peers the transport knows of.
    pub fn peers(&self) -> Vec<crate::transport::PeerInfo> {
        self.transport.peers()
    }
    /// Where peers reach this node (see [`Transport::address`]): after binding `udp://...:0`,
    /// the port the system chose.
    pub fn address(&self) -> Option<String> {
        self.transport.address()
    }

    /// Record everything that enters this node's core, and the values its ports accept, into
    /// the MCAP file `path` (and numbered segments after it), for Foxglove and `ayllu replay`
    /// (spec/flight-recorder.md). Call it before defining anything: a replay rebuilds the node
    /// from its first definition. Recording does not change what the node does; the file is
    /// written by a thread of its own, and closed by [`Node::stop_recording`] or on drop.
    pub fn record(&mut self, path: impl AsRef<std::path::Path>, options: crate::RecordOptions) -> Result<(), Error> {
        if self.recorder.is_some() {
            return Err(Error::Recording { what: "this node is already recording".into() });
        }
        self.recorder = Some(crate::recording::Recorder::start(&mut self.core, path.as_ref(), options)?);
        Ok(())
    }
    /// Stop recording and close the files; `None` if the node was not recording.
    pub fn stop_recording(&mut self) -> Option<crate::RecordStats> {
        let recorder = self.recorder.take()?;
        Some(recorder.finish(&mut self.core))
    }
    /// What the recorder has written and dropped so far; `None` if the node is not recording.
    pub fn recording_stats(&self) -> Option<crate::RecordStats> {
        self.recorder.as_ref().map(|r| r.stats())
    }

    /// Let `driver` write and read this node's body every turn (see [`crate::driver`]): from
    /// the next [`Node::step`] on, it takes in what arrived from outside before the core runs
    /// and sends out what the ports hold after.
    pub fn attach(&mut self, driver: impl Driver + 'static) {
        self.drivers.push(Box::new(driver));
    }

    /// Define a behavior class on this node (rule S2).
    pub fn define(&mut self, class: BehaviorClass) -> Result<(), Error> {
        Ok(self.core_mut().define(class)?)
    }
    /// Create behavior `name` of class `class` (rule S9: also while running).
    pub fn create(&mut self, class: &str, name: &str) -> Result<BehaviorRef, Error> {
        Ok(self.core_mut().create(class, name)?)
    }
    /// Remove behavior `name` and every connection into or out of it (rule S9).
    pub fn remove(&mut self, name: &str) -> Result<(), Error> {
        Ok(self.core_mut().remove(name)?)
    }
    /// Connect with the default options (priority 0); see [`Node::connect_with`].
    pub fn connect(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
    ) -> Result<ConnectionId, Error> {
        self.connect_with(source, destination, kind, ConnectOptions::default())
    }
    /// Connect `source` (a port of this node) to `destination` with `options` (the
    /// connection's priority, for Priority ports, D3.3).
    pub fn connect_with(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
        options: ConnectOptions,
    ) -> Result<ConnectionId, Error> {
        Ok(self.core_mut().connect(source, destination, kind, options)?)
    }
    /// Remove a connection this node owns; windows it holds here end at once (D6.9).
    pub fn disconnect(&mut self, id: ConnectionId) -> Result<(), Error> {
        Ok(self.core_mut().disconnect(id)?)
    }
    /// Join a broadcast group, on the core and on the transport.
    pub fn join(&mut self, group: &str) {
        self.core_mut().join(group);
        self.sync_groups();
    }
    /// Leave a broadcast group, on the core and on the transport.
    pub fn leave(&mut self, group: &str) {
        self.core_mut().leave(group);
        self.sync_groups();
    }
    /// Make `behavior` a BLE peer (rule S11) and join the group on the transport.
    pub fn ble_join(&mut self, behavior: &str, config: &BleConfig) -> Result<BleGroup, Error> {
        let g = self.core_mut().ble_join(behavior, config)?;
        self.sync_groups();
        Ok(g)
    }
    /// Write a port as its behavior would, now.
    pub fn write(&mut self, behavior: &str, port: &str, value: impl Into<Value>) -> Result<(), Error> {
        let now = self.clock.now();
        Ok(self.core.write_named(now, behavior, port, value)?)
    }
    /// The port's value now (its default while an aggregating port is empty). Reads answer
    /// at the clock's present, not at the last step's: a window or lifespan that ended since
    /// counts as ended (D8.2).
    pub fn read(&self, behavior: &str, port: &str) -> Result<Value, Error> {
        Ok(self.core.read_at(self.clock.now(), self.core.port(behavior, port)?)?)
    }
    /// The port's value if it is fresh now (rule S4), else `None`.
    pub fn get(&self, behavior: &str, port: &str) -> Result<Option<Value>, Error> {
        Ok(self.core.get_at(self.clock.now(), self.core.port(behavior, port)?)?)
    }
    /// Whether the port holds a value that is not stale now (rule S4).
    pub fn fresh(&self, behavior: &str, port: &str) -> Result<bool, Error> {
        Ok(self.core.fresh_at(self.clock.now(), self.core.port(behavior, port)?)?)
    }
    /// Whether monostable `mono` of `behavior` is high now (rule S2).
    pub fn monostable(&self, behavior: &str, mono: &str) -> Result<bool, Error> {
        Ok(self.core.monostable_at(self.clock.now(), behavior, mono)?)
    }
    /// Why the port holds what it holds and passes what it passes, now.
    pub fn why(&self, behavior: &str, port: &str) -> Result<PortReport, Error> {
        Ok(self.core.why_at(self.clock.now(), behavior, port)?)
    }

    /// One turn: send what the program wrote since the last turn, receive everything waiting,
    /// run what is due, send what is produced. Returns when the core next has work.
    pub fn step(&mut self) -> Option<Instant> {
        self.sync_groups();
        // Messages from writes made between turns leave before this turn receives and runs
        // processes: sending them does not depend on either, and a request then reaches its
        // peer a receive call and a scheduler pass sooner.
        if self.core.outgoing_len() > 0 {
            self.send_outgoing();
        }
        let now = self.clock.now();
        self.transport_due = self.transport.tick(now);
        let (core, received) = (&mut self.core, &mut self.stats.received);
        self.transport.recv_all(&mut |from, message| {
            *received += 1;
            core.receive_shared(now, from, message);
        });
        // After receiving, so that a dead node's last message still queued cannot take back
        // what its departure released.
        self.take_transport_events(now);
        for d in &mut self.drivers {
            d.input(&mut self.core, now);
        }
        let mut next = self.core.poll(now);
        for d in &mut self.drivers {
            if let Some(due) = d.output(&mut self.core, now) {
                next = Some(next.map_or(due, |n| n.min(due)));
            }
        }
        self.send_outgoing();
        if self.transport.counters_generation() != self.counters_generation {
            self.counters_generation = self.transport.counters_generation();
            self.transport.counters_into(self.core.transport_counters_mut());
        }
        self.stats.steps += 1;
        if let Some(recorder) = self.recorder.as_mut() {
            recorder.drain(&mut self.core);
        }
        match (next, self.transport_due) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Hand the transport everything the core wants sent, and end the batch (N3).
    fn send_outgoing(&mut self) {
        // Most turns of a node that waits send nothing: no call into the transport then.
        if self.core.outgoing_len() > 0 {
            let mut tally = SendTally::default();
            self.transport.send_all(self.core.outgoing_mut(), &mut tally);
            self.stats.sent += tally.sent;
            self.stats.held += tally.held;
            self.stats.dropped += tally.dropped;
            if tally.dropped > 0 {
                // A request the transport cannot send fails now, not after its retries.
                self.take_transport_events(self.clock.now());
            }
        }
        self.transport.flush();
    }

    /// Act on what the transport has to tell, in its order.
    fn take_transport_events(&mut self, now: Instant) {
        self.transport.take_events(&mut self.events);
        for event in self.events.drain(..) {
            match event {
                // Peers the transport gave up on: what they held on our ports is released
                // (D3.7).
                TransportEvent::PeerLost(node) => {
                    self.core.node_lost(now, node);
                }
                TransportEvent::Warning(w) => self.core.warn(w),
                TransportEvent::RequestFailed { to, id, why } => self.core.fail_request(to, id, why),
            }
        }
    }

    /// Sleep on the transport until a message may have arrived or `timeout` passes. For
    /// programs that drive [`Node::step`] from their own loop (and must not busy-wait between
    /// steps) instead of handing it to [`Node::run_for`].
    pub fn wait(&mut self, timeout: std::time::Duration) {
        self.transport.wait(timeout);
    }

    /// Run in real time for `duration`, sleeping on the transport between deadlines.
    /// With a manual clock, steps once (time is not this node's to move).
    pub fn run_for(&mut self, duration: std::time::Duration) {
        if !self.clock.is_real_time() {
            self.step();
            return;
        }
        let end = self.clock.now() + ayllu_core::Duration::from_nanos(duration.as_nanos().min(u64::MAX as u128) as u64);
        loop {
            let next = self.step();
            let now = self.clock.now();
            if now >= end {
                break;
            }
            let until = next.map_or(end, |n| n.min(end));
            if until > now {
                self.transport.wait(std::time::Duration::from_nanos((until - now).as_nanos()));
            }
        }
    }
}

impl Drop for Node {
    /// A recording ends with the node: what it journaled last is written and the files closed.
    fn drop(&mut self) {
        self.stop_recording();
    }
}
