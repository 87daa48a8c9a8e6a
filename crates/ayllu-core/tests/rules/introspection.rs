//! `NodeCore::why()`: why a port holds what it holds and passes what it passes (the
//! introspection that rules S3–S6 promise: supplier, windows, blocked causes, counters).

use crate::common;

use ayllu_core::*;
use common::*;

/// Sources of every special kind (S, I, OI, OO, WI) and a Normal source A, all into D;
/// D -> E. Returns the node and the connection ids in that order.
fn arbitrated() -> (NodeCore, [ConnectionId; 7]) {
    let mut node = wiring(&["S", "I", "OI", "OO", "WI", "A", "D", "E"]);
    let ids = [
        link(&mut node, "S", "D", ConnectionKind::Suppress(ms(100))),
        link(&mut node, "I", "D", ConnectionKind::Inhibit(ms(200))),
        link(&mut node, "OI", "D", ConnectionKind::OverrideIn(ms(300))),
        link(&mut node, "OO", "D", ConnectionKind::OverrideOut(ms(400))),
        link(&mut node, "WI", "D", ConnectionKind::WriteInhibit(ms(500))),
        link(&mut node, "A", "D", ConnectionKind::Normal),
        link(&mut node, "D", "E", ConnectionKind::Normal),
    ];
    (node, ids)
}

#[test]
fn why_reports_value_supplier_and_freshness() {
    // S3/S4 provenance: value, who supplied it, when, how many accepted.
    let (mut node, ids) = arbitrated();
    let idle = node.why("D", V).unwrap();
    assert_eq!((idle.value.clone(), idle.supplier, idle.last_accepted, idle.accepted), (Value::Int(0), None, None, 0));
    assert!(!idle.fresh);
    put(&mut node, at(5), "A", 3);
    let why = node.why("D", V).unwrap();
    assert_eq!(why.value, Value::Int(3));
    assert_eq!(why.supplier, Some(held_by(ids[5])));
    assert_eq!(why.last_accepted, Some(at(5)));
    assert_eq!(why.accepted, 1);
    assert!(why.fresh);
    assert_eq!(
        (why.behavior.as_str(), why.port.as_str(), why.kind, why.ty),
        ("D", V, PortKind::Normal, ValueType::Int)
    );
    assert_eq!(why.node, NODE);
    put(&mut node, at(6), "D", 4);
    assert_eq!(node.why("D", V).unwrap().supplier, Some(Source::internal(NODE)));
}

#[test]
fn why_lists_active_windows_with_holder_and_remaining_time() {
    // S6: every open window, who holds it and how long it has left, soonest-ending first.
    let (mut node, ids) = arbitrated();
    for (name, t) in [("WI", 0), ("OO", 10), ("OI", 20), ("I", 30), ("S", 40)] {
        put(&mut node, at(t), name, 0);
    }
    node.poll(at(50));
    let why = node.why("D", V).unwrap();
    let seen: Vec<(WindowKind, Source, Instant, Duration)> =
        why.windows.iter().map(|w| (w.kind, w.holder, w.ends, w.remaining)).collect();
    assert_eq!(
        seen,
        vec![
            (WindowKind::Suppress, held_by(ids[0]), at(140), ms(90)),
            (WindowKind::Inhibit, held_by(ids[1]), at(230), ms(180)),
            (WindowKind::OverrideIn, held_by(ids[2]), at(320), ms(270)),
            (WindowKind::OverrideOut, held_by(ids[3]), at(410), ms(360)),
            (WindowKind::WriteInhibit, held_by(ids[4]), at(500), ms(450)),
        ]
    );
    // Windows that ended are no longer listed.
    node.poll(at(240));
    let kinds: Vec<WindowKind> = node.why("D", V).unwrap().windows.iter().map(|w| w.kind).collect();
    assert_eq!(kinds, vec![WindowKind::OverrideIn, WindowKind::OverrideOut, WindowKind::WriteInhibit]);
    node.poll(at(500));
    assert!(node.why("D", V).unwrap().windows.is_empty());
}

#[test]
fn why_names_the_cause_that_blocks_input_and_output() {
    // S6: for each window kind, which direction it blocks and under what cause.
    type Expectation = (&'static str, Option<DropCause>, Option<DropCause>, Option<DropCause>);
    let cases: [Expectation; 6] = [
        ("A", None, None, None),
        ("S", Some(DropCause::Suppressed), None, None),
        ("I", None, Some(DropCause::Inhibited), Some(DropCause::Inhibited)),
        ("OI", Some(DropCause::OverriddenIn), None, None),
        ("OO", None, Some(DropCause::OverriddenOut), Some(DropCause::OverriddenOut)),
        ("WI", None, Some(DropCause::WriteInhibited), None),
    ];
    for (source, input, own, conn) in cases {
        let (mut node, _) = arbitrated();
        put(&mut node, at(0), source, 0);
        let why = node.why("D", V).unwrap();
        assert_eq!(why.input_blocked, input, "{source}: input");
        assert_eq!(why.internal_output_blocked, own, "{source}: own writes out");
        assert_eq!(why.connection_output_blocked, conn, "{source}: connection writes out");
    }
}

#[test]
fn why_counts_each_blocked_message_under_its_cause() {
    // S6 + counters: every blocked message is counted once, per port and per node.
    let (mut node, _) = arbitrated();
    put(&mut node, at(0), "S", 0);
    put(&mut node, at(1), "A", 1); // suppressed
    put(&mut node, at(2), "A", 2); // suppressed
    put(&mut node, at(100), "I", 0);
    put(&mut node, at(101), "A", 3); // stored, inhibited
    put(&mut node, at(102), "D", 4); // stored, inhibited
    put(&mut node, at(103), "D", 5); // stored, inhibited
    let counters = node.why("D", V).unwrap().counters;
    assert_eq!(counters.get(DropCause::Suppressed), 2);
    assert_eq!(counters.get(DropCause::Inhibited), 3);
    assert_eq!(counters.total(), 5);
    assert_eq!(node.counters().total(), 5);
    assert_eq!(node.why("E", V).unwrap().counters.total(), 0);
}

#[test]
fn why_lists_incoming_and_outgoing_connections() {
    // S6/S10: what is wired into and out of the port, with kind and period.
    let (node, ids) = arbitrated();
    let why = node.why("D", V).unwrap();
    let mut incoming: Vec<(ConnectionId, ConnectionKind)> = why.incoming.iter().map(|c| (c.id, c.kind)).collect();
    incoming.sort_by_key(|c| c.0);
    assert_eq!(
        incoming,
        vec![
            (ids[0], ConnectionKind::Suppress(ms(100))),
            (ids[1], ConnectionKind::Inhibit(ms(200))),
            (ids[2], ConnectionKind::OverrideIn(ms(300))),
            (ids[3], ConnectionKind::OverrideOut(ms(400))),
            (ids[4], ConnectionKind::WriteInhibit(ms(500))),
            (ids[5], ConnectionKind::Normal),
        ]
    );
    assert_eq!(why.outgoing.len(), 1);
    assert_eq!(why.outgoing[0].id, ids[6]);
    assert_eq!(why.outgoing[0].destination, Endpoint::local("E", V));
    assert_eq!(why.incoming[0].destination, Endpoint::local("D", V));
    let e = node.why("E", V).unwrap();
    assert_eq!(e.incoming.iter().map(|c| c.id).collect::<Vec<_>>(), vec![ids[6]]);
    assert!(e.outgoing.is_empty());
}

#[test]
fn why_display_says_blocked_and_shows_the_window() {
    // S6 introspection: a human reading `why` sees BLOCKED, the cause and the window.
    let (mut node, ids) = arbitrated();
    put(&mut node, at(0), "S", 0);
    put(&mut node, at(30), "A", 1);
    let text = node.why("D", V).unwrap().to_string();
    assert!(text.contains("BLOCKED (suppressed)"), "{text}");
    let holder = held_by(ids[0]).to_string();
    assert!(text.contains(&format!("suppress held by {holder} for 70ms more")), "{text}");
    assert!(text.contains("suppressed: 1"), "counter shown: {text}");
    // Once the window lapses nothing is blocked any more.
    node.poll(at(100));
    let text = node.why("D", V).unwrap().to_string();
    assert!(!text.contains("BLOCKED"), "{text}");
    assert!(!text.contains("window"), "{text}");
}

#[test]
fn why_display_shows_output_blocks() {
    // S6 introspection: output blocks are reported for own writes and connection writes.
    let (mut node, _) = arbitrated();
    put(&mut node, at(0), "WI", 0);
    let text = node.why("D", V).unwrap().to_string();
    assert!(text.contains("own writes BLOCKED (write_inhibited)"), "{text}");
    assert!(text.contains("connection writes open"), "{text}");
    assert!(text.contains("write-inhibit"), "{text}");
}

#[test]
fn why_of_an_unknown_port_is_an_error() {
    let (node, _) = arbitrated();
    assert!(matches!(node.why("D", "Nope"), Err(Error::UnknownPort { .. })));
    assert!(matches!(node.why("Nobody", V), Err(Error::UnknownBehavior { .. })));
}

#[test]
fn why_display_names_the_overrides_pass_holder() {
    // S6: the holder of an override has a pass. `why` used to say "connection writes BLOCKED
    // (overridden_out)" while the holder's own value was going out along the port's outgoing
    // connection.
    let (mut node, ids) = arbitrated();
    put(&mut node, at(0), "OO", 7);
    let text = node.why("D", V).unwrap().to_string();
    let oo = held_by(ids[3]).to_string();
    assert!(
        text.contains(&format!("connection writes BLOCKED (overridden_out) except along {oo} (the override's pass)")),
        "{text}"
    );
    assert_eq!(value(&node, "E"), 7, "the holder's value did go out");
    put(&mut node, at(1), "OI", 8);
    let text = node.why("D", V).unwrap().to_string();
    let oi = held_by(ids[2]).to_string();
    assert!(
        text.contains(&format!("input     BLOCKED (overridden_in) except along {oi} (the override's pass)")),
        "{text}"
    );
    // A suppression has no passes: then it is the cause, and nobody is excepted.
    put(&mut node, at(2), "S", 1);
    let text = node.why("D", V).unwrap().to_string();
    assert!(text.contains("input     BLOCKED (suppressed)\n"), "{text}");
}

#[test]
fn why_shows_a_priority_holders_priority_and_when_its_hold_ends() {
    // D3.3, D3.7: a lower-priority write was refused with nothing in `why` to say why, or
    // until when.
    let mut node = NodeCore::new(NODE);
    let mut class = BehaviorClass::new("Arb");
    class.port(PortSpec::new("P", 0i64).priority().window(ms(500))).unwrap();
    class.port(PortSpec::new("M", 0i64).max().window(ms(800))).unwrap();
    node.define(class).unwrap();
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new(V, 0i64)).unwrap();
    node.define(relay).unwrap();
    for name in ["AGG", "HI", "LO"] {
        node.create(if name == "AGG" { "Arb" } else { "Relay" }, name).unwrap();
    }
    for (from, priority) in [("HI", 9), ("LO", 3)] {
        node.connect(
            &Endpoint::local(from, V),
            &Endpoint::local("AGG", "P"),
            ConnectionKind::Normal,
            ConnectOptions { priority },
        )
        .unwrap();
    }
    node.connect(
        &Endpoint::local("LO", V),
        &Endpoint::local("AGG", "M"),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )
    .unwrap();
    let idle = node.why("AGG", "P").unwrap();
    assert_eq!((idle.supplier_priority, idle.released_in), (None, None), "empty: nothing held");
    put(&mut node, at(100), "HI", 1);
    put(&mut node, at(300), "LO", 2);
    node.poll(at(300));
    let why = node.why("AGG", "P").unwrap();
    assert_eq!(why.value, Value::Int(1), "the lower priority was absorbed");
    assert_eq!((why.supplier_priority, why.released_in), (Some(9), Some(ms(300))));
    let text = why.to_string();
    assert!(text.contains("at priority 9 (only a higher one replaces it)"), "{text}");
    assert!(text.contains("released in 300ms unless renewed (its lease ends)"), "{text}");
    // The Max port's window opened with LO's first value at 300 ms.
    let max = node.why("AGG", "M").unwrap();
    assert_eq!((max.supplier_priority, max.released_in), (None, Some(ms(800))));
    assert!(max.to_string().contains("released in 800ms unless renewed (its window or lifespan ends)"), "{max}");
    // A Normal port holds until replaced: nothing to show.
    assert_eq!(node.why("HI", V).unwrap().released_in, None);
}
