//! The model's rules (docs/semantics.md, "Rule table"), one module per rule: ports, connections,
//! propagation, processes, structure, remote addressing, BLE, transactions, and property tests of
//! arbitration and aggregation. Everything runs on virtual time against `NodeCore`, so a failure
//! replays exactly.
//!
//! One test binary for all of them (not one per file) because each binary links the whole crate
//! graph again: 30 binaries cost minutes of `make test`. Run one rule with
//! `cargo test -p ayllu-core --test rules connection_inhibit::`.

mod access;
mod aggregation_properties;
mod arbitration_properties;
mod ble;
mod common;
mod connection_inhibit;
mod connection_normal;
mod connection_override_in;
mod connection_override_out;
mod connection_suppress;
mod connection_write_inhibit;
mod fan_in;
mod freshness;
mod holder_release;
mod introspection;
mod misuse;
mod monostable;
mod network_vector;
mod port_max;
mod port_min;
mod port_normal;
mod port_priority;
mod port_sum;
mod process_periodic;
mod process_triggered;
mod process_while_fresh;
mod propagation;
mod receive_cache;
mod remote;
mod request_table;
mod shuttle;
// Checkpoints exist with the serde feature (the workspace's tests have it: `ayllu` asks for it).
#[cfg(feature = "serde")]
mod snapshot;
mod structure;
mod structure_from_process;
mod transaction_participant;
