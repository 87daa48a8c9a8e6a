//! A run of the task: the world, one Ayllu node per robot (body + controller), the radio
//! between them, and the metrics — all on virtual time, stepped by [`Sim::step`].
//!
//! Promise: [`run`] is a pure function of the [`Scenario`]: same scenario and seed, same
//! outcome bit for bit, on any machine and with any number of threads ([`Sim::set_threads`];
//! no clock, no hash-map iteration order; all randomness from seeded streams). The trace hash
//! is SHA-256 over every frame's exact state (f64 bits), so any divergence shows.
//!
//! One tick (`dt`, 50 ms = the observers' 20 Hz): kills due; the radio's deliveries due are set
//! aside; every `sense_every` ticks each live robot's body takes a camera frame and its sonar
//! sweep's noise draws, in robot order (one noise stream); then robot by robot (one visit each,
//! so its node stays in cache; shared out among threads if allowed): its deliveries, its sonar
//! sweep and its senses written to its ports, the oracle's word (Centralized only), its pose (Planner only), its node runs at
//! the tick's time, its motors are read; then every robot's outgoing messages enter the radio
//! in robot order; the Planner's base station (a node of its own, the radio's last station)
//! takes its deliveries, polls and sends; the world moves; metrics account the tick; every
//! `frame_dt` a frame is hashed (and recorded if asked). Robots meet only through the world
//! and the radio, and nothing sent in a tick is delivered before the next, so this equals
//! doing each stage for every robot in turn.
//!
//! The parts: [`Scenario`] and [`Kill`] are the data, defined in `scenario_spec` and named
//! here; ready-made scenarios are in `presets`; [`Sim`] owns a run and steps it (`sim`); one
//! robot's turn in a tick, and how the turns are shared among threads, is `visit`; `kills`
//! carries out failures, for the distributed server too; [`Outcome`] and [`SimError`] are what
//! a run gives back (`outcome`). The data lives outside this module because [`crate::bounds`]
//! reads it while [`Sim::new`] calls the bounds: the bounds sit between the data and the run.

mod kills;
mod outcome;
mod presets;
mod sim;
#[cfg(test)]
mod tests;
mod visit;

pub use crate::scenario_spec::{BaseStationFailure, BaseStationLoss, Kill, Scenario};
pub use kills::{apply_due_kills, most_useful_robot};
pub use outcome::{Outcome, RadioStats, SimError};
pub use presets::priorities;
pub use sim::{node_id, run, run_on, BuildController, Sim};
