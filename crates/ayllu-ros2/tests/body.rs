//! The ROS 2 body on two in-process nodes over real DDS (RustDDS on loopback, in a network
//! namespace of the test's own): a sample is a port write like any other — a robot-sized scan
//! is taken whole locally, resampled to Ayllu's sonar convention when the mapping says so,
//! arbitrated by a window like any write (and `why` says so), and goes stale after the
//! topic's lifespan; a port holding the raw scan cannot be connected across the network
//! (D-S10.7) while the resampled one can.

#[path = "../../ayllu-cli/tests/tool/common/ros2.rs"]
mod ros2_env;

use std::f64::consts::TAU;
use std::time::{Duration as Std, Instant as StdInstant};

use ayllu::*;

const BEAMS: usize = 1080;

fn publisher() -> String {
    let step = TAU / BEAMS as f64;
    format!(
        r#"
[ros2]
node = "lidar"
[[topic]]
name = "/t/scan"
type = "sensor_msgs/msg/LaserScan"
direction = "out"
qos = "sensor_data"
fields = {{ ranges = "LIDAR.Ranges" }}
set = {{ angle_min = 0.0, angle_increment = {step:?}, range_min = 0.1, range_max = 10.0, "header.frame_id" = "laser" }}

[[topic]]
name = "/t/scan2"
type = "sensor_msgs/msg/LaserScan"
direction = "out"
qos = "sensor_data"
fields = {{ ranges = "LIDAR.Ranges" }}
set = {{ angle_min = 0.0, angle_increment = {step:?}, range_min = 0.1, range_max = 10.0 }}
"#
    )
}

const SUBSCRIBER: &str = r#"
[ros2]
node = "controller"
[[topic]]
name = "/t/scan"
type = "sensor_msgs/msg/LaserScan"
direction = "in"
lifespan = 0.5
fields = { ranges = "RAW.Ranges" }

[[topic]]
name = "/t/scan2"
type = "sensor_msgs/msg/LaserScan"
direction = "in"
sonar = { beams = 16, rim = 0.2 }
fields = { ranges = "SONAR.Ranges" }
"#;

/// A sweep with everything 1 m away, but 0.5 m at 90° (left) and no return (inf) behind.
fn sweep(near: f64) -> Vec<f64> {
    (0..BEAMS)
        .map(|i| {
            let deg = i as f64 * 360.0 / BEAMS as f64;
            if (deg - 90.0).abs() < 2.0 {
                near
            } else if (deg - 180.0).abs() < 15.0 {
                f64::INFINITY
            } else {
                1.0
            }
        })
        .collect()
}

/// Turn both nodes until `until(b)` holds or `limit` passes; whether it held.
fn run_both(a: &mut Node, b: &mut Node, until: impl Fn(&Node) -> bool, limit: Std) -> bool {
    let end = StdInstant::now() + limit;
    while StdInstant::now() < end {
        a.run_for(Std::from_millis(5));
        b.run_for(Std::from_millis(5));
        if until(b) {
            return true;
        }
    }
    false
}

fn vector(node: &Node, b: &str, p: &str) -> Vec<f64> {
    node.read(b, p).ok().and_then(|v| v.as_vector().map(<[f64]>::to_vec)).unwrap_or_default()
}

#[test]
fn a_scan_is_a_port_write_taken_whole_resampled_arbitrated_and_kept_local() {
    ros2_env::own_network();
    let net = format!("mem://ros2-body-{}", std::process::id());
    let mut a = Node::open(NodeId(1), &net).unwrap();
    let mut b = Node::open(NodeId(2), &net).unwrap();
    let mut lidar = BehaviorClass::new("Lidar");
    lidar.port(PortSpec::new("Ranges", Vec::<f64>::new())).unwrap();
    a.define(lidar).unwrap();
    a.create("Lidar", "LIDAR").unwrap();
    ayllu_ros2::install(&mut a, &ayllu_ros2::Mapping::parse(&publisher()).unwrap()).unwrap();
    ayllu_ros2::install(&mut b, &ayllu_ros2::Mapping::parse(SUBSCRIBER).unwrap()).unwrap();
    // A local copy of the sonar, to see what propagates out of it.
    let mut copy = BehaviorClass::new("Copy");
    copy.port(PortSpec::new("Ranges", Vec::<f64>::new())).unwrap();
    b.define(copy).unwrap();
    b.create("Copy", "COPY").unwrap();
    b.connect(&Endpoint::local("SONAR", "Ranges"), &Endpoint::local("COPY", "Ranges"), ConnectionKind::Normal).unwrap();

    // Discovery takes a moment: keep publishing until the first scan is taken.
    let first = sweep(0.5);
    let end = StdInstant::now() + Std::from_secs(20);
    while vector(&b, "SONAR", "Ranges").len() != 16 || vector(&b, "RAW", "Ranges").len() != BEAMS {
        assert!(StdInstant::now() < end, "no scan arrived: {:?}", b.core().body_counters());
        a.write("LIDAR", "Ranges", first.as_slice()).unwrap();
        run_both(&mut a, &mut b, |_| false, Std::from_millis(50));
    }

    // Taken whole, REP 117's inf included.
    let raw = vector(&b, "RAW", "Ranges");
    assert_eq!(raw.len(), BEAMS);
    assert_eq!(raw[0], 1.0);
    assert!(raw[BEAMS / 2].is_infinite(), "no return behind: {}", raw[BEAMS / 2]);
    // Resampled: beam k at k·22.5°, nearest return less the 0.2 m rim; no return reads
    // range_max (10 m) less the rim.
    let sonar = vector(&b, "SONAR", "Ranges");
    let close = |x: f64, y: f64| (x - y).abs() < 1e-5;
    assert!(close(sonar[0], 0.8), "ahead: {sonar:?}");
    assert!(close(sonar[4], 0.3), "left, 90°: {sonar:?}");
    assert!(close(sonar[8], 9.8), "behind, no return: {sonar:?}");
    assert_eq!(vector(&b, "COPY", "Ranges"), sonar, "the sample propagated");

    // Across the network: the raw scan cannot go (255 numbers at most), the sonar can.
    let far = Endpoint::node(NodeId(9), "SONAR", "Ranges");
    let e = b.connect(&Endpoint::local("RAW", "Ranges"), &far, ConnectionKind::Normal).unwrap_err();
    assert!(e.to_string().contains("1080") && e.to_string().contains("at most 255"), "{e}");
    b.connect(&Endpoint::local("SONAR", "Ranges"), &far, ConnectionKind::Normal).unwrap();

    // An Inhibit window on the sonar: a new sample is stored, not propagated, and `why` says
    // who holds it.
    let mut hold = BehaviorClass::new("Hold");
    hold.port(PortSpec::new("Ranges", Vec::<f64>::new())).unwrap();
    b.define(hold).unwrap();
    b.create("Hold", "HOLD").unwrap();
    b.connect(
        &Endpoint::local("HOLD", "Ranges"),
        &Endpoint::local("SONAR", "Ranges"),
        ConnectionKind::Inhibit(Duration::from_secs(30)),
    )
    .unwrap();
    b.write("HOLD", "Ranges", vec![0.0; 16]).unwrap();
    let before = vector(&b, "COPY", "Ranges");
    let nearer = sweep(0.3);
    let end = StdInstant::now() + Std::from_secs(10);
    while !close(vector(&b, "SONAR", "Ranges")[4], 0.1) {
        assert!(StdInstant::now() < end, "the nearer sweep never arrived");
        a.write("LIDAR", "Ranges", nearer.as_slice()).unwrap();
        run_both(&mut a, &mut b, |_| false, Std::from_millis(50));
    }
    assert_eq!(vector(&b, "COPY", "Ranges"), before, "an inhibited port propagates nothing");
    let why = b.why("SONAR", "Ranges").unwrap();
    assert!(why.windows.iter().any(|w| w.kind == WindowKind::Inhibit), "{why:?}");

    // The lidar stops: after the topic's lifespan (0.5 s) the raw port reads absent.
    assert!(b.fresh("RAW", "Ranges").unwrap());
    let stopped = StdInstant::now();
    run_both(&mut a, &mut b, |b| !b.fresh("RAW", "Ranges").unwrap(), Std::from_secs(5));
    assert!(!b.fresh("RAW", "Ranges").unwrap(), "still fresh after {:?}", stopped.elapsed());
    assert!(stopped.elapsed() >= Std::from_millis(400), "went stale too soon: {:?}", stopped.elapsed());

    let counters: std::collections::BTreeMap<_, _> = b.core().body_counters().iter().cloned().collect();
    assert!(counters["/t/scan taken"] >= 2, "{counters:?}");
    for cause in ["truncated", "too_long", "malformed", "nan", "refused"] {
        assert_eq!(counters[&format!("/t/scan {cause}")], 0, "{counters:?}");
    }
}
