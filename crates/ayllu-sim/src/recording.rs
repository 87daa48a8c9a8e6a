//! What a run leaves behind for people: the frames of a replay and the series of a plot.
//!
//! A [`Recording`] is plain data (serde), written into the report's HTML page as JSON and read
//! by its canvas replay. It promises: one frame per `meta.frame_dt` seconds of virtual time,
//! frame 0 at t = 0; robots and targets in the same order in every frame as in `robots` /
//! `targets`; target ids 1..=m with target 1 the highest priority (the paper's OBS1).
//! Coordinates are metres in the arena frame (origin bottom-left, x right, y up); headings are
//! radians counter-clockwise from +x.

use serde::{Deserialize, Serialize};

/// The settings a replay needs to draw a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordingMeta {
    /// Controller name: "BLE", "Random", "Local", "ForceField", "Centralized", "Planner".
    pub controller: String,
    /// The run's seed.
    pub seed: u64,
    /// Arena width and height (m); walls run along its border.
    pub arena: [f64; 2],
    /// Camera field of view (rad, whole angle).
    pub camera_fov: f64,
    /// Camera range (m).
    pub camera_range: f64,
    /// A target counts as observed within this distance (m) and inside the field of view.
    pub observe_range: f64,
    /// Virtual seconds between frames.
    pub frame_dt: f64,
    /// Run length (s of virtual time).
    pub duration: f64,
    /// Radio loss probability per message and receiver.
    pub loss: f64,
}

/// A target as the replay draws it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetInfo {
    /// 1-based; target 1 has the highest priority.
    pub id: u32,
    /// Its priority (larger: more important).
    pub priority: f64,
    /// Its radius (m).
    pub radius: f64,
}

/// A robot as the replay draws it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobotInfo {
    /// The robot's node id.
    pub id: u32,
    /// Its radius (m).
    pub radius: f64,
}

/// One robot at one frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobotFrame {
    /// Position (m, arena frame).
    pub x: f64,
    /// Position (m, arena frame).
    pub y: f64,
    /// Heading (rad, counter-clockwise from +x).
    pub theta: f64,
    /// False once the robot has been killed.
    pub alive: bool,
    /// The target whose observer drives the robot's rotation (0: none, wandering).
    pub drive: u32,
    /// Targets this robot currently claims through BLE (empty for controllers without BLE).
    pub claims: Vec<u32>,
    /// Observer layers (target ids) whose output a peer's claim currently write-inhibits.
    pub inhibited: Vec<u32>,
    /// Targets this robot observes now (in view and within observe range).
    pub observing: Vec<u32>,
}

/// The world at one instant.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// Virtual time (s since the start of the run).
    pub t: f64,
    /// Every robot, in `Recording::robots` order (dead ones included).
    pub robots: Vec<RobotFrame>,
    /// Target positions [x, y], in `targets` order.
    pub targets: Vec<[f64; 2]>,
}

/// Something that happened at a time: today only robot failures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Event {
    /// When it happened (s of virtual time).
    pub t: f64,
    /// What happened: today always `"kill"`.
    pub kind: String,
    /// The robot's node id.
    pub robot: u32,
}

/// A whole run, frame by frame, for a replay.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Recording {
    /// The run's settings.
    pub meta: RecordingMeta,
    /// The robots' fixed facts.
    pub robots: Vec<RobotInfo>,
    /// The targets' fixed facts.
    pub targets: Vec<TargetInfo>,
    /// One frame every `meta.frame_dt`.
    pub frames: Vec<Frame>,
    /// Kills, in time order.
    pub events: Vec<Event>,
}

/// Coverage over time for a plot: one sample per frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CoverageSeries {
    /// Sample times (s of virtual time), one per frame.
    pub t: Vec<f64>,
    /// Targets observed by at least one robot.
    pub observed: Vec<u32>,
    /// Priority-weighted fraction observed, in [0, 1].
    pub weighted: Vec<f64>,
}
