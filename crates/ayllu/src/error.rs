//! Runtime errors: the core's misuse errors plus what can go wrong opening transports.

use core::fmt;

use ayllu_core::NodeId;

#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    Core(ayllu_core::Error),
    BadUrl {
        url: String,
        reason: String,
    },
    Unsupported {
        what: String,
    },
    /// Two nodes with the same id on one transport.
    DuplicateNode {
        node: NodeId,
    },
    /// The operating system refused something (binding a socket, joining a group).
    Io {
        what: String,
        error: String,
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
