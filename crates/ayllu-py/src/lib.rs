//! # ayllu-py — Ayllu for Python
//!
//! The native half of the `ayllu` Python package (PyO3, one abi3 wheel for CPython >= 3.9);
//! the Python half (`python/ayllu`) adds the declarative `Behavior` base class, decorators,
//! endpoint and connection-kind helpers, reports and the simulator's scenario builder.
//!
//! Promise: this crate *wraps*. Every rule of docs/semantics.md is decided by `ayllu-core`,
//! every run of the simulator by `ayllu-sim`; Python code only declares, wires, drives time
//! and reads results. Misuse raises a Python exception (`ayllu.AylluError` and subclasses);
//! a Python exception inside a process is counted and reported, never fatal to the node.

pub mod behavior;
pub mod connection;
pub mod errors;
pub mod node;
pub mod recording;
pub mod ros2;
pub mod served;
pub mod sim;
pub mod stdlib;
pub mod value;
pub mod wiring;

use pyo3::prelude::*;

/// The extension module `ayllu._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<behavior::PortDecl>()?;
    m.add_class::<behavior::SlotDecl>()?;
    m.add_class::<behavior::MonoDecl>()?;
    m.add_class::<behavior::Context>()?;
    m.add_class::<node::Node>()?;
    m.add_class::<node::Team>()?;
    m.add_class::<node::PortHandle>()?;
    m.add_function(wrap_pyfunction!(node::stop_all, m)?)?;
    m.add_function(wrap_pyfunction!(node::default_url, m)?)?;
    m.add_function(wrap_pyfunction!(recording::check_recording, m)?)?;
    m.add_function(wrap_pyfunction!(recording::check_team, m)?)?;
    m.add_function(wrap_pyfunction!(recording::why_team, m)?)?;
    sim::register(m)?;
    served::register(m)?;
    m.add("DROP_CAUSES", ayllu_core::DropCause::ALL.iter().map(|c| c.name()).collect::<Vec<_>>())?;
    Ok(())
}
