//! Rules R1–R6 (docs/semantics.md, "Reconfiguration"): structure changes made from inside a
//! process. They are applied in order when the process returns, before the next process runs
//! (R1); their outcomes are what its next activation reads, and a refusal never panics the
//! node (R2); a behavior may remove itself (R3); a connection made during a wave does not carry
//! that wave (R4); cycles made at run time terminate (R5); requests to other nodes leave at
//! once and are answered as any request (R6).

use std::sync::{Arc, Mutex};

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

type Log = Arc<Mutex<Vec<String>>>;

fn sink() -> BehaviorClass {
    let mut c = BehaviorClass::new("Sink");
    c.port(PortSpec::new("In", 0i64)).unwrap();
    c.port(PortSpec::new("Out", 0i64)).unwrap();
    c
}

fn read(n: &NodeCore, b: &str, p: &str) -> Value {
    n.read(n.port(b, p).unwrap()).unwrap()
}

/// R1, R2: a process that recruits a helper (creates it and wires it) on its first activation;
/// the structure is unchanged while it runs, changed once it returns, and the next activation
/// reads what became of each change (the new connection's id, a refusal).
#[test]
fn r1_r2_changes_apply_when_the_process_returns_and_their_outcomes_come_back() {
    let log: Log = Arc::default();
    let mut boss = BehaviorClass::new("Boss");
    let out = boss.port(PortSpec::new("Out", 0i64)).unwrap();
    let go = boss.port(PortSpec::new("Go", 0i64)).unwrap();
    let l = log.clone();
    boss.on_write("Recruit", go, move |ctx| {
        let outcomes: Vec<String> = ctx.changes().iter().map(|o| format!("{:?}", o.result)).collect();
        l.lock().unwrap().push(format!("outcomes {outcomes:?}"));
        if ctx.int(go) == Some(1) {
            ctx.create("Sink", "Helper").unwrap();
            ctx.connect(
                &Endpoint::local("Boss", "Out"),
                &Endpoint::local("Helper", "In"),
                ConnectionKind::Normal,
                ConnectOptions::default(),
            )
            .unwrap();
            ctx.create("NoSuchClass", "Ghost").unwrap();
            // Not applied yet: the helper does not exist while this process runs.
            l.lock().unwrap().push(format!("pending {}", ctx.pending_changes().len()));
        }
        ctx.write(out, 10 * ctx.int(go).unwrap_or(0)).unwrap();
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(boss).unwrap();
    n.define(sink()).unwrap();
    n.create("Boss", "Boss").unwrap();
    n.write_named(ms(0), "Boss", "Go", 1i64).unwrap();
    assert!(n.port("Helper", "In").is_err(), "nothing is applied before the process runs");
    n.poll(ms(0));
    assert!(n.port("Helper", "In").is_ok(), "R1: applied when the process returned");
    assert_eq!(read(&n, "Helper", "In"), Value::Int(0), "R4: its own write came before the connection");
    assert!(n.behavior_ref("Ghost").is_err());
    n.write_named(ms(10), "Boss", "Go", 2i64).unwrap();
    n.poll(ms(10));
    assert_eq!(read(&n, "Helper", "In"), Value::Int(20), "the next write crosses the new connection");
    let snapshot = log.lock().unwrap().clone();
    assert_eq!(snapshot[0], "outcomes []");
    assert_eq!(snapshot[1], "pending 3");
    let conn = n.connections_between(&Endpoint::local("Boss", "Out"), &Endpoint::local("Helper", "In"));
    assert_eq!(conn.len(), 1);
    assert_eq!(
        snapshot[2],
        format!(
            "outcomes [\"Ok(Done)\", \"Ok(Connection({:?}))\", \"Err(UnknownClass {{ class: \\\"NoSuchClass\\\" }})\"]",
            conn[0]
        )
    );
    // The activation after that asked for nothing: the one after it reads no outcomes.
    n.write_named(ms(20), "Boss", "Go", 3i64).unwrap();
    n.poll(ms(20));
    assert_eq!(log.lock().unwrap()[3], "outcomes []");
}

/// R2: what is wrong whatever the node holds is refused at the call and never queued; a
/// change refused when applied is an outcome, and the changes after it still apply.
#[test]
fn r2_refusals_come_back_to_the_process_and_never_panic_the_node() {
    let seen: Arc<Mutex<Vec<Result<Applied, Error>>>> = Arc::default();
    let mut c = BehaviorClass::new("Rewirer");
    let tick = c.port(PortSpec::new("Tick", 0i64)).unwrap();
    let s = seen.clone();
    c.on_write("Act", tick, move |ctx| {
        assert_eq!(ctx.create("Sink", "").unwrap_err(), Error::EmptyName { what: "behavior" });
        let zero = ctx.connect(
            &Endpoint::local("A", "Out"),
            &Endpoint::local("A", "In"),
            ConnectionKind::Suppress(Duration::ZERO),
            ConnectOptions::default(),
        );
        assert!(matches!(zero, Err(Error::ZeroPeriod { .. })));
        assert_eq!(
            ctx.connect(
                &Endpoint::group("G", "A", "Out"),
                &Endpoint::local("A", "In"),
                ConnectionKind::Normal,
                ConnectOptions::default()
            ),
            Err(Error::GroupSource)
        );
        if ctx.int(tick) == Some(1) {
            ctx.remove("Nobody").unwrap();
            ctx.connect(
                &Endpoint::local("A", "Out"),
                &Endpoint::local("A", "Nope"),
                ConnectionKind::Normal,
                ConnectOptions::default(),
            )
            .unwrap();
            ctx.disconnect(ConnectionId(999)).unwrap();
            ctx.disconnect_between(&Endpoint::local("A", "Out"), &Endpoint::local("A", "In")).unwrap();
            ctx.create("Sink", "A").unwrap(); // a duplicate name
            ctx.create("Sink", "B").unwrap(); // still applied after the refusals
        } else {
            s.lock().unwrap().extend(ctx.changes().iter().map(|o| o.result.clone()));
        }
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.define(sink()).unwrap();
    n.create("Rewirer", "R").unwrap();
    n.create("Sink", "A").unwrap();
    n.write_named(ms(0), "R", "Tick", 1i64).unwrap();
    n.poll(ms(0));
    n.write_named(ms(1), "R", "Tick", 2i64).unwrap();
    n.poll(ms(1));
    let seen = seen.lock().unwrap().clone();
    assert_eq!(seen.len(), 6, "the three refused at the call were never queued: {seen:?}");
    assert_eq!(seen[0], Err(Error::UnknownBehavior { behavior: "Nobody".into() }));
    assert_eq!(seen[1], Err(Error::UnknownPort { behavior: "A".into(), port: "Nope".into() }));
    assert_eq!(seen[2], Err(Error::UnknownConnection { id: 999 }));
    assert!(matches!(seen[3], Err(Error::NoConnectionBetween { .. })));
    assert_eq!(seen[4], Err(Error::DuplicateName { what: "behavior", name: "A".into() }));
    assert_eq!(seen[5], Ok(Applied::Done));
    assert!(n.behavior_ref("B").is_ok());
}

/// R3: a behavior that removes itself (handing its task over to a successor it creates in the
/// same activation). Its connections go at once (with the windows they held), its activations
/// still queued are dropped, the changes after its own removal still apply, and what it wrote
/// before returning stays written.
#[test]
fn r3_a_process_that_removes_its_own_behavior() {
    let runs: Arc<Mutex<Vec<String>>> = Arc::default();
    let mut quitter = BehaviorClass::new("Quitter");
    let go = quitter.port(PortSpec::new("Go", 0i64)).unwrap();
    let out = quitter.port(PortSpec::new("Out", 0i64)).unwrap();
    let r = runs.clone();
    quitter
        .on_write("Quit", go, move |ctx| {
            r.lock().unwrap().push(format!("quit {}", ctx.behavior()));
            ctx.write(out, 7i64).unwrap();
            let me = ctx.behavior().to_owned();
            ctx.remove(&me).unwrap();
            ctx.create("Sink", "Successor").unwrap();
            ctx.connect(
                &Endpoint::local("Successor", "Out"),
                &Endpoint::local("Watcher", "In"),
                ConnectionKind::Normal,
                ConnectOptions::default(),
            )
            .unwrap();
        })
        .unwrap();
    let r = runs.clone();
    // A second process of the same behavior, triggered by the same write: queued behind Quit,
    // it must not run once its behavior is gone.
    quitter.on_write("Also", go, move |_| r.lock().unwrap().push("also".into())).unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(quitter).unwrap();
    n.define(sink()).unwrap();
    n.create("Quitter", "Q").unwrap();
    n.create("Sink", "Watcher").unwrap();
    n.connect(
        &Endpoint::local("Q", "Out"),
        &Endpoint::local("Watcher", "In"),
        ConnectionKind::Suppress(Duration::from_secs(5)),
        ConnectOptions::default(),
    )
    .unwrap();
    n.connect(
        &Endpoint::local("Q", "Out"),
        &Endpoint::local("Watcher", "Out"),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )
    .unwrap();
    n.write_named(ms(0), "Q", "Go", 1i64).unwrap();
    n.poll(ms(0));
    assert_eq!(
        *runs.lock().unwrap(),
        vec!["quit Q".to_owned()],
        "the queued activation of the removed behavior is dropped"
    );
    assert!(n.behavior_ref("Q").is_err());
    assert_eq!(read(&n, "Watcher", "Out"), Value::Int(7), "its write before returning crossed its connection");
    assert!(n.report().connections.iter().all(|c| c.source.behavior() != "Q"), "its connections are gone");
    // The suppression window its connection opened ended with the connection (S9).
    let w = n.why("Watcher", "In").unwrap();
    assert!(w.windows.is_empty(), "windows: {:?}", w.windows);
    // The successor took over the wiring.
    n.write_named(ms(1), "Successor", "Out", 9i64).unwrap();
    assert_eq!(read(&n, "Watcher", "In"), Value::Int(9));
    n.poll(ms(2));
    assert_eq!(runs.lock().unwrap().len(), 1);
}

/// R4: a process asks for a connection that its own write would cross, and writes after
/// asking. The wave of that write is over before the connection exists (the write propagates
/// synchronously inside the process, S5), so it carries nothing; the connection carries the
/// next wave. A triggered process the write queued runs after the change is applied, and its
/// own write does cross it.
#[test]
fn r4_a_connection_made_during_a_wave_does_not_carry_that_wave() {
    let mut c = BehaviorClass::new("Wirer");
    let go = c.port(PortSpec::new("Go", 0i64)).unwrap();
    let out = c.port(PortSpec::new("Out", 0i64)).unwrap();
    let echo = c.port(PortSpec::new("Echo", 0i64)).unwrap();
    c.on_write("Wire", go, move |ctx| {
        if ctx.int(go) == Some(1) {
            ctx.connect(
                &Endpoint::local("W", "Out"),
                &Endpoint::local("S", "In"),
                ConnectionKind::Normal,
                ConnectOptions::default(),
            )
            .unwrap();
            ctx.connect(
                &Endpoint::local("W", "Echo"),
                &Endpoint::local("S", "Out"),
                ConnectionKind::Normal,
                ConnectOptions::default(),
            )
            .unwrap();
        }
        ctx.write(out, 100 + ctx.int(go).unwrap_or(0)).unwrap();
    })
    .unwrap();
    // Triggered by Out: queued by the write above, it runs after the process returned.
    c.on_write("Echo", out, move |ctx| {
        let v = ctx.int(out).unwrap_or(0);
        ctx.write(echo, v).unwrap();
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.define(sink()).unwrap();
    n.create("Wirer", "W").unwrap();
    n.create("Sink", "S").unwrap();
    n.write_named(ms(0), "W", "Go", 1i64).unwrap();
    n.poll(ms(0));
    assert_eq!(read(&n, "S", "In"), Value::Int(0), "the wave that ran while the change waited is not carried");
    assert_eq!(read(&n, "S", "Out"), Value::Int(101), "the next process runs after the change is applied");
    n.write_named(ms(1), "W", "Go", 2i64).unwrap();
    n.poll(ms(1));
    assert_eq!(read(&n, "S", "In"), Value::Int(102));
}

/// R5: a process that closes a cycle of connections at run time (A.Out -> B.In -> B.Out ->
/// A.Out, through B's pass-through). Every wave through it ends: each port is written at
/// most once per wave (S5), the revisit is counted, and nothing loops.
#[test]
fn r5_a_cycle_created_at_run_time_terminates() {
    let mut relay = BehaviorClass::new("Relay");
    let i = relay.port(PortSpec::new("In", 0i64)).unwrap();
    let o = relay.port(PortSpec::new("Out", 0i64)).unwrap();
    let go = relay.port(PortSpec::new("Go", false)).unwrap();
    relay
        .on_write("Close", go, move |ctx| {
            ctx.connect(
                &Endpoint::local("B", "Out"),
                &Endpoint::local("A", "In"),
                ConnectionKind::Normal,
                ConnectOptions::default(),
            )
            .unwrap();
        })
        .unwrap();
    let _ = (i, o);
    let mut n = NodeCore::new(NodeId(1));
    n.define(relay).unwrap();
    n.create("Relay", "A").unwrap();
    n.create("Relay", "B").unwrap();
    for (s, d) in [(("A", "In"), ("A", "Out")), (("A", "Out"), ("B", "In")), (("B", "In"), ("B", "Out"))] {
        n.connect(
            &Endpoint::local(s.0, s.1),
            &Endpoint::local(d.0, d.1),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    }
    n.write_named(ms(0), "A", "Go", true).unwrap();
    n.poll(ms(0));
    assert_eq!(n.connections_between(&Endpoint::local("B", "Out"), &Endpoint::local("A", "In")).len(), 1);
    let revisits = n.counters().get(DropCause::WaveRevisit);
    n.write_named(ms(1), "A", "In", 5i64).unwrap();
    for (b, p) in [("A", "In"), ("A", "Out"), ("B", "In"), ("B", "Out")] {
        assert_eq!(read(&n, b, p), Value::Int(5), "{b}.{p}");
    }
    assert_eq!(n.counters().get(DropCause::WaveRevisit), revisits + 1, "the wave came back to A.In once, and stopped");
    // And again: every wave through the cycle ends.
    for k in 0..100i64 {
        n.write_named(ms(2 + k as u64), "B", "Out", k).unwrap();
    }
    assert_eq!(read(&n, "A", "Out"), Value::Int(99));
}

/// R5 with processes: two behaviors whose processes each create a connection into the other
/// at run time, so each one's write triggers the other's process. The loop is held back by
/// D7.3 (once per poll, then 1 ms), never spinning.
#[test]
fn r5_a_cycle_of_processes_created_at_run_time_is_held_back() {
    let mut c = BehaviorClass::new("Pinger");
    let i = c.port(PortSpec::new("In", 0i64)).unwrap();
    let o = c.port(PortSpec::new("Out", 0i64)).unwrap();
    let go = c.port(PortSpec::new("Go", false)).unwrap();
    c.on_write("Wire", go, move |ctx| {
        let me = ctx.behavior().to_owned();
        let other = if me == "P" { "Q" } else { "P" };
        ctx.connect(
            &Endpoint::local(&me, "Out"),
            &Endpoint::local(other, "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    })
    .unwrap();
    c.on_write("Bounce", i, move |ctx| {
        let v = ctx.int(i).unwrap_or(0);
        ctx.write(o, v + 1).unwrap();
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("Pinger", "P").unwrap();
    n.create("Pinger", "Q").unwrap();
    n.write_named(ms(0), "P", "Go", true).unwrap();
    n.write_named(ms(0), "Q", "Go", true).unwrap();
    n.poll(ms(0));
    n.write_named(ms(1), "P", "In", 1i64).unwrap();
    n.poll(ms(1));
    let after_one = read(&n, "Q", "In");
    assert!(matches!(after_one, Value::Int(x) if (2..=4).contains(&x)), "{after_one:?}");
    assert_eq!(n.poll_at(), Some(ms(2)), "the loop waits 1 ms (D7.3)");
    for t in 2..50 {
        n.poll(ms(t));
    }
    let Value::Int(v) = read(&n, "P", "In") else { panic!() };
    assert!(v < 200, "at most a few bounces per millisecond, not a spin: {v}");
}

/// R6: a process asks another node to connect one of its ports back to this node; the request
/// leaves at once, the answer comes back in `request_status` on a later activation.
#[test]
fn r6_requests_to_other_nodes_from_a_process() {
    let status: Arc<Mutex<Option<RequestStatus>>> = Arc::default();
    let id: Arc<Mutex<Option<RequestId>>> = Arc::default();
    let mut c = BehaviorClass::new("Asker");
    let tick = c.port(PortSpec::new("Tick", 0i64)).unwrap();
    c.port(PortSpec::new("In", 0i64)).unwrap();
    let (s, i) = (status.clone(), id.clone());
    c.on_write("Ask", tick, move |ctx| {
        let mut held = i.lock().unwrap();
        match *held {
            None => {
                let r = ctx
                    .request_connect(
                        &Endpoint::node(NodeId(2), "Far", "Out"),
                        &Endpoint::local("Asker", "In"),
                        ConnectionKind::Normal,
                        ConnectOptions::default(),
                    )
                    .unwrap();
                *held = Some(r);
            }
            Some(r) => *s.lock().unwrap() = ctx.request_status(r),
        }
    })
    .unwrap();
    let mut a = NodeCore::new(NodeId(1));
    a.define(c).unwrap();
    a.create("Asker", "Asker").unwrap();
    let mut b = NodeCore::new(NodeId(2));
    b.define(sink()).unwrap();
    b.create("Sink", "Far").unwrap();
    a.write_named(ms(0), "Asker", "Tick", 1i64).unwrap();
    a.poll(ms(0));
    let out: Vec<Outgoing> = std::iter::from_fn(|| a.pop_outgoing()).collect();
    assert_eq!(out.len(), 1, "the request left at once");
    for o in out {
        b.receive(ms(1), NodeId(1), o.message);
    }
    for o in std::iter::from_fn(|| b.pop_outgoing()).collect::<Vec<_>>() {
        a.receive(ms(2), NodeId(2), o.message);
    }
    a.write_named(ms(3), "Asker", "Tick", 2i64).unwrap();
    a.poll(ms(3));
    assert!(matches!(*status.lock().unwrap(), Some(RequestStatus::Done(ReplyBody::Connection(_)))));
    b.write_named(ms(4), "Far", "Out", 42i64).unwrap();
    for o in std::iter::from_fn(|| b.pop_outgoing()).collect::<Vec<_>>() {
        a.receive(ms(5), NodeId(2), o.message);
    }
    assert_eq!(read(&a, "Asker", "In"), Value::Int(42));
}

/// R6 with access rules: a process's request obeys the other node's rules like any other
/// (D9.2): refused, and the refusal comes back to the process.
#[test]
fn r6_a_process_request_obeys_the_receivers_access_rules() {
    let mut a = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("Asker");
    let tick = c.port(PortSpec::new("Tick", 0i64)).unwrap();
    c.port(PortSpec::new("In", 0i64)).unwrap();
    c.on_write("Ask", tick, move |ctx| {
        ctx.request_disconnect(NodeId(2), ConnectionId(1));
    })
    .unwrap();
    a.define(c).unwrap();
    a.create("Asker", "Asker").unwrap();
    let mut b = NodeCore::new(NodeId(2));
    b.set_access(Access { ports: Allow::Everyone, structure: Allow::Nobody });
    a.write_named(ms(0), "Asker", "Tick", 1i64).unwrap();
    a.poll(ms(0));
    for o in std::iter::from_fn(|| a.pop_outgoing()).collect::<Vec<_>>() {
        b.receive(ms(1), NodeId(1), o.message);
    }
    for o in std::iter::from_fn(|| b.pop_outgoing()).collect::<Vec<_>>() {
        a.receive(ms(2), NodeId(2), o.message);
    }
    let st = a.request_status(RequestId(1)).unwrap();
    assert!(matches!(&st, RequestStatus::Failed(e) if e.contains("not allowed")), "{st:?}");
}

/// Groups and BLE from a process: join, leave and a BLE membership are applied at return.
#[test]
fn groups_and_ble_from_a_process() {
    let mut c = BehaviorClass::new("Joiner");
    let tick = c.port(PortSpec::new("Tick", 0i64)).unwrap();
    c.port(PortSpec::new("Rotate", 0.0)).unwrap();
    c.on_write("Join", tick, move |ctx| match ctx.int(tick) {
        Some(1) => {
            ctx.join("Team").unwrap();
            ctx.join("Other").unwrap();
            ctx.ble_join("J", &BleConfig::new("Peers", "Rotate", 1.0).unwrap()).unwrap();
        }
        _ => {
            ctx.leave("Other").unwrap();
        }
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("Joiner", "J").unwrap();
    n.write_named(ms(0), "J", "Tick", 1i64).unwrap();
    n.poll(ms(0));
    assert_eq!(n.groups().iter().map(|g| g.to_string()).collect::<Vec<_>>(), ["Team", "Other", "Peers"]);
    assert!(n.ble_status("J").unwrap().is_some());
    n.write_named(ms(1), "J", "Tick", 2i64).unwrap();
    n.poll(ms(1));
    assert_eq!(n.groups().iter().map(|g| g.to_string()).collect::<Vec<_>>(), ["Team", "Peers"]);
}

/// The journal records each change as the process's effect, and the calls the core makes to
/// apply them are not journaled again (a replay repeats them through its player).
#[test]
fn changes_are_journaled_as_process_effects() {
    let mut c = BehaviorClass::new("Boss");
    let go = c.port(PortSpec::new("Go", 0i64)).unwrap();
    c.on_write("Recruit", go, move |ctx| {
        ctx.create("Sink", "H").unwrap();
        ctx.request_disconnect(NodeId(9), ConnectionId(3));
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.define(sink()).unwrap();
    n.create("Boss", "B").unwrap();
    n.start_journal(1000);
    n.write_named(ms(0), "B", "Go", 1i64).unwrap();
    n.poll(ms(0));
    let mut entries = Vec::new();
    n.take_journal(&mut entries);
    let names: Vec<&'static str> = entries
        .iter()
        .filter_map(|e| match &e.event {
            Event::Run { .. } => Some("run"),
            Event::ProcessChange(c) if matches!(**c, Change::Create { .. }) => Some("change"),
            Event::ProcessRequest { .. } => Some("request"),
            Event::Create { .. } => Some("create"),
            Event::Request { .. } => Some("outer request"),
            _ => None,
        })
        .collect();
    assert_eq!(names, ["run", "change", "request"]);
}

/// Validation of a whole list against the structure as it stands (a transaction's PREPARE):
/// names the list creates count, names it removes do not, and nothing changes.
#[test]
fn validate_changes_tries_a_list_without_applying_it() {
    let mut n = NodeCore::new(NodeId(1));
    n.define(sink()).unwrap();
    n.create("Sink", "A").unwrap();
    let before = n.report().behaviors.len();
    let good = [
        Change::Create { class: "Sink".into(), name: "B".into() },
        Change::Connect {
            source: Endpoint::local("A", "Out"),
            destination: Endpoint::local("B", "In"),
            kind: ConnectionKind::Normal,
            priority: 0,
        },
    ];
    assert_eq!(n.validate_changes(&good), Ok(()));
    let bad = [
        Change::Remove { name: "A".into() },
        Change::Connect {
            source: Endpoint::local("A", "Out"),
            destination: Endpoint::node(NodeId(2), "X", "Y"),
            kind: ConnectionKind::Normal,
            priority: 0,
        },
    ];
    assert_eq!(n.validate_changes(&bad), Err((1, Error::UnknownBehavior { behavior: "A".into() })));
    let port = [Change::Connect {
        source: Endpoint::local("A", "Oops"),
        destination: Endpoint::local("A", "In"),
        kind: ConnectionKind::Normal,
        priority: 0,
    }];
    assert_eq!(n.validate_changes(&port), Err((0, Error::UnknownPort { behavior: "A".into(), port: "Oops".into() })));
    assert_eq!(n.report().behaviors.len(), before);
}
