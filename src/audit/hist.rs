//! Samples kept as histograms, so that the summaries of a row can be merged exactly from
//! shards: counts add, and quantiles and means are taken from the merged histogram.
//!
//! - [`Hist`]: non-negative integers (ulps, widths), exact. [`Stats`] of it equal the
//!   summary of the raw sample: sorted, the same quantile rule, the mean summed in ascending
//!   order.
//! - [`FloatHist`]: non-negative reals (err/cond, residuals), each rounded to 8 significant
//!   bits (relative error ≤ 2⁻⁹) before it is counted; the exact maximum is kept beside.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Summary of a sample of non-negative numbers.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Stats {
    /// Number of values.
    pub count: u64,
    /// Largest value (0 for none).
    pub max: f64,
    /// Median value.
    pub median: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Mean value.
    pub mean: f64,
}

/// Summarises a sorted sample given as ascending `(value, count)` runs: the value at rank
/// `round((n − 1)·p)` for the quantiles, the mean summed value by value in ascending order.
fn summarise(runs: impl Iterator<Item = (f64, u64)> + Clone, max: f64) -> Stats {
    let n: u64 = runs.clone().map(|(_, c)| c).sum();
    if n == 0 {
        return Stats::default();
    }
    let at = |p: f64| {
        let rank = ((n - 1) as f64 * p).round() as u64;
        let mut seen = 0;
        for (v, c) in runs.clone() {
            seen += c;
            if rank < seen {
                return v;
            }
        }
        max
    };
    let mut sum = 0.0;
    for (v, c) in runs.clone() {
        for _ in 0..c {
            sum += v;
        }
    }
    Stats {
        count: n,
        max,
        median: at(0.5),
        p99: at(0.99),
        mean: sum / n as f64,
    }
}

/// A histogram of non-negative integers: value → count.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Hist(BTreeMap<u64, u64>);

impl Hist {
    /// Counts one value.
    pub fn add(&mut self, v: u64) {
        *self.0.entry(v).or_insert(0) += 1;
    }
    /// Adds another histogram's counts (merging is exact: order does not matter).
    pub fn merge(&mut self, other: &Hist) {
        for (&v, &c) in &other.0 {
            *self.0.entry(v).or_insert(0) += c;
        }
    }
    /// Number of values counted.
    pub fn count(&self) -> u64 {
        self.0.values().sum()
    }
    /// Largest value counted (`None` when empty).
    pub fn max(&self) -> Option<u64> {
        self.0.keys().next_back().copied()
    }
    /// How many values exceed `v`.
    pub fn above(&self, v: u64) -> u64 {
        self.0.range(v.saturating_add(1)..).map(|(_, c)| c).sum()
    }
    /// `(value, count)` pairs, ascending by value.
    pub fn runs(&self) -> impl Iterator<Item = (u64, u64)> + Clone + '_ {
        self.0.iter().map(|(&v, &c)| (v, c))
    }
    /// Summary of the values.
    pub fn stats(&self) -> Stats {
        self.stats_of(|v| v as f64)
    }
    /// Summary of `f(value)` for a non-decreasing `f` (e.g. bits of error, log2(1 + ulps)).
    pub fn stats_of(&self, f: impl Fn(u64) -> f64 + Copy) -> Stats {
        let max = self.max().map(f).unwrap_or(0.0);
        summarise(self.runs().map(move |(v, c)| (f(v), c)), max)
    }
}

/// Significant bits kept by [`FloatHist`].
const FLOAT_BITS: u32 = 8;

/// A histogram of non-negative reals rounded to `FLOAT_BITS` significant bits, with the
/// exact maximum beside it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FloatHist {
    /// Rounded value (as `f64` bits, which order like the values) → count.
    runs: BTreeMap<u64, u64>,
    /// The exact largest value (as `f64` bits).
    max: u64,
}

/// `x ≥ 0` rounded to nearest with [`FLOAT_BITS`] significant bits.
fn round_bits(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let drop = 52 - (FLOAT_BITS - 1);
    let b = x.to_bits();
    let half = 1u64 << (drop - 1);
    f64::from_bits((b + half) & !((1u64 << drop) - 1))
}

impl FloatHist {
    /// Counts `x` (negative values and NaN are counted as their absolute value and +inf).
    pub fn add(&mut self, x: f64) {
        let x = if x.is_nan() { f64::INFINITY } else { x.abs() };
        *self.runs.entry(round_bits(x).to_bits()).or_insert(0) += 1;
        self.max = self.max.max(x.to_bits());
    }
    /// Adds another histogram's counts (merging is exact: order does not matter).
    pub fn merge(&mut self, other: &FloatHist) {
        for (&v, &c) in &other.runs {
            *self.runs.entry(v).or_insert(0) += c;
        }
        self.max = self.max.max(other.max);
    }
    /// How many values were counted.
    pub fn count(&self) -> u64 {
        self.runs.values().sum()
    }
    /// Summary: exact maximum; quantiles and mean of the rounded values.
    pub fn stats(&self) -> Stats {
        summarise(
            self.runs.iter().map(|(&v, &c)| (f64::from_bits(v), c)),
            f64::from_bits(self.max),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The summary the audit used before histograms: sort, rank round((n−1)p), sum in order.
    fn raw(mut v: Vec<f64>) -> Stats {
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        Stats {
            count: v.len() as u64,
            max: *v.last().unwrap(),
            median: q(0.5),
            p99: q(0.99),
            mean: v.iter().sum::<f64>() / v.len() as f64,
        }
    }

    #[test]
    fn integer_stats_equal_the_raw_sample_and_merge_exactly() {
        let mut h = 0x243f_6a88_85a3_08d3u64;
        let vals: Vec<u64> = (0..5000)
            .map(|i| {
                h = h.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                if i % 7 == 0 {
                    h >> 1
                } else {
                    h % 17
                }
            })
            .collect();
        let mut all = Hist::default();
        let (mut a, mut b) = (Hist::default(), Hist::default());
        for (i, &v) in vals.iter().enumerate() {
            all.add(v);
            if i % 3 == 0 { &mut a } else { &mut b }.add(v);
        }
        a.merge(&b);
        assert_eq!(a, all);
        assert_eq!(all.stats(), raw(vals.iter().map(|&v| v as f64).collect()));
        let bits = |u: u64| (1.0 + u as f64).log2();
        assert_eq!(
            all.stats_of(bits),
            raw(vals.iter().map(|&v| bits(v)).collect())
        );
        assert_eq!(
            all.above(16),
            vals.iter().filter(|&&v| v > 16).count() as u64
        );
    }

    #[test]
    fn float_stats_keep_the_exact_max_and_round_the_rest_to_8_bits() {
        let mut f = FloatHist::default();
        for x in [0.0, 1.0, std::f64::consts::PI, 1e-300, 2.5e7] {
            f.add(x);
        }
        let s = f.stats();
        assert_eq!(s.max, 2.5e7);
        assert_eq!(s.count, 5);
        assert_eq!(s.median, 1.0);
        let pi = std::f64::consts::PI;
        assert!((round_bits(pi) - pi).abs() / pi <= 1.0 / 256.0);
        assert_eq!(round_bits(1.0), 1.0);
        assert_eq!(round_bits(1.0 + 1.0 / 256.0), 1.0 + 1.0 / 128.0); // a tie rounds up
    }
}
