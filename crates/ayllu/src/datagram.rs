//! Datagram sockets: the one place the UDP transport touches the operating system, behind a
//! trait so that tests can put a deterministic in-memory network ([`DatagramBus`]) or a
//! fault injector ([`crate::faults::FaultySocket`]) in its place.
//!
//! Promises: `send_to` and `recv_from` never block; `wait` blocks at most for its timeout.
//! Errors from the OS are returned, never turned into panics.

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration as StdDuration;

/// A non-blocking datagram socket.
pub trait DatagramSocket: Send {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()>;
    /// The next datagram, if one is waiting. Never blocks.
    fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<Option<(usize, SocketAddr)>>;
    /// Block until a datagram may be waiting or `timeout` passes.
    fn wait(&mut self, timeout: StdDuration);
    fn local_addr(&self) -> io::Result<SocketAddr>;
    fn join_multicast(&mut self, group: Ipv4Addr) -> io::Result<()>;
}

/// A real UDP socket: non-blocking, broadcast allowed, address reusable (so several nodes on
/// one host can share a broadcast or multicast port).
pub struct OsSocket {
    socket: UdpSocket,
}

impl OsSocket {
    pub fn bind(addr: SocketAddr) -> io::Result<OsSocket> {
        use socket2::{Domain, Protocol, Socket, Type};
        let socket = Socket::new(Domain::for_address(addr), Type::DGRAM, Some(Protocol::UDP))?;
        socket.set_reuse_address(true)?;
        socket.set_broadcast(true)?;
        socket.set_nonblocking(true)?;
        // Bigger buffers absorb bursts of batched datagrams without loss.
        let _ = socket.set_recv_buffer_size(1 << 21);
        let _ = socket.set_send_buffer_size(1 << 21);
        socket.bind(&addr.into())?;
        if addr.ip().is_ipv4() {
            let _ = socket.set_multicast_loop_v4(true);
        }
        Ok(OsSocket { socket: socket.into() })
    }
}

impl DatagramSocket for OsSocket {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
        match self.socket.send_to(bytes, to) {
            Ok(_) => Ok(()),
            // A full send buffer loses this datagram, as the network would: best effort (N1).
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(()),
            Err(e) => Err(e),
        }
    }
    fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<Option<(usize, SocketAddr)>> {
        match self.socket.recv_from(buf) {
            Ok((n, from)) => Ok(Some((n, from))),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(None),
            // ICMP port-unreachable from an earlier send surfaces here on Linux; not fatal.
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => Ok(None),
            Err(e) => Err(e),
        }
    }
    fn wait(&mut self, timeout: StdDuration) {
        use std::os::fd::AsRawFd;
        let mut fds = libc::pollfd { fd: self.socket.as_raw_fd(), events: libc::POLLIN, revents: 0 };
        let ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
        // SAFETY: `fds` is a valid, initialised pollfd for a socket we own, and we pass a
        // count of exactly one; poll only writes `revents`.
        unsafe {
            libc::poll(&mut fds, 1, ms);
        }
    }
    fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
    fn join_multicast(&mut self, group: Ipv4Addr) -> io::Result<()> {
        self.socket.join_multicast_v4(&group, &Ipv4Addr::UNSPECIFIED)
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
