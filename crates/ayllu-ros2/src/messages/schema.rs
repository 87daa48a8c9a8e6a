//! The message types this body knows, as data: each type's fields in declaration order,
//! exactly as ROS 2 Jazzy's `.msg` files declare them, because CDR is positional.
//!
//! Adding a type is a `message!` line and an entry in the table: the other parts of
//! [`crate::messages`] walk any layout, so none of them names a type (the quaternion aside,
//! whose yaw is a leaf of its own). Promise: a [`MessageType`] is a `'static` that never
//! changes, and two are equal when their names are.

use std::fmt;

/// A ROS 2 message type this body knows: its name and the layout of its fields.
///
/// Only the types listed by [`message_types`] exist; get one with [`message_type`].
pub struct MessageType {
    pub(super) name: &'static str,
    pub(super) fields: &'static [Field],
    /// The static this is: samples and fields keep a `'static` reference to their type, and
    /// methods taking `&self` hand it out.
    pub(super) this: &'static MessageType,
}

#[derive(Debug)]
pub(super) struct Field {
    pub(super) name: &'static str,
    pub(super) ty: Ty,
}

/// The type of one field, as far as CDR and mapping care.
#[derive(Copy, Clone, Debug)]
pub(super) enum Ty {
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
pub(super) enum Prim {
    Bool,
    U8,
    I32,
    U32,
    I64,
    Real(Real),
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Real {
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
    ($vis:vis $static:ident = $name:literal { $($field:ident: $ty:expr),* $(,)? }) => {
        $vis static $static: MessageType = MessageType {
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
message!(pub(super) QUATERNION = "geometry_msgs/msg/Quaternion" { x: F64, y: F64, z: F64, w: F64 });
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

    /// How many slots a sample of this type has: one per leaf, nested messages flattened.
    pub(super) fn slots(&self) -> usize {
        self.fields.iter().map(|f| f.ty.slots()).sum()
    }
}

impl Ty {
    pub(super) fn slots(self) -> usize {
        match self {
            Ty::Struct(m) => m.slots(),
            _ => 1,
        }
    }
}
