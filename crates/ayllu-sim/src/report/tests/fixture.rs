//! A synthetic [`Report`] for the report's tests: 3 robots pursuing 4 moving targets for 30 s,
//! replayable as five runs (the paper setting with BLE on seeds 7 and 8 and with Local on seed 7;
//! robustness at 10 % loss, robot 3 killed at 15 s; and a run whose robots and targets hug the
//! walls and corners, where labels have no room on their usual side), coverage for 5
//! controllers, made-up rows for the paper setting, the robustness scenario and a small sweep.
//!
//! Shared by the unit tests (`report/tests.rs`) and `tests/simulator/report_chromium.rs`, which includes
//! this file with `#[path]`; so it names its types through `super::` and each includer brings
//! them into scope. Every number is rounded to 3 decimals so a JSON round trip is exact with
//! serde_json's default float parser. Made-up numbers: they exercise the page, not the task.

use super::{
    CoverageSeries, Event, Frame, Metrics, Recording, RecordingMeta, Replay, Report, RobotFrame, RobotInfo, Row,
    RunRow, TargetInfo,
};

pub const CONTROLLERS: [&str; 5] = ["BLE", "Centralized", "ForceField", "Local", "Random"];

fn r3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

fn target_at(j: usize, t: f64) -> [f64; 2] {
    let centres = [(4.0, 5.0), (8.5, 4.0), (6.0, 6.5), (9.5, 7.0)];
    let (cx, cy) = centres[j];
    let w = 0.12 + 0.03 * j as f64;
    let phase = j as f64 * 1.3;
    [r3(cx + 2.0 * (w * t + phase).cos()), r3(cy + 1.5 * (1.3 * w * t + phase).sin())]
}

fn wrap(a: f64) -> f64 {
    let mut a = a;
    while a > std::f64::consts::PI {
        a -= 2.0 * std::f64::consts::PI;
    }
    while a < -std::f64::consts::PI {
        a += 2.0 * std::f64::consts::PI;
    }
    a
}

/// Seconds between the replays' pose samples: two recorded frames (the page interpolates).
pub const STEP: f64 = 1.0;

/// The run the page opens on.
pub fn recording() -> Recording {
    recording_of("BLE", 7, false)
}

/// The made-up run of `controller` on `seed` (seeds move the robots' start), robot 3 killed
/// at 15 s if `kill`.
pub fn recording_of(controller: &str, seed: u64, kill: bool) -> Recording {
    let meta = RecordingMeta {
        controller: controller.into(),
        seed,
        arena: [12.0, 9.0],
        camera_fov: r3(60f64.to_radians()),
        camera_range: 3.5,
        observe_range: 2.0,
        frame_dt: 0.5,
        duration: 30.0,
        loss: 0.1,
    };
    let targets: Vec<TargetInfo> =
        (0..4).map(|j| TargetInfo { id: j + 1, priority: f64::from(4 - j), radius: 0.15 }).collect();
    let robots: Vec<RobotInfo> = (0..3).map(|k| RobotInfo { id: k + 1, radius: 0.25 }).collect();
    let shift = 0.3 * (seed % 5) as f64;
    let mut pose = [(1.0 + shift, 1.0, 0.5), (11.0 - shift, 1.0, 2.5), (6.0, 8.3 - shift, -1.6)];
    let mut frames = Vec::new();
    for i in 0..=60 {
        let t = f64::from(i) * meta.frame_dt;
        let tpos: Vec<[f64; 2]> = (0..4).map(|j| target_at(j, t)).collect();
        let alive = [true, true, !kill || t < 15.0];
        // Robot 3 wanders for its first 2 s, then everyone drives to "its" target (T1..T3).
        let drive: Vec<u32> = (0..3).map(|k| if !alive[k] || (k == 2 && t < 2.0) { 0 } else { k as u32 + 1 }).collect();
        let mut observing = vec![Vec::new(); 3];
        for k in 0..3 {
            if !alive[k] {
                continue;
            }
            let (x, y, th) = pose[k];
            for (j, p) in tpos.iter().enumerate() {
                let d = ((p[0] - x).powi(2) + (p[1] - y).powi(2)).sqrt();
                let off = wrap((p[1] - y).atan2(p[0] - x) - th).abs();
                if d <= meta.observe_range && off <= meta.camera_fov / 2.0 {
                    observing[k].push(j as u32 + 1);
                }
            }
        }
        let claims: Vec<Vec<u32>> = (0..3)
            .map(|k| if drive[k] != 0 && observing[k].contains(&drive[k]) { vec![drive[k]] } else { vec![] })
            .collect();
        let robots_now = (0..3)
            .map(|k| {
                let inhibited: Vec<u32> = (0..3)
                    .filter(|&o| o != k && alive[o])
                    .flat_map(|o| claims[o].iter().copied())
                    .filter(|id| !claims[k].contains(id))
                    .collect();
                RobotFrame {
                    x: r3(pose[k].0),
                    y: r3(pose[k].1),
                    theta: r3(pose[k].2),
                    alive: alive[k],
                    drive: drive[k],
                    claims: claims[k].clone(),
                    inhibited,
                    observing: observing[k].clone(),
                }
            })
            .collect();
        frames.push(Frame { t, robots: robots_now, targets: tpos.clone() });
        // Pursuit to ~1 m from the driven target; the wanderer turns in place.
        for k in 0..3 {
            if !alive[k] {
                continue;
            }
            let (x, y, th) = pose[k];
            if drive[k] == 0 {
                pose[k].2 = wrap(th + 0.4);
                continue;
            }
            let p = tpos[drive[k] as usize - 1];
            let want = (p[1] - y).atan2(p[0] - x);
            let nth = th + wrap(want - th).clamp(-0.6, 0.6);
            let d = ((p[0] - x).powi(2) + (p[1] - y).powi(2)).sqrt();
            let step = if d > 1.0 { (0.5 * meta.frame_dt * 1.6).min(d - 1.0) } else { 0.0 };
            pose[k] = (x + step * nth.cos(), y + step * nth.sin(), wrap(nth));
        }
    }
    let events = if kill { vec![Event { t: 15.0, kind: "kill".into(), robot: 3 }] } else { vec![] };
    Recording { meta, robots, targets, frames, events }
}

/// Robots and targets pressed against the walls and into the corners, still (10 s): every
/// label's usual side is a wall. Robot 1 in the bottom-left corner faces right, so its labels
/// (which go on the side it faces away from) would be drawn into the left wall; robot 2 in the
/// top-right corner faces left, its labels heading into the right wall; robot 3 sits against
/// the bottom wall, claiming and inhibited (three lines of labels that would run below it);
/// targets (labels on their right) sit in the other corners, at the right wall and at the top.
pub fn cornered() -> Recording {
    let mut rec = recording_of("Random", 1, false);
    rec.meta.duration = 10.0;
    let (w, h) = (rec.meta.arena[0], rec.meta.arena[1]);
    let robots = [(0.3, 0.3, 0.0), (w - 0.3, h - 0.3, 3.1), (w / 2.0, 0.26, 1.57)];
    let targets = [[0.2, h - 0.2], [w - 0.2, 0.2], [w - 0.16, h / 2.0], [w / 2.0, h - 0.16]];
    rec.frames = (0..=20)
        .map(|i| Frame {
            t: f64::from(i) * rec.meta.frame_dt,
            robots: robots
                .iter()
                .enumerate()
                .map(|(k, &(x, y, theta))| RobotFrame {
                    x,
                    y,
                    theta,
                    alive: true,
                    drive: if k == 2 { 4 } else { 0 },
                    claims: if k == 2 { vec![3, 4] } else { vec![] },
                    inhibited: if k == 2 { vec![1, 2] } else { vec![] },
                    observing: vec![],
                })
                .collect(),
            targets: targets.to_vec(),
        })
        .collect();
    rec
}

/// Every run the fixture's page can replay, in menu order; the first is [`recording`]'s.
pub fn replays() -> Vec<Replay> {
    vec![
        Replay::new("Paper setting", &recording(), STEP),
        Replay::new("Paper setting", &recording_of("BLE", 8, false), STEP),
        Replay::new("Paper setting", &recording_of("Local", 7, false), STEP),
        Replay::new("Robustness: 10 % loss", &recording_of("BLE", 7, true), STEP),
        Replay::new("Sweep: 3 robots, 4 targets, 0 % loss", &cornered(), STEP),
    ]
}

/// Made-up but plausible: BLE best, Random worst, coverage dipping after the kill.
fn quality(controller: &str) -> f64 {
    match controller {
        "BLE" => 0.78,
        "Centralized" => 0.82,
        "ForceField" => 0.61,
        "Local" => 0.55,
        _ => 0.32,
    }
}

pub fn coverage() -> Vec<(String, CoverageSeries)> {
    CONTROLLERS
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let q = quality(name);
            let mut s = CoverageSeries::default();
            for i in 0..=60 {
                let t = f64::from(i) * 0.5;
                let ramp = (t / 6.0).min(1.0);
                let dip = if (15.0..19.0).contains(&t) { 0.25 } else { 0.0 };
                let wobble = 0.06 * (t * 0.7 + c as f64).sin();
                let w = r3((q * ramp - dip + wobble).clamp(0.0, 1.0));
                s.t.push(t);
                s.weighted.push(w);
                s.observed.push((w * 4.0).round() as u32);
            }
            (name.to_string(), s)
        })
        .collect()
}

fn row(controller: &str, robots: u32, targets: u32, loss: f64, kill: bool) -> Row {
    let q = quality(controller) * (1.0 - 0.4 * loss) * (f64::from(robots) / f64::from(targets)).min(1.0).sqrt();
    let a_w = r3(q.clamp(0.0, 1.0));
    let a = r3(a_w * f64::from(targets) * 0.9);
    Row {
        controller: controller.into(),
        robots,
        targets,
        loss,
        kill,
        seeds: 10,
        metrics: Metrics {
            a,
            a_per_m: r3(a / f64::from(targets)),
            a_w,
            top_k: r3((a_w * 1.1).min(1.0)),
            k: robots.min(targets),
            top_k_alive: r3((a_w * 1.1).min(1.0)),
            redundant: r3(if controller == "Local" { 0.8 } else { 0.15 } + loss),
            switches_per_min: r3(if controller == "Random" { 6.5 } else { 1.2 + 3.0 * loss }),
            recover_s: kill.then(|| r3(4.0 + 20.0 * loss + 10.0 * (1.0 - quality(controller)))),
            unrecovered: 0,
            msgs_per_robot_s: if controller == "BLE" { r3(4.0 * f64::from(targets)) } else { 0.0 },
            bytes_per_robot_s: if controller == "BLE" { r3(160.0 * f64::from(targets)) } else { 0.0 },
        },
        a_w_sd: r3(0.02 + 0.05 * loss),
    }
}

pub fn report() -> Report {
    let mut sweep = Vec::new();
    for robots in [2, 3, 5] {
        for targets in [4, 8] {
            for loss in [0.0, 0.1, 0.3] {
                for c in CONTROLLERS {
                    sweep.push(row(c, robots, targets, loss, false));
                }
            }
        }
    }
    let mut robustness = Vec::new();
    for loss in [0.0, 0.1, 0.3] {
        for c in CONTROLLERS {
            robustness.push(row(c, 3, 4, loss, true));
        }
    }
    let paper: Vec<Row> = CONTROLLERS.iter().map(|c| row(c, 3, 4, 0.0, false)).collect();
    // Two seeds per paper row, each with the row's metrics (their mean is the row).
    let runs = paper
        .iter()
        .flat_map(|r| {
            (1..=2u64).map(move |seed| RunRow {
                table: "paper".into(),
                controller: r.controller.clone(),
                robots: r.robots,
                targets: r.targets,
                loss: r.loss,
                kill: r.kill,
                seed,
                duration: 30.0,
                metrics: r.metrics.clone(),
            })
        })
        .collect();
    Report {
        title: "CMOMMT with BLE: 3 robots, 4 targets".into(),
        command: "ayllu sim cmommt --robots 3 --targets 4 --seeds 10 --out report".into(),
        duration: 30.0,
        replays: replays(),
        coverage: coverage(),
        paper,
        sweep,
        robustness,
        runs,
        cells: Vec::new(),
    }
}
