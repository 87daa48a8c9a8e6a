//! The mapping file (docs/ros2.md, "The mapping file"): what it resolves (namespaces, `{id}`,
//! QoS profiles, the domain from `ROS_DOMAIN_ID`) and what it refuses — every refusal naming
//! where and the fix.

use ayllu_ros2::mapping::{Direction, Durability, Qos, Reliability};
use ayllu_ros2::Mapping;

fn parse(text: &str) -> Result<Mapping, String> {
    Mapping::parse_with_domain(text, None).map_err(|e| e.to_string())
}

const SCAN: &str = r#"
[ros2]
namespace = "robot2/"

[[topic]]
name = "scan"
type = "sensor_msgs/msg/LaserScan"
direction = "in"
fields = { ranges = "SONAR.Ranges" }

[[topic]]
name = "/cmd_vel"
type = "geometry_msgs/msg/Twist"
direction = "out"
rate = 10
fields = { linear.x = "BASE.Translate", "angular.z" = "BASE.Rotate" }
"#;

#[test]
fn names_resolve_in_the_namespace_and_qos_defaults_follow_the_direction() {
    let m = parse(SCAN).unwrap();
    assert_eq!(m.namespace, "/robot2");
    assert_eq!(m.domain, 0);
    assert_eq!(m.topics[0].name, "/robot2/scan", "relative: in the namespace");
    assert_eq!(m.topics[1].name, "/cmd_vel", "absolute: as written");
    assert_eq!(m.topics[0].qos, Qos::SENSOR_DATA, "in topics read sensors");
    assert_eq!(m.topics[1].qos, Qos::DEFAULT);
    assert_eq!(m.topics[1].direction, Direction::Out);
    assert_eq!(m.topics[1].rate, Some(10.0));
    // A dotted key written bare (a TOML table) or quoted is the same path.
    let paths: Vec<&str> = m.topics[1].fields.iter().map(|f| f.path.as_str()).collect();
    assert_eq!(paths, ["linear.x", "angular.z"], "in file order");
}

#[test]
fn the_domain_comes_from_the_file_else_ros_domain_id_else_zero() {
    let with = |file: &str, env: Option<&str>| {
        Mapping::parse_with_domain(&SCAN.replace("[ros2]", &format!("[ros2]\n{file}")), env)
    };
    assert_eq!(with("", Some("42")).unwrap().domain, 42);
    assert_eq!(with("domain = 7", Some("42")).unwrap().domain, 7);
    assert_eq!(with("", None).unwrap().domain, 0);
    assert!(with("", Some("abc")).unwrap_err().to_string().contains("ROS_DOMAIN_ID"));
}

#[test]
fn id_stands_for_the_node_and_is_refused_without_one() {
    let text = SCAN.replace("robot2/", "/robot{id}");
    let m = Mapping::parse_for(&text, Some(ayllu::NodeId(5))).unwrap();
    assert_eq!(m.topics[0].name, "/robot5/scan");
    let e = Mapping::parse_for(&text, None).unwrap_err().to_string();
    assert!(e.contains("{id}") && e.contains("line 3"), "{e}");
}

#[test]
fn qos_is_a_profile_or_a_table() {
    let q = |v: &str| parse(&SCAN.replace("direction = \"in\"", &format!("direction = \"in\"\nqos = {v}")));
    assert_eq!(q("\"default\"").unwrap().topics[0].qos, Qos::DEFAULT);
    let t = q("{ profile = \"sensor_data\", depth = 1, durability = \"transient_local\" }").unwrap();
    assert_eq!(
        t.topics[0].qos,
        Qos { reliability: Reliability::BestEffort, durability: Durability::TransientLocal, depth: 1 }
    );
    assert!(q("{ reliability = \"sometimes\" }").unwrap_err().contains("\"reliable\" or \"best_effort\""));
    assert!(q("{ depth = 0 }").unwrap_err().contains("from 1 to 10000"));
    assert!(q("{ reliabilty = \"reliable\" }").unwrap_err().contains("did you mean `reliability`?"));
}

#[test]
fn each_mistake_is_refused_where_it_is_with_the_fix() {
    for (from, to, needle) in [
        ("direction = \"in\"", "direction = \"in\"\nrate = 5", "rate is for \"out\" topics"),
        ("rate = 10", "lifespan = 0.5", "lifespan is for \"in\" topics"),
        ("direction = \"out\"", "direction = \"out\"\nsonar = { beams = 16 }", "sonar resamples an \"in\""),
        ("direction = \"in\"", "direction = \"in\"\nsonar = { beams = 0 }", "from 1 to 4096"),
        ("direction = \"in\"", "direction = \"in\"\nset = { angle_min = 0.0 }", "only for \"out\" topics"),
        ("direction = \"in\"", "direction = \"in\"\nlifespan = 1e-9", "under a microsecond"),
        ("name = \"scan\"", "name = \"2scan\"", "not a ROS 2 topic name"),
        ("name = \"scan\"", "name = \"~/scan\"", "not a ROS 2 topic name"),
        ("\"SONAR.Ranges\"", "\"SONAR.Range.s\"", "is not a port"),
        ("ranges = \"SONAR.Ranges\"", "range = \"SONAR.Ranges\"", "did you mean `ranges`?"),
        ("direction = \"in\"", "direction = \"both\"", "\"in\" (topic -> ports) or \"out\""),
        ("type = \"sensor_msgs/msg/LaserScan\"", "type = \"LaserScan\"", "did you mean \"sensor_msgs/msg/LaserScan\"?"),
        ("fields = { ranges = \"SONAR.Ranges\" }", "", "no fields mapped"),
        ("rate = 10", "rate = 10\nset = { \"linear.x\" = 1.0 }", "also mapped to a port"),
        ("rate = 10", "rate = 10\nset = { \"linear.y\" = \"fast\" }", "linear.y"),
        ("[ros2]", "[ros]", "unknown key `ros`: did you mean `ros2`?"),
    ] {
        let text = SCAN.replacen(from, to, 1);
        assert_ne!(text, SCAN, "{from}");
        let e = parse(&text).unwrap_err();
        assert!(e.contains(needle), "`{to}`: expected `{needle}` in: {e}");
    }
}

#[test]
fn two_topics_writing_one_port_are_refused_and_one_topic_twice_too() {
    let twice = format!(
        "{SCAN}\n[[topic]]\nname = \"scan_front\"\ntype = \"sensor_msgs/msg/LaserScan\"\ndirection = \"in\"\nfields = {{ ranges = \"SONAR.Ranges\" }}\n"
    );
    let e = parse(&twice).unwrap_err();
    assert!(e.contains("SONAR.Ranges is already written by /robot2/scan"), "{e}");
    let same = format!(
        "{SCAN}\n[[topic]]\nname = \"scan\"\ntype = \"sensor_msgs/msg/LaserScan\"\ndirection = \"in\"\nfields = {{ ranges = \"OTHER.Ranges\" }}\n"
    );
    assert!(parse(&same).unwrap_err().contains("mapped twice the same way"));
}

#[test]
fn bad_toml_and_an_empty_file_say_so() {
    assert!(parse("[[topic]\nname=").unwrap_err().contains("not valid TOML"));
    assert!(parse("").unwrap_err().contains("no [[topic]]"));
}
