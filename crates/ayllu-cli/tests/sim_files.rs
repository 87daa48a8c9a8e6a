//! Studies as files: `ayllu sim run SCENARIO.toml` and `ayllu sim sweep SWEEP.toml` with the
//! built binary. A file round-trips (file -> run -> results, the same numbers as the library
//! computes for the same file), a sweep writes one row per (cell, controller, seed) from which
//! its printed means are recomputed, and a misspelt field is an error naming it.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use common::ayllu;
use serde_json::Value as Json;

const LIMIT: Duration = Duration::from_secs(120);

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("sim_files-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_scenario_file_runs_to_the_same_numbers_as_the_library() {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/sim/paper.toml");
    let printed = ayllu(&["sim", "run", file, "--json"], LIMIT).ok().json();
    let text = std::fs::read_to_string(file).unwrap();
    let scenario = ayllu_sim::scenario_file::scenario(&text).unwrap();
    let m = ayllu_sim::scenario::run(&scenario).unwrap().metrics;
    assert_eq!(printed["controller"], "BLE");
    assert_eq!(printed["metrics"]["a_w"].as_f64(), Some(m.a_w), "{printed}");
    assert_eq!(printed["metrics"]["msgs_per_robot_s"].as_f64(), Some(m.msgs_per_robot_s));
    let text_run = ayllu(&["sim", "run", file], LIMIT).ok();
    assert!(text_run.stdout.starts_with("BLE, 3 robots, 4 targets, seed 1, 300 s: A_w"), "{text_run:?}");
}

#[test]
fn a_sweep_writes_every_run_and_its_means_are_recomputable() {
    let dir = scratch("sweep");
    let file = dir.join("sweep.toml");
    std::fs::write(
        &file,
        "seeds = 2\ncontrollers = [\"BLE\", \"Random\"]\nduration = 30.0\n[grid]\n\"radio.loss\" = [0.0, 0.2]\n",
    )
    .unwrap();
    let out = dir.join("out");
    let run = ayllu(&["sim", "sweep", file.to_str().unwrap(), "--out", out.to_str().unwrap()], LIMIT).ok();
    let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let rows: Vec<Vec<String>> = csv.lines().skip(1).map(|l| l.split(',').map(str::to_owned).collect()).collect();
    assert_eq!(rows.len(), 2 * 2 * 2, "cells x controllers x seeds");
    assert!(run.stdout.contains("cell2: radio.loss = 0.2"), "{}", run.stdout);
    // BLE in cell 2: the printed mean is the mean of its two rows.
    let a_w: Vec<f64> =
        rows.iter().filter(|r| r[0] == "cell2" && r[1] == "BLE").map(|r| r[10].parse().unwrap()).collect();
    let mean = a_w.iter().sum::<f64>() / 2.0;
    let line = run.stdout.lines().skip_while(|l| !l.starts_with("cell2")).find(|l| l.contains("BLE")).unwrap();
    assert!(line.contains(&format!("A_w {mean:.3}")), "{line} vs {mean}");
    let jsonl = std::fs::read_to_string(out.join("runs.jsonl")).unwrap();
    let first: Json = serde_json::from_str(jsonl.lines().next().unwrap()).unwrap();
    assert_eq!(first["table"], "cell1");
}

#[test]
fn a_misspelt_field_is_named() {
    let dir = scratch("bad");
    let file = dir.join("bad.toml");
    std::fs::write(&file, "[radio]\nlos = 0.1\n").unwrap();
    ayllu(&["sim", "run", file.to_str().unwrap()], LIMIT).fails(1, "unknown field `radio.los`");
    ayllu(&["sim", "run", "/nonexistent/scenario.toml"], LIMIT).fails(1, "reading /nonexistent/scenario.toml");
}
