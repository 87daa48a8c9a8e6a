//! A run squeezed for the page's replay, so that every run of a study can ride along in one
//! self-contained HTML page.
//!
//! A [`Replay`] keeps what the canvas draws from a [`Recording`], in two parts:
//! * poses of robots and targets, **decimated**: one sample every [`Replay::every`] recorded
//!   frames (plus the last frame), quantized to 1 cm and 1/256 of a turn and delta-coded as
//!   text ([`encode`]): about one character per coordinate instead of a dozen. The page
//!   interpolates between samples;
//! * each robot's discrete state (alive, drive, claims, inhibited, observing) at **every**
//!   recorded frame where it changes, so decimation loses no claim, drive or observation; coded
//!   the same way, a change in a handful of characters.
//!
//! Promises: [`Replay::robot_poses`] and [`Replay::target_path`] decode what the page decodes,
//! within half a quantum of the recording's values at the sample frames ([`Replay::sample_frames`]);
//! [`Replay::state_at`] is the recording's state at any frame. The same recording and step give
//! the same bytes.

use serde::{Deserialize, Serialize};

use crate::recording::{Event, Recording, RecordingMeta, RobotFrame, RobotInfo, TargetInfo};

/// Position quantum: 1 cm (a pixel or two on the page's canvas).
const CM: f64 = 100.0;
/// Heading quantum: 1/256 of a turn (1.4°).
const TURN: i64 = 256;
/// The 64 characters of the code (base64's, all plain in JSON and HTML).
const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
/// Deltas within ±SMALL take one character; others take [`ESCAPE`] and four more.
const SMALL: i64 = 31;
const ESCAPE: u8 = b'/';
/// Offset of an escaped delta, written as 4 base-64 digits (24 bits).
const BIG: i64 = 1 << 23;

/// A robot's discrete state from frame `.0` on (until its next change): frame index, alive
/// (0/1), drive (target id, 0: none), and the target ids it claims, is inhibited for, and
/// observes. In a [`Replay`] it is coded as integers: frames since the previous change, alive,
/// drive, then each list as its length and its ids.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct State(pub u32, pub u8, pub u32, pub Vec<u32>, pub Vec<u32>, pub Vec<u32>);

/// One run, ready for the page.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Replay {
    /// The page's first menu: "Paper setting", "Robustness: 10 % loss", "Sweep: 5 robots, ...".
    /// Runs sharing a setting differ by controller and seed (in `meta`).
    pub setting: String,
    /// The run's settings (controller, seed, arena, ...).
    pub meta: RecordingMeta,
    /// The robots' fixed facts.
    pub robots: Vec<RobotInfo>,
    /// The targets' fixed facts.
    pub targets: Vec<TargetInfo>,
    /// Kills, in time order.
    pub events: Vec<Event>,
    /// Recorded frames (frame i at i · `meta.frame_dt`).
    pub frames: u32,
    /// Recorded frames per pose sample: sample i is frame min(i · every, frames − 1).
    pub every: u32,
    /// Per robot: x, y (cm) and heading (1/256 turn) at each sample, delta-coded.
    pub poses: Vec<String>,
    /// Per target: x, y (cm) at each sample, delta-coded.
    pub paths: Vec<String>,
    /// Per robot: its [`State`] at frame 0 and at every frame where it changes, coded.
    pub states: Vec<String>,
}

impl Replay {
    /// `recording` with its poses sampled about every `step` seconds (at least every frame).
    pub fn new(setting: impl Into<String>, recording: &Recording, step: f64) -> Replay {
        let dt = recording.meta.frame_dt;
        let every = if dt > 0.0 && step > dt { (step / dt).round().max(1.0) as u32 } else { 1 };
        let frames = recording.frames.len() as u32;
        let sample_frames = sample_frames(frames, every);
        let poses = (0..recording.robots.len())
            .map(|k| {
                let mut code = Coder::default();
                let (mut x, mut y, mut h) = (0, 0, 0);
                for &i in &sample_frames {
                    let r = recording.frames[i as usize].robots.get(k);
                    let (nx, ny, nh) = r.map_or((x, y, h), |r| {
                        (cm(r.x), cm(r.y), (r.theta / std::f64::consts::TAU * TURN as f64).round() as i64)
                    });
                    code.push(nx - x);
                    code.push(ny - y);
                    // The shorter way round, so a heading crossing ±π costs one character.
                    code.push((nh - h + TURN / 2).rem_euclid(TURN) - TURN / 2);
                    (x, y, h) = (nx, ny, nh);
                }
                code.text
            })
            .collect();
        let paths = (0..recording.targets.len())
            .map(|j| {
                let mut code = Coder::default();
                let (mut x, mut y) = (0, 0);
                for &i in &sample_frames {
                    let (nx, ny) = recording.frames[i as usize].targets.get(j).map_or((x, y), |p| (cm(p[0]), cm(p[1])));
                    code.push(nx - x);
                    code.push(ny - y);
                    (x, y) = (nx, ny);
                }
                code.text
            })
            .collect();
        let states = (0..recording.robots.len())
            .map(|k| {
                let mut code = Coder::default();
                let mut last: Option<State> = None;
                for (i, f) in recording.frames.iter().enumerate() {
                    let Some(r) = f.robots.get(k) else { continue };
                    let s = state(i as u32, r);
                    if last.as_ref().is_some_and(|l| same_state(l, &s)) {
                        continue;
                    }
                    code.push(i64::from(s.0) - last.as_ref().map_or(0, |l| i64::from(l.0)));
                    code.push(i64::from(s.1));
                    code.push(i64::from(s.2));
                    for ids in [&s.3, &s.4, &s.5] {
                        code.push(ids.len() as i64);
                        ids.iter().for_each(|&id| code.push(i64::from(id)));
                    }
                    last = Some(s);
                }
                code.text
            })
            .collect();
        Replay {
            setting: setting.into(),
            meta: recording.meta.clone(),
            robots: recording.robots.clone(),
            targets: recording.targets.clone(),
            events: recording.events.clone(),
            frames,
            every,
            poses,
            paths,
            states,
        }
    }

    /// The recorded frame of each pose sample.
    pub fn sample_frames(&self) -> Vec<u32> {
        sample_frames(self.frames, self.every)
    }

    /// Robot `k`'s (x, y, heading) at each sample, decoded: metres, radians in [0, 2π).
    pub fn robot_poses(&self, k: usize) -> Option<Vec<(f64, f64, f64)>> {
        let d = decode(self.poses.get(k)?)?;
        let (mut x, mut y, mut h) = (0, 0, 0);
        let mut out = Vec::with_capacity(d.len() / 3);
        for c in d.chunks(3) {
            let [dx, dy, dh] = c else { return None };
            (x, y, h) = (x + dx, y + dy, (h + dh).rem_euclid(TURN));
            out.push((x as f64 / CM, y as f64 / CM, h as f64 / TURN as f64 * std::f64::consts::TAU));
        }
        Some(out)
    }

    /// Target `j`'s (x, y) at each sample, decoded (metres).
    pub fn target_path(&self, j: usize) -> Option<Vec<(f64, f64)>> {
        let d = decode(self.paths.get(j)?)?;
        let (mut x, mut y) = (0, 0);
        let mut out = Vec::with_capacity(d.len() / 2);
        for c in d.chunks(2) {
            let [dx, dy] = c else { return None };
            (x, y) = (x + dx, y + dy);
            out.push((x as f64 / CM, y as f64 / CM));
        }
        Some(out)
    }

    /// Robot `k`'s states, decoded: at frame 0 and at each change.
    pub fn changes(&self, k: usize) -> Option<Vec<State>> {
        let d = decode(self.states.get(k)?)?;
        let mut it = d.into_iter();
        let mut out = Vec::new();
        let mut frame = 0;
        let list = |it: &mut std::vec::IntoIter<i64>| -> Option<Vec<u32>> {
            let n = it.next()?;
            (0..n).map(|_| it.next().and_then(|id| u32::try_from(id).ok())).collect()
        };
        while let Some(step) = it.next() {
            frame += u32::try_from(step).ok()?;
            let alive = u8::try_from(it.next()?).ok()?;
            let drive = u32::try_from(it.next()?).ok()?;
            out.push(State(frame, alive, drive, list(&mut it)?, list(&mut it)?, list(&mut it)?));
        }
        Some(out)
    }

    /// Robot `k`'s state at `frame`: its last change at or before it.
    pub fn state_at(&self, k: usize, frame: u32) -> Option<State> {
        self.changes(k)?.into_iter().take_while(|s| s.0 <= frame).last()
    }
}

fn cm(v: f64) -> i64 {
    (v * CM).round() as i64
}

fn state(frame: u32, r: &RobotFrame) -> State {
    State(frame, u8::from(r.alive), r.drive, r.claims.clone(), r.inhibited.clone(), r.observing.clone())
}

fn same_state(a: &State, b: &State) -> bool {
    (a.1, a.2, &a.3, &a.4, &a.5) == (b.1, b.2, &b.3, &b.4, &b.5)
}

fn sample_frames(frames: u32, every: u32) -> Vec<u32> {
    if frames == 0 {
        return Vec::new();
    }
    let every = every.max(1);
    let mut out: Vec<u32> = (0..frames).step_by(every as usize).collect();
    if out.last() != Some(&(frames - 1)) {
        out.push(frames - 1);
    }
    out
}

/// Text of small integers: one character for |d| ≤ 31, five for anything up to ±2²³.
#[derive(Default)]
struct Coder {
    text: String,
}

impl Coder {
    fn push(&mut self, d: i64) {
        if (-SMALL..=SMALL).contains(&d) {
            self.text.push(ALPHABET[(d + SMALL) as usize] as char);
            return;
        }
        // Wider than any arena or heading this simulator makes; clamped rather than wrapped so
        // that a bug shows as a robot at the border, not as a robot teleported.
        let v = (d.clamp(-BIG + 1, BIG - 1) + BIG) as u32;
        self.text.push(ESCAPE as char);
        for shift in [18, 12, 6, 0] {
            self.text.push(ALPHABET[((v >> shift) & 63) as usize] as char);
        }
    }
}

/// The integers of `text` as [`encode`] wrote them (None for a character outside the code or a
/// truncated escape). Public for tests; the page has its own decoder in `replay.js`.
pub fn decode(text: &str) -> Option<Vec<i64>> {
    let digit = |c: u8| ALPHABET.iter().position(|&a| a == c).map(|p| p as i64);
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == ESCAPE {
            let digits = bytes.get(i + 1..i + 5)?;
            let mut v = 0;
            for &c in digits {
                v = v * 64 + digit(c)?;
            }
            out.push(v - BIG);
            i += 5;
        } else {
            out.push(digit(bytes[i])? - SMALL);
            i += 1;
        }
    }
    Some(out)
}

/// The characters of `values` as the page stores them (exposed for tests).
pub fn encode(values: &[i64]) -> String {
    let mut c = Coder::default();
    values.iter().for_each(|&v| c.push(v));
    c.text
}
