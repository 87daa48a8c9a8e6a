//! The journal: an optional tap on everything that enters a node's core and on every value its
//! ports accept — what a flight recorder writes and a replay feeds back (spec/flight-recorder.md).
//!
//! Why it is enough: the core is deterministic (module docs of [`crate::node`]), so the calls
//! made into it (structure changes, writes from outside, messages received, polls with their
//! times) determine everything it does. Processes are the exception: their code belongs to the
//! application (a C or Python function, maybe reading hardware), so each activation is
//! journaled with what it did through its [`crate::Ctx`] ([`Event::Run`] followed by its
//! effects), and a replay stands in for the process with a player of those effects.
//!
//! What it promises:
//! * Off by default, and then free: every tap is one `Option` check on the node.
//! * Bounded: at most the capacity given to [`NodeCore::start_journal`] entries wait to be
//!   taken; past it entries are dropped and counted, and the next entry taken is an
//!   [`Event::Gap`] saying how many were lost (a replay stops there).
//! * Only the outermost call is journaled: a structure change made inside another call (the
//!   connections `ble_join` makes, those `remove` drops, a CONNECT applied from a request) is
//!   the consequence of that call, which a replay repeats.
//! * Entries carry the node's time when they were made (after the call moved it), in the
//!   order the core made them.

use std::borrow::Cow;
use std::sync::Arc;

use crate::access::{Access, Limits};
use crate::address::{ConnectionId, Endpoint, NodeId};
use crate::behavior::{BehaviorClass, Trigger};
use crate::ble::BleConfig;
use crate::change::Change;
use crate::connection::ConnectionKind;
use crate::message::{ControlBody, Message};
use crate::node::NodeCore;
use crate::time::{Duration, Instant};
use crate::value::Value;

/// One journaled event and the node time it happened at.
///
/// 72 bytes: the variants whose fields are large and rare (a connection's endpoints, a BLE
/// configuration, a message, a request's body, a change) hold them boxed, so that the entries a
/// busy node makes all the time (writes, accepted values) are moved with a few register moves
/// where 152-byte entries were copied by `memmove` three times each (half the journal's cost,
/// docs/performance.md).
#[derive(Clone, Debug)]
pub struct Entry {
    /// The node's time once the call had moved it ([`NodeCore::now`]).
    pub at: Instant,
    /// What happened.
    pub event: Event,
}

/// What entered the core, what a process did, or what a port accepted.
#[derive(Clone, Debug)]
pub enum Event {
    /// [`NodeCore::define`]: the class as declared (its process bodies are not replayable).
    Define(Arc<BehaviorClass>),
    /// [`NodeCore::create`].
    Create {
        /// The class.
        class: String,
        /// The new behavior's name.
        name: String,
    },
    /// [`NodeCore::remove`].
    Remove {
        /// The behavior removed.
        name: String,
    },
    /// [`NodeCore::add_process`] (its body is not replayable).
    AddProcess {
        /// The behavior it was added to.
        behavior: String,
        /// The process's name.
        name: String,
        /// When it runs.
        trigger: Trigger,
    },
    /// [`NodeCore::connect`].
    Connect {
        /// The source port.
        source: Box<Endpoint>,
        /// The destination.
        destination: Box<Endpoint>,
        /// The connection's kind.
        kind: ConnectionKind,
        /// Its priority.
        priority: i32,
    },
    /// [`NodeCore::disconnect`].
    Disconnect {
        /// The connection removed.
        conn: ConnectionId,
    },
    /// [`NodeCore::node_lost`].
    NodeLost {
        /// The node the transport gave up on.
        node: NodeId,
    },
    /// [`NodeCore::set_access`].
    SetAccess(Access),
    /// [`NodeCore::set_limits`].
    SetLimits(Limits),
    /// [`NodeCore::join`].
    Join(String),
    /// [`NodeCore::leave`].
    Leave(String),
    /// [`NodeCore::ble_join`].
    BleJoin {
        /// The member behavior.
        behavior: String,
        /// Its configuration.
        config: Box<BleConfig>,
    },
    /// [`NodeCore::set_sequence_base`].
    SequenceBase(u64),
    /// [`NodeCore::warn`].
    Warn(String),
    /// [`NodeCore::write`] (from outside the node's processes).
    Write {
        /// The behavior written.
        behavior: Arc<str>,
        /// Its class (for the port's name: the journal copies no strings on a write).
        class: Arc<BehaviorClass>,
        /// The port's handle.
        port: u16,
        /// The value.
        value: Value,
    },
    /// [`NodeCore::trigger`] (from outside the node's processes).
    Trigger {
        /// The behavior.
        behavior: String,
        /// The monostable.
        mono: String,
        /// For how long.
        period: Duration,
    },
    /// [`NodeCore::reset`] (from outside the node's processes).
    Reset {
        /// The behavior.
        behavior: Arc<str>,
        /// The port.
        port: String,
    },
    /// [`NodeCore::receive`]: a message from another node.
    Receive {
        /// The sender.
        from: NodeId,
        /// The message as it arrived.
        message: Box<Message>,
    },
    /// [`NodeCore::request`], [`NodeCore::request_connect`], [`NodeCore::request_disconnect`].
    Request {
        /// The node asked.
        to: NodeId,
        /// What was asked.
        body: Box<ControlBody>,
    },
    /// [`NodeCore::poll`].
    Poll,
    /// A process activation began; its effects follow, until the next event that is not one.
    Run {
        /// The behavior.
        behavior: Arc<str>,
        /// The process's name.
        process: String,
        /// A process the core itself provides (BLE's select): a replay runs it, not a player.
        native: bool,
    },
    /// Effect of the running process: [`crate::Ctx::write`] of port number `port`.
    ProcessWrite {
        /// The port's handle.
        port: u16,
        /// The value.
        value: Value,
    },
    /// Effect of the running process: [`crate::Ctx::set_slot`].
    ProcessSetSlot {
        /// The slot's handle.
        slot: u16,
        /// The value.
        value: Value,
    },
    /// Effect of the running process: [`crate::Ctx::trigger`].
    ProcessTrigger {
        /// The monostable's handle.
        mono: u16,
        /// For how long.
        period: Duration,
    },
    /// Effect of the running process: [`crate::Ctx::reset`].
    ProcessReset {
        /// The port's handle.
        port: u16,
    },
    /// Effect of the running process: a structure change it asked for ([`crate::Ctx::change`]),
    /// applied when it returns.
    ProcessChange(Box<Change>),
    /// Effect of the running process: a control request it sent ([`crate::Ctx::request`]).
    ProcessRequest {
        /// The node asked.
        to: NodeId,
        /// What was asked.
        body: Box<ControlBody>,
    },
    /// A port accepted a value (from a write, a connection or a message).
    Accepted {
        /// The behavior.
        behavior: Arc<str>,
        /// Its class (for the port's name).
        class: Arc<BehaviorClass>,
        /// The port's handle.
        port: u16,
        /// The value stored by the merge.
        value: Value,
    },
    /// This many entries were dropped here because the journal was full.
    Gap {
        /// How many.
        lost: u64,
    },
}

/// What a [`Record`] stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum Kind {
    /// A value a port accepted ([`Event::Accepted`]).
    Accepted,
    /// A write from outside ([`Event::Write`]).
    Write,
    /// A write from outside that its port accepted as written (the plain path's, where the
    /// merge stores the value itself): two entries, [`Event::Write`] then [`Event::Accepted`],
    /// in one record.
    WriteAccepted,
    /// A whole entry, `entries[payload]`.
    Entry,
}

/// How a [`Record`]'s value is held: scalars in `payload` itself, shared values (text, bytes,
/// vectors: an `Arc`) in the batch's `shared`, at index `payload`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum Held {
    Bool,
    Int,
    Float,
    Shared,
}

/// One journaled record, 24 bytes and `Copy`: a value names its behavior by its place in the
/// batch's name table and holds a scalar in place, so that journaling it clones no `Arc` (each
/// clone and drop is an atomic operation), and a batch is emptied without dropping anything
/// but its shared values. Smaller records are fewer cache lines for the node to write and the
/// writer's core to read (docs/performance.md, "Issue 36").
#[derive(Clone, Copy, Debug)]
struct Record {
    at: Instant,
    /// A scalar's bits, or an index into `shared` (values) or `entries` ([`Kind::Entry`]).
    payload: u64,
    /// Index into the batch's `names` (values only).
    name: u32,
    port: u16,
    kind: Kind,
    held: Held,
}

/// What [`NodeCore::take_journal_batch`] takes: the entries journaled, with the names of the
/// behaviors they name, once each. For a consumer on another thread (the flight recorder's
/// writer), which reads them with [`JournalBatch::items`] and never needs the entries as
/// [`Entry`] values, so that taking and dropping a batch touches no reference count per entry.
#[derive(Clone, Debug, Default)]
pub struct JournalBatch {
    records: Vec<Record>,
    /// The entries that are not values, in the order they were journaled.
    entries: Vec<Entry>,
    /// The values that are not scalars.
    shared: Vec<Value>,
    names: Vec<(Arc<str>, Arc<BehaviorClass>)>,
    /// How many entries the records stand for (a [`Kind::WriteAccepted`] record is two).
    len: usize,
    /// The entries the journal lost, as its [`Event::Gap`] entries in this batch say.
    journal_lost: u64,
}

/// One entry of a [`JournalBatch`], borrowed.
#[derive(Clone, Debug)]
pub enum JournalItem<'a> {
    /// [`Event::Write`] or [`Event::Accepted`], by reference.
    Value {
        /// When.
        at: Instant,
        /// A write from outside; else a value a port accepted.
        write: bool,
        /// The behavior.
        behavior: &'a Arc<str>,
        /// Its class (for the port's name).
        class: &'a Arc<BehaviorClass>,
        /// The port's handle.
        port: u16,
        /// The value (a scalar is kept in the batch's record, so it comes out owned).
        value: Cow<'a, Value>,
    },
    /// Any other entry.
    Entry(&'a Entry),
}

impl JournalItem<'_> {
    /// When it happened (node time).
    pub fn at(&self) -> Instant {
        match self {
            JournalItem::Value { at, .. } => *at,
            JournalItem::Entry(e) => e.at,
        }
    }

    /// The entry's event, if it is not a value ([`JournalItem::Value`]).
    pub fn event(&self) -> Option<&Event> {
        match self {
            JournalItem::Value { .. } => None,
            JournalItem::Entry(e) => Some(&e.event),
        }
    }

    /// The entry as an owned [`Entry`] (cloning the names a value entry refers to).
    pub fn to_entry(&self) -> Entry {
        match self {
            JournalItem::Value { at, write, behavior, class, port, value } => {
                let (behavior, class, value, port) =
                    (Arc::clone(behavior), Arc::clone(class), value.clone().into_owned(), *port);
                let event = if *write {
                    Event::Write { behavior, class, port, value }
                } else {
                    Event::Accepted { behavior, class, port, value }
                };
                Entry { at: *at, event }
            }
            JournalItem::Entry(e) => (*e).clone(),
        }
    }
}

impl JournalBatch {
    /// How many entries it holds.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// How many records it can hold before it allocates (a record is one entry or two).
    pub fn capacity(&self) -> usize {
        self.records.capacity()
    }

    /// How many entries the journal lost before or among these, as the gaps it put in the
    /// batch say ([`Event::Gap`]).
    pub fn journal_lost(&self) -> u64 {
        self.journal_lost
    }

    /// Forget every entry, keeping the buffers.
    pub fn clear(&mut self) {
        self.records.clear();
        self.entries.clear();
        self.shared.clear();
        self.names.clear();
        self.len = 0;
        self.journal_lost = 0;
    }

    /// The first entry, borrowed.
    pub fn first(&self) -> Option<JournalItem<'_>> {
        self.items().next()
    }

    /// The entries in order, borrowed.
    pub fn items(&self) -> impl Iterator<Item = JournalItem<'_>> {
        self.records.iter().flat_map(move |r| {
            let (first, second) = self.expand(r);
            first.into_iter().chain(second)
        })
    }

    /// The one or two entries record `r` stands for.
    fn expand<'a>(&'a self, r: &Record) -> (Option<JournalItem<'a>>, Option<JournalItem<'a>>) {
        if r.kind == Kind::Entry {
            return (self.entries.get(r.payload as usize).map(JournalItem::Entry), None);
        }
        let Some((behavior, class)) = self.names.get(r.name as usize) else { return (None, None) };
        let value = match r.held {
            Held::Bool => Cow::Owned(Value::Bool(r.payload != 0)),
            Held::Int => Cow::Owned(Value::Int(r.payload as i64)),
            Held::Float => Cow::Owned(Value::Float(f64::from_bits(r.payload))),
            Held::Shared => match self.shared.get(r.payload as usize) {
                Some(v) => Cow::Borrowed(v),
                None => return (None, None),
            },
        };
        let item = |write: bool, value: Cow<'a, Value>| JournalItem::Value {
            at: r.at,
            write,
            behavior,
            class,
            port: r.port,
            value,
        };
        match r.kind {
            Kind::WriteAccepted => (Some(item(true, value.clone())), Some(item(false, value))),
            kind => (Some(item(kind == Kind::Write, value)), None),
        }
    }

    /// Append `other`'s entries, leaving it empty.
    pub fn append(&mut self, other: &mut JournalBatch) {
        let names = self.names.len() as u32;
        let (entries, shared) = (self.entries.len() as u64, self.shared.len() as u64);
        self.names.append(&mut other.names);
        self.entries.append(&mut other.entries);
        self.shared.append(&mut other.shared);
        self.records.extend(other.records.drain(..).map(|mut r| {
            match (r.kind, r.held) {
                (Kind::Entry, _) => r.payload += entries,
                (_, Held::Shared) => {
                    r.payload += shared;
                    r.name += names;
                }
                _ => r.name += names,
            }
            r
        }));
        self.len += other.len;
        self.journal_lost += other.journal_lost;
        other.clear();
    }
}

/// The journal's buffer (see the module docs).
#[derive(Debug)]
pub(crate) struct Journal {
    batch: JournalBatch,
    /// By behavior slot: the behavior id whose names `batch.names[ix]` holds, in batch
    /// `generation` (a name is added to a batch once, the first time the batch needs it).
    bound: Vec<(u64, u64, u32)>,
    generation: u64,
    capacity: usize,
    lost: u64,
}

impl Journal {
    fn new(capacity: usize) -> Journal {
        Journal { batch: JournalBatch::default(), bound: Vec::new(), generation: 1, capacity: capacity.max(1), lost: 0 }
    }

    /// Whether `n` more entries may be kept (counting the loss if not), after a gap entry if
    /// entries were lost before them.
    #[inline]
    fn room(&mut self, at: Instant, n: usize) -> bool {
        if self.batch.len + n > self.capacity {
            self.lost += n as u64;
            return false;
        }
        if self.lost > 0 {
            let lost = std::mem::take(&mut self.lost);
            self.push_record(at, Event::Gap { lost });
            self.batch.journal_lost += lost;
            if self.batch.len + n > self.capacity {
                self.lost = n as u64;
                return false;
            }
        }
        true
    }

    fn push_record(&mut self, at: Instant, event: Event) {
        let payload = self.batch.entries.len() as u64;
        self.batch.entries.push(Entry { at, event });
        self.batch.records.push(Record { at, payload, name: 0, port: 0, kind: Kind::Entry, held: Held::Int });
        self.batch.len += 1;
    }

    #[inline]
    pub(crate) fn push(&mut self, at: Instant, event: Event) {
        if self.room(at, 1) {
            self.push_record(at, event);
        }
    }

    /// Journal a value port `port` of the behavior in slot `b` (id `id`, named `behavior`, of
    /// class `class`) accepted, or a write from outside into it, or both
    /// ([`JournalValue::WriteAccepted`]).
    #[inline(always)]
    pub(crate) fn push_value(
        &mut self,
        at: Instant,
        what: JournalValue,
        (b, id): (u32, u64),
        (behavior, class): (&Arc<str>, &Arc<BehaviorClass>),
        port: u16,
        value: &Value,
    ) {
        let (kind, n) = match what {
            JournalValue::Accepted => (Kind::Accepted, 1),
            JournalValue::Write => (Kind::Write, 1),
            JournalValue::WriteAccepted if self.batch.len + usize::from(self.lost > 0) + 2 > self.capacity => {
                return self.push_split(at, (b, id), (behavior, class), port, value);
            }
            JournalValue::WriteAccepted => (Kind::WriteAccepted, 2),
        };
        if !self.room(at, n) {
            return;
        }
        let b = b as usize;
        if self.bound.len() <= b {
            self.bound.resize(b + 1, (0, 0, 0));
        }
        let (bound_id, generation, ix) = self.bound[b];
        let name = if bound_id == id && generation == self.generation {
            ix
        } else {
            let ix = self.batch.names.len() as u32;
            self.batch.names.push((behavior.clone(), class.clone()));
            self.bound[b] = (id, self.generation, ix);
            ix
        };
        let (held, payload) = match value {
            Value::Bool(v) => (Held::Bool, u64::from(*v)),
            Value::Int(v) => (Held::Int, *v as u64),
            Value::Float(v) => (Held::Float, v.to_bits()),
            shared => {
                self.batch.shared.push(shared.clone());
                (Held::Shared, self.batch.shared.len() as u64 - 1)
            }
        };
        self.batch.len += n;
        let records = &mut self.batch.records;
        records.reserve(1);
        // Written in place rather than pushed: a pushed record was built on the stack and then
        // copied with wide loads over its narrow stores, a store-forwarding stall that was most
        // of the journal's cost per value (docs/performance.md).
        // SAFETY: `reserve(1)` made room for one more record at index `len`; it is written
        // whole before the length counts it.
        unsafe {
            let len = records.len();
            records.as_mut_ptr().add(len).write(Record { at, payload, name, port, kind, held });
            records.set_len(len + 1);
        }
    }

    /// A write and its acceptance at the capacity's edge (a gap to make first counted): the
    /// journal keeps what the general path would, the write if it fits, then its acceptance is
    /// lost.
    #[cold]
    #[inline(never)]
    fn push_split(
        &mut self,
        at: Instant,
        behavior_at: (u32, u64),
        names: (&Arc<str>, &Arc<BehaviorClass>),
        port: u16,
        value: &Value,
    ) {
        self.push_value(at, JournalValue::Write, behavior_at, names, port, value);
        self.lost += 1;
    }

    /// The batch so far, leaving an empty one (`out`'s buffers, if it was empty).
    fn take(&mut self, out: &mut JournalBatch) {
        if out.is_empty() {
            out.clear();
            if out.records.capacity() == 0 {
                // No emptied batch to swap in (a consumer on another thread has not handed one
                // back): the next batch is made as large as this one at once rather than grown
                // from nothing, a reallocation and a copy at every doubling.
                out.records.reserve(self.batch.records.len());
                out.names.reserve(self.batch.names.len());
            }
            std::mem::swap(out, &mut self.batch);
        } else {
            out.append(&mut self.batch);
        }
        // The next batch has its own name table.
        self.generation += 1;
    }
}

/// Journal a value (out of line: writes and hops are the hot path, and with the journal off
/// only the check that calls this remains on it). Not `#[cold]`: with a recorder always on,
/// this is as hot as the hop, and [`Journal::push_value`] is inlined into it (one call a
/// value, not two).
#[inline(never)]
pub(crate) fn journal_value(
    j: &mut Journal,
    now: Instant,
    what: JournalValue,
    behavior_at: (u32, u64),
    names: (&Arc<str>, &Arc<BehaviorClass>),
    p: u16,
    value: &Value,
) {
    j.push_value(now, what, behavior_at, names, p, value);
}

/// Which entries [`Journal::push_value`] makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum JournalValue {
    /// A value a port accepted.
    Accepted,
    /// A write from outside (its acceptance, if any, journaled on its own).
    Write,
    /// A write from outside and the same value accepted by the port written (the plain path).
    WriteAccepted,
}

impl NodeCore {
    /// Start journaling everything that enters this core (see the module docs), keeping at
    /// most `capacity` entries until [`NodeCore::take_journal`] takes them. Replaces a
    /// journal already running (its entries are dropped).
    pub fn start_journal(&mut self, capacity: usize) {
        self.journal = Some(Box::new(Journal::new(capacity)));
    }

    /// Stop journaling; the entries not taken yet are returned.
    pub fn stop_journal(&mut self) -> Vec<Entry> {
        let mut out = Vec::new();
        self.take_journal(&mut out);
        self.journal = None;
        out
    }

    /// Whether a journal is running.
    pub fn journaling(&self) -> bool {
        self.journal.is_some()
    }

    /// Move the entries journaled since the last call into `out` (appended, oldest first), as
    /// [`Entry`] values. A consumer on another thread takes them as a [`JournalBatch`] instead
    /// ([`NodeCore::take_journal_batch`]): cheaper.
    pub fn take_journal(&mut self, out: &mut Vec<Entry>) {
        let mut batch = JournalBatch::default();
        self.take_journal_batch(&mut batch);
        out.extend(batch.items().map(|item| item.to_entry()));
    }

    /// Move the entries journaled since the last call into `out` (appended, oldest first). An
    /// empty `out` is swapped with the journal's buffer rather than filled, so a caller that
    /// hands back emptied batches moves no entry at all.
    pub fn take_journal_batch(&mut self, out: &mut JournalBatch) {
        if let Some(j) = self.journal.as_mut() {
            j.take(out);
        }
    }

    /// Journal `event` at the node's time, if a journal runs. The closure is not called when
    /// none does, so a tap costs one check.
    #[inline]
    pub(crate) fn journal(&mut self, event: impl FnOnce() -> Event) {
        if let Some(j) = self.journal.as_mut() {
            j.push(self.now, event());
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::*;

    /// A behavior removed and another created in its slot within one batch: each value names
    /// its own behavior (the name table is keyed by slot and behavior id), in batches and as
    /// entries, and the next batch has its own table.
    #[test]
    fn a_slot_reused_within_a_batch_names_each_value_by_its_own_behavior() {
        let mut node = NodeCore::new(NodeId(1));
        for name in ["A", "B"] {
            let mut c = BehaviorClass::new(name);
            c.port(PortSpec::new(&format!("{name}Out"), 0i64)).unwrap();
            node.define(c).unwrap();
        }
        node.start_journal(1_000);
        node.create("A", "a").unwrap();
        let p = node.port("a", "AOut").unwrap();
        node.write(Instant::from_millis(1), p, 1i64).unwrap();
        node.remove("a").unwrap();
        node.create("B", "b").unwrap();
        let q = node.port("b", "BOut").unwrap();
        node.write(Instant::from_millis(2), q, 2i64).unwrap();
        let mut batch = JournalBatch::default();
        node.take_journal_batch(&mut batch);
        let named: Vec<(String, String, bool)> = batch
            .items()
            .filter_map(|item| match item {
                JournalItem::Value { behavior, class, port, write, .. } => {
                    Some((behavior.to_string(), class.ports()[usize::from(port)].name.clone(), write))
                }
                JournalItem::Entry(_) => None,
            })
            .collect();
        let want = |b: &str, p: &str, w: bool| (b.to_owned(), p.to_owned(), w);
        assert_eq!(
            named,
            [want("a", "AOut", true), want("a", "AOut", false), want("b", "BOut", true), want("b", "BOut", false)]
        );
        // The same through entries, and in a batch taken later.
        node.write(Instant::from_millis(3), q, 3i64).unwrap();
        let mut entries = Vec::new();
        node.take_journal(&mut entries);
        let names: Vec<String> = entries
            .iter()
            .filter_map(|e| match &e.event {
                Event::Accepted { behavior, .. } => Some(behavior.to_string()),
                _ => None,
            })
            .collect();
        assert_eq!(names, ["b"]);
    }

    /// Batches appended keep each value (scalars in their records, text in the shared side
    /// vector, whose indices are offset) and each other entry (in the entries side vector).
    #[test]
    fn appended_batches_keep_their_values_and_entries() {
        let mut node = NodeCore::new(NodeId(1));
        let mut c = BehaviorClass::new("C");
        c.port(PortSpec::new("N", 0i64)).unwrap();
        c.port(PortSpec::new("T", "")).unwrap();
        node.define(c).unwrap();
        node.create("C", "x").unwrap();
        node.start_journal(1_000);
        let (n, t) = (node.port("x", "N").unwrap(), node.port("x", "T").unwrap());
        let mut batch = JournalBatch::default();
        for k in 0..3i64 {
            let at = Instant::from_millis(k as u64 + 1);
            node.write(at, t, Value::text(&format!("t{k}"))).unwrap();
            node.write(at, n, k).unwrap();
            node.warn(format!("w{k}"));
            node.take_journal_batch(&mut batch);
        }
        let seen: Vec<String> = batch
            .items()
            .map(|item| match item {
                JournalItem::Value { write, value, .. } => format!("{}{:?}", if write { "W" } else { "A" }, value),
                JournalItem::Entry(e) => format!("{:?}", e.event),
            })
            .collect();
        let mut want = Vec::new();
        for k in 0..3 {
            want.push(format!("W{:?}", Value::text(&format!("t{k}"))));
            want.push(format!("A{:?}", Value::text(&format!("t{k}"))));
            want.push(format!("W{:?}", Value::Int(k)));
            want.push(format!("A{:?}", Value::Int(k)));
            want.push(format!("{:?}", Event::Warn(format!("w{k}"))));
        }
        assert_eq!(seen, want);
        assert_eq!(batch.len(), want.len());
    }

    /// Batches appended keep each value's names (the appended table is offset).
    #[test]
    fn appended_batches_keep_their_names() {
        let mut node = NodeCore::new(NodeId(1));
        let mut c = BehaviorClass::new("C");
        c.port(PortSpec::new("Out", 0i64)).unwrap();
        node.define(c).unwrap();
        node.start_journal(1_000);
        for name in ["x", "y"] {
            node.create("C", name).unwrap();
        }
        let mut batch = JournalBatch::default();
        for (t, name) in [(1, "x"), (2, "y"), (3, "x")] {
            let p = node.port(name, "Out").unwrap();
            node.write(Instant::from_millis(t), p, t as i64).unwrap();
            node.take_journal_batch(&mut batch);
        }
        let written: Vec<String> = batch
            .items()
            .filter_map(|item| match item {
                JournalItem::Value { behavior, write: true, .. } => Some(behavior.to_string()),
                _ => None,
            })
            .collect();
        assert_eq!(written, ["x", "y", "x"]);
    }
}
