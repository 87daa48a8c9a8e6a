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
    copy_process(&mut c, hz, input, out, guarded, log);
    c
}

/// Process `P` of `c` at `hz`: "no value, no output" — it copies `input` to `out` and logs
/// `(now_ms, value)` when `input` holds a fresh value; guarded by `input` or not.
fn copy_process(c: &mut BehaviorClass, hz: f64, input: Port, out: Port, guarded: bool, log: &Log) {
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

/// Every way a guard port can accept a value or lose it, against the unguarded process: the
/// schedule remembers a guard found stale until the port accepts (crate::schedule), and these
/// check that it forgets it on every path (checkpoints need the serde feature, which the
/// workspace's tests have).
#[cfg(feature = "serde")]
mod paths {
    use super::*;

    /// What the guard port of [`paths`]'s nodes is: its kind, lifespan and window.
    #[derive(Clone, Debug)]
    struct GuardSpec {
        kind: PortKind,
        life_ms: Option<u64>,
        window_ms: Option<u64>,
    }

    fn guard_spec() -> impl Strategy<Value = GuardSpec> {
        let kind = prop::sample::select(vec![
            PortKind::Normal,
            PortKind::Max,
            PortKind::Min,
            PortKind::Sum,
            PortKind::Priority,
        ]);
        (kind, prop::option::of(1u64..300), prop::option::of(1u64..300)).prop_map(|(kind, life_ms, window_ms)| {
            GuardSpec { kind, life_ms, window_ms: window_ms.filter(|_| kind.is_aggregating()) }
        })
    }

    /// Process bodies by (class, process), for `restore`.
    type Bodies = std::collections::HashMap<(String, String), ProcessFn>;

    /// A node for [`paths`]: class `C` with the guard port `In` (as `g` says), `Out` and
    /// `Kick`; process `P` at `hz` copying `In` to `Out` and logging it when fresh (guarded by
    /// `In` or not), and `K`, triggered by `Kick`, writing `Kick`'s value into `In` from inside a
    /// process. Class `S` has `Out`, wired to `C.In` locally at priority 1. Both `C` and `S` are
    /// created; node 2 is a remote peer whose messages arrive on connection 7.
    fn path_node(g: &GuardSpec, hz: f64, guarded: bool, log: &Log, bodies: &mut Bodies) -> NodeCore {
        let mut c = BehaviorClass::new("C");
        let mut spec = PortSpec::new("In", 0.0).kind(g.kind);
        if let Some(l) = g.life_ms {
            spec = spec.lifespan(Duration::from_millis(l));
        }
        if let Some(w) = g.window_ms {
            spec = spec.window(Duration::from_millis(w));
        }
        let input = c.port(spec).unwrap();
        let out = c.port(PortSpec::new("Out", 0.0)).unwrap();
        let kick = c.port(PortSpec::new("Kick", 0.0)).unwrap();
        copy_process(&mut c, hz, input, out, guarded, log);
        c.on_write("K", kick, move |ctx| {
            let v = ctx.float(kick).unwrap_or(0.0);
            let _ = ctx.write(input, v);
        })
        .unwrap();
        let mut s = BehaviorClass::new("S");
        s.port(PortSpec::new("Out", 0.0)).unwrap();
        let mut n = NodeCore::new(NodeId(1));
        for class in [c, s] {
            for p in class.processes() {
                bodies.insert((class.name().to_owned(), p.name.clone()), p.body.clone());
            }
            n.define(class).unwrap();
        }
        n.create("C", "C").unwrap();
        n.create("S", "S").unwrap();
        wire(&mut n);
        n
    }

    fn wire(n: &mut NodeCore) {
        let options = ConnectOptions { priority: 1 };
        n.connect(&Endpoint::local("S", "Out"), &Endpoint::local("C", "In"), ConnectionKind::Normal, options).unwrap();
    }

    /// One step of [`paths`], each after `d` ms: a way for `In` to accept a value (or lose
    /// it), or a poll.
    #[derive(Clone, Debug)]
    enum PathStep {
        /// The application writes `In`.
        Write(u64, f64),
        /// `S.Out` is written: the value reaches `In` along the Local connection.
        Local(u64, f64),
        /// Node 2's message on connection 7 at this priority.
        Remote(u64, f64, i32),
        /// `Kick` is written: process `K` writes `In` at the next poll.
        Kick(u64, f64),
        /// `In` is reset (an aggregating port empties).
        Reset(u64),
        /// Node 2 is lost: what it supplied to an aggregating port is released.
        Lost(u64),
        /// `C` is removed (its ports and schedule entries with it) and created again, rewired.
        Recreate(u64),
        /// Both nodes are checkpointed and restored (through JSON).
        Restore,
        Poll(u64),
    }

    fn path_steps() -> impl Strategy<Value = Vec<PathStep>> {
        let d = 0u64..120;
        let v = -10.0f64..10.0;
        prop::collection::vec(
            prop_oneof![
                3 => (d.clone(), v.clone()).prop_map(|(d, v)| PathStep::Write(d, v)),
                3 => (d.clone(), v.clone()).prop_map(|(d, v)| PathStep::Local(d, v)),
                3 => (d.clone(), v.clone(), 0i32..3).prop_map(|(d, v, p)| PathStep::Remote(d, v, p)),
                2 => (d.clone(), v).prop_map(|(d, v)| PathStep::Kick(d, v)),
                1 => d.clone().prop_map(PathStep::Reset),
                1 => d.clone().prop_map(PathStep::Lost),
                1 => d.clone().prop_map(PathStep::Recreate),
                1 => Just(PathStep::Restore),
                6 => d.prop_map(PathStep::Poll),
            ],
            1..100,
        )
    }

    fn restored(n: &NodeCore, bodies: &Bodies) -> NodeCore {
        let json = serde_json::to_string(&n.snapshot()).unwrap();
        NodeCore::restore(serde_json::from_str(&json).unwrap(), |class, process| {
            bodies[&(class.to_owned(), process.to_owned())].clone()
        })
        .unwrap()
    }

    /// Apply `step` to `n` at time `*t` (advanced by the step's delay); `seq` numbers node 2's
    /// messages.
    fn apply(n: &mut NodeCore, bodies: &Bodies, t: &mut u64, seq: u64, step: &PathStep) {
        match *step {
            PathStep::Write(d, v) => {
                *t += d;
                let _ = n.write_named(ms(*t), "C", "In", v);
            }
            PathStep::Local(d, v) => {
                *t += d;
                n.write_named(ms(*t), "S", "Out", v).unwrap();
            }
            PathStep::Remote(d, v, priority) => {
                *t += d;
                let m = PortMessage {
                    conn: ConnectionId(7),
                    seq,
                    behavior: "C".into(),
                    port: "In".into(),
                    kind: ConnectionKind::Normal,
                    priority,
                    value: Value::Float(v),
                };
                n.receive(ms(*t), NodeId(2), Message::Port(m));
            }
            PathStep::Kick(d, v) => {
                *t += d;
                n.write_named(ms(*t), "C", "Kick", v).unwrap();
            }
            PathStep::Reset(d) => {
                *t += d;
                n.advance_to(ms(*t));
                let r = n.port("C", "In").unwrap();
                n.reset(r).unwrap();
            }
            PathStep::Lost(d) => {
                *t += d;
                n.node_lost(ms(*t), NodeId(2));
            }
            PathStep::Recreate(d) => {
                *t += d;
                n.advance_to(ms(*t));
                n.remove("C").unwrap();
                n.create("C", "C").unwrap();
                wire(n);
            }
            PathStep::Restore => *n = restored(n, bodies),
            PathStep::Poll(d) => {
                *t += d;
                n.poll(ms(*t));
            }
        }
    }

    #[test]
    fn a_port_made_fresh_between_two_due_times_by_any_path_is_seen_at_the_next() {
        // Stale at 0, 100 and 200 (each a due time: the schedule knows it stale after the first);
        // made fresh between two due times by each path in turn, then left to go stale again:
        // activated at the next due time after each.
        for (i, path) in ["write", "local", "remote", "process", "restore"].into_iter().enumerate() {
            let (log, mut bodies) = (Log::default(), Bodies::new());
            let g = GuardSpec { kind: PortKind::Normal, life_ms: Some(200), window_ms: None };
            let mut n = path_node(&g, 10.0, true, &log, &mut bodies);
            for t in [0, 100, 200] {
                n.poll(ms(t));
            }
            let at = 250;
            match path {
                "write" => n.write_named(ms(at), "C", "In", 1.0).unwrap(),
                "local" => n.write_named(ms(at), "S", "Out", 1.0).unwrap(),
                "remote" => {
                    let m = PortMessage {
                        conn: ConnectionId(7),
                        seq: 1,
                        behavior: "C".into(),
                        port: "In".into(),
                        kind: ConnectionKind::Normal,
                        priority: 0,
                        value: Value::Float(1.0),
                    };
                    n.receive(ms(at), NodeId(2), Message::Port(m));
                }
                "process" => {
                    n.write_named(ms(at - 10), "C", "Kick", 1.0).unwrap();
                    n.poll(ms(at));
                }
                "restore" => {
                    // Written on a copy taken while the schedule knew the port stale: the copy
                    // restored from it knows nothing, and reads the port.
                    let mut copy = restored(&n, &bodies);
                    copy.write_named(ms(at), "C", "In", 1.0).unwrap();
                    n = restored(&copy, &bodies);
                }
                _ => unreachable!(),
            }
            for t in [300, 400, 500] {
                n.poll(ms(t));
            }
            assert_eq!(*log.lock().unwrap(), vec![(300, 1.0), (400, 1.0)], "path {i}: {path}");
            let p = n.report().behaviors.into_iter().find(|b| b.name == "C").unwrap().processes;
            assert_eq!(p.iter().find(|p| p.name == "P").unwrap().runs, 2, "{path}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn every_path_to_a_fresh_port_activates_as_the_unguarded_process_sees_it(
            g in guard_spec(),
            hz in prop::sample::select(vec![3.0, 10.0, 20.0, 33.0, 100.0]),
            steps in path_steps(),
        ) {
            // As `writes_what_the_unguarded_process_writes`, over every way a port accepts a value
            // or loses it (a write, a Local connection, a remote message, a process's write, a
            // reset, a lost supplier, its behavior re-created, a checkpoint restored), on every
            // kind of port with and without lifespan and window.
            let (lg, lu): (Log, Log) = (Arc::default(), Arc::default());
            let (mut bg, mut bu) = (Bodies::new(), Bodies::new());
            let mut g_node = path_node(&g, hz, true, &lg, &mut bg);
            let mut u_node = path_node(&g, hz, false, &lu, &mut bu);
            let (mut tg, mut tu) = (0, 0);
            for (seq, step) in steps.iter().enumerate() {
                apply(&mut g_node, &bg, &mut tg, seq as u64 + 1, step);
                apply(&mut u_node, &bu, &mut tu, seq as u64 + 1, step);
                prop_assert_eq!(&*lg.lock().unwrap(), &*lu.lock().unwrap(), "after {:?}", step);
            }
            let runs = |n: &NodeCore| {
                let c = n.report().behaviors.into_iter().find(|b| b.name == "C").unwrap();
                let p = c.processes.into_iter().find(|p| p.name == "P").unwrap();
                (p.runs, p.next_due)
            };
            let ((rg, dg), (ru, du)) = (runs(&g_node), runs(&u_node));
            prop_assert_eq!(dg, du);
            prop_assert!(rg <= ru);
        }
    }
}
