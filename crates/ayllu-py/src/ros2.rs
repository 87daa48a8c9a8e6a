//! The ROS 2 body from Python: `Node.install_ros2_body(path)` makes the node's body behaviors
//! (VISION, SONAR, BASE, or whatever the mapping file names) ROS 2 topics, as the mapping file
//! says (docs/ros2.md). It is to a ROS 2 robot what `Node.install_served_body` is to the
//! simulator: the controller built on the body is the same.
//!
//! Promises:
//! * the method is in every build of the module, so the API and its stubs do not depend on
//!   how the wheel was built. Without the cargo feature `ros2` (the default: the body brings a
//!   DDS stack of ~110 crates) it raises `ayllu.AylluError` saying how to build a wheel that
//!   has it: not a `ValueError`, since nothing is wrong with the argument;
//! * with it, errors keep the body's own message, whole (the file, where in it, what is wrong
//!   and what to write instead), and the class a Python programmer would catch: a file that
//!   cannot be read is an `OSError` (`FileNotFoundError`, `PermissionError`,
//!   `IsADirectoryError` as `open()` raises them), a wrong mapping — or one that does not fit
//!   the node — `ayllu.InvalidError` (a `ValueError`), a refusal of the DDS stack
//!   `ayllu.NetworkError`.

use std::path::Path;

use pyo3::prelude::*;

use crate::errors;

/// What `install_ros2_body` says in a module built without the ROS 2 body.
#[cfg(not(feature = "ros2"))]
const WITHOUT_ROS2: &str =
    "this ayllu wheel was built without the ROS 2 body: build it with `make ros2-python` (docs/ros2.md)";

/// Install on `node` the ROS 2 body the mapping file at `path` describes (`{id}` in it stands
/// for the node's id).
#[cfg(feature = "ros2")]
pub fn install(node: &mut ayllu::Node, path: &Path) -> PyResult<()> {
    use ayllu_ros2::Error as E;
    ayllu_ros2::install_file(node, path).map_err(|e| {
        let message = e.to_string();
        match e {
            E::Read { .. } => os_error(path, message),
            E::Ros2(_) => errors::NetworkError::new_err(message),
            _ => errors::InvalidError::new_err(message),
        }
    })
}

/// Without the feature: the error that says how to get it.
#[cfg(not(feature = "ros2"))]
pub fn install(_node: &mut ayllu::Node, _path: &Path) -> PyResult<()> {
    Err(errors::AylluError::new_err(WITHOUT_ROS2))
}

/// The `OSError` subclass `open()` would raise for `path`, carrying `message`. `ayllu_ros2`
/// reports a read failure as text, so the file is asked again (opened and one byte read: a
/// directory opens on Linux and fails only on reading) for the kind of failure.
#[cfg(feature = "ros2")]
fn os_error(path: &Path, message: String) -> PyErr {
    use pyo3::exceptions::{PyFileNotFoundError, PyIsADirectoryError, PyOSError, PyPermissionError};
    use std::io::{ErrorKind, Read};
    let kind = std::fs::File::open(path).and_then(|mut f| f.read(&mut [0u8; 1])).err().map(|e| e.kind());
    match kind {
        Some(ErrorKind::NotFound) => PyFileNotFoundError::new_err(message),
        Some(ErrorKind::PermissionDenied) => PyPermissionError::new_err(message),
        Some(ErrorKind::IsADirectory) => PyIsADirectoryError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}
