//! Why a message did not get through: one counter per cause, per port and per node.
//!
//! Every message that is blocked, refused or lost is counted under exactly one [`Drop`] cause.
//! The counters are the raw material of `why` (introspection) and of the later network
//! counters (N4); they never allocate.

use core::fmt;

/// The cause under which a blocked or refused message is counted.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Drop {
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
    /// A control request for something that does not exist or is not allowed.
    BadRequest,
}

impl Drop {
    pub const ALL: [Drop; 14] = [
        Drop::Suppressed,
        Drop::OverriddenIn,
        Drop::Inhibited,
        Drop::OverriddenOut,
        Drop::WriteInhibited,
        Drop::TypeMismatch,
        Drop::NotANumber,
        Drop::ShapeMismatch,
        Drop::Absorbed,
        Drop::WaveRevisit,
        Drop::UnknownBehavior,
        Drop::UnknownPort,
        Drop::Stale,
        Drop::BadRequest,
    ];
    pub const COUNT: usize = Drop::ALL.len();

    pub fn name(self) -> &'static str {
        match self {
            Drop::Suppressed => "suppressed",
            Drop::OverriddenIn => "overridden_in",
            Drop::Inhibited => "inhibited",
            Drop::OverriddenOut => "overridden_out",
            Drop::WriteInhibited => "write_inhibited",
            Drop::TypeMismatch => "type_mismatch",
            Drop::NotANumber => "not_a_number",
            Drop::ShapeMismatch => "shape_mismatch",
            Drop::Absorbed => "absorbed",
            Drop::WaveRevisit => "wave_revisit",
            Drop::UnknownBehavior => "unknown_behavior",
            Drop::UnknownPort => "unknown_port",
            Drop::Stale => "stale",
            Drop::BadRequest => "bad_request",
        }
    }
}

impl fmt::Display for Drop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A fixed array of counters indexed by [`Drop`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    counts: [u64; Drop::COUNT],
}

impl Counters {
    pub fn add(&mut self, cause: Drop) {
        let c = &mut self.counts[cause as usize];
        *c = c.saturating_add(1);
    }
    pub fn get(&self, cause: Drop) -> u64 {
        self.counts[cause as usize]
    }
    pub fn total(&self) -> u64 {
        self.counts.iter().fold(0u64, |a, b| a.saturating_add(*b))
    }
    /// The non-zero counters, in the order of [`Drop::ALL`].
    pub fn nonzero(&self) -> impl Iterator<Item = (Drop, u64)> + '_ {
        Drop::ALL.iter().map(|d| (*d, self.get(*d))).filter(|(_, n)| *n > 0)
    }
}
