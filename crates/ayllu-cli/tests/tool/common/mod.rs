//! Shared by the multi-process tests: the built `ayllu` binary as child processes, their JSON
//! status lines as they arrive, network namespaces for real broadcast ([`netns`]), and cleanup
//! that always happens.
//!
//! Promises: every child is SIGKILLed and reaped when its guard drops (also when a test
//! panics); every wait has a limit; nothing here sleeps longer than a poll interval. No test
//! picks a port: a node binds port 0 and [`Proc::wait_ready`] returns the address it reports
//! on its first line (`{"listening":ADDR}`), so nothing else on the machine can take it in
//! between (docs/testing.md).

#![allow(dead_code)]

pub mod netns;
pub mod ros2;

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value as Json;

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_ayllu");

/// What a test needs and this machine cannot give it: `need` is one of `netns` (network
/// namespaces: root and `ip`), `nft` (nftables in them), `tun` (TAP interfaces for the
/// shaper), `dot` (Graphviz). The test fails here, naming what is missing, unless the environment asks to skip
/// exactly that (`AYLLU_SKIP=netns,nft,tun,dot`, a comma-separated list): then it says SKIPPED
/// loudly and the caller returns. `make test` and CI never ask, so no end-to-end test of real
/// broadcast and faults passes by skipping (docs/testing.md).
pub fn unavailable(need: &str, reason: &str) {
    // libtest names each test's thread after the test.
    let test = std::thread::current().name().unwrap_or("this test").to_owned();
    let asked = std::env::var("AYLLU_SKIP").unwrap_or_default();
    if asked.split(',').any(|n| n.trim() == need) {
        eprintln!("\n*** SKIPPED: {test}: {need} unavailable (AYLLU_SKIP={asked}): {reason} ***\n");
        return;
    }
    let how = match need {
        "netns" => "run as root with `ip` (iproute2) installed",
        "nft" => "install nftables (scripts/install-test-tools does)",
        "tun" => "give the test /dev/net/tun (the tun driver; in a container, the device and CAP_NET_ADMIN)",
        "dot" => "install Graphviz (scripts/install-test-tools does)",
        _ => "see docs/testing.md",
    };
    panic!("{test} needs {need}, which is unavailable here: {reason}; {how}, or set AYLLU_SKIP={need} to skip it");
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A running child whose stdout lines (JSON) are collected with the time they were read.
pub struct Proc {
    pub name: String,
    child: Child,
    lines: Arc<Mutex<Vec<(Instant, Json)>>>,
    /// The address from the `{"listening":ADDR}` line (kept out of `lines`).
    listening: Arc<Mutex<Option<String>>>,
    stderr: Arc<Mutex<String>>,
    /// The threads reading stdout and stderr: they end when the child's pipes close.
    readers: Vec<std::thread::JoinHandle<()>>,
    killed: bool,
}

impl Proc {
    /// Start `cmd` with stdout and stderr captured.
    pub fn spawn(name: &str, mut cmd: Command) -> Proc {
        loopback_by_default(&mut cmd);
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        let lines: Arc<Mutex<Vec<(Instant, Json)>>> = Arc::default();
        let listening: Arc<Mutex<Option<String>>> = Arc::default();
        let stderr: Arc<Mutex<String>> = Arc::default();
        let out = child.stdout.take().expect("piped stdout");
        let (sink, addr_sink) = (lines.clone(), listening.clone());
        let out_reader = std::thread::spawn(move || {
            for line in BufReader::new(out).lines() {
                let Ok(line) = line else { break };
                let read_at = Instant::now();
                if let Ok(j) = serde_json::from_str::<Json>(&line) {
                    match j["listening"].as_str() {
                        Some(addr) => *lock(&addr_sink) = Some(addr.to_owned()),
                        None => lock(&sink).push((read_at, j)),
                    }
                }
            }
        });
        let mut err = child.stderr.take().expect("piped stderr");
        let sink = stderr.clone();
        let err_reader = std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf) {
                if n == 0 {
                    break;
                }
                lock(&sink).push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        Proc {
            name: name.to_owned(),
            child,
            lines,
            listening,
            stderr,
            readers: vec![out_reader, err_reader],
            killed: false,
        }
    }

    pub fn lines(&self) -> Vec<(Instant, Json)> {
        lock(&self.lines).clone()
    }

    pub fn latest(&self) -> Option<(Instant, Json)> {
        lock(&self.lines).last().cloned()
    }

    pub fn stderr(&self) -> String {
        lock(&self.stderr).clone()
    }

    /// Wait until the node says where it listens (its socket is bound) and return that
    /// address, or panic after [`START_LIMIT`].
    pub fn wait_ready(&mut self) -> String {
        let end = Instant::now() + START_LIMIT;
        loop {
            if let Some(addr) = lock(&self.listening).clone() {
                return addr;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("{} exited with {status} before saying where it listens: {}", self.name, self.stderr());
            }
            assert!(Instant::now() < end, "{} did not start within {START_LIMIT:?}: {}", self.name, self.stderr());
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The child's exit status, if it has exited (reaped here).
    /// The child's exit status once it has exited, and then everything it wrote is in
    /// [`Proc::lines`] and [`Proc::stderr`]: a process's last lines can still be in its pipes
    /// when it is reaped, and a busy machine reads them late.
    pub fn exited(&mut self) -> Option<std::process::ExitStatus> {
        let status = self.child.try_wait().ok().flatten()?;
        // Bounded: a grandchild holding a pipe open must not hang the test.
        let end = Instant::now() + Duration::from_secs(10);
        while self.readers.iter().any(|r| !r.is_finished()) && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(5));
        }
        Some(status)
    }

    /// The child's process id (for /proc: memory, open descriptors).
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Resident memory (KiB) and open file descriptors of the child, from /proc.
    pub fn resources(&self) -> Option<(u64, usize)> {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).ok()?;
        let rss = status.lines().find_map(|l| l.strip_prefix("VmRSS:"))?.trim().trim_end_matches(" kB").trim();
        let fds = std::fs::read_dir(format!("/proc/{}/fd", self.pid())).ok()?.count();
        Some((rss.parse().ok()?, fds))
    }

    /// SIGKILL (a robot that dies without a word) and reap.
    pub fn kill(&mut self) {
        if !self.killed {
            self.killed = true;
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// What a finished CLI run left.
#[derive(Debug)]
pub struct Run {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    pub took: Duration,
}

impl Run {
    pub fn json(&self) -> Json {
        serde_json::from_str(&self.stdout).unwrap_or_else(|e| panic!("stdout is not JSON ({e}): {self:?}"))
    }
    /// Assert exit code 0 and return self.
    pub fn ok(self) -> Run {
        assert_eq!(self.code, Some(0), "expected success: {self:?}");
        self
    }
    /// Assert the exit code, that stderr says `needle`, and that nothing panicked.
    pub fn fails(self, code: i32, needle: &str) -> Run {
        assert_eq!(self.code, Some(code), "expected exit code {code}: {self:?}");
        assert!(self.stderr.contains(needle), "stderr should mention `{needle}`: {self:?}");
        assert!(!self.stderr.contains("panicked") && !self.stderr.contains("internal error"), "{self:?}");
        self
    }
}

/// Unless the test chose (set or removed `AYLLU_URL`), a command without `--udp` uses
/// loopback without discovery: tests never send multicast from the machine they share, and
/// never find nodes of other tests (docs/testing.md). The discovery tests run in namespaces.
fn loopback_by_default(cmd: &mut Command) {
    if !cmd.get_envs().any(|(k, _)| k == "AYLLU_URL") {
        cmd.env("AYLLU_URL", "udp://127.0.0.1:0");
    }
}

/// Run `cmd` to completion, killing it (and failing the test) if it takes longer than `limit`.
pub fn run(mut cmd: Command, limit: Duration) -> Run {
    loopback_by_default(&mut cmd);
    let start = Instant::now();
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("starting {cmd:?}: {e}"));
    let mut out = child.stdout.take().expect("piped stdout");
    let mut err = child.stderr.take().expect("piped stderr");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for the CLI") {
            break status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{cmd:?} ran longer than {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Run {
        code: status.code(),
        stdout: reader.join().unwrap_or_default(),
        stderr: err_reader.join().unwrap_or_default(),
        took: start.elapsed(),
    }
}

/// `ayllu ARGS...`, run to completion within `limit`.
pub fn ayllu(args: &[&str], limit: Duration) -> Run {
    let mut cmd = Command::new(BIN);
    cmd.args(args);
    run(cmd, limit)
}

/// Start `ayllu ARGS...` as nodes on loopback one after another, node k bound to port 0 and
/// told the addresses the earlier ones reported (`peer=` in its URL): the earlier ones learn
/// it from its HELLO, so the whole team knows each other. `args(k, url)` gives node k's
/// arguments (0-based) for its `--udp` URL. Returns the processes and their addresses.
pub fn start_on_loopback(
    n: usize,
    name: impl Fn(usize) -> String,
    args: impl Fn(usize, &str) -> Vec<String>,
) -> (Vec<Proc>, Vec<String>) {
    let mut procs = Vec::new();
    let mut addrs: Vec<String> = Vec::new();
    for k in 0..n {
        let peers: Vec<String> = addrs.iter().map(|a| format!("peer={a}")).collect();
        let url = format!("udp://127.0.0.1:0?{}", peers.join("&"));
        let mut cmd = Command::new(BIN);
        cmd.args(args(k, url.trim_end_matches('?')));
        let mut proc = Proc::spawn(&name(k), cmd);
        addrs.push(proc.wait_ready());
        procs.push(proc);
    }
    (procs, addrs)
}

/// How long a child may take to start and bind (a debug binary on a machine busy with other
/// builds and test suites; measured: well under a second when idle).
pub const START_LIMIT: Duration = Duration::from_secs(30);

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
