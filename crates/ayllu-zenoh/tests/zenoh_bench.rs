//! Benchmark (issue 12): Ayllu over `zenoh://` beside Ayllu over `udp://` and raw UDP, measured
//! in the same run, printing a table with the ratios (docs/zenoh.md, "Measured"). A figure,
//! not a verdict: ignored by `make test-zenoh`; run it with `make bench-zenoh` (about 30 s).
//!
//! What is measured, as crates/ayllu/benches/network.rs measures `udp://` (two threads, one per
//! node or raw socket, on loopback; each node runs `Node::step` + `Node::wait`, as a robot
//! program would):
//! * Round trip: node A writes `A.P` (connected to B's `B.Q`); B's OnWrite process copies `Q`
//!   into `B.R`, connected back to `A.S`; A steps until `S` shows the value, then writes the
//!   next. Raw: an 8-byte payload bounced by a thread in blocking `recv_from`.
//! * One-way rate: A writes one port and steps (one message per datagram) for [`FLOW_TIME`];
//!   B counts what its port accepted. Raw: 8-byte datagrams sent as fast as `send_to` goes.
//!   Rate is what was received per second; loss what was sent and never received.
//!
//! Transports: raw UDP; `udp://`; `zenoh://` in peer mode (one TCP link between the two
//! nodes); `zenoh://` in client mode through a router (a router-mode session in this process,
//! so its threads share the machine's cores with both nodes). Runs of each alternate and
//! repeat ([`RUNS`]) so that drift of the machine hits all alike; figures are medians over
//! runs. Every loop is bounded in count and time.

use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::{BehaviorClass, ConnectionKind, Endpoint, Node, NodeId, PortSpec};

const RUNS: usize = 3;
const ROUNDS: usize = 3_000;
const WARM_UP: usize = 300;
const FLOW_TIME: StdDuration = StdDuration::from_secs(1);
/// A receiver stops this long after the sender stopped and nothing more arrived.
const DRAIN: StdDuration = StdDuration::from_millis(200);
/// Any single wait (a round trip, a greeting) gives up after this.
const PATIENCE: StdDuration = StdDuration::from_secs(10);

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Raw,
    Udp,
    ZenohPeer,
    ZenohRouter,
}

impl Kind {
    fn label(self) -> &'static str {
        match self {
            Kind::Raw => "raw UDP",
            Kind::Udp => "udp://",
            Kind::ZenohPeer => "zenoh:// peer (TCP link)",
            Kind::ZenohRouter => "zenoh:// client via router",
        }
    }
}

/// Two nodes of `kind`, having met; the router (if any) is kept alive by the caller.
fn pair(kind: Kind) -> (Node, Node, Option<ayllu_zenoh::Router>) {
    ayllu_zenoh::register();
    let (a, b, router) = match kind {
        Kind::Raw => unreachable!("raw UDP has no nodes"),
        Kind::Udp => {
            let a = Node::open(NodeId(1), "udp://127.0.0.1:0?hello_ms=200").expect("udp node");
            let b = Node::open(NodeId(2), &format!("udp://127.0.0.1:0?hello_ms=200&peer={}", a.address().unwrap()))
                .expect("udp node");
            (a, b, None)
        }
        Kind::ZenohPeer => {
            let a =
                Node::open(NodeId(1), "zenoh://?scouting=0&listen=tcp/127.0.0.1:0&hello_ms=200").expect("zenoh node");
            // Where a listens, as bound: the port the system chose.
            let at = a.address().expect("a listens");
            let b =
                Node::open(NodeId(2), &format!("zenoh://?scouting=0&connect={at}&hello_ms=200")).expect("zenoh node");
            (a, b, None)
        }
        Kind::ZenohRouter => {
            let router = ayllu_zenoh::Router::open(&ayllu_zenoh::RouterOptions {
                listen: vec!["tcp/127.0.0.1:0".into()],
                scouting: Some(false),
                ..Default::default()
            })
            .expect("router");
            let at = router.locators().expect("locators")[0].clone();
            let url = format!("zenoh://?mode=client&scouting=0&connect={at}&hello_ms=200");
            let a = Node::open(NodeId(1), &url).expect("zenoh client");
            let b = Node::open(NodeId(2), &url).expect("zenoh client");
            (a, b, Some(router))
        }
    };
    let (mut a, mut b) = (a, b);
    let give_up = StdInstant::now() + PATIENCE;
    while a.peers().is_empty() || b.peers().is_empty() {
        assert!(StdInstant::now() < give_up, "{}: the nodes did not meet", kind.label());
        a.run_for(StdDuration::from_millis(2));
        b.run_for(StdDuration::from_millis(2));
    }
    (a, b, router)
}

/// Run `node`'s step + wait loop on its own thread until `stop`.
fn spawn_loop(mut node: Node, stop: Arc<AtomicBool>) -> thread::JoinHandle<Node> {
    thread::spawn(move || {
        while !stop.load(Ordering::Acquire) {
            node.step();
            node.wait(StdDuration::from_millis(5));
        }
        node
    })
}

/// Round-trip times (ns) of `kind`.
fn round_trips(kind: Kind) -> Vec<u64> {
    let mut samples = Vec::with_capacity(ROUNDS);
    if kind == Kind::Raw {
        let a = UdpSocket::bind("127.0.0.1:0").unwrap();
        let b = UdpSocket::bind("127.0.0.1:0").unwrap();
        let (a_addr, b_addr) = (a.local_addr().unwrap(), b.local_addr().unwrap());
        a.set_read_timeout(Some(PATIENCE)).unwrap();
        b.set_read_timeout(Some(StdDuration::from_millis(200))).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let echo = thread::spawn(move || {
            let mut buf = [0u8; 64];
            while !s.load(Ordering::Acquire) {
                if let Ok((n, from)) = b.recv_from(&mut buf) {
                    let _ = b.send_to(&buf[..n], from);
                }
            }
        });
        let mut buf = [0u8; 64];
        for i in 0..(WARM_UP + ROUNDS) as u64 {
            let t0 = StdInstant::now();
            a.send_to(&i.to_le_bytes(), b_addr).unwrap();
            while a.recv_from(&mut buf).map(|(n, _)| buf[..n] != i.to_le_bytes()[..]).unwrap_or(false) {}
            if i >= WARM_UP as u64 {
                samples.push(t0.elapsed().as_nanos() as u64);
            }
        }
        let _ = a_addr;
        stop.store(true, Ordering::Release);
        echo.join().unwrap();
        return samples;
    }
    let (mut a, mut b, router) = pair(kind);
    let mut ping = BehaviorClass::new("Ping");
    ping.port(PortSpec::new("P", 0i64)).unwrap();
    ping.port(PortSpec::new("S", 0i64)).unwrap();
    a.define(ping).unwrap();
    a.create("Ping", "A").unwrap();
    let mut pong = BehaviorClass::new("Pong");
    let q = pong.port(PortSpec::new("Q", 0i64)).unwrap();
    let r = pong.port(PortSpec::new("R", 0i64)).unwrap();
    pong.on_write("Echo", q, move |ctx| {
        let v = ctx.int(q).unwrap_or(0);
        let _ = ctx.write(r, v);
    })
    .unwrap();
    b.define(pong).unwrap();
    b.create("Pong", "B").unwrap();
    a.connect(&Endpoint::local("A", "P"), &Endpoint::node(NodeId(2), "B", "Q"), ConnectionKind::Normal).unwrap();
    b.connect(&Endpoint::local("B", "R"), &Endpoint::node(NodeId(1), "A", "S"), ConnectionKind::Normal).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let echo = spawn_loop(b, stop.clone());
    for i in 1..=(WARM_UP + ROUNDS) as i64 {
        let t0 = StdInstant::now();
        let mut sent_at = t0;
        a.write("A", "P", i).unwrap();
        loop {
            a.step();
            if a.read("A", "S").ok().and_then(|v| v.as_int()) == Some(i) {
                break;
            }
            assert!(t0.elapsed() < PATIENCE, "{}: round trip {i} never came back", kind.label());
            // A lost datagram (congestion control Drop): ask again.
            if sent_at.elapsed() > StdDuration::from_millis(200) {
                a.write("A", "P", i).unwrap();
                sent_at = StdInstant::now();
            }
            a.wait(StdDuration::from_millis(5));
        }
        if i > WARM_UP as i64 {
            samples.push(t0.elapsed().as_nanos() as u64);
        }
    }
    stop.store(true, Ordering::Release);
    drop(echo.join().unwrap());
    drop(a);
    if let Some(router) = router {
        let _ = router.close();
    }
    samples
}

struct Flow {
    sent: u64,
    received: u64,
    secs: f64,
}

/// One-way rate of `kind` (one message per datagram).
fn one_way(kind: Kind) -> Flow {
    let done = Arc::new(AtomicBool::new(false));
    let start = StdInstant::now();
    if kind == Kind::Raw {
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = rx.local_addr().unwrap();
        rx.set_read_timeout(Some(DRAIN)).unwrap();
        let d = done.clone();
        let receiver = thread::spawn(move || {
            let (mut n, mut last, mut buf) = (0u64, start, [0u8; 64]);
            loop {
                match rx.recv_from(&mut buf) {
                    Ok(_) => {
                        n += 1;
                        last = StdInstant::now();
                    }
                    Err(_) if d.load(Ordering::Acquire) => break,
                    Err(_) => {}
                }
            }
            (n, last)
        });
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut sent = 0u64;
        while start.elapsed() < FLOW_TIME {
            if tx.send_to(&sent.to_le_bytes(), to).is_ok() {
                sent += 1;
            }
        }
        done.store(true, Ordering::Release);
        let (received, last) = receiver.join().unwrap();
        return Flow { sent, received, secs: (last - start).as_secs_f64() };
    }
    let (mut tx, mut rx, router) = pair(kind);
    let mut src = BehaviorClass::new("Src");
    src.port(PortSpec::new("P", 0i64)).unwrap();
    tx.define(src).unwrap();
    tx.create("Src", "S").unwrap();
    let mut dst = BehaviorClass::new("Dst");
    dst.port(PortSpec::new("P", 0i64)).unwrap();
    rx.define(dst).unwrap();
    rx.create("Dst", "D").unwrap();
    tx.connect(&Endpoint::local("S", "P"), &Endpoint::node(NodeId(2), "D", "P"), ConnectionKind::Normal).unwrap();
    let accepted = |rx: &Node| rx.why("D", "P").map(|r| r.accepted).unwrap_or(0);
    let before = accepted(&rx);
    let sent_before = tx.stats().sent;
    let d = done.clone();
    let start = StdInstant::now();
    let receiver = thread::spawn(move || {
        let mut last = start;
        let mut seen = accepted(&rx);
        let give_up = start + FLOW_TIME + PATIENCE;
        while StdInstant::now() < give_up {
            rx.step();
            let now_seen = accepted(&rx);
            if now_seen != seen {
                seen = now_seen;
                last = StdInstant::now();
            } else if d.load(Ordering::Acquire) && last.elapsed() >= DRAIN {
                break;
            }
            rx.wait(StdDuration::from_millis(5));
        }
        (rx, last)
    });
    let mut v = 0i64;
    while start.elapsed() < FLOW_TIME {
        v += 1;
        tx.write("S", "P", v).unwrap();
        tx.step();
    }
    done.store(true, Ordering::Release);
    let (rx, last) = receiver.join().unwrap();
    let flow = Flow {
        sent: tx.stats().sent - sent_before,
        received: accepted(&rx) - before,
        secs: (last - start).as_secs_f64(),
    };
    drop((tx, rx));
    if let Some(router) = router {
        let _ = router.close();
    }
    flow
}

fn quantile(sorted: &[u64], q: f64) -> f64 {
    sorted.get(((sorted.len() as f64 - 1.0) * q) as usize).copied().unwrap_or(0) as f64 / 1000.0
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
#[ignore]
fn zenoh_beside_udp_and_raw_udp() {
    let kinds = [Kind::Raw, Kind::Udp, Kind::ZenohPeer, Kind::ZenohRouter];
    // Per kind: medians over runs of the run's median, p90, p99 (us); rates (messages/s), loss.
    let mut rtt: Vec<Vec<[f64; 3]>> = vec![Vec::new(); kinds.len()];
    let mut rate: Vec<Vec<(f64, f64)>> = vec![Vec::new(); kinds.len()];
    for run in 0..RUNS {
        for (k, &kind) in kinds.iter().enumerate() {
            let mut s = round_trips(kind);
            s.sort_unstable();
            rtt[k].push([quantile(&s, 0.5), quantile(&s, 0.9), quantile(&s, 0.99)]);
            let f = one_way(kind);
            let loss = if f.sent == 0 { 0.0 } else { 1.0 - f.received as f64 / f.sent as f64 };
            rate[k].push((f.received as f64 / f.secs.max(1e-9), loss.max(0.0)));
            eprintln!(
                "run {}/{RUNS} {}: rtt median {:.1} us; one-way {} sent, {} received in {:.2} s",
                run + 1,
                kind.label(),
                rtt[k][run][0],
                f.sent,
                f.received,
                f.secs
            );
        }
    }
    let rtt: Vec<[f64; 3]> =
        rtt.iter().map(|runs| std::array::from_fn(|q| median(runs.iter().map(|r| r[q]).collect()))).collect();
    let rate: Vec<(f64, f64)> = rate
        .iter()
        .map(|runs| (median(runs.iter().map(|r| r.0).collect()), median(runs.iter().map(|r| r.1).collect())))
        .collect();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("\nAyllu over zenoh:// beside udp:// and raw UDP, loopback, medians of {RUNS} runs ({ROUNDS} round trips each; one-way {FLOW_TIME:?}); load average {}", load.split_whitespace().take(3).collect::<Vec<_>>().join(" "));
    println!("| Transport | RTT median | p90 | p99 | RTT / raw | RTT / udp:// | one-way rate | loss | rate / raw | rate / udp:// |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (k, kind) in kinds.iter().enumerate() {
        println!(
            "| {} | {:.1} us | {:.1} us | {:.1} us | {:.1}x | {:.2}x | {:.0}/s | {:.1} % | {:.2}x | {:.2}x |",
            kind.label(),
            rtt[k][0],
            rtt[k][1],
            rtt[k][2],
            rtt[k][0] / rtt[0][0],
            rtt[k][0] / rtt[1][0],
            rate[k].0,
            rate[k].1 * 100.0,
            rate[k].0 / rate[0].0,
            rate[k].0 / rate[1].0,
        );
    }
    for (k, kind) in kinds.iter().enumerate() {
        assert!(rate[k].0 > 0.0, "{}: nothing arrived", kind.label());
    }
}
