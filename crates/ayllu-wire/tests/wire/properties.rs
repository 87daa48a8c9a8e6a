//! Properties of the codec over random input: encode→decode gives the messages back (singly
//! and batched to an MTU), decoding arbitrary or mutated bytes never panics and refuses or
//! accepts consistently, and the replay window agrees with a plain model of the spec.

use std::collections::BTreeSet;
use std::sync::Arc;

use ayllu_core::{
    BleConfig, Change, ConnectionId, ConnectionKind, ControlBody, Duration, Endpoint, NodeId, PortMessage, Value,
};
use ayllu_wire::{
    decode, decode_into, encode_datagram, DatagramWriter, EncodeError, Key, NameCache, PortTemplates, ReceiverConfig,
    ReplayWindow, ReplyPart, WireMessage, HEADER_LEN, MAX_DATAGRAM_LEN,
};
use proptest::prelude::*;

use crate::places::Places;

const KEY: Key = [0x5a; 32];

fn name() -> impl Strategy<Value = Arc<str>> {
    // Mostly short ASCII, sometimes multi-byte characters; never empty, never over 255 bytes.
    prop_oneof!["[A-Za-z0-9_]{1,12}", "[a-zé✓🤖]{1,40}",].prop_map(|s| Arc::from(s.as_str()))
}

fn value() -> impl Strategy<Value = Value> {
    prop_oneof![
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(Value::Int),
        any::<u64>().prop_map(|b| Value::Float(f64::from_bits(b))),
        ".{0,40}".prop_map(|s| Value::text(&s)),
        proptest::collection::vec(any::<u8>(), 0..40).prop_map(|b| Value::bytes(&b)),
        proptest::collection::vec(any::<u64>(), 0..12)
            .prop_map(|v| Value::vector(&v.into_iter().map(f64::from_bits).collect::<Vec<_>>())),
    ]
}

fn conn_kind() -> impl Strategy<Value = ConnectionKind> {
    (0u8..6, 1u64..u64::MAX).prop_map(|(k, p)| {
        let p = Duration::from_nanos(p);
        match k {
            0 => ConnectionKind::Normal,
            1 => ConnectionKind::Suppress(p),
            2 => ConnectionKind::Inhibit(p),
            3 => ConnectionKind::OverrideIn(p),
            4 => ConnectionKind::OverrideOut(p),
            _ => ConnectionKind::WriteInhibit(p),
        }
    })
}

fn endpoint() -> impl Strategy<Value = Endpoint> {
    prop_oneof![
        (any::<u32>(), "[A-Za-z0-9]{0,8}", "[A-Za-z0-9]{0,8}").prop_map(|(n, b, p)| Endpoint::node(NodeId(n), &b, &p)),
        (name(), "[A-Za-z0-9]{0,8}", "[A-Za-z0-9]{0,8}").prop_map(|(g, b, p)| Endpoint::Group {
            group: g,
            behavior: b.into(),
            port: p.into()
        }),
    ]
}

fn request_body() -> impl Strategy<Value = ControlBody> {
    prop_oneof![
        (name(), name(), endpoint(), conn_kind(), any::<i32>()).prop_map(|(b, p, d, k, pr)| ControlBody::Connect {
            source_behavior: b,
            source_port: p,
            destination: d,
            kind: k,
            priority: pr
        }),
        any::<u64>().prop_map(|c| ControlBody::Disconnect { conn: ConnectionId(c) }),
        Just(ControlBody::List),
        (name(), name()).prop_map(|(behavior, port)| ControlBody::Why { behavior, port }),
        (name(), name()).prop_map(|(behavior, port)| ControlBody::Read { behavior, port }),
        (any::<u64>(), proptest::collection::vec(change(), 0..6), any::<u64>())
            .prop_map(|(txn, changes, hold)| ControlBody::Prepare { txn, changes, hold: Duration::from_nanos(hold) }),
        (any::<u64>(), any::<u64>()).prop_map(|(txn, d)| ControlBody::Commit { txn, delay: Duration::from_nanos(d) }),
        any::<u64>().prop_map(|txn| ControlBody::Abort { txn }),
    ]
}

/// A change as a PREPARE carries it: non-empty names, endpoints never local.
fn change() -> impl Strategy<Value = Change> {
    let s = || "[A-Za-z0-9]{1,8}";
    prop_oneof![
        (s(), s()).prop_map(|(class, name)| Change::Create { class, name }),
        s().prop_map(|name| Change::Remove { name }),
        (endpoint(), endpoint(), conn_kind(), any::<i32>()).prop_map(|(source, destination, kind, priority)| {
            Change::Connect { source, destination, kind, priority }
        }),
        any::<u64>().prop_map(|c| Change::Disconnect { conn: ConnectionId(c) }),
        (endpoint(), endpoint()).prop_map(|(source, destination)| Change::DisconnectBetween { source, destination }),
        s().prop_map(|group| Change::Join { group }),
        s().prop_map(|group| Change::Leave { group }),
        (s(), s(), s(), any::<u32>(), any::<u64>(), any::<u64>()).prop_map(|(behavior, group, output, r, i, d)| {
            Change::BleJoin {
                behavior,
                config: BleConfig {
                    group,
                    output,
                    claim_rate_hz: f64::from(r) / 8.0,
                    inhibit_period: Duration::from_nanos(i),
                    network_delay: Duration::from_nanos(d),
                },
            }
        }),
    ]
}

fn reply() -> impl Strategy<Value = WireMessage> {
    let single = prop_oneof![
        ".{0,40}".prop_map(ReplyPart::Error),
        any::<u64>().prop_map(|c| ReplyPart::Connection(ConnectionId(c))),
        value().prop_map(ReplyPart::Value),
    ];
    prop_oneof![
        (any::<u64>(), single).prop_map(|(id, payload)| WireMessage::Reply { id, part: 0, parts: 1, payload }),
        (any::<u64>(), 1u16..=64, any::<u16>(), ".{0,60}").prop_map(|(id, parts, part, s)| WireMessage::Reply {
            id,
            part: part % parts,
            parts,
            payload: ReplyPart::Report(s)
        }),
    ]
}

fn port_message() -> impl Strategy<Value = PortMessage> {
    (any::<u64>(), any::<u64>(), name(), name(), conn_kind(), any::<i32>(), value()).prop_map(
        |(conn, seq, behavior, port, kind, priority, value)| PortMessage {
            conn: ConnectionId(conn),
            seq,
            behavior,
            port,
            kind,
            priority,
            value,
        },
    )
}

fn message() -> impl Strategy<Value = WireMessage> {
    prop_oneof![
        port_message().prop_map(WireMessage::Port),
        (name(), port_message()).prop_map(|(group, message)| WireMessage::GroupPort { group, message }),
        (1u32.., "[a-z0-9-]{0,12}", proptest::collection::vec(name(), 0..4))
            .prop_map(|(interval_ms, n, groups)| WireMessage::Hello { interval_ms, name: n.into(), groups }),
        (any::<u64>(), request_body(), proptest::option::of(any::<[u8; 32]>())).prop_map(|(id, body, sig)| {
            WireMessage::Request {
                id,
                body,
                signature: sig.map(|h| {
                    let mut s = [0u8; 64];
                    s[..32].copy_from_slice(&h);
                    s[32..].copy_from_slice(&h);
                    s
                }),
            }
        }),
        any::<[u8; 16]>().prop_map(|cookie| WireMessage::Challenge { cookie }),
        any::<[u8; 16]>().prop_map(|cookie| WireMessage::Echo { cookie }),
        (any::<u64>(), prop_oneof![Just(0u8), 9u8..=255]).prop_map(|(id, op)| WireMessage::UnknownRequest { id, op }),
        reply(),
    ]
}

/// Equality with floats compared by their bits (NaN == NaN of the same payload, -0.0 != 0.0).
fn same_value(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Float(x), Value::Float(y)) => x.to_bits() == y.to_bits(),
        (Value::Vector(x), Value::Vector(y)) => {
            x.len() == y.len() && x.iter().zip(y.iter()).all(|(p, q)| p.to_bits() == q.to_bits())
        }
        _ => a == b,
    }
}

fn same(a: &WireMessage, b: &WireMessage) -> bool {
    match (a, b) {
        (WireMessage::Port(p), WireMessage::Port(q)) => {
            let (mut p2, mut q2) = (p.clone(), q.clone());
            p2.value = Value::Int(0);
            q2.value = Value::Int(0);
            p2 == q2 && same_value(&p.value, &q.value)
        }
        (WireMessage::GroupPort { group: g, message: p }, WireMessage::GroupPort { group: h, message: q }) => {
            g == h && same(&WireMessage::Port(p.clone()), &WireMessage::Port(q.clone()))
        }
        (
            WireMessage::Reply { id, part, parts, payload: ReplyPart::Value(v) },
            WireMessage::Reply { id: i2, part: p2, parts: n2, payload: ReplyPart::Value(w) },
        ) => (id, part, parts) == (i2, p2, n2) && same_value(v, w),
        _ => a == b,
    }
}

fn all_same(a: &[WireMessage], b: &[WireMessage]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| same(x, y))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn round_trip(team: u32, sender: u32, seq: u64, auth: bool, msgs in proptest::collection::vec(message(), 0..8)) {
        let key = auth.then_some(KEY);
        let bytes = encode_datagram(team, NodeId(sender), seq, key, &msgs).unwrap();
        prop_assert!(bytes.len() <= MAX_DATAGRAM_LEN);
        let d = decode(&bytes, &ReceiverConfig { team, key }).unwrap();
        prop_assert_eq!(d.sender, NodeId(sender));
        prop_assert_eq!(d.seq, seq);
        prop_assert_eq!(d.authenticated, auth);
        prop_assert!(all_same(&d.messages, &msgs), "decoded {:?}\nsent {:?}", d.messages, msgs);
        // And the other receiver configuration refuses it.
        let other = ReceiverConfig { team, key: if auth { None } else { Some(KEY) } };
        prop_assert!(decode(&bytes, &other).is_err());
    }

    /// N3: batching to an MTU loses nothing and reorders nothing; every datagram fits.
    #[test]
    fn batching(mtu in 60usize..1600, msgs in proptest::collection::vec(message(), 0..40)) {
        let config = ReceiverConfig { team: 1, key: Some(KEY) };
        let mut datagrams = Vec::new();
        let mut sent = Vec::new();
        let mut seq = 1;
        let mut w = DatagramWriter::new(1, NodeId(1), seq, Some(KEY), mtu);
        for m in &msgs {
            match w.push(m) {
                Ok(()) => sent.push(m.clone()),
                Err(EncodeError::DoesNotFit { .. }) => {
                    datagrams.push(std::mem::replace(&mut w, { seq += 1; DatagramWriter::new(1, NodeId(1), seq, Some(KEY), mtu) }).finish());
                    match w.push(m) {
                        Ok(()) => sent.push(m.clone()),
                        Err(EncodeError::TooLarge { .. }) => {}
                        Err(e) => prop_assert!(false, "{e}"),
                    }
                }
                Err(EncodeError::TooLarge { .. }) => {}
                Err(e) => prop_assert!(false, "{e}"),
            }
        }
        datagrams.push(w.finish());
        let mut got = Vec::new();
        for d in &datagrams {
            prop_assert!(d.len() <= mtu.max(36));
            got.extend(decode(d, &config).unwrap().messages);
        }
        prop_assert!(all_same(&got, &sent));
    }

    /// A group message is the node-addressed message's bytes with the group appended: a
    /// receiver that stops reading after `value` (any receiver older than the field) sees exactly
    /// the node-addressed message, and one that knows the field reads the group back.
    #[test]
    fn group_field_is_appended(group in name(), message in port_message()) {
        let config = ReceiverConfig::open(7);
        let plain = encode_datagram(7, NodeId(1), 1, None, &[WireMessage::Port(message.clone())]).unwrap();
        let grouped = WireMessage::GroupPort { group: group.clone(), message: message.clone() };
        let bytes = encode_datagram(7, NodeId(1), 1, None, std::slice::from_ref(&grouped)).unwrap();
        // Same header and body prefix; only the message length and the appended str8 differ.
        let extra = 1 + group.len();
        prop_assert_eq!(bytes.len(), plain.len() + extra);
        prop_assert_eq!(&bytes[..21], &plain[..21]);
        prop_assert_eq!(
            u16::from_le_bytes([bytes[21], bytes[22]]),
            u16::from_le_bytes([plain[21], plain[22]]) + extra as u16
        );
        prop_assert_eq!(&bytes[23..plain.len()], &plain[23..]);
        prop_assert_eq!(bytes[plain.len()] as usize, group.len());
        prop_assert_eq!(&bytes[plain.len() + 1..], group.as_bytes());
        // The old receiver's view: the body cut after `value`.
        let mut old_view = bytes[..plain.len()].to_vec();
        old_view[21..23].copy_from_slice(&plain[21..23]);
        prop_assert_eq!(&old_view, &plain);
        let d = decode(&bytes, &config).unwrap();
        prop_assert!(all_same(&d.messages, &[grouped]));
        let d = decode(&plain, &config).unwrap();
        prop_assert!(all_same(&d.messages, &[WireMessage::Port(message)]));
    }

    /// `push_port` (the runtime's path, from the core's own message) writes the bytes, and
    /// returns the errors, that `push` does for the same message as a `WireMessage::Port` or
    /// `GroupPort`: message after message into one datagram, through its filling up and the
    /// messages too large for any datagram.
    #[test]
    fn push_port_is_push(
        mtu in 40usize..400,
        msgs in proptest::collection::vec((port_message(), proptest::option::of(name())), 0..12),
    ) {
        let mut by_push = DatagramWriter::new(7, NodeId(1), 1, None, mtu);
        let mut by_push_port = by_push.clone();
        for (message, group) in &msgs {
            let wire = match group {
                Some(group) => WireMessage::GroupPort { group: group.clone(), message: message.clone() },
                None => WireMessage::Port(message.clone()),
            };
            prop_assert_eq!(by_push.push(&wire), by_push_port.push_port(message, group.as_deref()));
        }
        prop_assert_eq!(by_push.finish(), by_push_port.finish());
    }

    /// `push_port_with` (the runtime's path: each connection's unchanging bytes from a
    /// template) writes the bytes, and returns the errors, that `push_port` does, message after
    /// message, while the templates are made, reused, taken over by another connection of the
    /// same slot (ids 1, 257, 513), or stand no more: the same connection with other name
    /// strings (equal text in another `Arc`, or other text), kind or priority. Every field is
    /// drawn from a few choices, so all of these happen within a few messages.
    #[test]
    fn push_port_with_is_push_port(
        mtu in 40usize..3000,
        msgs in proptest::collection::vec(
            (0usize..3, 0usize..5, 0usize..5, 0usize..3, 0usize..2, any::<u64>(), value(), proptest::option::weighted(0.1, name())),
            0..40,
        ),
    ) {
        let conns = [1u64, 257, 513];
        // Two strings of one text (a name looked up again), other texts (one too long for the
        // encoder's fixed block), and an invalid name.
        let names: [Arc<str>; 5] =
            [Arc::from("D"), Arc::from("D"), Arc::from("p07"), Arc::from("a_rather_long_behavior_name"), Arc::from("")];
        let kinds = [
            ConnectionKind::Normal,
            ConnectionKind::Suppress(Duration::from_millis(5)),
            ConnectionKind::Inhibit(Duration::ZERO),
        ];
        let mut templates = PortTemplates::new();
        let mut by_push_port = DatagramWriter::new(7, NodeId(1), 1, None, mtu);
        let mut by_template = by_push_port.clone();
        for (c, b, p, k, priority, seq, value, group) in msgs {
            let message = PortMessage {
                conn: ConnectionId(conns[c]),
                seq,
                behavior: names[b].clone(),
                port: names[p].clone(),
                kind: kinds[k],
                priority: priority as i32,
                value,
            };
            let group = group.as_deref();
            prop_assert_eq!(
                by_push_port.push_port(&message, group),
                by_template.push_port_with(&mut templates, &message, group)
            );
        }
        prop_assert_eq!(by_push_port.finish(), by_template.finish());
    }

    /// Decoding into places kept from datagram to datagram (`MessageSink::port_place`, as the
    /// UDP transport's inbox does) gives what `decode` gives, refusals included, whatever the
    /// places held: names from a few choices (so a place often holds the message's names, and
    /// often others), any value, groups, other messages in between, and bytes flipped.
    #[test]
    fn decoding_into_kept_places_is_decoding(
        datagrams in proptest::collection::vec(
            (
                proptest::collection::vec(
                    (0usize..4, 0usize..4, value(), proptest::option::weighted(0.2, 0usize..4), proptest::bool::weighted(0.1)),
                    0..8,
                ),
                proptest::collection::vec((any::<usize>(), any::<u8>()), 0..2),
            ),
            1..8,
        ),
    ) {
        let pool: [Arc<str>; 4] = [Arc::from("D"), Arc::from("D2"), Arc::from("p00"), Arc::from("é✓")];
        let config = ReceiverConfig::open(7);
        let mut names = NameCache::new();
        let mut sink = Places::default();
        for (seq, (messages, flips)) in datagrams.into_iter().enumerate() {
            let mut wire = Vec::new();
            for (i, (b, p, value, group, other_first)) in messages.into_iter().enumerate() {
                if other_first {
                    wire.push(WireMessage::Challenge { cookie: [i as u8; 16] });
                }
                let message = PortMessage {
                    conn: ConnectionId(i as u64),
                    seq: seq as u64,
                    behavior: pool[b].clone(),
                    port: pool[p].clone(),
                    kind: ConnectionKind::Normal,
                    priority: 0,
                    value,
                };
                wire.push(match group {
                    Some(g) => WireMessage::GroupPort { group: pool[g].clone(), message },
                    None => WireMessage::Port(message),
                });
            }
            let mut bytes = encode_datagram(7, NodeId(1), seq as u64, None, &wire).unwrap();
            for (at, bit) in flips {
                let at = HEADER_LEN + at % (bytes.len() - HEADER_LEN).max(1);
                if at < bytes.len() {
                    bytes[at] ^= 1 << (bit % 8);
                }
            }
            let expected = decode(&bytes, &config).map(|d| d.messages);
            sink.next_datagram();
            let got = decode_into(&bytes, &config, &mut names, &mut sink).map(|_| sink.got.clone());
            match (&expected, &got) {
                (Ok(a), Ok(b)) => prop_assert!(all_same(a, b), "{:?}\n{:?}", a, b),
                _ => prop_assert_eq!(expected.clone().err(), got.clone().err()),
            }
        }
    }

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600), auth: bool) {
        let _ = decode(&bytes, &ReceiverConfig { team: 7, key: auth.then_some(KEY) });
    }

    /// Random messages areas behind a valid header reach the body decoders.
    #[test]
    fn random_bodies_never_panic(body in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut bytes = DatagramWriter::new(7, NodeId(1), 1, None, 100).finish();
        bytes.extend_from_slice(&body);
        if let Ok(d) = decode(&bytes, &ReceiverConfig { team: 7, key: None }) {
            check_reencodes(&d.messages)?;
        }
    }

    #[test]
    fn mutated_datagrams_never_panic(
        msgs in proptest::collection::vec(message(), 1..6),
        auth: bool,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>(), 0u8..4), 1..6),
    ) {
        let key = auth.then_some(KEY);
        let mut bytes = encode_datagram(7, NodeId(1), 1, key, &msgs).unwrap();
        for (at, byte, op) in edits {
            let at = if bytes.is_empty() { 0 } else { at % bytes.len() };
            match op {
                0 if !bytes.is_empty() => bytes[at] = byte,
                1 if !bytes.is_empty() => bytes[at] ^= 1 << (byte % 8),
                2 => bytes.insert(at, byte),
                _ => bytes.truncate(at),
            }
        }
        if let Ok(d) = decode(&bytes, &ReceiverConfig { team: 7, key }) {
            check_reencodes(&d.messages)?;
        }
    }

    /// The replay window against the spec's words: accept a number once, if it is newer than
    /// the newest accepted or at most 64 below it.
    #[test]
    fn replay_window_model(seqs in proptest::collection::vec(0u64..300, 0..400)) {
        let mut w = ReplayWindow::new();
        let mut accepted = BTreeSet::new();
        let mut newest: Option<u64> = None;
        for s in seqs {
            let fresh = !accepted.contains(&s) && newest.is_none_or(|n| s > n || n - s <= 64);
            prop_assert_eq!(w.is_fresh(s), fresh);
            prop_assert_eq!(w.accept(s), fresh);
            if fresh {
                accepted.insert(s);
                newest = Some(newest.map_or(s, |n| n.max(s)));
            }
            prop_assert_eq!(w.newest(), newest);
        }
    }
}

/// Whatever the decoder accepts, the encoder can send: re-encoding the decoded messages (all
/// but skipped unknown kinds) succeeds and decodes to the same messages.
fn check_reencodes(messages: &[WireMessage]) -> Result<(), TestCaseError> {
    let known: Vec<WireMessage> =
        messages.iter().filter(|m| !matches!(m, WireMessage::Unknown { .. })).cloned().collect();
    let bytes = encode_datagram(7, NodeId(1), 1, None, &known).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let again = decode(&bytes, &ReceiverConfig { team: 7, key: None }).map_err(|e| TestCaseError::fail(e.name()))?;
    prop_assert!(all_same(&again.messages, &known));
    Ok(())
}
