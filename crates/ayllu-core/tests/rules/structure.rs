//! Rule S9, structure changes at run time: behaviors and connections are created and removed
//! while the node runs; removing a behavior removes its connections in both directions;
//! messages for a behavior or port that does not exist are dropped and counted
//! (`UnknownBehavior`, `UnknownPort`); a `PortRef` to a removed behavior is an error (even if
//! the name is reused); a re-created name starts from fresh state.

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

const ME: NodeId = NodeId(1);

fn node() -> NodeCore {
    let mut n = NodeCore::new(ME);
    let mut relay = BehaviorClass::new("Relay");
    let input = relay.port(PortSpec::new("In", 0i64)).unwrap();
    let out = relay.port(PortSpec::new("Out", 0i64)).unwrap();
    relay.slot("Hidden", 0i64).unwrap();
    relay
        .on_write("Forward", input, move |ctx| {
            let v = ctx.read(input);
            ctx.write(out, v).unwrap();
        })
        .unwrap();
    relay.every_hz("Tick", 10.0, |_| {}).unwrap();
    n.define(relay).unwrap();
    n
}

fn connect(n: &mut NodeCore, from: (&str, &str), to: (&str, &str)) -> ConnectionId {
    n.connect(
        &Endpoint::local(from.0, from.1),
        &Endpoint::local(to.0, to.1),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )
    .unwrap()
}

fn port_msg(conn: u64, seq: u64, behavior: &str, port: &str, v: i64) -> Message {
    Message::Port(PortMessage {
        conn: ConnectionId(conn),
        seq,
        behavior: behavior.into(),
        port: port.into(),
        kind: ConnectionKind::Normal,
        priority: 0,
        value: Value::Int(v),
    })
}

#[test]
fn behaviors_and_connections_can_be_added_while_running() {
    // S9: create and connect between polls; the new wiring carries values at once.
    let mut n = node();
    n.create("Relay", "A").unwrap();
    n.poll(ms(0));
    n.poll(ms(100));
    n.create("Relay", "B").unwrap();
    let c = connect(&mut n, ("A", "Out"), ("B", "In"));
    n.write_named(ms(150), "A", "In", 7i64).unwrap();
    n.poll(ms(150)); // A.Forward writes A.Out -> B.In; B.Forward writes B.Out
    assert_eq!(n.read(n.port("B", "In").unwrap()).unwrap(), Value::Int(7));
    assert_eq!(n.read(n.port("B", "Out").unwrap()).unwrap(), Value::Int(7));
    // ... and removing the connection stops the flow.
    n.disconnect(c).unwrap();
    assert!(n.connection(c).is_none());
    n.write_named(ms(160), "A", "In", 8i64).unwrap();
    n.poll(ms(160));
    assert_eq!(n.read(n.port("A", "Out").unwrap()).unwrap(), Value::Int(8));
    assert_eq!(n.read(n.port("B", "In").unwrap()).unwrap(), Value::Int(7));
}

#[test]
fn removing_a_behavior_removes_its_connections_in_both_directions() {
    // S9: every connection into or out of the removed behavior goes with it; others stay.
    let mut n = node();
    for b in ["A", "B", "C"] {
        n.create("Relay", b).unwrap();
    }
    let ab = connect(&mut n, ("A", "Out"), ("B", "In"));
    let bc = connect(&mut n, ("B", "Out"), ("C", "In"));
    let ac = connect(&mut n, ("A", "Out"), ("C", "In"));
    let bb = connect(&mut n, ("B", "Out"), ("B", "In"));
    let to_group = n
        .connect(
            &Endpoint::local("B", "Out"),
            &Endpoint::group("g", "B", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    assert_eq!(n.report().connections.len(), 5);
    n.remove("B").unwrap();
    let left: Vec<ConnectionId> = n.report().connections.iter().map(|c| c.id).collect();
    assert_eq!(left, vec![ac]);
    for gone in [ab, bc, bb, to_group] {
        assert!(n.connection(gone).is_none());
        assert!(matches!(n.disconnect(gone), Err(Error::UnknownConnection { .. })));
    }
    let ids = |v: Vec<ConnectionInfo>| v.into_iter().map(|c| c.id).collect::<Vec<_>>();
    assert_eq!(ids(n.why("A", "Out").unwrap().outgoing), vec![ac]);
    assert_eq!(ids(n.why("C", "In").unwrap().incoming), vec![ac]);
    // A still reaches C, and nothing is sent toward the group any more.
    n.write_named(ms(1), "A", "Out", 4i64).unwrap();
    assert_eq!(n.read(n.port("C", "In").unwrap()).unwrap(), Value::Int(4));
    assert_eq!(n.outgoing_len(), 0);
    assert!(n.report().behaviors.iter().all(|b| b.name != "B"));
}

#[test]
fn windows_held_by_a_removed_behaviors_connections_end() {
    // S9 + S6: a removed behavior's suppression of another port ends with its connection.
    let mut n = node();
    n.create("Relay", "A").unwrap();
    n.create("Relay", "S").unwrap();
    n.create("Relay", "C").unwrap();
    connect(&mut n, ("A", "Out"), ("C", "In"));
    n.connect(
        &Endpoint::local("S", "Out"),
        &Endpoint::local("C", "In"),
        ConnectionKind::Suppress(Duration::from_secs(60)),
        ConnectOptions::default(),
    )
    .unwrap();
    n.write_named(ms(0), "S", "Out", 1i64).unwrap();
    assert_eq!(n.why("C", "In").unwrap().input_blocked, Some(DropCause::Suppressed));
    n.remove("S").unwrap();
    assert_eq!(n.why("C", "In").unwrap().input_blocked, None);
    n.write_named(ms(1), "A", "Out", 5i64).unwrap();
    assert_eq!(n.read(n.port("C", "In").unwrap()).unwrap(), Value::Int(5));
}

#[test]
fn messages_for_a_removed_behavior_are_dropped_and_counted() {
    // S9: a message from another node for a behavior that no longer exists is dropped and
    // counted as unknown_behavior; nothing panics.
    let mut n = node();
    n.create("Relay", "A").unwrap();
    n.receive(ms(1), NodeId(2), port_msg(9, 1, "A", "In", 1));
    assert_eq!(n.read(n.port("A", "In").unwrap()).unwrap(), Value::Int(1));
    n.remove("A").unwrap();
    n.receive(ms(2), NodeId(2), port_msg(9, 2, "A", "In", 2));
    n.receive(ms(3), NodeId(2), port_msg(9, 3, "Never", "In", 3));
    assert_eq!(n.counters().get(DropCause::UnknownBehavior), 2);
    n.poll(ms(4));
}

#[test]
fn messages_for_an_unknown_port_or_a_slot_are_dropped_and_counted() {
    // S9/S2: an unknown port name, or a slot (never connectable), is unknown_port.
    let mut n = node();
    n.create("Relay", "A").unwrap();
    n.receive(ms(1), NodeId(2), port_msg(9, 1, "A", "Nope", 1));
    n.receive(ms(2), NodeId(2), port_msg(9, 2, "A", "Hidden", 1));
    assert_eq!(n.counters().get(DropCause::UnknownPort), 2);
    assert_eq!(n.counters().get(DropCause::UnknownBehavior), 0);
    assert_eq!(n.report().behaviors[0].slots, vec![("Hidden".to_owned(), Value::Int(0))]);
}

#[test]
fn a_port_ref_to_a_removed_behavior_is_an_error_even_if_the_name_returns() {
    // S9: handles go stale with their behavior; they never silently reach a newcomer.
    let mut n = node();
    n.create("Relay", "A").unwrap();
    let old = n.port("A", "In").unwrap();
    let old_b = n.behavior_ref("A").unwrap();
    n.write(ms(1), old, 1i64).unwrap();
    n.remove("A").unwrap();
    assert!(matches!(n.read(old), Err(Error::UnknownBehavior { .. })));
    assert!(matches!(n.write(ms(2), old, 2i64), Err(Error::UnknownBehavior { .. })));
    assert!(matches!(n.get(old), Err(Error::UnknownBehavior { .. })));
    assert!(matches!(n.fresh(old), Err(Error::UnknownBehavior { .. })));
    assert!(matches!(n.reset(old), Err(Error::UnknownBehavior { .. })));
    assert!(matches!(n.port("A", "In"), Err(Error::UnknownBehavior { .. })));
    n.create("Relay", "A").unwrap();
    assert_ne!(n.behavior_ref("A").unwrap(), old_b);
    assert!(matches!(n.read(old), Err(Error::UnknownBehavior { .. })));
    assert!(n.write(ms(3), old, 3i64).is_err());
    let new = n.port("A", "In").unwrap();
    assert_eq!(n.read(new).unwrap(), Value::Int(0), "the stale handle wrote nothing");
}

#[test]
fn a_recreated_name_gets_fresh_state() {
    // S9: a new behavior under an old name starts from defaults: values, freshness, counters,
    // process statistics, no connections.
    let mut n = node();
    n.create("Relay", "A").unwrap();
    n.create("Relay", "B").unwrap();
    connect(&mut n, ("A", "Out"), ("B", "In"));
    n.write_named(ms(0), "A", "In", 42i64).unwrap();
    n.poll(ms(0));
    n.poll(ms(300));
    assert_eq!(n.read(n.port("B", "In").unwrap()).unwrap(), Value::Int(42));
    n.remove("A").unwrap();
    n.create("Relay", "A").unwrap();
    let rep = n.why("A", "Out").unwrap();
    assert_eq!(rep.value, Value::Int(0));
    assert!(!rep.fresh);
    assert_eq!(rep.accepted, 0);
    assert_eq!(rep.last_accepted, None);
    assert!(rep.outgoing.is_empty());
    let beh = n.report().behaviors.into_iter().find(|b| b.name == "A").unwrap();
    assert!(beh.processes.iter().all(|p| p.runs == 0 && p.overruns == 0));
    // Its periodic process is phase-locked to the new creation time (300 ms).
    assert_eq!(beh.processes.iter().find(|p| p.name == "Tick").unwrap().next_due, Some(ms(300)));
    // The old connection does not come back: writing A.Out no longer reaches B.
    n.write_named(ms(310), "A", "Out", 1i64).unwrap();
    assert_eq!(n.read(n.port("B", "In").unwrap()).unwrap(), Value::Int(42));
}

#[test]
fn removing_an_unknown_behavior_is_an_error() {
    // S9: misuse is reported.
    let mut n = node();
    let e = n.remove("Ghost").unwrap_err();
    assert_eq!(e, Error::UnknownBehavior { behavior: "Ghost".into() });
    n.create("Relay", "A").unwrap();
    n.remove("A").unwrap();
    assert!(n.remove("A").is_err());
}

#[test]
fn removing_a_behavior_with_work_pending_toward_it_is_safe() {
    // S9: a process that runs after its target was removed writes into the void, safely.
    let mut n = node();
    n.create("Relay", "A").unwrap();
    n.create("Relay", "B").unwrap();
    connect(&mut n, ("A", "Out"), ("B", "In"));
    n.write_named(ms(0), "A", "In", 1i64).unwrap(); // A.Forward pending, will write A.Out -> B.In
    n.remove("B").unwrap();
    n.poll(ms(0));
    assert_eq!(n.read(n.port("A", "Out").unwrap()).unwrap(), Value::Int(1));
    assert_eq!(n.counters().total(), 0, "nothing was sent to the removed behavior");
}
