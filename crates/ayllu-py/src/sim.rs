//! The simulator from Python (filled in by the next milestone).
use pyo3::prelude::*;

/// Register the simulator's functions on the module.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
