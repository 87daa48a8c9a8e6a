//! Rule S7, periodic processes: run at their rate, phase-locked to the behavior's creation,
//! only inside `poll`; `poll` returns the next deadline; a late poll runs a process once, skips
//! the missed activations (no catch-up burst) and counts them as overruns in
//! `report().behaviors[..].processes[..].overruns`.

use std::sync::{Arc, Mutex};

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

type Log = Arc<Mutex<Vec<(&'static str, u64)>>>;

/// Class `C` with one periodic process per `(name, hz)`, each logging `(name, now_ms)` and
/// adding 1 to the Sum port `Ticks` (so propagation per run is observable too).
fn class(procs: &[(&'static str, f64)], log: &Log) -> BehaviorClass {
    let mut c = BehaviorClass::new("C");
    let ticks = c.port(PortSpec::new("Ticks", 0i64).sum()).unwrap();
    for &(name, hz) in procs {
        let l = log.clone();
        c.every_hz(name, hz, move |ctx| {
            l.lock().unwrap().push((name, ctx.now().as_nanos() / 1_000_000));
            ctx.write(ticks, 1i64).unwrap();
        })
        .unwrap();
    }
    c
}

fn process(n: &NodeCore, behavior: &str, name: &str) -> ProcessReport {
    let r = n.report();
    let b = r.behaviors.into_iter().find(|b| b.name == behavior).unwrap();
    b.processes.into_iter().find(|p| p.name == name).unwrap()
}

fn times(log: &Log, name: &str) -> Vec<u64> {
    log.lock().unwrap().iter().filter(|(n, _)| *n == name).map(|(_, t)| *t).collect()
}

#[test]
fn runs_at_its_rate_and_poll_returns_the_next_deadline() {
    // S7: a 10 Hz process runs every 100 ms starting at creation; poll returns the deadline.
    let log: Log = Arc::default();
    let mut n = NodeCore::new(NodeId(1));
    n.define(class(&[("P", 10.0)], &log)).unwrap();
    n.create("C", "B").unwrap();
    assert_eq!(n.poll_at(), Some(ms(0)));
    assert!(log.lock().unwrap().is_empty(), "nothing runs outside poll");
    assert_eq!(n.poll(ms(0)), Some(ms(100)));
    assert_eq!(n.poll(ms(50)), Some(ms(100)));
    assert_eq!(n.poll(ms(99)), Some(ms(100)));
    assert_eq!(times(&log, "P"), vec![0]);
    assert_eq!(n.poll(ms(100)), Some(ms(200)));
    assert_eq!(n.poll(ms(200)), Some(ms(300)));
    assert_eq!(times(&log, "P"), vec![0, 100, 200]);
    let p = process(&n, "B", "P");
    assert_eq!((p.runs, p.overruns, p.next_due), (3, 0, Some(ms(300))));
    assert_eq!(p.trigger, Trigger::Periodic(Duration::from_millis(100)));
}

#[test]
fn driving_by_poll_at_gives_exact_rates() {
    // S7/S8: a driver that sleeps until poll_at runs each process exactly at its rate.
    let log: Log = Arc::default();
    let mut n = NodeCore::new(NodeId(1));
    n.define(class(&[("Fast", 10.0), ("Slow", 4.0)], &log)).unwrap();
    n.create("C", "B").unwrap();
    while let Some(t) = n.poll_at() {
        if t > ms(1_000) {
            break;
        }
        n.poll(t);
    }
    assert_eq!(times(&log, "Fast"), (0..=10).map(|k| k * 100).collect::<Vec<_>>());
    assert_eq!(times(&log, "Slow"), vec![0, 250, 500, 750, 1_000]);
    assert_eq!(process(&n, "B", "Fast").overruns, 0);
    assert_eq!(process(&n, "B", "Slow").overruns, 0);
    assert_eq!(n.read(n.port("B", "Ticks").unwrap()).unwrap(), Value::Int(16));
}

#[test]
fn phase_is_locked_to_the_behaviors_creation() {
    // S7: a behavior created at 1030 ms runs at 1030, 1130, ... (created while running, S9).
    let log: Log = Arc::default();
    let mut n = NodeCore::new(NodeId(1));
    n.define(class(&[("P", 10.0)], &log)).unwrap();
    n.poll(ms(1_030));
    n.create("C", "B").unwrap();
    assert_eq!(n.poll_at(), Some(ms(1_030)));
    assert_eq!(n.poll(ms(1_030)), Some(ms(1_130)));
    assert_eq!(n.poll(ms(1_150)), Some(ms(1_230)));
    assert_eq!(times(&log, "P"), vec![1_030, 1_150]);
}

#[test]
fn a_late_poll_skips_missed_activations_and_counts_overruns() {
    // S7: polled 450 ms late, the process runs once (no burst), the activations at 200, 300,
    // 400 and 500 ms collapse into that one run: three are skipped and counted, and the phase is
    // kept (next at 600 ms).
    let log: Log = Arc::default();
    let mut n = NodeCore::new(NodeId(1));
    n.define(class(&[("P", 10.0)], &log)).unwrap();
    n.create("C", "B").unwrap();
    n.poll(ms(0));
    n.poll(ms(100));
    assert_eq!(n.poll(ms(550)), Some(ms(600)));
    assert_eq!(times(&log, "P"), vec![0, 100, 550]);
    let p = process(&n, "B", "P");
    assert_eq!((p.runs, p.overruns, p.next_due), (3, 3, Some(ms(600))));
    // The run wrote once: the Sum port saw 3 writes, not 6.
    assert_eq!(n.read(n.port("B", "Ticks").unwrap()).unwrap(), Value::Int(3));
    // Back on schedule afterwards, overruns stay put.
    n.poll(ms(600));
    n.poll(ms(700));
    let p = process(&n, "B", "P");
    assert_eq!((p.runs, p.overruns), (5, 3));
}

#[test]
fn a_late_first_poll_counts_the_activations_it_missed() {
    // S7: the first activation is due at creation; a first poll at 250 ms runs once and counts
    // the skipped 100 and 200 ms activations.
    let log: Log = Arc::default();
    let mut n = NodeCore::new(NodeId(1));
    n.define(class(&[("P", 10.0)], &log)).unwrap();
    n.create("C", "B").unwrap();
    assert_eq!(n.poll(ms(250)), Some(ms(300)));
    let p = process(&n, "B", "P");
    assert_eq!((p.runs, p.overruns), (1, 2));
}

#[test]
fn processes_run_one_at_a_time_in_declaration_order() {
    // S7: processes of one node run one at a time, each to completion.
    let log: Log = Arc::default();
    let depth = Arc::new(Mutex::new(0u32));
    let mut c = BehaviorClass::new("C");
    for name in ["A", "B", "C"] {
        let (l, d) = (log.clone(), depth.clone());
        c.every_hz(name, 1.0, move |ctx| {
            let mut g = d.lock().unwrap();
            *g += 1;
            assert_eq!(*g, 1, "two processes ran at once");
            l.lock().unwrap().push((name, ctx.now().as_nanos() / 1_000_000));
            *g -= 1;
        })
        .unwrap();
    }
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("C", "X").unwrap();
    n.poll(ms(0));
    assert_eq!(*log.lock().unwrap(), vec![("A", 0), ("B", 0), ("C", 0)]);
}

#[test]
fn a_removed_behavior_stops_being_scheduled() {
    // S7/S9: removing a behavior removes its processes from the schedule.
    let log: Log = Arc::default();
    let mut n = NodeCore::new(NodeId(1));
    n.define(class(&[("P", 10.0)], &log)).unwrap();
    n.create("C", "B").unwrap();
    n.poll(ms(0));
    n.remove("B").unwrap();
    assert_eq!(n.poll_at(), None);
    n.poll(ms(1_000));
    assert_eq!(times(&log, "P"), vec![0]);
}
