//! Python exceptions for Ayllu's errors.
//!
//! Promise: every refused call raises a subclass of `ayllu.AylluError` whose message is the
//! Rust error's `Display` (what to fix, in words a user can act on). The subclasses also derive
//! from the Python built-in a Python programmer would catch: a name that does not exist is a
//! `LookupError`, a value of the wrong type a `TypeError`, an invalid argument a `ValueError`.

use ayllu_core::Error as CoreError;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyLookupError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

create_exception!(ayllu._native, AylluError, PyException, "Base of every error Ayllu raises.");

/// An exception class deriving from both [`AylluError`] and a Python built-in, so a caller may
/// catch either (`except ayllu.InvalidError` or `except ValueError`). PyO3's
/// `create_exception!` takes one base only, so the class is made as a Python `class` statement
/// makes it: `type(name, (AylluError, builtin), namespace)`, once per interpreter.
macro_rules! ayllu_exception {
    ($name:ident, $builtin:ty, $doc:literal) => {
        #[doc = $doc]
        pub struct $name;

        impl $name {
            /// The class (made on first use).
            pub fn type_object(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
                static TYPE: PyOnceLock<Py<PyType>> = PyOnceLock::new();
                TYPE.get_or_try_init(py, || derived(py, stringify!($name), py.get_type::<$builtin>(), $doc))
                    .map(|t| t.bind(py))
            }

            /// An exception of this class with message `msg`.
            pub fn new_err(msg: impl Into<String>) -> PyErr {
                let msg = msg.into();
                Python::attach(|py| match Self::type_object(py) {
                    Ok(t) => PyErr::from_type(t.clone(), msg),
                    Err(e) => e,
                })
            }
        }
    };
}

/// `type(name, (AylluError, builtin), {...})`, in module `ayllu._native` (so it pickles).
fn derived(py: Python<'_>, name: &str, builtin: Bound<'_, PyType>, doc: &str) -> PyResult<Py<PyType>> {
    let bases = PyTuple::new(py, [py.get_type::<AylluError>(), builtin])?;
    let namespace = PyDict::new(py);
    namespace.set_item("__module__", "ayllu._native")?;
    namespace.set_item("__doc__", doc)?;
    let t = py.get_type::<PyType>().call1((name, bases, namespace))?;
    Ok(t.cast_into::<PyType>()?.unbind())
}

ayllu_exception!(
    NotFoundError,
    PyLookupError,
    "A class, behavior, port, process or connection that does not exist (also a `LookupError`)."
);
ayllu_exception!(
    ValueTypeError,
    PyTypeError,
    "A value of one type offered to a register of another (rule S1) (also a `TypeError`)."
);
ayllu_exception!(
    InvalidError,
    PyValueError,
    "An argument Ayllu refuses: a taken or reserved name, a zero period, a bad URL... (also a `ValueError`)."
);
create_exception!(
    ayllu._native,
    NodeBusyError,
    AylluError,
    "The node was called from inside one of its own processes: use the process's ctx."
);
create_exception!(ayllu._native, NetworkError, AylluError, "The transport could not be opened or used.");

/// Register the exceptions on the module. `NotFoundError`, `ValueTypeError` and `InvalidError`
/// are also subclasses of the matching built-in (`LookupError`, `TypeError`, `ValueError`).
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("AylluError", py.get_type::<AylluError>())?;
    m.add("NotFoundError", NotFoundError::type_object(py)?)?;
    m.add("ValueTypeError", ValueTypeError::type_object(py)?)?;
    m.add("InvalidError", InvalidError::type_object(py)?)?;
    m.add("NodeBusyError", py.get_type::<NodeBusyError>())?;
    m.add("NetworkError", py.get_type::<NetworkError>())?;
    Ok(())
}

/// The exception for a core error: from its [`ayllu_core::ErrorKind`], the classification C's
/// status codes come from too, so both sort every error alike (a name that is not a port is
/// not found in both; a vector of the wrong shape is a type error in both).
pub fn core(e: CoreError) -> PyErr {
    use ayllu_core::ErrorKind as K;
    let msg = e.to_string();
    match e.kind() {
        K::Unknown => NotFoundError::new_err(msg),
        K::Type => ValueTypeError::new_err(msg),
        K::Period | K::Rate | K::Invalid => InvalidError::new_err(msg),
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
