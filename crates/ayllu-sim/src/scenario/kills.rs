//! Robot failures as a run carries them out: which robot each [`Kill`] takes, and when.
//!
//! One rule for both ways a scenario runs, the in-process [`Sim`](super::Sim) and the
//! distributed server (`ayllu-cli`'s `sim_serve`), so that both kill the same robots.

use crate::scenario_spec::Kill;
use crate::world::World;

/// Carry out the kills of `kills` due at `t` (s) and not yet `done`: each, in order, marks
/// its robot dead in `world` ([`Kill::robot`]'s rule sees the robots this instant already
/// killed as dead). Returns the robot indexes killed now, for
/// [`crate::metrics::Meter::killed_together`] — all dead before their lost targets are judged.
/// Shared by the in-process [`Sim`](super::Sim) and the distributed server, so both kill the same robots.
pub fn apply_due_kills(kills: &[Kill], done: &mut [bool], t: f64, world: &mut World) -> Vec<usize> {
    let mut killed = Vec::new();
    for (k, kill) in kills.iter().enumerate() {
        if done[k] || kill.at > t {
            continue;
        }
        done[k] = true;
        let i = match kill.robot {
            Some(id) => (id as usize).checked_sub(1).filter(|&i| i < world.robots.len()),
            None => most_useful_robot(world),
        };
        let Some(i) = i else { continue };
        if !world.robots[i].alive {
            continue;
        }
        world.robots[i].alive = false;
        killed.push(i);
    }
    killed
}

/// The live robot observing the highest-priority observed target (lowest index on ties; the
/// first live robot if none observes anything).
pub fn most_useful_robot(world: &World) -> Option<usize> {
    let range = world.config.observe_range;
    let mut best: Option<(usize, usize)> = None; // (target index, robot)
    for (i, r) in world.robots.iter().enumerate() {
        if !r.alive {
            continue;
        }
        world.in_view(i, range, |j, _, _| {
            if best.is_none_or(|(bj, _)| j < bj) {
                best = Some((j, i));
            }
        });
    }
    best.map(|(_, i)| i).or_else(|| world.robots.iter().position(|r| r.alive))
}
