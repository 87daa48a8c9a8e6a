//! Many runs: the paper's setting over seeds, the sweep (robots x targets x loss) and the
//! robustness scenario (a robot killed halfway), each for BLE and every baseline.

use serde::{Deserialize, Serialize};

use crate::metrics::Metrics;

/// One cell of a table: a controller in one setting, metrics averaged over `seeds` runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub controller: String,
    pub robots: u32,
    pub targets: u32,
    pub loss: f64,
    /// A robot is killed halfway through each run.
    pub kill: bool,
    pub seeds: u32,
    /// Means over the seeds (recover_s: over the runs that had something to re-cover).
    pub metrics: Metrics,
    /// Standard deviation of A_w over the seeds.
    pub a_w_sd: f64,
}
