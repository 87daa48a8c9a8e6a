//! Tests of the report folder on the synthetic report of `tests/fixture.rs`: the files, the
//! page's self-containment and escaping, the JSON round trips, the replays' compact code, the
//! summary's verdicts, and the tables' shape. What the page looks like in a browser is
//! `tests/simulator/report_chromium.rs`'s job.

mod fixture;

use std::fs;
use std::path::PathBuf;

use super::{Replay, Report};
use crate::metrics::Metrics;
use crate::recording::{CoverageSeries, Event, Frame, Recording, RecordingMeta, RobotFrame, RobotInfo, TargetInfo};
use crate::study::{Row, RunRow};

use super::{compare, decode, encode, paper_claim, summary_text, tables_text, text_table, write, Verdict};

/// A fresh directory per test under the system temp dir (tests run in parallel).
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ayllu-sim-report-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    dir
}

/// The text between `<script type="application/json" id="ID">` and its `</script>`.
fn json_block<'a>(html: &'a str, id: &str) -> &'a str {
    let open = format!("<script type=\"application/json\" id=\"{id}\">");
    let start = html.find(&open).unwrap_or_else(|| panic!("no {id} block")) + open.len();
    let len = html[start..].find("</script>").expect("end of the block");
    &html[start..start + len]
}

fn data_block(html: &str) -> &str {
    json_block(html, "data")
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
            "results.md",
            "tables.txt",
            "runs.csv",
            "runs.jsonl"
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
fn every_replay_is_embedded_and_round_trips() {
    let report = fixture::report();
    let dir = scratch("data");
    write(&dir, &report).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    let value: serde_json::Value = serde_json::from_str(data_block(&html)).unwrap();
    let runs = value["runs"].as_array().unwrap();
    assert_eq!(runs.len(), report.replays.len());
    for (i, replay) in report.replays.iter().enumerate() {
        assert_eq!(runs[i]["setting"], replay.setting.as_str());
        assert_eq!(runs[i]["controller"], replay.meta.controller.as_str());
        assert_eq!(runs[i]["seed"], replay.meta.seed);
        let back: Replay = serde_json::from_str(json_block(&html, &format!("run-{i}"))).unwrap();
        assert_eq!(&back, replay, "run {i}");
    }
    assert!(!html.contains(&format!("id=\"run-{}\"", report.replays.len())), "no run beyond the replays");
    assert_eq!(value["colours"]["BLE"], "#1f5fbf", "BLE keeps its plot colour in the replay");
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_replay_decodes_to_the_recording_at_its_samples() {
    let rec = fixture::recording();
    let replay = Replay::new("Paper setting", &rec, 1.0);
    // Frames every 0.5 s, a sample every 1 s: every second frame, ending on the last one.
    assert_eq!((replay.frames, replay.every), (61, 2));
    let samples = replay.sample_frames();
    assert_eq!(samples.first(), Some(&0));
    assert_eq!(samples.last(), Some(&60));
    assert_eq!(samples.len(), 31);
    for k in 0..rec.robots.len() {
        let poses = replay.robot_poses(k).unwrap();
        assert_eq!(poses.len(), samples.len());
        for (&f, &(x, y, h)) in samples.iter().zip(&poses) {
            let r = &rec.frames[f as usize].robots[k];
            let near = |a: f64, b: f64| (a - b).abs() <= 0.005 + 1e-9;
            assert!(near(x, r.x) && near(y, r.y), "robot {k} frame {f}: {x},{y} vs {r:?}");
            let turn = std::f64::consts::TAU;
            let off = (h - r.theta).rem_euclid(turn).min((r.theta - h).rem_euclid(turn));
            assert!(off <= turn / 512.0 + 1e-9, "robot {k} frame {f}: heading {h} vs {}", r.theta);
        }
    }
    for j in 0..rec.targets.len() {
        let path = replay.target_path(j).unwrap();
        for (&f, &(x, y)) in samples.iter().zip(&path) {
            let p = rec.frames[f as usize].targets[j];
            assert!((x - p[0]).abs() <= 0.005 + 1e-9 && (y - p[1]).abs() <= 0.005 + 1e-9, "target {j} frame {f}");
        }
    }
    // Discrete state is exact at every frame, sampled or not.
    for (f, frame) in rec.frames.iter().enumerate() {
        for (k, r) in frame.robots.iter().enumerate() {
            let s = replay.state_at(k, f as u32).unwrap();
            assert_eq!(
                (s.1 == 1, s.2, &s.3, &s.4, &s.5),
                (r.alive, r.drive, &r.claims, &r.inhibited, &r.observing),
                "robot {k} frame {f}"
            );
        }
    }
    // A change is stored once, not once per frame.
    for k in 0..rec.robots.len() {
        assert!(replay.changes(k).unwrap().len() < rec.frames.len() / 2, "{:?}", replay.changes(k));
    }
}

#[test]
fn the_code_is_one_character_for_small_steps_and_five_for_big_ones() {
    let values = [0, 1, -1, 31, -31, 32, -32, 2000, -2000, 8_388_607, -8_388_607];
    let text = encode(&values);
    assert_eq!(text.len(), 5 + 5 * 6);
    assert_eq!(decode(&text).unwrap(), values);
    assert_eq!(encode(&[0, 5, -5]).len(), 3);
    assert!(text.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'+' || b == b'/'), "{text}");
    // Garbage and a truncated escape are refused, not misread.
    assert_eq!(decode("A\""), None);
    assert_eq!(decode("/AB"), None);
    // Far beyond any arena: clamped, not wrapped into a small number.
    assert_eq!(decode(&encode(&[1 << 40])).unwrap(), [(1 << 23) - 1]);
}

#[test]
fn a_simulated_run_costs_about_one_character_per_coordinate() {
    use crate::controller::Controller;
    use crate::scenario::{run, Scenario};
    // A real run: robots at up to 0.4 m/s and 1.5 rad/s, targets at 0.15 m/s, a robot killed.
    let outcome = run(&Scenario::paper(Controller::Ble, 1).duration(60.0).kill_halfway().recorded()).unwrap();
    let rec = outcome.recording.unwrap();
    let replay = Replay::new("Robustness: 0 % loss", &rec, 0.4);
    assert_eq!(replay.every, 2);
    let samples = replay.sample_frames().len();
    // The first sample is absolute (an escape per coordinate); then one character per step,
    // but for a few big ones (a robot pushed, a fast turn).
    for (k, code) in replay.poses.iter().enumerate() {
        assert!(code.len() <= 3 * samples + 3 * 4 + 40, "robot {k}: {} chars for {samples} samples", code.len());
        assert_eq!(replay.robot_poses(k).unwrap().len(), samples);
    }
    for (j, code) in replay.paths.iter().enumerate() {
        assert!(code.len() <= 2 * samples + 2 * 4 + 10, "target {j}: {} chars for {samples} samples", code.len());
    }
    // The kill is there, and the dead robot's state says so from then on.
    assert_eq!(replay.events.len(), 1);
    let dead = replay.events[0].robot as usize - 1;
    let changes = replay.changes(dead).unwrap();
    let last = changes.last().unwrap();
    assert_eq!((last.1, last.2), (0, 0), "{last:?}");
    assert!(f64::from(last.0) * rec.meta.frame_dt >= 30.0 - 1e-9);
    let json = serde_json::to_string(&replay).unwrap();
    // 60 s of 3 robots and 4 targets in under 4 kB (measured: 3.6 kB), where the recording's
    // JSON takes over 100 kB.
    assert!(json.len() < 4000, "{} bytes", json.len());
    assert!(serde_json::to_string(&rec).unwrap().len() > 100_000);
}

#[test]
fn hostile_strings_cannot_break_out_of_the_page() {
    let mut report = fixture::report();
    let evil = "</script><script>alert(1)</script><!-- & \"quotes\" 'single'";
    report.title = evil.into();
    report.command = evil.into();
    report.replays[0].meta.controller = evil.into();
    report.replays[1].setting = evil.into();
    report.paper[0].controller = evil.into();
    let dir = scratch("hostile");
    write(&dir, &report).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(!html.contains("<script>alert"), "a string from the report became markup");
    assert!(!html.contains("<!-- &"), "a string from the report opened an HTML comment");
    // Exactly the page's own scripts end: the error trap, the data, one per run, the replay.
    assert_eq!(html.matches("</script>").count(), 3 + report.replays.len());
    let value: serde_json::Value = serde_json::from_str(data_block(&html)).unwrap();
    assert_eq!(value["runs"][0]["controller"], evil);
    assert_eq!(value["runs"][1]["setting"], evil);
    let run: serde_json::Value = serde_json::from_str(json_block(&html, "run-0")).unwrap();
    assert_eq!(run["meta"]["controller"], evil);
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
    report.replays.truncate(1);
    let mut empty = fixture::recording();
    empty.frames.clear();
    empty.events.clear();
    report.replays[0] = Replay::new("Paper setting", &empty, 1.0);
    report.coverage.clear();
    report.paper.clear();
    report.sweep.clear();
    report.robustness.clear();
    let dir = scratch("empty");
    let files = write(&dir, &report).unwrap();
    assert_eq!(files.len(), 10);
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("(no runs)"));
    assert!(html.contains("No BLE runs"));
    report.replays.clear();
    write(&dir, &report).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("No run was recorded for a replay."));
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

#[test]
fn the_page_says_which_runs_it_can_replay_and_how_they_were_thinned() {
    let dir = scratch("note");
    write(&dir, &fixture::report()).unwrap();
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    // The fixture's rows say 10 seeds; its replays keep seeds 7-8, 7 and 1.
    assert!(
        html.contains("5 runs can be replayed: Paper setting: 2 controllers × seeds 7–8 of the 10 studied"),
        "{html}"
    );
    assert!(html.contains("Robustness: 1 controller × seed 7 of the 10 studied"));
    assert!(html.contains("positions are kept every 1.00 s (the simulator recorded a frame every 0.5 s)"));
    for id in ["run-setting", "run-controller", "run-seed"] {
        assert!(html.contains(&format!("<select id=\"{id}\"")), "{id}");
    }
    fs::remove_dir_all(&dir).unwrap();
}

fn paper_row(controller: &str, a_w: f64, sd: f64) -> Row {
    let mut row = fixture::report().paper[0].clone();
    row.controller = controller.into();
    row.metrics.a_w = a_w;
    row.a_w_sd = sd;
    row
}

#[test]
fn comparisons_tell_a_gap_from_noise() {
    // 10 seeds each, sd 0.05: one standard error of the difference is sqrt(2 * 0.0025 / 10).
    let se = (2.0 * 0.05f64.powi(2) / 10.0).sqrt();
    let paper = [
        paper_row("BLE", 0.70, 0.05),
        paper_row("Random", 0.10, 0.05),
        paper_row("Local", 0.70 - 1.9 * se, 0.05),
        paper_row("Centralized", 0.70 + 2.1 * se, 0.05),
    ];
    let c = compare(&paper);
    assert_eq!(c.iter().map(|c| c.controller.as_str()).collect::<Vec<_>>(), ["Random", "Local", "Centralized"]);
    assert!((c[0].se - se).abs() < 1e-12 && (c[0].diff - 0.6).abs() < 1e-12);
    assert_eq!([c[0].verdict, c[1].verdict, c[2].verdict], [Verdict::Better, Verdict::WithinNoise, Verdict::Worse]);
    // Local within noise: the paper's claim (better than Random AND Local) did not hold.
    assert_eq!(paper_claim(&paper), Some(false));
    let mut held = paper.clone();
    held[2].metrics.a_w = 0.5;
    assert_eq!(paper_claim(&held), Some(true));
    assert_eq!(paper_claim(&held[..2]), None, "no Local row: cannot be checked");
    assert!(compare(&held[1..]).is_empty(), "no BLE row: nothing to compare");
}

#[test]
fn the_summary_is_short_and_gives_the_verdicts() {
    let report = fixture::report();
    let text = summary_text(&report);
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines.len() <= 12, "{text}");
    assert!(lines[0].starts_with("W-CMOMMT in the paper's setting (3 robots, 4 targets, 0 % loss; 10 seeds x 30 s)"));
    for name in ["Random", "Local", "ForceField", "Centralized"] {
        assert!(text.contains(&format!("BLE − {name} = ")), "{name}: {text}");
    }
    // Fixture: BLE 0.675 against Local 0.476, sd 0.02 over 10 seeds each -> better, and the
    // claim held.
    assert!(text.contains("BLE − Local = +0.199 ± 0.009 (x1.42): BLE better"), "{text}");
    assert!(text.contains("The paper's claim held"), "{text}");
    assert!(text.contains("the upper bound: BLE reaches 95 % of its A_w"), "{text}");
    // Robustness at 0 % loss: the fixture's BLE recovers in 4 + 10 * (1 - 0.78) = 6.2 s.
    assert!(text.contains("Robot killed halfway (0 % loss): BLE's A_w 0.675 -> 0.675"), "{text}");
    assert!(text.contains("re-covered in 6.2 s on average"), "{text}");
    // Short enough for a terminal.
    assert!(lines.iter().all(|l| l.chars().count() <= 120), "{text}");
    let mut lost = report.clone();
    let ble_killed = lost.robustness.iter_mut().find(|r| r.controller == "BLE" && r.loss == 0.0).unwrap();
    ble_killed.metrics.unrecovered = 2;
    let text = summary_text(&lost);
    assert!(text
        .contains("re-covered in 6.2 s on average,\n  counting as the time left the 2 never re-covered in 10 runs."));
    assert!(text.lines().all(|l| l.chars().count() <= 120), "{text}");
    let mut worse = report.clone();
    worse.paper[3].metrics.a_w = 0.9; // Local
    assert!(summary_text(&worse).contains("The paper's claim did NOT hold: against Local: BLE worse."));
}

#[test]
fn tables_text_has_the_three_tables_under_their_settings() {
    let report = fixture::report();
    let text = tables_text(&report);
    assert!(text.starts_with("Paper setting: 3 robots, 4 targets (priorities 4,3,2,1), no loss; 10 seeds x 30 s\n"));
    assert!(text.contains("Robustness: paper setting, the most useful robot killed at 15 s; 10 seeds x 30 s\n"));
    assert!(text.contains("Sweep: robots x targets x radio loss; 10 seeds x 30 s\n"));
    assert_eq!(text.matches("controller  ").count(), 3);
    let rows = report.paper.len() + report.robustness.len() + report.sweep.len();
    assert_eq!(text.lines().filter(|l| l.contains(" ± ") && !l.starts_with("controller")).count(), rows);
    let mut none = report.clone();
    none.sweep.clear();
    assert!(tables_text(&none).contains("Sweep: skipped"));
}
