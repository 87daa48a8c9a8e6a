//! A wire-level mutation run against live nodes: `make fuzz-long`'s last step (issue 18,
//! docs/reliability.md).
//!
//! `live_wire_mutation AYLLU_BIN [--datagrams N] [--max-secs S] [--rate HZ] [--seed S]` starts
//! two real `ayllu node` processes (the paper's cross-subsumption controller, team 7) on
//! loopback, one open and one keyed with the golden vectors' key, each on a port the system
//! chose (read from its `{"listening":ADDR}` line). It sends them, over real UDP from a socket
//! of its own on loopback, up to N datagrams (default 2 million, at most S seconds, default
//! 900) made by mutating the golden vectors of spec/vectors/ (bit flips, interesting values,
//! insertions, deletions, truncations, splices of two vectors), paced at HZ datagrams a second
//! (default 20,000) so that the nodes read them rather than the kernel dropping them.
//!
//! Promises: it exits 0 only if, afterwards, both nodes are alive, answer a LIST (`ayllu list
//! NODE`), still accept a well-formed write (`ayllu write`, confirmed by the node), and kept
//! their resident memory within twice its settled figure + 16 MiB. It prints the figures: the
//! datagrams sent, each node's transport counters (received, and every drop cause) and its
//! memory. It sends only to the loopback ports its own nodes hold, and stops by itself.

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, UdpSocket};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The team of the golden vectors.
const TEAM: u32 = 7;
/// The longest window a mutated datagram may open on a node (`--max-window`): the checks at
/// the end wait this long, so that no window the flood legitimately opened still blocks them.
const MAX_WINDOW_SECS: f64 = 1.0;
/// Datagrams above the nodes' 8192-byte limit are made too, to exercise it; not beyond this.
const MAX_LEN: usize = 9000;
/// The tool's node ids in the end checks: a mutated sender id is unlikely to be one of these,
/// so no sequence number the flood sent stands in the way of its well-formed requests. Each
/// call gets its own: a node remembers the requests it answered by sender and request id, and
/// a second process with the same id would reuse the first one's request ids and be answered
/// from that memory.
const CHECKER_IDS: u32 = 0x7fff_ff00;

type Failure = Box<dyn std::error::Error>;

/// splitmix64: a seeded, reproducible stream (the run prints its seed).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// A number below `n` (n > 0).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// One mutation of `d`, with `other` (another vector) for splices.
fn mutate_once(rng: &mut Rng, d: &mut Vec<u8>, other: &[u8]) {
    const INTERESTING: [u64; 8] = [0, 1, 0x7f, 0x80, 0xff, 0x7fff_ffff, u32::MAX as u64, u64::MAX];
    if d.is_empty() {
        d.push(rng.next() as u8);
        return;
    }
    match rng.below(8) {
        0 => {
            let i = rng.below(d.len() * 8);
            d[i / 8] ^= 1 << (i % 8);
        }
        1 => {
            let i = rng.below(d.len());
            d[i] = rng.next() as u8;
        }
        2 => {
            // A 1-, 2-, 4- or 8-byte field set to a boundary value (lengths, counts, periods).
            let width = 1 << rng.below(4);
            let i = rng.below(d.len());
            let v = INTERESTING[rng.below(INTERESTING.len())].to_le_bytes();
            for (k, b) in v.iter().take(width).enumerate() {
                if let Some(x) = d.get_mut(i + k) {
                    *x = *b;
                }
            }
        }
        3 => {
            let i = rng.below(d.len() + 1);
            let n = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            d.splice(i..i, bytes);
        }
        4 => {
            let i = rng.below(d.len());
            let n = 1 + rng.below(d.len() - i);
            d.drain(i..i + n);
        }
        5 => d.truncate(rng.below(d.len())),
        6 => {
            // A range repeated: messages appended to a datagram, up to and past the limit.
            let i = rng.below(d.len());
            let n = 1 + rng.below(d.len() - i);
            let most = if rng.below(8) == 0 { 400 } else { 4 };
            let times = 1 + rng.below(most);
            let range = d[i..i + n].to_vec();
            for _ in 0..times {
                d.splice(i..i, range.iter().copied());
            }
        }
        _ => {
            // Splice: this datagram's head with another's tail.
            let cut = rng.below(d.len() + 1);
            let from = rng.below(other.len() + 1);
            d.truncate(cut);
            d.extend_from_slice(&other[from..]);
        }
    }
    d.truncate(MAX_LEN);
}

/// A datagram for the flood: a golden vector, mostly mutated (1 to 8 mutations).
fn mutant(rng: &mut Rng, vectors: &[Vec<u8>]) -> Vec<u8> {
    let mut d = vectors[rng.below(vectors.len())].clone();
    if rng.below(16) == 0 {
        return d; // unchanged now and then: replays of well-formed datagrams
    }
    let n = 1 + rng.below(8);
    for _ in 0..n {
        let other = &vectors[rng.below(vectors.len())];
        mutate_once(rng, &mut d, other);
    }
    d
}

fn hex(text: &str) -> Result<Vec<u8>, Failure> {
    if !text.len().is_multiple_of(2) || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("`{text}` is not hex").into());
    }
    (0..text.len()).step_by(2).map(|i| Ok(u8::from_str_radix(&text[i..i + 2], 16)?)).collect()
}

/// The golden vectors' datagrams and their team key.
fn golden() -> Result<(Vec<Vec<u8>>, String), Failure> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors/vectors.json");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path)?)?;
    let key = json["key_hex"].as_str().ok_or("vectors.json has no key_hex")?.to_owned();
    let vectors = json["vectors"].as_array().ok_or("vectors.json has no vectors")?;
    let datagrams = vectors.iter().map(|v| hex(v["hex"].as_str().unwrap_or_default())).collect::<Result<_, _>>()?;
    Ok((datagrams, key))
}

/// A running `ayllu node`: its address, its latest status line, its process.
struct LiveNode {
    id: u32,
    name: String,
    url_extra: String,
    child: Child,
    addr: SocketAddr,
    status: Arc<Mutex<serde_json::Value>>,
    settled_rss_kib: u64,
    max_rss_kib: u64,
}

impl LiveNode {
    fn start(ayllu: &str, id: u32, name: &str, url_extra: &str) -> Result<LiveNode, Failure> {
        let url = format!("udp://127.0.0.1:0?team={TEAM}{url_extra}");
        let mut child = Command::new(ayllu)
            .args(["node", "--id", &id.to_string(), "--udp", &url, "--status-ms", "500", "--sight", "1:0.9,2:0.5"])
            .args(["--max-window", &MAX_WINDOW_SECS.to_string()])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()?;
        let mut lines = BufReader::new(child.stdout.take().ok_or("no stdout")?).lines();
        let first = lines.next().ok_or("the node printed nothing")??;
        let listening: serde_json::Value = serde_json::from_str(&first)?;
        let addr: SocketAddr =
            listening["listening"].as_str().ok_or_else(|| format!("no listening address in {first}"))?.parse()?;
        let status = Arc::new(Mutex::new(serde_json::Value::Null));
        let sink = status.clone();
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                if let Ok(j) = serde_json::from_str::<serde_json::Value>(&line) {
                    *sink.lock().unwrap_or_else(|e| e.into_inner()) = j;
                }
            }
        });
        Ok(LiveNode {
            id,
            name: name.to_owned(),
            url_extra: url_extra.to_owned(),
            child,
            addr,
            status,
            settled_rss_kib: 0,
            max_rss_kib: 0,
        })
    }

    fn alive(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Resident memory (VmRSS), KiB.
    fn rss_kib(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).unwrap_or_default();
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
            .unwrap_or(0)
    }

    fn sample(&mut self) {
        self.max_rss_kib = self.max_rss_kib.max(self.rss_kib());
    }

    /// Run the `ayllu` tool against this node (its URL reaches the node as a peer).
    fn tool(&self, ayllu: &str, checker: u32, args: &[&str]) -> Result<String, Failure> {
        let url = format!("udp://127.0.0.1:0?team={TEAM}{}&peer={}", self.url_extra, self.addr);
        let id = (CHECKER_IDS + checker).to_string();
        let out = Command::new(ayllu)
            .args(args)
            .args(["--udp", &url, "--id", &id, "--timeout", "10"])
            .stdin(Stdio::null())
            .output()?;
        if !out.status.success() {
            return Err(format!(
                "`ayllu {}` against {} failed ({}): {}",
                args.join(" "),
                self.name,
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            )
            .into());
        }
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    }

    fn counters(&self) -> serde_json::Value {
        self.status.lock().unwrap_or_else(|e| e.into_inner())["counters"]["transport"].clone()
    }

    fn stop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for LiveNode {
    fn drop(&mut self) {
        self.stop();
    }
}

fn flag<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> Result<T, Failure> {
    match args.iter().position(|a| a == name) {
        Some(i) => args.get(i + 1).and_then(|v| v.parse().ok()).ok_or_else(|| format!("{name} needs a number").into()),
        None => Ok(default),
    }
}

fn run() -> Result<(), Failure> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let ayllu = args
        .first()
        .filter(|a| !a.starts_with("--"))
        .ok_or("usage: live_wire_mutation AYLLU_BIN [--datagrams N] [--max-secs S] [--rate HZ] [--seed S]")?
        .clone();
    let total: u64 = flag(&args, "--datagrams", 2_000_000)?;
    let max_secs: f64 = flag(&args, "--max-secs", 900.0)?;
    let rate: f64 = flag(&args, "--rate", 20_000.0)?;
    let seed: u64 = flag(&args, "--seed", 1)?;
    if !(rate > 0.0 && max_secs > 0.0) {
        return Err("--rate and --max-secs must be above 0".into());
    }

    let (vectors, key) = golden()?;
    // Ids no golden vector sends from: a datagram claiming the node's own id is dropped early
    // (duplicate_id), and the flood should reach deeper.
    let mut nodes = [
        LiveNode::start(&ayllu, 41, "n41 (open)", "")?,
        LiveNode::start(&ayllu, 42, "n42 (keyed)", &format!("&key={key}"))?,
    ];
    std::thread::sleep(Duration::from_secs(1));
    for n in &mut nodes {
        n.settled_rss_kib = n.rss_kib();
        n.max_rss_kib = n.settled_rss_kib;
    }
    println!(
        "live mutation run: {} golden vectors, seed {seed}, up to {total} datagrams at {rate} a second for at most {max_secs} s, to {} and {}",
        vectors.len(),
        nodes[0].addr,
        nodes[1].addr
    );

    let socket = UdpSocket::bind("127.0.0.1:0")?;
    let mut rng = Rng(seed);
    let started = Instant::now();
    let mut sent = 0u64;
    let mut send_errors = 0u64;
    let mut last_report = Instant::now();
    while sent < total && started.elapsed().as_secs_f64() < max_secs {
        let d = mutant(&mut rng, &vectors);
        let to = nodes[(sent % 2) as usize].addr;
        if socket.send_to(&d, to).is_err() {
            send_errors += 1; // e.g. ECONNREFUSED from an earlier datagram: counted, not fatal
        }
        sent += 1;
        if sent.is_multiple_of(256) {
            // Pace: no faster than `rate` on average.
            let due = Duration::from_secs_f64(sent as f64 / rate);
            if let Some(wait) = due.checked_sub(started.elapsed()) {
                std::thread::sleep(wait);
            }
            if last_report.elapsed() >= Duration::from_secs(10) {
                last_report = Instant::now();
                for n in &mut nodes {
                    if !n.alive() {
                        return Err(format!("{} died after {sent} datagrams", n.name).into());
                    }
                    n.sample();
                }
                println!(
                    "  {sent} sent in {:.0} s; RSS {} / {} KiB",
                    started.elapsed().as_secs_f64(),
                    nodes[0].rss_kib(),
                    nodes[1].rss_kib()
                );
            }
        }
    }
    let secs = started.elapsed().as_secs_f64();
    println!("sent {sent} datagrams in {secs:.1} s ({:.0} a second; {send_errors} send errors)", sent as f64 / secs);

    // Let any window the flood opened lapse, and a status line with the final counters come.
    std::thread::sleep(Duration::from_secs_f64(MAX_WINDOW_SECS + 1.0));
    let mut failures = Vec::new();
    for n in &mut nodes {
        n.sample();
        if !n.alive() {
            failures.push(format!("{} is dead", n.name));
            continue;
        }
        match n.tool(&ayllu, 2 * n.id, &["list", &n.id.to_string(), "--json"]) {
            Ok(out) if out.contains("\"behaviors\"") || out.contains("BASE") => {}
            Ok(out) => failures.push(format!("{}: LIST answered without its behaviors: {out}", n.name)),
            Err(e) => failures.push(e.to_string()),
        }
        if let Err(e) = n.tool(
            &ayllu,
            2 * n.id + 1,
            &["write", &n.id.to_string(), "BASE.Rotate", "0.25", "--kind", "override-in", "--period", "1"],
        ) {
            failures.push(e.to_string());
        }
        let bound = 2 * n.settled_rss_kib + 16 * 1024;
        let rss = n.rss_kib();
        println!(
            "{}: alive; RSS settled {} KiB, max {} KiB, now {rss} KiB (bound {bound}); transport counters {}",
            n.name,
            n.settled_rss_kib,
            n.max_rss_kib,
            n.counters()
        );
        if n.max_rss_kib > bound {
            failures.push(format!("{}: resident memory grew to {} KiB (bound {bound})", n.name, n.max_rss_kib));
        }
    }
    if failures.is_empty() {
        println!("live mutation run: clean (both nodes alive, answer LIST, accept a write, memory bounded)");
        Ok(())
    } else {
        Err(failures.join("; ").into())
    }
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("live_wire_mutation: FAILED: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
