//! Errors for misuse of the API: everything a user can get wrong is reported here with enough
//! context to fix it, never by a panic. Trouble that comes from *outside* (messages from the
//! network) is not an error: it is dropped and counted (see [`crate::counters`]).

use core::fmt;

use crate::connection::ConnectionKind;
use crate::counters::DropCause;
use crate::port::PortKind;
use crate::value::ValueType;

#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// No behavior class of this name was defined on this node.
    UnknownClass {
        class: String,
    },
    /// No behavior instance of this name exists on this node.
    UnknownBehavior {
        behavior: String,
    },
    /// The behavior exists but has no port (or slot/monostable) of this name.
    UnknownPort {
        behavior: String,
        port: String,
    },
    /// The name is a slot: internal to its behavior, never connectable (rule S2).
    NotAPort {
        behavior: String,
        name: String,
    },
    UnknownConnection {
        id: u64,
    },
    UnknownProcess {
        behavior: String,
        process: String,
    },
    /// A class, behavior, register, process or group name used twice.
    DuplicateName {
        what: &'static str,
        name: String,
    },
    EmptyName {
        what: &'static str,
    },
    /// A value of one type offered to a register or connection of another (rule S1).
    TypeMismatch {
        what: String,
        expected: ValueType,
        found: ValueType,
    },
    /// A port kind that cannot hold this type (e.g. a Max port of text).
    KindNotSupported {
        kind: PortKind,
        ty: ValueType,
    },
    /// A special connection needs a period, and it must be above zero.
    ZeroPeriod {
        kind: ConnectionKind,
    },
    NegativePeriod {
        seconds: f64,
    },
    InvalidDuration {
        seconds: f64,
    },
    /// Rates must be finite and above zero.
    InvalidRate {
        hz: f64,
    },
    /// A periodic process declared with a period of zero.
    ZeroProcessPeriod {
        process: String,
    },
    /// A declared window or lifespan of zero would empty the port at the instant it is written.
    ZeroWindow {
        port: String,
    },
    /// A window only makes sense for aggregating ports (Max, Min, Sum, Priority).
    WindowOnNormalPort {
        port: String,
    },
    /// A vector Sum port takes its shape from its default, which must not be empty.
    VectorShape {
        port: String,
    },
    /// The name belongs to a register every behavior has (the BLE ports `Local`, `Inhibit`,
    /// `Best`).
    ReservedName {
        name: String,
        reason: &'static str,
    },
    /// `(group, behavior, port)` cannot be a connection's source: ask each node of the group
    /// to connect its own port instead (as the paper's Fig. 2 does).
    GroupSource,
    /// The source of a connection must be on this node or on a named other node.
    NotLocal {
        what: String,
    },
    /// Too many registers in one behavior (the limit keeps handles to 16 bits).
    TooManyRegisters {
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
        reason: String,
    },
    /// A port of the right type refused a value by its merge rule (NaN into Max/Min/Sum, a
    /// vector of another length into a vector Sum).
    Refused {
        what: String,
        cause: DropCause,
    },
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
            Error::ZeroPeriod { kind } => write!(
                f,
                "a {} connection needs a period above zero",
                kind.name()
            ),
            Error::NegativePeriod { seconds } => {
                write!(f, "period of {seconds} s is negative; periods must be above zero")
            }
            Error::InvalidDuration { seconds } => write!(f, "{seconds} s is not a usable duration"),
            Error::InvalidRate { hz } => write!(f, "rate of {hz} Hz is invalid; rates must be finite and above zero"),
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
            Error::ReservedName { name, reason } => write!(f, "`{name}` is a reserved name: {reason}"),
            Error::GroupSource => f.write_str(
                "a broadcast group cannot be a connection's source; let each node connect its own port",
            ),
            Error::NotLocal { what } => write!(f, "{what} must be on this node"),
            Error::TooManyRegisters { behavior } => {
                write!(f, "behavior `{behavior}` declares more than 65535 registers")
            }
            Error::Ble { reason } => write!(f, "BLE group: {reason}"),
            Error::NotAllowed { what } => write!(f, "not allowed: {what}"),
            Error::Refused { what, cause } => write!(f, "{what} refused the value ({cause})"),
        }
    }
}

impl std::error::Error for Error {}
