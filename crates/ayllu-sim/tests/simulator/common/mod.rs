//! Worlds shared by the rule tests: one robot and one static target placed by hand.

use ayllu_sim::world::{Motion, Pose, World, WorldConfig};

/// One robot at `robot`, one static target at `target`, no noise and no missed frames, so
/// geometry checks are exact.
pub fn quiet(robot: Pose, target: (f64, f64)) -> World {
    let mut c = WorldConfig::lab(&[1.0]);
    c.bearing_noise = 0.0;
    c.height_noise = 0.0;
    c.sonar_noise = 0.0;
    c.miss_rate = 0.0;
    c.targets[0].motion = Motion::Static;
    let mut w = World::new(c, 1, 1);
    w.robots[0].pose = robot;
    w.targets[0].x = target.0;
    w.targets[0].y = target.1;
    w
}
