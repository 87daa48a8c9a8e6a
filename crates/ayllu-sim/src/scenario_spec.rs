//! What a scenario is: the data that defines one run, [`Scenario`] and its [`Kill`]s, as a
//! scenario file, the Python package or Rust code writes it. Both are named
//! `crate::scenario::{Scenario, Kill}`, beside the run; they are defined here, alone.
//!
//! Only the data: checking it is [`crate::bounds`]' job and running it
//! [`Sim`](crate::scenario::Sim)'s. It stands apart from both because the bounds read these
//! fields and the run calls the bounds: defined beside the run, the data would make the run's
//! module and the bounds need each other.

use serde::{Deserialize, Serialize};

use crate::controller::{Controller, ControllerConfig};
use crate::radio::RadioConfig;
use crate::world::WorldConfig;

/// A scheduled robot failure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Kill {
    /// Seconds into the run.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub at: f64,
    /// The robot's node id; `None`: the robot observing the highest-priority observed target
    /// at that moment (lowest id on ties; robot 1 if none observes anything) — the failure
    /// that hurts most, so re-covering is tested where it matters.
    pub robot: Option<u32>,
}

/// How the Planner's base station is lost ([`BaseStationFailure`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BaseStationLoss {
    /// It stops for good: no more plans, and what it knew is gone.
    Killed,
    /// The radio cuts it off from every robot (a partition with the base station alone on its
    /// side) until `until`, if given; it keeps running and planning from what reaches it
    /// (nothing), and picks up again once reconnected.
    Partitioned,
}

/// The Planner's base station failing at an instant (docs/cmommt.md, "Losing the base
/// station"): an event of the scenario like a kill. A run without a base station (every
/// controller but the Planner) has nothing to lose and runs as without it, so one sweep can
/// compare the Planner losing its base station with the teams that have none.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseStationFailure {
    /// Seconds into the run.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub at: f64,
    /// Killed or partitioned.
    pub how: BaseStationLoss,
    /// `Partitioned`: when the base station is reachable again (s); `None`: never.
    #[serde(default, deserialize_with = "crate::numbers::optional_number_de")]
    pub until: Option<f64>,
}

/// Everything that defines a run: the world, the team, the controller, the radio, the kills,
/// the seed and the rates. Serializable: `scenario_file` reads it from TOML.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// The arena, sensors and targets.
    pub world: WorldConfig,
    /// Robots at the start (node ids 1..=robots).
    pub robots: usize,
    /// The controller every robot runs.
    pub controller: Controller,
    /// The controllers' tunables (claim rate, wander seed, eligibility policy).
    pub controllers: ControllerConfig,
    /// The radio medium.
    pub radio: RadioConfig,
    /// Run length (s of virtual time).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub duration: f64,
    /// Seed of the placement, target-motion, sensor-noise and radio streams (the wander seed is
    /// `controllers.wander_seed`).
    pub seed: u64,
    /// Scheduled robot failures, any number, at any instants.
    pub kills: Vec<Kill>,
    /// The Planner's base station failing, if it does (nothing for the other controllers).
    /// Left out of the scenario's serde form when `None`, so that scenarios written before it
    /// existed read and write as they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_station_failure: Option<BaseStationFailure>,
    /// Keep every frame for a replay (costs memory; the hash is computed either way).
    pub record: bool,
    /// Virtual seconds between frames (hashed, sampled for coverage, recorded if `record`),
    /// rounded to a whole number of ticks.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub frame_dt: f64,
    /// Tick length (s of virtual time); 0.05 is the observers' 20 Hz.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub dt: f64,
    /// Ticks between camera frames and sonar sweeps (2: 10 Hz at 50 ms ticks).
    pub sense_every: u32,
}
