//! Propagation benchmarks: the cost of the core's hot paths next to a plain function call.
//!
//! Run with `cargo bench -p ayllu --bench propagation` (about a minute). Criterion prints its
//! usual report per benchmark; at the end a summary table gives each benchmark's median
//! ns/op (read back from the estimates Criterion wrote *in this run*) and its ratio to the
//! plain function call measured in the same run, plus the machine it ran on.
//!
//! What is measured (one iteration = one call of `NodeCore::write`, plus `poll` where said):
//! * `function_call` — baseline: an `#[inline(never)]` function storing an i64 into a field.
//! * `write_no_connection` — a write into a Normal port with no outgoing connection.
//! * `normal_hop` — a write into a port with one Normal connection to another port.
//! * `fan_out_4` — a write into a port with four Normal connections.
//! * `override_chain_5` — the paper's subsumption chain (Fig. 2, `ayOverrideOut`): layers
//!   L1 -> L2 -> L3 -> L4 -> L5, each layer's `Rotate` overriding the next one's for 200 ms
//!   (four OverrideOut hops, each refreshing a window); the write is at the top layer L1.
//! * `process_activation` — a write into a port with an OnWrite process, then the `poll` that
//!   runs it (the process reads the port and stores it in a slot).
//! * `normal_hop_journaled` — `normal_hop` with the core's journal on (the flight recorder's
//!   tap), its entries taken every 256 writes (as the recorder takes them, a `JournalBatch`)
//!   and dropped: what the tap itself costs the node's thread, with no writer thread beside it.
//! * `normal_hop_recorded` — `normal_hop` on a node with the flight recorder on
//!   (`ayllu::Recorder`, writing an MCAP file in the system's temp directory), drained every
//!   256 writes as a busy node's loop would: the cost the recorder adds to the node's own
//!   thread (the journal entries, and handing them over); the writer thread encodes and writes
//!   beside it, and drops (counted) what it cannot keep up with.
//!
//! The clock advances 1 µs per iteration, so windows are refreshed as in a live system.
//!
//! After the table, `sustained`: the recorder always on (rolling, the last 2 s of node time)
//! while the node accepts 1,000,000 values a second for 10 s of wall time on one core (500,000
//! writes a second through one Normal hop, paced, drained every 256 writes as a node's loop
//! does); it prints what was written and dropped, the node thread's time per write beside the
//! same paced loop with the recorder off (run just before it: the recorded hop's goal, judged
//! where the writer keeps up; in the tight loop of `normal_hop_recorded` it cannot, and the
//! journal drops most entries), and replays the kept window bit for bit (`ayllu replay
//! check`). `AYLLU_SUSTAINED_SECS` and `AYLLU_SUSTAINED_RATE` change the run.
//!
//! `propagation callgrind [N] [journaled]` skips Criterion and makes N (default 100 000)
//! `normal_hop` writes in `callgrind_normal_hops` (with the journal on, taken every 256
//! writes, if `journaled`), for instruction counts that a noisy machine cannot move:
//! `valgrind --tool=callgrind --toggle-collect='*callgrind_normal_hops*' BINARY callgrind`,
//! collected instructions ÷ N = instructions per write + hop.

#[path = "machine/mod.rs"]
mod machine;
use machine::machine;

use std::fs;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration as StdDuration, SystemTime};

use ayllu::{
    BehaviorClass, ConnectOptions, ConnectionKind, Duration, Endpoint, Instant, NodeCore, NodeId, PortRef, PortSpec,
    RecordOptions, Recorder,
};
use criterion::Criterion;

const GROUP: &str = "propagation";
const BASELINE: &str = "function_call";
const BENCHES: [&str; 8] = [
    BASELINE,
    "write_no_connection",
    "normal_hop",
    "fan_out_4",
    "override_chain_5",
    "process_activation",
    "normal_hop_journaled",
    "normal_hop_recorded",
];

struct Sink {
    value: i64,
}

/// The baseline: one real (not inlined) call that stores an i64 into a struct field.
#[inline(never)]
fn store(sink: &mut Sink, v: i64) {
    sink.value = v;
}

fn classes(node: &mut NodeCore) {
    let mut src = BehaviorClass::new("Src");
    src.port(PortSpec::new("Out", 0i64)).unwrap();
    node.define(src).unwrap();
    let mut dst = BehaviorClass::new("Dst");
    dst.port(PortSpec::new("In", 0i64)).unwrap();
    node.define(dst).unwrap();
    let mut layer = BehaviorClass::new("Layer");
    layer.port(PortSpec::new("Rotate", 0i64)).unwrap();
    node.define(layer).unwrap();
    let mut proc_ = BehaviorClass::new("Proc");
    let input = proc_.port(PortSpec::new("In", 0i64)).unwrap();
    let last = proc_.slot("Last", 0i64).unwrap();
    proc_
        .on_write("Copy", input, move |ctx| {
            let v = ctx.int(input).unwrap_or(0);
            ctx.set_slot(last, v).unwrap();
        })
        .unwrap();
    node.define(proc_).unwrap();
}

fn connect(node: &mut NodeCore, from: (&str, &str), to: (&str, &str), kind: ConnectionKind) {
    node.connect(&Endpoint::local(from.0, from.1), &Endpoint::local(to.0, to.1), kind, ConnectOptions::default())
        .unwrap();
}

/// A node with `Src` behavior `A` whose `Out` feeds `fan` `Dst` behaviors (0 = no connection).
fn fan_node(fan: usize) -> (NodeCore, PortRef) {
    let mut node = NodeCore::new(NodeId(1));
    classes(&mut node);
    node.create("Src", "A").unwrap();
    for i in 0..fan {
        let name = format!("D{i}");
        node.create("Dst", &name).unwrap();
        connect(&mut node, ("A", "Out"), (&name, "In"), ConnectionKind::Normal);
    }
    let out = node.port("A", "Out").unwrap();
    (node, out)
}

/// The subsumption chain L1 -> ... -> L5 (OverrideOut, 200 ms); returns L1.Rotate.
fn override_node() -> (NodeCore, PortRef) {
    let mut node = NodeCore::new(NodeId(1));
    classes(&mut node);
    for i in 1..=5 {
        node.create("Layer", &format!("L{i}")).unwrap();
    }
    for i in 1..5 {
        let (a, b) = (format!("L{i}"), format!("L{}", i + 1));
        connect(&mut node, (&a, "Rotate"), (&b, "Rotate"), ConnectionKind::OverrideOut(Duration::from_millis(200)));
    }
    let top = node.port("L1", "Rotate").unwrap();
    (node, top)
}

fn process_node() -> (NodeCore, PortRef) {
    let mut node = NodeCore::new(NodeId(1));
    classes(&mut node);
    node.create("Proc", "P").unwrap();
    let input = node.port("P", "In").unwrap();
    (node, input)
}

/// Benchmark `write` (and `poll` if `poll`) on `port`, advancing the clock 1 µs per iteration.
fn bench_write(
    c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    setup: (NodeCore, PortRef),
    poll: bool,
) {
    let (mut node, port) = setup;
    let mut t = 0u64;
    c.bench_function(name, |b| {
        b.iter(|| {
            t += 1_000;
            let now = Instant::from_nanos(t);
            node.write(now, port, black_box(t as i64)).unwrap();
            if poll {
                black_box(node.poll(now));
            }
        })
    });
}

/// `normal_hop` with the core's journal on, taken and dropped every 256 writes.
fn bench_journaled_hop(c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    let (mut node, port) = fan_node(1);
    node.start_journal(65_536);
    let mut taken = ayllu::JournalBatch::default();
    let mut t = 0u64;
    c.bench_function("normal_hop_journaled", |b| {
        b.iter(|| {
            t += 1_000;
            node.write(Instant::from_nanos(t), port, black_box(t as i64)).unwrap();
            if (t / 1_000).is_multiple_of(256) {
                node.take_journal_batch(&mut taken);
                taken.clear();
            }
        })
    });
}

/// `fan_node(1)` recorded into `path` from its start, always on as on a robot: a rolling
/// recording keeping the last `window`, so no byte cap ever stops it.
fn recorded_hop_node(path: &std::path::Path, window: StdDuration) -> (NodeCore, Recorder, PortRef) {
    let mut node = NodeCore::new(NodeId(1));
    let recorder = Recorder::start(&mut node, path, RecordOptions::default().keep_last(window)).unwrap();
    classes(&mut node);
    node.create("Src", "A").unwrap();
    node.create("Dst", "D0").unwrap();
    connect(&mut node, ("A", "Out"), ("D0", "In"), ConnectionKind::Normal);
    let port = node.port("A", "Out").unwrap();
    (node, recorder, port)
}

/// Remove every segment of the recording `path`.
fn remove_recording(path: &std::path::Path) {
    for n in ayllu::recording::segment_numbers(path) {
        let _ = fs::remove_file(ayllu::recording::segment_path(path, n));
    }
}

/// `normal_hop` with the flight recorder on (see the module docs).
fn bench_recorded_hop(c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    let path = std::env::temp_dir().join(format!("ayllu-bench-{}.mcap", std::process::id()));
    let (mut node, mut recorder, port) = recorded_hop_node(&path, StdDuration::from_secs(10));
    let mut t = 0u64;
    c.bench_function("normal_hop_recorded", |b| {
        b.iter(|| {
            t += 1_000;
            node.write(Instant::from_nanos(t), port, black_box(t as i64)).unwrap();
            if (t / 1_000).is_multiple_of(256) {
                recorder.drain(&mut node);
            }
        })
    });
    let stats = recorder.finish(&mut node);
    eprintln!(
        "normal_hop_recorded: {} entries written, {} dropped (writer behind), {} over the cap, {} bytes",
        stats.written,
        stats.dropped_queue + stats.dropped_journal,
        stats.dropped_cap,
        stats.bytes
    );
    remove_recording(&path);
}

/// What a paced run did: writes made, the node thread's busy time, and the most entries that
/// waited for the writer at once.
struct Paced {
    writes: u64,
    busy: StdDuration,
    behind_max: u64,
    wall: f64,
}

impl Paced {
    /// The node thread's time per write (and its hop, journal and hand-over), in ns.
    fn per_write_ns(&self) -> f64 {
        self.busy.as_nanos() as f64 / self.writes.max(1) as f64
    }
}

/// What a paced run does after each 256 writes.
enum Drain<'a> {
    /// Nothing: the recorder is off.
    Nothing,
    /// Take the journal's batch and empty it on the node's thread (the journal's own cost).
    Journal(ayllu::JournalBatch),
    /// Drain the recorder, as a node's loop does.
    Recorder(&'a mut Recorder),
}

/// `rate` values a second (each write is accepted twice: A.Out, then D0.In) for `secs` seconds
/// of wall time: 256 writes, then `drain`, then a wait for the wall clock to reach the next
/// batch's node time.
fn paced(node: &mut NodeCore, port: PortRef, mut drain: Drain<'_>, secs: u64, rate: u64) -> Paced {
    let writes_per_sec = rate / 2;
    let step_ns = 1_000_000_000 / writes_per_sec.max(1);
    let start = std::time::Instant::now();
    let mut writes = 0u64;
    let (mut busy, mut behind_max) = (StdDuration::ZERO, 0u64);
    while start.elapsed() < StdDuration::from_secs(secs) {
        let t0 = std::time::Instant::now();
        for _ in 0..256 {
            writes += 1;
            node.write(Instant::from_nanos(writes * step_ns), port, black_box(writes as i64)).unwrap();
        }
        match &mut drain {
            Drain::Nothing => {}
            Drain::Journal(taken) => {
                node.take_journal_batch(taken);
                taken.clear();
            }
            Drain::Recorder(r) => r.drain(node),
        }
        busy += t0.elapsed();
        if let Drain::Recorder(r) = &drain {
            behind_max = behind_max.max(r.stats().waiting);
        }
        // Paced: the next batch is due when the wall clock reaches its node time.
        let due = StdDuration::from_nanos(writes * step_ns);
        while start.elapsed() < due {
            std::hint::spin_loop();
        }
    }
    Paced { writes, busy, behind_max, wall: start.elapsed().as_secs_f64() }
}

/// The recorder always on while the node accepts `rate` values a second for `secs` seconds
/// (module docs): prints what was written and dropped, the node thread's time per write beside
/// the same paced loop with the recorder off and with the journal alone (run just before, each
/// for a third of the time), and checks the kept window replays.
fn sustained(secs: u64, rate: u64) {
    if secs == 0 || rate == 0 {
        println!("sustained: not run (AYLLU_SUSTAINED_SECS or AYLLU_SUSTAINED_RATE is 0)");
        return;
    }
    let (mut plain_node, plain_port) = fan_node(1);
    let plain = paced(&mut plain_node, plain_port, Drain::Nothing, secs.div_ceil(3), rate);
    let (mut journaled_node, journaled_port) = fan_node(1);
    journaled_node.start_journal(65_536);
    let journaled =
        paced(&mut journaled_node, journaled_port, Drain::Journal(Default::default()), secs.div_ceil(3), rate);
    let path = std::env::temp_dir().join(format!("ayllu-sustained-{}.mcap", std::process::id()));
    let (mut node, mut recorder, port) = recorded_hop_node(&path, StdDuration::from_secs(2));
    let run = paced(&mut node, port, Drain::Recorder(&mut recorder), secs, rate);
    let Paced { writes, busy, behind_max, wall } = run;
    let stats = recorder.finish(&mut node);
    let dropped = stats.dropped_queue + stats.dropped_journal + stats.dropped_cap;
    println!();
    println!(
        "sustained: {:.2} M values accepted a second for {wall:.1} s ({writes} writes), recorder on (rolling, last 2 s)",
        2.0 * writes as f64 / wall / 1e6
    );
    println!(
        "  node thread busy {:.1} % (writes, hops, journal, hand-over); writer: {} entries written, {} dropped, \
         at most {behind_max} waiting; {} MB written, {} segments deleted",
        100.0 * busy.as_secs_f64() / wall,
        stats.written,
        dropped,
        stats.bytes / 1_000_000,
        stats.deleted
    );
    let verdict = |ok: bool| if ok { "met" } else { "NOT met" };
    let (recorded_ns, journaled_ns, plain_ns) = (run.per_write_ns(), journaled.per_write_ns(), plain.per_write_ns());
    println!(
        "  node thread per write (+ hop, journal, hand-over), paced: {recorded_ns:.1} ns recorded ({dropped} dropped), \
         {journaled_ns:.1} ns with the journal alone, {plain_ns:.1} ns with the recorder off ({:.1}x, {:.1}x)",
        recorded_ns / plain_ns,
        journaled_ns / plain_ns
    );
    println!(
        "goal (the recorded hop within 3x the hop without it, while the writer keeps up): {} ({:.1}x)",
        verdict(dropped == 0 && recorded_ns <= 3.0 * plain_ns),
        recorded_ns / plain_ns
    );
    match ayllu::replay::Recording::open(&path) {
        Ok(rec) => {
            let mut replay = ayllu::replay::Replay::new(&rec);
            let checked = replay.run_to_end().map(|()| replay.checked());
            println!(
                "  the kept window replays: {} (from t={:.3}s to {:.3}s)",
                match &checked {
                    Ok(n) => format!("{n} accepted values reproduced bit for bit"),
                    Err(d) => format!("NO: {d}"),
                },
                rec.start().as_secs_f64(),
                rec.end().as_secs_f64()
            );
            println!(
                "goal (1,000,000 values a second for 10 s, 0 dropped, the file replays): {}",
                verdict(
                    dropped == 0
                        && checked.is_ok()
                        && 2 * writes >= rate * secs * 95 / 100
                        && rate >= 1_000_000
                        && secs >= 10
                )
            );
        }
        Err(e) => println!("  the recording does not open: {e}"),
    }
    remove_recording(&path);
}

fn benches(c: &mut Criterion) {
    let mut g = c.benchmark_group(GROUP);
    let mut sink = Sink { value: 0 };
    let mut v = 0i64;
    g.bench_function(BASELINE, |b| {
        b.iter(|| {
            v = v.wrapping_add(1);
            store(black_box(&mut sink), black_box(v));
        })
    });
    black_box(sink.value);
    bench_write(&mut g, "write_no_connection", fan_node(0), false);
    bench_write(&mut g, "normal_hop", fan_node(1), false);
    bench_write(&mut g, "fan_out_4", fan_node(4), false);
    bench_write(&mut g, "override_chain_5", override_node(), false);
    bench_write(&mut g, "process_activation", process_node(), true);
    bench_journaled_hop(&mut g);
    bench_recorded_hop(&mut g);
    g.finish();
}

/// Where Criterion writes its estimates (same rule as Criterion 0.5 itself).
fn criterion_dir() -> PathBuf {
    if let Some(home) = std::env::var_os("CRITERION_HOME") {
        return PathBuf::from(home);
    }
    if let Some(target) = std::env::var_os("CARGO_TARGET_DIR") {
        return PathBuf::from(target).join("criterion");
    }
    // The bench binary is <target>/<profile>/deps/propagation-<hash>.
    std::env::current_exe()
        .ok()
        .and_then(|exe| exe.ancestors().nth(3).map(|t| t.join("criterion")))
        .unwrap_or_else(|| PathBuf::from("target/criterion"))
}

/// The median (ns/op) Criterion estimated for `name`, if it was written after `since`.
fn median_ns(dir: &std::path::Path, name: &str, since: SystemTime) -> Option<f64> {
    let path = dir.join(GROUP).join(name).join("new").join("estimates.json");
    let modified = fs::metadata(&path).and_then(|m| m.modified()).ok()?;
    if modified < since {
        return None; // left over from an earlier run (e.g. filtered out this time)
    }
    let json = fs::read_to_string(&path).ok()?;
    let rest = &json[json.find("\"median\"")?..];
    let rest = &rest[rest.find("\"point_estimate\"")? + "\"point_estimate\"".len()..];
    let rest = rest.trim_start().strip_prefix(':')?.trim_start();
    let end = rest.find([',', '}']).unwrap_or(rest.len());
    rest[..end].trim().parse().ok()
}

/// N writes through one Normal hop, alone in a function so callgrind can collect just them;
/// with the journal on, its batch is taken and emptied every 256 writes (as
/// `normal_hop_journaled` does).
#[inline(never)]
fn callgrind_normal_hops(node: &mut NodeCore, port: PortRef, n: u64) {
    let mut taken = ayllu::JournalBatch::default();
    for t in 1..=n {
        node.write(Instant::from_nanos(t * 1_000), port, black_box(t as i64)).unwrap();
        if t.is_multiple_of(256) && node.journaling() {
            node.take_journal_batch(&mut taken);
            taken.clear();
        }
    }
}

fn main() {
    let mut args = std::env::args().skip(1).filter(|a| !a.starts_with("--"));
    if args.next().as_deref() == Some("callgrind") {
        let rest: Vec<String> = args.collect();
        let n = rest.iter().find_map(|a| a.parse().ok()).unwrap_or(100_000);
        let journaled = rest.iter().any(|a| a == "journaled");
        let (mut node, port) = fan_node(1);
        if journaled {
            node.start_journal(65_536);
        }
        callgrind_normal_hops(&mut node, port, n);
        println!("{n} writes through one Normal hop{}", if journaled { ", journaled" } else { "" });
        return;
    }
    // Files written by Criterion in this run are at least as new as this (minus fs granularity).
    let start = SystemTime::now() - StdDuration::from_secs(1);
    let mut c = Criterion::default()
        .warm_up_time(StdDuration::from_secs(1))
        .measurement_time(StdDuration::from_secs(3))
        .sample_size(50)
        .configure_from_args();
    benches(&mut c);
    c.final_summary();

    let dir = criterion_dir();
    let base = median_ns(&dir, BASELINE, start);
    println!();
    println!("Summary (median ns/op from this run; ratio = benchmark / {BASELINE})");
    println!("machine: {}", machine());
    println!("{:<22} {:>12} {:>10}", "benchmark", "ns/op", "ratio");
    for name in BENCHES {
        match (median_ns(&dir, name, start), base) {
            (Some(ns), Some(b)) => println!("{name:<22} {ns:>12.2} {:>9.1}x", ns / b),
            (Some(ns), None) => println!("{name:<22} {ns:>12.2} {:>10}", "n/a"),
            (None, _) => println!("{name:<22} {:>12} {:>10}", "not run", "-"),
        }
    }
    if let (Some(hop), Some(b)) = (median_ns(&dir, "normal_hop", start), base) {
        let verdict = if hop <= 10.0 * b { "met" } else { "NOT met" };
        println!("goal (one Normal hop within 10x of a function call): {verdict} ({:.1}x)", hop / b);
        if let Some(w) = median_ns(&dir, "write_no_connection", start) {
            let extra = hop - w;
            println!("  of which the hop itself (normal_hop - write_no_connection): {extra:.2} ns ({:.1}x)", extra / b);
        }
        if let Some(j) = median_ns(&dir, "normal_hop_journaled", start) {
            println!("  with the recorder's journal on: {j:.2} ns ({:.1}x the hop without it)", j / hop);
        }
        if let Some(r) = median_ns(&dir, "normal_hop_recorded", start) {
            println!("  with the flight recorder on: {r:.2} ns ({:.1}x the hop without it)", r / hop);
            let verdict = if r <= 3.0 * hop { "met" } else { "NOT met" };
            println!(
                "goal (the recorded hop within 3x the hop without it, in a tight loop: the writer is behind \
                 and the journal drops): {verdict} ({:.1}x)",
                r / hop
            );
        }
    }
    let env = |k: &str, d: u64| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    sustained(env("AYLLU_SUSTAINED_SECS", 10), env("AYLLU_SUSTAINED_RATE", 1_000_000));
}
