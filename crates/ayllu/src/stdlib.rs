//! The standard behavior library (the paper's `ayllustd.h`), as far as the core needs it:
//! a vision stand-in, a base (motors), a wander behavior, the target observer of Fig. 2, and
//! [`make_observer`] / [`cross_subsumption`] — the paper's `MakeObserver` macro and `main`.
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

/// `Base`: the motors. `Rotate` (rad/s) is what finally turns the robot.
pub fn base_class() -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Base");
    c.port(PortSpec::new("Rotate", 0.0))?;
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

/// `Observer` (Fig. 2's `ObserveTarget`): at 20 Hz, if its target is in view, turn towards it
/// (`Rotate = -TargetX`) and offer the apparent height as BLE eligibility (`Local`).
pub fn observer_class() -> Result<BehaviorClass, Error> {
    let mut c = BehaviorClass::new("Observer");
    let x = c.port(PortSpec::new("TargetX", 0.0).lifespan(VISION_LIFESPAN))?;
    let y = c.port(PortSpec::new("TargetY", 0.0).lifespan(VISION_LIFESPAN))?;
    let rotate = c.port(PortSpec::new("Rotate", 0.0))?;
    c.every_hz("TurnToTarget", 20.0, move |ctx| {
        // Errata: no output when the target is not seen.
        if let (Some(bearing), Some(height)) = (ctx.float(x), ctx.float(y)) {
            let _ = ctx.write(rotate, -bearing);
            let _ = ctx.write(Port::LOCAL, height);
        }
    })?;
    Ok(c)
}

/// The paper's `MakeObserver(num, next)`: create `OBS{num}`, feed it target `num` from
/// VISION, let its `Rotate` override `next.Rotate` (subsumption), and join the layer's BLE
/// group (cross-inhibition) with `ble` (whose `output` must be `Rotate`).
pub fn make_observer(node: &mut NodeCore, num: u32, next: &str, ble: &BleConfig) -> Result<BleGroup, Error> {
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
    node.ble_join(&name, ble)
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
