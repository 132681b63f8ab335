//! A batched ray–sphere kernel: structure of arrays, branch-free lanes, auto-vectorised.
//!
//! [`SphereBatch`] keeps the ten inputs of many tests as ten columns (`ox, oy, oz, dx, dy, dz,
//! cx, cy, cz, r`). A kernel runs one branch-free lane function per element in a plain loop
//! over the columns, which the compiler vectorises: every step of the method is computed for
//! every element and the early exits of the scalar methods become masks (`select`). Written
//! once over [`Real`], instantiated for `f32` and `f64`.
//!
//! **Same answers as the scalar methods, bit for bit.** [`geometric_lanes`] and [`rtg7_lanes`]
//! perform the same IEEE operations in the same order as [`methods::geometric`] and
//! [`methods::rtg7`] (no reassociation; Rust never contracts `a*b + c` into an FMA, even where
//! the kernel is compiled with FMA), so each element gets the same hit/miss verdict and the same
//! bits of `t`, also on invalid input (NaN, infinities, zero direction, radius ≤ 0).
//! [`GeometricFma`] is the FMA variant, a method of its own ([`methods::geometric_fma`], audited
//! like the others): its `a·b + c` are explicit fused multiply-adds, one rounding each, in the
//! scalar method and in the lanes alike, so it too is bit-identical to its scalar form (with
//! hardware FMA in the AVX2 and AVX-512 kernels, through the C library's `fma` elsewhere).
//! [`Certified`]'s lanes run its first look, whose certain answers are the correctly rounded `t`
//! (unique, so equal to the scalar method's); [`BatchMethod::finish`] gathers the tests it
//! leaves open into a second, smaller batch in `f64` and runs its second look there on lanes
//! ([`SecondLook`]: Newton steps with exact products by FMA), and only what that cannot prove
//! goes to the scalar method's later tiers. The tests check all of this on every case class
//! and on random bit patterns, and the second pass alone, run on every test, claims nothing
//! but the scalar method's answers.
//!
//! **Keeping the loops vectorised.** The compiler vectorises only a kernel's innermost loop
//! with everything in it inlined: a lane function has no loops of its own (steps are written
//! out) and no array `map` (not always inlined into a large function).
//!
//! **Output.** One value per test: the hit's `t`, or **NaN for a miss**. NaN is never a hit of
//! either scalar method (both require `t > 0`), while `geometric` can return a hit at `t = +∞`
//! on overflow, so NaN, not `+∞`, is the unambiguous miss marker ([`to_output`]).
//!
//! **Instruction sets.** The portable path is whatever the build targets (SSE2 on baseline
//! x86_64: 4 `f32` or 2 `f64` lanes per instruction). On x86_64 an AVX2 copy of the same code
//! (8 `f32` / 4 `f64` lanes) and an AVX-512 copy (F, VL, DQ: 16 `f32` / 8 `f64` lanes on `zmm`
//! registers, compares into mask registers `k`), both compiled with FMA, are chosen at run time
//! when the CPU has them ([`Isa::best`]; a CPU with AVX2 but without FMA gets the portable
//! path). FMA changes nothing in a method that does not ask for it. The assembly of the test
//! and bench binaries (`objdump -d`, rustc 1.95, release) shows the main loops vectorised, with
//! a scalar remainder loop for the last few elements:
//! - SSE2 path: `sqrtps`/`sqrtpd`, `divps`/`divpd`, `mulps`/`subps`/`addps`, the masks from
//!   `cmpltps`, `cmpleps`, `cmpneqps`, `cmpnltps`, `cmpordps` (and their `pd` forms), and the
//!   selects as `andps`/`andnps`/`orps` (SSE2 has no blend);
//! - AVX2 path: the VEX forms on `ymm` registers (`vsqrtps %ymm`, `vdivps %ymm`, `vcmpltps`,
//!   `vcmpneq_oqps`, …) with `vblendvps`/`vblendvpd` as the selects;
//! - AVX-512 path: the EVEX forms on `zmm` registers (`vsqrtps`, `vdivps`, `vcmpltps` into
//!   `k` masks, `korw`, `kmovw`);
//! - `vfmadd*` only in the `geometric_fma` kernels and in [`SecondLook`]'s (its exact products)
//!   of the AVX2 and AVX-512 paths.
//!
//! [`methods::geometric`]: super::methods::geometric
//! [`methods::geometric_fma`]: super::methods::geometric_fma
//! [`methods::rtg7`]: super::methods::rtg7

use super::cases::{generate, Class};
use super::certified;
use super::methods::{self, Ray, Sphere, SphereHit};
use super::oracle::Case;
use crate::numerics::real::Real;
use crate::numerics::timing::{self, Timing};
use serde::Serialize;

/// Ten columns, one element per ray–sphere test.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SphereBatch<F> {
    ox: Vec<F>,
    oy: Vec<F>,
    oz: Vec<F>,
    dx: Vec<F>,
    dy: Vec<F>,
    dz: Vec<F>,
    cx: Vec<F>,
    cy: Vec<F>,
    cz: Vec<F>,
    r: Vec<F>,
}

impl<F: Real> SphereBatch<F> {
    /// An empty batch.
    pub fn new() -> Self {
        SphereBatch {
            ox: vec![],
            oy: vec![],
            oz: vec![],
            dx: vec![],
            dy: vec![],
            dz: vec![],
            cx: vec![],
            cy: vec![],
            cz: vec![],
            r: vec![],
        }
    }

    /// Number of tests.
    pub fn len(&self) -> usize {
        self.r.len()
    }

    /// No tests.
    pub fn is_empty(&self) -> bool {
        self.r.is_empty()
    }

    /// Appends one test given as its ten scalars (o, d, c, r).
    pub fn push_scalars(&mut self, s: [F; 10]) {
        let cols = [
            &mut self.ox,
            &mut self.oy,
            &mut self.oz,
            &mut self.dx,
            &mut self.dy,
            &mut self.dz,
            &mut self.cx,
            &mut self.cy,
            &mut self.cz,
            &mut self.r,
        ];
        for (col, x) in cols.into_iter().zip(s) {
            col.push(x);
        }
    }

    /// Appends one test.
    pub fn push(&mut self, ray: &Ray<F>, sphere: &Sphere<F>) {
        let ([ox, oy, oz], [dx, dy, dz]) = (F::unvec3(ray.origin), F::unvec3(ray.dir));
        let [cx, cy, cz] = F::unvec3(sphere.center);
        self.push_scalars([ox, oy, oz, dx, dy, dz, cx, cy, cz, sphere.radius]);
    }

    /// Appends an audit case.
    pub fn push_case(&mut self, c: &Case<F>) {
        self.push_scalars(c.scalars());
    }

    /// A batch of audit cases, in order.
    pub fn from_cases<'a>(cases: impl IntoIterator<Item = &'a Case<F>>) -> Self {
        let mut b = SphereBatch::new();
        for c in cases {
            b.push_case(c);
        }
        b
    }

    /// Tests `idx` (each `< len`) in `f64`, exactly, column by column.
    pub fn gather_f64(&self, idx: &[usize]) -> SphereBatch<f64> {
        let col = |v: &[F]| idx.iter().map(|&i| v[i].to_f64()).collect();
        SphereBatch {
            ox: col(&self.ox),
            oy: col(&self.oy),
            oz: col(&self.oz),
            dx: col(&self.dx),
            dy: col(&self.dy),
            dz: col(&self.dz),
            cx: col(&self.cx),
            cy: col(&self.cy),
            cz: col(&self.cz),
            r: col(&self.r),
        }
    }

    /// Test `i` as an audit case (for replay lines), if it exists.
    pub fn case(&self, i: usize) -> Option<Case<F>> {
        (i < self.len()).then(|| {
            Case::from_scalars([
                self.ox[i], self.oy[i], self.oz[i], self.dx[i], self.dy[i], self.dz[i], self.cx[i],
                self.cy[i], self.cz[i], self.r[i],
            ])
        })
    }
}

/// The scalar answer in the batch's output convention: `t` for a hit, NaN for a miss.
#[inline(always)]
pub fn to_output<F: Real>(hit: Option<SphereHit<F>>) -> F {
    match hit {
        Some(h) => h.t,
        None => F::NAN,
    }
}

// ---- the lanes: the scalar methods with masks instead of early exits ----

type V<F> = [F; 3];

// The vector helpers of `methods`, so the lanes associate exactly as the scalar methods do
use super::methods::{dot, dot_c, madd, sub};

/// [`methods::geometric`] (or with `FMA`, [`methods::geometric_fma`]) for one element,
/// branch-free; `t` or NaN for a miss.
///
/// [`methods::geometric`]: super::methods::geometric
/// [`methods::geometric_fma`]: super::methods::geometric_fma
#[inline(always)]
pub fn geometric_lanes<F: Real, const FMA: bool>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
    // (1) Origin relative to the sphere
    let roc = sub(c, o);
    let loc = dot_c::<F, FMA>(roc, roc);
    let r2 = r * r;
    let outside = loc > r2;
    // (2) Distance along the ray to the point nearest the centre
    let d_min = dot_c::<F, FMA>(roc, d);
    // (3) Squared half chord
    let dhc2 = madd::<F, FMA>(d_min, d_min, r2 - loc);
    // (4) Both candidate roots, then the one the scalar method would take
    let s = dhc2.sqrt();
    let (near, far) = (d_min - s, d_min + s);
    let t = if outside { near } else { far };
    // Masks for the scalar method's three exits (non-short-circuit `&`, `|`)
    let miss = (outside & ((d_min < F::ZERO) | (dhc2 < F::ZERO))) | t.is_nan() | (t <= F::ZERO);
    if miss {
        F::NAN
    } else {
        t
    }
}

/// [`methods::rtg7`] for one element, branch-free; `t` or NaN for a miss.
///
/// [`methods::rtg7`]: super::methods::rtg7
#[inline(always)]
pub fn rtg7_lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
    // Quadratic a t² + 2b' t + c with b' = f·d
    let f = sub(o, c);
    let a = dot(d, d);
    let b = dot(f, d);
    let cc = dot(f, f) - r * r;
    // Discriminant from the perpendicular vector
    let len = a.sqrt();
    let dh = [d[0] / len, d[1] / len, d[2] / len];
    let k = dot(f, dh);
    let fd = sub(f, [dh[0] * k, dh[1] * k, dh[2] * k]);
    let disc = a * (r * r - dot(fd, fd));
    // Stable pair q/a, c/q, ordered, nearest positive
    let q = -b - disc.sqrt().copysign(b);
    let (t0, t1) = (cc / q, q / a);
    let ordered = t0 <= t1;
    let (lo, hi) = (if ordered { t0 } else { t1 }, if ordered { t1 } else { t0 });
    let t = if lo > F::ZERO { lo } else { hi };
    // Masks for the scalar method's exits: radius, discriminant, q and a, no positive root,
    // non-finite t
    let ok = (r > F::ZERO)
        & (disc >= F::ZERO)
        & (q != F::ZERO)
        & (a > F::ZERO)
        & ((lo > F::ZERO) | (hi > F::ZERO))
        & t.is_finite();
    if ok {
        t
    } else {
        F::NAN
    }
}

/// A lane's vector in `f64` (exactly). Indexed, not an array `map`: that one is not always
/// inlined into a large lane function, and the kernel's loop then stays scalar.
#[inline(always)]
fn w<F: Real>(v: V<F>) -> [f64; 3] {
    [v[0].to_f64(), v[1].to_f64(), v[2].to_f64()]
}

/// A lane function: one test on lane values, branch-free, so the kernel's loop vectorises.
pub trait Lanes {
    /// One test on lane values: `t`, or NaN for a miss (or a method's own mark for a test
    /// that [`BatchMethod::finish`] completes).
    fn lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F;
}

/// A method with a scalar form (in [`methods`]) and a lane form (here).
pub trait BatchMethod: Lanes {
    /// The method's name, as in [`methods::METHODS`].
    const NAME: &'static str;
    /// The scalar method of the same name.
    fn scalar<F: Real>(ray: &Ray<F>, sphere: &Sphere<F>) -> Option<SphereHit<F>>;
    /// After the vectorised pass with `isa`: completes the tests the lanes left open (none by
    /// default).
    #[inline(always)]
    fn finish<F: Real>(_isa: Isa, _b: &SphereBatch<F>, _out: &mut [F]) {}
}

/// The correctly rounded method ([`methods::certified`]) in two vectorised passes and a scalar
/// one: the lanes run its first look ([`certified::first_look_lane`] for `f32` inputs; for
/// `f64` inputs only its certain misses, [`certified::first_look_lane_f64`]); the tests it
/// leaves [`certified::UNSURE`] are gathered (in `f64`, exactly) and given its second look on
/// lanes ([`SecondLook`]); what that cannot prove is finished by the scalar method's later
/// phases. Every answer is the unique correctly rounded root (or a certain miss), so it is the
/// scalar method's, bit for bit.
pub struct Certified;

impl Lanes for Certified {
    #[inline(always)]
    fn lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
        F::from_f64(if F::MANT_BITS == 24 {
            certified::first_look_lane(w(o), w(d), w(c), r.to_f64(), certified::Terms::PROVED)
        } else {
            certified::first_look_lane_f64(w(o), w(d), w(c), r.to_f64())
        })
    }
}

impl BatchMethod for Certified {
    const NAME: &'static str = "certified";
    #[inline(always)]
    fn scalar<F: Real>(ray: &Ray<F>, sphere: &Sphere<F>) -> Option<SphereHit<F>> {
        methods::certified(ray, sphere)
    }
    fn finish<F: Real>(isa: Isa, b: &SphereBatch<F>, out: &mut [F]) {
        // The open tests, gathered in f64
        let open_mark = F::from_f64(certified::UNSURE);
        let n = out.len().min(b.len());
        let mut open = vec![];
        // (16 at a time, a vectorised test first: most chunks have none)
        for (k, chunk) in out[..n].chunks(16).enumerate() {
            if chunk.iter().fold(false, |any, &x| any | (x == open_mark)) {
                let first = 16 * k;
                open.extend((first..first + chunk.len()).filter(|&i| out[i] == open_mark));
            }
        }
        if open.is_empty() {
            return;
        }
        let sub = b.gather_f64(&open);
        // The second look on lanes, rounding to the inputs' precision
        let mut t = vec![0.0; sub.len()];
        let _ = if F::MANT_BITS == 24 {
            run_lanes::<SecondLook<true>, f64>(isa, &sub, &mut t)
        } else {
            run_lanes::<SecondLook<false>, f64>(isa, &sub, &mut t)
        };
        // Its answers back in place; what it left open, through the scalar method (its first
        // look again, then the tiers after the second look)
        for (&i, &t) in open.iter().zip(&t) {
            out[i] = if t == certified::UNSURE {
                b.case(i).map_or(F::NAN, |case| {
                    to_output(Certified::scalar(&case.ray(), &case.sphere()))
                })
            } else {
                F::from_f64(t)
            };
        }
    }
}

/// [`certified::floors`] on lanes: the part of `certified` that every answer computes, without
/// its certificate (not a method: a measuring stick, timed beside it in `benches/batch.rs`).
pub struct CertifiedFloor;

impl Lanes for CertifiedFloor {
    #[inline(always)]
    fn lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
        let f32 = F::MANT_BITS == 24;
        F::from_f64(certified::floors::floor_lane::<true>(
            w(o),
            w(d),
            w(c),
            r.to_f64(),
            f32,
        ))
    }
}

impl BatchMethod for CertifiedFloor {
    const NAME: &'static str = "certified_floor";
    #[inline(always)]
    fn scalar<F: Real>(ray: &Ray<F>, sphere: &Sphere<F>) -> Option<SphereHit<F>> {
        certified::floors::floor(ray, sphere)
    }
}

/// [`methods::certified`]'s second look on lanes ([`certified::second_look_lane`], two Newton
/// steps), for tests of `f32` inputs (`F32`) or of `f64` inputs, given in `f64`: the correctly
/// rounded `t`, or [`certified::UNSURE`].
///
/// [`methods::certified`]: super::methods::certified
pub struct SecondLook<const F32: bool>;

impl<const F32: bool> Lanes for SecondLook<F32> {
    #[inline(always)]
    fn lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
        F::from_f64(certified::second_look_lane::<F32>(
            w(o),
            w(d),
            w(c),
            r.to_f64(),
        ))
    }
}

/// Seed `000` §2's four-step method ([`methods::geometric`]).
pub struct Geometric;
/// The robust Ray Tracing Gems method ([`methods::rtg7`]).
pub struct Rtg7;

impl BatchMethod for Geometric {
    const NAME: &'static str = "geometric";
    #[inline(always)]
    fn scalar<F: Real>(ray: &Ray<F>, sphere: &Sphere<F>) -> Option<SphereHit<F>> {
        methods::geometric(ray, sphere)
    }
}

impl Lanes for Geometric {
    #[inline(always)]
    fn lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
        geometric_lanes::<F, false>(o, d, c, r)
    }
}

/// [`methods::geometric_fma`]: the same steps with every `a·b + c` fused, as a contracting
/// compiler builds them; the AVX2 and AVX-512 kernels run it with `vfmadd`.
///
/// [`methods::geometric_fma`]: super::methods::geometric_fma
pub struct GeometricFma;

impl BatchMethod for GeometricFma {
    const NAME: &'static str = "geometric_fma";
    #[inline(always)]
    fn scalar<F: Real>(ray: &Ray<F>, sphere: &Sphere<F>) -> Option<SphereHit<F>> {
        methods::geometric_fma(ray, sphere)
    }
}

impl Lanes for GeometricFma {
    #[inline(always)]
    fn lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
        geometric_lanes::<F, true>(o, d, c, r)
    }
}

impl BatchMethod for Rtg7 {
    const NAME: &'static str = "rtg7";
    #[inline(always)]
    fn scalar<F: Real>(ray: &Ray<F>, sphere: &Sphere<F>) -> Option<SphereHit<F>> {
        methods::rtg7(ray, sphere)
    }
}

impl Lanes for Rtg7 {
    #[inline(always)]
    fn lanes<F: Real>(o: V<F>, d: V<F>, c: V<F>, r: F) -> F {
        rtg7_lanes(o, d, c, r)
    }
}

// ---- the kernels ----

/// `out` and the batch differ in length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("a batch of {batch} tests but room for {output} answers")]
pub struct LengthMismatch {
    /// Tests in the batch.
    pub batch: usize,
    /// Room for answers.
    pub output: usize,
}

/// The instruction set a kernel runs with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Isa {
    /// What the build targets (SSE2 on baseline x86_64).
    Portable,
    /// x86_64 with AVX2 and FMA, chosen at run time.
    Avx2,
    /// x86_64 with AVX-512 (F, VL, DQ; 512-bit registers) and FMA, chosen at run time.
    Avx512,
}

impl Isa {
    /// `sse2` (or `portable` off x86_64), `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable if cfg!(target_arch = "x86_64") => "sse2",
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// Whether this machine can run it, under the cap of `RAYPROOF_ISA`
    /// ([`crate::numerics::cpu`]).
    pub fn available(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::Avx2 => crate::numerics::cpu::avx2(),
            Isa::Avx512 => crate::numerics::cpu::avx512(),
        }
    }

    /// Every instruction set this machine can run, portable first.
    pub fn all_available() -> Vec<Isa> {
        [Isa::Portable, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .filter(|i| i.available())
            .collect()
    }

    /// The widest available.
    pub fn best() -> Isa {
        if Isa::Avx512.available() {
            Isa::Avx512
        } else if Isa::Avx2.available() {
            Isa::Avx2
        } else {
            Isa::Portable
        }
    }
}

/// The loop every kernel is: one lane function per element over the columns, re-sliced to
/// one length so that the bounds checks leave the loop and it vectorises.
#[inline(always)]
fn kernel<M: Lanes, F: Real>(b: &SphereBatch<F>, out: &mut [F]) {
    let n = out.len().min(b.len());
    let (out, ox, oy, oz) = (&mut out[..n], &b.ox[..n], &b.oy[..n], &b.oz[..n]);
    let (dx, dy, dz) = (&b.dx[..n], &b.dy[..n], &b.dz[..n]);
    let (cx, cy, cz, r) = (&b.cx[..n], &b.cy[..n], &b.cz[..n], &b.r[..n]);
    for i in 0..n {
        out[i] = M::lanes(
            [ox[i], oy[i], oz[i]],
            [dx[i], dy[i], dz[i]],
            [cx[i], cy[i], cz[i]],
            r[i],
        );
    }
}

#[inline(never)]
fn kernel_portable<M: Lanes, F: Real>(b: &SphereBatch<F>, out: &mut [F]) {
    kernel::<M, F>(b, out)
}

/// The same loop compiled for AVX2 and FMA. Rust never contracts `a*b + c`, so only the
/// methods that ask for a fused multiply-add (`mul_add`) get one; the others round as before.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn kernel_avx2<M: Lanes, F: Real>(b: &SphereBatch<F>, out: &mut [F]) {
    kernel::<M, F>(b, out)
}

/// The same loop compiled for AVX-512 and FMA: 16 `f32` or 8 `f64` lanes per instruction; as
/// for AVX2, only the methods that ask for a fused multiply-add get one.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,fma")]
#[inline(never)]
fn kernel_avx512<M: Lanes, F: Real>(b: &SphereBatch<F>, out: &mut [F]) {
    kernel::<M, F>(b, out)
}

/// Runs method `M` over the batch with `isa` (falling back to the portable path if this
/// machine lacks it): `out[i]` is test `i`'s `t`, or NaN for a miss.
pub fn run_batch<M: BatchMethod, F: Real>(
    isa: Isa,
    b: &SphereBatch<F>,
    out: &mut [F],
) -> Result<(), LengthMismatch> {
    run_lanes::<M, F>(isa, b, out)?;
    M::finish(isa, b, out);
    Ok(())
}

/// The vectorised pass alone: lane function `L` over the batch with `isa` (or the portable
/// path if this machine lacks it).
pub fn run_lanes<L: Lanes, F: Real>(
    isa: Isa,
    b: &SphereBatch<F>,
    out: &mut [F],
) -> Result<(), LengthMismatch> {
    if out.len() != b.len() {
        return Err(LengthMismatch {
            batch: b.len(),
            output: out.len(),
        });
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 if isa.available() => {
            // SAFETY: the CPU was just checked to support AVX2
            unsafe { kernel_avx2::<L, F>(b, out) }
        }
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 if isa.available() => {
            // SAFETY: the CPU was just checked to support AVX-512 F, VL and DQ
            unsafe { kernel_avx512::<L, F>(b, out) }
        }
        _ => kernel_portable::<L, F>(b, out),
    }
    Ok(())
}

/// [`methods::geometric`] over a batch with the best instruction set: `t`, or NaN for a miss.
///
/// [`methods::geometric`]: super::methods::geometric
pub fn geometric_batch<F: Real>(b: &SphereBatch<F>, out: &mut [F]) -> Result<(), LengthMismatch> {
    run_batch::<Geometric, F>(Isa::best(), b, out)
}

/// [`methods::rtg7`] over a batch with the best instruction set: `t`, or NaN for a miss.
///
/// [`methods::rtg7`]: super::methods::rtg7
pub fn rtg7_batch<F: Real>(b: &SphereBatch<F>, out: &mut [F]) -> Result<(), LengthMismatch> {
    run_batch::<Rtg7, F>(Isa::best(), b, out)
}

/// [`methods::certified`] over a batch with the best instruction set: the correctly rounded
/// `t`, or NaN for a miss.
///
/// [`methods::certified`]: super::methods::certified
pub fn certified_batch<F: Real>(b: &SphereBatch<F>, out: &mut [F]) -> Result<(), LengthMismatch> {
    run_batch::<Certified, F>(Isa::best(), b, out)
}

/// The scalar method over the same tests, in the batch's output convention (the baseline the
/// batch is timed against; the method is called directly, so it may be inlined).
pub fn run_scalar<M: BatchMethod, F: Real>(
    rays: &[Ray<F>],
    spheres: &[Sphere<F>],
    out: &mut [F],
) -> Result<(), LengthMismatch> {
    if rays.len() != out.len() || spheres.len() != out.len() {
        return Err(LengthMismatch {
            batch: rays.len().min(spheres.len()),
            output: out.len(),
        });
    }
    for ((o, ray), sphere) in out.iter_mut().zip(rays).zip(spheres) {
        *o = to_output(M::scalar(ray, sphere));
    }
    Ok(())
}

/// The first test where the batch and the scalar method disagree: its index and inputs as a
/// replay line, with both answers as hex floats.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{method}/{precision} {isa}: test {index}: scalar {scalar}, batched {batched}\n  replay: rayproof probe sphere {replay}")]
pub struct Mismatch {
    /// The method's name.
    pub method: &'static str,
    /// `"f32"` or `"f64"`.
    pub precision: &'static str,
    /// The kernel's instruction set.
    pub isa: &'static str,
    /// Index of the test in the batch.
    pub index: usize,
    /// The scalar method's answer, as a hex float (or `miss`).
    pub scalar: String,
    /// The batch kernel's answer, as a hex float (or `miss`).
    pub batched: String,
    /// The `rayproof probe` arguments that replay the test.
    pub replay: String,
}

/// Checks that method `M` with `isa` gives the scalar method's answers bit for bit on every
/// test of the batch (NaN for NaN: a miss for a miss).
pub fn check_identical<M: BatchMethod, F: Real>(
    isa: Isa,
    b: &SphereBatch<F>,
) -> Result<(), Box<Mismatch>> {
    let mut out = vec![F::ZERO; b.len()];
    // Lengths match by construction
    let _ = run_batch::<M, F>(isa, b, &mut out);
    for (i, &got) in out.iter().enumerate() {
        let Some(case) = b.case(i) else { break };
        let want = to_output(M::scalar(&case.ray(), &case.sphere()));
        if got.to_bits_u64() != want.to_bits_u64() {
            return Err(Box::new(Mismatch {
                method: M::NAME,
                precision: F::NAME,
                isa: isa.name(),
                index: i,
                scalar: want.hex(),
                batched: got.hex(),
                replay: case.probe_args(),
            }));
        }
    }
    Ok(())
}

// ---- throughput ----

/// The classes of the timed mix: those of `benches/sphere.rs`'s `sphere/mix` batch.
pub const MIX: [Class; 6] = [
    Class::Random,
    Class::Inside,
    Class::FarSmall,
    Class::Huge,
    Class::Grazing,
    Class::Behind,
];

/// `per_class` cases of each [`MIX`] class under `seed` (class by class; a case the generator
/// gave up on is skipped).
pub fn mix_cases<F: Real>(seed: u64, per_class: u64) -> Vec<Case<F>> {
    MIX.into_iter()
        .flat_map(|class| (0..per_class).filter_map(move |i| generate::<F>(seed, class, i)))
        .collect()
}

/// How the throughput table is measured.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BatchOpts {
    /// Seed of the cases.
    pub seed: u64,
    /// Cases per [`MIX`] class.
    pub per_class: u64,
    /// Timed runs per row.
    pub runs: usize,
    /// Minimum duration of one timed run, in nanoseconds.
    pub min_ns: f64,
}

impl BatchOpts {
    /// 512 cases of each mix class under seed 7 (the `sphere/mix` batch), 15 runs.
    pub fn report() -> Self {
        BatchOpts {
            seed: 7,
            per_class: 512,
            runs: 15,
            min_ns: 2e6,
        }
    }
}

/// One row: a method in one precision, scalar vs batched with one instruction set.
#[derive(Clone, Debug, Serialize)]
pub struct BatchRow {
    /// The method's name.
    pub method: &'static str,
    /// `"f32"` or `"f64"`.
    pub precision: &'static str,
    /// The kernel's instruction set.
    pub isa: &'static str,
    /// Tests in the timed batch.
    pub tests: usize,
    /// Nanoseconds per test, scalar method over the same tests.
    pub scalar: Timing,
    /// Nanoseconds per test, batched.
    pub batched: Timing,
    /// `scalar.median / batched.median`: how many times faster the batch is.
    pub speedup: f64,
}

/// Scalar vs batched throughput for `geometric`, `geometric_fma`, `rtg7` and `certified`, `f32` and `f64`, every available
/// instruction set, on the mix batch. Bit-identity is checked before anything is timed; a
/// mismatch is returned instead of a table.
pub fn throughput_table(opts: &BatchOpts) -> Result<Vec<BatchRow>, Box<Mismatch>> {
    let mut rows = rows_for::<f32>(opts)?;
    rows.extend(rows_for::<f64>(opts)?);
    Ok(rows)
}

fn rows_for<F: Real>(opts: &BatchOpts) -> Result<Vec<BatchRow>, Box<Mismatch>> {
    // The fixed batch, in both layouts
    let cases = mix_cases::<F>(opts.seed, opts.per_class);
    let b = SphereBatch::from_cases(&cases);
    let rays: Vec<Ray<F>> = cases.iter().map(|c| c.ray()).collect();
    let spheres: Vec<Sphere<F>> = cases.iter().map(|c| c.sphere()).collect();
    let mut rows = vec![];
    rows.extend(method_rows::<Geometric, F>(opts, &b, &rays, &spheres)?);
    rows.extend(method_rows::<GeometricFma, F>(opts, &b, &rays, &spheres)?);
    rows.extend(method_rows::<Rtg7, F>(opts, &b, &rays, &spheres)?);
    rows.extend(method_rows::<Certified, F>(opts, &b, &rays, &spheres)?);
    Ok(rows)
}

fn method_rows<M: BatchMethod, F: Real>(
    opts: &BatchOpts,
    b: &SphereBatch<F>,
    rays: &[Ray<F>],
    spheres: &[Sphere<F>],
) -> Result<Vec<BatchRow>, Box<Mismatch>> {
    let n = b.len();
    let mut out = vec![F::ZERO; n];
    // Validate, then time the scalar method once and each instruction set
    let isas = Isa::all_available();
    for &isa in &isas {
        check_identical::<M, F>(isa, b)?;
    }
    let scalar = timing::measure(n, opts.runs, opts.min_ns, || {
        let _ = run_scalar::<M, F>(
            std::hint::black_box(rays),
            std::hint::black_box(spheres),
            &mut out,
        );
        std::hint::black_box(&mut out);
    });
    Ok(isas
        .into_iter()
        .map(|isa| {
            let batched = timing::measure(n, opts.runs, opts.min_ns, || {
                let _ = run_batch::<M, F>(isa, std::hint::black_box(b), &mut out);
                std::hint::black_box(&mut out);
            });
            BatchRow {
                method: M::NAME,
                precision: F::NAME,
                isa: isa.name(),
                tests: n,
                speedup: scalar.median_ns / batched.median_ns,
                scalar: scalar.clone(),
                batched,
            }
        })
        .collect())
}
