//! Flight recording from Python: `Node.record(path)` writes everything that enters the node's
//! core, and the values its ports accepted, into an MCAP file that Foxglove opens and `ayllu
//! replay` plays back (spec/flight-recorder.md); `ayllu.check_recording(path)` replays one.
//! A Python process's code is not needed to replay: what each activation did is recorded.

use std::path::Path;

use ayllu::replay::{Recording, Replay};
use ayllu::{RecordOptions, RecordStats};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors;

/// Start recording `node` into `path` (segments `path.1.mcap`, ... follow it), all segments
/// together at most `max_bytes` (None: 1 GiB); with `keep_last` (seconds), only about the last
/// that long is kept (a rolling recording).
pub fn record(node: &mut ayllu::Node, path: &Path, max_bytes: Option<u64>, keep_last: Option<f64>) -> PyResult<()> {
    let mut options = match max_bytes {
        None => RecordOptions::default(),
        Some(n) if n < 65_536 => {
            return Err(errors::InvalidError::new_err("max_bytes must be at least 65536"));
        }
        Some(n) => RecordOptions::default().max_bytes(n),
    };
    if let Some(secs) = keep_last {
        let window = ayllu::Duration::try_from_positive_secs(secs).map_err(errors::core)?;
        options = options.keep_last(std::time::Duration::from_nanos(window.as_nanos()));
    }
    node.record(path, options).map_err(errors::runtime)
}

/// What a recorder did, as a dict (`written`, `bytes`, `segments`, the three `dropped_*`
/// counts and `error`).
pub fn stats_dict<'py>(py: Python<'py>, s: &RecordStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("written", s.written)?;
    d.set_item("bytes", s.bytes)?;
    d.set_item("segments", s.segments)?;
    d.set_item("dropped_queue", s.dropped_queue)?;
    d.set_item("dropped_journal", s.dropped_journal)?;
    d.set_item("dropped_cap", s.dropped_cap)?;
    d.set_item("deleted", s.deleted)?;
    d.set_item("error", s.error.clone())?;
    Ok(d)
}

/// Replay the flight recording `path` to its end, checking every value its ports accepted
/// against the recording bit for bit; returns how many were compared. Raises
/// `ayllu.InvalidError` for a file that is not a recording and for a replay that diverged
/// (the message says where and what).
#[pyfunction]
pub fn check_recording(py: Python<'_>, path: std::path::PathBuf) -> PyResult<usize> {
    py.detach(|| {
        let recording = Recording::open(&path).map_err(|e| e.to_string())?;
        let mut replay = Replay::new(&recording);
        replay.run_to_end().map_err(|d| d.to_string())?;
        Ok::<usize, String>(replay.checked())
    })
    .map_err(errors::InvalidError::new_err)
}

/// Replay the flight recordings of several nodes of one team (files, in any order; the first
/// one's clock is the reference) as one system: each node's replay, the clocks against the
/// first's with a bound, and every remote value accepted matched with its sending (same value,
/// sent no later, accepted once). Returns a dict (`passed`, `clocks`, `unexplained`,
/// `findings`, ...: the `--json` of `ayllu replay FILE FILE... check`). With `mcap`, also
/// writes every value the ports accepted on one timeline there (Foxglove opens it). Raises
/// `ayllu.InvalidError` for a file that is not a flight recording.
#[pyfunction]
#[pyo3(signature = (paths, mcap = None))]
pub fn check_team(
    py: Python<'_>,
    paths: Vec<std::path::PathBuf>,
    mcap: Option<std::path::PathBuf>,
) -> PyResult<Py<PyAny>> {
    let json = py
        .detach(|| {
            let recordings =
                paths.iter().map(Recording::open).collect::<Result<Vec<_>, _>>().map_err(|e| e.to_string())?;
            let team = ayllu::team_replay::Team::open(recordings);
            if let Some(path) = &mcap {
                team.write_timeline(path).map_err(|e| format!("{}: {e}", path.display()))?;
            }
            Ok::<String, String>(team.check().to_json().to_string())
        })
        .map_err(errors::InvalidError::new_err)?;
    Ok(py.import("json")?.call_method1("loads", (json,))?.unbind())
}

/// Why `behavior.port` on node `node` held what it held at `at` (seconds on that node's
/// clock), followed across the team's recordings `paths` as far as `depth` messages away: a
/// list of links (dicts: `depth`, `level`, `node`, `t`, `kind`, `text`), the `--json` of
/// `ayllu replay FILE FILE... --at T why --node ID BEHAVIOR.PORT --depth N`.
#[pyfunction]
#[pyo3(signature = (paths, node, at, behavior, port, depth = 2))]
pub fn why_team(
    py: Python<'_>,
    paths: Vec<std::path::PathBuf>,
    node: u32,
    at: f64,
    behavior: String,
    port: String,
    depth: usize,
) -> PyResult<Py<PyAny>> {
    let at = ayllu::Duration::try_from_secs_f64(at).map_err(|e| errors::value_error(e.to_string()))?;
    let json = py
        .detach(|| {
            let recordings =
                paths.iter().map(Recording::open).collect::<Result<Vec<_>, _>>().map_err(|e| e.to_string())?;
            let team = ayllu::team_replay::Team::open(recordings);
            let chain = team
                .why(ayllu::NodeId(node), ayllu::Instant::ZERO + at, &behavior, &port, depth)
                .map_err(|e| e.to_string())?;
            Ok::<String, String>(chain.to_json().to_string())
        })
        .map_err(errors::InvalidError::new_err)?;
    Ok(py.import("json")?.call_method1("loads", (json,))?.unbind())
}
