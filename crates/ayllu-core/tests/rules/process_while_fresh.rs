//! Rule S7, D7.5: a periodic process guarded by a port of its behavior
//! (`Trigger::PeriodicWhileFresh`) has the due times of the unguarded process and is activated
//! at those at which the port is fresh only: it writes exactly what the unguarded process with
//! "no value, no output" at its top writes, and counts only the activations it ran.

use std::sync::{Arc, Mutex};

use proptest::prelude::*;

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

type Log = Arc<Mutex<Vec<(u64, f64)>>>;

/// Class `C`: `In` (float, lifespan `life_ms`) and `Out`; process `P` at `hz` copying `In` to
/// `Out` and logging `(now_ms, value)` when `In` is fresh — guarded by `In` or not.
fn class(hz: f64, life_ms: u64, guarded: bool, log: &Log) -> BehaviorClass {
    let mut c = BehaviorClass::new("C");
    let input = c.port(PortSpec::new("In", 0.0).lifespan(Duration::from_millis(life_ms))).unwrap();
    let out = c.port(PortSpec::new("Out", 0.0)).unwrap();
    let l = log.clone();
    let body = move |ctx: &mut Ctx<'_>| {
        let Some(v) = ctx.float(input) else { return };
        l.lock().unwrap().push((ctx.now().as_nanos() / 1_000_000, v));
        ctx.write(out, v).unwrap();
    };
    if guarded {
        c.every_hz_while_fresh("P", hz, input, body).unwrap();
    } else {
        c.every_hz("P", hz, body).unwrap();
    }
    c
}

fn node(hz: f64, life_ms: u64, guarded: bool, log: &Log) -> NodeCore {
    let mut n = NodeCore::new(NodeId(1));
    n.define(class(hz, life_ms, guarded, log)).unwrap();
    n.create("C", "B").unwrap();
    n
}

fn process(n: &NodeCore) -> ProcessReport {
    let r = n.report();
    let b = r.behaviors.into_iter().find(|b| b.name == "B").unwrap();
    b.processes.into_iter().find(|p| p.name == "P").unwrap()
}

fn input(n: &NodeCore) -> PortRef {
    n.port("B", "In").unwrap()
}

#[test]
fn runs_at_the_due_times_at_which_its_port_is_fresh_only() {
    // 10 Hz (due every 100 ms from 0), `In` fresh for 150 ms after each write: written at 0 and
    // 420, so fresh in [0, 150) and [420, 570): activated at 0, 100 and 500, not at the others.
    let log: Log = Arc::default();
    let mut n = node(10.0, 150, true, &log);
    let p = input(&n);
    n.write(ms(0), p, 1.0).unwrap();
    for t in (0..=1000).step_by(50) {
        if t == 450 {
            n.write(ms(420), p, 2.0).unwrap();
        }
        n.poll(ms(t));
    }
    assert_eq!(*log.lock().unwrap(), vec![(0, 1.0), (100, 1.0), (500, 2.0)]);
    let r = process(&n);
    assert_eq!((r.runs, r.overruns), (3, 0), "due times with a stale port are not activations");
    assert_eq!(r.next_due, Some(ms(1100)), "the grid goes on as the unguarded process's");
    assert_eq!(r.trigger, Trigger::PeriodicWhileFresh(Duration::from_millis(100), Port(3)));
}

#[test]
fn a_late_poll_counts_missed_due_times_only_when_it_runs() {
    // D7.2 as for any periodic process: a late poll that runs adds the due times it missed.
    let log: Log = Arc::default();
    let mut n = node(10.0, 10_000, true, &log);
    n.poll(ms(0));
    n.poll(ms(350));
    assert_eq!(process(&n).runs, 0, "stale at 0 and at 350: not activated");
    assert_eq!(process(&n).overruns, 0, "nor counted");
    let p = input(&n);
    n.write(ms(360), p, 5.0).unwrap();
    // Due at 400, 500, 600 and 700 when it polls at 720, `In` fresh: one run, three missed.
    n.poll(ms(720));
    let r = process(&n);
    assert_eq!((r.runs, r.overruns, r.next_due), (1, 3, Some(ms(800))));
    assert_eq!(*log.lock().unwrap(), vec![(720, 5.0)]);
}

#[test]
fn a_guard_the_class_did_not_declare_is_refused() {
    let mut c = BehaviorClass::new("C");
    c.port(PortSpec::new("In", 0.0)).unwrap();
    let e = c.every_hz_while_fresh("P", 10.0, Port(9), |_| {}).unwrap_err();
    assert!(matches!(e, Error::UnknownPort { .. }), "{e:?}");
    let e = c.every_hz_while_fresh("P", 0.0, Port(3), |_| {}).unwrap_err();
    assert!(matches!(e, Error::InvalidRate { .. }), "{e:?}");
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("C", "B").unwrap();
    let e = n.add_process("B", "Q", Trigger::PeriodicWhileFresh(Duration::from_millis(10), Port(9)), |_| {});
    assert!(matches!(e, Err(Error::UnknownPort { .. })), "{e:?}");
}

// Checkpoints exist with the serde feature (the workspace's tests have it).
#[cfg(feature = "serde")]
#[test]
fn a_restored_node_keeps_the_guard() {
    let log: Log = Arc::default();
    let mut n = node(10.0, 150, true, &log);
    n.poll(ms(0));
    let json = serde_json::to_string(&n.snapshot()).unwrap();
    let l = log.clone();
    let mut copy = NodeCore::restore(serde_json::from_str(&json).unwrap(), |_, _| {
        // The body as the class has it (only `P`).
        let l = l.clone();
        Arc::new(move |ctx: &mut Ctx<'_>| {
            let Some(v) = ctx.float(Port(3)) else { return };
            l.lock().unwrap().push((ctx.now().as_nanos() / 1_000_000, v));
        })
    })
    .unwrap();
    copy.poll(ms(100));
    assert_eq!(process(&copy).runs, 0, "stale: not activated");
    let p = input(&copy);
    copy.write(ms(150), p, 3.0).unwrap();
    copy.poll(ms(200));
    assert_eq!(process(&copy).runs, 1);
    assert_eq!(*log.lock().unwrap(), vec![(200, 3.0)]);
}

/// One step of the property below: a write of `In` at the step's time, or a poll.
#[derive(Clone, Debug)]
enum Step {
    Write(u64, f64),
    Poll(u64),
}

fn steps() -> impl Strategy<Value = Vec<Step>> {
    prop::collection::vec(
        prop_oneof![(1u64..120, -10.0f64..10.0).prop_map(|(d, v)| Step::Write(d, v)), (1u64..120).prop_map(Step::Poll)],
        1..80,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn writes_what_the_unguarded_process_writes(
        hz in prop::sample::select(vec![3.0, 10.0, 20.0, 33.0, 100.0]),
        life_ms in 1u64..400,
        steps in steps(),
    ) {
        // Two nodes, one guarded and one not, given the same writes and polls (times advance by
        // each step's delay): the same log of activations that saw a value, the same `Out` at
        // every step, the same next due time; the guarded one's runs are exactly those.
        let (lg, lu): (Log, Log) = (Arc::default(), Arc::default());
        let mut g = node(hz, life_ms, true, &lg);
        let mut u = node(hz, life_ms, false, &lu);
        let (pg, pu) = (input(&g), input(&u));
        let out = |n: &NodeCore, t: u64| n.why_at(ms(t), "B", "Out").unwrap().value;
        let mut t = 0;
        for step in steps {
            match step {
                Step::Write(d, v) => {
                    t += d;
                    g.write(ms(t), pg, v).unwrap();
                    u.write(ms(t), pu, v).unwrap();
                }
                Step::Poll(d) => {
                    t += d;
                    g.poll(ms(t));
                    u.poll(ms(t));
                }
            }
            prop_assert_eq!(out(&g, t), out(&u, t));
        }
        prop_assert_eq!(&*lg.lock().unwrap(), &*lu.lock().unwrap());
        let (rg, ru) = (process(&g), process(&u));
        prop_assert_eq!(rg.next_due, ru.next_due);
        prop_assert_eq!(rg.runs, lg.lock().unwrap().len() as u64);
        prop_assert!(rg.runs <= ru.runs);
    }
}
