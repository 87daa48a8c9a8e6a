//! The report page in a real browser: Debian's headless Chromium opens `index.html` written from
//! a synthetic report, and the test checks that the page says it drew the replay
//! (`<body data-status="drawn">`), that no script error was recorded (`data-errors="0"`), and,
//! from a screenshot, that the replay canvas is not blank and shows robots and targets.
//!
//! The checker is also run on pages built to fail (a script that throws, a canvas nobody draws
//! on) to show it can tell. Without `/usr/bin/chromium` the test fails and says to run
//! `scripts/install-chromium`; `AYLLU_SKIP_BROWSER=1` turns that into a loud skip.
//! `AYLLU_KEEP_REPORT=1` keeps the written folders (and screenshots) for a person to look at.

#[path = "../src/report/tests/fixture.rs"]
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
use ayllu_sim::report::{self, Report};
use ayllu_sim::study::Row;

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
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems.join("; "))
        }
    }
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
    finish(&dir);
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
