//! Register values between Python and Rust (rule S1: never coerced).
//!
//! Promise: `bool` is a Bool (checked before `int`, since Python's bool is an int), `int` an
//! Int (64-bit), `float` a Float, `str` a Text, `bytes` a Bytes, and a list or tuple of numbers
//! a Vector; anything else raises `TypeError`. Back to Python, a Vector is a list of floats.
//! Seconds are Python floats; [`duration`] refuses negative, NaN and infinite ones.

use ayllu_core::{Compact, Duration, Instant, Value};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyFloat, PyInt, PyList, PyString, PyTuple};

use crate::errors;

/// A Python object as a register value.
pub fn to_value(obj: &Bound<'_, PyAny>) -> PyResult<Value> {
    if let Ok(f) = obj.cast_exact::<PyFloat>() {
        return Ok(Value::Float(f.value()));
    }
    if obj.is_instance_of::<PyBool>() {
        return Ok(Value::Bool(obj.is_truthy()?));
    }
    if obj.is_instance_of::<PyInt>() {
        let i: i64 =
            obj.extract().map_err(|_| errors::value_error(format!("{obj} does not fit a 64-bit integer register")))?;
        return Ok(Value::Int(i));
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(Value::Float(obj.extract()?));
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Value::text(&s.to_cow()?));
    }
    if let Ok(b) = obj.cast::<PyBytes>() {
        return Ok(Value::bytes(b.as_bytes()));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let v: Vec<f64> =
            obj.extract().map_err(|_| errors::type_error("a vector value is a list or tuple of numbers"))?;
        return Ok(Value::Vector(v.into()));
    }
    if obj.hasattr("tolist")? {
        // A NumPy array (or anything array-like): as a vector.
        let v: Vec<f64> = obj
            .call_method0("tolist")?
            .extract()
            .map_err(|_| errors::type_error("a vector value is a one-dimensional array of numbers"))?;
        return Ok(Value::Vector(v.into()));
    }
    Err(errors::type_error(format!(
        "Ayllu registers hold bool, int, float, str, bytes or a list of floats, not {}",
        obj.get_type().name()?
    )))
}

/// A register value as a Python object.
pub fn to_py(py: Python<'_>, v: &Value) -> Py<PyAny> {
    match v {
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any().unbind(),
        Value::Int(i) => i.into_pyobject(py).map(|o| o.into_any().unbind()).unwrap_or_else(|_| py.None()),
        Value::Float(x) => PyFloat::new(py, *x).into_any().unbind(),
        Value::Text(s) => PyString::new(py, s).into_any().unbind(),
        Value::Bytes(b) => PyBytes::new(py, b).into_any().unbind(),
        Value::Vector(v) => PyList::new(py, v.iter()).map(|l| l.into_any().unbind()).unwrap_or_else(|_| py.None()),
    }
}

/// The longest span Ayllu's clock holds (nanoseconds in a `u64`), in whole seconds, for
/// messages: 18446744073 s, about 584 years.
const LONGEST_SECS: u64 = Duration::MAX_SECS;

/// `seconds`, given as the argument `what` (`seconds`, `tick`, `period`, `window`...), as a
/// duration: the core's check (`Duration::try_from_secs_f64`, the one the CLI and C use too),
/// its refusal in its words after the argument's name (`seconds = -1 s is negative: a span of
/// time is from 0 to 18446744073 s (about 584 years)`), as `InvalidError` (a `ValueError`).
/// Zero passes (where zero is refused, as for a period, the caller's next check says so).
pub fn duration(what: &str, seconds: f64) -> PyResult<Duration> {
    Duration::try_from_secs_f64(seconds).map_err(|e| errors::InvalidError::new_err(format!("{what} = {e}")))
}

/// A node-clock instant given in seconds since the clock's origin (`set_time`): a time, so
/// refused in words about time, not about periods.
pub fn instant(seconds: f64) -> PyResult<Instant> {
    if !(0.0..=LONGEST_SECS as f64).contains(&seconds) {
        return Err(errors::InvalidError::new_err(format!(
            "time {} s is not on the node's clock: times are seconds since the clock's start, from 0 to \
             {LONGEST_SECS} s (about 584 years)",
            Compact(seconds)
        )));
    }
    Ok(Instant::ZERO + duration("time", seconds)?)
}

/// A node-clock instant in seconds.
pub fn secs(t: Instant) -> f64 {
    t.as_secs_f64()
}
