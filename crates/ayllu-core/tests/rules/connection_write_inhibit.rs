//! Rule S6 *WriteInhibit*: for a while, what the destination's own behavior writes stays home.

use crate::common;

use ayllu_core::*;
use common::*;

/// W --WriteInhibit(100ms)--> D <--Normal-- A, and D --Normal--> E.
fn write_inhibited() -> (NodeCore, ConnectionId) {
    let mut node = wiring(&["W", "A", "D", "E"]);
    let w = link(&mut node, "W", "D", ConnectionKind::WriteInhibit(ms(100)));
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    (node, w)
}

#[test]
fn write_inhibit_message_is_not_written() {
    // S6 WriteInhibit: m is not written.
    let (mut node, w) = write_inhibited();
    put(&mut node, at(0), "W", 7);
    assert_eq!(value(&node, "D"), 0);
    assert_eq!(accepted(&node, "D"), 0);
    let why = node.why("D", V).unwrap();
    assert_eq!(
        (why.windows[0].kind, why.windows[0].holder, why.windows[0].ends),
        (WindowKind::WriteInhibit, held_by(w), at(100))
    );
}

#[test]
fn own_writes_are_stored_but_not_propagated() {
    // S6 WriteInhibit: values written into d from inside its own behavior are stored, not
    // propagated, until t + p.
    let (mut node, _) = write_inhibited();
    put(&mut node, at(0), "W", 0);
    put(&mut node, at(10), "D", 3);
    assert_eq!((value(&node, "D"), value(&node, "E")), (3, 0));
    assert_eq!(dropped(&node, "D", DropCause::WriteInhibited), 1);
    let why = node.why("D", V).unwrap();
    assert_eq!(why.internal_output_blocked, Some(DropCause::WriteInhibited));
    assert_eq!(why.connection_output_blocked, None);
    assert_eq!(why.input_blocked, None);
}

#[test]
fn connection_writes_still_propagate() {
    // S6 WriteInhibit: values arriving through connections still propagate.
    let (mut node, _) = write_inhibited();
    put(&mut node, at(0), "W", 0);
    put(&mut node, at(10), "A", 5);
    assert_eq!((value(&node, "D"), value(&node, "E")), (5, 5));
    assert_eq!(dropped(&node, "D", DropCause::WriteInhibited), 0);
}

#[test]
fn write_inhibit_lapses() {
    // S6 WriteInhibit: until t + p only.
    let (mut node, _) = write_inhibited();
    put(&mut node, at(0), "W", 0);
    node.write_named(Instant::from_nanos(ms(100).as_nanos() - 1), "D", V, 1i64).unwrap();
    assert_eq!(value(&node, "E"), 0);
    put(&mut node, at(100), "D", 2);
    assert_eq!(value(&node, "E"), 2);
}

#[test]
fn write_inhibit_is_refreshed_never_shortened() {
    // S6: end := max(end, t + p).
    let (mut node, _) = write_inhibited();
    node.create("Relay", "X").unwrap();
    link(&mut node, "X", "D", ConnectionKind::WriteInhibit(ms(5)));
    put(&mut node, at(0), "W", 0);
    put(&mut node, at(90), "W", 0); // until 190
    put(&mut node, at(95), "X", 0); // until 100: no shortening
    put(&mut node, at(189), "D", 1);
    assert_eq!(value(&node, "E"), 0);
    put(&mut node, at(190), "D", 2);
    assert_eq!(value(&node, "E"), 2);
}

#[test]
fn a_process_output_is_write_inhibited_while_relayed_input_passes() {
    // S6 WriteInhibit + S7 (the BLE pattern, S11): a behavior computing its output in a
    // process is silenced, while a value wired straight into the same port still propagates.
    let mut node = wiring(&["W", "A", "B", "E"]);
    let mut doubler = BehaviorClass::new("Doubler");
    let input = doubler.port(PortSpec::new("In", 0i64)).unwrap();
    let output = doubler.port(PortSpec::new("Out", 0i64)).unwrap();
    doubler
        .on_write("double", input, move |ctx| {
            let x = ctx.read(input).as_int().unwrap();
            ctx.write(output, 2 * x).unwrap();
        })
        .unwrap();
    node.define(doubler).unwrap();
    node.create("Doubler", "D").unwrap();
    let normal = ConnectOptions::default();
    node.connect(&Endpoint::local("A", V), &Endpoint::local("D", "In"), ConnectionKind::Normal, normal).unwrap();
    node.connect(&Endpoint::local("B", V), &Endpoint::local("D", "Out"), ConnectionKind::Normal, normal).unwrap();
    node.connect(&Endpoint::local("W", V), &Endpoint::local("D", "Out"), ConnectionKind::WriteInhibit(ms(100)), normal)
        .unwrap();
    node.connect(&Endpoint::local("D", "Out"), &Endpoint::local("E", V), ConnectionKind::Normal, normal).unwrap();
    let out = node.port("D", "Out").unwrap();

    put(&mut node, at(0), "A", 1);
    node.poll(at(0));
    assert_eq!(value(&node, "E"), 2, "not yet write-inhibited");

    put(&mut node, at(10), "W", 0);
    put(&mut node, at(20), "A", 5);
    node.poll(at(20));
    assert_eq!(node.read(out).unwrap(), Value::Int(10), "stored");
    assert_eq!(value(&node, "E"), 2, "not propagated");

    put(&mut node, at(30), "B", 7);
    assert_eq!(value(&node, "E"), 7, "connection write into the same port passes");

    put(&mut node, at(110), "A", 6);
    node.poll(at(110));
    assert_eq!(value(&node, "E"), 12, "lapsed");
}
