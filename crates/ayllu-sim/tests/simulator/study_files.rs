//! `ayllu sim cmommt`'s study written as files: the sweep files `examples/sim/cmommt_paper.toml`
//! and `cmommt_robustness.toml` give the rows of the study's "Paper setting" and "Robustness"
//! tables bit for bit (shortened here to 3 seeds of 40 s, the kill moved to half of that, as
//! the study does).

use ayllu_sim::scenario_file;
use ayllu_sim::study::{run_plan, Row, StudyConfig};
use ayllu_sim::sweep;

fn example(name: &str) -> String {
    let path = format!("{}/../../examples/sim/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .replace("seeds = 10", "seeds = 3")
        .replace("duration = 300.0", "duration = 40.0")
        .replace("at = 150.0", "at = 20.0")
}

fn rows(text: &str) -> Vec<Row> {
    let sw = scenario_file::sweep(text).expect("the example reads");
    let results = sweep::run(&sw, 2, &|| {}, None, "t", "c").expect("the sweep runs");
    results.cells.into_iter().flat_map(|c| c.rows).collect()
}

#[test]
fn the_example_files_give_the_studys_rows() {
    let config = StudyConfig { seeds: 3, duration: 40.0, sweep_robots: Vec::new(), ..StudyConfig::default() };
    let study = run_plan(&ayllu_sim::study::Plan::new(&config), 2, &|| {}).expect("the study runs");
    assert_eq!(rows(&example("cmommt_paper.toml")), study.paper);
    assert_eq!(rows(&example("cmommt_robustness.toml")), study.robustness);
}
