//! The node handle C holds: an [`ay_node`] owns one runtime `Node` and lets one call at a time
//! reach it. Every node function goes through [`with_node`], which is where a NULL, freed or
//! foreign pointer is refused and where a call made from the node's own process is refused
//! with `AY_ERR_BUSY` (that process already has its context).
//!
//! Promise: while `with_node` runs its closure, no other reference to the node's state exists.

use std::cell::{Cell, UnsafeCell};

use ayllu::{Node, PortRef};

use crate::registry::{self, Kind};
use crate::status::{ay_status, Fail};

/// A running node (opaque): the runtime's `Node` with its clock and transport.
#[allow(non_camel_case_types)]
pub struct ay_node {
    state: UnsafeCell<NodeState>,
    busy: Cell<bool>,
}

/// What a node handle owns.
pub(crate) struct NodeState {
    pub(crate) node: Node,
    /// Port handles given out by `ay_node_port`, by index.
    pub(super) refs: Vec<PortRef>,
}

struct Unbusy<'a>(&'a Cell<bool>);

impl Drop for Unbusy<'_> {
    fn drop(&mut self) {
        self.0.set(false);
    }
}

/// Run `f` on a live node that no other call is using.
pub(crate) fn with_node<T>(p: *mut ay_node, f: impl FnOnce(&mut NodeState) -> Result<T, Fail>) -> Result<T, Fail> {
    registry::check(p, Kind::Node, "node")?;
    // SAFETY: registered node pointers come from Box::into_raw in `open` and are unregistered
    // before they are freed, so `p` points to a live ay_node. Only a shared reference is made
    // here: the mutable parts are behind Cell and UnsafeCell.
    let h = unsafe { &*p };
    if h.busy.get() {
        return Err(Fail::new(
            ay_status::AY_ERR_BUSY,
            "the node is running its processes (a process reaches its own node through its context), \
             or another call on it has not returned",
        ));
    }
    h.busy.set(true);
    let _unbusy = Unbusy(&h.busy);
    // SAFETY: `busy` was false and is now true until `_unbusy` drops, so no other reference
    // to the state exists (a node is driven by one thread at a time, as documented, and
    // re-entrant calls are refused above).
    f(unsafe { &mut *h.state.get() })
}

/// The one place a node handle is made, so that every handle C holds is registered before C
/// sees it (what [`with_node`] checks).
pub(super) fn open(node: Node, out: *mut *mut ay_node) -> Result<(), Fail> {
    let p = Box::into_raw(Box::new(ay_node {
        state: UnsafeCell::new(NodeState { node, refs: Vec::new() }),
        busy: Cell::new(false),
    }));
    registry::add(p, Kind::Node);
    // SAFETY: `out` was checked non-null by the callers and is valid for a write (the C
    // caller's promise).
    unsafe { out.write(p) };
    Ok(())
}
