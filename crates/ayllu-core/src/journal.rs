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

/// The journal's buffer (see the module docs).
#[derive(Debug)]
pub(crate) struct Journal {
    entries: Vec<Entry>,
    capacity: usize,
    lost: u64,
}

impl Journal {
    #[inline]
    pub(crate) fn push(&mut self, at: Instant, event: Event) {
        if self.entries.len() >= self.capacity {
            self.lost += 1;
            return;
        }
        if self.lost > 0 {
            self.entries.push(Entry { at, event: Event::Gap { lost: self.lost } });
            self.lost = 0;
            if self.entries.len() >= self.capacity {
                self.lost = 1;
                return;
            }
        }
        self.entries.push(Entry { at, event });
    }
}

impl NodeCore {
    /// Start journaling everything that enters this core (see the module docs), keeping at
    /// most `capacity` entries until [`NodeCore::take_journal`] takes them. Replaces a
    /// journal already running (its entries are dropped).
    pub fn start_journal(&mut self, capacity: usize) {
        self.journal = Some(Box::new(Journal { entries: Vec::new(), capacity: capacity.max(1), lost: 0 }));
    }

    /// Stop journaling; the entries not taken yet are returned.
    pub fn stop_journal(&mut self) -> Vec<Entry> {
        self.journal.take().map(|j| j.entries).unwrap_or_default()
    }

    /// Whether a journal is running.
    pub fn journaling(&self) -> bool {
        self.journal.is_some()
    }

    /// Move the entries journaled since the last call into `out` (appended, oldest first).
    /// An empty `out` is swapped with the journal's buffer rather than filled, so a caller
    /// that hands back emptied buffers moves no entry at all.
    pub fn take_journal(&mut self, out: &mut Vec<Entry>) {
        if let Some(j) = self.journal.as_mut() {
            if out.is_empty() {
                std::mem::swap(out, &mut j.entries);
            } else {
                out.append(&mut j.entries);
            }
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
