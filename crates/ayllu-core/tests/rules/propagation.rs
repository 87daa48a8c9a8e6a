//! Rule S5: propagation is synchronous and depth-first; a port is visited (accepts a value) at
//! most once per wave, so wiring cycles terminate and second arrivals count as WaveRevisit.

use crate::common;

use std::sync::Arc;

use ayllu_core::*;
use common::*;

/// Relays plus "Total" behaviors (Sum int port `V`) and "Peak" behaviors (Max int port `V`).
fn wiring_with(relays: &[&str], totals: &[&str], peaks: &[&str]) -> NodeCore {
    let mut node = wiring(relays);
    let mut total = BehaviorClass::new("Total");
    total.port(PortSpec::new(V, 0i64).sum()).unwrap();
    node.define(total).unwrap();
    let mut peak = BehaviorClass::new("Peak");
    peak.port(PortSpec::new(V, 0i64).max()).unwrap();
    node.define(peak).unwrap();
    for name in totals {
        node.create("Total", name).unwrap();
    }
    for name in peaks {
        node.create("Peak", name).unwrap();
    }
    node
}

fn normal(node: &mut NodeCore, from: &str, to: &str) -> ConnectionId {
    link(node, from, to, ConnectionKind::Normal)
}

fn supplier(node: &NodeCore, name: &str) -> Option<Source> {
    node.why(name, V).unwrap().supplier
}

#[test]
fn propagation_is_synchronous() {
    // S5: the whole wave runs inside the write; no poll is needed and none is scheduled.
    let mut node = wiring(&["A", "B", "C", "D"]);
    normal(&mut node, "A", "B");
    normal(&mut node, "B", "C");
    normal(&mut node, "C", "D");
    put(&mut node, at(0), "A", 4);
    assert_eq!(value(&node, "D"), 4);
    assert_eq!(node.poll_at(), None);
}

#[test]
fn propagation_is_depth_first() {
    // S5: A -> B, A -> C, B -> C. Depth-first, C is reached through B (A -> B -> C) before
    // A's second connection is followed; that second arrival is then a revisit.
    // (Breadth-first would reach C from A first.)
    let mut node = wiring(&["A", "B", "C"]);
    normal(&mut node, "A", "B");
    let a_c = normal(&mut node, "A", "C");
    let b_c = normal(&mut node, "B", "C");
    put(&mut node, at(0), "A", 1);
    assert_eq!(supplier(&node, "C"), Some(held_by(b_c)));
    assert_ne!(supplier(&node, "C"), Some(held_by(a_c)));
    assert_eq!(dropped(&node, "C", DropCause::WaveRevisit), 1);
    assert_eq!(accepted(&node, "C"), 1);
}

#[test]
fn depth_first_follows_a_long_branch_to_the_end_before_a_short_one() {
    // S5: A -> B -> B2 -> L is finished before A -> C -> L is started, although the second
    // path is shorter. B2 is a Sum port holding 100, so the two paths deliver different
    // values to L: 101 along the deep path, 1 along the short one.
    let mut node = wiring_with(&["A", "B", "C", "L"], &["B2"], &[]);
    normal(&mut node, "A", "B");
    normal(&mut node, "A", "C");
    normal(&mut node, "B", "B2");
    let deep = normal(&mut node, "B2", "L");
    normal(&mut node, "C", "L");
    put(&mut node, at(0), "B2", 100);
    assert_eq!(value(&node, "L"), 100);
    put(&mut node, at(1), "A", 1);
    assert_eq!(value(&node, "L"), 101);
    assert_eq!(supplier(&node, "L"), Some(held_by(deep)));
    assert_eq!(value(&node, "C"), 1);
    assert_eq!(dropped(&node, "L", DropCause::WaveRevisit), 1);
}

#[test]
fn outgoing_connections_are_followed_in_the_order_they_were_made() {
    // S5 (determinism): of two ways into L, the one through the earlier connection wins.
    let mut node = wiring(&["A", "X", "Y", "L"]);
    normal(&mut node, "A", "Y");
    normal(&mut node, "A", "X");
    let y_l = normal(&mut node, "Y", "L");
    normal(&mut node, "X", "L");
    put(&mut node, at(0), "A", 1);
    assert_eq!(supplier(&node, "L"), Some(held_by(y_l)));
}

#[test]
fn a_diamond_delivers_once_per_wave() {
    // S5: each port is visited at most once per wave; D is a Sum port, so a double visit
    // would show as 2 x 5.
    let mut node = wiring_with(&["A", "B", "C"], &["D"], &[]);
    normal(&mut node, "A", "B");
    normal(&mut node, "A", "C");
    let b_d = normal(&mut node, "B", "D");
    normal(&mut node, "C", "D");
    put(&mut node, at(0), "A", 5);
    assert_eq!(value(&node, "D"), 5);
    assert_eq!(supplier(&node, "D"), Some(held_by(b_d)));
    assert_eq!(dropped(&node, "D", DropCause::WaveRevisit), 1);
    assert_eq!(node.counters().get(DropCause::WaveRevisit), 1);
    // The next wave visits D again.
    put(&mut node, at(1), "A", 2);
    assert_eq!(value(&node, "D"), 7);
    assert_eq!(dropped(&node, "D", DropCause::WaveRevisit), 2);
}

#[test]
fn a_refused_arrival_does_not_use_up_the_visit() {
    // S5 + decision: "visited" means "accepted a value". D (Max) holds 50: the first arrival
    // (5, via C) is absorbed, the second (105, via the Sum port B holding 100) is accepted.
    let mut node = wiring_with(&["A", "C"], &["B"], &["D"]);
    normal(&mut node, "A", "C");
    normal(&mut node, "A", "B");
    normal(&mut node, "C", "D");
    let b_d = normal(&mut node, "B", "D");
    put(&mut node, at(0), "D", 50);
    put(&mut node, at(0), "B", 100);
    assert_eq!(value(&node, "D"), 100);
    put(&mut node, at(1), "A", 5);
    assert_eq!(value(&node, "D"), 105);
    assert_eq!(supplier(&node, "D"), Some(held_by(b_d)));
    let why = node.why("D", V).unwrap();
    assert_eq!(why.counters.get(DropCause::Absorbed), 1);
    assert_eq!(why.counters.get(DropCause::WaveRevisit), 0);
}

#[test]
fn a_wiring_cycle_terminates() {
    // S5: A -> B -> C -> A. The wave stops when it comes back to A (WaveRevisit).
    let mut node = wiring(&["A", "B", "C"]);
    normal(&mut node, "A", "B");
    normal(&mut node, "B", "C");
    normal(&mut node, "C", "A");
    put(&mut node, at(0), "A", 1);
    for n in ["A", "B", "C"] {
        assert_eq!(value(&node, n), 1, "{n}");
    }
    assert_eq!(dropped(&node, "A", DropCause::WaveRevisit), 1);
    assert_eq!(node.counters().get(DropCause::WaveRevisit), 1);
    assert_eq!(accepted(&node, "A"), 1);
    // Entering the cycle elsewhere goes all the way round to the entry point.
    put(&mut node, at(1), "B", 2);
    for n in ["A", "B", "C"] {
        assert_eq!(value(&node, n), 2, "{n}");
    }
    assert_eq!(dropped(&node, "B", DropCause::WaveRevisit), 1);
    assert_eq!(node.counters().get(DropCause::WaveRevisit), 2);
}

#[test]
fn a_cycle_through_a_sum_port_adds_once_per_wave() {
    // S5: without the once-per-wave rule T -> R -> T would add forever.
    let mut node = wiring_with(&["R"], &["T"], &[]);
    normal(&mut node, "T", "R");
    normal(&mut node, "R", "T");
    put(&mut node, at(0), "T", 5);
    assert_eq!((value(&node, "T"), value(&node, "R")), (5, 5));
    put(&mut node, at(1), "T", 1);
    assert_eq!((value(&node, "T"), value(&node, "R")), (6, 6));
    assert_eq!(dropped(&node, "T", DropCause::WaveRevisit), 2);
}

#[test]
fn a_self_loop_terminates() {
    // S5: A -> A is a cycle of length one.
    let mut node = wiring(&["A", "B"]);
    normal(&mut node, "A", "A");
    normal(&mut node, "A", "B");
    put(&mut node, at(0), "A", 3);
    assert_eq!((value(&node, "A"), value(&node, "B")), (3, 3));
    assert_eq!(dropped(&node, "A", DropCause::WaveRevisit), 1);
    assert_eq!(node.why("A", V).unwrap().supplier, Some(Source::internal(NODE)));
}

#[test]
fn a_message_from_another_node_starts_its_own_wave_into_a_cycle() {
    // S5: a remote message is applied at once, as a new wave; the cycle still terminates.
    let mut node = wiring(&["A", "B", "C"]);
    normal(&mut node, "A", "B");
    normal(&mut node, "B", "C");
    normal(&mut node, "C", "A");
    node.receive(
        at(0),
        NodeId(2),
        Message::Port(PortMessage {
            conn: ConnectionId(1),
            seq: 1,
            behavior: Arc::from("B"),
            port: Arc::from(V),
            kind: ConnectionKind::Normal,
            priority: 0,
            value: Value::Int(8),
        }),
    );
    for n in ["A", "B", "C"] {
        assert_eq!(value(&node, n), 8, "{n}");
    }
    assert_eq!(dropped(&node, "B", DropCause::WaveRevisit), 1);
}

#[test]
fn remote_hops_leave_through_the_outbox_in_depth_first_order() {
    // S5: remote hops are asynchronous: they are queued, in depth-first order, not applied.
    // A -> B (local, made first), A -> n2 (remote), B -> n3 (remote): depth-first queues
    // B's hop to n3 before A's own hop to n2.
    let mut node = wiring(&["A", "B"]);
    let options = ConnectOptions::default();
    normal(&mut node, "A", "B");
    node.connect(&Endpoint::local("A", V), &Endpoint::node(NodeId(2), "X", V), ConnectionKind::Normal, options)
        .unwrap();
    node.connect(&Endpoint::local("B", V), &Endpoint::node(NodeId(3), "Y", V), ConnectionKind::Normal, options)
        .unwrap();
    put(&mut node, at(0), "A", 1);
    let first = node.pop_outgoing().unwrap();
    let second = node.pop_outgoing().unwrap();
    assert!(node.pop_outgoing().is_none());
    assert_eq!(first.to, Destination::Node(NodeId(3)));
    assert_eq!(second.to, Destination::Node(NodeId(2)));
}
