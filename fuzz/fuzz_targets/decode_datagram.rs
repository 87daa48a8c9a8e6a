//! Fuzz target: arbitrary bytes into `ayllu_wire::decode`.
//!
//! Promises checked, beyond "no panic, no unbounded allocation or loop" (which libFuzzer and
//! its sanitizers watch): every input is decoded by an open receiver and by a keyed one; the
//! same bytes given a valid MAC are decoded by the keyed receiver, so the body decoders are
//! reached behind authentication too; and whatever is accepted re-encodes, and the re-encoded
//! datagram decodes to messages that encode to the same bytes (the encoder can send
//! everything the decoder accepts, and the two agree).
#![no_main]

use ayllu_core::NodeId;
use ayllu_wire::{decode, encode_datagram, mac, ReceiverConfig, WireMessage, FLAG_AUTH, HEADER_LEN};
use libfuzzer_sys::fuzz_target;

const KEY: [u8; 32] = [0x42; 32];

fuzz_target!(|data: &[u8]| {
    // The receiver's team is taken from the input when there is one, so that `wrong_team`
    // does not hide everything behind it.
    let team = data.get(4..8).map_or(7, |t| u32::from_le_bytes([t[0], t[1], t[2], t[3]]));
    let open = ReceiverConfig { team, key: None };
    let keyed = ReceiverConfig { team, key: Some(KEY) };

    if let Ok(d) = decode(data, &open) {
        check_reencodes(team, &d.messages);
    }
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
