//! Nodes from C: open one on a `udp://` or `mem://` URL with the real clock or a manual one,
//! define classes, create and remove behaviors, write and read ports from outside, step and
//! run the loop, join groups and BLE. A node is driven by one thread at a time; a process may
//! not call node functions on its own node (it gets `AY_ERR_BUSY`: it has its context).
//!
//! Every node function keeps one path, `crate::node::…`, whichever file below holds it. The
//! files are declared in the order `include/ayllu_sys.h` lists their functions: cbindgen
//! writes a module's functions in file order, module by module in declaration order, so
//! reordering the `mod` lines reorders the committed header (and fails `tests/library/header.rs`).
//! The blank lines between them keep rustfmt from sorting them.

mod handle;

mod lifecycle;

mod behaviors;

mod ports;

mod monostables;

mod groups;

mod default_node;

pub use behaviors::*;
pub use default_node::*;
pub use groups::*;
pub use handle::ay_node;
pub(crate) use handle::with_node;
pub use lifecycle::*;
pub use monostables::*;
pub use ports::*;
