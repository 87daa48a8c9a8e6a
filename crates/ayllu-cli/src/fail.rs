//! Why a command failed, and the exit code that says so: 1 for errors, 2 for usage.
//!
//! Every error the tool can meet becomes one line of text for stderr; nothing is unwrapped.

use ayllu::RuntimeError;

/// A failed command: the message for stderr and the exit code.
#[derive(Debug)]
pub struct Fail {
    pub message: String,
    pub code: u8,
}

impl Fail {
    /// The command could not do its work (exit code 1).
    pub fn error(message: impl Into<String>) -> Fail {
        Fail { message: message.into(), code: 1 }
    }
    /// The arguments do not make sense together (exit code 2, like clap's own usage errors).
    pub fn usage(message: impl Into<String>) -> Fail {
        Fail { message: message.into(), code: 2 }
    }
}

impl From<RuntimeError> for Fail {
    fn from(e: RuntimeError) -> Fail {
        Fail::error(e.to_string())
    }
}

impl From<ayllu::Error> for Fail {
    fn from(e: ayllu::Error) -> Fail {
        Fail::error(e.to_string())
    }
}

impl From<std::io::Error> for Fail {
    fn from(e: std::io::Error) -> Fail {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            // The reader went away (`ayllu echo ... | head -3`): a normal way to stop.
            return Fail { message: String::new(), code: 0 };
        }
        Fail::error(format!("writing output: {e}"))
    }
}
