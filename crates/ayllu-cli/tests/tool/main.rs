//! The `ayllu` tool as a user runs it: the built binary (`CARGO_BIN_EXE_ayllu`) and real node
//! processes over real sockets, on loopback or in network namespaces the tests create (root and
//! `ip`; see `common/netns.rs`). One module per command family; the `ros2_*` modules are compiled
//! only with the `ros2` feature (`make test-ros2`).
//!
//! One test binary (not one per file): the build is shorter, and the tests that wait on real
//! clocks (a served world for 45 s) overlap with the others instead of running one after the
//! other. Every test names its own namespaces and binds port 0, so any of them may run beside any
//! other. Run one module with `cargo test -p ayllu-cli --test tool cli::`.

mod apply;
mod cli;
mod common;
mod cross_subsumption_processes;
mod discovery;
mod foxglove;
mod node_views;
mod quoted_figures;
mod readme;
mod replay;
mod rolling_recording;
mod ros2_bad_input;
mod ros2_cmommt;
mod ros2_robot;
mod sim_cmommt;
mod sim_distributed;
mod sim_distributed_scenario;
mod sim_files;
mod team_tools;
mod troubleshooting;
mod two_machines;
