//! The receive path remembers, per incoming connection, the port its last message was applied
//! to (so the next message needs no name lookups). These tests pin down that the memory never
//! changes where a message goes: a sender may reuse a connection id for another port (after a
//! restart, say), and the destination behavior may be removed and another created under the
//! same name.

use ayllu_core::*;

const PEER: NodeId = NodeId(9);

fn at(ms: u64) -> Instant {
    Instant::from_millis(ms)
}

/// A node with behaviors `A` and `B` of class `Rx`, each with int ports `In` and `Other`.
fn node() -> NodeCore {
    let mut n = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("Rx");
    c.port(PortSpec::new("In", 0i64)).unwrap();
    c.port(PortSpec::new("Other", 0i64)).unwrap();
    n.define(c).unwrap();
    n.create("Rx", "A").unwrap();
    n.create("Rx", "B").unwrap();
    n
}

fn message(seq: u64, behavior: &str, port: &str, v: i64) -> Message {
    Message::Port(PortMessage {
        conn: ConnectionId(1),
        seq,
        behavior: behavior.into(),
        port: port.into(),
        kind: ConnectionKind::Normal,
        priority: 0,
        value: Value::Int(v),
    })
}

fn read(n: &NodeCore, behavior: &str, port: &str) -> Value {
    n.read(n.port(behavior, port).unwrap()).unwrap()
}

#[test]
fn a_reused_connection_id_goes_where_its_message_says() {
    let mut n = node();
    n.receive(at(1), PEER, message(1, "A", "In", 1));
    n.receive(at(2), PEER, message(2, "A", "In", 2));
    // Same connection id, another port, then another behavior.
    n.receive(at(3), PEER, message(3, "A", "Other", 3));
    n.receive(at(4), PEER, message(4, "B", "In", 4));
    assert_eq!(read(&n, "A", "In"), Value::Int(2));
    assert_eq!(read(&n, "A", "Other"), Value::Int(3));
    assert_eq!(read(&n, "B", "In"), Value::Int(4));
    // Older than the newest on this connection: stale, wherever it points.
    n.receive(at(5), PEER, message(2, "A", "In", 99));
    assert_eq!(read(&n, "A", "In"), Value::Int(2));
    assert_eq!(n.counters().get(DropCause::Stale), 1);
}

#[test]
fn a_removed_and_recreated_behavior_is_found_again() {
    let mut n = node();
    n.receive(at(1), PEER, message(1, "A", "In", 1));
    n.remove("A").unwrap();
    n.receive(at(2), PEER, message(2, "A", "In", 2));
    assert_eq!(n.counters().get(DropCause::UnknownBehavior), 1);
    n.create("Rx", "A").unwrap();
    n.receive(at(3), PEER, message(3, "A", "In", 3));
    assert_eq!(read(&n, "A", "In"), Value::Int(3));
    // A behavior created in the freed slot under another name does not receive A's messages.
    n.remove("A").unwrap();
    n.create("Rx", "C").unwrap();
    n.receive(at(4), PEER, message(4, "A", "In", 4));
    assert_eq!(read(&n, "C", "In"), Value::Int(0));
    assert_eq!(n.counters().get(DropCause::UnknownBehavior), 2);
}

/// A message whose name strings are the very `Arc`s of earlier ones (as a sender's connection
/// shares them among its messages): the receiver trusts the port it remembers for them only
/// while no behavior was removed, and then finds it again by name.
fn shared(seq: u64, behavior: &std::sync::Arc<str>, port: &std::sync::Arc<str>, v: i64) -> Message {
    Message::Port(PortMessage {
        conn: ConnectionId(1),
        seq,
        behavior: behavior.clone(),
        port: port.clone(),
        kind: ConnectionKind::Normal,
        priority: 0,
        value: Value::Int(v),
    })
}

#[test]
fn the_same_name_strings_find_a_recreated_behavior_and_not_its_successor() {
    let mut n = node();
    let (a, b, input) = ("A".into(), "B".into(), "In".into());
    n.receive(at(1), PEER, shared(1, &a, &input, 1));
    assert_eq!(read(&n, "A", "In"), Value::Int(1));
    // Removed, and another behavior takes its slot: the remembered port is not A's any more.
    n.remove("A").unwrap();
    n.create("Rx", "C").unwrap();
    n.receive(at(2), PEER, shared(2, &a, &input, 2));
    assert_eq!(read(&n, "C", "In"), Value::Int(0));
    assert_eq!(n.counters().get(DropCause::UnknownBehavior), 1);
    // A again (in another slot): found by name with the same strings.
    n.create("Rx", "A").unwrap();
    n.receive(at(3), PEER, shared(3, &a, &input, 3));
    assert_eq!(read(&n, "A", "In"), Value::Int(3));
    // Re-created in the slot it had: found again, and C is untouched.
    n.remove("C").unwrap();
    n.remove("A").unwrap();
    n.create("Rx", "A").unwrap();
    n.receive(at(4), PEER, shared(4, &a, &input, 4));
    assert_eq!(read(&n, "A", "In"), Value::Int(4));
    // The same connection id re-pointed with other strings.
    n.receive(at(5), PEER, shared(5, &b, &input, 5));
    assert_eq!(read(&n, "B", "In"), Value::Int(5));
    n.receive(at(6), PEER, shared(6, &a, &input, 6));
    assert_eq!(read(&n, "A", "In"), Value::Int(6));
    assert_eq!(n.counters().get(DropCause::UnknownBehavior), 1);
    assert_eq!(n.seq_table_resets(), 0);
}

#[test]
fn a_remembered_port_is_not_trusted_after_65536_removals() {
    // The receiver counts removals in 16 bits: after exactly 65 536 of them the count is what
    // it was when the port was remembered, and the slot holds another behavior.
    let mut n = node();
    let (a, input) = ("A".into(), "In".into());
    n.receive(at(1), PEER, shared(1, &a, &input, 1));
    n.remove("A").unwrap();
    n.create("Rx", "C").unwrap();
    for _ in 1..65_536 {
        n.remove("B").unwrap();
        n.create("Rx", "B").unwrap();
    }
    n.receive(at(2), PEER, shared(2, &a, &input, 2));
    assert_eq!(read(&n, "C", "In"), Value::Int(0));
    assert_eq!(n.counters().get(DropCause::UnknownBehavior), 1);
}

#[test]
fn a_connection_id_re_pointed_without_end_clears_the_table_as_new_ids_do() {
    // Each re-pointing keeps the message's name strings alive; they are bounded like the
    // table's entries (16 384), and the table is cleared and counted when they are full.
    let mut n = node();
    let (a, b, input) = (std::sync::Arc::<str>::from("A"), std::sync::Arc::<str>::from("B"), "In".into());
    for seq in 1..=16_384u64 {
        // Fresh strings each time, so that every message re-points the connection.
        let name = if seq % 2 == 0 { a.to_string() } else { b.to_string() };
        n.receive(at(seq), PEER, shared(seq, &name.as_str().into(), &input, seq as i64));
    }
    assert_eq!(n.seq_table_resets(), 0);
    n.receive(at(16_385), PEER, shared(16_385, &b, &input, -1));
    assert_eq!(n.seq_table_resets(), 1);
    assert_eq!(read(&n, "B", "In"), Value::Int(-1));
    // The connection's newest number survived the clearing.
    n.receive(at(16_386), PEER, shared(16_384, &a, &input, -2));
    assert_eq!(n.counters().get(DropCause::Stale), 1);
    assert_eq!(read(&n, "A", "In"), Value::Int(16_384));
}

#[test]
fn a_node_stays_send_and_sync() {
    // The sequence table's entries change through shared references (atomics, not `Cell`s),
    // which must not cost the node its `Sync` (an `RwLock<NodeCore>` needs it).
    fn both<T: Send + Sync>() {}
    both::<NodeCore>();
}

/// The table remembers where a port is (not only its slot and index): after its behavior is
/// removed and re-created in the same slot, every later message, not only the first one that
/// finds it again, reaches the new behavior's port, and the removed one's memory is never
/// written (run under AddressSanitizer, a stale address would be a use after free).
#[test]
fn messages_after_a_recreation_reach_the_new_port_every_time() {
    let mut n = node();
    let (a, input) = ("A".into(), "In".into());
    for seq in 1..=3 {
        n.receive(at(seq), PEER, shared(seq, &a, &input, seq as i64));
    }
    n.remove("A").unwrap();
    n.create("Rx", "A").unwrap();
    for seq in 4..=8 {
        n.receive(at(seq), PEER, shared(seq, &a, &input, seq as i64 * 10));
        assert_eq!(read(&n, "A", "In"), Value::Int(seq as i64 * 10), "message {seq}");
    }
    // Messages by name (fresh strings each time) take the same remembered port.
    for seq in 9..=11 {
        n.receive(at(seq), PEER, message(seq, "A", "In", seq as i64));
        assert_eq!(read(&n, "A", "In"), Value::Int(seq as i64), "message {seq}");
    }
    assert_eq!(n.why("A", "In").unwrap().accepted, 8);
}

/// `receive_all_shared` (one call for a batch, each key hashed once for the hint and the
/// lookup) leaves a node exactly as one `receive_shared` a message does: the same values, the
/// same counts by cause (stale, unknown, absorbed), through re-pointed connection ids, stale
/// messages, several senders and connections, and a control request among them.
#[test]
fn a_batch_is_received_as_its_messages_one_by_one() {
    let on = |conn: u64, seq: u64, behavior: &str, port: &str, v: i64| match message(seq, behavior, port, v) {
        Message::Port(m) => Message::Port(PortMessage { conn: ConnectionId(conn), ..m }),
        control => control,
    };
    let batches: Vec<Vec<(NodeId, Message)>> = vec![
        vec![(PEER, on(1, 1, "A", "In", 1)), (NodeId(7), on(1, 1, "B", "In", 2)), (PEER, on(2, 1, "A", "Other", 3))],
        vec![
            (PEER, on(1, 2, "A", "In", 4)),
            (PEER, on(1, 2, "A", "In", 5)),
            (PEER, on(1, 3, "B", "Other", 6)),
            (NodeId(7), on(1, 1, "B", "In", 7)),
            (PEER, Message::Control(ControlMessage { id: 1, body: ControlBody::List })),
            (NodeId(7), on(3, 1, "Nobody", "In", 8)),
            (NodeId(7), on(1, 2, "B", "Nowhere", 9)),
        ],
        vec![],
        vec![(NodeId(8), on(5, 9, "A", "In", 10))],
    ];
    let (mut one, mut all) = (node(), node());
    for (t, batch) in batches.iter().enumerate() {
        for (from, m) in batch {
            one.receive_shared(at(t as u64 + 1), *from, m);
        }
        all.receive_all_shared(at(t as u64 + 1), &mut batch.iter().map(|(from, m)| (*from, m)));
        for (behavior, port) in [("A", "In"), ("A", "Other"), ("B", "In"), ("B", "Other")] {
            assert_eq!(read(&all, behavior, port), read(&one, behavior, port), "{behavior}.{port} after batch {t}");
        }
        assert_eq!(format!("{:?}", all.counters()), format!("{:?}", one.counters()), "after batch {t}");
        let (a, b): (Vec<_>, Vec<_>) =
            (std::iter::from_fn(|| all.pop_outgoing()).collect(), std::iter::from_fn(|| one.pop_outgoing()).collect());
        assert_eq!(a, b, "answers after batch {t}");
    }
    assert!(one.counters().get(DropCause::Stale) > 0 && one.counters().get(DropCause::UnknownBehavior) > 0);
}
