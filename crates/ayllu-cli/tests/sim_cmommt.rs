//! `ayllu sim cmommt` as a user runs it: the built binary, a small study (`--quick` with
//! fewer seeds and shorter runs, so that the debug build finishes in seconds), its tables on
//! stdout, its report folder on disk; the same numbers whatever `--jobs`; and the errors a user
//! meets (bad arguments, an output folder that cannot be written).
//!
//! Every run is bounded (killed, and the test failed, past its limit). The report folders go
//! under Cargo's per-target scratch directory, one per test, emptied first.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use common::ayllu;
use serde_json::Value as Json;

const CONTROLLERS: [&str; 5] = ["BLE", "Random", "Local", "ForceField", "Centralized"];
const LIMIT: Duration = Duration::from_secs(120);

/// A fresh, empty folder for one test's output.
fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("sim_cmommt-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("creating the scratch folder");
    dir
}

/// The lines of the table printed under the heading that starts with `title` (up to the
/// blank line that ends it), header first.
fn table<'a>(stdout: &'a str, title: &str) -> Vec<&'a str> {
    let mut lines = stdout.lines().skip_while(|l| !l.starts_with(title));
    assert!(lines.next().is_some(), "no `{title}` table in:\n{stdout}");
    lines.take_while(|l| !l.trim().is_empty()).collect()
}

/// A_w of `controller`'s first row: the number before the only `±` of the row.
fn a_w(rows: &[&str], controller: &str) -> f64 {
    let row = rows
        .iter()
        .find(|l| l.split_whitespace().next() == Some(controller))
        .unwrap_or_else(|| panic!("no {controller} row in {rows:#?}"));
    let cells: Vec<&str> = row.split_whitespace().collect();
    let at = cells.iter().position(|c| *c == "±").expect("an `A_w ± sd` cell");
    cells[at - 1].parse().unwrap_or_else(|e| panic!("A_w of `{row}`: {e}"))
}

#[test]
fn a_quick_study_prints_the_tables_and_writes_the_report() {
    let out = scratch("quick");
    let out_arg = out.to_str().expect("a UTF-8 path");
    let run = ayllu(&["sim", "cmommt", "--quick", "--seeds", "2", "--duration", "60", "--out", out_arg], LIMIT).ok();
    println!("{}\n{}took {:?}", run.stdout, run.stderr, run.took);

    let paper = table(&run.stdout, "Paper setting");
    let robustness = table(&run.stdout, "Robustness");
    let sweep = table(&run.stdout, "Sweep");
    for rows in [&paper, &robustness, &sweep] {
        assert!(rows[0].starts_with("controller"), "header first: {rows:#?}");
        for name in CONTROLLERS {
            assert!(rows.iter().any(|l| l.split_whitespace().next() == Some(name)), "{name} missing: {rows:#?}");
        }
    }
    // One row per controller; robustness at 3 loss levels; --quick's sweep is 2 x 1 x 2 settings.
    assert_eq!((paper.len(), robustness.len(), sweep.len()), (1 + 5, 1 + 15, 1 + 20));
    let (ble, random) = (a_w(&paper, "BLE"), a_w(&paper, "Random"));
    assert!(ble > random, "BLE's A_w {ble} should beat Random's {random}");
    for name in &CONTROLLERS[1..] {
        assert!(run.stdout.contains(&format!("BLE − {name} = ")), "no comparison line for {name}");
    }

    let index = out.join("index.html");
    assert!(run.stdout.contains(&format!("Report: {}", index.display())), "{}", run.stdout);
    assert!(run.stdout.contains("Wall time: "));
    for file in ["index.html", "coverage.svg", "sweep_robots.svg", "sweep_loss.svg", "robustness.svg", "results.json"] {
        let len = std::fs::metadata(out.join(file)).map(|m| m.len()).unwrap_or(0);
        assert!(len > 0, "{file} missing or empty in {}", out.display());
    }
    // Not a terminal: plain progress lines instead of a bar.
    assert!(run.stderr.contains("runs (100%)"), "{}", run.stderr);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn the_numbers_do_not_depend_on_the_number_of_threads() {
    let out = scratch("jobs");
    let out_arg = out.to_str().expect("a UTF-8 path");
    let study = |jobs: &str| {
        let args = ["sim", "cmommt", "--no-sweep", "--seeds", "2", "--duration", "20", "--json", "--jobs", jobs];
        ayllu(&[&args[..], &["--out", out_arg]].concat(), LIMIT).ok()
    };
    let one = study("1");
    let three = study("3");
    assert_eq!(one.stdout, three.stdout, "the same study on 1 and 3 threads");
    let doc: Json = one.json();
    assert_eq!(doc["paper"].as_array().map(Vec::len), Some(5), "{doc}");
    assert_eq!(doc["robustness"].as_array().map(Vec::len), Some(15), "{doc}");
    assert_eq!(doc["sweep"].as_array().map(Vec::len), Some(0), "--no-sweep: {doc}");
    assert_eq!(doc["paper"][0]["controller"], "BLE");
    assert_eq!(doc["robustness"][0]["kill"], true);
    assert_eq!(doc["report"].as_str(), Some(out.join("index.html").to_str().expect("UTF-8")));
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bad_arguments_and_an_unwritable_folder_fail_with_a_message() {
    let limit = Duration::from_secs(30);
    ayllu(&["sim", "cmommt", "--seeds", "0"], limit).fails(2, "--seeds");
    ayllu(&["sim", "cmommt", "--duration", "-3"], limit).fails(2, "--duration");
    ayllu(&["sim", "cmommt", "--jobs", "0"], limit).fails(2, "--jobs");

    // A file where the report folder should go.
    let dir = scratch("unwritable");
    let file = dir.join("taken");
    std::fs::write(&file, "not a folder").expect("writing the blocker");
    let args =
        ["sim", "cmommt", "--no-sweep", "--seeds", "1", "--duration", "5", "--out", file.to_str().expect("UTF-8")];
    ayllu(&args, LIMIT).fails(1, "writing the report into");
    let _ = std::fs::remove_dir_all(&dir);
}
