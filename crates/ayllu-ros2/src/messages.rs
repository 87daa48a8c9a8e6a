//! The ROS 2 message types the ROS 2 body knows, as runtime schemas, and their CDR form.
//!
//! A topic's samples are read and written without one Rust struct per message type. A
//! [`MessageType`] is a type's layout: its fields in declaration order, exactly as ROS 2 Jazzy
//! declares them, because CDR is positional. A [`Sample`] holds one value per leaf of that
//! layout, and a [`FieldRef`], resolved once from a path such as `pose.pose.position.x` when a
//! mapping file is loaded, reads or writes one leaf as an Ayllu [`Value`](ayllu_core::Value).
//!
//! The bytes go through serde, into and out of the very CDR (de)serializer RustDDS uses for a
//! topic's samples: [`Decode`] is the `DeserializeSeed` for ros2-client's
//! `Subscription::take_seed`, and [`Encoded`] is what a `Publisher<Encoded>` publishes.
//!
//! ## Promises
//! * Byte-exact with ROS 2's plain CDR (XCDR1, what `rmw_fastrtps_cpp` and
//!   `rmw_cyclonedds_cpp` send): primitives aligned to their size relative to the payload's
//!   start, strings and sequences prefixed by a `uint32` length, fixed arrays not.
//! * Nothing panics on any input. A payload that cannot be decoded is an error, and its
//!   [`DecodeCause`] is left in the cell the [`Decode`] was given, since `take_seed` hands back
//!   only a generic error.
//! * Bounded allocation: a sequence longer than [`Decode::max_elements`] is refused from its
//!   length field alone, before any of it is read or allocated.
//! * What is written is what is sent: [`Sample::set`] refuses values the field cannot hold (3e9
//!   into an `int32`, a vector of 35 into a `float64[36]`) and rounds floats to the field's
//!   width, so [`Sample::get`] returns what subscribers will receive.
//!
//! ## Non-goals
//! * Types beyond the list below: there is no `.msg` parser and no type discovery.
//! * XCDR2 and keyed topics (none of these types has a key).
//! * Mapping sequences of messages (`MultiArrayLayout.dim`): they are kept so a sample
//!   round-trips, but have no [`FieldKind`].
//!
//! ## The parts
//! `schema` is the table of types, `field` resolves paths to leaves, `sample` holds and
//! converts the values, and `cdr` turns a sample into bytes and back. Each depends only on
//! those before it, so a type added to the table needs nothing from the others.

mod cdr;
mod field;
mod sample;
mod schema;

pub use cdr::{Decode, DecodeCause, Encoded};
pub use field::{FieldError, FieldKind, FieldRef};
pub use sample::{Sample, SetError};
pub use schema::{message_type, message_types, MessageType};
