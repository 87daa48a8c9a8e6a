//! The rate of a port's messages: how often they arrive, how regularly (jitter), and where
//! they stopped for a while (gaps) or were lost (sequence numbers skipped). `ayllu hz` prints
//! it, as `ros2 topic hz` does for a topic.
//!
//! Promises: pure arithmetic on the arrival times and sequence numbers it is given (no clock);
//! a window keeps the last `window` arrivals, so a long run costs bounded memory; a gap is an
//! interval longer than `gap_factor` times the window's median interval, so it adapts to any
//! rate and no fixed threshold decides it.

use std::collections::VecDeque;

/// One arrival: when (seconds on any clock that does not go back) and, when known, the
/// sequence number of the connection that carried it (N1).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Arrival {
    /// Seconds.
    pub t: f64,
    /// The carrying connection's sequence number.
    pub seq: Option<u64>,
}

/// An interval much longer than usual.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Gap {
    /// When it started (the arrival before it), seconds.
    pub after: f64,
    /// How long it lasted, seconds.
    pub length: f64,
}

/// What a window of arrivals says about the rate.
#[derive(Clone, Debug, PartialEq)]
pub struct RateReport {
    /// Arrivals in the window.
    pub count: usize,
    /// Arrivals per second: intervals / time they span (0 with fewer than two arrivals).
    pub rate_hz: f64,
    /// Mean interval, seconds.
    pub mean: f64,
    /// Shortest interval, seconds.
    pub min: f64,
    /// Longest interval, seconds.
    pub max: f64,
    /// Standard deviation of the intervals (the jitter), seconds.
    pub std_dev: f64,
    /// Median interval, seconds.
    pub median: f64,
    /// Intervals longer than `gap_factor` x the median.
    pub gaps: Vec<Gap>,
    /// Messages missing by their sequence numbers (skipped numbers), in the window.
    pub lost: u64,
    /// Messages that arrived with a sequence number not above the previous one (duplicated
    /// or reordered by the network).
    pub out_of_order: u64,
}

/// The last `window` arrivals of one port.
#[derive(Clone, Debug)]
pub struct RateWindow {
    arrivals: VecDeque<Arrival>,
    window: usize,
    gap_factor: f64,
}

impl RateWindow {
    /// A window of `window` arrivals (at least 2); gaps are intervals over `gap_factor` x the
    /// median (at least 1).
    pub fn new(window: usize, gap_factor: f64) -> RateWindow {
        RateWindow { arrivals: VecDeque::new(), window: window.max(2), gap_factor: gap_factor.max(1.0) }
    }

    /// Add one arrival (the oldest leaves a full window).
    pub fn push(&mut self, arrival: Arrival) {
        if self.arrivals.len() == self.window {
            self.arrivals.pop_front();
        }
        self.arrivals.push_back(arrival);
    }

    /// Arrivals in the window.
    pub fn len(&self) -> usize {
        self.arrivals.len()
    }

    /// The window's figures.
    pub fn report(&self) -> RateReport {
        let a: Vec<Arrival> = self.arrivals.iter().copied().collect();
        let intervals: Vec<f64> = a.windows(2).map(|w| (w[1].t - w[0].t).max(0.0)).collect();
        let n = intervals.len();
        let (mut lost, mut out_of_order) = (0u64, 0u64);
        for w in a.windows(2) {
            if let (Some(p), Some(q)) = (w[0].seq, w[1].seq) {
                if q > p {
                    lost += q - p - 1;
                } else {
                    out_of_order += 1;
                }
            }
        }
        if n == 0 {
            return RateReport {
                count: a.len(),
                rate_hz: 0.0,
                mean: 0.0,
                min: 0.0,
                max: 0.0,
                std_dev: 0.0,
                median: 0.0,
                gaps: Vec::new(),
                lost,
                out_of_order,
            };
        }
        let span: f64 = intervals.iter().sum();
        let mean = span / n as f64;
        let var = intervals.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        let mut sorted = intervals.clone();
        sorted.sort_by(f64::total_cmp);
        let median = if n % 2 == 1 { sorted[n / 2] } else { (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0 };
        let gaps = a
            .windows(2)
            .zip(&intervals)
            .filter(|(_, len)| median > 0.0 && **len > self.gap_factor * median)
            .map(|(w, len)| Gap { after: w[0].t, length: *len })
            .collect();
        RateReport {
            count: a.len(),
            rate_hz: if span > 0.0 { n as f64 / span } else { 0.0 },
            mean,
            min: sorted[0],
            max: sorted[n - 1],
            std_dev: var.sqrt(),
            median,
            gaps,
            lost,
            out_of_order,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t: f64, seq: u64) -> Arrival {
        Arrival { t, seq: Some(seq) }
    }

    #[test]
    fn a_steady_stream_has_its_rate_and_no_gap() {
        let mut w = RateWindow::new(100, 3.0);
        for i in 0..11 {
            w.push(at(i as f64 * 0.1, i + 1));
        }
        let r = w.report();
        assert_eq!(r.count, 11);
        assert!((r.rate_hz - 10.0).abs() < 1e-9, "{r:?}");
        assert!(r.std_dev < 1e-9 && r.gaps.is_empty() && r.lost == 0);
    }

    #[test]
    fn a_silence_is_a_gap_and_skipped_numbers_are_lost() {
        let mut w = RateWindow::new(100, 3.0);
        for (t, s) in [(0.0, 1), (0.1, 2), (0.2, 3), (1.2, 9), (1.3, 10), (1.25, 10)] {
            w.push(at(t, s));
        }
        let r = w.report();
        assert_eq!(r.gaps, vec![Gap { after: 0.2, length: 1.0 }]);
        assert_eq!((r.lost, r.out_of_order), (5, 1));
    }

    #[test]
    fn the_window_keeps_the_last_arrivals() {
        let mut w = RateWindow::new(3, 2.0);
        for i in 0..10 {
            w.push(Arrival { t: i as f64, seq: None });
        }
        assert_eq!(w.len(), 3);
        assert_eq!(w.report().count, 3);
        assert_eq!(RateWindow::new(5, 2.0).report().rate_hz, 0.0);
    }
}
