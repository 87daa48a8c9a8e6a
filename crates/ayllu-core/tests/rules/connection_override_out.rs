//! Rule S6 *OverrideOut*: for a while, only what arrives along the holder leaves the port.

use crate::common;

use ayllu_core::*;
use common::*;

/// O --OverrideOut(100ms)--> D <--Normal-- A, and D --Normal--> E.
fn overridden() -> (NodeCore, ConnectionId) {
    let mut node = wiring(&["O", "A", "D", "E"]);
    let o = link(&mut node, "O", "D", ConnectionKind::OverrideOut(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    (node, o)
}

#[test]
fn override_out_message_is_written_and_propagated() {
    // S6 OverrideOut: m is written and propagated.
    let (mut node, o) = overridden();
    put(&mut node, at(0), "O", 7);
    assert_eq!((value(&node, "D"), value(&node, "E")), (7, 7));
    let why = node.why("D", V).unwrap();
    assert_eq!(why.supplier, Some(held_by(o)));
    assert_eq!(
        (why.windows[0].kind, why.windows[0].holder, why.windows[0].ends),
        (WindowKind::OverrideOut, held_by(o), at(100))
    );
}

#[test]
fn other_connection_values_are_stored_but_not_propagated() {
    // S6 OverrideOut: d is inhibited for everyone but the holder; what others write is kept.
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 7);
    put(&mut node, at(10), "A", 1);
    assert_eq!(value(&node, "D"), 1, "stored");
    assert_eq!(value(&node, "E"), 7, "not propagated");
    assert_eq!(dropped(&node, "D", DropCause::OverriddenOut), 1);
    assert_eq!(dropped(&node, "D", DropCause::OverriddenIn), 0);
}

#[test]
fn own_behavior_values_are_stored_but_not_propagated() {
    // S6 OverrideOut: the behavior's own writes are not messages along the holder either.
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 7);
    put(&mut node, at(10), "D", 2);
    assert_eq!((value(&node, "D"), value(&node, "E")), (2, 7));
    assert_eq!(dropped(&node, "D", DropCause::OverriddenOut), 1);
    let why = node.why("D", V).unwrap();
    assert_eq!(why.internal_output_blocked, Some(DropCause::OverriddenOut));
    assert_eq!(why.connection_output_blocked, Some(DropCause::OverriddenOut));
    assert_eq!(why.input_blocked, None);
}

#[test]
fn only_values_arriving_along_the_holder_propagate() {
    // S6 OverrideOut: messages along this connection keep the pass (and refresh it).
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 1);
    put(&mut node, at(10), "A", 2);
    put(&mut node, at(20), "O", 3);
    put(&mut node, at(30), "D", 4);
    put(&mut node, at(40), "O", 5);
    assert_eq!(value(&node, "E"), 5);
    assert_eq!(accepted(&node, "E"), 3);
    assert_eq!(accepted(&node, "D"), 5);
}

#[test]
fn two_override_outs_are_a_union_of_passes() {
    // S6 + decision: any active pass holder's values propagate, everyone else's do not.
    let (mut node, _) = overridden();
    node.create("Relay", "P").unwrap();
    link(&mut node, "P", "D", ConnectionKind::OverrideOut(ms(100)));
    put(&mut node, at(0), "O", 1);
    put(&mut node, at(10), "P", 2);
    assert_eq!(value(&node, "E"), 2);
    put(&mut node, at(20), "O", 3);
    assert_eq!(value(&node, "E"), 3);
    put(&mut node, at(30), "A", 4);
    assert_eq!(value(&node, "E"), 3);
}

#[test]
fn override_out_lapses() {
    // S6 OverrideOut: until t + p; afterwards every stored value propagates again.
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 1);
    node.write_named(Instant::from_nanos(ms(100).as_nanos() - 1), "A", V, 2i64).unwrap();
    assert_eq!(value(&node, "E"), 1);
    put(&mut node, at(100), "A", 3);
    assert_eq!(value(&node, "E"), 3);
    put(&mut node, at(101), "D", 4);
    assert_eq!(value(&node, "E"), 4);
}

#[test]
fn override_out_is_refreshed_never_shortened() {
    // S6: end := max(end, t + p).
    let (mut node, _) = overridden();
    put(&mut node, at(0), "O", 1);
    put(&mut node, at(80), "O", 2);
    put(&mut node, at(170), "A", 3);
    assert_eq!(value(&node, "E"), 2);
    put(&mut node, at(180), "A", 4);
    assert_eq!(value(&node, "E"), 4);
}

#[test]
fn a_refused_override_out_message_opens_no_window() {
    // D6.7: a remote OverrideOut whose value the port cannot take (wrong type) is refused whole.
    refused_override_opens_no_window(ConnectionKind::OverrideOut(ms(100)));
}
