//! Network benchmarks: Ayllu nodes talking over `udp://` on loopback, each figure printed
//! beside a raw-UDP baseline written here and measured in the same run.
//!
//! Run with `cargo bench -p ayllu --bench network` (about 20 s once compiled; `-- rtt` or
//! `-- flow` runs one part). Two threads on 127.0.0.1, one per node (or per raw socket),
//! pinned to CPUs (see [`Placement`]: on a virtual machine, where the scheduler puts them
//! changes a round trip twentyfold); every phase is bounded in count and time. Raw and Ayllu
//! runs are paired, side by side, in an order that flips from one pair to the next, and
//! repeated ([`RTT_RUNS`], [`FLOW_RUNS`]): each ratio is the median over pairs of the pair's
//! own ratio, so that the machine's drift over seconds hits both sides of a ratio alike and
//! one disturbed run does not decide it. The table at the end gives each figure, its
//! baseline, the ratio, an interval holding the median ratio with about 95 % confidence, the
//! goal and the verdict: met or not met only when that interval lies on one side of the goal,
//! "within noise" otherwise; then the machine and its load average.
//!
//! What is measured:
//! * Round trip. Raw: one std `UdpSocket` per thread, blocking `recv_from`, an 8-byte
//!   payload bounced back by the other thread. Ayllu: node A writes its port `A.P` (Normal
//!   connection to node B's `B.Q`); B's OnWrite process on `Q` writes `B.R`, connected back
//!   to A's `A.S`; A steps and sleeps on its socket until `S` shows the value, then writes
//!   again. Both nodes run `Node::step` + `Node::wait` loops, as a robot program would. Also
//!   raw UDP making the system calls such a loop makes ([`RawStyle::NodeLoop`]): the floor
//!   for any node loop that sleeps in `poll`.
//! * One-way, one message per datagram. Raw: a sender blasting 8-byte datagrams for
//!   [`FLOW_TIME`]; Ayllu: a sender writing one port and stepping (which flushes: one
//!   datagram per message) for the same time. The receiver counts what arrives (Ayllu:
//!   what the port *accepted*); the rate is what was received per second, loss is what was
//!   sent and never received.
//! * Batching. The Ayllu sender writes [`BATCH_PORTS`] ports, each connected to a port of
//!   the receiver, then steps: one turn's messages share datagrams up to the MTU (rule N3).
//!   Counted as port messages accepted by the receiving node's ports per second, beside raw
//!   UDP sending datagrams of the same bytes ([`batched_datagram`]), each counted as the port
//!   messages Ayllu packs in one.
//! * Peers: `network peer raw|ayllu ping|pong|send|recv ...` is one process of a pair for
//!   `make bench-peers` (benches/peers/run), which sets the other systems beside these.
//!
//! `cargo bench -p ayllu --bench network -- callgrind` instead runs the round trip and the
//! batching path on one thread (one node's turn, then the other's, over real loopback
//! sockets) a fixed number of times, for `valgrind --tool=callgrind --toggle-collect=PATTERN`:
//! `*lockstep_round_trips*` counts the instructions of 10 000 round trips; `*sender_turn*`
//! and `*receiver_turn*` those of one side of 128 000 batched port messages (and
//! `*lockstep_turns*` both). `callgrind rtt` or `callgrind flow` runs only that part, and a
//! number among the arguments is the batches' MTU (`callgrind flow 8192`; default 1472)
//! (callgrind's call counts include calls made while collection is off: read instructions,
//! not calls, across parts). Timings on this kind of machine move by tens of percent between
//! runs; instruction counts do not.

#[path = "machine/mod.rs"]
mod machine;
use machine::machine;
#[path = "spread/mod.rs"]
mod spread;
use spread::{spread, Spread};

use std::hint::black_box;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::udp_config::DEFAULT_MTU;
use ayllu::{
    BehaviorClass, ConnectionKind, Endpoint, MonotonicClock, Node, NodeId, PortRef, PortSpec, UdpConfig, UdpTransport,
};

/// Round-trip pairs with both threads on one CPU: a raw run and an Ayllu run next to each
/// other (about 50 ms each), which goes first alternating between pairs. The figure is the
/// median over pairs of each pair's ratio: this host's speed drifts by tens of percent over
/// seconds, and a pair's two runs share the same moment of it, where whole runs seconds apart
/// do not (2026-11-29: single 20 000-round runs gave 0.95-1.44x within one benchmark).
const RTT_RUNS: usize = 31;
/// Round-trip runs with the threads on two CPUs, and round trips in each (they take ~75 us).
const RTT_TWO_CPU_RUNS: usize = 3;
const TWO_CPU_ROUNDS: usize = 5_000;
/// Throughput runs (about 3.5 s each: six flows, raw and Ayllu, in the opposite order from
/// one run to the next). Each ratio is the median over runs of the run's own ratio, for the
/// reason given at [`RTT_RUNS`].
const FLOW_RUNS: usize = 11;
/// Round trips measured per run, after the warm-up ones.
const ROUNDS: usize = 2_000;
const WARM_UP: usize = 500;
/// How long a sender sends in one throughput run.
const FLOW_TIME: StdDuration = StdDuration::from_millis(500);
/// How long a receiver waits after the sender stopped and nothing more arrives.
const DRAIN: StdDuration = StdDuration::from_millis(100);
/// Ports written per turn in the batching phase.
const BATCH_PORTS: usize = 64;
/// The loopback MTU used for the large-datagram batching figure (the largest datagram a
/// receiver accepts, spec/protocol.md).
const LOOPBACK_MTU: usize = 8192;
/// Socket buffers as `ayllu::datagram::OsSocket` sets them, so raw and Ayllu queue alike.
const SOCKET_BUFFER: usize = 1 << 21;

/// Round-trip goal: Ayllu at most this many times raw UDP.
const GOAL_RTT_RATIO: f64 = 1.2;
/// Batching goal: port messages per second at least this share of what raw UDP carries in
/// datagrams of the same bytes (each worth as many port messages as Ayllu packs in one),
/// measured in the same run.
const GOAL_BATCHED_RATIO: f64 = 0.8;

/// Where the two threads of a measurement run: `(first, second)` CPU. See [`Placement`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placement {
    /// Both on CPU 0: a round trip is two thread switches on one CPU.
    SameCpu,
    /// First on CPU 0, second on CPU 1. In a virtual machine a message then has to wake an
    /// idle virtual CPU, which the hypervisor does in tens of microseconds: that, not the
    /// software under test, is most of what a round trip measures.
    TwoCpus,
}

impl Placement {
    fn cpus(self) -> (usize, usize) {
        match self {
            Placement::SameCpu => (0, 0),
            Placement::TwoCpus => (0, 1),
        }
    }
}

/// The machine's CPUs, counted before any thread is pinned (the count follows the affinity).
fn cpu_count() -> usize {
    static CPUS: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CPUS.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// Run the calling thread on `cpu` only, so that where the scheduler happens to put the two
/// threads (same CPU or not) does not decide the figures: on this kind of machine it changes
/// a loopback round trip from about 4 to about 75 microseconds.
fn pin(cpu: usize) {
    #[cfg(target_os = "linux")]
    {
        let cpus = cpu_count();
        // SAFETY: `set` is a plain bit set, initialised by CPU_ZERO before use; pid 0 is the
        // calling thread, and the size passed is that of the set.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_ZERO(&mut set);
            libc::CPU_SET(cpu % cpus, &mut set);
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = cpu;
}

// ----- raw UDP ------------------------------------------------------------------------------

/// A blocking std socket on loopback with the same buffer sizes Ayllu's sockets ask for.
fn raw_socket() -> UdpSocket {
    use socket2::{Domain, Protocol, Socket, Type};
    let s = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).expect("socket");
    let _ = s.set_recv_buffer_size(SOCKET_BUFFER);
    let _ = s.set_send_buffer_size(SOCKET_BUFFER);
    s.bind(&"127.0.0.1:0".parse::<SocketAddr>().expect("address").into()).expect("bind");
    s.into()
}

/// How a raw-UDP round trip waits for its answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RawStyle {
    /// The baseline: one blocking `recv_from`.
    Blocking,
    /// The system calls a node's loop made before its wait became the receive: a
    /// non-blocking socket, a receive attempt before each send (the turn's receive), then
    /// poll + receive. The floor for a loop that polls and then receives (docs/performance.md).
    NodeLoop,
}

/// Block until `socket` is readable or `timeout` passes, as `ayllu::datagram::OsSocket` does.
fn wait_readable(socket: &UdpSocket, timeout: StdDuration) {
    use std::os::fd::AsRawFd;
    let mut fd = libc::pollfd { fd: socket.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    // SAFETY: one valid pollfd for a socket we own; (p)poll only writes `revents`.
    #[cfg(target_os = "linux")]
    unsafe {
        let ts = libc::timespec { tv_sec: timeout.as_secs() as libc::time_t, tv_nsec: timeout.subsec_nanos() as _ };
        libc::ppoll(&mut fd, 1, &ts, std::ptr::null());
    }
    #[cfg(not(target_os = "linux"))]
    unsafe {
        libc::poll(&mut fd, 1, timeout.as_millis() as libc::c_int);
    }
}

/// Round-trip times (ns) of `rounds` 8-byte ping-pongs after `WARM_UP` unmeasured ones.
fn raw_round_trips(rounds: usize, place: Placement, style: RawStyle) -> Vec<u64> {
    let (cpu_a, cpu_b) = place.cpus();
    pin(cpu_a);
    let (a, b) = (raw_socket(), raw_socket());
    let b_addr = b.local_addr().expect("addr");
    let polled = style == RawStyle::NodeLoop;
    for s in [&a, &b] {
        s.set_read_timeout(Some(StdDuration::from_secs(2))).expect("timeout");
        s.set_nonblocking(polled).expect("non-blocking");
    }
    let total = WARM_UP + rounds;
    let echo = thread::spawn(move || {
        pin(cpu_b);
        let mut buf = [0u8; 64];
        let (mut echoed, give_up) = (0, StdInstant::now() + StdDuration::from_secs(60));
        while echoed < total && StdInstant::now() < give_up {
            if polled {
                wait_readable(&b, StdDuration::from_millis(10));
            }
            match b.recv_from(&mut buf) {
                Ok((n, from)) => {
                    b.send_to(&buf[..n], from).expect("echo");
                    echoed += 1;
                }
                Err(_) if polled => {}
                Err(_) => return,
            }
        }
    });
    let mut samples = Vec::with_capacity(rounds);
    let mut buf = [0u8; 64];
    for i in 0..total as u64 {
        let t0 = StdInstant::now();
        if polled {
            let _ = a.recv_from(&mut buf); // the turn's receive: nothing is waiting
        }
        a.send_to(&i.to_le_bytes(), b_addr).expect("ping");
        let n = loop {
            if polled {
                wait_readable(&a, StdDuration::from_millis(10));
            }
            match a.recv_from(&mut buf) {
                Ok((n, _)) => break n,
                Err(_) if polled && t0.elapsed() < StdDuration::from_secs(2) => {}
                Err(e) => panic!("no pong within 2 s on loopback: {e}"),
            }
        };
        let dt = t0.elapsed();
        assert_eq!(&buf[..n], &i.to_le_bytes());
        if i >= WARM_UP as u64 {
            samples.push(dt.as_nanos() as u64);
        }
    }
    echo.join().expect("echo thread");
    samples
}

/// Messages sent and received in one throughput run, and over how long.
#[derive(Clone, Copy, Debug, Default)]
struct Flow {
    sent: u64,
    received: u64,
    /// From the sender's start to the last message received.
    secs: f64,
    datagrams: u64,
}

impl Flow {
    fn rate(&self) -> f64 {
        self.received as f64 / self.secs.max(1e-9)
    }
    fn loss(&self) -> f64 {
        1.0 - self.received as f64 / (self.sent.max(1)) as f64
    }
}

/// A raw sender blasting `size`-byte datagrams for `FLOW_TIME` at a blocking receiver.
fn raw_one_way(size: usize) -> Flow {
    pin(0);
    let (tx, rx) = (raw_socket(), raw_socket());
    let to = rx.local_addr().expect("addr");
    rx.set_read_timeout(Some(DRAIN)).expect("timeout");
    let done = Arc::new(AtomicBool::new(false));
    let start = StdInstant::now();
    let receiver = {
        let done = done.clone();
        thread::spawn(move || {
            pin(1);
            let mut buf = [0u8; 64];
            let (mut received, mut last) = (0u64, start);
            loop {
                match rx.recv_from(&mut buf) {
                    Ok(_) => {
                        received += 1;
                        last = StdInstant::now();
                    }
                    Err(_) if done.load(Ordering::Acquire) => break,
                    Err(_) => {}
                }
            }
            (received, last)
        })
    };
    let mut sent = 0u64;
    let mut payload = vec![0u8; size.max(8)];
    loop {
        // The clock is read once per 64 sends so that the baseline is the socket alone.
        for _ in 0..64 {
            payload[..8].copy_from_slice(&sent.to_le_bytes());
            if tx.send_to(&payload, to).is_ok() {
                sent += 1;
            }
        }
        if start.elapsed() >= FLOW_TIME {
            break;
        }
    }
    done.store(true, Ordering::Release);
    let (received, last) = receiver.join().expect("receiver");
    Flow { sent, received, secs: (last - start).as_secs_f64(), datagrams: received }
}

// ----- Ayllu --------------------------------------------------------------------------------

/// A node on a fresh loopback port; `peer` is where it announces itself first.
fn udp_node(id: u32, mtu: usize, peer: Option<SocketAddr>) -> (Node, SocketAddr) {
    let mut config = UdpConfig::new("127.0.0.1:0".parse().expect("address"));
    config.mtu = mtu;
    config.peers.extend(peer);
    let transport = UdpTransport::bind(NodeId(id), config).expect("bind loopback");
    let addr = transport.local_addr().expect("bound address");
    (Node::new(MonotonicClock::new(), transport), addr)
}

/// Step both nodes until each knows the other (HELLO, rule N6).
fn meet(a: &mut Node, b: &mut Node) {
    let give_up = StdInstant::now() + StdDuration::from_secs(5);
    while a.peers().is_empty() || b.peers().is_empty() {
        assert!(StdInstant::now() < give_up, "the two nodes did not hear each other's HELLO");
        a.step();
        b.step();
        thread::sleep(StdDuration::from_millis(1));
    }
}

/// How long a node loop may sleep: until its next deadline, at most `cap`.
fn sleep_for(node: &Node, next: Option<ayllu::Instant>, cap: StdDuration) -> StdDuration {
    let now = node.now();
    next.map_or(
        cap,
        |n| if n > now { StdDuration::from_nanos((n - now).as_nanos()).min(cap) } else { StdDuration::ZERO },
    )
}

/// Run `node` in a step + wait loop on its own thread until `stop` is set; returns it.
fn spawn_loop(mut node: Node, stop: Arc<AtomicBool>, cpu: usize) -> thread::JoinHandle<Node> {
    thread::spawn(move || {
        pin(cpu);
        while !stop.load(Ordering::Acquire) {
            let next = node.step();
            let t = sleep_for(&node, next, StdDuration::from_secs(1));
            node.wait(t);
        }
        node
    })
}

fn int_port(name: &str) -> PortSpec {
    PortSpec::new(name, 0i64)
}

/// The two nodes of the round trip (see the module docs), having met; `A.P` and `A.S`.
fn ping_pair() -> (Node, Node, PortRef, PortRef) {
    let (mut b, b_addr) = udp_node(2, DEFAULT_MTU, None);
    let (mut a, _) = udp_node(1, DEFAULT_MTU, Some(b_addr));
    let mut ping = BehaviorClass::new("Ping");
    ping.port(int_port("P")).expect("port");
    ping.port(int_port("S")).expect("port");
    a.define(ping).expect("class");
    a.create("Ping", "A").expect("behavior");
    let mut pong = BehaviorClass::new("Pong");
    let q = pong.port(int_port("Q")).expect("port");
    let r = pong.port(int_port("R")).expect("port");
    pong.on_write("Echo", q, move |ctx| {
        let v = ctx.int(q).unwrap_or(0);
        let _ = ctx.write(r, v);
    })
    .expect("process");
    b.define(pong).expect("class");
    b.create("Pong", "B").expect("behavior");
    let normal = ConnectionKind::Normal;
    a.connect(&Endpoint::local("A", "P"), &Endpoint::node(NodeId(2), "B", "Q"), normal).expect("connect");
    b.connect(&Endpoint::local("B", "R"), &Endpoint::node(NodeId(1), "A", "S"), normal).expect("connect");
    meet(&mut a, &mut b);
    let p = a.core().port("A", "P").expect("port");
    let s = a.core().port("A", "S").expect("port");
    (a, b, p, s)
}

/// Round-trip times (ns): see the module docs.
fn ayllu_round_trips(rounds: usize, place: Placement) -> Vec<u64> {
    let (cpu_a, cpu_b) = place.cpus();
    pin(cpu_a);
    let (mut a, b, p, s) = ping_pair();
    let stop = Arc::new(AtomicBool::new(false));
    let echo = spawn_loop(b, stop.clone(), cpu_b);
    let mut samples = Vec::with_capacity(rounds);
    for i in 1..=(WARM_UP + rounds) as i64 {
        let t0 = StdInstant::now();
        let mut sent_at = t0;
        let core = a.core_mut(); // told the present
        let now = core.now();
        core.write(now, p, i).expect("write");
        loop {
            let next = a.step();
            if a.core().read(s).ok().and_then(|v| v.as_int()) == Some(i) {
                break;
            }
            // Loopback does not lose datagrams in practice; if one is lost, ask again.
            if sent_at.elapsed() > StdDuration::from_millis(200) {
                let core = a.core_mut(); // told the present
                let now = core.now();
                core.write(now, p, i).expect("write");
                sent_at = StdInstant::now();
                continue;
            }
            let t = sleep_for(&a, next, StdDuration::from_secs(1));
            a.wait(t);
        }
        let dt = t0.elapsed();
        if i > WARM_UP as i64 {
            samples.push(dt.as_nanos() as u64);
        }
    }
    stop.store(true, Ordering::Release);
    echo.join().expect("echo node");
    samples
}

/// A sender node whose behavior `S` has `ports` ports, each connected to the same-named port
/// of the receiver's behavior `D`; the sender steps after every `per_turn` writes.
fn ayllu_flow(ports: usize, mtu: usize) -> Flow {
    pin(0);
    let (mut tx, mut rx, handles) = batch_pair(ports, mtu);
    let sent_before = tx.stats().sent;
    let datagrams_before = counter(&tx, "datagrams_sent");

    let done = Arc::new(AtomicBool::new(false));
    let start = StdInstant::now();
    let receiver = {
        let done = done.clone();
        thread::spawn(move || {
            pin(1);
            let mut last = start;
            let mut seen = rx.stats().received;
            loop {
                let next = rx.step();
                let received = rx.stats().received;
                if received != seen {
                    seen = received;
                    last = StdInstant::now();
                } else if done.load(Ordering::Acquire) && last.elapsed() >= DRAIN {
                    // Loopback delivers into our socket buffer during the send, so once the
                    // sender stopped, a quiet DRAIN means everything has been read.
                    break;
                }
                let t = sleep_for(&rx, next, StdDuration::from_secs(1));
                rx.wait(t);
            }
            (rx, last)
        })
    };
    let mut v = 0i64;
    while start.elapsed() < FLOW_TIME {
        v += 1;
        let core = tx.core_mut(); // told the present
        let now = core.now();
        for &h in &handles {
            core.write(now, h, v).expect("write");
        }
        black_box(tx.step());
    }
    done.store(true, Ordering::Release);
    let (rx, last) = receiver.join().expect("receiver node");
    let received: u64 = (0..ports).map(|i| rx.why("D", &format!("p{i:02}")).expect("port").accepted).sum();
    Flow {
        sent: tx.stats().sent - sent_before,
        received,
        secs: (last - start).as_secs_f64(),
        datagrams: counter(&tx, "datagrams_sent") - datagrams_before,
    }
}

/// Sender and receiver of the batching phase, ready to run on one thread.
fn batch_pair(ports: usize, mtu: usize) -> (Node, Node, Vec<PortRef>) {
    let (mut rx, rx_addr) = udp_node(2, mtu, None);
    let (mut tx, _) = udp_node(1, mtu, Some(rx_addr));
    let names: Vec<String> = (0..ports).map(|i| format!("p{i:02}")).collect();
    let mut src = BehaviorClass::new("Src");
    let mut dst = BehaviorClass::new("Dst");
    for n in &names {
        src.port(int_port(n)).expect("port");
        dst.port(int_port(n)).expect("port");
    }
    tx.define(src).expect("class");
    tx.create("Src", "S").expect("behavior");
    rx.define(dst).expect("class");
    rx.create("Dst", "D").expect("behavior");
    for n in &names {
        tx.connect(&Endpoint::local("S", n), &Endpoint::node(NodeId(2), "D", n), ConnectionKind::Normal)
            .expect("connect");
    }
    meet(&mut tx, &mut rx);
    let handles = names.iter().map(|n| tx.core().port("S", n).expect("port")).collect();
    (tx, rx, handles)
}

/// `turns` sender turns, each followed by a receiver turn.
#[inline(never)]
fn lockstep_turns(tx: &mut Node, rx: &mut Node, handles: &[PortRef], turns: i64) {
    for v in 1..=turns {
        sender_turn(tx, handles, v);
        receiver_turn(rx);
    }
}

/// Write every port, then step (which sends). Separate so callgrind can count each side.
#[inline(never)]
fn sender_turn(tx: &mut Node, handles: &[PortRef], v: i64) {
    let core = tx.core_mut(); // told the present
    let now = core.now();
    for &h in handles {
        core.write(now, h, v).expect("write");
    }
    tx.step();
}

#[inline(never)]
fn receiver_turn(rx: &mut Node) {
    rx.step();
}

/// `rounds` round trips on one thread: A writes and steps, B steps, A steps (and reads).
#[inline(never)]
fn lockstep_round_trips(a: &mut Node, b: &mut Node, p: PortRef, s: PortRef, rounds: i64) {
    for i in 1..=rounds {
        let core = a.core_mut(); // told the present
        let now = core.now();
        core.write(now, p, i).expect("write");
        a.step();
        while a.core().read(s).ok().and_then(|v| v.as_int()) != Some(i) {
            b.step();
            a.step();
        }
    }
}

/// The single-threaded runs for callgrind (see the module docs).
fn callgrind_mode(rtt: bool, flow: bool, mtu: usize) {
    if rtt {
        callgrind_round_trips();
    }
    if flow {
        callgrind_batches(mtu);
    }
}

fn callgrind_round_trips() {
    const ROUND_TRIPS: i64 = 10_000;
    let (mut a, mut b, p, s) = ping_pair();
    lockstep_round_trips(&mut a, &mut b, p, s, ROUND_TRIPS);
    println!(
        "callgrind mode: {ROUND_TRIPS} round trips ({} steps of A, {} of B; messages sent {} by A, {} by B; \
         datagrams sent {} by A, {} by B)",
        a.stats().steps,
        b.stats().steps,
        a.stats().sent,
        b.stats().sent,
        counter(&a, "datagrams_sent"),
        counter(&b, "datagrams_sent")
    );
    println!("instructions per round trip = Ir of lockstep_round_trips / {ROUND_TRIPS}");
}

fn callgrind_batches(mtu: usize) {
    const TURNS: i64 = 2_000;
    let (mut tx, mut rx, handles) = batch_pair(BATCH_PORTS, mtu);
    lockstep_turns(&mut tx, &mut rx, &handles, TURNS);
    let accepted: u64 = (0..BATCH_PORTS).map(|i| rx.why("D", &format!("p{i:02}")).expect("port").accepted).sum();
    let sent = tx.stats().sent;
    println!(
        "callgrind mode: {TURNS} turns of {BATCH_PORTS} ports at MTU {mtu}: {sent} port messages sent, {accepted} accepted"
    );
    println!("instructions per port message = Ir of lockstep_turns / {accepted}");
}

fn counter(node: &Node, name: &str) -> u64 {
    node.transport_counters().iter().find(|(c, _)| c == name).map_or(0, |(_, n)| *n)
}

// ----- peers: one process of a pair, for `make bench-peers` ---------------------------------

/// `network peer SYSTEM ROLE ADDR PAYLOAD AMOUNT`: one process of the two that
/// `benches/peers/run` starts for raw UDP (`raw`) and Ayllu (`ayllu`), speaking the same
/// lines as the other peers' programs. `pong` and `recv` bind `ADDR`; `ping` and `send` send
/// to it. `AMOUNT` is round trips (ping, pong) or seconds of sending (send). Ayllu carries
/// the payload as one port value: an `i64` for 8 bytes, else bytes of that length.
fn peer_mode(args: &[String]) {
    let [system, role, addr, payload, amount] = args else {
        eprintln!("usage: network peer raw|ayllu ping|pong|send|recv ADDR PAYLOAD_BYTES AMOUNT");
        std::process::exit(2);
    };
    let addr: SocketAddr = addr.parse().expect("ADDR as 127.0.0.1:PORT");
    let size: usize = payload.parse().expect("payload bytes");
    let amount: f64 = amount.parse().expect("amount");
    match (system.as_str(), role.as_str()) {
        ("raw", "pong") => raw_peer_pong(addr, amount as usize),
        ("raw", "ping") => print_rtt(&raw_peer_ping(addr, size, amount as usize)),
        ("raw", "send") => raw_peer_send(addr, size, amount),
        ("raw", "recv") => raw_peer_recv(addr),
        ("ayllu", "pong") => ayllu_peer_pong(addr, size, amount as usize),
        ("ayllu", "ping") => print_rtt(&ayllu_peer_ping(addr, size, amount as usize)),
        ("ayllu", "send") => ayllu_peer_send(addr, size, amount),
        ("ayllu", "recv") => ayllu_peer_recv(addr, size),
        _ => panic!("unknown peer {system} {role}"),
    }
}

fn print_rtt(ns: &[u64]) {
    let text: Vec<String> = ns.iter().map(|n| n.to_string()).collect();
    println!("rtt_ns {}", text.join(" "));
}

fn bound_raw(addr: SocketAddr) -> UdpSocket {
    use socket2::{Domain, Protocol, Socket, Type};
    let s = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).expect("socket");
    let _ = s.set_recv_buffer_size(SOCKET_BUFFER);
    let _ = s.set_send_buffer_size(SOCKET_BUFFER);
    s.bind(&addr.into()).expect("bind");
    s.into()
}

fn raw_peer_pong(addr: SocketAddr, rounds: usize) {
    let s = bound_raw(addr);
    s.set_read_timeout(Some(StdDuration::from_secs(5))).expect("timeout");
    let mut buf = [0u8; 2048];
    for _ in 0..rounds {
        let Ok((n, from)) = s.recv_from(&mut buf) else { return };
        s.send_to(&buf[..n], from).expect("echo");
    }
}

fn raw_peer_ping(to: SocketAddr, size: usize, rounds: usize) -> Vec<u64> {
    let s = raw_socket();
    s.set_read_timeout(Some(StdDuration::from_millis(200))).expect("timeout");
    let (mut out, mut buf, mut samples) = (vec![0u8; size.max(8)], [0u8; 2048], Vec::with_capacity(rounds));
    let give_up = StdInstant::now() + StdDuration::from_secs(120);
    let mut i = 0u64;
    while samples.len() < rounds && StdInstant::now() < give_up {
        i += 1;
        out[..8].copy_from_slice(&i.to_le_bytes());
        let t0 = StdInstant::now();
        s.send_to(&out[..size.max(8)], to).expect("ping");
        // A lost ping (the pong not started yet) is sent again as the next round.
        while let Ok(n) = s.recv(&mut buf) {
            if n >= 8 && buf[..8] == i.to_le_bytes() {
                samples.push(t0.elapsed().as_nanos() as u64);
                break;
            }
        }
    }
    samples
}

fn raw_peer_send(to: SocketAddr, size: usize, secs: f64) {
    let s = raw_socket();
    let out = vec![7u8; size];
    let (start, mut sent) = (StdInstant::now(), 0u64);
    while start.elapsed().as_secs_f64() < secs {
        for _ in 0..64 {
            if s.send_to(&out, to).is_ok() {
                sent += 1;
            }
        }
    }
    println!("flow sent={sent}");
}

/// Count datagrams until 300 ms pass without one (30 s before the first).
fn raw_peer_recv(addr: SocketAddr) {
    let s = bound_raw(addr);
    let mut buf = [0u8; 2048];
    println!("ready");
    s.set_read_timeout(Some(StdDuration::from_secs(30))).expect("timeout");
    if s.recv_from(&mut buf).is_err() {
        println!("flow received=0 secs=0");
        return;
    }
    let (first, mut last, mut received) = (StdInstant::now(), StdInstant::now(), 1u64);
    s.set_read_timeout(Some(StdDuration::from_millis(300))).expect("timeout");
    while s.recv_from(&mut buf).is_ok() {
        received += 1;
        last = StdInstant::now();
    }
    println!("flow received={received} secs={:.6}", (last - first).as_secs_f64());
}

/// The payload as a port value carrying round `i` (see [`peer_mode`]).
fn peer_value(size: usize, i: i64) -> ayllu::Value {
    if size == 8 {
        ayllu::Value::Int(i)
    } else {
        let mut b = vec![7u8; size.max(8)];
        b[..8].copy_from_slice(&i.to_le_bytes());
        ayllu::Value::Bytes(b.into())
    }
}

fn peer_round(v: &ayllu::Value) -> Option<i64> {
    match v {
        ayllu::Value::Int(i) => Some(*i),
        ayllu::Value::Bytes(b) if b.len() >= 8 => Some(i64::from_le_bytes(b[..8].try_into().ok()?)),
        _ => None,
    }
}

fn peer_port(name: &str, size: usize) -> PortSpec {
    PortSpec::new(name, peer_value(size, 0))
}

/// A node on `bind`, announcing itself to `peer`.
fn peer_node(id: u32, bind: SocketAddr, peer: Option<SocketAddr>) -> Node {
    let mut config = UdpConfig::new(bind);
    config.peers.extend(peer);
    Node::new(MonotonicClock::new(), UdpTransport::bind(NodeId(id), config).expect("bind"))
}

/// Node 2, behavior `B` (class Pong: `Q` echoed to `R` by an OnWrite process, `R` connected
/// to node 1's `A.S`), in a step + wait loop until it has echoed `rounds` or heard nothing for 5 s.
fn ayllu_peer_pong(addr: SocketAddr, size: usize, rounds: usize) {
    let mut b = peer_node(2, addr, None);
    let mut pong = BehaviorClass::new("Pong");
    let q = pong.port(peer_port("Q", size)).expect("port");
    let r = pong.port(peer_port("R", size)).expect("port");
    let echoed = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let count = echoed.clone();
    pong.on_write("Echo", q, move |ctx| {
        let v = ctx.read(q);
        let _ = ctx.write(r, v);
        count.fetch_add(1, Ordering::Relaxed);
    })
    .expect("process");
    b.define(pong).expect("class");
    b.create("Pong", "B").expect("behavior");
    b.connect(&Endpoint::local("B", "R"), &Endpoint::node(NodeId(1), "A", "S"), ConnectionKind::Normal)
        .expect("connect");
    let (mut last, mut seen) = (StdInstant::now(), 0);
    let give_up = StdInstant::now() + StdDuration::from_secs(120);
    while last.elapsed() < StdDuration::from_secs(5) && StdInstant::now() < give_up {
        let next = b.step();
        let now_echoed = echoed.load(Ordering::Relaxed);
        if now_echoed != seen {
            seen = now_echoed;
            last = StdInstant::now();
            if seen >= rounds {
                // The last echo has left with this step.
                break;
            }
        }
        let t = sleep_for(&b, next, StdDuration::from_secs(1));
        b.wait(t);
    }
}

/// Node 1, behavior `A` (class Ping: `P` connected to node 2's `B.Q`; `S` hears the echo).
fn ayllu_peer_ping(to: SocketAddr, size: usize, rounds: usize) -> Vec<u64> {
    let mut a = peer_node(1, "127.0.0.1:0".parse().expect("address"), Some(to));
    let mut ping = BehaviorClass::new("Ping");
    ping.port(peer_port("P", size)).expect("port");
    ping.port(peer_port("S", size)).expect("port");
    a.define(ping).expect("class");
    a.create("Ping", "A").expect("behavior");
    a.connect(&Endpoint::local("A", "P"), &Endpoint::node(NodeId(2), "B", "Q"), ConnectionKind::Normal)
        .expect("connect");
    let (p, s) = (a.core().port("A", "P").expect("port"), a.core().port("A", "S").expect("port"));
    let mut samples = Vec::with_capacity(rounds);
    let give_up = StdInstant::now() + StdDuration::from_secs(120);
    let mut i = 0i64;
    'rounds: while samples.len() < rounds && StdInstant::now() < give_up {
        i += 1;
        let t0 = StdInstant::now();
        let core = a.core_mut(); // told the present
        let now = core.now();
        core.write(now, p, peer_value(size, i)).expect("write");
        loop {
            let next = a.step();
            if a.core().read(s).ok().as_ref().and_then(peer_round) == Some(i) {
                samples.push(t0.elapsed().as_nanos() as u64);
                continue 'rounds;
            }
            // Lost (the pong not started, or not met yet): the next round writes again.
            if t0.elapsed() > StdDuration::from_millis(200) {
                continue 'rounds;
            }
            let t = sleep_for(&a, next, StdDuration::from_secs(1));
            a.wait(t);
        }
    }
    samples
}

fn ayllu_peer_send(to: SocketAddr, size: usize, secs: f64) {
    let mut tx = peer_node(1, "127.0.0.1:0".parse().expect("address"), Some(to));
    let mut src = BehaviorClass::new("Src");
    src.port(peer_port("p", size)).expect("port");
    tx.define(src).expect("class");
    tx.create("Src", "S").expect("behavior");
    tx.connect(&Endpoint::local("S", "p"), &Endpoint::node(NodeId(2), "D", "p"), ConnectionKind::Normal)
        .expect("connect");
    let h = tx.core().port("S", "p").expect("port");
    // Meet the receiver first: until then messages are held, not sent (a bounded wait).
    let met_by = StdInstant::now() + StdDuration::from_secs(10);
    while tx.peers().is_empty() && StdInstant::now() < met_by {
        tx.step();
        tx.wait(StdDuration::from_millis(5));
    }
    let sent_before = tx.stats().sent;
    let (start, mut v) = (StdInstant::now(), 0i64);
    while start.elapsed().as_secs_f64() < secs {
        v += 1;
        let core = tx.core_mut(); // told the present
        let now = core.now();
        core.write(now, h, peer_value(size, v)).expect("write");
        tx.step();
    }
    println!("flow sent={}", tx.stats().sent - sent_before);
}

fn ayllu_peer_recv(addr: SocketAddr, size: usize) {
    let mut rx = peer_node(2, addr, None);
    let mut dst = BehaviorClass::new("Dst");
    dst.port(peer_port("p", size)).expect("port");
    rx.define(dst).expect("class");
    rx.create("Dst", "D").expect("behavior");
    let (mut received, mut first, mut last) = (0u64, None, StdInstant::now());
    let began = StdInstant::now();
    println!("ready");
    loop {
        let next = rx.step();
        let accepted = rx.stats().received;
        if accepted != received {
            let now = StdInstant::now();
            first.get_or_insert(now);
            received = accepted;
            last = now;
        }
        let quiet = if received == 0 { StdDuration::from_secs(30) } else { StdDuration::from_millis(300) };
        if last.max(began).elapsed() >= quiet {
            break;
        }
        let t = sleep_for(&rx, next, StdDuration::from_millis(100));
        rx.wait(t);
    }
    let secs = first.map_or(0.0, |f| (last - f).as_secs_f64());
    // What the port accepted (a message older than the last one accepted is dropped, N1).
    let accepted = rx.why("D", "p").map_or(received, |r| r.accepted);
    println!("flow received={accepted} secs={secs:.6}");
}

// ----- figures ------------------------------------------------------------------------------

struct Latency {
    median: f64,
    mean: f64,
    p99: f64,
}

fn latency(mut ns: Vec<u64>) -> Latency {
    ns.sort_unstable();
    let at = |q: f64| ns[((ns.len() - 1) as f64 * q).round() as usize] as f64 / 1000.0;
    let mean = ns.iter().sum::<u64>() as f64 / ns.len() as f64 / 1000.0;
    Latency { median: at(0.5), mean, p99: at(0.99) }
}

/// The run with the median receive rate.
fn median_flow(mut runs: Vec<Flow>) -> Flow {
    runs.sort_by(|x, y| x.rate().total_cmp(&y.rate()));
    runs[runs.len() / 2]
}

/// The load average, so a reader can tell a quiet run from one sharing the CPUs.
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_owned())
}

fn mps(x: f64) -> String {
    format!("{:.3} M/s", x / 1e6)
}

/// Round-trip figures of one side over all runs: the median of the runs' medians (and so on),
/// so that a run disturbed by another process on the machine does not decide the figure.
fn across_runs(runs: &[Latency]) -> Latency {
    let mid = |f: fn(&Latency) -> f64| {
        let mut v: Vec<f64> = runs.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    Latency { median: mid(|l| l.median), mean: mid(|l| l.mean), p99: mid(|l| l.p99) }
}

/// Round-trip figures of one placement: Ayllu, the raw baseline, and raw UDP making a node
/// loop's system calls (each the median over runs of the run's statistic), and each pair's
/// ratios of medians (Ayllu ÷ raw, node loop ÷ raw).
struct RoundTrips {
    ayllu: Latency,
    raw: Latency,
    raw_node_loop: Latency,
    ratios: Spread,
    node_loop_ratios: Spread,
}

/// `runs` pairs of raw and Ayllu round-trip runs with the threads placed as `place` says
/// (plus raw UDP with a node loop's system calls), each pair's order the other way round from
/// the pair before, so that drift within a pair does not favour either side.
fn round_trip_phase(place: Placement, runs: usize, rounds: usize) -> RoundTrips {
    let (mut raw_runs, mut loop_runs, mut ayllu_runs) = (Vec::new(), Vec::new(), Vec::new());
    let (mut ratios, mut loop_ratios) = (Vec::new(), Vec::new());
    for run in 1..=runs {
        let raw_first = run % 2 == 1;
        let first = if raw_first {
            latency(raw_round_trips(rounds, place, RawStyle::Blocking))
        } else {
            latency(ayllu_round_trips(rounds, place))
        };
        let polled = latency(raw_round_trips(rounds, place, RawStyle::NodeLoop));
        let second = if raw_first {
            latency(ayllu_round_trips(rounds, place))
        } else {
            latency(raw_round_trips(rounds, place, RawStyle::Blocking))
        };
        let (raw, ayl) = if raw_first { (first, second) } else { (second, first) };
        println!(
            "round trip {place:?} pair {run:>2} ({}): raw median {:.2} us (p99 {:.2}), ayllu {:.2} us (p99 {:.2}): \
             {:.2}x; raw with a node loop's system calls {:.2} us: {:.2}x",
            if raw_first { "raw first" } else { "ayllu first" },
            raw.median,
            raw.p99,
            ayl.median,
            ayl.p99,
            ayl.median / raw.median,
            polled.median,
            polled.median / raw.median
        );
        ratios.push(ayl.median / raw.median);
        loop_ratios.push(polled.median / raw.median);
        raw_runs.push(raw);
        loop_runs.push(polled);
        ayllu_runs.push(ayl);
    }
    RoundTrips {
        ayllu: across_runs(&ayllu_runs),
        raw: across_runs(&raw_runs),
        raw_node_loop: across_runs(&loop_runs),
        ratios: spread(ratios),
        node_loop_ratios: spread(loop_ratios),
    }
}

/// The bytes and port messages of the batching phase's datagrams at `mtu`, on average over a
/// turn (a turn's [`BATCH_PORTS`] messages fill datagrams up to the MTU, and the last one is
/// partly full): what the batching goal's raw-UDP baseline sends per datagram. Worked out with
/// the wire encoder on a message like the benchmark's (an `i64` to port `D.pNN`; `strace`
/// shows the same sizes), so the raw sender carries the same bytes per datagram as Ayllu does.
fn batched_datagram(mtu: usize) -> (usize, f64) {
    let message = ayllu_wire::WireMessage::Port(ayllu_core::PortMessage {
        conn: ayllu_core::ConnectionId(40),
        seq: 1 << 40,
        behavior: "D".into(),
        port: "p40".into(),
        kind: ConnectionKind::Normal,
        priority: 0,
        value: ayllu::Value::Int(100_000),
    });
    let (head, each) = (ayllu_wire::HEADER_LEN, ayllu_wire::encoded_len(&message).expect("encodable"));
    let per = ((mtu - head) / each).min(BATCH_PORTS);
    let datagrams = BATCH_PORTS.div_ceil(per);
    let bytes = datagrams * head + BATCH_PORTS * each;
    (bytes / datagrams, BATCH_PORTS as f64 / datagrams as f64)
}

/// Alternating raw / Ayllu flows; returns the median run of each: raw, one message per
/// datagram, batched at the default MTU, batched at the loopback MTU, and raw UDP sending
/// datagrams of the batched ones' sizes.
/// The flows' figures: the median run of each flow, each run's three ratios (one-way,
/// batched at each MTU) and the largest loss of each Ayllu flow in any run.
struct Flows {
    median: [Flow; 6],
    one_way: Spread,
    batched: [Spread; 2],
    worst_loss: [f64; 3],
}

fn flow_phase() -> Flows {
    let mut runs: [Vec<Flow>; 6] = Default::default();
    let (mut one_way, mut batched_small, mut batched_large) = (Vec::new(), Vec::new(), Vec::new());
    let ((small, per_small), (large, per_large)) = (batched_datagram(DEFAULT_MTU), batched_datagram(LOOPBACK_MTU));
    type Run = fn(usize) -> Flow;
    let plan: [(&str, Run, usize); 6] = [
        ("raw", raw_one_way, 8),
        ("ayllu 1/datagram", |_| ayllu_flow(1, DEFAULT_MTU), 0),
        ("ayllu batched 1472", |_| ayllu_flow(BATCH_PORTS, DEFAULT_MTU), 0),
        ("ayllu batched 8192", |_| ayllu_flow(BATCH_PORTS, LOOPBACK_MTU), 0),
        ("raw, 1472's bytes", raw_one_way, small),
        ("raw, 8192's bytes", raw_one_way, large),
    ];
    for run in 1..=FLOW_RUNS {
        let mut order: Vec<usize> = (0..plan.len()).collect();
        if run % 2 == 0 {
            order.reverse();
        }
        let mut flows = [Flow::default(); 6];
        for i in order {
            let (what, flow, size) = plan[i];
            let f = flow(size);
            println!(
                "flow run {run} {what:<18}: sent {:>9} received {:>9} in {:.3} s = {} (loss {:.2} %, {:.1} msgs/datagram)",
                f.sent,
                f.received,
                f.secs,
                mps(f.rate()),
                100.0 * f.loss(),
                f.sent as f64 / f.datagrams.max(1) as f64
            );
            flows[i] = f;
        }
        let [raw, single, batch, big, raw_small, raw_large] = flows;
        one_way.push(single.rate() / raw.rate());
        batched_small.push(batch.rate() / (raw_small.rate() * per_small));
        batched_large.push(big.rate() / (raw_large.rate() * per_large));
        for (i, f) in flows.into_iter().enumerate() {
            runs[i].push(f);
        }
    }
    let worst = |i: usize| runs[i].iter().map(Flow::loss).fold(0.0, f64::max);
    Flows {
        worst_loss: [worst(1), worst(2), worst(3)],
        median: runs.map(median_flow),
        one_way: spread(one_way),
        batched: [spread(batched_small), spread(batched_large)],
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    if args.first().is_some_and(|a| a == "peer") {
        return peer_mode(&args[1..]);
    }
    // `rtt` or `flow` runs only that part; nothing (or anything else) runs both.
    let only = |part: &str| args.iter().any(|a| a == "rtt" || a == "flow") && !args.iter().any(|a| a == part);
    if args.iter().any(|a| a == "callgrind") {
        // A number among the arguments is the batches' MTU (default: the default MTU).
        let mtu = args.iter().find_map(|a| a.parse().ok()).unwrap_or(DEFAULT_MTU);
        return callgrind_mode(!only("rtt"), !only("flow"), mtu);
    }
    let began = StdInstant::now();
    cpu_count(); // before any pinning
                 // Before any thread is pinned: the CPU count follows the calling thread's affinity.
    let machine = machine();
    println!("network benchmarks on loopback; machine: {machine}; load average {}", load());
    let rtt = (!only("rtt")).then(|| {
        (
            round_trip_phase(Placement::SameCpu, RTT_RUNS, ROUNDS),
            round_trip_phase(Placement::TwoCpus, RTT_TWO_CPU_RUNS, TWO_CPU_ROUNDS),
        )
    });
    let flows = (!only("flow")).then(flow_phase);

    println!();
    println!(
        "Summary: raw UDP and Ayllu alternating in this run; round trips: {RTT_RUNS} pairs of runs (two CPUs: \
         {RTT_TWO_CPU_RUNS}), each ratio the median over pairs of the pair's ratio, each time the median over runs \
         of the run's statistic; flows (sender on CPU 0, receiver on CPU 1): {FLOW_RUNS} runs, each \
         ratio the median over runs of the run's ratio, each rate the median run's"
    );
    println!("machine: {machine}; load average at the end {}", load());
    println!("{:<44} {:>14} {:>16} {:>7}  {:<26} verdict", "figure", "ayllu", "raw UDP", "ratio", "goal");
    if let Some((one, two)) = rtt {
        let (ayllu, raw, r) = (one.ayllu, one.raw, one.ratios);
        println!(
            "{:<44} {:>11.2} us {:>13.2} us {:>6.2}x  {:<26} {}",
            format!("round trip, median of {RTT_RUNS} pairs' ratios (one CPU)"),
            ayllu.median,
            raw.median,
            r.median,
            "<= 1.2x raw",
            r.verdict(GOAL_RTT_RATIO, true)
        );
        println!("{}", r.describe());
        for (what, a, b, ratio) in [
            ("round trip, mean (one CPU)", ayllu.mean, raw.mean, ayllu.mean / raw.mean),
            ("round trip, p99 (one CPU)", ayllu.p99, raw.p99, ayllu.p99 / raw.p99),
            ("  raw UDP polling, then receiving", one.raw_node_loop.median, raw.median, one.node_loop_ratios.median),
            ("round trip, median (threads on two CPUs)", two.ayllu.median, two.raw.median, two.ratios.median),
            ("round trip, p99 (two CPUs)", two.ayllu.p99, two.raw.p99, two.ayllu.p99 / two.raw.p99),
        ] {
            println!("{what:<44} {a:>11.2} us {b:>13.2} us {ratio:>6.2}x  {:<26} -", "(information)");
        }
    }
    if let Some(flows) = flows {
        let [raw, single, batch, big, raw_small, raw_large] = flows.median;
        let r = flows.one_way;
        println!(
            "{:<44} {:>14} {:>16} {:>6.2}x  {:<26} {}",
            "one-way, 1 msg/datagram (received/s)",
            mps(single.rate()),
            mps(raw.rate()),
            r.median,
            ">= 1.0x raw, no loss",
            if flows.worst_loss[0] > 0.0 { "NOT met (loss)" } else { r.verdict(1.0, false) }
        );
        println!("{}", r.describe());
        println!(
            "{:<44} {:>13.3}% {:>15.3}% {:>7}  {:<26} -",
            "  loss, the worst run (sent, never received)",
            100.0 * flows.worst_loss[0],
            100.0 * raw.loss(),
            "",
            "(information)"
        );
        // The baseline: raw UDP datagrams of the same bytes, each worth as many port messages
        // as Ayllu puts in one.
        for (what, f, mtu, base, r, loss) in [
            (
                format!("batched, {BATCH_PORTS} ports/turn, mtu {DEFAULT_MTU} (accepted/s)"),
                batch,
                DEFAULT_MTU,
                raw_small,
                flows.batched[0],
                flows.worst_loss[1],
            ),
            (
                format!("batched, {BATCH_PORTS} ports/turn, mtu {LOOPBACK_MTU} (accepted/s)"),
                big,
                LOOPBACK_MTU,
                raw_large,
                flows.batched[1],
                flows.worst_loss[2],
            ),
        ] {
            let (bytes, per) = batched_datagram(mtu);
            // Both MTUs are judged (issue 36 made the 8192-byte one a goal too).
            println!(
                "{what:<44} {:>14} {:>16} {:>6.2}x  {:<26} {}",
                mps(f.rate()),
                mps(base.rate() * per),
                r.median,
                format!(">= {GOAL_BATCHED_RATIO}x raw ({bytes} B, x {per:.1})"),
                r.verdict(GOAL_BATCHED_RATIO, false)
            );
            println!("{}", r.describe());
            println!(
                "{:<44} {:>13.3}% {:>16} {:>7}  {:<26} -",
                format!("  loss, the worst run; {:.1} msgs/datagram", f.sent as f64 / f.datagrams.max(1) as f64),
                100.0 * loss,
                "",
                "",
                "(information)"
            );
        }
    }
    println!("(whole benchmark: {:.1} s)", began.elapsed().as_secs_f64());
}
