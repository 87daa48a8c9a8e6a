//! `ayllu shape`: the userspace shaper between network namespaces (`crate::shaper`), for
//! kernels without `tc netem`. This file only reads the arguments and prints: a first line
//! naming the TAP interfaces it made, then one JSON line of counters per status period.
//!
//! Promises: if one TAP interface cannot be made, the command exits with code 1, an error
//! naming the namespace and why, and no interface left behind; the interfaces disappear when
//! the command ends; Ctrl-C, SIGTERM, `--for` and a closed stdout end it.

use std::io::Write as _;

use crate::shaper::{self, Hub, ShaperCounts, Tap};
use ayllu::faults::FaultConfig;
use ayllu::{Clock as _, Duration, MonotonicClock};
use clap::Args;
use serde_json::json;

use crate::fail::Fail;
use crate::{positive_secs, signals};

#[derive(Args, Debug)]
pub struct ShapeArgs {
    /// A network namespace to join (a name from `ip netns add`, or a path such as
    /// /proc/PID/ns/net); give two or more. Each gets a TAP interface, down and without an
    /// address: configure it with `ip -n NETNS addr add ... dev TAP; ip -n NETNS link set TAP up`.
    #[arg(long, value_name = "NETNS", required = true, num_args = 1)]
    pub netns: Vec<String>,
    /// The TAP interface's name in every namespace.
    #[arg(long, value_name = "NAME", default_value = "ayllu0")]
    pub tap: String,
    /// Seed of the faults (robot i's link uses seed + i): the same seed, the same faults for
    /// the same frames at the same times.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Delay added to every frame, in milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 0.0, value_parser = non_negative_ms)]
    pub delay_ms: f64,
    /// Extra delay, uniform in 0..JITTER milliseconds (reorders frames closer than that).
    #[arg(long, value_name = "MS", default_value_t = 0.0, value_parser = non_negative_ms)]
    pub jitter_ms: f64,
    /// Probability that a frame is dropped (per frame and destination, 0-1).
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = probability)]
    pub loss: f64,
    /// Probability that a frame is delivered twice.
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = probability)]
    pub duplicate: f64,
    /// Probability that a frame is held back and delivered after the next one.
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = probability)]
    pub reorder: f64,
    /// Probability that one bit of a frame is flipped (the receiver's checksums drop it).
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = probability)]
    pub corrupt: f64,
    /// Print the counters this often.
    #[arg(long, value_name = "MS", default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..))]
    pub status_ms: u64,
    /// Stop after this many seconds (default: run until killed or Ctrl-C).
    #[arg(long = "for", value_name = "SECS", value_parser = positive_secs)]
    pub for_secs: Option<f64>,
}

fn probability(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(p) if (0.0..=1.0).contains(&p) => Ok(p),
        _ => Err(format!("`{s}` is not a probability (0 to 1)")),
    }
}

/// Milliseconds, 0 to 60 000.
fn non_negative_ms(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(ms) if (0.0..=60_000.0).contains(&ms) => Ok(ms),
        _ => Err(format!("`{s}` is not a number of milliseconds (0 to 60000)")),
    }
}

fn millis(ms: f64) -> Duration {
    Duration::from_nanos((ms * 1e6).round() as u64)
}

fn counts_json(t: f64, c: &ShaperCounts) -> serde_json::Value {
    json!({
        "t": (t * 1000.0).round() / 1000.0,
        "received": c.received,
        "sent": c.faults.sent,
        "lost": c.faults.lost,
        "duplicated": c.faults.duplicated,
        "reordered": c.faults.reordered,
        "delayed": c.faults.delayed,
        "corrupted": c.faults.corrupted,
        "written": c.written,
        "out_of_order": c.out_of_order,
        "runts": c.runts,
        "io_errors": c.io_errors,
    })
}

pub fn run(args: &ShapeArgs) -> Result<(), Fail> {
    if args.netns.len() < 2 {
        return Err(Fail::usage("give two or more --netns to join"));
    }
    let config = FaultConfig {
        seed: args.seed,
        loss: args.loss,
        duplicate: args.duplicate,
        reorder: args.reorder,
        corrupt: args.corrupt,
        delay: millis(args.delay_ms),
        jitter: millis(args.jitter_ms),
    };
    let taps = args
        .netns
        .iter()
        .map(|ns| Tap::open(&args.tap, Some(ns)).map_err(|e| Fail::error(format!("namespace {ns}: {e}"))))
        .collect::<Result<Vec<_>, _>>()?;
    let mut hub = Hub::new(taps, &config);
    signals::install();
    let clock = MonotonicClock::new();
    let until = args.for_secs.map(|s| clock.now() + Duration::from_nanos((s * 1e9) as u64));
    let mut out = std::io::stdout().lock();
    let ports: Vec<_> = args.netns.iter().map(|ns| json!({"netns": ns, "tap": args.tap})).collect();
    writeln!(out, "{}", json!({"shaping": ports, "seed": args.seed}))?;
    out.flush()?;
    let mut write_error = None;
    shaper::run(&mut hub, &clock, until, Duration::from_millis(args.status_ms), |now, counts| {
        let line = writeln!(out, "{}", counts_json(now.as_secs_f64(), counts)).and_then(|()| out.flush());
        match line {
            Ok(()) => !signals::stopped(),
            Err(e) => {
                write_error = Some(e);
                false
            }
        }
    })
    .map_err(|e| Fail::error(format!("shaping: {e}")))?;
    match write_error {
        Some(e) => Err(e.into()),
        None => Ok(()),
    }
}
