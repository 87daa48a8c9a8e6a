//! What a scenario may hold: the bounds of every field of [`Scenario`], and the one check that
//! holds a scenario to them, [`Scenario::validate`], before anything is allocated or run.
//!
//! Every way into a run goes through this check: [`Sim::new`](crate::scenario::Sim::new) and
//! [`Sim::with_controller`](crate::scenario::Sim::with_controller) make it first, so
//! [`run`](crate::scenario::run), traces, sweeps, studies and the Python package do; the file
//! reader ([`crate::scenario_file`]) makes it on each scenario and each sweep cell as it reads
//! them, so that a file's mistake is reported with the file's name before any run starts. No
//! caller decides a bound of its own: the tool and the Python package call this check, and
//! docs/cmommt.md ("What a scenario may hold") gives each bound and its reason.
//!
//! Promises: a scenario that passes runs to its end without a panic, in memory bounded by its
//! bounds (the world's grid, the frames kept, the messages in flight); the first field out of
//! bounds is reported as an [`InvalidScenario`] naming its path as a scenario file writes it
//! (`world.arena`, `kills[1].robot`), the value, and what the field accepts.
//!
//! A number a scenario's data spells as `"NaN"` or `"inf"` (JSON has neither) reaches this
//! check as the number it names, read by the `numbers` module, so that the check, not the
//! parser, refuses it and names its field.

use std::f64::consts::TAU;
use std::fmt;

use crate::controller::{Controller, PLANNER_NODE};
// The scenario's data alone: the run (`Sim::new`) calls this check, so depending on
// `crate::scenario`, where the run is, would tie the two modules in a loop.
use crate::scenario_spec::Scenario;
use crate::world::{grid_cell, WorldConfig};

// Kept here too so that `bounds::non_finite_text`, where callers first found it, still names it.
pub use crate::numbers::non_finite_text;

/// The longest time a scenario names (s), as the `ayllu` tool's flags take: about 31 years,
/// far beyond any run, and a whole number of nanoseconds in every duration type.
pub const MAX_SECONDS: f64 = 1e9;

/// The largest team: the file reader's and `sim cmommt --robots`' bound. Each robot is a node
/// with its own behaviors; ten thousand already take minutes a simulated second.
pub const MAX_ROBOTS: usize = 10_000;

/// The most targets: each is an observer layer on every robot's node.
pub const MAX_TARGETS: usize = 1000;

/// The most sonar beams: a lidar's resolution (0.35°). Each sweep costs beams x nearby
/// circles, every robot, every sensing tick.
pub const MAX_BEAMS: usize = 1024;

/// The most cells of the world's spatial grid (4 bytes each, rebuilt every sensing tick):
/// 64 MiB. The cell is the sonar range (or four robot radii if larger), so the largest arena
/// depends on it: about 12 km a side at the lab's 3 m.
pub const MAX_GRID_CELLS: f64 = (1u64 << 24) as f64;

/// The most ticks of a run: at 50 ms, 1.6 years of virtual time; every tick visits every
/// robot, so a run beyond this does not end in a working day.
pub const MAX_TICKS: f64 = 1e9;

/// The most frames a run keeps: its coverage series holds 20 bytes a frame (200 MB), and a
/// frame is also hashed.
pub const MAX_FRAMES: f64 = 1e7;

/// The most poses a recording keeps (frames x (robots + targets)): about 100 bytes each, so
/// 2 GB. A sweep or a study records a run only if its recording fits.
pub const MAX_RECORDED: f64 = 2e7;

/// The most deliveries held in flight (8 bytes each: 800 MB), estimated as robots x
/// [`EMISSIONS_PER_ROBOT_S`] x (delay + jitter) x robots (a broadcast with no range limit
/// reaches the whole team).
pub const MAX_IN_FLIGHT: f64 = 1e8;

/// Radio emissions a robot may make a second, for [`MAX_IN_FLIGHT`]: the most BLE sent in the
/// study (15-36 a robot a second, docs/cmommt.md), rounded up.
pub const EMISSIONS_PER_ROBOT_S: f64 = 40.0;

/// An interval a number must lie in.
struct Bound {
    min: f64,
    /// `min` itself is refused.
    above: bool,
    max: f64,
    /// The interval as messages write it, unit included.
    text: &'static str,
}

impl Bound {
    fn holds(&self, v: f64) -> bool {
        v.is_finite() && (v > self.min || (!self.above && v == self.min)) && v <= self.max
    }
}

/// Run length.
const DURATION: Bound = Bound { min: 0.0, above: true, max: MAX_SECONDS, text: "(0, 1e9] s" };
/// Instants (kills, partitions) and the frame period.
const TIME: Bound = Bound { min: 0.0, above: false, max: MAX_SECONDS, text: "[0, 1e9] s" };
/// The tick.
const TICK: Bound = Bound { min: 1e-4, above: false, max: 1.0, text: "[1e-4, 1] s" };
/// An arena's side.
const SIDE: Bound = Bound { min: 0.0, above: true, max: 1e6, text: "(0, 1e6] m" };
/// Lengths that may be zero (radii, ranges, heights).
const LENGTH: Bound = Bound { min: 0.0, above: false, max: 1e6, text: "[0, 1e6] m" };
const FOCAL: Bound = Bound { min: 0.0, above: false, max: 1e6, text: "[0, 1e6] px" };
const SPEED: Bound = Bound { min: 0.0, above: false, max: 1e6, text: "[0, 1e6] m/s" };
const TURN: Bound = Bound { min: 0.0, above: false, max: 1e6, text: "[0, 1e6] rad/s" };
const FOV: Bound = Bound { min: 0.0, above: false, max: TAU, text: "[0, 2π] rad" };
const ANGLE_NOISE: Bound = Bound { min: 0.0, above: false, max: 1e6, text: "[0, 1e6] rad" };
const FRACTION_NOISE: Bound = Bound { min: 0.0, above: false, max: 1e6, text: "[0, 1e6]" };
const PROBABILITY: Bound = Bound { min: 0.0, above: false, max: 1.0, text: "[0, 1]" };
const PRIORITY: Bound = Bound { min: 0.0, above: false, max: 1e6, text: "[0, 1e6]" };
/// Radio delay and jitter.
const DELAY: Bound = Bound { min: 0.0, above: false, max: 10.0, text: "[0, 10] s" };
const RANGE: Bound = Bound { min: 0.0, above: false, max: f64::MAX, text: "[0, ∞) m (omit it for no limit)" };
/// Claim and plan rates: their periods are durations of 1 ns to [`MAX_SECONDS`].
const RATE: Bound = Bound { min: 1e-9, above: false, max: 1e9, text: "[1e-9, 1e9] Hz" };
/// A base station's coordinates.
const PLACE: Bound = Bound { min: -1e6, above: false, max: 1e6, text: "[-1e6, 1e6] m" };

/// Why a scenario cannot run: its first field out of bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct InvalidScenario {
    /// The field's path as a scenario file writes it: `world.arena`, `kills[1].robot`.
    pub field: String,
    /// The value refused, as written (`[0, 0]`, `NaN`, `1e300`).
    pub value: String,
    /// What the field is (`arena`, `probability`), for the message.
    pub what: &'static str,
    /// What the field accepts (`each side must be finite and in (0, 1e6] m`).
    pub accepts: String,
}

impl fmt::Display for InvalidScenario {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {} is not a usable {}: {}", self.field, self.value, self.what, self.accepts)
    }
}

impl std::error::Error for InvalidScenario {}

fn refuse(
    field: impl Into<String>,
    value: impl Into<String>,
    what: &'static str,
    accepts: impl Into<String>,
) -> InvalidScenario {
    InvalidScenario { field: field.into(), value: value.into(), what, accepts: accepts.into() }
}

/// A number as a message writes it: short (`1e300`, not 301 digits), `NaN` and `inf` as Rust
/// spells them.
pub fn show(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// A large count or estimate, to two figures (`1.1e9`).
fn about(v: f64) -> String {
    if v < 1e6 {
        format!("{v:.0}")
    } else {
        format!("{v:.1e}")
    }
}

fn show_pair([a, b]: [f64; 2]) -> String {
    format!("[{}, {}]", show(a), show(b))
}

fn number(field: impl Into<String>, v: f64, what: &'static str, b: &Bound) -> Result<(), InvalidScenario> {
    if b.holds(v) {
        Ok(())
    } else {
        Err(refuse(field, show(v), what, format!("must be finite and in {}", b.text)))
    }
}

/// The team's size: 1 to [`MAX_ROBOTS`] robots. `n` is `None` when what was written (`shown`)
/// is not a whole number; the file reader asks before it sizes the room for the team.
pub fn robots(n: Option<u64>, shown: impl fmt::Display) -> Result<usize, InvalidScenario> {
    match n {
        Some(n) if (1..=MAX_ROBOTS as u64).contains(&n) => Ok(n as usize),
        _ => Err(refuse("robots", shown.to_string(), "team", format!("must be a whole number from 1 to {MAX_ROBOTS}"))),
    }
}

/// How many targets: 1 to [`MAX_TARGETS`] (`field` is `targets` in a file, `world.targets`
/// for the list). The file reader asks before it makes the list.
pub fn targets(field: &str, n: Option<u64>, shown: impl fmt::Display) -> Result<usize, InvalidScenario> {
    match n {
        Some(n) if (1..=MAX_TARGETS as u64).contains(&n) => Ok(n as usize),
        _ => Err(refuse(
            field,
            shown.to_string(),
            "number of targets",
            format!("a scenario has from 1 to {MAX_TARGETS} targets"),
        )),
    }
}

impl Scenario {
    /// Whether every field is within its bounds (module docs; docs/cmommt.md, "What a scenario
    /// may hold"): the first one that is not, named. [`Sim::new`](crate::scenario::Sim::new)
    /// calls it first, so a scenario that passes builds and runs without a panic.
    ///
    /// ```
    /// use ayllu_sim::controller::Controller;
    /// use ayllu_sim::scenario::Scenario;
    /// let mut s = Scenario::paper(Controller::Ble, 1);
    /// assert!(s.validate().is_ok());
    /// s.world.arena = [0.0, 0.0];
    /// let e = s.validate().unwrap_err();
    /// assert_eq!(e.field, "world.arena");
    /// assert_eq!(e.to_string(), "world.arena: [0, 0] is not a usable arena: each side must be finite and in (0, 1e6] m");
    /// ```
    pub fn validate(&self) -> Result<(), InvalidScenario> {
        let n = robots(Some(self.robots as u64), self.robots)?;
        world(&self.world)?;
        timing(self)?;
        radio(self, n)?;
        kills(self, n)?;
        base_station_failure(self)?;
        controllers(self)?;
        recording(self)
    }

    /// Ticks between frames: `frame_dt` rounded to whole ticks, at least one.
    pub(crate) fn frame_every(&self) -> u64 {
        ((self.frame_dt / self.dt).round() as u64).max(1)
    }
}

fn world(w: &WorldConfig) -> Result<(), InvalidScenario> {
    let [width, height] = w.arena;
    if !(SIDE.holds(width) && SIDE.holds(height)) {
        return Err(refuse(
            "world.arena",
            show_pair(w.arena),
            "arena",
            format!("each side must be finite and in {}", SIDE.text),
        ));
    }
    number("world.robot_radius", w.robot_radius, "robot radius", &LENGTH)?;
    number("world.target_radius", w.target_radius, "target radius", &LENGTH)?;
    // Bodies are kept inside the walls (clamped between a radius and the side less one).
    let half = width.min(height) / 2.0;
    for (field, r, what) in [
        ("world.robot_radius", w.robot_radius, "robot radius"),
        ("world.target_radius", w.target_radius, "target radius"),
    ] {
        if r > half {
            return Err(refuse(
                field,
                show(r),
                what,
                format!(
                    "the body must fit the arena {}: at most half its shorter side, {} m",
                    show_pair(w.arena),
                    show(half)
                ),
            ));
        }
    }
    number("world.target_height", w.target_height, "target height", &LENGTH)?;
    number("world.focal", w.focal, "focal length", &FOCAL)?;
    number("world.max_speed", w.max_speed, "speed", &SPEED)?;
    number("world.max_turn", w.max_turn, "turn rate", &TURN)?;
    number("world.camera_fov", w.camera_fov, "field of view", &FOV)?;
    number("world.camera_range", w.camera_range, "range", &LENGTH)?;
    number("world.observe_range", w.observe_range, "range", &LENGTH)?;
    if w.sonar_beams > MAX_BEAMS {
        return Err(refuse(
            "world.sonar_beams",
            w.sonar_beams.to_string(),
            "number of beams",
            format!("must be from 0 to {MAX_BEAMS}"),
        ));
    }
    number("world.sonar_range", w.sonar_range, "range", &LENGTH)?;
    number("world.bearing_noise", w.bearing_noise, "noise", &ANGLE_NOISE)?;
    number("world.height_noise", w.height_noise, "noise", &FRACTION_NOISE)?;
    number("world.sonar_noise", w.sonar_noise, "noise", &LENGTH)?;
    number("world.miss_rate", w.miss_rate, "probability", &PROBABILITY)?;
    targets("world.targets", Some(w.targets.len() as u64), format!("{} targets", w.targets.len()))?;
    for (j, t) in w.targets.iter().enumerate() {
        number(format!("world.targets[{j}].priority"), t.priority, "priority", &PRIORITY)?;
        number(format!("world.targets[{j}].speed"), t.speed, "speed", &SPEED)?;
    }
    let cell = grid_cell(w);
    if cell <= 0.0 {
        return Err(refuse(
            "world.sonar_range",
            "0",
            "range",
            "with robots of radius 0 the world's grid has no cell size: one of them must be above 0",
        ));
    }
    let cells = (width / cell).ceil() * (height / cell).ceil();
    if cells > MAX_GRID_CELLS {
        let side = MAX_GRID_CELLS.sqrt() * cell;
        return Err(refuse(
            "world.arena",
            show_pair(w.arena),
            "arena",
            format!(
                "its grid of {} m cells (the sonar range, or four robot radii if larger) would have {} cells, more \
                 than {}: at this sonar range a square arena is at most {} m a side",
                show(cell),
                about(cells),
                MAX_GRID_CELLS,
                show(side.floor())
            ),
        ));
    }
    Ok(())
}

fn timing(s: &Scenario) -> Result<(), InvalidScenario> {
    number("duration", s.duration, "duration", &DURATION)?;
    number("dt", s.dt, "tick", &TICK)?;
    number("frame_dt", s.frame_dt, "frame period", &TIME)?;
    let ticks = (s.duration / s.dt).ceil();
    if ticks > MAX_TICKS {
        return Err(refuse(
            "duration",
            show(s.duration),
            "duration",
            format!(
                "at a tick of {} s it is {} ticks; a run has at most {}",
                show(s.dt),
                about(ticks),
                show(MAX_TICKS)
            ),
        ));
    }
    let frames = (ticks / s.frame_every() as f64).floor() + 1.0;
    if frames > MAX_FRAMES {
        return Err(refuse(
            "duration",
            show(s.duration),
            "duration",
            format!(
                "with a frame every {} s it keeps {} frames, more than {}: shorten the run or raise frame_dt",
                show(s.frame_every() as f64 * s.dt),
                about(frames),
                show(MAX_FRAMES)
            ),
        ));
    }
    Ok(())
}

fn radio(s: &Scenario, robots: usize) -> Result<(), InvalidScenario> {
    let r = &s.radio;
    number("radio.loss", r.loss, "probability", &PROBABILITY)?;
    number("radio.delay", r.delay, "delay", &DELAY)?;
    number("radio.jitter", r.jitter, "jitter", &DELAY)?;
    if let Some(range) = r.range {
        number("radio.range", range, "range", &RANGE)?;
    }
    let team = robots as f64;
    let in_flight = team * EMISSIONS_PER_ROBOT_S * (r.delay + r.jitter) * team;
    if in_flight > MAX_IN_FLIGHT {
        return Err(refuse(
            "radio.delay",
            show(r.delay),
            "delay",
            format!(
                "with {} s of jitter, {robots} robots would hold about {} deliveries in flight, more than {}: for this \
                 team delay + jitter must be at most {} s",
                show(r.jitter),
                about(in_flight),
                show(MAX_IN_FLIGHT),
                show(MAX_IN_FLIGHT / (team * team * EMISSIONS_PER_ROBOT_S))
            ),
        ));
    }
    let planner = s.controller == Controller::Planner;
    for (k, p) in r.partitions.iter().enumerate() {
        number(format!("radio.partitions[{k}].start"), p.start, "instant", &TIME)?;
        number(format!("radio.partitions[{k}].end"), p.end, "instant", &TIME)?;
        if p.end < p.start {
            return Err(refuse(
                format!("radio.partitions[{k}].end"),
                show(p.end),
                "instant",
                format!("a partition ends at or after it starts ({} s)", show(p.start)),
            ));
        }
        for &id in &p.island {
            let exists = (1..=robots as u64).contains(&u64::from(id)) || (planner && id == PLANNER_NODE.0);
            if !exists {
                let base =
                    if planner { format!(", or the Planner's base station {}", PLANNER_NODE.0) } else { String::new() };
                return Err(refuse(
                    format!("radio.partitions[{k}].island"),
                    id.to_string(),
                    "node id",
                    format!("must name a robot of the team, 1 to {robots}{base}"),
                ));
            }
        }
    }
    Ok(())
}

fn base_station_failure(s: &Scenario) -> Result<(), InvalidScenario> {
    let Some(f) = &s.base_station_failure else { return Ok(()) };
    number("base_station_failure.at", f.at, "instant", &TIME)?;
    if let Some(until) = f.until {
        number("base_station_failure.until", until, "instant", &TIME)?;
        if until < f.at {
            return Err(refuse(
                "base_station_failure.until",
                show(until),
                "instant",
                format!("the base station is reconnected at or after it is cut off ({} s)", show(f.at)),
            ));
        }
        if f.how == crate::scenario::BaseStationLoss::Killed {
            return Err(refuse(
                "base_station_failure.until",
                show(until),
                "instant",
                "a killed base station does not come back: `until` goes with how = \"partitioned\"".to_owned(),
            ));
        }
    }
    Ok(())
}

fn kills(s: &Scenario, robots: usize) -> Result<(), InvalidScenario> {
    if s.kills.len() > robots {
        return Err(refuse(
            "kills",
            format!("{} kills", s.kills.len()),
            "list of kills",
            format!("a team of {robots} robots can lose at most {robots}"),
        ));
    }
    for (k, kill) in s.kills.iter().enumerate() {
        number(format!("kills[{k}].at"), kill.at, "instant", &TIME)?;
        let Some(id) = kill.robot else { continue };
        if !(1..=robots as u64).contains(&u64::from(id)) {
            return Err(refuse(
                format!("kills[{k}].robot"),
                id.to_string(),
                "robot",
                format!("must name a robot of the team, 1 to {robots} (omit it for the most useful robot)"),
            ));
        }
        if let Some(first) = s.kills[..k].iter().position(|o| o.robot == Some(id)) {
            return Err(refuse(
                format!("kills[{k}].robot"),
                id.to_string(),
                "robot",
                format!("kills[{first}] already kills robot {id}"),
            ));
        }
    }
    Ok(())
}

fn controllers(s: &Scenario) -> Result<(), InvalidScenario> {
    let c = &s.controllers;
    number("controllers.claim_hz", c.claim_hz, "rate", &RATE)?;
    number("controllers.plan_hz", c.plan_hz, "rate", &RATE)?;
    if let Some(place) = c.base_station {
        if !(PLACE.holds(place[0]) && PLACE.holds(place[1])) {
            return Err(refuse(
                "controllers.base_station",
                show_pair(place),
                "place",
                format!("each coordinate must be finite and in {}", PLACE.text),
            ));
        }
    }
    if let ayllu::stdlib::Eligibility::OnChange { threshold, .. } = c.eligibility {
        number("controllers.eligibility.threshold", threshold, "threshold", &FRACTION_NOISE)?;
    }
    Ok(())
}

fn recording(s: &Scenario) -> Result<(), InvalidScenario> {
    if !s.record {
        return Ok(());
    }
    let frames = ((s.duration / s.dt).ceil() / s.frame_every() as f64).floor() + 1.0;
    let poses = frames * (s.robots + s.world.targets.len()) as f64;
    if poses > MAX_RECORDED {
        return Err(refuse(
            "record",
            "true",
            "recording",
            format!(
                "{} frames of {} robots and {} targets are {} poses, more than {}: shorten the run, raise frame_dt or \
                 do not record",
                about(frames),
                s.robots,
                s.world.targets.len(),
                about(poses),
                show(MAX_RECORDED)
            ),
        ));
    }
    Ok(())
}
