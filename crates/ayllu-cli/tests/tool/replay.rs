//! `ayllu node --record` and `ayllu replay` with real node processes on loopback: two robots of
//! the paper's Fig. 2 record themselves; each recording replays to its end with every accepted
//! value reproduced bit for bit; `why` at a past instant names robot 2's BLE claim on robot 1
//! (a write-inhibit window held by node 2, with the time it had left); `list` and `echo` answer
//! from the recording; bad files and arguments fail with a reason.
//!
//! No verdict depends on timing: the recordings are whatever the run was, and the assertions
//! are about what the replay finds in them (a claim is renewed every second for 4 s, so some
//! sampled instant shows it).

use crate::common;

use std::path::PathBuf;
use std::time::Duration;

use common::{ayllu, start_on_loopback, wait_for};
use serde_json::Value as Json;

const LIMIT: Duration = Duration::from_secs(60);

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("replay-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn recorded_node_processes_replay_bit_for_bit_and_answer_about_the_past() {
    let dir = scratch("team");
    let sight = ["1:0.9,2:0.5", "1:0.7,2:0.8"];
    let files: Vec<String> = (1..=2).map(|k| dir.join(format!("n{k}.mcap")).display().to_string()).collect();
    let (mut procs, _) = start_on_loopback(
        2,
        |k| format!("n{}", k + 1),
        |k, url| {
            let id = (k + 1).to_string();
            let args = ["node", "--id", &id, "--udp", url, "--layers", "2", "--sight", sight[k]];
            let more = ["--status-ms", "500", "--for", "4", "--record", &files[k]];
            args.iter().chain(more.iter()).map(|s| s.to_string()).collect()
        },
    );
    for p in &mut procs {
        let status = wait_for(LIMIT, Duration::from_millis(50), || p.exited());
        assert!(status.is_some_and(|s| s.success()), "{} did not end well: {}", p.name, p.stderr());
        assert!(p.stderr().contains("recorded"), "{}", p.stderr());
    }

    for f in &files {
        let check = ayllu(&["replay", f, "--json", "check"], LIMIT).ok();
        let j = check.json();
        assert_eq!(j["complete"], true, "{check:?}");
        assert!(j["accepted_checked"].as_u64().unwrap() > 300, "{check:?}");
        assert!(check.stderr.contains("closed"), "{check:?}");
        let text = ayllu(&["replay", f, "check"], LIMIT).ok();
        assert!(text.stdout.contains("reproduced bit for bit"), "{text:?}");
    }

    // Robot 2 sees target 2 closer: it claims layer 2, which write-inhibits robot 1's
    // OBS2.Rotate for 2.3 s at each 1 Hz claim. Asked at some past instants, robot 1's replay
    // names the window, its holder (a connection of node 2) and the time it still had.
    let mut seen = None;
    for at in ["2.5s", "3s", "3.5s", "3.9s"] {
        let why = ayllu(&["replay", &files[0], "--at", at, "--json", "why", "OBS2.Rotate"], LIMIT).ok();
        let j = why.json();
        let window = j["windows"].as_array().unwrap().iter().find(|w| w["kind"] == "WriteInhibit").cloned();
        if let Some(w) = window {
            seen = Some((at, w));
            break;
        }
    }
    let (at, w) = seen.expect("robot 2's claim on layer 2 shows in robot 1's replay");
    assert_eq!(w["holder"]["node"], 2, "{w}");
    let remaining = w["remaining"].as_f64().unwrap();
    assert!(remaining > 0.0 && remaining <= 2.3 + 1e-9, "{w}");
    let text = ayllu(&["replay", &files[0], "--at", at, "why", "OBS2.Rotate"], LIMIT).ok();
    assert!(text.stdout.contains("write-inhibit held by n2/"), "{text:?}");
    assert!(
        text.stdout.contains(&format!(
            "n1:OBS2.Rotate (normal float) at {:.3}s",
            at.trim_end_matches('s').parse::<f64>().unwrap()
        )),
        "{text:?}"
    );

    // The whole node as it was, and a port's values over a time range.
    let list = ayllu(&["replay", &files[0], "--at", "2s", "--json", "list"], LIMIT).ok().json();
    let names: Vec<&str> = list["behaviors"].as_array().unwrap().iter().map(|b| b["name"].as_str().unwrap()).collect();
    for b in ["BASE", "OBS1", "OBS2", "VISION", "WANDER"] {
        assert!(names.contains(&b), "{names:?}");
    }
    let echo = ayllu(&["replay", &files[0], "--json", "echo", "OBS1.Local", "--from", "1", "--to", "2"], LIMIT).ok();
    let values: Vec<Json> = echo.stdout.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert!(values.len() >= 5, "{echo:?}");
    assert!(values.iter().all(|v| (1.0..=2.0).contains(&v["t"].as_f64().unwrap()) && v["type"] == "float"));
}

#[test]
fn bad_recordings_and_arguments_fail_with_a_reason() {
    let dir = scratch("bad");
    let missing = dir.join("missing.mcap").display().to_string();
    ayllu(&["replay", &missing, "check"], LIMIT).fails(1, "missing.mcap");
    let text = dir.join("text.mcap");
    std::fs::write(&text, "not a recording").unwrap();
    ayllu(&["replay", &text.display().to_string(), "list"], LIMIT).fails(1, "not an MCAP file");
    ayllu(&["replay", &missing, "--at", "soon", "list"], LIMIT).fails(2, "not a time");
    ayllu(&["node", "--id", "1", "--record-max-bytes", "100000"], LIMIT).fails(2, "--record");
    ayllu(&["node", "--id", "1", "--record", "x.mcap", "--record-max-bytes", "10"], LIMIT).fails(2, "10");
}

/// The files that made the MCAP reader panic (crates/ayllu/tests/malformed_recordings/, see
/// crates/ayllu/tests/runtime/recording_malformed.rs) are refused with a reason by every command that
/// reads a recording: exit 1, no "internal error".
#[test]
fn files_that_made_the_mcap_reader_panic_are_refused_with_a_reason() {
    let inputs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../ayllu/tests/malformed_recordings");
    let garbage = inputs.join("garbage.mcap").display().to_string();
    for command in ["check", "list"] {
        let run = ayllu(&["replay", &garbage, command], LIMIT).fails(1, "not an Ayllu flight recording");
        assert!(run.stderr.contains("at byte 8: a record (opcode 0xff) of 18446744073709551615 bytes"), "{run:?}");
    }
    ayllu(&["play", &garbage, "--udp", "udp://127.0.0.1:0"], LIMIT).fails(1, "cannot read");
    for name in ["message-length-max.mcap", "attachment-short.mcap"] {
        let file = inputs.join(name).display().to_string();
        let run = ayllu(&["replay", &file, "check"], LIMIT);
        assert!(!run.stderr.contains("panicked") && !run.stderr.contains("internal error"), "{name}: {run:?}");
        // Their headers say they are flight recordings: `play` sends them to `replay`, which
        // is the reader that says what is wrong with them (above).
        ayllu(&["play", &file, "--udp", "udp://127.0.0.1:0"], LIMIT).fails(1, "a flight recording of one node");
    }
}

/// `node --record FILE` never replaces a recording (as `sim run --mcap` and `keygen` never
/// replace their files): a robot restarted with the same command line keeps the recording of
/// the run before. A following segment left by an earlier recording is refused too (the
/// recorder would remove it).
#[test]
fn node_record_refuses_a_file_that_exists() {
    let dir = scratch("exists");
    let file = dir.join("flight.mcap");
    std::fs::write(&file, b"the run before").unwrap();
    let path = file.display().to_string();
    let run = ayllu(&["node", "--id", "5", "--udp", "udp://127.0.0.1:0", "--for", "0.2", "--record", &path], LIMIT)
        .fails(1, "flight.mcap exists");
    assert!(run.stderr.contains("move or remove it, or record into another file"), "{run:?}");
    assert!(run.stdout.is_empty(), "refused before the node started: {run:?}");
    assert_eq!(std::fs::read(&file).unwrap(), b"the run before");

    let fresh = dir.join("fresh.mcap");
    std::fs::write(dir.join("fresh.1.mcap"), b"a segment of the run before").unwrap();
    let fresh_path = fresh.display().to_string();
    ayllu(&["node", "--id", "5", "--udp", "udp://127.0.0.1:0", "--for", "0.2", "--record", &fresh_path], LIMIT)
        .fails(1, "fresh.1.mcap exists");
    assert!(!fresh.exists());

    let new = dir.join("new.mcap").display().to_string();
    ayllu(&["node", "--id", "5", "--udp", "udp://127.0.0.1:0", "--for", "0.2", "--record", &new], LIMIT).ok();
    ayllu(&["replay", &new, "check"], LIMIT).ok();
    ayllu(&["node", "--id", "5", "--udp", "udp://127.0.0.1:0", "--for", "0.2", "--record", &new], LIMIT)
        .fails(1, "new.mcap exists");
}

/// A time beyond what a node's clock holds is printed compactly (`1e300 s`, not 301 digits)
/// with the range times take, for every time argument of `replay`.
#[test]
fn times_beyond_the_clock_are_refused_compactly_with_the_range() {
    let dir = scratch("times");
    let file = dir.join("none.mcap").display().to_string();
    for args in [
        &["replay", &file, "--at", "1e300", "list"][..],
        &["replay", &file, "echo", "A.B", "--from", "1e300"],
        &["replay", &file, "echo", "A.B", "--to", "1e300"],
    ] {
        let run = ayllu(args, LIMIT).fails(2, "`1e300` (1e300 s) is not a time on the node's clock");
        assert!(run.stderr.contains("from 0 to 18446744073 s"), "{run:?}");
        assert!(!run.stderr.contains("0000000000"), "{run:?}");
    }
    ayllu(&["replay", &file, "--at", "1e300ms", "list"], LIMIT).fails(2, "(1e297 s) is not a time");
    ayllu(&["replay", &file, "--at=-1", "list"], LIMIT).fails(2, "(-1 s) is not a time on the node's clock");
}

/// `replay echo --from X --to Y` with X after Y is an empty range: a usage error (exit 2), not
/// an empty answer; so is --from after --at when --at ends the range.
#[test]
fn echo_refuses_a_from_after_its_to() {
    let dir = scratch("range");
    let file = dir.join("relay.mcap");
    let path = file.display().to_string();
    let node = ["node", "--id", "5", "--controller", "relay", "--udp", "udp://127.0.0.1:0", "--for", "0.3"];
    ayllu(&[&node[..], &["--record", &path]].concat(), LIMIT).ok();
    let run = ayllu(&["replay", &path, "echo", "RELAY.In", "--from", "2", "--to", "1"], LIMIT)
        .fails(2, "--from 2.000s is after --to 1.000s: nothing lies between them");
    assert!(run.stdout.is_empty(), "{run:?}");
    ayllu(&["replay", &path, "--at", "1", "echo", "RELAY.In", "--from", "1500ms"], LIMIT)
        .fails(2, "--from 1.500s is after --at 1.000s");
    ayllu(&["replay", &path, "echo", "RELAY.In", "--from", "1", "--to", "1"], LIMIT).ok();
    let late = ayllu(&["replay", &path, "echo", "RELAY.In", "--from", "100"], LIMIT).ok();
    assert!(late.stderr.contains("--from 100.000s is after the recording's end"), "{late:?}");
}

/// A recording cut short (a robot killed, a file cut) tells nothing after its last entry the
/// replay applies (spec/flight-recorder.md, "Replay": a replay never goes past it). `--at`
/// after that instant is refused (exit 1) naming the instant, instead of an answer "at T" that
/// shows the node living on with no input (windows lapsed, values aging); without `--at` the
/// replay answers at that instant, and says up to when the recording tells. A closed
/// recording keeps answering after its end with a warning (probe 4, bugs/07).
#[test]
fn replay_never_answers_past_the_end_of_a_cut_recording() {
    let dir = scratch("cut");
    let closed = dir.join("closed.mcap");
    let path = closed.display().to_string();
    // 3 s: the writer closes a chunk every 0.5 s, so a cut at two thirds keeps several.
    let node = ["node", "--id", "5", "--controller", "relay", "--udp", "udp://127.0.0.1:0", "--for", "3"];
    ayllu(&[&node[..], &["--record", &path]].concat(), LIMIT).ok();
    let late = ayllu(&["replay", &path, "--at", "100", "why", "RELAY.In"], LIMIT).ok();
    assert!(late.stderr.contains("is after the recording's end"), "{late:?}");

    // The same recording without its last third: what a killed node leaves.
    let bytes = std::fs::read(&closed).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let cut = cut.display().to_string();
    let check = ayllu(&["replay", &cut, "--json", "check"], LIMIT).ok();
    assert!(check.stderr.contains("cut short"), "{check:?}");
    let known = check.stderr.split("tells about the node up to t=").nth(1).expect("the header says up to when");
    let last: f64 = known.split('s').next().unwrap().parse().unwrap();
    assert!(last > 0.0 && last < 3.0, "{check:?}");

    for what in [&["why", "RELAY.In"][..], &["list"], &["echo", "RELAY.In"]] {
        let args = [&["replay", &cut, "--at", "100"][..], what].concat();
        let run = ayllu(&args, LIMIT).fails(1, &format!("--at 100.000s is after {last:.3}s, the last instant"));
        assert!(run.stderr.contains("it was cut short"), "{run:?}");
        assert!(run.stdout.is_empty(), "no answer past the cut: {run:?}");
    }
    // Without --at: the answer is at the last instant the recording tells about.
    let why = ayllu(&["replay", &cut, "why", "RELAY.In"], LIMIT).ok();
    assert!(why.stdout.contains(&format!("n5:RELAY.In (normal int) at {last:.3}s")), "{why:?}");
    // (`last` is rounded to the millisecond: a millisecond earlier is surely inside.)
    let at = format!("{:.3}", last - 0.001);
    ayllu(&["replay", &cut, "--at", &at, "why", "RELAY.In"], LIMIT).ok();
}

/// The two kinds of recording are both `.mcap` files: handed the other kind, `play` and
/// `replay` say what the file is and which tool reads it (probe 4, bugs/09).
#[test]
fn play_and_replay_name_the_tool_for_the_other_kind_of_recording() {
    let dir = scratch("kinds");
    let flight = dir.join("flight.mcap").display().to_string();
    let team = dir.join("team.mcap").display().to_string();
    let node = ["node", "--id", "5", "--controller", "relay", "--udp", "udp://127.0.0.1:0", "--for", "0.3"];
    ayllu(&[&node[..], &["--record", &flight]].concat(), LIMIT).ok();
    let (_node, addrs) = common::start_on_loopback(
        1,
        |_| "n1".to_owned(),
        |_, url| {
            ["node", "--id", "1", "--controller", "relay", "--udp", url, "--for", "60"]
                .iter()
                .map(|s| s.to_string())
                .collect()
        },
    );
    let url = format!("udp://127.0.0.1:0?peer={}", addrs[0]);
    ayllu(&["record", "-o", &team, "--for", "1", "--udp", &url], LIMIT).ok();

    let run = ayllu(&["play", &flight, "--udp", "udp://127.0.0.1:0"], LIMIT)
        .fails(1, "a flight recording of one node (made by `ayllu node --record`), not a team recording");
    assert!(run.stderr.contains("ask it with `ayllu replay` (why, list, echo or check)"), "{run:?}");
    let run = ayllu(&["replay", &team, "check"], LIMIT)
        .fails(1, "a team recording (made by `ayllu record`), not a flight recording: play it with `ayllu play`");
    assert!(!run.stderr.contains("not an Ayllu flight recording"), "{run:?}");
}
