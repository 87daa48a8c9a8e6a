//! What the zenoh:// test binaries share: starting `ayllu-zenoh` processes and reading their
//! JSON lines, the Relay nodes the in-process teams are made of, stepping nodes until a
//! condition holds, and scratch directories.
//!
//! Promises: every wait is bounded by the limit its caller passes (timing never decides a
//! verdict, only how long a failure takes to show); every process started here is killed and
//! reaped when its [`Proc`] drops, and every [`TempDir`] removed when it drops. Each test
//! binary uses only part of this module, hence `dead_code` allowed.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ayllu::{BehaviorClass, Node, NodeId, PortSpec, ReplyBody, RequestId, RequestStatus, Value};
use serde_json::Value as Json;

/// The tool under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_ayllu-zenoh");

/// A team key as the `key=` URL parameter and `--key` take it.
pub fn key_hex(key: &[u8; 32]) -> String {
    key.iter().map(|b| format!("{b:02x}")).collect()
}

/// Where a node opened with `listen=tcp/127.0.0.1:0` listens, as its `connect=` takes it
/// (`tcp/127.0.0.1:45125`): the port the system chose, read back from the node's Zenoh session
/// (`Transport::address`), so a test never picks a port it does not hold.
pub fn listening(node: &Node) -> String {
    let at = node.address().unwrap_or_else(|| panic!("node {} listens nowhere", node.id().0));
    assert!(!at.contains(',') && !at.ends_with(":0"), "one listener, its port resolved: {at}");
    at
}

/// The endpoint of a `{"listening":...}` line of an `ayllu-zenoh node` (or `sim robot`)
/// started with `listen=tcp/127.0.0.1:0`, as `connect=` takes it.
pub fn listening_line(j: &Json) -> String {
    let at = j["listening"].as_str().unwrap_or_else(|| panic!("no endpoint in {j}")).to_owned();
    assert!(!at.contains(',') && !at.ends_with(":0"), "one listener, its port resolved: {at}");
    at
}

/// Owned arguments for [`Proc::start`].
pub fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

/// The unsigned integers of array `field` of a status line (none if absent).
pub fn ints(j: &Json, field: &str) -> Vec<u64> {
    j[field].as_array().map(|a| a.iter().filter_map(Json::as_u64).collect()).unwrap_or_default()
}

/// Node `id` opened on `url` with Relay behaviors SRC and DST (int ports In, Out), joined to
/// `groups`.
pub fn relay_node(id: u32, url: &str, groups: &[&str]) -> Node {
    let mut node = Node::open(NodeId(id), url).unwrap_or_else(|e| panic!("open node {id} on {url}: {e}"));
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("In", 0i64)).unwrap();
    relay.port(PortSpec::new("Out", 0i64)).unwrap();
    node.define(relay).unwrap();
    node.create("Relay", "SRC").unwrap();
    node.create("Relay", "DST").unwrap();
    for g in groups {
        node.join(g);
    }
    node
}

/// Apply `step` to every node in turn until `done` holds or `limit` passes; whether it held.
pub fn run_until(
    nodes: &mut [Node],
    limit: Duration,
    mut step: impl FnMut(&mut Node),
    mut done: impl FnMut(&mut [Node]) -> bool,
) -> bool {
    let give_up = Instant::now() + limit;
    while Instant::now() < give_up {
        for n in nodes.iter_mut() {
            step(n);
        }
        if done(nodes) {
            return true;
        }
    }
    false
}

/// The answer to request `id` that node `asker` (an index) sent, stepping as [`run_until`]
/// does; panics if the request failed or no answer came within `limit`.
pub fn answer(
    nodes: &mut [Node],
    asker: usize,
    id: RequestId,
    limit: Duration,
    step: impl FnMut(&mut Node),
) -> ReplyBody {
    let mut reply = None;
    let answered = run_until(nodes, limit, step, |nodes| match nodes[asker].core().request_status(id) {
        Some(RequestStatus::Done(body)) => {
            reply = Some(body);
            true
        }
        Some(RequestStatus::Failed(text)) => panic!("request failed: {text}"),
        _ => false,
    });
    assert!(answered, "no answer within {limit:?}");
    reply.unwrap()
}

/// What port `port` of behavior `behavior` holds.
pub fn read(node: &Node, behavior: &str, port: &str) -> Value {
    node.read(behavior, port).unwrap()
}

/// The transport's counter `cause` (0 if it never counted one).
pub fn count(node: &Node, cause: &str) -> u64 {
    node.transport_counters().iter().find(|(c, _)| c == cause).map_or(0, |(_, n)| *n)
}

/// Poll `check` every `every` until it returns `Some`, or `None` after `limit`.
pub fn wait_for<T>(limit: Duration, every: Duration, mut check: impl FnMut() -> Option<T>) -> Option<T> {
    let end = Instant::now() + limit;
    loop {
        if let Some(t) = check() {
            return Some(t);
        }
        if Instant::now() >= end {
            return None;
        }
        std::thread::sleep(every);
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A reader thread that panicked leaves what it collected, which is still worth reporting.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A child process whose stdout JSON lines are collected with the time they were read, and
/// its stderr kept for [`Proc::report`]; killed and reaped when dropped.
pub struct Proc {
    pub name: String,
    // Behind a lock so waiting (which asks whether it exited) needs only `&self`.
    child: Mutex<Child>,
    lines: Arc<Mutex<Vec<(Instant, Json)>>>,
    stderr: Arc<Mutex<String>>,
    killed: bool,
}

impl Proc {
    /// `ayllu-zenoh ARGS`, called `name` in reports.
    pub fn start(name: &str, args: &[String]) -> Proc {
        let mut cmd = Command::new(BIN);
        cmd.args(args);
        Proc::spawn(name, cmd)
    }

    /// Start `cmd` (stdin closed, stdout and stderr read by threads of their own so the pipes
    /// never fill).
    pub fn spawn(name: &str, mut cmd: Command) -> Proc {
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        let lines: Arc<Mutex<Vec<(Instant, Json)>>> = Arc::default();
        let stderr: Arc<Mutex<String>> = Arc::default();
        let (out, mut err) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
        let sink = lines.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if let Ok(j) = serde_json::from_str::<Json>(&line) {
                    lock(&sink).push((Instant::now(), j));
                }
            }
        });
        let sink = stderr.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf) {
                if n == 0 {
                    break;
                }
                lock(&sink).push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        Proc { name: name.to_owned(), child: Mutex::new(child), lines, stderr, killed: false }
    }

    /// Every JSON line so far, with the time it was read.
    pub fn timed_lines(&self) -> Vec<(Instant, Json)> {
        lock(&self.lines).clone()
    }

    /// Every JSON line so far.
    pub fn lines(&self) -> Vec<Json> {
        lock(&self.lines).iter().map(|(_, j)| j.clone()).collect()
    }

    /// The latest status line (one with a `t`).
    pub fn latest(&self) -> Option<Json> {
        lock(&self.lines).iter().rev().find(|(_, j)| j.get("t").is_some()).map(|(_, j)| j.clone())
    }

    /// The first line (from the start) for which `pick` holds, waited for at most `limit`;
    /// `None` once the limit passed, or at once if the process exited without printing one.
    pub fn wait_line(&self, limit: Duration, mut pick: impl FnMut(&Json) -> bool) -> Option<Json> {
        let end = Instant::now() + limit;
        loop {
            // Whether it had exited is read before the lines, so a last line is never missed.
            let exited = matches!(lock(&self.child).try_wait(), Ok(Some(_)));
            if let Some((_, j)) = lock(&self.lines).iter().find(|(_, j)| pick(j)) {
                return Some(j.clone());
            }
            if exited || Instant::now() >= end {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// As [`Proc::wait_line`], panicking with [`Proc::report`] if no such line came.
    pub fn expect_line(&self, limit: Duration, pick: impl FnMut(&Json) -> bool) -> Json {
        self.wait_line(limit, pick).unwrap_or_else(|| {
            let status = lock(&self.child).try_wait().ok().flatten();
            let how = status.map_or("still running".to_owned(), |s| format!("exited ({s})"));
            panic!("{}: no such line within {limit:?}, {how}\n{}", self.name, self.report())
        })
    }

    /// The last three lines and the whole stderr, for a failure's message.
    pub fn report(&self) -> String {
        let tail: Vec<String> = self.timed_lines().iter().rev().take(3).map(|(_, j)| j.to_string()).collect();
        format!("--- {}: last lines {tail:#?}\nstderr: {}", self.name, lock(&self.stderr))
    }

    /// Kill and reap the process (once).
    pub fn kill(&mut self) {
        if !self.killed {
            self.killed = true;
            let child = self.child.get_mut().unwrap_or_else(|e| e.into_inner());
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Run `ayllu-zenoh ARGS --udp URL --timeout 15` to the end (killed after `limit`), calling
/// `meanwhile` between polls (stepping a node the tool talks to, or sleeping); its output,
/// printed for --nocapture and a failure's report.
pub fn run_tool(args: &[&str], url: &str, limit: Duration, mut meanwhile: impl FnMut()) -> Output {
    let mut child = Command::new(BIN)
        .args(args)
        .args(["--udp", url, "--timeout", "15"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ayllu-zenoh");
    let give_up = Instant::now() + limit;
    while child.try_wait().expect("poll the tool").is_none() && Instant::now() < give_up {
        meanwhile();
    }
    if child.try_wait().expect("poll the tool").is_none() {
        let _ = child.kill();
    }
    let out = child.wait_with_output().expect("the tool's output");
    println!(
        "$ ayllu-zenoh {}\n{}{}",
        args.join(" "),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A directory of this test run, removed when dropped.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// A new directory under the system's temporary directory, named after `tag`, this
    /// process and the time.
    pub fn new(tag: &str) -> TempDir {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().subsec_nanos();
        let dir = std::env::temp_dir().join(format!("ayllu-{tag}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create a temporary directory");
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
