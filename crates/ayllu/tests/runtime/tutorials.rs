//! The book's tutorials (docs/tutorials/) run as tests: each tutorial program checks what its
//! page says happens (it panics otherwise), and the test checks the lines the page quotes.

#[path = "../../../../examples/tutorial/01_first_behavior/main.rs"]
#[allow(dead_code)] // its `main` is for `cargo run --example`
mod first_behavior;

#[path = "../../../../examples/tutorial/02_subsumption/main.rs"]
#[allow(dead_code)]
mod subsumption;

#[path = "../../../../examples/tutorial/03_two_nodes_udp/main.rs"]
#[allow(dead_code)]
mod two_nodes_udp;

/// The first unindented ```text block of a tutorial page: the output the page quotes.
fn quoted(page: &str) -> String {
    let path = format!("{}/../../docs/tutorials/{page}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text.find("\n```text\n").expect("the page quotes output") + "\n```text\n".len();
    text[start..start + text[start..].find("```").unwrap()].to_owned()
}

#[test]
fn tutorial_1_a_first_behavior() {
    let out = first_behavior::run().unwrap();
    assert_eq!(quoted("01-first-behavior.md"), out, "the page quotes what the program prints");
    assert!(out.contains("0.0 s: Range 0.3 m -> Turn Some(1.0), Backing true"), "{out}");
    assert!(out.contains("2.0 s: Turn Some(0.0), Backing false"), "{out}");
}

#[test]
fn tutorial_2_two_behaviors_in_subsumption() {
    let out = subsumption::run().unwrap();
    assert_eq!(quoted("02-subsumption.md"), out, "the page quotes what the program prints");
    assert!(out.contains("1.5 s  MOTOR.Turn = 1"), "{out}");
    assert!(out.contains("3.0 s  MOTOR.Turn = 0.2"), "{out}");
}

#[test]
fn tutorial_3_two_nodes_over_udp() {
    let out = two_nodes_udp::run().unwrap();
    assert!(out.contains("MOTOR.Speed on robot 2 came from n1"), "{out}");
}

#[path = "../../../../examples/tutorial/00_concepts/main.rs"]
#[allow(dead_code)]
mod concepts;

#[test]
fn the_concepts_page_code_runs() {
    assert_eq!(concepts::run().unwrap(), "every concept ran as the page says\n");
}

#[path = "../../../../examples/tutorial/06_recording_why_in_the_past/main.rs"]
#[allow(dead_code)]
mod recording_why_in_the_past;

#[test]
fn tutorial_6_recording_a_team_and_asking_why_in_the_past() {
    let dir = std::env::temp_dir().join(format!("ayllu-tutorial-06-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = recording_why_in_the_past::run(&dir).unwrap();
    assert!(out.contains("write-inhibit held by n1/"), "robot 1's claim is named as the holder: {out}");
    std::fs::remove_dir_all(&dir).unwrap();
}
