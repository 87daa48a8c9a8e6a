//! The point of a study in a few lines: BLE against every other controller on A_w in the
//! paper's setting, with the standard error of each difference so that a gap can be told from
//! seed-to-seed noise; whether the paper's claim held; what a robot killed halfway cost BLE.
//!
//! Promises: the verdicts are computed here once, for the terminal, `tables.txt` and the page
//! alike. A gap is "within noise" when it is at most two standard errors of the difference,
//! sqrt(sd_BLE²/n_BLE + sd²/n) (sd: the sample standard deviation of A_w over seeds).

use std::fmt::Write as _;

use super::tables::percent;
use super::Report;
use crate::controller::Controller;
use crate::study::Row;

/// BLE's A_w against another controller's, from BLE's side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// BLE's A_w is higher by more than two standard errors of the difference.
    Better,
    /// BLE's A_w is lower by more than two standard errors of the difference.
    Worse,
    /// The difference is within two standard errors: noise.
    WithinNoise,
}

impl Verdict {
    fn text(self) -> &'static str {
        match self {
            Verdict::Better => "BLE better",
            Verdict::Worse => "BLE worse",
            Verdict::WithinNoise => "within noise",
        }
    }
}

/// One controller's A_w in the paper's setting against BLE's.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// The other controller's name.
    pub controller: String,
    /// Its mean A_w over the seeds (docs/cmommt.md).
    pub a_w: f64,
    /// The sample standard deviation of its A_w over the seeds.
    pub a_w_sd: f64,
    /// BLE's A_w minus this controller's.
    pub diff: f64,
    /// One standard error of `diff`.
    pub se: f64,
    /// What `diff` and `se` say: better, worse or within noise.
    pub verdict: Verdict,
}

/// Every controller of `paper` but BLE, in row order, against BLE (empty without a BLE row).
pub fn compare(paper: &[Row]) -> Vec<Comparison> {
    let Some(ble) = paper.iter().find(|r| r.controller == Controller::Ble.name()) else { return Vec::new() };
    paper
        .iter()
        .filter(|r| r.controller != ble.controller)
        .map(|row| {
            let diff = ble.metrics.a_w - row.metrics.a_w;
            let n = |r: &Row| f64::from(r.seeds.max(1));
            let se = (ble.a_w_sd.powi(2) / n(ble) + row.a_w_sd.powi(2) / n(row)).sqrt();
            let verdict = if diff.abs() <= 2.0 * se {
                Verdict::WithinNoise
            } else if diff > 0.0 {
                Verdict::Better
            } else {
                Verdict::Worse
            };
            Comparison {
                controller: row.controller.clone(),
                a_w: row.metrics.a_w,
                a_w_sd: row.a_w_sd,
                diff,
                se,
                verdict,
            }
        })
        .collect()
}

/// The paper's claim (section 4, tested in `tests/simulator/cmommt.rs`): with BLE the team covers the
/// priority-weighted targets better than robots that wander (Random) and than robots that
/// follow what they see without talking (Local). `Some(true)` when BLE is better than both
/// beyond noise, `Some(false)` when not, `None` when the study lacks one of the three.
pub fn paper_claim(paper: &[Row]) -> Option<bool> {
    let comparisons = compare(paper);
    let verdict =
        |c: Controller| comparisons.iter().find(|x| x.controller == c.name()).map(|x| x.verdict == Verdict::Better);
    Some(verdict(Controller::Random)? && verdict(Controller::Local)?)
}

pub(super) fn text(report: &Report) -> String {
    let mut out = String::new();
    if !report.cells.is_empty() {
        return cells_text(report);
    }
    let Some(ble) = report.paper.iter().find(|r| r.controller == Controller::Ble.name()) else {
        out.push_str("No BLE runs in the paper's setting: nothing to compare.\n");
        return out;
    };
    let _ = writeln!(
        out,
        "W-CMOMMT in the paper's setting ({} robots, {} targets, {} % loss; {} seeds x {} s).",
        ble.robots,
        ble.targets,
        percent(ble.loss),
        ble.seeds,
        report.duration
    );
    let _ =
        writeln!(out, "A_w: priority-weighted fraction of targets observed (0-1, higher is better) ± sd over seeds;");
    let _ = writeln!(out, "BLE − other ± one standard error of the difference, within noise if under two:");
    let comparisons = compare(&report.paper);
    let width = report.paper.iter().map(|r| r.controller.chars().count()).max().unwrap_or(0);
    let _ = writeln!(out, "  {:<width$}  A_w {:.3} ± {:.3}", ble.controller, ble.metrics.a_w, ble.a_w_sd);
    for c in &comparisons {
        let name = &c.controller;
        let ratio = if c.a_w > 0.0 { format!("x{:.2}", ble.metrics.a_w / c.a_w) } else { "-".to_owned() };
        let _ = writeln!(
            out,
            "  {name:<width$}  A_w {:.3} ± {:.3}   BLE − {name} = {:+.3} ± {:.3} ({ratio}): {}",
            c.a_w,
            c.a_w_sd,
            c.diff,
            c.se,
            c.verdict.text()
        );
    }
    if let Some(c) = comparisons.iter().find(|c| c.controller == Controller::Centralized.name() && c.a_w > 0.0) {
        let share = 100.0 * ble.metrics.a_w / c.a_w;
        let _ = writeln!(
            out,
            "Centralized is an omniscient planner, the upper bound: BLE reaches {share:.0} % of its A_w."
        );
        if let Some(p) = comparisons.iter().find(|p| p.controller == Controller::Planner.name()) {
            let _ = writeln!(
                out,
                "Planner is a central planner whose reports and assignments cross the same radio: it reaches \
                 {:.0} % of Centralized's A_w.",
                100.0 * p.a_w / c.a_w
            );
        }
    }
    out.push_str(&claim(report));
    out.push('\n');
    if let Some(line) = kill_line(report, ble) {
        out.push_str(&line);
    }
    out
}

/// One sentence: whether the paper's claim held (and if not, against whom).
/// A sweep's summary: in each cell, the controllers by decreasing A_w (± sd), with their
/// messages per robot per second.
fn cells_text(report: &Report) -> String {
    let mut out = String::new();
    for cell in &report.cells {
        let _ = writeln!(out, "{}", cell.title);
        let mut rows: Vec<&Row> = cell.rows.iter().collect();
        rows.sort_by(|a, b| b.metrics.a_w.total_cmp(&a.metrics.a_w));
        let width = rows.iter().map(|r| r.controller.chars().count()).max().unwrap_or(0);
        for r in rows {
            let _ = writeln!(
                out,
                "  {:<width$}  A_w {:.3} ± {:.3}   msgs/robot/s {:.1}",
                r.controller, r.metrics.a_w, r.a_w_sd, r.metrics.msgs_per_robot_s
            );
        }
    }
    out
}

pub(super) fn claim(report: &Report) -> String {
    if !report.cells.is_empty() {
        return format!("A sweep of {} cells.", report.cells.len());
    }
    match paper_claim(&report.paper) {
        Some(true) => "The paper's claim held: BLE beats Random (wandering) and Local (no communication) beyond noise."
            .to_string(),
        Some(false) => {
            let comparisons = compare(&report.paper);
            let why: Vec<String> = [Controller::Random, Controller::Local]
                .into_iter()
                .filter_map(|c| comparisons.iter().find(|x| x.controller == c.name()))
                .filter(|c| c.verdict != Verdict::Better)
                .map(|c| format!("against {}: {}", c.controller, c.verdict.text()))
                .collect();
            format!("The paper's claim did NOT hold: {}.", why.join("; "))
        }
        None => "The paper's claim could not be checked: this study lacks BLE, Random or Local.".to_string(),
    }
}

/// What a robot killed halfway cost BLE, at the lowest loss of the robustness scenario.
fn kill_line(report: &Report, ble: &Row) -> Option<String> {
    let row =
        report.robustness.iter().filter(|r| r.controller == ble.controller).min_by(|a, b| a.loss.total_cmp(&b.loss))?;
    let mut line = format!("Robot killed halfway ({} % loss): BLE's A_w ", percent(row.loss));
    // Against its A_w without a kill when that was measured at the same loss.
    if row.loss == ble.loss {
        let _ = write!(line, "{:.3} -> {:.3}", ble.metrics.a_w, row.metrics.a_w);
    } else {
        let _ = write!(line, "{:.3}", row.metrics.a_w);
    }
    let m = &row.metrics;
    match (m.recover_s, m.unrecovered) {
        (None, _) => line.push_str("; the killed robots had nothing to re-cover.\n"),
        (Some(s), 0) => {
            let _ = writeln!(line, "; its targets re-covered in {s:.1} s on average.");
        }
        (Some(s), n) => {
            let _ = writeln!(
                line,
                "; its targets re-covered in {s:.1} s on average,\n  counting as the time left the {n} never \
                 re-covered in {} runs.",
                row.seeds
            );
        }
    }
    Some(line)
}
