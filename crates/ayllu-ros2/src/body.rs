//! [`Ros2Body`]: the driver that makes a node's body behaviors ROS 2 topics, as a
//! [`Mapping`] says.
//!
//! Each "in" topic is a subscription: every sample it takes is written into its ports with
//! [`NodeCore::write`], the behavior's own write — so it propagates, is arbitrated, is
//! journaled and recorded, and `why` explains it exactly as it would a simulator's sensor
//! write. Each "out" topic is a publication of its ports' values, whenever one of them
//! accepts a value or at the topic's rate.
//!
//! Promises:
//! * behaviors the mapping names that the node does not have are created, with one port per
//!   mapped field (its type from the field: float, int, bool, text, vector; an "in" topic's
//!   `lifespan` on its ports); behaviors the node has (the stdlib's, a controller's own) are
//!   used as they are, and a port they lack or whose type cannot take the field is refused at
//!   install with an error that says so;
//! * a sample that cannot be used is dropped and counted by topic and cause — `truncated`,
//!   `too_long`, `malformed`, `bad_text`, `nan` (a NaN in a mapped number; a LaserScan's
//!   `ranges` and `intensities` may hold NaN and ±inf, REP 117's readings, and pass), `refused`
//!   (the port would not take it) — and nothing else happens: the node runs on;
//! * the counters are in the node's reports (`ayllu list`: `body`), with each topic's matched
//!   publishers or subscribers, refreshed once a second;
//! * at most [`MAX_SAMPLES_PER_TURN`] samples are taken from one topic a turn, so a flooded
//!   topic cannot starve the node's loop; the DDS reader's history (the QoS depth) bounds what
//!   waits.

use std::cell::Cell;
use std::time::SystemTime;

use ayllu_core::{BehaviorClass, Duration, Error as CoreError, Instant, NodeCore, PortRef, PortSpec, Value, ValueType};
use ros2_client::{Context, ContextOptions, MessageTypeName, Name, NodeName, NodeOptions, QosProfile};

use crate::mapping::{Direction, Durability, Mapping, Qos, Reliability, Sonar, Topic};
use crate::messages::{Decode, DecodeCause, Encoded, FieldKind, FieldRef, Sample};
use crate::Error;

/// The most samples taken from one topic in one turn of the node.
pub const MAX_SAMPLES_PER_TURN: usize = 64;

/// How often the matched-endpoint counts are refreshed (they take locks inside the DDS stack).
const MATCH_PERIOD: Duration = Duration::from_secs(1);

/// The causes an "in" topic counts, in report order.
const IN_CAUSES: [&str; 11] = [
    "taken",
    "truncated",
    "too_long",
    "malformed",
    "bad_text",
    "nan",
    "refused",
    "read_error",
    "publishers",
    "wrong_type_publishers",
    "qos_mismatch_publishers",
];
/// Where each cause of [`IN_CAUSES`] and [`OUT_CAUSES`] sits among a topic's counters.
mod slot {
    pub const TAKEN: usize = 0;
    pub const TRUNCATED: usize = 1;
    pub const TOO_LONG: usize = 2;
    pub const MALFORMED: usize = 3;
    pub const BAD_TEXT: usize = 4;
    pub const NAN: usize = 5;
    pub const REFUSED: usize = 6;
    pub const READ_ERROR: usize = 7;
    /// The first of the three endpoint counts (matched, wrong type, QoS mismatch) of an in topic.
    pub const PUBLISHERS: usize = 8;
    pub const PUBLISHED: usize = 0;
    pub const PUBLISH_FAILED: usize = 1;
    /// The first of the three endpoint counts of an out topic.
    pub const SUBSCRIBERS: usize = 2;
}
/// The causes an "out" topic counts.
const OUT_CAUSES: [&str; 5] =
    ["published", "publish_failed", "subscribers", "wrong_type_subscribers", "qos_mismatch_subscribers"];

fn profile(q: &Qos) -> QosProfile {
    use ros2_client::qos::{Durability as D, History, Reliability as R, WhenFull};
    let base = QosProfile::subscription_default();
    base.reliability(match q.reliability {
        // A body never blocks the node's loop on a slow reader: a full window fails the publish
        // at once, and it is counted.
        Reliability::Reliable => R::Reliable { when_full: WhenFull::Fail },
        Reliability::BestEffort => R::BestEffort,
    })
    .durability(match q.durability {
        Durability::Volatile => D::Volatile,
        Durability::TransientLocal => D::TransientLocal,
    })
    .history(History::KeepLast { depth: q.depth })
}

/// How a field's value becomes its port's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Convert {
    Same,
    IntToFloat,
    BoolToInt,
}

/// Whether a field of `kind` can feed a port of type `port` (in), and how.
fn convert_in(kind: FieldKind, port: ValueType) -> Option<Convert> {
    match (kind, port) {
        (FieldKind::Float | FieldKind::Yaw, ValueType::Float)
        | (FieldKind::Int, ValueType::Int)
        | (FieldKind::Bool, ValueType::Bool)
        | (FieldKind::Text, ValueType::Text)
        | (FieldKind::Floats, ValueType::Vector) => Some(Convert::Same),
        (FieldKind::Int, ValueType::Float) => Some(Convert::IntToFloat),
        (FieldKind::Bool, ValueType::Int) => Some(Convert::BoolToInt),
        _ => None,
    }
}

/// Whether a port of type `port` can fill a field of `kind` (out).
fn fits_out(port: ValueType, kind: FieldKind) -> bool {
    matches!(
        (port, kind),
        (ValueType::Float, FieldKind::Float | FieldKind::Yaw)
            | (ValueType::Int, FieldKind::Int | FieldKind::Float)
            | (ValueType::Bool, FieldKind::Bool | FieldKind::Int)
            | (ValueType::Text, FieldKind::Text)
            | (ValueType::Vector, FieldKind::Floats)
    )
}

/// The port type a new port gets for a field of `kind`, and its default.
fn new_port(kind: FieldKind, sonar: Option<&Sonar>) -> Value {
    match kind {
        FieldKind::Float | FieldKind::Yaw => Value::Float(0.0),
        FieldKind::Int => Value::Int(0),
        FieldKind::Bool => Value::Bool(false),
        FieldKind::Text => Value::from(""),
        // A resampled scan has its beams from the first sample on; until then every beam reads
        // 0 m — an obstacle at the rim — so a controller that reads the default stops.
        FieldKind::Floats => Value::vector(&vec![0.0; sonar.map_or(0, |s| s.beams)]),
    }
}

fn kind_word(k: FieldKind) -> &'static str {
    match k {
        FieldKind::Bool => "a bool",
        FieldKind::Int => "an integer",
        FieldKind::Float => "a float",
        FieldKind::Yaw => "an angle (float)",
        FieldKind::Text => "a string",
        FieldKind::Floats => "an array of numbers (vector)",
    }
}

/// The fields a LaserScan resampling reads.
struct ScanFields {
    angle_min: FieldRef,
    angle_increment: FieldRef,
    range_min: FieldRef,
    range_max: FieldRef,
}

struct InField {
    field: FieldRef,
    port: PortRef,
    convert: Convert,
    /// NaN here drops the sample (false for a LaserScan's REP 117 arrays).
    nan_drops: bool,
    /// This field is `ranges`, resampled.
    resampled: bool,
}

/// What the graph check compares a topic's remote endpoints with.
struct Endpoint {
    /// The DDS topic (`rt/robot1/scan`).
    dds_topic: String,
    /// The ROS 2 name and type, for warnings.
    name: String,
    ty: &'static crate::messages::MessageType,
    qos: ros2_client::dds::rustdds::QosPolicies,
    /// Remote endpoints already warned about (their GUIDs), so each is reported once.
    warned: Vec<String>,
}

struct Input {
    endpoint: Endpoint,
    sub: ros2_client::Subscription<Sample>,
    topic: &'static crate::messages::MessageType,
    max_elements: usize,
    fields: Vec<InField>,
    sonar: Option<(Sonar, ScanFields)>,
    /// Index of this topic's first counter in the body's counters.
    counters: usize,
}

struct Output {
    endpoint: Endpoint,
    publisher: ros2_client::Publisher<Encoded>,
    template: Sample,
    fields: Vec<(FieldRef, PortRef)>,
    /// `header.stamp`'s fields, filled with the publishing time when the mapping does not map
    /// or set them.
    stamp: Option<(FieldRef, FieldRef)>,
    period: Option<Duration>,
    next_due: Option<Instant>,
    /// The newest acceptance published, per field.
    published: Vec<Option<Instant>>,
    counters: usize,
}

/// The ROS 2 body of one node (module docs). Attach it with [`crate::install`], or drive it
/// by hand through [`ayllu::Driver`].
pub struct Ros2Body {
    inputs: Vec<Input>,
    outputs: Vec<Output>,
    poll: Duration,
    /// Counters by (topic, cause), mirrored into the node's report when they change.
    counts: Vec<(String, u64)>,
    /// Where `counts` starts in the node's body counters.
    base: usize,
    dirty: bool,
    next_match: Instant,
    /// Last: the DDS entities above must go before their node and context. The node is kept
    /// alive (its spinner keeps the ROS 2 graph), never read.
    _node: ros2_client::Node,
    _context: Context,
}

/// A DDS participant on ROS domain `domain`, for [`Ros2Body::install_in`].
pub fn participant(domain: u16) -> Result<Context, Error> {
    Context::with_options(ContextOptions::new().domain_id(domain))
        .map_err(|e| create_error(format!("starting DDS on ROS domain {domain}"), e))
}

fn create_error(what: impl std::fmt::Display, e: impl std::fmt::Debug) -> Error {
    Error::Ros2(format!("{what}: {e:?}"))
}

impl Ros2Body {
    /// Create what the mapping needs on `core` (behaviors, ports) and the DDS participant,
    /// node, subscriptions and publications. The participant joins ROS domain
    /// `mapping.domain`.
    pub fn install(core: &mut NodeCore, mapping: &Mapping) -> Result<Ros2Body, Error> {
        let context = participant(mapping.domain)?;
        Ros2Body::install_in(core, mapping, &context)
    }

    /// [`Ros2Body::install`] in a DDS participant shared with other bodies (a simulator
    /// serving a fleet: one participant, one ROS 2 node per robot). The mapping's domain is the
    /// participant's.
    pub fn install_in(core: &mut NodeCore, mapping: &Mapping, context: &Context) -> Result<Ros2Body, Error> {
        if context.domain_id() != mapping.domain {
            return Err(Error::Install(format!(
                "the mapping names ROS domain {}, the shared participant is on domain {}",
                mapping.domain,
                context.domain_id()
            )));
        }
        let context = context.clone();
        Ros2Body::create_behaviors(core, mapping)?;
        let node_name = NodeName::new(&mapping.namespace, &mapping.node_name)
            .map_err(|e| create_error(format!("ROS 2 node name {}/{}", mapping.namespace, mapping.node_name), e))?;
        // No rosout (a body logs nothing to ROS) and no parameter services (it has none).
        let options = NodeOptions::new().enable_rosout(false).start_parameter_services(false);
        let mut node = context
            .new_node(node_name, options)
            .map_err(|e| create_error(format!("creating ROS 2 node {}", mapping.node_name), e))?;
        // The spinner keeps the ROS 2 graph (matched endpoints, ros_discovery_info) current.
        let spinner = node.spinner().map_err(|e| create_error("starting the ROS 2 node's spinner", e))?;
        std::thread::Builder::new()
            .name("ayllu-ros2-spin".into())
            .spawn(move || {
                let _ = futures::executor::block_on(spinner.spin());
            })
            .map_err(|e| Error::Ros2(format!("starting the spinner thread: {e}")))?;

        let mut counts = Vec::new();
        let mut inputs = Vec::new();
        let mut outputs = Vec::new();
        for t in &mapping.topics {
            let name = Name::parse(&t.name).map_err(|e| create_error(format!("topic name {}", t.name), e))?;
            let type_name = MessageTypeName::new(t.ty.package(), t.ty.short_name());
            let qos = profile(&t.qos);
            let topic = node
                .create_topic(&name, type_name, &qos)
                .map_err(|e| create_error(format!("creating topic {} ({})", t.name, t.ty.name()), e))?;
            let first = counts.len();
            match t.direction {
                Direction::In => {
                    counts.extend(IN_CAUSES.iter().map(|c| (format!("{} {c}", t.name), 0)));
                    let sub = node
                        .create_subscription::<Sample>(&topic, Some(qos))
                        .map_err(|e| create_error(format!("subscribing to {}", t.name), e))?;
                    inputs.push(Ros2Body::input(core, t, sub, first)?);
                }
                Direction::Out => {
                    counts.extend(OUT_CAUSES.iter().map(|c| (format!("{} {c}", t.name), 0)));
                    let publisher = node
                        .create_publisher::<Encoded>(&topic, Some(qos))
                        .map_err(|e| create_error(format!("publishing {}", t.name), e))?;
                    outputs.push(Ros2Body::output(core, t, publisher, first)?);
                }
            }
        }
        let base = core.body_counters_mut().len();
        core.body_counters_mut().extend(counts.iter().cloned());
        Ok(Ros2Body {
            inputs,
            outputs,
            poll: Duration::from_nanos(mapping.poll.as_nanos().min(u128::from(u64::MAX)) as u64),
            counts,
            base,
            dirty: false,
            next_match: core.now(),
            _node: node,
            _context: context,
        })
    }

    /// Create the behaviors the node lacks; check the ports of those it has.
    fn create_behaviors(core: &mut NodeCore, mapping: &Mapping) -> Result<(), Error> {
        // Behavior -> its ports' specs, in file order.
        let mut wanted: Vec<(String, Vec<PortSpec>)> = Vec::new();
        for t in &mapping.topics {
            for f in &t.fields {
                let kind = f.field.kind();
                if core.behavior_ref(&f.behavior).is_ok() {
                    let port = core.port(&f.behavior, &f.port).map_err(|_| {
                        Error::Install(format!(
                            "{} maps {} to {}.{}, but behavior {} has no port {}",
                            t.name, f.path, f.behavior, f.port, f.behavior, f.port
                        ))
                    })?;
                    let ty = core.read(port).map(|v| v.ty()).map_err(|e| Error::Install(e.to_string()))?;
                    let fits = match t.direction {
                        Direction::In => convert_in(kind, ty).is_some(),
                        Direction::Out => fits_out(ty, kind),
                    };
                    if !fits {
                        return Err(Error::Install(format!(
                            "{}: {} is {}, and {}.{} holds a {}: map it to a port of a matching type",
                            t.name,
                            f.path,
                            kind_word(kind),
                            f.behavior,
                            f.port,
                            ty.name()
                        )));
                    }
                    continue;
                }
                let i = match wanted.iter().position(|(b, _)| *b == f.behavior) {
                    Some(i) => i,
                    None => {
                        wanted.push((f.behavior.clone(), Vec::new()));
                        wanted.len() - 1
                    }
                };
                let specs = &mut wanted[i].1;
                if specs.iter().any(|s| s.name == f.port) {
                    // An out port feeding two topics (or two fields) is one port.
                    continue;
                }
                let resampled = t.sonar.is_some() && f.path == "ranges";
                let mut spec = PortSpec::new(&f.port, new_port(kind, t.sonar.as_ref().filter(|_| resampled)));
                if let Some(l) = t.lifespan {
                    spec = spec.lifespan(Duration::from_nanos(l.as_nanos().min(u128::from(u64::MAX)) as u64));
                }
                specs.push(spec);
            }
        }
        for (behavior, specs) in wanted {
            let class_name = format!("Ros2Body{behavior}");
            let mut class = BehaviorClass::new(&class_name);
            for spec in specs {
                class.port(spec)?;
            }
            core.define(class)?;
            core.create(&class_name, &behavior)?;
        }
        Ok(())
    }

    fn input(
        core: &NodeCore,
        t: &Topic,
        sub: ros2_client::Subscription<Sample>,
        counters: usize,
    ) -> Result<Input, Error> {
        let scan = t.ty.name() == "sensor_msgs/msg/LaserScan";
        let mut fields = Vec::with_capacity(t.fields.len());
        for f in &t.fields {
            let port = core.port(&f.behavior, &f.port)?;
            let ty = core.read(port)?.ty();
            let convert = convert_in(f.field.kind(), ty).unwrap_or(Convert::Same);
            let rep117 = scan && (f.path == "ranges" || f.path == "intensities");
            fields.push(InField {
                field: f.field.clone(),
                port,
                convert,
                nan_drops: !rep117,
                resampled: t.sonar.is_some() && f.path == "ranges",
            });
        }
        let sonar = match t.sonar {
            Some(s) => {
                let f = |p: &str| t.ty.field(p).map_err(|e| Error::Install(e.to_string()));
                Some((
                    s,
                    ScanFields {
                        angle_min: f("angle_min")?,
                        angle_increment: f("angle_increment")?,
                        range_min: f("range_min")?,
                        range_max: f("range_max")?,
                    },
                ))
            }
            None => None,
        };
        Ok(Input { endpoint: Endpoint::of(t), sub, topic: t.ty, max_elements: t.max_elements, fields, sonar, counters })
    }

    fn output(
        core: &NodeCore,
        t: &Topic,
        publisher: ros2_client::Publisher<Encoded>,
        counters: usize,
    ) -> Result<Output, Error> {
        let mut template = t.ty.default_sample();
        for c in &t.set {
            template.set(&c.field, &c.value).map_err(|e| Error::Install(format!("{}: set {}: {e}", t.name, c.path)))?;
        }
        let mut fields = Vec::with_capacity(t.fields.len());
        for f in &t.fields {
            fields.push((f.field.clone(), core.port(&f.behavior, &f.port)?));
        }
        let given =
            |p: &str| t.fields.iter().any(|f| f.path.starts_with(p)) || t.set.iter().any(|c| c.path.starts_with(p));
        let stamp = match (t.ty.field("header.stamp.sec"), t.ty.field("header.stamp.nanosec")) {
            (Ok(s), Ok(n)) if !given("header.stamp") => Some((s, n)),
            _ => None,
        };
        let period = t.rate.map(|hz| Duration::from_nanos((1e9 / hz).round() as u64));
        Ok(Output {
            endpoint: Endpoint::of(t),
            publisher,
            template,
            published: vec![None; fields.len()],
            fields,
            stamp,
            period,
            next_due: None,
            counters,
        })
    }

    /// Set a gauge (matched endpoints).
    fn set(&mut self, at: usize, n: u64) {
        if self.counts[at].1 != n {
            self.counts[at].1 = n;
            self.dirty = true;
        }
    }

    fn count(&mut self, at: usize, n: u64) {
        self.counts[at].1 += n;
        self.dirty = true;
    }

    /// Take what arrived on every "in" topic and write it into the ports.
    fn take_in(&mut self, core: &mut NodeCore, now: Instant) {
        for i in 0..self.inputs.len() {
            for _ in 0..MAX_SAMPLES_PER_TURN {
                let cause = Cell::new(None);
                let input = &self.inputs[i];
                let seed = Decode { ty: input.topic, max_elements: input.max_elements, cause: &cause };
                let at = input.counters;
                match input.sub.take_seed(seed) {
                    Ok(None) => break,
                    Ok(Some((sample, _info))) => {
                        let slot = match self.write_sample(core, now, i, &sample) {
                            Ok(()) => slot::TAKEN,
                            Err(slot) => slot,
                        };
                        self.count(at + slot, 1);
                    }
                    Err(_) => {
                        let slot = match cause.get() {
                            Some(DecodeCause::Truncated) => slot::TRUNCATED,
                            Some(DecodeCause::TooLong) => slot::TOO_LONG,
                            Some(DecodeCause::Malformed) => slot::MALFORMED,
                            Some(DecodeCause::BadText) => slot::BAD_TEXT,
                            None => slot::READ_ERROR,
                        };
                        self.count(at + slot, 1);
                    }
                }
            }
        }
    }

    /// Write one sample's fields; `Err(counter slot)` if it was dropped (nothing written then,
    /// unless a port refused a value after others took theirs).
    fn write_sample(&self, core: &mut NodeCore, now: Instant, i: usize, sample: &Sample) -> Result<(), usize> {
        let input = &self.inputs[i];
        // First check everything, so a sample is written whole or not at all.
        let mut values = Vec::with_capacity(input.fields.len());
        for f in &input.fields {
            let Some(v) = sample.get(&f.field) else { return Err(slot::MALFORMED) };
            if f.nan_drops && (v.is_nan() || v.as_vector().is_some_and(|xs| xs.iter().any(|x| x.is_nan()))) {
                return Err(slot::NAN);
            }
            let v = if f.resampled {
                let Some((sonar, scan)) = &input.sonar else { return Err(slot::MALFORMED) };
                let num = |r: &FieldRef| sample.get(r).and_then(|v| v.as_float()).unwrap_or(f64::NAN);
                match v.as_vector() {
                    Some(ranges) => Value::vector(&resample(
                        ranges,
                        num(&scan.angle_min),
                        num(&scan.angle_increment),
                        num(&scan.range_min),
                        num(&scan.range_max),
                        sonar,
                    )),
                    None => return Err(slot::MALFORMED),
                }
            } else {
                match (f.convert, &v) {
                    (Convert::Same, _) => v,
                    (Convert::IntToFloat, Value::Int(n)) => Value::Float(*n as f64),
                    (Convert::BoolToInt, Value::Bool(b)) => Value::Int(i64::from(*b)),
                    _ => return Err(slot::MALFORMED),
                }
            };
            values.push((f.port, v));
        }
        for (port, v) in values {
            if core.write(now, port, v).is_err() {
                return Err(slot::REFUSED);
            }
        }
        Ok(())
    }

    /// Publish every "out" topic that is due.
    fn give_out(&mut self, core: &NodeCore, now: Instant) -> Option<Instant> {
        let mut next: Option<Instant> = None;
        for o in 0..self.outputs.len() {
            let out = &mut self.outputs[o];
            let due = match out.period {
                Some(period) => {
                    let due_at = *out.next_due.get_or_insert(now);
                    if now >= due_at {
                        // A late turn skips what it missed (no burst), as periodic processes do.
                        let mut n = due_at + period;
                        if n <= now {
                            n = now + period;
                        }
                        out.next_due = Some(n);
                    }
                    let n = out.next_due.unwrap_or(now);
                    next = Some(next.map_or(n, |x| x.min(n)));
                    now >= due_at
                }
                None => {
                    let mut changed = false;
                    for (k, (_, port)) in out.fields.iter().enumerate() {
                        let accepted = core.last_accepted(*port).ok().flatten();
                        if accepted.is_some() && accepted != out.published[k] {
                            changed = true;
                        }
                    }
                    changed
                }
            };
            if !due {
                continue;
            }
            let mut sample = out.template.clone();
            for (k, (field, port)) in out.fields.iter().enumerate() {
                out.published[k] = core.last_accepted(*port).ok().flatten();
                if let Ok(v) = core.read_at(now, *port) {
                    // A value the field cannot hold (an int out of its width) leaves the
                    // template's; the publish goes on with the others.
                    let _ = sample.set(field, &v);
                }
            }
            if let Some((sec, nanosec)) = &out.stamp {
                let t = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).unwrap_or_default();
                let _ = sample.set(sec, &Value::Int(t.as_secs().min(i32::MAX as u64) as i64));
                let _ = sample.set(nanosec, &Value::Int(i64::from(t.subsec_nanos())));
            }
            let at = out.counters;
            let ok = out.publisher.publish(Encoded(sample)).is_ok();
            self.count(at + if ok { slot::PUBLISHED } else { slot::PUBLISH_FAILED }, 1);
        }
        next
    }

    /// Count, from the DDS discovery data, the remote endpoints on this body's topics that
    /// match it (`publishers`, `subscribers`: the same type and a QoS that fits; read from the
    /// participant's discovery data rather than the ROS 2 node's match events, which bodies
    /// sharing a participant drain from one channel), and those DDS will never match with it: another type, or a QoS that
    /// does not fit (a best-effort publisher for a reliable subscription, a volatile publisher
    /// for a transient-local one, ...). Their samples never arrive, so they cannot be counted
    /// as samples: they are counted as endpoints, and each is named once in a warning.
    fn matches(&mut self, core: &mut NodeCore) {
        let participant = self._context.domain_participant();
        // (topic, type name, QoS, GUID) of every remote endpoint of a kind.
        let writers: Vec<_> = participant
            .discovered_writers()
            .into_iter()
            .map(|w| {
                let d = w.publication_topic_data;
                (d.topic_name.clone(), d.type_name.clone(), d.qos(), format!("{:?}", d.key))
            })
            .collect();
        let readers: Vec<_> = participant
            .discovered_readers()
            .into_iter()
            .map(|r| {
                let d = &r.subscription_topic_data;
                (
                    d.topic_name().clone(),
                    d.type_name().clone(),
                    d.qos(),
                    format!("{:?}", r.reader_proxy.remote_reader_guid),
                )
            })
            .collect();
        for i in 0..self.inputs.len() {
            let counts = self.inputs[i].endpoint.survey(&writers, false, core);
            let at = self.inputs[i].counters + slot::PUBLISHERS;
            for (k, n) in counts.into_iter().enumerate() {
                self.set(at + k, n);
            }
        }
        for o in 0..self.outputs.len() {
            let counts = self.outputs[o].endpoint.survey(&readers, true, core);
            let at = self.outputs[o].counters + slot::SUBSCRIBERS;
            for (k, n) in counts.into_iter().enumerate() {
                self.set(at + k, n);
            }
        }
    }

    /// This body's counters by (topic, cause): what reports show as `body`.
    pub fn counters(&self) -> &[(String, u64)] {
        &self.counts
    }
}

/// Why a remote endpoint and this body's will not be matched by DDS.
#[derive(Clone, Debug)]
enum Mismatch {
    /// Its type (the DDS type name).
    Type(String),
    /// Its QoS: the policy that fails, and whether the remote is the reader.
    Qos(String),
}

impl Mismatch {
    fn describe(&self, e: &Endpoint) -> String {
        match self {
            Mismatch::Type(t) => format!(
                "its type is {} and the body's {} ({}): DDS does not match them and none of its samples arrive; \
                 map the topic with the type the robot uses",
                ros_type_name(t),
                e.ty.name(),
                e.ty.dds_type_name()
            ),
            Mismatch::Qos(what) => format!(
                "its QoS is incompatible with the body's ({what}): DDS does not match them; set the topic's qos in \
                 the mapping file to one that fits (docs/ros2.md, \"QoS\")"
            ),
        }
    }
}

/// `sensor_msgs::msg::dds_::LaserScan_` as ROS 2 writes it, `sensor_msgs/msg/LaserScan`.
fn ros_type_name(dds: &str) -> String {
    let parts: Vec<&str> = dds.split("::").collect();
    match parts.as_slice() {
        [pkg, kind, "dds_", ty] => format!("{pkg}/{kind}/{}", ty.strip_suffix('_').unwrap_or(ty)),
        _ => dds.to_owned(),
    }
}

impl Endpoint {
    fn of(t: &Topic) -> Endpoint {
        Endpoint {
            dds_topic: format!("rt{}", t.name),
            name: t.name.clone(),
            ty: t.ty,
            qos: ros2_client::dds::rustdds::QosPolicies::from(profile(&t.qos)),
            warned: Vec::new(),
        }
    }

    /// Among the remote endpoints (topic, type, QoS, GUID) of the other kind — readers when
    /// `remote_reads` — those on this topic that fit, that have another type, and whose QoS
    /// does not fit; each misfit is named in a warning once.
    fn survey(
        &mut self,
        remote: &[(String, String, ros2_client::dds::rustdds::QosPolicies, String)],
        remote_reads: bool,
        core: &mut NodeCore,
    ) -> [u64; 3] {
        let mut counts = [0u64; 3];
        for (_, type_name, qos, guid) in remote.iter().filter(|r| r.0 == self.dds_topic) {
            let Some(problem) = self.problem(type_name, qos, remote_reads) else {
                counts[0] += 1;
                continue;
            };
            counts[if matches!(problem, Mismatch::Type(_)) { 1 } else { 2 }] += 1;
            if self.warned.len() < 64 && !self.warned.contains(guid) {
                self.warned.push(guid.clone());
                let who = if remote_reads { "a subscription to" } else { "a publisher on" };
                core.warn(format!("ROS 2: {who} {}: {}", self.name, problem.describe(self)));
            }
        }
        counts
    }

    /// Whether a remote endpoint of `type_name` and `qos` fits this one; `remote_reads`: the
    /// remote endpoint is a reader (this one publishes).
    fn problem(
        &self,
        type_name: &str,
        qos: &ros2_client::dds::rustdds::QosPolicies,
        remote_reads: bool,
    ) -> Option<Mismatch> {
        if type_name != self.ty.dds_type_name() {
            return Some(Mismatch::Type(type_name.to_owned()));
        }
        let (offered, requested) = if remote_reads { (&self.qos, qos) } else { (qos, &self.qos) };
        offered.compliance_failure_wrt(requested).map(|policy| {
            let side = |mine: bool, q: &ros2_client::dds::rustdds::QosPolicies| {
                format!(
                    "{} {}, {}",
                    if mine { "the body's" } else { "its" },
                    if q.is_reliable() { "reliable" } else { "best_effort" },
                    if q.is_volatile() { "volatile" } else { "transient_local" }
                )
            };
            Mismatch::Qos(format!(
                "{policy:?}: {} against {}",
                side(false, if remote_reads { requested } else { offered }),
                side(true, if remote_reads { offered } else { requested })
            ))
        })
    }
}

/// A scan's ranges in Ayllu's sonar convention (see [`Sonar`]): beam k is the nearest valid
/// reading whose angle rounds to `k * 2π / beams`; a reading that is not a number, is infinite
/// or lies outside `[range_min, range_max]` is no return (REP 117); a beam with no return reads
/// `range_max` (infinity if the scan's `range_max` is not a positive number).
pub fn resample(
    ranges: &[f64],
    angle_min: f64,
    increment: f64,
    range_min: f64,
    range_max: f64,
    sonar: &Sonar,
) -> Vec<f64> {
    use std::f64::consts::TAU;
    let beams = sonar.beams.max(1);
    let sector = TAU / beams as f64;
    let far = if range_max.is_finite() && range_max > 0.0 { range_max } else { f64::INFINITY };
    let near = if range_min.is_finite() { range_min } else { 0.0 };
    let mut out = vec![f64::INFINITY; beams];
    if angle_min.is_finite() && increment.is_finite() {
        for (i, &r) in ranges.iter().enumerate() {
            if !(r.is_finite() && r >= near && r <= far) {
                continue;
            }
            let a = (angle_min + i as f64 * increment).rem_euclid(TAU);
            let k = ((a / sector).round() as usize) % beams;
            out[k] = out[k].min(r);
        }
    }
    for o in &mut out {
        let r = if o.is_finite() { *o } else { far };
        *o = (r - sonar.rim).max(0.0);
    }
    out
}

impl ayllu::Driver for Ros2Body {
    fn input(&mut self, core: &mut NodeCore, now: Instant) {
        self.take_in(core, now);
    }

    fn output(&mut self, core: &mut NodeCore, now: Instant) -> Option<Instant> {
        let rate_due = self.give_out(core, now);
        if now >= self.next_match {
            self.matches(core);
            self.next_match = now + MATCH_PERIOD;
        }
        if self.dirty {
            let counters = core.body_counters_mut();
            for (k, (_, n)) in self.counts.iter().enumerate() {
                if let Some(c) = counters.get_mut(self.base + k) {
                    c.1 = *n;
                }
            }
            self.dirty = false;
        }
        let poll = now + self.poll;
        Some(rate_due.map_or(poll, |d| d.min(poll)))
    }
}

impl From<CoreError> for Error {
    fn from(e: CoreError) -> Error {
        Error::Install(e.to_string())
    }
}
