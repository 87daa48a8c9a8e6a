//! The Linux system calls behind [`OsSocket`], and the state they need: reading up to
//! [`READ_AHEAD`] datagrams in one `recvmmsg`, a long wait that *is* the receive (blocking
//! `recvmmsg`/`recvfrom` under `SO_RCVTIMEO`), polling while datagrams stream in, `ppoll` to the
//! nanosecond, `sendto` without blocking on the blocking main socket, and a turn's datagrams
//! for one address in one `sendmsg` (UDP GSO, given up for good on the first refusal).
//!
//! Every item here is Linux-only; this module is compiled only there (`mod linux` in
//! `datagram/mod.rs` carries the one `cfg`). Each `unsafe` block says why it is sound: the
//! kernel only ever reads or writes buffers that are alive and as long as it is told.

use std::io;
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::Duration as StdDuration;

use super::os_socket::{nothing_waiting, OsSocket, ReadAhead, READ_AHEAD, SLOT, STREAK};

/// Waits at least this long block in the receive itself (`recvmmsg` bounded by `SO_RCVTIMEO`,
/// one system call that waits and reads) instead of `ppoll` then a receive (two). Shorter
/// waits use `ppoll`, which keeps time to the nanosecond: the receive timeout counts in
/// scheduler ticks (1-10 ms) and the kernel's timer wheel may fire it up to an eighth late.
pub(super) const BLOCKING_WAIT_MIN: StdDuration = StdDuration::from_millis(20);
/// While traffic is sparse, one blocking wait in this many reads with `recvmmsg` all the same,
/// so that traffic that became dense is noticed (the others read one datagram each).
const PROBE_EVERY: u8 = 16;
/// The most a receive timeout may overrun, in ticks: one tick at HZ = 100.
const TICK_MARGIN: StdDuration = StdDuration::from_millis(10);

/// One `recvmmsg` call's headers, each pointing at its slot of `ReadAhead::data`, its iovec and
/// its address buffer. Boxed (and `data` is a Vec that never grows), so the pointers stay valid
/// when the socket moves.
pub(super) struct MmsgCall {
    headers: [libc::mmsghdr; READ_AHEAD],
    iov: [libc::iovec; READ_AHEAD],
    names: [libc::sockaddr_storage; READ_AHEAD],
}

impl MmsgCall {
    /// The headers for `data`, [`READ_AHEAD`] slots of [`SLOT`] bytes (`ReadAhead::data`).
    pub(super) fn new(data: &mut [u8]) -> Box<MmsgCall> {
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
    }
}

// SAFETY: the raw pointers in `MmsgCall` point only into allocations owned by the same
// `ReadAhead` (its `data` and its own box), which moves between threads as a whole and is used
// by one thread at a time (`&mut self`).
unsafe impl Send for ReadAhead {}

impl ReadAhead {
    /// Read what the socket has, up to `READ_AHEAD` datagrams, without blocking.
    pub(super) fn fill(&mut self, socket: &UdpSocket) -> io::Result<()> {
        self.fill_with(socket, libc::MSG_DONTWAIT)
    }
    /// Read up to `READ_AHEAD` datagrams with `recvmmsg` flags `flags`: `MSG_DONTWAIT` never
    /// blocks; `MSG_WAITFORONE` on the (blocking) main socket waits for the first datagram, at
    /// most its receive timeout, then takes what else is there without waiting.
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
}

/// The address the kernel wrote into a `sockaddr_storage`, if it is IPv4 or IPv6.
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

impl OsSocket {
    /// A wait's read succeeded (a blocking one, or a poll that found datagrams): the next
    /// receive reads what was read ahead; if the read emptied the socket, the next turn counts
    /// it empty from that turn's time (a datagram arriving after the read is read by the next
    /// wait or, RECHECK after that turn's start, by a turn).
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
    /// between them) for up to [`SPIN`](super::SPIN), at most `timeout`, before the wait
    /// sleeps. `None`: it read datagrams (the wait is over); otherwise the time it spent, to
    /// take off the sleep. A poll that finds nothing in time ends the streak: the next wait
    /// sleeps at once.
    pub(super) fn poll_stream(&mut self, timeout: StdDuration) -> Option<StdDuration> {
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

    /// Wait for the main socket's first datagram for at most `timeout` (at least
    /// [`BLOCKING_WAIT_MIN`]) and read what has come, in one system call. False if the receive
    /// timed out with nothing read: its timeout is shorter than `timeout` (see below), and the
    /// caller sleeps out the rest.
    pub(super) fn receive_waiting(&mut self, timeout: StdDuration) -> bool {
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

    /// One `sendto` that never blocks (`MSG_DONTWAIT`), though the main socket does (see
    /// `OsSocket::bind`).
    pub(super) fn send_unblocking(&self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
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
        if n < 0 {
            Err(io::Error::last_os_error())
        } else {
            Ok(())
        }
    }

    /// A train in one segmented `sendmsg`, if this socket still sends them: true if it left
    /// (or a full send buffer lost it, as it may lose any datagram), false if the caller must
    /// send its datagrams one by one.
    pub(super) fn sent_in_one_call(&mut self, bytes: &[u8], segment: usize, to: SocketAddr) -> bool {
        if self.segmented && bytes.len() > segment {
            if let Ok(size) = u16::try_from(segment) {
                match self.send_segmented(bytes, size, to) {
                    Ok(()) => return true,
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => return true,
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
        false
    }
}

/// `to` as the C socket address the kernel reads, built on the stack (socket2's `SockAddr`
/// zeroes and fills 128 bytes per call, on the path of every datagram sent).
enum CAddr {
    V4(libc::sockaddr_in),
    V6(libc::sockaddr_in6),
}

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
const UDP_SEGMENT: libc::c_int = 103;

/// Sleep until one of `fds` is readable or `timeout` passes.
pub(super) fn ppoll(fds: &mut [libc::pollfd], timeout: StdDuration) {
    // SAFETY: `fds` holds initialised pollfds and we pass its exact length; ppoll only writes
    // `revents`.
    unsafe {
        // To the nanosecond: poll's milliseconds would turn a wait of 0.9 ms into a busy loop.
        let ts = libc::timespec {
            tv_sec: timeout.as_secs().min(i32::MAX as u64) as libc::time_t,
            tv_nsec: libc::c_long::from(timeout.subsec_nanos() as i32),
        };
        libc::ppoll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, &ts, std::ptr::null());
    }
}
