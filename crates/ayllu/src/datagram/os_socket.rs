//! [`OsSocket`], the real UDP socket, as every platform has it: its state, the read-ahead
//! buffer it hands datagrams out of, when an empty finding may stand (`RECHECK`), when a wait
//! polls first (`SPIN`), and the [`DatagramSocket`] methods. It keeps the trait's promises:
//! sends and receives never block, a wait ends by its timeout, OS errors come back as errors.
//!
//! The system calls that are Linux's own (`recvmmsg`, `ppoll`, `sendto` on the blocking main
//! socket, segmented sends) are in `linux.rs`; the `cfg(target_os = "linux")` lines left here
//! only call into it, and the `cfg(not(target_os = "linux"))` ones are the fallbacks elsewhere.

use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::time::Duration as StdDuration;

use ayllu_core::Instant;

#[cfg(target_os = "linux")]
use super::linux::{ppoll, MmsgCall, BLOCKING_WAIT_MIN};
use super::DatagramSocket;

/// A real UDP socket: non-blocking, broadcast allowed. The main socket is *exclusive*: binding
/// an address another socket holds fails (`AddrInUse`) instead of silently sharing it, since a
/// second node on a node's address would take its unicast traffic (a lingering process after a
/// robot restart). Only the receive-only sockets for broadcast and multicast addresses are
/// shared (`SO_REUSEADDR`), so several nodes on one host can all hear their team's broadcasts.
///
/// A socket bound to a unicast address (`10.0.0.1:7400`) does not receive datagrams sent to a
/// broadcast or multicast address (the kernel matches the destination against the bound
/// address). [`OsSocket::listen_also`] adds receive-only sockets bound to those addresses, so
/// a node bound to its own address still hears its team's broadcasts; sends always leave from
/// the main socket, so peers learn the node's unicast address.
pub struct OsSocket {
    pub(super) socket: UdpSocket,
    /// Receive-only sockets for broadcast and multicast addresses the main one cannot hear.
    pub(super) extra: Vec<UdpSocket>,
    /// Datagrams read from the main socket ahead of `recv_from`.
    pub(super) ahead: ReadAhead,
    /// Until when (turn time) the sockets count as empty: they were found empty `recheck` before, and
    /// until then `recv_from` answers "nothing waiting" without asking the kernel again.
    pub(super) empty_until: Option<Instant>,
    /// See [`DatagramSocket::set_recheck`].
    recheck: StdDuration,
    /// The current turn's time ([`DatagramSocket::set_turn_time`]).
    turn_time: Instant,
    /// A wait read the socket empty: the next turn counts it empty from its own time.
    pub(super) waited_empty: bool,
    /// The main socket's receive timeout (`SO_RCVTIMEO`) as last set, for blocking waits.
    #[cfg(target_os = "linux")]
    pub(super) receive_timeout: StdDuration,
    /// Reads have been finding several datagrams waiting: a blocking wait reads with
    /// `recvmmsg` (see `receive_waiting`).
    #[cfg(target_os = "linux")]
    pub(super) dense: bool,
    /// Blocking waits read with a plain `recvfrom` since the last `recvmmsg`.
    #[cfg(target_os = "linux")]
    pub(super) sparse_waits: u8,
    /// When a read last found datagrams (wall clock), and how many reads in a row found them
    /// less than [`SPIN`] after the read before: a stream, for which a wait polls first.
    pub(super) last_data: Option<std::time::Instant>,
    pub(super) streak: u8,
    /// How long a wait may poll ([`SPIN`] unless the URL's `spin_us` says otherwise); zero:
    /// no two reads are ever that close, so no streak builds and no wait polls.
    pub(super) spin: StdDuration,
    /// Empty findings in a row since a read last found datagrams: the next one stands for
    /// `recheck` doubled this many times ([`RECHECK_DOUBLINGS`] at most).
    quiet: u32,
    /// Sent something since a read last found datagrams: what comes next may be a peer's
    /// answer, and that peer may need this very CPU to make it, so a wait does not poll.
    pub(super) sent_since_read: bool,
    /// Whether the kernel takes segmented sends (UDP GSO, Linux 4.18 and later, and a route
    /// whose device can checksum them): false after the first refusal, and every train is
    /// then sent one datagram per call.
    #[cfg(target_os = "linux")]
    pub(super) segmented: bool,
}

/// How long a finding that the sockets are empty stands, for a node on a real-time clock: a
/// node that steps in a tight loop without waiting asks the kernel at most once per `RECHECK`
/// (a datagram arriving meanwhile is read up to this much later), instead of once per turn. A
/// node that waits reads in the wait itself, at once. Why: a turn's receive attempt that
/// finds nothing is a system call as expensive as the send the turn makes; a sender stepping
/// once per message paid two calls per message instead of raw UDP's one.
pub const RECHECK: StdDuration = StdDuration::from_micros(20);
/// An empty finding that follows empty findings stands longer: twice as long as the one before,
/// up to `RECHECK` doubled this many times (160 µs); a read that finds datagrams starts again
/// from `RECHECK`. Why: a node that only sends (a busy sender stepping once per message) found
/// the socket empty every 20 µs, one wasted system call per few messages, about a tenth of its
/// time per message on this kind of machine (docs/performance.md); a node that hears traffic
/// keeps the 20 µs, and a node that waits reads in the wait, at once, whatever this says.
pub const RECHECK_DOUBLINGS: u32 = 3;

/// How long a wait polls the socket before it sleeps, while datagrams stream in (each of the
/// last two reads found datagrams less than this after the one before) on a node with a
/// real-time clock: a receiver asleep in the kernel must be woken by every datagram, which the
/// sender pays for in its send (on this kind of machine about a sixth of raw UDP's one-way
/// rate: docs/performance.md), while one that polls takes the datagram without a wake-up.
/// Bounded, and every poll that finds nothing yields the CPU (`sched_yield`), so a peer
/// waiting for this CPU runs first; sparse traffic (a robot team's 20 Hz) never polls, and
/// neither does a node that sent since its last read: what it waits for may be the answer,
/// which the peer may need this CPU to make (a round trip with both ends on one CPU was 10-20 %
/// slower polling, even yielding).
pub const SPIN: StdDuration = StdDuration::from_micros(50);
/// Reads in a row that found datagrams less than [`SPIN`] apart before a wait polls.
pub(super) const STREAK: u8 = 2;

/// Datagrams the main socket delivered in one system call (`recvmmsg(2)` on Linux), handed
/// out one per `recv_from`. Under load that is one call for up to [`READ_AHEAD`] datagrams
/// instead of one each. At any load it saves the call that only answers "nothing more": a
/// read that filled fewer slots than it offered shows the socket was empty at that moment, so
/// once those datagrams are handed out, `recv_from` says "nothing waiting" without asking the
/// kernel again for [`RECHECK`] (and `wait` reads at once whatever arrived since).
pub(super) struct ReadAhead {
    /// `READ_AHEAD` slots of `SLOT` bytes.
    pub(super) data: Vec<u8>,
    /// Length and sender of the datagram in each filled slot.
    pub(super) got: Vec<(usize, SocketAddr)>,
    pub(super) next: usize,
    pub(super) drained: bool,
    /// The `recvmmsg` arguments, made once: setting them up each call cost more than the rest
    /// of a loop turn's receive path.
    #[cfg(target_os = "linux")]
    pub(super) call: Box<MmsgCall>,
}

/// Datagrams read by one system call, at most.
pub(super) const READ_AHEAD: usize = 16;
/// A slot holds the largest datagram accepted plus one byte, so a longer one is seen as such
/// (and dropped as `oversized` by the transport), as with a `recvfrom` buffer of that size.
pub(super) const SLOT: usize = crate::udp_config::MAX_DATAGRAM + 1;

impl ReadAhead {
    fn new() -> ReadAhead {
        let mut data = vec![0; READ_AHEAD * SLOT];
        #[cfg(target_os = "linux")]
        let call = MmsgCall::new(&mut data);
        ReadAhead {
            data,
            got: Vec::with_capacity(READ_AHEAD),
            next: 0,
            drained: false,
            #[cfg(target_os = "linux")]
            call,
        }
    }

    pub(super) fn pending(&self) -> bool {
        self.next < self.got.len()
    }

    /// The next datagram read ahead, copied into `buf` (cut to its length, like UDP).
    fn pop(&mut self, buf: &mut [u8]) -> Option<(usize, SocketAddr)> {
        let &(len, from) = self.got.get(self.next)?;
        self.next += 1;
        let n = len.min(buf.len());
        let start = (self.next - 1) * SLOT;
        buf[..n].copy_from_slice(&self.data[start..start + n]);
        Some((n, from))
    }

    /// Elsewhere: one `recvfrom` per call, and no claim that the socket is empty.
    #[cfg(not(target_os = "linux"))]
    fn fill(&mut self, socket: &UdpSocket) -> io::Result<()> {
        self.got.clear();
        self.next = 0;
        let (n, from) = socket.recv_from(&mut self.data[..SLOT])?;
        self.got.push((n, from));
        Ok(())
    }
}

/// A receive error that only means "nothing to read now".
pub(super) fn nothing_waiting(e: &io::Error) -> bool {
    // ICMP port-unreachable from an earlier send surfaces as ConnectionRefused on Linux.
    matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::ConnectionRefused)
}

/// A non-blocking UDP socket bound to `addr`; `shared` lets other sockets bind it too (for
/// broadcast and multicast addresses only).
fn os_socket(addr: SocketAddr, shared: bool) -> io::Result<UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let socket = Socket::new(Domain::for_address(addr), Type::DGRAM, Some(Protocol::UDP))?;
    socket.set_reuse_address(shared)?;
    socket.set_broadcast(true)?;
    socket.set_nonblocking(true)?;
    // Bigger buffers absorb bursts of batched datagrams without loss.
    let _ = socket.set_recv_buffer_size(1 << 21);
    let _ = socket.set_send_buffer_size(1 << 21);
    socket.bind(&addr.into())?;
    if addr.ip().is_ipv4() {
        let _ = socket.set_multicast_loop_v4(true);
    }
    Ok(socket.into())
}

impl OsSocket {
    /// An exclusive, non-blocking socket bound to `addr` (port 0: the system chooses).
    pub fn bind(addr: SocketAddr) -> io::Result<OsSocket> {
        let socket = os_socket(addr, false)?;
        // On Linux the main socket itself blocks, so that a wait can be the receive (see
        // `wait`); every other call on it passes MSG_DONTWAIT, so none of them blocks.
        #[cfg(target_os = "linux")]
        socket.set_nonblocking(false)?;
        Ok(OsSocket {
            socket,
            extra: Vec::new(),
            ahead: ReadAhead::new(),
            empty_until: None,
            recheck: StdDuration::ZERO,
            turn_time: Instant::ZERO,
            waited_empty: false,
            #[cfg(target_os = "linux")]
            receive_timeout: StdDuration::ZERO,
            #[cfg(target_os = "linux")]
            segmented: true,
            #[cfg(target_os = "linux")]
            dense: false,
            #[cfg(target_os = "linux")]
            sparse_waits: 0,
            last_data: None,
            streak: 0,
            spin: SPIN,
            quiet: 0,
            sent_since_read: false,
        })
    }

    /// A read found datagrams: extend or restart the streak that makes a wait poll first
    /// ([`SPIN`]). Only on a real-time clock (a non-zero `recheck`): on a manual clock a wait is
    /// never asked to poll.
    pub(super) fn got_data(&mut self) {
        self.quiet = 0;
        self.sent_since_read = false;
        if self.recheck.is_zero() {
            return;
        }
        let now = std::time::Instant::now();
        let close = self.last_data.is_some_and(|t| now.duration_since(t) < self.spin);
        self.streak = if close { self.streak.saturating_add(1) } else { 0 };
        self.last_data = Some(now);
    }

    /// The sockets were found empty now: the finding stands for `recheck` of turn time (not at
    /// all when it is zero).
    fn found_empty(&mut self) {
        if !self.recheck.is_zero() {
            let stands = self.recheck * (1u32 << self.quiet);
            self.empty_until = Some(self.turn_time + ayllu_core::Duration::from_nanos(stands.as_nanos() as u64));
            self.quiet = (self.quiet + 1).min(RECHECK_DOUBLINGS);
        }
    }

    /// Also receive datagrams sent to `addr` (a broadcast or multicast address), unless the
    /// main socket already does (bound to the unspecified address on the same port).
    pub fn listen_also(&mut self, addr: SocketAddr) -> io::Result<()> {
        let main = self.socket.local_addr()?;
        if main.ip().is_unspecified() && main.port() == addr.port() {
            return Ok(());
        }
        if self.extra.iter().any(|s| s.local_addr().ok() == Some(addr)) {
            return Ok(());
        }
        self.extra.push(os_socket(addr, true)?);
        Ok(())
    }
}

/// What a send's result means for the caller: a full send buffer loses the datagram, as the
/// network would (best effort, N1), and is not an error.
fn sent(result: io::Result<()>) -> io::Result<()> {
    match result {
        Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(()),
        other => other,
    }
}

impl DatagramSocket for OsSocket {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
        self.sent_since_read = true;
        // The main socket blocks on Linux (see `bind`): this send must not.
        #[cfg(target_os = "linux")]
        {
            sent(self.send_unblocking(bytes, to))
        }
        #[cfg(not(target_os = "linux"))]
        sent(self.socket.send_to(bytes, to).map(|_| ()))
    }
    fn send_segments(&mut self, bytes: &[u8], segment: usize, to: SocketAddr) -> io::Result<()> {
        self.sent_since_read = true;
        #[cfg(target_os = "linux")]
        if self.sent_in_one_call(bytes, segment, to) {
            return Ok(());
        }
        for datagram in bytes.chunks(segment.max(1)) {
            self.send_to(datagram, to)?;
        }
        Ok(())
    }
    fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<Option<(usize, SocketAddr)>> {
        if let Some(got) = self.ahead.pop(buf) {
            return Ok(Some(got));
        }
        // Found empty a moment ago (by a read that emptied the socket, or by the wait): the
        // answer stands for RECHECK of turn time.
        if let Some(until) = self.empty_until {
            if self.turn_time < until {
                return Ok(None);
            }
            self.empty_until = None;
        }
        // Asking now: what a wait found before no longer counts.
        self.waited_empty = false;
        match self.ahead.fill(&self.socket) {
            Ok(()) => {
                #[cfg(target_os = "linux")]
                if self.ahead.got.len() > 1 {
                    self.dense = true;
                }
                if !self.ahead.got.is_empty() {
                    self.got_data();
                }
                if self.ahead.drained && self.extra.is_empty() {
                    self.found_empty();
                }
                if let Some(got) = self.ahead.pop(buf) {
                    return Ok(Some(got));
                }
            }
            Err(e) if nothing_waiting(&e) => {}
            Err(e) => return Err(e),
        }
        for socket in &self.extra {
            match socket.recv_from(buf) {
                Ok((n, from)) => return Ok(Some((n, from))),
                Err(e) if nothing_waiting(&e) => {}
                Err(e) => return Err(e),
            }
        }
        self.found_empty();
        Ok(None)
    }
    fn wait(&mut self, timeout: StdDuration) {
        use std::os::fd::AsRawFd;
        if self.ahead.pending() {
            return;
        }
        #[cfg(target_os = "linux")]
        let timeout = match self.poll_stream(timeout) {
            None => return,
            Some(spent) => timeout.saturating_sub(spent),
        };
        #[cfg(target_os = "linux")]
        let timeout = if self.extra.is_empty() && timeout >= BLOCKING_WAIT_MIN {
            let started = std::time::Instant::now();
            if self.receive_waiting(timeout) {
                return;
            }
            // Timed out early by design: sleep out the rest to the nanosecond.
            timeout.saturating_sub(started.elapsed())
        } else {
            timeout
        };
        // Whatever ppoll finds, the next receive asks the kernel.
        self.empty_until = None;
        self.waited_empty = false;
        let pollfd = |s: &UdpSocket| libc::pollfd { fd: s.as_raw_fd(), events: libc::POLLIN, revents: 0 };
        // On the stack for the usual single socket: this runs every loop turn.
        let mut one = [pollfd(&self.socket)];
        let mut many: Vec<libc::pollfd>;
        let fds: &mut [libc::pollfd] = if self.extra.is_empty() {
            &mut one
        } else {
            many = std::iter::once(&self.socket).chain(&self.extra).map(pollfd).collect();
            &mut many
        };
        #[cfg(target_os = "linux")]
        ppoll(fds, timeout);
        // SAFETY: `fds` holds valid, initialised pollfds for sockets we own, and we pass its
        // exact length; poll only writes `revents`.
        #[cfg(not(target_os = "linux"))]
        unsafe {
            let ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
            libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, ms);
        }
    }
    fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
    fn set_spin(&mut self, budget: StdDuration) {
        self.spin = budget;
    }
    fn set_recheck(&mut self, interval: StdDuration) {
        self.recheck = interval;
        self.empty_until = None;
        self.waited_empty = false;
    }
    fn set_turn_time(&mut self, now: Instant) {
        self.turn_time = now;
        if std::mem::take(&mut self.waited_empty) {
            self.found_empty();
        }
    }
    fn set_multicast_ttl(&mut self, ttl: u32) -> io::Result<()> {
        self.socket.set_multicast_ttl_v4(ttl)
    }
    fn join_multicast(&mut self, group: Ipv4Addr) -> io::Result<()> {
        self.socket.join_multicast_v4(&group, &Ipv4Addr::UNSPECIFIED)?;
        // The receive-only socket bound to the group's address needs the membership too.
        for s in &self.extra {
            if s.local_addr().is_ok_and(|a| a.ip() == IpAddr::V4(group)) {
                s.join_multicast_v4(&group, &Ipv4Addr::UNSPECIFIED)?;
            }
        }
        Ok(())
    }
}
