//! Replay of processes that rewire (docs/semantics.md R7; spec/flight-recorder.md): the
//! structure changes and requests a process made are in its journal as its effects, written
//! to and read back from the recording's JSON, and a replay with no application code rebuilds
//! the same structure and accepts the same values, bit for bit.

use std::sync::Arc;

use ayllu::recording_format::{decode, encode};
use ayllu::replay::{Ending, Recording, Replay};
use ayllu::{
    BehaviorClass, ConnectOptions, ConnectionId, ConnectionKind, Endpoint, Entry, Event, Instant, NodeCore, NodeId,
    PortSpec, Value,
};

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// A node whose processes recruit a helper, wire it, hand their task over by removing
/// themselves, ask another node for a connection, and refuse a bad change; its journal through
/// the JSON form; the replay's structure and values equal the live node's.
#[test]
fn a_process_that_rewires_replays_with_no_application_code() {
    let mut live = NodeCore::new(NodeId(1));
    live.start_journal(1 << 20);
    let mut boss = BehaviorClass::new("Boss");
    let go = boss.port(PortSpec::new("Go", 0i64)).unwrap();
    let out = boss.port(PortSpec::new("Out", 0i64)).unwrap();
    boss.on_write("Steer", go, move |ctx| {
        let g = ctx.int(go).unwrap_or(0);
        match g {
            1 => {
                ctx.create("Worker", "Helper").unwrap();
                ctx.connect(
                    &Endpoint::local("Boss", "Out"),
                    &Endpoint::local("Helper", "In"),
                    ConnectionKind::Normal,
                    ConnectOptions::default(),
                )
                .unwrap();
                ctx.create("Missing", "X").unwrap(); // refused when applied
                ctx.join("Team").unwrap();
            }
            2 => {
                ctx.request_disconnect(NodeId(7), ConnectionId(4));
            }
            3 => {
                // Hand over: a successor takes the wiring, this behavior goes.
                ctx.create("Boss", "Boss2").unwrap();
                ctx.connect(
                    &Endpoint::local("Boss2", "Out"),
                    &Endpoint::local("Helper", "In"),
                    ConnectionKind::Suppress(ayllu::Duration::from_millis(300)),
                    ConnectOptions::default(),
                )
                .unwrap();
                ctx.remove("Boss").unwrap();
            }
            _ => {}
        }
        ctx.write(out, g * 10).unwrap();
    })
    .unwrap();
    let mut worker = BehaviorClass::new("Worker");
    let input = worker.port(PortSpec::new("In", 0i64)).unwrap();
    let count = worker.port(PortSpec::new("Count", 0i64)).unwrap();
    worker
        .on_write("Count", input, move |ctx| {
            let n = ctx.int(count).unwrap_or(0);
            ctx.write(count, n + 1).unwrap();
        })
        .unwrap();
    live.define(boss).unwrap();
    live.define(worker).unwrap();
    live.create("Boss", "Boss").unwrap();
    for (t, g) in [(0, 1i64), (10, 2), (20, 4), (30, 3)] {
        live.write_named(ms(t), "Boss", "Go", g).unwrap();
        live.poll(ms(t));
    }
    live.write_named(ms(40), "Boss2", "Out", 5i64).unwrap();
    live.write_named(ms(50), "Boss2", "Go", 9i64).unwrap();
    live.poll(ms(50));
    assert_eq!(live.read(live.port("Helper", "Count").unwrap()).unwrap(), Value::Int(3));
    while live.pop_outgoing().is_some() {}
    let journal = live.stop_journal();
    assert!(journal.iter().any(|e| matches!(e.event, Event::ProcessChange(_))));
    assert!(journal.iter().any(|e| matches!(e.event, Event::ProcessRequest { .. })));

    // Through the recording's JSON, as a file would carry it.
    let entries: Vec<Entry> = journal
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let (_, json) = encode(i as u64, e);
            decode(&json).unwrap_or_else(|err| panic!("entry {i} ({:?}): {err}", e.event)).entry
        })
        .collect();
    let recording = Recording {
        node: NodeId(1),
        segments: Vec::new(),
        entries,
        ending: Ending::Closed,
        gap: None,
        checkpoint: None,
    };
    let mut replay = Replay::new(&recording);
    replay.run_to_end().unwrap_or_else(|d| panic!("{d}"));
    assert!(replay.checked() >= 8, "values compared: {}", replay.checked());
    let (a, b) = (live.report(), replay.core().report());
    let names = |r: &ayllu::NodeReport| r.behaviors.iter().map(|b| b.name.clone()).collect::<Vec<_>>();
    assert_eq!(names(&a), names(&b));
    let conns = |r: &ayllu::NodeReport| {
        r.connections.iter().map(|c| (c.source.to_string(), c.destination.to_string(), c.kind)).collect::<Vec<_>>()
    };
    assert_eq!(conns(&a), conns(&b));
    assert_eq!(live.groups(), replay.core().groups());
    let count: Arc<str> = Arc::from("Helper");
    assert!(replay.accepted().iter().any(|x| x.behavior == count && x.port == "Count" && x.value == Value::Int(3)));
}

/// A participant's side of a transaction (PREPARE, COMMIT with a delay, the switch inside a
/// later poll; then a second transaction ABORTed) replays from its journal alone: the
/// messages are `receive` inputs and the switch a consequence of a `poll` (R7).
#[test]
fn a_transaction_applied_to_a_node_replays() {
    use ayllu::{Change, ControlBody, ControlMessage, Duration, Message, TransactionState};
    let mut live = NodeCore::new(NodeId(2));
    live.start_journal(1 << 20);
    let mut layer = BehaviorClass::new("Layer");
    layer.port(PortSpec::new("Out", 0i64)).unwrap();
    layer.port(PortSpec::new("In", 0i64)).unwrap();
    live.define(layer).unwrap();
    live.create("Layer", "A").unwrap();
    live.create("Layer", "B").unwrap();
    live.connect(
        &Endpoint::local("A", "Out"),
        &Endpoint::local("B", "In"),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )
    .unwrap();
    let here = |b: &str, p: &str| Endpoint::node(NodeId(2), b, p);
    let changes = vec![
        Change::DisconnectBetween { source: here("A", "Out"), destination: here("B", "In") },
        Change::Create { class: "Layer".into(), name: "C".into() },
        Change::Connect {
            source: here("A", "Out"),
            destination: here("C", "In"),
            kind: ConnectionKind::Suppress(Duration::from_millis(300)),
            priority: 0,
        },
    ];
    let send = |core: &mut NodeCore, t: u64, id: u64, body: ControlBody| {
        core.receive(ms(t), NodeId(9), Message::Control(ControlMessage { id, body }));
        while core.pop_outgoing().is_some() {}
    };
    send(&mut live, 0, 1, ControlBody::Prepare { txn: 1, changes: changes.clone(), hold: Duration::from_secs(2) });
    send(&mut live, 10, 2, ControlBody::Commit { txn: 1, delay: Duration::from_millis(40) });
    for t in [20, 49, 50, 60] {
        live.poll(ms(t));
        live.write_named(ms(t), "A", "Out", t as i64).unwrap();
    }
    send(
        &mut live,
        70,
        3,
        ControlBody::Prepare {
            txn: 2,
            changes: vec![Change::Remove { name: "C".into() }],
            hold: Duration::from_secs(2),
        },
    );
    send(&mut live, 80, 4, ControlBody::Abort { txn: 2 });
    live.poll(ms(90));
    assert!(matches!(live.transactions()[0].state, TransactionState::Applied { at, .. } if at == ms(50)));
    let journal = live.stop_journal();
    let entries: Vec<Entry> =
        journal.iter().enumerate().map(|(i, e)| decode(&encode(i as u64, e).1).unwrap().entry).collect();
    let recording = Recording {
        node: NodeId(2),
        segments: Vec::new(),
        entries,
        ending: Ending::Closed,
        gap: None,
        checkpoint: None,
    };
    let mut replay = Replay::new(&recording);
    replay.run_to_end().unwrap_or_else(|d| panic!("{d}"));
    let conns = |r: &ayllu::NodeReport| {
        r.connections.iter().map(|c| (c.source.to_string(), c.destination.to_string(), c.kind)).collect::<Vec<_>>()
    };
    assert_eq!(conns(&live.report()), conns(&replay.core().report()));
    assert_eq!(live.transactions(), replay.core().transactions());
    assert!(replay.checked() >= 4);
}
