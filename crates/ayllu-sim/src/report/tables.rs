//! The study's rows as tables: fixed-width text for a terminal, Markdown, and HTML.
//!
//! All three show the same columns with the same number formatting ([`cells`]), so a number read
//! in the terminal can be found again in the page or the Markdown.

use std::fmt::Write as _;

use super::Report;
use crate::study::Row;

/// Column headers, in order.
pub(super) const HEADERS: [&str; 14] = [
    "controller",
    "robots",
    "targets",
    "loss %",
    "kill",
    "seeds",
    "A",
    "A/m",
    "A_w ± sd",
    "top-k",
    "redundant",
    "switches/min",
    "recover s",
    "msgs/robot/s",
];

/// Index of the A_w column, which the HTML emphasises.
const A_W_COLUMN: usize = 8;

/// A row's cells, formatted. Precision follows what differs between controllers: A_w and
/// top-k are fractions read to the third decimal; counts of targets to the second; times and
/// message rates to the first.
pub(super) fn cells(row: &Row) -> [String; 14] {
    let m = &row.metrics;
    [
        row.controller.clone(),
        row.robots.to_string(),
        row.targets.to_string(),
        percent(row.loss),
        if row.kill { "yes" } else { "no" }.to_string(),
        row.seeds.to_string(),
        format!("{:.2}", m.a),
        format!("{:.3}", m.a_per_m),
        format!("{:.3} ± {:.3}", m.a_w, row.a_w_sd),
        format!("{:.3}", m.top_k),
        format!("{:.2}", m.redundant),
        format!("{:.2}", m.switches_per_min),
        m.recover_s.map_or_else(|| "-".to_string(), |s| format!("{s:.1}")),
        format!("{:.1}", m.msgs_per_robot_s),
    ]
}

/// A loss probability as a percentage: whole numbers stay whole ("10"), others keep one decimal.
pub(super) fn percent(loss: f64) -> String {
    let p = loss * 100.0;
    if (p - p.round()).abs() < 1e-9 {
        format!("{p:.0}")
    } else {
        format!("{p:.1}")
    }
}

pub(super) fn text(rows: &[Row]) -> String {
    let body: Vec<[String; 14]> = rows.iter().map(cells).collect();
    let mut widths = HEADERS.map(|h| h.chars().count());
    for cells in &body {
        for (w, c) in widths.iter_mut().zip(cells) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |cells: &[String; 14]| {
        let mut s = String::new();
        for (i, (c, w)) in cells.iter().zip(widths).enumerate() {
            if i > 0 {
                s.push_str("  ");
            }
            // The controller name reads left to right; numbers line up on their last digit.
            if i == 0 {
                let _ = write!(s, "{c:<w$}");
            } else {
                let _ = write!(s, "{c:>w$}");
            }
        }
        s.trim_end().to_string()
    };
    let mut out = line(&HEADERS.map(str::to_string));
    out.push('\n');
    for cells in &body {
        out.push_str(&line(cells));
        out.push('\n');
    }
    out
}

/// The three tables as fixed-width text under headings that give their settings (what
/// `ayllu sim cmommt --full` prints after the summary); a sweep's cells, each under its title.
pub(super) fn text_all(report: &Report) -> String {
    if !report.cells.is_empty() {
        let mut out = String::new();
        for cell in &report.cells {
            let seeds = cell.rows.iter().map(|r| r.seeds).max().unwrap_or(0);
            let _ = writeln!(out, "{} ({seeds} seeds)", cell.title);
            let _ = writeln!(out, "{}", text(&cell.rows));
        }
        return out;
    }
    let seeds = report.paper.iter().chain(&report.robustness).chain(&report.sweep).map(|r| r.seeds).max().unwrap_or(0);
    let runs = format!("{seeds} seeds x {} s", report.duration);
    let mut out = String::new();
    match report.paper.first() {
        Some(r) => {
            let priorities: Vec<String> = (1..=r.targets).rev().map(|p| p.to_string()).collect();
            let _ = writeln!(
                out,
                "Paper setting: {} robots, {} targets (priorities {}), no loss; {runs}",
                r.robots,
                r.targets,
                priorities.join(",")
            );
        }
        None => out.push_str("Paper setting\n"),
    }
    let _ = writeln!(out, "{}", text(&report.paper));
    let _ =
        writeln!(out, "Robustness: paper setting, the most useful robot killed at {} s; {runs}", report.duration / 2.0);
    let _ = writeln!(out, "{}", text(&report.robustness));
    if report.sweep.is_empty() {
        out.push_str("Sweep: skipped\n");
    } else {
        let _ = writeln!(out, "Sweep: robots x targets x radio loss; {runs}");
        let _ = writeln!(out, "{}", text(&report.sweep));
    }
    out
}

/// The three tables of the report, titled, as one Markdown document.
pub(super) fn markdown(report: &Report) -> String {
    let mut out = format!("# {}\n\n```\n{}\n```\n", report.title, report.command);
    for (title, rows) in sections(report) {
        let _ = write!(out, "\n## {title}\n\n");
        if rows.is_empty() {
            out.push_str("(no runs)\n");
            continue;
        }
        out.push_str(&format!("| {} |\n", HEADERS.join(" | ")));
        let align: Vec<&str> = (0..HEADERS.len()).map(|i| if i == 0 { ":---" } else { "---:" }).collect();
        out.push_str(&format!("| {} |\n", align.join(" | ")));
        for row in rows {
            let cells = cells(row).map(|c| c.replace('|', "\\|"));
            out.push_str(&format!("| {} |\n", cells.join(" | ")));
        }
    }
    out
}

/// The report's tables with their titles, in the order the page and the Markdown show them: a
/// sweep's cells, or the paper study's three tables.
pub(super) fn sections(report: &Report) -> Vec<(&str, &[Row])> {
    if !report.cells.is_empty() {
        return report.cells.iter().map(|c| (c.title.as_str(), &c.rows[..])).collect();
    }
    vec![
        ("Paper setting", &report.paper[..]),
        ("Robustness: a robot killed halfway", &report.robustness[..]),
        ("Sweep: robots × targets × loss", &report.sweep[..]),
    ]
}

/// One HTML `<table>`. Within each group of rows sharing a setting (robots, targets, loss,
/// kill), the best A_w is bold, because that is the comparison the tables exist for.
pub(super) fn html(rows: &[Row], escape: impl Fn(&str) -> String) -> String {
    if rows.is_empty() {
        return "<p class=\"empty\">(no runs)</p>\n".to_string();
    }
    let setting = |r: &Row| (r.robots, r.targets, r.loss.to_bits(), r.kill);
    let best = |r: &Row| rows.iter().filter(|o| setting(o) == setting(r)).all(|o| o.metrics.a_w <= r.metrics.a_w);
    let mut out = String::from("<table>\n<thead><tr>");
    for h in HEADERS {
        let _ = write!(out, "<th>{}</th>", escape(h));
    }
    out.push_str("</tr></thead>\n<tbody>\n");
    for row in rows {
        let class = if row.controller == "BLE" { " class=\"ble\"" } else { "" };
        let _ = write!(out, "<tr{class}>");
        for (i, c) in cells(row).iter().enumerate() {
            let text = escape(c);
            if i == 0 {
                let _ = write!(out, "<td class=\"name\">{text}</td>");
            } else if i == A_W_COLUMN && best(row) {
                let _ = write!(out, "<td class=\"best\"><b>{text}</b></td>");
            } else {
                let _ = write!(out, "<td>{text}</td>");
            }
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody>\n</table>\n");
    out
}
