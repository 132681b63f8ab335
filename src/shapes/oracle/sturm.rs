//! Exact real-root isolation for polynomials with rational coefficients (the oracle of the
//! root finders, seed 002 §1.1–§1.4).
//!
//! Coefficient slices are ASCENDING: `c[0] + c[1]·x + … + c[n]·xⁿ`, each a GMP rational, so
//! every sign below is exact.
//!
//! - **Counting**: Sturm's theorem. For the sequence `p₀ = s, p₁ = s′, pₖ₊₁ = −rem(pₖ₋₁, pₖ)` of
//!   a square-free `s`, the number of roots in `(a, b]` is `V(a) − V(b)` (sign variations,
//!   zeros skipped), also when `a` or `b` is a root. On a polynomial with multiple roots the
//!   count at `±∞` is the number of distinct real roots.
//! - **Isolation**: bisection of `(−2ᵏ, 2ᵏ]`, where `2ᵏ` exceeds Cauchy's bound
//!   `1 + max|cᵢ/cₙ|`, at dyadic midpoints until every interval holds one root of the
//!   square-free part `s = p / gcd(p, p′)`.
//! - **Multiplicity**: with `g₁ = gcd(p, p′)`, `g₂ = gcd(g₁, g₁′)`, …, a root of `p` has
//!   multiplicity `1 + #{j : gⱼ vanishes there}` (the roots of `gⱼ₊₁` are among those of `gⱼ`).
//! - **Correct rounding** ([`round_root`]): bisection on the floats of the precision (ordinal
//!   midpoints, so any magnitude takes at most 64 steps), with the exact sign of `s` at each
//!   float; once the root lies between two adjacent floats, the sign at their exact midpoint (the
//!   rounding boundary) decides, and a root exactly on it is rounded ties-to-even.

use crate::numerics::exact::{q, round_q};
use crate::numerics::Precision;
use rug::{Integer, Rational};
use std::cmp::Ordering;

/// One distinct real root, isolated: it is the only root of the polynomial in `(lo, hi]` (or it
/// equals `lo == hi`).
#[derive(Clone, Debug, PartialEq)]
pub struct RealRoot {
    /// Lower end (excluded unless it equals `hi`).
    pub lo: Rational,
    /// Upper end.
    pub hi: Rational,
    /// The root's multiplicity.
    pub multiplicity: u32,
}

/// A polynomial with rational coefficients, ascending, without zero leading coefficients (the
/// zero polynomial is empty).
type Poly = Vec<Rational>;

/// The coefficients without their zero high-order terms.
pub fn trim(c: &[Rational]) -> Poly {
    let n = c
        .iter()
        .rposition(|x| x.cmp0() != Ordering::Equal)
        .map_or(0, |i| i + 1);
    c[..n].to_vec()
}

/// The exact coefficients of a list of floats (ascending).
pub fn exact_coeffs(c: &[f64]) -> Poly {
    c.iter().map(|&x| q(x)).collect()
}

fn derivative(p: &[Rational]) -> Poly {
    p.iter()
        .enumerate()
        .skip(1)
        .map(|(i, x)| Rational::from(x * Integer::from(i)))
        .collect()
}

/// `p(x)`, exactly (Horner).
pub fn eval(p: &[Rational], x: &Rational) -> Rational {
    let mut acc = Rational::new();
    for c in p.iter().rev() {
        acc *= x;
        acc += c;
    }
    acc
}

/// The sign of `p(x)`.
pub fn sign_at(p: &[Rational], x: &Rational) -> Ordering {
    eval(p, x).cmp0()
}

/// Quotient and remainder of `a / b` (`b` non-zero).
fn divide(a: &[Rational], b: &[Rational]) -> (Poly, Poly) {
    let mut r = trim(a);
    let db = b.len() - 1;
    let lead = &b[db];
    let mut quo = vec![Rational::new(); r.len().saturating_sub(db).max(1)];
    while r.len() > db {
        // Cancel the leading term of the remainder
        let k = r.len() - 1 - db;
        let f = Rational::from(&r[r.len() - 1] / lead);
        for (i, bi) in b.iter().enumerate() {
            r[k + i] -= Rational::from(&f * bi);
        }
        quo[k] = f;
        r = trim(&r);
    }
    (trim(&quo), r)
}

/// The monic greatest common divisor (`[1]` for coprime polynomials).
fn gcd(a: &[Rational], b: &[Rational]) -> Poly {
    let (mut x, mut y) = (trim(a), trim(b));
    while !y.is_empty() {
        let r = divide(&x, &y).1;
        x = std::mem::replace(&mut y, r);
    }
    let lead = x.last().cloned().unwrap_or_else(|| Rational::from(1));
    x.iter().map(|c| Rational::from(c / &lead)).collect()
}

/// `p / gcd(p, p′)`: the same roots, each simple.
pub fn square_free(p: &[Rational]) -> Poly {
    let p = trim(p);
    if p.len() <= 2 {
        return p;
    }
    divide(&p, &gcd(&p, &derivative(&p))).0
}

/// A Sturm sequence.
struct Sturm(Vec<Poly>);

impl Sturm {
    fn new(p: &[Rational]) -> Sturm {
        let p = trim(p);
        let mut seq = vec![p.clone()];
        let mut next = derivative(&p);
        while !next.is_empty() {
            let r = divide(&seq[seq.len() - 1], &next).1;
            seq.push(next);
            next = r.into_iter().map(|c| -c).collect();
        }
        Sturm(seq)
    }

    fn variations(signs: impl Iterator<Item = Ordering>) -> u32 {
        let mut last = Ordering::Equal;
        let mut v = 0;
        for s in signs.filter(|s| *s != Ordering::Equal) {
            v += (last != Ordering::Equal && s != last) as u32;
            last = s;
        }
        v
    }

    fn at(&self, x: &Rational) -> u32 {
        Self::variations(self.0.iter().map(|p| sign_at(p, x)))
    }

    /// Variations at `+∞` (`up`) or `−∞`.
    fn at_infinity(&self, up: bool) -> u32 {
        Self::variations(self.0.iter().map(|p| {
            let s = p.last().map_or(Ordering::Equal, |c| c.cmp0());
            if up || p.len() % 2 == 1 {
                s
            } else {
                s.reverse()
            }
        }))
    }

    fn total(&self) -> u32 {
        self.at_infinity(false) - self.at_infinity(true)
    }
}

/// The number of distinct real roots (0 for a constant; the zero polynomial also gives 0).
pub fn count_distinct(c: &[Rational]) -> u32 {
    let p = trim(c);
    if p.len() <= 1 {
        return 0;
    }
    Sturm::new(&p).total()
}

/// The number of distinct real roots in the closed interval `[lo, hi]` (`lo ≤ hi`; a non-zero
/// polynomial).
pub fn count_in(c: &[Rational], lo: &Rational, hi: &Rational) -> u32 {
    let s = square_free(c);
    if s.len() <= 1 {
        return 0;
    }
    let st = Sturm::new(&s);
    st.at(lo) - st.at(hi) + (sign_at(&s, lo) == Ordering::Equal) as u32
}

/// A power of two above every root's magnitude (Cauchy: `|x| < 1 + max|cᵢ/cₙ|`).
fn root_bound(p: &[Rational]) -> Rational {
    let lead = p[p.len() - 1].clone().abs();
    let mut m = Rational::new();
    for c in &p[..p.len() - 1] {
        let r = c.clone().abs() / &lead;
        if r > m {
            m = r;
        }
    }
    let ceil = Integer::from((m + 1u32).ceil_ref());
    Rational::from(Integer::from(1) << ceil.significant_bits())
}

/// The distinct real roots of a polynomial (ascending coefficients, `c.last() != 0` after
/// trimming), isolated, in ascending order, with multiplicities. The zero polynomial and
/// constants have none.
pub fn real_roots(c: &[Rational]) -> Vec<RealRoot> {
    let p = trim(c);
    if p.len() <= 1 {
        return vec![];
    }
    // Multiplicities from the chain of repeated factors
    let chain = repeated_factors(&p);
    isolate(&p, &square_free(&p))
        .into_iter()
        .map(|(lo, hi)| {
            let extra = chain.iter().take_while(|g| g.at(&lo) > g.at(&hi)).count();
            RealRoot {
                lo,
                hi,
                multiplicity: 1 + extra as u32,
            }
        })
        .collect()
}

/// The distinct real roots isolated as [`real_roots`] does, without their multiplicities (which
/// cost a chain of gcds), and the square-free part: for callers that only count or round.
pub fn isolated(c: &[Rational]) -> (Vec<(Rational, Rational)>, Poly) {
    let p = trim(c);
    if p.len() <= 1 {
        return (vec![], p);
    }
    let s = square_free(&p);
    (isolate(&p, &s), s)
}

/// The only root of the square-free `s` in `(lo, hi]` (as [`isolated`] gives them), correctly
/// rounded as [`round_root`] does.
pub fn round_in(s: &[Rational], lo: &Rational, hi: &Rational, prec: Precision) -> f64 {
    round_isolated(s, lo.clone(), hi.clone(), prec)
}

/// Intervals `(lo, hi]` each holding one root of `p` (trimmed, degree ≥ 1), ascending, by
/// Sturm bisection on its square-free part `s`.
fn isolate(p: &[Rational], s: &[Rational]) -> Vec<(Rational, Rational)> {
    let st = Sturm::new(s);
    // Bisect (−B, B] down to one root per interval
    let b = root_bound(p);
    let mut out = vec![];
    let mut stack = vec![(
        Rational::from(-&b),
        b.clone(),
        st.at(&-b.clone()),
        st.at(&b),
    )];
    while let Some((lo, hi, vlo, vhi)) = stack.pop() {
        match vlo - vhi {
            0 => {}
            1 => out.push((lo, hi)),
            _ => {
                let mid = Rational::from(&lo + &hi) / 2u32;
                let vm = st.at(&mid);
                stack.push((mid.clone(), hi, vm, vhi));
                stack.push((lo, mid, vlo, vm));
            }
        }
    }
    out
}

/// Sturm sequences of the square-free parts of `g₁ = gcd(p, p′)`, `g₂ = gcd(g₁, g₁′)`, ….
fn repeated_factors(p: &[Rational]) -> Vec<Sturm> {
    let mut out = vec![];
    let mut g = gcd(p, &derivative(p));
    while g.len() > 1 {
        out.push(Sturm::new(&square_free(&g)));
        g = gcd(&g, &derivative(&g));
    }
    out
}

/// Position of a value of the precision on its number line (±0 share 0; ±inf are the ends).
pub(crate) fn ordinal(x: f64, prec: Precision) -> i64 {
    let (mag, neg) = match prec {
        Precision::F32 => ((x as f32).to_bits() as i64 & 0x7fff_ffff, x < 0.0),
        Precision::F64 => ((x.to_bits() & !(1 << 63)) as i64, x < 0.0),
    };
    if neg {
        -mag
    } else {
        mag
    }
}

pub(crate) fn from_ordinal(o: i64, prec: Precision) -> f64 {
    let mag = match prec {
        Precision::F32 => f32::from_bits(o.unsigned_abs() as u32) as f64,
        Precision::F64 => f64::from_bits(o.unsigned_abs()),
    };
    if o < 0 {
        -mag
    } else {
        mag
    }
}

/// The rounding boundary between adjacent values `a < b` of the precision (their exact
/// midpoint; beyond the largest finite value, where rounding to nearest overflows).
fn boundary(a: f64, b: f64, prec: Precision) -> Rational {
    let top =
        |max: f64, half_ulp: i32| q(max) + Rational::from(Integer::from(1) << half_ulp as u32);
    let half_ulp = match prec {
        Precision::F32 => 103,
        Precision::F64 => 970,
    };
    let max = match prec {
        Precision::F32 => f32::MAX as f64,
        Precision::F64 => f64::MAX,
    };
    if b.is_infinite() {
        top(max, half_ulp)
    } else if a.is_infinite() {
        -top(max, half_ulp)
    } else {
        (q(a) + q(b)) / 2u32
    }
}

/// Root `r` of `c` (as returned by [`real_roots`]) correctly rounded to the precision, as `f64`
/// (ties to even; ±inf beyond the largest finite value).
pub fn round_root(c: &[Rational], r: &RealRoot, prec: Precision) -> f64 {
    round_isolated(&square_free(c), r.lo.clone(), r.hi.clone(), prec)
}

/// The only root of the square-free `s` in `(lo, hi]`, correctly rounded.
fn round_isolated(s: &[Rational], mut lo: Rational, mut hi: Rational, prec: Precision) -> f64 {
    // Exact roots at the ends (the root is in (lo, hi]: a root at lo is another one, and the
    // sign just right of it is that of s′ there)
    if lo == hi || sign_at(s, &hi) == Ordering::Equal {
        return round_q(&hi, prec);
    }
    let s_lo = match sign_at(s, &lo) {
        Ordering::Equal => sign_at(&derivative(s), &lo),
        o => o,
    };
    // The floats either side of an f64 estimate, each an exact sign: usually two signs narrow
    // (lo, hi] to two ulps, where the loop below would have bisected every float between them
    if let Some(a) = estimate(s, &lo, &hi, s_lo, prec) {
        let oa = ordinal(a, prec);
        for x in [from_ordinal(oa - 1, prec), from_ordinal(oa + 1, prec)] {
            if !x.is_finite() {
                continue;
            }
            let xq = q(x);
            if !(xq > lo && xq < hi) {
                continue;
            }
            match sign_at(s, &xq) {
                Ordering::Equal => return x,
                sx if sx == s_lo => lo = xq,
                _ => hi = xq,
            }
        }
    }
    loop {
        let (a, b) = (round_q(&lo, prec), round_q(&hi, prec));
        let (oa, ob) = (ordinal(a, prec), ordinal(b, prec));
        if oa == ob {
            return a;
        }
        // Adjacent floats: the sign at the rounding boundary decides
        if ob as i128 - oa as i128 == 1 {
            let m = boundary(a, b, prec);
            return match sign_at(s, &m) {
                Ordering::Equal => round_q(&m, prec),
                sm if sm == s_lo => b,
                _ => a,
            };
        }
        // Otherwise halve the floats between the ends
        let f = from_ordinal(((oa as i128 + ob as i128) / 2) as i64, prec);
        let fq = q(f);
        match sign_at(s, &fq) {
            Ordering::Equal => return f,
            sf if sf == s_lo => lo = fq,
            _ => hi = fq,
        }
    }
}

/// The root of `s` in `(lo, hi]` estimated in `f64` (bisection on the `f64` line with signs
/// evaluated in `f64`: not trusted, only a place to look), rounded to the precision.
fn estimate(
    s: &[Rational],
    lo: &Rational,
    hi: &Rational,
    s_lo: Ordering,
    prec: Precision,
) -> Option<f64> {
    let c: Vec<f64> = s.iter().map(|x| x.to_f64()).collect();
    if !c.iter().all(|x| x.is_finite()) {
        return None;
    }
    let sign = |x: f64| {
        c.iter()
            .rev()
            .fold(0.0, |acc, &k| acc * x + k)
            .partial_cmp(&0.0)
    };
    let (mut a, mut b) = (lo.to_f64(), hi.to_f64());
    for _ in 0..70 {
        let (oa, ob) = (ordinal(a, Precision::F64), ordinal(b, Precision::F64));
        if ob as i128 - oa as i128 <= 1 {
            break;
        }
        let m = from_ordinal(((oa as i128 + ob as i128) / 2) as i64, Precision::F64);
        if sign(m) == Some(s_lo) {
            a = m;
        } else {
            b = m;
        }
    }
    let r = match prec {
        Precision::F32 => b as f32 as f64,
        Precision::F64 => b,
    };
    r.is_finite().then_some(r)
}

/// Every distinct real root correctly rounded, ascending.
pub fn rounded_roots(c: &[Rational], prec: Precision) -> Vec<f64> {
    let p = trim(c);
    if p.len() <= 1 {
        return vec![];
    }
    let s = square_free(&p);
    isolate(&p, &s)
        .into_iter()
        .map(|(lo, hi)| round_isolated(&s, lo, hi, prec))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poly(c: &[f64]) -> Poly {
        exact_coeffs(c)
    }

    #[test]
    fn multiplicities_and_exact_roots() {
        // (x − 1)²(x − 2) = x³ − 4x² + 5x − 2
        let p = poly(&[-2.0, 5.0, -4.0, 1.0]);
        let r = real_roots(&p);
        assert_eq!(r.len(), 2);
        assert_eq!(
            r.iter().map(|r| r.multiplicity).collect::<Vec<_>>(),
            vec![2, 1]
        );
        assert_eq!(rounded_roots(&p, Precision::F64), vec![1.0, 2.0]);
        assert_eq!(count_distinct(&p), 2);
        // (x − 3)³ x
        let p = poly(&[0.0, -27.0, 27.0, -9.0, 1.0]);
        let r = real_roots(&p);
        assert_eq!(
            r.iter().map(|r| r.multiplicity).collect::<Vec<_>>(),
            vec![1, 3]
        );
        assert_eq!(rounded_roots(&p, Precision::F32), vec![0.0, 3.0]);
    }

    #[test]
    fn sqrt2_in_both_precisions() {
        let p = poly(&[-2.0, 0.0, 1.0]);
        assert_eq!(
            rounded_roots(&p, Precision::F64),
            vec![-std::f64::consts::SQRT_2, std::f64::consts::SQRT_2]
        );
        let s = std::f32::consts::SQRT_2 as f64;
        assert_eq!(rounded_roots(&p, Precision::F32), vec![-s, s]);
        assert_eq!(count_distinct(&poly(&[2.0, 0.0, 1.0])), 0);
    }

    #[test]
    fn different_magnitudes() {
        // (x − 1e-20)(x − 1e20)(x + 1e30), the roots exactly the f64 values
        let (a, b, c) = (q(1e-20), q(1e20), q(-1e30));
        let p = vec![
            -(Rational::from(&a * &b) * &c),
            Rational::from(&a * &b) + Rational::from(&a * &c) + Rational::from(&b * &c),
            -(Rational::from(&a + &b) + &c),
            Rational::from(1),
        ];
        assert_eq!(rounded_roots(&p, Precision::F64), vec![-1e30, 1e-20, 1e20]);
        assert_eq!(
            rounded_roots(&p, Precision::F32),
            vec![
                (-1e30f64) as f32 as f64,
                1e-20f64 as f32 as f64,
                1e20f64 as f32 as f64
            ]
        );
    }

    #[test]
    fn ties_round_to_even_and_overflow() {
        // 2x − (1 + 2⁻⁵³·… ): a root exactly between 1 and its successor rounds to 1
        let mid = (q(1.0) + q(1f64.next_up())) / 2u32;
        let p = vec![-mid.clone(), Rational::from(1)];
        assert_eq!(rounded_roots(&p, Precision::F64), vec![1.0]);
        // A root beyond f32's range rounds to +inf in f32
        let p = poly(&[-1e39, 1.0]);
        assert_eq!(rounded_roots(&p, Precision::F32), vec![f64::INFINITY]);
        assert_eq!(rounded_roots(&p, Precision::F64), vec![1e39]);
    }

    #[test]
    fn counts_in_closed_intervals() {
        let p = poly(&[-2.0, 5.0, -4.0, 1.0]);
        assert_eq!(count_in(&p, &q(1.0), &q(2.0)), 2);
        assert_eq!(count_in(&p, &q(1.5), &q(2.0)), 1);
        assert_eq!(count_in(&p, &q(1.1), &q(1.9)), 0);
        assert!(real_roots(&poly(&[0.0, 0.0])).is_empty());
        assert!(real_roots(&poly(&[3.0])).is_empty());
    }
}
