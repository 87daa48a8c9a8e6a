//! One robot's turn in a tick, its visit: its deliveries, senses, node run and motors; and how
//! a tick's visits are shared out among threads and, in a large team, loaded ahead.
//!
//! Promise: a visit reads only the tick's shared state ([`Tick`]) and writes only its own
//! robot's node, command, drive and outbox, so the visits of a tick may be grouped in any
//! blocks on any number of threads and made in either order, and loading ahead is a hint:
//! none of these changes an outcome.

use ayllu_core::{Error, Instant, NodeCore, Outgoing, PortRef, Value};

use crate::body::Body;
use crate::controller::{chain_quiet, Brain};
use crate::radio::Radio;
use crate::world::{wrap, Command, SonarScratch, World};

/// The smallest team whose robots' messages are loaded ahead of their visits (`Sim::step`),
/// the planner's base station not counted. Measured on a 2-vCPU EPYC (1 MiB L2 per core,
/// 32 MiB L3): the hints saved 19-23 % of the user time of a 1000-robot run, were even at
/// 300 robots and cost 7 % at 100, whose nodes stay in cache (docs/performance.md, issue
/// 13's fifth pass).
pub(super) const LOOK_AHEAD_TEAM: usize = 300;

/// The first stage of loading robot `i`'s messages ahead of its visit (see `Sim::step`): the
/// sequence-table slots they look up. Hints only.
fn load_slots(radio: &Radio, robots: &[RobotNode], base: usize, k: usize) {
    if let Some(r) = robots.get(k) {
        radio.deliver_due(base + k, |from, m| r.core.prefetch_receive(from, m));
    }
}

/// The second stage, once the slots are in: the ports they name. Hints only.
fn load_ports(radio: &Radio, robots: &[RobotNode], base: usize, k: usize) {
    if let Some(r) = robots.get(k) {
        radio.deliver_due(base + k, |from, m| r.core.prefetch_target(from, m));
    }
}

/// Robots a thread takes at the least: below this a share's visits are a few microseconds,
/// no more than handing them to a worker and waiting for it (crate::workers), so a smaller
/// team runs on fewer threads, down to one. Measured: 100 robots on two threads ran 1.4-1.8x
/// faster than on one (docs/performance.md, eighth pass).
pub(super) const ROBOTS_PER_THREAD: usize = 50;

/// Robots a thread visits in turn before it takes the next block of a tick ([`Sim::set_threads`]):
/// small enough that a thread slowed by the machine leaves most of its work to the others,
/// large enough that a block's first two robots, whose messages were not loaded ahead
/// ([`LOOK_AHEAD_TEAM`]), are few.
pub(super) const BLOCK: usize = 25;

/// How many threads visit a team of `robots` when [`Sim::set_threads`] allows `allowed`.
pub(super) fn visit_threads(allowed: usize, robots: usize) -> usize {
    allowed.min(robots / ROBOTS_PER_THREAD).max(1)
}

/// What every visit of one tick reads, shared by the threads that visit.
pub(super) struct Tick<'a> {
    pub(super) now: Instant,
    pub(super) radio: &'a Radio,
    pub(super) world: &'a World,
    /// Centralized: the oracle's assignment per robot.
    pub(super) assignment: &'a [Option<usize>],
    /// Whether the bodies observed this tick (their senses are written in the visit).
    pub(super) sense: bool,
    /// BLE and Local: a bare observer chain (see the drives below).
    pub(super) chain_only: bool,
    pub(super) centralized: bool,
    /// Whether any robot's brain takes its pose (Planner, BLE-seek; see [`visit`]).
    pub(super) localize: bool,
    /// Load each robot's messages ahead of its visit ([`LOOK_AHEAD_TEAM`]).
    pub(super) ahead: bool,
    /// Visit the robots from the last to the first (see [`visit`]).
    pub(super) backward: bool,
}

/// Visit robots `base..base + robots.len()` in turn (from the last to the first if
/// `tick.backward`): each one's deliveries, its sonar sweep (`sweep` for room) and senses, the
/// oracle's word (Centralized), pose (Planner), its node's run, then its motors. Its outgoing
/// messages go to `outbox` (robot index first) for the radio, in robot order either way. In a
/// large team, what a robot's messages will touch in its node loads ahead of its visit, in two
/// stages, so that the loads of each stage overlap one another and the visits between: two
/// visits ahead, the sequence-table slots its messages look up; one visit ahead, the ports
/// those slots name (by then the slots are in cache). A small team's nodes stay in cache from
/// tick to tick: there the hints would only cost.
pub(super) fn visit(
    tick: &Tick<'_>,
    base: usize,
    robots: &mut [RobotNode],
    commands: &mut [Command],
    drives: &mut [u32],
    outbox: &mut Vec<(usize, Outgoing)>,
    sweep: &mut SonarScratch,
) -> Result<(), Error> {
    let radio = tick.radio;
    let n = robots.len();
    // The robot visited `j`-th, if there is one.
    let nth = |j: usize| (j < n).then(|| if tick.backward { n - 1 - j } else { j });
    let first_out = outbox.len();
    if tick.ahead {
        for j in [0, 1] {
            if let Some(k) = nth(j) {
                load_slots(radio, robots, base, k);
            }
        }
        if let Some(k) = nth(0) {
            load_ports(radio, robots, base, k);
        }
    }
    // Backward, the visits go on past an error so that the one returned is the first in robot
    // order, as a forward walk (or the threads, block by block) returns it.
    let mut failed = None;
    for j in 0..n {
        let k = nth(j).expect("j < n");
        if tick.ahead {
            if let Some(k2) = nth(j + 2) {
                load_slots(radio, robots, base, k2);
            }
            if let Some(k1) = nth(j + 1) {
                load_ports(radio, robots, base, k1);
            }
        }
        match visit_one(tick, base, k, &mut robots[k], &mut commands[k], &mut drives[k], outbox, sweep) {
            Ok(()) => {}
            Err(e) if tick.backward => failed = Some(e),
            Err(e) => return Err(e),
        }
    }
    if tick.backward {
        // The radio takes the messages in robot order, each robot's in its own order: the
        // robots' runs were pushed last first, so reverse the whole, then each robot's run.
        let sent = &mut outbox[first_out..];
        sent.reverse();
        for run in sent.chunk_by_mut(|a, b| a.0 == b.0) {
            run.reverse();
        }
    }
    failed.map_or(Ok(()), Err)
}

/// The visit of robot `base + k` (see [`visit`]).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn visit_one(
    tick: &Tick<'_>,
    base: usize,
    k: usize,
    r: &mut RobotNode,
    command: &mut Command,
    drive: &mut u32,
    outbox: &mut Vec<(usize, Outgoing)>,
    sweep: &mut SonarScratch,
) -> Result<(), Error> {
    let (now, radio) = (tick.now, tick.radio);
    let i = base + k;
    let alive = tick.world.robots[i].alive;
    if !alive {
        return Ok(());
    }
    // A broadcast reaches its receivers as one shared message: nothing copied. The node takes
    // its messages in one call, each one's sequence-table slot loading while the one before
    // is applied.
    r.core.receive_all_shared(now, &mut radio.due(i));
    if tick.sense {
        r.body.write_senses(&mut r.core, now, tick.world, i, sweep)?;
        // Only a team with localizing brains reads them here (a brain is a line of its own).
        if let (true, Brain::Follow { pose, .. } | Brain::Seek { pose, .. }) = (tick.localize, &r.brain) {
            // Localization: the robot knows where it is (as odometry on a map would).
            let p = tick.world.robots[i].pose;
            r.core.write(now, *pose, Value::vector(&[p.x, p.y, p.theta]))?;
        }
    }
    if tick.centralized {
        steer(tick, i, r)?;
    }
    // The next tick comes at its time whatever is due: no `poll_at` scan.
    r.core.run_due(now);
    while let Some(out) = r.core.pop_outgoing() {
        outbox.push((i, out));
    }
    *command = r.body.command(&r.core);
    // Ble and Local build a bare chain: a robot that saw no target lately has no driver,
    // and neither its brain nor its ports need reading.
    *drive = if tick.chain_only && chain_quiet(now, r.body.latest_seen()) {
        0
    } else {
        r.brain.drive_seen(&r.core, r.body.seen())
    };
    Ok(())
}

/// The oracle's word to live robot `i` this tick (see [`Sim::plan`]).
fn steer(tick: &Tick<'_>, i: usize, r: &mut RobotNode) -> Result<(), Error> {
    let w = tick.world;
    let (Some(j), Brain::Oracle { angle, assigned }) = (tick.assignment[i], &r.brain) else { return Ok(()) };
    let p = w.robots[i].pose;
    let t = &w.targets[j];
    let bearing = wrap((t.y - p.y).atan2(t.x - p.x) - p.theta);
    let (angle, assigned): (PortRef, PortRef) = (*angle, *assigned);
    r.core.write(tick.now, angle, -bearing)?;
    r.core.write(tick.now, assigned, j as i64 + 1)?;
    Ok(())
}

// In declaration order (`repr(C)`): the node is a whole number of cache lines, so the body's
// every-tick fields (`Body`'s first 64 bytes) start a line of their own.
#[repr(C)]
pub(super) struct RobotNode {
    pub(super) core: NodeCore,
    pub(super) body: Body,
    pub(super) brain: Brain,
}
