//! A node's part in a transaction: structure changes that a team applies all at once or not at
//! all (docs/semantics.md R8–R12; the coordinator is `ayllu::transaction`).
//!
//! The protocol, from the participant's side: PREPARE validates the node's part against its
//! structure as it stands and *holds* it (the node refuses other structure changes from the
//! network and other PREPAREs meanwhile) for `hold` after receipt; COMMIT fixes the switch at
//! `delay` after its receipt, on this node's clock, and is answered with the time left to
//! the switch; the first poll at or after that instant applies the changes, before any
//! process of that poll runs. ABORT drops a held part. A held
//! part that hears neither by the end of its hold aborts by itself.
//!
//! What it promises:
//! * Idempotent: a repeated PREPARE, COMMIT or ABORT is answered as the first was, and never
//!   moves a switch already fixed. An ABORT of a transaction never prepared here is remembered,
//!   so a PREPARE that arrives after it is refused.
//! * Bounded: one transaction held at a time; the last 32 finished ones are remembered.
//! * Deterministic and sans-IO like the rest of the core: it acts only inside `receive` and
//!   `poll`, whose inputs the journal holds, so a replay repeats it exactly.

use std::collections::VecDeque;

use crate::address::NodeId;
use crate::change::{Change, ChangeOutcome};
use crate::error::Error;
use crate::message::{ControlBody, ReplyBody};
use crate::node::NodeCore;
use crate::time::{Duration, Instant};
use crate::value::Value;

/// Finished transactions remembered, at most (for idempotent answers and reports).
const REMEMBERED: usize = 32;
/// Changes one PREPARE may carry, at most.
pub const MAX_CHANGES: usize = 256;

/// Where a transaction stands on this node.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TransactionState {
    /// Validated and held; aborts by itself at `deadline` unless committed or aborted before.
    Prepared {
        /// The end of the hold (this node's clock).
        deadline: Instant,
    },
    /// Committed: switches at `switch_at` (this node's clock).
    Committed {
        /// When the changes are applied.
        switch_at: Instant,
    },
    /// Switched: the changes were applied at `at`.
    Applied {
        /// When (this node's clock: the first poll at or after the switch time).
        at: Instant,
        /// What became of each change (one refused here means the node's own code changed
        /// the structure during the hold: R10).
        outcomes: Vec<ChangeOutcome>,
    },
    /// Dropped at `at`: by an ABORT, or by itself at the end of its hold.
    Aborted {
        /// When.
        at: Instant,
        /// Why, in words.
        why: String,
    },
}

/// One transaction as this node knows it.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TransactionStatus {
    /// The coordinator's transaction number.
    pub txn: u64,
    /// The node that coordinates it.
    pub coordinator: NodeId,
    /// How many changes this node's part has.
    pub changes: usize,
    /// Where it stands.
    pub state: TransactionState,
}

// In declaration order (`repr(C)`), `held` boxed: every poll asks whether a part is held,
// and that question is then one word at the front, which the node keeps among the fields every
// visit reads (`NodeCore`'s layout note), where the inline `Option<Held>` put the answer in a
// line of its own.
#[derive(Clone, Debug, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[repr(C)]
pub(crate) struct Transactions {
    held: Option<Box<Held>>,
    done: VecDeque<TransactionStatus>,
}

#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Held {
    txn: u64,
    from: NodeId,
    changes: Vec<Change>,
    deadline: Instant,
    switch_at: Option<Instant>,
}

fn answer(word: &str) -> Result<ReplyBody, Error> {
    Ok(ReplyBody::Value(Value::text(word)))
}

/// A COMMIT's answer: nanoseconds from now to the switch (negative: it switched that long
/// ago), so the coordinator can place the switch on its own clock within the round trip.
fn until(switch_at: Instant, now: Instant) -> Result<ReplyBody, Error> {
    let ns = |d: Duration| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX);
    let v = if switch_at >= now { ns(switch_at - now) } else { -ns(now - switch_at) };
    Ok(ReplyBody::Value(Value::Int(v)))
}

fn refuse(what: String) -> Result<ReplyBody, Error> {
    Err(Error::Transaction { what })
}

impl NodeCore {
    /// The transaction held here, if any, and the last finished ones, oldest first.
    pub fn transactions(&self) -> Vec<TransactionStatus> {
        let mut v: Vec<TransactionStatus> = self.txns.done.iter().cloned().collect();
        if let Some(h) = &self.txns.held {
            let state = match h.switch_at {
                Some(switch_at) => TransactionState::Committed { switch_at },
                None => TransactionState::Prepared { deadline: h.deadline },
            };
            v.push(TransactionStatus { txn: h.txn, coordinator: h.from, changes: h.changes.len(), state });
        }
        v
    }

    /// Whether a transaction's part is held here (network structure requests are refused).
    pub fn transaction_held(&self) -> Option<(NodeId, u64)> {
        self.txns.held.as_ref().map(|h| (h.from, h.txn))
    }

    /// When the held transaction next needs a poll: its switch, or the end of its hold.
    pub(crate) fn transaction_due(&self) -> Option<Instant> {
        self.txns.held.as_ref().map(|h| h.switch_at.unwrap_or(h.deadline))
    }

    fn finished(&self, from: NodeId, txn: u64) -> Option<&TransactionStatus> {
        self.txns.done.iter().rev().find(|t| t.coordinator == from && t.txn == txn)
    }

    fn finish(&mut self, status: TransactionStatus) {
        if self.txns.done.len() >= REMEMBERED {
            self.txns.done.pop_front();
        }
        self.txns.done.push_back(status);
    }

    /// Apply PREPARE, COMMIT or ABORT from `from` (access rules already checked).
    pub(crate) fn apply_transaction(&mut self, from: NodeId, body: ControlBody) -> Result<ReplyBody, Error> {
        let now = self.now;
        let held_here =
            |core: &NodeCore, txn: u64| core.txns.held.as_ref().is_some_and(|h| h.from == from && h.txn == txn);
        match body {
            ControlBody::Prepare { txn, changes, hold } => {
                if held_here(self, txn) {
                    let committed = self.txns.held.as_ref().is_some_and(|h| h.switch_at.is_some());
                    return answer(if committed { "committed" } else { "prepared" });
                }
                match self.finished(from, txn).map(|t| t.state.clone()) {
                    Some(TransactionState::Applied { .. }) => return answer("applied"),
                    Some(TransactionState::Aborted { why, .. }) => return refuse(format!("aborted: {why}")),
                    _ => {}
                }
                if let Some(h) = &self.txns.held {
                    return refuse(format!(
                        "busy: transaction {} of {} is held here until {}",
                        h.txn,
                        h.from,
                        h.switch_at.unwrap_or(h.deadline)
                    ));
                }
                if changes.len() > MAX_CHANGES {
                    return refuse(format!("{} changes; a node takes at most {MAX_CHANGES} in one", changes.len()));
                }
                if hold.is_zero() || hold > self.limits().max_remote_period {
                    return refuse(format!(
                        "a hold of {hold}; this node holds above zero and at most {}",
                        self.limits().max_remote_period
                    ));
                }
                if let Err((i, e)) = self.validate_changes(&changes) {
                    return refuse(format!("change {} ({}): {e}", i + 1, changes[i].describe()));
                }
                self.txns.held = Some(Box::new(Held { txn, from, changes, deadline: now + hold, switch_at: None }));
                answer("prepared")
            }
            ControlBody::Commit { txn, delay } => {
                if held_here(self, txn) {
                    let h = self.txns.held.as_mut().expect("held");
                    let switch_at = *h.switch_at.get_or_insert(now + delay);
                    if switch_at <= now {
                        self.switch_transaction();
                    }
                    return until(switch_at, now);
                }
                match self.finished(from, txn).map(|t| t.state.clone()) {
                    Some(TransactionState::Applied { at, .. }) => until(at, now),
                    Some(TransactionState::Aborted { why, .. }) => refuse(format!("aborted: {why}")),
                    _ => refuse(format!("transaction {txn} of {from} was never prepared here")),
                }
            }
            ControlBody::Abort { txn } => {
                if held_here(self, txn) {
                    let h = self.txns.held.as_ref().expect("held");
                    if let Some(t) = h.switch_at {
                        return refuse(format!("committed already: it switches at {t}"));
                    }
                    let h = self.txns.held.take().expect("held");
                    let state = TransactionState::Aborted { at: now, why: "aborted by its coordinator".into() };
                    self.finish(TransactionStatus { txn, coordinator: from, changes: h.changes.len(), state });
                    return answer("aborted");
                }
                match self.finished(from, txn).map(|t| t.state.clone()) {
                    Some(TransactionState::Applied { .. }) => refuse("applied already".into()),
                    Some(TransactionState::Aborted { .. }) => answer("aborted"),
                    _ => {
                        // Remembered, so that a PREPARE arriving after its ABORT is refused.
                        let state = TransactionState::Aborted { at: now, why: "aborted before it was prepared".into() };
                        self.finish(TransactionStatus { txn, coordinator: from, changes: 0, state });
                        answer("aborted")
                    }
                }
            }
            _ => refuse("not a transaction request".into()),
        }
    }

    /// Inside `poll`, before any process: switch a committed transaction whose time has come,
    /// or drop a prepared one whose hold ended.
    pub(crate) fn poll_transaction(&mut self) {
        let Some(h) = &self.txns.held else { return };
        match h.switch_at {
            Some(t) if self.now >= t => self.switch_transaction(),
            None if self.now >= h.deadline => {
                let h = self.txns.held.take().expect("held");
                let why = format!("no COMMIT or ABORT within its hold (until {})", h.deadline);
                let warning = format!("transaction {} of {}: {why}; aborted by itself", h.txn, h.from);
                // A consequence of the poll, which the journal holds: not journaled again.
                self.unjournaled(|core| core.warn(warning));
                let state = TransactionState::Aborted { at: self.now, why };
                self.finish(TransactionStatus { txn: h.txn, coordinator: h.from, changes: h.changes.len(), state });
            }
            _ => {}
        }
    }

    fn switch_transaction(&mut self) {
        let Some(h) = self.txns.held.take() else { return };
        let outcomes: Vec<ChangeOutcome> = h
            .changes
            .iter()
            .map(|c| ChangeOutcome { change: c.clone(), result: self.unjournaled(|core| core.apply_change(c)) })
            .collect();
        let state = TransactionState::Applied { at: self.now, outcomes };
        self.finish(TransactionStatus { txn: h.txn, coordinator: h.from, changes: h.changes.len(), state });
    }
}

/// The hold a coordinator asks for when none is given: long enough for a hundred resends of a
/// lost COMMIT at 20 ms (R11).
pub const DEFAULT_HOLD: Duration = Duration::from_secs(5);
