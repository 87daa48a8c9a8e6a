//! Datagram sockets: the one place the UDP transport touches the operating system, behind a
//! trait so that tests can put a deterministic in-memory network ([`DatagramBus`]) or a
//! fault injector ([`crate::faults::FaultySocket`]) in its place.
//!
//! Promises: `send_to` and `recv_from` never block; `wait` blocks at most for its timeout.
//! On Linux, [`OsSocket`]'s wait of `BLOCKING_WAIT_MIN` (20 ms) or more *is* the receive (one
//! `recvmmsg` that waits), and for a node on a real-time clock a receive that found the socket
//! empty stands for [`RECHECK`] (20 µs, counted in the node's turn time, so a receive reads no
//! clock; longer after empty findings in a row, up to 160 µs), a wait polls for up to [`SPIN`]
//! before it sleeps while datagrams stream in, and a turn's datagrams for one address leave in
//! one `sendmsg` (UDP GSO):
//! see docs/performance.md for the system calls this saves.
//! Errors from the OS are returned, never turned into panics.

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration as StdDuration;

use ayllu_core::Instant;

/// A non-blocking datagram socket.
pub trait DatagramSocket: Send {
    /// Send one datagram to `to`. A full send buffer drops it silently (best effort, N1).
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()>;
    /// Send `bytes` as datagrams of `segment` bytes each (the last may be shorter), in order,
    /// to `to`: the same datagrams as one `send_to` each, which is what this default does
    /// (stopping at the first error). [`OsSocket`] on Linux sends them in one system call (UDP
    /// GSO). Never blocks; a full send buffer drops them silently (best effort, N1).
    fn send_segments(&mut self, bytes: &[u8], segment: usize, to: SocketAddr) -> io::Result<()> {
        for datagram in bytes.chunks(segment.max(1)) {
            self.send_to(datagram, to)?;
        }
        Ok(())
    }
    /// The next datagram, if one is waiting. Never blocks.
    fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<Option<(usize, SocketAddr)>>;
    /// Block until a datagram may be waiting or `timeout` passes.
    fn wait(&mut self, timeout: StdDuration);
    /// For how long a receive that found nothing may answer later receives without asking
    /// again (zero, the default: every receive asks). A node on a real-time clock sets
    /// [`RECHECK`] through [`crate::Transport::set_real_time`]; on a manual clock (lockstep
    /// teams, simulated time) every step must hear what has arrived.
    fn set_recheck(&mut self, interval: StdDuration) {
        let _ = interval;
    }
    /// How long a wait may poll while datagrams stream in ([`SPIN`] unless told; zero never
    /// polls). Sockets that never poll ignore it.
    fn set_spin(&mut self, budget: StdDuration) {
        let _ = budget;
    }
    /// The time of the node's turn now beginning (its clock; the UDP transport passes it on
    /// every turn): what [`DatagramSocket::set_recheck`]'s interval is counted against, so
    /// that a receive need not read the clock. A socket that never hears it counts from zero;
    /// a wrapper that passes `set_recheck` on to another socket must pass this on too.
    fn set_turn_time(&mut self, now: Instant) {
        let _ = now;
    }
    /// The address the socket is bound to.
    fn local_addr(&self) -> io::Result<SocketAddr>;
    /// Also receive datagrams sent to multicast `group` (on the default interface).
    fn join_multicast(&mut self, group: Ipv4Addr) -> io::Result<()>;
    /// The TTL of multicast datagrams sent (0: they never leave this machine).
    fn set_multicast_ttl(&mut self, ttl: u32) -> io::Result<()> {
        let _ = ttl;
        Ok(())
    }
}

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
    socket: UdpSocket,
    /// Receive-only sockets for broadcast and multicast addresses the main one cannot hear.
    extra: Vec<UdpSocket>,
    /// Datagrams read from the main socket ahead of `recv_from`.
    ahead: ReadAhead,
    /// Until when (turn time) the sockets count as empty: they were found empty `recheck` before, and
    /// until then `recv_from` answers "nothing waiting" without asking the kernel again.
    empty_until: Option<Instant>,
    /// See [`DatagramSocket::set_recheck`].
    recheck: StdDuration,
    /// The current turn's time ([`DatagramSocket::set_turn_time`]).
    turn_time: Instant,
    /// A wait read the socket empty: the next turn counts it empty from its own time.
    waited_empty: bool,
    /// The main socket's receive timeout (`SO_RCVTIMEO`) as last set, for blocking waits.
    #[cfg(target_os = "linux")]
    receive_timeout: StdDuration,
    /// Reads have been finding several datagrams waiting: a blocking wait reads with
    /// `recvmmsg` (see `receive_waiting`).
    #[cfg(target_os = "linux")]
    dense: bool,
    /// Blocking waits read with a plain `recvfrom` since the last `recvmmsg`.
    #[cfg(target_os = "linux")]
    sparse_waits: u8,
    /// When a read last found datagrams (wall clock), and how many reads in a row found them
    /// less than [`SPIN`] after the read before: a stream, for which a wait polls first.
    last_data: Option<std::time::Instant>,
    streak: u8,
    /// How long a wait may poll ([`SPIN`] unless the URL's `spin_us` says otherwise); zero:
    /// no two reads are ever that close, so no streak builds and no wait polls.
    spin: StdDuration,
    /// Empty findings in a row since a read last found datagrams: the next one stands for
    /// `recheck` doubled this many times ([`RECHECK_DOUBLINGS`] at most).
    quiet: u32,
    /// Sent something since a read last found datagrams: what comes next may be a peer's
    /// answer, and that peer may need this very CPU to make it, so a wait does not poll.
    sent_since_read: bool,
    /// Whether the kernel takes segmented sends (UDP GSO, Linux 4.18 and later, and a route
    /// whose device can checksum them): false after the first refusal, and every train is
    /// then sent one datagram per call.
    #[cfg(target_os = "linux")]
    segmented: bool,
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

/// Waits at least this long block in the receive itself (`recvmmsg` bounded by `SO_RCVTIMEO`,
/// one system call that waits and reads) instead of `ppoll` then a receive (two). Shorter
/// waits use `ppoll`, which keeps time to the nanosecond: the receive timeout counts in
/// scheduler ticks (1-10 ms) and the kernel's timer wheel may fire it up to an eighth late.
#[cfg(target_os = "linux")]
const BLOCKING_WAIT_MIN: StdDuration = StdDuration::from_millis(20);
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
const STREAK: u8 = 2;

/// While traffic is sparse, one blocking wait in this many reads with `recvmmsg` all the same,
/// so that traffic that became dense is noticed (the others read one datagram each).
#[cfg(target_os = "linux")]
const PROBE_EVERY: u8 = 16;
/// The most a receive timeout may overrun, in ticks: one tick at HZ = 100.
#[cfg(target_os = "linux")]
const TICK_MARGIN: StdDuration = StdDuration::from_millis(10);

/// Datagrams the main socket delivered in one system call (`recvmmsg(2)` on Linux), handed
/// out one per `recv_from`. Under load that is one call for up to [`READ_AHEAD`] datagrams
/// instead of one each. At any load it saves the call that only answers "nothing more": a
/// read that filled fewer slots than it offered shows the socket was empty at that moment, so
/// once those datagrams are handed out, `recv_from` says "nothing waiting" without asking the
/// kernel again for [`RECHECK`] (and `wait` reads at once whatever arrived since).
struct ReadAhead {
    /// `READ_AHEAD` slots of `SLOT` bytes.
    data: Vec<u8>,
    /// Length and sender of the datagram in each filled slot.
    got: Vec<(usize, SocketAddr)>,
    next: usize,
    drained: bool,
    /// The `recvmmsg` arguments, made once: setting them up each call cost more than the rest
    /// of a loop turn's receive path.
    #[cfg(target_os = "linux")]
    call: Box<MmsgCall>,
}

/// One `recvmmsg` call's headers, each pointing at its slot of `ReadAhead::data`, its iovec and
/// its address buffer. Boxed (and `data` is a Vec that never grows), so the pointers stay valid
/// when the socket moves.
#[cfg(target_os = "linux")]
struct MmsgCall {
    headers: [libc::mmsghdr; READ_AHEAD],
    iov: [libc::iovec; READ_AHEAD],
    names: [libc::sockaddr_storage; READ_AHEAD],
}

// SAFETY: the raw pointers in `MmsgCall` point only into allocations owned by the same
// `ReadAhead` (its `data` and its own box), which moves between threads as a whole and is used
// by one thread at a time (`&mut self`).
#[cfg(target_os = "linux")]
unsafe impl Send for ReadAhead {}

/// Datagrams read by one system call, at most.
const READ_AHEAD: usize = 16;
/// A slot holds the largest datagram accepted plus one byte, so a longer one is seen as such
/// (and dropped as `oversized` by the transport), as with a `recvfrom` buffer of that size.
const SLOT: usize = crate::udp_config::MAX_DATAGRAM + 1;

impl ReadAhead {
    fn new() -> ReadAhead {
        let mut data = vec![0; READ_AHEAD * SLOT];
        #[cfg(target_os = "linux")]
        let call = {
            // SAFETY: all-zero is a valid value of these plain C structs (null pointers, zero
            // lengths); the pointers set below point into `data` (slot i of READ_AHEAD * SLOT
            // bytes) and into the box itself, whose heap address does not change.
            let mut call: Box<MmsgCall> = Box::new(unsafe { std::mem::zeroed() });
            let base = data.as_mut_ptr();
            for i in 0..READ_AHEAD {
                call.iov[i] = libc::iovec { iov_base: unsafe { base.add(i * SLOT) }.cast(), iov_len: SLOT };
                let name: *mut libc::sockaddr_storage = &mut call.names[i];
                let iov: *mut libc::iovec = &mut call.iov[i];
                let h = &mut call.headers[i].msg_hdr;
                h.msg_name = name.cast();
                h.msg_iov = iov;
                h.msg_iovlen = 1;
            }
            call
        };
        ReadAhead {
            data,
            got: Vec::with_capacity(READ_AHEAD),
            next: 0,
            drained: false,
            #[cfg(target_os = "linux")]
            call,
        }
    }

    fn pending(&self) -> bool {
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

    /// Read what the socket has, up to `READ_AHEAD` datagrams, without blocking.
    #[cfg(target_os = "linux")]
    fn fill(&mut self, socket: &UdpSocket) -> io::Result<()> {
        self.fill_with(socket, libc::MSG_DONTWAIT)
    }
    /// Read up to `READ_AHEAD` datagrams with `recvmmsg` flags `flags`: `MSG_DONTWAIT` never
    /// blocks; `MSG_WAITFORONE` on the (blocking) main socket waits for the first datagram, at
    /// most its receive timeout, then takes what else is there without waiting.
    #[cfg(target_os = "linux")]
    fn fill_with(&mut self, socket: &UdpSocket, flags: libc::c_int) -> io::Result<()> {
        use std::os::fd::AsRawFd;
        self.got.clear();
        self.next = 0;
        let call = &mut *self.call;
        for h in &mut call.headers {
            // In: the room for the sender's address (the kernel writes back what it used).
            h.msg_hdr.msg_namelen = std::mem::size_of::<libc::sockaddr_storage>() as libc::socklen_t;
        }
        // SAFETY: `headers` holds READ_AHEAD message headers set up in `new`, each pointing at
        // its own slot of `self.data`, iovec and address buffer, all alive and not otherwise
        // borrowed; the kernel writes only into those, and into `msg_len` and `msg_flags`.
        let n = unsafe {
            libc::recvmmsg(
                socket.as_raw_fd(),
                call.headers.as_mut_ptr(),
                READ_AHEAD as libc::c_uint,
                flags,
                std::ptr::null_mut(),
            )
        };
        if n < 0 {
            return Err(io::Error::last_os_error());
        }
        let n = n as usize;
        for (h, name) in call.headers.iter().zip(&call.names).take(n) {
            if let Some(from) = socket_addr(name) {
                self.got.push((h.msg_len as usize, from));
            }
        }
        self.drained = n < READ_AHEAD;
        Ok(())
    }

    /// Wait for one datagram (the main socket blocks, for at most its receive timeout) and
    /// read it with a plain `recvfrom`; the socket then counts as drained (unlike
    /// [`ReadAhead::fill_with`], this does not ask whether more is waiting).
    #[cfg(target_os = "linux")]
    fn fill_one(&mut self, socket: &UdpSocket) -> io::Result<()> {
        use std::os::fd::AsRawFd;
        self.got.clear();
        self.next = 0;
        // SAFETY: all-zero is a valid sockaddr_storage; the kernel writes at most `len` bytes
        // into it and at most SLOT bytes into the first slot of `data`, which holds
        // READ_AHEAD * SLOT bytes.
        let (n, name) = unsafe {
            let mut name: libc::sockaddr_storage = std::mem::zeroed();
            let mut len = std::mem::size_of::<libc::sockaddr_storage>() as libc::socklen_t;
            let n = libc::recvfrom(
                socket.as_raw_fd(),
                self.data.as_mut_ptr().cast(),
                SLOT,
                0,
                (&mut name as *mut libc::sockaddr_storage).cast(),
                &mut len,
            );
            (n, name)
        };
        if n < 0 {
            return Err(io::Error::last_os_error());
        }
        if let Some(from) = socket_addr(&name) {
            self.got.push((n as usize, from));
        }
        self.drained = true;
        Ok(())
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

/// The address the kernel wrote into a `sockaddr_storage`, if it is IPv4 or IPv6.
#[cfg(target_os = "linux")]
fn socket_addr(s: &libc::sockaddr_storage) -> Option<SocketAddr> {
    use std::net::{Ipv6Addr, SocketAddrV4, SocketAddrV6};
    match libc::c_int::from(s.ss_family) {
        libc::AF_INET => {
            // SAFETY: the family says the storage holds a sockaddr_in, which it is large and
            // aligned enough for.
            let a = unsafe { &*(s as *const libc::sockaddr_storage).cast::<libc::sockaddr_in>() };
            let ip = Ipv4Addr::from(u32::from_be(a.sin_addr.s_addr));
            Some(SocketAddr::V4(SocketAddrV4::new(ip, u16::from_be(a.sin_port))))
        }
        libc::AF_INET6 => {
            // SAFETY: as above, for sockaddr_in6.
            let a = unsafe { &*(s as *const libc::sockaddr_storage).cast::<libc::sockaddr_in6>() };
            let ip = Ipv6Addr::from(a.sin6_addr.s6_addr);
            Some(SocketAddr::V6(SocketAddrV6::new(ip, u16::from_be(a.sin6_port), a.sin6_flowinfo, a.sin6_scope_id)))
        }
        _ => None,
    }
}

/// A receive error that only means "nothing to read now".
fn nothing_waiting(e: &io::Error) -> bool {
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
    fn got_data(&mut self) {
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

    /// A wait's read succeeded (a blocking one, or a poll that found datagrams): the next
    /// receive reads what was read ahead; if the read emptied the socket, the next turn counts
    /// it empty from that turn's time (a datagram arriving after the read is read by the next
    /// wait or, RECHECK after that turn's start, by a turn).
    #[cfg(target_os = "linux")]
    fn read_in_wait(&mut self) {
        self.empty_until = None;
        if self.ahead.drained {
            self.waited_empty = true;
        }
        if !self.ahead.got.is_empty() {
            self.got_data();
        }
    }

    /// While datagrams stream in, poll the main socket (non-blocking reads, yielding the CPU
    /// between them) for up to [`SPIN`], at most `timeout`, before the wait sleeps. `None`:
    /// it read datagrams (the wait is over); otherwise the time it spent, to take off the
    /// sleep. A poll that finds nothing in time ends the streak: the next wait sleeps at once.
    #[cfg(target_os = "linux")]
    fn poll_stream(&mut self, timeout: StdDuration) -> Option<StdDuration> {
        if self.streak < STREAK || self.sent_since_read || !self.extra.is_empty() {
            return Some(StdDuration::ZERO);
        }
        let start = std::time::Instant::now();
        let budget = self.spin.min(timeout);
        loop {
            match self.ahead.fill(&self.socket) {
                Ok(()) if !self.ahead.got.is_empty() => {
                    self.dense = self.ahead.got.len() > 1;
                    self.read_in_wait();
                    return None;
                }
                Ok(()) => {}
                Err(e) if nothing_waiting(&e) => {}
                // Reported by the next receive, which asks again.
                Err(_) => return Some(start.elapsed()),
            }
            let spent = start.elapsed();
            if spent >= budget {
                self.streak = 0;
                return Some(spent);
            }
            // SAFETY: sched_yield takes no arguments and only affects scheduling.
            unsafe { libc::sched_yield() };
        }
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

    /// Wait for the main socket's first datagram for at most `timeout` (at least
    /// [`BLOCKING_WAIT_MIN`]) and read what has come, in one system call. False if the receive
    /// timed out with nothing read: its timeout is shorter than `timeout` (see below), and the
    /// caller sleeps out the rest.
    #[cfg(target_os = "linux")]
    fn receive_waiting(&mut self, timeout: StdDuration) -> bool {
        // The longest timeout that, overrun by a tick and an eighth, still ends before
        // `timeout`. The one set is kept while it lies between a third of that and that, and a
        // new one is set to two thirds of it, so that a loop's waits (each a little shorter
        // than the last) do not cost a `setsockopt` each.
        // (A wait of a day or of `Duration::MAX` asks for an hour at most: the rest is slept by
        // the caller, and the arithmetic cannot overflow.)
        let longest = (timeout.min(StdDuration::from_secs(3600)) - TICK_MARGIN) * 3 / 4;
        if self.receive_timeout > longest || self.receive_timeout < longest / 3 {
            let set = longest * 2 / 3;
            if self.socket.set_read_timeout(Some(set)).is_err() {
                return false;
            }
            self.receive_timeout = set;
        }
        // Sparse traffic (each read found one datagram): a plain blocking `recvfrom`, raw UDP's
        // call, cheaper than `recvmmsg` by the second receive attempt it makes to tell whether
        // more is waiting (0.4 us a wait here: docs/performance.md); the socket then counts as
        // emptied by it. Every PROBE_EVERY-th such wait, and every wait once reads find several
        // datagrams, reads with `recvmmsg`, up to READ_AHEAD at once.
        let single = !self.dense && self.sparse_waits < PROBE_EVERY;
        let read = if single {
            self.sparse_waits += 1;
            self.ahead.fill_one(&self.socket)
        } else {
            self.sparse_waits = 0;
            let read = self.ahead.fill_with(&self.socket, libc::MSG_WAITFORONE);
            if read.is_ok() {
                self.dense = self.ahead.got.len() > 1;
            }
            read
        };
        match read {
            Ok(()) => self.read_in_wait(),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => return false,
            // Interrupted, or an error the next receive reports.
            Err(_) => self.empty_until = None,
        }
        true
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

/// `to` as the C socket address the kernel reads, built on the stack (socket2's `SockAddr`
/// zeroes and fills 128 bytes per call, on the path of every datagram sent).
#[cfg(target_os = "linux")]
enum CAddr {
    V4(libc::sockaddr_in),
    V6(libc::sockaddr_in6),
}

#[cfg(target_os = "linux")]
impl CAddr {
    fn new(to: SocketAddr) -> CAddr {
        match to {
            SocketAddr::V4(a) => CAddr::V4(libc::sockaddr_in {
                sin_family: libc::AF_INET as libc::sa_family_t,
                sin_port: a.port().to_be(),
                sin_addr: libc::in_addr { s_addr: u32::from(*a.ip()).to_be() },
                sin_zero: [0; 8],
            }),
            SocketAddr::V6(a) => CAddr::V6(libc::sockaddr_in6 {
                sin6_family: libc::AF_INET6 as libc::sa_family_t,
                sin6_port: a.port().to_be(),
                sin6_flowinfo: a.flowinfo(),
                sin6_addr: libc::in6_addr { s6_addr: a.ip().octets() },
                sin6_scope_id: a.scope_id(),
            }),
        }
    }
    fn ptr(&self) -> *const libc::sockaddr {
        match self {
            CAddr::V4(a) => (a as *const libc::sockaddr_in).cast(),
            CAddr::V6(a) => (a as *const libc::sockaddr_in6).cast(),
        }
    }
    fn len(&self) -> libc::socklen_t {
        let size = match self {
            CAddr::V4(_) => std::mem::size_of::<libc::sockaddr_in>(),
            CAddr::V6(_) => std::mem::size_of::<libc::sockaddr_in6>(),
        };
        size as libc::socklen_t
    }
}

/// `SOL_UDP` option and control message: the segment size of a segmented send (linux/udp.h;
/// not in the libc crate).
#[cfg(target_os = "linux")]
const UDP_SEGMENT: libc::c_int = 103;

/// What a send's result means for the caller: a full send buffer loses the datagram, as the
/// network would (best effort, N1), and is not an error.
fn sent(result: io::Result<()>) -> io::Result<()> {
    match result {
        Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(()),
        other => other,
    }
}

#[cfg(target_os = "linux")]
impl OsSocket {
    /// One `sendmsg` carrying `bytes` as datagrams of `segment` bytes (the `UDP_SEGMENT`
    /// control message): the kernel cuts them, and passes them down its stack as one.
    fn send_segmented(&self, bytes: &[u8], segment: u16, to: SocketAddr) -> io::Result<()> {
        use std::os::fd::AsRawFd;
        let addr = CAddr::new(to);
        let mut iov = libc::iovec { iov_base: bytes.as_ptr() as *mut libc::c_void, iov_len: bytes.len() };
        // Room for one control message holding a u16, aligned for a cmsghdr.
        let mut control = [0u64; 4];
        // SAFETY: all-zero is a valid msghdr; every pointer set below points at a live local
        // (the address, the iovec over `bytes`, which the kernel only reads, and `control`,
        // 32 bytes, more than CMSG_SPACE(2) = 24 on 64-bit Linux and 16 on 32-bit); the
        // control message is written through CMSG_FIRSTHDR/CMSG_DATA inside that buffer.
        unsafe {
            let mut msg: libc::msghdr = std::mem::zeroed();
            msg.msg_name = addr.ptr() as *mut libc::c_void;
            msg.msg_namelen = addr.len();
            msg.msg_iov = &mut iov;
            msg.msg_iovlen = 1;
            msg.msg_control = control.as_mut_ptr().cast();
            msg.msg_controllen = libc::CMSG_SPACE(std::mem::size_of::<u16>() as libc::c_uint) as _;
            let cmsg = libc::CMSG_FIRSTHDR(&msg);
            (*cmsg).cmsg_level = libc::SOL_UDP;
            (*cmsg).cmsg_type = UDP_SEGMENT;
            (*cmsg).cmsg_len = libc::CMSG_LEN(std::mem::size_of::<u16>() as libc::c_uint) as _;
            libc::CMSG_DATA(cmsg).cast::<u16>().write_unaligned(segment);
            if libc::sendmsg(self.socket.as_raw_fd(), &msg, libc::MSG_DONTWAIT) < 0 {
                return Err(io::Error::last_os_error());
            }
        }
        Ok(())
    }
}

impl DatagramSocket for OsSocket {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
        self.sent_since_read = true;
        // The main socket blocks on Linux (see `bind`): this send must not.
        #[cfg(target_os = "linux")]
        {
            use std::os::fd::AsRawFd;
            let addr = CAddr::new(to);
            // SAFETY: `bytes` and `addr` are live for the call and their lengths are theirs;
            // the kernel only reads them.
            let n = unsafe {
                libc::sendto(
                    self.socket.as_raw_fd(),
                    bytes.as_ptr().cast(),
                    bytes.len(),
                    libc::MSG_DONTWAIT,
                    addr.ptr(),
                    addr.len(),
                )
            };
            sent(if n < 0 { Err(io::Error::last_os_error()) } else { Ok(()) })
        }
        #[cfg(not(target_os = "linux"))]
        sent(self.socket.send_to(bytes, to).map(|_| ()))
    }
    fn send_segments(&mut self, bytes: &[u8], segment: usize, to: SocketAddr) -> io::Result<()> {
        self.sent_since_read = true;
        #[cfg(target_os = "linux")]
        if self.segmented && bytes.len() > segment {
            if let Ok(size) = u16::try_from(segment) {
                match self.send_segmented(bytes, size, to) {
                    Ok(()) => return Ok(()),
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(()),
                    // Refused as a segmented send (no GSO in this kernel, a device that cannot
                    // checksum it, segments larger than the route's MTU): never again on this
                    // socket. Any other error may be this train's alone. Either way these go
                    // one by one, which reports any error of their own.
                    Err(e) => {
                        let refused = [libc::EIO, libc::EINVAL, libc::EMSGSIZE, libc::ENOPROTOOPT, libc::EOPNOTSUPP];
                        if e.raw_os_error().is_some_and(|code| refused.contains(&code)) {
                            self.segmented = false;
                        }
                    }
                }
            }
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
        // SAFETY: `fds` holds valid, initialised pollfds for sockets we own, and we pass its
        // exact length; (p)poll only writes `revents`.
        #[cfg(target_os = "linux")]
        unsafe {
            // To the nanosecond: poll's milliseconds would turn a wait of 0.9 ms into a busy loop.
            let ts = libc::timespec {
                tv_sec: timeout.as_secs().min(i32::MAX as u64) as libc::time_t,
                tv_nsec: libc::c_long::from(timeout.subsec_nanos() as i32),
            };
            libc::ppoll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, &ts, std::ptr::null());
        }
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

type Queue = Arc<(Mutex<VecDeque<(Vec<u8>, SocketAddr)>>, Condvar)>;

#[derive(Default)]
struct Bus {
    sockets: BTreeMap<SocketAddr, Queue>,
    multicast: BTreeMap<(Ipv4Addr, u16), Vec<SocketAddr>>,
}

/// An in-memory IPv4 network for deterministic tests: exact addresses deliver to one socket,
/// `a.b.c.255` delivers to every socket on that port except the sender (subnet broadcast),
/// multicast addresses deliver to the sockets that joined them. No loss, no reordering.
#[derive(Clone, Default)]
pub struct DatagramBus {
    bus: Arc<Mutex<Bus>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl DatagramBus {
    /// An empty network.
    pub fn new() -> DatagramBus {
        DatagramBus::default()
    }
    /// A socket on the bus at `addr` (port 0 is not assigned: give a real port).
    pub fn bind(&self, addr: SocketAddr) -> io::Result<BusSocket> {
        let mut bus = lock(&self.bus);
        if bus.sockets.contains_key(&addr) {
            return Err(io::Error::new(io::ErrorKind::AddrInUse, format!("{addr} is taken on this bus")));
        }
        let queue: Queue = Arc::default();
        bus.sockets.insert(addr, queue.clone());
        Ok(BusSocket { addr, bus: self.clone(), queue })
    }
}

/// One socket on a [`DatagramBus`].
pub struct BusSocket {
    addr: SocketAddr,
    bus: DatagramBus,
    queue: Queue,
}

impl DatagramSocket for BusSocket {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
        let bus = lock(&self.bus.bus);
        let targets: Vec<Queue> = match to.ip() {
            IpAddr::V4(ip) if ip.is_multicast() => bus
                .multicast
                .get(&(ip, to.port()))
                .into_iter()
                .flatten()
                .filter(|a| **a != self.addr)
                .filter_map(|a| bus.sockets.get(a).cloned())
                .collect(),
            IpAddr::V4(ip) if ip.octets()[3] == 255 => bus
                .sockets
                .iter()
                .filter(|(a, _)| a.port() == to.port() && **a != self.addr)
                .map(|(_, q)| q.clone())
                .collect(),
            _ => bus.sockets.get(&to).cloned().into_iter().collect(),
        };
        for q in targets {
            let (queue, ready) = &*q;
            lock(queue).push_back((bytes.to_vec(), self.addr));
            ready.notify_all();
        }
        Ok(())
    }
    fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<Option<(usize, SocketAddr)>> {
        let Some((bytes, from)) = lock(&self.queue.0).pop_front() else { return Ok(None) };
        // Like UDP: a datagram longer than the buffer is cut.
        let n = bytes.len().min(buf.len());
        buf[..n].copy_from_slice(&bytes[..n]);
        Ok(Some((n, from)))
    }
    fn wait(&mut self, timeout: StdDuration) {
        let (queue, ready) = &*self.queue;
        let q = lock(queue);
        if q.is_empty() {
            let _ = ready.wait_timeout(q, timeout);
        }
    }
    fn local_addr(&self) -> io::Result<SocketAddr> {
        Ok(self.addr)
    }
    fn join_multicast(&mut self, group: Ipv4Addr) -> io::Result<()> {
        let mut bus = lock(&self.bus.bus);
        let members = bus.multicast.entry((group, self.addr.port())).or_default();
        if !members.contains(&self.addr) {
            members.push(self.addr);
        }
        Ok(())
    }
}

impl Drop for BusSocket {
    fn drop(&mut self) {
        let mut bus = lock(&self.bus.bus);
        bus.sockets.remove(&self.addr);
        for members in bus.multicast.values_mut() {
            members.retain(|a| *a != self.addr);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A receiving and a sending socket on fresh loopback ports.
    fn loopback_pair() -> (OsSocket, OsSocket) {
        let loopback: SocketAddr = "127.0.0.1:0".parse().unwrap();
        (OsSocket::bind(loopback).unwrap(), OsSocket::bind(loopback).unwrap())
    }

    /// The read-ahead hands out every datagram once, in order, with its sender and length
    /// (a longer one than accepted cut to `SLOT`), across more than one batch.
    #[test]
    fn os_socket_reads_ahead_without_losing_or_reordering() {
        let (mut rx, mut tx) = loopback_pair();
        let (to, from) = (rx.local_addr().unwrap(), tx.local_addr().unwrap());
        let sizes: Vec<usize> = (0..3 * READ_AHEAD + 5).map(|i| if i == 7 { SLOT + 100 } else { 1 + i * 37 }).collect();
        for (i, &n) in sizes.iter().enumerate() {
            tx.send_to(&vec![i as u8; n], to).unwrap();
        }
        let mut buf = vec![0u8; SLOT];
        for (i, &n) in sizes.iter().enumerate() {
            rx.wait(StdDuration::from_secs(1));
            let (len, sender) = rx.recv_from(&mut buf).unwrap().expect("datagram waiting");
            assert_eq!((len, sender), (n.min(SLOT), from), "datagram {i}");
            assert!(buf[..len].iter().all(|&b| b == i as u8), "datagram {i} content");
        }
        // Nothing left: asked twice, since the first answer may come from the read-ahead.
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None);
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None);
        let t = std::time::Instant::now();
        rx.wait(StdDuration::from_millis(20));
        assert!(t.elapsed() >= StdDuration::from_millis(15), "wait returned early with nothing to read");
    }

    /// A segmented send the kernel refuses (here: more than one UDP payload in all) is sent
    /// one datagram per call instead, and the socket does not try segmenting again.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_refused_segmented_send_goes_one_datagram_per_call() {
        let (mut rx, mut tx) = loopback_pair();
        let train: Vec<u8> = (0..2 * 40_000).map(|i| (i / 40_000) as u8 + 1).collect();
        tx.send_segments(&train, 40_000, rx.local_addr().unwrap()).unwrap();
        assert!(!tx.segmented, "80 000 bytes in one send is refused (EMSGSIZE): segmenting is off");
        let mut buf = vec![0u8; SLOT];
        for i in 1..=2u8 {
            rx.wait(StdDuration::from_secs(1));
            let (len, from) = rx.recv_from(&mut buf).unwrap().expect("datagram waiting");
            // Longer than a receiver accepts, so cut to SLOT, as any receive would.
            assert_eq!((len, from), (SLOT, tx.local_addr().unwrap()), "datagram {i}");
            assert!(buf[..len].iter().all(|&b| b == i), "datagram {i} content");
        }
    }

    /// RECHECK is counted in turn time: an empty finding stands within a turn and for turns
    /// less than RECHECK later, and no longer; a wait that emptied the socket counts from the
    /// next turn, and a later wait that heard something undoes that.
    #[test]
    fn an_empty_finding_stands_for_recheck_of_turn_time() {
        let (mut rx, mut tx) = loopback_pair();
        let to = rx.local_addr().unwrap();
        let mut buf = vec![0u8; SLOT];
        let t = |us: u64| Instant::ZERO + ayllu_core::Duration::from_micros(us);
        rx.set_recheck(RECHECK);
        rx.set_turn_time(t(1_000));
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "nothing sent yet");
        tx.send_to(b"a", to).unwrap();
        // The datagram is in the socket (loopback delivers within the send), but the finding
        // stands for the rest of the turn and the next turn 19 us later.
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "same turn");
        rx.set_turn_time(t(1_019));
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "19 us later");
        rx.set_turn_time(t(1_020));
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "20 us later: asked again");
        // A blocking wait (>= 20 ms) that reads the socket empty: the next turn's later
        // receives do not ask again within RECHECK...
        tx.send_to(b"b", to).unwrap();
        rx.wait(StdDuration::from_secs(1));
        rx.set_turn_time(t(5_000));
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "what the wait read");
        tx.send_to(b"c", to).unwrap();
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "the wait's finding stands");
        // ...but a short wait (ppoll) that finds something makes the next receive ask.
        rx.wait(StdDuration::from_millis(5));
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "after the short wait");
    }

    /// Empty findings in a row stand longer and longer (RECHECK, then doubled up to
    /// RECHECK_DOUBLINGS times), and a read that finds datagrams starts again from RECHECK.
    #[test]
    fn empty_findings_in_a_row_stand_longer_up_to_a_bound() {
        let (mut rx, mut tx) = loopback_pair();
        let to = rx.local_addr().unwrap();
        let mut buf = vec![0u8; SLOT];
        let t = |us: u64| Instant::ZERO + ayllu_core::Duration::from_micros(us);
        rx.set_recheck(RECHECK);
        // Found empty at 0 (stands 20 us), 20 (40), 60 (80), 140 (160), 300 (160: the bound).
        let mut at = 0;
        for stands in [20, 40, 80, 160, 160] {
            rx.set_turn_time(t(at));
            assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "empty at {at}");
            at += stands;
        }
        tx.send_to(b"a", to).unwrap();
        rx.set_turn_time(t(at - 1));
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "the last finding stands 160 us");
        rx.set_turn_time(t(at));
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "asked again at {at}");
        // That read emptied the socket: its finding stands RECHECK again, not 160 us.
        tx.send_to(b"b", to).unwrap();
        rx.set_turn_time(t(at + 19));
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "19 us after the read");
        rx.set_turn_time(t(at + 20));
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "20 us after the read");
    }

    /// While datagrams stream in, a wait polls before it sleeps, and reads what came; a poll
    /// that finds nothing ends the streak (the next wait sleeps at once). A socket on a manual
    /// clock (no RECHECK) never polls, however close its reads come.
    #[test]
    fn a_wait_polls_only_while_datagrams_stream_in() {
        let (mut rx, mut tx) = loopback_pair();
        let to = rx.local_addr().unwrap();
        let mut buf = vec![0u8; SLOT];
        // Manual clock: reads build no streak.
        for i in 0..4u8 {
            tx.send_to(&[i], to).unwrap();
            assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1));
        }
        assert_eq!((rx.streak, rx.last_data), (0, None), "no streak on a manual clock");
        // Real time, a stream (set as a read a moment ago would leave it): the wait's poll
        // reads the datagram and keeps the streak going.
        rx.set_recheck(RECHECK);
        let before = std::time::Instant::now();
        rx.streak = STREAK;
        rx.last_data = Some(before);
        tx.send_to(b"s", to).unwrap();
        rx.wait(StdDuration::from_secs(1));
        assert!(rx.ahead.pending(), "the poll read the datagram");
        assert!(rx.last_data.is_some_and(|t| t > before), "the poll's read was recorded");
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1));
        // Having sent, the socket waits for what may be the answer without polling.
        rx.streak = STREAK;
        rx.send_to(b"q", tx.local_addr().unwrap()).unwrap();
        rx.wait(StdDuration::from_millis(1));
        assert_eq!(rx.streak, STREAK, "no poll after a send, so the streak stands");
        rx.sent_since_read = false;
        // Nothing comes: the poll gives up after SPIN, the streak ends, and the wait sleeps
        // out its time as any wait does.
        rx.streak = STREAK;
        rx.wait(StdDuration::from_millis(1));
        assert_eq!(rx.streak, 0, "a poll that found nothing ends the streak");
        tx.send_to(b"t", to).unwrap();
        rx.wait(StdDuration::from_secs(1));
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "the sleeping wait hears it");
    }

    /// `spin_us=0` (`set_spin(0)`): on a real-time clock too, no two reads are ever close
    /// enough to make a stream, so a read ends any streak and no wait polls.
    #[test]
    fn a_spin_of_zero_never_makes_a_stream() {
        let (mut rx, mut tx) = loopback_pair();
        let to = rx.local_addr().unwrap();
        let mut buf = vec![0u8; SLOT];
        rx.set_recheck(RECHECK);
        rx.set_spin(StdDuration::ZERO);
        for i in 0..4u8 {
            // As if a stream had been running: the read must end it all the same.
            (rx.streak, rx.last_data) = (STREAK, Some(std::time::Instant::now()));
            tx.send_to(&[i], to).unwrap();
            rx.wait(StdDuration::from_secs(1));
            assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1));
            assert_eq!(rx.streak, 0, "read {i}");
        }
    }

    /// A train sent in one call arrives as the very datagrams it holds, in order, with the
    /// sender's address: the kernel's segmented send (Linux) and the trait's default (one
    /// `send_to` each, here on the in-memory bus) alike.
    #[test]
    fn segments_arrive_as_the_datagrams_they_hold() {
        let sizes = [1430usize, 1430, 1430, 208];
        let mut train = Vec::new();
        for (i, &n) in sizes.iter().enumerate() {
            train.extend((0..n).map(|j| (i * 31 + j) as u8));
        }
        let (mut rx, mut tx) = loopback_pair();
        let bus = DatagramBus::new();
        let (mut brx, mut btx) =
            (bus.bind("10.0.0.1:1".parse().unwrap()).unwrap(), bus.bind("10.0.0.2:1".parse().unwrap()).unwrap());
        tx.send_segments(&train, 1430, rx.local_addr().unwrap()).unwrap();
        btx.send_segments(&train, 1430, brx.local_addr().unwrap()).unwrap();
        let receivers: [(&mut dyn DatagramSocket, SocketAddr); 2] =
            [(&mut rx, tx.local_addr().unwrap()), (&mut brx, btx.local_addr().unwrap())];
        for (socket, from) in receivers {
            let mut buf = vec![0u8; SLOT];
            let mut at = 0;
            for (i, &n) in sizes.iter().enumerate() {
                socket.wait(StdDuration::from_secs(1));
                let (len, sender) = socket.recv_from(&mut buf).unwrap().expect("datagram waiting");
                assert_eq!((len, sender), (n, from), "datagram {i}");
                assert_eq!(&buf[..len], &train[at..at + n], "datagram {i} content");
                at += n;
            }
            assert_eq!(socket.recv_from(&mut buf).unwrap(), None, "nothing more");
        }
    }

    /// A receive that found nothing may stand for a while (a real-time node's RECHECK), but a
    /// wait always reads what has arrived since, whether it waits in `ppoll` (short waits) or
    /// in the receive itself (long ones).
    #[test]
    fn os_socket_wait_hears_what_came_after_an_empty_receive() {
        let (mut rx, mut tx) = loopback_pair();
        let to = rx.local_addr().unwrap();
        let mut buf = vec![0u8; SLOT];
        for (i, (recheck, wait)) in [
            (RECHECK, StdDuration::from_millis(5)),
            (RECHECK, StdDuration::from_secs(1)),
            (StdDuration::from_secs(3600), StdDuration::from_secs(60)),
            (StdDuration::ZERO, StdDuration::from_secs(1)),
        ]
        .into_iter()
        .enumerate()
        {
            rx.set_recheck(recheck);
            assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "case {i}: nothing sent yet");
            tx.send_to(&[i as u8; 3], to).unwrap();
            rx.wait(wait);
            let (len, _) = rx.recv_from(&mut buf).unwrap().expect("the wait read the datagram");
            assert_eq!(&buf[..len], &[i as u8; 3], "case {i}");
        }
    }
}
