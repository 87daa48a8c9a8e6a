//! The `ayllu` tool against a real node process over real loopback sockets: every connection
//! kind written by hand (`write --kind ...`) into a relay node, checked with `why --json`;
//! `echo` receiving values and cleaning up; `list`; and the errors a user meets (unknown
//! node, unknown port, bad value, bad period), each with exit code and message.
//!
//! The relay node (`ayllu node --controller relay`) has `RELAY` (int) and `FRELAY` (float):
//! `In -> (process copies) -> Out -> (local connection) -> Aux`, so `Aux` shows what `Out`
//! let through. Every test starts its own relay, so tests run in parallel.

use crate::common;

use std::process::Command;
use std::time::Duration;

use common::{ayllu, wait_for, Proc, Run, BIN};
use serde_json::{json, Value as Json};

/// Every CLI run must finish within this (its own --timeout is far shorter).
const LIMIT: Duration = Duration::from_secs(15);

/// A relay node on its own port, and the CLI's URL to reach it.
struct Relay {
    _proc: Proc,
    url: String,
}

impl Relay {
    fn start() -> Relay {
        Relay::start_with(&[])
    }

    /// A relay with extra `ayllu node` arguments (access rules, limits).
    fn start_with(extra: &[&str]) -> Relay {
        let mut cmd = Command::new(BIN);
        cmd.args(["node", "--id", "1", "--controller", "relay", "--status-ms", "100", "--for", "60"])
            .args(["--udp", "udp://127.0.0.1:0"])
            .args(extra);
        let mut proc = Proc::spawn("relay", cmd);
        let addr = proc.wait_ready();
        Relay { _proc: proc, url: format!("udp://127.0.0.1:0?peer={addr}") }
    }

    /// `ayllu ARGS... --udp URL`.
    fn cli(&self, args: &[&str]) -> Run {
        let mut all: Vec<&str> = args.to_vec();
        all.extend(["--udp", &self.url]);
        ayllu(&all, LIMIT)
    }

    fn write(&self, target: &str, value: &str, extra: &[&str]) -> Run {
        let mut args = vec!["write", "1", target, value];
        args.extend(extra);
        self.cli(&args)
    }

    fn why(&self, target: &str) -> Json {
        self.cli(&["why", "1", target, "--json"]).ok().json()
    }
}

fn windows_of(why: &Json, kind: &str) -> Vec<Json> {
    why["windows"].as_array().into_iter().flatten().filter(|w| w["kind"] == kind).cloned().collect()
}

fn counted(why: &Json, cause: &str) -> u64 {
    why["counted"][cause].as_u64().unwrap_or(0)
}

#[test]
fn list_shows_the_nodes_heard_and_a_nodes_behaviors() {
    let relay = Relay::start();
    let heard = relay.cli(&["list", "--json", "--timeout", "0.5"]).ok().json();
    let node = heard.as_array().unwrap().iter().find(|p| p["node"] == 1).cloned();
    assert!(node.is_some_and(|n| n["name"] == "node-1"), "{heard}");

    let report = relay.cli(&["list", "1", "--json"]).ok().json();
    let behaviors: Vec<&str> =
        report["behaviors"].as_array().unwrap().iter().filter_map(|b| b["name"].as_str()).collect();
    assert_eq!(behaviors, ["FRELAY", "RELAY"], "{report}");
    let relay_ports: Vec<&str> = report["behaviors"][1]["ports"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| p["name"].as_str())
        .filter(|n| ["In", "Out", "Aux"].contains(n))
        .collect();
    assert_eq!(relay_ports, ["In", "Out", "Aux"]);
    assert_eq!(report["connections"].as_array().unwrap().len(), 2, "Out -> Aux on each relay");
    assert!(report["transport_counted"]["datagrams_received"].as_u64().unwrap() > 0, "{report}");

    let text = relay.cli(&["list", "1"]).ok().stdout;
    for needle in ["RELAY (Relay)", "FRELAY (FloatRelay)", "RELAY.Out -> RELAY.Aux", "counters:"] {
        assert!(text.contains(needle), "`{needle}` missing from:\n{text}");
    }
}

#[test]
fn normal_writes_arrive_and_echo_prints_what_a_port_sends() {
    let relay = Relay::start();
    let ok = relay.write("RELAY.In", "5", &[]).ok();
    assert!(ok.stdout.ends_with(": confirmed\n"), "{ok:?}");
    assert!(ok.stdout.contains(" along normal as "), "the default priority goes unsaid: {ok:?}");
    // A priority decides at a Priority port (D3.3): the line says which one was sent.
    let ok = relay.write("FRELAY.In", "0.5", &["--priority", "5"]).ok();
    assert!(ok.stdout.contains(" along normal at priority 5 as "), "{ok:?}");
    assert_eq!(relay.why("RELAY.Aux")["value"], json!({"Int": 5}), "In -> Out -> Aux");
    relay.write("FRELAY.In", "-2.5", &[]).ok();
    assert_eq!(relay.why("FRELAY.Aux")["value"], json!({"Float": -2.5}));

    // echo RELAY.Aux while a writer feeds RELAY.In at 20 Hz; echo has a fixed id so the test
    // can check that it disconnected afterwards.
    let mut echo_cmd = Command::new(BIN);
    echo_cmd.args(["echo", "1", "RELAY.Aux", "--count", "3", "--json", "--timeout", "8", "--id", "0x7ffe0001"]);
    echo_cmd.args(["--udp", &relay.url]);
    let echo = std::thread::spawn(move || common::run(echo_cmd, LIMIT));
    let writer = relay.write("RELAY.In", "7", &["--repeat-hz", "20", "--for", "2", "--json"]).ok().json();
    assert_eq!(writer["confirmed"], true, "{writer}");
    assert!(writer["sent"].as_u64().unwrap() >= 30, "{writer}");
    let echo = echo.join().unwrap().ok();
    let values: Vec<Json> = echo.stdout.lines().map(|l| serde_json::from_str::<Json>(l).unwrap()).collect();
    assert_eq!(values.len(), 3, "{echo:?}");
    assert!(values.iter().all(|v| v["value"] == 7 && v["type"] == "int" && v["t"].as_f64().is_some()), "{echo:?}");

    // echo disconnected on exit: no connection towards its id is left on the relay.
    let report = relay.cli(&["list", "1", "--json"]).ok().json();
    let to_echo = report["connections"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["destination"]["Node"]["node"] == 0x7ffe_0001u32)
        .count();
    assert_eq!(to_echo, 0, "{report}");
}

#[test]
fn suppress_refuses_later_normal_writes_and_counts_them() {
    let relay = Relay::start();
    relay.write("RELAY.In", "5", &[]).ok();
    relay.write("RELAY.In", "7", &["--kind", "suppress", "--period", "5"]).ok();
    let why = relay.why("RELAY.In");
    assert_eq!(why["input_blocked"], "Suppressed", "{why}");
    assert_eq!(windows_of(&why, "Suppress").len(), 1, "{why}");
    assert_eq!(why["value"], json!({"Int": 5}), "a suppress connection writes nothing");

    relay.write("RELAY.In", "9", &[]).fails(1, "suppressed");
    let why = relay.why("RELAY.In");
    assert!(counted(&why, "suppressed") >= 1, "{why}");
    assert_eq!(why["value"], json!({"Int": 5}), "{why}");
}

#[test]
fn inhibit_stops_what_leaves_the_port_and_why_shows_the_window() {
    let relay = Relay::start();
    relay.write("RELAY.In", "1", &[]).ok();
    relay.write("RELAY.Out", "0", &["--kind", "inhibit", "--period", "5"]).ok();
    let why = relay.why("RELAY.Out");
    let windows = windows_of(&why, "Inhibit");
    assert_eq!(windows.len(), 1, "{why}");
    let remaining = windows[0]["remaining"].as_f64().unwrap();
    assert!(remaining > 3.0 && remaining <= 5.0, "window of 5 s (JSON times are seconds): {why}");
    assert_eq!(why["internal_output_blocked"], "Inhibited");
    assert_eq!(why["connection_output_blocked"], "Inhibited");

    // RELAY.Out still takes the new value, but nothing leaves it: Aux keeps the old one.
    relay.write("RELAY.In", "2", &[]).ok();
    assert_eq!(relay.why("RELAY.Out")["value"], json!({"Int": 2}));
    let aux = relay.why("RELAY.Aux");
    assert_eq!(aux["value"], json!({"Int": 1}), "{aux}");
    assert!(counted(&relay.why("RELAY.Out"), "inhibited") >= 1);
}

#[test]
fn override_in_lets_only_its_holder_write() {
    let relay = Relay::start();
    relay.write("RELAY.In", "42", &["--kind", "override-in", "--period", "5"]).ok();
    let why = relay.why("RELAY.In");
    assert_eq!(why["value"], json!({"Int": 42}));
    assert_eq!(windows_of(&why, "OverrideIn").len(), 1, "{why}");
    assert_eq!(relay.why("RELAY.Aux")["value"], json!({"Int": 42}), "the override's value propagates");

    relay.write("RELAY.In", "1", &[]).fails(1, "overridden_in");
    let why = relay.why("RELAY.In");
    assert_eq!(why["value"], json!({"Int": 42}));
    assert!(counted(&why, "overridden_in") >= 1, "{why}");
}

#[test]
fn override_out_lets_only_its_holders_values_leave() {
    let relay = Relay::start();
    relay.write("RELAY.Out", "10", &["--kind", "override-out", "--period", "5"]).ok();
    assert_eq!(relay.why("RELAY.Aux")["value"], json!({"Int": 10}), "the holder's value passes");
    // The relay's own write of Out (copied from In) is stored but held back.
    relay.write("RELAY.In", "3", &[]).ok();
    let out = relay.why("RELAY.Out");
    assert_eq!(out["value"], json!({"Int": 3}), "{out}");
    assert_eq!(out["internal_output_blocked"], "OverriddenOut", "{out}");
    assert_eq!(windows_of(&out, "OverrideOut").len(), 1, "{out}");
    assert!(counted(&out, "overridden_out") >= 1, "{out}");
    assert_eq!(relay.why("RELAY.Aux")["value"], json!({"Int": 10}));
}

#[test]
fn write_inhibit_holds_back_the_behaviors_own_writes_only() {
    let relay = Relay::start();
    relay.write("RELAY.In", "1", &[]).ok();
    relay.write("RELAY.Out", "0", &["--kind", "write-inhibit", "--period", "5"]).ok();
    // Own write (the relay's copy process): stored, not propagated.
    relay.write("RELAY.In", "4", &[]).ok();
    let out = relay.why("RELAY.Out");
    assert_eq!(out["value"], json!({"Int": 4}));
    assert_eq!(out["internal_output_blocked"], "WriteInhibited", "{out}");
    assert_eq!(out["connection_output_blocked"], Json::Null, "{out}");
    assert!(counted(&out, "write_inhibited") >= 1);
    assert_eq!(relay.why("RELAY.Aux")["value"], json!({"Int": 1}));
    // A value arriving along a connection still passes.
    relay.write("RELAY.Out", "6", &[]).ok();
    assert_eq!(relay.why("RELAY.Aux")["value"], json!({"Int": 6}));
}

#[test]
fn a_window_held_by_hand_lasts_while_repeated_and_lapses_after() {
    let relay = Relay::start();
    let url = relay.url.clone();
    // 0.3 s windows renewed at 10 Hz for 1.5 s.
    let hold = std::thread::spawn(move || {
        common::run(
            {
                let mut c = Command::new(BIN);
                c.args(["write", "1", "RELAY.Out", "0", "--kind", "inhibit", "--period", "0.3"]).args([
                    "--repeat-hz",
                    "10",
                    "--for",
                    "1.5",
                    "--udp",
                    &url,
                ]);
                c
            },
            LIMIT,
        )
    });
    // Held by repetition: decided on the node's own clock, not on how long we slept. The first
    // window seen, and when it was to end; then an answer at a node time past that end with
    // the window still open (renewed, so ending later): one window, never two.
    let seconds = |v: &Json| v.as_f64().unwrap_or_else(|| panic!("seconds expected: {v}"));
    let first_end = wait_for(LIMIT, Duration::from_millis(20), || {
        let why = relay.why("RELAY.Out");
        windows_of(&why, "Inhibit").first().map(|w| seconds(&w["ends"]))
    })
    .expect("the repeated writes never opened an inhibit window");
    let renewed = wait_for(LIMIT, Duration::from_millis(50), || {
        let why = relay.why("RELAY.Out");
        let windows = windows_of(&why, "Inhibit");
        (seconds(&why["now"]) >= first_end).then(|| (windows.len(), windows.first().map(|w| seconds(&w["ends"]))))
    });
    match renewed {
        Some((1, Some(end))) => assert!(end > first_end, "the window open after {first_end} s ends at {end} s"),
        other => panic!("not held by repetition past the first window's end ({first_end} s): {other:?}"),
    }
    let done = hold.join().unwrap().ok();
    assert!(done.stdout.contains("confirmed; then") && done.stdout.contains("more over"), "{done:?}");
    // Released: the last window ends 0.3 s after the last write.
    let lapsed = wait_for(Duration::from_secs(3), Duration::from_millis(100), || {
        let why = relay.why("RELAY.Out");
        windows_of(&why, "Inhibit").is_empty().then_some(())
    });
    assert!(lapsed.is_some(), "the inhibition never lapsed");
}

#[test]
fn a_tool_run_again_under_the_same_id_is_not_taken_for_its_old_self() {
    // The first run sends ~20 messages on its connection c1 and asks a few requests; the
    // second run's c1 and request ids start above them (boot-time base, in 2^-32 s), so the
    // relay neither drops its value as stale nor answers its requests from memory — even when
    // the second run starts within the same second.
    let relay = Relay::start();
    relay.write("RELAY.In", "5", &["--id", "0x7ffe0002", "--repeat-hz", "50", "--for", "0.4"]).ok();
    let again = relay.write("RELAY.In", "6", &["--id", "0x7ffe0002", "--json"]).ok().json();
    assert_eq!(again["confirmed"], true, "{again}");
    let why = relay.why("RELAY.In");
    assert_eq!(why["value"], json!({"Int": 6}), "{why}");
    let report = relay.cli(&["list", "1", "--json"]).ok().json();
    assert_eq!(report["counted"]["stale"], Json::Null, "nothing dropped as stale: {}", report["counted"]);
}

#[test]
fn the_tools_id_cannot_be_the_id_of_the_node_asked_about() {
    // The tool is a node of the team: with the asked node's id, each side would drop the
    // other's datagrams as its own id's duplicates, and the wait would blame the URL.
    let relay = Relay::start();
    let run =
        relay.cli(&["list", "1", "--id", "1", "--timeout", "2"]).fails(2, "--id 1 is the id of the node asked about");
    assert!(!run.stderr.contains("check the node id and the URL"), "{run:?}");
    relay.cli(&["why", "1", "RELAY.In", "--id", "1"]).fails(2, "needs an id of its own");
    relay.cli(&["list", "1", "--id", "2"]).ok();
}

/// `foxglove` and `record` talk to every node they hear, not to one named on the command line:
/// with an `--id` a node of the team has, that node would be left out in silence (each side
/// drops the other's datagrams). They look first, under another id, and refuse as `list 1
/// --id 1` does; `record` leaves no file behind.
#[test]
fn tools_that_watch_every_node_refuse_an_id_a_node_has() {
    let relay = Relay::start();
    let dir = std::env::temp_dir().join(format!("ayllu-cli-id-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("team.mcap");
    let out = file.display().to_string();
    let run = relay
        .cli(&["record", "-o", &out, "--for", "1", "--id", "1"])
        .fails(2, "--id 1 is the id of a node heard on the network (node-1 at 127.0.0.1:");
    assert!(run.stderr.contains("needs an id of its own"), "{run:?}");
    assert!(!file.exists(), "nothing recorded, no file left: {run:?}");
    relay.cli(&["record", "-o", &out, "--for", "0.5", "--id", "2"]).ok();
    #[cfg(feature = "foxglove")]
    {
        relay
            .cli(&["foxglove", "--port", "0", "--for", "1", "--id", "1"])
            .fails(2, "--id 1 is the id of a node heard on the network");
        relay.cli(&["foxglove", "--port", "0", "--for", "0.5", "--id", "2"]).ok();
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Only a connection to another node or a group sends anything: `list NODE` prints `(sent N)`
/// for those, and nothing for a connection inside the node (its count would always be 0).
#[test]
fn list_says_sent_only_for_connections_that_leave_the_node() {
    let relay = Relay::start();
    let text = relay.cli(&["list", "1"]).ok().stdout;
    let local = text.lines().find(|l| l.contains("RELAY.Out -> RELAY.Aux")).expect("the relay's connection");
    assert!(!local.contains("sent"), "{text}");
    // Robot 2 of the paper's Fig. 2: its BLE claims go to the group Peers.
    let mut cmd = Command::new(BIN);
    cmd.args(["node", "--id", "2", "--layers", "1", "--status-ms", "100", "--for", "60", "--udp", "udp://127.0.0.1:0"]);
    let mut robot = Proc::spawn("robot", cmd);
    let url = format!("udp://127.0.0.1:0?peer={}", robot.wait_ready());
    let text = ayllu(&["list", "2", "--udp", &url], LIMIT).ok().stdout;
    let group = text.lines().find(|l| l.contains("-> *Peers:")).unwrap_or_else(|| panic!("a group connection: {text}"));
    assert!(group.contains("(sent "), "{text}");
    for line in text.lines().filter(|l| l.contains(" -> ") && !l.contains("*Peers:")) {
        assert!(!line.contains("sent"), "{line}\n{text}");
    }
    // The JSON keeps every connection's count.
    let json = ayllu(&["list", "2", "--json", "--udp", &url], LIMIT).ok().json();
    assert!(json["connections"].as_array().unwrap().iter().all(|c| c["sent"].is_u64()), "{json}");
}

/// Numbers out of an argument's range are printed as typed in exponent form (`1e300`, not 301
/// digits) with the range the argument takes.
#[test]
fn arguments_out_of_range_say_the_range_compactly() {
    for args in [
        &["list", "1", "--timeout", "1e300"][..],
        &["hz", "1", "A.B", "--every", "1e300"],
        &["write", "1", "A.B", "1", "--kind", "inhibit", "--period", "1e300"],
        &["node", "--id", "1", "--max-window", "1e300"],
    ] {
        // The core's words (Duration::try_from_positive_secs), as C and Python say it.
        let run = ayllu(args, LIMIT)
            .fails(2, "1e300 s is too long: a span of time is from 0 to 18446744073 s (about 584 years)");
        assert!(!run.stderr.contains("0000000000"), "{run:?}");
    }
    ayllu(&["list", "1", "--timeout", "0"], LIMIT).fails(2, "0 s is not allowed here: a span above zero is from 1 ns");
    ayllu(&["write", "1", "A.B", "1", "--repeat-hz", "1e-300"], LIMIT).fails(
        2,
        "rate of 1e-300 Hz is invalid; rates must be finite and above zero, with a period from 1 ns to 584 years",
    );
}

#[test]
fn an_unknown_node_times_out_with_a_clear_message() {
    let relay = Relay::start();
    let run = relay.cli(&["why", "99", "RELAY.In", "--timeout", "1"]).fails(1, "unknown node n99");
    assert!(run.stderr.contains("no HELLO") && run.stderr.contains("n1 at 127.0.0.1"), "{run:?}");
    assert!(run.took < Duration::from_secs(4), "bounded by --timeout: {run:?}");
    // Nobody to ask at all (no peer=, no broadcast=).
    let run = ayllu(&["list", "3", "--timeout", "0.5"], LIMIT).fails(1, "heard no node at all");
    assert!(run.stderr.contains("peer=ADDR:PORT"), "{run:?}");
    ayllu(&["write", "3", "B.P", "1", "--timeout", "0.5"], LIMIT).fails(1, "unknown node n3");
    ayllu(&["echo", "3", "B.P", "--timeout", "0.5"], LIMIT).fails(1, "unknown node n3");
}

#[test]
fn an_unknown_port_or_behavior_reports_the_nodes_own_error() {
    let relay = Relay::start();
    relay.cli(&["why", "1", "RELAY.Nope"]).fails(1, "behavior `RELAY` has no port named `Nope`");
    relay.cli(&["echo", "1", "GHOST.Out", "--count", "1"]).fails(1, "no behavior named `GHOST`");
    relay.write("RELAY.Nope", "1", &[]).fails(1, "has no port named `Nope`");
}

#[test]
fn bad_values_and_periods_are_refused_before_anything_is_written() {
    let relay = Relay::start();
    relay.write("RELAY.In", "abc", &[]).fails(1, "holds int: expected an integer");
    relay.write("FRELAY.In", "fast", &[]).fails(1, "holds float");
    relay.write("RELAY.In", "1", &["--kind", "suppress", "--period", "0"]).fails(2, "0 s is not allowed here");
    relay.write("RELAY.In", "1", &["--kind", "inhibit", "--period", "-1"]).fails(2, "-1 s is negative");
    relay.write("RELAY.In", "1", &["--period", "1"]).fails(2, "--period applies to");
    relay.write("RELAY.In", "1", &["--kind", "sideways"]).fails(2, "invalid value 'sideways'");
    // Nothing reached the port.
    let why = relay.why("RELAY.In");
    assert_eq!(why["accepted"], 0, "{why}");
}

#[test]
fn usage_errors_exit_with_code_2() {
    ayllu(&["why", "robot", "B.P"], LIMIT).fails(2, "not a node id");
    ayllu(&["why", "1", "nodot"], LIMIT).fails(2, "BEHAVIOR.PORT");
    ayllu(&["frobnicate"], LIMIT).fails(2, "unrecognized subcommand");
    ayllu(&["list", "--udp", "mem://x"], LIMIT).fails(2, "udp://");
    ayllu(&["list", "--udp", "udp://127.0.0.1:1?colour=blue"], LIMIT).fails(1, "unknown option `colour`");
    ayllu(&["node", "--id", "1", "--udp", "udp://127.0.0.1:0", "--sight", "9:0.5"], LIMIT).fails(2, "only 4 layers");
    let help = ayllu(&["--help"], LIMIT).ok();
    for sub in ["list", "why", "echo", "write", "node"] {
        assert!(help.stdout.contains(sub), "{help:?}");
    }
}

#[test]
fn list_without_a_node_exits_1_when_it_hears_nobody() {
    // A script must see "found nothing" in the exit code, with what to check.
    let run = ayllu(&["list", "--timeout", "0.3"], LIMIT).fails(1, "no node heard");
    assert!(run.stderr.contains("AYLLU_URL"), "{run:?}");
    let run = ayllu(&["list", "--json", "--timeout", "0.3"], LIMIT).fails(1, "no node heard");
    assert_eq!(run.stdout.trim(), "[]", "JSON still gets its (empty) list: {run:?}");
}

#[test]
fn disconnect_removes_a_connection_a_killed_echo_left() {
    let relay = Relay::start();
    // An echo killed without a word leaves its connection on the node until the node forgets
    // it (D9.1: three of its HELLO periods; a minute each here, so the lease outlasts the test).
    let mut echo = start_echo(&relay, 60_000);
    let conns = echo_connections(&relay);
    echo.kill();
    let conn = format!("c{}", conns[0]);
    let done = relay.cli(&["disconnect", "1", &conn]).ok();
    assert!(done.stdout.contains(&format!("disconnected n1's connection {conn}")), "{done:?}");
    let report = relay.cli(&["list", "1", "--json"]).ok().json();
    assert!(!report["connections"].to_string().contains("ECHO"), "{report}");
    // Twice: the node says it has no such connection.
    relay.cli(&["disconnect", "1", &conn]).fails(1, "no connection with id");
    ayllu(&["disconnect", "1", "cx"], LIMIT).fails(2, "not a connection id");
}

#[test]
fn typos_in_names_get_a_suggestion() {
    let relay = Relay::start();
    relay.cli(&["why", "1", "RELAY.Ou"]).fails(1, "did you mean `RELAY.Out`?");
    relay.cli(&["why", "1", "relay.Out"]).fails(1, "did you mean `RELAY.Out`?");
    relay.write("FRELAY.inn", "1", &[]).fails(1, "did you mean `FRELAY.In`?");
    // Nothing close: no suggestion.
    let run = relay.cli(&["why", "1", "RELAY.Completely"]).fails(1, "has no port named");
    assert!(!run.stderr.contains("did you mean"), "{run:?}");
}

/// A suggestion names a port that exists: behavior and port are matched together, each
/// case-insensitively, and the real names are given (`relay.in` is `RELAY.In`, not the
/// nonexistent `RELAY.in`).
#[test]
fn a_suggestion_names_a_real_port_whatever_the_case_of_both_names() {
    let relay = Relay::start();
    for (typed, real) in
        [("relay.in", "RELAY.In"), ("relay.aux", "RELAY.Aux"), ("Relay.OUT", "RELAY.Out"), ("frelay.In", "FRELAY.In")]
    {
        let run = relay.cli(&["why", "1", typed]).fails(1, &format!("did you mean `{real}`?"));
        assert_eq!(run.stderr.matches("did you mean").count(), 1, "{run:?}");
    }
    // The port itself is mistyped too: still a real one.
    relay.cli(&["why", "1", "relay.inn"]).fails(1, "did you mean `RELAY.In`?");
    // A behavior that is close but has no port close to the one typed: no suggestion.
    let run = relay.cli(&["why", "1", "relay.Completely"]).fails(1, "no behavior named `relay`");
    assert!(!run.stderr.contains("did you mean"), "{run:?}");
}

/// A keyed node of team 3 reached by `peer=`: a tool with another key, no key or another team
/// hears nothing back (the node drops its datagrams without a word, so there is nothing for
/// the tool to count), and its hint names team/key as the thing to check.
#[test]
fn a_node_reached_by_peer_with_another_team_or_key_gets_the_team_key_hint() {
    let (k1, k2) = ("a".repeat(64), "b".repeat(64));
    let url = format!("udp://127.0.0.1:0?key={k1}&team=3");
    let mut cmd = Command::new(BIN);
    cmd.args(["node", "--id", "1", "--controller", "relay", "--status-ms", "100", "--for", "60", "--udp", &url]);
    let mut proc = Proc::spawn("keyed relay", cmd);
    let addr = proc.wait_ready();
    for tool in [format!("key={k2}&team=3"), "team=3".to_owned(), format!("key={k1}&team=4")] {
        let url = format!("udp://127.0.0.1:0?peer={addr}&{tool}");
        let run = ayllu(&["why", "1", "RELAY.In", "--timeout", "1", "--udp", &url], LIMIT).fails(1, "unknown node n1");
        assert!(run.stderr.contains("and team/key: a node whose team= or key= differs"), "{run:?}");
        assert!(!run.stderr.contains(&k1) && !run.stderr.contains(&k2), "the key stays hidden: {run:?}");
    }
    // The right team and key: answered.
    let url = format!("udp://127.0.0.1:0?peer={addr}&key={k1}&team=3");
    ayllu(&["why", "1", "RELAY.In", "--udp", &url], LIMIT).ok();
}

#[test]
fn output_for_people_rounds_floats_and_json_times_are_seconds() {
    let relay = Relay::start();
    relay.write("FRELAY.In", "0.30000000000000004", &[]).ok();
    let why = relay.cli(&["why", "1", "FRELAY.In"]).ok();
    assert!(why.stdout.contains("0.30000000000000004"), "why keeps the exact value: {why:?}");
    let text = relay.cli(&["list", "1"]).ok();
    assert!(text.stdout.contains(" 0.3 ") && !text.stdout.contains("0.30000000000000004"), "{text:?}");
    // The implicit BLE ports show only on BLE members (the relay has none).
    assert!(!text.stdout.contains("Best") && !text.stdout.contains("Inhibit"), "{text:?}");
    let json = relay.cli(&["why", "1", "FRELAY.In", "--json"]).ok().json();
    assert!(json["now"].is_f64(), "times in seconds: {json}");
    assert!(json["last_accepted"].is_f64(), "{json}");
    assert_eq!(json["value"], json!({"Float": 0.30000000000000004}), "JSON keeps every bit");
}

/// `ayllu echo 1 RELAY.Out` against the relay, announcing itself every `hello_ms`.
fn start_echo(relay: &Relay, hello_ms: u64) -> Proc {
    let mut cmd = Command::new(BIN);
    cmd.args(["echo", "1", "RELAY.Out", "--udp", &format!("{}&hello_ms={hello_ms}", relay.url)]);
    Proc::spawn("echo", cmd)
}

/// The relay's connections to an echo, once there is one.
fn echo_connections(relay: &Relay) -> Vec<u64> {
    wait_for(LIMIT, Duration::from_millis(50), || {
        let conns = connections_to_echo(relay);
        (!conns.is_empty()).then_some(conns)
    })
    .expect("echo connected")
}

fn connections_to_echo(relay: &Relay) -> Vec<u64> {
    let report = relay.cli(&["list", "1", "--json"]).ok().json();
    report["connections"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["destination"].to_string().contains("ECHO"))
        .filter_map(|c| c["id"].as_u64())
        .collect()
}

#[test]
fn a_killed_echos_connection_expires_with_its_lease() {
    // D9.1: the connection an echo asked for is leased to it; killed (no DISCONNECT), it
    // stops announcing itself, the relay forgets it after three HELLO periods and removes the
    // connection. `list` shows whose request made a connection meanwhile.
    let relay = Relay::start();
    let mut echo = start_echo(&relay, 200);
    let conns = echo_connections(&relay);
    let text = relay.cli(&["list", "1"]).ok();
    assert!(text.stdout.contains("requested by"), "{text:?}");
    echo.kill();
    let gone = wait_for(LIMIT, Duration::from_millis(100), || connections_to_echo(&relay).is_empty().then_some(()));
    assert!(gone.is_some(), "connections {conns:?} outlived their requester");
}

#[test]
fn a_node_can_refuse_rewiring_and_writes_from_the_network() {
    // D9.2: `--allow-rewire none` refuses the CONNECT an echo needs, with the reason; port
    // writes stay open. `--allow-write none` drops port messages, counted as not_allowed; the
    // node sends no answer to a port message, so write reads that count back and reports the
    // refusal (exit 1).
    let relay = Relay::start_with(&["--allow-rewire", "none"]);
    relay.cli(&["echo", "1", "RELAY.Out", "--count", "1"]).fails(1, "not allowed");
    relay.write("RELAY.In", "4", &[]).ok();
    let relay = Relay::start_with(&["--allow-write", "none", "--max-window", "10"]);
    let run = relay.write("RELAY.In", "4", &["--json"]).fails(1, "refused 4: the node does not let");
    assert!(run.stderr.contains("(its --allow-write); counted as `not_allowed`"), "{run:?}");
    let report = relay.cli(&["list", "1", "--json"]).ok().json();
    assert!(report["counted"]["not_allowed"].as_u64().unwrap_or(0) >= 1, "{report}");
    ayllu(&["node", "--id", "1", "--allow-write", "robots"], LIMIT).fails(2, "not a node id");
}

#[test]
fn a_window_longer_than_the_nodes_limit_is_reported_as_refused_with_the_reason() {
    // D9.3: the node drops a port message whose window is longer than its --max-window and
    // only counts it (`too_long`): write reads the count back and says so, exit 1. Within
    // the limit the same write is confirmed.
    let relay = Relay::start_with(&["--max-window", "10"]);
    let run = relay.write("RELAY.Out", "3", &["--kind", "inhibit", "--period", "11"]).fails(1, "refused 3");
    assert!(run.stderr.contains("inhibit window of 11.000s is longer than the node takes"), "{run:?}");
    assert!(run.stderr.contains("counted as `too_long`"), "{run:?}");
    assert!(run.stdout.is_empty(), "{run:?}");
    let report = relay.cli(&["list", "1", "--json"]).ok().json();
    assert!(report["counted"]["too_long"].as_u64().unwrap_or(0) >= 2, "{report}");
    let run = relay.write("RELAY.Out", "3", &["--kind", "inhibit", "--period", "10"]).ok();
    assert!(run.stdout.contains("confirmed"), "{run:?}");
}

#[test]
fn a_node_given_an_operator_key_is_rewired_only_by_the_operators_tools() {
    // D9.4: `ayllu keygen` makes the pair; a relay started with operator=PUBLIC refuses an
    // echo's CONNECT from a tool without the secret (with the reason) and accepts it from a
    // tool with operator_secret=FILE. Port writes need no signature.
    let dir = std::env::temp_dir().join(format!("ayllu-cli-operator-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let secret = dir.join("operator.secret");
    let keygen = ayllu(&["keygen", secret.to_str().unwrap()], LIMIT).ok();
    let public = keygen.stdout.trim().to_owned();
    assert_eq!(public.len(), 64, "{keygen:?}");
    ayllu(&["keygen", secret.to_str().unwrap()], LIMIT).fails(1, "exists");

    let mut cmd = Command::new(BIN);
    cmd.args(["node", "--id", "1", "--controller", "relay", "--status-ms", "100", "--for", "60"])
        .args(["--udp", &format!("udp://127.0.0.1:0?operator={public}")]);
    let mut proc = Proc::spawn("relay", cmd);
    let addr = proc.wait_ready();
    let plain = format!("udp://127.0.0.1:0?peer={addr}");
    let signed = format!("{plain}&operator_secret={}", secret.display());
    ayllu(&["echo", "1", "RELAY.Out", "--count", "1", "--udp", &plain], LIMIT).fails(1, "operator key");
    ayllu(&["write", "1", "RELAY.In", "4", "--udp", &plain], LIMIT).ok();
    // The operator's echo is connected; a writer feeds RELAY.In so that Out has values to send.
    let mut echo_cmd = Command::new(BIN);
    echo_cmd.args(["echo", "1", "RELAY.Out", "--count", "2", "--timeout", "8", "--udp", &signed]);
    let echo = std::thread::spawn(move || common::run(echo_cmd, LIMIT));
    ayllu(&["write", "1", "RELAY.In", "9", "--repeat-hz", "20", "--for", "2", "--udp", &plain], LIMIT).ok();
    let echo = echo.join().unwrap().ok();
    assert_eq!(echo.stdout.lines().count(), 2, "{echo:?}");
    let report = ayllu(&["list", "1", "--json", "--udp", &plain], LIMIT).ok().json();
    assert!(report["transport_counted"]["unsigned"].as_u64().unwrap_or(0) >= 1, "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The error examples of docs/cli.md and docs/troubleshooting.md are the real messages: the
/// unknown-node hint (with the example's address), a node's refusal of an unknown behavior,
/// and `graph -o` (there is no `--out`) with a file it cannot write.
#[test]
fn the_documented_error_examples_are_the_real_messages() {
    let docs =
        |page: &str| std::fs::read_to_string(format!("{}/../../docs/{page}", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let (cli, troubleshooting) = (docs("cli.md"), docs("troubleshooting.md"));
    let relay = Relay::start();
    let addr = relay.url.split("peer=").nth(1).unwrap().to_owned();
    let run = relay.cli(&["why", "9", "RELAY.In", "--timeout", "1"]).fails(1, "unknown node n9");
    let shown = run.stderr.trim().replace(&addr, "127.0.0.1:7400");
    assert!(cli.contains(&format!("{shown}\n")), "docs/cli.md \"Errors\" should show:\n{shown}");
    let run = relay.cli(&["why", "1", "MOTR.Turn"]).fails(1, "no behavior named `MOTR`");
    let shown = run.stderr.trim().trim_start_matches("ayllu: ");
    assert!(troubleshooting.contains(shown), "troubleshooting.md should quote: {shown}");
    relay.cli(&["graph", "-o", "/nonexistent-dir/x.dot"]).fails(1, "cannot write /nonexistent-dir/x.dot");
    ayllu(&["graph", "--out", "x.dot"], LIMIT).fails(2, "unexpected argument '--out'");
    assert!(!troubleshooting.contains("graph --out") && troubleshooting.contains("ayllu graph -o FILE"));
    // "unknown node" is also what a tool that heard nobody says: the page explains both.
    ayllu(&["why", "9", "RELAY.In", "--timeout", "0.3"], LIMIT).fails(1, "(heard no node at all)");
    let row = troubleshooting.lines().find(|l| l.starts_with("| `unknown node N:")).unwrap();
    assert!(row.contains("heard no node at all") && row.contains("heard n1 at ADDR"), "{row}");
}
