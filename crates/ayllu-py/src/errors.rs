//! Python exceptions for Ayllu's errors.
//!
//! Promise: every refused call raises a subclass of `ayllu.AylluError` whose message is the
//! Rust error's `Display` (what to fix, in words a user can act on). The subclasses also derive
//! from the Python built-in a Python programmer would catch: a name that does not exist is a
//! `LookupError`, a value of the wrong type a `TypeError`, an invalid argument a `ValueError`.

use ayllu_core::Error as CoreError;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;

create_exception!(_native, AylluError, PyException, "Base of every error Ayllu raises.");
create_exception!(
    _native,
    NotFoundError,
    AylluError,
    "A class, behavior, port, process or connection that does not exist."
);
create_exception!(
    _native,
    ValueTypeError,
    AylluError,
    "A value of one type offered to a register of another (rule S1)."
);
create_exception!(
    _native,
    InvalidError,
    AylluError,
    "An argument Ayllu refuses: a taken or reserved name, a zero period, a bad URL..."
);
create_exception!(
    _native,
    NodeBusyError,
    AylluError,
    "The node was called from inside one of its own processes: use the process's ctx."
);
create_exception!(_native, NetworkError, AylluError, "The transport could not be opened or used.");

/// Register the exceptions on the module, and make each also a subclass of the matching
/// built-in (done in Python, see `ayllu/__init__.py`).
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("AylluError", py.get_type::<AylluError>())?;
    m.add("NotFoundError", py.get_type::<NotFoundError>())?;
    m.add("ValueTypeError", py.get_type::<ValueTypeError>())?;
    m.add("InvalidError", py.get_type::<InvalidError>())?;
    m.add("NodeBusyError", py.get_type::<NodeBusyError>())?;
    m.add("NetworkError", py.get_type::<NetworkError>())?;
    Ok(())
}

/// The exception for a core error.
pub fn core(e: CoreError) -> PyErr {
    let msg = e.to_string();
    match e {
        CoreError::UnknownClass { .. }
        | CoreError::UnknownBehavior { .. }
        | CoreError::UnknownPort { .. }
        | CoreError::UnknownConnection { .. }
        | CoreError::UnknownProcess { .. } => NotFoundError::new_err(msg),
        CoreError::TypeMismatch { .. } => ValueTypeError::new_err(msg),
        _ => InvalidError::new_err(msg),
    }
}

/// The exception for a runtime error.
pub fn runtime(e: ayllu::RuntimeError) -> PyErr {
    match e {
        ayllu::RuntimeError::Core(c) => core(c),
        ayllu::RuntimeError::Io { .. } => NetworkError::new_err(e.to_string()),
        other => InvalidError::new_err(other.to_string()),
    }
}

/// Python's own `TypeError`, for arguments of a type no register takes.
pub fn type_error(msg: impl Into<String>) -> PyErr {
    PyTypeError::new_err(msg.into())
}

/// Python's own `ValueError`.
pub fn value_error(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// Python's own `RuntimeError` (a node used after it was closed or killed).
pub fn closed(what: &str) -> PyErr {
    PyRuntimeError::new_err(format!("{what} is closed (killed, or closed with close())"))
}
