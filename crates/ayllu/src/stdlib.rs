//! The standard behavior library (the paper's `ayllustd.h`): the body's interface (vision,
//! base, sonar — what a robot or the simulator writes and reads), safe velocity from sonar
//! (`MakeSafeVelBeh`), wander (constant and seeded random), the target observer of Fig. 2, and
//! [`make_observer`] / [`cross_subsumption`] — the paper's `MakeObserver` macro and `main`.
//!
//! Conventions shared with every body: `TargetNAngle` is the bearing in radians, positive to the
//! *right* of the camera's axis (like image x growing to the right); `Rotate` is rad/s,
//! positive to the *left* (counter-clockwise), so an observer turns with `Rotate = -angle`;
//! `Translate` is m/s forward; `Ranges` holds one sonar range (m, from the robot's rim) per
//! beam, beam k pointing `k * 2π / beams` counter-clockwise from straight ahead.
//!
//! Values follow Fig. 2 with its errata fixed (docs/semantics.md, "Fig. 2 errata"):
//! * each observer's eligibility goes to the *same* layer's `Best` on the peers (Fig. 2 sends
//!   every layer's to `OBS1`);
//! * the claim's write-inhibition outlasts the claim period (Fig. 2: 1 Hz claims, 0.5 s);
//! * an observer writes nothing when its target is not seen (its inputs have a lifespan), so
//!   lower layers take over instead of being overridden by stale output.

use ayllu_core::{
    BehaviorClass, BleConfig, BleGroup, ConnectOptions, ConnectionKind, Duration, Endpoint, Error, NodeCore, Port,
    PortSpec,
};

/// The vision behavior's name on every node.
pub const VISION: &str = "VISION";
/// The base (motor) behavior's name.
pub const BASE: &str = "BASE";
/// The wander behavior's name.
pub const WANDER: &str = "WANDER";
/// The sonar behavior's name.
pub const SONAR: &str = "SONAR";
/// The safe-velocity behavior's name (the paper's `VEL`).
pub const VEL: &str = "VEL";
/// What WANDER writes to `Rotate` (a gentle left turn, rad/s).
pub const WANDER_TURN: f64 = 0.25;
/// How long a vision reading stays fresh: a little over two frames at 10 Hz.
pub const VISION_LIFESPAN: Duration = Duration::from_millis(250);
/// The Fig. 2 subsumption period between observer layers.
pub const OVERRIDE_PERIOD: Duration = Duration::from_millis(200);

/// `VISION`: for targets `1..=targets`, ports `Target{n}Angle` (bearing, rad) and
/// `Target{n}Bottom` (apparent height, larger = closer). A body (robot or simulator) writes them
/// while the target is in view; they go stale when it is not.
pub fn vision_class(targets: u32) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Vision");
    for n in 1..=targets {
        c.port(PortSpec::new(&format!("Target{n}Angle"), 0.0).lifespan(VISION_LIFESPAN))?;
        c.port(PortSpec::new(&format!("Target{n}Bottom"), 0.0).lifespan(VISION_LIFESPAN))?;
    }
    Ok(c)
}

/// `Base`: the motors. `Rotate` (rad/s) is what finally turns the robot, `Translate` (m/s)
/// what drives it forward.
pub fn base_class() -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Base");
    c.port(PortSpec::new("Rotate", 0.0))?;
    c.port(PortSpec::new("Translate", 0.0))?;
    Ok(c)
}

/// How long a sonar reading stays fresh: a little over two sweeps at 10 Hz.
pub const SONAR_LIFESPAN: Duration = Duration::from_millis(250);

/// `Sonar`: `Ranges`, one range per beam (see the module's conventions), written by the body.
pub fn sonar_class(beams: usize, max_range: f64) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Sonar");
    c.port(PortSpec::new("Ranges", vec![max_range; beams]).lifespan(SONAR_LIFESPAN))?;
    Ok(c)
}

/// How the safe-velocity behavior slows down: full `speed` when the nearest obstacle in the
/// front sector is `slow` metres away or more, nothing at `stop` or less, linear between.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SafeVelocity {
    /// Translation speed (m/s) with a clear way ahead.
    pub speed: f64,
    /// Distance (m) at or under which the robot stops.
    pub stop: f64,
    /// Distance (m) from which the robot goes at full speed.
    pub slow: f64,
    /// Half-width of the front sector (rad) whose beams count.
    pub sector: f64,
}

impl Default for SafeVelocity {
    /// A Pioneer-like robot: 0.4 m/s, stops about a foot from what is ahead.
    fn default() -> Self {
        SafeVelocity { speed: 0.4, stop: 0.3, slow: 1.2, sector: 0.8 }
    }
}

/// `SafeVelocity` (the paper's `MakeSafeVelBeh`): at 10 Hz, reads `Ranges` (fed from SONAR) and
/// writes `Translate` from the nearest obstacle ahead. Stale or missing sonar: stop, because
/// driving blind is what a safety behavior must not do.
pub fn safe_velocity_class(cfg: SafeVelocity) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("SafeVelocity");
    let ranges = c.port(PortSpec::new("Ranges", Vec::<f64>::new()).lifespan(SONAR_LIFESPAN))?;
    let translate = c.port(PortSpec::new("Translate", 0.0))?;
    // Which beams are in the front sector depends only on how many there are: worked out for
    // the first sweep and kept beside the body, as a mask (a sweep of another length, or of
    // more than 64 beams, works them out again).
    let in_front = move |k: usize, beams: usize| {
        let a = k as f64 * (std::f64::consts::TAU / beams as f64);
        a.min(std::f64::consts::TAU - a) <= cfg.sector + 1e-9
    };
    let front_mask = std::sync::OnceLock::<(usize, u64)>::new();
    c.every_hz("SafeVel", 10.0, move |ctx| {
        let speed = match ctx.get_ref(ranges) {
            Some(ayllu_core::Value::Vector(r)) if !r.is_empty() => {
                let n = r.len();
                let mask = |n: usize| (0..n).filter(|&k| in_front(k, n)).fold(0u64, |m, k| m | 1 << k);
                let &(beams, mut front) = front_mask.get_or_init(|| (n, if n <= 64 { mask(n) } else { 0 }));
                let front = if beams == n && n <= 64 {
                    // The same beams in the same order as the filter below: the same minimum.
                    let mut nearest = f64::INFINITY;
                    while front != 0 {
                        nearest = nearest.min(r[front.trailing_zeros() as usize]);
                        front &= front - 1;
                    }
                    nearest
                } else {
                    (0..n).filter(|&k| in_front(k, n)).map(|k| r[k]).fold(f64::INFINITY, f64::min)
                };
                cfg.speed * ((front - cfg.stop) / (cfg.slow - cfg.stop)).clamp(0.0, 1.0)
            }
            _ => 0.0,
        };
        let _ = ctx.write(translate, speed);
    })?;
    Ok(c)
}

/// `RandomWander`: at `hz`, writes a turn rate to `Rotate` that changes every 1 to 4 s to a
/// new value of 0.15 to 0.6 rad/s either way — never straight, so a robot stopped by
/// SafeVelocity at a wall always turns free. Seeded from `seed` and the node id: the same
/// seed gives the same walk.
pub fn random_wander_class(hz: f64, seed: u64) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("RandomWander");
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    // The PRNG state and the current leg live in slots, so one class serves many behaviors.
    let state = c.slot("Rng", 0i64)?;
    let turn = c.slot("Turn", 0.0)?;
    let until = c.slot("Until", 0i64)?;
    c.every_hz("Wander", hz, move |ctx| {
        let now = ctx.now().as_nanos() as i64;
        let stored = ctx.slot(state);
        let mut s = match stored {
            ayllu_core::Value::Int(0) => seed ^ (u64::from(ctx.node().0).wrapping_mul(0x9E37_79B9_7F4A_7C15)),
            ayllu_core::Value::Int(x) => x as u64,
            _ => seed,
        };
        let leg_over = matches!(ctx.slot(until), ayllu_core::Value::Int(t) if now >= t);
        if leg_over {
            let mut rng = fastrand::Rng::with_seed(s);
            let w = 0.15 + 0.45 * rng.f64();
            let w = if rng.bool() { w } else { -w };
            let leg = 1_000_000_000 + rng.i64(0..3_000_000_000);
            s = rng.get_seed().max(1);
            let _ = ctx.set_slot(turn, w);
            let _ = ctx.set_slot(until, now + leg);
        }
        // Between legs the state does not change: not stored again.
        if stored != ayllu_core::Value::Int(s as i64) {
            let _ = ctx.set_slot(state, s as i64);
        }
        let w = match ctx.slot(turn) {
            ayllu_core::Value::Float(w) => w,
            _ => 0.0,
        };
        let _ = ctx.write(rotate, w);
    })?;
    Ok(c)
}

/// `Wander`: writes [`WANDER_TURN`] to `Rotate` at `hz` — the lowest layer.
pub fn wander_class(hz: f64) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Wander");
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    c.every_hz("Wander", hz, move |ctx| {
        let _ = ctx.write(rotate, WANDER_TURN);
    })?;
    Ok(c)
}

/// The avoid behavior's name.
pub const AVOID: &str = "AVOID";

/// How [`avoid_class`] turns away: when the nearest echo in the front sector is under `near`
/// metres, turn at `turn` rad/s towards the side with more room.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Avoid {
    /// Distance (m, from the rim) under which an echo ahead makes the robot turn away.
    pub near: f64,
    /// Turn rate (rad/s) while avoiding.
    pub turn: f64,
    /// Half-width of the front sector (rad) whose beams count.
    pub sector: f64,
}

impl Default for Avoid {
    /// Turns before [`SafeVelocity::default`] stops the robot (0.3 m), so a robot heading for
    /// a wall turns while it slows.
    fn default() -> Self {
        Avoid { near: 0.6, turn: 0.8, sector: 0.8 }
    }
}

/// `Avoid`: at 10 Hz, reads `Ranges` (fed from SONAR); when something is nearer than
/// `near` in the front sector, writes a turn away from it to `Rotate` (the side whose nearest
/// echo is farther wins; straight ahead turns left). Writes nothing when the way is clear, so
/// the layer it overrides takes over again once its override window ends. Stale sonar: nothing
/// (SafeVelocity already stops the robot).
pub fn avoid_class(cfg: Avoid) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Avoid");
    let ranges = c.port(PortSpec::new("Ranges", Vec::<f64>::new()).lifespan(SONAR_LIFESPAN))?;
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    c.every_hz("Avoid", 10.0, move |ctx| {
        let Some(ayllu_core::Value::Vector(r)) = ctx.get_ref(ranges) else { return };
        let n = r.len();
        let (mut left, mut right, mut ahead) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for (k, &d) in r.iter().enumerate() {
            // Beam k points k * 2π / n counter-clockwise: angles in (0, π) are on the left.
            let a = k as f64 * (std::f64::consts::TAU / n as f64);
            let off = a.min(std::f64::consts::TAU - a);
            if off > cfg.sector + 1e-9 {
                continue;
            }
            ahead = ahead.min(d);
            if a > 1e-9 && a < std::f64::consts::PI {
                left = left.min(d);
            } else if a > std::f64::consts::PI {
                right = right.min(d);
            }
        }
        if ahead < cfg.near {
            let w = if left >= right { cfg.turn } else { -cfg.turn };
            let _ = ctx.write(rotate, w);
        }
    })?;
    Ok(c)
}

/// The classic three-layer subsumption controller on a body (SONAR and BASE already on `node`):
/// `VEL` ([`safe_velocity_class`]) drives `BASE.Translate` from the sonar; `WANDER`
/// ([`random_wander_class`], seeded by `seed`) turns `BASE.Rotate`; `AVOID` ([`avoid_class`])
/// overrides `BASE.Rotate` ([`ConnectionKind::OverrideIn`], [`OVERRIDE_PERIOD`]) while
/// something is close ahead. What `ayllu node --controller wander` runs, on any body.
pub fn wander_avoid(node: &mut NodeCore, seed: u64) -> Result<(), Error> {
    node.define(safe_velocity_class(SafeVelocity::default())?)?;
    node.define(random_wander_class(10.0, seed)?)?;
    node.define(avoid_class(Avoid::default())?)?;
    node.create("SafeVelocity", VEL)?;
    node.create("RandomWander", WANDER)?;
    node.create("Avoid", AVOID)?;
    let wire = |node: &mut NodeCore, (sb, sp): (&str, &str), (db, dp): (&str, &str), kind: ConnectionKind| {
        node.connect(&Endpoint::local(sb, sp), &Endpoint::local(db, dp), kind, ConnectOptions::default()).map(|_| ())
    };
    wire(node, (SONAR, "Ranges"), (VEL, "Ranges"), ConnectionKind::Normal)?;
    wire(node, (SONAR, "Ranges"), (AVOID, "Ranges"), ConnectionKind::Normal)?;
    wire(node, (VEL, "Translate"), (BASE, "Translate"), ConnectionKind::Normal)?;
    wire(node, (WANDER, "Rotate"), (BASE, "Rotate"), ConnectionKind::Normal)?;
    wire(node, (AVOID, "Rotate"), (BASE, "Rotate"), ConnectionKind::OverrideIn(OVERRIDE_PERIOD))?;
    Ok(())
}

/// How often an observer offers its eligibility (`Local`, which BLE broadcasts to its peers).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Eligibility {
    /// Every 20 Hz activation while the target is seen: the paper's Fig. 2 (about 20
    /// broadcasts a second per layer that sees its target).
    EveryActivation,
    /// Only when it changed by more than `threshold` (relative) since it was last offered, or
    /// `refresh` after that: far fewer broadcasts, still several per claim cycle when
    /// `refresh` is a fraction of the claim period (docs/cmommt.md, "A cheaper BLE").
    OnChange {
        /// Relative change of the apparent height that is worth a broadcast (0.1 = 10 %).
        threshold: f64,
        /// Offer it again at least this often while the target is seen.
        refresh: Duration,
    },
}

impl Eligibility {
    /// The cheaper policy measured in docs/cmommt.md ("A cheaper BLE"): a 10 % change, or every
    /// 500 ms (two offers per 1 Hz claim cycle, so one lost broadcast does not lose a claim).
    /// About 5.7x fewer messages than the paper's, A_w within its seed-to-seed spread.
    pub const LEAN: Eligibility = Eligibility::OnChange { threshold: 0.1, refresh: Duration::from_millis(500) };
}

/// `Observer` (Fig. 2's `ObserveTarget`): at 20 Hz, if its target is in view, turn towards it
/// (`Rotate = -TargetX`) and offer the apparent height as BLE eligibility (`Local`) at every
/// activation, as the paper does.
pub fn observer_class() -> Result<BehaviorClass, Error> {
    observer_class_with(Eligibility::EveryActivation)
}

/// [`observer_class`] offering its eligibility by `policy`.
pub fn observer_class_with(policy: Eligibility) -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Observer");
    let x = c.port(PortSpec::new("TargetX", 0.0).lifespan(VISION_LIFESPAN))?;
    let y = c.port(PortSpec::new("TargetY", 0.0).lifespan(VISION_LIFESPAN))?;
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    // What was last offered and when (seconds; negative: never).
    let offered = c.slot("Offered", 0.0)?;
    let offered_at = c.slot("OfferedAt", -1.0)?;
    // Errata: no output when the target is not seen. Activated only while `TargetX` is fresh
    // (D7.5): most due times do not see the target, and those are not run at all (a team of
    // a thousand robots skips about 99 of every 100 observer runs); the body still checks,
    // as the due times of a process that ran at every one would find it. `TargetY` is read
    // only once `TargetX` is fresh: each read is a cold port on a node coming back from memory.
    c.every_hz_while_fresh("TurnToTarget", 20.0, x, move |ctx| {
        if let Some(bearing) = ctx.float(x) {
            let Some(height) = ctx.float(y) else { return };
            let _ = ctx.write(rotate, -bearing);
            let offer = match policy {
                Eligibility::EveryActivation => true,
                Eligibility::OnChange { threshold, refresh } => {
                    let last = ctx.slot(offered).as_float().unwrap_or(0.0);
                    let at = ctx.slot(offered_at).as_float().unwrap_or(-1.0);
                    let now = ctx.now().as_secs_f64();
                    at < 0.0
                        || now - at >= refresh.as_secs_f64()
                        || (height - last).abs() > threshold * last.abs().max(f64::MIN_POSITIVE)
                }
            };
            if offer {
                let _ = ctx.write(Port::LOCAL, height);
                let _ = ctx.set_slot(offered, height);
                let _ = ctx.set_slot(offered_at, ctx.now().as_secs_f64());
            }
        }
    })?;
    Ok(c)
}

/// The paper's `MakeObserver(num, next)`: create `OBS{num}`, feed it target `num` from
/// VISION, let its `Rotate` override `next.Rotate` (subsumption), and join the layer's BLE
/// group (cross-inhibition) with `ble` (whose `output` must be `Rotate`).
pub fn make_observer(node: &mut NodeCore, num: u32, next: &str, ble: &BleConfig) -> Result<BleGroup, Error> {
    let name = make_observer_layer(node, num, next)?;
    node.ble_join(&name, ble)
}

/// [`make_observer`] without the BLE group: one layer of plain (local) subsumption. Returns
/// the observer's name, `OBS{num}`.
pub fn make_observer_layer(node: &mut NodeCore, num: u32, next: &str) -> Result<String, Error> {
    let name = format!("OBS{num}");
    node.create("Observer", &name)?;
    let normal = ConnectionKind::Normal;
    let opts = ConnectOptions::default();
    node.connect(
        &Endpoint::local(VISION, &format!("Target{num}Angle")),
        &Endpoint::local(&name, "TargetX"),
        normal,
        opts,
    )?;
    node.connect(
        &Endpoint::local(VISION, &format!("Target{num}Bottom")),
        &Endpoint::local(&name, "TargetY"),
        normal,
        opts,
    )?;
    node.connect(
        &Endpoint::local(&name, "Rotate"),
        &Endpoint::local(next, "Rotate"),
        ConnectionKind::OverrideOut(OVERRIDE_PERIOD),
        opts,
    )?;
    Ok(name)
}

/// The whole Fig. 2 controller on one node: VISION, BASE, WANDER, and `layers` observers in a
/// subsumption chain (`OBS1` highest) over WANDER, each cross-inhibited in group `group`.
/// Returns the BLE groups made, highest layer first.
pub fn cross_subsumption(
    node: &mut NodeCore,
    layers: u32,
    group: &str,
    claim_rate_hz: f64,
) -> Result<Vec<BleGroup>, Error> {
    node.define(vision_class(layers)?)?;
    node.define(base_class()?)?;
    node.define(wander_class(10.0)?)?;
    node.define(observer_class()?)?;
    node.create("Vision", VISION)?;
    node.create("Base", BASE)?;
    node.create("Wander", WANDER)?;
    node.connect(
        &Endpoint::local(WANDER, "Rotate"),
        &Endpoint::local(BASE, "Rotate"),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )?;
    let ble = BleConfig::new(group, "Rotate", claim_rate_hz)?;
    let mut groups = Vec::new();
    // Lowest layer first, so that each layer's `next` exists when it is made.
    for num in (1..=layers).rev() {
        let next = if num == layers { WANDER.to_owned() } else { format!("OBS{}", num + 1) };
        groups.push(make_observer(node, num, &next, &ble)?);
    }
    groups.reverse();
    Ok(groups)
}
