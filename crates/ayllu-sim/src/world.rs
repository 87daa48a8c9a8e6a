//! The physical world: a walled rectangular arena, unicycle robots with a sonar ring and a
//! camera, and moving targets with priorities. Pure and deterministic: [`World::step`] takes
//! the commands and a time step, and every random draw comes from the world's own seeded
//! streams (target motion and sensor noise are separate streams, so a controller's choices never
//! change how the targets move: every controller meets the same targets).
//!
//! Geometry: metres and radians, origin at the arena's bottom-left corner, headings
//! counter-clockwise from +x. Collisions are resolved by pushing circles apart and back inside
//! the walls; nothing tunnels at the speeds allowed (a step moves less than a radius).

use std::f64::consts::{PI, TAU};

use serde::{Deserialize, Serialize};

/// How a target moves.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Motion {
    /// Stays where it starts.
    Static,
    /// Picks a random point in the arena, goes there at its speed, pauses 0-5 s, repeats.
    RandomWaypoint,
    /// Straight lines, reflecting off the walls; the heading drifts a little at random.
    Bounce,
}

/// A target's declaration: priority, speed and motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetSpec {
    /// Larger is more important; the scenario numbers targets by decreasing priority.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub priority: f64,
    /// Speed while moving (m/s).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub speed: f64,
    /// How it moves (see [`Motion`]).
    pub motion: Motion,
}

/// Everything fixed about a world.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorldConfig {
    /// Width and height (m), origin at the bottom-left corner; walls on the border.
    #[serde(deserialize_with = "crate::numbers::pair_de")]
    pub arena: [f64; 2],
    /// Robot radius (m).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub robot_radius: f64,
    /// Target radius (m).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub target_radius: f64,
    /// Height of a target (m); its apparent height is `focal * height / distance`.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub target_height: f64,
    /// Camera focal length in pixels: apparent height 100 px for a 0.5 m target at 1 m.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub focal: f64,
    /// Fastest forward or backward speed (m/s): [`Command::translate`] is clamped to ±this.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub max_speed: f64,
    /// Fastest turn (rad/s): [`Command::rotate`] is clamped to ±this.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub max_turn: f64,
    /// Camera field of view (rad, whole angle, centred on the heading).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub camera_fov: f64,
    /// Camera range (m): farther targets are not seen.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub camera_range: f64,
    /// A target counts as observed (metrics) in the field of view and within this distance (m).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub observe_range: f64,
    /// Sonar beams, evenly spaced around the robot from its heading.
    pub sonar_beams: usize,
    /// Sonar range (m), from the robot's rim; farther echoes are not heard.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub sonar_range: f64,
    /// Standard deviation of a sighting's bearing (rad), Gaussian.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub bearing_noise: f64,
    /// Standard deviation of a sighting's apparent height, as a fraction of it (0.05: 5 %).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub height_noise: f64,
    /// Standard deviation of a sonar range (m), Gaussian.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub sonar_noise: f64,
    /// Probability that one camera frame misses a visible target (drawn per target and frame).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub miss_rate: f64,
    /// The targets; in decreasing priority after [`WorldConfig::by_priority`] (which the
    /// scenario applies), so target id n is the n-th most important.
    pub targets: Vec<TargetSpec>,
}

impl WorldConfig {
    /// The same world with its targets in decreasing priority (stable): target n is then the
    /// n-th most important, as the observer chain `OBSn` over `TargetN` requires.
    pub fn by_priority(mut self) -> WorldConfig {
        self.targets.sort_by(|a, b| b.priority.total_cmp(&a.priority));
        self
    }

    /// The paper's lab, scaled to a Pioneer team: an 8 m x 8 m room, a 60° camera seeing 5 m,
    /// targets observed within 2 m, targets slower than robots.
    pub fn lab(priorities: &[f64]) -> WorldConfig {
        WorldConfig {
            arena: [8.0, 8.0],
            robot_radius: 0.25,
            target_radius: 0.2,
            target_height: 0.5,
            focal: 200.0,
            max_speed: 0.4,
            max_turn: 1.5,
            camera_fov: 60f64.to_radians(),
            camera_range: 5.0,
            observe_range: 2.0,
            sonar_beams: 8,
            sonar_range: 3.0,
            bearing_noise: 0.02,
            height_noise: 0.05,
            sonar_noise: 0.02,
            miss_rate: 0.02,
            targets: priorities
                .iter()
                .map(|&p| TargetSpec { priority: p, speed: 0.15, motion: Motion::RandomWaypoint })
                .collect(),
        }
    }
}

/// Where a robot is and which way it faces.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position (m).
    pub x: f64,
    /// Position (m).
    pub y: f64,
    /// Heading (rad, counter-clockwise from +x, in (-π, π]).
    pub theta: f64,
}

/// A robot's body in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Robot {
    /// Its pose in the arena.
    pub pose: Pose,
    /// False once killed: it no longer moves or counts as observing, but stays as an obstacle.
    pub alive: bool,
}

/// A target in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    /// Position (m).
    pub x: f64,
    /// Position (m).
    pub y: f64,
    /// Direction of travel (rad, counter-clockwise from +x).
    pub heading: f64,
    waypoint: (f64, f64),
    pause: f64,
}

/// One target as one camera frame sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sighting {
    /// Index into the world's targets (target id - 1).
    pub target: usize,
    /// Bearing (rad) positive to the right of the camera axis (the stdlib convention).
    pub angle: f64,
    /// Apparent height in pixels: larger is closer.
    pub height: f64,
}

/// What the motors are asked to do.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Command {
    /// Forward speed asked (m/s), clamped to `max_speed`.
    pub translate: f64,
    /// Turn rate asked (rad/s), clamped to `max_turn`.
    pub rotate: f64,
}

/// The world's ground truth: robots, targets, walls; stepped on virtual time.
pub struct World {
    /// Its configuration (fixed for the world's life).
    pub config: WorldConfig,
    /// The robots, by index (node id - 1).
    pub robots: Vec<Robot>,
    /// The targets, by index (target id - 1).
    pub targets: Vec<Target>,
    motion_rng: fastrand::Rng,
    noise_rng: fastrand::Rng,
    /// Spatial hash of robots and targets for sonar: cell size = sonar range.
    grid: Grid,
    /// Reused by `camera` so a frame allocates nothing.
    view: Vec<(usize, f64, f64)>,
    /// [`World::sonar`]'s own room and draws.
    sweep: SonarScratch,
    draws: Vec<(f64, f64)>,
    /// A sweep that heard nothing (every beam at the range), as a port value shared by every
    /// robot: see [`World::quiet_sweep`].
    quiet: ayllu_core::Value,
}

/// What a sonar sweep needs besides the world, kept from sweep to sweep so that a sweep
/// allocates nothing: the beams' directions and room for the circles in reach. One for each
/// thread that sweeps ([`World::sonar_with`]).
#[derive(Default)]
pub struct SonarScratch {
    /// (sin, cos) of each sonar beam's offset from the heading.
    beams: Vec<(f64, f64)>,
    /// Circles within the sweep's reach, as [`Echo`]s from the sweeping robot.
    circles: Vec<Echo>,
    /// Each beam's direction this sweep (x and y components).
    dirs: (Vec<f64>, Vec<f64>),
    /// A body's sweep ([`World::sonar_from`]), worked out and written to the port in one
    /// visit, so kept with the thread rather than with each body
    /// (`crate::body::Body::write_senses`).
    pub(crate) ranges: Vec<f64>,
}

/// A sonar sweep's noise for `beams` beams from `rng` into `draws`: a pair of uniform draws for
/// each pair of beams ([`World::sonar_draws`]).
fn draw_pairs(rng: &mut fastrand::Rng, beams: usize, draws: &mut Vec<(f64, f64)>) {
    draws.clear();
    for _ in 0..beams.div_ceil(2) {
        let u = rng.f64();
        let v = rng.f64();
        draws.push((u, v));
    }
}

/// A standard normal draw (Box-Muller), from a stream that only this module uses.
fn gauss(rng: &mut fastrand::Rng) -> f64 {
    gauss_pair(rng).0
}

/// Two independent standard normal draws: both outputs of one Box-Muller transform (one
/// logarithm, one square root and one sin_cos for two draws) of two uniform draws.
fn gauss_pair(rng: &mut fastrand::Rng) -> (f64, f64) {
    let u = rng.f64();
    let v = rng.f64();
    gauss_from(u, v)
}

/// [`gauss_pair`] from its two uniform draws, taken earlier ([`World::sonar_draws`]). Not
/// inlined: in a caller's loop the compiler called `sin` and `cos` apart, where on its own it
/// makes one `sincos`.
#[inline(never)]
fn gauss_from(u: f64, v: f64) -> (f64, f64) {
    let u = u.max(f64::MIN_POSITIVE);
    let r = (-2.0 * u.ln()).sqrt();
    let (s, c) = (TAU * v).sin_cos();
    (r * c, r * s)
}

/// No output of [`gauss_pair`] is larger in size: its radius `sqrt(-2 ln u)` is largest at
/// the smallest `u`, `f64::MIN_POSITIVE`, where it is 37.64, and sine and cosine are at most 1.
const GAUSS_BOUND: f64 = 38.0;

/// Euclidean length; `f64::hypot` guards against overflow we cannot have here, at several
/// times the cost in the sonar's inner loop.
#[inline]
fn dist(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}

/// True if `dist(dx, dy)` is certainly above `r`, seen from one coordinate alone: the length
/// is at least the larger coordinate within a few units of rounding, far inside the margin.
/// False for NaN, and for radii so small that squares could underflow, so a caller then
/// computes the length as it did before.
#[inline]
fn surely_beyond(dx: f64, dy: f64, r: f64) -> bool {
    let r = r * (1.0 + 1e-9);
    r > 1e-150 && (dx.abs() > r || dy.abs() > r)
}

/// Wrap an angle into (-π, π].
pub fn wrap(a: f64) -> f64 {
    // `rem_euclid` is `a % TAU`, plus TAU if negative; for |a| < TAU the remainder is `a`
    // itself, exactly, so the common case skips the division's library call and gives the
    // same bits.
    let a = if a.abs() < TAU {
        if a < 0.0 {
            a + TAU
        } else {
            a
        }
    } else {
        a.rem_euclid(TAU)
    };
    if a > PI {
        a - TAU
    } else {
        a
    }
}

/// A circle as seen from a ray's origin, with what does not depend on the ray's direction
/// computed once: a sonar sweep tests every circle within reach against each of its beams.
#[derive(Clone, Copy)]
struct Echo {
    /// Origin minus the circle's centre.
    fx: f64,
    fy: f64,
    /// `fx² + fy² - r²`: the origin's power with respect to the circle.
    c: f64,
}

impl Echo {
    fn new(ox: f64, oy: f64, cx: f64, cy: f64, r: f64) -> Echo {
        let (fx, fy) = (ox - cx, oy - cy);
        Echo { fx, fy, c: fx * fx + fy * fy - r * r }
    }

    /// Distance along the ray in direction (dx, dy) (unit) to the circle, if it hits ahead
    /// of the origin.
    #[cfg(test)]
    fn hit(&self, dx: f64, dy: f64) -> Option<f64> {
        let b = self.fx * dx + self.fy * dy;
        if b > 0.0 {
            // Facing away from the centre: `-b - sqrt(..)` is negative, so no hit ahead, and
            // the square root can wait for a beam that may hit.
            return None;
        }
        let disc = b * b - self.c;
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t >= 0.0).then_some(t)
    }

    /// [`Echo::hit`] as a distance, infinity for a miss, computed without a branch. `t >= 0`
    /// alone decides: a negative discriminant makes `t` NaN, and when `b > 0`, `-b` is
    /// negative and subtracting a square root (never negative) keeps it so, whatever the
    /// rounding.
    #[inline(always)]
    fn hit_or_infinity(&self, dx: f64, dy: f64) -> f64 {
        let b = self.fx * dx + self.fy * dy;
        let disc = b * b - self.c;
        let t = -b - disc.sqrt();
        if t >= 0.0 {
            t
        } else {
            f64::INFINITY
        }
    }
}

impl World {
    /// A world with `robots` robots and the configured targets placed at random (seeded),
    /// apart from each other and from the walls.
    pub fn new(config: WorldConfig, robots: usize, seed: u64) -> World {
        let mut place_rng = fastrand::Rng::with_seed(seed ^ 0x5EED_0001);
        let motion_rng = fastrand::Rng::with_seed(seed ^ 0x5EED_0002);
        let noise_rng = fastrand::Rng::with_seed(seed ^ 0x5EED_0003);
        let [w, h] = config.arena;
        let mut taken: Vec<(f64, f64, f64)> = Vec::new();
        let mut place = |r: f64, rng: &mut fastrand::Rng| {
            // Bounded tries: a crowded arena still gets a (possibly overlapping) place, and
            // the collision step separates overlaps.
            for attempt in 0..200 {
                let x = r + rng.f64() * (w - 2.0 * r);
                let y = r + rng.f64() * (h - 2.0 * r);
                let clear = taken.iter().all(|&(tx, ty, tr)| dist(tx - x, ty - y) > tr + r + 0.2);
                if clear || attempt == 199 {
                    taken.push((x, y, r));
                    return (x, y);
                }
            }
            unreachable!("the last attempt always places")
        };
        let targets = (0..config.targets.len())
            .map(|_| {
                let (x, y) = place(config.target_radius, &mut place_rng);
                Target { x, y, heading: place_rng.f64() * TAU, waypoint: (x, y), pause: 0.0 }
            })
            .collect();
        let robots = (0..robots)
            .map(|_| {
                let (x, y) = place(config.robot_radius, &mut place_rng);
                Robot { pose: Pose { x, y, theta: wrap(place_rng.f64() * TAU) }, alive: true }
            })
            .collect();
        let grid = Grid::new(config.arena, grid_cell(&config));
        World {
            robots,
            targets,
            motion_rng,
            noise_rng,
            grid,
            view: Vec::new(),
            sweep: SonarScratch::default(),
            draws: Vec::new(),
            quiet: ayllu_core::Value::vector(&vec![config.sonar_range; config.sonar_beams]),
            config,
        }
    }

    /// If `sweep` is one that heard nothing (every beam reads exactly the sonar range, as in
    /// open space), the port value holding it, one for every robot: writing it bumps a count
    /// on a line every sweep touches instead of allocating and copying a vector. `None` for
    /// any other sweep.
    pub fn quiet_sweep(&self, sweep: &[f64]) -> Option<&ayllu_core::Value> {
        let range = self.config.sonar_range.to_bits();
        let quiet = sweep.len() == self.config.sonar_beams && sweep.iter().all(|r| r.to_bits() == range);
        quiet.then_some(&self.quiet)
    }

    /// Advance by `dt` seconds: targets move, live robots follow `commands` (clamped to the
    /// motor limits; dead robots stay where they died, still solid), then contacts resolve.
    pub fn step(&mut self, dt: f64, commands: &[Command]) {
        self.move_targets(dt);
        let c = &self.config;
        for (robot, cmd) in self.robots.iter_mut().zip(commands) {
            if !robot.alive {
                continue;
            }
            let v = cmd.translate.clamp(-c.max_speed, c.max_speed);
            let w = cmd.rotate.clamp(-c.max_turn, c.max_turn);
            let p = &mut robot.pose;
            // Midpoint heading: exact enough at 20 Hz and symmetric in time.
            let mid = p.theta + 0.5 * w * dt;
            p.x += v * mid.cos() * dt;
            p.y += v * mid.sin() * dt;
            p.theta = wrap(p.theta + w * dt);
        }
        self.resolve_contacts();
    }

    fn move_targets(&mut self, dt: f64) {
        let [w, h] = self.config.arena;
        let r = self.config.target_radius;
        for (t, spec) in self.targets.iter_mut().zip(&self.config.targets) {
            match spec.motion {
                Motion::Static => {}
                Motion::RandomWaypoint => {
                    if t.pause > 0.0 {
                        t.pause -= dt;
                        continue;
                    }
                    let (dx, dy) = (t.waypoint.0 - t.x, t.waypoint.1 - t.y);
                    let d = dist(dx, dy);
                    let step = spec.speed * dt;
                    if d <= step {
                        t.x = t.waypoint.0;
                        t.y = t.waypoint.1;
                        t.pause = self.motion_rng.f64() * 5.0;
                        t.waypoint =
                            (r + self.motion_rng.f64() * (w - 2.0 * r), r + self.motion_rng.f64() * (h - 2.0 * r));
                    } else {
                        t.heading = dy.atan2(dx);
                        t.x += dx / d * step;
                        t.y += dy / d * step;
                    }
                }
                Motion::Bounce => {
                    t.heading = wrap(t.heading + gauss(&mut self.motion_rng) * 0.3 * dt.sqrt());
                    t.x += spec.speed * t.heading.cos() * dt;
                    t.y += spec.speed * t.heading.sin() * dt;
                    if t.x < r || t.x > w - r {
                        t.heading = wrap(PI - t.heading);
                        t.x = t.x.clamp(r, w - r);
                    }
                    if t.y < r || t.y > h - r {
                        t.heading = wrap(-t.heading);
                        t.y = t.y.clamp(r, h - r);
                    }
                }
            }
        }
    }

    /// Push robots out of each other, out of targets (targets are not pushed: they are
    /// people or other robots with their own minds) and back inside the walls.
    fn resolve_contacts(&mut self) {
        let rr = self.config.robot_radius;
        let tr = self.config.target_radius;
        let [w, h] = self.config.arena;
        self.grid.fill_robots(&self.robots);
        let (grid, robots) = (&self.grid, &mut self.robots);
        for i in 0..robots.len() {
            let (x, y) = (robots[i].pose.x, robots[i].pose.y);
            let mi = robots[i].alive as u8 as f64;
            let mut push = (0.0, 0.0);
            grid.near(x, y, |j| {
                if j <= i {
                    return;
                }
                let o = &mut robots[j];
                let (dx, dy) = (o.pose.x - x, o.pose.y - y);
                if surely_beyond(dx, dy, 2.0 * rr) {
                    return;
                }
                let d = dist(dx, dy);
                let overlap = 2.0 * rr - d;
                if overlap > 0.0 {
                    // Coincident centres separate along x, deterministically.
                    let (ux, uy) = if d > 1e-12 { (dx / d, dy / d) } else { (1.0, 0.0) };
                    let mj = o.alive as u8 as f64;
                    let total = (mi + mj).max(1.0);
                    let (si, sj) = (overlap * mi / total, overlap * mj / total);
                    push.0 -= ux * si;
                    push.1 -= uy * si;
                    o.pose.x += ux * sj;
                    o.pose.y += uy * sj;
                }
            });
            let p = &mut robots[i].pose;
            p.x += push.0;
            p.y += push.1;
            for t in &self.targets {
                let (dx, dy) = (p.x - t.x, p.y - t.y);
                if surely_beyond(dx, dy, rr + tr) {
                    continue;
                }
                let d = dist(dx, dy);
                let overlap = rr + tr - d;
                if overlap > 0.0 {
                    let (ux, uy) = if d > 1e-12 { (dx / d, dy / d) } else { (1.0, 0.0) };
                    p.x += ux * overlap;
                    p.y += uy * overlap;
                }
            }
            p.x = p.x.clamp(rr, w - rr);
            p.y = p.y.clamp(rr, h - rr);
        }
    }

    /// Noise-free: targets robot `i` sees, with their true distance (for metrics and the
    /// omniscient baseline).
    #[inline]
    pub fn in_view(&self, i: usize, range: f64, mut f: impl FnMut(usize, f64, f64)) {
        let p = self.robots[i].pose;
        let half = 0.5 * self.config.camera_fov;
        for (j, t) in self.targets.iter().enumerate() {
            let (dx, dy) = (t.x - p.x, t.y - p.y);
            if surely_beyond(dx, dy, range) {
                continue;
            }
            let d = dist(dx, dy);
            if d > range {
                continue;
            }
            let bearing = wrap(dy.atan2(dx) - p.theta);
            if bearing.abs() <= half {
                f(j, d, bearing);
            }
        }
    }

    /// One camera frame of robot `i`, with noise and misses, into `out` (cleared first).
    pub fn camera(&mut self, i: usize, out: &mut Vec<Sighting>) {
        out.clear();
        let mut seen = std::mem::take(&mut self.view);
        seen.clear();
        self.in_view(i, self.config.camera_range, |j, d, b| seen.push((j, d, b)));
        let c = &self.config;
        for &(j, d, b) in &seen {
            if self.noise_rng.f64() < c.miss_rate {
                continue;
            }
            let (nb, nh) = gauss_pair(&mut self.noise_rng);
            let angle = -(b + c.bearing_noise * nb);
            let height = c.focal * c.target_height / d.max(0.05) * (1.0 + c.height_noise * nh);
            out.push(Sighting { target: j, angle, height: height.max(0.0) });
        }
        self.view = seen;
    }

    /// One sonar sweep of robot `i` into `out` (one range per beam, from the robot's rim,
    /// capped at the sonar range), with noise. Sees walls, other robots (dead ones too) and
    /// targets; echoes from beyond the range are not heard. Call [`World::index`] once after
    /// the robots moved, before the sweeps.
    pub fn sonar(&mut self, i: usize, out: &mut [f64]) {
        let mut draws = std::mem::take(&mut self.draws);
        let mut sweep = std::mem::take(&mut self.sweep);
        self.sonar_draws(out.len(), &mut draws);
        self.sonar_with(i, &draws, &mut sweep, out);
        (self.draws, self.sweep) = (draws, sweep);
    }

    /// The sonar's noise for one sweep of `beams` beams, drawn from the world's noise stream
    /// into `draws`: a pair of uniform draws for each pair of beams, whether or not the sweep
    /// will need them (so the stream moves alike). The first half of [`World::sonar`]: a team's
    /// draws are taken in robot order, and the sweeps ([`World::sonar_with`]) may then run on
    /// any thread, in any order.
    pub fn sonar_draws(&mut self, beams: usize, draws: &mut Vec<(f64, f64)>) {
        draw_pairs(&mut self.noise_rng, beams, draws);
    }

    /// [`World::sonar_draws`] kept as where they start: the noise stream moves past a sweep's
    /// draws as it does there, and the state it started from is returned, from which the
    /// sweep ([`World::sonar_from`]) draws the same numbers again as it takes them. Eight bytes
    /// for a body to keep between its observation and its sweep instead of the draws.
    pub fn skip_sonar_draws(&mut self, beams: usize) -> u64 {
        let start = self.noise_rng.get_seed();
        for _ in 0..beams.div_ceil(2) {
            self.noise_rng.f64();
            self.noise_rng.f64();
        }
        start
    }

    /// The second half of [`World::sonar`]: robot `i`'s sweep into `out` (`out.len()` beams),
    /// its noise from `draws` ([`World::sonar_draws`] for as many beams), `scratch` for room.
    /// Reads the world only.
    pub fn sonar_with(&self, i: usize, draws: &[(f64, f64)], scratch: &mut SonarScratch, out: &mut [f64]) {
        // Noise comes in pairs (Box-Muller): an even beam and the next share one draw.
        assert_eq!(draws.len(), out.len().div_ceil(2), "a sweep's draws are for its beams");
        self.sweep(i, draws.iter().copied(), scratch, out);
    }

    /// [`World::sonar_with`] with the draws that [`World::skip_sonar_draws`] passed over from
    /// `start` (for `out.len()` beams), drawn again as the sweep takes them: the numbers
    /// [`World::sonar_draws`] would have drawn there, never stored.
    pub fn sonar_from(&self, i: usize, start: u64, scratch: &mut SonarScratch, out: &mut [f64]) {
        let mut rng = fastrand::Rng::with_seed(start);
        self.sweep(i, std::iter::repeat_with(move || (rng.f64(), rng.f64())), scratch, out);
    }

    /// The sweep of [`World::sonar_with`] and [`World::sonar_from`], a pair of `draws` (u, v)
    /// for each pair of beams.
    #[inline(always)]
    fn sweep(&self, i: usize, draws: impl Iterator<Item = (f64, f64)>, scratch: &mut SonarScratch, out: &mut [f64]) {
        let c = &self.config;
        let p = self.robots[i].pose;
        let [w, h] = c.arena;
        let (rr, range, sn) = (c.robot_radius, c.sonar_range, c.sonar_noise);
        let beams = out.len();
        if scratch.beams.len() != beams {
            scratch.beams = (0..beams).map(|k| (k as f64 * TAU / beams as f64).sin_cos()).collect();
        }
        // The circles a beam can hit within range, once per sweep rather than once per beam.
        let reach = range + rr;
        let mut circles = std::mem::take(&mut scratch.circles);
        circles.clear();
        let mut consider = |x: f64, y: f64, r: f64| {
            let (dx, dy) = (x - p.x, y - p.y);
            if dx * dx + dy * dy <= (reach + r) * (reach + r) {
                circles.push(Echo::new(p.x, p.y, x, y, r));
            }
        };
        self.grid.near(p.x, p.y, |j| {
            if j != i {
                let o = &self.robots[j].pose;
                consider(o.x, o.y, rr);
            }
        });
        for t in &self.targets {
            consider(t.x, t.y, c.target_radius);
        }
        // A beam whose nearest echo is at `best` reads `best - rr + sn * n`, clamped to
        // [0, range], for its noise draw n. No draw exceeds GAUSS_BOUND in size, and
        // floating-point subtraction and addition are monotonic, so when `best - rr - margin`
        // already reaches the range the beam reads exactly `range` whatever n is: its noise
        // need not be computed (only drawn, so that the stream stays where it was).
        // (A negative range makes the clamp panic, as it did before: nothing is saturated.)
        let margin = if range >= 0.0 { sn.abs() * GAUSS_BOUND } else { f64::NAN };
        let saturated = |best: f64| best - rr - margin >= range;
        // A wall at least `far` away (across) is, along any beam, saturated too (the 1 %
        // covers the beam's length being 1 within rounding): such a robot's sweep skips the
        // walls, which changes no reading.
        let far = (range + rr + margin) * 1.01;
        let walls = !(rr >= 0.0 && range > 0.0 && p.x >= far && w - p.x >= far && p.y >= far && h - p.y >= far);
        if walls || !circles.is_empty() {
            let (s0, c0) = p.theta.sin_cos();
            let (mut xs, mut ys) = std::mem::take(&mut scratch.dirs);
            xs.resize(beams, 0.0);
            ys.resize(beams, 0.0);
            for (((slot, &(sk, ck)), x), y) in out.iter_mut().zip(&scratch.beams).zip(&mut xs).zip(&mut ys) {
                // Beam direction = heading rotated by the beam's fixed offset (one sin_cos a
                // sweep).
                let (dx, dy) = (c0 * ck - s0 * sk, s0 * ck + c0 * sk);
                (*x, *y) = (dx, dy);
                *slot = if walls { wall_distance(p.x, p.y, w, h, dx, dy) } else { f64::INFINITY };
            }
            // Circle after circle, every beam at once and without a branch (which beams a
            // circle hits is data, badly predicted): each beam still meets the circles in the
            // same order after its walls, and `min` with infinity changes nothing, so each
            // reading is the one the beam-by-beam test gave.
            for e in &circles {
                for ((slot, &dx), &dy) in out.iter_mut().zip(&xs).zip(&ys) {
                    *slot = slot.min(e.hit_or_infinity(dx, dy));
                }
            }
            scratch.dirs = (xs, ys);
        } else {
            out.fill(f64::INFINITY);
        }
        // Noise comes in pairs (Box-Muller): an even beam and the next share one draw, drawn
        // whether or not the pair needs it.
        for (pair, (u, v)) in out.chunks_mut(2).zip(draws) {
            if pair.iter().all(|&best| saturated(best)) {
                pair.fill(range);
                continue;
            }
            let noise = gauss_from(u, v);
            for (slot, n) in pair.iter_mut().zip([noise.0, noise.1]) {
                let r = *slot - rr + sn * n;
                *slot = r.clamp(0.0, range);
            }
        }
        scratch.circles = circles;
    }

    /// Rebuild the spatial index after robots moved (the sonar uses it).
    pub fn index(&mut self) {
        self.grid.fill_robots(&self.robots);
    }
}

/// The side of the world's grid cells (m): the sonar range, or four robot radii if larger, so
/// that a sweep's or a contact's robots lie in the 3 x 3 cells around it. One place for the
/// world and for the bound on the grid's size (crate::bounds).
pub(crate) fn grid_cell(config: &WorldConfig) -> f64 {
    config.sonar_range.max(config.robot_radius * 4.0)
}

/// A uniform grid over the arena holding robot indices, so that contacts and sonar look only
/// at nearby robots: cost per robot stays constant as the team grows at constant density.
/// The cells' indices lie in one array, cell after cell in row-major order, so the three
/// neighbouring cells of a row are one contiguous run.
struct Grid {
    cell: f64,
    cols: usize,
    rows: usize,
    /// The last column and row, as floats.
    last: (f64, f64),
    /// Robot indices, by cell (row-major), each cell's in increasing order.
    items: Vec<u32>,
    /// Cell k holds `items[starts[k]..starts[k + 1]]`.
    starts: Vec<u32>,
    /// Scratch of `fill_robots`: each robot's cell.
    home: Vec<u32>,
}

impl Grid {
    fn new(arena: [f64; 2], cell: f64) -> Grid {
        let cols = ((arena[0] / cell).ceil() as usize).max(1);
        let rows = ((arena[1] / cell).ceil() as usize).max(1);
        Grid {
            cell,
            cols,
            rows,
            last: ((cols - 1) as f64, (rows - 1) as f64),
            items: Vec::new(),
            starts: vec![0; cols * rows + 1],
            home: Vec::new(),
        }
    }

    #[inline]
    fn cell_of(&self, x: f64, y: f64) -> (usize, usize) {
        // Capped as a float before the cast (the last column and row are whole numbers, so
        // the floor of the capped quotient is the capped floor): the cast then needs no
        // saturation beyond u32's, and NaN still lands in cell 0.
        let c = (x / self.cell).max(0.0).min(self.last.0) as u32 as usize;
        let r = (y / self.cell).max(0.0).min(self.last.1) as u32 as usize;
        (c, r)
    }

    fn fill_robots(&mut self, robots: &[Robot]) {
        // A counting sort: count per cell, sum into each cell's end, then place the robots
        // from the last so each cell lists its robots in increasing order.
        let cells = self.cols * self.rows;
        self.starts.clear();
        self.starts.resize(cells + 1, 0);
        self.home.clear();
        for r in robots {
            let (c, row) = self.cell_of(r.pose.x, r.pose.y);
            let k = row * self.cols + c;
            self.home.push(k as u32);
            self.starts[k] += 1;
        }
        let mut end = 0;
        for s in &mut self.starts[..cells] {
            end += *s;
            *s = end;
        }
        self.starts[cells] = end;
        self.items.clear();
        self.items.resize(robots.len(), 0);
        for (i, &k) in self.home.iter().enumerate().rev() {
            let s = &mut self.starts[k as usize];
            *s -= 1;
            self.items[*s as usize] = i as u32;
        }
    }

    /// Robots in the 3 x 3 cells around (x, y), cell by cell (row-major), each cell in
    /// increasing index order: a fixed order, so results are reproducible.
    fn near(&self, x: f64, y: f64, mut f: impl FnMut(usize)) {
        let (c, r) = self.cell_of(x, y);
        let (first, last) = (c.saturating_sub(1), (c + 1).min(self.cols - 1));
        for row in r.saturating_sub(1)..(r + 2).min(self.rows) {
            let k = row * self.cols;
            let run = self.starts[k + first] as usize..self.starts[k + last + 1] as usize;
            for &j in &self.items[run] {
                f(j as usize);
            }
        }
    }
}

/// How far a ray from (`x`, `y`) along (`dx`, `dy`) travels before it meets the wall of the
/// `w` x `h` arena from the inside (infinity for a ray along a wall); one place for the sonar
/// and the reference sweep its test compares against, so both make the same operations.
#[inline(always)]
fn wall_distance(x: f64, y: f64, w: f64, h: f64, dx: f64, dy: f64) -> f64 {
    let mut best = f64::INFINITY;
    if dx > 1e-12 {
        best = best.min((w - x) / dx);
    } else if dx < -1e-12 {
        best = best.min(-x / dx);
    }
    if dy > 1e-12 {
        best = best.min((h - y) / dy);
    } else if dy < -1e-12 {
        best = best.min(-y / dy);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `wrap` as it was written before its fast path: the same bits are owed.
    fn wrap_by_remainder(a: f64) -> f64 {
        let a = a.rem_euclid(TAU);
        if a > PI {
            a - TAU
        } else {
            a
        }
    }

    #[test]
    fn wrap_gives_the_bits_of_the_remainder() {
        let mut rng = fastrand::Rng::with_seed(11);
        let edges = [0.0, -0.0, PI, -PI, TAU, -TAU, 1e-300, -1e-300, f64::EPSILON, -f64::EPSILON, 100.0, -100.0];
        let near =
            edges.iter().flat_map(|&e| [e, f64::from_bits(e.to_bits() + 1), f64::from_bits(e.to_bits().max(1) - 1)]);
        let random = (0..100_000).map(|_| (rng.f64() - 0.5) * 8.0 * TAU);
        for a in near.chain(random) {
            assert_eq!(wrap(a).to_bits(), wrap_by_remainder(a).to_bits(), "{a:e}");
        }
        assert!(wrap(f64::NAN).is_nan());
    }

    /// `World::sonar` as it was written before it skipped saturated beams' noise and far
    /// walls: the same bits, and the same noise stream, are owed.
    fn sonar_as_before(world: &mut World, i: usize, out: &mut [f64]) {
        let c = &world.config;
        let p = world.robots[i].pose;
        let [w, h] = c.arena;
        let beams = out.len();
        let offsets: Vec<(f64, f64)> = (0..beams).map(|k| (k as f64 * TAU / beams as f64).sin_cos()).collect();
        let reach = c.sonar_range + c.robot_radius;
        let mut circles = Vec::new();
        let mut consider = |x: f64, y: f64, r: f64| {
            let (dx, dy) = (x - p.x, y - p.y);
            if dx * dx + dy * dy <= (reach + r) * (reach + r) {
                circles.push(Echo::new(p.x, p.y, x, y, r));
            }
        };
        world.grid.near(p.x, p.y, |j| {
            if j != i {
                let o = &world.robots[j].pose;
                consider(o.x, o.y, c.robot_radius);
            }
        });
        for t in &world.targets {
            consider(t.x, t.y, c.target_radius);
        }
        let (s0, c0) = p.theta.sin_cos();
        let mut noise = (0.0, 0.0);
        for (k, slot) in out.iter_mut().enumerate() {
            let (sk, ck) = offsets[k];
            let (dx, dy) = (c0 * ck - s0 * sk, s0 * ck + c0 * sk);
            let mut best = wall_distance(p.x, p.y, w, h, dx, dy);
            for e in &circles {
                if let Some(t) = e.hit(dx, dy) {
                    best = best.min(t);
                }
            }
            let n = if k % 2 == 0 {
                noise = gauss_pair(&mut world.noise_rng);
                noise.0
            } else {
                noise.1
            };
            let r = best - c.robot_radius + c.sonar_noise * n;
            *slot = r.clamp(0.0, c.sonar_range);
        }
    }

    #[test]
    fn a_sweep_gives_the_bits_it_gave_before() {
        let mut place = fastrand::Rng::with_seed(5);
        let mut skipped = 0;
        // Crowded and sparse rooms, small and large, even and odd beam counts, noise large
        // enough that the margin matters and none at all.
        for (case, (side, robots, beams, noise)) in
            [(8.0, 4, 8, 0.02), (40.0, 100, 8, 0.02), (12.0, 60, 7, 0.3), (30.0, 20, 8, 0.0), (6.0, 30, 5, 0.02)]
                .into_iter()
                .enumerate()
        {
            let mut config = WorldConfig::lab(&[3.0, 2.0, 1.0]);
            config.arena = [side, side];
            config.sonar_noise = noise;
            let mut new = World::new(config.clone(), robots, case as u64);
            let mut old = World::new(config, robots, case as u64);
            for _ in 0..50 {
                for world in [&mut new, &mut old] {
                    // The same poses in both, anywhere (walls, overlaps and corners included).
                    let mut poses = place.clone();
                    for r in &mut world.robots {
                        r.pose = Pose { x: poses.f64() * side, y: poses.f64() * side, theta: wrap(poses.f64() * TAU) };
                    }
                    world.index();
                }
                place.f64();
                for i in 0..robots {
                    let (mut a, mut b) = (vec![0.0; beams], vec![0.0; beams]);
                    new.sonar(i, &mut a);
                    sonar_as_before(&mut old, i, &mut b);
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&a), bits(&b), "case {case}, robot {i}");
                    skipped += a.iter().filter(|&&r| r == new.config.sonar_range).count();
                }
                assert_eq!(new.noise_rng.u64(..), old.noise_rng.u64(..), "the noise stream moved alike");
            }
        }
        assert!(skipped > 1000, "saturated beams were tested: {skipped}");
    }

    #[test]
    fn the_grid_lists_neighbours_cell_by_cell_in_index_order() {
        let mut rng = fastrand::Rng::with_seed(3);
        for (side, n) in [(8.0, 5), (40.0, 100), (20.0, 300), (2.0, 7)] {
            let mut grid = Grid::new([side, side], 3.0);
            let robots: Vec<Robot> = (0..n)
                .map(|_| Robot {
                    pose: Pose { x: (rng.f64() * 1.2 - 0.1) * side, y: (rng.f64() * 1.2 - 0.1) * side, theta: 0.0 },
                    alive: true,
                })
                .collect();
            grid.fill_robots(&robots);
            for _ in 0..200 {
                let (x, y) = ((rng.f64() * 1.2 - 0.1) * side, (rng.f64() * 1.2 - 0.1) * side);
                let mut got = Vec::new();
                grid.near(x, y, |j| got.push(j));
                // As the grid of one list per cell gave them: 3 x 3 cells row-major, each
                // cell's robots in increasing index.
                let (c, r) = grid.cell_of(x, y);
                let mut want = Vec::new();
                for row in r.saturating_sub(1)..=(r + 1).min(grid.rows - 1) {
                    for col in c.saturating_sub(1)..=(c + 1).min(grid.cols - 1) {
                        want.extend((0..n).filter(|&j| grid.cell_of(robots[j].pose.x, robots[j].pose.y) == (col, row)));
                    }
                }
                assert_eq!(got, want);
            }
        }
    }

    #[test]
    fn a_cell_is_the_one_the_saturating_cast_gave() {
        let grid = Grid::new([40.0, 25.0], 3.0);
        let as_before = |x: f64, y: f64| {
            (
                ((x / grid.cell).max(0.0) as usize).min(grid.cols - 1),
                ((y / grid.cell).max(0.0) as usize).min(grid.rows - 1),
            )
        };
        let mut rng = fastrand::Rng::with_seed(9);
        let edges = [0.0, -0.0, -1.0, 2.999999999, 3.0, 3.0000001, 38.9999, 39.0, 42.0, 1e300, -1e300];
        let special = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, f64::MAX, f64::MIN_POSITIVE];
        let random = (0..10_000).map(|_| rng.f64() * 60.0 - 10.0);
        let xs: Vec<f64> = edges.into_iter().chain(special).chain(random).collect();
        for (k, &x) in xs.iter().enumerate() {
            let y = xs[(k * 7 + 3) % xs.len()];
            assert_eq!(grid.cell_of(x, y), as_before(x, y), "({x}, {y})");
        }
    }

    #[test]
    fn surely_beyond_is_beyond() {
        let mut rng = fastrand::Rng::with_seed(13);
        let radii = [0.45, 0.5, 2.0, 5.0, 1e-300, 1e300];
        for _ in 0..200_000 {
            let r = radii[rng.usize(..radii.len())];
            // Around the radius, where rounding decides.
            let dx = r * (1.0 + (rng.f64() - 0.5) * 1e-8) * if rng.bool() { 1.0 } else { -1.0 };
            let dy = r * (rng.f64() - 0.5) * if rng.bool() { 1e-9 } else { 2.0 };
            for (a, b) in [(dx, dy), (dy, dx)] {
                if surely_beyond(a, b, r) {
                    assert!(dist(a, b) > r, "({a:e}, {b:e}) against {r:e}");
                    assert!(r - dist(a, b) <= 0.0);
                }
            }
        }
        assert!(!surely_beyond(f64::NAN, 0.0, 1.0) && !surely_beyond(0.0, f64::NAN, 1.0));
    }

    #[test]
    fn no_gaussian_draw_exceeds_the_bound() {
        let largest = (-2.0 * f64::MIN_POSITIVE.ln()).sqrt();
        assert!(largest < GAUSS_BOUND, "{largest}");
    }

    #[test]
    fn an_echo_is_the_ray_circle_hit() {
        // Straight ahead at 2 m, radius 0.5: hit at 1.5; behind: no hit; beside: no hit.
        let e = Echo::new(0.0, 0.0, 2.0, 0.0, 0.5);
        assert_eq!(e.hit(1.0, 0.0), Some(1.5));
        assert_eq!(e.hit(-1.0, 0.0), None);
        assert_eq!(e.hit(0.0, 1.0), None);
    }

    #[test]
    fn the_branch_free_echo_gives_the_same_bits() {
        let mut rng = fastrand::Rng::with_seed(13);
        for k in 0..200_000 {
            // Origins inside, on and outside the circle; rays touching it; tiny radii.
            let (cx, cy) = (rng.f64() * 4.0 - 2.0, rng.f64() * 4.0 - 2.0);
            let r = if k % 7 == 0 { 0.0 } else { rng.f64() * 2.0 };
            let e = Echo::new(0.0, 0.0, cx, cy, r);
            let a = if k % 5 == 0 { cy.atan2(cx) } else { rng.f64() * TAU };
            let (dy, dx) = a.sin_cos();
            let want = e.hit(dx, dy).unwrap_or(f64::INFINITY);
            assert_eq!(e.hit_or_infinity(dx, dy).to_bits(), want.to_bits(), "{cx} {cy} {r} {a}");
        }
    }
}
