//! [`NodeCore`]: one node's behaviors, connections and scheduler, as a sans-IO state machine.
//!
//! What it promises:
//! * It never reads a clock, opens a socket or spawns: time comes in through `poll(now)`,
//!   `write(now, ..)` and `receive(now, ..)`; messages for other nodes leave through
//!   [`NodeCore::pop_outgoing`]. Same inputs, same outputs (determinism).
//! * Propagation (rule S5) is synchronous and depth-first inside one call; every port is
//!   written at most once per wave, so wiring cycles terminate. The explicit stack and the
//!   trigger queue are reused, so propagating a scalar allocates nothing.
//! * Processes (rule S7) run only inside `poll`, one at a time, each to completion.
//! * Nothing that arrives from outside can make it panic; what cannot be applied is dropped
//!   and counted by cause.
//!
//! The node is one struct, [`NodeCore`], with its code split by concern over the files
//! of this module, each an `impl NodeCore` block with its own module docs saying which rules
//! it keeps:
//! * `tables`: the per-port, per-process, per-behavior and per-connection state, laid out on
//!   cache lines for the paths every message takes;
//! * `structure`: classes, behaviors and processes made and removed at run time (S9), and
//!   the handles that name them;
//! * `connections`: connections (S6, S10), lost nodes, access, limits, groups, and the
//!   control requests this node sends (N2);
//! * `propagation`: writes and the waves that carry them (S3–S6);
//! * `receive`: messages from other nodes (S8, S10; N1, N2, N4), and the outbox;
//! * `scheduler`: `poll` and the process runs it makes (S7, S8);
//! * `registers`: ports, monostables and slots read and set from outside the processes.
//!
//! This file holds the node's state (one struct, so that its cache-line layout is in one
//! place), the handles users hold, and the node's own counters and warnings.

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;

use crate::access::{Access, Limits};
use crate::address::NodeId;
use crate::behavior::{BehaviorClass, Port};
use crate::counters::{Counters, DropCause};
use crate::journal::{Event, Journal};
use crate::message::{Outgoing, ReplyBody};
use crate::schedule::Schedule;
use crate::sequence::SeqTable;
use crate::time::{Duration, Instant};

mod connections;
mod names;
mod propagation;
mod receive;
mod registers;
mod scheduler;
#[cfg(feature = "serde")]
pub(crate) mod snapshot;
mod structure;
mod tables;

pub(crate) use connections::connect_request;
use connections::Request;
use propagation::Frame;
pub(crate) use registers::current;
#[cfg(feature = "serde")]
pub use snapshot::{Snapshot, SNAPSHOT_VERSION};
pub(crate) use tables::{Behavior, Conn, Edge, MonoState, PortState, ProcState, Target};

/// Whether a process body is running, for `run_body`'s borrowed body: a behavior removed
/// while one runs is parked, not dropped, since the body running may be one of its processes'.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Running {
    Idle,
    Body,
    /// A body runs and `NodeCore::parked` holds behaviors removed meanwhile.
    Parked,
}

/// A handle to a port of a live behavior, cheap to copy. It goes stale (and is reported as
/// unknown) when its behavior is removed, even if another one later takes the same name.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub struct PortRef {
    pub(crate) b: u32,
    pub(crate) id: u64,
    pub(crate) port: Port,
}

impl PortRef {
    /// The port's handle within its behavior, as the class's processes know it.
    pub fn port(&self) -> Port {
        self.port
    }
}

/// A handle to a live behavior.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub struct BehaviorRef {
    pub(crate) b: u32,
    pub(crate) id: u64,
}

/// Id of a control request this node sent.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct RequestId(pub u64);

/// Where a control request stands.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum RequestStatus {
    /// Not answered yet; resent every 200 ms until answered or 25 sends (N2).
    Pending {
        /// Times sent so far.
        sends: u32,
    },
    /// Answered: what the request returned.
    Done(ReplyBody),
    /// The receiver refused it (its error text, e.g. the rule that refused it), or no answer
    /// came after 25 sends.
    Failed(String),
}

/// A triggered process that is triggered again in the poll in which it already ran (it
/// triggers itself, directly or through a cycle of processes) runs again no sooner than this:
/// such a loop runs at most 1000 times a second instead of spinning a core (D7.3).
pub const RETRIGGER_INTERVAL: Duration = Duration::from_millis(1);

/// Senders whose request rate is tracked, at most (see `Limits::requests_per_second`).
pub const RATE_BUCKETS: usize = 1_024;

/// Warnings kept in a node's report, at most (see [`NodeCore::warn`]).
pub const MAX_WARNINGS: usize = 64;

/// One node's behaviors, connections and scheduler. See the module docs.
///
/// The runtime (`ayllu::Node`) wraps it with a clock and a transport; tests and simulators
/// drive it directly, passing time in (nanoseconds on the node's clock, rule S8):
///
/// ```
/// use ayllu_core::*;
///
/// let mut node = NodeCore::new(NodeId(1));
/// let mut sonar = BehaviorClass::new("Sonar");
/// sonar.port(PortSpec::new("Range", 0.0))?; // metres
/// let mut motor = BehaviorClass::new("Motor");
/// // A command older than 300 ms is stale: the motor must not act on it (S4).
/// let speed = motor.port(PortSpec::new("Speed", 0.0).lifespan(Duration::from_millis(300)))?;
/// let commands = motor.port(PortSpec::new("Commands", 0i64))?;
/// motor.on_write("Count", speed, move |ctx| {
///     let n = ctx.int(commands).unwrap_or(0);
///     ctx.write(commands, n + 1).unwrap();
/// })?;
/// node.define(sonar)?;
/// node.define(motor)?;
/// node.create("Sonar", "S")?;
/// node.create("Motor", "M")?;
/// node.connect(
///     &Endpoint::local("S", "Range"),
///     &Endpoint::local("M", "Speed"),
///     ConnectionKind::Normal,
///     ConnectOptions::default(),
/// )?;
///
/// let (range, speed) = (node.port("S", "Range")?, node.port("M", "Speed")?);
/// node.write(Instant::from_millis(100), range, 1.5)?;
/// assert_eq!(node.read(speed)?, Value::Float(1.5)); // propagated within the write (S5)
/// node.poll(Instant::from_millis(100)); // processes run only here (S7)
/// assert_eq!(node.read(node.port("M", "Commands")?)?, Value::Int(1));
/// assert_eq!(node.get_at(Instant::from_millis(399), speed)?, Some(Value::Float(1.5)));
/// assert_eq!(node.get_at(Instant::from_millis(400), speed)?, None); // stale
/// // Values are never coerced (S1).
/// let err = node.write(Instant::from_millis(500), range, 2i64).unwrap_err();
/// assert!(matches!(err, Error::TypeMismatch { .. }));
/// # Ok::<(), Error>(())
/// ```
// In declaration order (`repr(C)`) on whole cache lines (`align(64)`): what every visit of a
// robot touches (a message received, a poll, the outbox) in the first five lines, up to
// whether a transaction is held (`txns`' first word); the propagation stack, used only by a
// write that hops, and what only structure operations, control requests and reports touch
// after them. A simulator steps hundreds of nodes, each cold by the time its turn comes
// back: the compiler's order spread the fields a message reads over eight lines of the
// node's eighteen, and the stack and an inline `Option<Held>` in the hot lines made seven.
#[repr(C, align(64))]
pub struct NodeCore {
    pub(crate) now: Instant,
    pub(crate) wave: u64,
    /// The flight recorder's tap (crate::journal); `None`, and then free, unless started.
    pub(crate) journal: Option<Box<Journal>>,
    /// Tests only: every write and hop takes the general path, to compare the plain one with.
    #[cfg(test)]
    pub(crate) general_only: bool,
    pub(crate) behaviors: Vec<Option<Behavior>>,
    pub(crate) id: NodeId,
    /// Behaviors removed, wrapping at 16 bits: the epoch of `newest_seq`'s resolved ports
    /// ([`Incoming::epoch`](crate::sequence::Incoming::epoch)).
    removals: u16,
    /// Whether a process of this node ever kept change outcomes (R2): until then a run need
    /// not read its process's outcomes to know there are none to clear.
    outcomes_kept: bool,
    /// Whether a process body is running (`run_body`), and whether a behavior removed
    /// meanwhile waits in `parked` (see `Running`).
    running: Running,
    /// Keyed by `incoming_key(sender, connection)`; looked up for every message received.
    newest_seq: SeqTable,
    access: Access,
    pending: VecDeque<(u32, u64, u16)>,
    poll_epoch: u64,
    /// When the processes in `deferred` may run (`Instant::MAX` while there are none).
    deferred_due: Instant,
    deferred: Vec<(u32, u64, u16)>,
    /// The periodic processes and the next monostable edge, so that a poll need not walk
    /// every process (crate::schedule).
    schedule: Schedule,
    outbox: VecDeque<Outgoing>,
    requests: Vec<Request>,
    /// This node's part in transactions (crate::transaction); whether a part is held is its
    /// first word, the last every visit reads.
    pub(crate) txns: crate::transaction::Transactions,
    /// Used by a write that propagates (a hop), not by every visit.
    stack: Vec<Frame>,
    pub(crate) counters: Counters,
    limits: Limits,
    /// Behaviors removed while a process body ran, kept until it returns (see `Running`).
    parked: Vec<Behavior>,
    classes: HashMap<String, Arc<BehaviorClass>>,
    free_behaviors: Vec<u32>,
    /// Behavior slots by name (short names kept in the key: `names`).
    names: HashMap<names::NameKey, u32>,
    next_behavior_id: u64,
    pub(crate) conns: Vec<Option<Conn>>,
    free_conns: Vec<u32>,
    conn_ids: HashMap<u64, u32>,
    next_conn_id: u64,
    groups: Vec<Arc<str>>,
    groups_generation: u64,
    seq_table_resets: u64,
    /// How many of `requests` are finished (see `FINISHED_REQUESTS_KEPT`).
    finished_requests: usize,
    next_request: u64,
    /// Where new connections start numbering their messages (see `set_sequence_base`).
    seq_base: u64,
    answered: HashMap<(NodeId, u64), Result<ReplyBody, String>>,
    answered_order: VecDeque<(NodeId, u64)>,
    /// Estimated bytes of `answered`.
    answered_bytes: usize,
    /// Estimated bytes of the answers put in `outbox` since it was last found empty.
    answers_waiting: usize,
    pub(crate) warnings: Vec<String>,
    pub(crate) transport_counters: Vec<(String, u64)>,
    /// The body drivers' counters by cause (samples taken, dropped), for reports.
    pub(crate) body_counters: Vec<(String, u64)>,
    /// Control-request token buckets by sender: tokens left and when last refilled.
    request_buckets: HashMap<NodeId, (f64, Instant)>,
}

// Whether a transaction is held, the last field every visit reads, ends within the first
// five lines (test builds carry `general_only` in front, one word more).
#[cfg(not(test))]
const _: () = assert!(std::mem::offset_of!(NodeCore, txns) + std::mem::size_of::<usize>() <= 5 * 64);

impl NodeCore {
    /// An empty node at time zero: no classes, behaviors, connections or groups; open access
    /// and default [`Limits`]. `id` must be unique in the team: it names the node's sources,
    /// and lower ids win BLE and Max/Min ties (D3.4).
    pub fn new(id: NodeId) -> NodeCore {
        NodeCore {
            id,
            now: Instant::ZERO,
            classes: HashMap::new(),
            behaviors: Vec::new(),
            free_behaviors: Vec::new(),
            names: HashMap::new(),
            next_behavior_id: 1,
            conns: Vec::new(),
            free_conns: Vec::new(),
            conn_ids: HashMap::new(),
            next_conn_id: 1,
            groups: Vec::new(),
            groups_generation: 0,
            wave: 0,
            stack: Vec::with_capacity(64),
            pending: VecDeque::with_capacity(64),
            schedule: Schedule::default(),
            outcomes_kept: false,
            running: Running::Idle,
            parked: Vec::new(),
            deferred: Vec::new(),
            deferred_due: Instant::MAX,
            poll_epoch: 0,
            outbox: VecDeque::new(),
            counters: Counters::default(),
            newest_seq: SeqTable::new(),
            removals: 0,
            seq_table_resets: 0,
            requests: Vec::new(),
            finished_requests: 0,
            next_request: 1,
            seq_base: 0,
            answered: HashMap::new(),
            answered_order: VecDeque::new(),
            answered_bytes: 0,
            answers_waiting: 0,
            warnings: Vec::new(),
            transport_counters: Vec::new(),
            body_counters: Vec::new(),
            access: Access::default(),
            limits: Limits::default(),
            request_buckets: HashMap::new(),
            journal: None,
            #[cfg(test)]
            general_only: false,
            txns: crate::transaction::Transactions::default(),
        }
    }

    /// This node's id.
    pub fn id(&self) -> NodeId {
        self.id
    }

    /// Number this node's control requests and the messages of connections made from now on
    /// above `base`. A node that restarts under the same id passes its boot time (as the
    /// wire's datagram numbers do), so that peers do not drop its fresh messages as older than
    /// its previous life's (N1: `stale`) nor answer its new requests from memory (N2).
    pub fn set_sequence_base(&mut self, base: u64) {
        self.journal(|| Event::SequenceBase(base));
        self.seq_base = self.seq_base.max(base);
        self.next_request = self.next_request.max(base.saturating_add(1));
    }

    /// Where this node's requests and new connections number from (see
    /// [`NodeCore::set_sequence_base`]).
    pub fn sequence_base(&self) -> u64 {
        self.seq_base
    }

    /// Whether nothing has been declared here yet: no class, behavior, connection or group
    /// (a flight recording must start then, to be replayable from its beginning).
    pub fn is_pristine(&self) -> bool {
        self.classes.is_empty() && self.names.is_empty() && self.conn_ids.is_empty() && self.groups.is_empty()
    }

    /// The latest time this node has been told. Time never goes backwards: an earlier `now`
    /// passed in later is treated as this one.
    pub fn now(&self) -> Instant {
        self.now
    }

    fn advance(&mut self, now: Instant) {
        if now > self.now {
            self.now = now;
        }
    }

    /// Tell the core the time without running anything. What is called next (a behavior
    /// created, a BLE join, a connection removed) is dated `now` rather than the last poll's
    /// time, so a node that has not been polled for a while (wired before it starts, or added
    /// to a running team) does not date a change in its past: a periodic process keeps the
    /// phase of its creation (D7.2), a new BLE member listens a whole cycle from its join
    /// (D11.3). Processes due by then run at the next poll, as they would have. A runtime
    /// calls it before every change made between polls (`ayllu::Node::core_mut` does).
    /// Time never goes backwards: an earlier `now` changes nothing.
    pub fn advance_to(&mut self, now: Instant) {
        self.advance(now);
    }

    // ----- counters and warnings (N4) ------------------------------------------------------

    /// Node-wide counters of dropped and blocked messages, by cause.
    ///
    /// [`DropCause::Absorbed`] is the sum of the live ports' own counts and of those of the
    /// ports removed with their behaviors: a message that a port absorbs (most of what a Max
    /// port of eligibilities is offered) is counted on the port only, in the line its wave mark
    /// is in, not also in the node's far-off counters.
    pub fn counters(&self) -> Counters {
        let mut c = self.counters.clone();
        let live =
            self.behaviors.iter().flatten().flat_map(|b| &b.ports).fold(0u64, |a, p| a.saturating_add(p.absorbed));
        c.add_n(DropCause::Absorbed, live);
        c
    }

    /// How often the sequence table (N1) was full and had to be cleared.
    pub fn seq_table_resets(&self) -> u64 {
        self.seq_table_resets
    }

    /// Record the runtime transport's counters so that reports (also remote ones: LIST) show
    /// what was dropped before reaching the core (N4).
    pub fn set_transport_counters(&mut self, counters: Vec<(String, u64)>) {
        self.transport_counters = counters;
    }

    /// The transport counters reports show, for a runtime that refreshes them in place after
    /// every loop turn (no allocation when only the numbers changed).
    pub fn transport_counters_mut(&mut self) -> &mut Vec<(String, u64)> {
        &mut self.transport_counters
    }

    /// The counters a body's driver keeps (`ayllu::Driver`: a ROS 2 body's samples taken and
    /// dropped by cause), shown in reports (also remote ones: LIST) beside the transport's.
    /// The driver updates them in place.
    pub fn body_counters_mut(&mut self) -> &mut Vec<(String, u64)> {
        &mut self.body_counters
    }

    /// The body drivers' counters (see [`NodeCore::body_counters_mut`]).
    pub fn body_counters(&self) -> &[(String, u64)] {
        &self.body_counters
    }

    /// Add a warning to the node's report (the runtime reports the network's here, e.g. a
    /// second node using this node's id). At most [`MAX_WARNINGS`] are kept; later ones are
    /// dropped so a flood cannot grow memory.
    pub fn warn(&mut self, warning: String) {
        if self.journal.is_some() {
            let recorded = warning.clone();
            self.journal(|| Event::Warn(recorded));
        }
        if self.warnings.len() < MAX_WARNINGS {
            self.warnings.push(warning);
        }
    }

    /// Warnings the node has raised (e.g. a BLE inhibition too short for its claim rate).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Run `f` with the journal set aside: what it does is the consequence of a call already
    /// journaled, which a replay repeats (crate::journal).
    pub(crate) fn unjournaled<T>(&mut self, f: impl FnOnce(&mut NodeCore) -> T) -> T {
        let journal = self.journal.take();
        let out = f(self);
        self.journal = journal;
        out
    }
}
