//! The node's tables: what it keeps per port, monostable, process, behavior and connection.
//!
//! These are the structures every message, write and poll walks, so their layout is part of
//! the node's performance: the hot ones are `repr(C)` and cache-line aligned, each with a
//! comment saying which fields share which line and why. Reordering a field, or adding one
//! in the wrong place, costs cache misses on every message; measure before changing them.
//! Their methods are the few that only need the table itself (trigger bits, drop counts).

use std::collections::VecDeque;
use std::sync::Arc;

use crate::address::{Endpoint, NodeId};
use crate::arbitration::Windows;
use crate::behavior::{BehaviorClass, ProcessSpec};
use crate::ble::BleState;
use crate::change::ChangeOutcome;
use crate::connection::ConnectionKind;
use crate::counters::{Counters, DropCause};
use crate::message::Destination;
use crate::port::PortCell;
use crate::time::Instant;
use crate::value::Value;

use super::scheduler::queue;

/// Laid out in declaration order (`repr(C)`) on whole cache lines (`align(64)`, 384 bytes):
/// the first line holds what every message into the port reads or writes of the port's own
/// state (the plain flag, the wave mark, the acceptance counts, whether windows are open, the
/// outgoing connections), the second what a merge, an acceptance or a freshness read touches
/// of the cell (its supplier included: `PortCell`'s order), what only a Priority merge, a
/// window's opening or a reset reads of the cell and the triggers after it, and the drop
/// counters (touched only when something is refused) last. A message into a Normal port, or
/// into a Max or Min port that holds a number, accepted or absorbed, then costs two cache
/// lines, as does a plain hop, where the compiler's order and an unaligned 376-byte slot
/// spread them over four or five.
#[derive(Clone)]
#[repr(C, align(64))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(crate) struct PortState {
    /// Whether a value accepted here needs none of the general path's checks (see
    /// [`PortState::is_plain`]); kept up to date wherever the triggers or windows change.
    /// Not in a checkpoint: worked out again from the triggers and windows.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub(crate) plain: bool,
    /// Whether a periodic process of this behavior is guarded by this port (D7.5): an
    /// acceptance here must tell the schedule, whose entries may remember the port as stale
    /// (`crate::schedule`). In the padding after `plain`, in the line every acceptance reads.
    /// A guarded port is not plain, so only the general path (`write_internal`, `deliver_to`)
    /// accepts into it. Never cleared (a behavior's processes go only with it). Not in a
    /// checkpoint: worked out again from the processes' triggers.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub(crate) guarded: bool,
    /// `triggers` as a set of bits (bit `i`: process `i`) in the padding after `plain`, so
    /// that an accepted value finds the processes to queue in this first line instead of the
    /// far one `triggers` lives in (one cache line per accepted message). Exact while every
    /// trigger is a process below 31 added in ascending order (the bits then iterate in the
    /// list's order); otherwise [`TRIGGERS_LISTED`], and the list is read. Not in a
    /// checkpoint: worked out again from the list ([`PortState::set_triggers`]).
    #[cfg_attr(feature = "serde", serde(skip))]
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
    pub(super) fn add_trigger(&mut self, ix: u16) {
        let bits = self.trigger_bits;
        // Ascending below 31: the new bit is above every bit set (and the list bit is not).
        self.trigger_bits = if ix < 31 && bits >> ix == 0 { bits | 1 << ix } else { TRIGGERS_LISTED };
        self.triggers.push(ix);
    }

    /// Work `trigger_bits` and `plain` out again from the triggers and windows (a port
    /// restored from a checkpoint keeps neither).
    #[cfg(feature = "serde")]
    pub(super) fn set_triggers(&mut self) {
        let triggers = std::mem::take(&mut self.triggers);
        self.trigger_bits = 0;
        for ix in triggers {
            self.add_trigger(ix);
        }
        self.refresh_plain();
    }

    /// Queue the processes this port triggers (in the order of `triggers`) that are not
    /// pending yet. Inlined into its two callers (a plain `#[inline]` was not taken: 19
    /// instructions a call).
    #[inline(always)]
    pub(super) fn queue_triggered(
        &self,
        pending: &mut VecDeque<(u32, u64, u16)>,
        processes: &mut [ProcState],
        b: u32,
        id: u64,
    ) {
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

#[derive(Clone)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
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
    /// or a cycle of processes) and was held back by
    /// [`RETRIGGER_INTERVAL`](super::RETRIGGER_INTERVAL) (D7.3).
    pub(crate) retriggers: u64,
    /// What became of the structure changes its previous activation asked for (R2).
    pub(crate) outcomes: Vec<ChangeOutcome>,
}

impl ProcState {
    /// A process that has not run yet (a periodic one is first due when the schedule lists
    /// it: at its creation, D7.2).
    pub(super) fn new(spec: ProcessSpec) -> ProcState {
        ProcState { spec, runs: 0, overruns: 0, pending: false, ran_in_poll: 0, retriggers: 0, outcomes: Vec::new() }
    }

    pub(crate) fn is_periodic(&self) -> bool {
        self.spec.trigger.period().is_some()
    }
}

/// In declaration order (`repr(C)`) and on a cache line of its own (`align(64)`): what a
/// message arriving at one of its ports or a process's run reads (the id a cached target is
/// checked against, the ports, the processes it may trigger) and the BLE state's box in the
/// first line; the name, class and slots (a process's `Ctx::slot`) in the second; the
/// monostables, read only when one is set or a poll looks for the next wake-up, last (across
/// the second and third). The compiler's own order put the first line's fields in three lines
/// of a 248-byte slot. The BLE state is boxed: inline, its enum tag was the niche
/// `Option<Behavior>` took (at byte 128), so every `behaviors[b]` check read a third line;
/// boxed, the niche is the ports' capacity, in the first line, and the slot is 192 bytes
/// instead of 256. The box came after the monostables, at byte 128, so that each layer's
/// select (once a second, every robot's five layers on the same tick) read a third line of
/// the behavior for it alone; in the first line, in place of the name's first half (the name
/// straddled the first two lines), a 1000-robot run misses the last level about 17 % less
/// (docs/performance.md, issue 36's sensing pass).
#[repr(C, align(64))]
pub(crate) struct Behavior {
    pub(crate) id: u64,
    pub(crate) ports: Vec<PortState>,
    pub(crate) processes: Vec<ProcState>,
    pub(crate) ble: Option<Box<BleState>>,
    pub(crate) name: Arc<str>,
    pub(crate) class: Arc<BehaviorClass>,
    pub(crate) slots: Vec<Value>,
    pub(crate) monos: Vec<MonoState>,
}

// The BLE state's box in the first line, the slots in the second (see the layout note above).
const _: () = assert!(std::mem::offset_of!(Behavior, ble) + std::mem::size_of::<Option<Box<BleState>>>() <= 64);
const _: () = assert!(std::mem::offset_of!(Behavior, slots) + std::mem::size_of::<Vec<Value>>() <= 128);
const _: () = assert!(std::mem::size_of::<Behavior>() == 192);

#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(crate) enum Target {
    Local { b: u32, p: u16 },
    Remote { to: Destination, behavior: Arc<str>, port: Arc<str> },
}

#[derive(Clone)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
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
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(crate) struct Edge {
    /// Index into `NodeCore::conns`.
    pub(crate) conn: u32,
    pub(crate) id: u64,
    /// The destination port when it is on this node.
    pub(crate) local: Option<(u32, u16)>,
    pub(crate) kind: ConnectionKind,
    pub(crate) priority: i32,
}
