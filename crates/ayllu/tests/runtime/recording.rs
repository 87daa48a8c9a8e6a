//! The flight recorder (spec/flight-recorder.md): it does not change what a node does, its
//! files stay under their size cap, they are valid MCAP with JSON Schemas, and bad or cut
//! files give clear errors or shorter recordings, never panics.

use std::path::{Path, PathBuf};

use ayllu::recording::segment_path;
use ayllu::replay::{Ending, Recording, Replay};
use ayllu::{
    BehaviorClass, ConnectionKind, Duration, Endpoint, Event, Instant, Lockstep, ManualClock, Node, NodeId, PortSpec,
    RecordOptions, Value,
};

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("recording-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Two nodes on `mem://` and a manual clock: a counter process on node 1 feeds node 2 through
/// an OverrideIn connection, node 2 sums into a Max port; what each port holds after every
/// step is returned. `record` makes both nodes record into `dir`.
fn two_node_run(record: Option<&Path>, steps: u64) -> Vec<String> {
    let team = Lockstep::new(if record.is_some() { "rec-on" } else { "rec-off" });
    let clock: ManualClock = team.clock().clone();
    let mut nodes = Vec::new();
    for id in [1u32, 2] {
        let mut node = Node::new(clock.clone(), team.network().attach(NodeId(id)).unwrap());
        if let Some(d) = record {
            node.record(d.join(format!("n{id}.mcap")), RecordOptions::default()).unwrap();
        }
        let mut c = BehaviorClass::new("Counter");
        let out = c.port(PortSpec::new("Out", 0.0)).unwrap();
        c.port(PortSpec::new("In", 0.0).max().window(Duration::from_millis(250))).unwrap();
        let n = c.slot("N", 0i64).unwrap();
        c.every_hz("Tick", 20.0, move |ctx| {
            let k = ctx.slot(n).as_int().unwrap_or(0) + 1;
            ctx.set_slot(n, k).unwrap();
            ctx.write(out, (k as f64).sin()).unwrap();
        })
        .unwrap();
        node.define(c).unwrap();
        node.create("Counter", "C").unwrap();
        nodes.push(node);
    }
    nodes[0]
        .connect(
            &Endpoint::local("C", "Out"),
            &Endpoint::node(NodeId(2), "C", "In"),
            ConnectionKind::OverrideIn(Duration::from_millis(120)),
        )
        .unwrap();
    let mut trace = Vec::new();
    for k in 0..steps {
        clock.set(Instant::from_millis(k * 7));
        if k % 13 == 0 {
            nodes[1].write("C", "In", k as f64 / 100.0).unwrap();
        }
        for node in &mut nodes {
            node.step();
            for p in ["Out", "In"] {
                trace.push(format!("{k} {} {p} {:?}", node.id(), node.read("C", p).unwrap()));
            }
        }
    }
    for node in &mut nodes {
        trace.push(format!("{:?}", node.core().report().counters));
        if let Some(stats) = node.stop_recording() {
            assert_eq!(stats.error, None);
        }
    }
    trace
}

#[test]
fn recording_does_not_change_what_the_nodes_do() {
    let d = dir("same");
    let without = two_node_run(None, 600);
    let with = two_node_run(Some(&d), 600);
    assert_eq!(with, without);
    // And what was recorded replays to the same values.
    for id in [1, 2] {
        let rec = Recording::open(d.join(format!("n{id}.mcap"))).unwrap();
        let mut replay = Replay::new(&rec);
        replay.run_to_end().unwrap();
        assert!(replay.checked() > 80, "{}", replay.checked());
        let live =
            with.iter().rev().find(|l| l.starts_with("599 ") && l.contains(" In ") && l.contains(&format!(" n{id} ")));
        let replayed = replay.core().read(replay.core().port("C", "In").unwrap()).unwrap();
        if let Some(live) = live {
            assert!(live.ends_with(&format!("{replayed:?}")), "{live} vs {replayed:?}");
        }
    }
}

#[test]
fn the_file_is_mcap_with_a_ros2msg_schema_on_four_cdr_channels() {
    let d = dir("mcap");
    two_node_run(Some(&d), 100);
    let bytes = std::fs::read(d.join("n1.mcap")).unwrap();
    let summary = mcap::read::Summary::read(&bytes).unwrap().expect("a summary section");
    let mut topics: Vec<(String, String, String)> = summary
        .channels
        .values()
        .map(|c| {
            let s = c.schema.as_ref().expect("every channel has a schema");
            (c.topic.clone(), c.message_encoding.clone(), s.encoding.clone())
        })
        .collect();
    topics.sort();
    let names: Vec<&str> = topics.iter().map(|t| t.0.as_str()).collect();
    assert_eq!(names, ["/ayllu/accepted", "/ayllu/input", "/ayllu/process", "/ayllu/structure"]);
    assert!(topics.iter().all(|t| t.1 == "cdr" && t.2 == "ros2msg"));
    for c in summary.channels.values() {
        let schema = c.schema.as_ref().unwrap();
        assert_eq!(schema.name, ayllu::recording_cdr::SCHEMA_NAME);
        assert_eq!(&schema.data[..], ayllu::recording_cdr::SCHEMA.as_bytes());
    }
    // Every message is one entry, with log times in Unix ns.
    let mut n = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert!(matches!(ayllu::recording_cdr::decode(&m.data), Ok(ayllu::recording_cdr::Decoded::Entry(_))));
        assert!(m.log_time > 1_600_000_000_000_000_000);
        n += 1;
    }
    assert!(n > 50, "{n} messages");
}

/// A recording in the JSON form an earlier build wrote (format version 1: one JSON object per
/// message on four channels with JSON Schemas), made here message by message from a recording
/// of this build: it replays to the same values.
#[test]
fn a_recording_in_the_json_form_of_earlier_builds_still_replays() {
    let d = dir("json");
    two_node_run(Some(&d), 600);
    let rec = Recording::open(d.join("n1.mcap")).unwrap();
    let path = d.join("old.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile(ayllu::recording_format::PROFILE)
        .create(std::io::BufWriter::new(std::fs::File::create(&path).unwrap()))
        .unwrap();
    let mut channels = Vec::new();
    for topic in &ayllu::recording_format::Topic::ALL[..4] {
        let schema = serde_json::to_vec(&topic.schema()).unwrap();
        let s = w.add_schema(topic.schema_name(), "jsonschema", &schema).unwrap();
        channels.push((*topic, w.add_channel(s, topic.name(), "json", &Default::default()).unwrap()));
    }
    let metadata = [("version", "1"), ("node", "1"), ("segment", "0"), ("epoch_unix_ns", "0")];
    let metadata = metadata.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
    w.write_metadata(&mcap::records::Metadata { name: ayllu::recording_format::METADATA.into(), metadata }).unwrap();
    for (seq, e) in rec.entries.iter().enumerate() {
        // A recorded entry names its class by a stand-in: give the port name the JSON form had.
        let (topic, json) = ayllu::recording_format::encode(seq as u64, e);
        let channel = channels.iter().find(|(t, _)| *t == topic).unwrap().1;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: seq as u32,
            log_time: e.at.as_nanos(),
            publish_time: e.at.as_nanos(),
        };
        w.write_to_known_channel(&header, &serde_json::to_vec(&json).unwrap()).unwrap();
    }
    let end = [("next_seq".to_string(), rec.entries.len().to_string()), ("capped".into(), "false".into())];
    let end =
        mcap::records::Metadata { name: format!("{}.end", ayllu::recording_format::METADATA), metadata: end.into() };
    w.write_metadata(&end).unwrap();
    w.finish().unwrap();
    drop(w);

    let old = Recording::open(&path).unwrap();
    assert_eq!(old.ending, Ending::Closed);
    assert_eq!(old.entries.len(), rec.entries.len());
    let (mut a, mut b) = (Replay::new(&old), Replay::new(&rec));
    a.run_to_end().unwrap();
    b.run_to_end().unwrap();
    assert!(a.checked() > 60, "{}", a.checked());
    assert_eq!(a.accepted(), b.accepted());
}

#[test]
fn the_size_cap_is_honoured_with_numbered_segments() {
    let d = dir("cap");
    let path = d.join("big.mcap");
    let clock = ManualClock::new();
    let team = Lockstep::new("rec-cap");
    let mut node = Node::new(clock.clone(), team.network().attach(NodeId(9)).unwrap());
    let options = RecordOptions { max_bytes: 300_000, segment_bytes: 100_000, ..RecordOptions::default() };
    node.record(&path, options).unwrap();
    let mut c = BehaviorClass::new("Sink");
    c.port(PortSpec::new("In", Value::text(""))).unwrap();
    node.define(c).unwrap();
    node.create("Sink", "S").unwrap();
    for k in 0..20_000u64 {
        clock.set(Instant::from_micros(k * 100));
        node.write("S", "In", Value::text(&format!("value number {k} with some padding to fill the file"))).unwrap();
        if k % 10 == 0 {
            node.step();
        }
    }
    let stats = node.stop_recording().unwrap();
    assert!(stats.dropped_cap > 0, "{stats:?}");
    let mut total = 0;
    let mut n = 0;
    while segment_path(&path, n).exists() {
        let len = std::fs::metadata(segment_path(&path, n)).unwrap().len();
        assert!(len <= 100_000, "segment {n}: {len} bytes");
        total += len;
        n += 1;
    }
    assert!(n >= 3, "{n} segments of at most 100 kB");
    assert!(total <= 300_000, "{total} bytes");
    assert_eq!(stats.bytes, total);
    let rec = Recording::open(&path).unwrap();
    assert_eq!(rec.segments.len() as u64, n);
    assert!(matches!(rec.ending, Ending::Capped { .. }), "{:?}", rec.ending);
    // What was kept replays exactly.
    let mut replay = Replay::new(&rec);
    replay.run_to_end().unwrap();
    assert!(replay.checked() > 500, "{} {:?}", replay.checked(), stats);
}

#[test]
fn bad_and_cut_files_give_clear_errors_or_shorter_recordings() {
    let d = dir("bad");
    let missing = Recording::open(d.join("nothing.mcap")).unwrap_err().to_string();
    assert!(missing.contains("nothing.mcap"), "{missing}");
    std::fs::write(d.join("empty.mcap"), b"").unwrap();
    let empty = Recording::open(d.join("empty.mcap")).unwrap_err().to_string();
    assert!(empty.contains("not an MCAP file"), "{empty}");
    std::fs::write(d.join("text.mcap"), b"hello, this is not a recording").unwrap();
    assert!(Recording::open(d.join("text.mcap")).unwrap_err().to_string().contains("not an MCAP file"));

    two_node_run(Some(&d), 300);
    let good = std::fs::read(d.join("n1.mcap")).unwrap();
    // Cut at many places: never a panic; an error or a recording that ends early and replays.
    for cut in (0..good.len()).step_by(good.len() / 37 + 1) {
        let p = d.join("cut.mcap");
        std::fs::write(&p, &good[..cut]).unwrap();
        match Recording::open(&p) {
            Err(e) => assert!(!e.to_string().is_empty()),
            Ok(rec) => {
                assert!(matches!(rec.ending, Ending::Cut { .. }), "cut at {cut}: {:?}", rec.ending);
                Replay::new(&rec).run_to_end().unwrap();
            }
        }
    }
    // Flipped bytes: the same.
    for (i, at) in (100..good.len()).step_by(good.len() / 23 + 1).enumerate() {
        let mut bad = good.clone();
        bad[at] ^= 0x5a ^ (i as u8);
        let p = d.join("flipped.mcap");
        std::fs::write(&p, &bad).unwrap();
        if let Ok(rec) = Recording::open(&p) {
            let _ = Replay::new(&rec).run_to_end();
        }
    }
    // A recording must start before anything is declared.
    let clock = ManualClock::new();
    let team = Lockstep::new("rec-late");
    let mut node = Node::new(clock, team.network().attach(NodeId(3)).unwrap());
    node.define(BehaviorClass::new("Early")).unwrap();
    let late = node.record(d.join("late.mcap"), RecordOptions::default()).unwrap_err().to_string();
    assert!(late.contains("before defining"), "{late}");
    // Events of every kind came through.
    let rec = Recording::open(d.join("n2.mcap")).unwrap();
    assert!(rec.entries.iter().any(|e| matches!(e.event, Event::Define(_))));
    assert!(rec.entries.iter().any(|e| matches!(e.event, Event::Receive { .. })));
}

/// A writer that cannot keep up (here: a queue of 50 entries and a journal of 100; a first
/// turn of 40 entries, then turns of 300) never makes the node wait: what does not fit is dropped and counted,
/// the recording marks the hole, and a replay stops before it, exact up to there.
#[test]
fn a_writer_that_cannot_keep_up_drops_counts_and_marks_the_hole() {
    let d = dir("slow");
    let path = d.join("slow.mcap");
    let clock = ManualClock::new();
    let team = Lockstep::new("rec-slow");
    let mut node = Node::new(clock.clone(), team.network().attach(NodeId(5)).unwrap());
    let options = RecordOptions { journal_capacity: 100, queue: 50, ..RecordOptions::default() };
    node.record(&path, options).unwrap();
    let mut c = BehaviorClass::new("Sink");
    c.port(PortSpec::new("In", 0i64)).unwrap();
    node.define(c).unwrap();
    node.create("Sink", "S").unwrap();
    node.step();
    for k in 0..1000i64 {
        clock.set(Instant::from_millis(k as u64));
        node.write("S", "In", k).unwrap();
        if k == 19 || k % 150 == 149 {
            node.step();
        }
    }
    let stats = node.stop_recording().unwrap();
    assert!(stats.dropped_journal + stats.dropped_queue > 0, "{stats:?}");
    let rec = Recording::open(&path).unwrap();
    let (seq, _) = rec.gap.expect("the hole is marked");
    let mut replay = Replay::new(&rec);
    replay.run_to_end().unwrap();
    // The replay ends before the last input ahead of the hole (its consequences may be in it):
    // every value accepted before that input is checked.
    let last_input =
        rec.entries[..seq as usize].iter().rposition(|e| matches!(e.event, Event::Write { .. } | Event::Poll)).unwrap();
    let before = rec.entries[..last_input].iter().filter(|e| matches!(e.event, Event::Accepted { .. })).count();
    assert_eq!(replay.checked(), before);
    // The first turn's 20 writes were sent whole; the journal then kept what its capacity
    // (100 entries) holds while the writer was behind, and lost the rest.
    assert!(replay.checked() >= 20, "{}", replay.checked());
    assert!(stats.dropped_queue > 0, "the writer was behind: {stats:?}");
}
