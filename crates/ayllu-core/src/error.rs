//! Errors for misuse of the API: everything a user can get wrong is reported here with enough
//! context to fix it, never by a panic. Trouble that comes from *outside* (messages from the
//! network) is not an error: it is dropped and counted (see [`crate::counters`]).

use core::fmt;

use crate::connection::ConnectionKind;
use crate::counters::DropCause;
use crate::port::PortKind;
use crate::time::{Compact, Duration};
use crate::value::ValueType;

/// Why an API call was refused. `Display` says what to fix, in words a user can act on;
/// trouble from the network is never an `Error` but a counted [`DropCause`].
#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// No behavior class of this name was defined on this node.
    UnknownClass {
        /// The class name asked for.
        class: String,
    },
    /// No behavior instance of this name exists on this node.
    UnknownBehavior {
        /// The behavior name asked for, or `(removed behavior #id)` for a
        /// [`PortRef`](crate::PortRef) to a removed behavior (S9).
        behavior: String,
    },
    /// The behavior exists but has no port (or slot/monostable) of this name.
    UnknownPort {
        /// The behavior that was searched.
        behavior: String,
        /// The register name (or `#index` for a handle from another class) that it lacks.
        port: String,
    },
    /// The name is a slot: internal to its behavior, never connectable (rule S2).
    NotAPort {
        /// The behavior that owns the slot.
        behavior: String,
        /// The slot's name.
        name: String,
    },
    /// No connection with this id is owned by this node (never made, or already removed).
    UnknownConnection {
        /// The raw [`ConnectionId`](crate::ConnectionId) asked for.
        id: u64,
    },
    /// The behavior has no process of this name.
    UnknownProcess {
        /// The behavior that was searched.
        behavior: String,
        /// The process name asked for.
        process: String,
    },
    /// A class, behavior, register, process or group name used twice.
    DuplicateName {
        /// What kind of thing the name is for (`behavior class`, `register`, ...).
        what: &'static str,
        /// The name, qualified by its behavior where it has one (`OBS1.Rotate`).
        name: String,
    },
    /// A class, behavior, register, process or group was given an empty name.
    EmptyName {
        /// What kind of thing needed the name.
        what: &'static str,
    },
    /// A value of one type offered to a register or connection of another (rule S1).
    TypeMismatch {
        /// The register or connection that refused (`port OBS1.Rotate`).
        what: String,
        /// The type it was declared with.
        expected: ValueType,
        /// The type that was offered.
        found: ValueType,
    },
    /// A port kind that cannot hold this type (e.g. a Max port of text).
    KindNotSupported {
        /// The port kind declared.
        kind: PortKind,
        /// The type of the port's default, which that kind cannot merge (rule S3).
        ty: ValueType,
    },
    /// A special connection needs a period, and it must be above zero.
    ZeroPeriod {
        /// The kind, with its zero period.
        kind: ConnectionKind,
    },
    /// A period given for a Normal connection, which has none
    /// ([`ConnectionKind::from_parts`](crate::ConnectionKind::from_parts)).
    PeriodOnNormal {
        /// The seconds given.
        seconds: f64,
    },
    /// A connection kind name that is none of the six.
    UnknownConnectionKind {
        /// The name given.
        name: String,
    },
    /// A span that must be above zero (a timeout, a listening time, a step) was given as zero
    /// ([`Duration::try_from_positive_secs`](crate::Duration::try_from_positive_secs)).
    ZeroDuration,
    /// A duration given in seconds was negative
    /// ([`Duration::try_from_secs_f64`](crate::Duration::try_from_secs_f64), D6.8).
    NegativePeriod {
        /// The seconds given.
        seconds: f64,
    },
    /// A duration given in seconds was NaN, infinite, or beyond what nanoseconds in a `u64` hold
    /// (about 584 years).
    InvalidDuration {
        /// The seconds given.
        seconds: f64,
    },
    /// A duration given in seconds was above zero but under half a nanosecond, the clock's
    /// resolution: it would round to zero (and then read as "no period").
    BelowResolution {
        /// The seconds given.
        seconds: f64,
    },
    /// Rates must be finite and above zero, with a period of at least 1 ns and under 584
    /// years.
    InvalidRate {
        /// The rate given, in hertz.
        hz: f64,
    },
    /// A periodic process declared with a period of zero.
    ZeroProcessPeriod {
        /// The process, as `behavior.process`.
        process: String,
    },
    /// A declared window or lifespan of zero would empty the port at the instant it is written.
    ZeroWindow {
        /// The port's name.
        port: String,
    },
    /// A window only makes sense for aggregating ports (Max, Min, Sum, Priority).
    WindowOnNormalPort {
        /// The port's name.
        port: String,
    },
    /// A vector Sum port takes its shape from its default, which must not be empty.
    VectorShape {
        /// The port's name.
        port: String,
    },
    /// A connection to another node from a port whose vector is longer than a message carries
    /// ([`crate::value::MAX_NETWORK_VECTOR`]): no value of it could ever arrive.
    TooLongForNetwork {
        /// The source port, as `behavior.port`.
        port: String,
        /// How many numbers it holds now.
        len: usize,
    },
    /// The name belongs to a register every behavior has (the BLE ports `Local`, `Inhibit`,
    /// `Best`).
    ReservedName {
        /// The refused name, as `behavior.name`.
        name: String,
        /// Why it is reserved.
        reason: &'static str,
    },
    /// `(group, behavior, port)` cannot be a connection's source: ask each node of the group
    /// to connect its own port instead (as the paper's Fig. 2 does).
    GroupSource,
    /// No connection of this node runs from `source` to `destination` (a change that removes
    /// connections by their endpoints).
    NoConnectionBetween {
        /// The source, as written.
        source: String,
        /// The destination, as written.
        destination: String,
    },
    /// A transaction's request was refused (docs/semantics.md R8–R12): its part does not
    /// validate here, another transaction is held, or it is unknown or finished.
    Transaction {
        /// What is wrong, in words (naming the change at fault).
        what: String,
    },
    /// The source of a connection must be on this node or on a named other node.
    NotLocal {
        /// What had to be local, in words.
        what: String,
    },
    /// Too many registers in one behavior (the limit keeps handles to 16 bits).
    TooManyRegisters {
        /// The behavior (or class) that declared too many.
        behavior: String,
    },
    /// The node's access rules or limits refuse a request from the network (`Access`,
    /// `Limits`).
    NotAllowed {
        /// What was refused, and by which rule.
        what: String,
    },
    /// A BLE group needs the behavior to have the named output port.
    Ble {
        /// What is wrong, in words.
        reason: String,
    },
    /// A port of the right type refused a value by its merge rule (NaN into Max/Min/Sum, a
    /// vector of another length into a vector Sum).
    Refused {
        /// The port that refused (`port OBS1.Best`).
        what: String,
        /// The merge rule that refused it: `not_a_number` or `shape_mismatch` (D3.5, D3.6).
        cause: DropCause,
    },
    /// An error restored from a checkpoint (`NodeCore::restore`): a change outcome a process
    /// had not read yet, or a transaction's, kept by its kind and its words (an error's other
    /// fields are not data a checkpoint can hold). It reads, prints and classifies as the
    /// original did.
    Restored {
        /// The original's kind.
        kind: ErrorKind,
        /// The original's message.
        what: String,
    },
}

/// What kind of refusal an [`Error`] is: the one classification C's status codes
/// (`AY_ERR_UNKNOWN`, ...), Python's exception classes (`NotFoundError`, ...) and the tool's
/// messages come from, so the three agree on every error. Decided once per variant in
/// [`Error::kind`], with no catch-all: a new variant cannot compile without its kind.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ErrorKind {
    /// No class, behavior, port, process or connection of that name (or the name is not a
    /// port). C `AY_ERR_UNKNOWN`; Python `NotFoundError` (a `LookupError`).
    Unknown,
    /// A value, port or register of the wrong type (rule S1), a kind or shape the type cannot
    /// have. C `AY_ERR_TYPE`; Python `ValueTypeError` (a `TypeError`).
    Type,
    /// A period, lifespan, window or duration that is zero where one is required, negative,
    /// not finite or under the clock's resolution. C `AY_ERR_PERIOD`; Python `InvalidError`.
    Period,
    /// A rate that is zero, negative or not finite. C `AY_ERR_RATE`; Python `InvalidError`.
    Rate,
    /// Any other argument refused. C `AY_ERR_INVALID`; Python `InvalidError` (a `ValueError`).
    Invalid,
}

impl Error {
    /// This error's kind (see [`ErrorKind`]).
    pub fn kind(&self) -> ErrorKind {
        use ErrorKind as K;
        match self {
            Error::UnknownClass { .. }
            | Error::UnknownBehavior { .. }
            | Error::UnknownPort { .. }
            | Error::NotAPort { .. }
            | Error::UnknownConnection { .. }
            | Error::UnknownProcess { .. } => K::Unknown,
            Error::TypeMismatch { .. } | Error::KindNotSupported { .. } | Error::VectorShape { .. } => K::Type,
            Error::ZeroPeriod { .. }
            | Error::ZeroDuration
            | Error::NegativePeriod { .. }
            | Error::InvalidDuration { .. }
            | Error::BelowResolution { .. }
            | Error::ZeroProcessPeriod { .. }
            | Error::ZeroWindow { .. }
            | Error::PeriodOnNormal { .. } => K::Period,
            Error::InvalidRate { .. } => K::Rate,
            Error::DuplicateName { .. }
            | Error::UnknownConnectionKind { .. }
            | Error::EmptyName { .. }
            | Error::WindowOnNormalPort { .. }
            | Error::TooLongForNetwork { .. }
            | Error::ReservedName { .. }
            | Error::GroupSource
            | Error::NoConnectionBetween { .. }
            | Error::Transaction { .. }
            | Error::NotLocal { .. }
            | Error::TooManyRegisters { .. }
            | Error::NotAllowed { .. }
            | Error::Ble { .. }
            | Error::Refused { .. } => K::Invalid,
            Error::Restored { kind, .. } => *kind,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::UnknownClass { class } => write!(f, "no behavior class named `{class}` is defined"),
            Error::UnknownBehavior { behavior } => write!(f, "no behavior named `{behavior}` on this node"),
            Error::UnknownPort { behavior, port } => {
                write!(f, "behavior `{behavior}` has no port named `{port}`")
            }
            Error::NotAPort { behavior, name } => write!(
                f,
                "`{behavior}.{name}` is a slot (internal to its behavior) and cannot be connected"
            ),
            Error::UnknownConnection { id } => write!(f, "no connection with id {id}"),
            Error::UnknownProcess { behavior, process } => {
                write!(f, "behavior `{behavior}` has no process named `{process}`")
            }
            Error::DuplicateName { what, name } => write!(f, "a {what} named `{name}` already exists"),
            Error::EmptyName { what } => write!(f, "a {what} name must not be empty"),
            Error::TypeMismatch { what, expected, found } => {
                write!(f, "{what} holds {expected} values, not {found}")
            }
            Error::KindNotSupported { kind, ty } => {
                write!(f, "a {kind:?} port cannot hold {ty} values")
            }
            Error::PeriodOnNormal { seconds } => write!(
                f,
                "a Normal connection has no period (the paper leaves p unspecified for it): leave it out (got {} s)",
                Compact(*seconds)
            ),
            Error::UnknownConnectionKind { name } => write!(
                f,
                "connection kind `{name}` is none of normal, suppress, inhibit, override-in, override-out, write-inhibit"
            ),
            Error::ZeroPeriod { kind } => write!(
                f,
                "a {} connection needs a period above zero",
                kind.name()
            ),
            Error::ZeroDuration => write!(
                f,
                "0 s is not allowed here: a span above zero is from 1 ns (1e-9 s) to {} s (about 584 years)",
                Duration::MAX_SECS
            ),
            // These three speak of "a span of time", not of periods: the same words serve a
            // period, a lifespan, a timeout and a clock's step, in the CLI, C and Python alike.
            Error::NegativePeriod { seconds } => write!(
                f,
                "{} s is negative: a span of time is from 0 to {} s (about 584 years)",
                Compact(*seconds),
                Duration::MAX_SECS
            ),
            Error::InvalidDuration { seconds } if !seconds.is_finite() => write!(
                f,
                "{} is not a number of seconds: a span of time is finite, from 0 to {} s (about 584 years)",
                Compact(*seconds),
                Duration::MAX_SECS
            ),
            Error::InvalidDuration { seconds } => write!(
                f,
                "{} s is too long: a span of time is from 0 to {} s (about 584 years)",
                Compact(*seconds),
                Duration::MAX_SECS
            ),
            Error::BelowResolution { seconds } => write!(
                f,
                "{} s is above zero but under 1 ns, the clock's resolution, so it would round to 0 s: give at least 1 ns (1e-9 s), or 0 where none is meant",
                Compact(*seconds)
            ),
            Error::InvalidRate { hz } => write!(
                f,
                "rate of {} Hz is invalid; rates must be finite and above zero, with a period from 1 ns to 584 years",
                Compact(*hz)
            ),
            Error::ZeroProcessPeriod { process } => {
                write!(f, "process `{process}`: a periodic process needs a period above zero")
            }
            Error::ZeroWindow { port } => write!(f, "port `{port}`: window and lifespan must be above zero"),
            Error::WindowOnNormalPort { port } => write!(
                f,
                "port `{port}`: only aggregating ports (Max, Min, Sum, Priority) have a window; use a lifespan for freshness"
            ),
            Error::VectorShape { port } => write!(
                f,
                "port `{port}`: a vector Sum takes its shape from its default; declare it with a default of the right length (e.g. [0, 0, 0])"
            ),
            Error::TooLongForNetwork { port, len } => write!(
                f,
                "`{port}` holds {len} numbers, and a value sent to another node carries at most {} (the wire \
                 counts them in one byte, spec/protocol.md): connect a smaller port across the network (a ROS 2 \
                 body resamples a scan with `sonar = {{ beams = 16 }}`; a local behavior can reduce it), and keep \
                 this one local",
                crate::value::MAX_NETWORK_VECTOR
            ),
            Error::ReservedName { name, reason } => write!(f, "`{name}` is a reserved name: {reason}"),
            Error::GroupSource => f.write_str(
                "a broadcast group cannot be a connection's source; let each node connect its own port",
            ),
            Error::NoConnectionBetween { source, destination } => {
                write!(f, "no connection from {source} to {destination} on this node")
            }
            Error::Transaction { what } => write!(f, "transaction refused: {what}"),
            Error::NotLocal { what } => write!(f, "{what} must be on this node"),
            Error::TooManyRegisters { behavior } => {
                write!(f, "behavior `{behavior}` declares more than 65535 registers")
            }
            Error::Ble { reason } => write!(f, "BLE group: {reason}"),
            Error::NotAllowed { what } => write!(f, "not allowed: {what}"),
            Error::Refused { what, cause } => write!(f, "{what} refused the value ({cause})"),
            Error::Restored { what, .. } => f.write_str(what),
        }
    }
}

impl std::error::Error for Error {}
