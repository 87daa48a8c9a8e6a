//! A connection as Python spells it: endpoints (`ayllu.Endpoint` or a `(behavior, port)`
//! tuple) and kinds (`ayllu.Kind`), checked into the core's [`Endpoint`] and
//! [`ConnectionKind`]. A node's `connect` (`wiring.rs`) and a process's reconfiguration
//! requests (`behavior.rs`) take the same arguments, so both read them here.
//!
//! Promise: every argument is checked before a node is touched; a malformed one raises
//! `TypeError` or `ValueError` naming the forms it may take.

use ayllu_core::{ConnectionKind, Endpoint, NodeId};
use pyo3::prelude::*;

use crate::errors;
use crate::value::duration;

/// An endpoint as Python passes it: `(behavior, port, node, group)`, node and group optional.
pub type EndpointArg = (String, String, Option<u32>, Option<String>);

/// The endpoint of a Python endpoint tuple.
pub fn endpoint(e: &EndpointArg) -> PyResult<Endpoint> {
    Ok(match (&e.2, &e.3) {
        (None, None) => Endpoint::local(&e.0, &e.1),
        (Some(n), None) => Endpoint::node(NodeId(*n), &e.0, &e.1),
        (None, Some(g)) => Endpoint::group(g, &e.0, &e.1),
        (Some(_), Some(_)) => return Err(errors::value_error("an endpoint is on one node or one group, not both")),
    })
}

/// The connection kind named `name` (`normal`, `suppress`, `inhibit`, `override-in`,
/// `override-out`, `write-inhibit`) with `period` seconds (required for every kind but normal).
pub fn kind(name: &str, period: Option<f64>) -> PyResult<ConnectionKind> {
    if name != "normal" && period.is_none() && ConnectionKind::from_name(name, ayllu_core::Duration::ZERO).is_some() {
        return Err(errors::value_error(format!("a {name} connection needs a period (seconds)")));
    }
    let period = period.map(|p| duration("period", p)).transpose()?;
    ConnectionKind::from_parts(name, period).map_err(errors::core)
}

/// An endpoint argument: an `ayllu.Endpoint` (a named tuple `(behavior, port, node, group)`)
/// or a plain `(behavior, port)` tuple for a local port.
pub fn endpoint_arg(obj: &Bound<'_, PyAny>) -> PyResult<EndpointArg> {
    if let Ok(e) = obj.extract::<EndpointArg>() {
        return Ok(e);
    }
    if let Ok((b, p)) = obj.extract::<(String, String)>() {
        return Ok((b, p, None, None));
    }
    Err(errors::type_error(format!(
        "an endpoint is ayllu.local(b, p), ayllu.remote(node, b, p), ayllu.broadcast(group, b, p) or (b, p); got {obj}"
    )))
}

/// A connection-kind argument: an `ayllu.Kind` (a named tuple `(name, period)`); None is Normal.
pub fn kind_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<ConnectionKind> {
    let Some(obj) = obj else { return Ok(ConnectionKind::Normal) };
    if obj.is_none() {
        return Ok(ConnectionKind::Normal);
    }
    let (name, period): (String, Option<f64>) = obj.extract().map_err(|_| {
        errors::type_error(format!(
            "a connection kind is ayllu.NORMAL or ayllu.suppress(s), inhibit(s), override_in(s), override_out(s), write_inhibit(s); got {obj}"
        ))
    })?;
    kind(&name, period)
}

/// A `connect` call's `(source, destination, kind)` arguments, checked.
pub type ConnectArgs = (EndpointArg, EndpointArg, ConnectionKind);

/// Check a `connect` call's `source`, `destination` and `kind` (before the node is touched).
pub fn connect_args(
    source: &Bound<'_, PyAny>,
    destination: &Bound<'_, PyAny>,
    kind: Option<&Bound<'_, PyAny>>,
) -> PyResult<ConnectArgs> {
    Ok((endpoint_arg(source)?, endpoint_arg(destination)?, kind_arg(kind)?))
}
