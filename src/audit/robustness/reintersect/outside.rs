//! Reintersection for a routine from outside the crate (a `--plugin` symbol or an `--exec`
//! child): the sphere's, the triangle's and the hinge's instances, primary rays, spawned rays and
//! judgement are the built-in methods' (the same seed gives the same rays), and the routine
//! answers every ray (a hinge is a case per triangle, the nearest hit kept, as for the built-ins).
//!
//! The routine is asked in batches, not ray by ray (a call to a worker or a child costs far more
//! than the arithmetic): the test runs once to collect the primary rays, which are answered in
//! one batch; again to collect the spawned rays, which depend on those answers; and a last time
//! with every answer known, which gives the rows. The passes are deterministic, so the last
//! asks nothing new.
//!
//! The renderer's point is rayproof's offset rule applied to the routine's `t`: the sphere's hit
//! reprojected onto the sphere as for every built-in method (pbrt's rule, `γ₅|p − c| + γ₁|p|`),
//! a triangle's `o + t·d` with `γ₂(|o| + |t·d|)`, the bound a routine that returns only `t` can
//! justify. A routine whose `t` is too far off for that bound re-hits its own surface: what the
//! test is there to show. A hit whose `t` is not finite and `> 0` (outside the answer contract,
//! judged in the audit's rows) is taken as no hit here.

use super::surfaces::{SphereR, Surface, TriR};
use super::Instance;
use crate::audit::robustness::offset::ReintersectRow;
use crate::audit::Method;
use crate::numerics::Precision;
use crate::shapes::sphere::methods::PickPrecision;
use crate::shapes::triangle::TriHit;
use rand_chacha::ChaCha8Rng;
use std::collections::HashMap;
use std::sync::Mutex;

enum Kind {
    Sphere(SphereR),
    Tri(TriR),
}

/// The routine's nearest hit on a case: which part and its `t` (`None`: a miss).
type Nearest = Option<(usize, f64)>;

/// An outside routine on one surface's instances, its answers cached by case.
struct Outside<'a> {
    kind: Kind,
    method: &'a dyn Method,
    prec: Precision,
    /// The routine's nearest hit of each case answered, by the case's bits.
    answers: Mutex<HashMap<Vec<u64>, Nearest>>,
    /// Cases asked in this pass and not yet answered (answered as misses in this pass).
    asked: Mutex<Vec<Vec<f64>>>,
}

fn key<F: PickPrecision>(input: &[F]) -> Vec<u64> {
    input.iter().map(|x| x.to_f64().to_bits()).collect()
}

impl Outside<'_> {
    /// The routine's nearest hit on the case `input` (object space): which part and its `t`;
    /// a case not answered yet is noted for the next batch (and a miss for now).
    fn hit<F: PickPrecision>(&self, input: &[F]) -> Option<(usize, F)> {
        let k = key(input);
        let known = self.answers.lock().expect("not poisoned").get(&k).copied();
        match known {
            Some(h) => h.map(|(i, t)| (i, F::from_f64(t))),
            None => {
                let mut asked = self.asked.lock().expect("not poisoned");
                asked.push(input.iter().map(|x| x.to_f64()).collect());
                None
            }
        }
    }

    /// The routine's inputs for one case: the sphere's as it is, a triangle per part.
    fn parts(&self, input: &[f64]) -> Vec<Vec<f64>> {
        match &self.kind {
            Kind::Sphere(_) => vec![input.to_vec()],
            Kind::Tri(k) => (0..k.tris())
                .map(|i| {
                    let (o, d, p) = k.tri(input, i);
                    [&o[..], &d[..], &p.concat()[..]].concat()
                })
                .collect(),
        }
    }

    /// Answers every case asked since the last batch: `false` when none was.
    fn answer_asked(&self) -> Result<bool, String> {
        let mut asked = std::mem::take(&mut *self.asked.lock().expect("not poisoned"));
        asked.sort_by_cached_key(|a| key(a));
        asked.dedup_by(|a, b| key(a) == key(b));
        if asked.is_empty() {
            return Ok(false);
        }
        let per = self.parts(&asked[0]).len();
        let inputs: Vec<Vec<f64>> = asked.iter().flat_map(|c| self.parts(c)).collect();
        let mut got = Vec::with_capacity(inputs.len());
        for chunk in inputs.chunks(crate::audit::run::CHUNK as usize) {
            let mut a = crate::audit::run::answers(&[self.method], self.prec, chunk)?;
            got.append(&mut a[0]);
        }
        let mut answers = self.answers.lock().expect("not poisoned");
        for (case, parts) in asked.iter().zip(got.chunks(per)) {
            // The nearest hit ahead; a t outside the contract (not finite, not > 0) is no hit
            let nearest = parts
                .iter()
                .enumerate()
                .filter(|(_, a)| a.count > 0)
                .filter_map(|(i, a)| a.values.first().map(|&t| (i, t)))
                .filter(|(_, t)| t.is_finite() && *t > 0.0)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            answers.insert(key(case), nearest);
        }
        Ok(true)
    }
}

impl Surface for Outside<'_> {
    fn name(&self) -> &'static str {
        match &self.kind {
            Kind::Sphere(k) => k.name(),
            Kind::Tri(k) => k.name(),
        }
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        // Renamed to the routine's own name by `rows`
        vec![("outside", self.method.robust())]
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, at: [f64; 3], prec: Precision) -> Instance {
        match &self.kind {
            Kind::Sphere(k) => k.instance(rng, s, at, prec),
            Kind::Tri(k) => k.instance(rng, s, at, prec),
        }
    }
    fn run<F: PickPrecision>(&self, _m: usize, input: &[F]) -> Option<F> {
        self.hit(input).map(|(_, t)| t)
    }
    fn exact(&self, input: &[f64]) -> Option<f64> {
        match &self.kind {
            Kind::Sphere(k) => k.exact(input),
            Kind::Tri(k) => k.exact(input),
        }
    }
    fn surface<F: PickPrecision>(&self, _m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]) {
        match &self.kind {
            // Every method's hit is reprojected the same way
            Kind::Sphere(k) => k.surface(0, input, t),
            Kind::Tri(k) => {
                // The part the routine hit (asked again: one call, the same answer)
                let part = self.hit(input).map_or(0, |(i, _)| i);
                let h = TriHit { t, b: [F::ZERO; 3] };
                k.point_of(0, input, part, &h)
            }
        }
    }
    fn curvature(&self, params: &[f64]) -> f64 {
        match &self.kind {
            Kind::Sphere(k) => k.curvature(params),
            Kind::Tri(k) => k.curvature(params),
        }
    }
    fn other_part<F: PickPrecision>(&self, _m: usize, primary: &[F], spawned: &[f64]) -> bool {
        let spawned: Vec<F> = spawned.iter().map(|&x| F::from_f64(x)).collect();
        match (self.hit(primary), self.hit(&spawned)) {
            (Some((a, _)), Some((b, _))) => a != b,
            _ => false,
        }
    }
}

/// The reintersection rows (every rule) of the outside routine `method` on the surface `name`
/// (`sphere`, `triangle` or `hinge`; empty for another), in precision `prec`; the routine's
/// first failure is the error.
pub fn outside_rows(
    name: &str,
    seed: u64,
    per_scale: u64,
    prec: Precision,
    method: &dyn Method,
) -> Result<Vec<ReintersectRow>, String> {
    let kind = match name {
        "sphere" => Kind::Sphere(SphereR),
        "triangle" => Kind::Tri(TriR { hinge: false }),
        "hinge" => Kind::Tri(TriR { hinge: true }),
        _ => return Ok(vec![]),
    };
    let k = Outside {
        kind,
        method,
        prec,
        answers: Mutex::new(HashMap::new()),
        asked: Mutex::new(vec![]),
    };
    // Primary rays, then spawned rays, then the rows with every answer known
    let mut rows = super::rows(&k, seed, per_scale, prec);
    let mut passes = 1;
    while k.answer_asked()? {
        rows = super::rows(&k, seed, per_scale, prec);
        passes += 1;
        if passes > 3 {
            return Err(format!(
                "{}: the reintersection test kept asking new rays after three passes (a bug: please report it)",
                method.name()
            ));
        }
    }
    for r in &mut rows {
        r.method = method.name().to_string();
    }
    Ok(rows)
}
