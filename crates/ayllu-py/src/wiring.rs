//! Building on a node's core: defining Python classes, creating behaviors, connecting ports,
//! joining groups and BLE. Shared by [`crate::node::Node`] (a node of the runtime) and
//! the simulator's robot builder (a robot's node inside the simulator), so both take the same
//! arguments and raise the same exceptions.
//!
//! Promise: nothing here decides semantics; each call is one call of the core's API.

use std::sync::Arc;

use ayllu_core::{
    Allow, BleConfig, ConnectOptions, ConnectionId, ControlBody, Limits, NodeCore, NodeId, ReplyBody, RequestId,
    RequestStatus,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::behavior::{self, Processes};
use crate::connection::{endpoint, ConnectArgs};
use crate::errors;
use crate::stdlib::{define_stdlib_class, StdlibOptions};
use crate::value::duration;

/// `core.connect` with Python arguments; the connection's id.
pub fn connect(core: &mut NodeCore, (source, destination, kind): &ConnectArgs, priority: i32) -> PyResult<u64> {
    core.connect(&endpoint(source)?, &endpoint(destination)?, *kind, ConnectOptions { priority })
        .map(|ConnectionId(id)| id)
        .map_err(errors::core)
}

/// `core.ble_join`: what it made, as a dict (`eligibility`, `inhibition`, `warnings`).
#[allow(clippy::too_many_arguments)]
pub fn ble_join<'py>(
    py: Python<'py>,
    core: &mut NodeCore,
    behavior: &str,
    group: &str,
    output: &str,
    claim_hz: f64,
    inhibit_period: Option<f64>,
    network_delay: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut cfg = BleConfig::new(group, output, claim_hz).map_err(errors::core)?;
    if let Some(d) = network_delay {
        cfg = cfg.network_delay(duration("network_delay", d)?);
    }
    if let Some(p) = inhibit_period {
        cfg = cfg.inhibit_period(duration("inhibit_period", p)?);
    }
    let g = core.ble_join(behavior, &cfg).map_err(errors::core)?;
    let d = PyDict::new(py);
    d.set_item("eligibility", g.eligibility.0)?;
    d.set_item("inhibition", g.inhibition.0)?;
    d.set_item("warnings", g.warnings)?;
    d.set_item("inhibit_period", cfg.inhibit_period.as_secs_f64())?;
    Ok(d)
}

/// Define a subclass of `ayllu.Behavior` (see [`behavior::define`]).
pub fn define(py: Python<'_>, core: &mut NodeCore, procs: &Arc<Processes>, cls: &Bound<'_, PyAny>) -> PyResult<()> {
    behavior::define(py, core, procs, cls)
}

/// Create behavior `name` of `cls` (a class name, or an `ayllu.Behavior` subclass, defined
/// first if this node does not have it yet); the behavior's Python object (None for a Rust
/// class).
pub fn create(
    py: Python<'_>,
    core: &mut NodeCore,
    procs: &Arc<Processes>,
    cls: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<Option<Py<PyAny>>> {
    let class: String = match cls.extract::<String>() {
        Ok(s) => s,
        Err(_) => {
            let class = behavior::Declaration::of(cls)?.name;
            if !core.has_class(&class) {
                define(py, core, procs, cls)?;
            }
            class
        }
    };
    core.create(&class, name).map_err(errors::core)?;
    match procs.instantiate(py, &class, name) {
        Ok(obj) => Ok(obj),
        Err(e) => {
            let _ = core.remove(name);
            Err(e)
        }
    }
}

/// A report (JSON from the core's serde) as an `ayllu.Report`, with `text` as its `str()`.
pub fn report(py: Python<'_>, json: &str, text: Option<String>) -> PyResult<Py<PyAny>> {
    Ok(py.import("ayllu.report")?.getattr("from_json")?.call1((json, text))?.unbind())
}

/// A serde value as JSON text for Python (`json.loads` on the other side).
pub fn json<T: serde::Serialize>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| errors::value_error(e.to_string()))
}

/// Define one of the standard library's classes on `core` (see [`define_stdlib_class`]).
pub fn define_stdlib(core: &mut NodeCore, name: &str, options: &StdlibOptions) -> PyResult<()> {
    let class = define_stdlib_class(name, options).map_err(errors::core)?;
    core.define(class).map_err(errors::core)
}

/// `core.request_connect` with Python arguments: ask `source`'s node (a remote endpoint) to
/// connect its port to `destination`; the request's id.
pub fn request_connect(core: &mut NodeCore, (source, destination, kind): &ConnectArgs, priority: i32) -> PyResult<u64> {
    core.request_connect(&endpoint(source)?, &endpoint(destination)?, *kind, ConnectOptions { priority })
        .map(|RequestId(id)| id)
        .map_err(errors::core)
}

/// `core.request(node, body)`: the request's id.
pub fn request(core: &mut NodeCore, node: u32, body: ControlBody) -> PyResult<u64> {
    core.request(NodeId(node), body).map(|RequestId(id)| id).map_err(errors::core)
}

/// Where request `id` stands, as an `ayllu.RequestStatus` (`state` `pending`, `done` or
/// `failed`; `sends`, `result`, `error`). A request this node never sent raises `NotFoundError`.
pub fn request_status(py: Python<'_>, core: &NodeCore, id: u64) -> PyResult<Py<PyAny>> {
    let status = core
        .request_status(RequestId(id))
        .ok_or_else(|| errors::NotFoundError::new_err(format!("request {id} was never sent by node {}", core.id())))?;
    let (state, sends, result, error): (&str, u32, Option<Py<PyAny>>, Option<String>) = match status {
        RequestStatus::Pending { sends } => ("pending", sends, None, None),
        RequestStatus::Done(body) => ("done", 0, Some(reply(py, body)?), None),
        RequestStatus::Failed(msg) => ("failed", 0, None, Some(msg)),
    };
    let cls = py.import("ayllu.report")?.getattr("RequestStatus")?;
    Ok(cls.call1((state, sends, result, error))?.unbind())
}

/// A reply as Python: a connection id (int), a value, or a report (`ayllu.Report`).
fn reply(py: Python<'_>, body: ReplyBody) -> PyResult<Py<PyAny>> {
    Ok(match body {
        ReplyBody::Connection(ConnectionId(c)) => c.into_pyobject(py)?.into_any().unbind(),
        ReplyBody::Value(v) => crate::value::to_py(py, &v),
        ReplyBody::Node(r) => report(py, &json(&*r)?, None)?,
        ReplyBody::Port(r) => report(py, &json(&*r)?, Some(r.to_string()))?,
        ReplyBody::OtherReport(j) => report(py, &j, None)?,
    })
}

/// An access right as Python gives it: `"all"`, `"none"` or a list of node ids.
pub fn allow(what: &str, obj: &Bound<'_, PyAny>) -> PyResult<Allow> {
    if let Ok(s) = obj.extract::<String>() {
        return match s.as_str() {
            "all" => Ok(Allow::Everyone),
            "none" => Ok(Allow::Nobody),
            _ => Err(errors::InvalidError::new_err(format!(
                "{what}= is \"all\", \"none\" or a list of node ids, not {s:?}"
            ))),
        };
    }
    let ids: Vec<u32> = obj
        .extract()
        .map_err(|_| errors::type_error(format!("{what}= is \"all\", \"none\" or a list of node ids; got {obj}")))?;
    Ok(Allow::Only(ids.into_iter().map(NodeId).collect()))
}

/// Limits from Python's keyword arguments; each one left out keeps `Limits::default()`'s.
pub fn limits(
    remote_connections: Option<usize>,
    remote_connections_per_node: Option<usize>,
    max_remote_period: Option<f64>,
    requests_per_second: Option<u32>,
    requests_burst: Option<u32>,
) -> PyResult<Limits> {
    let d = Limits::default();
    Ok(Limits {
        remote_connections: remote_connections.unwrap_or(d.remote_connections),
        remote_connections_per_node: remote_connections_per_node.unwrap_or(d.remote_connections_per_node),
        max_remote_period: max_remote_period
            .map(|p| duration("max_remote_period", p))
            .transpose()?
            .unwrap_or(d.max_remote_period),
        requests_per_second: requests_per_second.unwrap_or(d.requests_per_second),
        requests_burst: requests_burst.unwrap_or(d.requests_burst),
    })
}
