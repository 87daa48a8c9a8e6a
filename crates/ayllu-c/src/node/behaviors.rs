//! Classes and behaviors on a node from C: define a class (built by C with `ay_class_*`, or by a
//! builder function the node calls, which is what `ayDefBehaviorClass` generates), then create
//! and remove behaviors of it, also while the node runs (rule S9).
//!
//! Promise: a class handed to `ay_node_define` is consumed whether or not the node accepts it,
//! so C never frees it twice.

use std::ffi::{c_char, c_void};

use super::handle::{ay_node, with_node, NodeState};
use crate::class::{self, ay_class};
use crate::cstr::text;
use crate::registry::{self, Kind};
use crate::status::{ay_status, boundary, Fail};

/// A signature for class builders (`ay_node_define_with`): declare the class's ports, slots,
/// monostables and processes on `class`.
#[allow(non_camel_case_types)]
pub type ay_class_fn = Option<unsafe extern "C" fn(cls: *mut ay_class, user: *mut c_void)>;

/// Define class `cls` on the node (rule S2), consuming it whether or not this succeeds.
///
/// Ownership: takes `cls` (the handle is invalid afterwards). Thread-safety: the node's
/// thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE` (node or class), `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (a class of that name is already defined here).
///
/// # Safety
/// `node` and `cls` are NULL or pointers from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_node_define(node: *mut ay_node, cls: *mut ay_class) -> ay_status {
    boundary("ay_node_define", || {
        registry::check(node, Kind::Node, "node")?;
        registry::remove(cls, Kind::Class, "class")?;
        // SAFETY: came from Box::into_raw in ay_class_new and was just unregistered.
        let class = unsafe { Box::from_raw(cls) };
        with_node(node, |s| Ok(s.node.define(class.finish())?))
    })
}

fn define_with(s: &mut NodeState, name: &str, build: ay_class_fn, user: *mut c_void) -> Result<(), Fail> {
    let Some(build) = build else { return Err(Fail::null("builder")) };
    let mut class = ay_class::new(name);
    class::lend(&mut class);
    // SAFETY: `build` is a C function of this signature; the class is registered for the
    // call, so the builder's ay_class_* calls on it are checked like any other.
    unsafe { build(&mut class, user) };
    class::unlend(&mut class);
    Ok(s.node.define(class.finish())?)
}

/// Define class `name` on the node by calling `build(class, user)` to declare its interface
/// and processes (what `ayDefBehaviorClass` generates). Errors from inside `build` are its
/// own calls' to handle; the class is defined with whatever they declared.
///
/// Ownership: `user` is passed to `build` and stored by the processes it declares with it.
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL` (name, build), `AY_ERR_HANDLE`,
/// `AY_ERR_BUSY`, `AY_ERR_INVALID` (empty name, class already defined here).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `name` is NULL or NUL-terminated; `build`
/// is NULL or a function of this signature.
#[no_mangle]
pub unsafe extern "C" fn ay_node_define_with(
    node: *mut ay_node,
    name: *const c_char,
    build: ay_class_fn,
    user: *mut c_void,
) -> ay_status {
    boundary("ay_node_define_with", || {
        // SAFETY: the C caller's promise on `name`.
        let name = unsafe { text(name, "name") }?;
        if name.is_empty() {
            return Err(Fail::invalid("a class needs a name"));
        }
        with_node(node, |s| define_with(s, name, build, user))
    })
}

/// Create behavior `name` of class `class` (the paper's `ayInitBehavior`), first defining
/// the class with `build(class, user)` if the node does not have it yet (`build` may be NULL
/// when the class is known to be defined).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (class not defined and no builder), `AY_ERR_INVALID` (empty or taken
/// behavior name).
///
/// # Safety
/// As [`ay_node_define_with`]; `behavior` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_init_behavior(
    node: *mut ay_node,
    class_name: *const c_char,
    build: ay_class_fn,
    user: *mut c_void,
    behavior: *const c_char,
) -> ay_status {
    boundary("ay_node_init_behavior", || {
        // SAFETY: the C caller's promises on `class` and `behavior`.
        let (class, behavior) = unsafe { (text(class_name, "class")?, text(behavior, "behavior")?) };
        with_node(node, |s| {
            if !s.node.core().has_class(class) && build.is_some() {
                define_with(s, class, build, user)?;
            }
            s.node.create(class, behavior)?;
            Ok(())
        })
    })
}

/// Create behavior `behavior` of a defined class `class` (rule S9: also while running).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN` (no such class), `AY_ERR_INVALID` (empty or taken name).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; the names are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_create(
    node: *mut ay_node,
    class_name: *const c_char,
    behavior: *const c_char,
) -> ay_status {
    boundary("ay_node_create", || {
        // SAFETY: the C caller's promises on the names.
        let (class, behavior) = unsafe { (text(class_name, "class")?, text(behavior, "behavior")?) };
        with_node(node, |s| Ok(s.node.create(class, behavior).map(|_| ())?))
    })
}

/// Remove behavior `behavior` and every connection into or out of it (rule S9).
///
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_UNKNOWN`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `node` is NULL or a pointer from this library; `behavior` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_remove(node: *mut ay_node, behavior: *const c_char) -> ay_status {
    boundary("ay_node_remove", || {
        // SAFETY: the C caller's promise on `behavior`.
        let behavior = unsafe { text(behavior, "behavior") }?;
        with_node(node, |s| Ok(s.node.remove(behavior)?))
    })
}
