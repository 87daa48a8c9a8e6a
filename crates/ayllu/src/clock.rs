//! Clocks (rule S8): the one place the runtime reads time. The core never does.
//!
//! [`MonotonicClock`] is real time for robots; [`ManualClock`] is time that a test or the
//! simulator moves by hand (cheap to clone; every clone sees the same time), so the same
//! controller runs unchanged in both (copper-rs calls this a mockable clock).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use ayllu_core::{Duration, Instant};

/// A source of `now` for one node.
pub trait Clock: Send {
    /// The current instant on this clock (nanoseconds since the clock's origin); never goes backwards.
    fn now(&self) -> Instant;
    /// Whether waiting for this clock means sleeping (real time) or not (manual time).
    fn is_real_time(&self) -> bool;
}

/// The operating system's monotonic clock, measured from when this value was made.
#[derive(Clone, Debug)]
pub struct MonotonicClock {
    origin: std::time::Instant,
}

impl MonotonicClock {
    /// A clock whose origin is now.
    pub fn new() -> MonotonicClock {
        MonotonicClock { origin: std::time::Instant::now() }
    }
    /// The real instant at which this clock reads `t`, for sleeping until a deadline.
    pub fn to_std(&self, t: Instant) -> std::time::Instant {
        self.origin + std::time::Duration::from_nanos(t.as_nanos())
    }
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for MonotonicClock {
    fn now(&self) -> Instant {
        let d = self.origin.elapsed();
        Instant::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
    }
    fn is_real_time(&self) -> bool {
        true
    }
}

/// Time that only moves when told to. Clones share the same time.
#[derive(Clone, Debug, Default)]
pub struct ManualClock {
    nanos: Arc<AtomicU64>,
}

impl ManualClock {
    /// A clock at `Instant::ZERO` that moves only when [`ManualClock::advance`] is called.
    pub fn new() -> ManualClock {
        ManualClock::default()
    }
    /// Set the time; earlier times are ignored (time never goes backwards).
    pub fn set(&self, t: Instant) {
        self.nanos.fetch_max(t.as_nanos(), Ordering::SeqCst);
    }
    /// Move this clock (and every clone of it) forward by `d`.
    pub fn advance(&self, d: Duration) {
        let _ = self.nanos.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| Some(n.saturating_add(d.as_nanos())));
    }
}

impl Clock for ManualClock {
    fn now(&self) -> Instant {
        Instant::from_nanos(self.nanos.load(Ordering::SeqCst))
    }
    fn is_real_time(&self) -> bool {
        false
    }
}

/// Where a process's sequence numbers start (datagrams, connections' messages, requests): the
/// wall-clock time in units of 2^-32 s (seconds in the upper 32 bits, the fraction of the
/// second in the lower), so a process restarted under the same node id numbers above its
/// previous life (spec/protocol.md, "sequence") without storing anything — even when it
/// restarts within the same second, as two quick `ayllu` commands with one `--id` do.
pub(crate) fn boot_sequence_base() -> u64 {
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    let secs = now.as_secs().min(u64::from(u32::MAX));
    let fraction = (u64::from(now.subsec_nanos()) << 32) / 1_000_000_000;
    secs << 32 | fraction
}
