//! Fuzz target: arbitrary bytes as one message of a flight recording (format version 3, CDR:
//! `ayllu::recording_cdr::decode`), the decoder every replayed entry goes through.
//!
//! Promises checked, beyond "no panic, no unbounded allocation": an entry that decodes encodes
//! again into a message that decodes to the same entry (the class of a port is a stand-in on
//! decoding, so the comparison is of what encoding writes). Seeds: messages of a small
//! recording of `ayllu node --controller relay` (fuzz/corpus/flight_entry/).
#![no_main]

use ayllu::recording_cdr::{decode, encode_into, Decoded};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(Decoded::Entry(d)) = decode(data) {
        let mut again = Vec::new();
        encode_into(d.seq, &d.entry, &mut again);
        let Ok(Decoded::Entry(e)) = decode(&again) else { panic!("a decoded entry does not decode again") };
        let mut twice = Vec::new();
        encode_into(e.seq, &e.entry, &mut twice);
        assert_eq!(again, twice, "encoding is not stable");
    }
});
