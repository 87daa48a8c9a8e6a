//! The message schemas against ROS 2's CDR: golden payloads written out by hand, decoding
//! that refuses short, lying and malformed payloads by cause without panicking or allocating
//! for a lie, round trips of random samples, and field paths.
//!
//! Bytes go through RustDDS's own adapters, the exact calls `Publisher::publish` and
//! `Subscription::take_seed` make, so a golden test here pins what goes on the wire.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::f64::consts::PI;
use std::marker::PhantomData;

use ayllu_core::Value;
use ayllu_ros2::messages::{
    message_type, message_types, Decode, DecodeCause, Encoded, FieldKind, MessageType, Sample, SetError,
};
use proptest::prelude::*;
use ros2_client::dds::rustdds::no_key::{DeserializerAdapter, SerializerAdapter};
use ros2_client::dds::rustdds::serialization::{to_writer_with_rep_id, CdrDeserializeSeedDecoder};
use ros2_client::dds::rustdds::{CDRDeserializerAdapter, CDRSerializerAdapter, RepresentationIdentifier};
use ros2_client::MessageTypeName;

/// The largest single allocation this thread made while `LARGEST` was armed.
struct Measuring;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note(size: usize) {
    if ARMED.try_with(Cell::get).unwrap_or(false) {
        let _ = LARGEST.try_with(|l| l.set(l.get().max(size)));
    }
}

// SAFETY: every call is forwarded unchanged to `System`; we only note sizes.
unsafe impl GlobalAlloc for Measuring {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        System.realloc(ptr, layout, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static ALLOCATOR: Measuring = Measuring;

/// The largest single allocation `f` makes on this thread.
fn largest_allocation<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LARGEST.with(|l| l.set(0));
    ARMED.with(|a| a.set(true));
    let out = f();
    ARMED.with(|a| a.set(false));
    (out, LARGEST.with(Cell::get))
}

fn ty(name: &str) -> &'static MessageType {
    message_type(name).unwrap_or_else(|| panic!("{name} is known"))
}

/// What `Publisher<Encoded>::publish` puts in a payload (after the encapsulation header).
fn encode(sample: &Sample) -> Vec<u8> {
    CDRSerializerAdapter::<Encoded>::to_bytes(&Encoded(sample.clone())).expect("a sample encodes").to_vec()
}

/// What `Subscription::take_seed` makes of a payload: the sample, or the cause left behind.
fn decode_as(
    ty: &'static MessageType,
    bytes: &[u8],
    max_elements: usize,
    rep: RepresentationIdentifier,
) -> Result<Sample, Option<DecodeCause>> {
    let cause = Cell::new(Some(DecodeCause::Malformed)); // stale on purpose: a decode resets it
    let seed = Decode { ty, max_elements, cause: &cause };
    let decoder = CdrDeserializeSeedDecoder::new(seed, PhantomData::<()>);
    match CDRDeserializerAdapter::<Sample>::from_bytes_with(bytes, rep, decoder) {
        Ok(sample) => {
            assert_eq!(cause.get(), None, "a decoded sample leaves no cause");
            Ok(sample)
        }
        Err(_) => Err(cause.get()),
    }
}

fn decode(ty: &'static MessageType, bytes: &[u8]) -> Result<Sample, Option<DecodeCause>> {
    decode_as(ty, bytes, 65536, RepresentationIdentifier::CDR_LE)
}

fn set(sample: &mut Sample, path: &str, v: impl Into<Value>) {
    let field = sample.message_type().field(path).unwrap();
    sample.set(&field, &v.into()).unwrap();
}

fn get(sample: &Sample, path: &str) -> Value {
    sample.get(&sample.message_type().field(path).unwrap()).unwrap()
}

/// Checks both directions: the sample encodes to exactly `bytes`, and `bytes` decode to it.
fn golden(sample: &Sample, bytes: &[u8]) {
    assert_eq!(encode(sample), bytes, "{:?} encodes as written by hand", sample.message_type());
    assert_eq!(decode(sample.message_type(), bytes).as_ref(), Ok(sample));
}

fn f64s(xs: &[f64]) -> Vec<u8> {
    xs.iter().flat_map(|x| x.to_le_bytes()).collect()
}

#[test]
fn float64_golden() {
    let mut s = ty("std_msgs/msg/Float64").default_sample();
    set(&mut s, "data", 1.5);
    golden(&s, &[0, 0, 0, 0, 0, 0, 0xf8, 0x3f]);
}

#[test]
fn twist_golden() {
    let mut s = ty("geometry_msgs/msg/Twist").default_sample();
    set(&mut s, "linear.x", 0.5);
    set(&mut s, "linear.y", -1.0);
    set(&mut s, "angular.z", 0.25);
    // linear.x, .y, .z, angular.x, .y, .z: six float64 back to back, no padding.
    golden(&s, &f64s(&[0.5, -1.0, 0.0, 0.0, 0.0, 0.25]));
}

#[test]
fn pose2d_golden() {
    let mut s = ty("geometry_msgs/msg/Pose2D").default_sample();
    set(&mut s, "x", 1.0);
    set(&mut s, "y", 2.0);
    set(&mut s, "theta", -PI);
    golden(&s, &f64s(&[1.0, 2.0, -PI]));
}

fn laser_scan() -> (Sample, Vec<u8>) {
    let mut s = ty("sensor_msgs/msg/LaserScan").default_sample();
    set(&mut s, "header.stamp.sec", 1i64);
    set(&mut s, "header.stamp.nanosec", 2i64);
    set(&mut s, "header.frame_id", "laser");
    set(&mut s, "angle_min", -1.5);
    set(&mut s, "angle_max", 1.5);
    set(&mut s, "angle_increment", 1.5);
    set(&mut s, "range_max", 30.0);
    set(&mut s, "ranges", vec![1.0, 2.5, f64::INFINITY]);
    set(&mut s, "intensities", vec![100.0]);
    let mut b = Vec::new();
    b.extend(1i32.to_le_bytes()); // 0: header.stamp.sec
    b.extend(2u32.to_le_bytes()); // 4: header.stamp.nanosec
    b.extend(6u32.to_le_bytes()); // 8: header.frame_id's length, counting its NUL
    b.extend(b"laser\0"); // 12..18
    b.extend([0, 0]); // 18: padding, a float32 aligns to 4 (from the payload's start)
    for x in [-1.5f32, 1.5, 1.5, 0.0, 0.0, 0.0, 30.0] {
        b.extend(x.to_le_bytes()); // 20..48: angle_min ... range_max
    }
    b.extend(3u32.to_le_bytes()); // 48: ranges' length
    for x in [1.0f32, 2.5, f32::INFINITY] {
        b.extend(x.to_le_bytes()); // 52..64
    }
    b.extend(1u32.to_le_bytes()); // 64: intensities' length
    b.extend(100f32.to_le_bytes()); // 68..72
    (s, b)
}

#[test]
fn laser_scan_golden() {
    let (s, bytes) = laser_scan();
    assert_eq!(bytes.len(), 72);
    golden(&s, &bytes);
}

#[test]
fn range_golden() {
    let mut s = ty("sensor_msgs/msg/Range").default_sample();
    set(&mut s, "radiation_type", 1i64);
    set(&mut s, "field_of_view", 0.5);
    set(&mut s, "min_range", 0.25);
    set(&mut s, "max_range", 4.0);
    set(&mut s, "range", 2.0);
    set(&mut s, "variance", 0.125);
    let mut b = Vec::new();
    b.extend([0; 8]); // 0: header.stamp
    b.extend(1u32.to_le_bytes()); // 8: header.frame_id's length: "" is its NUL alone
    b.push(0); // 12
    b.push(1); // 13: radiation_type, a uint8: no alignment
    b.extend([0, 0]); // 14: padding to 16 for the float32s
    for x in [0.5f32, 0.25, 4.0, 2.0, 0.125] {
        b.extend(x.to_le_bytes()); // 16..36: field_of_view, min_range, max_range, range, variance
    }
    golden(&s, &b);
}

#[test]
fn odometry_golden() {
    let mut s = ty("nav_msgs/msg/Odometry").default_sample();
    set(&mut s, "header.stamp.sec", 10i64);
    set(&mut s, "header.stamp.nanosec", 500i64);
    set(&mut s, "header.frame_id", "odom");
    set(&mut s, "child_frame_id", "base_link");
    set(&mut s, "pose.pose.position.x", 1.0);
    set(&mut s, "pose.pose.position.y", -2.0);
    set(&mut s, "pose.pose.orientation.yaw", PI / 3.0);
    assert_eq!(get(&s, "pose.pose.orientation.w"), Value::Float((PI / 6.0).cos()));
    let covariance: Vec<f64> = (0..36).map(f64::from).collect();
    set(&mut s, "pose.covariance", covariance.clone());
    set(&mut s, "twist.twist.linear.x", 0.5);
    set(&mut s, "twist.twist.angular.z", -0.25);
    let mut b = Vec::new();
    b.extend(10i32.to_le_bytes()); // 0: header.stamp.sec
    b.extend(500u32.to_le_bytes()); // 4: header.stamp.nanosec
    b.extend(5u32.to_le_bytes()); // 8: header.frame_id's length
    b.extend(b"odom\0"); // 12..17
    b.extend([0; 3]); // 17: padding to 20 for child_frame_id's uint32 length
    b.extend(10u32.to_le_bytes()); // 20
    b.extend(b"base_link\0"); // 24..34
    b.extend([0; 6]); // 34: padding to 40, a float64 aligns to 8
    b.extend(f64s(&[1.0, -2.0, 0.0])); // 40: pose.pose.position
    b.extend(f64s(&[0.0, 0.0, (PI / 6.0).sin(), (PI / 6.0).cos()])); // 64: pose.pose.orientation x y z w
    b.extend(f64s(&covariance)); // 96: pose.covariance, float64[36]: no length
    b.extend(f64s(&[0.5, 0.0, 0.0, 0.0, 0.0, -0.25])); // 384: twist.twist
    b.extend(f64s(&[0.0; 36])); // 432: twist.covariance
    assert_eq!(b.len(), 720);
    golden(&s, &b);
}

#[test]
fn float64_multi_array_keeps_its_dimensions() {
    let mut b = Vec::new();
    b.extend(2u32.to_le_bytes()); // 0: layout.dim's length
    b.extend(2u32.to_le_bytes()); // 4: dim[0].label's length
    b.extend(b"x\0"); // 8..10
    b.extend([0, 0]); // 10: padding to 12
    b.extend(3u32.to_le_bytes()); // 12: dim[0].size
    b.extend(6u32.to_le_bytes()); // 16: dim[0].stride
    b.extend(3u32.to_le_bytes()); // 20: dim[1].label's length
    b.extend(b"yz\0"); // 24..27
    b.push(0); // 27: padding to 28
    b.extend(2u32.to_le_bytes()); // 28: dim[1].size
    b.extend(2u32.to_le_bytes()); // 32: dim[1].stride
    b.extend(0u32.to_le_bytes()); // 36: layout.data_offset
    b.extend(6u32.to_le_bytes()); // 40: data's length
    b.extend([0; 4]); // 44: padding to 48
    b.extend(f64s(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])); // 48..96
    let t = ty("std_msgs/msg/Float64MultiArray");
    let s = decode(t, &b).unwrap();
    assert_eq!(get(&s, "data"), Value::vector(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]));
    assert_eq!(get(&s, "layout.data_offset"), Value::Int(0));
    assert_eq!(encode(&s), b, "the dimensions round-trip");
    assert_eq!(t.leaves(), ["layout.data_offset", "data"]);
    let e = t.field("layout.dim.label").unwrap_err();
    assert!(e.to_string().contains("sequence of std_msgs/msg/MultiArrayDimension"), "{e}");
}

#[test]
fn big_endian_payloads_and_trailing_padding_decode() {
    let (s, le) = laser_scan();
    let mut be = Vec::new();
    to_writer_with_rep_id(&mut be, &Encoded(s.clone()), RepresentationIdentifier::CDR_BE).unwrap();
    assert_ne!(be, le);
    assert_eq!(decode_as(s.message_type(), &be, 65536, RepresentationIdentifier::CDR_BE), Ok(s.clone()));
    // Writers pad a payload to a multiple of 4; the padding follows the message and is ignored.
    let (odometry, mut padded) = (ty("nav_msgs/msg/Odometry").default_sample(), Vec::new());
    padded.extend(encode(&odometry));
    padded.extend([0; 3]);
    assert_eq!(decode(odometry.message_type(), &padded), Ok(odometry));
}

#[test]
fn every_prefix_of_a_laser_scan_is_truncated() {
    let (s, bytes) = laser_scan();
    for n in 0..bytes.len() {
        assert_eq!(decode(s.message_type(), &bytes[..n]), Err(Some(DecodeCause::Truncated)), "first {n} bytes");
    }
}

/// The golden LaserScan, its `ranges` length replaced by `len` and nothing after it.
fn lying_scan(len: u32) -> Vec<u8> {
    let mut bytes = laser_scan().1;
    bytes.truncate(48);
    bytes.extend(len.to_le_bytes());
    bytes.extend(1f32.to_le_bytes());
    bytes
}

#[test]
fn a_sequence_over_the_limit_is_refused_from_its_length() {
    let scan = ty("sensor_msgs/msg/LaserScan");
    for len in [65537, 1_000_000, u32::MAX] {
        let (result, largest) = largest_allocation(|| decode(scan, &lying_scan(len)));
        assert_eq!(result, Err(Some(DecodeCause::TooLong)), "length {len}");
        assert!(largest < 4096, "length {len}: allocated {largest} bytes at once");
    }
    // Within the limit but not there: a short payload, and growing only as elements arrive.
    let (result, largest) = largest_allocation(|| decode(scan, &lying_scan(65536)));
    assert_eq!(result, Err(Some(DecodeCause::Truncated)));
    assert!(largest <= 4096 * 8, "allocated {largest} bytes at once");
    // The limit is inclusive.
    let (s, bytes) = laser_scan();
    assert_eq!(decode_as(scan, &bytes, 3, RepresentationIdentifier::CDR_LE), Ok(s));
    assert_eq!(decode_as(scan, &bytes, 2, RepresentationIdentifier::CDR_LE), Err(Some(DecodeCause::TooLong)));
    // Sequences of messages too.
    let array = ty("std_msgs/msg/Float64MultiArray");
    assert_eq!(decode(array, &u32::MAX.to_le_bytes()), Err(Some(DecodeCause::TooLong)));
}

#[test]
fn bad_text_and_bad_bools_are_told_apart() {
    let (s, mut bytes) = laser_scan();
    bytes[13] = 0xff; // inside "laser"
    assert_eq!(decode(s.message_type(), &bytes), Err(Some(DecodeCause::BadText)));
    let mut bytes = laser_scan().1;
    bytes[17] = b'!'; // the NUL
    assert_eq!(decode(s.message_type(), &bytes), Err(Some(DecodeCause::Malformed)));
    let b = ty("std_msgs/msg/Bool");
    assert_eq!(get(&decode(b, &[1]).unwrap(), "data"), Value::Bool(true));
    assert_eq!(decode(b, &[2]), Err(Some(DecodeCause::Malformed)));
    assert_eq!(decode(b, &[]), Err(Some(DecodeCause::Truncated)));
}

#[test]
fn the_known_types_and_their_dds_names() {
    let names: Vec<&str> = message_types().map(MessageType::name).collect();
    for expected in [
        "builtin_interfaces/msg/Time",
        "std_msgs/msg/Header",
        "std_msgs/msg/Float64MultiArray",
        "geometry_msgs/msg/PoseWithCovariance",
        "sensor_msgs/msg/LaserScan",
        "sensor_msgs/msg/Range",
        "nav_msgs/msg/Odometry",
    ] {
        assert!(names.contains(&expected), "{expected}");
    }
    assert_eq!(names.len(), 25);
    assert_eq!(message_type("sensor_msgs/LaserScan"), None);
    let scan = ty("sensor_msgs/msg/LaserScan");
    assert_eq!((scan.package(), scan.short_name()), ("sensor_msgs", "LaserScan"));
    assert_eq!(scan.dds_type_name(), "sensor_msgs::msg::dds_::LaserScan_");
    for t in message_types() {
        assert_eq!(message_type(t.name()), Some(t));
        assert_eq!(t.name(), format!("{}/msg/{}", t.package(), t.short_name()));
        // ros2-client's own spelling of the convention.
        assert_eq!(t.dds_type_name(), MessageTypeName::new(t.package(), t.short_name()).dds_msg_type());
    }
}

#[test]
fn every_leaf_resolves_and_reads_its_default() {
    for t in message_types() {
        let sample = t.default_sample();
        for leaf in t.leaves() {
            let f = t.field(&leaf).unwrap_or_else(|e| panic!("{e}"));
            let v = sample.get(&f).unwrap();
            let expected = match (f.kind(), leaf.as_str()) {
                (_, l) if l.ends_with("orientation.w") || l == "w" => Value::Float(1.0),
                (FieldKind::Bool, _) => Value::Bool(false),
                (FieldKind::Int, _) => Value::Int(0),
                (FieldKind::Float | FieldKind::Yaw, _) => Value::Float(0.0),
                (FieldKind::Text, _) => Value::text(""),
                (FieldKind::Floats, _) if f.ros_type().ends_with("[36]") => Value::vector(&[0.0; 36]),
                (FieldKind::Floats, _) => Value::vector(&[]),
            };
            assert_eq!(v, expected, "{} {leaf}", t.name());
        }
    }
    let odometry = ty("nav_msgs/msg/Odometry");
    let kind = |p: &str| odometry.field(p).unwrap().kind();
    assert_eq!(kind("header.stamp.sec"), FieldKind::Int);
    assert_eq!(kind("header.frame_id"), FieldKind::Text);
    assert_eq!(kind("twist.twist.angular.z"), FieldKind::Float);
    assert_eq!(kind("pose.covariance"), FieldKind::Floats);
    assert_eq!(kind("pose.pose.orientation.yaw"), FieldKind::Yaw);
    assert_eq!(odometry.field("pose.covariance").unwrap().ros_type(), "float64[36]");
    assert_eq!(ty("sensor_msgs/msg/LaserScan").field("ranges").unwrap().ros_type(), "float32[]");
}

#[test]
fn mistyped_paths_get_suggestions() {
    let odometry = ty("nav_msgs/msg/Odometry");
    let e = odometry.field("pose.pose.positon.x").unwrap_err();
    assert_eq!(
        e.to_string(),
        "`pose.pose.positon.x` is not a field of nav_msgs/msg/Odometry: did you mean `pose.pose.position.x`?"
    );
    let suggestion = |t: &str, p: &str| ty(t).field(p).unwrap_err().suggestion;
    assert_eq!(suggestion("nav_msgs/msg/Odometry", "position.x").as_deref(), Some("pose.pose.position.x"));
    assert_eq!(suggestion("geometry_msgs/msg/TwistStamped", "linear.x").as_deref(), Some("twist.linear.x"));
    assert_eq!(suggestion("sensor_msgs/msg/LaserScan", "rangs").as_deref(), Some("ranges"));
    assert_eq!(suggestion("sensor_msgs/msg/LaserScan", "header.frame").as_deref(), Some("header.frame_id"));
    assert_eq!(suggestion("sensor_msgs/msg/LaserScan", "ranges.x").as_deref(), Some("ranges"));
    assert_eq!(suggestion("sensor_msgs/msg/LaserScan", "completely_unrelated"), None);
    assert_eq!(suggestion("geometry_msgs/msg/Pose2D", ""), None);
    assert!(ty("geometry_msgs/msg/Pose2D").field("yaw").is_err(), "yaw is only below quaternions");
    let e = odometry.field("pose.pose").unwrap_err();
    assert_eq!(e.suggestion, None);
    assert_eq!(
        e.to_string(),
        "`pose.pose` is a geometry_msgs/msg/Pose, not a single value: map one of `pose.pose.position.x`, \
         `pose.pose.position.y`, `pose.pose.position.z`, `pose.pose.orientation.x`, `pose.pose.orientation.y`, \
         `pose.pose.orientation.z`, `pose.pose.orientation.w`, `pose.pose.orientation.yaw`"
    );
    let long = "x".repeat(100_000);
    assert_eq!(odometry.field(&long).unwrap_err().suggestion, None);
}

#[test]
fn set_converts_only_what_fits() {
    let scan = ty("sensor_msgs/msg/LaserScan");
    let mut s = scan.default_sample();
    let f = |p: &str| scan.field(p).unwrap();
    let out_of_range = |r| matches!(r, Err(SetError::OutOfRange { .. }));
    assert!(out_of_range(s.set(&f("header.stamp.sec"), &Value::Int(3_000_000_000))));
    assert!(out_of_range(s.set(&f("header.stamp.nanosec"), &Value::Int(-1))));
    s.set(&f("header.stamp.nanosec"), &Value::Int(u32::MAX.into())).unwrap();
    s.set(&f("header.stamp.sec"), &Value::Bool(true)).unwrap();
    assert_eq!(s.get(&f("header.stamp.sec")), Some(Value::Int(1)));
    assert!(matches!(s.set(&f("header.stamp.sec"), &Value::Float(1.0)), Err(SetError::WrongType { .. })));
    // float32 fields hold what subscribers will receive: rounded, and never a new infinity.
    s.set(&f("angle_min"), &Value::Float(0.1)).unwrap();
    assert_eq!(s.get(&f("angle_min")), Some(Value::Float(f64::from(0.1f32))));
    s.set(&f("angle_max"), &Value::Int(3)).unwrap();
    assert_eq!(s.get(&f("angle_max")), Some(Value::Float(3.0)));
    assert!(out_of_range(s.set(&f("range_max"), &Value::Float(1e39))));
    assert!(out_of_range(s.set(&f("ranges"), &Value::vector(&[1.0, 1e39]))));
    s.set(&f("ranges"), &Value::vector(&[0.1, f64::INFINITY])).unwrap();
    assert_eq!(s.get(&f("ranges")), Some(Value::vector(&[f64::from(0.1f32), f64::INFINITY])));
    assert!(matches!(s.set(&f("header.frame_id"), &Value::Int(1)), Err(SetError::WrongType { .. })));
    let range = ty("sensor_msgs/msg/Range");
    let mut r = range.default_sample();
    assert!(out_of_range(r.set(&range.field("radiation_type").unwrap(), &Value::Int(256))));
    assert!(matches!(r.set(&f("ranges"), &Value::vector(&[])), Err(SetError::OtherMessage { .. })));
    assert_eq!(r.get(&f("ranges")), None);
    let odometry = ty("nav_msgs/msg/Odometry");
    let mut o = odometry.default_sample();
    let covariance = odometry.field("pose.covariance").unwrap();
    let short = o.set(&covariance, &Value::vector(&[0.0; 35]));
    assert_eq!(short, Err(SetError::WrongLength { expected: 36, got: 35 }));
    let yaw = odometry.field("pose.pose.orientation.yaw").unwrap();
    assert!(out_of_range(o.set(&yaw, &Value::Float(f64::NAN))));
    assert!(matches!(o.set(&yaw, &Value::text("north")), Err(SetError::WrongType { .. })));
    assert_eq!(o, odometry.default_sample(), "a refused value changes nothing");
}

#[test]
fn yaw_reads_any_quaternion() {
    let pose = ty("geometry_msgs/msg/Pose");
    let mut s = pose.default_sample();
    let yaw = pose.field("orientation.yaw").unwrap();
    assert_eq!(s.get(&yaw), Some(Value::Float(0.0)));
    // A quarter turn about z, not normalized: the scale does not matter.
    set(&mut s, "orientation.z", 3.0);
    set(&mut s, "orientation.w", 3.0);
    let Some(Value::Float(y)) = s.get(&yaw) else { panic!() };
    assert!((y - PI / 2.0).abs() < 1e-12, "{y}");
    // Rolled 0.3 and pitched 0.2 as well (z-y-x Euler angles): the yaw is still 1.
    let (roll, pitch, heading) = (0.3f64, 0.2f64, 1.0f64);
    let ((sr, cr), (sp, cp), (sy, cy)) = ((roll / 2.0).sin_cos(), (pitch / 2.0).sin_cos(), (heading / 2.0).sin_cos());
    set(&mut s, "orientation.x", sr * cp * cy - cr * sp * sy);
    set(&mut s, "orientation.y", cr * sp * cy + sr * cp * sy);
    set(&mut s, "orientation.z", cr * cp * sy - sr * sp * cy);
    set(&mut s, "orientation.w", cr * cp * cy + sr * sp * sy);
    let Some(Value::Float(y)) = s.get(&yaw) else { panic!() };
    assert!((y - heading).abs() < 1e-12, "{y}");
}

const TYPE_COUNT: usize = 25;

/// A value for a leaf, from random material, that the leaf accepts.
fn value_for(kind: FieldKind, ros_type: &str, x: f64, int: i64, text: &str, floats: &[f64]) -> Value {
    // A float32 field refuses finite numbers it would make infinite.
    let fit = |x: f64| {
        let too_big = ros_type.starts_with("float32") && x.is_finite() && x.abs() > f64::from(f32::MAX);
        if too_big {
            x.signum() * f64::from(f32::MAX)
        } else {
            x
        }
    };
    match kind {
        FieldKind::Bool => Value::Bool(int & 1 == 1),
        FieldKind::Int => Value::Int(match ros_type {
            "uint8" => int.rem_euclid(256),
            "int32" => i64::from(int as i32),
            "uint32" => i64::from(int as u32),
            _ => int,
        }),
        FieldKind::Float | FieldKind::Yaw => Value::Float(fit(x)),
        FieldKind::Text => Value::text(text),
        FieldKind::Floats => {
            let fixed: Option<usize> = ros_type.split_once('[').and_then(|(_, n)| n.trim_end_matches(']').parse().ok());
            let xs: Vec<f64> = match fixed {
                Some(n) => floats.iter().copied().chain(std::iter::repeat(x)).take(n).collect(),
                None => floats.to_vec(),
            };
            Value::vector(&xs.into_iter().map(fit).collect::<Vec<_>>())
        }
    }
}

/// Any float but NaN (which no sample equals), mostly of everyday size.
fn float() -> impl Strategy<Value = f64> {
    use proptest::num::f64::{INFINITE, NEGATIVE, NORMAL, POSITIVE, SUBNORMAL, ZERO};
    prop_oneof![-1e6..1e6, POSITIVE | NEGATIVE | NORMAL | SUBNORMAL | ZERO | INFINITE]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_samples_round_trip(
        which in 0..TYPE_COUNT,
        material in prop::collection::vec(
            (float(), any::<i64>(), "\\PC{0,12}", prop::collection::vec(float(), 0..40)), 1..60),
    ) {
        let t = message_types().nth(which).unwrap();
        let mut s = t.default_sample();
        let mut expected = Vec::new();
        for (i, leaf) in t.leaves().iter().enumerate() {
            let f = t.field(leaf).unwrap();
            if f.kind() == FieldKind::Yaw {
                continue; // it would overwrite the quaternion's random components
            }
            let (bits, int, text, floats) = &material[i % material.len()];
            let v = value_for(f.kind(), &f.ros_type(), *bits, *int, text, floats);
            s.set(&f, &v).unwrap_or_else(|e| panic!("{leaf} = {v}: {e}"));
            expected.push((f, v));
        }
        for (f, v) in &expected {
            let rounded = |x: f64| if f.ros_type().starts_with("float32") { f64::from(x as f32) } else { x };
            let v = match v {
                Value::Float(x) => Value::Float(rounded(*x)),
                Value::Vector(xs) => Value::vector(&xs.iter().map(|x| rounded(*x)).collect::<Vec<_>>()),
                other => other.clone(),
            };
            prop_assert_eq!(s.get(f), Some(v));
        }
        let bytes = encode(&s);
        prop_assert_eq!(decode(t, &bytes), Ok(s.clone()));
        let mut be = Vec::new();
        to_writer_with_rep_id(&mut be, &Encoded(s.clone()), RepresentationIdentifier::CDR_BE).unwrap();
        prop_assert_eq!(decode_as(t, &be, 65536, RepresentationIdentifier::CDR_BE), Ok(s));
    }

    #[test]
    fn yaw_round_trips(yaw in -PI..=PI) {
        prop_assume!(yaw > -PI);
        let odometry = ty("nav_msgs/msg/Odometry");
        let f = odometry.field("pose.pose.orientation.yaw").unwrap();
        let mut s = odometry.default_sample();
        s.set(&f, &Value::Float(yaw)).unwrap();
        let Some(Value::Float(back)) = s.get(&f) else { panic!("yaw reads as a float") };
        prop_assert!((back - yaw).abs() < 1e-12, "{} read back as {}", yaw, back);
        prop_assert_eq!(get(&s, "pose.pose.orientation.x"), Value::Float(0.0));
        prop_assert_eq!(get(&s, "pose.pose.orientation.y"), Value::Float(0.0));
    }

    #[test]
    fn arbitrary_bytes_never_panic(
        which in 0..TYPE_COUNT,
        bytes in prop::collection::vec(any::<u8>(), 0..800),
        max_elements in 0usize..100,
    ) {
        let t = message_types().nth(which).unwrap();
        check_decode(t, &bytes, max_elements)?;
    }

    #[test]
    fn mutated_payloads_never_panic(
        which in 0..TYPE_COUNT,
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
    ) {
        // A valid payload with a few bytes changed, then cut anywhere: reaches deeper than noise.
        let t = message_types().nth(which).unwrap();
        let mut s = t.default_sample();
        for leaf in t.leaves() {
            let f = t.field(&leaf).unwrap();
            let _ = s.set(&f, &Value::text("frame"));
            let _ = s.set(&f, &Value::vector(&[1.0, 2.0, 3.0]));
        }
        let mut bytes = encode(&s);
        for (at, byte) in &flips {
            let i = at.index(bytes.len());
            bytes[i] = *byte;
        }
        let keep = cut.index(bytes.len() + 1);
        check_decode(t, &bytes[..keep], 16)?;
    }
}

/// Decoding `bytes` gives a sample that re-encodes stably, or an error with a cause.
fn check_decode(t: &'static MessageType, bytes: &[u8], max_elements: usize) -> Result<(), TestCaseError> {
    match decode_as(t, bytes, max_elements, RepresentationIdentifier::CDR_LE) {
        // Compared as bytes: random floats include NaNs, which no sample equals.
        Ok(s) => {
            let again = encode(&s);
            prop_assert_eq!(
                encode(&decode_as(t, &again, max_elements, RepresentationIdentifier::CDR_LE).unwrap()),
                again
            );
        }
        Err(cause) => prop_assert!(cause.is_some(), "an error without a cause"),
    }
    Ok(())
}
