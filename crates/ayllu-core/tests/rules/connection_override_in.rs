//! Rule S6 *OverrideIn* — classic Brooks "suppression": the input is replaced for a while.

use crate::common;

use ayllu_core::*;
use common::*;

/// O --OverrideIn(100ms)--> D <--Normal-- A, and D --Normal--> E.
fn overridden() -> (NodeCore, ConnectionId) {
    let mut node = wiring(&["O", "A", "D", "E"]);
    let o = link(&mut node, "O", "D", ConnectionKind::OverrideIn(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    (node, o)
}

#[test]
fn override_in_message_is_written_and_propagated() {
    // S6 OverrideIn: m is written and propagated.
    let (mut node, o) = overridden();
    put(&mut node, at(0), "O", 7);
    assert_eq!((value(&node, "D"), value(&node, "E")), (7, 7));
    let why = node.why("D", V).unwrap();
    assert_eq!(why.supplier, Some(held_by(o)));
    assert_eq!(why.windows.len(), 1);
    assert_eq!(
        (why.windows[0].kind, why.windows[0].holder, why.windows[0].ends),
        (WindowKind::OverrideIn, held_by(o), at(100))
    );
}

#[test]
fn other_connections_are_blocked_for_the_period() {
    // S6 OverrideIn: d is suppressed until t + p for every connection except this one.
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 7);
    put(&mut node, at(10), "A", 1);
    put(&mut node, at(99), "A", 2);
    assert_eq!((value(&node, "D"), value(&node, "E")), (7, 7));
    assert_eq!(dropped(&node, "D", DropCause::OverriddenIn), 2);
    assert_eq!(node.counters().get(DropCause::OverriddenIn), 2);
}

#[test]
fn the_holder_keeps_its_pass_and_refreshes_it() {
    // S6 OverrideIn: the connection holds a pass until t + p; each message refreshes it.
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 1);
    put(&mut node, at(50), "O", 2);
    assert_eq!((value(&node, "D"), value(&node, "E")), (2, 2));
    put(&mut node, at(140), "A", 3);
    assert_eq!(value(&node, "D"), 2, "pass refreshed at 50ms: overridden until 150ms");
    put(&mut node, at(150), "A", 4);
    assert_eq!((value(&node, "D"), value(&node, "E")), (4, 4));
}

#[test]
fn two_overrides_share_the_port_as_a_union_of_passes() {
    // S6 + decision: several overrides on one port — any active pass holder may write,
    // everyone else is blocked.
    let (mut node, _) = overridden();
    node.create("Relay", "P").unwrap();
    let p = link(&mut node, "P", "D", ConnectionKind::OverrideIn(ms(100)));
    put(&mut node, at(0), "O", 1);
    put(&mut node, at(10), "P", 2);
    assert_eq!((value(&node, "D"), value(&node, "E")), (2, 2));
    put(&mut node, at(20), "O", 3);
    assert_eq!((value(&node, "D"), value(&node, "E")), (3, 3));
    put(&mut node, at(30), "A", 4);
    assert_eq!(value(&node, "D"), 3);
    // O's pass (refreshed at 20ms) ends at 120ms; P's at 110ms: from 110ms P is overridden
    // by O like anyone else.
    put(&mut node, at(115), "A", 5);
    assert_eq!(value(&node, "D"), 3);
    assert_eq!(dropped(&node, "D", DropCause::OverriddenIn), 2);
    // P sending again re-opens its own pass (its window always takes effect first).
    put(&mut node, at(116), "P", 6);
    assert_eq!(value(&node, "D"), 6);
    assert_eq!(node.why("D", V).unwrap().supplier, Some(held_by(p)));
}

#[test]
fn override_in_lapses_back_to_normal() {
    // S6 OverrideIn: after t + p the port is writable by every connection again.
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 1);
    node.write_named(Instant::from_nanos(ms(100).as_nanos() - 1), "A", V, 2i64).unwrap();
    assert_eq!(value(&node, "D"), 1);
    put(&mut node, at(100), "A", 3);
    assert_eq!((value(&node, "D"), value(&node, "E")), (3, 3));
    assert!(node.why("D", V).unwrap().windows.is_empty());
    assert_eq!(node.why("D", V).unwrap().input_blocked, None);
}

#[test]
fn own_writes_are_unaffected_by_override_in() {
    // S6: a behavior's own processes can always write their own ports, and those writes
    // propagate (OverrideIn only blocks connection writes).
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 1);
    put(&mut node, at(10), "D", 9);
    assert_eq!((value(&node, "D"), value(&node, "E")), (9, 9));
    assert_eq!(node.why("D", V).unwrap().supplier, Some(Source::internal(NODE)));
    let why = node.why("D", V).unwrap();
    assert_eq!(why.input_blocked, Some(DropCause::OverriddenIn));
    assert_eq!(why.internal_output_blocked, None);
}

#[test]
fn disconnecting_the_holder_ends_its_override_at_once() {
    // S9 + decision: disconnect() removes the windows the connection holds on local ports.
    let (mut node, o) = overridden();
    put(&mut node, at(0), "O", 1);
    node.disconnect(o).unwrap();
    put(&mut node, at(10), "A", 2);
    assert_eq!((value(&node, "D"), value(&node, "E")), (2, 2));
}

#[test]
fn a_refused_override_in_message_opens_no_window() {
    // D6.7: a remote OverrideIn whose value the port cannot take (wrong type) is refused whole.
    refused_override_opens_no_window(ConnectionKind::OverrideIn(ms(100)));
}
