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
//!
//! Where things are: [`DatagramSocket`], the contract every socket keeps, is here;
//! `os_socket.rs` is [`OsSocket`] as every platform has it, and `linux.rs` the Linux system
//! calls it makes (`recvmmsg`, `ppoll`, `sendto`, segmented `sendmsg`), compiled only there;
//! `bus.rs` is the in-memory [`DatagramBus`].

use std::io;
use std::net::{Ipv4Addr, SocketAddr};
use std::time::Duration as StdDuration;

use ayllu_core::Instant;

mod bus;
#[cfg(target_os = "linux")]
mod linux;
mod os_socket;
#[cfg(test)]
mod tests;

pub use bus::{BusSocket, DatagramBus};
pub use os_socket::{OsSocket, RECHECK, RECHECK_DOUBLINGS, SPIN};

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
