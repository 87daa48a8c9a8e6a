//! Rules R8–R12 (docs/semantics.md, "Reconfiguration"), a node's side of a transaction:
//! PREPARE validates and holds, COMMIT fixes the switch at a delay from its receipt on the
//! node's own clock, the first poll at or after it applies the part, ABORT drops it, and a held
//! part that hears nothing by the end of its hold aborts by itself. Repeats are idempotent;
//! the access rules apply as to CONNECT.

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

const COORD: NodeId = NodeId(9);

fn node() -> NodeCore {
    let mut n = NodeCore::new(NodeId(2));
    let mut c = BehaviorClass::new("Layer");
    c.port(PortSpec::new("In", 0i64)).unwrap();
    c.port(PortSpec::new("Out", 0i64)).unwrap();
    n.define(c).unwrap();
    n.create("Layer", "A").unwrap();
    n.create("Layer", "B").unwrap();
    n
}

/// Send `body` from the coordinator as control request `id`; the reply's result.
fn ask(n: &mut NodeCore, at: Instant, id: u64, body: ControlBody) -> Result<ReplyBody, String> {
    n.receive(at, COORD, Message::Control(ControlMessage { id, body }));
    let mut result = None;
    while let Some(o) = n.pop_outgoing() {
        if let Message::Control(ControlMessage { id: rid, body: ControlBody::Reply { result: r } }) = o.message {
            if rid == id {
                result = Some(r);
            }
        }
    }
    result.expect("a reply")
}

fn rewire() -> Vec<Change> {
    vec![
        Change::Create { class: "Layer".into(), name: "C".into() },
        Change::Connect {
            source: Endpoint::node(NodeId(2), "A", "Out"),
            destination: Endpoint::node(NodeId(2), "C", "In"),
            kind: ConnectionKind::Suppress(Duration::from_secs(1)),
            priority: 0,
        },
    ]
}

fn text(r: &Result<ReplyBody, String>) -> String {
    match r {
        Ok(ReplyBody::Value(Value::Text(t))) => t.to_string(),
        Ok(ReplyBody::Value(Value::Int(i))) => format!("in {i} ns"),
        other => format!("{other:?}"),
    }
}

#[test]
fn r8_prepare_holds_commit_switches_at_its_delay_on_the_nodes_clock() {
    let mut n = node();
    let hold = Duration::from_secs(2);
    assert_eq!(text(&ask(&mut n, ms(0), 1, ControlBody::Prepare { txn: 5, changes: rewire(), hold })), "prepared");
    assert!(n.behavior_ref("C").is_err(), "nothing changes at PREPARE");
    assert_eq!(n.transaction_held(), Some((COORD, 5)));
    // The reservation: other structure requests from the network are refused meanwhile (R9).
    let busy = ask(
        &mut n,
        ms(10),
        2,
        ControlBody::Connect {
            source_behavior: "A".into(),
            source_port: "Out".into(),
            destination: Endpoint::node(NodeId(2), "B", "In"),
            kind: ConnectionKind::Normal,
            priority: 0,
        },
    );
    assert!(matches!(&busy, Err(e) if e.contains("busy")), "{busy:?}");
    let other = ask(&mut n, ms(10), 3, ControlBody::Prepare { txn: 6, changes: vec![], hold });
    assert!(matches!(&other, Err(e) if e.contains("busy")), "{other:?}");
    // COMMIT at 100 ms with a delay of 50 ms: the switch is at 150 ms on this clock.
    let c = ask(&mut n, ms(100), 4, ControlBody::Commit { txn: 5, delay: Duration::from_millis(50) });
    assert_eq!(text(&c), "in 50000000 ns");
    assert_eq!(n.poll_at(), Some(ms(150)));
    // A repeat (a new copy with another delay) never moves it.
    let again = ask(&mut n, ms(120), 5, ControlBody::Commit { txn: 5, delay: Duration::from_millis(500) });
    assert_eq!(text(&again), "in 30000000 ns");
    n.poll(ms(149));
    assert!(n.behavior_ref("C").is_err(), "not before the switch");
    n.poll(ms(150));
    assert!(n.behavior_ref("C").is_ok(), "switched at the first poll at the switch time");
    assert_eq!(n.connections_between(&Endpoint::local("A", "Out"), &Endpoint::local("C", "In")).len(), 1);
    let t = n.transactions();
    assert!(
        matches!(&t[0].state, TransactionState::Applied { at, outcomes } if *at == ms(150) && outcomes.iter().all(|o| o.result.is_ok()))
    );
    // Late copies are answered from what happened.
    assert_eq!(
        text(&ask(&mut n, ms(200), 6, ControlBody::Commit { txn: 5, delay: Duration::ZERO })),
        "in -50000000 ns"
    );
    assert_eq!(text(&ask(&mut n, ms(200), 7, ControlBody::Prepare { txn: 5, changes: rewire(), hold })), "applied");
    assert!(ask(&mut n, ms(200), 8, ControlBody::Abort { txn: 5 }).is_err(), "an applied transaction is not aborted");
    assert!(n.transaction_held().is_none());
}

#[test]
fn r8_a_part_that_does_not_validate_is_refused_with_the_change_at_fault() {
    let mut n = node();
    let mut bad = rewire();
    bad.push(Change::Connect {
        source: Endpoint::node(NodeId(2), "B", "Ouput"),
        destination: Endpoint::node(NodeId(2), "A", "In"),
        kind: ConnectionKind::Normal,
        priority: 0,
    });
    let r = ask(&mut n, ms(0), 1, ControlBody::Prepare { txn: 1, changes: bad, hold: Duration::from_secs(1) });
    let e = r.unwrap_err();
    assert!(e.contains("change 3") && e.contains("Ouput"), "{e}");
    assert!(n.transaction_held().is_none(), "nothing is held");
    assert!(n.behavior_ref("C").is_err());
}

#[test]
fn r11_a_prepared_node_that_hears_nothing_aborts_by_itself_at_the_end_of_its_hold() {
    let mut n = node();
    let hold = Duration::from_millis(800);
    assert!(ask(&mut n, ms(0), 1, ControlBody::Prepare { txn: 3, changes: rewire(), hold }).is_ok());
    assert_eq!(n.poll_at(), Some(ms(800)));
    n.poll(ms(799));
    assert!(n.transaction_held().is_some());
    n.poll(ms(800));
    assert!(n.transaction_held().is_none());
    assert!(matches!(n.transactions()[0].state, TransactionState::Aborted { at, .. } if at == ms(800)));
    assert!(n.warnings().iter().any(|w| w.contains("aborted by itself")));
    // A COMMIT that comes after is refused: the coordinator learns the node did not switch.
    let late = ask(&mut n, ms(900), 2, ControlBody::Commit { txn: 3, delay: Duration::ZERO });
    assert!(matches!(&late, Err(e) if e.contains("aborted")), "{late:?}");
    assert!(n.behavior_ref("C").is_err());
}

#[test]
fn r12_abort_drops_a_held_part_and_an_abort_before_prepare_blocks_a_late_prepare() {
    let mut n = node();
    let hold = Duration::from_secs(1);
    assert!(ask(&mut n, ms(0), 1, ControlBody::Prepare { txn: 3, changes: rewire(), hold }).is_ok());
    assert_eq!(text(&ask(&mut n, ms(5), 2, ControlBody::Abort { txn: 3 })), "aborted");
    assert!(n.transaction_held().is_none());
    assert_eq!(text(&ask(&mut n, ms(6), 3, ControlBody::Abort { txn: 3 })), "aborted", "idempotent");
    // The ABORT of transaction 4 overtakes its PREPARE.
    assert_eq!(text(&ask(&mut n, ms(10), 4, ControlBody::Abort { txn: 4 })), "aborted");
    let late = ask(&mut n, ms(11), 5, ControlBody::Prepare { txn: 4, changes: rewire(), hold });
    assert!(late.is_err(), "{late:?}");
    assert!(n.transaction_held().is_none());
    n.poll(ms(2000));
    assert!(n.behavior_ref("C").is_err());
}

#[test]
fn r9_transactions_obey_the_access_rules_like_connect() {
    let mut n = node();
    n.set_access(Access { ports: Allow::Everyone, structure: Allow::Only(vec![NodeId(1)]) });
    let r = ask(&mut n, ms(0), 1, ControlBody::Prepare { txn: 1, changes: rewire(), hold: Duration::from_secs(1) });
    assert!(matches!(&r, Err(e) if e.contains("not allowed")), "{r:?}");
    assert!(ask(&mut n, ms(0), 2, ControlBody::Commit { txn: 1, delay: Duration::ZERO }).is_err());
    assert!(n.transaction_held().is_none());
    let too_long = {
        let mut m = node();
        ask(&mut m, ms(0), 1, ControlBody::Prepare { txn: 1, changes: rewire(), hold: Duration::from_secs(100_000) })
    };
    assert!(too_long.is_err(), "a hold beyond max_remote_period is refused");
}

/// `change` put to node `n` in a PREPARE of its own (transaction `txn`): the refusal's text, or
/// `None` if it prepared (then aborted, so the next can prepare).
fn refusal(n: &mut NodeCore, txn: u64, changes: Vec<Change>) -> Option<String> {
    let r = ask(n, ms(txn), txn * 2, ControlBody::Prepare { txn, changes, hold: Duration::from_secs(1) });
    if r.is_ok() {
        ask(n, ms(txn), txn * 2 + 1, ControlBody::Abort { txn }).unwrap();
    }
    r.err()
}

fn ble_join(behavior: &str, group: &str, rate: f64) -> Change {
    let inhibit_period = Duration::from_millis(2_500);
    let config = BleConfig {
        group: group.into(),
        output: "Out".into(),
        claim_rate_hz: rate,
        inhibit_period,
        network_delay: Duration::from_millis(50),
    };
    Change::BleJoin { behavior: behavior.into(), config }
}

#[test]
fn r8_prepare_refuses_what_the_switch_would_refuse() {
    // An outside test found parts that prepared, committed, and were then refused change by
    // change at the switch (the coordinator reported "switched"): a BLE join of a behavior
    // already in a group, one at a claim rate of NaN. PREPARE now applies the same checks.
    let mut n = node();
    n.ble_join("A", &BleConfig::new("G1", "Out", 1.0).unwrap()).unwrap();
    let mut text = BehaviorClass::new("Text");
    text.port(PortSpec::new("T", "")).unwrap();
    n.define(text).unwrap();
    n.create("Text", "T").unwrap();
    let conn = n
        .connect(
            &Endpoint::local("A", "Out"),
            &Endpoint::local("B", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    let a_to_b =
        || Change::DisconnectBetween { source: Endpoint::local("A", "Out"), destination: Endpoint::local("B", "In") };
    let cases: Vec<(Vec<Change>, &str)> = vec![
        (vec![ble_join("A", "G2", 1.0)], "already belongs to a BLE group"),
        (vec![ble_join("B", "G2", 1.0), ble_join("B", "G3", 1.0)], "change 2"),
        (vec![ble_join("B", "G2", f64::NAN)], "change 1"),
        (vec![ble_join("B", "G2", 0.0)], "change 1"),
        (
            vec![Change::BleJoin {
                behavior: "B".into(),
                config: BleConfig { inhibit_period: Duration::ZERO, ..BleConfig::new("G2", "Out", 1.0).unwrap() },
            }],
            "change 1",
        ),
        (
            vec![Change::Connect {
                source: Endpoint::local("A", "Out"),
                destination: Endpoint::node(NodeId(2), "T", "T"),
                kind: ConnectionKind::Normal,
                priority: 0,
            }],
            "holds text values",
        ),
        (vec![Change::Disconnect { conn }, Change::Disconnect { conn }], "change 2"),
        (vec![a_to_b(), a_to_b()], "change 2"),
        (vec![Change::Remove { name: "A".into() }, Change::Disconnect { conn }], "change 2"),
    ];
    for (k, (changes, expected)) in cases.into_iter().enumerate() {
        let described: Vec<String> = changes.iter().map(Change::describe).collect();
        let e = refusal(&mut n, 10 + k as u64, changes).unwrap_or_else(|| panic!("{described:?} prepared"));
        assert!(e.contains(expected), "{described:?}: {e}");
    }
    // Still valid: a BLE join of a behavior created, or removed and re-created, in the part;
    // a disconnection of what the part itself connected.
    let ok: Vec<Vec<Change>> = vec![
        vec![Change::Create { class: "Layer".into(), name: "C".into() }, ble_join("C", "G2", 1.0)],
        vec![
            Change::Remove { name: "A".into() },
            Change::Create { class: "Layer".into(), name: "A".into() },
            ble_join("A", "G2", 1.0),
        ],
        vec![
            a_to_b(),
            Change::Connect {
                source: Endpoint::local("A", "Out"),
                destination: Endpoint::local("B", "In"),
                kind: ConnectionKind::Normal,
                priority: 0,
            },
            a_to_b(),
        ],
    ];
    for (k, changes) in ok.into_iter().enumerate() {
        let described: Vec<String> = changes.iter().map(Change::describe).collect();
        assert_eq!(refusal(&mut n, 100 + k as u64, changes), None, "{described:?}");
    }
}

mod validation_matches_application {
    //! The property behind R8: `validate_changes` refuses a list exactly when applying it in
    //! order would refuse a change, and names that change.
    use super::*;
    use proptest::prelude::*;

    /// Behaviors A, B (Layer: int In, Out) and T (Text: text T, int Out); A in BLE group G1;
    /// connections A.Out -> B.In (Normal) and B.Out -> A.In (Suppress 1 s).
    fn fixture() -> NodeCore {
        let mut n = node();
        let mut text = BehaviorClass::new("Text");
        text.port(PortSpec::new("T", "")).unwrap();
        text.port(PortSpec::new("Out", 0i64)).unwrap();
        n.define(text).unwrap();
        n.create("Text", "T").unwrap();
        n.ble_join("A", &BleConfig::new("G1", "Out", 1.0).unwrap()).unwrap();
        let o = ConnectOptions::default();
        n.connect(&Endpoint::local("A", "Out"), &Endpoint::local("B", "In"), ConnectionKind::Normal, o).unwrap();
        let suppress = ConnectionKind::Suppress(Duration::from_secs(1));
        n.connect(&Endpoint::local("B", "Out"), &Endpoint::local("A", "In"), suppress, o).unwrap();
        n
    }

    fn name() -> impl Strategy<Value = String> {
        prop_oneof![Just("A"), Just("B"), Just("C"), Just("T")].prop_map(String::from)
    }

    fn endpoint() -> impl Strategy<Value = Endpoint> {
        let port = prop_oneof![Just("In"), Just("Out"), Just("T"), Just("Bad")];
        (name(), port, 0u8..4).prop_map(|(b, p, at)| match at {
            0 | 1 => Endpoint::local(&b, p),
            2 => Endpoint::node(NodeId(2), &b, p),
            _ => Endpoint::node(NodeId(3), &b, p),
        })
    }

    fn kind() -> impl Strategy<Value = ConnectionKind> {
        prop_oneof![
            Just(ConnectionKind::Normal),
            Just(ConnectionKind::Suppress(Duration::from_secs(1))),
            Just(ConnectionKind::WriteInhibit(Duration::from_secs(1))),
            Just(ConnectionKind::Inhibit(Duration::ZERO)),
        ]
    }

    fn change() -> impl Strategy<Value = Change> {
        let rate = prop_oneof![Just(1.0), Just(20.0), Just(0.0), Just(f64::NAN), Just(-1.0)];
        let inhibit =
            prop_oneof![Just(Duration::from_millis(2_500)), Just(Duration::ZERO), Just(Duration::from_millis(10))];
        let output = prop_oneof![Just("Out"), Just("T"), Just("Bad")];
        let group = prop_oneof![Just("G1"), Just("G2"), Just("")];
        prop_oneof![
            (prop_oneof![Just("Layer"), Just("Text"), Just("None")], name())
                .prop_map(|(class, name)| Change::Create { class: class.into(), name }),
            name().prop_map(|name| Change::Remove { name }),
            (endpoint(), endpoint(), kind()).prop_map(|(source, destination, kind)| Change::Connect {
                source,
                destination,
                kind,
                priority: 0
            }),
            (1u64..6).prop_map(|c| Change::Disconnect { conn: ConnectionId(c) }),
            (endpoint(), endpoint())
                .prop_map(|(source, destination)| Change::DisconnectBetween { source, destination }),
            group.clone().prop_map(|g| Change::Join { group: g.into() }),
            (name(), group, output, rate, inhibit).prop_map(
                |(behavior, group, output, claim_rate_hz, inhibit_period)| {
                    Change::BleJoin {
                        behavior,
                        config: BleConfig {
                            group: group.into(),
                            output: output.into(),
                            claim_rate_hz,
                            inhibit_period,
                            network_delay: Duration::from_millis(50),
                        },
                    }
                }
            ),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2_000, ..ProptestConfig::default() })]
        #[test]
        fn prepare_refuses_exactly_what_the_switch_would(changes in proptest::collection::vec(change(), 1..7)) {
            let n = fixture();
            let validated = n.validate_changes(&changes).map_err(|(i, _)| i);
            let mut applied = fixture();
            let first_refused = changes.iter().position(|c| applied.apply_change(c).is_err());
            let described: Vec<String> = changes.iter().map(Change::describe).collect();
            prop_assert_eq!(validated.err(), first_refused, "{:?}", described);
        }
    }
}
