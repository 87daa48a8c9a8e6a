//! Connection kinds (rule S6) and the connection record a node keeps.
//!
//! Naming is deliberate: the paper's *Suppress* only blocks the destination's inputs; classic
//! Brooks "suppression" (replace an input for a while) is [`ConnectionKind::OverrideIn`]. The
//! API never uses the word "suppress" for the replacing behaviour.

use core::fmt;

use crate::address::ConnectionId;
use crate::error::Error;
use crate::time::Duration;

/// What a connection does to its destination port `d` when a message `m` arrives.
///
/// Each timed kind opens or refreshes a window on `d` for its period, measured on the node
/// that owns `d` from when the message is applied (rule S6, S8); the period must be above zero
/// ([`Error::ZeroPeriod`], D6.8).
///
/// Brooks's subsumption, a joystick overriding a planner's speed command for 1 s after each
/// stick message:
///
/// ```
/// use ayllu_core::*;
///
/// let mut node = NodeCore::new(NodeId(1));
/// for (class, port) in [("Planner", "Cmd"), ("Joystick", "Stick"), ("Motor", "Speed")] {
///     let mut c = BehaviorClass::new(class);
///     c.port(PortSpec::new(port, 0.0))?; // m/s
///     node.define(c)?;
///     node.create(class, class)?;
/// }
/// let speed = Endpoint::local("Motor", "Speed");
/// let opts = ConnectOptions::default();
/// node.connect(&Endpoint::local("Planner", "Cmd"), &speed, ConnectionKind::Normal, opts)?;
/// let hold = ConnectionKind::OverrideIn(Duration::from_secs(1));
/// node.connect(&Endpoint::local("Joystick", "Stick"), &speed, hold, opts)?;
/// let (cmd, stick, motor) =
///     (node.port("Planner", "Cmd")?, node.port("Joystick", "Stick")?, node.port("Motor", "Speed")?);
///
/// node.write(Instant::from_millis(0), cmd, 0.5)?;
/// node.write(Instant::from_millis(100), stick, 0.0)?; // operator stops the robot
/// node.write(Instant::from_millis(600), cmd, 0.7)?; // blocked: no pass until 1.1 s
/// assert_eq!(node.read(motor)?, Value::Float(0.0));
/// assert_eq!(node.why("Motor", "Speed")?.counters.get(DropCause::OverriddenIn), 1);
/// node.write(Instant::from_millis(1100), cmd, 0.8)?; // the window has closed
/// assert_eq!(node.read(motor)?, Value::Float(0.8));
/// # Ok::<(), Error>(())
/// ```
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ConnectionKind {
    /// Write `m` into `d` (unless `d` is suppressed); if accepted, propagate.
    Normal,
    /// Do not write `m`; block every connection write into `d` for the period.
    Suppress(Duration),
    /// Do not write `m`; block all propagation out of `d` for the period.
    Inhibit(Duration),
    /// Write and propagate `m`; for the period only this connection may write `d`
    /// (Brooks's suppression: the input is *replaced*).
    OverrideIn(Duration),
    /// Write and propagate `m`; for the period only values that arrive along this connection
    /// propagate out of `d`.
    OverrideOut(Duration),
    /// Do not write `m`; for the period, values written into `d` by its own behavior are stored
    /// but not propagated (values arriving through connections still are).
    WriteInhibit(Duration),
}

impl ConnectionKind {
    /// The window a timed kind opens on its destination; `None` for Normal, which opens none.
    pub fn period(self) -> Option<Duration> {
        match self {
            ConnectionKind::Normal => None,
            ConnectionKind::Suppress(p)
            | ConnectionKind::Inhibit(p)
            | ConnectionKind::OverrideIn(p)
            | ConnectionKind::OverrideOut(p)
            | ConnectionKind::WriteInhibit(p) => Some(p),
        }
    }
    /// Whether the message itself is written into the destination.
    pub fn writes(self) -> bool {
        matches!(self, ConnectionKind::Normal | ConnectionKind::OverrideIn(_) | ConnectionKind::OverrideOut(_))
    }
    /// The kind's name without its period, as reports and the CLI print it (`override-in`);
    /// [`ConnectionKind::from_name`] reads it back.
    pub fn name(self) -> &'static str {
        match self {
            ConnectionKind::Normal => "normal",
            ConnectionKind::Suppress(_) => "suppress",
            ConnectionKind::Inhibit(_) => "inhibit",
            ConnectionKind::OverrideIn(_) => "override-in",
            ConnectionKind::OverrideOut(_) => "override-out",
            ConnectionKind::WriteInhibit(_) => "write-inhibit",
        }
    }
    /// The kind named `name` (as printed by [`ConnectionKind::name`]) with `period`.
    pub fn from_name(name: &str, period: Duration) -> Option<ConnectionKind> {
        Some(match name {
            "normal" => ConnectionKind::Normal,
            "suppress" => ConnectionKind::Suppress(period),
            "inhibit" => ConnectionKind::Inhibit(period),
            "override-in" | "override_in" => ConnectionKind::OverrideIn(period),
            "override-out" | "override_out" => ConnectionKind::OverrideOut(period),
            "write-inhibit" | "write_inhibit" => ConnectionKind::WriteInhibit(period),
            _ => return None,
        })
    }

    /// A kind from its name and its period as the APIs take them (C, Python): the one place
    /// that decides a Normal connection takes no period (the paper leaves `p` unspecified for
    /// it: a period there is a mistake, refused rather than ignored) and that every other kind
    /// needs one (above zero: checked where the connection is made, [`Error::ZeroPeriod`]).
    pub fn from_parts(name: &str, period: Option<Duration>) -> Result<ConnectionKind, Error> {
        match (name, period) {
            ("normal", None) => Ok(ConnectionKind::Normal),
            ("normal", Some(p)) => Err(Error::PeriodOnNormal { seconds: p.as_secs_f64() }),
            (_, p) => ConnectionKind::from_name(name, p.unwrap_or(Duration::ZERO))
                .ok_or_else(|| Error::UnknownConnectionKind { name: name.to_owned() }),
        }
    }
}

impl fmt::Display for ConnectionKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.period() {
            None => f.write_str(self.name()),
            Some(p) => write!(f, "{}({p})", self.name()),
        }
    }
}

/// Options for making a connection beyond source, destination and kind.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub struct ConnectOptions {
    /// The priority of this connection's messages at a Priority port.
    pub priority: i32,
}

/// Summary of a connection for listing and introspection.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ConnectionInfo {
    /// Unique on the node that owns the connection, never reused.
    pub id: ConnectionId,
    /// The port values come from: always on the owning node.
    pub source: crate::address::Endpoint,
    /// Where they go: a local port, a port on a named node, or a group.
    pub destination: crate::address::Endpoint,
    /// What the connection does at the destination, with its period (rule S6).
    pub kind: ConnectionKind,
    /// The priority of its messages at a Priority port (D3.3); 0 by default.
    pub priority: i32,
    /// Messages sent along this connection so far.
    pub sent: u64,
    /// The node whose request created it: the connection lasts as long as that node is alive
    /// (D9.1). `None` for connections made on this node.
    #[cfg_attr(feature = "serde", serde(default))]
    pub requested_by: Option<crate::address::NodeId>,
}
