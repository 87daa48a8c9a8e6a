//! [`DatagramBus`], an in-memory IPv4 network for deterministic tests, and its
//! [`BusSocket`]s: the same [`DatagramSocket`] contract as a real socket, without the OS, so a
//! test of many nodes runs the same way every time. It promises delivery without loss or
//! reordering: to the one socket at an exact address, to every other socket on the port for
//! `a.b.c.255`, and to the sockets that joined a multicast group.

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration as StdDuration;

use super::DatagramSocket;

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
