//! `ayllu node --record-last SECS --record FILE`, a rolling flight recorder on a real node
//! process talking UDP to another: while it runs its files stay bounded (never more than the
//! runs that reach back the window), the first segment goes once the window has passed, and
//! `ayllu replay FILE check` replays what is left from its oldest checkpoint with every value
//! reproduced bit for bit; `why` answers inside the window and refuses an instant before it.
//!
//! Verdicts do not depend on timing: the bounds are counts of files and instants on the node's
//! own clock as its recording states them. The ten-minute run of the issue (`--record-last 60`)
//! is the ignored test `ten_minutes` (`make soak-recorder`).

use crate::common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{ayllu, start_on_loopback, wait_for};

const LIMIT: Duration = Duration::from_secs(60);

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("rolling-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The segment files in `dir` and their total size.
fn kept(dir: &Path) -> (usize, u64) {
    let files: Vec<u64> = std::fs::read_dir(dir)
        .map(|rd| rd.flatten().filter_map(|e| e.metadata().ok()).map(|m| m.len()).collect())
        .unwrap_or_default();
    (files.len(), files.iter().sum())
}

/// Two robots of the paper's Fig. 2 over loopback for `secs`, robot 1 recording its last
/// `window` seconds; checks what the module docs say and prints the figures.
fn rolling(name: &str, secs: u64, window: u64) {
    let dir = scratch(name);
    let file = dir.join("n1.mcap").display().to_string();
    let (for_s, window_s) = (secs.to_string(), window.to_string());
    let (mut procs, _) = start_on_loopback(
        2,
        |k| format!("n{}", k + 1),
        |k, url| {
            let id = (k + 1).to_string();
            let mut args: Vec<String> = ["node", "--id", &id, "--udp", url, "--layers", "2", "--claim-hz", "2"]
                .iter()
                .map(|s| s.to_string())
                .collect();
            args.extend(["--sight", "1:0.9,2:0.5", "--status-ms", "1000", "--for", &for_s].map(String::from));
            if k == 0 {
                args.extend(["--record", &file, "--record-last", &window_s].map(String::from));
            }
            args
        },
    );
    // A checkpoint every quarter of the window (at least every second): the runs that reach
    // back the window, plus the one being written.
    let interval = (window as f64 / 4.0).max(1.0);
    let most = (window as f64 / interval).ceil() as usize + 2;
    let (mut max_files, mut max_bytes) = (0, 0);
    let status = wait_for(Duration::from_secs(secs + 60), Duration::from_millis(250), || {
        let (n, bytes) = kept(&dir);
        max_files = max_files.max(n);
        max_bytes = max_bytes.max(bytes);
        procs[0].exited()
    });
    for p in &mut procs {
        let s = wait_for(LIMIT, Duration::from_millis(50), || p.exited());
        assert!(s.is_some_and(|s| s.success()), "{} did not end well: {}", p.name, p.stderr());
    }
    assert!(status.is_some());
    let stderr = procs[0].stderr();
    assert!(stderr.contains("rolling recording: kept"), "{stderr}");
    let (files, bytes) = kept(&dir);
    eprintln!(
        "rolling {name}: {secs} s run, last {window} s kept: at most {max_files} files and {max_bytes} bytes at once; \
         {files} files, {bytes} bytes at the end"
    );
    assert!(max_files <= most, "{max_files} segment files at once (at most {most}): {stderr}");
    assert!(!dir.join("n1.mcap").exists(), "the first segment is deleted once the window has passed");

    let check = ayllu(&["replay", &file, "--json", "check"], LIMIT).ok();
    let j = check.json();
    assert_eq!(j["complete"], true, "{check:?}");
    assert!(j["accepted_checked"].as_u64().unwrap() > 50, "{check:?}");
    let (start, end) = (j["start"].as_f64().unwrap(), j["end"].as_f64().unwrap());
    assert!(j["checkpoint_entry"].as_u64().unwrap() > 0, "{check:?}");
    // On the node's clock: the kept part reaches back the window, and at most an interval more
    // (plus the last loop turn's slack).
    assert!(end - start >= window as f64 && end - start <= window as f64 + interval + 0.5, "{check:?}");
    assert!(check.stderr.contains("rolling: it starts from its checkpoint"), "{check:?}");
    let text = ayllu(&["replay", &file, "check"], LIMIT).ok();
    assert!(text.stdout.contains("from its checkpoint at t="), "{text:?}");
    // The folder stands for the recording whose first segment is gone.
    let folder = ayllu(&["replay", &dir.display().to_string(), "--json", "check"], LIMIT).ok().json();
    assert_eq!(folder["accepted_checked"], j["accepted_checked"], "{folder}");

    // Inside the window `why` answers as the live node would have; before it, it refuses.
    let inside = format!("{:.3}", start + 0.5);
    let why = ayllu(&["replay", &file, "--at", &inside, "--json", "why", "OBS1.Rotate"], LIMIT).ok();
    assert!(why.json()["windows"].is_array(), "{why:?}");
    let before = format!("{:.3}", (start - 0.5).max(0.0));
    ayllu(&["replay", &file, "--at", &before, "why", "OBS1.Rotate"], LIMIT).fails(1, "what came before was not kept");
}

#[test]
fn a_rolling_node_process_keeps_a_bounded_window_and_replays_it_from_a_checkpoint() {
    rolling("short", 14, 4);
}

/// The run: ten minutes keeping the last 60 s (`AYLLU_ROLLING_MINUTES` changes the
/// length). `make soak-recorder`.
#[test]
#[ignore]
fn ten_minutes() {
    let minutes: u64 = std::env::var("AYLLU_ROLLING_MINUTES").ok().and_then(|m| m.parse().ok()).unwrap_or(10);
    rolling("ten-minutes", minutes * 60, 60);
}
