//! Tests of the report folder on the synthetic report of `tests/fixture.rs`: the files, the
//! page's self-containment and escaping, the JSON round trips, and the tables' shape. What the
//! page looks like in a browser is `tests/report_chromium.rs`'s job.

mod fixture;

use std::fs;
use std::path::PathBuf;

use super::Report;
use crate::metrics::Metrics;
use crate::recording::{CoverageSeries, Event, Frame, Recording, RecordingMeta, RobotFrame, RobotInfo, TargetInfo};
use crate::study::Row;

use super::{text_table, write};

/// A fresh directory per test under the system temp dir (tests run in parallel).
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ayllu-sim-report-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    dir
}

/// The text between `<script type="application/json" id="data">` and its `</script>`.
fn data_block(html: &str) -> &str {
    let open = "<script type=\"application/json\" id=\"data\">";
    let start = html.find(open).expect("data block") + open.len();
    let len = html[start..].find("</script>").expect("end of data block");
    &html[start..start + len]
}

#[test]
fn writes_every_file_it_promises() {
    let dir = scratch("files");
    let files = write(&dir, &fixture::report()).unwrap();
    let names: Vec<String> = files.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(
        names,
        [
            "index.html",
            "coverage.svg",
            "sweep_robots.svg",
            "sweep_loss.svg",
            "robustness.svg",
            "results.json",
            "results.md"
        ]
    );
    for f in &files {
        assert!(f.starts_with(&dir));
        assert!(fs::metadata(f).unwrap().len() > 200, "{} is nearly empty", f.display());
    }
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn page_is_self_contained() {
    let dir = scratch("self-contained");
    write(&dir, &fixture::report()).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    let without_svg_ns = html.replace("xmlns=\"http://www.w3.org/2000/svg\"", "");
    assert!(!without_svg_ns.contains("http://"), "external http reference");
    assert!(!without_svg_ns.contains("https://"), "external https reference");
    assert!(!html.contains("<link"), "no linked resources");
    assert!(!html.contains(" src="), "no loaded resources (scripts, images)");
    assert!(!html.contains("<img"), "plots are inline SVG, not images");
    // The four plots are inline, and also files with the same markup.
    assert_eq!(html.matches("<svg width=\"").count() - html.matches("<li><svg").count(), 4);
    for plot in ["coverage", "sweep_robots", "sweep_loss", "robustness"] {
        let svg = fs::read_to_string(dir.join(format!("{plot}.svg"))).unwrap();
        assert!(svg.starts_with("<svg"), "{plot}.svg");
        assert!(html.contains(svg.trim_end()), "{plot}.svg is inlined");
    }
    assert!(html.contains("data-status=\"loading\""), "the script, not the server, says drawn");
    assert!(html.contains("id=\"arena\""));
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn embedded_data_round_trips_to_the_recording() {
    let report = fixture::report();
    let dir = scratch("data");
    write(&dir, &report).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    let value: serde_json::Value = serde_json::from_str(data_block(&html)).unwrap();
    let recording: Recording = serde_json::from_value(value["recording"].clone()).unwrap();
    assert_eq!(recording, report.recording);
    assert_eq!(value["coverage"].as_array().unwrap().len(), 5);
    assert_eq!(value["coverage"][0]["colour"], "#1f5fbf", "BLE keeps its plot colour in the replay");
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn hostile_strings_cannot_break_out_of_the_page() {
    let mut report = fixture::report();
    let evil = "</script><script>alert(1)</script><!-- & \"quotes\" 'single'";
    report.title = evil.into();
    report.command = evil.into();
    report.recording.meta.controller = evil.into();
    report.paper[0].controller = evil.into();
    let dir = scratch("hostile");
    write(&dir, &report).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(!html.contains("<script>alert"), "a string from the report became markup");
    assert!(!html.contains("<!-- &"), "a string from the report opened an HTML comment");
    // Exactly the page's own three scripts end: the error trap, the data, the replay.
    assert_eq!(html.matches("</script>").count(), 3);
    let value: serde_json::Value = serde_json::from_str(data_block(&html)).unwrap();
    assert_eq!(value["recording"]["meta"]["controller"], evil);
    assert!(html.contains("&lt;/script&gt;&lt;script&gt;alert(1)"));
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn results_json_is_the_whole_report() {
    let report = fixture::report();
    let dir = scratch("json");
    write(&dir, &report).unwrap();
    let back: Report = serde_json::from_str(&fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    assert_eq!(back, report);
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn markdown_has_the_three_tables() {
    let report = fixture::report();
    let dir = scratch("md");
    write(&dir, &report).unwrap();
    let md = fs::read_to_string(dir.join("results.md")).unwrap();
    assert_eq!(md.matches("| controller | robots |").count(), 3);
    let rows =
        md.lines().filter(|l| l.starts_with("| ") && !l.starts_with("| controller") && !l.starts_with("| :--")).count();
    assert_eq!(rows, report.paper.len() + report.robustness.len() + report.sweep.len());
    assert!(md.contains("## Paper setting") && md.contains("## Robustness") && md.contains("## Sweep"));
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn writing_twice_gives_the_same_bytes() {
    let report = fixture::report();
    let (a, b) = (scratch("det-a"), scratch("det-b"));
    let fa = write(&a, &report).unwrap();
    let fb = write(&b, &report).unwrap();
    for (x, y) in fa.iter().zip(&fb) {
        assert_eq!(fs::read(x).unwrap(), fs::read(y).unwrap(), "{}", x.display());
    }
    fs::remove_dir_all(&a).unwrap();
    fs::remove_dir_all(&b).unwrap();
}

#[test]
fn an_empty_report_still_writes_a_page() {
    let mut report = fixture::report();
    report.recording.frames.clear();
    report.recording.events.clear();
    report.coverage.clear();
    report.paper.clear();
    report.sweep.clear();
    report.robustness.clear();
    let dir = scratch("empty");
    let files = write(&dir, &report).unwrap();
    assert_eq!(files.len(), 7);
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("(no runs)"));
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn text_table_is_a_header_and_one_line_per_row() {
    let report = fixture::report();
    let table = text_table(&report.robustness);
    let lines: Vec<&str> = table.lines().collect();
    assert_eq!(lines.len(), report.robustness.len() + 1);
    for h in ["controller", "robots", "targets", "loss %", "kill", "seeds", "A_w ± sd", "top-k", "recover s"] {
        assert!(lines[0].contains(h), "header lacks {h}");
    }
    // Robustness rows: 10 % loss reads "10", the kill column "yes", A_w with its spread.
    let r = &report.robustness[5];
    assert_eq!((r.controller.as_str(), r.loss), ("BLE", 0.1));
    let ble_10 = lines[6];
    let cols: Vec<&str> = ble_10.split_whitespace().collect();
    assert_eq!(&cols[..6], ["BLE", "3", "4", "10", "yes", "10"]);
    assert!(ble_10.contains(&format!("{:.3} ± {:.3}", r.metrics.a_w, r.a_w_sd)));
    // Numbers are right-aligned: every line ends at the same column.
    let width = lines[0].chars().count();
    assert!(lines.iter().all(|l| l.chars().count() == width), "ragged table:\n{table}");
}

#[test]
fn text_table_shows_a_dash_without_a_recover_time() {
    let report = fixture::report();
    let table = text_table(&report.paper);
    assert_eq!(table.lines().count(), report.paper.len() + 1);
    for line in table.lines().skip(1) {
        let cols: Vec<&str> = line.split_whitespace().collect();
        // ... recover s, msgs/robot/s: the second-to-last column.
        assert_eq!(cols[cols.len() - 2], "-", "{line}");
    }
    assert_eq!(text_table(&[]).lines().count(), 1);
}

#[test]
fn moving_average_is_centred_and_keeps_the_ends() {
    let t: Vec<f64> = (0..7).map(f64::from).collect();
    let y = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    let smooth = super::plots::moving_average(&t, &y, 2.0);
    let ys: Vec<f64> = smooth.iter().map(|p| p.1).collect();
    assert_eq!(smooth.len(), 7);
    assert_eq!(ys, [0.0, 0.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.0, 0.0]);
    assert_eq!(smooth[3].0, 3.0, "times are not shifted");
}

#[test]
fn a_long_coverage_series_is_smoothed_and_says_so() {
    let mut report = fixture::report();
    for (_, s) in &mut report.coverage {
        let n = 3000;
        s.t = (0..n).map(|i| f64::from(i) * 0.2).collect();
        s.weighted = (0..n).map(|i| if i % 2 == 0 { 0.25 } else { 0.75 }).collect();
        s.observed = (0..n).map(|i| if i % 2 == 0 { 1 } else { 3 }).collect();
    }
    let dir = scratch("smooth");
    write(&dir, &report).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("moving average over 12.0 s"));
    fs::remove_dir_all(&dir).unwrap();
}
