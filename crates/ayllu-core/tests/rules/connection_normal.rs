//! Rule S6 *Normal* connections (with S5 propagation of the merged value).

use crate::common;

use ayllu_core::*;
use common::*;

#[test]
fn normal_writes_the_destination_and_propagates_onwards() {
    // S6 Normal: write m into d; if accepted, propagate (S5).
    let mut node = wiring(&["A", "B", "C"]);
    link(&mut node, "A", "B", ConnectionKind::Normal);
    link(&mut node, "B", "C", ConnectionKind::Normal);
    put(&mut node, at(0), "A", 7);
    assert_eq!(value(&node, "B"), 7);
    assert_eq!(value(&node, "C"), 7);
    put(&mut node, at(1), "A", -3);
    assert_eq!((value(&node, "B"), value(&node, "C")), (-3, -3));
    assert_eq!(accepted(&node, "C"), 2);
}

#[test]
fn normal_connection_names_its_connection_as_supplier() {
    // S6 Normal / S3: the destination remembers who supplied its value.
    let mut node = wiring(&["A", "B"]);
    let c = link(&mut node, "A", "B", ConnectionKind::Normal);
    put(&mut node, at(0), "A", 1);
    assert_eq!(node.why("B", V).unwrap().supplier, Some(held_by(c)));
    assert_eq!(node.why("A", V).unwrap().supplier, Some(Source::internal(NODE)));
}

#[test]
fn fan_out_reaches_every_destination() {
    // S6 Normal, S5: the value goes along every outgoing connection.
    let mut node = wiring(&["A", "B", "C", "D"]);
    for d in ["B", "C", "D"] {
        link(&mut node, "A", d, ConnectionKind::Normal);
    }
    put(&mut node, at(0), "A", 42);
    for d in ["B", "C", "D"] {
        assert_eq!(value(&node, d), 42, "{d}");
    }
}

#[test]
fn fan_in_every_source_writes_and_last_one_wins() {
    // S6 Normal into a Normal port (S3 c := m): any number of incoming connections.
    let mut node = wiring(&["A", "B", "C", "D", "E"]);
    let ca = link(&mut node, "A", "D", ConnectionKind::Normal);
    let cb = link(&mut node, "B", "D", ConnectionKind::Normal);
    let cc = link(&mut node, "C", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    put(&mut node, at(0), "B", 2);
    assert_eq!((value(&node, "D"), value(&node, "E")), (2, 2));
    assert_eq!(node.why("D", V).unwrap().supplier, Some(held_by(cb)));
    put(&mut node, at(1), "C", 3);
    assert_eq!((value(&node, "D"), value(&node, "E")), (3, 3));
    assert_eq!(node.why("D", V).unwrap().supplier, Some(held_by(cc)));
    put(&mut node, at(2), "A", 1);
    assert_eq!((value(&node, "D"), value(&node, "E")), (1, 1));
    assert_eq!(node.why("D", V).unwrap().supplier, Some(held_by(ca)));
    assert_eq!(accepted(&node, "D"), 3);
    assert_eq!(node.why("D", V).unwrap().incoming.len(), 3);
}

/// A node with Relays plus a "Peak" (Max int port `M`) and a "Total" (Sum int port `S`).
fn with_aggregators(relays: &[&str]) -> NodeCore {
    let mut node = wiring(relays);
    let mut peak = BehaviorClass::new("Peak");
    peak.port(PortSpec::new("M", 0i64).max()).unwrap();
    node.define(peak).unwrap();
    let mut total = BehaviorClass::new("Total");
    total.port(PortSpec::new("S", 0i64).sum()).unwrap();
    node.define(total).unwrap();
    node.create("Peak", "P").unwrap();
    node.create("Total", "T").unwrap();
    node
}

fn wire(node: &mut NodeCore, from: (&str, &str), to: (&str, &str)) -> ConnectionId {
    node.connect(
        &Endpoint::local(from.0, from.1),
        &Endpoint::local(to.0, to.1),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )
    .unwrap()
}

#[test]
fn a_max_port_in_the_middle_forwards_its_maximum_not_the_incoming_value() {
    // S5: what travels is the port's value after the merge; S3 Max accepts only new extremes.
    let mut node = with_aggregators(&["A", "B", "E"]);
    wire(&mut node, ("A", V), ("P", "M"));
    wire(&mut node, ("B", V), ("P", "M"));
    wire(&mut node, ("P", "M"), ("E", V));
    put(&mut node, at(0), "A", 10);
    assert_eq!(value(&node, "E"), 10);
    // A smaller value is absorbed: nothing new travels, E keeps the maximum.
    put(&mut node, at(1), "B", 3);
    assert_eq!(value(&node, "E"), 10);
    assert_eq!(accepted(&node, "E"), 1);
    assert_eq!(node.why("P", "M").unwrap().counters.get(DropCause::Absorbed), 1);
    put(&mut node, at(2), "B", 12);
    assert_eq!(value(&node, "E"), 12);
    assert_eq!(accepted(&node, "E"), 2);
}

#[test]
fn a_sum_port_in_the_middle_forwards_the_sum_not_the_incoming_value() {
    // S5: the merged value (c + m) is what goes along the outgoing connection.
    let mut node = with_aggregators(&["A", "B", "E"]);
    wire(&mut node, ("A", V), ("T", "S"));
    wire(&mut node, ("B", V), ("T", "S"));
    wire(&mut node, ("T", "S"), ("E", V));
    put(&mut node, at(0), "A", 3);
    assert_eq!(value(&node, "E"), 3);
    put(&mut node, at(1), "B", 4);
    assert_eq!(value(&node, "E"), 7);
    put(&mut node, at(2), "A", -10);
    assert_eq!(value(&node, "E"), -3);
}

#[test]
fn type_mismatch_at_connect_is_an_error_for_kinds_that_write() {
    // S1/S6: a connection that writes must join ports of one type; checked at connect time.
    let mut node = wiring(&["A"]);
    let mut gauge = BehaviorClass::new("Gauge");
    gauge.port(PortSpec::new("F", 0.0)).unwrap();
    node.define(gauge).unwrap();
    node.create("Gauge", "G").unwrap();
    let (a, g) = (Endpoint::local("A", V), Endpoint::local("G", "F"));
    for kind in [ConnectionKind::Normal, ConnectionKind::OverrideIn(ms(10)), ConnectionKind::OverrideOut(ms(10))] {
        let err = node.connect(&a, &g, kind, ConnectOptions::default()).unwrap_err();
        assert!(
            matches!(err, Error::TypeMismatch { expected: ValueType::Float, found: ValueType::Int, .. }),
            "{kind}: {err:?}"
        );
    }
    // Nothing was wired by the failed attempts.
    assert!(node.report().connections.is_empty());
    put(&mut node, at(0), "A", 5);
    assert_eq!(node.read(node.port("G", "F").unwrap()).unwrap(), Value::Float(0.0));
    // Kinds that never write m only open windows: any source type will do.
    for kind in
        [ConnectionKind::Suppress(ms(10)), ConnectionKind::Inhibit(ms(10)), ConnectionKind::WriteInhibit(ms(10))]
    {
        assert!(node.connect(&a, &g, kind, ConnectOptions::default()).is_ok(), "{kind}");
    }
}

#[test]
fn normal_connection_has_no_window() {
    // S6 Normal: it only writes; it leaves no arbitration behind.
    let mut node = wiring(&["A", "B", "C"]);
    link(&mut node, "A", "B", ConnectionKind::Normal);
    link(&mut node, "C", "B", ConnectionKind::Normal);
    put(&mut node, at(0), "A", 1);
    let why = node.why("B", V).unwrap();
    assert!(why.windows.is_empty());
    assert_eq!(why.input_blocked, None);
    put(&mut node, at(0), "C", 2);
    assert_eq!(value(&node, "B"), 2);
}
