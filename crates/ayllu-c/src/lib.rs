//! # libayllu — the C ABI over the Ayllu runtime
//!
//! What C and C++ programs link (`libayllu.a`, `libayllu.so`) to write behaviors as the
//! paper does: nodes on `udp://` and `mem://` with the real clock or a manual one, behavior
//! classes with ports of every kind and type, slots, monostables and processes whose bodies
//! are C functions, connections of every kind (local, remote, group), BLE in one call,
//! `why`/`list` reports as JSON, the standard behaviors, the simulator's robot body and the
//! ROS 2 body (its code only with the cargo feature `ros2`; the function is always there).
//! `include/ayllu_sys.h` is generated from this crate by cbindgen (a test fails when it
//! drifts); `include/ayllu.h` is the paper's macro layer over it (docs/c-api.md).
//!
//! Promises at the boundary:
//! * every function returns an [`ay_status`] (or is infallible and says so); a failure also
//!   sets the calling thread's message, [`ay_last_error`];
//! * nothing unwinds into C and nothing aborts: panics are caught ([`status::boundary`]) and
//!   returned as `AY_ERR_PANIC`;
//! * handles are opaque and typed; a NULL, freed or foreign handle is refused before it is
//!   touched ([`registry`]);
//! * the semantics are the runtime's: this crate converts and checks, never re-implements.

#![warn(missing_docs)]

pub mod class;
pub mod clock;
pub mod connection;
mod cstr;
pub mod node;
pub mod process;
pub mod reconfiguration;
pub mod recording;
mod register;
mod registry;
pub mod report;
pub mod ros2;
mod seconds;
pub mod served_world;
pub mod status;
pub mod stdlib;

pub use cstr::ay_string_free;
pub use status::{ay_last_error, ay_status};
