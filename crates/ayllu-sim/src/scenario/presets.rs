//! Ready-made scenarios: the paper's setting ([`Scenario::paper`]), the same density for a team
//! of any size ([`Scenario::sized`], [`Scenario::try_sized`]), and the one-line variations
//! (loss, length, a recording, a kill halfway) that tests, benches and the tool make of them.
//!
//! Promise: whatever counts they are given, these allocate nothing beyond the bounds
//! ([`crate::bounds`]); what they make is checked like any scenario when it runs.

use crate::bounds::{InvalidScenario, MAX_ROBOTS, MAX_TARGETS};
use crate::controller::{Controller, ControllerConfig};
use crate::radio::RadioConfig;
use crate::scenario_spec::{Kill, Scenario};
use crate::world::WorldConfig;

/// The paper's target priorities for m targets: m, m-1, ..., 1.
pub fn priorities(targets: usize) -> Vec<f64> {
    (1..=targets).rev().map(|p| p as f64).collect()
}

impl Scenario {
    /// The paper's setting (section 4.3): 3 robots, 4 targets with priorities 4, 3, 2, 1, in
    /// the 8 m x 8 m lab, 300 s, no loss.
    pub fn paper(controller: Controller, seed: u64) -> Scenario {
        Scenario::sized(controller, 3, 4, seed)
    }

    /// `robots` robots and `targets` targets in a room that grows with the larger of the two
    /// so that density stays that of the paper's setting (8 m x 8 m for 4).
    ///
    /// Nothing is checked here (that is [`Scenario::validate`]'s job, which every run does), but
    /// nothing beyond the bounds is allocated either: `targets` above [`MAX_TARGETS`] makes
    /// `MAX_TARGETS + 1` targets, and the room is sized from counts capped likewise, so
    /// `sized(.., usize::MAX, ..)` costs nothing and the scenario is refused by `validate`
    /// (naming `robots` or `world.targets`), never shrunk into a valid one. For counts a user
    /// typed, [`Scenario::try_sized`] refuses them with the count as given.
    pub fn sized(controller: Controller, robots: usize, targets: usize, seed: u64) -> Scenario {
        let mut world = WorldConfig::lab(&priorities(targets.min(MAX_TARGETS + 1)));
        let room_for = robots.min(MAX_ROBOTS + 1).max(targets.min(MAX_TARGETS + 1));
        let side = 8.0 * (room_for as f64 / 4.0).sqrt().max(1.0);
        world.arena = [side, side];
        Scenario {
            world,
            robots,
            controller,
            controllers: ControllerConfig { wander_seed: seed, ..ControllerConfig::default() },
            radio: RadioConfig::default(),
            duration: 300.0,
            seed,
            kills: Vec::new(),
            base_station_failure: None,
            record: false,
            frame_dt: 0.2,
            dt: 0.05,
            sense_every: 2,
        }
    }

    /// [`Scenario::sized`], refusing first a team of other than 1 to [`MAX_ROBOTS`] robots or
    /// other than 1 to [`MAX_TARGETS`] targets, naming the count as given (`robots`,
    /// `targets`). The rest is checked by [`Scenario::validate`], as for any scenario.
    pub fn try_sized(
        controller: Controller,
        robots: usize,
        targets: usize,
        seed: u64,
    ) -> Result<Scenario, InvalidScenario> {
        crate::bounds::robots(u64::try_from(robots).ok(), robots)?;
        crate::bounds::targets("targets", u64::try_from(targets).ok(), targets)?;
        Ok(Scenario::sized(controller, robots, targets, seed))
    }

    /// The same scenario with radio loss probability `loss`.
    pub fn loss(mut self, loss: f64) -> Scenario {
        self.radio.loss = loss;
        self
    }

    /// The same scenario lasting `seconds` of virtual time.
    pub fn duration(mut self, seconds: f64) -> Scenario {
        self.duration = seconds;
        self
    }

    /// The same scenario keeping every frame for a replay.
    pub fn recorded(mut self) -> Scenario {
        self.record = true;
        self
    }

    /// Kill the most useful robot halfway through (see [`Kill::robot`]).
    pub fn kill_halfway(mut self) -> Scenario {
        self.kills.push(Kill { at: self.duration / 2.0, robot: None });
        self
    }
}
