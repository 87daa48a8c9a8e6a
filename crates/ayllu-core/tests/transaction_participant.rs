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
