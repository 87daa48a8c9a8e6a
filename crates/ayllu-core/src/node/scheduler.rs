//! Scheduling (rules S7, S8): `poll`, which runs everything due at the time passed in, and
//! the process runs it makes.
//!
//! What it promises: processes run only inside `poll`, one at a time, each to completion;
//! late periodic processes skip the activations they missed and count them; a triggered
//! process runs at most once per poll, and one that triggers itself again is held back by
//! [`RETRIGGER_INTERVAL`] (D7.3) instead of spinning a core. Structure changes a process asks
//! for are applied after it returns (R1) and their outcomes kept for its next activation
//! (R2). Time is only ever passed in (S8). The bookkeeping of periodic processes and
//! monostable edges is `crate::schedule`'s; this part drives it.

use std::collections::VecDeque;
use std::sync::Arc;

use crate::change::{Change, ChangeOutcome};
use crate::journal::Event;
use crate::process::Ctx;
use crate::schedule::{guard_port, Guard, Periodic};
use crate::time::Instant;

use super::{NodeCore, ProcState, RequestStatus, Running, RETRIGGER_INTERVAL};

impl NodeCore {
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
            // D7.5: a due time at which the guard port is stale is not an activation (neither
            // run nor counted); the next due time is the unguarded process's either way. A
            // port can turn fresh only by accepting a value, and an acceptance turns `Stale`
            // back to `Read` (`Schedule::guard_accepted`), so a port found stale at an earlier
            // due time is still stale while the entry says `Stale`: known without reading the
            // behavior and the port's cell, two cold lines at most due times of a quiet
            // observer.
            match entry.guard {
                Guard::None => {}
                Guard::Stale => continue,
                Guard::Read => {
                    let fresh = self.behaviors[b as usize].as_ref().is_some_and(|beh| {
                        guard_port(beh, pi)
                            .and_then(|g| beh.ports.get(usize::from(g)))
                            .is_some_and(|port| port.cell.fresh(now))
                    });
                    if !fresh {
                        entry.guard = Guard::Stale;
                        continue;
                    }
                }
            }
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
        // Most polls have no request of their own waiting: no call for them.
        if !self.requests.is_empty() {
            self.flush_requests();
        }
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
    pub(super) fn debug_check_schedule(&self) {
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
}

/// Queue process `pi` of the behavior in slot `b` (whose id is `id`) to run: once, however
/// often it is triggered before it runs.
pub(super) fn queue(pending: &mut VecDeque<(u32, u64, u16)>, proc_: &mut ProcState, b: u32, id: u64, pi: u16) {
    if !proc_.pending {
        proc_.pending = true;
        pending.push_back((b, id, pi));
    }
}
