//! Recordings from outside cannot crash their readers: whatever a file's bytes, a flight
//! recording ([`Recording::open`], [`Recording::from_bytes`]) and a team recording
//! ([`read_recording`]) read as a recording or as an error, never a panic, and what reads as
//! a recording replays. The `mcap` crate's own readers (0.26) panic on some of these files;
//! ours frame the records themselves.
//!
//! tests/malformed_recordings/ holds the files that found the panics, kept as they were:
//! * `garbage.mcap`: the MCAP magic, then 100 bytes of 0xff (a record length of `u64::MAX`;
//!   found by an outside tester: `ayllu replay FILE check` panicked);
//! * `message-length-max.mcap`: a real recording whose second chunk's first message claims
//!   `u64::MAX - 3` bytes (the length plus its 9-byte prefix wraps around);
//! * `attachment-short.mcap`: a header and an attachment record that ends right after its
//!   own header (mcap's attachment parser slices out of range);
//! * `killed.mcap`: a copy taken while a node was still recording (what a killed node leaves:
//!   its last chunk still has the writer's `!0` placeholder lengths);
//! * `truncated-in-chunk.mcap`: a real recording cut inside its second chunk;
//! * `chunk-records-size-max.mcap`, `topic-length-huge.mcap`, `metadata-map-overrun.mcap`: a
//!   real recording with a chunk's records size, a channel's topic length or a metadata
//!   map's length made larger than the file.

use std::path::{Path, PathBuf};

use ayllu::replay::{Ending, Recording, Replay};
use ayllu::team_recording::read_recording;
use ayllu::{BehaviorClass, Duration, Instant, Lockstep, Node, NodeId, PortSpec, RecordOptions};

fn inputs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed_recordings")
}

/// A fresh directory of its own for each call: the tests run in parallel in one process, and
/// two of them writing (and clearing) one directory made a recording read back torn.
fn dir(name: &str) -> PathBuf {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("malformed-{name}-{}-{call}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A small real flight recording (some 10 kB): a class, a behavior, a periodic process, a
/// write from outside, six steps.
fn small_recording() -> Vec<u8> {
    let d = dir("small");
    let path = d.join("small.mcap");
    // Its own network too, for the same reason.
    let team = Lockstep::new(&d.file_name().unwrap().to_string_lossy());
    let clock = team.clock().clone();
    let mut node = Node::new(clock.clone(), team.network().attach(NodeId(7)).unwrap());
    node.record(&path, RecordOptions::default()).unwrap();
    let mut c = BehaviorClass::new("Tiny");
    let out = c.port(PortSpec::new("Out", 0i64)).unwrap();
    c.port(PortSpec::new("In", 0.0).max().window(Duration::from_millis(50))).unwrap();
    c.every_hz("Tick", 10.0, move |ctx| {
        let k = ctx.int(out).unwrap_or(0);
        ctx.write(out, k + 1).unwrap();
    })
    .unwrap();
    node.define(c).unwrap();
    node.create("Tiny", "T").unwrap();
    for k in 0..6u64 {
        clock.set(Instant::from_millis(k * 100));
        if k == 2 {
            node.write("T", "In", 0.5).unwrap();
        }
        node.step();
    }
    assert_eq!(node.stop_recording().unwrap().error, None);
    std::fs::read(&path).unwrap()
}

/// What a reader may do with damaged bytes: an error, or a recording that replays (a
/// divergence is an answer too: a flipped byte can change a recorded value).
fn read_any(bytes: &[u8]) -> Result<Recording, String> {
    let _ = read_recording(bytes);
    let rec = Recording::from_bytes(bytes).map_err(|e| e.to_string())?;
    let _ = Replay::new(&rec).run_to_end();
    Ok(rec)
}

#[test]
fn the_files_that_made_the_mcap_reader_panic_are_errors_or_shorter_recordings() {
    let mut names: Vec<PathBuf> =
        std::fs::read_dir(inputs()).unwrap().map(|e| e.unwrap().path()).filter(|p| p.is_file()).collect();
    names.sort();
    assert_eq!(names.len(), 8, "{names:?}");
    for path in &names {
        let bytes = std::fs::read(path).unwrap();
        let from_file = Recording::open(path).map_err(|e| e.to_string());
        let from_bytes = read_any(&bytes);
        assert_eq!(from_file.is_ok(), from_bytes.is_ok(), "{}", path.display());
        assert!(read_recording(&bytes).is_err(), "{}: not a team recording", path.display());
    }

    let garbage = Recording::open(inputs().join("garbage.mcap")).unwrap_err().to_string();
    assert!(garbage.contains("garbage.mcap: not an Ayllu flight recording"), "{garbage}");
    assert!(garbage.contains("at byte 8: a record (opcode 0xff) of 18446744073709551615 bytes"), "{garbage}");
    let team = read_recording(&std::fs::read(inputs().join("garbage.mcap")).unwrap()).unwrap_err().to_string();
    assert!(team.contains("at byte 8"), "{team}");
    assert!(Recording::open(inputs().join("attachment-short.mcap")).is_err());

    // A killed node's file and the cut ones keep what was complete, and say where they end.
    let killed = Recording::open(inputs().join("killed.mcap")).unwrap();
    assert_eq!(killed.node, NodeId(7));
    assert!(!killed.entries.is_empty());
    assert!(matches!(&killed.ending, Ending::Cut { reason } if reason.contains("18446744073709551615")));
    Replay::new(&killed).run_to_end().unwrap();
    for cut in ["message-length-max.mcap", "truncated-in-chunk.mcap", "chunk-records-size-max.mcap"] {
        let rec = Recording::open(inputs().join(cut)).unwrap();
        assert!(matches!(rec.ending, Ending::Cut { .. }), "{cut}: {:?}", rec.ending);
        Replay::new(&rec).run_to_end().unwrap();
    }
}

#[test]
fn every_truncation_of_a_small_recording_is_a_shorter_recording_or_an_error() {
    let good = small_recording();
    assert!(good.len() < 20_000, "{}", good.len());
    let whole = Recording::from_bytes(&good).unwrap();
    assert_eq!(whole.ending, Ending::Closed);
    let mut recordings = 0;
    for cut in 0..good.len() {
        let bytes = &good[..cut];
        let _ = read_recording(bytes);
        match Recording::from_bytes(bytes) {
            Err(e) => assert!(!e.to_string().is_empty()),
            Ok(rec) => {
                recordings += 1;
                // Only the end magic (the last 8 bytes) may go missing unnoticed.
                if cut < good.len() - 8 {
                    assert!(matches!(rec.ending, Ending::Cut { .. }), "cut at {cut}: {:?}", rec.ending);
                }
                assert!(rec.entries.len() <= whole.entries.len());
                // A prefix of a good recording replays without a divergence.
                Replay::new(&rec).run_to_end().unwrap_or_else(|d| panic!("cut at {cut}: {d}"));
            }
        }
    }
    assert!(recordings > good.len() / 2, "{recordings} of {} cuts read as recordings", good.len());
}

/// Where `file`'s chunks keep their CRC (the offset of the `u32`), and the byte range of each
/// one's records. Walks the records of a well-formed file (MCAP spec: opcode, `u64` length,
/// body; a chunk's body: start and end times, uncompressed size, CRC, compression, records
/// size, records).
fn chunks(file: &[u8]) -> Vec<(usize, std::ops::Range<usize>)> {
    let u32_at = |at: usize| u32::from_le_bytes(file[at..at + 4].try_into().unwrap()) as usize;
    let u64_at = |at: usize| usize::try_from(u64::from_le_bytes(file[at..at + 8].try_into().unwrap())).unwrap();
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= file.len() {
        let body = at + 9;
        if file[at] == 0x06 {
            let crc = body + 24;
            let size = crc + 8 + u32_at(crc + 4);
            out.push((crc, size + 8..size + 8 + u64_at(size)));
        }
        at = body + u64_at(at + 1);
    }
    out
}

#[test]
fn a_flipped_byte_in_a_chunk_is_refused_by_the_chunks_crc() {
    // The chunk CRC was not checked: a flipped byte in a recorded value read as another value.
    let good = small_recording();
    let found = chunks(&good);
    assert!(found.len() >= 2, "{found:?}");
    let mut flips = 0;
    for (crc, records) in &found {
        assert_ne!(good[*crc..crc + 4], [0u8; 4], "Ayllu's writer computes chunk CRCs");
        for at in records.clone() {
            let mut bad = good.clone();
            bad[at] ^= 0x04;
            flips += 1;
            match Recording::from_bytes(&bad) {
                // Damage before the recording's own metadata: not a recording at all.
                Err(e) => assert!(e.to_string().contains("do not match its CRC"), "byte {at}: {e}"),
                // After it: the recording ends where the damage starts.
                Ok(rec) => assert!(
                    matches!(&rec.ending, Ending::Cut { reason } if reason.contains("a chunk's records do not match its CRC")),
                    "byte {at}: {:?}",
                    rec.ending
                ),
            }
        }
    }
    assert!(flips > 1000, "{flips}");

    // A team recording too.
    let good = small_team_recording();
    assert_eq!(read_recording(&good).unwrap().len(), 5);
    let (_, records) = chunks(&good).remove(0);
    let mut bad = good.clone();
    bad[records.end - 3] ^= 0x01; // inside the last value's JSON
    let e = read_recording(&bad).unwrap_err().to_string();
    assert!(
        e.contains("a chunk's records do not match its CRC (stored 0x") && e.contains("the file is damaged"),
        "{e}"
    );
}

#[test]
fn every_byte_of_a_small_recording_mutated_reads_or_is_refused() {
    // Chunk CRCs zeroed ("not computed"), so that mutations inside chunks reach the records'
    // framing and decoding rather than stopping at the CRC (tested above).
    let mut good = small_recording();
    for (crc, _) in chunks(&good) {
        good[crc..crc + 4].fill(0);
    }
    assert!(Recording::from_bytes(&good).is_ok());
    // Every byte set to 0xff (a length it is part of becomes huge); every fifth also set to
    // 0x00 (short) and flipped (in the JSON, mostly): no panic. (All three on every byte take
    // 20 s unoptimized, for little more.)
    for at in 0..good.len() {
        let mut values = vec![0xff];
        if at % 5 == 0 {
            values.extend([0x00, !good[at]]);
        }
        for v in values {
            let mut bad = good.clone();
            bad[at] = v;
            let _ = read_any(&bad);
        }
    }
}

#[test]
fn every_truncation_of_a_small_team_recording_is_an_error() {
    let good = small_team_recording();
    assert_eq!(read_recording(&good).unwrap().len(), 5);
    for cut in 0..good.len() - 8 {
        assert!(read_recording(&good[..cut]).is_err(), "cut at {cut}");
    }
}

/// A team recording of five float values on one channel, the bytes `ayllu record` writes.
fn small_team_recording() -> Vec<u8> {
    use ayllu::team_channels::PortChannel;
    use ayllu::team_recording::TeamWriter;
    use ayllu::{Value, ValueType};
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut w = TeamWriter::new(&mut buf).unwrap();
        let ch = PortChannel { node: NodeId(1), behavior: "R".into(), port: "Out".into(), ty: ValueType::Float };
        for i in 0..5 {
            w.write(&ch, &Value::Float(f64::from(i)), None, 1_000 + u64::try_from(i).unwrap()).unwrap();
        }
        w.finish().unwrap();
    }
    buf.into_inner()
}
