//! Deterministic replay (spec/flight-recorder.md): a recording played back into a fresh core
//! reproduces every value the node's ports accepted, bit for bit, with no application code;
//! and `why` asked of a past instant names the windows open then, their holders and the time
//! they had left.

use std::net::SocketAddr;
use std::path::PathBuf;

use ayllu::datagram::{DatagramSocket, OsSocket};
use ayllu::faults::{FaultConfig, FaultySocket};
use ayllu::replay::{Ending, Recording, Replay};
use ayllu::stdlib::{cross_subsumption, BASE, VISION};
use ayllu::{
    BehaviorClass, Clock, ConnectionKind, Duration, Endpoint, Event, Instant, Lockstep, ManualClock, Node, NodeId,
    PortSpec, RecordOptions, Source, UdpConfig, UdpTransport, Value, WindowKind,
};

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("replay-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A node's clock: the team's, `shift` ahead (robots whose clocks started at different moments).
pub(crate) struct Shifted(pub ManualClock, pub Duration);

impl Clock for Shifted {
    fn now(&self) -> Instant {
        self.0.now() + self.1
    }
    fn is_real_time(&self) -> bool {
        false
    }
}

/// Three nodes over real loopback UDP, each one's sends through the fault injector (15 % loss,
/// duplication, reordering, delay, seeded by `seed`), running the paper's cross-subsumption
/// with BLE plus a remote relay ring with a process, each recording into `d` (`nI.mcap`), node
/// `i`'s clock the team's shifted by `shift_ms[i]`; run for `secs` of the team's time. The
/// recordings are still on.
pub(crate) fn recorded_udp_team(d: &std::path::Path, name: &str, seed: u64, shift_ms: [u64; 3], secs: u64) -> Lockstep {
    let mut team = Lockstep::new(name);
    let mut sockets: Vec<OsSocket> = (0..3).map(|_| OsSocket::bind("127.0.0.1:0".parse().unwrap()).unwrap()).collect();
    let addrs: Vec<SocketAddr> = sockets.iter().map(|s| s.local_addr().unwrap()).collect();
    sockets.reverse();
    let faults = FaultConfig {
        loss: 0.15,
        duplicate: 0.05,
        reorder: 0.05,
        delay: Duration::from_millis(3),
        jitter: Duration::from_millis(6),
        ..FaultConfig::none(seed)
    };
    for id in 1..=3u32 {
        let socket = sockets.pop().unwrap();
        let mut config = UdpConfig::new(socket.local_addr().unwrap());
        config.peers = addrs.clone();
        config.hello_interval = Duration::from_millis(200);
        let socket = FaultySocket::new(
            socket,
            team.clock().clone(),
            FaultConfig { seed: seed + u64::from(id), ..faults.clone() },
        );
        let clock = Shifted(team.clock().clone(), Duration::from_millis(shift_ms[id as usize - 1]));
        let mut node = Node::new(clock, UdpTransport::with_socket(NodeId(id), config, socket).unwrap());
        node.record(d.join(format!("n{id}.mcap")), RecordOptions::default()).unwrap();
        cross_subsumption(node.core_mut(), 3, "Peers", 2.0).unwrap();
        // A relay whose process doubles what arrives (a process the replay has no code for).
        let mut relay = BehaviorClass::new("Relay");
        let input = relay.port(PortSpec::new("In", 0.0)).unwrap();
        let out = relay.port(PortSpec::new("Out", 0.0)).unwrap();
        relay
            .on_write("Double", input, move |ctx| {
                let x = ctx.float(input).unwrap_or(0.0);
                ctx.write(out, x * 2.0 + 1e-9).unwrap();
            })
            .unwrap();
        node.define(relay).unwrap();
        node.create("Relay", "R").unwrap();
        let next = NodeId(id % 3 + 1);
        node.connect(&Endpoint::local("R", "Out"), &Endpoint::node(next, "R", "In"), ConnectionKind::Normal).unwrap();
        team.add_node(node);
    }
    let tick = Duration::from_millis(10);
    let mut k = 0u64;
    while team.now() < Instant::from_secs(secs) {
        if k.is_multiple_of(10) {
            for i in 0..3 {
                let id = team.nodes()[i].id().0;
                let node = team.node(i);
                for n in 1..=3u32 {
                    if !(n + id).is_multiple_of(3) {
                        node.write(VISION, &format!("Target{n}Angle"), 0.1 * f64::from(n)).unwrap();
                        node.write(VISION, &format!("Target{n}Bottom"), 0.3 + 0.1 * f64::from(id * n % 5)).unwrap();
                    }
                }
                node.write("R", "In", (k as f64).sqrt() / 3.0).unwrap();
            }
        }
        team.advance(tick, tick);
        // Real sockets: let the kernel deliver before the next step.
        std::thread::sleep(std::time::Duration::from_micros(200));
        k += 1;
    }
    team
}

/// Three nodes over real loopback UDP with faults ([`recorded_udp_team`]), each recording.
/// Every recording replays to its end with every accepted value equal, bit for bit, and none
/// missing.
#[test]
fn a_recorded_three_node_udp_run_with_loss_replays_bit_for_bit() {
    let d = dir("udp-loss");
    let mut team = recorded_udp_team(&d, "replay-udp-loss", 7, [0; 3], 5);
    let (mut sent, mut received) = (0, 0);
    for i in 0..3 {
        let node = team.node(i);
        let count = |name: &str| node.transport_counters().iter().find(|(k, _)| k == name).map_or(0, |(_, v)| *v);
        sent += count("datagrams_sent");
        received += count("datagrams_received");
        let stats = node.stop_recording().unwrap();
        assert_eq!((stats.dropped_queue, stats.dropped_journal, stats.dropped_cap), (0, 0, 0), "{stats:?}");
        assert_eq!(stats.error, None);
    }
    // The loss was real: a good part of what was sent never arrived.
    assert!(received * 100 < sent * 95, "{received} of {sent} datagrams arrived");
    for id in 1..=3u32 {
        let rec = Recording::open(d.join(format!("n{id}.mcap"))).unwrap();
        assert_eq!(rec.node, NodeId(id));
        assert_eq!(rec.ending, Ending::Closed);
        assert_eq!(rec.gap, None);
        let recorded = rec.entries.iter().filter(|e| matches!(e.event, Event::Accepted { .. })).count();
        let received = rec.entries.iter().filter(|e| matches!(e.event, Event::Receive { .. })).count();
        let runs = rec.entries.iter().filter(|e| matches!(e.event, Event::Run { native: false, .. })).count();
        assert!(
            recorded > 1000 && received > 100 && runs > 100,
            "n{id}: {recorded} accepted, {received} received, {runs} runs"
        );
        let mut replay = Replay::new(&rec);
        replay.run_to_end().unwrap_or_else(|d| panic!("n{id}: {d}"));
        assert_eq!(replay.checked(), recorded, "n{id}: every accepted value compared");
        // And the replayed node ends where the live one did.
        let live = team.nodes().iter().find(|n| n.id() == NodeId(id)).unwrap();
        for (b, p) in [(BASE, "Rotate"), ("R", "Out"), ("R", "In")] {
            let replayed = replay.core().read(replay.core().port(b, p).unwrap()).unwrap();
            let now = live.core().read(live.core().port(b, p).unwrap()).unwrap();
            assert_eq!(format!("{replayed:?}"), format!("{now:?}"), "n{id} {b}.{p}");
        }
    }
}

/// The recording is checked, not trusted: a recording whose accepted value was altered makes
/// the replay stop there and say what differed.
#[test]
fn a_tampered_recording_is_reported_as_a_divergence() {
    let d = dir("tamper");
    let path = d.join("t.mcap");
    run_suppression(&path);
    let mut rec = Recording::open(&path).unwrap();
    let i = rec.entries.iter().rposition(|e| matches!(e.event, Event::Accepted { .. })).unwrap();
    if let Event::Accepted { value, .. } = &mut rec.entries[i].event {
        *value = Value::Float(12345.0);
    }
    let err = Replay::new(&rec).run_to_end().unwrap_err();
    assert_eq!(err.seq, i as u64);
    assert!(err.what.contains("12345"), "{err}");
}

/// A bumper suppresses a motor's input for 2 s at t = 1 s; a planner keeps writing. Asked at
/// 2.5 s, the replay names the Suppress window, its holder (the bumper's connection) and its
/// 0.5 s left; asked at 3.5 s there is none; asked at 0.5 s neither.
fn run_suppression(path: &std::path::Path) -> ayllu::ConnectionId {
    let team = Lockstep::new("replay-why");
    let clock = team.clock().clone();
    let mut node = Node::new(clock.clone(), team.network().attach(NodeId(4)).unwrap());
    node.record(path, RecordOptions::default()).unwrap();
    for (class, port) in [("Planner", "Cmd"), ("Bumper", "Hit"), ("Motor", "Speed")] {
        let mut c = BehaviorClass::new(class);
        c.port(PortSpec::new(port, 0.0)).unwrap();
        node.define(c).unwrap();
        node.create(class, class).unwrap();
    }
    let speed = Endpoint::local("Motor", "Speed");
    node.connect(&Endpoint::local("Planner", "Cmd"), &speed, ConnectionKind::Normal).unwrap();
    let stop = node
        .connect(&Endpoint::local("Bumper", "Hit"), &speed, ConnectionKind::Suppress(Duration::from_secs(2)))
        .unwrap();
    for ms in (0..5000).step_by(100) {
        clock.set(Instant::from_millis(ms));
        if ms == 1000 {
            node.write("Bumper", "Hit", 1.0).unwrap();
        }
        node.write("Planner", "Cmd", ms as f64 / 1000.0).unwrap();
        node.step();
    }
    node.stop_recording().unwrap();
    stop
}

#[test]
fn why_at_a_past_instant_names_the_window_its_holder_and_its_remaining_time() {
    let d = dir("why");
    let path = d.join("why.mcap");
    let stop = run_suppression(&path);
    let rec = Recording::open(&path).unwrap();
    let mut replay = Replay::new(&rec);
    let early = replay.why_at(Instant::from_millis(500), "Motor", "Speed").unwrap();
    assert!(early.windows.is_empty());
    assert_eq!(early.value, Value::Float(0.5));

    let mut replay = Replay::new(&rec);
    let report = replay.why_at(Instant::from_millis(2500), "Motor", "Speed").unwrap();
    assert_eq!(report.windows.len(), 1, "{report}");
    let w = &report.windows[0];
    assert_eq!(w.kind, WindowKind::Suppress);
    assert_eq!(w.holder, Source::connection(NodeId(4), stop));
    assert_eq!(w.remaining, Duration::from_millis(500));
    assert_eq!(w.ends, Instant::from_millis(3000));
    // The planner's writes were refused from 1 s (the bumper wrote first): the motor still
    // holds the 0.9 of t = 0.9 s.
    assert_eq!(report.value, Value::Float(0.9));
    assert!(report.to_string().contains("suppress"), "{report}");
    // Later instants on the same replay: the window has closed and the planner drives again.
    let later = replay.why_at(Instant::from_millis(3500), "Motor", "Speed").unwrap();
    assert!(later.windows.is_empty());
    assert_eq!(later.value, Value::Float(3.5));
    // The whole node as it was, too.
    let list = replay.list_at(Instant::from_millis(3500)).unwrap();
    assert_eq!(list.behaviors.len(), 3);
    assert_eq!(list.connections.len(), 2);
}

/// Every kind of input and effect on two `mem://` nodes: monostables triggered from outside
/// and by processes, processes on monostables, a process added to one behavior, resets, a Sum
/// port fed remotely, behaviors removed and created again, connections removed, groups joined
/// and left, access and limits, a lost peer, a warning, a LIST request and its reply. Both
/// recordings replay exactly, every entry of every kind accounted for.
#[test]
fn every_kind_of_input_and_effect_replays() {
    let d = dir("kinds");
    let team = Lockstep::new("replay-kinds");
    let clock = team.clock().clone();
    let mut nodes = Vec::new();
    for id in [1u32, 2] {
        let mut node = Node::new(clock.clone(), team.network().attach(NodeId(id)).unwrap());
        node.record(d.join(format!("k{id}.mcap")), RecordOptions::default()).unwrap();
        let mut c = BehaviorClass::new("Kit");
        let out = c.port(PortSpec::new("Out", 0i64)).unwrap();
        let sum = c.port(PortSpec::new("Sum", 0i64).sum().window(Duration::from_millis(300))).unwrap();
        let n = c.slot("N", 0i64).unwrap();
        let busy = c.monostable("Busy").unwrap();
        c.every_hz("Tick", 25.0, move |ctx| {
            let k = ctx.slot(n).as_int().unwrap_or(0) + 1;
            ctx.set_slot(n, k).unwrap();
            ctx.write(out, k).unwrap();
            if k % 7 == 0 {
                ctx.trigger(busy, Duration::from_millis(90));
            }
            if k % 11 == 0 {
                ctx.reset(sum);
            }
        })
        .unwrap();
        c.on_monostable("Edge", busy, move |ctx| {
            let high = ctx.is_high(busy);
            ctx.write(out, if high { -1i64 } else { -2 }).unwrap();
        })
        .unwrap();
        node.define(c).unwrap();
        node.create("Kit", "K").unwrap();
        node.core_mut()
            .add_process("K", "Extra", ayllu::Trigger::OnWrite(sum), move |ctx| {
                let s = ctx.int(sum).unwrap_or(0);
                ctx.write(out, s.wrapping_mul(3) % 1000).unwrap();
            })
            .unwrap();
        nodes.push(node);
    }
    nodes[0]
        .connect(&Endpoint::local("K", "Out"), &Endpoint::node(NodeId(2), "K", "Sum"), ConnectionKind::Normal)
        .unwrap();
    nodes[1]
        .connect(&Endpoint::local("K", "Out"), &Endpoint::node(NodeId(1), "K", "Sum"), ConnectionKind::Normal)
        .unwrap();
    for k in 0..400u64 {
        clock.set(Instant::from_millis(k * 5));
        match k {
            50 => nodes[0]
                .core_mut()
                .trigger(Instant::from_millis(k * 5), "K", "Busy", Duration::from_millis(120))
                .unwrap(),
            80 => {
                let r = nodes[1].core().port("K", "Sum").unwrap();
                nodes[1].core_mut().reset(r).unwrap();
            }
            100 => nodes[0].join("G"),
            120 => nodes[0].leave("G"),
            140 => nodes[1].core_mut().set_access(ayllu::Access::default()),
            150 => nodes[1].core_mut().set_limits(ayllu::Limits::default()),
            160 => nodes[0].core_mut().warn("a warning".into()),
            170 => {
                nodes[0].core_mut().request(NodeId(2), ayllu::ControlBody::List).unwrap();
            }
            200 => {
                nodes[1].remove("K").unwrap();
                nodes[1].create("Kit", "K").unwrap();
            }
            250 => {
                let conn = nodes[0].core().report().connections[0].id;
                nodes[0].disconnect(conn).unwrap();
            }
            300 => drop(nodes[0].core_mut().node_lost(Instant::from_millis(k * 5), NodeId(2))),
            _ => {}
        }
        if k % 3 == 0 {
            nodes[k as usize % 2].write("K", "Sum", k as i64).unwrap();
        }
        for node in &mut nodes {
            node.step();
        }
    }
    for node in &mut nodes {
        node.stop_recording().unwrap();
    }
    for id in [1u32, 2] {
        let rec = Recording::open(d.join(format!("k{id}.mcap"))).unwrap();
        let kinds: std::collections::BTreeSet<String> = rec
            .entries
            .iter()
            .map(|e| format!("{:?}", e.event).split([' ', '(', '{']).next().unwrap().to_owned())
            .collect();
        let recorded = rec.entries.iter().filter(|e| matches!(e.event, Event::Accepted { .. })).count();
        let mut replay = Replay::new(&rec);
        replay.run_to_end().unwrap_or_else(|d| panic!("k{id}: {d} (kinds {kinds:?})"));
        assert_eq!(replay.checked(), recorded, "k{id}");
        for kind in [
            "Define",
            "Create",
            "AddProcess",
            "Connect",
            "Write",
            "Receive",
            "Poll",
            "Run",
            "ProcessWrite",
            "ProcessSetSlot",
            "ProcessTrigger",
            "ProcessReset",
            "Accepted",
        ] {
            assert!(kinds.contains(kind), "k{id} has no {kind}: {kinds:?}");
        }
        if id == 1 {
            for kind in ["Trigger", "Join", "Leave", "Warn", "Request", "Disconnect", "NodeLost"] {
                assert!(kinds.contains(kind), "k1 has no {kind}: {kinds:?}");
            }
        } else {
            for kind in ["Reset", "SetAccess", "SetLimits", "Remove"] {
                assert!(kinds.contains(kind), "k2 has no {kind}: {kinds:?}");
            }
        }
    }
}

/// A closed recording runs to the node's end: it sets no last known instant. The same file cut
/// short tells about the node only up to the last entry its replay applies
/// (`Recording::last_known`, spec/flight-recorder.md "Replay"), which is before the cut and
/// no later than what is left of the file. Each reader of one kind of recording knows the
/// other kind by its header: `replay` refuses a team recording naming it as such.
#[test]
fn a_cut_recording_knows_the_last_instant_it_tells_about() {
    let d = dir("cut-known");
    let path = d.join("whole.mcap");
    run_suppression(&path);
    let whole = Recording::open(&path).unwrap();
    assert_eq!(whole.ending, Ending::Closed);
    assert_eq!(whole.last_known(), None);
    let bytes = std::fs::read(&path).unwrap();
    assert!(ayllu::replay::is_flight_recording(&bytes));
    assert!(!ayllu::team_recording::is_team_recording(&bytes));

    // Cut inside its only chunk: nothing is left, and nothing after the start is known.
    let cut_path = d.join("cut.mcap");
    std::fs::write(&cut_path, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let cut = Recording::open(&cut_path).unwrap();
    assert!(matches!(cut.ending, Ending::Cut { .. }), "{:?}", cut.ending);
    assert_eq!(cut.last_known(), Some(Instant::ZERO), "{}", cut.entries.len());

    // A killed node's recording (tests/runtime/recording_malformed.rs).
    let cut_path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/malformed_recordings/killed.mcap");
    let cut = Recording::open(&cut_path).unwrap();
    assert!(matches!(cut.ending, Ending::Cut { .. }), "{:?}", cut.ending);
    assert!(!cut.entries.is_empty());
    let last = cut.last_known().expect("a cut recording says up to when it tells");
    assert!(last > Instant::ZERO && last <= cut.end(), "{last} {}", cut.end());
    // Every entry a replay applies is at or before it: the replay of the cut file, run to its
    // end, has not gone past it.
    let mut replay = Replay::new(&cut);
    replay.run_to_end().unwrap();
    assert!(replay.accepted().iter().all(|a| a.at <= last));

    // A team recording handed to the flight recording reader.
    let team = d.join("team.mcap");
    let mut file = std::fs::File::create(&team).unwrap();
    ayllu::team_recording::TeamWriter::new(&mut file).unwrap().finish().unwrap();
    drop(file);
    let team_bytes = std::fs::read(&team).unwrap();
    assert!(ayllu::team_recording::is_team_recording(&team_bytes));
    assert!(!ayllu::replay::is_flight_recording(&team_bytes));
    let err = Recording::open(&team).unwrap_err().to_string();
    assert!(err.contains("a team recording (made by `ayllu record`), not a flight recording"), "{err}");
    assert!(err.contains("`ayllu play`"), "{err}");
}
