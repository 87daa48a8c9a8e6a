//! Figures over repeated runs, and verdicts against a goal that this host's noise cannot
//! fake: a median with an interval that holds the true median with about 95 % confidence
//! whatever the distribution (order statistics), its quartiles and its range. A goal is called
//! met or not met only when that interval lies wholly on one side of it. Shared by the network
//! benchmark of this crate and the simulator's speed benchmark (`#[path]`), so both decide the
//! same way.

// Each benchmark that includes this module uses a part of it.
#![allow(dead_code)]

/// Per-run (or per-pair) figures: their median, quartiles, range and the median's 95 %
/// interval (`low`-`high`).
#[derive(Clone, Copy, Debug)]
pub struct Spread {
    pub runs: usize,
    pub q1: f64,
    pub median: f64,
    pub q3: f64,
    pub min: f64,
    pub max: f64,
    pub low: f64,
    pub high: f64,
}

/// The spread of `v` (at least one figure).
pub fn spread(mut v: Vec<f64>) -> Spread {
    assert!(!v.is_empty(), "a spread needs at least one run");
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let at = |q: f64| v[((n - 1) as f64 * q).round() as usize];
    // The median lies below each run's figure with probability one half, so the ranks of the
    // interval come from the binomial(n, 1/2) (normal approximation): 1-based rank
    // k = floor((n + 1) / 2 - 0.98 sqrt(n)), at least 1, gives [x_(k), x_(n + 1 - k)].
    let k = (((n + 1) as f64 / 2.0 - 0.98 * (n as f64).sqrt()).floor() as usize).max(1);
    Spread {
        runs: n,
        q1: at(0.25),
        median: at(0.5),
        q3: at(0.75),
        min: v[0],
        max: v[n - 1],
        low: v[k - 1],
        high: v[n - k],
    }
}

impl Spread {
    /// Whether the goal `figure <= goal` (`at_most`) or `figure >= goal` holds beyond this
    /// host's noise: met or not met when the median's 95 % interval lies on one side of the
    /// goal, otherwise "within noise", with the side the median is on.
    pub fn verdict(&self, goal: f64, at_most: bool) -> &'static str {
        let (good, bad, median_good) = if at_most {
            (self.high <= goal, self.low > goal, self.median <= goal)
        } else {
            (self.low >= goal, self.high < goal, self.median >= goal)
        };
        match (good, bad, median_good) {
            (true, _, _) => "MET",
            (_, true, _) => "NOT met",
            (_, _, true) => "median met, within noise",
            _ => "median not met, within noise",
        }
    }

    /// One line: the median's interval, the quartiles and the range, each followed by `unit`
    /// (`x` for ratios and speed-ups).
    pub fn describe_in(&self, unit: &str, decimals: usize) -> String {
        let d = decimals;
        format!(
            "  {} runs: median in {:.d$}-{:.d$}{unit} (95 %); quartiles {:.d$}-{:.d$}{unit}, all {:.d$}-{:.d$}{unit}",
            self.runs, self.low, self.high, self.q1, self.q3, self.min, self.max
        )
    }

    /// [`Spread::describe_in`] for ratios.
    pub fn describe(&self) -> String {
        self.describe_in("x", 2)
    }
}
