//! The report folder of `ayllu sim cmommt`: what a person opens after a study.
//!
//! [`write()`] fills one folder with:
//! * `index.html`: one self-contained page (inline CSS and JS, no network): the command, whether
//!   the paper's claim held, a canvas replay of any run in [`Report::replays`] (chosen with three
//!   menus: setting, controller, seed; it opens on the first), the summary ([`summary_text`]),
//!   the tables, and the plots inlined as SVG markup. Each time it has drawn a run it sets
//!   `data-status="drawn"` and `data-run` (the run's "setting|controller|seed") on `<body>`;
//!   every script error is counted in `data-errors` and shown in a red box. It also publishes the replay canvas's page
//!   rectangle as `data-canvas="x,y,w,h"` (CSS px), the arena's inner walls on the canvas as
//!   `data-walls`, every label drawn in the arena as `data-labels` ("text@x,y,w,h;...", canvas
//!   px; the page keeps them inside the walls) and the robots' drawn positions as `data-robots`
//!   ("x,y;...", arena metres), so a browser test knows where to look and what to expect.
//! * `coverage.svg`, `sweep_robots.svg`, `sweep_loss.svg`, `robustness.svg`: the same plots as
//!   files, for papers and slides.
//! * `results.json`: the whole [`Report`], replays included, so it deserializes back into a
//!   `Report` and a page can be re-rendered from it without re-running the study.
//! * `results.md`: the three tables in Markdown, with the columns of [`text_table`].
//! * `tables.txt`: what `ayllu sim cmommt --full` prints: the summary, then the three tables as
//!   fixed-width text ([`tables_text`]).
//! * `runs.csv` and `runs.jsonl`: every run of the study, one row each ([`runs_csv`],
//!   [`RunRow`]), so that every printed mean can be recomputed and analysed elsewhere.
//!
//! A sweep's report (`ayllu sim sweep`, [`crate::sweep`]) is the same page with a table per cell
//! ([`Report::cells`]) and a summary of each cell's ranking in place of the paper's comparisons.
//!
//! Everything is a pure function of the `Report`: the same report writes the same bytes.

mod page;
mod plots;
mod replay;
mod summary;
mod tables;
#[cfg(test)]
mod tests;

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::recording::CoverageSeries;
use crate::study::{Row, RunRow};

pub use replay::{decode, encode, Replay, State};
pub use summary::{compare, paper_claim, Comparison, Verdict};

/// Everything a report shows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The page's title.
    pub title: String,
    /// The command line that produced it, for people to re-run.
    pub command: String,
    /// Seconds of virtual time per run (for the tables' headings).
    pub duration: f64,
    /// The runs the page can replay, in the order its menus list them; it opens on the first.
    pub replays: Vec<Replay>,
    /// Coverage over time in the first replay's world, one series per controller (same seed).
    pub coverage: Vec<(String, CoverageSeries)>,
    /// The paper's setting: one row per controller.
    pub paper: Vec<Row>,
    /// robots x targets x loss, every controller.
    pub sweep: Vec<Row>,
    /// A robot killed halfway, at 0, 10 and 30 % loss, every controller.
    pub robustness: Vec<Row>,
    /// Every run's metrics (written as `runs.csv` and `runs.jsonl`).
    #[serde(default)]
    pub runs: Vec<RunRow>,
    /// A sweep's cells, one table each (`ayllu sim sweep`); when present, the page, the
    /// Markdown and `tables.txt` show these tables instead of the three of the paper's study.
    #[serde(default)]
    pub cells: Vec<CellTable>,
}

/// One cell of a sweep as a table: its grid values as a title, one row per controller.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellTable {
    /// "cell2: radio.loss = 0.3, robots = 5" (or the scenario as written, for a sweep without a
    /// grid).
    pub title: String,
    /// One row per controller, in the sweep's order.
    pub rows: Vec<Row>,
}

/// Write the report into `dir` (created if missing); returns the files written.
pub fn write(dir: &Path, report: &Report) -> io::Result<Vec<PathBuf>> {
    fs::create_dir_all(dir)?;
    let plots = plots::render_all(report)?;
    let mut written = Vec::new();
    let mut put = |name: &str, contents: &str| -> io::Result<()> {
        let path = dir.join(name);
        fs::write(&path, contents)?;
        written.push(path);
        Ok(())
    };
    put("index.html", &page::render(report, &plots))?;
    for plot in &plots {
        put(plot.file, &plot.svg)?;
    }
    let json = serde_json::to_string_pretty(report).map_err(io::Error::other)?;
    put("results.json", &json)?;
    put("results.md", &tables::markdown(report))?;
    put("tables.txt", &format!("{}\n{}", summary_text(report), tables_text(report)))?;
    put("runs.csv", &runs_csv(&report.runs))?;
    let mut jsonl = String::new();
    for r in &report.runs {
        jsonl.push_str(&serde_json::to_string(r).map_err(io::Error::other)?);
        jsonl.push('\n');
    }
    put("runs.jsonl", &jsonl)?;
    Ok(written)
}

/// Every run as CSV: a header, then one line per run with its place (table, controller,
/// robots, targets, loss, kill, seed, duration) and every metric (empty `recover_s` when the
/// run had nothing to re-cover). Numbers are written in full (shortest round trip).
pub fn runs_csv(runs: &[RunRow]) -> String {
    let mut out = String::from(
        "table,controller,robots,targets,loss,kill,seed,duration,a,a_per_m,a_w,top_k,k,top_k_alive,redundant,\
         switches_per_min,recover_s,unrecovered,msgs_per_robot_s,bytes_per_robot_s\n",
    );
    for r in runs {
        let m = &r.metrics;
        let recover = m.recover_s.map_or(String::new(), |x| x.to_string());
        out.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            r.table,
            r.controller,
            r.robots,
            r.targets,
            r.loss,
            r.kill,
            r.seed,
            r.duration,
            m.a,
            m.a_per_m,
            m.a_w,
            m.top_k,
            m.k,
            m.top_k_alive,
            m.redundant,
            m.switches_per_min,
            recover,
            m.unrecovered,
            m.msgs_per_robot_s,
            m.bytes_per_robot_s
        ));
    }
    out
}

/// The rows as a fixed-width text table for a terminal: a header line, then one line per row.
pub fn text_table(rows: &[Row]) -> String {
    tables::text(rows)
}

/// The few lines that say what the study found: BLE against every other controller on A_w in
/// the paper's setting, whether the paper's claim held, and what a robot killed halfway cost.
pub fn summary_text(report: &Report) -> String {
    summary::text(report)
}

/// The three tables as fixed-width text, each under a heading that gives its setting.
pub fn tables_text(report: &Report) -> String {
    tables::text_all(report)
}
