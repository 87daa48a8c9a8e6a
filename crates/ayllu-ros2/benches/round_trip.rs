//! The cost of the ROS 2 body: a port -> topic -> port round trip through two bodies, beside
//! the same round trip through ros2-client (RustDDS) alone, measured in the same run.
//!
//! Run with `make bench-ros2` (i.e. `CARGO_TARGET_DIR=target/ros2 cargo bench -p ayllu-ros2
//! --bench round_trip`; about half a minute once compiled). It needs root: the process first
//! moves into a network namespace of its own (unshare, then loopback up with multicast and a
//! route for 224.0.0.0/4), so DDS discovery and traffic never leave the machine; without root
//! it says so and exits non-zero.
//!
//! What is measured, each variant on a ROS domain of its own, one after the other:
//! * Ayllu: node A (thread "ping") writes its port `PING.Out` (float); its body publishes
//!   `/bench/ping` (std_msgs/msg/Float64) when the port accepts the value. Node B (thread
//!   "echo", `run_for` loops) takes the sample into `PONG.In`; an OnWrite process copies it to
//!   `PONG.Out`; B's body publishes `/bench/pong`; A's body takes it into `PING.In`. A runs
//!   `step` + `wait` and the figure is write to acceptance of `PING.In`, on A's clock. The
//!   two nodes are on `mem://` networks of their own: they talk ROS 2 only. Once with the
//!   body's default polling period (`poll`, 2 ms), once with `poll = 0.0002` (200 us).
//! * DDS alone: the same echo written with ros2-client directly (a Publisher and a
//!   Subscription of a serde `Float64 { data: f64 }` per side, the same QoS as the body's:
//!   reliable, volatile, keep last 10), on the same two threads. Each side waits for its
//!   subscription as efficiently as ros2-client allows (mio 1 readiness, as its `listener`
//!   example does): the baseline every ratio is taken against. Then the same with each side
//!   taking and sleeping 2 ms (and 200 us) instead, as the body's loop does, so that the share
//!   of the difference that is the polling period can be read off.
//!
//! Every variant first waits for DDS discovery (a round trip that comes back, asked again
//! every 100 ms, for at most [`DISCOVERY_LIMIT`]), then runs [`WARM_UP_TIME`] (and at least
//! [`WARM_UP_ROUNDS`]) of unmeasured round trips, then measures [`ROUNDS`] round trips or
//! [`MEASURE_LIMIT`], whichever comes first. A round trip with no answer in [`ROUND_LIMIT`]
//! is counted as timed out and not timed (none is expected on loopback with reliable QoS).
//! Printed per variant: round trips timed, median, p90, p99, min and mean in microseconds, and
//! each Ayllu variant's median as a ratio of the DDS-alone (mio) median, and of the DDS-alone
//! median polled at the same period. A polled round trip takes one or two periods of the
//! pinging side (the answer comes back before its next look or after it), so its median may
//! land on either mode from one run to the next; the mean moves less. Nothing here passes or
//! fails on timing. Threads are not pinned (RustDDS runs threads of its own that could not
//! be), so where the scheduler puts them moves the figures by tens of percent between runs on
//! a small virtual machine.

// The runtime's benchmarks' machine line, shared rather than copied.
#[path = "../../ayllu/benches/machine/mod.rs"]
mod machine;

use std::process::{Command, ExitCode};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use ayllu::{BehaviorClass, Node, NodeId, PortRef, PortSpec};
use ayllu_ros2::Mapping;
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{Context, ContextOptions, MessageTypeName, Name, NodeName, NodeOptions, QosProfile};
use serde::{Deserialize, Serialize};

/// Round trips timed per variant, at most.
const ROUNDS: usize = 2_000;
/// How long a variant's timed round trips may take, at most.
const MEASURE_LIMIT: Duration = Duration::from_secs(20);
/// Unmeasured round trips after discovery: this long, and at least [`WARM_UP_ROUNDS`].
const WARM_UP_TIME: Duration = Duration::from_secs(1);
const WARM_UP_ROUNDS: usize = 20;
/// How long a variant may wait for its first answer (DDS discovery) before giving up.
const DISCOVERY_LIMIT: Duration = Duration::from_secs(20);
/// A ping not answered within this long while waiting for discovery is sent again.
const DISCOVERY_RETRY: Duration = Duration::from_millis(100);
/// A timed round trip not answered within this long is counted as timed out.
const ROUND_LIMIT: Duration = Duration::from_millis(200);
/// The body's default polling period (`ayllu_ros2::mapping::DEFAULT_POLL`) and the short one.
const POLL_DEFAULT: Duration = ayllu_ros2::mapping::DEFAULT_POLL;
const POLL_SHORT: Duration = Duration::from_micros(200);
/// The first variant's ROS domain; each variant takes the next one.
const FIRST_DOMAIN: u16 = 40;

/// std_msgs/msg/Float64 as a plain serde struct, for the DDS-alone side.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
struct Float64 {
    data: f64,
}

/// How a side waits for its subscription.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Wait {
    /// mio 1 readiness on the subscription (ros2-client's `listener` example).
    Mio,
    /// Take, then sleep this long, as the body's loop does.
    Every(Duration),
}

#[derive(Clone, Copy, Debug)]
enum Variant {
    Dds(Wait),
    Ayllu(Duration),
}

impl Variant {
    fn label(self) -> String {
        match self {
            Variant::Dds(Wait::Mio) => "DDS alone, mio wait (baseline)".to_owned(),
            Variant::Dds(Wait::Every(p)) => format!("DDS alone, polled every {}", period(p)),
            Variant::Ayllu(p) if p == POLL_DEFAULT => format!("Ayllu bodies, poll {} (default)", period(p)),
            Variant::Ayllu(p) => format!("Ayllu bodies, poll {}", period(p)),
        }
    }
}

fn period(p: Duration) -> String {
    if p >= Duration::from_millis(1) {
        format!("{} ms", p.as_secs_f64() * 1e3)
    } else {
        format!("{} us", p.as_secs_f64() * 1e6)
    }
}

/// What one variant measured.
struct Figures {
    /// Round-trip times, in microseconds.
    samples: Vec<f64>,
    timed_out: usize,
    /// From the start to the first answer.
    discovery: Duration,
    warm_up: usize,
}

/// One round trip at a time: send `value`, wait for it back at most `limit`.
trait Pinger {
    fn round(&mut self, value: f64, limit: Duration) -> Option<Duration>;
}

/// Discovery, warm-up, then the timed round trips (module docs).
fn measure(p: &mut impl Pinger) -> Result<Figures, String> {
    let start = Instant::now();
    let mut value = 0.0;
    loop {
        value += 1.0;
        if p.round(value, DISCOVERY_RETRY).is_some() {
            break;
        }
        if start.elapsed() > DISCOVERY_LIMIT {
            return Err(format!("no answer within {} s: DDS discovery failed", DISCOVERY_LIMIT.as_secs()));
        }
    }
    let discovery = start.elapsed();
    let warm_start = Instant::now();
    let mut warm_up = 0;
    while (warm_up < WARM_UP_ROUNDS || warm_start.elapsed() < WARM_UP_TIME) && warm_start.elapsed() < MEASURE_LIMIT {
        value += 1.0;
        if p.round(value, ROUND_LIMIT).is_some() {
            warm_up += 1;
        }
    }
    let (mut samples, mut timed_out) = (Vec::with_capacity(ROUNDS), 0);
    let timed = Instant::now();
    while samples.len() < ROUNDS && timed.elapsed() < MEASURE_LIMIT {
        value += 1.0;
        match p.round(value, ROUND_LIMIT) {
            Some(dt) => samples.push(dt.as_secs_f64() * 1e6),
            None => timed_out += 1,
        }
    }
    Ok(Figures { samples, timed_out, discovery, warm_up })
}

// ----- DDS alone ----------------------------------------------------------------------------

/// The body's QoS for a `qos = "default"` topic (body.rs `profile`): reliable (a full window
/// fails the write rather than blocking), volatile, keep last 10.
fn qos() -> QosProfile {
    QosProfile::subscription_default()
        .reliability(Reliability::Reliable { when_full: WhenFull::Fail })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// `what` failed, and why, for `map_err`.
fn err<E: std::fmt::Debug>(what: &'static str) -> impl Fn(E) -> String {
    move |e| format!("{what}: {e:?}")
}

/// One side of the DDS-alone echo: its participant, node (with its spinner, as a body's), a
/// publisher on `out` and a subscription on `inp`, and how it waits.
struct DdsSide {
    publisher: ros2_client::Publisher<Float64>,
    subscription: ros2_client::Subscription<Float64>,
    wait: Wait,
    poll: Option<(Poll, Events)>,
    // Last: the entities above go before their node and participant.
    _node: ros2_client::Node,
    _context: Context,
}

impl DdsSide {
    fn new(domain: u16, name: &str, out: &str, inp: &str, wait: Wait) -> Result<DdsSide, String> {
        let context = Context::with_options(ContextOptions::new().domain_id(domain)).map_err(err("participant"))?;
        let options = NodeOptions::new().enable_rosout(false).start_parameter_services(false);
        let mut node =
            context.new_node(NodeName::new("/", name).map_err(err("node name"))?, options).map_err(err("node"))?;
        let spinner = node.spinner().map_err(err("spinner"))?;
        thread::spawn(move || {
            let _ = futures::executor::block_on(spinner.spin());
        });
        let topic = |n: &str| -> Result<_, String> {
            let name = Name::new("/bench", n).map_err(err("topic name"))?;
            node.create_topic(&name, MessageTypeName::new("std_msgs", "Float64"), &qos()).map_err(err("topic"))
        };
        let (out_topic, in_topic) = (topic(out)?, topic(inp)?);
        let publisher = node.create_publisher::<Float64>(&out_topic, Some(qos())).map_err(err("publisher"))?;
        let mut subscription =
            node.create_subscription::<Float64>(&in_topic, Some(qos())).map_err(err("subscription"))?;
        let poll = match wait {
            Wait::Mio => {
                let poll = Poll::new().map_err(err("mio poll"))?;
                poll.registry()
                    .register(&mut subscription, Token(1), Interest::READABLE)
                    .map_err(err("registering the subscription"))?;
                Some((poll, Events::with_capacity(8)))
            }
            Wait::Every(_) => None,
        };
        Ok(DdsSide { publisher, subscription, wait, poll, _node: node, _context: context })
    }

    /// Wait for the subscription at most `timeout`.
    fn wait(&mut self, timeout: Duration) {
        match (self.wait, self.poll.as_mut()) {
            (Wait::Mio, Some((poll, events))) => {
                let _ = poll.poll(events, Some(timeout));
            }
            (Wait::Every(p), _) => thread::sleep(p.min(timeout)),
            (Wait::Mio, None) => thread::sleep(timeout),
        }
    }
}

impl Pinger for DdsSide {
    fn round(&mut self, value: f64, limit: Duration) -> Option<Duration> {
        let t0 = Instant::now();
        // A failed publish (none is expected) is a ping lost: waited for, then timed out.
        let _ = self.publisher.publish(Float64 { data: value });
        loop {
            // Edge-triggered readiness: take everything that is there before waiting again.
            while let Ok(Some((m, _))) = self.subscription.take() {
                if m.data == value {
                    return Some(t0.elapsed());
                }
            }
            let left = limit.checked_sub(t0.elapsed())?;
            self.wait(left);
        }
    }
}

/// The echo side until `stop`: every sample taken is published back.
fn dds_echo(mut side: DdsSide, stop: &AtomicBool) {
    while !stop.load(Ordering::Acquire) {
        while let Ok(Some((m, _))) = side.subscription.take() {
            let _ = side.publisher.publish(m);
        }
        side.wait(Duration::from_millis(50));
    }
}

fn run_dds(domain: u16, wait: Wait) -> Result<Figures, String> {
    let stop = Arc::new(AtomicBool::new(false));
    let echo = {
        let stop = stop.clone();
        thread::Builder::new()
            .name("echo".into())
            .spawn(move || -> Result<(), String> {
                dds_echo(DdsSide::new(domain, "bench_echo", "pong", "ping", wait)?, &stop);
                Ok(())
            })
            .map_err(|e| e.to_string())?
    };
    let ping = thread::Builder::new()
        .name("ping".into())
        .spawn(move || measure(&mut DdsSide::new(domain, "bench_ping", "ping", "pong", wait)?))
        .map_err(|e| e.to_string())?;
    let figures = ping.join().map_err(|_| "the ping thread panicked".to_owned())?;
    stop.store(true, Ordering::Release);
    echo.join().map_err(|_| "the echo thread panicked".to_owned())??;
    figures
}

// ----- Ayllu --------------------------------------------------------------------------------

fn mapping(domain: u16, node: &str, poll: Duration, out: (&str, &str), inp: (&str, &str)) -> Result<Mapping, String> {
    let text = format!(
        r#"
[ros2]
domain = {domain}
node = "{node}"
poll = {poll}

[[topic]]
name = "{}"
type = "std_msgs/msg/Float64"
direction = "out"
qos = "default"
fields = {{ data = "{}" }}

[[topic]]
name = "{}"
type = "std_msgs/msg/Float64"
direction = "in"
qos = "default"
fields = {{ data = "{}" }}
"#,
        out.0,
        out.1,
        inp.0,
        inp.1,
        poll = poll.as_secs_f64(),
    );
    Mapping::parse(&text).map_err(|e| format!("mapping of {node}: {e}"))
}

/// Node A: `PING.Out` published on `/bench/ping`, `/bench/pong` taken into `PING.In`.
struct AylluPing {
    node: Node,
    out: PortRef,
    inp: PortRef,
}

impl AylluPing {
    fn new(domain: u16, poll: Duration) -> Result<AylluPing, String> {
        let mut node = Node::open(NodeId(1), &format!("mem://bench-ros2-ping-{domain}")).map_err(|e| e.to_string())?;
        let mut class = BehaviorClass::new("Ping");
        class.port(PortSpec::new("Out", 0.0)).map_err(|e| e.to_string())?;
        class.port(PortSpec::new("In", 0.0)).map_err(|e| e.to_string())?;
        node.define(class).map_err(|e| e.to_string())?;
        node.create("Ping", "PING").map_err(|e| e.to_string())?;
        let m = mapping(domain, "bench_ping", poll, ("/bench/ping", "PING.Out"), ("/bench/pong", "PING.In"))?;
        ayllu_ros2::install(&mut node, &m).map_err(|e| e.to_string())?;
        let out = node.core().port("PING", "Out").map_err(|e| e.to_string())?;
        let inp = node.core().port("PING", "In").map_err(|e| e.to_string())?;
        Ok(AylluPing { node, out, inp })
    }
}

impl Pinger for AylluPing {
    /// Write `PING.Out`, then step and wait until `PING.In` holds the value; the time is from
    /// the write to `PING.In`'s acceptance, on the node's clock.
    fn round(&mut self, value: f64, limit: Duration) -> Option<Duration> {
        let start = Instant::now();
        let core = self.node.core_mut(); // told the present
        let t0 = core.now();
        core.write(t0, self.out, value).expect("PING.Out takes a float");
        loop {
            let next = self.node.step();
            let core = self.node.core();
            if core.read(self.inp).ok().and_then(|v| v.as_float()) == Some(value) {
                let at = core.last_accepted(self.inp).ok().flatten()?;
                return Some(Duration::from_nanos((at - t0).as_nanos()));
            }
            let left = limit.checked_sub(start.elapsed())?;
            let now = self.node.now();
            let until =
                next.map_or(
                    left,
                    |n| if n > now { Duration::from_nanos((n - now).as_nanos()) } else { Duration::ZERO },
                );
            self.node.wait(until.min(left));
        }
    }
}

/// Node B: `/bench/ping` taken into `PONG.In`, copied by an OnWrite process to `PONG.Out`,
/// published on `/bench/pong`.
fn ayllu_echo(domain: u16, poll: Duration) -> Result<Node, String> {
    let mut node = Node::open(NodeId(2), &format!("mem://bench-ros2-echo-{domain}")).map_err(|e| e.to_string())?;
    let mut class = BehaviorClass::new("Pong");
    let inp = class.port(PortSpec::new("In", 0.0)).map_err(|e| e.to_string())?;
    let out = class.port(PortSpec::new("Out", 0.0)).map_err(|e| e.to_string())?;
    class
        .on_write("Echo", inp, move |ctx| {
            let v = ctx.float(inp).unwrap_or(0.0);
            let _ = ctx.write(out, v);
        })
        .map_err(|e| e.to_string())?;
    node.define(class).map_err(|e| e.to_string())?;
    node.create("Pong", "PONG").map_err(|e| e.to_string())?;
    let m = mapping(domain, "bench_echo", poll, ("/bench/pong", "PONG.Out"), ("/bench/ping", "PONG.In"))?;
    ayllu_ros2::install(&mut node, &m).map_err(|e| e.to_string())?;
    Ok(node)
}

fn run_ayllu(domain: u16, poll: Duration) -> Result<Figures, String> {
    let stop = Arc::new(AtomicBool::new(false));
    let echo = {
        let stop = stop.clone();
        thread::Builder::new()
            .name("echo".into())
            .spawn(move || -> Result<(), String> {
                let mut node = ayllu_echo(domain, poll)?;
                while !stop.load(Ordering::Acquire) {
                    node.run_for(Duration::from_millis(50));
                }
                Ok(())
            })
            .map_err(|e| e.to_string())?
    };
    let ping = thread::Builder::new()
        .name("ping".into())
        .spawn(move || measure(&mut AylluPing::new(domain, poll)?))
        .map_err(|e| e.to_string())?;
    let figures = ping.join().map_err(|_| "the ping thread panicked".to_owned())?;
    stop.store(true, Ordering::Release);
    echo.join().map_err(|_| "the echo thread panicked".to_owned())??;
    figures
}

// ----- the run ------------------------------------------------------------------------------

/// Move this process (one thread so far) into a network namespace of its own with loopback up,
/// multicast on and a multicast route (crates/ayllu-cli/tests/tool/common/ros2.rs `own_network`).
fn own_network() -> Result<(), String> {
    // SAFETY: geteuid takes nothing and cannot fail.
    if unsafe { libc::geteuid() } != 0 {
        return Err("this benchmark runs DDS in a network namespace of its own (unshare(CLONE_NEWNET)), \
                    which needs root: run it as root (e.g. in the project's container)"
            .to_owned());
    }
    // SAFETY: unshare(CLONE_NEWNET) takes no pointers; it moves the calling thread into a new
    // network namespace. It is called first in main, before any thread exists, so the whole
    // process moves, and every thread started later (ours and RustDDS's) is inside.
    if unsafe { libc::unshare(libc::CLONE_NEWNET) } != 0 {
        return Err(format!("unshare(CLONE_NEWNET): {}", std::io::Error::last_os_error()));
    }
    for args in [
        &["link", "set", "lo", "up"][..],
        &["link", "set", "lo", "multicast", "on"],
        &["route", "add", "224.0.0.0/4", "dev", "lo"],
    ] {
        let out = Command::new("ip").args(args).output().map_err(|e| format!("running ip (iproute2): {e}"))?;
        if !out.status.success() {
            return Err(format!("ip {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim()));
        }
    }
    Ok(())
}

/// The `q` quantile of sorted `v` (nearest rank).
fn quantile(v: &[f64], q: f64) -> f64 {
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_owned())
}

fn main() -> ExitCode {
    if let Err(e) = own_network() {
        eprintln!("round_trip: {e}");
        return ExitCode::FAILURE;
    }
    let machine = machine::machine();
    println!(
        "ROS 2 round trip, port -> topic -> port through two ROS 2 bodies, beside ros2-client 0.12.1 (RustDDS) alone"
    );
    println!("host: {machine}; load average {}", load());
    println!(
        "note: timings on this noisy 2-core virtual machine are indicative (threads unpinned; figures move by tens of \
         percent between runs); compare the rows of one run"
    );
    println!(
        "each variant: a ROS domain of its own, discovery, {} s / {WARM_UP_ROUNDS}+ round trips of warm-up, then up to \
         {ROUNDS} round trips or {} s",
        WARM_UP_TIME.as_secs(),
        MEASURE_LIMIT.as_secs()
    );
    println!();
    let variants = [
        Variant::Dds(Wait::Mio),
        Variant::Ayllu(POLL_DEFAULT),
        Variant::Dds(Wait::Every(POLL_DEFAULT)),
        Variant::Ayllu(POLL_SHORT),
        Variant::Dds(Wait::Every(POLL_SHORT)),
    ];
    let mut results = Vec::new();
    for (k, &variant) in variants.iter().enumerate() {
        let domain = FIRST_DOMAIN + k as u16;
        let began = Instant::now();
        let figures = match variant {
            Variant::Dds(wait) => run_dds(domain, wait),
            Variant::Ayllu(poll) => run_ayllu(domain, poll),
        };
        match figures {
            Ok(mut f) => {
                f.samples.sort_by(f64::total_cmp);
                println!(
                    "{:<34} discovery {:.2} s, {} warm-up round trips, {} timed, {} timed out; {:.1} s in all",
                    variant.label(),
                    f.discovery.as_secs_f64(),
                    f.warm_up,
                    f.samples.len(),
                    f.timed_out,
                    began.elapsed().as_secs_f64()
                );
                results.push((variant, f));
            }
            Err(e) => {
                eprintln!("round_trip: {}: {e}", variant.label());
                return ExitCode::FAILURE;
            }
        }
    }

    let median = |f: &Figures| if f.samples.is_empty() { f64::NAN } else { quantile(&f.samples, 0.5) };
    let baseline =
        results.iter().find(|(v, _)| matches!(v, Variant::Dds(Wait::Mio))).map_or(f64::NAN, |(_, f)| median(f));
    let polled_at = |p: Duration| {
        results
            .iter()
            .find(|(v, _)| matches!(v, Variant::Dds(Wait::Every(q)) if *q == p))
            .map_or(f64::NAN, |(_, f)| median(f))
    };
    println!();
    println!("round-trip times in microseconds; ratios are of medians");
    println!(
        "{:<34} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>13}",
        "variant", "rounds", "median", "p90", "p99", "min", "mean", "vs DDS mio", "vs DDS polled"
    );
    for (variant, f) in &results {
        let v = &f.samples;
        if v.is_empty() {
            println!("{:<34} {:>6}  (no round trip timed)", variant.label(), 0);
            continue;
        }
        let (vs_mio, vs_polled) = match variant {
            Variant::Ayllu(p) => {
                (format!("{:.2}x", median(f) / baseline), format!("{:.2}x", median(f) / polled_at(*p)))
            }
            _ => (String::new(), String::new()),
        };
        println!(
            "{:<34} {:>6} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>10} {:>13}",
            variant.label(),
            v.len(),
            quantile(v, 0.5),
            quantile(v, 0.9),
            quantile(v, 0.99),
            v[0],
            v.iter().sum::<f64>() / v.len() as f64,
            vs_mio,
            vs_polled
        );
    }
    println!("load average at the end {}", load());
    ExitCode::SUCCESS
}
