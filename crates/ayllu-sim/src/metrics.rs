//! The task's figures of merit, computed online from the world's ground truth each tick.
//!
//! Formulas (docs/cmommt.md): over ticks t of length dt, T = total time, m targets with
//! priorities w_j, o_j(t) = 1 if some live robot observes target j (in its field of view,
//! within the observe range), n_j(t) = how many do.
//! * A = (1/T) Σ_t dt Σ_j o_j(t) (Parker's average number of targets observed); A/m = A / m.
//! * A_w = (1/T) Σ_t dt Σ_j w_j o_j(t) / Σ_j w_j (priority-weighted fraction, 0..1).
//! * top-k = (1/T) Σ_t dt (1/k) Σ_{j ≤ k} o_j(t), with k = min(robots, m) and targets sorted by
//!   priority: how well the targets a perfect team could always cover are covered. It is
//!   against the *starting* team; top-k alive uses k(t) = min(live robots, m) instead, so a team
//!   that lost robots is judged against what it still could cover.
//! * redundant = (1/T) Σ_t dt Σ_j max(0, n_j(t) - 1): robot-observations beyond the first.
//! * switches/min: changes of the target driving each robot (including to and from none), per
//!   live robot per minute.
//! * recover: for each target observed by a robot when it is killed, the time until another
//!   robot observes it; the mean over such targets (None when no kill, or nothing to re-cover;
//!   a target never re-covered counts as the time left in the run). Robots killed at the same
//!   instant are all dead before their lost targets are judged, so one doomed robot does not
//!   count as re-covering another's target, and a target they shared is one task.
//! * msgs/robot/s: radio messages sent (one per destination node, a broadcast counts once per
//!   sender) per robot per second; bytes/robot/s: their encoded size (the udp:// wire format).

use serde::{Deserialize, Serialize};

/// The figures of merit of one run (or a cell's means), as defined in the module docs.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// A, Parker's average number of targets observed (0..=m; docs/cmommt.md).
    pub a: f64,
    /// A / m: the same as a fraction of the targets (0..=1).
    pub a_per_m: f64,
    /// A_w, the priority-weighted fraction of targets observed (0..=1; docs/cmommt.md).
    pub a_w: f64,
    /// top-k: time-averaged fraction of the k highest-priority targets observed (0..=1), with
    /// k = min(robots at the start, m).
    pub top_k: f64,
    /// The k of top-k: min(robots at the start, targets).
    pub k: u32,
    /// top-k against the robots alive at each instant (k(t) = min(live robots, m)).
    #[serde(default)]
    pub top_k_alive: f64,
    /// Observations beyond the first, summed over the targets and averaged over time.
    pub redundant: f64,
    /// Changes of the target driving a robot (to or from none too), per live robot per minute
    /// of virtual time.
    pub switches_per_min: f64,
    /// Mean virtual seconds from a kill until another robot observes each target lost with it
    /// (module docs); `None`: no kill, or nothing to re-cover.
    pub recover_s: Option<f64>,
    /// Tasks lost to a kill and never re-covered before the end (counted in `recover_s` as
    /// the time left).
    pub unrecovered: u32,
    /// Radio emissions per robot per second of virtual time (a broadcast counts once per
    /// sender; Centralized: one per assigned robot per second).
    pub msgs_per_robot_s: f64,
    /// Their encoded size, bytes per robot per second ([`crate::radio::wire_len`]; the
    /// omniscient planner's words are no radio messages and weigh nothing).
    #[serde(default)]
    pub bytes_per_robot_s: f64,
}

use crate::world::World;

/// Accumulates the metrics tick by tick from the world's ground truth.
pub struct Meter {
    /// Priorities by target index (target id - 1), non-increasing.
    priorities: Vec<f64>,
    k: usize,
    time: f64,
    a: f64,
    a_w: f64,
    top_k: f64,
    top_k_alive: f64,
    redundant: f64,
    switches: u64,
    live_robot_time: f64,
    last_drive: Vec<u32>,
    /// (target index, time of the kill) not yet re-covered.
    pending: Vec<(usize, f64)>,
    recovered: Vec<f64>,
    /// Scratch: observers per target this tick.
    count: Vec<u32>,
}

impl Meter {
    /// A meter for targets of `priorities` (non-increasing) and a team of `robots`.
    pub fn new(priorities: &[f64], robots: usize) -> Meter {
        Meter {
            priorities: priorities.to_vec(),
            k: robots.min(priorities.len()),
            time: 0.0,
            a: 0.0,
            a_w: 0.0,
            top_k: 0.0,
            top_k_alive: 0.0,
            redundant: 0.0,
            switches: 0,
            live_robot_time: 0.0,
            last_drive: vec![0; robots],
            pending: Vec::new(),
            recovered: Vec::new(),
            count: vec![0; priorities.len()],
        }
    }

    /// How many live robots observe each target now (noise-free), into the scratch counts.
    fn count(&mut self, world: &World) {
        self.count.iter_mut().for_each(|c| *c = 0);
        let range = world.config.observe_range;
        for (i, r) in world.robots.iter().enumerate() {
            if r.alive {
                let count = &mut self.count;
                world.in_view(i, range, |j, _, _| count[j] += 1);
            }
        }
    }

    /// Account one tick of `dt` seconds ending at `now` (s); `drives[i]` is the target driving
    /// robot i. Returns (targets observed, priority-weighted fraction observed).
    pub fn observe(&mut self, now: f64, dt: f64, world: &World, drives: &[u32]) -> (u32, f64) {
        self.count(world);
        let total_w: f64 = self.priorities.iter().sum();
        let alive = world.robots.iter().filter(|r| r.alive).count();
        let k_alive = alive.min(self.priorities.len());
        let mut observed = 0u32;
        let mut weighted = 0.0;
        let (mut top, mut top_alive) = (0u32, 0u32);
        let mut redundant = 0u32;
        for (j, &c) in self.count.iter().enumerate() {
            if c > 0 {
                observed += 1;
                weighted += self.priorities[j];
                if j < self.k {
                    top += 1;
                }
                if j < k_alive {
                    top_alive += 1;
                }
                redundant += c - 1;
            }
        }
        let weighted = if total_w > 0.0 { weighted / total_w } else { 0.0 };
        self.time += dt;
        self.a += dt * f64::from(observed);
        self.a_w += dt * weighted;
        if self.k > 0 {
            self.top_k += dt * f64::from(top) / self.k as f64;
        }
        if k_alive > 0 {
            self.top_k_alive += dt * f64::from(top_alive) / k_alive as f64;
        }
        self.redundant += dt * f64::from(redundant);
        for (i, r) in world.robots.iter().enumerate() {
            if r.alive {
                self.live_robot_time += dt;
                if drives[i] != self.last_drive[i] {
                    self.switches += 1;
                    self.last_drive[i] = drives[i];
                }
            }
        }
        let count = &self.count;
        let recovered = &mut self.recovered;
        self.pending.retain(|&(j, since)| {
            if count[j] > 0 {
                recovered.push(now - since);
                false
            } else {
                true
            }
        });
        (observed, weighted)
    }

    /// Robot `i` was just killed (already marked dead in `world`): every target it observed
    /// that no other robot observes is a task to re-cover.
    pub fn killed(&mut self, now: f64, world: &World, i: usize) {
        self.killed_together(now, world, &[i]);
    }

    /// Robots `killed` died at the same instant (all already marked dead in `world`): every
    /// target one of them observed is one task; it is re-covered at once if a live robot
    /// observes it, else pending until one does.
    pub fn killed_together(&mut self, now: f64, world: &World, killed: &[usize]) {
        self.count(world);
        let range = world.config.observe_range;
        let mut lost = Vec::new();
        for &i in killed {
            world.in_view(i, range, |j, _, _| lost.push(j));
        }
        lost.sort_unstable();
        lost.dedup();
        for j in lost {
            if self.pending.iter().any(|&(p, _)| p == j) {
                continue; // already lost to an earlier kill, still pending
            }
            if self.count[j] == 0 {
                self.pending.push((j, now));
            } else {
                self.recovered.push(0.0);
            }
        }
    }

    /// The metrics of the whole run; `messages` radio emissions of `bytes` bytes in all by
    /// `robots` robots.
    pub fn finish(mut self, end: f64, robots: usize, messages: u64, bytes: u64) -> Metrics {
        let unrecovered = self.pending.len() as u32;
        for (_, since) in self.pending.drain(..) {
            self.recovered.push(end - since);
        }
        let t = self.time.max(f64::MIN_POSITIVE);
        let m = self.priorities.len().max(1) as f64;
        Metrics {
            a: self.a / t,
            a_per_m: self.a / t / m,
            a_w: self.a_w / t,
            top_k: self.top_k / t,
            k: self.k as u32,
            top_k_alive: self.top_k_alive / t,
            redundant: self.redundant / t,
            switches_per_min: if self.live_robot_time > 0.0 {
                self.switches as f64 / (self.live_robot_time / 60.0)
            } else {
                0.0
            },
            recover_s: (!self.recovered.is_empty())
                .then(|| self.recovered.iter().sum::<f64>() / self.recovered.len() as f64),
            unrecovered,
            msgs_per_robot_s: messages as f64 / robots.max(1) as f64 / t,
            bytes_per_robot_s: bytes as f64 / robots.max(1) as f64 / t,
        }
    }
}
