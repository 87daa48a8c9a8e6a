//! A robot's body as behaviors with ports — the simulator's stand-in for the paper's
//! `ayInitPioControl`. The body is three behaviors on the robot's node, with the stdlib's
//! interface: `VISION` (`Target{n}Angle`, `Target{n}Bottom`), `SONAR` (`Ranges`) and `BASE`
//! (`Rotate`, `Translate`). The simulator writes the sensor ports and reads the motor ports,
//! exactly as a robot driver would; a controller connects to them by name and cannot tell the
//! difference.
//!
//! Promise: a frame in which a target is not seen writes nothing for it, so its ports go
//! stale after the stdlib's lifespan (the observer then stays silent, rule S4).

use ayllu::stdlib::{base_class, sonar_class, vision_class, BASE, SONAR, VISION};
use ayllu_core::{Error, Instant, NodeCore, PortRef, Value};

use crate::classes::SharedClasses;
use crate::world::{Command, Sighting, SonarScratch, World, WorldConfig};

/// The port handles of one robot's body on its node.
// In declaration order (`repr(C)`): what every tick reads (the motor ports' handles and
// `latest`) first, with the sonar's handle, in 64 bytes, so that a tick that does not sense
// reads one line of the body, which a simulator's visit (`RobotNode`) places at the start of
// a line; what only a sensing tick reads after it.
#[repr(C)]
pub struct Body {
    rotate: PortRef,
    translate: PortRef,
    /// The latest of `seen`, kept beside the port handles that every tick reads: most ticks
    /// it alone says that no observer layer can drive.
    latest: Option<Instant>,
    ranges: PortRef,
    vision: Vec<(PortRef, PortRef)>,
    sightings: Vec<Sighting>,
    /// The sonar's beams.
    beams: usize,
    /// Where the noise stream stood when [`Body::observe`] moved it past this sweep's draws
    /// ([`World::skip_sonar_draws`]): the draws themselves, and the sweep's ranges, are made
    /// in the visit ([`World::sonar_from`]), in the visiting thread's room (`SonarScratch`), so that a sensing tick
    /// writes no per-robot buffer that the next one would find evicted at 1000 robots.
    noise: u64,
    /// When this body last wrote each target's VISION ports (`None`: never).
    seen: Vec<Option<Instant>>,
}

// What every tick reads fills the first line exactly (see the layout note above).
const _: () = assert!(std::mem::offset_of!(Body, vision) == 64);

impl Body {
    /// Define and create VISION, SONAR and BASE on `core` for `targets` targets.
    pub fn install(core: &mut NodeCore, targets: usize, world: &WorldConfig) -> Result<Body, Error> {
        Body::install_shared(core, targets, world, &mut SharedClasses::new())
    }

    /// [`Body::install`] with the body's classes taken from (or built into) `classes`, so that
    /// the robots of one scenario share them (crate::classes).
    pub fn install_shared(
        core: &mut NodeCore,
        targets: usize,
        world: &WorldConfig,
        classes: &mut SharedClasses,
    ) -> Result<Body, Error> {
        classes.define(core, "Vision", || vision_class(targets as u32))?;
        classes.define(core, "Sonar", || sonar_class(world.sonar_beams, world.sonar_range))?;
        classes.define(core, "Base", base_class)?;
        core.create("Vision", VISION)?;
        core.create("Sonar", SONAR)?;
        core.create("Base", BASE)?;
        Body::attach(core, targets, world.sonar_beams)
    }

    /// Handles to a body that already exists on `core`.
    pub fn attach(core: &NodeCore, targets: usize, beams: usize) -> Result<Body, Error> {
        let vision = (1..=targets)
            .map(|n| {
                Ok((core.port(VISION, &format!("Target{n}Angle"))?, core.port(VISION, &format!("Target{n}Bottom"))?))
            })
            .collect::<Result<_, Error>>()?;
        Ok(Body {
            vision,
            ranges: core.port(SONAR, "Ranges")?,
            rotate: core.port(BASE, "Rotate")?,
            translate: core.port(BASE, "Translate")?,
            sightings: Vec::new(),
            beams,
            noise: 0,
            seen: vec![None; targets],
            latest: None,
        })
    }

    /// Take one camera frame and one sonar sweep of robot `i` and write them to the ports.
    pub fn sense(&mut self, core: &mut NodeCore, now: Instant, world: &mut World, i: usize) -> Result<(), Error> {
        self.observe(world, i);
        self.write_senses(core, now, world, i, &mut SonarScratch::default())
    }

    /// The first half of [`Body::sense`]: everything that draws from the world's noise
    /// stream, for robot `i`: its camera frame, and its sonar sweep's noise (the stream moved
    /// past it, and where it started kept, [`World::skip_sonar_draws`]). Touches no node,
    /// so a team's bodies can all observe in robot order (the stream's order) before any node
    /// runs, and the rest of each robot's work, sweeps included, can then run on any thread.
    pub fn observe(&mut self, world: &mut World, i: usize) {
        world.camera(i, &mut self.sightings);
        self.noise = world.skip_sonar_draws(self.beams);
    }

    /// The second half of [`Body::sense`], after [`Body::observe`]: robot `i`'s sonar sweep
    /// (with the noise that `observe` passed over, drawn again here; `scratch` for room), then
    /// the camera frame and the sweep written to the ports. Reads the world only.
    pub fn write_senses(
        &mut self,
        core: &mut NodeCore,
        now: Instant,
        world: &World,
        i: usize,
        scratch: &mut SonarScratch,
    ) -> Result<(), Error> {
        let mut ranges = std::mem::take(&mut scratch.ranges);
        ranges.resize(self.beams, 0.0);
        world.sonar_from(i, self.noise, scratch, &mut ranges);
        scratch.ranges = ranges;
        let ranges = scratch.ranges.as_slice();
        for s in &self.sightings {
            let (angle, bottom) = self.vision[s.target];
            core.write(now, angle, s.angle)?;
            core.write(now, bottom, s.height)?;
            self.seen[s.target] = Some(now);
            self.latest = Some(now);
        }
        // A sweep that heard nothing is the world's one shared value (no copy of the beams).
        match world.quiet_sweep(ranges) {
            Some(quiet) => core.write(now, self.ranges, quiet.clone())?,
            None => core.write(now, self.ranges, ranges)?,
        }
        Ok(())
    }

    /// What the controller asks of the motors now.
    pub fn command(&self, core: &NodeCore) -> Command {
        let f = |p| core.read_with(p, Value::as_float).ok().flatten().unwrap_or(0.0);
        Command { translate: f(self.translate), rotate: f(self.rotate) }
    }

    /// When this body last wrote each target's VISION ports (index: target id - 1; `None`:
    /// never), for [`crate::controller::Brain::drive_seen`].
    pub fn seen(&self) -> &[Option<Instant>] {
        &self.seen
    }

    /// When this body last wrote any target's VISION ports (the latest of [`Body::seen`]).
    pub fn latest_seen(&self) -> Option<Instant> {
        self.latest
    }

    /// The last camera frame (for the distributed server, which forwards it).
    pub fn sightings(&self) -> &[Sighting] {
        &self.sightings
    }
}
