//! Why a message did not get through: one counter per cause, per port and per node.
//!
//! Every message that is blocked, refused or lost is counted under exactly one [`DropCause`] cause.
//! The counters are the raw material of `why` (introspection) and of the later network
//! counters (N4); they never allocate.

use core::fmt;

/// The cause under which a blocked or refused message is counted.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum DropCause {
    /// A connection write refused because the destination is suppressed (plain Suppress).
    Suppressed,
    /// A connection write refused because another connection overrides the input (OverrideIn).
    OverriddenIn,
    /// Propagation out of a port stopped by a plain Inhibit window.
    Inhibited,
    /// Propagation out of a port stopped by another connection's OverrideOut window.
    OverriddenOut,
    /// Propagation of a behavior's own write stopped by a WriteInhibit window.
    WriteInhibited,
    /// The value's type differs from the register's (never coerced).
    TypeMismatch,
    /// A float NaN offered to an ordered or summing port.
    NotANumber,
    /// A vector of another length offered to a summing vector port.
    ShapeMismatch,
    /// An aggregating port kept its value (a smaller value for Max, a lower priority, ...).
    /// Not an error: counted so `why` can say where values went.
    Absorbed,
    /// A port already written in this propagation wave (rule S5: cycles terminate).
    WaveRevisit,
    /// Addressed to a behavior this node does not have (any more).
    UnknownBehavior,
    /// Addressed to a port the behavior does not have (or to a slot).
    UnknownPort,
    /// A message older than the newest already applied from the same connection (N1).
    Stale,
    /// A control request for something that does not exist, or that the node cannot do.
    BadRequest,
    /// A message or request the node's access rules refuse (`Access`).
    NotAllowed,
    /// A window from the network longer than the node's limit (`Limits::max_remote_period`).
    TooLong,
    /// A control request over its sender's rate (`Limits::requests_per_second`): dropped
    /// unanswered.
    RateLimited,
}

impl DropCause {
    /// Every cause, in counter order (the index into [`Counters`]).
    pub const ALL: [DropCause; 17] = [
        DropCause::Suppressed,
        DropCause::OverriddenIn,
        DropCause::Inhibited,
        DropCause::OverriddenOut,
        DropCause::WriteInhibited,
        DropCause::TypeMismatch,
        DropCause::NotANumber,
        DropCause::ShapeMismatch,
        DropCause::Absorbed,
        DropCause::WaveRevisit,
        DropCause::UnknownBehavior,
        DropCause::UnknownPort,
        DropCause::Stale,
        DropCause::BadRequest,
        DropCause::NotAllowed,
        DropCause::TooLong,
        DropCause::RateLimited,
    ];
    /// The number of causes.
    pub const COUNT: usize = DropCause::ALL.len();

    /// The counter's name as docs/semantics.md, reports and `ayllu why` spell it
    /// (`overridden_in`).
    pub fn name(self) -> &'static str {
        match self {
            DropCause::Suppressed => "suppressed",
            DropCause::OverriddenIn => "overridden_in",
            DropCause::Inhibited => "inhibited",
            DropCause::OverriddenOut => "overridden_out",
            DropCause::WriteInhibited => "write_inhibited",
            DropCause::TypeMismatch => "type_mismatch",
            DropCause::NotANumber => "not_a_number",
            DropCause::ShapeMismatch => "shape_mismatch",
            DropCause::Absorbed => "absorbed",
            DropCause::WaveRevisit => "wave_revisit",
            DropCause::UnknownBehavior => "unknown_behavior",
            DropCause::UnknownPort => "unknown_port",
            DropCause::Stale => "stale",
            DropCause::BadRequest => "bad_request",
            DropCause::NotAllowed => "not_allowed",
            DropCause::TooLong => "too_long",
            DropCause::RateLimited => "rate_limited",
        }
    }
}

impl fmt::Display for DropCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A fixed array of counters indexed by [`DropCause`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Counters {
    counts: [u64; DropCause::COUNT],
}

impl Counters {
    /// Count one more message under `cause` (saturating, never wraps).
    pub fn add(&mut self, cause: DropCause) {
        let c = &mut self.counts[cause as usize];
        *c = c.saturating_add(1);
    }
    /// Count `n` more messages under `cause` (saturating).
    pub(crate) fn add_n(&mut self, cause: DropCause, n: u64) {
        let c = &mut self.counts[cause as usize];
        *c = c.saturating_add(n);
    }
    /// How many messages were counted under `cause`.
    pub fn get(&self, cause: DropCause) -> u64 {
        self.counts[cause as usize]
    }
    /// All causes together (saturating).
    pub fn total(&self) -> u64 {
        self.counts.iter().fold(0u64, |a, b| a.saturating_add(*b))
    }
    /// The non-zero counters, in the order of [`DropCause::ALL`].
    pub fn nonzero(&self) -> impl Iterator<Item = (DropCause, u64)> + '_ {
        DropCause::ALL.iter().map(|d| (*d, self.get(*d))).filter(|(_, n)| *n > 0)
    }
}
