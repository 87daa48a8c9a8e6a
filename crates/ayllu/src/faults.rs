//! Seeded network faults — loss, delay and jitter, duplication, reordering and corruption — for
//! testing that arbitration stays correct when the network misbehaves.
//!
//! [`FaultLine`] is the fault schedule itself: datagrams go in, and come out (or not) when
//! their time has come, lost, duplicated, held back behind the next one, corrupted and
//! delayed as a [`FaultConfig`] says. Two things drive one: [`FaultySocket`], which wraps a
//! node's socket and applies a line to what it sends, and the userspace shaper
//! (`crate::shaper`, Linux), which applies one line per robot to the Ethernet frames
//! between network namespaces.
//!
//! Promises: the same seed and the same sequence of calls (and clock readings) give the same
//! faults; every fault is counted; nothing is held longer than `delay + jitter` after the
//! clock passes it, or, held back for reordering, until the next datagram put in the same line.

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

impl std::ops::AddAssign for FaultCounts {
    fn add_assign(&mut self, o: FaultCounts) {
        self.sent += o.sent;
        self.lost += o.lost;
        self.duplicated += o.duplicated;
        self.reordered += o.reordered;
        self.corrupted += o.corrupted;
        self.delayed += o.delayed;
    }
}

/// The seeded fault schedule: datagrams (bytes with a destination `D`) go in with
/// [`FaultLine::push`] and come out of [`FaultLine::pop_due`] once due, with the faults of its
/// [`FaultConfig`] applied and counted. It does no I/O and reads no clock: the caller says what
/// time it is, so the same seed and the same calls give the same output.
#[derive(Debug)]
pub struct FaultLine<D> {
    config: FaultConfig,
    rng: fastrand::Rng,
    /// Datagrams waiting for their release time, in release order.
    held: VecDeque<(Instant, Vec<u8>, D)>,
    /// One datagram held back to go after the next.
    swapped: Option<(Vec<u8>, D)>,
    counts: FaultCounts,
}

impl<D: Clone> FaultLine<D> {
    /// A line applying `config`, its faults drawn from `config.seed`.
    pub fn new(config: FaultConfig) -> Self {
        let rng = fastrand::Rng::with_seed(config.seed);
        FaultLine { config, rng, held: VecDeque::new(), swapped: None, counts: FaultCounts::default() }
    }

    /// The faults this line applies.
    pub fn config(&self) -> &FaultConfig {
        &self.config
    }

    /// What the line has done so far.
    pub fn counts(&self) -> FaultCounts {
        self.counts
    }

    /// How many datagrams are waiting (delayed, or held back for reordering).
    pub fn waiting(&self) -> usize {
        self.held.len() + usize::from(self.swapped.is_some())
    }

    /// When the earliest delayed datagram is due, if any (one held back for reordering waits
    /// for the next push instead).
    pub fn next_due(&self) -> Option<Instant> {
        self.held.front().map(|(t, _, _)| *t)
    }

    /// Take the next datagram due at `now`, in release order (equal times in push order).
    pub fn pop_due(&mut self, now: Instant) -> Option<(Vec<u8>, D)> {
        if self.held.front().is_some_and(|(t, _, _)| *t <= now) {
            self.held.pop_front().map(|(_, bytes, to)| (bytes, to))
        } else {
            None
        }
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.rng.f64() < p
    }

    /// Put one datagram in at `now`: it may be dropped, duplicated, held back behind the next
    /// one, corrupted, and is due after `delay` plus up to `jitter`.
    pub fn push(&mut self, now: Instant, bytes: &[u8], to: D) {
        self.counts.sent += 1;
        if self.chance(self.config.loss) {
            self.counts.lost += 1;
            return;
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
                self.swapped = Some((bytes.to_vec(), to.clone()));
                continue;
            }
            self.schedule(now, bytes.to_vec(), to.clone());
            if let Some((b, t)) = self.swapped.take() {
                self.schedule(now, b, t);
            }
        }
    }

    /// Corrupt and delay one datagram, then queue it for its release time.
    fn schedule(&mut self, now: Instant, mut bytes: Vec<u8>, to: D) {
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
        if !delay.is_zero() {
            self.counts.delayed += 1;
        }
        let at = now + delay;
        // Keep release order; equal times keep push order.
        let pos = self.held.iter().position(|(t, _, _)| *t > at).unwrap_or(self.held.len());
        self.held.insert(pos, (at, bytes, to));
    }
}

/// Wraps a socket and applies a [`FaultConfig`] (through a [`FaultLine`]) to what it sends.
pub struct FaultySocket<S, C> {
    inner: S,
    clock: C,
    line: FaultLine<SocketAddr>,
}

impl<S: DatagramSocket, C: Clock> FaultySocket<S, C> {
    /// Wrap `inner`: faults are drawn from `config`'s seed and delays measured on `clock`.
    pub fn new(inner: S, clock: C, config: FaultConfig) -> Self {
        FaultySocket { inner, clock, line: FaultLine::new(config) }
    }

    /// What the injector has done so far.
    pub fn counts(&self) -> FaultCounts {
        self.line.counts()
    }

    /// Send held datagrams whose time has come.
    fn release(&mut self) -> io::Result<()> {
        let now = self.clock.now();
        while let Some((bytes, to)) = self.line.pop_due(now) {
            self.inner.send_to(&bytes, to)?;
        }
        Ok(())
    }
}

impl<S: DatagramSocket, C: Clock> DatagramSocket for FaultySocket<S, C> {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) -> io::Result<()> {
        self.release()?;
        self.line.push(self.clock.now(), bytes, to);
        // Undelayed datagrams leave at once.
        self.release()
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

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> FaultConfig {
        FaultConfig {
            seed: 9,
            loss: 0.1,
            duplicate: 0.1,
            reorder: 0.1,
            corrupt: 0.0,
            delay: Duration::from_millis(20),
            jitter: Duration::from_millis(30),
        }
    }

    /// Push 1000 numbered datagrams 1 ms apart and drain the line as time passes.
    fn drive(config: FaultConfig) -> (Vec<(Instant, u32)>, FaultCounts) {
        let mut line = FaultLine::new(config);
        let mut out = Vec::new();
        for i in 0..1000u32 {
            let now = Instant::from_nanos(u64::from(i) * 1_000_000);
            line.push(now, &i.to_le_bytes(), i);
            while let Some((bytes, to)) = line.pop_due(now) {
                assert_eq!(bytes, to.to_le_bytes());
                out.push((now, to));
            }
        }
        let end = Instant::from_nanos(2_000_000_000);
        while let Some((_, to)) = line.pop_due(end) {
            out.push((end, to));
        }
        (out, line.counts())
    }

    #[test]
    fn the_same_seed_gives_the_same_faults_and_every_fault_is_counted() {
        let (a, counts) = drive(config());
        assert_eq!(drive(config()), (a.clone(), counts));
        assert_ne!(drive(FaultConfig { seed: 10, ..config() }).0, a);
        assert_eq!(counts.sent, 1000);
        for (what, n) in [("lost", counts.lost), ("duplicated", counts.duplicated), ("reordered", counts.reordered)] {
            assert!((50..=150).contains(&n), "{what}: {n} of 1000 at 10 %");
        }
        // Every copy not lost comes out, except at most one still held back for reordering.
        let copies = counts.sent - counts.lost + counts.duplicated;
        assert!(a.len() as u64 == copies || a.len() as u64 + 1 == copies, "{} out of {copies}", a.len());
        assert_eq!(counts.delayed, a.len() as u64);
        // Jitter and holding back put some out of order.
        assert!(a.windows(2).any(|w| w[1].1 < w[0].1));
    }

    #[test]
    fn nothing_comes_out_before_its_delay_or_later_than_delay_plus_jitter() {
        let cfg = FaultConfig { reorder: 0.0, ..config() };
        let (out, _) = drive(cfg.clone());
        for (at, i) in out.into_iter().filter(|(at, _)| at.as_nanos() < 1_000_000_000) {
            let pushed = u64::from(i) * 1_000_000;
            let waited = at.as_nanos() - pushed;
            assert!(waited >= cfg.delay.as_nanos(), "{i} left after {waited} ns");
            // Released on the next 1 ms push at the latest.
            assert!(waited <= (cfg.delay + cfg.jitter).as_nanos() + 1_000_000, "{i} left after {waited} ns");
        }
    }

    #[test]
    fn no_faults_is_a_pass_through() {
        let (out, counts) = drive(FaultConfig::none(1));
        assert_eq!(out.iter().map(|(_, i)| *i).collect::<Vec<_>>(), (0..1000).collect::<Vec<_>>());
        assert!(out.iter().all(|(at, i)| at.as_nanos() == u64::from(*i) * 1_000_000));
        assert_eq!(counts, FaultCounts { sent: 1000, ..FaultCounts::default() });
    }
}
