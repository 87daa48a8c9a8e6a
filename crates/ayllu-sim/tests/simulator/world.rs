//! The physical world's rules: unicycle kinematics, walls, contacts, the camera's bearing
//! convention and apparent height, the sonar ring, target motion.

use std::f64::consts::PI;

use crate::common;

use ayllu_sim::world::{Command, Motion, Pose, Sighting, SonarScratch, World, WorldConfig};
use common::quiet;

fn run(w: &mut World, cmd: Command, seconds: f64) {
    for _ in 0..(seconds / 0.05).round() as usize {
        w.step(0.05, &[cmd]);
    }
}

#[test]
fn unicycle_drives_straight_and_turns() {
    let mut w = quiet(Pose { x: 1.0, y: 1.0, theta: 0.0 }, (7.5, 7.5));
    run(&mut w, Command { translate: 0.4, rotate: 0.0 }, 5.0);
    let p = w.robots[0].pose;
    assert!((p.x - 3.0).abs() < 1e-9 && (p.y - 1.0).abs() < 1e-9, "{p:?}");
    run(&mut w, Command { translate: 0.0, rotate: 0.5 }, 3.0);
    assert!((w.robots[0].pose.theta - 1.5).abs() < 1e-9);
    // Headings wrap into (-π, π].
    run(&mut w, Command { translate: 0.0, rotate: 0.5 }, 4.0);
    assert!((w.robots[0].pose.theta - (3.5 - 2.0 * PI)).abs() < 1e-9);
}

#[test]
fn motor_limits_clamp_commands() {
    let mut w = quiet(Pose { x: 1.0, y: 1.0, theta: 0.0 }, (7.5, 7.5));
    run(&mut w, Command { translate: 10.0, rotate: 0.0 }, 1.0);
    assert!((w.robots[0].pose.x - 1.4).abs() < 1e-9);
}

#[test]
fn walls_hold_robots_in() {
    let mut w = quiet(Pose { x: 1.0, y: 4.0, theta: PI }, (7.5, 7.5));
    run(&mut w, Command { translate: 0.4, rotate: 0.0 }, 20.0);
    assert!((w.robots[0].pose.x - w.config.robot_radius).abs() < 1e-9);
}

#[test]
fn robots_do_not_pass_through_targets() {
    let mut w = quiet(Pose { x: 1.0, y: 4.0, theta: 0.0 }, (3.0, 4.0));
    run(&mut w, Command { translate: 0.4, rotate: 0.0 }, 20.0);
    let gap = 3.0 - w.robots[0].pose.x;
    assert!(gap >= w.config.robot_radius + w.config.target_radius - 1e-9, "{gap}");
}

fn frame(w: &mut World) -> Vec<Sighting> {
    let mut out = Vec::new();
    w.camera(0, &mut out);
    out
}

#[test]
fn camera_bearing_is_positive_to_the_right() {
    // Target ahead and a little to the left (counter-clockwise): negative angle.
    let mut w = quiet(Pose { x: 2.0, y: 2.0, theta: 0.0 }, (4.0, 2.3));
    let s = frame(&mut w);
    assert_eq!(s.len(), 1);
    assert!(s[0].angle < 0.0 && (s[0].angle + (0.3f64).atan2(2.0)).abs() < 1e-12);
    // To the right: positive.
    let mut w = quiet(Pose { x: 2.0, y: 2.0, theta: 0.0 }, (4.0, 1.7));
    assert!(frame(&mut w)[0].angle > 0.0);
}

#[test]
fn apparent_height_falls_with_distance() {
    let near = frame(&mut quiet(Pose { x: 2.0, y: 2.0, theta: 0.0 }, (3.0, 2.0)))[0].height;
    let far = frame(&mut quiet(Pose { x: 2.0, y: 2.0, theta: 0.0 }, (6.0, 2.0)))[0].height;
    assert!((near - 100.0).abs() < 1e-9, "0.5 m target at 1 m is 100 px: {near}");
    assert!((far - 25.0).abs() < 1e-9);
}

#[test]
fn camera_sees_only_inside_its_field_and_range() {
    // Behind the robot.
    assert!(frame(&mut quiet(Pose { x: 4.0, y: 4.0, theta: 0.0 }, (2.0, 4.0))).is_empty());
    // Just outside the 60° field (35° off axis).
    let off = 35f64.to_radians();
    assert!(frame(&mut quiet(Pose { x: 1.0, y: 1.0, theta: 0.0 }, (1.0 + 2.0 * off.cos(), 1.0 + 2.0 * off.sin())))
        .is_empty());
    // Beyond the 5 m range.
    let mut c = WorldConfig::lab(&[1.0]);
    c.arena = [20.0, 20.0];
    c.miss_rate = 0.0;
    let mut w = World::new(c, 1, 1);
    w.robots[0].pose = Pose { x: 1.0, y: 1.0, theta: 0.0 };
    w.targets[0].x = 6.5;
    w.targets[0].y = 1.0;
    assert!(frame(&mut w).is_empty());
}

#[test]
fn sonar_measures_from_the_rim_to_walls_and_targets() {
    let mut w = quiet(Pose { x: 2.0, y: 4.0, theta: 0.0 }, (3.0, 4.0));
    w.index();
    let mut r = vec![0.0; 8];
    w.sonar(0, &mut r);
    let c = &w.config;
    // Ahead: the target's near edge at 1 - 0.2 m from the centre, minus the robot's radius.
    assert!((r[0] - (0.8 - c.robot_radius)).abs() < 1e-9, "{r:?}");
    // Behind (beam 4): the wall at x = 0, 2 m away; capped at the sonar range (3 m).
    assert!((r[4] - (2.0 - c.robot_radius)).abs() < 1e-9, "{r:?}");
    // Left (beam 2, +90°): the wall at y = 8 is 4 m away: capped.
    assert_eq!(r[2], c.sonar_range);
}

/// A sweep whose noise was passed over and drawn again in the sweep (`skip_sonar_draws`,
/// `sonar_from`, what the simulator's bodies do) reads what one with its draws kept
/// (`sonar_draws`, `sonar_with`) reads, and leaves the noise stream where that one does.
#[test]
fn a_sweep_with_its_noise_drawn_again_reads_as_one_with_it_kept() {
    let world = || {
        let mut c = WorldConfig::lab(&[1.0]);
        c.sonar_noise = 0.3;
        let mut w = World::new(c, 2, 7);
        w.robots[0].pose = Pose { x: 1.0, y: 1.0, theta: 0.3 };
        w.robots[1].pose = Pose { x: 1.6, y: 1.2, theta: 0.0 };
        w.index();
        w
    };
    let (mut kept, mut again) = (world(), world());
    let mut scratch = SonarScratch::default();
    for beams in [8, 7, 1] {
        let (mut a, mut b) = (vec![0.0; beams], vec![0.0; beams]);
        let mut draws = Vec::new();
        kept.sonar_draws(beams, &mut draws);
        kept.sonar_with(0, &draws, &mut scratch, &mut a);
        let start = again.skip_sonar_draws(beams);
        again.sonar_from(0, start, &mut scratch, &mut b);
        assert_eq!(
            a.iter().map(|r| r.to_bits()).collect::<Vec<_>>(),
            b.iter().map(|r| r.to_bits()).collect::<Vec<_>>()
        );
        assert!(a.iter().any(|&r| r < kept.config.sonar_range), "something in reach: {a:?}");
        // The stream moved alike: what it draws next is the same.
        let (mut x, mut y) = (Vec::new(), Vec::new());
        kept.sonar_draws(2, &mut x);
        again.sonar_draws(2, &mut y);
        assert_eq!(x, y);
    }
}

#[test]
fn targets_stay_in_the_arena_and_move_at_their_speed() {
    for motion in [Motion::RandomWaypoint, Motion::Bounce] {
        let mut c = WorldConfig::lab(&[1.0, 2.0, 3.0]);
        for t in &mut c.targets {
            t.motion = motion;
        }
        let mut w = World::new(c, 0, 5);
        let mut last: Vec<(f64, f64)> = w.targets.iter().map(|t| (t.x, t.y)).collect();
        for _ in 0..4000 {
            w.step(0.05, &[]);
            for (t, l) in w.targets.iter().zip(&mut last) {
                assert!(t.x >= 0.0 && t.x <= 8.0 && t.y >= 0.0 && t.y <= 8.0);
                let step = (t.x - l.0).hypot(t.y - l.1);
                assert!(step <= 0.15 * 0.05 + 1e-9, "{motion:?} moved {step}");
                *l = (t.x, t.y);
            }
        }
    }
}
