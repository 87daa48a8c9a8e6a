//! A simulator run as Foxglove's 3-D panel draws it: one [`SceneUpdate`] and one
//! [`FrameTransforms`] per recorded frame, built from the run's [`Recording`] (the same frames
//! the HTML report replays).
//!
//! Promises: pure functions of the recording (no clock, no I/O), so a seed gives the same
//! scene; coordinates are the recording's (metres, arena frame `world`: origin at a corner,
//! x and y along the walls, z up); every entity keeps its id across frames (`arena`,
//! `robot{n}`, `target{n}`, `claims`), so each frame replaces the previous one's.
//!
//! What is drawn: the arena's walls; targets as spheres coloured by priority (red: target 1,
//! the most important, to blue: the least) with their id and priority; robots as cylinders
//! (grey once killed) with a heading arrow, the camera's field of view as a translucent fan
//! (its observe range darker) and a label (`n2 -> T1 [T1]`: the target that drives it and
//! those it claims); a line from each robot to every target it claims through BLE.

use ayllu_sim::recording::{Frame, Recording};
use foxglove::messages::{
    ArrowPrimitive, Color, CylinderPrimitive, FrameTransform, FrameTransforms, LinePrimitive, Point3, Pose, Quaternion,
    SceneEntity, SceneUpdate, SpherePrimitive, TextPrimitive, Timestamp, TriangleListPrimitive, Vector3,
};

/// The fixed frame every entity is drawn in.
pub const WORLD_FRAME: &str = "world";
/// How tall robots are drawn (m); the recording is 2-D.
const ROBOT_HEIGHT: f64 = 0.3;
/// Segments of a field-of-view fan.
const FAN_SEGMENTS: usize = 12;

/// A frame's time as a Foxglove timestamp: virtual seconds since the run began (the log
/// times of a simulator's MCAP start at the epoch).
pub fn timestamp(t: f64) -> Timestamp {
    Timestamp::saturating_from_epoch_secs_f64(t.max(0.0))
}

/// The same time in nanoseconds (MCAP log time).
pub fn nanos(t: f64) -> u64 {
    timestamp(t).total_nanos()
}

fn color(r: f64, g: f64, b: f64, a: f64) -> Option<Color> {
    Some(Color { r, g, b, a })
}

fn at(x: f64, y: f64, z: f64, theta: f64) -> Option<Pose> {
    let half = theta / 2.0;
    Some(Pose {
        position: Some(Vector3 { x, y, z }),
        orientation: Some(Quaternion { x: 0.0, y: 0.0, z: half.sin(), w: half.cos() }),
    })
}

fn point(x: f64, y: f64, z: f64) -> Point3 {
    Point3 { x, y, z }
}

/// Target `rank` of `count` (0 = the most important): red to blue.
fn priority_color(rank: usize, count: usize) -> Option<Color> {
    let f = if count > 1 { rank as f64 / (count - 1) as f64 } else { 0.0 };
    color(0.9 * (1.0 - f) + 0.1 * f, 0.2, 0.2 * (1.0 - f) + 0.9 * f, 0.95)
}

fn entity(id: &str, t: f64) -> SceneEntity {
    SceneEntity {
        timestamp: Some(timestamp(t)),
        frame_id: WORLD_FRAME.to_owned(),
        id: id.to_owned(),
        ..SceneEntity::default()
    }
}

fn label(x: f64, y: f64, z: f64, text: String) -> TextPrimitive {
    TextPrimitive {
        pose: at(x, y, z, 0.0),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: color(1.0, 1.0, 1.0, 1.0),
        text,
    }
}

/// A fan of `range` over `fov` centred on `theta`, as triangles at height `z`.
fn fan(x: f64, y: f64, theta: f64, fov: f64, range: f64, z: f64, c: Option<Color>) -> TriangleListPrimitive {
    let mut points = Vec::with_capacity(FAN_SEGMENTS * 3);
    for k in 0..FAN_SEGMENTS {
        let a0 = theta - fov / 2.0 + fov * k as f64 / FAN_SEGMENTS as f64;
        let a1 = theta - fov / 2.0 + fov * (k + 1) as f64 / FAN_SEGMENTS as f64;
        points.push(point(x, y, z));
        points.push(point(x + range * a0.cos(), y + range * a0.sin(), z));
        points.push(point(x + range * a1.cos(), y + range * a1.sin(), z));
    }
    TriangleListPrimitive { pose: at(0.0, 0.0, 0.0, 0.0), points, color: c, ..TriangleListPrimitive::default() }
}

/// The scene at one frame of `rec`.
pub fn scene(rec: &Recording, frame: &Frame) -> SceneUpdate {
    let t = frame.t;
    let meta = &rec.meta;
    let [w, h] = meta.arena;
    let mut entities = Vec::with_capacity(rec.robots.len() + rec.targets.len() + 2);

    let mut arena = entity("arena", t);
    arena.lines.push(LinePrimitive {
        r#type: foxglove::messages::line_primitive::Type::LineLoop as i32,
        pose: at(0.0, 0.0, 0.0, 0.0),
        thickness: 0.05,
        points: vec![point(0.0, 0.0, 0.0), point(w, 0.0, 0.0), point(w, h, 0.0), point(0.0, h, 0.0)],
        color: color(0.8, 0.8, 0.8, 1.0),
        ..LinePrimitive::default()
    });
    entities.push(arena);

    for (k, (info, pos)) in rec.targets.iter().zip(&frame.targets).enumerate() {
        let mut e = entity(&format!("target{}", info.id), t);
        let d = 2.0 * info.radius;
        e.spheres.push(SpherePrimitive {
            pose: at(pos[0], pos[1], info.radius, 0.0),
            size: Some(Vector3 { x: d, y: d, z: d }),
            color: priority_color(k, rec.targets.len()),
        });
        e.texts.push(label(pos[0], pos[1], d + 0.2, format!("T{} p{}", info.id, info.priority)));
        entities.push(e);
    }

    let mut claims = entity("claims", t);
    let mut claim_points = Vec::new();
    for (info, r) in rec.robots.iter().zip(&frame.robots) {
        let mut e = entity(&format!("robot{}", info.id), t);
        let body = if r.alive { color(0.2, 0.75, 0.3, 1.0) } else { color(0.4, 0.4, 0.4, 1.0) };
        let d = 2.0 * info.radius;
        e.cylinders.push(CylinderPrimitive {
            pose: at(r.x, r.y, ROBOT_HEIGHT / 2.0, r.theta),
            size: Some(Vector3 { x: d, y: d, z: ROBOT_HEIGHT }),
            bottom_scale: 1.0,
            top_scale: 1.0,
            color: body,
        });
        e.arrows.push(ArrowPrimitive {
            pose: at(r.x, r.y, ROBOT_HEIGHT + 0.02, r.theta),
            shaft_length: info.radius + 0.2,
            shaft_diameter: 0.04,
            head_length: 0.12,
            head_diameter: 0.1,
            color: color(1.0, 1.0, 1.0, 1.0),
        });
        if r.alive {
            e.triangles.push(fan(
                r.x,
                r.y,
                r.theta,
                meta.camera_fov,
                meta.camera_range,
                0.01,
                color(1.0, 0.9, 0.3, 0.12),
            ));
            e.triangles.push(fan(
                r.x,
                r.y,
                r.theta,
                meta.camera_fov,
                meta.observe_range,
                0.02,
                color(1.0, 0.9, 0.3, 0.25),
            ));
        }
        let drive = if r.drive == 0 { "wander".to_owned() } else { format!("T{}", r.drive) };
        let claimed: Vec<String> = r.claims.iter().map(|c| format!("T{c}")).collect();
        let text = if r.alive {
            format!("n{} -> {drive} [{}]", info.id, claimed.join(" "))
        } else {
            format!("n{} (killed)", info.id)
        };
        e.texts.push(label(r.x, r.y, ROBOT_HEIGHT + 0.4, text));
        entities.push(e);
        for c in &r.claims {
            if let Some(pos) = rec.targets.iter().position(|ti| ti.id == *c).and_then(|k| frame.targets.get(k)) {
                claim_points.push(point(r.x, r.y, ROBOT_HEIGHT));
                claim_points.push(point(pos[0], pos[1], 0.1));
            }
        }
    }
    claims.lines.push(LinePrimitive {
        r#type: foxglove::messages::line_primitive::Type::LineList as i32,
        pose: at(0.0, 0.0, 0.0, 0.0),
        thickness: 0.03,
        points: claim_points,
        color: color(0.3, 0.7, 1.0, 0.9),
        ..LinePrimitive::default()
    });
    entities.push(claims);
    SceneUpdate { deletions: Vec::new(), entities }
}

/// Each robot's pose at one frame as a transform `world -> robot{n}`, so a panel can follow one.
pub fn transforms(rec: &Recording, frame: &Frame) -> FrameTransforms {
    let transforms = rec
        .robots
        .iter()
        .zip(&frame.robots)
        .map(|(info, r)| {
            let pose = at(r.x, r.y, 0.0, r.theta).expect("built");
            FrameTransform {
                timestamp: Some(timestamp(frame.t)),
                parent_frame_id: WORLD_FRAME.to_owned(),
                child_frame_id: format!("robot{}", info.id),
                translation: pose.position,
                rotation: pose.orientation,
            }
        })
        .collect();
    FrameTransforms { transforms }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_sim::controller::Controller;
    use ayllu_sim::scenario::{run, Scenario};

    #[test]
    fn every_robot_and_target_is_an_entity_of_every_frame() {
        let scenario = Scenario::paper(Controller::Ble, 1).duration(2.0).recorded();
        let rec = run(&scenario).unwrap().recording.unwrap();
        let frame = rec.frames.last().unwrap();
        let s = scene(&rec, frame);
        let ids: Vec<&str> = s.entities.iter().map(|e| e.id.as_str()).collect();
        assert_eq!(ids.len(), 1 + rec.targets.len() + rec.robots.len() + 1, "{ids:?}");
        assert!(ids.contains(&"robot1") && ids.contains(&"target4") && ids.contains(&"arena"));
        let robot = s.entities.iter().find(|e| e.id == "robot1").unwrap();
        assert_eq!(robot.triangles[0].points.len(), FAN_SEGMENTS * 3);
        assert_eq!(transforms(&rec, frame).transforms.len(), rec.robots.len());
        assert_eq!(nanos(frame.t), (frame.t * 1e9).round() as u64);
    }

    #[test]
    fn target_one_is_red_and_the_last_blue() {
        let first = priority_color(0, 4).unwrap();
        let last = priority_color(3, 4).unwrap();
        assert!(first.r > first.b && last.b > last.r);
    }
}
