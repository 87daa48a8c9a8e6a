//! Golden vectors of the transaction requests PREPARE, COMMIT and ABORT (spec/protocol.md
//! "Transactions"), in `spec/vectors/transactions.json`, kept apart from `vectors.json`
//! because AylluLite does not take part in transactions: its conformance check is that it
//! decodes each of these as a request of an unknown operation (`lite_expect`) and answers it
//! with an error.
//!
//! `AYLLU_BLESS=1 cargo test -p ayllu-wire --test wire` writes the file and the
//! fuzzing seeds (`fuzz/corpus/decode_datagram/txn_*`); otherwise the test fails if they
//! differ from what the encoder gives. Every vector decodes to its messages and re-encodes to
//! its bytes; every prefix of every vector decodes without a panic, to the same messages or
//! to none.

use std::path::{Path, PathBuf};

use ayllu_core::{BleConfig, Change, ConnectionId, ConnectionKind, ControlBody, Duration, Endpoint, NodeId};
use ayllu_wire::{decode, encode_datagram, ReceiverConfig, WireMessage};
use serde_json::{json, Value as Json};

const TEAM: u32 = 7;
const SENDER: u32 = 1;
const SEQ: u64 = 1 << 32;

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn request(id: u64, body: ControlBody) -> WireMessage {
    WireMessage::Request { id, body, signature: None }
}

/// Name, description, request.
fn vectors() -> Vec<(&'static str, &'static str, WireMessage)> {
    let n2 = |b: &str, p: &str| Endpoint::node(NodeId(2), b, p);
    vec![
        (
            "txn_prepare_rewire",
            "PREPARE txn 77, hold 5 s: create Avoid2 (Avoid), connect Avoid2.Out -> Motor.In suppressing for 2 s \
             at priority 3, remove Avoid1",
            request(
                60,
                ControlBody::Prepare {
                    txn: 77,
                    hold: Duration::from_secs(5),
                    changes: vec![
                        Change::Create { class: "Avoid".into(), name: "Avoid2".into() },
                        Change::Connect {
                            source: n2("Avoid2", "Out"),
                            destination: n2("Motor", "In"),
                            kind: ConnectionKind::Suppress(Duration::from_secs(2)),
                            priority: 3,
                        },
                        Change::Remove { name: "Avoid1".into() },
                    ],
                },
            ),
        ),
        (
            "txn_prepare_every_change",
            "PREPARE txn 78, hold 1 s, one change of every tag: disconnect 19, disconnect between two ports, \
             join and leave a group, connect to a group, BLE join",
            request(
                61,
                ControlBody::Prepare {
                    txn: 78,
                    hold: Duration::from_secs(1),
                    changes: vec![
                        Change::Disconnect { conn: ConnectionId(19) },
                        Change::DisconnectBetween { source: n2("OBS1", "Rotate"), destination: n2("Motor", "In") },
                        Change::Join { group: "Peers".into() },
                        Change::Leave { group: "Old".into() },
                        Change::Connect {
                            source: n2("OBS1", "Local"),
                            destination: Endpoint::group("Peers", "OBS1", "Best"),
                            kind: ConnectionKind::Normal,
                            priority: 0,
                        },
                        Change::BleJoin {
                            behavior: "OBS1".into(),
                            config: BleConfig {
                                group: "Peers".into(),
                                output: "Rotate".into(),
                                claim_rate_hz: 1.0,
                                inhibit_period: ms(2250),
                                network_delay: ms(50),
                            },
                        },
                    ],
                },
            ),
        ),
        (
            "txn_prepare_empty",
            "PREPARE txn 79 with no changes (a node that only switches with the others)",
            request(62, ControlBody::Prepare { txn: 79, hold: ms(800), changes: vec![] }),
        ),
        (
            "txn_commit",
            "COMMIT txn 77: switch 180 ms after receipt",
            request(63, ControlBody::Commit { txn: 77, delay: ms(180) }),
        ),
        ("txn_abort", "ABORT txn 77", request(64, ControlBody::Abort { txn: 77 })),
    ]
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn op_code(m: &WireMessage) -> u8 {
    match m {
        WireMessage::Request { body: ControlBody::Prepare { .. }, .. } => ayllu_wire::op::PREPARE,
        WireMessage::Request { body: ControlBody::Commit { .. }, .. } => ayllu_wire::op::COMMIT,
        _ => ayllu_wire::op::ABORT,
    }
}

fn document() -> (String, Vec<(&'static str, Vec<u8>)>) {
    let mut seeds = Vec::new();
    let list: Vec<Json> = vectors()
        .into_iter()
        .map(|(name, description, m)| {
            let bytes = encode_datagram(TEAM, NodeId(SENDER), SEQ, None, std::slice::from_ref(&m)).unwrap();
            let WireMessage::Request { id, body, .. } = &m else { unreachable!() };
            seeds.push((name, bytes.clone()));
            json!({
                "name": name, "description": description, "team": TEAM, "auth": false, "hex": hex(&bytes),
                "expect": {"ok": true, "sender": SENDER, "seq": SEQ, "request": {"id": id, "debug": format!("{body:?}")}},
                "lite_expect": {"ok": true, "sender": SENDER, "seq": SEQ,
                    "messages": [{"kind": "request", "id": id, "op": "unknown", "code": op_code(&m)}]},
            })
        })
        .collect();
    let doc = json!({"protocol_version": 1, "vectors": list});
    let mut text = serde_json::to_string_pretty(&doc).unwrap();
    text.push('\n');
    (text, seeds)
}

#[test]
fn transaction_vectors() {
    let (text, seeds) = document();
    let path = repo().join("spec/vectors/transactions.json");
    let corpus = repo().join("fuzz/corpus/decode_datagram");
    if std::env::var_os("AYLLU_BLESS").is_some_and(|v| v == "1") {
        std::fs::write(&path, &text).unwrap();
        std::fs::create_dir_all(&corpus).unwrap();
        for (name, bytes) in &seeds {
            std::fs::write(corpus.join(name), bytes).unwrap();
        }
    } else {
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            on_disk == text,
            "{} differs from what the encoder generates; if intended, run \
             `AYLLU_BLESS=1 cargo test -p ayllu-wire --test wire`",
            path.display()
        );
        for (name, bytes) in &seeds {
            assert_eq!(&std::fs::read(corpus.join(name)).unwrap_or_default(), bytes, "fuzz seed {name} is stale");
        }
    }
    let config = ReceiverConfig::open(TEAM);
    for (name, _, m) in vectors() {
        let bytes = encode_datagram(TEAM, NodeId(SENDER), SEQ, None, std::slice::from_ref(&m)).unwrap();
        let d = decode(&bytes, &config).unwrap_or_else(|e| panic!("{name}: dropped as {e}"));
        assert_eq!(d.messages, vec![m.clone()], "{name}");
        // Every prefix: no panic; a cut message is either refused whole or absent.
        for cut in 0..bytes.len() {
            if let Ok(d) = decode(&bytes[..cut], &config) {
                assert!(
                    d.messages.iter().all(|x| *x == m || !matches!(x, WireMessage::Request { .. })),
                    "{name}@{cut}"
                );
            }
        }
    }
}

#[test]
fn what_cannot_be_sent_is_refused_by_the_encoder() {
    let bad = |changes: Vec<Change>| {
        let m = request(1, ControlBody::Prepare { txn: 1, hold: ms(1), changes });
        encode_datagram(TEAM, NodeId(SENDER), SEQ, None, &[m]).is_err()
    };
    // A local endpoint means different things on each side: never sent.
    assert!(bad(vec![Change::DisconnectBetween {
        source: Endpoint::local("A", "Out"),
        destination: Endpoint::node(NodeId(2), "B", "In")
    }]));
    assert!(bad(vec![Change::Join { group: String::new() }]));
    assert!(bad(vec![Change::Remove { name: "x".into() }; 256]), "at most 255 changes in one PREPARE");
    assert!(!bad(vec![Change::Remove { name: "x".into() }; 30]));
}
