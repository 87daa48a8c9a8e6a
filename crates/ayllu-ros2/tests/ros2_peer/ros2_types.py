#!/usr/bin/env python3
"""ROS 2 Jazzy message types, topic names and QoS profiles for Cyclone DDS (Python).

What it is for: the test peers in this folder (robot.py, peer.py, topics.py)
speak to the Ayllu ROS 2 body exactly as a ROS 2 node on rmw_cyclonedds_cpp
would, without ROS 2 installed. This module is the only place that knows the
wire conventions.

What it promises:

* Each class is a Cyclone IDL struct with the DDS type name ROS 2 gives the
  message (`pkg::msg::dds_::Type_`) and its fields in the order of the ROS 2
  .msg file, so the CDR bytes are those of a ROS 2 node. Types are keyless and
  `final`, and written as XCDR1 (plain CDR, encapsulation CDR_LE), which is
  what rmw_cyclonedds_cpp writes.
* `ros_topic_to_dds("/robot1/scan") == "rt/robot1/scan"` (ROS 2's `rt/`
  prefix for topics) and the inverse `dds_topic_to_ros`.
* `qos_default()` is ROS 2's default profile (reliable, volatile, keep last
  10) and `qos_sensor_data()` its sensor-data profile (best effort, volatile,
  keep last 5); `qos_profile(name)` picks one by name.
* `resolve_type(name)` accepts "Float64", "std_msgs/msg/Float64" or
  "std_msgs::msg::dds_::Float64_"; `to_jsonable` / `from_jsonable` convert
  samples to and from plain dicts (non-finite floats as the strings "NaN",
  "Infinity", "-Infinity", so the output is strict JSON).
* `take_valid(reader)` takes samples without the data-less ones Cyclone
  delivers when a writer goes away.

No `from __future__ import annotations` here: cyclonedds resolves field
annotations at run time and cannot resolve postponed (string) ones.
"""

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from typing import Any

from cyclonedds.core import Policy, Qos
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import (
    array,
    float32,
    float64,
    int8,
    int32,
    int64,
    sequence,
    uint8,
    uint32,
)
from cyclonedds.internal import InvalidSample
from cyclonedds.util import duration

# ---------------------------------------------------------------- builtin_interfaces


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


# ---------------------------------------------------------------- std_msgs


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Bool(IdlStruct, typename="std_msgs::msg::dds_::Bool_"):
    data: bool = False


@dataclass
class Int32(IdlStruct, typename="std_msgs::msg::dds_::Int32_"):
    data: int32 = 0


@dataclass
class Int64(IdlStruct, typename="std_msgs::msg::dds_::Int64_"):
    data: int64 = 0


@dataclass
class Float32(IdlStruct, typename="std_msgs::msg::dds_::Float32_"):
    data: float32 = 0.0


@dataclass
class Float64(IdlStruct, typename="std_msgs::msg::dds_::Float64_"):
    data: float64 = 0.0


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str = ""


# ---------------------------------------------------------------- geometry_msgs


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class Pose2D(IdlStruct, typename="geometry_msgs::msg::dds_::Pose2D_"):
    x: float64 = 0.0
    y: float64 = 0.0
    theta: float64 = 0.0


@dataclass
class PointStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PointStamped_"):
    header: Header = field(default_factory=Header)
    point: Point = field(default_factory=Point)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


def _zero_covariance() -> list[float]:
    return [0.0] * 36


@dataclass
class PoseWithCovariance(
    IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"
):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=_zero_covariance)


@dataclass
class TwistWithCovariance(
    IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"
):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=_zero_covariance)


# ---------------------------------------------------------------- sensor_msgs


@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header = field(default_factory=Header)
    angle_min: float32 = 0.0
    angle_max: float32 = 0.0
    angle_increment: float32 = 0.0
    time_increment: float32 = 0.0
    scan_time: float32 = 0.0
    range_min: float32 = 0.0
    range_max: float32 = 0.0
    ranges: sequence[float32] = field(default_factory=list)
    intensities: sequence[float32] = field(default_factory=list)


@dataclass
class Range(IdlStruct, typename="sensor_msgs::msg::dds_::Range_"):
    header: Header = field(default_factory=Header)
    radiation_type: uint8 = 0  # ULTRASOUND = 0, INFRARED = 1
    field_of_view: float32 = 0.0
    min_range: float32 = 0.0
    max_range: float32 = 0.0
    range: float32 = 0.0


# ---------------------------------------------------------------- nav_msgs


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


# ---------------------------------------------------------------- rmw_dds_common
# The ROS 2 graph topic `ros_discovery_info` (no `rt/` prefix). Jazzy's Gid is
# 16 bytes (it was 24 up to Humble).


def _zero_gid() -> list[int]:
    return [0] * 16


@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: array[uint8, 16] = field(default_factory=_zero_gid)


@dataclass
class NodeEntitiesInfo(
    IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"
):
    node_namespace: str = "/"
    node_name: str = ""
    reader_gid_seq: sequence[Gid] = field(default_factory=list)
    writer_gid_seq: sequence[Gid] = field(default_factory=list)


@dataclass
class ParticipantEntitiesInfo(
    IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"
):
    gid: Gid = field(default_factory=Gid)
    node_entities_info_seq: sequence[NodeEntitiesInfo] = field(default_factory=list)


ROS_DISCOVERY_TOPIC = "ros_discovery_info"

# ---------------------------------------------------------------- bad look-alikes
# Same DDS type names as real messages, different (shorter) layouts: a receiver
# that trusts the type name runs out of bytes while decoding. Used by peer.py bad.


@dataclass
class TruncatedFloat64(IdlStruct, typename="std_msgs::msg::dds_::Float64_"):
    data: int8 = 0


@dataclass
class TruncatedTwist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: int8 = 0


@dataclass
class TruncatedLaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header = field(default_factory=Header)


@dataclass
class TruncatedOdometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = field(default_factory=Header)


TRUNCATED: dict[type, type] = {
    Float64: TruncatedFloat64,
    Twist: TruncatedTwist,
    LaserScan: TruncatedLaserScan,
    Odometry: TruncatedOdometry,
}

# ---------------------------------------------------------------- names

MESSAGE_TYPES: tuple[type, ...] = (
    Time,
    Header,
    Bool,
    Int32,
    Int64,
    Float32,
    Float64,
    String,
    Vector3,
    Point,
    Quaternion,
    Pose,
    Pose2D,
    PointStamped,
    PoseStamped,
    Twist,
    PoseWithCovariance,
    TwistWithCovariance,
    LaserScan,
    Range,
    Odometry,
)


def dds_type_name(cls: type) -> str:
    """The DDS type name, e.g. "sensor_msgs::msg::dds_::LaserScan_"."""
    return str(cls.__idl_typename__)  # type: ignore[attr-defined]


def ros_type_from_dds(dds_name: str) -> str:
    """Render "pkg::msg::dds_::Type_" as "pkg/msg/Type"; other names unchanged."""
    parts = dds_name.split("::")
    if len(parts) == 4 and parts[2] == "dds_" and parts[3].endswith("_"):
        return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"
    return dds_name


def ros_type_name(cls: type) -> str:
    """The ROS 2 type name, e.g. "sensor_msgs/msg/LaserScan"."""
    return ros_type_from_dds(dds_type_name(cls))


_BY_NAME: dict[str, type] = {}
for _cls in MESSAGE_TYPES:
    _BY_NAME[_cls.__name__] = _cls
    _BY_NAME[ros_type_name(_cls)] = _cls
    _BY_NAME[dds_type_name(_cls)] = _cls


def resolve_type(name: str) -> type:
    """A message class from "Float64", "std_msgs/msg/Float64" or the DDS name."""
    try:
        return _BY_NAME[name]
    except KeyError:
        known = sorted(c.__name__ for c in MESSAGE_TYPES)
        raise ValueError(f"unknown message type {name!r}; known: {known}") from None


def ros_topic_to_dds(topic: str) -> str:
    """ROS 2 topic "/robot1/scan" (or "robot1/scan") -> DDS topic "rt/robot1/scan"."""
    if topic.startswith("rt/"):
        return topic
    return "rt/" + topic.lstrip("/")


def dds_topic_to_ros(topic: str) -> str | None:
    """DDS topic "rt/robot1/scan" -> "/robot1/scan"; None for non-topic names."""
    if topic.startswith("rt/"):
        return "/" + topic[3:]
    return None


# ---------------------------------------------------------------- QoS

# rmw_cyclonedds_cpp writes XCDR1; say so, so that Cyclone does not pick XCDR2.
_XCDR1 = Policy.DataRepresentation(use_cdrv0_representation=True)


def qos_default(depth: int = 10) -> Qos:
    """ROS 2 default profile: reliable, volatile, keep last 10."""
    return Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.Durability.Volatile,
        Policy.History.KeepLast(depth),
        _XCDR1,
    )


def qos_sensor_data(depth: int = 5) -> Qos:
    """ROS 2 sensor-data profile: best effort, volatile, keep last 5."""
    return Qos(
        Policy.Reliability.BestEffort,
        Policy.Durability.Volatile,
        Policy.History.KeepLast(depth),
        _XCDR1,
    )


def qos_discovery_info() -> Qos:
    """QoS of `ros_discovery_info` writers: reliable, transient local, keep last 1."""
    return Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(1),
        _XCDR1,
    )


QOS_PROFILES = {"default": qos_default, "sensor_data": qos_sensor_data}


def qos_profile(name: str) -> Qos:
    """The profile named "default" or "sensor_data"."""
    try:
        return QOS_PROFILES[name]()
    except KeyError:
        raise ValueError(f"unknown QoS profile {name!r}") from None


# ---------------------------------------------------------------- JSON

_NONFINITE = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def _json_float(x: float) -> float | str:
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "Infinity" if x > 0 else "-Infinity"
    return x


def to_jsonable(value: Any) -> Any:
    """A sample (or part of one) as plain JSON-safe Python values."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: to_jsonable(getattr(value, f.name))
            for f in dataclasses.fields(value)
        }
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, float):
        return _json_float(value)
    return value


def _strip_annotated(hint: Any) -> Any:
    while typing.get_origin(hint) is typing.Annotated:
        hint = typing.get_args(hint)[0]
    return hint


def _element_hint(hint: Any) -> Any:
    """The element type of a sequence/array field hint, or None."""
    for meta in getattr(hint, "__metadata__", ()):
        sub = getattr(meta, "subtype", None)
        if sub is not None:
            return sub
    return None


def _convert(hint: Any, raw: Any, where: str) -> Any:
    element = _element_hint(hint)
    if element is not None:
        if not isinstance(raw, list):
            raise TypeError(f"{where}: expected a list, got {raw!r}")
        return [_convert(element, v, f"{where}[{i}]") for i, v in enumerate(raw)]
    base = _strip_annotated(hint)
    if isinstance(base, type) and issubclass(base, IdlStruct):
        return from_jsonable(base, raw)
    if isinstance(raw, str) and base is float and raw in _NONFINITE:
        return _NONFINITE[raw]
    if base is float and isinstance(raw, (int, float)) and not isinstance(raw, bool):
        return float(raw)
    if isinstance(raw, (dict, list)):
        raise TypeError(f"{where}: expected a scalar, got {raw!r}")
    return raw


def from_jsonable(cls: type, data: Any) -> Any:
    """Build a `cls` sample from a (possibly partial, nested) field dict."""
    if data is None:
        return cls()
    if not isinstance(data, dict):
        raise TypeError(f"{cls.__name__}: expected an object, got {data!r}")
    hints = typing.get_type_hints(cls, include_extras=True)
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = set(data) - set(names)
    if unknown:
        raise ValueError(f"{cls.__name__}: unknown fields {sorted(unknown)}")
    kwargs = {
        name: _convert(hints[name], data[name], f"{cls.__name__}.{name}")
        for name in names
        if name in data
    }
    return cls(**kwargs)


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """A rotation of `yaw` radians about +z."""
    return Quaternion(0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def quaternion_to_yaw(q: Quaternion) -> float:
    """The yaw (rotation about +z) of a quaternion, in (-pi, pi]."""
    return math.atan2(
        2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z)
    )


def take_valid(reader: Any, n: int = 64) -> list[Any]:
    """Take up to n samples, dropping the data-less ones (e.g. "no more writers")."""
    return [s for s in reader.take(n) if not isinstance(s, InvalidSample)]


def stamp_now(ns: int) -> Time:
    """builtin_interfaces/Time from nanoseconds since the epoch."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
