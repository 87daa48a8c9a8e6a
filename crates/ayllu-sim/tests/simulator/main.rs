//! The simulator's rules and studies: the world, the radio, the body, the paper's claim, the
//! baselines, determinism (trace hashes), scenario bounds, the served world on loopback, the
//! report in headless Chromium, and the book's simulator tutorials. One module per concern.
//!
//! One test binary (not one per file) keeps the test build short. Run one module with
//! `cargo test -p ayllu-sim --test simulator determinism::`.

mod ble_seek;
mod body;
mod cmommt;
mod common;
mod determinism;
mod metrics;
mod planner;
mod radio;
mod redistribution;
mod report_chromium;
mod scenario_validation;
mod served_world;
mod study_files;
mod tutorials;
mod world;
