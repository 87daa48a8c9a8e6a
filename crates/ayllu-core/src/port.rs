//! Ports and how they merge what is written into them (rules S2–S4).
//!
//! A [`PortSpec`] declares a port: name, kind, type (from its default), and optionally a
//! freshness lifespan and, for aggregating kinds, a window. A [`PortCell`] is one live port:
//! its value, who supplied it, when it last accepted a value, and its merge rule. Merging is
//! a pure function of the cell, the incoming value, its source and `now`, so aggregation can
//! be tested exhaustively and is order-independent (property-tested).

use core::cmp::Ordering;

use crate::address::{NodeId, Source};
use crate::counters::DropCause;
use crate::error::Error;
use crate::time::{Duration, Instant};
use crate::value::{Value, ValueType};

/// How a port merges an incoming value `m` into its current value `c` (rule S3).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum PortKind {
    /// `c := m`.
    Normal,
    /// `c := max(c, m)`; remembers who supplied the maximum.
    Max,
    /// `c := min(c, m)`; remembers who supplied the minimum.
    Min,
    /// `c := c + m` (integers wrap, floats add, vectors add element-wise).
    Sum,
    /// `c := m` iff `priority(m) > priority(c)`; the current holder may always update.
    Priority,
}

impl PortKind {
    /// Max, Min, Sum and Priority ports start empty and empty again on reset or window end.
    pub fn is_aggregating(self) -> bool {
        !matches!(self, PortKind::Normal)
    }
    /// Whether a port of this kind can hold `ty` (rule S3): Max and Min take bool, int and
    /// float; Sum takes int, float and vector; Normal and Priority take every type.
    pub fn supports(self, ty: ValueType) -> bool {
        match self {
            PortKind::Normal | PortKind::Priority => true,
            PortKind::Max | PortKind::Min => {
                matches!(ty, ValueType::Bool | ValueType::Int | ValueType::Float)
            }
            PortKind::Sum => matches!(ty, ValueType::Int | ValueType::Float | ValueType::Vector),
        }
    }
    /// The kind as reports and `ayllu why` print it (`max`).
    pub fn name(self) -> &'static str {
        match self {
            PortKind::Normal => "normal",
            PortKind::Max => "max",
            PortKind::Min => "min",
            PortKind::Sum => "sum",
            PortKind::Priority => "priority",
        }
    }
}

/// The declaration of a port in a behavior class.
///
/// A builder: [`PortSpec::new`] makes a Normal port, the other methods change its kind and
/// add a lifespan or a window. [`BehaviorClass::port`](crate::BehaviorClass::port) checks the
/// result.
///
/// ```
/// use ayllu_core::*;
///
/// let mut c = BehaviorClass::new("Observer");
/// // Normal: the last value written; absent 300 ms after the last one (S4).
/// c.port(PortSpec::new("Rotate", 0.0).lifespan(Duration::from_millis(300)))?;
/// // Max: the greatest value offered in a 1 s window opened by the first one (D3.2).
/// c.port(PortSpec::new("Nearest", 0.0).max().window(Duration::from_secs(1)))?;
/// // Min: the smallest value offered since the last reset.
/// c.port(PortSpec::new("Closest", 0i64).min())?;
/// // Sum: forces of every avoider, element-wise; the shape is the default's (D3.5).
/// c.port(PortSpec::new("Force", vec![0.0, 0.0]).sum())?;
/// // Priority: the highest connection priority wins; the holder's lease is 0.5 s (D3.7).
/// c.port(PortSpec::new("Goal", "idle").priority().window(Duration::from_millis(500)))?;
/// // Refused: text has no order, and only aggregating ports have a window.
/// assert!(matches!(c.port(PortSpec::new("Name", "x").max()), Err(Error::KindNotSupported { .. })));
/// let w = PortSpec::new("W", 0.0).window(Duration::from_secs(1));
/// assert!(matches!(c.port(w), Err(Error::WindowOnNormalPort { .. })));
///
/// let mut node = NodeCore::new(NodeId(1));
/// node.define(c)?;
/// node.create("Observer", "OBS1")?;
/// let nearest = node.port("OBS1", "Nearest")?;
/// assert_eq!(node.get(nearest)?, None); // empty until the first value (D3.1)
/// node.write(Instant::ZERO, nearest, 3.0)?; // opens the window until 1 s
/// node.write(Instant::from_millis(500), nearest, 2.0)?; // absorbed: below the maximum
/// assert_eq!(node.read(nearest)?, Value::Float(3.0));
/// node.write(Instant::from_millis(1200), nearest, 2.0)?; // a new window: the maximum may fall
/// assert_eq!(node.read(nearest)?, Value::Float(2.0));
/// # Ok::<(), Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PortSpec {
    /// The port's name, unique among its behavior's registers.
    pub name: String,
    /// How it merges what is written (rule S3).
    pub kind: PortKind,
    /// What the port reads as while empty or never written; its type is the port's type for
    /// good (rule S1).
    pub default: Value,
    /// After this long without an accepted value the port reads as absent (rule S4).
    pub lifespan: Option<Duration>,
    /// Aggregating ports only: the port empties this long after the first value of a window.
    pub window: Option<Duration>,
}

impl PortSpec {
    /// A Normal port whose type is the default's type.
    pub fn new(name: &str, default: impl Into<Value>) -> PortSpec {
        PortSpec {
            name: name.to_owned(),
            kind: PortKind::Normal,
            default: default.into(),
            lifespan: None,
            window: None,
        }
    }
    /// Set the kind (see [`PortKind`]); [`PortSpec::max`] and the others are shorthands.
    pub fn kind(mut self, kind: PortKind) -> Self {
        self.kind = kind;
        self
    }
    /// A Max port: keeps the greatest value offered (ties go to the smaller source, D3.4).
    pub fn max(self) -> Self {
        self.kind(PortKind::Max)
    }
    /// A Min port: keeps the smallest value offered (ties go to the smaller source, D3.4).
    pub fn min(self) -> Self {
        self.kind(PortKind::Min)
    }
    /// A Sum port: adds what is offered (integers wrap, vectors add element-wise, D3.5).
    pub fn sum(self) -> Self {
        self.kind(PortKind::Sum)
    }
    /// A Priority port: the value of the highest-priority connection
    /// ([`ConnectOptions::priority`](crate::ConnectOptions::priority)) wins; the holder may
    /// update it at its own priority (D3.3).
    pub fn priority(self) -> Self {
        self.kind(PortKind::Priority)
    }
    /// The port reads as absent (`get` is `None`, `fresh` false) once `d` has passed since it
    /// last accepted a value (rule S4); an aggregating port also releases its holder then
    /// (D3.7). Zero is refused ([`Error::ZeroWindow`]).
    pub fn lifespan(mut self, d: Duration) -> Self {
        self.lifespan = Some(d);
        self
    }
    /// Aggregating ports only: Max, Min and Sum empty `d` after the first value of a window;
    /// a Priority port empties `d` after its holder's last accepted write (D3.2, D3.7). Zero
    /// or a Normal port is refused ([`Error::ZeroWindow`], [`Error::WindowOnNormalPort`]).
    pub fn window(mut self, d: Duration) -> Self {
        self.window = Some(d);
        self
    }
    /// The port's value type: its default's.
    pub fn ty(&self) -> ValueType {
        self.default.ty()
    }
    pub(crate) fn validate(&self) -> Result<(), Error> {
        if self.name.is_empty() {
            return Err(Error::EmptyName { what: "port" });
        }
        if !self.kind.supports(self.ty()) {
            return Err(Error::KindNotSupported { kind: self.kind, ty: self.ty() });
        }
        if self.lifespan.is_some_and(Duration::is_zero) || self.window.is_some_and(Duration::is_zero) {
            return Err(Error::ZeroWindow { port: self.name.clone() });
        }
        if self.window.is_some() && !self.kind.is_aggregating() {
            return Err(Error::WindowOnNormalPort { port: self.name.clone() });
        }
        if self.kind == PortKind::Sum && self.default.as_vector().is_some_and(<[f64]>::is_empty) {
            return Err(Error::VectorShape { port: self.name.clone() });
        }
        Ok(())
    }
}

/// A live port's value state. Arbitration windows live beside it (see `arbitration`).
// In declaration order (`repr(C)`): what a merge, a Normal write or a freshness read touches
// (kind, value, time of the last acceptance, window end, lifespan, and the supplier, which
// every acceptance writes) in the first 64 bytes, which the node places on a cache line of
// their own (`crate::node::PortState`); then what only a Priority merge, opening a window or a
// reset reads (supplier priority, window, default) last. To fit, the optional fields are split
// into their parts with their presence in bits of `flags` (in the padding after
// `has_accepted`): the supplier's node and connection (an `Option<Source>` is 24 bytes), and
// the lifespan's length (an `Option<Duration>` is 16). The last acceptance is likewise a flag
// plus a bare `Instant`. With the supplier in the far line, every accepted write and hop wrote
// a third line of the port (a third of the writes that missed the last level at 1000 robots,
// docs/performance.md). A checkpoint and `Debug` show the fields as they were declared before
// (`CellForm`), so a snapshot's form is unchanged.
#[derive(Clone)]
#[repr(C)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(from = "CellForm", into = "CellForm"))]
pub struct PortCell {
    pub(crate) kind: PortKind,
    /// Aggregating ports: no value in the current window. Normal ports are never empty.
    pub(crate) empty: bool,
    /// Whether the port ever accepted a value: `accepted_at` means something only then.
    pub(crate) has_accepted: bool,
    /// [`HAS_SUPPLIER`] and [`HAS_LIFESPAN`].
    flags: u8,
    /// The supplier's node, if [`HAS_SUPPLIER`].
    supplier_node: NodeId,
    pub(crate) value: Value,
    /// The time of the last acceptance, if `has_accepted`.
    pub(crate) accepted_at: Instant,
    pub(crate) window_end: Instant,
    /// The lifespan, if [`HAS_LIFESPAN`] (else zero).
    lifespan: Duration,
    /// The supplier's connection, if [`HAS_SUPPLIER`].
    supplier_conn: u64,
    pub(crate) supplier_priority: i32,
    pub(crate) window: Option<Duration>,
    pub(crate) default: Value,
}

/// [`PortCell::flags`]: the cell has a supplier (`supplier_node`, `supplier_conn`).
const HAS_SUPPLIER: u8 = 1;
/// [`PortCell::flags`]: the port has a lifespan (`lifespan`).
const HAS_LIFESPAN: u8 = 2;

// What a freshness read, a merge and an acceptance need ends within the first 64 bytes (see
// the layout note above).
const _: () = assert!(std::mem::offset_of!(PortCell, supplier_conn) + std::mem::size_of::<u64>() <= 64);
const _: () = assert!(std::mem::offset_of!(PortCell, lifespan) + std::mem::size_of::<Duration>() <= 64);

/// A [`PortCell`] as checkpoints and `Debug` show it: its fields as declared before the
/// supplier and the lifespan were split to fit the cell's first line (see the layout note).
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename = "PortCell"))]
struct CellForm {
    kind: PortKind,
    empty: bool,
    has_accepted: bool,
    supplier_priority: i32,
    value: Value,
    accepted_at: Instant,
    window_end: Instant,
    lifespan: Option<Duration>,
    supplier: Option<Source>,
    window: Option<Duration>,
    default: Value,
}

impl From<PortCell> for CellForm {
    fn from(c: PortCell) -> CellForm {
        CellForm {
            kind: c.kind,
            empty: c.empty,
            has_accepted: c.has_accepted,
            supplier_priority: c.supplier_priority,
            accepted_at: c.accepted_at,
            window_end: c.window_end,
            lifespan: c.lifespan(),
            supplier: c.supplier(),
            window: c.window,
            value: c.value,
            default: c.default,
        }
    }
}

impl From<CellForm> for PortCell {
    fn from(f: CellForm) -> PortCell {
        let mut c = PortCell {
            kind: f.kind,
            empty: f.empty,
            has_accepted: f.has_accepted,
            flags: 0,
            supplier_node: NodeId(0),
            value: f.value,
            accepted_at: f.accepted_at,
            window_end: f.window_end,
            lifespan: Duration::ZERO,
            supplier_conn: 0,
            supplier_priority: f.supplier_priority,
            window: f.window,
            default: f.default,
        };
        c.set_lifespan(f.lifespan);
        c.set_supplier(f.supplier);
        c
    }
}

impl std::fmt::Debug for PortCell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let form = CellForm::from(self.clone());
        f.debug_struct("PortCell")
            .field("kind", &form.kind)
            .field("empty", &form.empty)
            .field("has_accepted", &form.has_accepted)
            .field("supplier_priority", &form.supplier_priority)
            .field("value", &form.value)
            .field("accepted_at", &form.accepted_at)
            .field("window_end", &form.window_end)
            .field("lifespan", &form.lifespan)
            .field("supplier", &form.supplier)
            .field("window", &form.window)
            .field("default", &form.default)
            .finish()
    }
}

impl PortCell {
    /// A live port as `spec` declares it; aggregating kinds start empty (D3.1).
    pub fn new(spec: &PortSpec) -> PortCell {
        let mut c = PortCell {
            kind: spec.kind,
            default: spec.default.clone(),
            value: spec.default.clone(),
            empty: spec.kind.is_aggregating(),
            flags: 0,
            supplier_node: NodeId(0),
            supplier_conn: 0,
            supplier_priority: i32::MIN,
            has_accepted: false,
            accepted_at: Instant::ZERO,
            window_end: Instant::MAX,
            lifespan: Duration::ZERO,
            window: spec.window,
        };
        c.set_lifespan(spec.lifespan);
        c
    }

    /// How long a value stays fresh after it is accepted (`None`: for ever).
    #[inline(always)]
    pub(crate) fn lifespan(&self) -> Option<Duration> {
        (self.flags & HAS_LIFESPAN != 0).then_some(self.lifespan)
    }

    fn set_lifespan(&mut self, l: Option<Duration>) {
        self.lifespan = l.unwrap_or(Duration::ZERO);
        self.flags = if l.is_some() { self.flags | HAS_LIFESPAN } else { self.flags & !HAS_LIFESPAN };
    }

    /// `from` supplied the value.
    #[inline(always)]
    fn supply(&mut self, from: Source) {
        self.supplier_node = from.node;
        self.supplier_conn = from.conn;
        self.flags |= HAS_SUPPLIER;
    }

    fn set_supplier(&mut self, s: Option<Source>) {
        match s {
            Some(from) => self.supply(from),
            None => self.flags &= !HAS_SUPPLIER,
        }
    }

    /// When the port last accepted a value, if ever.
    #[inline]
    pub(crate) fn last_accepted(&self) -> Option<Instant> {
        self.has_accepted.then_some(self.accepted_at)
    }

    /// Record an acceptance at `now`.
    ///
    /// This is the only way a cell turns fresh, and the schedule relies on it: a guarded
    /// process's entry remembers a stale guard until the port accepts (D7.5,
    /// `Schedule::guard_accepted`, told by the node's `write_internal` and `deliver_to`). A
    /// new way to make a cell fresh (a lifespan changed at run time, a cell restored in place)
    /// must tell the schedule too.
    #[inline(always)]
    fn accepted(&mut self, now: Instant) {
        self.has_accepted = true;
        self.accepted_at = now;
    }

    /// How the port merges values.
    pub fn kind(&self) -> PortKind {
        self.kind
    }
    /// The port's value type (rule S1). Read from the value, which always has the default's
    /// type (every merge checks it, a reset copies the default): the default sits at the far
    /// end of the cell, one more cache line for every merge that checks a type.
    pub fn ty(&self) -> ValueType {
        self.value.ty()
    }

    /// When the value an aggregating port holds is released (D3.2, D3.7): at the end of its
    /// window (for a Priority port the window is its holder's lease, renewed by every accepted
    /// write) or when it goes stale (lifespan), whichever comes first. `Instant::MAX`: never.
    pub(crate) fn release_at(&self) -> Instant {
        match (self.lifespan(), self.last_accepted()) {
            (Some(l), Some(t)) => self.window_end.min(t + l),
            _ => self.window_end,
        }
    }

    /// Whether an aggregating port holds nothing at `now` (empty, or released and not yet
    /// written again). Normal ports are never empty.
    pub fn is_empty(&self, now: Instant) -> bool {
        self.kind.is_aggregating() && (self.empty || now >= self.release_at())
    }

    /// Lazily release what an aggregating port holds once its window ended or it went stale:
    /// the port empties, and the next value is judged against nothing (rules S3, D3.7).
    pub(crate) fn expire(&mut self, now: Instant) {
        if !self.empty && self.is_empty(now) {
            self.reset();
        }
    }

    /// Release the value if `gone` supplied it (its connection was removed or its node is
    /// gone): an aggregating port empties; a Normal port keeps its value (it holds no one's
    /// claim). Returns whether it released.
    pub(crate) fn release_from(&mut self, gone: impl Fn(Source) -> bool) -> bool {
        if self.kind.is_aggregating() && !self.empty && self.supplier().is_some_and(gone) {
            self.reset();
            return true;
        }
        false
    }

    /// Empty an aggregating port; a Normal port returns to its default.
    pub fn reset(&mut self) {
        self.value = self.default.clone();
        self.empty = self.kind.is_aggregating();
        self.set_supplier(None);
        self.supplier_priority = i32::MIN;
        self.window_end = Instant::MAX;
    }

    /// The value, or the default while empty. Does not look at freshness.
    pub fn value(&self) -> &Value {
        &self.value
    }

    /// Whether the port holds a value that is not stale (rule S4): it has accepted a value,
    /// its aggregating window (if any) is still open, and its lifespan (if any) has not run out.
    #[inline]
    pub fn fresh(&self, now: Instant) -> bool {
        let Some(t) = self.last_accepted() else { return false };
        if self.kind.is_aggregating() {
            return !self.is_empty(now);
        }
        match self.lifespan() {
            Some(l) => now < t + l,
            None => true,
        }
    }

    /// Whether `m` can be offered to this port at all: its type, and for ordered and summing
    /// ports a number (not NaN) of the declared shape. A value that fails here is refused
    /// whatever the port holds; one that passes may still be absorbed by the merge.
    pub fn check(&self, m: &Value) -> Result<(), DropCause> {
        if m.ty() != self.ty() {
            return Err(DropCause::TypeMismatch);
        }
        match self.kind {
            PortKind::Max | PortKind::Min if m.is_nan() => Err(DropCause::NotANumber),
            PortKind::Sum => {
                if m.is_nan() || m.as_vector().is_some_and(|v| v.iter().any(|x| x.is_nan())) {
                    return Err(DropCause::NotANumber);
                }
                // A vector Sum's shape is its declared default's (D3.5).
                match (m.as_vector(), self.default.as_vector()) {
                    (Some(v), Some(d)) if v.len() != d.len() => Err(DropCause::ShapeMismatch),
                    _ => Ok(()),
                }
            }
            _ => Ok(()),
        }
    }

    /// The value if fresh, else `None` ("absent").
    #[inline]
    pub fn get(&self, now: Instant) -> Option<&Value> {
        self.fresh(now).then_some(&self.value)
    }

    /// Who supplied the value as of the last merge or reset (D3.4). Not cleared lazily: check
    /// [`PortCell::is_empty`] or [`PortCell::fresh`] before trusting it.
    #[inline]
    pub fn supplier(&self) -> Option<Source> {
        (self.flags & HAS_SUPPLIER != 0).then_some(Source { node: self.supplier_node, conn: self.supplier_conn })
    }

    /// Merge `m` from `from` at `now` (rule S3). `Ok(())` means the port *accepted* the value
    /// and it must be propagated (rule S5); `Err(cause)` means it was refused or absorbed.
    #[inline(always)]
    pub fn merge(&mut self, now: Instant, m: &Value, from: Source, priority: i32) -> Result<(), DropCause> {
        // Fast path for the common case, inlined into the hop: a Normal port never expires,
        // so this is exactly the `PortKind::Normal` arm below.
        if self.kind == PortKind::Normal && m.ty() == self.ty() {
            self.accept_normal(now, m, from);
            return Ok(());
        }
        if let Some(outcome) = self.merge_held_number(now, m, from) {
            return outcome;
        }
        self.merge_any(now, m, from, priority)
    }

    /// A number offered to a Max or Min port that holds one (an eligibility into BLE's `Best`,
    /// most of what aggregating ports are offered: each broadcast reaches every peer), inlined
    /// into the receive path: a call to [`PortCell::merge_any`], which saves and restores the
    /// registers its every arm needs, was most of this case's cost. The `Max | Min` arm of
    /// `merge_any` with what `check` and `expire` decide for this case (not NaN, nothing to
    /// release) taken first: the same comparisons on the same values, so the same outcome.
    /// `None`: not this case, for `merge_any` to merge.
    #[inline(always)]
    fn merge_held_number(&mut self, now: Instant, m: &Value, from: Source) -> Option<Result<(), DropCause>> {
        let better = match self.kind {
            PortKind::Max => Ordering::Greater,
            PortKind::Min => Ordering::Less,
            _ => return None,
        };
        let holds = !self.empty && now < self.release_at();
        let (Value::Float(x), Value::Float(c)) = (m, &mut self.value) else { return None };
        if !holds || x.is_nan() {
            return None;
        }
        match x.total_cmp(c) {
            ord if ord == better => {
                *c = *x;
                self.supply(from);
            }
            Ordering::Equal => {
                if self.supplier().is_none_or(|s| from < s) {
                    self.supply(from);
                }
            }
            _ => return Some(Err(DropCause::Absorbed)),
        }
        self.accepted(now);
        Some(Ok(()))
    }

    /// The Normal merge of a value already known to be of the port's type (rule S3: `c := m`).
    #[inline(always)]
    pub(crate) fn accept_normal(&mut self, now: Instant, m: &Value, from: Source) {
        debug_assert!(self.kind == PortKind::Normal && m.ty() == self.ty());
        assign(&mut self.value, m);
        self.supply(from);
        self.accepted(now);
    }

    #[inline(never)]
    fn merge_any(&mut self, now: Instant, m: &Value, from: Source, priority: i32) -> Result<(), DropCause> {
        // (A number offered to a Max or Min port that holds one was merged by
        // `merge_held_number` before this call.)
        self.check(m)?;
        self.expire(now);
        match self.kind {
            PortKind::Normal => {
                assign(&mut self.value, m);
                self.supply(from);
            }
            PortKind::Max | PortKind::Min => {
                if self.empty {
                    self.open(now, m, from);
                } else {
                    let ord = m.order(&self.value).ok_or(DropCause::TypeMismatch)?;
                    let better = if self.kind == PortKind::Max { Ordering::Greater } else { Ordering::Less };
                    if ord == better {
                        assign(&mut self.value, m);
                        self.supply(from);
                    } else if ord == Ordering::Equal {
                        // Ties go to the smaller source, whatever the arrival order.
                        if self.supplier().is_none_or(|s| from < s) {
                            self.supply(from);
                        }
                    } else {
                        return Err(DropCause::Absorbed);
                    }
                }
            }
            PortKind::Sum => {
                if self.empty {
                    self.open(now, m, from);
                } else {
                    let sum = match (&self.value, m) {
                        (Value::Int(a), Value::Int(b)) => Value::Int(a.wrapping_add(*b)),
                        (Value::Float(a), Value::Float(b)) => Value::Float(a + b),
                        (Value::Vector(a), Value::Vector(b)) => {
                            if a.len() != b.len() {
                                return Err(DropCause::ShapeMismatch);
                            }
                            Value::Vector(a.iter().zip(b.iter()).map(|(x, y)| x + y).collect())
                        }
                        _ => return Err(DropCause::TypeMismatch),
                    };
                    // +inf and -inf make NaN: refused, so that a Sum is never poisoned (D3.6).
                    if sum.is_nan() || sum.as_vector().is_some_and(|v| v.iter().any(|x| x.is_nan())) {
                        return Err(DropCause::NotANumber);
                    }
                    self.value = sum;
                    self.supply(from);
                }
            }
            PortKind::Priority => {
                let wins = self.empty
                    || priority > self.supplier_priority
                    || (priority == self.supplier_priority && self.supplier() == Some(from));
                if !wins {
                    return Err(DropCause::Absorbed);
                }
                if self.empty {
                    self.open(now, m, from);
                } else {
                    assign(&mut self.value, m);
                    self.supply(from);
                }
                self.supplier_priority = priority;
                // A Priority port's window is its holder's lease: every accepted write renews
                // it, so a holder that keeps writing is never displaced by a lower priority at
                // a window boundary (D3.7).
                if let Some(w) = self.window {
                    self.window_end = now + w;
                }
            }
        }
        self.accepted(now);
        Ok(())
    }

    fn open(&mut self, now: Instant, m: &Value, from: Source) {
        assign(&mut self.value, m);
        self.supply(from);
        self.empty = false;
        self.window_end = match self.window {
            Some(w) => now + w,
            None => Instant::MAX,
        };
    }
}

/// `*dst = m.clone()`, with scalars stored directly. The derived `clone_from` copies the
/// enum through a stack temporary with overlapping partial stores, which stalls store
/// forwarding and made it the most expensive step of a hop; this is the same assignment.
#[inline]
fn assign(dst: &mut Value, m: &Value) {
    match (dst, m) {
        (Value::Int(d), Value::Int(x)) => *d = *x,
        (Value::Float(d), Value::Float(x)) => *d = *x,
        (Value::Bool(d), Value::Bool(x)) => *d = *x,
        (dst, m) => dst.clone_from(m),
    }
}

#[cfg(all(test, feature = "serde"))]
mod tests {
    use super::*;

    /// A checkpoint shows a cell with the fields and order it had before the supplier and the
    /// lifespan were split to fit the first line, and reads it back as it was.
    #[test]
    fn a_cell_keeps_its_checkpoint_form() {
        let mut cell = PortCell::new(&PortSpec::new("P", 0i64).lifespan(Duration::from_millis(5)));
        cell.accept_normal(Instant::from_nanos(7), &Value::Int(3), Source { node: NodeId(2), conn: 9 });
        let json = serde_json::to_string(&cell).unwrap();
        assert_eq!(
            json,
            r#"{"kind":"Normal","empty":false,"has_accepted":true,"supplier_priority":-2147483648,"value":{"Int":3},"accepted_at":{"nanos":7},"window_end":{"nanos":18446744073709551615},"lifespan":{"nanos":5000000},"supplier":{"node":2,"conn":9},"window":null,"default":{"Int":0}}"#
        );
        let back: PortCell = serde_json::from_str(&json).unwrap();
        assert_eq!(format!("{back:?}"), format!("{cell:?}"));
        assert_eq!((back.supplier(), back.lifespan()), (cell.supplier(), Some(Duration::from_millis(5))));
        let empty: PortCell =
            serde_json::from_str(&serde_json::to_string(&PortCell::new(&PortSpec::new("Q", 0.0))).unwrap()).unwrap();
        assert_eq!((empty.supplier(), empty.lifespan()), (None, None));
    }
}
