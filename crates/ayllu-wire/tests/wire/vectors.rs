//! Golden vectors: the conformance contract every implementation of `spec/protocol.md` checks
//! itself against (`spec/conformance.md`).
//!
//! The vectors are generated here, from the list in [`vectors`]. `AYLLU_BLESS=1 cargo test -p
//! ayllu-wire --test wire` writes `spec/vectors/vectors.json` and the fuzzing seed corpus
//! (`fuzz/corpus/decode_datagram/`); without the variable the test regenerates both in memory
//! and fails if the files differ, so a change of the encoding can never go unnoticed. Then it
//! reads the file as another implementation would: decodes every vector and compares with its
//! expectation, and re-encodes every valid vector from its JSON expectation, byte for byte.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use ayllu_core::{ConnectionId, ConnectionKind, ControlBody, Duration, Endpoint, NodeId, PortMessage, Value};
use ayllu_wire::{
    decode, encode_datagram, kind, DatagramWriter, DropReason, Key, ReceiverConfig, ReplyPart, WireMessage,
    MAX_DATAGRAM_LEN,
};
use serde_json::{json, Value as Json};

const TEAM: u32 = 7;
const SENDER: u32 = 1;
/// A sender started at Unix second 1 (`boot_seconds << 32`), first datagram.
const SEQ: u64 = 1 << 32;
/// The team key of every `"auth": true` vector: bytes 0x00..=0x1f.
const KEY: Key = {
    let mut k = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        k[i] = i as u8;
        i += 1;
    }
    k
};

struct Vector {
    name: &'static str,
    description: &'static str,
    /// The receiver's team.
    team: u32,
    /// The receiver holds [`KEY`].
    auth: bool,
    bytes: Vec<u8>,
    /// Whether an encoder produces these bytes from the expected messages.
    encode: bool,
    expect: Expect,
}

enum Expect {
    Ok { sender: u32, seq: u64, messages: Vec<WireMessage> },
    Drop(DropReason),
}

// ---------------------------------------------------------------------------------------------
// Building vectors

fn port(conn: u64, seq: u64, kind: ConnectionKind, priority: i32, behavior: &str, port: &str, v: Value) -> WireMessage {
    WireMessage::Port(PortMessage {
        conn: ConnectionId(conn),
        seq,
        behavior: behavior.into(),
        port: port.into(),
        kind,
        priority,
        value: v,
    })
}

/// `message` (a [`WireMessage::Port`]) as sent to `group`.
fn group_port(group: &str, message: WireMessage) -> WireMessage {
    let WireMessage::Port(message) = message else { panic!("a PORT message") };
    WireMessage::GroupPort { group: group.into(), message }
}

fn port_value(v: Value) -> WireMessage {
    port(3, 1, ConnectionKind::Normal, 0, "OBS2", "Rotate", v)
}

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn float_bits(bits: u64) -> Value {
    Value::Float(f64::from_bits(bits))
}

fn request(id: u64, body: ControlBody) -> WireMessage {
    WireMessage::Request { id, body, signature: None }
}

/// The operator secret the signed vectors use (its seed is 32 bytes of 0x11); the vectors are
/// requests from node 3 to node 9 of team 7.
fn vector_operator() -> ayllu_wire::OperatorSecret {
    ayllu_wire::OperatorSecret::from_seed(&[0x11; 32])
}

fn signed_request(id: u64, body: ControlBody) -> WireMessage {
    let request = ayllu_wire::SignedRequest { team: 7, requester: NodeId(3), receiver: NodeId(9), id, body: &body };
    let signature = Some(vector_operator().sign(&request).unwrap());
    WireMessage::Request { id, body, signature }
}

fn reply(id: u64, part: u16, parts: u16, payload: ReplyPart) -> WireMessage {
    WireMessage::Reply { id, part, parts, payload }
}

fn hello(interval_ms: u32, name: &str, groups: &[&str]) -> WireMessage {
    WireMessage::Hello { interval_ms, name: name.into(), groups: groups.iter().map(|g| Arc::from(*g)).collect() }
}

/// A valid vector the encoder produces: team 7, sender 1, sequence 2^32, open.
fn ok(name: &'static str, description: &'static str, messages: Vec<WireMessage>) -> Vector {
    ok_with(name, description, SENDER, SEQ, false, messages)
}

fn ok_with(
    name: &'static str,
    description: &'static str,
    sender: u32,
    seq: u64,
    auth: bool,
    messages: Vec<WireMessage>,
) -> Vector {
    let bytes = encode_datagram(TEAM, NodeId(sender), seq, auth.then_some(KEY), &messages)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    Vector { name, description, team: TEAM, auth, bytes, encode: true, expect: Expect::Ok { sender, seq, messages } }
}

fn dropped(name: &'static str, description: &'static str, auth: bool, bytes: Vec<u8>, cause: DropReason) -> Vector {
    Vector { name, description, team: TEAM, auth, bytes, encode: false, expect: Expect::Drop(cause) }
}

/// A datagram header with any fields, for input no encoder produces.
fn header(flags: u8, team: u32) -> Vec<u8> {
    let mut b = vec![0x41, 0x59, 1, flags];
    b.extend_from_slice(&team.to_le_bytes());
    b.extend_from_slice(&SENDER.to_le_bytes());
    b.extend_from_slice(&SEQ.to_le_bytes());
    b
}

/// Messages as `(kind, body)`, for input no encoder produces.
type RawMessages = Vec<(u8, Vec<u8>)>;

/// An open datagram of team 7 holding raw messages `(kind, body)`.
fn raw(messages: &[(u8, Vec<u8>)]) -> Vec<u8> {
    let mut b = header(0, TEAM);
    for (kind, body) in messages {
        b.push(*kind);
        b.extend_from_slice(&(body.len() as u16).to_le_bytes());
        b.extend_from_slice(body);
    }
    b
}

/// Little-endian body builder.
#[derive(Default, Clone)]
struct B(Vec<u8>);

impl B {
    fn u8(mut self, v: u8) -> Self {
        self.0.push(v);
        self
    }
    fn u16(mut self, v: u16) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u32(mut self, v: u32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u64(mut self, v: u64) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn i32(self, v: i32) -> Self {
        self.u32(v as u32)
    }
    fn bytes(mut self, v: &[u8]) -> Self {
        self.0.extend_from_slice(v);
        self
    }
    fn str8(self, v: &[u8]) -> Self {
        self.u8(v.len() as u8).bytes(v)
    }
    fn done(self) -> Vec<u8> {
        self.0
    }
}

/// A PORT body with the given connection kind, period, names and encoded value.
fn port_body(kind: u8, period: u64, behavior: &[u8], port: &[u8], value: &[u8]) -> Vec<u8> {
    B::default().u64(3).u64(1).u8(kind).u64(period).i32(0).str8(behavior).str8(port).bytes(value).done()
}

/// A REPLY body header.
fn reply_head(status: u8, part: u16, parts: u16) -> B {
    B::default().u64(77).u8(status).u16(part).u16(parts)
}

/// A CONNECT request body up to (excluding) the destination endpoint.
fn connect_head() -> B {
    B::default().u64(40).u8(1).str8(b"OBS1").str8(b"Rotate")
}

fn int_value(v: i64) -> Vec<u8> {
    let mut b = vec![1];
    b.extend_from_slice(&v.to_le_bytes());
    b
}

fn vectors() -> Vec<Vector> {
    let long_behavior = format!("{}x", "ñ".repeat(127)); // 255 bytes, multi-byte UTF-8
    let long_port = "P".repeat(255);
    let mut v = vec![
        // --- PORT, one per connection kind ---
        ok(
            "port_normal_int",
            "one PORT message, normal connection (period 0), int value",
            vec![port(3, 1, ConnectionKind::Normal, 0, "OBS2", "Rotate", Value::Int(42))],
        ),
        ok(
            "port_suppress_bool",
            "suppress for 200 ms; the value (bool true) is carried but not written",
            vec![port(4, 2, ConnectionKind::Suppress(ms(200)), 0, "Motor", "Speed", Value::Bool(true))],
        ),
        ok(
            "port_inhibit_bool_false",
            "inhibit for 2.25 s, bool false",
            vec![port(5, 3, ConnectionKind::Inhibit(ms(2250)), 0, "Motor", "Speed", Value::Bool(false))],
        ),
        ok(
            "port_override_in_float",
            "override-in for 100 ms with priority -3, float pi",
            vec![port(
                6,
                9,
                ConnectionKind::OverrideIn(ms(100)),
                -3,
                "Avoid",
                "Heading",
                Value::Float(std::f64::consts::PI),
            )],
        ),
        ok(
            "port_override_out_float_negative_zero",
            "override-out for 200 ms, float -0.0 (bits 8000000000000000, not 0.0)",
            vec![port(7, 1, ConnectionKind::OverrideOut(ms(200)), 0, "OBS2", "Rotate", Value::Float(-0.0))],
        ),
        ok(
            "port_write_inhibit_bool",
            "write-inhibit for 2.3 s (a BLE claim), largest priority",
            vec![port(
                21,
                1000,
                ConnectionKind::WriteInhibit(Duration::from_nanos(2_300_000_000)),
                i32::MAX,
                "OBS1",
                "Rotate",
                Value::Bool(true),
            )],
        ),
        ok(
            "port_large_numbers",
            "connection id and sequence 2^53-1, smallest priority, int -(2^53-1)",
            vec![port(
                (1 << 53) - 1,
                (1 << 53) - 1,
                ConnectionKind::Normal,
                i32::MIN,
                "B",
                "P",
                Value::Int(-((1 << 53) - 1)),
            )],
        ),
        ok(
            "port_max_names",
            "behavior (multi-byte UTF-8) and port names of 255 bytes, the str8 maximum",
            vec![port(3, 1, ConnectionKind::Normal, 0, &long_behavior, &long_port, Value::Int(0))],
        ),
        // --- values ---
        ok(
            "value_float_nan_payload",
            "a quiet NaN with payload 1: the bits survive",
            vec![port_value(float_bits(0x7ff8_0000_0000_0001))],
        ),
        ok(
            "value_float_negative_nan",
            "a NaN with the sign bit set",
            vec![port_value(float_bits(0xfff8_0000_0000_0000))],
        ),
        ok("value_float_infinity", "float -infinity", vec![port_value(Value::Float(f64::NEG_INFINITY))]),
        ok("value_text_empty", "text of length 0", vec![port_value(Value::text(""))]),
        ok("value_text_unicode", "text with 2-, 3- and 4-byte UTF-8", vec![port_value(Value::text("héllo ✓ 🤖"))]),
        ok("value_bytes", "bytes 00 ff 10 80", vec![port_value(Value::bytes(&[0x00, 0xff, 0x10, 0x80]))]),
        ok("value_bytes_empty", "bytes of length 0", vec![port_value(Value::bytes(&[]))]),
        ok(
            "value_vector",
            "a vector of 4 floats, including -0.0 and a NaN",
            vec![port_value(Value::vector(&[1.5, -2.0, -0.0, f64::from_bits(0x7ff8_0000_0000_0000)]))],
        ),
        ok("value_vector_empty", "a vector of 0 floats", vec![port_value(Value::vector(&[]))]),
        // --- HELLO ---
        ok(
            "hello",
            "HELLO every 1000 ms from robot-1, in two groups",
            vec![hello(1000, "robot-1", &["Peers", "Scouts"])],
        ),
        ok("hello_bare", "HELLO with an empty name and no groups", vec![hello(250, "", &[])]),
        // --- REQUEST ---
        ok(
            "request_connect_node",
            "CONNECT OBS1.Rotate to node 2's OBS2.Rotate, override-out 200 ms",
            vec![request(
                40,
                ControlBody::Connect {
                    source_behavior: "OBS1".into(),
                    source_port: "Rotate".into(),
                    destination: Endpoint::node(NodeId(2), "OBS2", "Rotate"),
                    kind: ConnectionKind::OverrideOut(ms(200)),
                    priority: 0,
                },
            )],
        ),
        ok(
            "request_connect_group",
            "CONNECT OBS1.Local to group Peers' OBS1.Best, normal, priority 5",
            vec![request(
                41,
                ControlBody::Connect {
                    source_behavior: "OBS1".into(),
                    source_port: "Local".into(),
                    destination: Endpoint::group("Peers", "OBS1", "Best"),
                    kind: ConnectionKind::Normal,
                    priority: 5,
                },
            )],
        ),
        ok(
            "request_disconnect",
            "DISCONNECT connection 19",
            vec![request(42, ControlBody::Disconnect { conn: ConnectionId(19) })],
        ),
        ok("request_list", "LIST (no arguments)", vec![request(43, ControlBody::List)]),
        ok(
            "request_why",
            "WHY OBS1.Rotate",
            vec![request(44, ControlBody::Why { behavior: "OBS1".into(), port: "Rotate".into() })],
        ),
        ok(
            "request_read",
            "READ OBS1.Rotate",
            vec![request(45, ControlBody::Read { behavior: "OBS1".into(), port: "Rotate".into() })],
        ),
        ok(
            "request_disconnect_signed",
            "DISCONNECT connection 19 with an operator signature (seed 32 x 0x11, node 3 to node 9, team 7)",
            vec![signed_request(49, ControlBody::Disconnect { conn: ConnectionId(19) })],
        ),
        ok(
            "request_connect_signed",
            "CONNECT with an operator signature (seed 32 x 0x11, node 3 to node 9, team 7)",
            vec![signed_request(
                50,
                ControlBody::Connect {
                    source_behavior: "OBS1".into(),
                    source_port: "Rotate".into(),
                    destination: Endpoint::Node { node: NodeId(3), behavior: "TOOL".into(), port: "In".into() },
                    kind: ConnectionKind::OverrideIn(ms(500)),
                    priority: 0,
                },
            )],
        ),
        ok("challenge", "CHALLENGE: echo this cookie", vec![WireMessage::Challenge { cookie: *b"0123456789abcdef" }]),
        ok("echo", "ECHO: a cookie sent back", vec![WireMessage::Echo { cookie: *b"0123456789abcdef" }]),
        ok(
            "request_unknown_op",
            "a REQUEST with operation 127: not malformed, answered with an error REPLY",
            vec![WireMessage::UnknownRequest { id: 46, op: 127 }],
        ),
        // --- REPLY ---
        ok(
            "reply_connection",
            "REPLY ok: connection 19 (to CONNECT or DISCONNECT)",
            vec![reply(40, 0, 1, ReplyPart::Connection(ConnectionId(19)))],
        ),
        ok(
            "reply_value",
            "REPLY ok: a float value (to READ)",
            vec![reply(45, 0, 1, ReplyPart::Value(Value::Float(-0.1)))],
        ),
        ok(
            "reply_report_part_0",
            "REPLY ok: part 0 of a report in 2 parts",
            vec![reply(43, 0, 2, ReplyPart::Report(r#"{"note":"a report cut "#.into()))],
        ),
        ok_with(
            "reply_report_part_1",
            "REPLY ok: part 1 of the same report (next datagram); the slices concatenate to JSON",
            SENDER,
            SEQ + 1,
            false,
            vec![reply(43, 1, 2, ReplyPart::Report(r#"in two ✓","n":[1,2]}"#.into()))],
        ),
        ok(
            "reply_error",
            "REPLY error: why the request failed",
            vec![reply(44, 0, 1, ReplyPart::Error("unknown behavior `OBS9`".into()))],
        ),
        // --- datagrams ---
        ok("empty_datagram", "a header and no messages (valid, applies nothing)", vec![]),
        ok(
            "batch_three",
            "three messages batched in one datagram: PORT, HELLO, REQUEST",
            vec![
                port(3, 2, ConnectionKind::Normal, 0, "OBS2", "Rotate", Value::Float(0.5)),
                hello(1000, "robot-1", &["Peers"]),
                request(47, ControlBody::List),
            ],
        ),
        ok_with(
            "auth_port",
            "an authenticated datagram: AUTH flag, MAC under key_hex",
            2,
            (1_700_000_000 << 32) + 5,
            true,
            vec![port(8, 4, ConnectionKind::Inhibit(ms(500)), 0, "OBS1", "Rotate", Value::Bool(true))],
        ),
        ok_with("auth_empty", "an authenticated datagram with no messages", 2, 9, true, vec![]),
        // --- PORT sent to a group (D-S10.6): the optional group field appended ---
        ok(
            "port_to_group",
            "a PORT sent to group `arm`: the node-addressed body plus the group as str8; receivers that have \
             not joined `arm` drop it (not_member), older receivers ignore the field",
            vec![group_port("arm", port(3, 1, ConnectionKind::Normal, 0, "OBS2", "Rotate", Value::Int(42)))],
        ),
        ok(
            "port_to_group_and_node",
            "a PORT to group `Peers` (override-in, text value) batched with a node-addressed PORT",
            vec![
                group_port(
                    "Peers",
                    port(9, 7, ConnectionKind::OverrideIn(ms(100)), 2, "Avoid", "Heading", Value::Text("left".into())),
                ),
                port(3, 2, ConnectionKind::Normal, 0, "OBS2", "Rotate", Value::Float(0.5)),
            ],
        ),
    ];

    // --- valid input no encoder produces ---
    let p = port_value(Value::Int(1));
    let p_body = port_body(0, 0, b"OBS2", b"Rotate", &int_value(1));
    let h = hello(1000, "robot-1", &[]);
    let h_body = B::default().u32(1000).str8(b"robot-1").u8(0).done();
    v.push(Vector {
        name: "unknown_kind_skipped",
        description: "a message of unknown kind 0x7e (4 bytes) between two known ones: skipped, the rest applied",
        team: TEAM,
        auth: false,
        bytes: raw(&[(kind::PORT, p_body.clone()), (0x7e, vec![1, 2, 3, 4]), (kind::HELLO, h_body)]),
        encode: false,
        expect: Expect::Ok {
            sender: SENDER,
            seq: SEQ,
            messages: vec![p.clone(), WireMessage::Unknown { code: 0x7e, length: 4 }, h],
        },
    });
    let mut longer = p_body.clone();
    longer.extend_from_slice(&[0xaa, 0xbb, 0xcc]);
    v.push(Vector {
        name: "trailing_body_bytes",
        description: "a PORT body with 3 bytes after its fields (a later version's fields): ignored",
        team: TEAM,
        auth: false,
        bytes: raw(&[(kind::PORT, longer)]),
        encode: false,
        expect: Expect::Ok { sender: SENDER, seq: SEQ, messages: vec![p.clone()] },
    });
    let mut grouped = p_body.clone();
    grouped.extend_from_slice(&[3, b'a', b'r', b'm', 0xaa, 0xbb]);
    v.push(Vector {
        name: "port_group_then_later_bytes",
        description: "a PORT naming group `arm` followed by 2 bytes (a later version's fields): the group is read, \
                      the rest ignored",
        team: TEAM,
        auth: false,
        bytes: raw(&[(kind::PORT, grouped)]),
        encode: false,
        expect: Expect::Ok { sender: SENDER, seq: SEQ, messages: vec![group_port("arm", p.clone())] },
    });
    let mut empty_group = p_body.clone();
    empty_group.extend_from_slice(&[0, 0xaa]);
    v.push(Vector {
        name: "port_empty_group",
        description: "a PORT whose group field is empty (then a later byte): sent to a node, applied by every \
                      receiver",
        team: TEAM,
        auth: false,
        bytes: raw(&[(kind::PORT, empty_group)]),
        encode: false,
        expect: Expect::Ok { sender: SENDER, seq: SEQ, messages: vec![p.clone()] },
    });
    let mut bad_group = p_body.clone();
    bad_group.extend_from_slice(&[2, 0xc3, 0x28]);
    v.push(Vector {
        name: "port_group_not_utf8",
        description: "a PORT whose bytes after the value are a str8 of invalid UTF-8: not a group, ignored as a \
                      later field would be (sent to a node)",
        team: TEAM,
        auth: false,
        bytes: raw(&[(kind::PORT, bad_group)]),
        encode: false,
        expect: Expect::Ok { sender: SENDER, seq: SEQ, messages: vec![p.clone()] },
    });
    v.push(Vector {
        name: "unknown_op_with_arguments",
        description: "a REQUEST with unknown operation 200 and argument bytes, which are not kept",
        team: TEAM,
        auth: false,
        bytes: raw(&[(kind::REQUEST, B::default().u64(48).u8(200).bytes(&[1, 2, 3]).done())]),
        encode: false,
        expect: Expect::Ok {
            sender: SENDER,
            seq: SEQ,
            messages: vec![WireMessage::UnknownRequest { id: 48, op: 200 }],
        },
    });
    let filler = MAX_DATAGRAM_LEN - 20 - 3;
    v.push(Vector {
        name: "max_size_accepted",
        description: "8192 bytes, the largest datagram a receiver accepts (one unknown-kind message)",
        team: TEAM,
        auth: false,
        bytes: raw(&[(0x7e, vec![0; filler])]),
        encode: false,
        expect: Expect::Ok {
            sender: SENDER,
            seq: SEQ,
            messages: vec![WireMessage::Unknown { code: 0x7e, length: filler as u16 }],
        },
    });

    // --- drop causes ---
    use DropReason::*;
    let good = v[0].bytes.clone();
    let good_auth = encode_datagram(TEAM, NodeId(2), 9, Some(KEY), std::slice::from_ref(&p)).unwrap();
    let mut d = vec![
        dropped(
            "oversized",
            "8193 bytes, one more than receivers accept",
            false,
            raw(&[(0x7e, vec![0; filler + 1])]),
            Oversized,
        ),
        dropped("truncated_header", "2 bytes", false, vec![0x41, 0x59], Truncated),
        dropped("truncated_header_19", "19 of the 20 header bytes", false, good[..19].to_vec(), Truncated),
        dropped(
            "truncated_message_header",
            "2 bytes after the header: less than a message header",
            false,
            {
                let mut b = header(0, TEAM);
                b.extend_from_slice(&[kind::PORT, 5]);
                b
            },
            Truncated,
        ),
        dropped(
            "truncated_message_body",
            "a PORT whose length runs one byte past the end of the datagram",
            false,
            good[..good.len() - 1].to_vec(),
            Truncated,
        ),
        dropped(
            "truncated_auth",
            "AUTH set but fewer than 36 bytes (no room for the MAC)",
            true,
            {
                let mut b = header(1, TEAM);
                b.extend_from_slice(&[0; 15]);
                b
            },
            Truncated,
        ),
        dropped(
            "bad_magic",
            "magic \"AZ\"",
            false,
            {
                let mut b = good.clone();
                b[1] = 0x5a;
                b
            },
            BadMagic,
        ),
        dropped(
            "bad_version",
            "version 2",
            false,
            {
                let mut b = good.clone();
                b[2] = 2;
                b
            },
            BadVersion,
        ),
        dropped(
            "bad_flags",
            "reserved flag bit 1 set",
            false,
            {
                let mut b = good.clone();
                b[3] = 0x02;
                b
            },
            BadFlags,
        ),
        dropped(
            "bad_flags_with_auth",
            "AUTH and reserved bit 7 set, receiver with key",
            true,
            {
                let mut b = good_auth.clone();
                b[3] = 0x81;
                b
            },
            BadFlags,
        ),
        dropped(
            "wrong_team",
            "a datagram of team 8 at a receiver of team 7",
            false,
            {
                let mut b = good.clone();
                b[4] = 8;
                b
            },
            WrongTeam,
        ),
        dropped(
            "wrong_team_before_mac",
            "team 8 with a bad MAC at a keyed receiver of team 7: the team is checked first",
            true,
            {
                let mut b = good_auth.clone();
                b[4] = 8;
                b
            },
            WrongTeam,
        ),
        dropped(
            "unauthenticated",
            "no AUTH flag at a receiver that holds the key",
            true,
            good.clone(),
            Unauthenticated,
        ),
        dropped(
            "unexpected_auth",
            "an authenticated datagram at an open receiver (never trusted unverified)",
            false,
            good_auth.clone(),
            UnexpectedAuth,
        ),
        dropped(
            "bad_mac",
            "the last MAC bit flipped",
            true,
            {
                let mut b = good_auth.clone();
                *b.last_mut().unwrap() ^= 1;
                b
            },
            BadMac,
        ),
        dropped(
            "bad_mac_body_changed",
            "one body byte changed after the MAC was computed",
            true,
            {
                let mut b = good_auth.clone();
                b[24] ^= 0x80;
                b
            },
            BadMac,
        ),
        dropped(
            "bad_mac_wrong_key",
            "a MAC under another key",
            true,
            encode_datagram(TEAM, NodeId(2), 9, Some([0xee; 32]), std::slice::from_ref(&p)).unwrap(),
            BadMac,
        ),
    ];
    // Malformed bodies: each breaks one rule of a known kind.
    let text = |b: &[u8]| {
        let mut v = vec![3];
        v.extend_from_slice(&(b.len() as u16).to_le_bytes());
        v.extend_from_slice(b);
        v
    };
    let malformed: Vec<(&'static str, &'static str, RawMessages)> = vec![
        ("malformed_port_short", "a PORT body of 10 bytes", vec![(kind::PORT, vec![0; 10])]),
        (
            "malformed_name_utf8",
            "a behavior name that is not UTF-8 (ff fe)",
            vec![(kind::PORT, port_body(0, 0, &[0xff, 0xfe], b"Rotate", &int_value(1)))],
        ),
        (
            "malformed_text_utf8",
            "a text value that is not UTF-8 (c3 28)",
            vec![(kind::PORT, port_body(0, 0, b"OBS2", b"Rotate", &text(&[0xc3, 0x28])))],
        ),
        ("malformed_bool", "a bool byte of 2", vec![(kind::PORT, port_body(0, 0, b"OBS2", b"Rotate", &[0, 2]))]),
        (
            "malformed_value_type",
            "value type 6",
            vec![(kind::PORT, port_body(0, 0, b"OBS2", b"Rotate", &[6, 0, 0, 0, 0, 0, 0, 0, 0]))],
        ),
        (
            "malformed_value_short",
            "an int value with 7 of its 8 bytes",
            vec![(kind::PORT, port_body(0, 0, b"OBS2", b"Rotate", &int_value(1)[..8]))],
        ),
        (
            "malformed_vector_short",
            "a vector that says 3 floats and has 2",
            vec![(kind::PORT, port_body(0, 0, b"OBS2", b"Rotate", &B::default().u8(5).u8(3).u64(0).u64(0).done()))],
        ),
        (
            "malformed_text_short",
            "a text value that says 5 bytes and has 2",
            vec![(kind::PORT, port_body(0, 0, b"OBS2", b"Rotate", &[3, 5, 0, b'h', b'i']))],
        ),
        (
            "malformed_normal_with_period",
            "a normal connection with period 1 ns",
            vec![(kind::PORT, port_body(0, 1, b"OBS2", b"Rotate", &int_value(1)))],
        ),
        (
            "malformed_timed_without_period",
            "a suppress connection with period 0",
            vec![(kind::PORT, port_body(1, 0, b"OBS2", b"Rotate", &int_value(1)))],
        ),
        (
            "malformed_conn_kind",
            "connection kind 6",
            vec![(kind::PORT, port_body(6, 1000, b"OBS2", b"Rotate", &int_value(1)))],
        ),
        (
            "malformed_empty_behavior",
            "a PORT with a zero-length behavior name",
            vec![(kind::PORT, port_body(0, 0, b"", b"Rotate", &int_value(1)))],
        ),
        (
            "malformed_empty_port",
            "a PORT with a zero-length port name",
            vec![(kind::PORT, port_body(0, 0, b"OBS2", b"", &int_value(1)))],
        ),
        (
            "malformed_hello_zero_interval",
            "HELLO with interval_ms 0",
            vec![(kind::HELLO, B::default().u32(0).str8(b"r").u8(0).done())],
        ),
        (
            "malformed_hello_empty_group",
            "HELLO listing a zero-length group name",
            vec![(kind::HELLO, B::default().u32(1000).str8(b"r").u8(2).str8(b"Peers").str8(b"").done())],
        ),
        (
            "malformed_hello_no_groups",
            "HELLO without its group count",
            vec![(kind::HELLO, B::default().u32(1000).str8(b"r").done())],
        ),
        (
            "malformed_endpoint_tag_0",
            "CONNECT to endpoint tag 0 (local: never sent)",
            vec![(kind::REQUEST, connect_head().u8(0).str8(b"OBS2").str8(b"Rotate").u8(0).u64(0).i32(0).done())],
        ),
        (
            "malformed_endpoint_tag_3",
            "CONNECT to endpoint tag 3 (unknown)",
            vec![(kind::REQUEST, connect_head().u8(3).str8(b"OBS2").str8(b"Rotate").u8(0).u64(0).i32(0).done())],
        ),
        (
            "malformed_endpoint_empty_group",
            "CONNECT to a group with a zero-length name",
            vec![(
                kind::REQUEST,
                connect_head().u8(2).str8(b"").str8(b"OBS1").str8(b"Best").u8(0).u64(0).i32(0).done(),
            )],
        ),
        (
            "malformed_connect_short",
            "CONNECT without its priority",
            vec![(kind::REQUEST, connect_head().u8(1).u32(2).str8(b"OBS2").str8(b"Rotate").u8(0).u64(0).done())],
        ),
        (
            "malformed_connect_kind",
            "CONNECT with a suppress kind and period 0",
            vec![(kind::REQUEST, connect_head().u8(1).u32(2).str8(b"OBS2").str8(b"Rotate").u8(1).u64(0).i32(0).done())],
        ),
        (
            "malformed_why_short",
            "WHY without its port name",
            vec![(kind::REQUEST, B::default().u64(44).u8(4).str8(b"OBS1").done())],
        ),
        (
            "malformed_reply_parts_0",
            "REPLY with parts 0",
            vec![(kind::REPLY, reply_head(0, 0, 0).u8(3).u16(2).bytes(b"{}").done())],
        ),
        (
            "malformed_reply_parts_65",
            "REPLY with parts 65 (at most 64)",
            vec![(kind::REPLY, reply_head(0, 0, 65).u8(3).u16(2).bytes(b"{}").done())],
        ),
        (
            "malformed_reply_part_index",
            "REPLY part 2 of 2 (parts are numbered from 0)",
            vec![(kind::REPLY, reply_head(0, 2, 2).u8(3).u16(2).bytes(b"{}").done())],
        ),
        (
            "malformed_reply_error_in_parts",
            "an error REPLY with parts 2 (only reports have parts)",
            vec![(kind::REPLY, reply_head(1, 0, 2).u16(2).bytes(b"no").done())],
        ),
        (
            "malformed_reply_value_in_parts",
            "a value REPLY with parts 2 (only reports have parts)",
            vec![(kind::REPLY, reply_head(0, 0, 2).u8(2).bytes(&[0, 1]).done())],
        ),
        ("malformed_reply_status", "REPLY status 2", vec![(kind::REPLY, reply_head(2, 0, 1).u8(1).u64(19).done())]),
        ("malformed_reply_result", "REPLY result 4", vec![(kind::REPLY, reply_head(0, 0, 1).u8(4).u64(19).done())]),
        (
            "malformed_report_utf8",
            "a report slice that is not UTF-8 (cut inside a character)",
            vec![(kind::REPLY, reply_head(0, 0, 2).u8(3).u16(3).bytes(&[b'{', 0xe2, 0x9c]).done())],
        ),
        (
            "malformed_after_valid",
            "a valid HELLO, then a malformed PORT: the whole datagram is dropped",
            vec![
                (kind::HELLO, B::default().u32(1000).str8(b"r").u8(0).done()),
                (kind::PORT, port_body(0, 0, b"OBS2", b"Rotate", &[0, 9])),
            ],
        ),
    ];
    for (name, description, messages) in malformed {
        d.push(dropped(name, description, false, raw(&messages), Malformed));
    }
    // Malformed inside a correctly authenticated datagram: the MAC passes, the body does not.
    let mut w = DatagramWriter::new(TEAM, NodeId(2), 9, Some(KEY), MAX_DATAGRAM_LEN);
    w.push_raw(kind::PORT, &port_body(0, 0, b"OBS2", b"Rotate", &[0, 2])).unwrap();
    d.push(dropped(
        "malformed_authenticated",
        "a bad bool byte in a datagram whose MAC is valid",
        true,
        w.finish(),
        Malformed,
    ));
    v.extend(d);
    v
}

// ---------------------------------------------------------------------------------------------
// JSON, as spec/conformance.md lays it out

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    assert!(s.len().is_multiple_of(2), "odd hex length");
    (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex digit")).collect()
}

fn bits_json(x: f64) -> Json {
    json!(format!("{:016x}", x.to_bits()))
}

fn bits_from(j: &Json) -> f64 {
    f64::from_bits(u64::from_str_radix(j.as_str().expect("bits string"), 16).expect("16 hex digits"))
}

fn value_json(v: &Value) -> Json {
    match v {
        Value::Bool(b) => json!({"type": "bool", "v": b}),
        Value::Int(i) => json!({"type": "int", "v": i}),
        Value::Float(x) => json!({"type": "float", "bits": bits_json(*x)}),
        Value::Text(s) => json!({"type": "text", "v": &**s}),
        Value::Bytes(b) => json!({"type": "bytes", "hex": hex(b)}),
        Value::Vector(xs) => json!({"type": "vector", "bits": xs.iter().map(|x| bits_json(*x)).collect::<Vec<_>>()}),
    }
}

fn value_from(j: &Json) -> Value {
    match j["type"].as_str().expect("value type") {
        "bool" => Value::Bool(j["v"].as_bool().unwrap()),
        "int" => Value::Int(j["v"].as_i64().unwrap()),
        "float" => Value::Float(bits_from(&j["bits"])),
        "text" => Value::text(j["v"].as_str().unwrap()),
        "bytes" => Value::bytes(&unhex(j["hex"].as_str().unwrap())),
        "vector" => Value::vector(&j["bits"].as_array().unwrap().iter().map(bits_from).collect::<Vec<_>>()),
        other => panic!("unknown value type {other}"),
    }
}

fn kind_json(k: ConnectionKind) -> (Json, Json) {
    (json!(k.name()), json!(k.period().map_or(0, Duration::as_nanos)))
}

fn kind_from(j: &Json) -> ConnectionKind {
    let period = Duration::from_nanos(j["period_ns"].as_u64().unwrap());
    ConnectionKind::from_name(j["conn_kind"].as_str().unwrap(), period).expect("connection kind name")
}

fn str_from(j: &Json, field: &str) -> Arc<str> {
    Arc::from(j[field].as_str().unwrap_or_else(|| panic!("missing string {field}")))
}

fn u64_from(j: &Json, field: &str) -> u64 {
    j[field].as_u64().unwrap_or_else(|| panic!("missing number {field}"))
}

fn message_json(m: &WireMessage) -> Json {
    match m {
        WireMessage::Port(p) => {
            let (conn_kind, period_ns) = kind_json(p.kind);
            json!({
                "kind": "port", "conn": p.conn.0, "seq": p.seq, "conn_kind": conn_kind, "period_ns": period_ns,
                "priority": p.priority, "behavior": &*p.behavior, "port": &*p.port, "value": value_json(&p.value),
            })
        }
        WireMessage::GroupPort { group, message } => {
            let mut j = message_json(&WireMessage::Port(message.clone()));
            j.as_object_mut().unwrap().insert("group".into(), json!(&**group));
            j
        }
        WireMessage::Hello { interval_ms, name, groups } => json!({
            "kind": "hello", "interval_ms": interval_ms, "name": &**name,
            "groups": groups.iter().map(|g| &**g).collect::<Vec<_>>(),
        }),
        WireMessage::Request { id, body, signature } => {
            let mut j = json!({"kind": "request", "id": id});
            let o = j.as_object_mut().unwrap();
            match body {
                ControlBody::Connect { source_behavior, source_port, destination, kind, priority } => {
                    o.insert("op".into(), json!("connect"));
                    o.insert("src_behavior".into(), json!(&**source_behavior));
                    o.insert("src_port".into(), json!(&**source_port));
                    let dest = match destination {
                        Endpoint::Node { node, behavior, port } => {
                            json!({"node": node.0, "behavior": &**behavior, "port": &**port})
                        }
                        Endpoint::Group { group, behavior, port } => {
                            json!({"group": &**group, "behavior": &**behavior, "port": &**port})
                        }
                        Endpoint::Local { .. } => panic!("local endpoints are never sent"),
                    };
                    o.insert("destination".into(), dest);
                    let (conn_kind, period_ns) = kind_json(*kind);
                    o.insert("conn_kind".into(), conn_kind);
                    o.insert("period_ns".into(), period_ns);
                    o.insert("priority".into(), json!(priority));
                }
                ControlBody::Disconnect { conn } => {
                    o.insert("op".into(), json!("disconnect"));
                    o.insert("conn".into(), json!(conn.0));
                }
                ControlBody::List => {
                    o.insert("op".into(), json!("list"));
                }
                ControlBody::Why { behavior, port } | ControlBody::Read { behavior, port } => {
                    let op = if matches!(body, ControlBody::Why { .. }) { "why" } else { "read" };
                    o.insert("op".into(), json!(op));
                    o.insert("behavior".into(), json!(&**behavior));
                    o.insert("port".into(), json!(&**port));
                }
                ControlBody::Reply { .. } => panic!("replies are REPLY messages"),
                ControlBody::Prepare { .. } | ControlBody::Commit { .. } | ControlBody::Abort { .. } => {
                    panic!("transaction requests have their own vectors (tests/wire/transaction_vectors.rs)")
                }
            }
            if let Some(sig) = signature {
                o.insert("signature_hex".into(), json!(hex(sig)));
            }
            j
        }
        WireMessage::Challenge { cookie } => json!({"kind": "challenge", "cookie_hex": hex(cookie)}),
        WireMessage::Echo { cookie } => json!({"kind": "echo", "cookie_hex": hex(cookie)}),
        WireMessage::UnknownRequest { id, op } => json!({"kind": "request", "id": id, "op": "unknown", "code": op}),
        WireMessage::Reply { id, part, parts, payload } => {
            let mut j = json!({"kind": "reply", "id": id});
            let o = j.as_object_mut().unwrap();
            let status = if matches!(payload, ReplyPart::Error(_)) { "error" } else { "ok" };
            o.insert("status".into(), json!(status));
            o.insert("part".into(), json!(part));
            o.insert("parts".into(), json!(parts));
            match payload {
                ReplyPart::Error(message) => o.insert("message".into(), json!(message)),
                ReplyPart::Connection(c) => o.insert("result".into(), json!({"connection": c.0})),
                ReplyPart::Value(v) => o.insert("result".into(), json!({"value": value_json(v)})),
                ReplyPart::Report(s) => o.insert("result".into(), json!({"report": s})),
            };
            j
        }
        WireMessage::Unknown { code, length } => json!({"kind": "unknown", "code": code, "length": length}),
    }
}

fn message_from(j: &Json) -> WireMessage {
    match j["kind"].as_str().expect("message kind") {
        "port" => {
            let message = PortMessage {
                conn: ConnectionId(u64_from(j, "conn")),
                seq: u64_from(j, "seq"),
                behavior: str_from(j, "behavior"),
                port: str_from(j, "port"),
                kind: kind_from(j),
                priority: j["priority"].as_i64().unwrap() as i32,
                value: value_from(&j["value"]),
            };
            match j.get("group") {
                Some(_) => WireMessage::GroupPort { group: str_from(j, "group"), message },
                None => WireMessage::Port(message),
            }
        }
        "hello" => WireMessage::Hello {
            interval_ms: u64_from(j, "interval_ms") as u32,
            name: str_from(j, "name"),
            groups: j["groups"].as_array().unwrap().iter().map(|g| Arc::from(g.as_str().unwrap())).collect(),
        },
        "request" => {
            let id = u64_from(j, "id");
            let body = match j["op"].as_str().unwrap() {
                "connect" => {
                    let d = &j["destination"];
                    let destination = if d.get("node").is_some() {
                        Endpoint::Node {
                            node: NodeId(u64_from(d, "node") as u32),
                            behavior: str_from(d, "behavior"),
                            port: str_from(d, "port"),
                        }
                    } else {
                        Endpoint::Group {
                            group: str_from(d, "group"),
                            behavior: str_from(d, "behavior"),
                            port: str_from(d, "port"),
                        }
                    };
                    ControlBody::Connect {
                        source_behavior: str_from(j, "src_behavior"),
                        source_port: str_from(j, "src_port"),
                        destination,
                        kind: kind_from(j),
                        priority: j["priority"].as_i64().unwrap() as i32,
                    }
                }
                "disconnect" => ControlBody::Disconnect { conn: ConnectionId(u64_from(j, "conn")) },
                "list" => ControlBody::List,
                "why" => ControlBody::Why { behavior: str_from(j, "behavior"), port: str_from(j, "port") },
                "read" => ControlBody::Read { behavior: str_from(j, "behavior"), port: str_from(j, "port") },
                "unknown" => return WireMessage::UnknownRequest { id, op: u64_from(j, "code") as u8 },
                other => panic!("unknown op {other}"),
            };
            let signature = j.get("signature_hex").map(|h| unhex(h.as_str().unwrap()).try_into().unwrap());
            WireMessage::Request { id, body, signature }
        }
        "challenge" => WireMessage::Challenge { cookie: unhex(j["cookie_hex"].as_str().unwrap()).try_into().unwrap() },
        "echo" => WireMessage::Echo { cookie: unhex(j["cookie_hex"].as_str().unwrap()).try_into().unwrap() },
        "reply" => {
            let payload = match j["status"].as_str().unwrap() {
                "error" => ReplyPart::Error(j["message"].as_str().unwrap().to_owned()),
                "ok" => {
                    let r = &j["result"];
                    if let Some(c) = r.get("connection") {
                        ReplyPart::Connection(ConnectionId(c.as_u64().unwrap()))
                    } else if let Some(v) = r.get("value") {
                        ReplyPart::Value(value_from(v))
                    } else {
                        ReplyPart::Report(r["report"].as_str().unwrap().to_owned())
                    }
                }
                other => panic!("unknown status {other}"),
            };
            WireMessage::Reply {
                id: u64_from(j, "id"),
                part: u64_from(j, "part") as u16,
                parts: u64_from(j, "parts") as u16,
                payload,
            }
        }
        other => panic!("message kind {other} cannot be encoded"),
    }
}

fn document(vectors: &[Vector]) -> String {
    let list: Vec<Json> = vectors
        .iter()
        .map(|v| {
            let mut j = json!({
                "name": v.name, "description": v.description, "team": v.team, "auth": v.auth,
            });
            let o = j.as_object_mut().unwrap();
            if !v.encode && matches!(v.expect, Expect::Ok { .. }) {
                o.insert("encode".into(), json!(false));
            }
            o.insert("hex".into(), json!(hex(&v.bytes)));
            let expect = match &v.expect {
                Expect::Ok { sender, seq, messages } => json!({
                    "ok": true, "sender": sender, "seq": seq,
                    "messages": messages.iter().map(message_json).collect::<Vec<_>>(),
                }),
                Expect::Drop(cause) => json!({"ok": false, "cause": cause.name()}),
            };
            o.insert("expect".into(), expect);
            j
        })
        .collect();
    let doc = json!({"protocol_version": 1, "key_hex": hex(&KEY), "vectors": list});
    let mut text = serde_json::to_string_pretty(&doc).unwrap();
    text.push('\n');
    text
}

// ---------------------------------------------------------------------------------------------
// The test

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn corpus_dir() -> PathBuf {
    repo().join("fuzz/corpus/decode_datagram")
}

#[test]
fn golden_vectors() {
    let vectors = vectors();
    let mut names: Vec<_> = vectors.iter().map(|v| v.name).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), vectors.len(), "vector names are unique");
    for cause in DropReason::ALL {
        assert!(
            vectors.iter().any(|v| matches!(v.expect, Expect::Drop(c) if c == cause)),
            "no vector for drop cause {cause}"
        );
    }

    let text = document(&vectors);
    let path = repo().join("spec/vectors/vectors.json");
    if std::env::var_os("AYLLU_BLESS").is_some_and(|v| v == "1") {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &text).unwrap();
        std::fs::create_dir_all(corpus_dir()).unwrap();
        for v in &vectors {
            std::fs::write(corpus_dir().join(v.name), &v.bytes).unwrap();
        }
    } else {
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        if on_disk != text {
            let line = on_disk.lines().zip(text.lines()).position(|(a, b)| a != b).unwrap_or(0) + 1;
            panic!(
                "{} differs from what the encoder generates (first at line {line}); if the change is \
                 intended, run `AYLLU_BLESS=1 cargo test -p ayllu-wire --test wire`",
                path.display()
            );
        }
        for v in &vectors {
            let seed = std::fs::read(corpus_dir().join(v.name)).unwrap_or_default();
            assert_eq!(seed, v.bytes, "fuzz seed {} is stale: bless the vectors", v.name);
        }
    }

    // Read the file back as any implementation would, and check every vector from it.
    let doc: Json = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(doc["protocol_version"], 1);
    let key: Key = unhex(doc["key_hex"].as_str().unwrap()).try_into().unwrap();
    let list = doc["vectors"].as_array().unwrap();
    assert_eq!(list.len(), vectors.len());
    let mut encoded = 0;
    for v in list {
        let name = v["name"].as_str().unwrap();
        let bytes = unhex(v["hex"].as_str().unwrap());
        let auth = v["auth"].as_bool().unwrap();
        let team = u64_from(v, "team") as u32;
        let config = ReceiverConfig { team, key: auth.then_some(key) };
        let expect = &v["expect"];
        let got = decode(&bytes, &config);
        if !expect["ok"].as_bool().unwrap() {
            assert_eq!(got.err().map(DropReason::name), expect["cause"].as_str(), "{name}: drop cause");
            continue;
        }
        let d = got.unwrap_or_else(|e| panic!("{name}: dropped as {e}"));
        assert_eq!(u64::from(d.sender.0), u64_from(expect, "sender"), "{name}: sender");
        assert_eq!(d.seq, u64_from(expect, "seq"), "{name}: seq");
        assert_eq!(d.authenticated, auth, "{name}: authenticated");
        let messages: Vec<Json> = d.messages.iter().map(message_json).collect();
        assert_eq!(&Json::from(messages), &expect["messages"], "{name}: messages");
        if v.get("encode").and_then(Json::as_bool) == Some(false) {
            continue;
        }
        let from_json: Vec<WireMessage> = expect["messages"].as_array().unwrap().iter().map(message_from).collect();
        let again = encode_datagram(team, d.sender, d.seq, auth.then_some(key), &from_json)
            .unwrap_or_else(|e| panic!("{name}: re-encoding failed: {e}"));
        assert_eq!(hex(&again), hex(&bytes), "{name}: re-encoded bytes");
        encoded += 1;
    }
    assert!(encoded >= 30, "most valid vectors are re-encoded ({encoded})");
}

/// The core refuses a connection to another node from a port holding a vector longer than
/// `MAX_NETWORK_VECTOR` (D-S10.7) because the wire cannot carry one: the two agree.
#[test]
fn the_core_s_longest_network_vector_is_the_longest_the_wire_encodes() {
    let at = |n: usize| {
        ayllu_wire::encoded_len(&port(1, 1, ConnectionKind::Normal, 0, "S", "Ranges", Value::vector(&vec![0.5; n])))
    };
    assert!(at(ayllu_core::MAX_NETWORK_VECTOR).is_ok());
    assert!(matches!(at(ayllu_core::MAX_NETWORK_VECTOR + 1), Err(ayllu_wire::EncodeError::Invalid(_))));
}
