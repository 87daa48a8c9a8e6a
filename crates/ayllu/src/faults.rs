//! A fault-injecting datagram socket: seeded loss, delay, duplication, reordering and
//! corruption between a node and its network, for testing that arbitration stays correct
//! when the network misbehaves.
//!
//! Promises: the same seed and the same sequence of calls (and clock readings) give the same
//! faults; every fault is counted; nothing is held longer than `delay + jitter` after the
//! clock passes it, or one extra datagram for reordering.

use std::collections::VecDeque;
use std::io;
use std::net::{Ipv4Addr, SocketAddr};
use std::time::Duration as StdDuration;

use ayllu_core::{Duration, Instant};

use crate::clock::Clock;
use crate::datagram::DatagramSocket;

/// What to do to outgoing datagrams. Probabilities are per datagram, in `0.0..=1.0`.
#[derive(Clone, Debug, PartialEq)]
pub struct FaultConfig {
    /// Seed of the injector's random stream: the same seed, the same faults.
    pub seed: u64,
    /// Probability that a datagram is dropped.
    pub loss: f64,
    /// Probability that a datagram is sent twice.
    pub duplicate: f64,
    /// Hold a datagram back and send it after the next one.
    pub reorder: f64,
    /// Flip one random bit.
    pub corrupt: f64,
    /// Fixed delay added to every datagram.
    pub delay: Duration,
    /// Extra delay, uniform in `0..jitter`.
    pub jitter: Duration,
}

impl FaultConfig {
    /// No faults at all (a pass-through), with a seed.
    pub fn none(seed: u64) -> FaultConfig {
        FaultConfig {
            seed,
            loss: 0.0,
            duplicate: 0.0,
            reorder: 0.0,
            corrupt: 0.0,
            delay: Duration::ZERO,
            jitter: Duration::ZERO,
        }
    }
}

/// How many datagrams each fault touched.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultCounts {
    /// Datagrams handed to the injector.
    pub sent: u64,
    /// Datagrams dropped.
    pub lost: u64,
    /// Datagrams sent twice.
    pub duplicated: u64,
    /// Datagrams held back behind the next one.
    pub reordered: u64,
    /// Datagrams with one bit flipped.
    pub corrupted: u64,
    /// Datagrams delayed.
    pub delayed: u64,
}

/// Wraps a socket and applies a [`FaultConfig`] to what it sends.
pub struct FaultySocket<S, C> {
    inner: S,
    clock: C,
    config: FaultConfig,
    rng: fastrand::Rng,
    /// Datagrams waiting for their release time, in release order.
    held: VecDeque<(Instant, Vec<u8>, SocketAddr)>,
    /// One datagram held back to be sent after the next.
    swapped: Option<(Vec<u8>, SocketAddr)>,
    counts: FaultCounts,
}

impl<S: DatagramSocket, C: Clock> FaultySocket<S, C> {
    /// Wrap `inner`: faults are drawn from `config`'s seed and delays measured on `clock`.
    pub fn new(inner: S, clock: C, config: FaultConfig) -> Self {
        let rng = fastrand::Rng::with_seed(config.seed);
        FaultySocket { inner, clock, config, rng, held: VecDeque::new(), swapped: None, counts: FaultCounts::default() }
    }

    /// What the injector has done so far.
    pub fn counts(&self) -> FaultCounts {
        self.counts
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.rng.f64() < p
    }

    /// Send held datagrams whose time has come.
    fn release(&mut self) -> io::Result<()> {
        let now = self.clock.now();
        while self.held.front().is_some_and(|(t, _, _)| *t <= now) {
            let (_, bytes, to) = self.held.pop_front().expect("checked non-empty");
            self.inner.send_to(&bytes, to)?;
        }
        Ok(())
    }

    fn emit(&mut self, mut bytes: Vec<u8>, to: SocketAddr) -> io::Result<()> {
        if self.chance(self.config.corrupt) && !bytes.is_empty() {
            let bit = self.rng.usize(..bytes.len() * 8);
            bytes[bit / 8] ^= 1 << (bit % 8);
            self.counts.corrupted += 1;
        }
        let extra = match self.config.jitter.as_nanos() {
            0 => 0,
            j => self.rng.u64(..j),
        };
        let delay = self.config.delay + Duration::from_nanos(extra);
        if delay.is_zero() {
            return self.inner.send_to(&bytes, to);
        }
        self.counts.delayed += 1;
        let at = self.clock.now() + delay;
        // Keep release order; equal times keep send order.
        let pos = self.held.iter().position(|(t, _, _)| *t > at).unwrap_or(self.held.len());
        self.held.insert(pos, (at, bytes, to));
        Ok(())
    }
}

impl<S: DatagramSocket, C: Clock> DatagramSocket for FaultySocket<S, C> {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
        self.release()?;
        self.counts.sent += 1;
        if self.chance(self.config.loss) {
            self.counts.lost += 1;
            return Ok(());
        }
        let copies = if self.chance(self.config.duplicate) {
            self.counts.duplicated += 1;
            2
        } else {
            1
        };
        for _ in 0..copies {
            if self.swapped.is_none() && self.chance(self.config.reorder) {
                self.counts.reordered += 1;
                self.swapped = Some((bytes.to_vec(), to));
                continue;
            }
            self.emit(bytes.to_vec(), to)?;
            if let Some((b, t)) = self.swapped.take() {
                self.emit(b, t)?;
            }
        }
        Ok(())
    }
    fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<Option<(usize, SocketAddr)>> {
        self.release()?;
        self.inner.recv_from(buf)
    }
    fn wait(&mut self, timeout: StdDuration) {
        let _ = self.release();
        self.inner.wait(timeout);
    }
    fn local_addr(&self) -> io::Result<SocketAddr> {
        self.inner.local_addr()
    }
    fn join_multicast(&mut self, group: Ipv4Addr) -> io::Result<()> {
        self.inner.join_multicast(group)
    }
}
