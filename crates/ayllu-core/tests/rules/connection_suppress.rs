//! Rule S6 *Suppress* (the paper's: it only blocks; Brooks's replacing suppression is
//! OverrideIn, see connection_override_in.rs).

use crate::common;

use std::sync::Arc;

use ayllu_core::*;
use common::*;

/// S --Suppress(100ms)--> D <--Normal-- A, and D --Normal--> E.
fn suppressed() -> (NodeCore, ConnectionId) {
    let mut node = wiring(&["S", "A", "D", "E"]);
    let s = link(&mut node, "S", "D", ConnectionKind::Suppress(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    (node, s)
}

#[test]
fn suppress_message_is_not_written() {
    // S6 Suppress: m is not written.
    let (mut node, _) = suppressed();
    put(&mut node, at(0), "S", 7);
    assert_eq!(value(&node, "D"), 0);
    assert_eq!(value(&node, "E"), 0);
    assert_eq!(accepted(&node, "D"), 0);
    assert_eq!(node.why("D", V).unwrap().last_accepted, None);
}

#[test]
fn suppress_blocks_every_connection_write_for_the_period() {
    // S6 Suppress: no connection may write d until t + p; refused writes are counted.
    let (mut node, s) = suppressed();
    put(&mut node, at(0), "A", 1);
    assert_eq!(value(&node, "D"), 1);
    put(&mut node, at(10), "S", 0);
    put(&mut node, at(20), "A", 2);
    put(&mut node, at(109), "A", 3);
    assert_eq!(value(&node, "D"), 1);
    assert_eq!(value(&node, "E"), 1);
    assert_eq!(dropped(&node, "D", DropCause::Suppressed), 2);
    assert_eq!(node.counters().get(DropCause::Suppressed), 2);
    let why = node.why("D", V).unwrap();
    assert_eq!(why.windows.len(), 1);
    assert_eq!((why.windows[0].kind, why.windows[0].holder), (WindowKind::Suppress, held_by(s)));
    assert_eq!(why.windows[0].ends, at(110));
}

#[test]
fn suppress_lapses_after_the_period() {
    // S6 Suppress: the block lasts until t + p, not longer (window end is exclusive).
    let (mut node, _) = suppressed();
    put(&mut node, at(0), "S", 0);
    node.write_named(Instant::from_nanos(ms(100).as_nanos() - 1), "A", V, 1i64).unwrap();
    assert_eq!(value(&node, "D"), 0);
    put(&mut node, at(100), "A", 2);
    assert_eq!(value(&node, "D"), 2);
    assert_eq!(value(&node, "E"), 2);
    assert!(node.why("D", V).unwrap().windows.is_empty());
}

#[test]
fn suppress_is_refreshed_by_each_message() {
    // S6: every window is refreshed: end := max(end, t + p).
    let (mut node, _) = suppressed();
    put(&mut node, at(0), "S", 0);
    put(&mut node, at(80), "S", 0);
    put(&mut node, at(150), "A", 1);
    assert_eq!(value(&node, "D"), 0, "refreshed at 80ms, so blocked until 180ms");
    put(&mut node, at(180), "A", 2);
    assert_eq!(value(&node, "D"), 2);
}

#[test]
fn a_later_shorter_suppress_does_not_shorten_the_window() {
    // S6: refreshed, never shortened — a second, shorter Suppress leaves the longer one in force.
    let (mut node, _) = suppressed();
    node.create("Relay", "Q").unwrap();
    link(&mut node, "Q", "D", ConnectionKind::Suppress(ms(10)));
    put(&mut node, at(0), "S", 0); // until 100ms
    put(&mut node, at(50), "Q", 0); // until 60ms
    put(&mut node, at(70), "A", 1);
    put(&mut node, at(99), "A", 2);
    assert_eq!(value(&node, "D"), 0);
    put(&mut node, at(100), "A", 3);
    assert_eq!(value(&node, "D"), 3);
}

#[test]
fn a_shorter_period_from_the_same_holder_does_not_shorten_the_window() {
    // S6/S8: a remote holder's message carries its period; a later, shorter one from the same
    // (node, connection) refreshes to max(end, t + p), never earlier.
    let mut node = wiring(&["D", "E"]);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    let peer = NodeId(9);
    let message = |seq: u64, kind: ConnectionKind| {
        Message::Port(PortMessage {
            conn: ConnectionId(5),
            seq,
            behavior: Arc::from("D"),
            port: Arc::from(V),
            kind,
            priority: 0,
            value: Value::Int(seq as i64),
        })
    };
    node.receive(at(0), peer, message(1, ConnectionKind::Suppress(ms(100))));
    node.receive(at(50), peer, message(2, ConnectionKind::Suppress(ms(10))));
    let why = node.why("D", V).unwrap();
    assert_eq!(why.windows.len(), 1);
    assert_eq!(why.windows[0].holder, Source::connection(peer, ConnectionId(5)));
    assert_eq!(why.windows[0].ends, at(100));
    node.receive(at(99), NodeId(8), message(1, ConnectionKind::Normal));
    assert_eq!(value(&node, "D"), 0);
    node.receive(at(100), NodeId(8), message(2, ConnectionKind::Normal));
    assert_eq!(value(&node, "D"), 2);
}

#[test]
fn own_behavior_writes_are_stored_and_propagated_while_suppressed() {
    // S6: suppression affects connection writes only; the behavior's own writes go through.
    let (mut node, _) = suppressed();
    put(&mut node, at(0), "S", 0);
    put(&mut node, at(10), "D", 5);
    assert_eq!(value(&node, "D"), 5);
    assert_eq!(value(&node, "E"), 5);
    assert_eq!(dropped(&node, "D", DropCause::Suppressed), 0);
}

#[test]
fn own_process_writes_go_through_a_suppressed_port() {
    // S6 + S7: a process of the suppressed behavior writes its own port; it is stored and
    // propagates, while a connection into that port is refused.
    let mut node = wiring(&["S", "A", "E"]);
    let mut counter = BehaviorClass::new("Counter");
    let v = counter.port(PortSpec::new(V, 0i64)).unwrap();
    counter
        .every_hz("count", 100.0, move |ctx| {
            let n = ctx.read(v).as_int().unwrap_or(0);
            ctx.write(v, n + 1).unwrap();
        })
        .unwrap();
    node.define(counter).unwrap();
    node.create("Counter", "D").unwrap();
    link(&mut node, "S", "D", ConnectionKind::Suppress(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    put(&mut node, at(0), "S", 0);
    node.poll(at(0));
    node.poll(at(10));
    assert_eq!(value(&node, "D"), 2);
    assert_eq!(value(&node, "E"), 2);
    put(&mut node, at(15), "A", 100);
    assert_eq!(value(&node, "D"), 2);
    assert_eq!(dropped(&node, "D", DropCause::Suppressed), 1);
}

#[test]
fn suppress_blocks_override_pass_holders_too() {
    // S6: a plain Suppress blocks everything, pass holders included.
    let (mut node, _) = suppressed();
    node.create("Relay", "O").unwrap();
    let o = link(&mut node, "O", "D", ConnectionKind::OverrideIn(ms(500)));
    put(&mut node, at(0), "O", 1);
    assert_eq!((value(&node, "D"), value(&node, "E")), (1, 1));
    put(&mut node, at(10), "S", 0);
    put(&mut node, at(20), "O", 2);
    assert_eq!((value(&node, "D"), value(&node, "E")), (1, 1));
    assert_eq!(dropped(&node, "D", DropCause::Suppressed), 1);
    // The override still holds its (refreshed) pass: once the Suppress lapses, it writes and
    // everyone else is still overridden.
    assert!(node
        .why("D", V)
        .unwrap()
        .windows
        .iter()
        .any(|w| w.kind == WindowKind::OverrideIn && w.holder == held_by(o) && w.ends == at(520)));
    put(&mut node, at(110), "O", 3);
    assert_eq!((value(&node, "D"), value(&node, "E")), (3, 3));
    put(&mut node, at(120), "A", 4);
    assert_eq!(value(&node, "D"), 3);
}

#[test]
fn suppress_does_not_block_propagation_of_what_the_port_already_holds() {
    // S6: Suppress blocks writes into d, not the outputs of d (that is Inhibit).
    let (mut node, _) = suppressed();
    put(&mut node, at(0), "S", 0);
    let why = node.why("D", V).unwrap();
    assert_eq!(why.input_blocked, Some(DropCause::Suppressed));
    assert_eq!(why.internal_output_blocked, None);
    assert_eq!(why.connection_output_blocked, None);
}
