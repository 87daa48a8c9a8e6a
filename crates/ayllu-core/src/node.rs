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

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::Ordering::Relaxed;
use std::sync::Arc;

use crate::access::{Access, Limits};
use crate::address::{ConnectionId, Endpoint, NodeId, Source};
use crate::arbitration::{Origin, WindowKind, Windows};
use crate::behavior::{validate_process, BehaviorClass, Mono, Port, ProcessSpec, Slot, Trigger};
use crate::ble::BleState;
use crate::change::{Change, ChangeOutcome};
use crate::connection::{ConnectOptions, ConnectionInfo, ConnectionKind};
use crate::counters::{Counters, DropCause};
use crate::error::Error;
use crate::journal::{Event, Journal};
use crate::message::{ControlBody, ControlMessage, Destination, Message, Outgoing, PortMessage, ReplyBody};
use crate::port::PortCell;
use crate::process::Ctx;
use crate::schedule::{Periodic, Schedule};
use crate::sequence::{incoming_key, Incoming, IncomingKey, SeqEntry, SeqTable};
use crate::time::{Duration, Instant};
use crate::value::Value;

/// Whether a process body is running, for `run_body`'s borrowed body: a behavior removed
/// while one runs is parked, not dropped, since the body running may be one of its processes'.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Running {
    Idle,
    Body,
    /// A body runs and `NodeCore::parked` holds behaviors removed meanwhile.
    Parked,
}

/// How many (sender, connection) sequence numbers a node remembers (N1). Bounded so a peer
/// inventing connection ids cannot grow memory; when full the table is cleared and counted.
const SEQ_TABLE_MAX: usize = 16_384;
/// How many answered control requests are remembered for idempotent replies (N2).
const ANSWERED_MAX: usize = 1_024;
/// And how many bytes they may take together (estimated, [`answer_bytes`]): a thousand LIST
/// answers of a large node held 262 MB for good; the oldest answers go first.
const ANSWERED_BYTES: usize = 2 << 20;
/// How many bytes of answers may wait in the outbox (estimated, [`answer_bytes`]) before
/// further control requests are dropped unanswered until it is sent (D9.3). A turn receives
/// everything waiting on its socket, and a flood of LIST requests from invented ids (each
/// its own sender, so under every per-sender rate) made one answer each: 3 000 of them, 70 KB
/// each, held 210 MB at once before the turn sent or dropped them.
const ANSWERS_WAITING_BYTES: usize = 2 << 20;
/// Control requests are retried this often until answered...
const RETRY_INTERVAL: Duration = Duration::from_millis(200);
/// ...and given up after this many sends.
const RETRY_LIMIT: u32 = 25;
/// How many of this node's own finished requests (answered or failed) it keeps for
/// [`NodeCore::request_status`]. A tool that asks forever (a viewer polling LIST) would
/// otherwise grow without bound; the oldest finished ones are forgotten first, pending ones
/// never (they end by themselves after `RETRY_LIMIT` sends).
const FINISHED_REQUESTS_KEPT: usize = 1_024;

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

/// Laid out in declaration order (`repr(C)`) on whole cache lines (`align(64)`, 384 bytes):
/// the first line holds what every message into the port reads or writes of the port's own
/// state (the plain flag, the wave mark, the acceptance counts, whether windows are open, the
/// outgoing connections), the second what a merge reads of the cell (`PortCell`'s order), the
/// supplier and the triggers after it, and the drop counters (touched only when something is
/// refused) last. A message into an aggregating port that absorbs it then costs two or three
/// cache lines, a plain hop three, where the compiler's order and an unaligned 376-byte slot
/// spread them over four or five.
#[repr(C, align(64))]
pub(crate) struct PortState {
    /// Whether a value accepted here needs none of the general path's checks (see
    /// [`PortState::is_plain`]); kept up to date wherever the triggers or windows change.
    pub(crate) plain: bool,
    /// `triggers` as a set of bits (bit `i`: process `i`) in the padding after `plain`, so
    /// that an accepted value finds the processes to queue in this first line instead of the
    /// far one `triggers` lives in (one cache line per accepted message). Exact while every
    /// trigger is a process below 31 added in ascending order (the bits then iterate in the
    /// list's order); otherwise [`TRIGGERS_LISTED`], and the list is read.
    pub(crate) trigger_bits: u32,
    pub(crate) visited: u64,
    pub(crate) accepted: u64,
    /// Values this port absorbed (counted under [`DropCause::Absorbed`]): kept here, beside
    /// the wave mark, rather than in `counters` at the far end of the port, because an
    /// aggregating port absorbs most of what it is offered (a Max port of eligibilities) and
    /// the far end is one more cache line per message. `counters` holds every other cause.
    pub(crate) absorbed: u64,
    pub(crate) windows: Windows,
    /// Outgoing connections, with what a hop needs copied in so that a local hop never
    /// touches the connection table (see [`Edge`]).
    pub(crate) out: Vec<Edge>,
    pub(crate) cell: PortCell,
    /// Processes of this behavior triggered when the port accepts a value.
    pub(crate) triggers: Vec<u16>,
    pub(crate) counters: Counters,
}

/// [`PortState::trigger_bits`] when the bits cannot stand for the list: read `triggers`.
pub(crate) const TRIGGERS_LISTED: u32 = 1 << 31;

impl PortState {
    /// Add process `ix` to the processes this port triggers.
    fn add_trigger(&mut self, ix: u16) {
        let bits = self.trigger_bits;
        // Ascending below 31: the new bit is above every bit set (and the list bit is not).
        self.trigger_bits = if ix < 31 && bits >> ix == 0 { bits | 1 << ix } else { TRIGGERS_LISTED };
        self.triggers.push(ix);
    }

    /// Queue the processes this port triggers (in the order of `triggers`) that are not
    /// pending yet. Inlined into its two callers (a plain `#[inline]` was not taken: 19
    /// instructions a call).
    #[inline(always)]
    fn queue_triggered(&self, pending: &mut VecDeque<(u32, u64, u16)>, processes: &mut [ProcState], b: u32, id: u64) {
        let mut bits = self.trigger_bits;
        if bits & TRIGGERS_LISTED != 0 {
            for &pi in &self.triggers {
                queue(pending, &mut processes[usize::from(pi)], b, id, pi);
            }
            return;
        }
        while bits != 0 {
            let pi = bits.trailing_zeros() as u16;
            bits &= bits - 1;
            queue(pending, &mut processes[usize::from(pi)], b, id, pi);
        }
    }

    /// Count a message this port blocked, refused or absorbed, on the port and, unless the
    /// port absorbed it, in the node's counters `node` (the node's figure for
    /// [`DropCause::Absorbed`] is summed from its ports when asked: `NodeCore::counters`).
    #[inline]
    pub(crate) fn count_both(&mut self, node: &mut Counters, cause: DropCause) {
        if cause == DropCause::Absorbed {
            self.absorbed = self.absorbed.saturating_add(1);
        } else {
            self.counters.add(cause);
            node.add(cause);
        }
    }

    /// The port's counters by cause, [`DropCause::Absorbed`] included.
    pub(crate) fn counters(&self) -> Counters {
        let mut c = self.counters.clone();
        c.add_n(DropCause::Absorbed, self.absorbed);
        c
    }
}

pub(crate) struct MonoState {
    pub(crate) end: Instant,
    pub(crate) high: bool,
    pub(crate) watchers: Vec<u16>,
}

/// In declaration order (`repr(C)`): what every run reads or writes (the trigger and body, in
/// `spec`, and the run count) together at the front, so that a node coming back from cold
/// memory costs about one cache line per process run, not two. (The change outcomes further
/// on are read only on nodes whose processes ever asked for changes; a periodic process's due
/// time lives in the node's schedule, `crate::schedule`.)
#[repr(C)]
pub(crate) struct ProcState {
    pub(crate) spec: ProcessSpec,
    pub(crate) runs: u64,
    pub(crate) ran_in_poll: u64,
    pub(crate) pending: bool,
    pub(crate) overruns: u64,
    /// Times it was triggered again in a poll in which it had already run (by its own write
    /// or a cycle of processes) and was held back by [`RETRIGGER_INTERVAL`] (D7.3).
    pub(crate) retriggers: u64,
    /// What became of the structure changes its previous activation asked for (R2).
    pub(crate) outcomes: Vec<ChangeOutcome>,
}

impl ProcState {
    /// A process that has not run yet (a periodic one is first due when the schedule lists
    /// it: at its creation, D7.2).
    fn new(spec: ProcessSpec) -> ProcState {
        ProcState { spec, runs: 0, overruns: 0, pending: false, ran_in_poll: 0, retriggers: 0, outcomes: Vec::new() }
    }

    pub(crate) fn is_periodic(&self) -> bool {
        matches!(self.spec.trigger, Trigger::Periodic(_))
    }
}

/// A triggered process that is triggered again in the poll in which it already ran (it
/// triggers itself, directly or through a cycle of processes) runs again no sooner than this:
/// such a loop runs at most 1000 times a second instead of spinning a core (D7.3).
pub const RETRIGGER_INTERVAL: Duration = Duration::from_millis(1);

/// Senders whose request rate is tracked, at most (see `Limits::requests_per_second`).
pub const RATE_BUCKETS: usize = 1_024;

/// Warnings kept in a node's report, at most (see [`NodeCore::warn`]).
pub const MAX_WARNINGS: usize = 64;

/// In declaration order (`repr(C)`) and on a cache line of its own (`align(64)`): what a
/// message arriving at one of its ports reads (the id a cached target is checked against, the
/// ports, the processes it may trigger, the name) in the first line, the rest after. The
/// compiler's own order put those four in three lines of a 248-byte slot. The BLE state is
/// boxed: inline, its enum tag was the niche `Option<Behavior>` took (at byte 128), so every
/// `behaviors[b]` check read a third line; boxed, the niche is the ports' capacity, in the
/// first line, and the slot is 192 bytes instead of 256.
#[repr(C, align(64))]
pub(crate) struct Behavior {
    pub(crate) id: u64,
    pub(crate) ports: Vec<PortState>,
    pub(crate) processes: Vec<ProcState>,
    pub(crate) name: Arc<str>,
    pub(crate) class: Arc<BehaviorClass>,
    pub(crate) slots: Vec<Value>,
    pub(crate) monos: Vec<MonoState>,
    pub(crate) ble: Option<Box<BleState>>,
}

#[derive(Clone, Debug)]
pub(crate) enum Target {
    Local { b: u32, p: u16 },
    Remote { to: Destination, behavior: Arc<str>, port: Arc<str> },
}

pub(crate) struct Conn {
    pub(crate) id: u64,
    pub(crate) src: (u32, u16),
    pub(crate) dst: Target,
    pub(crate) kind: ConnectionKind,
    pub(crate) priority: i32,
    pub(crate) seq: u64,
    /// The sequence number the connection started from (`sent` counts from it).
    pub(crate) seq_start: u64,
    pub(crate) source: Endpoint,
    pub(crate) destination: Endpoint,
    /// The node whose request created it (leased to that node, D9.1); `None`: made here.
    pub(crate) requested_by: Option<NodeId>,
}

/// One outgoing connection as the propagation loop sees it: a copy of the connection's
/// immutable facts. `conns` stays the owner (sequence numbers, endpoints, remote targets).
#[derive(Copy, Clone, Debug)]
pub(crate) struct Edge {
    /// Index into `NodeCore::conns`.
    pub(crate) conn: u32,
    pub(crate) id: u64,
    /// The destination port when it is on this node.
    pub(crate) local: Option<(u32, u16)>,
    pub(crate) kind: ConnectionKind,
    pub(crate) priority: i32,
}

#[derive(Copy, Clone)]
struct Frame {
    b: u32,
    p: u16,
    next: u32,
}

struct Request {
    id: u64,
    to: NodeId,
    body: ControlBody,
    next_send: Instant,
    sends: u32,
    status: RequestStatus,
}

/// The CONNECT that asks `source`'s node for a connection to `destination` (a local
/// destination means `me`'s port), checked as [`NodeCore::request_connect`] documents: from
/// outside a process and from inside one alike.
pub(crate) fn connect_request(
    me: NodeId,
    source: &Endpoint,
    destination: &Endpoint,
    kind: ConnectionKind,
    options: ConnectOptions,
) -> Result<(NodeId, ControlBody), Error> {
    if kind.period().is_some_and(|p| p.is_zero()) {
        return Err(Error::ZeroPeriod { kind });
    }
    let Endpoint::Node { node, behavior, port } = source else {
        return Err(if matches!(source, Endpoint::Group { .. }) {
            Error::GroupSource
        } else {
            Error::NotLocal { what: "request_connect's source must be a (node, behavior, port)".into() }
        });
    };
    let destination = match destination {
        Endpoint::Local { behavior, port } => {
            Endpoint::Node { node: me, behavior: behavior.clone(), port: port.clone() }
        }
        other => other.clone(),
    };
    let body = ControlBody::Connect {
        source_behavior: behavior.clone(),
        source_port: port.clone(),
        destination,
        kind,
        priority: options.priority,
    };
    Ok((*node, body))
}

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
// robot touches (a message received, a write, a poll) in the first seven lines, what only
// structure operations, control requests and reports touch after them. A simulator steps
// hundreds of nodes, each cold by the time its turn comes back: the compiler's order spread
// the fields a message reads over eight lines of the node's eighteen.
#[repr(C, align(64))]
pub struct NodeCore {
    pub(crate) now: Instant,
    pub(crate) wave: u64,
    /// The flight recorder's tap (crate::journal); `None`, and then free, unless started.
    pub(crate) journal: Option<Box<Journal>>,
    pub(crate) behaviors: Vec<Option<Behavior>>,
    pub(crate) id: NodeId,
    /// Behaviors removed, wrapping at 16 bits: the epoch of `newest_seq`'s resolved ports
    /// ([`Incoming::epoch`]).
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
    stack: Vec<Frame>,
    poll_epoch: u64,
    /// When the processes in `deferred` may run (`Instant::MAX` while there are none).
    deferred_due: Instant,
    deferred: Vec<(u32, u64, u16)>,
    /// The periodic processes and the next monostable edge, so that a poll need not walk
    /// every process (crate::schedule).
    schedule: Schedule,
    outbox: VecDeque<Outgoing>,
    requests: Vec<Request>,
    /// This node's part in transactions (crate::transaction).
    pub(crate) txns: crate::transaction::Transactions,
    pub(crate) counters: Counters,
    limits: Limits,
    /// Behaviors removed while a process body ran, kept until it returns (see `Running`).
    parked: Vec<Behavior>,
    classes: HashMap<String, Arc<BehaviorClass>>,
    free_behaviors: Vec<u32>,
    names: HashMap<Arc<str>, u32>,
    next_behavior_id: u64,
    pub(crate) conns: Vec<Option<Conn>>,
    free_conns: Vec<u32>,
    conn_ids: HashMap<u64, u32>,
    next_conn_id: u64,
    groups: Vec<Arc<str>>,
    groups_generation: u64,
    /// The name strings whose addresses `newest_seq` entries compare against
    /// ([`Incoming::behavior`]), kept alive until no entry can compare against them.
    held_names: Vec<(Arc<str>, Arc<str>)>,
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
            held_names: Vec::new(),
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

    // ----- structure (rule S9) -------------------------------------------------------------

    /// Make a behavior class available for [`NodeCore::create`]. A class is immutable once
    /// defined, so one `Arc<BehaviorClass>` may be defined on many nodes: a simulated team
    /// then keeps one copy of each process's closure and port specifications instead of one
    /// per node (its state is in the behaviors' ports and slots, never in the class).
    pub fn define(&mut self, class: impl Into<Arc<BehaviorClass>>) -> Result<(), Error> {
        let class: Arc<BehaviorClass> = class.into();
        if class.name.is_empty() {
            return Err(Error::EmptyName { what: "behavior class" });
        }
        if self.classes.contains_key(&class.name) {
            return Err(Error::DuplicateName { what: "behavior class", name: class.name.clone() });
        }
        self.classes.insert(class.name.clone(), class.clone());
        self.journal(|| Event::Define(class));
        Ok(())
    }

    /// Whether a class of this name has been defined here.
    pub fn has_class(&self, name: &str) -> bool {
        self.classes.contains_key(name)
    }

    /// Instantiate class `class` as behavior `name` (the paper's `ayInitBehavior`).
    pub fn create(&mut self, class: &str, name: &str) -> Result<BehaviorRef, Error> {
        if name.is_empty() {
            return Err(Error::EmptyName { what: "behavior" });
        }
        let class = self.classes.get(class).cloned().ok_or_else(|| Error::UnknownClass { class: class.to_owned() })?;
        if self.names.contains_key(name) {
            return Err(Error::DuplicateName { what: "behavior", name: name.to_owned() });
        }
        let now = self.now;
        let id = self.next_behavior_id;
        self.next_behavior_id += 1;
        let mut ports: Vec<PortState> = class
            .ports
            .iter()
            .map(|spec| PortState {
                plain: false,
                trigger_bits: 0,
                cell: PortCell::new(spec),
                windows: Windows::default(),
                out: Vec::new(),
                triggers: Vec::new(),
                visited: 0,
                counters: Counters::default(),
                accepted: 0,
                absorbed: 0,
            })
            .collect();
        let mut monos: Vec<MonoState> =
            class.monos.iter().map(|_| MonoState { end: Instant::ZERO, high: false, watchers: Vec::new() }).collect();
        let mut processes = Vec::with_capacity(class.processes.len());
        for (i, spec) in class.processes.iter().enumerate() {
            attach_trigger(&mut ports, &mut monos, spec.trigger, i as u16);
            processes.push(ProcState::new(spec.clone()));
        }
        ports.iter_mut().for_each(PortState::refresh_plain);
        let behavior = Behavior {
            id,
            name: Arc::from(name),
            slots: class.slots.iter().map(|s| s.default.clone()).collect(),
            class,
            ports,
            monos,
            processes,
            ble: None,
        };
        let b = match self.free_behaviors.pop() {
            Some(b) => {
                self.behaviors[b as usize] = Some(behavior);
                b
            }
            None => {
                self.behaviors.push(Some(behavior));
                (self.behaviors.len() - 1) as u32
            }
        };
        self.names.insert(Arc::from(name), b);
        self.schedule.add_behavior(b, &self.behaviors[b as usize].as_ref().expect("just placed").processes, now);
        self.debug_check_schedule();
        let class = self.behaviors[b as usize].as_ref().map_or(String::new(), |beh| beh.class.name.clone());
        self.journal(|| Event::Create { class, name: name.to_owned() });
        Ok(BehaviorRef { b, id })
    }

    /// Remove a behavior and every connection into or out of it (rule S9). Messages that
    /// later arrive for it are dropped and counted as `unknown_behavior`.
    pub fn remove(&mut self, name: &str) -> Result<(), Error> {
        self.journal(|| Event::Remove { name: name.to_owned() });
        self.unjournaled(|core| core.remove_behavior(name))
    }

    fn remove_behavior(&mut self, name: &str) -> Result<(), Error> {
        let b = *self.names.get(name).ok_or_else(|| Error::UnknownBehavior { behavior: name.to_owned() })?;
        let doomed: Vec<u64> = self
            .conns
            .iter()
            .flatten()
            .filter(|c| c.src.0 == b || matches!(c.dst, Target::Local { b: db, .. } if db == b))
            .map(|c| c.id)
            .collect();
        for id in doomed {
            self.disconnect(ConnectionId(id))?;
        }
        self.names.remove(name);
        let gone = self.behaviors[b as usize].take();
        if let Some(gone) = gone.as_ref() {
            // What its ports absorbed stays in the node-wide figure (see `counters`).
            let absorbed = gone.ports.iter().fold(0u64, |a, p| a.saturating_add(p.absorbed));
            self.counters.add_n(DropCause::Absorbed, absorbed);
        }
        if self.running != Running::Idle {
            // The running body may be among the removed behavior's (see `Running`).
            self.parked.extend(gone);
            self.running = Running::Parked;
        }
        self.behavior_removed();
        self.schedule.remove_behavior(b);
        self.debug_check_schedule();
        self.free_behaviors.push(b);
        Ok(())
    }

    /// Add a process to one behavior instance (used by the BLE helper; also for users who
    /// want an instance-specific process).
    pub fn add_process(
        &mut self,
        behavior: &str,
        name: &str,
        trigger: Trigger,
        body: impl Fn(&mut Ctx<'_>) + Send + Sync + 'static,
    ) -> Result<(), Error> {
        let now = self.now;
        let b = self.behavior_index(behavior)?;
        let beh = self.behaviors[b as usize].as_mut().expect("indexed behavior exists");
        let spec = ProcessSpec { name: name.to_owned(), trigger, body: Arc::new(body) };
        let existing: Vec<ProcessSpec> = beh.processes.iter().map(|p| p.spec.clone()).collect();
        validate_process(&beh.name, &spec, beh.ports.len(), beh.monos.len(), &existing)?;
        let ix = u16::try_from(beh.processes.len())
            .map_err(|_| Error::TooManyRegisters { behavior: behavior.to_owned() })?;
        attach_trigger(&mut beh.ports, &mut beh.monos, spec.trigger, ix);
        let trigger = spec.trigger;
        beh.processes.push(ProcState::new(spec));
        if matches!(trigger, Trigger::Periodic(_)) {
            self.schedule.add_process(b, ix, beh.processes.last().expect("just pushed"), now);
            self.debug_check_schedule();
        }
        self.journal(|| Event::AddProcess { behavior: behavior.to_owned(), name: name.to_owned(), trigger });
        Ok(())
    }

    /// Whether class `class` has a port named `port`; `None` if no such class is defined.
    pub(crate) fn class_port(&self, class: &str, port: &str) -> Option<bool> {
        self.classes.get(class).map(|c| c.port_handle(port).is_some())
    }

    /// The value type of port `port` of class `class`, if both exist.
    pub(crate) fn class_port_type(&self, class: &str, port: &str) -> Option<crate::value::ValueType> {
        let c = self.classes.get(class)?;
        c.port_handle(port).map(|h| c.ports[usize::from(h.0)].ty())
    }

    /// The id the next connection made on this node will get (ids are never reused).
    pub(crate) fn next_connection_id(&self) -> u64 {
        self.next_conn_id
    }

    /// Whether the existing behavior `name` is in a BLE group.
    pub(crate) fn in_ble_group(&self, name: &str) -> bool {
        self.behavior_index(name).ok().and_then(|b| self.behavior(b)).is_some_and(|b| b.ble.is_some())
    }

    /// The class of behavior `name`, if it exists.
    pub(crate) fn class_name_of(&self, name: &str) -> Option<String> {
        let b = self.behavior_index(name).ok()?;
        self.behavior(b).map(|beh| beh.class.name.clone())
    }

    pub(crate) fn behavior_index(&self, name: &str) -> Result<u32, Error> {
        self.names.get(name).copied().ok_or_else(|| Error::UnknownBehavior { behavior: name.to_owned() })
    }

    pub(crate) fn behavior(&self, b: u32) -> Option<&Behavior> {
        self.behaviors.get(b as usize).and_then(Option::as_ref)
    }

    pub(crate) fn behavior_mut(&mut self, b: u32) -> Option<&mut Behavior> {
        self.behaviors.get_mut(b as usize).and_then(Option::as_mut)
    }

    /// A handle to `behavior.port` for fast repeated writes and reads.
    pub fn port(&self, behavior: &str, port: &str) -> Result<PortRef, Error> {
        let b = self.behavior_index(behavior)?;
        let beh = self.behavior(b).expect("indexed behavior exists");
        match beh.class.port_handle(port) {
            Some(p) => Ok(PortRef { b, id: beh.id, port: p }),
            None if beh.class.slot_handle(port).is_some() => {
                Err(Error::NotAPort { behavior: behavior.to_owned(), name: port.to_owned() })
            }
            None => Err(Error::UnknownPort { behavior: behavior.to_owned(), port: port.to_owned() }),
        }
    }

    /// A handle to the port whose handle within its class is `port` (as the class's
    /// processes know it), of behavior `behavior`; [`NodeCore::port`] finds it by name.
    pub fn port_by_handle(&self, behavior: &str, port: Port) -> Result<PortRef, Error> {
        let b = self.behavior_index(behavior)?;
        let beh = self.behavior(b).expect("indexed behavior exists");
        if usize::from(port.0) >= beh.ports.len() {
            return Err(Error::UnknownPort { behavior: behavior.to_owned(), port: format!("#{}", port.0) });
        }
        Ok(PortRef { b, id: beh.id, port })
    }

    /// The behavior handle for `name`.
    pub fn behavior_ref(&self, name: &str) -> Result<BehaviorRef, Error> {
        let b = self.behavior_index(name)?;
        Ok(BehaviorRef { b, id: self.behavior(b).expect("indexed behavior exists").id })
    }

    /// The port a handle names, if its behavior still lives. Inlined into the readers below
    /// (which a body calls for every robot each tick), its error built out of line.
    #[inline]
    pub(crate) fn resolve(&self, r: PortRef) -> Result<&PortState, Error> {
        match self.behavior(r.b).filter(|beh| beh.id == r.id).and_then(|beh| beh.ports.get(usize::from(r.port.0))) {
            Some(ps) => Ok(ps),
            None => Err(stale_handle(r)),
        }
    }

    fn local_port(&self, behavior: &str, port: &str) -> Result<(u32, u16), Error> {
        let r = self.port(behavior, port)?;
        Ok((r.b, r.port.0))
    }

    // ----- connections (rules S6, S10) -----------------------------------------------------

    /// Connect `source` (a port on this node) to `destination` (a port on this node, another
    /// node, or every node of a group). Returns the new connection's id.
    ///
    /// Refused: a zero period ([`Error::ZeroPeriod`], D6.8); a source on another node
    /// ([`Error::NotLocal`]: use [`NodeCore::request_connect`]) or a group
    /// ([`Error::GroupSource`]); an unknown behavior or port, or a slot; for the kinds that
    /// write (Normal, OverrideIn, OverrideOut) a local destination of another type
    /// ([`Error::TypeMismatch`], D6.7). Remote destinations are checked by their node.
    pub fn connect(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
        options: ConnectOptions,
    ) -> Result<ConnectionId, Error> {
        if let Some(p) = kind.period() {
            if p.is_zero() {
                return Err(Error::ZeroPeriod { kind });
            }
        }
        let (sb, sp) = match source {
            Endpoint::Local { behavior, port } => self.local_port(behavior, port)?,
            Endpoint::Node { node, behavior, port } if *node == self.id => self.local_port(behavior, port)?,
            Endpoint::Node { .. } => {
                return Err(Error::NotLocal {
                    what: format!("the source {source} of connect (use request_connect for another node's port)"),
                })
            }
            Endpoint::Group { .. } => return Err(Error::GroupSource),
        };
        let src_ty = self.behavior(sb).expect("resolved").ports[usize::from(sp)].cell.ty();
        if !matches!(destination, Endpoint::Local { .. })
            && !matches!(destination, Endpoint::Node { node, .. } if *node == self.id)
        {
            // A value that can never be encoded would be dropped at every send (D-S10.7).
            let beh = self.behavior(sb).expect("resolved");
            let cell = &beh.ports[usize::from(sp)].cell;
            let len = current(cell, self.now).as_vector().map_or(0, <[f64]>::len);
            if len > crate::value::MAX_NETWORK_VECTOR {
                let name = beh.class.ports().get(usize::from(sp)).map_or("", |p| p.name.as_str());
                return Err(Error::TooLongForNetwork { port: format!("{}.{name}", beh.name), len });
            }
        }
        let dst = match destination {
            Endpoint::Local { behavior, port } => self.local_target(behavior, port, kind, src_ty)?,
            Endpoint::Node { node, behavior, port } if *node == self.id => {
                self.local_target(behavior, port, kind, src_ty)?
            }
            Endpoint::Node { node, behavior, port } => {
                check_name(behavior, port)?;
                Target::Remote { to: Destination::Node(*node), behavior: behavior.clone(), port: port.clone() }
            }
            Endpoint::Group { group, behavior, port } => {
                check_name(behavior, port)?;
                Target::Remote { to: Destination::Group(group.clone()), behavior: behavior.clone(), port: port.clone() }
            }
        };
        let id = self.next_conn_id;
        self.next_conn_id += 1;
        let source = match source {
            Endpoint::Node { behavior, port, .. } => Endpoint::Local { behavior: behavior.clone(), port: port.clone() },
            other => other.clone(),
        };
        let local = match dst {
            Target::Local { b, p } => Some((b, p)),
            Target::Remote { .. } => None,
        };
        let journaled_source = self.journal.is_some().then(|| source.clone());
        let conn = Conn {
            id,
            src: (sb, sp),
            dst,
            kind,
            priority: options.priority,
            seq: self.seq_base,
            seq_start: self.seq_base,
            requested_by: None,
            source,
            destination: destination.clone(),
        };
        let c = match self.free_conns.pop() {
            Some(c) => {
                self.conns[c as usize] = Some(conn);
                c
            }
            None => {
                self.conns.push(Some(conn));
                (self.conns.len() - 1) as u32
            }
        };
        self.conn_ids.insert(id, c);
        let edge = Edge { conn: c, id, local, kind, priority: options.priority };
        self.behavior_mut(sb).expect("resolved").ports[usize::from(sp)].out.push(edge);
        self.journal(|| Event::Connect {
            source: journaled_source.unwrap_or_else(|| Endpoint::local("", "")),
            destination: destination.clone(),
            kind,
            priority: options.priority,
        });
        Ok(ConnectionId(id))
    }

    fn local_target(
        &self,
        behavior: &str,
        port: &str,
        kind: ConnectionKind,
        src_ty: crate::value::ValueType,
    ) -> Result<Target, Error> {
        let (b, p) = self.local_port(behavior, port)?;
        let cell = &self.behavior(b).expect("resolved").ports[usize::from(p)].cell;
        if kind.writes() && cell.ty() != src_ty {
            return Err(Error::TypeMismatch {
                what: format!("port {behavior}.{port}"),
                expected: cell.ty(),
                found: src_ty,
            });
        }
        Ok(Target::Local { b, p })
    }

    /// Remove a connection this node owns. Windows it holds on local ports end at once.
    pub fn disconnect(&mut self, id: ConnectionId) -> Result<(), Error> {
        let c = self.conn_ids.remove(&id.0).ok_or(Error::UnknownConnection { id: id.0 })?;
        let conn = self.conns[c as usize].take().expect("indexed connection exists");
        self.free_conns.push(c);
        let me = self.id;
        if let Some(beh) = self.behavior_mut(conn.src.0) {
            beh.ports[usize::from(conn.src.1)].out.retain(|e| e.conn != c);
        }
        if let Target::Local { b, p } = conn.dst {
            if let Some(beh) = self.behavior_mut(b) {
                let port = &mut beh.ports[usize::from(p)];
                let gone = Source::connection(me, id);
                port.windows.forget_holder(gone);
                port.refresh_plain();
                // What the connection supplied to an aggregating port is no longer offered.
                port.cell.release_from(|s| s == gone);
            }
        }
        self.journal(|| Event::Disconnect { conn: id });
        Ok(())
    }

    /// Node `node` is gone (its transport has not heard from it for its liveness period, N6):
    /// every aggregating port it holds releases its value, so the next value is judged against
    /// what is still supplied, not against a dead robot's claim (D3.7). Its windows lapse by
    /// themselves at the end of their periods. Returns how many ports were released.
    pub fn node_lost(&mut self, now: Instant, node: NodeId) -> usize {
        self.advance(now);
        self.journal(|| Event::NodeLost { node });
        self.unjournaled(|core| core.release_node(node))
    }

    fn release_node(&mut self, node: NodeId) -> usize {
        if node == self.id {
            return 0;
        }
        let mut released = 0;
        for beh in self.behaviors.iter_mut().flatten() {
            for port in &mut beh.ports {
                if port.cell.release_from(|s| s.node == node) {
                    released += 1;
                }
            }
        }
        // Connections it asked for were leased to it (D9.1).
        let leased: Vec<u64> =
            self.conns.iter().flatten().filter(|c| c.requested_by == Some(node)).map(|c| c.id).collect();
        for id in leased {
            let _ = self.disconnect(ConnectionId(id));
        }
        released
    }

    /// Take one token from `from`'s request bucket (`Limits::requests_per_second`, burst
    /// `requests_burst`); `false` when it is empty. At most [`RATE_BUCKETS`] senders are
    /// tracked; the one idle longest is forgotten first (a forgotten sender starts full).
    fn admit_request(&mut self, from: NodeId) -> bool {
        let rate = f64::from(self.limits.requests_per_second);
        let burst = f64::from(self.limits.requests_burst.max(1));
        let now = self.now;
        if !self.request_buckets.contains_key(&from) && self.request_buckets.len() >= RATE_BUCKETS {
            if let Some(idle) = self.request_buckets.iter().min_by_key(|(_, (_, t))| *t).map(|(n, _)| *n) {
                self.request_buckets.remove(&idle);
            }
        }
        let (tokens, last) = self.request_buckets.entry(from).or_insert((burst, now));
        let refill = (now - *last).as_secs_f64() * rate;
        *tokens = (*tokens + refill).min(burst);
        *last = now;
        if *tokens < 1.0 {
            return false;
        }
        *tokens -= 1.0;
        true
    }

    /// Set who may write this node's ports and change its structure from the network.
    pub fn set_access(&mut self, access: Access) {
        self.journal(|| Event::SetAccess(access.clone()));
        self.access = access;
    }

    /// The access rules in force.
    pub fn access(&self) -> &Access {
        &self.access
    }

    /// Set the bounds on what the network can make this node hold.
    pub fn set_limits(&mut self, limits: Limits) {
        self.journal(|| Event::SetLimits(limits.clone()));
        self.limits = limits;
    }

    /// The limits in force.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// Join a broadcast group: messages sent to `(group, behavior, port)` by others reach us.
    /// The transport decides delivery; the core only records membership for listing.
    pub fn join(&mut self, group: &str) {
        self.journal(|| Event::Join(group.to_owned()));
        if !self.groups.iter().any(|g| &**g == group) {
            self.groups.push(Arc::from(group));
            self.groups_generation += 1;
        }
    }

    /// Leave a broadcast group (nothing if not a member). Connections *to* the group stay:
    /// remove them with [`NodeCore::disconnect`].
    pub fn leave(&mut self, group: &str) {
        self.journal(|| Event::Leave(group.to_owned()));
        let before = self.groups.len();
        self.groups.retain(|g| &**g != group);
        if self.groups.len() != before {
            self.groups_generation += 1;
        }
    }

    /// Changes whenever the set of joined groups changes, so a runtime can keep its
    /// transport's memberships in step with the core's without comparing lists every turn.
    pub fn groups_generation(&self) -> u64 {
        self.groups_generation
    }

    /// The groups joined, in join order.
    pub fn groups(&self) -> &[Arc<str>] {
        &self.groups
    }

    /// Ask `source`'s node to make a connection from its port to `destination` (N2: retried
    /// until answered, idempotent). `destination` must name a node or group, since "local"
    /// would be ambiguous on the other side.
    pub fn request_connect(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
        options: ConnectOptions,
    ) -> Result<RequestId, Error> {
        let (node, body) = connect_request(self.id, source, destination, kind, options)?;
        Ok(self.send_request(node, body))
    }

    /// Ask `node` to remove its connection `conn`.
    pub fn request_disconnect(&mut self, node: NodeId, conn: ConnectionId) -> RequestId {
        self.send_request(node, ControlBody::Disconnect { conn })
    }

    fn send_request(&mut self, to: NodeId, body: ControlBody) -> RequestId {
        if self.journal.is_some() {
            let recorded = body.clone();
            self.journal(|| Event::Request { to, body: recorded });
        }
        let id = self.next_request;
        self.next_request += 1;
        self.requests.push(Request {
            id,
            to,
            body,
            next_send: self.now,
            sends: 0,
            status: RequestStatus::Pending { sends: 0 },
        });
        self.flush_requests();
        RequestId(id)
    }

    /// Where request `id` stands; `None` if this node never sent it or has forgotten it. The
    /// runtime's [`NodeCore::poll`] drives the retries. A finished request (answered or
    /// failed) is kept until [`NodeCore::forget_request`] or until 1,024 newer ones have
    /// finished, whichever comes first, so a program that never forgets stays bounded.
    pub fn request_status(&self, id: RequestId) -> Option<RequestStatus> {
        self.requests.iter().rev().find(|r| r.id == id.0).map(|r| r.status.clone())
    }

    /// Forget request `id` and return where it stood: a pending request is no longer retried
    /// and its answer, if one comes, is ignored. `None` if this node never sent it or has
    /// already forgotten it.
    pub fn forget_request(&mut self, id: RequestId) -> Option<RequestStatus> {
        let i = self.requests.iter().rposition(|r| r.id == id.0)?;
        let r = self.requests.remove(i);
        if !matches!(r.status, RequestStatus::Pending { .. }) {
            self.finished_requests -= 1;
        }
        Some(r.status)
    }

    /// Request `id` to `to` cannot be sent at all (the transport says why: larger than a
    /// datagram, ...): it fails now with `reason` instead of being retried until it gives up.
    /// Nothing happens if it is not pending.
    pub fn fail_request(&mut self, to: NodeId, id: u64, reason: String) {
        let Some(r) = self.requests.iter_mut().rev().find(|r| r.id == id && r.to == to) else { return };
        if matches!(r.status, RequestStatus::Pending { .. }) {
            r.status = RequestStatus::Failed(reason);
            self.request_finished();
        }
    }

    /// How many requests this node holds (pending and finished): bounded, see
    /// [`NodeCore::request_status`].
    pub fn requests_held(&self) -> usize {
        self.requests.len()
    }

    /// Count one more finished request and, past the bound, forget the oldest finished ones
    /// (in batches, so the cost per request stays constant).
    fn request_finished(&mut self) {
        self.finished_requests += 1;
        if self.finished_requests > FINISHED_REQUESTS_KEPT + FINISHED_REQUESTS_KEPT / 4 {
            let mut excess = self.finished_requests - FINISHED_REQUESTS_KEPT;
            self.requests.retain(|r| {
                if excess > 0 && !matches!(r.status, RequestStatus::Pending { .. }) {
                    excess -= 1;
                    false
                } else {
                    true
                }
            });
            self.finished_requests = FINISHED_REQUESTS_KEPT;
        }
    }

    fn flush_requests(&mut self) {
        let now = self.now;
        let mut failed = 0;
        for r in &mut self.requests {
            if !matches!(r.status, RequestStatus::Pending { .. }) || r.next_send > now {
                continue;
            }
            if r.sends >= RETRY_LIMIT {
                r.status = RequestStatus::Failed(format!("no answer from {} after {} tries", r.to, r.sends));
                failed += 1;
                continue;
            }
            r.sends += 1;
            r.status = RequestStatus::Pending { sends: r.sends };
            r.next_send = now + RETRY_INTERVAL;
            self.outbox.push_back(Outgoing {
                to: Destination::Node(r.to),
                message: Message::Control(ControlMessage { id: r.id, body: r.body.clone() }),
            });
        }
        for _ in 0..failed {
            self.request_finished();
        }
    }

    // ----- writes and propagation (rules S3–S6) --------------------------------------------

    /// Write `value` into a port as its own behavior would (rule S6: suppression does not stop
    /// it; inhibition and write-inhibition stop its propagation). Triggered processes run at
    /// the next `poll`.
    #[inline]
    pub fn write(&mut self, now: Instant, port: PortRef, value: impl Into<Value>) -> Result<(), Error> {
        self.advance(now);
        let value = value.into();
        if self.journal.is_none() && self.write_plain(port, &value) {
            return Ok(());
        }
        self.resolve(port)?;
        if self.journal.is_some() {
            self.journal_write(port, &value);
        }
        self.write_internal(port.b, port.port.0, &value).map_err(|cause| self.drop_error(port, cause, &value))
    }

    /// Write by name; see [`NodeCore::write`].
    pub fn write_named(
        &mut self,
        now: Instant,
        behavior: &str,
        port: &str,
        value: impl Into<Value>,
    ) -> Result<(), Error> {
        let r = self.port(behavior, port)?;
        self.write(now, r, value)
    }

    fn drop_error(&self, port: PortRef, cause: DropCause, value: &Value) -> Error {
        let beh = self.behavior(port.b).expect("resolved");
        let spec = &beh.class.ports[usize::from(port.port.0)];
        let what = format!("port {}.{}", beh.name, spec.name);
        match cause {
            DropCause::TypeMismatch => Error::TypeMismatch { what, expected: spec.ty(), found: value.ty() },
            _ => Error::Refused { what, cause },
        }
    }

    /// A behavior's own write. `Ok` if the port stored the value (propagated or not);
    /// `Err(cause)` for a type mismatch or NaN (refused). `Absorbed` is reported as `Ok`.
    pub(crate) fn write_internal(&mut self, b: u32, p: u16, value: &Value) -> Result<(), DropCause> {
        self.wave += 1;
        let (now, wave, me) = (self.now, self.wave, self.id);
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else {
            self.counters.add(DropCause::UnknownBehavior);
            return Err(DropCause::UnknownBehavior);
        };
        let id = beh.id;
        let Some(port) = beh.ports.get_mut(usize::from(p)) else {
            self.counters.add(DropCause::UnknownPort);
            return Err(DropCause::UnknownPort);
        };
        if let Err(cause) = port.cell.merge(now, value, Source::internal(me), 0) {
            port.count_both(&mut self.counters, cause);
            return if cause == DropCause::Absorbed { Ok(()) } else { Err(cause) };
        }
        port.visited = wave;
        port.accepted += 1;
        if let Some(j) = self.journal.as_deref_mut() {
            journal_accepted(j, now, &beh.name, &beh.class, p, &port.cell.value);
        }
        port.queue_triggered(&mut self.pending, &mut beh.processes, b, id);
        // A port with nowhere to send has nothing to block: only real blocks are counted.
        if port.out.is_empty() {
            return Ok(());
        }
        match port.windows.admit_propagation(now, Origin::Internal) {
            Ok(()) => self.propagate_from(b, p),
            Err(cause) => {
                port.count_both(&mut self.counters, cause);
            }
        }
        Ok(())
    }

    /// The wave from port (b, p), which has just accepted and may propagate (rule S5): the
    /// common case — local edges into ports that do not pass the value on — is taken here
    /// without a stack frame. The first edge that needs more (a destination that propagates
    /// further, a remote destination) hands the rest of the wave to [`NodeCore::run_wave`] at
    /// exactly that point, so the depth-first order, and every check `deliver` makes, are
    /// those of the general path.
    #[inline]
    pub(crate) fn propagate_from(&mut self, b: u32, p: u16) {
        self.propagate_from_edge(b, p, 0);
    }

    /// [`NodeCore::propagate_from`] from the port's edge `next` on (the ones before it taken).
    pub(crate) fn propagate_from_edge(&mut self, b: u32, p: u16, mut next: u32) {
        let me = self.id;
        loop {
            let Some(beh) = self.behaviors.get(b as usize).and_then(Option::as_ref) else { return };
            let port = &beh.ports[usize::from(p)];
            let Some(&edge) = port.out.get(next as usize) else { return };
            let Some((db, dp)) = edge.local else {
                self.stack.push(Frame { b, p, next });
                self.run_wave();
                return;
            };
            let last = next as usize + 1 == port.out.len();
            let value = port.cell.value.clone();
            next += 1;
            let from = Source::connection(me, ConnectionId(edge.id));
            if edge.kind == ConnectionKind::Normal && self.journal.is_none() && self.hop_plain(db, dp, from, &value) {
                if last {
                    return;
                }
                continue;
            }
            if self.deliver(db, dp, edge.kind, from, edge.priority, &value) {
                if !last {
                    self.stack.push(Frame { b, p, next });
                }
                self.stack.push(Frame { b: db, p: dp, next: 0 });
                self.run_wave();
                return;
            }
            if last {
                return;
            }
        }
    }

    /// Depth-first propagation from the frames on the stack (rule S5).
    fn run_wave(&mut self) {
        let me = self.id;
        while let Some(top) = self.stack.last_mut() {
            let Frame { b, p, next } = *top;
            let Some(beh) = self.behaviors.get(b as usize).and_then(Option::as_ref) else {
                self.stack.pop();
                continue;
            };
            let port = &beh.ports[usize::from(p)];
            let Some(&edge) = port.out.get(next as usize) else {
                self.stack.pop();
                continue;
            };
            // Taking the port's last connection finishes its frame: pop it now rather than
            // revisit it (same depth-first order; `out` cannot change during a wave).
            if next as usize + 1 == port.out.len() {
                self.stack.pop();
            } else {
                top.next += 1;
            }
            let value = port.cell.value.clone();
            let from = Source::connection(me, ConnectionId(edge.id));
            let (kind, priority) = (edge.kind, edge.priority);
            if let Some((db, dp)) = edge.local {
                if self.deliver(db, dp, kind, from, priority, &value) {
                    self.stack.push(Frame { b: db, p: dp, next: 0 });
                }
                continue;
            }
            let Some(conn) = self.conns.get_mut(edge.conn as usize).and_then(Option::as_mut) else { continue };
            match &conn.dst {
                Target::Local { .. } => {}
                Target::Remote { to, behavior, port } => {
                    conn.seq += 1;
                    let message = Message::Port(PortMessage {
                        conn: ConnectionId(conn.id),
                        seq: conn.seq,
                        behavior: behavior.clone(),
                        port: port.clone(),
                        kind,
                        priority,
                        value,
                    });
                    self.outbox.push_back(Outgoing { to: to.clone(), message });
                }
            }
        }
    }

    /// Apply one message arriving along a connection at local port (b, p). Returns whether the
    /// value was stored *and* may propagate.
    #[inline]
    fn deliver(&mut self, b: u32, p: u16, kind: ConnectionKind, from: Source, priority: i32, value: &Value) -> bool {
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else {
            self.counters.add(DropCause::UnknownBehavior);
            return false;
        };
        let Some(port) = beh.ports.get_mut(usize::from(p)) else {
            self.counters.add(DropCause::UnknownPort);
            return false;
        };
        let port: *mut PortState = port;
        // SAFETY: `port` is port `p` of the live behavior in slot `b`, borrowed just above and
        // released; nothing else refers to it during the call.
        unsafe { self.deliver_to(b, p, port, kind, from, priority, value) }
    }

    /// [`NodeCore::deliver`] at a port already found: `port` is port `p` of behavior slot `b`.
    /// The behavior itself is read only when it must be (the port triggers processes, or the
    /// journal records the value), so a message whose port the sequence table remembers
    /// ([`crate::sequence::SeqEntry`]) loads the port's line and the behavior's side by side
    /// instead of the behavior's first and the port's after it (its address is in the
    /// behavior): one cold load less on the chain of every remote message.
    ///
    /// # Safety
    /// `port` points to port `p` of the live behavior in slot `b`, inside that behavior's
    /// `ports` buffer (which neither moves nor changes length while the behavior lives), and
    /// no reference to that port is alive during the call.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn deliver_to(
        &mut self,
        b: u32,
        p: u16,
        port: *mut PortState,
        kind: ConnectionKind,
        from: Source,
        priority: i32,
        value: &Value,
    ) -> bool {
        let (now, wave) = (self.now, self.wave);
        // SAFETY: the caller's promise; `self.behaviors` below is read for other fields of
        // the behavior (its id, processes, name), never for its ports.
        let port = unsafe { &mut *port };
        // An override's value must be one the port could take (type, NaN, shape): a message
        // refused as invalid opens no window (D6.7). The blocking kinds carry no value to check.
        if matches!(kind, ConnectionKind::OverrideIn(_) | ConnectionKind::OverrideOut(_)) {
            if let Err(cause) = port.cell.check(value) {
                port.count_both(&mut self.counters, cause);
                return false;
            }
        }
        // A special connection's window always takes effect when its message arrives; only
        // the write of `m` itself is subject to the blocks in force (docs/semantics.md, D6.2).
        if kind != ConnectionKind::Normal {
            port.plain = false; // a window opens below
        }
        match kind {
            ConnectionKind::Normal => {}
            ConnectionKind::Suppress(d) => {
                port.windows.refresh(now, WindowKind::Suppress, from, now + d);
                return false;
            }
            ConnectionKind::Inhibit(d) => {
                port.windows.refresh(now, WindowKind::Inhibit, from, now + d);
                return false;
            }
            ConnectionKind::WriteInhibit(d) => {
                port.windows.refresh(now, WindowKind::WriteInhibit, from, now + d);
                return false;
            }
            ConnectionKind::OverrideIn(d) => port.windows.refresh(now, WindowKind::OverrideIn, from, now + d),
            ConnectionKind::OverrideOut(d) => port.windows.refresh(now, WindowKind::OverrideOut, from, now + d),
        }
        let outcome = if port.visited == wave {
            Err(DropCause::WaveRevisit)
        } else {
            port.windows.admit_write(now, from).and_then(|()| port.cell.merge(now, value, from, priority))
        };
        if let Err(cause) = outcome {
            port.count_both(&mut self.counters, cause);
            return false;
        }
        port.visited = wave;
        port.accepted += 1;
        if let Some(j) = self.journal.as_deref_mut() {
            let beh = self.behaviors[b as usize].as_ref().expect("the caller's live behavior");
            journal_accepted(j, now, &beh.name, &beh.class, p, &port.cell.value);
        }
        if port.trigger_bits != 0 {
            let beh = self.behaviors[b as usize].as_mut().expect("the caller's live behavior");
            let id = beh.id;
            port.queue_triggered(&mut self.pending, &mut beh.processes, b, id);
        }
        if port.out.is_empty() {
            return false;
        }
        match port.windows.admit_propagation(now, Origin::Connection(from)) {
            Ok(()) => true,
            Err(cause) => {
                port.count_both(&mut self.counters, cause);
                false
            }
        }
    }

    // ----- messages from other nodes (rules S8, S10; N1, N2, N4) ---------------------------

    /// Apply a message from node `from`. Port messages are applied at once (a new wave);
    /// triggered processes run at the next `poll`. Never panics; what cannot be applied is
    /// counted.
    pub fn receive(&mut self, now: Instant, from: NodeId, message: Message) {
        self.advance(now);
        if self.journal.is_some() {
            let recorded = message.clone();
            self.journal(|| Event::Receive { from, message: recorded });
        }
        match message {
            Message::Port(m) => self.receive_port(from, &m),
            Message::Control(c) => self.receive_control(from, c),
        }
    }

    /// [`NodeCore::receive`] for a message shared by several receivers (a broadcast in a
    /// simulator): a port message is applied without being copied; a control message is.
    pub fn receive_shared(&mut self, now: Instant, from: NodeId, message: &Message) {
        self.advance(now);
        self.journal(|| Event::Receive { from, message: message.clone() });
        match message {
            Message::Port(m) => self.receive_port(from, m),
            Message::Control(c) => self.receive_control(from, c.clone()),
        }
    }

    /// A hint that `message` from `from` is about to be received: starts loading what its
    /// lookup reads first (the sequence table's slot), so that a caller holding several
    /// messages for this node (a simulator's radio) overlaps their loads. Changes nothing.
    #[inline]
    pub fn prefetch_receive(&self, from: NodeId, message: &Message) {
        if let Message::Port(m) = message {
            self.newest_seq.prefetch(&incoming_key(from, m.conn));
        }
    }

    /// The second hint, for a message whose [`NodeCore::prefetch_receive`] was given a while
    /// before: reads its sequence-table entry and starts loading the port the entry remembers,
    /// so that a caller holding several messages for this node has their ports' loads in flight
    /// together instead of one after the other. Changes nothing.
    #[inline]
    pub fn prefetch_target(&self, from: NodeId, message: &Message) {
        if let Message::Port(m) = message {
            self.newest_seq.prefetch_target(&incoming_key(from, m.conn));
        }
    }

    // Inlined into its two callers (a plain `#[inline]` was not taken): a broadcast in a
    // simulator reaches each receiver through `receive_shared`, and one call less per delivery
    // is one register save and restore less (24 instructions).
    #[inline(always)]
    fn receive_port(&mut self, from: NodeId, m: &PortMessage) {
        if !self.access.ports.admits(from) {
            self.counters.add(DropCause::NotAllowed);
            return;
        }
        if m.kind.period().is_some_and(|p| p > self.limits.max_remote_period) {
            self.counters.add(DropCause::TooLong);
            return;
        }
        let key = incoming_key(from, m.conn);
        // One hash lookup per message from a known connection: this runs for every message.
        let cached = match self.newest_seq.get(&key) {
            Some(entry) => {
                let incoming = entry.get();
                if m.seq <= incoming.newest {
                    self.counters.add(DropCause::Stale);
                    return;
                }
                entry.newest.store(m.seq, Relaxed);
                // The port stands if no behavior was removed since it was resolved and the
                // message carries the very names it was resolved from.
                (incoming.epoch == self.removals && same_names(&incoming, m)).then_some((
                    incoming.b,
                    incoming.p,
                    incoming.target,
                ))
            }
            None => {
                if self.newest_seq.len() >= SEQ_TABLE_MAX {
                    self.forget_incoming();
                }
                self.newest_seq.insert(SeqEntry::new(key, Incoming::unresolved(m.seq)));
                None
            }
        };
        let (b, p, target) = match cached {
            Some(resolved) => resolved,
            None => match self.resolve_incoming(key, m) {
                Some(resolved) => resolved,
                None => return,
            },
        };
        self.wave += 1;
        let source = Source::connection(from, m.conn);
        // SAFETY: `target` is port `p` of the live behavior in slot `b`: either just resolved
        // (`resolve_incoming`), or remembered by the entry with the epoch checked above: no
        // behavior was removed since it was stored, so slot `b` holds the same behavior, whose
        // `ports` buffer has not moved (a behavior's ports are fixed at its creation). No
        // reference to the port is alive here.
        if unsafe { self.deliver_to(b, p, target, m.kind, source, m.priority, &m.value) } {
            self.propagate_from(b, p);
        }
    }

    /// Resolve the port message `m` names, for the sequence table's entry `key` (which exists)
    /// whose remembered port does not stand as it is (a behavior was removed since, or the
    /// message carries other name strings). If the behavior now in the remembered slot has the
    /// names the message carries, that is the port the names resolve to (names are unique on
    /// a node), and the entry keeps it and the strings it holds. Otherwise the names are looked
    /// up and the port and the message's name strings remembered. `None`, counted, if there is
    /// no such port.
    #[cold]
    #[inline(never)]
    fn resolve_incoming(&mut self, key: IncomingKey, m: &PortMessage) -> Option<(u32, u16, *mut PortState)> {
        let incoming = self.newest_seq.get(&key).expect("entered by the caller").get();
        if incoming.behavior != 0 {
            let named = self.behavior(incoming.b).is_some_and(|beh| {
                *beh.name == *m.behavior
                    && beh.class.ports.get(usize::from(incoming.p)).is_some_and(|p| p.name == *m.port)
            });
            if named {
                // The slot may hold a behavior re-created since: its ports are new.
                let target = self.port_address(incoming.b, incoming.p);
                if let Some(entry) = self.newest_seq.get(&key) {
                    entry.set(Incoming { epoch: self.removals, target, ..entry.get() });
                }
                return Some((incoming.b, incoming.p, target));
            }
        }
        let Some(&b) = self.names.get(&*m.behavior) else {
            self.counters.add(DropCause::UnknownBehavior);
            return None;
        };
        let Some(beh) = self.behavior(b) else {
            self.counters.add(DropCause::UnknownBehavior);
            return None;
        };
        let Some(port) = beh.class.port_handle(&m.port) else {
            self.counters.add(DropCause::UnknownPort);
            return None;
        };
        let p = port.0;
        // The names held are bounded like the entries (N1): a sender that keeps re-pointing
        // a connection id clears the table as one that invents connection ids does.
        if self.held_names.len() >= SEQ_TABLE_MAX {
            self.forget_incoming();
            self.newest_seq.insert(SeqEntry::new(key, incoming));
        }
        let target = self.port_address(b, p);
        let Some(entry) = self.newest_seq.get(&key) else { return Some((b, p, target)) };
        let (behavior, port) = (name_address(&m.behavior), name_address(&m.port));
        entry.set(Incoming { behavior, port, b, p, epoch: self.removals, target, ..incoming });
        self.held_names.push((m.behavior.clone(), m.port.clone()));
        Some((b, p, target))
    }

    /// Where port `p` of the live behavior in slot `b` is, for [`NodeCore::deliver_to`]: taken
    /// with `as_mut_ptr`, which makes no reference to the buffer, so the pointer stays usable
    /// beside the references later code makes to it (and to the other ports) in turn.
    fn port_address(&mut self, b: u32, p: u16) -> *mut PortState {
        let beh = self.behaviors[b as usize].as_mut().expect("a resolved port's behavior lives");
        assert!(usize::from(p) < beh.ports.len(), "a resolved port exists");
        // SAFETY: in bounds (asserted), inside the buffer's one allocation.
        unsafe { beh.ports.as_mut_ptr().add(usize::from(p)) }
    }

    /// Clear the sequence table (N1) and the names its entries held; counted.
    fn forget_incoming(&mut self) {
        self.newest_seq.clear();
        self.held_names.clear();
        self.seq_table_resets += 1;
    }

    /// A behavior was removed: the sequence table's resolved ports are no longer trusted as
    /// they are ([`Incoming::epoch`]). When the 16-bit epoch wraps, an entry resolved 65 536
    /// removals ago would look current: every entry forgets its port instead (and with it
    /// the names it held).
    fn behavior_removed(&mut self) {
        self.removals = self.removals.wrapping_add(1);
        if self.removals == 0 {
            for entry in self.newest_seq.iter() {
                entry.set(Incoming { behavior: 0, port: 0, ..entry.get() });
            }
            self.held_names.clear();
        }
    }

    fn receive_control(&mut self, from: NodeId, c: ControlMessage) {
        let result = match c.body {
            ControlBody::Reply { result } => {
                if let Some(r) = self.requests.iter_mut().rev().find(|r| r.id == c.id && r.to == from) {
                    if matches!(r.status, RequestStatus::Pending { .. }) {
                        r.status = match result {
                            Ok(body) => RequestStatus::Done(body),
                            Err(e) => RequestStatus::Failed(e),
                        };
                        self.request_finished();
                    }
                }
                return;
            }
            body => {
                if !self.admit_request(from) {
                    // Unanswered: an answer would be the very traffic the limit is for.
                    self.counters.add(DropCause::RateLimited);
                    return;
                }
                // The outbox is emptied by whoever sends it (the transport takes it all): an
                // empty one holds no answers.
                if self.outbox.is_empty() {
                    self.answers_waiting = 0;
                }
                if self.answers_waiting >= ANSWERS_WAITING_BYTES {
                    // As over the rate: the requester retries (N2) once this turn's answers
                    // have gone.
                    self.counters.add(DropCause::RateLimited);
                    return;
                }
                if let Some(result) = self.answered.get(&(from, c.id)) {
                    self.answers_waiting += answer_bytes(result);
                    result.clone()
                } else {
                    let result = self.unjournaled(|core| core.apply_control(from, body));
                    if let Err(e) = &result {
                        let refused = matches!(e, Error::NotAllowed { .. });
                        self.counters.add(if refused { DropCause::NotAllowed } else { DropCause::BadRequest });
                    }
                    let result = result.map_err(|e| e.to_string());
                    let bytes = answer_bytes(&result);
                    while self.answered_order.len() >= ANSWERED_MAX
                        || (self.answered_bytes + bytes > ANSWERED_BYTES && !self.answered_order.is_empty())
                    {
                        if let Some(old) = self.answered_order.pop_front() {
                            if let Some(gone) = self.answered.remove(&old) {
                                self.answered_bytes -= answer_bytes(&gone);
                            }
                        }
                    }
                    self.answered.insert((from, c.id), result.clone());
                    self.answered_order.push_back((from, c.id));
                    self.answered_bytes += bytes;
                    self.answers_waiting += bytes;
                    result
                }
            }
        };
        self.outbox.push_back(Outgoing {
            to: Destination::Node(from),
            message: Message::Control(ControlMessage { id: c.id, body: ControlBody::Reply { result } }),
        });
    }

    fn apply_control(&mut self, from: NodeId, body: ControlBody) -> Result<ReplyBody, Error> {
        if body.changes_structure() && !self.access.structure.admits(from) {
            return Err(Error::NotAllowed {
                what: format!("{from} may not change this node's structure (its access rules)"),
            });
        }
        if matches!(body, ControlBody::Connect { .. } | ControlBody::Disconnect { .. }) {
            if let Some((coordinator, txn)) = self.transaction_held() {
                // The reservation a PREPARE holds (R9).
                return Err(Error::Transaction {
                    what: format!("busy: transaction {txn} of {coordinator} is held here"),
                });
            }
        }
        match body {
            body @ (ControlBody::Prepare { .. } | ControlBody::Commit { .. } | ControlBody::Abort { .. }) => {
                self.apply_transaction(from, body)
            }
            ControlBody::Connect { source_behavior, source_port, destination, kind, priority } => {
                if matches!(destination, Endpoint::Local { .. }) {
                    return Err(Error::NotLocal {
                        what: "a requested connection's destination must name its node".into(),
                    });
                }
                if kind.period().is_some_and(|p| p > self.limits.max_remote_period) {
                    return Err(Error::NotAllowed {
                        what: format!(
                            "a {} period over this node's limit of {} for requests",
                            kind.name(),
                            self.limits.max_remote_period
                        ),
                    });
                }
                let mine = self.conns.iter().flatten().filter(|c| c.requested_by == Some(from)).count();
                let all = self.conns.iter().flatten().filter(|c| c.requested_by.is_some()).count();
                if mine >= self.limits.remote_connections_per_node || all >= self.limits.remote_connections {
                    return Err(Error::NotAllowed {
                        what: format!(
                            "a new connection: this node holds {all} made by request ({mine} by {from}); its limits \
                             are {} in all and {} per node",
                            self.limits.remote_connections, self.limits.remote_connections_per_node
                        ),
                    });
                }
                let source = Endpoint::Local { behavior: source_behavior, port: source_port };
                let id = self.connect(&source, &destination, kind, ConnectOptions { priority })?;
                if let Some(c) = self.conn_ids.get(&id.0).and_then(|&c| self.conns[c as usize].as_mut()) {
                    c.requested_by = Some(from);
                }
                Ok(ReplyBody::Connection(id))
            }
            ControlBody::Disconnect { conn } => self.disconnect(conn).map(|()| ReplyBody::Connection(conn)),
            ControlBody::List => Ok(ReplyBody::Node(Box::new(self.report()))),
            ControlBody::Why { behavior, port } => self.why(&behavior, &port).map(|r| ReplyBody::Port(Box::new(r))),
            ControlBody::Read { behavior, port } => {
                let r = self.port(&behavior, &port)?;
                self.read(r).map(ReplyBody::Value)
            }
            ControlBody::Reply { .. } => unreachable!("replies are handled before apply_control"),
        }
    }

    /// Ask `node` to describe itself (LIST), explain a port (WHY) or read one (READ); the
    /// answer arrives in [`NodeCore::request_status`].
    pub fn request(&mut self, node: NodeId, body: ControlBody) -> Result<RequestId, Error> {
        match body {
            ControlBody::Reply { .. } => Err(Error::NotLocal { what: "a reply is not a request".into() }),
            body => Ok(self.send_request(node, body)),
        }
    }

    /// The next message to send, oldest first.
    pub fn pop_outgoing(&mut self) -> Option<Outgoing> {
        self.outbox.pop_front()
    }

    /// The messages waiting to be sent, oldest first, for a runtime that sends them where
    /// they lie and then empties the queue, rather than taking them out one by one with
    /// [`NodeCore::pop_outgoing`] (each a move of the whole message). Sending them in this
    /// order, each once, is the caller's part.
    pub fn outgoing_mut(&mut self) -> &mut VecDeque<Outgoing> {
        &mut self.outbox
    }

    /// How many messages wait to be sent.
    pub fn outgoing_len(&self) -> usize {
        self.outbox.len()
    }

    // ----- scheduling (rules S7, S8) -------------------------------------------------------

    /// Run everything due at `now`: monostable edges, periodic processes (late ones skip
    /// missed activations and count them), triggered processes (each at most once per poll,
    /// so a process that re-triggers itself cannot spin), and control retries. Returns when
    /// the next call is due (`poll_at`).
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        self.run_due(now);
        self.poll_at()
    }

    /// [`NodeCore::poll`] without working out when the next call is due: for a caller that
    /// calls again at its own pace whatever the answer (a simulator's fixed tick), which saves
    /// the walk over every process and request that [`NodeCore::poll_at`] makes.
    pub fn run_due(&mut self, now: Instant) {
        self.advance(now);
        self.journal(|| Event::Poll);
        let now = self.now;
        self.poll_transaction();
        self.poll_epoch += 1;
        if now >= self.deferred_due {
            self.pending.extend(self.deferred.drain(..));
            self.deferred_due = Instant::MAX;
        }
        // Monostable falling edges: none before the schedule's bound on the earliest end.
        if now >= self.schedule.mono_edge {
            let mut edge = Instant::MAX;
            for b in 0..self.behaviors.len() as u32 {
                let Some(beh) = self.behaviors[b as usize].as_mut() else { continue };
                let id = beh.id;
                for m in &mut beh.monos {
                    if m.high && now >= m.end {
                        m.high = false;
                        for &pi in &m.watchers {
                            queue(&mut self.pending, &mut beh.processes[usize::from(pi)], b, id, pi);
                        }
                    }
                    if m.high {
                        edge = edge.min(m.end);
                    }
                }
            }
            self.schedule.mono_edge = edge;
        }
        self.run_triggered();
        // Periodic processes, in (behavior slot, declaration) order, as a walk over the slots
        // this poll started with would find them (crate::schedule): a process that changed
        // the structure makes the walk find its place again after the process just run.
        let slots = self.behaviors.len() as u32;
        let mut generation = self.schedule.generation;
        let mut i = 0;
        while let Some(entry) = self.schedule.periodic.get_mut(i) {
            let (b, pi) = (entry.b, entry.pi);
            if b >= slots {
                break;
            }
            i += 1;
            if entry.next_due > now {
                continue;
            }
            let period = entry.period;
            let mut next = entry.next_due + period;
            let missed = if next <= now { (now - next).as_nanos() / period.as_nanos() + 1 } else { 0 };
            next += period * missed;
            entry.next_due = next;
            entry.runs += 1;
            // What the run needs is in the entry: the process's state is touched only to count
            // skipped activations (and, in `run_body`, on a node that keeps change outcomes).
            let body = Arc::as_ptr(&entry.body);
            if missed > 0 {
                if let Some(beh) = self.behaviors[b as usize].as_mut() {
                    beh.processes[usize::from(pi)].overruns += missed;
                }
            }
            self.run_body(b, pi, body);
            self.run_triggered();
            if self.schedule.generation != generation {
                generation = self.schedule.generation;
                i = self.schedule.after(b, pi);
            }
        }
        if !self.deferred.is_empty() && self.deferred_due == Instant::MAX {
            self.deferred_due = now + RETRIGGER_INTERVAL;
        }
        self.flush_requests();
    }

    /// Run the processes triggered so far (most calls find none: checked here, inlined; a
    /// plain `#[inline]` was left out of `run_due` when the receive path changed).
    #[inline(always)]
    fn run_triggered(&mut self) {
        if !self.pending.is_empty() {
            self.run_pending();
        }
    }

    fn run_pending(&mut self) {
        let epoch = self.poll_epoch;
        while let Some((b, id, pi)) = self.pending.pop_front() {
            let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut).filter(|x| x.id == id) else {
                continue;
            };
            let proc_ = &mut beh.processes[usize::from(pi)];
            if proc_.ran_in_poll == epoch {
                proc_.retriggers += 1;
                if proc_.retriggers == 1 {
                    let warning = format!(
                        "process {}.{} triggers itself (by its own write or through a cycle of processes); \
                         it now runs at most once per {RETRIGGER_INTERVAL}",
                        beh.name, proc_.spec.name
                    );
                    self.warnings.push(warning);
                }
                self.deferred.push((b, id, pi));
                continue;
            }
            proc_.pending = false;
            proc_.ran_in_poll = epoch;
            self.run_process(b, pi);
        }
    }

    /// Run a triggered process (a periodic one's run count and body are in the schedule).
    fn run_process(&mut self, b: u32, pi: u16) {
        let Some(beh) = self.behavior_mut(b) else { return };
        let proc_ = &mut beh.processes[usize::from(pi)];
        proc_.runs += 1;
        let body = Arc::as_ptr(&proc_.spec.body);
        self.run_body(b, pi, body);
    }

    /// Run process `pi` of the behavior in slot `b`, whose body is `body`, and apply the
    /// structure changes it asked for.
    ///
    /// `body` points into the `ProcessFn` (an `Arc`) of that process's state or schedule
    /// entry, borrowed, not cloned: a clone and its drop were two locked instructions a run,
    /// each a full barrier that waited for the cold node's outstanding misses (most of
    /// `run_due`'s own samples). Callers pass `Arc::as_ptr` of a live `ProcessFn` of process
    /// `pi` of slot `b`.
    #[inline(always)]
    fn run_body(&mut self, b: u32, pi: u16, body: *const (dyn Fn(&mut Ctx<'_>) + Send + Sync)) {
        // Only this process's own activations set its outcomes, and they do not nest.
        let had_outcomes = self.outcomes_kept
            && self.behavior(b).is_some_and(|beh| !beh.processes[usize::from(pi)].outcomes.is_empty());
        if let Some(j) = self.journal.as_mut() {
            let beh = self.behaviors[b as usize].as_ref().expect("running behavior exists");
            let spec = &beh.processes[usize::from(pi)].spec;
            let native = beh.ble.is_some() && spec.name == crate::ble::BLE_SELECT;
            j.push(self.now, Event::Run { behavior: beh.name.clone(), process: spec.name.clone(), native });
        }
        // The borrowed body's safety below rests on bodies never nesting: nothing a `Ctx` can
        // reach runs another process.
        debug_assert_eq!(self.running, Running::Idle, "process bodies do not nest");
        let mut ctx = Ctx { core: self, b, pi, changes: Vec::new() };
        ctx.core.running = Running::Body;
        // SAFETY: `body` came from `Arc::as_ptr` of a `ProcessFn` held by the process's state
        // (and, for a periodic process, the same `Arc` by its schedule entry), so it is
        // valid while that state lives. The state lives until this call returns: the only
        // place a process state is dropped is `remove_behavior` (a behavior's processes are
        // never removed or replaced one by one, and the node cannot be dropped while `ctx`
        // borrows it), and while `running` is not `Idle` that parks the removed behavior in
        // `parked` instead of dropping it, until the body has returned (below). A body asks
        // for structure changes through `Ctx::change` (R1), applied only after it returns,
        // so today nothing reaches `remove_behavior` during a run at all; the parking keeps
        // this sound should that change. Moving the `Arc` (a schedule `Vec` that grows) does
        // not move its pointee. The pointee is only ever shared (`Fn`), so the `&mut` the
        // body receives does not alias it.
        unsafe { (*body)(&mut ctx) };
        if ctx.core.running == Running::Parked {
            ctx.core.parked.clear();
        }
        ctx.core.running = Running::Idle;
        if ctx.changes.is_empty() && !had_outcomes {
            return;
        }
        let changes = std::mem::take(&mut ctx.changes);
        self.apply_process_changes(b, pi, changes);
    }

    /// Apply the structure changes an activation of process `pi` of behavior `b` asked for,
    /// in order, now that it has returned (R1), and keep their outcomes for its next
    /// activation (R2). They were journaled as the process's effects when asked for, so they
    /// are applied unjournaled (a replay repeats them through its player).
    fn apply_process_changes(&mut self, b: u32, pi: u16, changes: Vec<Change>) {
        let id = self.behavior(b).map(|beh| beh.id);
        let had_outcomes = self.behavior(b).is_some_and(|beh| !beh.processes[usize::from(pi)].outcomes.is_empty());
        if changes.is_empty() && !had_outcomes {
            return;
        }
        let outcomes: Vec<ChangeOutcome> = changes
            .into_iter()
            .map(|change| {
                let result = self.unjournaled(|core| core.apply_change(&change));
                ChangeOutcome { change, result }
            })
            .collect();
        // A behavior that removed itself has no next activation to read them (R3).
        self.outcomes_kept |= !outcomes.is_empty();
        if let Some(beh) = self.behavior_mut(b).filter(|beh| Some(beh.id) == id) {
            beh.processes[usize::from(pi)].outcomes = outcomes;
        }
    }

    /// Debug builds: the schedule lists exactly the node's periodic processes, in run order.
    fn debug_check_schedule(&self) {
        if cfg!(debug_assertions) {
            let listed: Vec<(u32, u16)> = self.schedule.periodic.iter().map(|e| (e.b, e.pi)).collect();
            let live: Vec<(u32, u16)> = (0..self.behaviors.len() as u32)
                .filter_map(|b| Some((b, self.behaviors[b as usize].as_ref()?)))
                .flat_map(|(b, beh)| {
                    beh.processes.iter().enumerate().filter(|(_, p)| p.is_periodic()).map(move |(pi, _)| (b, pi as u16))
                })
                .collect();
            assert_eq!(listed, live, "the schedule does not list the node's periodic processes");
        }
    }

    /// The schedule's entry for process `pi` of the behavior in slot `b` (its next due time
    /// and run count); `None` for a process that is not periodic (or not there).
    pub(crate) fn periodic(&self, b: u32, pi: u16) -> Option<&Periodic> {
        self.schedule.entry(b, pi)
    }

    /// When `poll` next has work: the earliest periodic activation, monostable edge or
    /// control retry; `now` if triggered processes wait; `None` if nothing is scheduled.
    pub fn poll_at(&self) -> Option<Instant> {
        if !self.pending.is_empty() {
            return Some(self.now);
        }
        let mut at: Option<Instant> = None;
        let mut consider = |t: Instant| at = Some(at.map_or(t, |a| a.min(t)));
        if !self.deferred.is_empty() {
            consider(self.deferred_due);
        }
        for p in &self.schedule.periodic {
            consider(p.next_due);
        }
        for beh in self.behaviors.iter().flatten() {
            for m in &beh.monos {
                if m.high && !m.watchers.is_empty() {
                    consider(m.end);
                }
            }
        }
        for r in &self.requests {
            if matches!(r.status, RequestStatus::Pending { .. }) {
                consider(r.next_send);
            }
        }
        if let Some(t) = self.transaction_due() {
            consider(t);
        }
        at
    }

    // ----- registers from outside ----------------------------------------------------------

    /// The port's value, or its default while empty (aggregating ports) — see `get` for
    /// freshness. Answers at the latest time the node was told ([`NodeCore::now`]); use
    /// [`NodeCore::read_at`] to ask about a later instant without polling (D8.2).
    #[inline]
    pub fn read(&self, port: PortRef) -> Result<Value, Error> {
        self.read_at(self.now, port)
    }

    /// [`NodeCore::read`] as of `now` (never before the node's own time: time does not go
    /// backwards). Windows and lifespans that ended by `now` count as ended.
    #[inline]
    pub fn read_at(&self, now: Instant, port: PortRef) -> Result<Value, Error> {
        let now = now.max(self.now);
        self.resolve(port).map(|ps| current(&ps.cell, now).clone())
    }

    /// What `f` makes of the value [`NodeCore::read`] would return, without copying it out:
    /// e.g. `read_with(p, Value::as_float)` for a body's motor command each tick.
    #[inline]
    pub fn read_with<R>(&self, port: PortRef, f: impl FnOnce(&Value) -> R) -> Result<R, Error> {
        self.resolve(port).map(|ps| f(current(&ps.cell, self.now)))
    }

    /// The port's value if fresh (rule S4), else `None`.
    #[inline]
    pub fn get(&self, port: PortRef) -> Result<Option<Value>, Error> {
        self.get_at(self.now, port)
    }

    /// [`NodeCore::get`] as of `now` (see [`NodeCore::read_at`]).
    #[inline]
    pub fn get_at(&self, now: Instant, port: PortRef) -> Result<Option<Value>, Error> {
        let now = now.max(self.now);
        self.resolve(port).map(|ps| ps.cell.get(now).cloned())
    }

    /// Whether the port holds a fresh value (rule S4) at [`NodeCore::now`]; errors for a handle
    /// to a removed behavior.
    #[inline]
    pub fn fresh(&self, port: PortRef) -> Result<bool, Error> {
        self.fresh_at(self.now, port)
    }

    /// [`NodeCore::fresh`] as of `now` (see [`NodeCore::read_at`]).
    #[inline]
    pub fn fresh_at(&self, now: Instant, port: PortRef) -> Result<bool, Error> {
        let now = now.max(self.now);
        self.resolve(port).map(|ps| ps.cell.fresh(now))
    }

    /// When the port last accepted a value (refused writes do not count), if ever — e.g. to
    /// tell which subsumption layer is driving without allocating a report.
    #[inline]
    pub fn last_accepted(&self, port: PortRef) -> Result<Option<Instant>, Error> {
        self.resolve(port).map(|ps| ps.cell.last_accepted())
    }

    /// Whether monostable `mono` of `behavior` is high (rule S2), as of `now` (see
    /// [`NodeCore::read_at`]): true until the end its triggers set, whether or not a poll has
    /// seen the fall yet.
    pub fn monostable_at(&self, now: Instant, behavior: &str, mono: &str) -> Result<bool, Error> {
        let now = now.max(self.now);
        let b = self.behavior_index(behavior)?;
        let beh = self.behavior(b).expect("indexed behavior exists");
        let m = beh
            .class
            .mono_handle(mono)
            .ok_or_else(|| Error::UnknownPort { behavior: behavior.to_owned(), port: mono.to_owned() })?;
        Ok(now < beh.monos[usize::from(m.0)].end)
    }

    /// Empty an aggregating port (a Normal port returns to its default).
    pub fn reset(&mut self, port: PortRef) -> Result<(), Error> {
        self.resolve(port)?;
        if self.journal.is_some() {
            let beh = self.behavior(port.b).expect("resolved");
            let (behavior, name) = (beh.name.clone(), beh.class.ports[usize::from(port.port.0)].name.clone());
            self.journal(|| Event::Reset { behavior, port: name });
        }
        self.behavior_mut(port.b).expect("resolved").ports[usize::from(port.port.0)].cell.reset();
        Ok(())
    }

    /// Trigger monostable `mono` of `behavior` for `period` (rule S2).
    pub fn trigger(&mut self, now: Instant, behavior: &str, mono: &str, period: Duration) -> Result<(), Error> {
        self.advance(now);
        self.journal(|| Event::Trigger { behavior: behavior.to_owned(), mono: mono.to_owned(), period });
        let b = self.behavior_index(behavior)?;
        let m = self
            .behavior(b)
            .and_then(|beh| beh.class.mono_handle(mono))
            .ok_or_else(|| Error::UnknownPort { behavior: behavior.to_owned(), port: mono.to_owned() })?;
        self.trigger_mono(b, m, period);
        Ok(())
    }

    pub(crate) fn trigger_mono(&mut self, b: u32, m: Mono, period: Duration) {
        let now = self.now;
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else { return };
        let id = beh.id;
        let Some(mono) = beh.monos.get_mut(usize::from(m.0)) else { return };
        let rising = now >= mono.end;
        mono.end = mono.end.max(now + period);
        if rising && mono.end > now {
            mono.high = true;
            for &pi in &mono.watchers {
                queue(&mut self.pending, &mut beh.processes[usize::from(pi)], b, id, pi);
            }
        }
        if mono.high {
            self.schedule.mono_high_until(mono.end);
        }
    }

    pub(crate) fn set_slot(&mut self, b: u32, s: Slot, value: Value) -> Result<(), Error> {
        let Some(beh) = self.behavior_mut(b) else {
            return Err(Error::UnknownBehavior { behavior: format!("#{b}") });
        };
        let Some(slot) = beh.slots.get_mut(usize::from(s.0)) else {
            return Err(Error::UnknownPort { behavior: beh.name.to_string(), port: format!("slot #{}", s.0) });
        };
        if slot.ty() != value.ty() {
            return Err(Error::TypeMismatch {
                what: format!("slot {}.{}", beh.name, beh.class.slots[usize::from(s.0)].name),
                expected: slot.ty(),
                found: value.ty(),
            });
        }
        // Scalars are stored field by field: moving the whole enum in costs a store-forwarding
        // stall (see `port::assign`).
        match (slot, value) {
            (Value::Int(d), Value::Int(x)) => *d = x,
            (Value::Float(d), Value::Float(x)) => *d = x,
            (Value::Bool(d), Value::Bool(x)) => *d = x,
            (slot, value) => *slot = value,
        }
        Ok(())
    }

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

    pub(crate) fn connection_infos(&self) -> Vec<ConnectionInfo> {
        let mut v: Vec<ConnectionInfo> = self
            .conns
            .iter()
            .flatten()
            .map(|c| ConnectionInfo {
                id: ConnectionId(c.id),
                source: c.source.clone(),
                destination: c.destination.clone(),
                kind: c.kind,
                priority: c.priority,
                sent: c.seq - c.seq_start,
                requested_by: c.requested_by,
            })
            .collect();
        v.sort_by_key(|c| c.id);
        v
    }

    /// Journal a write from outside (kept out of line: `write` is the hot path).
    #[cold]
    #[inline(never)]
    fn journal_write(&mut self, port: PortRef, value: &Value) {
        let Some(beh) = self.behavior(port.b) else { return };
        let (behavior, class) = (beh.name.clone(), beh.class.clone());
        let value = value.clone();
        self.journal(|| Event::Write { behavior, class, port: port.port.0, value });
    }

    /// Run `f` with the journal set aside: what it does is the consequence of a call already
    /// journaled, which a replay repeats (crate::journal).
    pub(crate) fn unjournaled<T>(&mut self, f: impl FnOnce(&mut NodeCore) -> T) -> T {
        let journal = self.journal.take();
        let out = f(self);
        self.journal = journal;
        out
    }

    pub(crate) fn conn_index(&self, id: ConnectionId) -> Option<&Conn> {
        self.conn_ids.get(&id.0).and_then(|&c| self.conns[c as usize].as_ref())
    }
}

/// Journal a value port `p` of behavior `behavior` accepted (out of line: propagation is the
/// hot path, and with the journal off only the check that calls this remains).
#[cold]
#[inline(never)]
fn journal_accepted(
    j: &mut Journal,
    now: Instant,
    behavior: &Arc<str>,
    class: &Arc<BehaviorClass>,
    p: u16,
    value: &Value,
) {
    let event = Event::Accepted { behavior: behavior.clone(), class: class.clone(), port: p, value: value.clone() };
    j.push(now, event);
}

/// The error for a handle whose behavior was removed (or whose slot was reused).
#[cold]
#[inline(never)]
fn stale_handle(r: PortRef) -> Error {
    Error::UnknownBehavior { behavior: format!("(removed behavior #{})", r.id) }
}

/// The readable value of a cell at `now`: its value, or its default once it released it.
/// Inlined with the readers; a Normal port (never empty) is answered without a call.
#[inline]
pub(crate) fn current(cell: &PortCell, now: Instant) -> &Value {
    if cell.kind.is_aggregating() && cell.is_empty(now) {
        &cell.default
    } else {
        &cell.value
    }
}

/// A cheap upper estimate of what a remembered answer holds in memory, for the byte bound of
/// the answer memory (it need not be exact, only grow with the answer).
fn answer_bytes(result: &Result<ReplyBody, String>) -> usize {
    const BASE: usize = 64;
    let value = |v: &Value| match v {
        Value::Text(t) => t.len(),
        Value::Bytes(b) => b.len(),
        Value::Vector(x) => x.len() * 8,
        _ => 8,
    };
    BASE + match result {
        Err(e) => e.len(),
        Ok(ReplyBody::Connection(_)) => 8,
        Ok(ReplyBody::Value(v)) => value(v),
        Ok(ReplyBody::OtherReport(text)) => text.len(),
        Ok(ReplyBody::Port(r)) => {
            512 + r.windows.len() * 64 + (r.incoming.len() + r.outgoing.len()) * 256 + r.triggers.len() * 128
        }
        Ok(ReplyBody::Node(r)) => {
            let behaviors: usize = r
                .behaviors
                .iter()
                .map(|b| {
                    256 + b.ports.iter().map(|p| 96 + p.name.len() + value(&p.value)).sum::<usize>()
                        + b.slots.iter().map(|(n, v)| 64 + n.len() + value(v)).sum::<usize>()
                        + b.monostables.len() * 64
                        + b.processes.len() * 128
                })
                .sum();
            512 + behaviors
                + r.connections.len() * 256
                + r.transport.len() * 64
                + r.warnings.iter().map(|w| 32 + w.len()).sum::<usize>()
        }
    }
}

/// Whether `m` carries the very name strings `incoming`'s port was resolved from (address
/// comparison; those strings are held in `NodeCore::held_names`).
fn same_names(incoming: &Incoming, m: &PortMessage) -> bool {
    incoming.behavior == name_address(&m.behavior) && incoming.port == name_address(&m.port)
}

/// The address of a name string, which identifies it while it lives (never 0).
fn name_address(name: &Arc<str>) -> usize {
    Arc::as_ptr(name).cast::<u8>() as usize
}

fn queue(pending: &mut VecDeque<(u32, u64, u16)>, proc_: &mut ProcState, b: u32, id: u64, pi: u16) {
    if !proc_.pending {
        proc_.pending = true;
        pending.push_back((b, id, pi));
    }
}

fn attach_trigger(ports: &mut [PortState], monos: &mut [MonoState], trigger: Trigger, ix: u16) {
    match trigger {
        Trigger::OnWrite(Port(p)) => {
            let port = &mut ports[usize::from(p)];
            port.add_trigger(ix);
            port.refresh_plain();
        }
        Trigger::OnMonostable(Mono(m)) => monos[usize::from(m)].watchers.push(ix),
        Trigger::Periodic(_) => {}
    }
}

fn check_name(behavior: &str, port: &str) -> Result<(), Error> {
    if behavior.is_empty() {
        return Err(Error::EmptyName { what: "behavior" });
    }
    if port.is_empty() {
        return Err(Error::EmptyName { what: "port" });
    }
    Ok(())
}
