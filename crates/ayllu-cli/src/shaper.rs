//! The userspace shaper: a hub that joins robots' network namespaces and applies seeded
//! delay, jitter, reordering, duplication, loss (and, if asked, corruption) to the real
//! Ethernet frames between them — what `tc netem` would do, for kernels without it. `ayllu
//! shape` runs it (docs/testing.md); the faulted-team tests put three `ayllu node` processes
//! behind it.
//!
//! Each namespace gets a TAP device ([`Tap`], opened on `/dev/net/tun` from inside the
//! namespace): what the namespace's kernel sends on it, the shaper reads, and what the shaper
//! writes, the kernel receives. [`Hub`] is the switch between them: it learns which port each
//! source address lives behind, floods broadcast, multicast and unknown destinations (ARP and
//! the nodes' subnet-broadcast HELLOs), and passes every copy through its output port's
//! [`FaultLine`] (the schedule [`ayllu::faults::FaultySocket`] uses too), one line per port
//! with seed `seed + port`, so each robot's link has its own faults. [`run`] is the event loop
//! (`ppoll` on the TAP descriptors until the next frame is due).
//!
//! Promises: the hub never blocks and never panics on what it reads; the same seed, frames
//! and clock readings give the same faults; every frame read, every fault and every frame
//! written is counted ([`ShaperCounts`]); a frame is written no later than its due time plus
//! one loop turn; the station table is bounded ([`MAX_STATIONS`]); the TAP devices disappear
//! with the process (they are not persistent). Opening TAP devices and entering namespaces
//! needs root (CAP_NET_ADMIN, CAP_SYS_ADMIN); [`Tap::open`] says why it could not.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, RawFd};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use ayllu::{Duration, Instant};

use ayllu::clock::Clock;
use ayllu::faults::{FaultConfig, FaultCounts, FaultLine};

/// The largest frame read (a TAP's default MTU is 1500; room for jumbo frames).
pub const MAX_FRAME: usize = 65_536;
/// Source addresses remembered; the table is cleared when full (frames are then flooded until
/// the stations are learned again).
pub const MAX_STATIONS: usize = 4096;
/// Frames read from one port per loop turn, so one busy robot cannot starve the others.
pub const READS_PER_TURN: usize = 256;

/// One side of the hub: a source and sink of Ethernet frames.
pub trait FramePort {
    /// Read one waiting frame into `buf`; `Ok(None)` when none is waiting (never blocks).
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>>;
    /// Write one frame.
    fn send(&mut self, frame: &[u8]) -> io::Result<()>;
}

/// What the hub has done so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShaperCounts {
    /// Frames read from the ports.
    pub received: u64,
    /// Frames shorter than an Ethernet header, ignored.
    pub runts: u64,
    /// The faults, summed over the output ports' lines. `sent` counts copies handed to a line:
    /// one per destination port (a broadcast to two robots is two).
    pub faults: FaultCounts,
    /// Frames written to the ports.
    pub written: u64,
    /// Frames written after a frame that reached the hub later, on the same output port
    /// (reordering as the receiver sees it: by jitter, or held back behind the next frame).
    pub out_of_order: u64,
    /// Reads and writes that failed (e.g. a namespace's interface is down); the frame is lost.
    pub io_errors: u64,
}

/// The switch: frames from each port go to the others through per-port fault lines.
pub struct Hub<P> {
    ports: Vec<P>,
    /// One line per output port; the destination carried is the frame's arrival number.
    lines: Vec<FaultLine<u64>>,
    /// The arrival number of the latest-arrived frame written to each port.
    newest_written: Vec<Option<u64>>,
    arrivals: u64,
    stations: HashMap<[u8; 6], usize>,
    counts: ShaperCounts,
    buf: Vec<u8>,
}

impl<P: FramePort> Hub<P> {
    /// A hub between `ports`, the line of port `i` applying `config` with seed `config.seed + i`.
    pub fn new(ports: Vec<P>, config: &FaultConfig) -> Hub<P> {
        let lines = (0..ports.len() as u64)
            .map(|i| FaultLine::new(FaultConfig { seed: config.seed.wrapping_add(i), ..config.clone() }))
            .collect();
        Hub {
            newest_written: vec![None; ports.len()],
            ports,
            lines,
            arrivals: 0,
            stations: HashMap::new(),
            counts: ShaperCounts::default(),
            buf: vec![0; MAX_FRAME],
        }
    }

    /// The ports, in the order given.
    pub fn ports(&self) -> &[P] {
        &self.ports
    }

    /// What the hub has done so far.
    pub fn counts(&self) -> ShaperCounts {
        let mut counts = self.counts;
        for line in &self.lines {
            counts.faults += line.counts();
        }
        counts
    }

    /// Frames waiting in the lines (delayed or held back).
    #[cfg(test)]
    pub fn waiting(&self) -> usize {
        self.lines.iter().map(FaultLine::waiting).sum()
    }

    /// When the earliest delayed frame is due.
    pub fn next_due(&self) -> Option<Instant> {
        self.lines.iter().filter_map(FaultLine::next_due).min()
    }

    /// Read what is waiting on every port (at most [`READS_PER_TURN`] frames each) and
    /// forward it at `now`. Returns how many frames were read.
    pub fn receive(&mut self, now: Instant) -> usize {
        let mut buf = std::mem::take(&mut self.buf);
        let mut read = 0;
        for from in 0..self.ports.len() {
            for _ in 0..READS_PER_TURN {
                match self.ports[from].recv(&mut buf) {
                    Ok(Some(n)) => {
                        read += 1;
                        self.forward(from, &buf[..n], now);
                    }
                    Ok(None) => break,
                    Err(_) => {
                        self.counts.io_errors += 1;
                        break;
                    }
                }
            }
        }
        self.buf = buf;
        read
    }

    /// Put one frame that arrived on port `from` at `now` into the lines of the ports it goes
    /// to: the port its destination was learned behind, or every other port for broadcast,
    /// multicast and unknown destinations.
    pub fn forward(&mut self, from: usize, frame: &[u8], now: Instant) {
        self.counts.received += 1;
        if frame.len() < 14 {
            self.counts.runts += 1;
            return;
        }
        let mac = |at: usize| -> [u8; 6] { frame[at..at + 6].try_into().expect("six bytes") };
        let (dst, src) = (mac(0), mac(6));
        // The group bit marks broadcast and multicast; those are never a station's address.
        if src[0] & 1 == 0 {
            if self.stations.len() >= MAX_STATIONS && !self.stations.contains_key(&src) {
                self.stations.clear();
            }
            self.stations.insert(src, from);
        }
        let arrival = self.arrivals;
        self.arrivals += 1;
        match self.stations.get(&dst).copied().filter(|_| dst[0] & 1 == 0) {
            Some(to) if to == from => {} // already on its side
            Some(to) => self.lines[to].push(now, frame, arrival),
            None => {
                for to in (0..self.ports.len()).filter(|&to| to != from) {
                    self.lines[to].push(now, frame, arrival);
                }
            }
        }
    }

    /// Write every frame due at `now`. Returns how many were written.
    pub fn deliver(&mut self, now: Instant) -> usize {
        let mut written = 0;
        for to in 0..self.ports.len() {
            while let Some((frame, arrival)) = self.lines[to].pop_due(now) {
                let newest = &mut self.newest_written[to];
                match *newest {
                    Some(n) if arrival < n => self.counts.out_of_order += 1,
                    _ => *newest = Some(arrival),
                }
                match self.ports[to].send(&frame) {
                    Ok(()) => {
                        self.counts.written += 1;
                        written += 1;
                    }
                    Err(_) => self.counts.io_errors += 1,
                }
            }
        }
        written
    }
}

/// A TAP device: the kernel's side is a network interface (in the namespace it was opened
/// in), this side a descriptor carrying whole Ethernet frames (no packet-info header). The
/// interface goes away when this is dropped.
#[derive(Debug)]
pub struct Tap {
    file: File,
}

/// The directory where `ip netns add` puts named namespaces.
const NETNS_DIR: &str = "/run/netns";

impl Tap {
    /// Create TAP interface `name` (at most 15 bytes) in network namespace `netns` (a name
    /// `ip netns add` made, or a path such as `/proc/PID/ns/net`; `None`: this process's own).
    /// The interface is down and has no address: configure it with `ip -n NETNS`.
    pub fn open(name: &str, netns: Option<&str>) -> io::Result<Tap> {
        if name.is_empty() || name.len() >= libc::IFNAMSIZ || name.bytes().any(|b| b == 0 || b == b'/') {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, format!("`{name}` is not an interface name")));
        }
        let file = match netns {
            None => open_tap(name)?,
            Some(ns) => {
                let path = if ns.contains('/') { PathBuf::from(ns) } else { Path::new(NETNS_DIR).join(ns) };
                in_netns(&path, || open_tap(name))?
            }
        };
        Ok(Tap { file })
    }
}

/// Open `/dev/net/tun` non-blocking and attach it to a new TAP interface `name`.
fn open_tap(name: &str) -> io::Result<File> {
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_CLOEXEC)
        .open("/dev/net/tun")
        .map_err(|e| io::Error::new(e.kind(), format!("opening /dev/net/tun: {e}")))?;
    // SAFETY: `ifreq` is plain old data (arrays of integers and a union of integers and
    // pointers); all zeroes is a valid value of it.
    let mut req: libc::ifreq = unsafe { std::mem::zeroed() };
    for (dst, &b) in req.ifr_name.iter_mut().zip(name.as_bytes()) {
        *dst = b as libc::c_char;
    }
    req.ifr_ifru.ifru_flags = (libc::IFF_TAP | libc::IFF_NO_PI) as libc::c_short;
    // SAFETY: TUNSETIFF reads and writes one `struct ifreq`; `req` is one, alive and exclusively
    // borrowed for the call, its name NUL-terminated (shorter than IFNAMSIZ, zero-filled); the
    // descriptor is open and ours.
    let r = unsafe { libc::ioctl(file.as_raw_fd(), libc::TUNSETIFF, &mut req as *mut libc::ifreq) };
    if r < 0 {
        let e = io::Error::last_os_error();
        return Err(io::Error::new(e.kind(), format!("creating TAP interface {name} (TUNSETIFF): {e}")));
    }
    Ok(file)
}

/// Run `f` with this thread in the network namespace at `path`, then move the thread back.
/// What `f` creates (sockets, TAP interfaces) stays in that namespace.
fn in_netns<T>(path: &Path, f: impl FnOnce() -> io::Result<T>) -> io::Result<T> {
    let home = File::open("/proc/thread-self/ns/net")?;
    let target =
        File::open(path).map_err(|e| io::Error::new(e.kind(), format!("network namespace {}: {e}", path.display())))?;
    setns(target.as_raw_fd()).map_err(|e| io::Error::new(e.kind(), format!("entering {}: {e}", path.display())))?;
    let out = f();
    if let Err(e) = setns(home.as_raw_fd()) {
        // Staying in the robot's namespace would make every later step wrong without a word.
        panic!("could not return to this thread's network namespace: {e}");
    }
    out
}

fn setns(fd: RawFd) -> io::Result<()> {
    // SAFETY: setns only reads its arguments; `fd` is an open namespace file we hold for the
    // call, and CLONE_NEWNET asks for exactly a network namespace (anything else fails).
    if unsafe { libc::setns(fd, libc::CLONE_NEWNET) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

impl FramePort for Tap {
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        match self.file.read(buf) {
            Ok(n) => Ok(Some(n)),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted => Ok(None),
            Err(e) => Err(e),
        }
    }
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.file.write(frame).map(|_| ())
    }
}

impl AsRawFd for Tap {
    fn as_raw_fd(&self) -> RawFd {
        self.file.as_raw_fd()
    }
}

/// Run `hub` until `until` (or forever): wait on its TAP descriptors until a frame arrives or
/// one is due, forward and deliver, and every `status_every` call `status` with the time and
/// the counts (it returns `false` to stop).
pub fn run(
    hub: &mut Hub<Tap>,
    clock: &impl Clock,
    until: Option<Instant>,
    status_every: Duration,
    mut status: impl FnMut(Instant, &ShaperCounts) -> bool,
) -> io::Result<()> {
    let mut fds: Vec<libc::pollfd> =
        hub.ports().iter().map(|t| libc::pollfd { fd: t.as_raw_fd(), events: libc::POLLIN, revents: 0 }).collect();
    let mut next_status = clock.now() + status_every;
    loop {
        let now = clock.now();
        hub.deliver(now);
        if now >= next_status {
            next_status = now + status_every;
            if !status(now, &hub.counts()) {
                return Ok(());
            }
        }
        if until.is_some_and(|u| now >= u) {
            status(now, &hub.counts());
            return Ok(());
        }
        let wake = [Some(next_status), hub.next_due(), until].into_iter().flatten().min().unwrap_or(next_status);
        let wait = wake.saturating_since(now);
        let ts = libc::timespec {
            tv_sec: (wait.as_nanos() / 1_000_000_000).min(i32::MAX as u64) as libc::time_t,
            tv_nsec: (wait.as_nanos() % 1_000_000_000) as libc::c_long,
        };
        // SAFETY: `fds` holds valid, initialised pollfds for descriptors the hub owns, and we
        // pass its exact length; `ts` lives across the call; ppoll only writes `revents`.
        let r = unsafe { libc::ppoll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, &ts, std::ptr::null()) };
        if r < 0 {
            let e = io::Error::last_os_error();
            if e.kind() != io::ErrorKind::Interrupted {
                return Err(e);
            }
        }
        if r > 0 {
            hub.receive(clock.now());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::VecDeque;

    /// A port whose frames the test puts in and takes out.
    #[derive(Default)]
    struct Fake {
        inbox: VecDeque<Vec<u8>>,
        outbox: Vec<Vec<u8>>,
    }

    impl FramePort for Fake {
        fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
            Ok(self.inbox.pop_front().map(|f| {
                buf[..f.len()].copy_from_slice(&f);
                f.len()
            }))
        }
        fn send(&mut self, frame: &[u8]) -> io::Result<()> {
            self.outbox.push(frame.to_vec());
            Ok(())
        }
    }

    fn frame(dst: [u8; 6], src: [u8; 6], n: u32) -> Vec<u8> {
        [&dst[..], &src, &[0x08, 0x00], &n.to_le_bytes()].concat()
    }

    const BCAST: [u8; 6] = [0xff; 6];
    fn station(i: u8) -> [u8; 6] {
        [2, 0, 0, 0, 0, i]
    }

    fn hub(n: usize, config: FaultConfig) -> Hub<Fake> {
        Hub::new((0..n).map(|_| Fake::default()).collect(), &config)
    }

    #[test]
    fn broadcast_floods_and_unicast_goes_to_the_learned_port_only() {
        let mut h = hub(3, FaultConfig::none(1));
        let t = Instant::ZERO;
        h.ports[0].inbox.push_back(frame(BCAST, station(1), 0));
        h.receive(t);
        h.deliver(t);
        assert_eq!((h.ports[1].outbox.len(), h.ports[2].outbox.len(), h.ports[0].outbox.len()), (1, 1, 0));
        // Station 1 is now known behind port 0: a reply from port 2 goes there only.
        h.ports[2].inbox.push_back(frame(station(1), station(3), 1));
        h.receive(t);
        h.deliver(t);
        assert_eq!((h.ports[0].outbox.len(), h.ports[1].outbox.len()), (1, 1));
        // An unknown destination floods; a runt is counted and dropped.
        h.forward(1, &frame(station(9), station(2), 2), t);
        h.forward(1, &[1, 2, 3], t);
        h.deliver(t);
        assert_eq!((h.ports[0].outbox.len(), h.ports[2].outbox.len()), (2, 2));
        let c = h.counts();
        assert_eq!((c.received, c.runts, c.written, c.faults.sent, c.out_of_order), (4, 1, 5, 5, 0));
    }

    #[test]
    fn faults_are_applied_per_output_port_counted_and_seeded() {
        let config = FaultConfig {
            seed: 5,
            loss: 0.1,
            duplicate: 0.1,
            reorder: 0.1,
            corrupt: 0.0,
            delay: Duration::from_millis(20),
            jitter: Duration::from_millis(30),
        };
        let trace = |config: &FaultConfig| {
            let mut h = hub(3, config.clone());
            for i in 0..600u32 {
                let now = Instant::from_nanos(u64::from(i) * 1_000_000);
                h.forward(i as usize % 3, &frame(BCAST, station(i as u8 % 3), i), now);
                h.deliver(now);
            }
            h.deliver(Instant::from_nanos(10_000_000_000));
            (h.ports.iter().map(|p| p.outbox.clone()).collect::<Vec<_>>(), h.counts())
        };
        let (out, c) = trace(&config);
        assert_eq!(trace(&config), (out.clone(), c));
        assert_eq!((c.received, c.faults.sent), (600, 1200));
        assert!(c.faults.lost > 0 && c.faults.duplicated > 0 && c.faults.reordered > 0 && c.out_of_order > 0, "{c:?}");
        assert_eq!(c.faults.delayed, c.written);
        assert!(c.written + 3 >= c.faults.sent - c.faults.lost + c.faults.duplicated, "{c:?}");
        assert_eq!(out.iter().map(Vec::len).sum::<usize>() as u64, c.written);
        // Each port gets its own faults: the same frames, different fates.
        let numbers = |p: &Vec<Vec<u8>>| p.iter().map(|f| f[14]).collect::<Vec<_>>();
        assert_ne!(numbers(&out[0]), numbers(&out[1]));
    }

    #[test]
    fn frames_wait_for_their_delay() {
        let config = FaultConfig { delay: Duration::from_millis(30), ..FaultConfig::none(3) };
        let mut h = hub(2, config);
        h.forward(0, &frame(BCAST, station(1), 0), Instant::ZERO);
        assert_eq!(h.next_due(), Some(Instant::from_nanos(30_000_000)));
        assert_eq!(h.deliver(Instant::from_nanos(29_999_999)), 0);
        assert_eq!(h.deliver(Instant::from_nanos(30_000_000)), 1);
        assert_eq!(h.waiting(), 0);
    }
}
