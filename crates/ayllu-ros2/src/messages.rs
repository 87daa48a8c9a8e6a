//! The ROS 2 message types the ROS 2 body knows, as runtime schemas, and their CDR form.
//!
//! A topic's samples are read and written without one Rust struct per message type. A
//! [`MessageType`] is a type's layout: its fields in declaration order, exactly as ROS 2 Jazzy
//! declares them, because CDR is positional. A [`Sample`] holds one value per leaf of that
//! layout, and a [`FieldRef`], resolved once from a path such as `pose.pose.position.x` when a
//! mapping file is loaded, reads or writes one leaf as an Ayllu [`Value`].
//!
//! The bytes go through serde, into and out of the very CDR (de)serializer RustDDS uses for a
//! topic's samples: [`Decode`] is the `DeserializeSeed` for ros2-client's
//! `Subscription::take_seed`, and [`Encoded`] is what a `Publisher<Encoded>` publishes.
//!
//! ## Promises
//! * Byte-exact with ROS 2's plain CDR (XCDR1, what `rmw_fastrtps_cpp` and
//!   `rmw_cyclonedds_cpp` send): primitives aligned to their size relative to the payload's
//!   start, strings and sequences prefixed by a `uint32` length, fixed arrays not.
//! * Nothing panics on any input. A payload that cannot be decoded is an error, and its
//!   [`DecodeCause`] is left in the cell the [`Decode`] was given, since `take_seed` hands back
//!   only a generic error.
//! * Bounded allocation: a sequence longer than [`Decode::max_elements`] is refused from its
//!   length field alone, before any of it is read or allocated.
//! * What is written is what is sent: [`Sample::set`] refuses values the field cannot hold (3e9
//!   into an `int32`, a vector of 35 into a `float64[36]`) and rounds floats to the field's
//!   width, so [`Sample::get`] returns what subscribers will receive.
//!
//! ## Non-goals
//! * Types beyond the list below: there is no `.msg` parser and no type discovery.
//! * XCDR2 and keyed topics (none of these types has a key).
//! * Mapping sequences of messages (`MultiArrayLayout.dim`): they are kept so a sample
//!   round-trips, but have no [`FieldKind`].

use std::cell::Cell;
use std::fmt;
use std::marker::PhantomData;
use std::sync::Arc;

use ayllu_core::{Value, ValueType};
use serde::de::{self, DeserializeSeed, Deserializer, SeqAccess, Visitor};
use serde::ser::{self, Serialize, SerializeSeq, SerializeTuple, Serializer};

/// A ROS 2 message type this body knows: its name and the layout of its fields.
///
/// Only the types listed by [`message_types`] exist; get one with [`message_type`].
pub struct MessageType {
    name: &'static str,
    fields: &'static [Field],
    /// The static this is: samples and fields keep a `'static` reference to their type, and
    /// methods taking `&self` hand it out.
    this: &'static MessageType,
}

#[derive(Debug)]
struct Field {
    name: &'static str,
    ty: Ty,
}

/// The type of one field, as far as CDR and mapping care.
#[derive(Copy, Clone, Debug)]
enum Ty {
    Prim(Prim),
    Text,
    Struct(&'static MessageType),
    /// `float32[]`, `float64[]`: a `uint32` length, then the elements.
    Seq(Real),
    /// `float64[36]`: the elements only.
    Array(Real, usize),
    /// A sequence of messages (`MultiArrayDimension[]`).
    Structs(&'static MessageType),
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Prim {
    Bool,
    U8,
    I32,
    U32,
    I64,
    Real(Real),
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Real {
    F32,
    F64,
}

const BOOL: Ty = Ty::Prim(Prim::Bool);
const U8: Ty = Ty::Prim(Prim::U8);
const I32: Ty = Ty::Prim(Prim::I32);
const U32: Ty = Ty::Prim(Prim::U32);
const I64: Ty = Ty::Prim(Prim::I64);
const F32: Ty = Ty::Prim(Prim::Real(Real::F32));
const F64: Ty = Ty::Prim(Prim::Real(Real::F64));
const TEXT: Ty = Ty::Text;

macro_rules! message {
    ($static:ident = $name:literal { $($field:ident: $ty:expr),* $(,)? }) => {
        static $static: MessageType = MessageType {
            name: $name,
            fields: &[$(Field { name: stringify!($field), ty: $ty }),*],
            this: &$static,
        };
    };
}

// The layouts of ROS 2 Jazzy's `.msg` files (common_interfaces, rcl_interfaces), field for field.
message!(TIME = "builtin_interfaces/msg/Time" { sec: I32, nanosec: U32 });
message!(HEADER = "std_msgs/msg/Header" { stamp: Ty::Struct(&TIME), frame_id: TEXT });
message!(BOOL_MSG = "std_msgs/msg/Bool" { data: BOOL });
message!(INT32_MSG = "std_msgs/msg/Int32" { data: I32 });
message!(INT64_MSG = "std_msgs/msg/Int64" { data: I64 });
message!(FLOAT32_MSG = "std_msgs/msg/Float32" { data: F32 });
message!(FLOAT64_MSG = "std_msgs/msg/Float64" { data: F64 });
message!(STRING_MSG = "std_msgs/msg/String" { data: TEXT });
message!(DIMENSION = "std_msgs/msg/MultiArrayDimension" { label: TEXT, size: U32, stride: U32 });
message!(LAYOUT = "std_msgs/msg/MultiArrayLayout" { dim: Ty::Structs(&DIMENSION), data_offset: U32 });
message!(FLOAT64_ARRAY = "std_msgs/msg/Float64MultiArray" { layout: Ty::Struct(&LAYOUT), data: Ty::Seq(Real::F64) });
message!(VECTOR3 = "geometry_msgs/msg/Vector3" { x: F64, y: F64, z: F64 });
message!(POINT = "geometry_msgs/msg/Point" { x: F64, y: F64, z: F64 });
message!(QUATERNION = "geometry_msgs/msg/Quaternion" { x: F64, y: F64, z: F64, w: F64 });
message!(POSE = "geometry_msgs/msg/Pose" { position: Ty::Struct(&POINT), orientation: Ty::Struct(&QUATERNION) });
message!(POSE2D = "geometry_msgs/msg/Pose2D" { x: F64, y: F64, theta: F64 });
message!(POSE_STAMPED = "geometry_msgs/msg/PoseStamped" { header: Ty::Struct(&HEADER), pose: Ty::Struct(&POSE) });
message!(POINT_STAMPED = "geometry_msgs/msg/PointStamped" { header: Ty::Struct(&HEADER), point: Ty::Struct(&POINT) });
message!(TWIST = "geometry_msgs/msg/Twist" { linear: Ty::Struct(&VECTOR3), angular: Ty::Struct(&VECTOR3) });
message!(TWIST_STAMPED = "geometry_msgs/msg/TwistStamped" { header: Ty::Struct(&HEADER), twist: Ty::Struct(&TWIST) });
message!(POSE_COV = "geometry_msgs/msg/PoseWithCovariance" {
    pose: Ty::Struct(&POSE),
    covariance: Ty::Array(Real::F64, 36),
});
message!(TWIST_COV = "geometry_msgs/msg/TwistWithCovariance" {
    twist: Ty::Struct(&TWIST),
    covariance: Ty::Array(Real::F64, 36),
});
message!(LASER_SCAN = "sensor_msgs/msg/LaserScan" {
    header: Ty::Struct(&HEADER),
    angle_min: F32, angle_max: F32, angle_increment: F32, time_increment: F32, scan_time: F32,
    range_min: F32, range_max: F32,
    ranges: Ty::Seq(Real::F32), intensities: Ty::Seq(Real::F32),
});
// `variance` arrived in Iron (common_interfaces 5.0): a Jazzy peer sends and expects it.
message!(RANGE = "sensor_msgs/msg/Range" {
    header: Ty::Struct(&HEADER),
    radiation_type: U8, field_of_view: F32, min_range: F32, max_range: F32, range: F32, variance: F32,
});
message!(ODOMETRY = "nav_msgs/msg/Odometry" {
    header: Ty::Struct(&HEADER),
    child_frame_id: TEXT,
    pose: Ty::Struct(&POSE_COV),
    twist: Ty::Struct(&TWIST_COV),
});

static TYPES: [&MessageType; 25] = [
    &TIME,
    &HEADER,
    &BOOL_MSG,
    &INT32_MSG,
    &INT64_MSG,
    &FLOAT32_MSG,
    &FLOAT64_MSG,
    &STRING_MSG,
    &DIMENSION,
    &LAYOUT,
    &FLOAT64_ARRAY,
    &VECTOR3,
    &POINT,
    &QUATERNION,
    &POSE,
    &POSE2D,
    &POSE_STAMPED,
    &POINT_STAMPED,
    &TWIST,
    &TWIST_STAMPED,
    &POSE_COV,
    &TWIST_COV,
    &LASER_SCAN,
    &RANGE,
    &ODOMETRY,
];

/// The message type called `name` in ROS 2's spelling, `"sensor_msgs/msg/LaserScan"`, if
/// this body knows it.
pub fn message_type(name: &str) -> Option<&'static MessageType> {
    TYPES.iter().copied().find(|t| t.name == name)
}

/// Every message type this body knows, for error messages that list them.
pub fn message_types() -> impl Iterator<Item = &'static MessageType> {
    TYPES.iter().copied()
}

// Types are told apart by name; printing one in full would drown what is being debugged.
impl fmt::Debug for MessageType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("MessageType").field(&self.name).finish()
    }
}

impl PartialEq for MessageType {
    fn eq(&self, other: &MessageType) -> bool {
        self.name == other.name
    }
}

impl Eq for MessageType {}

impl MessageType {
    /// The ROS 2 name, `"sensor_msgs/msg/LaserScan"`.
    pub fn name(&self) -> &'static str {
        self.name
    }

    /// The package, `"sensor_msgs"`.
    pub fn package(&self) -> &'static str {
        self.name.split_once('/').map_or(self.name, |(package, _)| package)
    }

    /// The type's own name, `"LaserScan"`.
    pub fn short_name(&self) -> &'static str {
        self.name.rsplit_once('/').map_or(self.name, |(_, short)| short)
    }

    /// The name DDS knows the type by, `"sensor_msgs::msg::dds_::LaserScan_"`: the one
    /// `rosidl` generates, which peers match topics on.
    pub fn dds_type_name(&self) -> String {
        format!("{}::msg::dds_::{}_", self.package(), self.short_name())
    }

    /// Resolves a dotted path to one leaf: `"ranges"`, `"pose.pose.position.x"`,
    /// `"header.stamp.sec"`. Below every `geometry_msgs/msg/Quaternion` there is also the
    /// virtual leaf `yaw` (`"pose.pose.orientation.yaw"`), read from the quaternion and written
    /// as the rotation about z alone.
    ///
    /// A path that names nothing gets the nearest leaf as a suggestion; a path to a message
    /// rather than a leaf is told the leaves under it.
    pub fn field(&self, path: &str) -> Result<FieldRef, FieldError> {
        let (mut within, mut fields, mut index) = (self.name, self.fields, 0);
        let mut segments = path.split('.').peekable();
        while let Some(segment) = segments.next() {
            let last = segments.peek().is_none();
            let Some(at) = fields.iter().position(|f| f.name == segment) else {
                if segment == "yaw" && last && within == QUATERNION.name {
                    return Ok(FieldRef { ty: self.this, index, leaf: Leaf::Yaw });
                }
                break;
            };
            index += fields.iter().take(at).map(|f| f.ty.slots()).sum::<usize>();
            let leaf = match fields[at].ty {
                Ty::Struct(m) if last => return Err(self.not_a_leaf(path, m)),
                Ty::Struct(m) => {
                    (within, fields) = (m.name, m.fields);
                    continue;
                }
                Ty::Structs(m) => {
                    let message = format!("is in a sequence of {} messages, and those cannot be mapped", m.name);
                    return Err(FieldError { path: path.to_string(), message, suggestion: None });
                }
                Ty::Prim(p) => Leaf::Prim(p),
                Ty::Text => Leaf::Text,
                Ty::Seq(r) => Leaf::Seq(r),
                Ty::Array(r, n) => Leaf::Array(r, n),
            };
            if last {
                return Ok(FieldRef { ty: self.this, index, leaf });
            }
            break;
        }
        let leaves = self.leaves();
        Err(FieldError {
            path: path.to_string(),
            message: format!("is not a field of {}", self.name),
            suggestion: suggest(path, &leaves),
        })
    }

    fn not_a_leaf(&self, path: &str, m: &MessageType) -> FieldError {
        let under: Vec<String> =
            self.leaves().into_iter().filter(|l| l.strip_prefix(path).is_some_and(|r| r.starts_with('.'))).collect();
        let message = format!("is a {}, not a single value: map one of `{}`", m.name, under.join("`, `"));
        FieldError { path: path.to_string(), message, suggestion: None }
    }

    /// Every path [`field`](Self::field) resolves, in layout order: what a mapping can name,
    /// and what "did you mean" suggestions are drawn from.
    pub fn leaves(&self) -> Vec<String> {
        fn walk(m: &MessageType, prefix: &str, out: &mut Vec<String>) {
            let path = |name: &str| if prefix.is_empty() { name.to_string() } else { format!("{prefix}.{name}") };
            for f in m.fields {
                match f.ty {
                    Ty::Struct(inner) => walk(inner, &path(f.name), out),
                    Ty::Structs(_) => {}
                    _ => out.push(path(f.name)),
                }
            }
            if m.name == QUATERNION.name {
                out.push(path("yaw"));
            }
        }
        let mut out = Vec::new();
        walk(self, "", &mut out);
        out
    }

    /// A sample with every number zero, every string and sequence empty, and every quaternion
    /// the identity (`w = 1`, as ROS 2 declares it), ready to be filled with [`Sample::set`].
    pub fn default_sample(&self) -> Sample {
        fn fill(m: &MessageType, out: &mut Vec<Slot>) {
            for f in m.fields {
                out.push(match f.ty {
                    Ty::Struct(inner) => {
                        fill(inner, out);
                        continue;
                    }
                    Ty::Prim(Prim::Bool) => Slot::Bool(false),
                    Ty::Prim(Prim::Real(_)) => Slot::Float(0.0),
                    Ty::Prim(_) => Slot::Int(0),
                    Ty::Text => Slot::Text(Arc::from("")),
                    Ty::Seq(_) => Slot::Floats(Arc::from(Vec::new())),
                    Ty::Array(_, n) => Slot::Floats(Arc::from(vec![0.0; n])),
                    Ty::Structs(_) => Slot::Records(Vec::new()),
                });
            }
            if m.name == QUATERNION.name {
                if let Some(Slot::Float(w)) = out.last_mut() {
                    *w = 1.0;
                }
            }
        }
        let mut slots = Vec::with_capacity(self.slots());
        fill(self, &mut slots);
        Sample { ty: self.this, slots }
    }

    /// How many slots a sample of this type has: one per leaf, nested messages flattened.
    fn slots(&self) -> usize {
        self.fields.iter().map(|f| f.ty.slots()).sum()
    }

    /// How many items the decoder reads for one of these: one per field, plus one for the
    /// length of each sequence (see [`Fields`]).
    fn items(&self) -> usize {
        self.fields.iter().map(|f| if matches!(f.ty, Ty::Seq(_) | Ty::Structs(_)) { 2 } else { 1 }).sum()
    }
}

impl Ty {
    fn slots(self) -> usize {
        match self {
            Ty::Struct(m) => m.slots(),
            _ => 1,
        }
    }
}

/// The nearest leaf to a mistyped path, if one is near enough to be what was meant.
fn suggest(path: &str, leaves: &[String]) -> Option<String> {
    // The commonest slip is a path missing its outer parts (`position.x` in an Odometry):
    // a single leaf ending in it is surely what was meant.
    let mut tails = leaves.iter().filter(|l| l.strip_suffix(path).is_some_and(|head| head.ends_with('.')));
    if let (Some(only), None) = (tails.next(), tails.next()) {
        return Some(only.clone());
    }
    // Otherwise a typo of one (the mapping file's rule for every "did you mean").
    if path.chars().count() > 256 {
        return None;
    }
    crate::mapping::closest(path, leaves.iter().map(String::as_str)).map(str::to_owned)
}

/// A path that does not name a leaf of a message type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldError {
    /// The path as given.
    pub path: String,
    /// What is wrong, worded to follow the path: "is not a field of nav_msgs/msg/Odometry".
    pub message: String,
    /// The leaf probably meant, when one is close.
    pub suggestion: Option<String>,
}

impl fmt::Display for FieldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` {}", self.path, self.message)?;
        match &self.suggestion {
            Some(s) => write!(f, ": did you mean `{s}`?"),
            None => Ok(()),
        }
    }
}

impl std::error::Error for FieldError {}

/// One leaf of one message type, resolved by [`MessageType::field`]: read and written with
/// [`Sample::get`] and [`Sample::set`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldRef {
    ty: &'static MessageType,
    index: usize,
    leaf: Leaf,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Leaf {
    Prim(Prim),
    Text,
    Seq(Real),
    Array(Real, usize),
    /// Index is the quaternion's `x`; `y`, `z`, `w` follow.
    Yaw,
}

/// What kind of Ayllu value a leaf reads as and accepts.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum FieldKind {
    /// `bool`: a [`Value::Bool`].
    Bool,
    /// Any integer width: a [`Value::Int`] (a `Value::Bool` is accepted as 0 or 1).
    Int,
    /// `float32` or `float64`: a [`Value::Float`] (a `Value::Int` is accepted).
    Float,
    /// `string`: a [`Value::Text`].
    Text,
    /// A numeric sequence or fixed-size array: a [`Value::Vector`].
    Floats,
    /// The yaw of a quaternion, in radians in (-π, π]: a [`Value::Float`].
    Yaw,
}

impl FieldRef {
    /// What kind of value the leaf reads as and accepts.
    pub fn kind(&self) -> FieldKind {
        match self.leaf {
            Leaf::Prim(Prim::Bool) => FieldKind::Bool,
            Leaf::Prim(Prim::Real(_)) => FieldKind::Float,
            Leaf::Prim(_) => FieldKind::Int,
            Leaf::Text => FieldKind::Text,
            Leaf::Seq(_) | Leaf::Array(..) => FieldKind::Floats,
            Leaf::Yaw => FieldKind::Yaw,
        }
    }

    /// The leaf's type as a `.msg` file spells it (`"float32[]"`, `"float64[36]"`, `"uint8"`),
    /// for error messages.
    pub fn ros_type(&self) -> String {
        self.leaf.to_string()
    }

    /// The message type the leaf belongs to.
    pub fn message_type(&self) -> &'static MessageType {
        self.ty
    }
}

impl fmt::Display for Leaf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let real = |r: Real| if r == Real::F32 { "float32" } else { "float64" };
        match *self {
            Leaf::Prim(Prim::Bool) => f.write_str("bool"),
            Leaf::Prim(Prim::U8) => f.write_str("uint8"),
            Leaf::Prim(Prim::I32) => f.write_str("int32"),
            Leaf::Prim(Prim::U32) => f.write_str("uint32"),
            Leaf::Prim(Prim::I64) => f.write_str("int64"),
            Leaf::Prim(Prim::Real(r)) => f.write_str(real(r)),
            Leaf::Text => f.write_str("string"),
            Leaf::Seq(r) => write!(f, "{}[]", real(r)),
            Leaf::Array(r, n) => write!(f, "{}[{n}]", real(r)),
            Leaf::Yaw => f.write_str("yaw (of a quaternion)"),
        }
    }
}

/// One message's values: one per leaf of its type, in layout order.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    ty: &'static MessageType,
    slots: Vec<Slot>,
}

/// One leaf's value. Integers of every width are kept as `i64` and floats as `f64`, always
/// within the field's range and (for `float32`) exactly representable in it.
#[derive(Clone, Debug, PartialEq)]
enum Slot {
    Bool(bool),
    Int(i64),
    Float(f64),
    Text(Arc<str>),
    Floats(Arc<[f64]>),
    /// A sequence of messages: each element's slots.
    Records(Vec<Vec<Slot>>),
}

impl Sample {
    /// The message type this is a sample of.
    pub fn message_type(&self) -> &'static MessageType {
        self.ty
    }

    /// The leaf's value: a bool, an integer, a float, text, or a vector for numeric arrays;
    /// `None` only for a field of another message type.
    pub fn get(&self, f: &FieldRef) -> Option<Value> {
        if f.ty != self.ty {
            return None;
        }
        if f.leaf == Leaf::Yaw {
            return self.quaternion(f.index).map(|q| Value::Float(yaw(q)));
        }
        Some(match self.slots.get(f.index)? {
            Slot::Bool(b) => Value::Bool(*b),
            Slot::Int(i) => Value::Int(*i),
            Slot::Float(x) => Value::Float(*x),
            Slot::Text(s) => Value::Text(s.clone()),
            Slot::Floats(xs) => Value::Vector(xs.clone()),
            Slot::Records(_) => return None,
        })
    }

    /// Writes the leaf, converting `v` to the field's type: a float to `float32` (rounded) or
    /// `float64`, an integer or bool to any integer width that holds it, an integer to a float,
    /// text to a string, a vector to a numeric sequence (or to a fixed array of its exact
    /// length). A yaw rewrites the whole quaternion as the rotation about z alone. Anything
    /// else is refused and leaves the sample unchanged.
    pub fn set(&mut self, f: &FieldRef, v: &Value) -> Result<(), SetError> {
        if f.ty != self.ty {
            return Err(SetError::OtherMessage { field_of: f.ty.name, sample_of: self.ty.name });
        }
        let wrong_type = || SetError::WrongType { field: f.leaf.to_string(), value: v.ty() };
        let out_of_range = || SetError::OutOfRange { field: f.leaf.to_string(), value: v.to_string() };
        let number = match *v {
            Value::Float(x) => Some(x),
            Value::Int(i) => Some(i as f64),
            _ => None,
        };
        let slot = match (f.leaf, v, number) {
            (Leaf::Yaw, _, Some(yaw)) if yaw.is_finite() => {
                let (sin, cos) = (yaw / 2.0).sin_cos();
                let quaternion = self.slots.get_mut(f.index..f.index + 4).ok_or_else(wrong_type)?;
                quaternion.clone_from_slice(&[0.0, 0.0, sin, cos].map(Slot::Float));
                return Ok(());
            }
            (Leaf::Yaw, _, Some(_)) => return Err(out_of_range()),
            (Leaf::Prim(Prim::Real(r)), _, Some(x)) => Slot::Float(to_real(r, x).ok_or_else(out_of_range)?),
            (Leaf::Prim(Prim::Bool), Value::Bool(b), _) => Slot::Bool(*b),
            (Leaf::Prim(p), Value::Int(i), _) if p != Prim::Bool && !fits(p, *i) => return Err(out_of_range()),
            (Leaf::Prim(p), Value::Int(i), _) if p != Prim::Bool => Slot::Int(*i),
            (Leaf::Prim(p), Value::Bool(b), _) if fits(p, 1) => Slot::Int(i64::from(*b)),
            (Leaf::Text, Value::Text(s), _) => Slot::Text(s.clone()),
            (Leaf::Array(_, n), Value::Vector(xs), _) if xs.len() != n => {
                return Err(SetError::WrongLength { expected: n, got: xs.len() })
            }
            (Leaf::Seq(Real::F64) | Leaf::Array(Real::F64, _), Value::Vector(xs), _) => Slot::Floats(xs.clone()),
            (Leaf::Seq(r) | Leaf::Array(r, _), Value::Vector(xs), _) => Slot::Floats(
                xs.iter().map(|x| to_real(r, *x)).collect::<Option<Arc<[f64]>>>().ok_or_else(out_of_range)?,
            ),
            _ => return Err(wrong_type()),
        };
        *self.slots.get_mut(f.index).ok_or_else(wrong_type)? = slot;
        Ok(())
    }

    fn quaternion(&self, at: usize) -> Option<[f64; 4]> {
        match self.slots.get(at..at + 4)? {
            [Slot::Float(x), Slot::Float(y), Slot::Float(z), Slot::Float(w)] => Some([*x, *y, *z, *w]),
            _ => None,
        }
    }
}

/// `x` at the field's width; `None` for a finite number a `float32` would make infinite.
fn to_real(r: Real, x: f64) -> Option<f64> {
    match r {
        Real::F64 => Some(x),
        Real::F32 => {
            let y = x as f32;
            (y.is_finite() || !x.is_finite()).then_some(f64::from(y))
        }
    }
}

fn fits(p: Prim, i: i64) -> bool {
    match p {
        Prim::U8 => u8::try_from(i).is_ok(),
        Prim::I32 => i32::try_from(i).is_ok(),
        Prim::U32 => u32::try_from(i).is_ok(),
        Prim::I64 => true,
        Prim::Bool | Prim::Real(_) => false,
    }
}

/// The rotation about z, from any quaternion, normalized or not (both terms scale by |q|²).
fn yaw([x, y, z, w]: [f64; 4]) -> f64 {
    (2.0 * (w * z + x * y)).atan2(w * w + x * x - y * y - z * z)
}

/// Why [`Sample::set`] refused a value.
#[derive(Clone, Debug, PartialEq)]
pub enum SetError {
    /// The value's type does not convert to the field's (a float into an `int32`, text into
    /// a `float64[]`).
    WrongType {
        /// The field's type, as a `.msg` file spells it.
        field: String,
        /// The type of the value offered.
        value: ValueType,
    },
    /// A number the field cannot hold: 3e9 into an `int32`, -1 into a `uint8`, 1e39 into a
    /// `float32`, a non-finite yaw.
    OutOfRange {
        /// The field's type, as a `.msg` file spells it.
        field: String,
        /// The value offered.
        value: String,
    },
    /// A vector of another length for a fixed-size array.
    WrongLength {
        /// The array's length.
        expected: usize,
        /// The vector's length.
        got: usize,
    },
    /// The field was resolved on another message type than the sample's.
    OtherMessage {
        /// The field's message type.
        field_of: &'static str,
        /// The sample's message type.
        sample_of: &'static str,
    },
}

impl fmt::Display for SetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetError::WrongType { field, value } => write!(f, "a {value} cannot go into a {field} field"),
            SetError::OutOfRange { field, value } => write!(f, "{value} is out of range for a {field} field"),
            SetError::WrongLength { expected, got } => {
                write!(f, "a vector of {got} cannot go into an array of exactly {expected}")
            }
            SetError::OtherMessage { field_of, sample_of } => {
                write!(f, "a field of {field_of} cannot be set in a {sample_of}")
            }
        }
    }
}

impl std::error::Error for SetError {}

/// Why a payload could not be decoded, left in [`Decode::cause`].
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum DecodeCause {
    /// The payload ended before the message did.
    Truncated,
    /// A sequence longer than [`Decode::max_elements`], refused from its length field.
    TooLong,
    /// A string that is not UTF-8.
    BadText,
    /// Anything else: a bool neither 0 nor 1, a string without its NUL terminator.
    Malformed,
}

impl DecodeCause {
    /// The cause's name for counters and logs (`too_long`).
    pub fn name(self) -> &'static str {
        match self {
            DecodeCause::Truncated => "truncated",
            DecodeCause::TooLong => "too_long",
            DecodeCause::BadText => "bad_text",
            DecodeCause::Malformed => "malformed",
        }
    }
}

impl fmt::Display for DecodeCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Decodes one sample of `ty` from the CDR deserializer RustDDS hands it: the seed for
/// `Subscription::<Sample>::take_seed`.
///
/// On failure the cause is left in `cause`. Reset it before each take: a payload in an
/// encoding RustDDS does not decode never reaches the seed, and fails with the cell untouched.
#[derive(Copy, Clone, Debug)]
pub struct Decode<'a> {
    /// The type the topic carries.
    pub ty: &'static MessageType,
    /// The most elements a sequence may have; a longer one is refused (`TooLong`) from its
    /// length field, before anything is allocated for it.
    pub max_elements: usize,
    /// Where the cause of a failed decode is left.
    pub cause: &'a Cell<Option<DecodeCause>>,
}

/// A lying length must not make a large allocation before the payload runs out: vectors
/// start at most this big and grow as elements actually arrive.
const PREALLOCATE: usize = 4096;

impl Decode<'_> {
    fn fail<E: de::Error>(&self, cause: DecodeCause, message: impl fmt::Display) -> E {
        self.cause.set(Some(cause));
        E::custom(message)
    }
}

impl<'de> DeserializeSeed<'de> for Decode<'_> {
    type Value = Sample;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Sample, D::Error> {
        self.cause.set(None);
        let mut slots = Vec::with_capacity(self.ty.slots());
        let read = Fields { ty: self.ty, ctx: self, out: &mut slots }.deserialize(d);
        if read.is_err() && self.cause.get().is_none() {
            self.cause.set(Some(DecodeCause::Malformed));
        }
        read.map(|()| Sample { ty: self.ty, slots })
    }
}

/// The next item of a tuple. Every error this module raises records its cause first, so an
/// error without one came from the CDR deserializer itself, whose reads of numbers, lengths
/// and byte runs fail only when the payload runs out.
fn next<'de, A: SeqAccess<'de>, S: DeserializeSeed<'de>>(
    seq: &mut A,
    ctx: Decode<'_>,
    seed: S,
) -> Result<S::Value, A::Error> {
    match seq.next_element_seed(seed) {
        Ok(Some(v)) => Ok(v),
        Ok(None) => Err(ctx.fail(DecodeCause::Malformed, "the deserializer ended a tuple early")),
        Err(e) => {
            if ctx.cause.get().is_none() {
                ctx.cause.set(Some(DecodeCause::Truncated));
            }
            Err(e)
        }
    }
}

/// A sequence's length, refused if over the limit.
///
/// CDR's `deserialize_seq` reads the length itself and hides it (its `SeqAccess` gives no
/// `size_hint`), so it is read here as the `uint32` it is, and the elements as a tuple of that
/// length: the same bytes, but the length is known before the first element.
fn length<'de, A: SeqAccess<'de>>(seq: &mut A, ctx: Decode<'_>) -> Result<usize, A::Error> {
    let len = next(seq, ctx, PhantomData::<u32>)?;
    match usize::try_from(len) {
        Ok(n) if n <= ctx.max_elements => Ok(n),
        _ => Err(ctx.fail(DecodeCause::TooLong, format_args!("a sequence of {len}, over {}", ctx.max_elements))),
    }
}

/// Reads one message's fields, appending their slots.
struct Fields<'s, 'a> {
    ty: &'static MessageType,
    ctx: Decode<'a>,
    out: &'s mut Vec<Slot>,
}

impl<'de> DeserializeSeed<'de> for Fields<'_, '_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        // A CDR struct is its fields back to back, exactly what a tuple is.
        d.deserialize_tuple(self.ty.items(), self)
    }
}

impl<'de> Visitor<'de> for Fields<'_, '_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "a {}", self.ty.name)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let Fields { ty, ctx, out } = self;
        for f in ty.fields {
            let slot = match f.ty {
                Ty::Struct(m) => {
                    next(&mut seq, ctx, Fields { ty: m, ctx, out: &mut *out })?;
                    continue;
                }
                Ty::Prim(p) => next(&mut seq, ctx, PrimSeed(p, ctx))?,
                Ty::Text => next(&mut seq, ctx, TextSeed(ctx))?,
                Ty::Array(real, len) => Slot::Floats(next(&mut seq, ctx, Reals { real, len, ctx })?),
                Ty::Seq(real) => {
                    let len = length(&mut seq, ctx)?;
                    Slot::Floats(next(&mut seq, ctx, Reals { real, len, ctx })?)
                }
                Ty::Structs(m) => {
                    let len = length(&mut seq, ctx)?;
                    Slot::Records(next(&mut seq, ctx, Records { ty: m, len, ctx })?)
                }
            };
            out.push(slot);
        }
        Ok(())
    }
}

struct PrimSeed<'a>(Prim, Decode<'a>);

impl<'de> DeserializeSeed<'de> for PrimSeed<'_> {
    type Value = Slot;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Slot, D::Error> {
        use serde::Deserialize;
        Ok(match self.0 {
            // Read as the byte it is, so a bad value is told apart from a short payload.
            Prim::Bool => match u8::deserialize(d)? {
                0 => Slot::Bool(false),
                1 => Slot::Bool(true),
                b => return Err(self.1.fail(DecodeCause::Malformed, format_args!("{b} is not a bool"))),
            },
            Prim::U8 => Slot::Int(u8::deserialize(d)?.into()),
            Prim::I32 => Slot::Int(i32::deserialize(d)?.into()),
            Prim::U32 => Slot::Int(u32::deserialize(d)?.into()),
            Prim::I64 => Slot::Int(i64::deserialize(d)?),
            Prim::Real(Real::F32) => Slot::Float(f32::deserialize(d)?.into()),
            Prim::Real(Real::F64) => Slot::Float(f64::deserialize(d)?),
        })
    }
}

struct TextSeed<'a>(Decode<'a>);

impl<'de> DeserializeSeed<'de> for TextSeed<'_> {
    type Value = Slot;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Slot, D::Error> {
        // A CDR string is a byte run whose length counts the NUL: read as bytes, so that
        // invalid UTF-8 is told apart from a short payload.
        d.deserialize_bytes(self)
    }
}

impl<'de> Visitor<'de> for TextSeed<'_> {
    type Value = Slot;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a string")
    }

    fn visit_bytes<E: de::Error>(self, bytes: &[u8]) -> Result<Slot, E> {
        let text = match bytes.split_last() {
            // Length 0 is not valid CDR but some DDSs send it for "": RustDDS accepts it too.
            None => bytes,
            Some((0, text)) => text,
            Some(_) => return Err(self.0.fail(DecodeCause::Malformed, "a string without its NUL")),
        };
        match std::str::from_utf8(text) {
            Ok(s) => Ok(Slot::Text(Arc::from(s))),
            Err(_) => Err(self.0.fail(DecodeCause::BadText, "a string that is not UTF-8")),
        }
    }
}

/// `len` floats, back to back (the length, if any, already read).
struct Reals<'a> {
    real: Real,
    len: usize,
    ctx: Decode<'a>,
}

impl<'de> DeserializeSeed<'de> for Reals<'_> {
    type Value = Arc<[f64]>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Arc<[f64]>, D::Error> {
        d.deserialize_tuple(self.len, self)
    }
}

impl<'de> Visitor<'de> for Reals<'_> {
    type Value = Arc<[f64]>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} floats", self.len)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Arc<[f64]>, A::Error> {
        let mut xs = Vec::with_capacity(self.len.min(PREALLOCATE));
        for _ in 0..self.len {
            xs.push(match self.real {
                Real::F32 => f64::from(next(&mut seq, self.ctx, PhantomData::<f32>)?),
                Real::F64 => next(&mut seq, self.ctx, PhantomData::<f64>)?,
            });
        }
        Ok(Arc::from(xs))
    }
}

/// `len` messages of type `ty`, back to back.
struct Records<'a> {
    ty: &'static MessageType,
    len: usize,
    ctx: Decode<'a>,
}

impl<'de> DeserializeSeed<'de> for Records<'_> {
    type Value = Vec<Vec<Slot>>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_tuple(self.len, self)
    }
}

impl<'de> Visitor<'de> for Records<'_> {
    type Value = Vec<Vec<Slot>>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.len, self.ty.name)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut records = Vec::with_capacity(self.len.min(PREALLOCATE));
        for _ in 0..self.len {
            let mut record = Vec::with_capacity(self.ty.slots());
            next(&mut seq, self.ctx, Fields { ty: self.ty, ctx: self.ctx, out: &mut record })?;
            records.push(record);
        }
        Ok(records)
    }
}

/// A sample to publish: serializes as its type's CDR, for `Publisher<Encoded>::publish`.
#[derive(Clone, Debug, PartialEq)]
pub struct Encoded(pub Sample);

impl From<Sample> for Encoded {
    fn from(sample: Sample) -> Encoded {
        Encoded(sample)
    }
}

impl Serialize for Encoded {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        Item { ty: Ty::Struct(self.0.ty), slots: &self.0.slots }.serialize(s)
    }
}

/// One field (or a whole message) and its slots.
struct Item<'s> {
    ty: Ty,
    slots: &'s [Slot],
}

impl Serialize for Item<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // A Sample's slots always match its type (they are only made by default_sample,
        // Decode and set), so the errors below are never raised; they keep a bug from
        // becoming a panic or a wrong message.
        let mismatch = || ser::Error::custom("the sample does not match its message type");
        let too_long = || ser::Error::custom("over 2^32 - 1 elements, more than CDR can say");
        match (self.ty, self.slots) {
            (Ty::Struct(m), slots) => {
                let mut tuple = s.serialize_tuple(m.fields.len())?;
                let mut rest = slots;
                for f in m.fields {
                    let (here, tail) = rest.split_at_checked(f.ty.slots()).ok_or_else(mismatch)?;
                    tuple.serialize_element(&Item { ty: f.ty, slots: here })?;
                    rest = tail;
                }
                if !rest.is_empty() {
                    return Err(mismatch());
                }
                tuple.end()
            }
            (Ty::Prim(Prim::Bool), [Slot::Bool(b)]) => s.serialize_bool(*b),
            (Ty::Prim(Prim::U8), [Slot::Int(i)]) => s.serialize_u8(u8::try_from(*i).map_err(|_| mismatch())?),
            (Ty::Prim(Prim::I32), [Slot::Int(i)]) => s.serialize_i32(i32::try_from(*i).map_err(|_| mismatch())?),
            (Ty::Prim(Prim::U32), [Slot::Int(i)]) => s.serialize_u32(u32::try_from(*i).map_err(|_| mismatch())?),
            (Ty::Prim(Prim::I64), [Slot::Int(i)]) => s.serialize_i64(*i),
            (Ty::Prim(Prim::Real(Real::F32)), [Slot::Float(x)]) => s.serialize_f32(*x as f32),
            (Ty::Prim(Prim::Real(Real::F64)), [Slot::Float(x)]) => s.serialize_f64(*x),
            // The length written counts the NUL, so one less than u32::MAX is the most.
            (Ty::Text, [Slot::Text(t)]) if t.len() < u32::MAX as usize => s.serialize_str(t),
            (Ty::Text, [Slot::Text(_)]) => Err(too_long()),
            (Ty::Seq(real), [Slot::Floats(xs)]) => {
                let len = u32::try_from(xs.len()).map_err(|_| too_long())?;
                let mut seq = s.serialize_seq(Some(len as usize))?;
                for x in xs.iter() {
                    match real {
                        Real::F32 => seq.serialize_element(&(*x as f32))?,
                        Real::F64 => seq.serialize_element(x)?,
                    }
                }
                seq.end()
            }
            (Ty::Array(real, n), [Slot::Floats(xs)]) if xs.len() == n => {
                let mut tuple = s.serialize_tuple(n)?;
                for x in xs.iter() {
                    match real {
                        Real::F32 => tuple.serialize_element(&(*x as f32))?,
                        Real::F64 => tuple.serialize_element(x)?,
                    }
                }
                tuple.end()
            }
            (Ty::Structs(m), [Slot::Records(records)]) => {
                let len = u32::try_from(records.len()).map_err(|_| too_long())?;
                let mut seq = s.serialize_seq(Some(len as usize))?;
                for record in records {
                    seq.serialize_element(&Item { ty: Ty::Struct(m), slots: record })?;
                }
                seq.end()
            }
            _ => Err(mismatch()),
        }
    }
}
