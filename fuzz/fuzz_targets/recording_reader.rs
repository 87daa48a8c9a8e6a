//! Fuzz target: arbitrary bytes as a recording file, into the readers of files that come from
//! outside: `Recording::from_bytes` (flight recordings: `ayllu replay`, `ayllu.check_recording`,
//! `ay_recording_check`) and `team_recording::read_recording` (`ayllu play`).
//!
//! Promises checked, beyond "no panic, no unbounded allocation or loop" (which libFuzzer and
//! its sanitizers watch; the `mcap` crate's own readers panicked on a length near `u64::MAX`):
//! what reads as a flight recording replays to its end or stops at a divergence, and the
//! replay's answers (`list` of the replayed node) can be asked of it. Seeds: a small flight
//! recording, a small team recording, and the files in
//! crates/ayllu/tests/malformed_recordings/ that made the old reader panic.
#![no_main]

use ayllu::replay::{Recording, Replay};
use ayllu::team_recording::read_recording;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = read_recording(data);
    if let Ok(rec) = Recording::from_bytes(data) {
        let mut replay = Replay::new(&rec);
        let _ = replay.run_to_end();
        let _ = replay.core().report();
    }
});
