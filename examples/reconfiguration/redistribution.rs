//! Redistribution of tasks across a team, while it runs (the paper, §3): three robots run the
//! paper's cross-subsumption (Fig. 2) on CMOMMT for 120 s; at 60 s an operator switches the
//! whole team, in one transaction, to the reverse priority order of the targets. Coverage is
//! measured before, during and after the switch.
//!
//! cargo run --release -p ayllu-sim --example redistribution [SEED]

use ayllu_sim::redistribution::{run, RedistributionOptions};

fn main() {
    let seed = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(1);
    let options = RedistributionOptions::paper(seed, 120.0);
    match run(&options) {
        Ok(report) => print!("{report}"),
        Err(e) => {
            eprintln!("redistribution: {e}");
            std::process::exit(1);
        }
    }
}
