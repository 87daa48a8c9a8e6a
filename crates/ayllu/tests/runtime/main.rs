//! The runtime on real and in-memory transports: nodes, `mem://` and `udp://` over loopback,
//! recording and replay, transactions, the operator key, flood resistance, the README's examples
//! and the book's tutorials. One module per concern.
//!
//! One test binary (not one per file) keeps the test build short. Two tests stay binaries of their
//! own because each installs a `#[global_allocator]` that counts allocations: `allocation.rs`
//! and `forged_flood.rs`. Run one module with `cargo test -p ayllu --test runtime udp_transport::`.

mod address;
mod changes_between_steps;
mod cross_subsumption;
mod examples;
mod group_membership;
mod mem_transport;
mod open_team_flood;
mod operator_key;
mod priority_takeover;
mod reads_from_outside;
mod recording;
mod recording_malformed;
mod replay;
mod replay_rewiring;
mod retrigger;
mod return_routability;
mod rolling_recording;
mod team_recording;
mod team_replay;
mod transaction_mem;
mod transaction_operator;
mod transaction_udp;
mod transport_wrappers;
mod tutorials;
mod udp_transport;
mod url_vectors;
