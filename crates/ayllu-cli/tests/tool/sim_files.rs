//! Studies as files: `ayllu sim run SCENARIO.toml` and `ayllu sim sweep SWEEP.toml` with the
//! built binary. A file round-trips (file -> run -> results, the same numbers as the library
//! computes for the same file), a sweep writes one row per (cell, controller, seed) from which
//! its printed means are recomputed, and a misspelt field is an error naming it.

use crate::common;

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
    // The report page of `sim cmommt`, a table per cell, seed 1 of each cell and controller
    // replayable.
    let html = std::fs::read_to_string(out.join("index.html")).expect("the sweep's report page");
    assert!(run.stdout.contains(&format!("Report: {}", out.join("index.html").display())), "{}", run.stdout);
    for title in ["cell1: radio.loss = 0.0", "cell2: radio.loss = 0.2"] {
        assert!(html.contains(&format!("<h2>{title}</h2>")), "no table for {title}");
    }
    assert_eq!(html.matches("<script type=\"application/json\" id=\"run-").count(), 2 * 2);
    let tables = std::fs::read_to_string(out.join("tables.txt")).unwrap();
    assert!(tables.contains("cell2: radio.loss = 0.2"), "{tables}");
}

/// `--threads` shares a large team's ticks among threads: the same run, the same trace.
#[test]
fn threads_print_the_same_run_and_trace() {
    let dir = scratch("threads");
    let file = dir.join("big.toml");
    std::fs::write(&file, "robots = 120\nduration = 4.0\n[radio]\nloss = 0.1\n").unwrap();
    let f = file.to_str().unwrap();
    let run = |threads: &str| {
        let trace = dir.join(format!("t{threads}.csv"));
        let printed =
            ayllu(&["sim", "run", f, "--json", "--threads", threads, "--trace", trace.to_str().unwrap()], LIMIT).ok();
        (printed.stdout, std::fs::read_to_string(trace).unwrap())
    };
    let (one, two) = (run("1"), run("2"));
    assert_eq!(one.0, two.0);
    assert!(one.1 == two.1, "the traces differ");
    assert_eq!(one.1.lines().count(), 81, "a header and 80 ticks");
    ayllu(&["sim", "run", f, "--threads", "0"], LIMIT).fails(2, "--threads");
}

#[test]
fn traces_on_request_for_a_run_and_for_every_run_of_a_sweep() {
    let dir = scratch("trace");
    let file = dir.join("s.toml");
    std::fs::write(&file, "controller = \"ForceField\"\nduration = 10.0\n[[kills]]\nat = 5.0\nrobot = 3\n").unwrap();
    let (csv, jsonl) = (dir.join("t.csv"), dir.join("t.jsonl"));
    let f = file.to_str().unwrap();
    let printed = ayllu(&["sim", "run", f, "--json", "--trace", csv.to_str().unwrap()], LIMIT).ok().json();
    ayllu(&["sim", "run", f, "--trace", jsonl.to_str().unwrap()], LIMIT).ok();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(&header[..4], ["t", "observed", "weighted", "messages"]);
    assert!(header.contains(&"r3_alive") && header.contains(&"t4_observers"), "{header:?}");
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|c| c.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len(), 200, "10 s of 50 ms ticks");
    // The trace recomputes the printed A_w; robot 3 dies at 5 s.
    let a_w = rows.iter().map(|r| r[2] * 0.05).sum::<f64>() / 10.0;
    assert!((a_w - printed["metrics"]["a_w"].as_f64().unwrap()).abs() < 1e-9, "{a_w} vs {printed}");
    let alive = header.iter().position(|h| *h == "r3_alive").unwrap();
    assert_eq!((rows[90][alive], rows[110][alive]), (1.0, 0.0));
    let json_lines = std::fs::read_to_string(&jsonl).unwrap();
    assert_eq!(json_lines.lines().count(), 200);
    let last: Json = serde_json::from_str(json_lines.lines().last().unwrap()).unwrap();
    assert_eq!(last["robots"][2]["alive"], 0);

    let sweep = dir.join("sweep.toml");
    std::fs::write(&sweep, "seeds = 2\ncontrollers = [\"Local\"]\nduration = 5.0\n[grid]\nrobots = [2, 3]\n").unwrap();
    let traces = dir.join("traces");
    let out = dir.join("out");
    let s = sweep.to_str().unwrap();
    ayllu(&["sim", "sweep", s, "--out", out.to_str().unwrap(), "--traces", traces.to_str().unwrap()], LIMIT).ok();
    let mut names: Vec<String> =
        std::fs::read_dir(&traces).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(
        names,
        ["cell1-Local-seed1.csv", "cell1-Local-seed2.csv", "cell2-Local-seed1.csv", "cell2-Local-seed2.csv"]
    );
    let three = std::fs::read_to_string(traces.join("cell2-Local-seed1.csv")).unwrap();
    assert!(three.lines().next().unwrap().contains("r3_drive"));
}

#[test]
fn every_example_study_file_reads() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/sim");
    let mut seen = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        // A sweep has seeds, a list of controllers or a grid; the rest are scenarios.
        let is_sweep = ["seeds", "compare", "controllers = [", "[grid]"].iter().any(|k| text.contains(k));
        let read = if is_sweep {
            ayllu_sim::scenario_file::sweep(&text).map(|_| ())
        } else {
            ayllu_sim::scenario_file::scenario(&text).map(|_| ())
        };
        read.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        seen += 1;
    }
    assert!(seen >= 7, "{seen} example files");
}

#[test]
fn a_misspelt_field_is_named() {
    let dir = scratch("bad");
    let file = dir.join("bad.toml");
    std::fs::write(&file, "[radio]\nlos = 0.1\n").unwrap();
    ayllu(&["sim", "run", file.to_str().unwrap()], LIMIT).fails(1, "unknown field `radio.los`");
    ayllu(&["sim", "run", "/nonexistent/scenario.toml"], LIMIT).fails(1, "reading /nonexistent/scenario.toml");
}

/// A scenario out of the simulator's bounds (docs/cmommt.md, "What a scenario may hold") is
/// refused when the file is read, naming the field, the value and what it takes, with no
/// panic and no abort (an empty arena used to panic, a 1e7 m one to abort asking for 44 TB);
/// a sweep's cell, and a sweep with no controller, likewise.
#[test]
fn a_scenario_out_of_bounds_is_refused_naming_its_field() {
    let dir = scratch("bounds");
    let write = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_owned()
    };
    let empty = write("empty.toml", "duration = 10.0\n[world]\narena = [0.0, 0.0]\n");
    ayllu(&["sim", "run", &empty], LIMIT)
        .fails(1, "empty.toml: world.arena: [0, 0] is not a usable arena: each side must be finite and in (0, 1e6] m");
    let huge = write("huge.toml", "duration = 10.0\n[world]\narena = [1e7, 1e7]\n");
    ayllu(&["sim", "run", &huge], LIMIT).fails(1, "world.arena: [1e7, 1e7] is not a usable arena");
    let nan = write("nan.toml", "duration = nan\n");
    ayllu(&["sim", "run", &nan, "--json"], LIMIT).fails(1, "duration: NaN is not a usable duration");
    let grid = write("grid.toml", "seeds = 1\ncontrollers = [\"BLE\"]\n[grid]\n\"world.arena\" = [[0.0, 0.0]]\n");
    let out = dir.join("out");
    ayllu(&["sim", "sweep", &grid, "--out", out.to_str().unwrap()], LIMIT)
        .fails(1, "cell1 (world.arena = [0.0,0.0]): world.arena");
    let none = write("none.toml", "seeds = 1\ncontrollers = []\n");
    ayllu(&["sim", "sweep", &none, "--out", out.to_str().unwrap()], LIMIT)
        .fails(1, "controllers: [] names no controller");
    assert!(!out.exists(), "nothing ran, no report");
}
