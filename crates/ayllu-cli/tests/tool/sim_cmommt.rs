//! `ayllu sim cmommt` as a user runs it: the built binary, a small study (`--quick` with
//! fewer seeds and shorter runs, so that the debug build finishes in seconds), its short summary
//! on stdout (and its tables with `--full`), its report folder on disk; the same numbers whatever
//! `--jobs`; the errors a user meets (bad arguments, an output folder that cannot be written);
//! a reader that goes away early (`| head -1`), which must end the command with exit code 0 and
//! no panic; and the progress bar, which must appear when stderr is a terminal.
//!
//! Every run is bounded (killed, and the test failed, past its limit). The report folders go
//! under Cargo's per-target scratch directory, one per test, emptied first.

use crate::common;

use std::fs::File;
use std::io::Read;
use std::os::fd::{FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use common::{ayllu, BIN};
use serde_json::Value as Json;

const CONTROLLERS: [&str; 6] = ["BLE", "Random", "Local", "ForceField", "Centralized", "Planner"];
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

/// The small study every test here runs, into `out`, with `extra` arguments.
fn quick_args<'a>(out: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let out = out.to_str().expect("a UTF-8 path");
    [&["sim", "cmommt", "--quick", "--seeds", "2", "--duration", "60", "--out", out][..], extra].concat()
}

#[test]
fn a_quick_study_prints_the_summary_then_the_tables_with_full_and_writes_the_report() {
    let out = scratch("quick");
    let run = ayllu(&quick_args(&out, &["--full"]), LIMIT).ok();
    println!("{}\n{}took {:?}", run.stdout, run.stderr, run.took);
    // The point first: the summary opens the output, the tables follow.
    assert!(run.stdout.starts_with("W-CMOMMT in the paper's setting"), "{}", run.stdout);
    let summary_end = run.stdout.find("\nPaper setting:").expect("the tables after the summary");
    assert!(run.stdout[..summary_end].contains("The paper's claim "), "{}", run.stdout);

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
    assert_eq!((paper.len(), robustness.len(), sweep.len()), (1 + 6, 1 + 18, 1 + 24));
    let (ble, random) = (a_w(&paper, "BLE"), a_w(&paper, "Random"));
    assert!(ble > random, "BLE's A_w {ble} should beat Random's {random}");
    for name in &CONTROLLERS[1..] {
        assert!(run.stdout.contains(&format!("BLE − {name} = ")), "no comparison line for {name}");
    }

    let index = out.join("index.html");
    assert!(run.stdout.contains(&format!("Report: {}", index.display())), "{}", run.stdout);
    assert!(run.stdout.contains("Wall time: "));
    // What --full printed before the report's path is the folder's tables.txt.
    let tables = std::fs::read_to_string(out.join("tables.txt")).expect("tables.txt");
    assert!(run.stdout.starts_with(&tables), "stdout:\n{}\ntables.txt:\n{tables}", run.stdout);
    for file in ["index.html", "coverage.svg", "sweep_robots.svg", "sweep_loss.svg", "robustness.svg", "results.json"] {
        let len = std::fs::metadata(out.join(file)).map(|m| m.len()).unwrap_or(0);
        assert!(len > 0, "{file} missing or empty in {}", out.display());
    }
    // Not a terminal: plain progress lines instead of a bar.
    assert!(run.stderr.contains("runs (100%)"), "{}", run.stderr);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn by_default_it_prints_a_short_summary_and_the_page_replays_every_recorded_run() {
    let out = scratch("summary");
    let run = ayllu(&quick_args(&out, &[]), LIMIT).ok();
    println!("{}\n{}", run.stdout, run.stderr);
    let lines: Vec<&str> = run.stdout.lines().collect();
    assert!(lines.len() <= 18, "{} lines is not short:\n{}", lines.len(), run.stdout);
    assert!(lines[0].starts_with("W-CMOMMT in the paper's setting (3 robots, 4 targets, 0 % loss; 2 seeds x 60 s)"));
    // BLE against every baseline on A_w, then the verdict on the paper's claim.
    for name in &CONTROLLERS[1..] {
        assert!(run.stdout.contains(&format!("BLE − {name} = ")), "no comparison line for {name}");
    }
    let rows: Vec<&str> = lines.iter().copied().filter(|l| l.starts_with("  ") && l.contains(" A_w ")).collect();
    assert_eq!(rows.len(), CONTROLLERS.len(), "one line per controller: {rows:#?}");
    assert!(a_w(&rows, "BLE") > a_w(&rows, "Random"), "{}", run.stdout);
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("The paper's claim held") || l.starts_with("The paper's claim did NOT hold")),
        "{}",
        run.stdout
    );
    assert!(lines.iter().any(|l| l.starts_with("Robot killed halfway (0 % loss): BLE's A_w ")), "{}", run.stdout);
    // No table on stdout, but where the tables are.
    assert!(!lines.iter().any(|l| l.starts_with("controller ")), "{}", run.stdout);
    let tables = out.join("tables.txt");
    assert!(run.stdout.contains(&format!("Tables: {} (or run with --full)", tables.display())), "{}", run.stdout);
    let tables = std::fs::read_to_string(tables).expect("tables.txt");
    assert_eq!(tables.lines().filter(|l| l.starts_with("controller ")).count(), 3, "{tables}");
    assert!(tables.starts_with(&run.stdout[..run.stdout.find("\n\n").expect("a blank line after the summary")]));

    // The page: every controller and seed of the paper's setting (6 x 2) and of the robustness
    // scenario (18 x 2), seed 1 of each sweep cell (24), each a run of its own, and BLE first.
    let html = std::fs::read_to_string(out.join("index.html")).expect("index.html");
    let runs = html.matches("<script type=\"application/json\" id=\"run-").count();
    assert_eq!(runs, 12 + 36 + 24, "replayable runs");
    let open = "<script type=\"application/json\" id=\"data\">";
    let data = &html[html.find(open).expect("the data block") + open.len()..];
    let data: Json = serde_json::from_str(&data[..data.find("</script>").expect("its end")]).expect("JSON");
    let menu = data["runs"].as_array().expect("the runs' menu");
    assert_eq!(
        (menu[0]["setting"].as_str(), menu[0]["controller"].as_str(), menu[0]["seed"].as_u64()),
        (Some("Paper setting"), Some("BLE"), Some(1))
    );
    for setting in ["Robustness: 0 % loss", "Robustness: 30 % loss", "Sweep: 5 robots, 4 targets, 30 % loss"] {
        for name in CONTROLLERS {
            assert!(menu.iter().any(|r| r["setting"] == setting && r["controller"] == name), "{setting} {name}");
        }
    }
    assert!(html.contains("72 runs can be replayed"), "the page says what it holds");
    let _ = std::fs::remove_dir_all(&out);
}

/// Waits for `child` up to `limit`, killing it (and failing the test) past it.
fn wait_bounded(child: &mut Child, limit: Duration) -> ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("waiting for the CLI") {
            return status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("ayllu sim cmommt ran longer than {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A pipe whose buffer is one page, and that size: a writer blocks (and then meets the closed
/// end) once it is full, whatever the system's default pipe size, so the test does not depend on
/// timing.
fn small_pipe() -> (File, OwnedFd, u64) {
    let mut fds = [0; 2];
    // SAFETY: pipe2 writes two new descriptors into the array we own; we take ownership of both.
    assert_eq!(unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) }, 0, "pipe2");
    // SAFETY: fds[0] is an open pipe descriptor owned here.
    let size = unsafe { libc::fcntl(fds[0], libc::F_SETPIPE_SZ, 4096) };
    assert!(size >= 4096, "F_SETPIPE_SZ: {}", std::io::Error::last_os_error());
    // SAFETY: both descriptors are open and owned by nobody else.
    unsafe { (File::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1]), size as u64) }
}

/// Reads up to and including the first newline, one byte at a time (nothing read beyond it).
fn first_line(reader: &mut File) -> String {
    let mut line = Vec::new();
    let mut byte = [0u8];
    while reader.read(&mut byte).expect("reading the pipe") == 1 {
        line.push(byte[0]);
        if byte[0] == b'\n' {
            break;
        }
    }
    String::from_utf8_lossy(&line).into_owned()
}

#[test]
fn a_reader_that_goes_away_after_one_line_ends_the_command_quietly() {
    // `ayllu sim cmommt --full | head -1`: the output (summary and tables, about 7 kB) cannot
    // fit in the 4 kB pipe with the line read, so the command certainly writes after the reader
    // closed its end.
    let out = scratch("pipe");
    let (mut reader, writer, capacity) = small_pipe();
    let mut child = Command::new(BIN)
        .args(quick_args(&out, &["--full"]))
        .stdin(Stdio::null())
        .stdout(Stdio::from(writer))
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting ayllu");
    let mut stderr = child.stderr.take().expect("piped stderr");
    let err_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let line = first_line(&mut reader);
    drop(reader);
    let status = wait_bounded(&mut child, LIMIT);
    let stderr = err_reader.join().expect("stderr reader");
    println!("first line: {line}stderr:\n{stderr}");
    assert!(line.starts_with("W-CMOMMT"), "{line:?}");
    let written = std::fs::metadata(out.join("tables.txt")).map(|m| m.len()).unwrap_or(0);
    assert!(written > capacity + line.len() as u64, "the output ({written} bytes) must overflow the pipe");
    assert_eq!(status.code(), Some(0), "{status:?}\n{stderr}");
    assert!(!stderr.contains("panicked") && !stderr.contains("internal error"), "{stderr}");
    assert!(!stderr.contains("ayllu:"), "no error message for a reader that left: {stderr}");

    // `2>&1 | head -1`: progress lines share the closed pipe too; they must not end the command
    // either (a panic there would abort, as the panic hook's own message cannot be written).
    let (mut reader, writer, _) = small_pipe();
    let both = writer.try_clone().expect("dup");
    let mut child = Command::new(BIN)
        .args(quick_args(&out, &["--full"]))
        .stdin(Stdio::null())
        .stdout(Stdio::from(writer))
        .stderr(Stdio::from(both))
        .spawn()
        .expect("starting ayllu");
    let line = first_line(&mut reader);
    drop(reader);
    let status = wait_bounded(&mut child, LIMIT);
    assert!(line.starts_with("sim cmommt: "), "{line:?}");
    assert_eq!(status.code(), Some(0), "{status:?}");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn the_progress_bar_appears_when_stderr_is_a_terminal() {
    let out = scratch("tty");
    let (mut master, mut slave) = (-1, -1);
    let size = libc::winsize { ws_row: 40, ws_col: 120, ws_xpixel: 0, ws_ypixel: 0 };
    // SAFETY: openpty writes two new descriptors into our integers; name and termios may be null.
    let opened = unsafe { libc::openpty(&mut master, &mut slave, std::ptr::null_mut(), std::ptr::null(), &size) };
    assert_eq!(opened, 0, "openpty: {}", std::io::Error::last_os_error());
    // SAFETY: both descriptors are open and owned by nobody else.
    let (mut master, slave) = unsafe { (File::from_raw_fd(master), OwnedFd::from_raw_fd(slave)) };
    let mut child = Command::new(BIN)
        .args(quick_args(&out, &[]))
        .env("TERM", "xterm")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::from(slave))
        .spawn()
        .expect("starting ayllu");
    // Reads until the terminal's other side is closed (EIO once the child has exited).
    let reader = std::thread::spawn(move || {
        let mut seen = Vec::new();
        let mut buf = [0u8; 4096];
        while let Ok(n) = master.read(&mut buf) {
            if n == 0 {
                break;
            }
            seen.extend_from_slice(&buf[..n]);
        }
        String::from_utf8_lossy(&seen).into_owned()
    });
    let status = wait_bounded(&mut child, LIMIT);
    let seen = reader.join().expect("terminal reader");
    println!("{seen:?}");
    assert_eq!(status.code(), Some(0), "{seen}");
    // The bar: "00:00:01 [=====>    ] 57/96 runs, 1s left", redrawn in place.
    assert!(seen.contains("/96 runs, ") && seen.contains(" left") && seen.contains("=>"), "no bar: {seen:?}");
    // And not the plain lines meant for logs.
    assert!(!seen.contains("runs (100%)"), "plain progress lines on a terminal: {seen:?}");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn the_numbers_do_not_depend_on_the_number_of_threads() {
    let out = scratch("jobs");
    let out_arg = out.to_str().expect("a UTF-8 path");
    // --json prints the rows only: the same document for the same arguments.
    let study = |jobs: &str| {
        let args = ["sim", "cmommt", "--no-sweep", "--seeds", "2", "--duration", "20", "--json", "--jobs", jobs];
        ayllu(&[&args[..], &["--out", out_arg]].concat(), LIMIT).ok()
    };
    let one = study("1");
    let three = study("3");
    assert_eq!(one.stdout, three.stdout, "the same study on 1 and 3 threads");
    let doc: Json = one.json();
    assert_eq!(doc["paper"].as_array().map(Vec::len), Some(6), "{doc}");
    assert_eq!(doc["robustness"].as_array().map(Vec::len), Some(18), "{doc}");
    assert_eq!(doc["sweep"].as_array().map(Vec::len), Some(0), "--no-sweep: {doc}");
    assert_eq!(doc["paper"][0]["controller"], "BLE");
    assert_eq!(doc["robustness"][0]["kill"], true);
    assert_eq!(doc["report"].as_str(), Some(out.join("index.html").to_str().expect("UTF-8")));
    let _ = std::fs::remove_dir_all(&out);
}

/// `--eligibility lean` adds a BLE-lean row after BLE in every table and changes no other row:
/// the study's rows without it are those with it, the BLE-lean rows taken out.
#[test]
fn eligibility_lean_adds_a_ble_lean_row_and_changes_no_other() {
    let out = scratch("lean");
    let out_arg = out.to_str().expect("a UTF-8 path");
    let study = |extra: &[&str]| {
        let args = ["sim", "cmommt", "--no-sweep", "--seeds", "1", "--duration", "20", "--json", "--out", out_arg];
        ayllu(&[&args[..], extra].concat(), LIMIT).ok().json()
    };
    let paper: Json = study(&[]);
    let lean: Json = study(&["--eligibility", "lean"]);
    for table in ["paper", "robustness"] {
        let with: &Vec<Json> = lean[table].as_array().expect("rows");
        let names: Vec<&str> = with.iter().filter_map(|r| r["controller"].as_str()).take(7).collect();
        assert_eq!(names, ["BLE", "BLE-lean", "Random", "Local", "ForceField", "Centralized", "Planner"], "{table}");
        let without: Vec<&Json> = with.iter().filter(|r| r["controller"] != "BLE-lean").collect();
        let before: Vec<&Json> = paper[table].as_array().expect("rows").iter().collect();
        assert_eq!(without, before, "{table}: the other rows are unchanged");
        let msgs = |c: &str| {
            with.iter().find(|r| r["controller"] == c).expect("a row")["metrics"]["msgs_per_robot_s"].as_f64()
        };
        assert!(msgs("BLE-lean") < msgs("BLE"), "{table}: the lean policy sends fewer messages");
    }
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

#[test]
fn every_run_is_exported_and_the_printed_means_are_recomputable_from_them() {
    // runs.csv and runs.jsonl: one row per (table, cell, seed) of the study, with every
    // metric; the mean of a cell's rows is the number its table prints (results.json).
    let out = scratch("runs");
    ayllu(&quick_args(&out, &["--json"]), LIMIT).ok();
    let results: Json = serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name} column"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let cells: usize = ["paper", "sweep", "robustness"].iter().map(|t| results[t].as_array().unwrap().len()).sum();
    assert_eq!(rows.len(), cells * 2, "one row per cell and seed (2 seeds)");
    let jsonl = std::fs::read_to_string(out.join("runs.jsonl")).unwrap();
    assert_eq!(jsonl.lines().count(), rows.len());
    for (table, tname) in [("paper", "paper"), ("robustness", "robustness")] {
        for row in results[table].as_array().unwrap() {
            let controller = row["controller"].as_str().unwrap();
            let loss = row["loss"].as_f64().unwrap();
            let mine: Vec<f64> = rows
                .iter()
                .filter(|r| r[col("table")] == tname && r[col("controller")] == controller)
                .filter(|r| r[col("loss")].parse::<f64>().unwrap() == loss)
                .map(|r| r[col("a_w")].parse().unwrap())
                .collect();
            assert_eq!(mine.len(), 2, "{table} {controller} {loss}");
            let mean = mine.iter().sum::<f64>() / 2.0;
            let printed = row["metrics"]["a_w"].as_f64().unwrap();
            assert!((mean - printed).abs() < 1e-12, "{table} {controller}: {mean} vs {printed}");
        }
    }
}
