//! The node's schedule of timed work: its periodic processes in run order, and a lower bound
//! on the next monostable falling edge.
//!
//! A poll used to walk every behavior's every process to find the periodic ones that are due,
//! and every behavior's monostables to find the edges, touching each process's state (a cache
//! line each once the node is cold, as it is in a simulator stepping hundreds of nodes). The
//! schedule keeps what that walk needs in one compact array, so a poll reads one entry per
//! periodic process and nothing for the others.
//!
//! An entry also holds what a run needs of its process (the period, the body, the run count),
//! so that a periodic run does not touch the process's state at all: at 20 Hz with several
//! processes per node, that state was a cache miss per run once the node had gone cold. The
//! walk reads every entry at every poll, so an entry is kept to 48 bytes (a BLE robot's twelve
//! processes: nine lines where 56-byte entries made ten or eleven). The body cannot leave the
//! entry for the class's copy: a class's specs are cold too in a simulated team, and an
//! instance's own processes (BLE's select) would read their state again (measured: more
//! last-level misses, not fewer). Nor can a split of the entry into the walk's half and the
//! run's: the run's half of a 10 Hz process then leaves the lines read every tick, and misses
//! the last level at every run (measured).
//!
//! A guarded process (D7.5) is activated only at the due times at which its guard port is
//! fresh; an observer whose target is out of sight finds it stale at almost every one. Reading
//! the port to find that costs two lines (the behavior's, for its ports, and the port's cell),
//! so an entry remembers that its guard was found stale (`Guard::Stale`): a port turns fresh
//! only by accepting a value, and a guard port (marked `guarded`, which keeps it off the plain
//! path) tells the schedule when it accepts (`guard_accepted`), so the remembered answer is
//! exact. A restored node and a new entry know nothing yet and read the port.
//!
//! What it promises: the poll runs the same processes in the same order as the walk over
//! (behavior slot, declaration) did, structure changes made by a running process included
//! (a behavior created into a later free slot runs in the same poll, one created into an
//! earlier slot or past the slots the poll started with does not), with the same due times
//! and overrun counts. It is kept up to date where periodic processes come and go (`create`,
//! a behavior's removal, `add_process`), and it is where a periodic process's due time and run
//! count live (the reports read them here), so a run writes them in the schedule only.

use std::fmt;

use crate::behavior::{ProcessFn, Trigger};
use crate::node::{Behavior, ProcState};
use crate::time::{Duration, Instant};

/// One periodic process: where it lives, when it is next due, what is known of its guard, and
/// what a run needs. 48 bytes (asserted): a poll walks every entry, so each byte is read at
/// every poll of every node.
#[derive(Clone)]
pub(crate) struct Periodic {
    pub(crate) b: u32,
    pub(crate) pi: u16,
    /// Whether the process is guarded (D7.5) and what is known of its guard port. The port
    /// itself is the process's trigger's (`guard_port`): in the entry, with the run count and
    /// the body, it would make it 56 bytes.
    pub(crate) guard: Guard,
    pub(crate) next_due: Instant,
    pub(crate) period: Duration,
    /// Activations run (the process's `runs` in reports).
    pub(crate) runs: u64,
    /// The process's body (the same `Arc` as its state's).
    pub(crate) body: ProcessFn,
}

const _: () = assert!(std::mem::size_of::<Periodic>() == 48);

impl fmt::Debug for Periodic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Periodic")
            .field("b", &self.b)
            .field("pi", &self.pi)
            .field("guard", &self.guard)
            .field("next_due", &self.next_due)
            .field("period", &self.period)
            .field("runs", &self.runs)
            .finish()
    }
}

/// Whether a periodic process is guarded (D7.5), and what the schedule knows of its guard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Guard {
    /// A plain periodic process.
    None,
    /// Guarded: the port must be read at the next due time.
    Read,
    /// Guarded, and the port was found stale at an earlier due time and has accepted nothing
    /// since: it is stale now (see `Schedule::guard_accepted`).
    Stale,
}

impl Periodic {
    /// Process `pi` (`p`) of slot `b`, next due at `next_due`, having run `runs` times, if it
    /// is periodic. Nothing is known of a guard yet.
    pub(crate) fn new(b: u32, pi: u16, p: &ProcState, next_due: Instant, runs: u64) -> Option<Periodic> {
        let (period, guard) = match p.spec.trigger {
            Trigger::Periodic(period) => (period, Guard::None),
            Trigger::PeriodicWhileFresh(period, _) => (period, Guard::Read),
            Trigger::OnWrite(_) | Trigger::OnMonostable(_) => return None,
        };
        Some(Periodic { b, pi, next_due, period, guard, runs, body: p.spec.body.clone() })
    }
}

/// The port guarding process `pi` of `beh`, if it is guarded (D7.5): its trigger's, read from
/// the process's state only when the schedule must read the port, which is rare (a guard
/// known stale is not read at all).
pub(crate) fn guard_port(beh: &Behavior, pi: u16) -> Option<u16> {
    match beh.processes.get(usize::from(pi))?.spec.trigger {
        Trigger::PeriodicWhileFresh(_, port) => Some(port.0),
        _ => None,
    }
}

/// See the module docs.
#[derive(Debug)]
pub(crate) struct Schedule {
    /// Every periodic process of the node, ordered by (behavior slot, declaration).
    pub(crate) periodic: Vec<Periodic>,
    /// Bumped whenever `periodic` changes shape, so that a poll walking it knows to find its
    /// place again (see `after`).
    pub(crate) generation: u64,
    /// No high monostable ends before this (`Instant::MAX`: none is high). A lower bound, not
    /// the exact earliest end: a poll before it has no edge to look for.
    pub(crate) mono_edge: Instant,
}

impl Default for Schedule {
    fn default() -> Schedule {
        Schedule { periodic: Vec::new(), generation: 0, mono_edge: Instant::MAX }
    }
}

impl Schedule {
    /// The position of the first entry after process `pi` of slot `b` in run order.
    pub(crate) fn after(&self, b: u32, pi: u16) -> usize {
        self.periodic.partition_point(|e| (e.b, e.pi) <= (b, pi))
    }

    /// The entry of process `pi` of slot `b`, if it is periodic.
    pub(crate) fn entry(&self, b: u32, pi: u16) -> Option<&Periodic> {
        let at = self.periodic.partition_point(|e| (e.b, e.pi) < (b, pi));
        self.periodic.get(at).filter(|e| (e.b, e.pi) == (b, pi))
    }

    /// List the periodic processes of the behavior just placed in slot `b`, first due `now`
    /// (D7.2).
    pub(crate) fn add_behavior(&mut self, b: u32, processes: &[ProcState], now: Instant) {
        let at = self.periodic.partition_point(|e| e.b < b);
        let new = processes.iter().enumerate().filter_map(|(pi, p)| Periodic::new(b, pi as u16, p, now, 0));
        self.periodic.splice(at..at, new);
        self.generation += 1;
    }

    /// Forget the periodic processes of the behavior removed from slot `b`.
    pub(crate) fn remove_behavior(&mut self, b: u32) {
        let from = self.periodic.partition_point(|e| e.b < b);
        let to = self.periodic.partition_point(|e| e.b <= b);
        self.periodic.drain(from..to);
        self.generation += 1;
    }

    /// List process `pi` (`p`), just added to the behavior in slot `b` (the last of its
    /// processes), if it is periodic.
    pub(crate) fn add_process(&mut self, b: u32, pi: u16, p: &ProcState, next_due: Instant) {
        let Some(entry) = Periodic::new(b, pi, p, next_due, 0) else { return };
        let at = self.after(b, pi);
        self.periodic.insert(at, entry);
        self.generation += 1;
    }

    /// A port guarding a process of the behavior in slot `b` accepted a value: it may be fresh
    /// now, so no entry of that behavior may take its guard for stale without reading it.
    /// Every one of the behavior's entries, not only those of that port: a port does not know
    /// which processes it guards, and a behavior has few.
    #[cold]
    #[inline(never)]
    pub(crate) fn guard_accepted(&mut self, b: u32) {
        let from = self.periodic.partition_point(|e| e.b < b);
        for e in self.periodic[from..].iter_mut().take_while(|e| e.b == b) {
            if e.guard == Guard::Stale {
                e.guard = Guard::Read;
            }
        }
    }

    /// A monostable just rose (or stays high) until `end`.
    pub(crate) fn mono_high_until(&mut self, end: Instant) {
        self.mono_edge = self.mono_edge.min(end);
    }
}

#[cfg(test)]
mod tests {
    //! The poll's order and due times with structure changed by running processes, as the
    //! walk over (behavior slot, declaration) gave them before the schedule existed (the
    //! expected lines were recorded with that walk).

    use std::sync::{Arc, Mutex};

    use crate::*;

    type Log = Arc<Mutex<Vec<String>>>;

    fn node(log: &Log) -> NodeCore {
        let mut node = NodeCore::new(NodeId(1));
        let mut tick = BehaviorClass::new("Tick");
        let out = tick.port(PortSpec::new("Out", 0i64)).unwrap();
        let l = log.clone();
        tick.process("P", Trigger::Periodic(Duration::from_millis(100)), move |ctx| {
            l.lock().unwrap().push(format!("{}.P@{}", ctx.behavior(), ctx.now().as_nanos() / 1_000_000));
            let _ = ctx.write(out, 1i64);
        })
        .unwrap();
        let l = log.clone();
        tick.on_write("W", out, move |ctx| l.lock().unwrap().push(format!("{}.W", ctx.behavior()))).unwrap();
        let l = log.clone();
        tick.process("Q", Trigger::Periodic(Duration::from_millis(30)), move |ctx| {
            l.lock().unwrap().push(format!("{}.Q@{}", ctx.behavior(), ctx.now().as_nanos() / 1_000_000));
        })
        .unwrap();
        node.define(tick).unwrap();
        let mut maker = BehaviorClass::new("Maker");
        let l = log.clone();
        maker
            .process("M", Trigger::Periodic(Duration::from_millis(100)), move |ctx| {
                let t = ctx.now().as_nanos() / 1_000_000;
                l.lock().unwrap().push(format!("{}.M@{t}", ctx.behavior()));
                if t == 0 {
                    // Frees slots 0 (A) and 3 (C); X takes 3 (after M: runs now), Y takes 0
                    // (before M: not now), Z a new slot 4 (past the poll's slots: not now).
                    ctx.remove("A").unwrap();
                    ctx.remove("C").unwrap();
                    ctx.create("Tick", "X").unwrap();
                    ctx.create("Tick", "Y").unwrap();
                    ctx.create("Tick", "Z").unwrap();
                }
                if t == 250 {
                    // Removes itself and the behavior after it, then re-creates into its own
                    // slot (the last freed): the new behavior's processes run in this poll.
                    ctx.remove("B").unwrap();
                    ctx.remove("M").unwrap();
                    ctx.create("Tick", "R").unwrap();
                }
            })
            .unwrap();
        node.define(maker).unwrap();
        for (class, name) in [("Tick", "A"), ("Maker", "M"), ("Tick", "B"), ("Tick", "C")] {
            node.create(class, name).unwrap();
        }
        node
    }

    fn processes(node: &NodeCore) -> String {
        let mut s = String::new();
        for b in node.report().behaviors {
            for p in b.processes {
                s += &format!(
                    "{}.{} runs {} overruns {} next {:?}\n",
                    b.name,
                    p.name,
                    p.runs,
                    p.overruns,
                    p.next_due.map(|t| t.as_nanos() / 1_000_000)
                );
            }
        }
        s
    }

    #[test]
    fn the_poll_runs_periodic_processes_in_slot_and_declaration_order_through_structure_changes() {
        let log: Log = Arc::default();
        let mut node = node(&log);
        let mut polls = Vec::new();
        for t in [0u64, 50, 120, 130, 250, 400, 410, 1000] {
            node.run_due(Instant::from_millis(t));
            polls.push(log.lock().unwrap().drain(..).collect::<Vec<_>>().join(" "));
            if t == 130 {
                let l = log.clone();
                node.add_process("X", "Late", Trigger::Periodic(Duration::from_millis(200)), move |ctx| {
                    l.lock().unwrap().push(format!("{}.Late@{}", ctx.behavior(), ctx.now().as_nanos() / 1_000_000))
                })
                .unwrap();
            }
        }
        let expected: [&str; 8] = [
            "A.P@0 A.W A.Q@0 M.M@0 B.P@0 B.W B.Q@0 X.P@0 X.W X.Q@0",
            "Y.P@50 Y.W Y.Q@50 B.Q@50 X.Q@50 Z.P@50 Z.W Z.Q@50",
            "Y.P@120 Y.W Y.Q@120 M.M@120 B.P@120 B.W B.Q@120 X.P@120 X.W X.Q@120 Z.P@120 Z.W Z.Q@120",
            "",
            "Y.P@250 Y.W Y.Q@250 M.M@250 R.Q@250 X.P@250 X.W X.Q@250 X.Late@250 Z.P@250 Z.W Z.Q@250",
            "Y.P@400 Y.W Y.Q@400 R.P@400 R.W R.Q@400 X.P@400 X.W X.Q@400 X.Late@400 Z.P@400 Z.W Z.Q@400",
            "",
            "Y.P@1000 Y.W Y.Q@1000 R.P@1000 R.W R.Q@1000 X.P@1000 X.W X.Q@1000 X.Late@1000 Z.P@1000 Z.W Z.Q@1000",
        ];
        assert_eq!(polls, expected);
        let expected = concat!(
            "R.P runs 2 overruns 6 next Some(1050)\n",
            "R.W runs 2 overruns 0 next None\n",
            "R.Q runs 3 overruns 23 next Some(1030)\n",
            "X.P runs 5 overruns 6 next Some(1100)\n",
            "X.W runs 5 overruns 0 next None\n",
            "X.Q runs 6 overruns 28 next Some(1020)\n",
            "X.Late runs 3 overruns 2 next Some(1130)\n",
            "Y.P runs 5 overruns 6 next Some(1100)\n",
            "Y.W runs 5 overruns 0 next None\n",
            "Y.Q runs 5 overruns 29 next Some(1020)\n",
            "Z.P runs 5 overruns 6 next Some(1100)\n",
            "Z.W runs 5 overruns 0 next None\n",
            "Z.Q runs 5 overruns 29 next Some(1020)\n",
        );
        assert_eq!(processes(&node), expected);
        assert_eq!(node.poll_at(), Some(Instant::from_millis(1020)));
    }

    /// Sets its flag when dropped: tells when a process body (which owns one) is freed.
    struct DropFlag(Arc<std::sync::atomic::AtomicBool>);
    impl Drop for DropFlag {
        fn drop(&mut self) {
            self.0.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }

    #[test]
    fn a_body_that_removes_its_own_behavior_is_dropped_only_after_it_returns() {
        // The poll calls a body through its process's `Arc` without cloning it
        // (node/scheduler.rs, `run_body`): removing the running behavior must not free the
        // body under it. The instance-specific processes below are held by their state and
        // schedule entry only (no class holds them), so the removal drops the last other
        // owners.
        use std::sync::atomic::{AtomicBool, Ordering::SeqCst};
        let log: Log = Arc::default();
        let mut node = NodeCore::new(NodeId(1));
        let mut class = BehaviorClass::new("Host");
        let out = class.port(PortSpec::new("Out", 0i64)).unwrap();
        node.define(class).unwrap();
        for name in ["Now", "Later", "Trig"] {
            node.create("Host", name).unwrap();
        }
        // Removed at once, from inside the body, the way a future immediate change would:
        // the behavior is parked until the body returns.
        let now_dropped = Arc::new(AtomicBool::new(false));
        let (flag, seen, l) = (DropFlag(now_dropped.clone()), now_dropped.clone(), log.clone());
        node.add_process("Now", "Kill", Trigger::Periodic(Duration::from_millis(100)), move |ctx| {
            ctx.core.remove("Now").unwrap();
            let _owned = &flag;
            l.lock().unwrap().push(format!("Now.Kill dropped {}", seen.load(SeqCst)));
        })
        .unwrap();
        // Removed through the process's changes (R1): applied after it returns.
        let later_dropped = Arc::new(AtomicBool::new(false));
        let (flag, seen, l) = (DropFlag(later_dropped.clone()), later_dropped.clone(), log.clone());
        node.add_process("Later", "Kill", Trigger::Periodic(Duration::from_millis(100)), move |ctx| {
            ctx.remove("Later").unwrap();
            let _owned = &flag;
            l.lock().unwrap().push(format!("Later.Kill dropped {}", seen.load(SeqCst)));
        })
        .unwrap();
        // A triggered process (run through `run_process`) that removes its behavior at once.
        let trig_dropped = Arc::new(AtomicBool::new(false));
        let (flag, seen, l) = (DropFlag(trig_dropped.clone()), trig_dropped.clone(), log.clone());
        node.add_process("Trig", "Kill", Trigger::OnWrite(out), move |ctx| {
            ctx.core.remove("Trig").unwrap();
            let _owned = &flag;
            l.lock().unwrap().push(format!("Trig.Kill dropped {}", seen.load(SeqCst)));
        })
        .unwrap();
        let trig_out = node.port("Trig", "Out").unwrap();
        node.write(Instant::ZERO, trig_out, 1i64).unwrap();
        node.run_due(Instant::ZERO);
        assert_eq!(
            log.lock().unwrap().join(" "),
            "Trig.Kill dropped false Now.Kill dropped false Later.Kill dropped false"
        );
        assert!(now_dropped.load(SeqCst) && later_dropped.load(SeqCst) && trig_dropped.load(SeqCst));
        assert!(node.report().behaviors.is_empty());
        node.run_due(Instant::from_millis(100));
        assert_eq!(log.lock().unwrap().len(), 3, "removed processes do not run again");
    }

    #[test]
    fn a_monostable_edge_is_found_whenever_it_falls() {
        let log: Log = Arc::default();
        let mut node = NodeCore::new(NodeId(1));
        let mut c = BehaviorClass::new("Mono");
        let m = c.monostable("Busy").unwrap();
        let l = log.clone();
        c.on_monostable("Edge", m, move |ctx| {
            l.lock().unwrap().push(format!("{}@{}", ctx.is_high(m), ctx.now().as_nanos() / 1_000_000))
        })
        .unwrap();
        node.define(c).unwrap();
        node.create("Mono", "K").unwrap();
        node.create("Mono", "L").unwrap();
        let mut seen = Vec::new();
        for t in [0u64, 5, 10, 20, 30, 45, 60, 70, 100, 150] {
            match t {
                0 => node.trigger(Instant::from_millis(t), "K", "Busy", Duration::from_millis(40)).unwrap(),
                5 => node.trigger(Instant::from_millis(t), "L", "Busy", Duration::from_millis(10)).unwrap(),
                20 => node.trigger(Instant::from_millis(t), "K", "Busy", Duration::from_millis(50)).unwrap(),
                60 => node.remove("K").unwrap(),
                70 => node.trigger(Instant::from_millis(t), "L", "Busy", Duration::from_millis(20)).unwrap(),
                _ => {}
            }
            let at = node.poll(Instant::from_millis(t));
            seen.push(format!(
                "{t}: {} next {:?}",
                log.lock().unwrap().drain(..).collect::<Vec<_>>().join(" "),
                at.map(|a| a.as_nanos() / 1_000_000)
            ));
        }
        let expected = [
            "0: true@0 next Some(40)",
            "5: true@5 next Some(15)",
            "10:  next Some(15)",
            "20: false@20 next Some(70)",
            "30:  next Some(70)",
            "45:  next Some(70)",
            "60:  next None",
            "70: true@70 next Some(90)",
            "100: false@100 next None",
            "150:  next None",
        ];
        assert_eq!(seen, expected);
    }
}
