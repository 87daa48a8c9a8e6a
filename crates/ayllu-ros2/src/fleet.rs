//! The simulator as a fleet of ROS 2 robots (`ayllu sim serve --ros2`, docs/ros2.md): each
//! simulated robot's body is published and commanded on ROS 2 topics under `/robotK/`, as a
//! ROS 2 driver would, so that controllers with a ROS 2 body — and any ROS 2 tool — drive the
//! simulated team exactly as they would real robots.
//!
//! Robot K's topics (K = 1, 2, ...; the controller of robot K is Ayllu node K):
//!
//! | topic | type | way | what |
//! |---|---|---|---|
//! | `/robotK/scan` | `sensor_msgs/msg/LaserScan` | published | the sonar sweep: beam k at `k·2π/beams` counter-clockwise from ahead, ranges from the robot's rim (Ayllu's convention), `sensor_data` QoS |
//! | `/robotK/odom` | `nav_msgs/msg/Odometry` | published | the true pose (frame `odom`) and the commanded twist |
//! | `/robotK/targetN` | `geometry_msgs/msg/PointStamped` | published | target N while in view: `point.x` its bearing (rad, positive to the right), `point.y` its apparent height; nothing while it is not seen |
//! | `/robotK/cmd_vel` | `geometry_msgs/msg/Twist` | subscribed | `linear.x` (m/s), `angular.z` (rad/s, counter-clockwise) |
//! | `/robotK/ayllu/alive` | `std_msgs/msg/Int64` | published | 1, then 0 once the scenario kills the robot |
//! | `/robotK/ayllu/reach` | `std_msgs/msg/Float64MultiArray` | published | which robots' radio reaches robot K now (the scenario's radio) |
//! | `/robotK/ayllu/drive`, `sent`, `bytes` | `std_msgs/msg/Int64` | subscribed | the robot's report for the metrics (its drive, its radio counts) |
//!
//! `examples/ros2/sim-robot.toml` is the robot's side of this table, one file for every robot
//! (`{id}`); targets are the body's usual `VISION.TargetNAngle` / `TargetNBottom` ports.
//!
//! Promise: a served body here is the same [`ayllu_sim::body::Body`] the in-process and
//! UDP-served simulators write, behind a [`Ros2Body`] whose mapping is this table read from the
//! world's side; nothing about the world, its sensing or its metrics changes.

use std::fmt::Write as _;

use ayllu_core::{BehaviorClass, Error as CoreError, NodeCore, PortSpec};
use ayllu_sim::served_robot::{link_class, LINK};
use ayllu_sim::world::WorldConfig;

use crate::{Context, Error, Mapping, Ros2Body};

/// The behavior holding a served robot's odometry (`X`, `Y`, `Yaw`, `Translate`, `Rotate`).
pub const ODOM: &str = "ODOM";

/// The class of [`ODOM`].
pub fn odom_class() -> Result<BehaviorClass, CoreError> {
    let mut c = BehaviorClass::new("Odom");
    for p in ["X", "Y", "Yaw", "Translate", "Rotate"] {
        c.port(PortSpec::new(p, 0.0))?;
    }
    Ok(c)
}

/// The mapping of robot `k`'s body as the simulator serves it (the module's table, from the
/// world's side), for `targets` targets in `world`, on ROS domain `domain`.
pub fn served_mapping(k: u32, targets: usize, world: &WorldConfig, domain: u16) -> Result<Mapping, Error> {
    let beams = world.sonar_beams.max(1);
    let step = std::f64::consts::TAU / beams as f64;
    let mut t = String::new();
    // `write!` into a String cannot fail.
    let _ = write!(
        t,
        r#"[ros2]
domain = {domain}
namespace = "/robot{k}"
node = "ayllu_sim_body"

[[topic]]
name = "scan"
type = "sensor_msgs/msg/LaserScan"
direction = "out"
qos = "sensor_data"
fields = {{ ranges = "SONAR.Ranges" }}
set = {{ "header.frame_id" = "robot{k}/base_scan", angle_min = 0.0, angle_max = {max:?}, angle_increment = {step:?}, scan_time = 0.1, range_min = 0.0, range_max = {range:?} }}

[[topic]]
name = "odom"
type = "nav_msgs/msg/Odometry"
direction = "out"
fields = {{ "pose.pose.position.x" = "ODOM.X", "pose.pose.position.y" = "ODOM.Y", "pose.pose.orientation.yaw" = "ODOM.Yaw", "twist.twist.linear.x" = "ODOM.Translate", "twist.twist.angular.z" = "ODOM.Rotate" }}
set = {{ "header.frame_id" = "odom", child_frame_id = "robot{k}/base_link" }}

[[topic]]
name = "cmd_vel"
type = "geometry_msgs/msg/Twist"
direction = "in"
qos = "default"
fields = {{ "linear.x" = "BASE.Translate", "angular.z" = "BASE.Rotate" }}

[[topic]]
name = "ayllu/alive"
type = "std_msgs/msg/Int64"
direction = "out"
qos = {{ profile = "default", durability = "transient_local", depth = 1 }}
fields = {{ data = "LINK.Alive" }}

[[topic]]
name = "ayllu/reach"
type = "std_msgs/msg/Float64MultiArray"
direction = "out"
qos = "sensor_data"
fields = {{ data = "LINK.Reach" }}
"#,
        max = step * (beams - 1) as f64,
        range = world.sonar_range,
    );
    for report in ["drive", "sent", "bytes"] {
        let port = match report {
            "drive" => "Drive",
            "sent" => "Sent",
            _ => "Bytes",
        };
        let _ = write!(
            t,
            "\n[[topic]]\nname = \"ayllu/{report}\"\ntype = \"std_msgs/msg/Int64\"\ndirection = \"in\"\nqos = \"default\"\nfields = {{ data = \"LINK.{port}\" }}\n"
        );
    }
    for n in 1..=targets {
        let _ = write!(
            t,
            "\n[[topic]]\nname = \"target{n}\"\ntype = \"geometry_msgs/msg/PointStamped\"\ndirection = \"out\"\nqos = \"sensor_data\"\nfields = {{ \"point.x\" = \"VISION.Target{n}Angle\", \"point.y\" = \"VISION.Target{n}Bottom\" }}\nset = {{ \"header.frame_id\" = \"robot{k}/camera\" }}\n"
        );
    }
    Mapping::parse(&t).map_err(|error| Error::Mapping { path: format!("(the served mapping of robot {k})"), error })
}

/// On a served body's node, whose VISION, SONAR and BASE exist ([`ayllu_sim::body::Body`]):
/// create [`LINK`] and [`ODOM`] and the ROS 2 body of robot `k` in `context`.
pub fn install_served(
    core: &mut NodeCore,
    k: u32,
    targets: usize,
    world: &WorldConfig,
    context: &Context,
) -> Result<Ros2Body, Error> {
    core.define(link_class()?)?;
    core.create("Link", LINK)?;
    core.define(odom_class()?)?;
    core.create("Odom", ODOM)?;
    let mapping = served_mapping(k, targets, world, context.domain_id())?;
    Ros2Body::install_in(core, &mapping, context)
}
