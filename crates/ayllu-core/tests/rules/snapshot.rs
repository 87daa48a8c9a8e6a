//! Checkpoints (`NodeCore::snapshot` / `NodeCore::restore`): a node restored from a snapshot
//! taken at any instant, given the same inputs as the original from then on, does what the
//! original does: the same values accepted, the same reports, the same messages sent.
//!
//! Two nodes in a BLE group over an in-test network that delays and drops by the test's
//! choice; node 1 has triggered, periodic and monostable-driven processes, aggregating ports
//! with windows, a Suppress and an Inhibit into its output, a remote connection from node 2,
//! control requests both ways and a process that changes the structure (R1-R6). At a random
//! step node 1 is snapshotted, put through JSON, and restored beside the original; from then on
//! both get every input and are compared after each.

use std::collections::HashMap;
use std::sync::Arc;

use ayllu_core::*;
use proptest::prelude::*;

#[derive(Copy, Clone, Debug)]
enum Step {
    /// Let this many milliseconds pass, then poll both nodes.
    Wait(u64),
    /// The application writes node 1's sonar.
    Sonar(i64),
    /// Node 2's avoid behavior writes (its connection suppresses node 1's output).
    Avoid,
    /// Deliver the oldest message in flight (or drop it).
    Deliver(bool),
    /// Deliver the last message delivered again (the network duplicated it: N1 drops it).
    Again,
    /// Node 2 asks node 1 for a LIST; node 1 asks node 2 to connect.
    Ask,
}

fn steps() -> impl Strategy<Value = Vec<Step>> {
    let step = prop_oneof![
        4 => (1u64..120).prop_map(Step::Wait),
        2 => (-5i64..50).prop_map(Step::Sonar),
        1 => Just(Step::Avoid),
        4 => any::<bool>().prop_map(Step::Deliver),
        1 => Just(Step::Again),
        1 => Just(Step::Ask),
    ];
    proptest::collection::vec(step, 1..160)
}

/// Process bodies by (class, process), for `restore`.
type Bodies = HashMap<(String, String), ProcessFn>;

fn define(node: &mut NodeCore, class: BehaviorClass, bodies: &mut Bodies) {
    for p in class.processes() {
        bodies.insert((class.name().to_owned(), p.name.clone()), p.body.clone());
    }
    node.define(class).unwrap();
}

/// Node `id` of the team (see the module docs).
fn node(id: u32, bodies: &mut Bodies) -> NodeCore {
    let mut n = NodeCore::new(NodeId(id));
    n.set_sequence_base(u64::from(id) * 1_000_000);
    let mut obs = BehaviorClass::new("Observer");
    let rotate = obs.port(PortSpec::new("Rotate", 0.0)).unwrap();
    let range = obs.port(PortSpec::new("Range", 0i64).lifespan(Duration::from_millis(250))).unwrap();
    let nearest =
        obs.port(PortSpec::new("Nearest", 0i64).kind(PortKind::Max).window(Duration::from_millis(90))).unwrap();
    let seen = obs.slot("Seen", 0i64).unwrap();
    let backing = obs.monostable("Backing").unwrap();
    obs.on_write("React", range, move |ctx| {
        let r = ctx.int(range).unwrap_or(0);
        let n = ctx.slot(seen).as_int().unwrap_or(0);
        ctx.set_slot(seen, n + r).unwrap();
        ctx.write(nearest, r).unwrap();
        if r < 10 {
            ctx.trigger(backing, Duration::from_millis(300));
        }
        if r == 7 {
            // A structure change from a process (R1): its outcome waits for the next run.
            ctx.change(Change::Create { class: "Motor".into(), name: format!("M{n}") }).ok();
        }
    })
    .unwrap();
    obs.on_monostable("Edge", backing, move |ctx| {
        let high = ctx.is_high(backing);
        ctx.write(rotate, if high { -1.0 } else { 0.5 }).unwrap();
    })
    .unwrap();
    obs.every_hz("Turn", 20.0, move |ctx| {
        let n = ctx.slot(seen).as_int().unwrap_or(0);
        ctx.write(Port::LOCAL, (n % 17) as f64 / 3.0).unwrap();
        ctx.write(rotate, 1.0).unwrap();
    })
    .unwrap();
    let mut motor = BehaviorClass::new("Motor");
    motor.port(PortSpec::new("Rotate", 0.0)).unwrap();
    motor.port(PortSpec::new("Load", 0.0).kind(PortKind::Sum).window(Duration::from_millis(200))).unwrap();
    let mut avoid = BehaviorClass::new("Avoid");
    avoid.port(PortSpec::new("Turn", 0.0)).unwrap();
    define(&mut n, obs, bodies);
    define(&mut n, motor, bodies);
    define(&mut n, avoid, bodies);
    n.create("Observer", "OBS").unwrap();
    n.create("Motor", "Motor").unwrap();
    n.create("Avoid", "Avoid").unwrap();
    let local = |b: &str, p: &str| Endpoint::local(b, p);
    n.connect(&local("OBS", "Rotate"), &local("Motor", "Rotate"), ConnectionKind::Normal, ConnectOptions::default())
        .unwrap();
    n.connect(&local("OBS", "Rotate"), &local("Motor", "Load"), ConnectionKind::Normal, ConnectOptions::default())
        .unwrap();
    n.connect(
        &local("Avoid", "Turn"),
        &local("Motor", "Rotate"),
        ConnectionKind::Inhibit(Duration::from_millis(150)),
        ConnectOptions::default(),
    )
    .unwrap();
    let other = NodeId(3 - id);
    n.connect(
        &local("Avoid", "Turn"),
        &Endpoint::node(other, "OBS", "Rotate"),
        ConnectionKind::Suppress(Duration::from_millis(400)),
        ConnectOptions::default(),
    )
    .unwrap();
    n.join("Peers");
    let config = BleConfig::new("Peers", "Rotate", 5.0).unwrap();
    n.ble_join("OBS", &config).unwrap();
    // An added process (its body is the behavior's own, not the class's).
    let total = n.port("Motor", "Load").unwrap().port();
    n.add_process("Motor", "Watch", Trigger::OnWrite(total), |ctx| {
        let _ = ctx.float(Port(4));
    })
    .unwrap();
    bodies.insert(
        ("Motor".into(), "Watch".into()),
        Arc::new(|ctx: &mut Ctx<'_>| {
            let _ = ctx.float(Port(4));
        }),
    );
    n
}

/// What a node shows: every port's value and report, BLE statuses, counters.
fn shown(n: &NodeCore, now: Instant) -> String {
    format!("{:?}\n{:?}\n{:?}", n.report_at(now), n.ble_statuses(), n.counters())
}

fn restored(n: &NodeCore, bodies: &Bodies) -> NodeCore {
    let json = serde_json::to_string(&n.snapshot()).unwrap();
    let snapshot: Snapshot = serde_json::from_str(&json).unwrap();
    NodeCore::restore(snapshot, |owner, process| {
        bodies
            .get(&(owner.to_owned(), process.to_owned()))
            .cloned()
            .unwrap_or_else(|| panic!("no body {owner}.{process}"))
    })
    .unwrap()
}

fn drain(n: &mut NodeCore) -> Vec<Outgoing> {
    std::iter::from_fn(|| n.pop_outgoing()).collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn a_restored_node_does_what_the_original_does(steps in steps(), at in 0usize..160) {
        let mut bodies = Bodies::new();
        let mut a = node(1, &mut bodies);
        let mut b = node(2, &mut Bodies::new());
        let mut copy: Option<NodeCore> = None;
        let mut now = Instant::ZERO;
        let mut flight: std::collections::VecDeque<(u32, Outgoing)> = Default::default();
        let mut last: Option<(u32, Outgoing)> = None;
        for (i, step) in steps.iter().enumerate() {
            if i == at.min(steps.len() - 1) {
                copy = Some(restored(&a, &bodies));
            }
            let mut both = |f: &mut dyn FnMut(&mut NodeCore)| {
                f(&mut a);
                if let Some(c) = copy.as_mut() {
                    f(c);
                }
            };
            match *step {
                Step::Wait(ms) => {
                    now += Duration::from_millis(ms);
                    both(&mut |n| {
                        n.poll(now);
                    });
                    b.poll(now);
                }
                Step::Sonar(v) => both(&mut |n| {
                    let r = n.port("OBS", "Range").unwrap();
                    let _ = n.write(now, r, v);
                }),
                Step::Avoid => {
                    let t = b.port("Avoid", "Turn").unwrap();
                    b.write(now, t, 0.25).unwrap();
                }
                Step::Deliver(keep) => {
                    if let Some((to, out)) = flight.pop_front() {
                        if keep {
                            last = Some((to, out.clone()));
                            if to == 1 {
                                both(&mut |n| n.receive(now, NodeId(2), out.message.clone()));
                            } else {
                                b.receive(now, NodeId(1), out.message);
                            }
                        }
                    }
                }
                Step::Again => {
                    if let Some((to, out)) = last.clone() {
                        if to == 1 {
                            both(&mut |n| n.receive(now, NodeId(2), out.message.clone()));
                        } else {
                            b.receive(now, NodeId(1), out.message);
                        }
                    }
                }
                Step::Ask => {
                    let _ = b.request(NodeId(1), ControlBody::List);
                    both(&mut |n| {
                        let _ = n.request_connect(
                            &Endpoint::node(NodeId(2), "Avoid", "Turn"),
                            &Endpoint::local("Motor", "Rotate"),
                            ConnectionKind::Suppress(Duration::from_millis(100)),
                            ConnectOptions::default(),
                        );
                    });
                }
            }
            let sent = drain(&mut a);
            if let Some(c) = copy.as_mut() {
                prop_assert_eq!(&drain(c), &sent, "step {}: {:?}", i, step);
                prop_assert_eq!(shown(c, now), shown(&a, now), "step {}: {:?}", i, step);
            }
            flight.extend(sent.into_iter().map(|o| (2, o)));
            flight.extend(drain(&mut b).into_iter().map(|o| (1, o)));
        }
        prop_assert!(copy.is_some());
    }
}

#[test]
fn a_snapshot_of_another_version_or_with_a_dangling_index_is_refused() {
    let mut bodies = Bodies::new();
    let mut a = node(1, &mut bodies);
    a.poll(Instant::from_millis(10));
    let json = serde_json::to_value(a.snapshot()).unwrap();
    let body = |_: &str, _: &str| -> ProcessFn { Arc::new(|_: &mut Ctx<'_>| {}) };

    let mut other = json.clone();
    other["version"] = 99.into();
    let e = NodeCore::restore(serde_json::from_value(other).unwrap(), body).err().unwrap();
    assert!(e.contains("version 99"), "{e}");

    let mut dangling = json.clone();
    dangling["conns"][0]["src"] = serde_json::json!([40, 0]);
    let e = NodeCore::restore(serde_json::from_value(dangling).unwrap(), body).err().unwrap();
    assert!(e.contains("joins no port"), "{e}");

    let mut schedule = json.clone();
    schedule["schedule"]["periodic"][0][1] = 77.into();
    let e = NodeCore::restore(serde_json::from_value(schedule).unwrap(), body).err().unwrap();
    assert!(e.contains("no process"), "{e}");

    // A schedule entry's period of zero (found by `a_damaged_snapshot_is_refused_or_runs`:
    // the next poll divided by it) or another than its process's is refused.
    for nanos in [0u64, 1] {
        let mut period = json.clone();
        period["schedule"]["periodic"][0][3] = serde_json::json!({ "nanos": nanos });
        let e = NodeCore::restore(serde_json::from_value(period).unwrap(), body).err().unwrap();
        assert!(e.contains("another period"), "{e}");
    }
}

/// Every number in `j`, as a path of keys and indices.
fn numbers(j: &serde_json::Value, path: &mut Vec<serde_json::Value>, out: &mut Vec<Vec<serde_json::Value>>) {
    match j {
        serde_json::Value::Number(_) => out.push(path.clone()),
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                path.push(i.into());
                numbers(x, path, out);
                path.pop();
            }
        }
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                path.push(k.as_str().into());
                numbers(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn at_path<'a>(j: &'a mut serde_json::Value, path: &[serde_json::Value]) -> &'a mut serde_json::Value {
    path.iter().fold(j, |j, k| match k {
        serde_json::Value::String(s) => &mut j[s.as_str()],
        n => &mut j[n.as_u64().unwrap() as usize],
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// A damaged checkpoint (numbers changed at random: indices, ids, times, counts) is refused
    /// or restores into a node that runs: never a panic, then or later.
    #[test]
    fn a_damaged_snapshot_is_refused_or_runs(changes in proptest::collection::vec((any::<prop::sample::Index>(), 0u64..70), 1..6)) {
        let mut bodies = Bodies::new();
        let mut a = node(1, &mut bodies);
        let mut b = node(2, &mut Bodies::new());
        for t in 1..40u64 {
            a.poll(Instant::from_millis(t * 37));
            b.poll(Instant::from_millis(t * 37));
            while let Some(o) = b.pop_outgoing() {
                a.receive(Instant::from_millis(t * 37), NodeId(2), o.message);
            }
        }
        let mut json = serde_json::to_value(a.snapshot()).unwrap();
        let mut paths = Vec::new();
        numbers(&json, &mut Vec::new(), &mut paths);
        for (ix, v) in &changes {
            let path = ix.get(&paths).clone();
            *at_path(&mut json, &path) = (*v).into();
        }
        let Ok(snapshot) = serde_json::from_value::<Snapshot>(json) else { return Ok(()) };
        let Ok(mut c) = NodeCore::restore(snapshot, |owner, process| {
            bodies.get(&(owner.to_owned(), process.to_owned())).cloned().unwrap_or_else(|| Arc::new(|_: &mut Ctx<'_>| {}))
        }) else {
            return Ok(());
        };
        for t in 40..80u64 {
            let now = Instant::from_millis(t * 37);
            c.poll(now);
            if let Ok(r) = c.port("OBS", "Range") {
                let _ = c.write(now, r, (t % 12) as i64);
            }
            b.poll(now);
            while let Some(o) = b.pop_outgoing() {
                c.receive(now, NodeId(2), o.message);
            }
            let _ = c.report_at(now);
            while c.pop_outgoing().is_some() {}
        }
    }
}
