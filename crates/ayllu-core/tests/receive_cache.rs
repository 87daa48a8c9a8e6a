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
