//! A simulator run written as an MCAP file that Foxglove opens as it is: the 3-D scene
//! (`/sim/scene`, `foxglove.SceneUpdate`; `/sim/tf`, `foxglove.FrameTransforms`), every robot's
//! ports on the team channels (`/n{node}/{behavior}/{port}`, as `ayllu record` and the live
//! `ayllu foxglove` write them) and the BLE claims (`/ble/OBS{n}`).
//!
//! Promises:
//! * one message per recorded frame on `/sim/scene` and `/sim/tf` (frame 0 at t = 0, then one
//!   every `frame_dt` of virtual time), and on every port channel of every live robot; one
//!   per frame on each `/ble/OBS{n}` when the controller is BLE;
//! * log times are the run's virtual time (nanoseconds since the start, so the file's clock
//!   begins at the epoch), written in time order; the same scenario and seed give the same
//!   messages;
//! * the simulator itself is unchanged and unaware of Foxglove: this module drives its public
//!   stepping API and reads the nodes' reports and the run's recording.

use std::path::Path;

use ayllu_core::NodeId;
use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::{Outcome, Scenario, Sim};
use foxglove::messages::{FrameTransforms, SceneUpdate};
use foxglove::{Context, PartialMetadata};

use crate::sim_scene::{nanos, scene, transforms};
use crate::team_bridge::{LayerClaims, TeamBridge};

/// The scene topic.
pub const SCENE_TOPIC: &str = "/sim/scene";
/// The robots' transforms topic.
pub const TF_TOPIC: &str = "/sim/tf";

/// What was written.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct McapSummary {
    /// Frames (messages on `/sim/scene`).
    pub frames: u64,
    /// Messages in all.
    pub messages: u64,
    /// Topics in all.
    pub topics: usize,
}

/// Why a run could not be written.
#[derive(Debug)]
pub enum SimMcapError {
    /// The simulation failed (a scenario out of bounds, a controller that cannot be built...).
    Sim(ayllu_sim::scenario::SimError),
    /// The file could not be made or written.
    Mcap(foxglove::FoxgloveError),
}

impl std::fmt::Display for SimMcapError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SimMcapError::Sim(e) => write!(f, "the run failed: {e}"),
            SimMcapError::Mcap(e) => write!(f, "writing the MCAP file: {e}"),
        }
    }
}

impl std::error::Error for SimMcapError {}

/// Every robot's ports at one frame, kept until the frame's scene is written before them.
struct PortFrame {
    t: f64,
    reports: Vec<ayllu_core::NodeReport>,
}

fn snapshot(sim: &Sim, robots: usize) -> PortFrame {
    let t = sim.now().as_secs_f64();
    let reports = (0..robots)
        .filter(|&i| sim.world().robots[i].alive)
        .map(|i| {
            let mut r = sim.core(i).report();
            // Only what the channels carry: the rest of a report is large and unused here.
            r.connections.clear();
            r.transport.clear();
            r.warnings.clear();
            r
        })
        .collect();
    PortFrame { t, reports }
}

/// Run `scenario` (recorded whatever its `record` says) and write it to a new MCAP file at
/// `path` (an existing file is refused). Returns the run's outcome and what was written.
pub fn run_to_mcap(scenario: &Scenario, path: &Path) -> Result<(Outcome, McapSummary), SimMcapError> {
    let scenario = scenario.clone().recorded();
    let mut sim = Sim::new(&scenario).map_err(SimMcapError::Sim)?;
    let robots = scenario.robots;
    // The sim records a frame at tick 0 and every `frame_every` ticks; so do we.
    let frame_every = ((scenario.frame_dt / scenario.dt).round() as u64).max(1);
    let mut ports = vec![snapshot(&sim, robots)];
    let mut tick = 0u64;
    while !sim.done() {
        sim.step().map_err(|e| SimMcapError::Sim(e.into()))?;
        tick += 1;
        if tick.is_multiple_of(frame_every) {
            ports.push(snapshot(&sim, robots));
        }
    }
    let outcome = sim.finish();
    let summary = write(&scenario, &outcome, &ports, path)?;
    Ok((outcome, summary))
}

fn write(
    scenario: &Scenario,
    outcome: &Outcome,
    ports: &[PortFrame],
    path: &Path,
) -> Result<McapSummary, SimMcapError> {
    let Some(rec) = &outcome.recording else {
        return Ok(McapSummary { frames: 0, messages: 0, topics: 0 });
    };
    let ctx = Context::new();
    let mcap = ctx.mcap_writer().create_new_buffered_file(path).map_err(SimMcapError::Mcap)?;
    let scene_channel = ctx.channel_builder(SCENE_TOPIC).build::<SceneUpdate>();
    let tf_channel = ctx.channel_builder(TF_TOPIC).build::<FrameTransforms>();
    let mut bridge = TeamBridge::new(&ctx);
    let ble = scenario.controller == Controller::Ble;
    let mut messages = 0u64;
    for (k, frame) in rec.frames.iter().enumerate() {
        let t = nanos(frame.t);
        scene_channel.log_with_meta(&scene(rec, frame), PartialMetadata { log_time: Some(t) });
        tf_channel.log_with_meta(&transforms(rec, frame), PartialMetadata { log_time: Some(t) });
        messages += 2;
        // Frames and port snapshots are taken at the same ticks; a mismatch would be a change
        // in the simulator's frame schedule, and the ports are then matched by time.
        let snap = ports
            .get(k)
            .filter(|p| (p.t - frame.t).abs() < 1e-6)
            .or_else(|| ports.iter().find(|p| (p.t - frame.t).abs() < 1e-6));
        if let Some(snap) = snap {
            for r in &snap.reports {
                bridge.node_report(r, t);
            }
        }
        if ble {
            for target in &rec.targets {
                let alive: Vec<NodeId> =
                    rec.robots.iter().zip(&frame.robots).filter(|(_, r)| r.alive).map(|(i, _)| NodeId(i.id)).collect();
                let claimers: Vec<NodeId> = rec
                    .robots
                    .iter()
                    .zip(&frame.robots)
                    .filter(|(_, r)| r.alive && r.claims.contains(&target.id))
                    .map(|(i, _)| NodeId(i.id))
                    .collect();
                let claims = LayerClaims {
                    behavior: format!("OBS{}", target.id),
                    group: Some(ayllu_sim::controller::GROUP.to_owned()),
                    claimers,
                    members: alive,
                };
                bridge.layer_claims(&claims, t);
            }
        }
    }
    messages += bridge.published();
    let topics = 2 + bridge.topics();
    mcap.close().map_err(SimMcapError::Mcap)?;
    Ok(McapSummary { frames: rec.frames.len() as u64, messages, topics })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_run_writes_one_scene_per_frame() {
        let dir = std::env::temp_dir().join(format!("ayllu-foxglove-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.mcap");
        let _ = std::fs::remove_file(&path);
        let scenario = Scenario::paper(Controller::Ble, 3).duration(3.0);
        let (outcome, summary) = run_to_mcap(&scenario, &path).unwrap();
        let frames = outcome.recording.as_ref().unwrap().frames.len() as u64;
        assert_eq!(summary.frames, frames);
        assert_eq!(frames, 16, "0 s to 3 s every 0.2 s");
        assert!(summary.topics > 2 + 4, "{summary:?}");
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89MCAP0\r\n");
        // An existing file is never overwritten.
        assert!(run_to_mcap(&scenario, &path).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
