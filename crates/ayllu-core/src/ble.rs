//! Broadcast of Local Eligibility (rule S11, paper §4.1): cross-inhibition of peer behaviors.
//!
//! [`NodeCore::ble_join`] is the one call that makes a behavior take part in a BLE group:
//! * its `Local` port is broadcast (Normal) to the peers' `Best` ports (Max);
//! * its `Inhibit` port is broadcast as a WriteInhibit of the peers' output port;
//! * a select process runs at the claim rate: if `Local` was written during the last cycle and
//!   beats `Best` (ties go to the lower node id), it writes `Inhibit` — the *claim* — and in
//!   any case empties `Best` for the next cycle. A new member listens for one whole cycle
//!   before its first claim.
//!
//! A claim is a lease: it holds only while renewed. If the claimer dies, the peers'
//! write-inhibition lapses after `inhibit_period` and the task is free. For that to work
//! without flapping, `inhibit_period` must outlast the gap between two claims as seen by a
//! peer: about twice the claim period plus network delay. Shorter periods are accepted but
//! warned about — the paper's own Fig. 2 claims at 1 Hz and inhibits for 0.5 s.

use std::sync::Arc;

use crate::address::{ConnectionId, Endpoint, Source};
use crate::arbitration::WindowKind;
use crate::behavior::{Port, Trigger, BEST, INHIBIT, LOCAL};
use crate::connection::{ConnectOptions, ConnectionKind};
use crate::error::Error;
use crate::node::NodeCore;
use crate::process::Ctx;
use crate::time::{Duration, Instant};

/// How a behavior joins a BLE group.
///
/// Start from [`BleConfig::new`], which picks an inhibit period that outlasts the gap between
/// two claims (D11.2), and pass it to [`NodeCore::ble_join`]:
///
/// ```
/// use ayllu_core::*;
///
/// let mut node = NodeCore::new(NodeId(1));
/// let mut obs = BehaviorClass::new("Observer");
/// obs.port(PortSpec::new("Rotate", 0.0))?;
/// node.define(obs)?;
/// node.create("Observer", "OBS1")?;
///
/// // Claim at 1 Hz; the peers' `OBS1.Rotate` is write-inhibited for 2.3 s per claim.
/// let config = BleConfig::new("Peers", "Rotate", 1.0)?;
/// assert_eq!(config.inhibit_period, Duration::from_millis(2300)); // 2 x 1 s + 50 ms + 250 ms
/// let joined = node.ble_join("OBS1", &config)?;
/// assert!(joined.warnings.is_empty());
/// assert!(node.groups().iter().any(|g| &**g == "Peers"));
///
/// // The first cycle only listens (D11.3). Then eligibility written within the last cycle
/// // that beats every peer's (none here: `Best` is empty) is a claim.
/// node.poll(Instant::ZERO);
/// let local = node.port("OBS1", LOCAL)?;
/// node.write(Instant::from_millis(1500), local, 0.8)?;
/// node.poll(Instant::from_secs(2));
/// let status = node.ble_status("OBS1")?.unwrap();
/// assert!(status.claiming);
/// assert_eq!(status.claims, 1);
/// assert_eq!(status.local, Some(0.8));
/// // Eligibility and the claim went out to the group for the transport to deliver.
/// let out: Vec<Outgoing> = std::iter::from_fn(|| node.pop_outgoing()).collect();
/// assert!(out.iter().all(|o| o.to == Destination::Group("Peers".into())));
///
/// // The paper's Fig. 2 inhibits for 0.5 s at 1 Hz: accepted, with a warning.
/// node.create("Observer", "OBS2")?;
/// let short = BleConfig::new("Peers", "Rotate", 1.0)?.inhibit_period(Duration::from_millis(500));
/// assert_eq!(node.ble_join("OBS2", &short)?.warnings.len(), 1);
/// # Ok::<(), Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BleConfig {
    /// The broadcast group of peers (the paper's `Peers`).
    pub group: String,
    /// The behavior's output port that a claim write-inhibits on the peers (`Rotate`).
    pub output: String,
    /// How often the select process runs (the paper: 1 Hz).
    pub claim_rate_hz: f64,
    /// How long a claim write-inhibits the peers' output.
    pub inhibit_period: Duration,
    /// The network delay the team expects, for the period check.
    pub network_delay: Duration,
}

impl BleConfig {
    /// A config with the recommended inhibit period: twice the claim period plus delay, plus
    /// a quarter period of margin (with the default delay of 50 ms). A claim rate that is not
    /// finite and above zero is refused with [`Error::InvalidRate`].
    pub fn new(group: &str, output: &str, claim_rate_hz: f64) -> Result<BleConfig, Error> {
        let period = Duration::try_from_hz(claim_rate_hz)?;
        let network_delay = Duration::from_millis(50);
        Ok(BleConfig {
            group: group.to_owned(),
            output: output.to_owned(),
            claim_rate_hz,
            inhibit_period: period * 2 + network_delay + Duration::from_nanos(period.as_nanos() / 4),
            network_delay,
        })
    }
    /// Use `d` as the inhibit period instead of the recommended one. Shorter than
    /// [`minimum_inhibit_period`] is accepted but warned about by [`NodeCore::ble_join`] (D11.2).
    pub fn inhibit_period(mut self, d: Duration) -> Self {
        self.inhibit_period = d;
        self
    }
    /// Set the network delay the period check allows for (default 50 ms). It does not recompute
    /// `inhibit_period`, which [`BleConfig::new`] derived from the default delay.
    pub fn network_delay(mut self, d: Duration) -> Self {
        self.network_delay = d;
        self
    }
}

/// The shortest inhibit period that keeps a claim alive between renewals.
pub fn minimum_inhibit_period(claim_rate_hz: f64, network_delay: Duration) -> Result<Duration, Error> {
    Ok(Duration::try_from_hz(claim_rate_hz)? * 2 + network_delay)
}

/// A warning if `inhibit_period` is too short for the claim rate (rule S11), else `None`.
pub fn check_inhibit_period(
    claim_rate_hz: f64,
    inhibit_period: Duration,
    network_delay: Duration,
) -> Result<Option<String>, Error> {
    let min = minimum_inhibit_period(claim_rate_hz, network_delay)?;
    if inhibit_period >= min {
        return Ok(None);
    }
    Ok(Some(format!(
        "BLE inhibit period {inhibit_period} is shorter than twice the claim period ({}) plus network delay ({network_delay}) = {min}: \
         claims will lapse between renewals and peers will take the task back and forth (the paper's Fig. 2 claims at 1 Hz and inhibits for 0.5 s)",
        Duration::try_from_hz(claim_rate_hz)?
    )))
}

/// What `ble_join` refuses in `config` alone, whatever the node holds: a claim rate that is
/// not a usable frequency, a zero inhibit period, an empty group name, and what
/// [`check_inhibit_period`] refuses. Shared with a transaction's PREPARE
/// (`NodeCore::validate_changes`), so that a part that prepared also switches (R8).
pub(crate) fn check_ble_config(config: &BleConfig) -> Result<(), Error> {
    Duration::try_from_hz(config.claim_rate_hz)?;
    if config.inhibit_period.is_zero() {
        return Err(Error::ZeroPeriod { kind: ConnectionKind::WriteInhibit(config.inhibit_period) });
    }
    if config.group.is_empty() {
        return Err(Error::EmptyName { what: "group" });
    }
    check_inhibit_period(config.claim_rate_hz, config.inhibit_period, config.network_delay)?;
    Ok(())
}

/// What `ble_join` made.
#[derive(Clone, Debug, PartialEq)]
pub struct BleGroup {
    /// `Local -> (group, behavior, Best)`, Normal.
    pub eligibility: ConnectionId,
    /// `Inhibit -> (group, behavior, output)`, WriteInhibit.
    pub inhibition: ConnectionId,
    /// Warnings from the period check (also kept in `NodeCore::warnings`).
    pub warnings: Vec<String>,
}

/// Per-behavior BLE bookkeeping, for introspection ("who claims which task").
///
/// In declaration order (`repr(C)`) on a line of its own (`align(64)`): what `select` reads
/// and writes at every claim period (the period, the join time, the last local and best
/// eligibilities) in the first 64 bytes, what only a claim (rare) or a report touches after.
/// Every layer of every robot selects on the same tick; in the compiler's order the select's
/// fields spread over two or three lines of the box. A checkpoint keeps the declaration order
/// of before (`snapshot::BleStateForm`).
#[derive(Clone, Debug)]
#[repr(C, align(64))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(from = "crate::node::snapshot::BleStateForm", into = "crate::node::snapshot::BleStateForm")
)]
pub(crate) struct BleState {
    pub(crate) claim_period: Duration,
    /// When the behavior joined: it listens for one full cycle before it may claim.
    pub(crate) joined_at: Instant,
    pub(crate) last_local: Option<f64>,
    pub(crate) last_best: Option<(f64, Source)>,
    pub(crate) claims: u64,
    pub(crate) last_claim: Option<Instant>,
    pub(crate) group: Arc<str>,
    pub(crate) inhibit_period: Duration,
    pub(crate) output: Port,
}

// What `select` touches ends within the first line.
const _: () = assert!(std::mem::offset_of!(BleState, last_best) + std::mem::size_of::<Option<(f64, Source)>>() <= 64);

/// A behavior's BLE standing at `now`.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BleStatus {
    /// The member behavior (the layer, e.g. `OBS1`).
    pub behavior: String,
    /// Its BLE group.
    pub group: String,
    /// This node claimed the task within the last inhibit period.
    pub claiming: bool,
    /// When this node last claimed the task (its own clock), if ever.
    pub last_claim: Option<Instant>,
    /// How many times this node has claimed since it joined.
    pub claims: u64,
    /// Eligibility at the last select, if `Local` was fresh.
    pub local: Option<f64>,
    /// Best peer eligibility at the last select, and who supplied it.
    pub best: Option<(f64, Source)>,
    /// Peers whose claim currently write-inhibits our output, with the time left.
    pub inhibited_by: Vec<(Source, Duration)>,
}

impl NodeCore {
    /// Make `behavior` a member of a BLE peer group (see module docs and the example on
    /// [`BleConfig`]). One call per behavior.
    ///
    /// Refused: an invalid claim rate ([`Error::InvalidRate`]), a zero inhibit period
    /// ([`Error::ZeroPeriod`]), an empty group name, an unknown behavior or output port, a
    /// behavior already in a group ([`Error::Ble`]). A too short inhibit period is accepted
    /// and warned about (D11.2).
    pub fn ble_join(&mut self, behavior: &str, config: &BleConfig) -> Result<BleGroup, Error> {
        self.journal(|| crate::journal::Event::BleJoin {
            behavior: behavior.to_owned(),
            config: Box::new(config.clone()),
        });
        self.unjournaled(|core| core.join_ble_group(behavior, config))
    }

    fn join_ble_group(&mut self, behavior: &str, config: &BleConfig) -> Result<BleGroup, Error> {
        check_ble_config(config)?;
        let claim_period = Duration::try_from_hz(config.claim_rate_hz)?;
        let output = self.port(behavior, &config.output)?.port();
        if self.behavior(self.behavior_index(behavior)?).is_some_and(|b| b.ble.is_some()) {
            return Err(Error::Ble { reason: format!("`{behavior}` already belongs to a BLE group") });
        }
        let mut warnings = Vec::new();
        if let Some(w) = check_inhibit_period(config.claim_rate_hz, config.inhibit_period, config.network_delay)? {
            let w = format!("{behavior}: {w}");
            self.warnings.push(w.clone());
            warnings.push(w);
        }
        let eligibility = self.connect(
            &Endpoint::local(behavior, LOCAL),
            &Endpoint::group(&config.group, behavior, BEST),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
        let inhibition = self.connect(
            &Endpoint::local(behavior, INHIBIT),
            &Endpoint::group(&config.group, behavior, &config.output),
            ConnectionKind::WriteInhibit(config.inhibit_period),
            ConnectOptions::default(),
        )?;
        self.join(&config.group);
        self.add_process(behavior, BLE_SELECT, Trigger::Periodic(claim_period), select)?;
        let b = self.behavior_index(behavior)?;
        self.behavior_mut(b).expect("indexed").ble = Some(Box::new(BleState {
            group: Arc::from(config.group.as_str()),
            output,
            claim_period,
            inhibit_period: config.inhibit_period,
            joined_at: self.now(),
            claims: 0,
            last_claim: None,
            last_best: None,
            last_local: None,
        }));
        Ok(BleGroup { eligibility, inhibition, warnings })
    }

    /// The BLE standing of `behavior`, or `None` if it is in no BLE group.
    pub fn ble_status(&self, behavior: &str) -> Result<Option<BleStatus>, Error> {
        let now = self.now();
        let beh = self.behavior(self.behavior_index(behavior)?).expect("indexed");
        let Some(ble) = &beh.ble else { return Ok(None) };
        let inhibited_by = beh.ports[usize::from(ble.output.0)]
            .windows
            .active(now)
            .into_iter()
            .filter(|w| w.kind == WindowKind::WriteInhibit)
            .map(|w| (w.holder, w.end - now))
            .collect();
        Ok(Some(BleStatus {
            behavior: beh.name.to_string(),
            group: ble.group.to_string(),
            claiming: ble.last_claim.is_some_and(|t| now < t + ble.inhibit_period),
            last_claim: ble.last_claim,
            claims: ble.claims,
            local: ble.last_local,
            best: ble.last_best,
            inhibited_by,
        }))
    }

    /// Every BLE member on this node, by behavior name.
    pub fn ble_statuses(&self) -> Vec<BleStatus> {
        let mut names: Vec<&str> =
            self.behaviors.iter().flatten().filter(|b| b.ble.is_some()).map(|b| &*b.name).collect();
        names.sort_unstable();
        names.into_iter().filter_map(|n| self.ble_status(n).ok().flatten()).collect()
    }
}

/// The name of the process [`NodeCore::ble_join`] adds to a BLE member (the paper's
/// `BLE_Select`): tools tell BLE members by it.
pub const BLE_SELECT: &str = "BLE_Select";

/// The BLE select process (paper: `BLE_Select`, 1 Hz).
pub(crate) fn select(ctx: &mut Ctx<'_>) {
    let now = ctx.now();
    let me = ctx.node();
    let Some((period, joined_at)) =
        ctx.core.behavior(ctx.b).and_then(|b| b.ble.as_ref()).map(|s| (s.claim_period, s.joined_at))
    else {
        return;
    };
    // A new member first listens for a whole cycle, so that its `Best` has heard every peer;
    // otherwise everyone joining at once would claim everything once and inhibit each other.
    let listening = now < joined_at + period;
    // Eligibility counts only if written during the last cycle: no output, no claim.
    let local = match (ctx.last_accepted(Port::LOCAL), ctx.float(Port::LOCAL)) {
        (Some(t), Some(x)) if now < t + period && !x.is_nan() => Some(x),
        _ => None,
    };
    let best = ctx.float(Port::BEST).zip(ctx.supplier(Port::BEST));
    let wins = match (local, best) {
        _ if listening => false,
        (None, _) => false,
        (Some(_), None) => true,
        (Some(l), Some((b, who))) => l > b || (l == b && me < who.node),
    };
    if wins {
        // A failed write here would mean the class redefined Inhibit; nothing to claim then.
        let _ = ctx.write(Port::INHIBIT, true);
    }
    ctx.reset(Port::BEST);
    if let Some(state) = ctx.core.behavior_mut(ctx.b).and_then(|b| b.ble.as_mut()) {
        state.last_local = local;
        state.last_best = best;
        if wins {
            state.claims += 1;
            state.last_claim = Some(now);
        }
    }
}
