//! The report folder of `ayllu sim cmommt`: what a person opens after a study.
//!
//! [`write()`] fills one folder with:
//! * `index.html`: one self-contained page (inline CSS and JS, no network): the command, a canvas
//!   replay of [`Report::recording`], the tables, and the plots inlined as SVG markup. Once it has
//!   drawn the first replay frame it sets `data-status="drawn"` on `<body>`; every script error
//!   is counted in `data-errors` and shown in a red box. It also publishes the replay canvas's
//!   page rectangle as `data-canvas="x,y,w,h"` (CSS px) so a screenshot test knows where to look.
//! * `coverage.svg`, `sweep_robots.svg`, `sweep_loss.svg`, `robustness.svg`: the same plots as
//!   files, for papers and slides.
//! * `results.json`: the whole [`Report`], replay frames included, so it deserializes back into a
//!   `Report` and a page can be re-rendered from it without re-running the study.
//! * `results.md`: the three tables in Markdown, with the columns of [`text_table`].
//!
//! Everything is a pure function of the `Report`: the same report writes the same bytes.

mod page;
mod plots;
mod tables;
#[cfg(test)]
mod tests;

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::recording::{CoverageSeries, Recording};
use crate::study::Row;

/// Everything a report shows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub title: String,
    /// The command line that produced it, for people to re-run.
    pub command: String,
    /// The run replayed on the page (BLE in the paper's setting).
    pub recording: Recording,
    /// Coverage over time in the replayed world, one series per controller (same seed).
    pub coverage: Vec<(String, CoverageSeries)>,
    /// The paper's setting: one row per controller.
    pub paper: Vec<Row>,
    /// robots x targets x loss, every controller.
    pub sweep: Vec<Row>,
    /// A robot killed halfway, at 0, 10 and 30 % loss, every controller.
    pub robustness: Vec<Row>,
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
    Ok(written)
}

/// The rows as a fixed-width text table for a terminal: a header line, then one line per row.
pub fn text_table(rows: &[Row]) -> String {
    tables::text(rows)
}
