//! Fuzz target: arbitrary bytes into `ayllu_wire::decode`.
//!
//! Promises checked, beyond "no panic, no unbounded allocation or loop" (which libFuzzer and
//! its sanitizers watch): every input is decoded by an open receiver and by a keyed one; the
//! same bytes given a valid MAC are decoded by the keyed receiver, so the body decoders are
//! reached behind authentication too; and whatever is accepted re-encodes, and the re-encoded
//! datagram decodes to messages that encode to the same bytes (the encoder can send
//! everything the decoder accepts, and the two agree). Decoding into places that hold an
//! earlier datagram's port messages (`MessageSink::port_place`, as the UDP transport's inbox
//! does) gives what `decode` gives, refusals included.
#![no_main]

use std::sync::Arc;

use ayllu_core::{ConnectionId, ConnectionKind, NodeId, PortMessage, Value};
use ayllu_wire::{
    decode, decode_into, encode_datagram, mac, NameCache, ReceiverConfig, WireMessage, FLAG_AUTH, HEADER_LEN,
};
use libfuzzer_sys::fuzz_target;

// The sink the wire crate's property test decodes into, shared rather than copied.
#[path = "../../crates/ayllu-wire/tests/wire/places.rs"]
mod places;
use places::Places;

const KEY: [u8; 32] = [0x42; 32];

fuzz_target!(|data: &[u8]| {
    // The receiver's team is taken from the input when there is one, so that `wrong_team`
    // does not hide everything behind it.
    let team = data.get(4..8).map_or(7, |t| u32::from_le_bytes([t[0], t[1], t[2], t[3]]));
    let open = ReceiverConfig { team, key: None };
    let keyed = ReceiverConfig { team, key: Some(KEY) };

    let decoded = decode(data, &open);
    if let Ok(d) = &decoded {
        check_reencodes(team, &d.messages);
    }
    check_kept_places(data, &open, decoded.map(|d| d.messages));
    let _ = decode(data, &keyed);

    // The same bytes, authenticated: set AUTH and append a valid MAC.
    if data.len() >= HEADER_LEN && data.len() <= 8192 {
        let mut signed = data.to_vec();
        signed[3] |= FLAG_AUTH;
        let tag = mac(&KEY, &signed);
        signed.extend_from_slice(&tag);
        if let Ok(d) = decode(&signed, &keyed) {
            assert!(d.authenticated);
            check_reencodes(team, &d.messages);
        }
    }
});

fn check_reencodes(team: u32, messages: &[WireMessage]) {
    let known: Vec<WireMessage> =
        messages.iter().filter(|m| !matches!(m, WireMessage::Unknown { .. })).cloned().collect();
    let bytes = encode_datagram(team, NodeId(1), 1, None, &known).expect("decoded messages re-encode");
    let again = decode(&bytes, &ReceiverConfig { team, key: None }).expect("re-encoded datagram decodes");
    // Compare as bytes: floats (NaN payloads) compare exactly that way.
    let bytes2 = encode_datagram(team, NodeId(1), 1, None, &again.messages).expect("re-encodes again");
    assert_eq!(bytes, bytes2);
}

/// `data` decoded into places that hold an earlier datagram's port messages (names the input
/// may spell or not) gives `expected`, `decode`'s outcome.
fn check_kept_places(data: &[u8], config: &ReceiverConfig, expected: Result<Vec<WireMessage>, ayllu_wire::DropReason>) {
    let earlier: Vec<WireMessage> = ["D", "p00", "x"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            WireMessage::Port(PortMessage {
                conn: ConnectionId(i as u64),
                seq: 1,
                behavior: Arc::from(*name),
                port: Arc::from(*name),
                kind: ConnectionKind::Normal,
                priority: 0,
                value: Value::Int(0),
            })
        })
        .collect();
    let earlier = encode_datagram(config.team, NodeId(1), 1, None, &earlier).expect("encodes");
    let mut names = NameCache::new();
    let mut sink = Places::default();
    decode_into(&earlier, config, &mut names, &mut sink).expect("decodes");
    sink.next_datagram();
    let got = decode_into(data, config, &mut names, &mut sink).map(|_| std::mem::take(&mut sink.got));
    match (expected, got) {
        (Ok(a), Ok(b)) => {
            // As bytes: floats (NaN payloads) compare exactly that way.
            let known = |m: &Vec<WireMessage>| -> Vec<WireMessage> {
                m.iter().filter(|m| !matches!(m, WireMessage::Unknown { .. })).cloned().collect()
            };
            let (a, b) = (known(&a), known(&b));
            assert_eq!(
                encode_datagram(config.team, NodeId(1), 1, None, &a).expect("re-encodes"),
                encode_datagram(config.team, NodeId(1), 1, None, &b).expect("re-encodes")
            );
        }
        (a, b) => assert_eq!(a.err(), b.err()),
    }
}
