//! In-run timing for reports: the median of repeated runs with its spread.
//!
//! Criterion stays the precise tool (`cargo bench`); this is what `rayproof report` uses so
//! that every figure in a report is measured in the same run as the others. Machines are shared
//! and noisy, so reports print the spread and prefer ratios.

use serde::Serialize;
use std::time::Instant;

/// Repeated measurements of one quantity, in nanoseconds per unit.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Timing {
    /// Median over the runs.
    pub median_ns: f64,
    /// Fastest run.
    pub min_ns: f64,
    /// Slowest run.
    pub max_ns: f64,
    /// Number of timed runs.
    pub runs: usize,
}

impl Timing {
    /// Summarises per-unit samples (any order).
    pub fn of(mut v: Vec<f64>) -> Timing {
        assert!(!v.is_empty(), "Timing::of needs at least one sample");
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Timing {
            median_ns: median,
            min_ns: v[0],
            max_ns: v[n - 1],
            runs: n,
        }
    }

    /// Spread as (max − min) / median, a fraction.
    pub fn spread(&self) -> f64 {
        (self.max_ns - self.min_ns) / self.median_ns.max(f64::MIN_POSITIVE)
    }

    /// Half the spread in percent, `(±4%)`; beyond ±25 % the median is marked as not to be
    /// used, `(±547%: too noisy to use)`.
    pub fn plus_minus(&self) -> String {
        let h = 50.0 * self.spread();
        if h <= 25.0 {
            format!("(±{h:.0}%)")
        } else {
            format!("(±{h:.0}%: too noisy to use)")
        }
    }

    /// "12.3 ns (±4%)", the form reports print (three significant digits below 1 ns).
    pub fn label(&self) -> String {
        let digits = if self.median_ns < 1.0 { 3 } else { 1 };
        format!("{:.*} ns {}", digits, self.median_ns, self.plus_minus())
    }
}

/// Times `f` (which processes `units` items per call): one warm-up call, then `runs` timed
/// calls, each repeated until it lasts at least `min_ns` so short kernels are not lost in timer
/// resolution. Returns nanoseconds per unit.
pub fn measure<R>(units: usize, runs: usize, min_ns: f64, mut f: impl FnMut() -> R) -> Timing {
    std::hint::black_box(f());
    let samples = (0..runs.max(1))
        .map(|_| {
            let (mut reps, mut elapsed) = (0u64, 0f64);
            let clock = Instant::now();
            while elapsed < min_ns || reps == 0 {
                std::hint::black_box(f());
                reps += 1;
                elapsed = clock.elapsed().as_nanos() as f64;
            }
            elapsed / (reps as f64 * units.max(1) as f64)
        })
        .collect();
    Timing::of(samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_spread() {
        let t = Timing::of(vec![3.0, 1.0, 2.0, 10.0]);
        assert_eq!(
            (t.median_ns, t.min_ns, t.max_ns, t.runs),
            (2.5, 1.0, 10.0, 4)
        );
        assert!((t.spread() - 3.6).abs() < 1e-12);
        assert_eq!(Timing::of(vec![5.0]).median_ns, 5.0);
    }
}
