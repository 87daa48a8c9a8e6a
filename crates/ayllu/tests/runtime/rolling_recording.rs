//! The rolling flight recorder (`RecordOptions::keep_last`, spec/flight-recorder.md,
//! "Checkpoints"): a node that records all the time keeps only its last window, its files stay
//! bounded, and a replay of what is kept starts from the oldest checkpoint and reproduces every
//! value the node accepted from there, bit for bit, the same values a whole recording of the
//! same run holds.

use std::path::{Path, PathBuf};

use ayllu::replay::{Recording, Replay};
use ayllu::stdlib::{cross_subsumption, VISION};
use ayllu::{Duration, Instant, Lockstep, Node, NodeId, RecordOptions, RecordStats};

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("rolling-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Three nodes of the paper's cross-subsumption (BLE) over the in-process network, node 1
/// recorded into `path` with `options`; `secs` of virtual time with targets moving. The run is
/// the same every time (virtual time, in-process network), whatever node 1's recorder does.
fn run(path: &Path, options: RecordOptions, secs: u64) -> RecordStats {
    run_team(path, &[Some(options), None, None], secs).remove(0)
}

/// [`run`], node `i + 1` recorded with `options[i]` (`None`: not recorded) into `path`'s
/// folder as `n{i+1}.mcap` (node 1 into `path`). What each recorder did, in order.
fn run_team(path: &Path, options: &[Option<RecordOptions>; 3], secs: u64) -> Vec<RecordStats> {
    let mut team = Lockstep::new(&format!("rolling-{}", path.display()));
    for id in 1..=3u32 {
        let mut node = Node::new(team.clock().clone(), team.network().attach(NodeId(id)).unwrap());
        if let Some(o) = &options[id as usize - 1] {
            let file = if id == 1 { path.to_path_buf() } else { path.with_file_name(format!("n{id}.mcap")) };
            node.record(file, o.clone()).unwrap();
        }
        cross_subsumption(node.core_mut(), 3, "Peers", 5.0).unwrap();
        team.add_node(node);
    }
    let tick = Duration::from_millis(20);
    let mut k = 0u64;
    while team.now() < Instant::from_secs(secs) {
        if k.is_multiple_of(5) {
            for i in 0..3 {
                let id = team.nodes()[i].id().0 as u64;
                for n in 1..=3u64 {
                    let wobble = ((k / 5 + id * n) % 13) as f64 / 20.0;
                    team.node(i).write(VISION, &format!("Target{n}Angle"), 0.1 * n as f64).unwrap();
                    team.node(i).write(VISION, &format!("Target{n}Bottom"), 0.2 + wobble).unwrap();
                }
            }
        }
        team.advance(tick, tick);
        k += 1;
        // Virtual time runs far faster than real time here: let the writer keep up, as it does
        // on a robot, so that checkpoints come when due (a recorder whose writer is behind
        // waits for it before checkpointing).
        let waited = std::time::Instant::now();
        while (0..3).any(|i| team.node(i).recording_stats().is_some_and(|s| s.waiting > 0))
            && waited.elapsed() < std::time::Duration::from_secs(10)
        {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
    }
    (0..3).filter_map(|i| team.node(i).stop_recording()).collect()
}

fn files(d: &Path) -> Vec<(String, u64)> {
    let mut out: Vec<(String, u64)> = std::fs::read_dir(d)
        .unwrap()
        .flatten()
        .map(|e| (e.file_name().to_string_lossy().into_owned(), e.metadata().unwrap().len()))
        .collect();
    out.sort();
    out
}

#[test]
fn a_rolling_recording_keeps_its_last_window_and_replays_it_bit_for_bit_from_a_checkpoint() {
    let d = dir("window");
    let window = std::time::Duration::from_secs(4);
    let stats = run(&d.join("n1.mcap"), RecordOptions::default().keep_last(window), 40);
    let kept = files(&d);
    // Checkpoints every second (a quarter of the window): the files are the runs that reach
    // back the window, at most 4 s + 1 s of the node's life.
    assert!(stats.deleted > 20, "{stats:?} {kept:?}");
    assert!(!d.join("n1.mcap").exists(), "the first segment was deleted: {kept:?}");
    assert!(kept.len() <= 6, "{kept:?}");

    let rec = Recording::open(d.join("n1.mcap")).unwrap();
    let checkpoint = rec.checkpoint.clone().expect("a rolling recording starts from a checkpoint");
    let end = rec.end();
    let span = end - checkpoint.at;
    assert!(
        span >= Duration::from_secs(4) && span <= Duration::from_secs(5) + Duration::from_millis(100),
        "kept {}s",
        span.as_secs_f64()
    );
    assert!(rec.gap.is_none(), "{:?}", rec.gap);
    let mut replay = Replay::new(&rec);
    replay.run_to_end().unwrap();
    let accepted = replay.accepted().to_vec();
    assert!(accepted.len() > 500, "{}", accepted.len());
    assert_eq!(replay.checked(), accepted.len());

    // The same run recorded whole: from the checkpoint's instant on, it accepted the same
    // values (the rolling recording lost nothing inside its window).
    let whole = dir("whole");
    run(&whole.join("n1.mcap"), RecordOptions::default(), 40);
    let all = Recording::open(whole.join("n1.mcap")).unwrap();
    assert!(all.checkpoint.is_none());
    let mut full = Replay::new(&all);
    full.run_to_end().unwrap();
    let tail: Vec<_> = full.accepted().iter().filter(|a| a.at > checkpoint.at).cloned().collect();
    let rolled: Vec<_> = accepted.iter().filter(|a| a.at > checkpoint.at).cloned().collect();
    assert_eq!(rolled.len(), tail.len());
    assert!(rolled == tail, "the rolling recording's window differs from the whole recording's");

    // `why` and `list` at an instant inside the window answer as from the whole recording.
    let t = checkpoint.at + Duration::from_millis(2_345);
    let mut a = Replay::new(&rec);
    let mut b = Replay::new(&all);
    assert_eq!(a.list_at(t).unwrap(), b.list_at(t).unwrap());
    assert_eq!(a.why_at(t, "OBS1", "Rotate").unwrap(), b.why_at(t, "OBS1", "Rotate").unwrap());
}

#[test]
fn a_byte_cap_shorter_than_the_window_deletes_sooner_and_still_replays() {
    let d = dir("bytes");
    let options = RecordOptions { max_bytes: 600 * 1024, segment_bytes: 128 * 1024, ..RecordOptions::default() }
        .keep_last(std::time::Duration::from_secs(30));
    let stats = run(&d.join("n1.mcap"), options, 30);
    let total: u64 = files(&d).iter().map(|(_, n)| n).sum();
    assert!(total <= 600 * 1024, "{total} bytes kept: {:?}", files(&d));
    assert!(stats.deleted > 0, "{stats:?}");
    let rec = Recording::open(d.join("n1.mcap")).unwrap();
    assert!(rec.checkpoint.is_some());
    Replay::new(&rec).run_to_end().unwrap();
}

/// A team of rolling recordings (windows of different lengths, one whole) replays as one
/// team: every remote value accepted inside the windows is matched with its sending, and those
/// sent before a sender's window are counted apart, not judged.
#[test]
fn rolling_recordings_of_a_team_replay_as_one_team() {
    let d = dir("team");
    let rolling = |s: u64| Some(RecordOptions::default().keep_last(std::time::Duration::from_secs(s)));
    run_team(&d.join("n1.mcap"), &[rolling(4), rolling(8), Some(RecordOptions::default())], 30);
    let recs: Vec<Recording> = (1..=3).map(|i| Recording::open(d.join(format!("n{i}.mcap"))).unwrap()).collect();
    assert!(recs[0].checkpoint.is_some() && recs[1].checkpoint.is_some() && recs[2].checkpoint.is_none());
    let check = ayllu::team_replay::check(&recs);
    assert!(check.passed(), "{check}");
    assert_eq!(check.unexplained(), 0, "{check}");
    assert!(check.explained > 100, "{check}");
    // Node 3's whole recording accepted values node 1 and 2 sent before their windows.
    assert!(check.before_sender_started.values().sum::<usize>() > 100, "{check}");
    assert!(check.to_string().contains("before their sender's rolling recording starts"), "{check}");
}
