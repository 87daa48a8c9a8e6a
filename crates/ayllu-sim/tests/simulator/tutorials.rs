//! The book's simulator tutorials (docs/tutorials/04-*, 05-*) run as tests: each program checks
//! what its page says happens (it panics otherwise); the test checks what the page quotes.

#[path = "../../../../examples/tutorial/04_ble_in_the_simulator/main.rs"]
#[allow(dead_code)] // its `main` is for `cargo run --example`
mod ble_in_the_simulator;

#[path = "../../../../examples/tutorial/05_study_sweep_plot/main.rs"]
#[allow(dead_code)]
mod study_sweep_plot;

/// The first unindented ```text block of a tutorial page: the output the page quotes.
fn quoted(page: &str) -> String {
    let path = format!("{}/../../docs/tutorials/{page}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text.find("\n```text\n").expect("the page quotes output") + "\n```text\n".len();
    text[start..start + text[start..].find("```").unwrap()].to_owned()
}

#[test]
fn tutorial_4_a_ble_group_of_three_robots() {
    let out = ble_in_the_simulator::run_tutorial().unwrap();
    assert_eq!(quoted("04-ble-in-the-simulator.md"), out, "the page quotes what the program prints");
    assert!(out.contains("A_w with BLE"), "{out}");
    assert_eq!(out.lines().filter(|l| l.contains(" |  ")).count(), 6, "a line every 10 s for 60 s: {out}");
}

#[test]
fn tutorial_5_a_study_with_a_sweep_and_a_plot() {
    let dir = std::env::temp_dir().join(format!("ayllu-tutorial-05-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plot = dir.join("coverage_vs_loss.svg");
    let out = study_sweep_plot::run_tutorial(&plot).unwrap();
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("radio loss") && svg.contains("BLE"), "{svg}");
    assert_eq!(out.lines().filter(|l| l.contains(" loss ")).count(), 8, "{out}");
    let table: String = out.lines().filter(|l| l.contains(" loss ")).map(|l| format!("{l}\n")).collect();
    assert_eq!(quoted("05-study-sweep-plot.md"), table, "the page quotes what the program prints");
    std::fs::remove_dir_all(&dir).unwrap();
}
