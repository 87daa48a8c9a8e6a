//! Runtime errors: the core's misuse errors plus what can go wrong opening transports.

use core::fmt;

use ayllu_core::NodeId;

/// What went wrong in the runtime: the core refused (misuse), a URL did not parse, a
/// transport is not available, or the operating system said no. Never a panic.
#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// The core refused the call (see [`ayllu_core::Error`]).
    Core(ayllu_core::Error),
    /// A transport URL that does not parse; `reason` names the bad part.
    BadUrl {
        /// The URL as given.
        url: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A transport or feature this build does not have.
    Unsupported {
        /// What was asked for.
        what: String,
    },
    /// Two nodes with the same id on one transport.
    DuplicateNode {
        /// The id already attached.
        node: NodeId,
    },
    /// The operating system refused something (binding a socket, joining a group).
    Io {
        /// What the runtime was doing, with what to do about it where known.
        what: String,
        /// The operating system's error message.
        error: String,
    },
    /// A flight recording could not be made or read (see `recording` and `replay`).
    Recording {
        /// What went wrong, naming the file.
        what: String,
    },
    /// A transaction's plan or options that cannot be run (see `transaction`).
    Plan {
        /// What is wrong, naming the node and change at fault.
        what: String,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Core(e) => e.fmt(f),
            Error::BadUrl { url, reason } => write!(f, "bad transport URL `{url}`: {reason}"),
            Error::Unsupported { what } => write!(f, "{what}"),
            Error::DuplicateNode { node } => write!(f, "node {node} is already attached to this network"),
            Error::Io { what, error } => write!(f, "{what}: {error}"),
            Error::Recording { what } => write!(f, "{what}"),
            Error::Plan { what } => write!(f, "plan: {what}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Core(e) => Some(e),
            _ => None,
        }
    }
}

impl From<ayllu_core::Error> for Error {
    fn from(e: ayllu_core::Error) -> Error {
        Error::Core(e)
    }
}
