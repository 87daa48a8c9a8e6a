//! The report page in a real browser: Debian's headless Chromium opens `index.html` written from
//! a synthetic report, and the test checks that the page says it drew the replay
//! (`<body data-status="drawn">`), that no script error was recorded (`data-errors="0"`), that
//! every label drawn in the arena lies inside its walls (`data-labels`, `data-walls`), and, from a
//! screenshot, that the replay canvas is not blank and shows robots and targets. A second page
//! chooses every run through the page's menus, as a person would, and then a run with a robot
//! killed: each must draw without errors, with its labels inside the walls, the last one with the
//! positions the report holds for it and a dead robot on the canvas.
//!
//! The checker is also run on pages built to fail (a script that throws, a canvas nobody draws
//! on) to show it can tell. Without `/usr/bin/chromium` the test fails and says to run
//! `scripts/install-chromium`; `AYLLU_SKIP_BROWSER=1` turns that into a loud skip.
//! `AYLLU_KEEP_REPORT=1` keeps the written folders (and screenshots) for a person to look at.

#[path = "../../src/report/tests/fixture.rs"]
mod fixture;

use std::collections::HashMap;
use std::fs;
use std::io::{BufReader, Read};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use ayllu_sim::metrics::Metrics;
use ayllu_sim::recording::{CoverageSeries, Event, Frame, Recording, RecordingMeta, RobotFrame, RobotInfo, TargetInfo};
use ayllu_sim::report::{self, Replay, Report};
use ayllu_sim::study::{Row, RunRow};

const CHROMIUM: &str = "/usr/bin/chromium";
const WINDOW: (u32, u32) = (1280, 900);
/// Chromium has this long to render a page before it is killed.
const TIMEOUT: Duration = Duration::from_secs(60);

/// What the browser showed: the body's attributes after scripts ran, and the screenshot's
/// verdict on the canvas region.
#[derive(Debug)]
struct PageCheck {
    status: Option<String>,
    errors: u32,
    error_messages: Vec<String>,
    canvas: Option<[u32; 4]>,
    /// Share of canvas pixels that differ from its most common colour.
    ink: f64,
    /// Distinct colours within the canvas.
    colours: usize,
    /// Pixels of the first robot's colour and of the highest-priority target's colour.
    robot_pixels: usize,
    target_pixels: usize,
    /// Pixels of a dead robot's grey.
    dead_pixels: usize,
    /// The run drawn (`data-run`), the arena's inner walls and the labels drawn in it.
    run: Option<String>,
    walls: Option<[f64; 4]>,
    labels: Vec<(String, [f64; 4])>,
    /// Robots' positions on the canvas (`data-robots`, arena metres).
    robots: Vec<[f64; 2]>,
    /// What the test's own script wrote into `<pre id="visited">`, if anything.
    visited: Option<String>,
}

impl PageCheck {
    /// Everything wrong with the page, or Ok.
    fn verdict(&self) -> Result<(), String> {
        let mut problems = Vec::new();
        if self.status.as_deref() != Some("drawn") {
            problems.push(format!("page did not finish drawing (data-status = {:?})", self.status));
        }
        if self.errors > 0 {
            problems.push(format!("{} script error(s): {:?}", self.errors, self.error_messages));
        }
        match self.canvas {
            None => problems.push("page did not publish its canvas rectangle (data-canvas)".into()),
            Some(_) if self.ink < 0.01 || self.colours < 20 => problems.push(format!(
                "canvas is blank: {:.2} % of its pixels differ from the background, {} colours",
                self.ink * 100.0,
                self.colours
            )),
            Some(_) => {}
        }
        match self.walls {
            None => problems.push("page did not publish its arena walls (data-walls)".into()),
            Some(walls) => problems.extend(labels_outside(&self.labels, walls)),
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems.join("; "))
        }
    }
}

/// Tolerance for text measured in fractional pixels and published to 0.1 px.
const LABEL_SLACK: f64 = 0.11;

/// A problem for each label whose box crosses the walls `[x, y, w, h]`.
fn labels_outside(labels: &[(String, [f64; 4])], [wx, wy, ww, wh]: [f64; 4]) -> Vec<String> {
    labels
        .iter()
        .filter(|(_, [x, y, w, h])| {
            *x < wx - LABEL_SLACK
                || *y < wy - LABEL_SLACK
                || x + w > wx + ww + LABEL_SLACK
                || y + h > wy + wh + LABEL_SLACK
        })
        .map(|(text, b)| format!("label {text:?} at {b:?} crosses the walls {:?}", [wx, wy, ww, wh]))
        .collect()
}

/// "x,y,w,h" as numbers.
fn numbers<const N: usize>(s: &str) -> Option<[f64; N]> {
    let v: Vec<f64> = s.split(',').map(|n| n.trim().parse::<f64>()).collect::<Result<_, _>>().ok()?;
    v.try_into().ok()
}

/// `data-labels`: "text@x,y,w,h;...".
fn parse_labels(s: &str) -> Vec<(String, [f64; 4])> {
    s.split(';')
        .filter(|l| !l.is_empty())
        .map(|l| {
            let (text, rect) = l.rsplit_once('@').unwrap_or_else(|| panic!("label without a box: {l:?}"));
            (text.to_string(), numbers(rect).unwrap_or_else(|| panic!("bad label box: {l:?}")))
        })
        .collect()
}

/// The text of the page's `<pre id="visited">`, HTML entities undone.
fn visited(dom: &str) -> Option<String> {
    let open = "<pre id=\"visited\">";
    let start = dom.find(open)? + open.len();
    let end = start + dom[start..].find("</pre>")?;
    Some(dom[start..end].replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&amp;", "&"))
}

/// Chromium, or None when the caller should skip; panics when it is missing and not skipped.
fn chromium() -> Option<&'static str> {
    if std::env::var("AYLLU_SKIP_BROWSER").is_ok_and(|v| v == "1") {
        eprintln!(
            "\n*** SKIPPED: report_chromium (AYLLU_SKIP_BROWSER=1): the report page was NOT checked in a browser ***\n"
        );
        return None;
    }
    assert!(
        Path::new(CHROMIUM).exists(),
        "{CHROMIUM} is missing: run scripts/install-chromium (or set AYLLU_SKIP_BROWSER=1 to skip this test)"
    );
    Some(CHROMIUM)
}

fn scratch(name: &str) -> PathBuf {
    static N: AtomicU32 = AtomicU32::new(0);
    let nanos = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.subsec_nanos());
    let n = N.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("ayllu-report-chromium-{}-{name}-{nanos}-{n}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn keep() -> bool {
    std::env::var("AYLLU_KEEP_REPORT").is_ok_and(|v| v == "1")
}

/// Runs headless Chromium on a page with `extra` arguments; returns its stdout. Killed (its
/// whole process group: the browser forks renderers) when it overruns [`TIMEOUT`].
fn run_chromium(browser: &str, page: &Path, extra: &[String]) -> String {
    let profile = scratch("profile");
    let mut cmd = Command::new(browser);
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--no-first-run",
        "--no-default-browser-check",
        "--disable-extensions",
        "--hide-scrollbars",
        "--force-device-scale-factor=1",
        "--virtual-time-budget=3000",
    ])
    .arg(format!("--window-size={},{}", WINDOW.0, WINDOW.1))
    .arg(format!("--user-data-dir={}", profile.display()))
    .args(extra)
    .arg(format!("file://{}", page.display()))
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .process_group(0);
    let mut child = cmd.spawn().unwrap_or_else(|e| panic!("cannot start {browser}: {e}"));
    // Drain both pipes on threads: a full pipe would stall the browser until the timeout.
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out_thread = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let err_thread = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > TIMEOUT {
            let _ = Command::new("kill").args(["-KILL", "--", &format!("-{}", child.id())]).status();
            let _ = child.wait();
            panic!("{browser} did not finish within {TIMEOUT:?} on {}", page.display());
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let stdout = out_thread.join().unwrap();
    let stderr = err_thread.join().unwrap();
    let _ = fs::remove_dir_all(&profile);
    assert!(status.success(), "{browser} failed ({status}) on {}:\n{stderr}", page.display());
    stdout
}

/// The attributes of the first `<body ...>` tag of a serialized DOM.
fn body_attributes(dom: &str) -> HashMap<String, String> {
    let start = dom.find("<body").expect("dumped DOM has a <body>");
    let end = start + dom[start..].find('>').unwrap();
    let tag = &dom[start + 5..end];
    let mut attrs = HashMap::new();
    let mut rest = tag;
    while let Some(eq) = rest.find("=\"") {
        let name = rest[..eq].trim().to_string();
        let after = &rest[eq + 2..];
        let close = after.find('"').unwrap();
        attrs.insert(name, after[..close].to_string());
        rest = &after[close + 1..];
    }
    attrs
}

/// The `<li>` texts of the page's red error box.
fn error_messages(dom: &str) -> Vec<String> {
    let Some(start) = dom.find("id=\"errors\"") else { return vec![] };
    let end = start + dom[start..].find("</div>").unwrap_or(dom.len() - start);
    dom[start..end].split("<li>").skip(1).map(|s| s.split("</li>").next().unwrap_or("").to_string()).collect()
}

fn check_page(browser: &str, page: &Path) -> PageCheck {
    let dom = run_chromium(browser, page, &["--dump-dom".to_string()]);
    let attrs = body_attributes(&dom);
    let canvas = attrs.get("data-canvas").map(|s| {
        let v: Vec<u32> = s.split(',').map(|n| n.trim().parse::<f64>().unwrap().max(0.0) as u32).collect();
        [v[0], v[1], v[2], v[3]]
    });
    let shot = page.with_file_name(format!("{}-screenshot.png", page.file_stem().unwrap().to_string_lossy()));
    run_chromium(browser, page, &[format!("--screenshot={}", shot.display())]);
    let mut check = PageCheck {
        status: attrs.get("data-status").cloned(),
        errors: attrs.get("data-errors").map_or(0, |s| s.parse().unwrap()),
        error_messages: error_messages(&dom),
        canvas,
        ink: 0.0,
        colours: 0,
        robot_pixels: 0,
        target_pixels: 0,
        dead_pixels: 0,
        run: attrs.get("data-run").cloned(),
        walls: attrs.get("data-walls").and_then(|s| numbers(s)),
        labels: attrs.get("data-labels").map_or_else(Vec::new, |s| parse_labels(s)),
        robots: attrs.get("data-robots").map_or_else(Vec::new, |s| {
            s.split(';').filter(|p| !p.is_empty()).map(|p| numbers(p).expect("x,y")).collect()
        }),
        visited: visited(&dom),
    };
    if let Some(rect) = canvas {
        inspect_canvas(&shot, rect, &mut check);
    }
    check
}

/// Looks at the canvas region of the screenshot (inset by 3 px, past its border).
fn inspect_canvas(png_path: &Path, [x, y, w, h]: [u32; 4], check: &mut PageCheck) {
    let decoder = png::Decoder::new(BufReader::new(fs::File::open(png_path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    assert!(info.bit_depth == png::BitDepth::Eight && channels >= 3, "unexpected PNG format {info:?}");
    let (x0, y0) = (x + 3, y + 3);
    let x1 = (x + w).saturating_sub(3).min(info.width);
    let y1 = (y + h).saturating_sub(3).min(info.height);
    let mut counts: HashMap<[u8; 3], usize> = HashMap::new();
    for py in y0..y1 {
        for px in x0..x1 {
            let i = (py as usize * info.width as usize + px as usize) * channels;
            *counts.entry([buf[i], buf[i + 1], buf[i + 2]]).or_default() += 1;
        }
    }
    let total: usize = counts.values().sum();
    if total == 0 {
        return;
    }
    let background = counts.values().copied().max().unwrap();
    let near = |c: &[u8; 3], want: [u8; 3]| c.iter().zip(want).all(|(a, b)| a.abs_diff(b) <= 3);
    check.ink = 1.0 - background as f64 / total as f64;
    check.colours = counts.len();
    // The replay's colour for the first robot and for the highest-priority target.
    check.robot_pixels = counts.iter().filter(|(c, _)| near(c, [0x1f, 0x77, 0xb4])).map(|(_, n)| n).sum();
    check.target_pixels = counts.iter().filter(|(c, _)| near(c, [192, 40, 30])).map(|(_, n)| n).sum();
    check.dead_pixels = counts.iter().filter(|(c, _)| near(c, [0xa9, 0xa9, 0xa9])).map(|(_, n)| n).sum();
}

fn finish(dir: &Path) {
    if keep() {
        eprintln!("kept {}", dir.display());
    } else {
        let _ = fs::remove_dir_all(dir);
    }
}

#[test]
fn the_report_page_draws_its_replay_without_errors() {
    let Some(browser) = chromium() else { return };
    let dir = scratch("report");
    report::write(&dir, &fixture::report()).unwrap();
    let check = check_page(browser, &dir.join("index.html"));
    eprintln!("{check:?}");
    if let Err(problems) = check.verdict() {
        panic!("report page in {}: {problems}", dir.display());
    }
    assert!(check.robot_pixels > 30, "no robot drawn in the replay: {check:?}");
    assert!(check.target_pixels > 30, "no top-priority target drawn in the replay: {check:?}");
    let [x, y, w, h] = check.canvas.unwrap();
    assert!(x + w <= WINDOW.0 && y + h <= WINDOW.1, "canvas not fully on the first screen: {check:?}");
    assert_eq!(check.run.as_deref(), Some("Paper setting|BLE|7"), "it opens on the first run");
    // R1-R3 and, per target, its id and priority; claims and inhibitions when there are some.
    assert!(check.labels.len() >= 3 + 2 * 4, "{:?}", check.labels);
    // A few grey pixels can come from anti-aliasing; a dead robot is a disc of hundreds.
    assert!(check.dead_pixels <= 10, "nobody is dead at t = 0 in this run: {check:?}");
    finish(&dir);
}

/// Appended to the page: picks every run through the three menus (firing `change` as a person's
/// choice does), notes what each drew, then picks the robustness run and moves its slider to
/// 20 s, after robot 3 was killed at 15 s.
const CHOOSER: &str = r#"<pre id="visited"></pre>
<script>
(function () {
  const pick = (id, value) => {
    const sel = document.getElementById(id);
    sel.value = value;
    sel.dispatchEvent(new Event('change'));
  };
  const options = (id) => Array.from(document.getElementById(id).options).map((o) => o.value);
  const b = document.body.dataset;
  const seen = [];
  for (const setting of options('run-setting')) {
    pick('run-setting', setting);
    for (const controller of options('run-controller')) {
      pick('run-controller', controller);
      for (const seed of options('run-seed')) {
        pick('run-seed', seed);
        seen.push({ want: [setting, controller, seed].join('|'), run: b.run, status: b.status, errors: b.errors,
          labels: b.labels, walls: b.walls });
      }
    }
  }
  document.getElementById('visited').textContent = JSON.stringify(seen);
  pick('run-setting', 'Robustness: 10 % loss');
  pick('run-controller', 'BLE');
  pick('run-seed', '7');
  const slider = document.getElementById('slider');
  slider.value = '20';
  slider.dispatchEvent(new Event('input'));
})();
</script>
"#;

#[test]
fn choosing_another_run_draws_it_without_errors() {
    let Some(browser) = chromium() else { return };
    let dir = scratch("choose");
    let report = fixture::report();
    report::write(&dir, &report).unwrap();
    let page = dir.join("choose.html");
    let html = fs::read_to_string(dir.join("index.html")).unwrap();
    let at = html.rfind("</body>").unwrap();
    fs::write(&page, format!("{}{CHOOSER}{}", &html[..at], &html[at..])).unwrap();
    let check = check_page(browser, &page);
    eprintln!("{check:?}");
    if let Err(problems) = check.verdict() {
        panic!("report page in {} after choosing runs: {problems}", dir.display());
    }

    // Every run was reached through the menus, and each drew without errors and with its labels
    // inside its walls.
    let visited: serde_json::Value = serde_json::from_str(check.visited.as_deref().expect("the chooser ran")).unwrap();
    let visited = visited.as_array().unwrap();
    let keys: Vec<String> =
        report.replays.iter().map(|r| format!("{}|{}|{}", r.setting, r.meta.controller, r.meta.seed)).collect();
    let drawn: Vec<&str> = visited.iter().map(|v| v["run"].as_str().unwrap_or("")).collect();
    assert_eq!(drawn, keys, "the menus reach every run once, in order");
    for v in visited {
        assert_eq!(v["want"], v["run"], "{v}");
        assert_eq!((v["status"].as_str(), v["errors"].as_str()), (Some("drawn"), Some("0")), "{v}");
        let walls = numbers(v["walls"].as_str().unwrap()).unwrap();
        let labels = parse_labels(v["labels"].as_str().unwrap());
        assert!(labels.len() >= 2 * report.replays[0].targets.len(), "{v}");
        let outside = labels_outside(&labels, walls);
        assert!(outside.is_empty(), "{}: {outside:?}", v["run"]);
        // The run squeezed into the corners: every robot and target labelled, three lines for
        // robot 3 (claims, inhibitions).
        if v["run"].as_str().is_some_and(|r| r.starts_with("Sweep")) {
            let texts: Vec<&str> = labels.iter().map(|(t, _)| t.as_str()).collect();
            assert_eq!(texts.len(), 3 + 2 + 2 * 4, "{texts:?}");
            assert!(texts.contains(&"claims T3,T4") && texts.contains(&"inhib T1,T2"), "{texts:?}");
        }
    }

    // The last choice: the robustness run at 20 s, robot 3 dead (grey, with a red cross), and
    // the robots where the report says they are (what the page decoded is what Rust encoded).
    assert_eq!(check.run.as_deref(), Some("Robustness: 10 % loss|BLE|7"));
    assert!(check.dead_pixels > 30, "no dead robot drawn after the kill: {check:?}");
    let replay: &Replay = &report.replays[3];
    let sample = replay.sample_frames().iter().position(|&f| f as f64 * replay.meta.frame_dt == 20.0).unwrap();
    assert_eq!(check.robots.len(), replay.robots.len());
    for (k, p) in check.robots.iter().enumerate() {
        let (x, y, _) = replay.robot_poses(k).unwrap()[sample];
        assert!((p[0] - x).abs() < 1e-3 && (p[1] - y).abs() < 1e-3, "robot {k}: page {p:?}, report ({x}, {y})");
    }
    finish(&dir);
}

#[test]
fn the_label_check_sees_a_label_across_a_wall() {
    let walls = [10.0, 20.0, 300.0, 200.0];
    let inside = ("T1".to_string(), [12.0, 22.0, 20.0, 16.0]);
    assert!(labels_outside(std::slice::from_ref(&inside), walls).is_empty());
    for outside in
        [[305.0, 30.0, 20.0, 16.0], [5.0, 30.0, 20.0, 16.0], [50.0, 15.0, 20.0, 16.0], [50.0, 210.0, 20.0, 16.0]]
    {
        let found = labels_outside(&[inside.clone(), ("R1".to_string(), outside)], walls);
        assert_eq!(found.len(), 1, "{outside:?}");
        assert!(found[0].contains("\"R1\""), "{found:?}");
    }
    assert_eq!(
        parse_labels("R1 dead@1.5,2,30.25,16;claims T3,T4@0,0,1,1"),
        [("R1 dead".to_string(), [1.5, 2.0, 30.25, 16.0]), ("claims T3,T4".to_string(), [0.0, 0.0, 1.0, 1.0])]
    );
}

#[test]
fn the_checker_sees_a_script_error() {
    let Some(browser) = chromium() else { return };
    let dir = scratch("broken");
    report::write(&dir, &fixture::report()).unwrap();
    // The real page with its data block corrupted: the replay's JSON.parse throws.
    let page = dir.join("index.html");
    let html = fs::read_to_string(&page).unwrap();
    let broken = html.replacen("id=\"data\">{", "id=\"data\">{oops", 1);
    assert_ne!(broken, html);
    fs::write(&page, broken).unwrap();
    let check = check_page(browser, &page);
    eprintln!("{check:?}");
    let problems = check.verdict().expect_err("a page whose script throws passed the checker");
    assert!(check.errors >= 1, "{check:?}");
    assert!(problems.contains("script error"), "{problems}");
    assert!(problems.contains("did not finish drawing"), "{problems}");
    assert!(!check.error_messages.is_empty(), "the red box lists the error: {check:?}");
    finish(&dir);
}

#[test]
fn the_checker_sees_a_blank_canvas() {
    let Some(browser) = chromium() else { return };
    let dir = scratch("blank");
    // Says it drew, has no errors, publishes its canvas: but never draws on it.
    let page = dir.join("blank.html");
    fs::write(
        &page,
        r#"<!DOCTYPE html><html><body style="margin:0" data-status="loading" data-errors="0">
<canvas id="arena" width="600" height="400" style="background:#eceae4"></canvas>
<script>
const r = document.getElementById('arena').getBoundingClientRect();
document.body.dataset.canvas = [r.left, r.top, r.width, r.height].join(',');
document.body.dataset.status = 'drawn';
</script></body></html>"#,
    )
    .unwrap();
    let check = check_page(browser, &page);
    eprintln!("{check:?}");
    let problems = check.verdict().expect_err("a blank canvas passed the checker");
    assert!(problems.contains("blank"), "{problems}");
    assert_eq!(check.errors, 0);
    assert_eq!(check.status.as_deref(), Some("drawn"));
    finish(&dir);
}
