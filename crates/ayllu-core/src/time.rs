//! Time as the core sees it: an [`Instant`] on the node's own clock and a [`Duration`].
//!
//! The core never reads a clock (rule S8). Whoever drives it — the runtime's monotonic clock,
//! a test, the simulator — passes `now` in. Both types count nanoseconds in a `u64` (about
//! 584 years), are `Copy`, and saturate instead of overflowing or panicking, so arithmetic on
//! values that came from the network can never crash a node.

use core::fmt;
use core::ops::{Add, AddAssign, Mul, Sub};

use crate::error::Error;

/// A point on one node's clock, in nanoseconds since that clock's origin.
///
/// Instants from different nodes are not comparable; nothing in Ayllu needs them to be.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Instant {
    nanos: u64,
}

/// A span of time in nanoseconds. Never negative: negative spans are rejected where they are
/// made from user input ([`Duration::try_from_secs_f64`]).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Duration {
    nanos: u64,
}

impl Instant {
    /// The clock's origin.
    pub const ZERO: Instant = Instant { nanos: 0 };
    /// The far future; used as "never".
    pub const MAX: Instant = Instant { nanos: u64::MAX };

    /// `nanos` nanoseconds after the clock's origin.
    pub const fn from_nanos(nanos: u64) -> Self {
        Instant { nanos }
    }
    /// `us` microseconds after the origin, saturating at [`Instant::MAX`].
    pub const fn from_micros(us: u64) -> Self {
        Instant { nanos: us.saturating_mul(1_000) }
    }
    /// `ms` milliseconds after the origin, saturating at [`Instant::MAX`].
    pub const fn from_millis(ms: u64) -> Self {
        Instant { nanos: ms.saturating_mul(1_000_000) }
    }
    /// `s` seconds after the origin, saturating at [`Instant::MAX`].
    pub const fn from_secs(s: u64) -> Self {
        Instant { nanos: s.saturating_mul(1_000_000_000) }
    }
    /// Nanoseconds since the clock's origin.
    pub const fn as_nanos(self) -> u64 {
        self.nanos
    }
    /// Seconds since the origin, for printing and plots: exact to the nanosecond only up to
    /// 2^53 ns (about 104 days).
    pub fn as_secs_f64(self) -> f64 {
        self.nanos as f64 / 1e9
    }
    /// The span from `earlier` to `self`, or zero if `earlier` is later.
    pub const fn saturating_since(self, earlier: Instant) -> Duration {
        Duration { nanos: self.nanos.saturating_sub(earlier.nanos) }
    }
}

/// A number of seconds or hertz as messages print it: plainly from 1e-4 to under 1e6 (`0.25`,
/// `-1`, `3600`), in scientific notation outside (`1e300`, `1e-12`), so a wild value reads as
/// what was typed rather than as hundreds of digits. NaN and infinities print as Rust prints
/// them (`NaN`, `inf`).
///
/// ```
/// use ayllu_core::Compact;
/// assert_eq!(Compact(1e300).to_string(), "1e300");
/// assert_eq!(Compact(-0.5).to_string(), "-0.5");
/// assert_eq!(Compact(1e-12).to_string(), "1e-12");
/// ```
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Compact(pub f64);

impl fmt::Display for Compact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if self.0.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
            write!(f, "{:e}", self.0)
        } else {
            write!(f, "{}", self.0)
        }
    }
}

impl Duration {
    /// No time. Refused as a period, window or lifespan (D6.8, D7.4).
    pub const ZERO: Duration = Duration { nanos: 0 };
    /// The longest span, about 584 years; arithmetic saturates here.
    pub const MAX: Duration = Duration { nanos: u64::MAX };
    /// [`Duration::MAX`] in whole seconds, 18446744073 s (about 584 years), as messages name
    /// the limit.
    pub const MAX_SECS: u64 = u64::MAX / 1_000_000_000;

    /// `nanos` nanoseconds.
    pub const fn from_nanos(nanos: u64) -> Self {
        Duration { nanos }
    }
    /// `us` microseconds, saturating at [`Duration::MAX`].
    pub const fn from_micros(us: u64) -> Self {
        Duration { nanos: us.saturating_mul(1_000) }
    }
    /// `ms` milliseconds, saturating at [`Duration::MAX`].
    pub const fn from_millis(ms: u64) -> Self {
        Duration { nanos: ms.saturating_mul(1_000_000) }
    }
    /// `s` seconds, saturating at [`Duration::MAX`].
    pub const fn from_secs(s: u64) -> Self {
        Duration { nanos: s.saturating_mul(1_000_000_000) }
    }
    /// Seconds as a float, as users write them (`0.2`), to the nearest nanosecond. Negative,
    /// NaN or infinite input is an error, never a panic: a period typed wrong must be reported,
    /// not wrapped. So is a positive value that rounds to zero (under half a nanosecond,
    /// [`Error::BelowResolution`]): it was meant to be something, and zero means none.
    pub fn try_from_secs_f64(secs: f64) -> Result<Self, Error> {
        if secs.is_nan() || secs.is_infinite() {
            return Err(Error::InvalidDuration { seconds: secs });
        }
        if secs < 0.0 {
            return Err(Error::NegativePeriod { seconds: secs });
        }
        let nanos = secs * 1e9;
        if nanos >= u64::MAX as f64 {
            return Err(Error::InvalidDuration { seconds: secs });
        }
        let nanos = nanos.round() as u64;
        // A positive span the clock cannot hold is refused rather than read as none: a
        // "period above zero" of 1e-12 s would otherwise be refused for being zero.
        if nanos == 0 && secs > 0.0 {
            return Err(Error::BelowResolution { seconds: secs });
        }
        Ok(Duration { nanos })
    }
    /// Seconds a user gives for a span that must be above zero (a timeout, a listening time,
    /// a step): what [`Duration::try_from_secs_f64`] takes, zero refused
    /// ([`Error::ZeroDuration`]). The one check the CLI's, C's and Python's seconds go through,
    /// so all three accept the same numbers, from 1 ns to [`Duration::MAX_SECS`], and refuse
    /// the rest with the same words.
    pub fn try_from_positive_secs(secs: f64) -> Result<Self, Error> {
        match Duration::try_from_secs_f64(secs)? {
            d if d.is_zero() => Err(Error::ZeroDuration),
            d => Ok(d),
        }
    }
    /// The period of a rate in hertz. Zero, negative, NaN or infinite rates are errors.
    pub fn try_from_hz(hz: f64) -> Result<Self, Error> {
        if !(hz.is_finite() && hz > 0.0) {
            return Err(Error::InvalidRate { hz });
        }
        // A rate so low that its period overflows, or so high that it rounds to zero, is a
        // bad rate (said as such, not as a bad duration the caller never wrote).
        match Duration::try_from_secs_f64(1.0 / hz) {
            Ok(d) if !d.is_zero() => Ok(d),
            _ => Err(Error::InvalidRate { hz }),
        }
    }
    /// The span in nanoseconds.
    pub const fn as_nanos(self) -> u64 {
        self.nanos
    }
    /// The span in seconds, as users write periods (`0.2`).
    pub fn as_secs_f64(self) -> f64 {
        self.nanos as f64 / 1e9
    }
    /// Whether the span is zero, which no period, window or lifespan may be.
    pub const fn is_zero(self) -> bool {
        self.nanos == 0
    }
    /// `n` times the span, saturating at [`Duration::MAX`] (also what `*` does).
    pub const fn saturating_mul(self, n: u64) -> Duration {
        Duration { nanos: self.nanos.saturating_mul(n) }
    }
}

impl Add<Duration> for Instant {
    type Output = Instant;
    fn add(self, d: Duration) -> Instant {
        Instant { nanos: self.nanos.saturating_add(d.nanos) }
    }
}
impl AddAssign<Duration> for Instant {
    fn add_assign(&mut self, d: Duration) {
        *self = *self + d;
    }
}
impl Sub<Instant> for Instant {
    type Output = Duration;
    /// Saturating: an earlier minus a later instant is zero.
    fn sub(self, other: Instant) -> Duration {
        self.saturating_since(other)
    }
}
impl Add for Duration {
    type Output = Duration;
    fn add(self, d: Duration) -> Duration {
        Duration { nanos: self.nanos.saturating_add(d.nanos) }
    }
}
impl Sub for Duration {
    type Output = Duration;
    fn sub(self, d: Duration) -> Duration {
        Duration { nanos: self.nanos.saturating_sub(d.nanos) }
    }
}
impl Mul<u64> for Duration {
    type Output = Duration;
    fn mul(self, n: u64) -> Duration {
        self.saturating_mul(n)
    }
}

impl fmt::Display for Instant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.3}s", self.as_secs_f64())
    }
}
impl fmt::Display for Duration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.nanos < 1_000_000 {
            write!(f, "{}us", self.nanos / 1_000)
        } else if self.nanos < 1_000_000_000 {
            write!(f, "{}ms", self.nanos / 1_000_000)
        } else {
            write!(f, "{:.3}s", self.as_secs_f64())
        }
    }
}
