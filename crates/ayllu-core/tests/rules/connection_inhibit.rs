//! Rule S6 *Inhibit*: nothing propagates out of the destination for the period.

use crate::common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use ayllu_core::*;
use common::*;

/// I --Inhibit(100ms)--> D <--Normal-- A, and D --Normal--> E.
fn inhibited() -> (NodeCore, ConnectionId) {
    let mut node = wiring(&["I", "A", "D", "E"]);
    let i = link(&mut node, "I", "D", ConnectionKind::Inhibit(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    (node, i)
}

#[test]
fn inhibit_message_is_not_written() {
    // S6 Inhibit: m is not written.
    let (mut node, i) = inhibited();
    put(&mut node, at(0), "I", 7);
    assert_eq!(value(&node, "D"), 0);
    assert_eq!(accepted(&node, "D"), 0);
    let why = node.why("D", V).unwrap();
    assert_eq!(why.windows.len(), 1);
    assert_eq!(
        (why.windows[0].kind, why.windows[0].holder, why.windows[0].ends),
        (WindowKind::Inhibit, held_by(i), at(100))
    );
}

#[test]
fn nothing_propagates_out_while_inhibited() {
    // S6 Inhibit: nothing propagates out of d until t + p — neither connection writes nor
    // the behavior's own writes.
    let (mut node, _) = inhibited();
    put(&mut node, at(0), "A", 1);
    assert_eq!(value(&node, "E"), 1);
    put(&mut node, at(10), "I", 0);
    put(&mut node, at(20), "A", 2);
    put(&mut node, at(30), "D", 3);
    assert_eq!(value(&node, "E"), 1);
    assert_eq!(accepted(&node, "E"), 1);
    assert_eq!(dropped(&node, "D", DropCause::Inhibited), 2);
    assert_eq!(node.counters().get(DropCause::Inhibited), 2);
}

#[test]
fn an_inhibited_port_still_stores_and_reads_what_reaches_it() {
    // S6: an inhibited port still stores what reaches it and its behavior can read it.
    let (mut node, _) = inhibited();
    put(&mut node, at(0), "I", 0);
    put(&mut node, at(10), "A", 2);
    assert_eq!(value(&node, "D"), 2);
    assert_eq!(node.why("D", V).unwrap().supplier.map(|s| s.is_internal()), Some(false));
    put(&mut node, at(20), "D", 3);
    assert_eq!(value(&node, "D"), 3);
    assert_eq!(node.why("D", V).unwrap().last_accepted, Some(at(20)));
    assert_eq!(accepted(&node, "D"), 2);
    assert_eq!(value(&node, "E"), 0);
}

#[test]
fn an_inhibited_port_still_triggers_its_on_write_processes() {
    // S6 + S7: storing is accepting, so OnWrite processes of d run even while its output is
    // inhibited.
    let mut node = wiring(&["I", "A", "E"]);
    let seen = Arc::new(AtomicU64::new(0));
    let mut listener = BehaviorClass::new("Listener");
    let v = listener.port(PortSpec::new(V, 0i64)).unwrap();
    let s = seen.clone();
    listener
        .on_write("note", v, move |ctx| {
            s.store(ctx.read(v).as_int().unwrap() as u64, Ordering::SeqCst);
        })
        .unwrap();
    node.define(listener).unwrap();
    node.create("Listener", "D").unwrap();
    link(&mut node, "I", "D", ConnectionKind::Inhibit(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    put(&mut node, at(0), "I", 0);
    put(&mut node, at(10), "A", 9);
    node.poll(at(10));
    assert_eq!(seen.load(Ordering::SeqCst), 9);
    assert_eq!(value(&node, "E"), 0);
}

#[test]
fn inhibit_lapses_after_the_period() {
    // S6 Inhibit: until t + p and no longer.
    let (mut node, _) = inhibited();
    put(&mut node, at(0), "I", 0);
    node.write_named(Instant::from_nanos(ms(100).as_nanos() - 1), "A", V, 1i64).unwrap();
    assert_eq!(value(&node, "E"), 0);
    put(&mut node, at(100), "A", 2);
    assert_eq!(value(&node, "E"), 2);
    put(&mut node, at(101), "D", 3);
    assert_eq!(value(&node, "E"), 3);
    assert!(node.why("D", V).unwrap().windows.is_empty());
}

#[test]
fn the_value_stored_during_inhibition_is_not_sent_when_it_lapses() {
    // S5/S6: propagation happens when a value is accepted; a lapse does not replay it.
    let (mut node, _) = inhibited();
    put(&mut node, at(0), "I", 0);
    put(&mut node, at(10), "A", 5);
    node.poll(at(200));
    assert_eq!(value(&node, "E"), 0);
}

#[test]
fn inhibit_is_refreshed_never_shortened() {
    // S6: end := max(end, t + p), across holders too.
    let (mut node, _) = inhibited();
    node.create("Relay", "J").unwrap();
    link(&mut node, "J", "D", ConnectionKind::Inhibit(ms(10)));
    put(&mut node, at(0), "I", 0); // until 100
    put(&mut node, at(60), "I", 0); // until 160
    put(&mut node, at(70), "J", 0); // until 80: must not shorten
    put(&mut node, at(150), "A", 1);
    assert_eq!(value(&node, "E"), 0);
    put(&mut node, at(160), "A", 2);
    assert_eq!(value(&node, "E"), 2);
}

#[test]
fn inhibit_blocks_override_out_pass_holders_too() {
    // S6: a plain Inhibit blocks everything, OverrideOut pass holders included.
    let (mut node, _) = inhibited();
    node.create("Relay", "O").unwrap();
    link(&mut node, "O", "D", ConnectionKind::OverrideOut(ms(500)));
    put(&mut node, at(0), "O", 1);
    assert_eq!(value(&node, "E"), 1);
    put(&mut node, at(10), "I", 0);
    put(&mut node, at(20), "O", 2);
    assert_eq!(value(&node, "D"), 2, "stored");
    assert_eq!(value(&node, "E"), 1, "not propagated");
    assert_eq!(dropped(&node, "D", DropCause::Inhibited), 1);
    put(&mut node, at(110), "O", 3);
    assert_eq!(value(&node, "E"), 3);
}

#[test]
fn inhibit_does_not_block_writes_into_the_port() {
    // S6: Inhibit is about the outputs of d; its inputs stay open (that is Suppress).
    let (mut node, _) = inhibited();
    put(&mut node, at(0), "I", 0);
    let why = node.why("D", V).unwrap();
    assert_eq!(why.input_blocked, None);
    assert_eq!(why.internal_output_blocked, Some(DropCause::Inhibited));
    assert_eq!(why.connection_output_blocked, Some(DropCause::Inhibited));
}

#[test]
fn a_port_with_nowhere_to_send_counts_no_blocks() {
    // S6 + counters: "every blocked message is counted" — a port with no outgoing connection
    // stops nothing, so an inhibit window over it counts nothing, while the same window over
    // a port that has somewhere to send counts each stopped value once.
    let mut node = wiring(&["I", "A", "D", "E"]);
    link(&mut node, "I", "D", ConnectionKind::Inhibit(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    put(&mut node, at(0), "I", 1);
    put(&mut node, at(1), "A", 2);
    put(&mut node, at(2), "D", 3);
    assert_eq!(value(&node, "D"), 3, "still stored");
    assert_eq!(dropped(&node, "D", DropCause::Inhibited), 0);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    put(&mut node, at(3), "D", 4);
    put(&mut node, at(4), "A", 5);
    assert_eq!(dropped(&node, "D", DropCause::Inhibited), 2);
    assert_eq!(value(&node, "E"), 0);
}
