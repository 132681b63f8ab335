//! LDR-ꟻLIP of two 8-bit sRGB images, computed as NVIDIA's C++ computes it and several times
//! faster.
//!
//! The reference is `FLIP::image<float>::FLIP` of NVlabs/flip (`cpp/CPP/image.h`, as vendored in
//! nv-flip-sys 0.1.1 `extern/cpp/CPP/`): sRGB → YCxCz, the separated spatial filters (a Gaussian
//! each for Y and Cx, two for Cz), YCxCz → linear RGB clamped → CIELab with Hunt's adjustment,
//! HyAB, the feature filters (a Gaussian and its first and second derivatives on Y), and
//! `colour^(1 − feature)`. Every value is computed with the same f32 operations in the same
//! order (the filters' sums too), laid out so that it vectorises:
//! - planes instead of colour triples, each row padded with its edge pixels instead of a
//!   clamped index per tap, a block of 128 columns summed over all taps in registers, and the
//!   filters along y a strip of 512 columns at a time (the rows they read stay in cache), two
//!   output rows at once (each row read once for both; each sum still in the C++'s order);
//! - sRGB → linear through a 256-entry table (the input has 256 values per channel);
//! - the powers without a call: [`pow`] in f64, CIELab's cube roots by [`cbrt`] (Newton steps,
//!   no division), and the feature difference's (·)^½ as a square root. All are correctly
//!   rounded but for rare last-ulp cases, as glibc's `powf` is, so a power can differ from the
//!   C++'s by one ulp where either slips (for the cube root, on every f32 of its range: ours
//!   on 6, glibc's on 42,041 of 66 million).
//!
//! How far such a slip moves the map: the map is continuous, and Lipschitz except where two
//! filtered colours are nearly equal. There the colour difference d^0.7 has an infinite slope at
//! d = 0: a perturbation δ of the HyAB distance (an ulp or two of L ≤ 100: δ ≲ 3e-5) moves the
//! remapped colour error by at most δ^0.7 · 0.95 / (0.4 · cmax) = 3.9e-5 (cmax = 203.3^0.7 =
//! 41.3), and the final power `c^e`, e ∈ [0, 1], moves it no further than c itself moved.
//! `the_kernel_is_nv_flips` holds every pixel within 1e-4 of nv-flip's (measured: worst 6.9e-6,
//! 99.7 % of its 20,728 pixels bit for bit; on the images it had before a 700 × 23 pair was
//! added, worst 3.6e-6 and 99.6 %, as before the cube root and the paired rows).

/// ꟻLIP's constants (`sharedflip.h` `FLIPConstants`).
const GQC: f32 = 0.7;
const GPC: f32 = 0.4;
const GPT: f32 = 0.95;
const GW: f32 = 0.082;
const PI: f32 = 3.141_592_653_589_79;

/// D65 white and its inverse (`color.h` `DEFAULT_ILLUMINANT`, `INV_DEFAULT_ILLUMINANT`).
const WHITE: [f32; 3] = [0.950_428_545, 1.0, 1.088_900_371];
const INV_WHITE: [f32; 3] = [1.052_156_925, 1.0, 0.918_357_670];

#[inline(always)]
fn linear_to_xyz([r, g, b]: [f32; 3]) -> [f32; 3] {
    const A: [[f32; 3]; 3] = [
        [
            10135552.0 / 24577794.0,
            8788810.0 / 24577794.0,
            4435075.0 / 24577794.0,
        ],
        [
            2613072.0 / 12288897.0,
            8788810.0 / 12288897.0,
            887015.0 / 12288897.0,
        ],
        [
            1425312.0 / 73733382.0,
            8788810.0 / 73733382.0,
            70074185.0 / 73733382.0,
        ],
    ];
    // Written out (not `A.map`), so that a loop of them vectorises
    [
        A[0][0] * r + A[0][1] * g + A[0][2] * b,
        A[1][0] * r + A[1][1] * g + A[1][2] * b,
        A[2][0] * r + A[2][1] * g + A[2][2] * b,
    ]
}

#[inline(always)]
fn xyz_to_linear([x, y, z]: [f32; 3]) -> [f32; 3] {
    const A: [[f32; 3]; 3] = [
        [3.241_003_275, -1.537_398_934, -0.498_615_861],
        [-0.969_224_334, 1.875_930_071, 0.041_554_224],
        [0.055_639_423, -0.204_011_202, 1.057_148_933],
    ];
    [
        A[0][0] * x + A[0][1] * y + A[0][2] * z,
        A[1][0] * x + A[1][1] * y + A[1][2] * z,
        A[2][0] * x + A[2][1] * y + A[2][2] * z,
    ]
}

fn xyz_to_ycxcz(xyz: [f32; 3]) -> [f32; 3] {
    let [x, y, z] = [
        xyz[0] * INV_WHITE[0],
        xyz[1] * INV_WHITE[1],
        xyz[2] * INV_WHITE[2],
    ];
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

#[inline(always)]
fn ycxcz_to_xyz([yy, cx, cz]: [f32; 3]) -> [f32; 3] {
    let y = (yy + 16.0) / 116.0;
    let (cx, cz) = (cx / 500.0, cz / 200.0);
    [(y + cx) * WHITE[0], y * WHITE[1], (y - cz) * WHITE[2]]
}

#[inline(always)]
fn xyz_to_lab(xyz: [f32; 3]) -> [f32; 3] {
    let delta = 6.0f32 / 29.0;
    let delta_square = delta * delta;
    let delta_cube = delta * delta_square;
    let factor = 1.0 / (3.0 * delta_square);
    let term = 4.0f32 / 29.0;
    // Both sides computed and one kept: a select, not a branch
    let f = |v: f32| {
        let (root, line) = (cbrt(v), factor * v + term);
        if v > delta_cube {
            root
        } else {
            line
        }
    };
    let [x, y, z] = [
        f(xyz[0] * INV_WHITE[0]),
        f(xyz[1] * INV_WHITE[1]),
        f(xyz[2] * INV_WHITE[2]),
    ];
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

/// The C++ `Max` and `Min` macros (a NaN falls to the second argument).
#[inline(always)]
fn max(x: f32, y: f32) -> f32 {
    if x > y {
        x
    } else {
        y
    }
}

#[inline(always)]
fn min(x: f32, y: f32) -> f32 {
    if x > y {
        y
    } else {
        x
    }
}

#[inline(always)]
fn clamp01(v: f32) -> f32 {
    min(max(v, 0.0), 1.0)
}

/// `x^y` for x ≥ 0 finite and y ∈ [0, 1] (the only powers ꟻLIP takes), without a branch or a
/// call, so that a loop of them vectorises: 2^(y · log2 x) in f64, rounded once to f32.
///
/// Error analysis. x = 2^e · m with m ∈ [√½, √2) (exact, from the bits). With
/// t = (m − 1)/(m + 1), |t| ≤ 0.1716, log2 m = (2/ln 2)·(t + t³/3 + … + t¹⁵/15): the series
/// left out is below t¹⁷/17 ≤ 3.5e-14 · |t| relative, and m − 1 is exact (Sterbenz), so
/// L = e + log2 m carries a relative error of a few 1e-16 and z = y · L an absolute one below
/// 1e-13 (|L| ≤ 150). 2^z = 2^n · 2^f with n = round(z) and |f| ≤ ½: the Taylor series of
/// e^(f ln 2) to the 10th power leaves out less than 0.347¹¹/11! = 2.2e-13 relative. The f64
/// result is therefore within 5e-13 relative of xʸ, and its rounding to f32 is the correctly
/// rounded xʸ unless xʸ lies within 5e-13 relative of a midpoint between two f32s, where it can
/// be the other neighbour: one ulp at most, as glibc's `powf` (which the C++ calls, "< 1 ULP")
/// can be. x = 0 gives 0 (y > 0), 1 (y = 0) or ∞ (y < 0), as `powf`.
#[inline(always)]
fn pow(x: f32, y: f32) -> f32 {
    const SQRT2: f64 = std::f64::consts::SQRT_2;
    const LOG2E2: f64 = 2.0 * std::f64::consts::LOG2_E;
    const LN2: f64 = std::f64::consts::LN_2;
    const ROUND: f64 = 6_755_399_441_055_744.0; // 1.5 · 2⁵², adding it rounds to an integer
    let (x, y) = (x as f64, y as f64);
    let bits = x.to_bits();
    let e0 = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let m0 = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    let big = m0 > SQRT2;
    let m = if big { m0 * 0.5 } else { m0 };
    let e = (if big { e0 + 1 } else { e0 }) as f64;
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let mut s = 1.0 / 15.0;
    for k in [13.0, 11.0, 9.0, 7.0, 5.0, 3.0, 1.0] {
        s = s * t2 + 1.0 / k;
    }
    let z = y * (e + LOG2E2 * t * s);
    let n = (z + ROUND) - ROUND;
    let a = (z - n) * LN2;
    let mut p = 1.0;
    for k in [10.0, 9.0, 8.0, 7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0] {
        p = 1.0 + a * (1.0 / k) * p;
    }
    let r = f64::from_bits(p.to_bits().wrapping_add(((n as i64) << 52) as u64)) as f32;
    match x == 0.0 {
        true if y == 0.0 => 1.0,
        true if y < 0.0 => f32::INFINITY,
        true => 0.0,
        false => r,
    }
}

/// `powf(x, 1.0f / 3.0f)` for x ∈ (0.0088, 2) (CIELab's cube root above (6/29)³; the C++ takes
/// the power of the f32 nearest ⅓, c = ⅓ + δ with δ = ⅓ · 2⁻²⁵), without a division, a
/// branch or a call, so that a loop of them vectorises; what it gives outside that range is
/// finite or not, but kept by no caller.
///
/// Error analysis. A seed r₀ ≈ x^(−⅓) from the bits (relative error ≤ 3.5 %: the magic
/// constant minimises it), then three Newton steps r ← r·(4/3 − (x/3)·r³) in f32, which
/// leave h = 1 − x·r³ with |h| ≤ 6.2e-7 (measured on every f32 of the range). Then in f64,
/// where r², x·r² and x·r³ are exact or within 2⁻⁵³ relative and h = 1 − x·r³ is exact
/// (Sterbenz): x^⅓ = x·r²·(1 − h)^(−⅔) = x·r²·(1 + ⅔h + 5/9·h² + O(h³)), the h³ term below
/// 1.2e-19; and x^δ = 1 + δ·ln x + O((δ ln x)²) with |δ ln x| ≤ 4.8e-8 (the square term below
/// 1.2e-15), ln x from the exponent and a degree-6 polynomial in the mantissa (error ≤ 3.5e-6,
/// times δ: 3.5e-14), computed in f32 (its rounding, ≤ 1e-6 absolute, times δ: 1e-14). The
/// product's cross term ⅔h·δ ln x, left out, is below 2e-14. The f64 value is within 7e-14
/// relative of x^c, so its rounding to f32 is the correctly rounded x^c unless x^c lies that
/// close to a midpoint between two f32s; then it is one ulp off. Of the 66 million f32s in
/// ((6/29)³, 2), 6 results are not the correctly rounded one, where glibc's `powf` (which the
/// C++ calls) misses it on 42,041 (`cube_root_is_powf`); up to 1.01, 5 (the f64 [`pow`] with
/// exponent ⅓: 13).
#[inline(always)]
fn cbrt(x: f32) -> f32 {
    // ln(1 + u) on [0, 1), Chebyshev fit of degree 6
    const C: [f32; 7] = [
        3.511_021_4e-6,
        0.999_792_36,
        -0.496_977_43,
        0.314_589_17,
        -0.188_780_82,
        0.081_725_645,
        -0.017_207_8,
    ];
    const DELTA: f32 = ((1.0f32 / 3.0) as f64 - 1.0 / 3.0) as f32;
    let i = x.to_bits();
    let mut r = f32::from_bits(0x54a2_32a0u32.wrapping_sub(i / 3));
    let x3 = x * (1.0 / 3.0);
    for _ in 0..3 {
        r = r * (4.0 / 3.0 - x3 * (r * r * r));
    }
    let e = ((i >> 23) as i32 - 127) as f32;
    let u = f32::from_bits((i & 0x007f_ffff) | 0x3f80_0000) - 1.0;
    let mut p = C[6];
    for k in (0..6).rev() {
        p = p * u + C[k];
    }
    let d = DELTA * (e * std::f32::consts::LN_2 + p);
    let (x, r) = (x as f64, r as f64);
    let xr2 = x * (r * r);
    let h = 1.0 - xr2 * r;
    (xr2 + xr2 * (h * (2.0 / 3.0 + h * (5.0 / 9.0)) + d as f64)) as f32
}

/// [`lab_hunt`] of a row's Y, Cx and Cz, into three rows.
#[inline(always)]
fn lab_rows(y: &[f32], cx: &[f32], cz: &[f32], out: &mut [Vec<f32>; 3]) {
    let n = y.len();
    let (cx, cz) = (&cx[..n], &cz[..n]);
    let [l, a, b] = out;
    let (l, a, b) = (&mut l[..n], &mut a[..n], &mut b[..n]);
    for x in 0..n {
        [l[x], a[x], b[x]] = lab_hunt([y[x], cx[x], cz[x]]);
    }
}

/// CIELab with Hunt's adjustment of a and b.
#[inline(always)]
fn lab_hunt(ycxcz: [f32; 3]) -> [f32; 3] {
    let [r, g, b] = xyz_to_linear(ycxcz_to_xyz(ycxcz));
    let rgb = [clamp01(r), clamp01(g), clamp01(b)];
    let [l, a, b] = xyz_to_lab(linear_to_xyz(rgb));
    [l, 0.01 * l * a, 0.01 * l * b]
}

#[inline(always)]
fn hyab(r: [f32; 3], t: [f32; 3]) -> f32 {
    (r[0] - t[0]).abs() + ((r[1] - t[1]) * (r[1] - t[1]) + (r[2] - t[2]) * (r[2] - t[2])).sqrt()
}

fn gaussian(x2: f32, a: f32, b: f32) -> f32 {
    a * (PI / b).sqrt() * (-(PI * PI) * x2 / b).exp()
}

fn gaussian_sqrt(x2: f32, a: f32, b: f32) -> f32 {
    (a * (PI / b).sqrt()).sqrt() * (-(PI * PI) * x2 / b).exp()
}

/// The four separated spatial filters: Y, Cx, and the two halves of Cz's sum of Gaussians
/// (`setSpatialFilters`, radius from `calculateSpatialFilterRadius`).
fn spatial_filters(ppd: f32) -> [Vec<f32>; 4] {
    let max_b = 0.04f32; // the largest of the Gaussians' scale parameters
    let radius = (3.0 * (max_b / (2.0 * (PI * PI))).sqrt() * ppd).ceil() as i32;
    let dx = 1.0 / ppd;
    let mut f: [Vec<f32>; 4] = Default::default();
    for x in 0..2 * radius + 1 {
        let ix = (x - radius) as f32 * dx;
        let ix2 = ix * ix;
        f[0].push(gaussian(ix2, 1.0, 0.0047));
        f[1].push(gaussian(ix2, 1.0, 0.0053));
        f[2].push(gaussian_sqrt(ix2, 34.1, 0.04));
        f[3].push(gaussian_sqrt(ix2, 13.5, 0.025));
    }
    let sum = |v: &[f32]| v.iter().fold(0f32, |s, &x| s + x);
    let (sy, scx, sz1, sz2) = (sum(&f[0]), sum(&f[1]), sum(&f[2]), sum(&f[3]));
    let (ny, ncx) = (1.0 / sy, 1.0 / scx);
    let nz = 1.0 / (sz1 * sz1 + sz2 * sz2).sqrt();
    for (v, n) in f.iter_mut().zip([ny, ncx, nz, nz]) {
        v.iter_mut().for_each(|x| *x *= n);
    }
    f
}

/// The feature filters: a Gaussian, its first and its second derivative (`setFeatureFilter`).
fn feature_filters(ppd: f32) -> [Vec<f32>; 3] {
    let sd = 0.5 * GW * ppd;
    let radius = (3.0 * sd).ceil() as i32;
    let (mut g, mut dg, mut ddg) = (vec![], vec![], vec![]);
    let (mut g_sum, mut dg_neg, mut dg_pos, mut ddg_neg, mut ddg_pos) =
        (0f32, 0f32, 0f32, 0f32, 0f32);
    for x in 0..2 * radius + 1 {
        let xx = (x - radius) as f32;
        let gv = (-(xx * xx) / (2.0 * sd * sd)).exp();
        g_sum += gv;
        let d = -xx * gv;
        if d > 0.0 {
            dg_pos += d
        } else {
            dg_neg -= d
        }
        let dd = (xx * xx / (sd * sd) - 1.0) * gv;
        if dd > 0.0 {
            ddg_pos += dd
        } else {
            ddg_neg -= dd
        }
        g.push(gv);
        dg.push(d);
        ddg.push(dd);
    }
    g.iter_mut().for_each(|v| *v /= g_sum);
    dg.iter_mut()
        .for_each(|v| *v /= if *v > 0.0 { dg_pos } else { dg_neg });
    ddg.iter_mut()
        .for_each(|v| *v /= if *v > 0.0 { ddg_pos } else { ddg_neg });
    [g, dg, ddg]
}

/// How many rows (and columns) away from a pixel the kernel reads at `ppd` pixels per degree:
/// the larger of its filters' radii.
#[cfg(test)]
pub(super) fn reach(ppd: f32) -> usize {
    (spatial_filters(ppd)[0].len() / 2).max(feature_filters(ppd)[0].len() / 2)
}

/// `computeMaxDistance`: the HyAB distance of green to blue, to the power `GQC`.
fn max_distance() -> f32 {
    let lab = |rgb| {
        let [l, a, b] = xyz_to_lab(linear_to_xyz(rgb));
        [l, 0.01 * l * a, 0.01 * l * b]
    };
    hyab(lab([0.0, 1.0, 0.0]), lab([0.0, 0.0, 1.0])).powf(GQC)
}

/// 8-bit sRGB → linear, as `sRGB2LinearRGB(float(v) / 255.0f)`.
fn linear_table() -> [f32; 256] {
    std::array::from_fn(|v| {
        let s = v as f32 / 255.0;
        match s <= 0.04045 {
            true => s / 12.92,
            false => ((s + 0.055) / 1.055).powf(2.4),
        }
    })
}

/// One image's Y, Cx and Cz planes.
#[inline(always)]
fn ycxcz_planes(rgb8: &[u8], lin: &[f32; 256]) -> [Vec<f32>; 3] {
    let n = rgb8.len() / 3;
    let mut p: [Vec<f32>; 3] = std::array::from_fn(|_| plane(n));
    let [py, pcx, pcz] = &mut p;
    for (i, px) in rgb8.chunks_exact(3).enumerate() {
        let c = xyz_to_ycxcz(linear_to_xyz([
            lin[px[0] as usize],
            lin[px[1] as usize],
            lin[px[2] as usize],
        ]));
        (py[i], pcx[i], pcz[i]) = (c[0], c[1], c[2]);
    }
    p
}

thread_local! {
    /// Planes a thread used before: the kernel runs once per band and exposure, and memory
    /// the process already touched costs no page faults.
    static PLANES: std::cell::RefCell<Vec<Vec<f32>>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// A plane of `n` values (their contents are whatever a former use left: every caller writes
/// each value before it reads it).
fn plane(n: usize) -> Vec<f32> {
    let mut v = PLANES.with(|p| p.borrow_mut().pop()).unwrap_or_default();
    v.resize(n, 0.0);
    v
}

/// Gives planes back for the next band.
fn give_back(planes: impl IntoIterator<Item = Vec<f32>>) {
    PLANES.with(|p| p.borrow_mut().extend(planes));
}

/// Columns summed at once: as many accumulators as keep the vector units busy (4 AVX-512
/// registers, 8 AVX2, 16 SSE), all in registers.
const BLOCK: usize = 128;

/// `out[x] = Σₖ f[k] · rows[k][x]` for every x, each sum taken in k's order from 0.0, as the
/// C++ takes its taps. A block of columns is summed over all taps before it is stored, so each
/// tap costs one load and one multiply-add per column.
#[inline(always)]
fn weighted_sum(out: &mut [f32], f: &[f32], rows: &[&[f32]]) {
    let n = out.len();
    let mut x = 0;
    while x + BLOCK <= n {
        let mut acc = [0f32; BLOCK];
        for (&wk, row) in f.iter().zip(rows) {
            let s: &[f32; BLOCK] = row[x..x + BLOCK].try_into().expect("a block");
            for j in 0..BLOCK {
                acc[j] += wk * s[j];
            }
        }
        out[x..x + BLOCK].copy_from_slice(&acc);
        x += BLOCK;
    }
    for (i, o) in out[x..].iter_mut().enumerate() {
        let mut a = 0f32;
        for (&wk, row) in f.iter().zip(rows) {
            a += wk * row[x + i];
        }
        *o = a;
    }
}

/// Rows filtered along y at once by [`along_y_rows`], and the columns of a block there (the
/// accumulators, 2 × 128 columns, fill 16 AVX-512 registers; 4 × 64 measured no faster).
const ROWS: usize = 2;
const ROWS_BLOCK: usize = 128;

/// [`weighted_sum`] into `R` outputs at once, `out[i][x] = Σₖ f[k] · rows[k + i][x]` (each sum
/// in k's order from 0.0, as there): each row is fetched from the L2 cache once for the `R`
/// sums that read it, not once for each (the filters along y are bound by that traffic).
#[inline(always)]
fn weighted_sums<const R: usize>(mut out: [&mut [f32]; R], f: &[f32], rows: &[&[f32]]) {
    const B: usize = ROWS_BLOCK;
    let n = out[0].len();
    let mut x = 0;
    while x + B <= n {
        let mut a = [[0f32; B]; R];
        for (k, &wk) in f.iter().enumerate() {
            for (i, ai) in a.iter_mut().enumerate() {
                let s: &[f32; B] = rows[k + i][x..x + B].try_into().expect("a block");
                for j in 0..B {
                    ai[j] += wk * s[j];
                }
            }
        }
        for (o, ai) in out.iter_mut().zip(&a) {
            o[x..x + B].copy_from_slice(ai);
        }
        x += B;
    }
    for c in x..n {
        for (i, o) in out.iter_mut().enumerate() {
            let mut a = 0f32;
            for (k, &wk) in f.iter().enumerate() {
                a += wk * rows[k + i][c];
            }
            o[c] = a;
        }
    }
}

/// The rows of `src` (w wide, h high) convolved along x with each of `filters` (all of one
/// radius r): `dst[j]` takes filter `j`. Each row is padded with r copies of its first and of
/// its last pixel (the C++ clamps the index instead).
#[inline(always)]
fn along_x(
    src: impl Fn(usize) -> f32,
    w: usize,
    h: usize,
    filters: &[&[f32]],
    dst: &mut [Vec<f32>],
) {
    let r = filters[0].len() / 2;
    assert!(2 * r < 64, "a filter of {} taps: at most 63", 2 * r + 1);
    let mut padded = vec![0f32; w + 2 * r];
    for d in dst.iter_mut() {
        *d = plane(w * h);
    }
    for y in 0..h {
        for (i, p) in padded[r..r + w].iter_mut().enumerate() {
            *p = src(y * w + i);
        }
        let (first, last) = (padded[r], padded[r + w - 1]);
        padded[..r].fill(first);
        padded[r + w..].fill(last);
        let taps: [&[f32]; 64] = std::array::from_fn(|k| &padded[k.min(2 * r)..]);
        for (f, d) in filters.iter().zip(dst.iter_mut()) {
            weighted_sum(&mut d[y * w..(y + 1) * w], f, &taps[..2 * r + 1]);
        }
    }
}

/// Row `y` of `src` (w × h) convolved along y with `f`, edges clamped, into `out`.
#[inline(always)]
fn along_y(
    out: &mut [f32],
    src: &[f32],
    w: usize,
    h: usize,
    y: usize,
    cols: (usize, usize),
    f: &[f32],
) {
    let r = f.len() / 2;
    let rows: [&[f32]; 64] = std::array::from_fn(|k| {
        let yy = (y + k.min(2 * r)).saturating_sub(r).min(h - 1);
        &src[yy * w + cols.0..yy * w + cols.1]
    });
    weighted_sum(&mut out[..cols.1 - cols.0], f, &rows[..f.len()]);
}

/// Rows `y` to `y + R − 1` (< h) of `src` (w × h) convolved along y with `f`, edges clamped,
/// into `out[0..R]`, as `R` calls of [`along_y`] give them.
#[inline(always)]
fn along_y_rows<const R: usize>(
    out: [&mut [f32]; R],
    src: &[f32],
    w: usize,
    h: usize,
    y: usize,
    cols: (usize, usize),
    f: &[f32],
) {
    let r = f.len() / 2;
    let rows: [&[f32]; 64 + ROWS] = std::array::from_fn(|k| {
        let yy = (y + k.min(2 * r + R - 1)).saturating_sub(r).min(h - 1);
        &src[yy * w + cols.0..yy * w + cols.1]
    });
    let n = cols.1 - cols.0;
    weighted_sums(out.map(|o| &mut o[..n]), f, &rows[..f.len() + R - 1]);
}

/// The rows in groups of [`ROWS`] for [`along_y_rows`]: (first row, rows in the group), the last
/// group smaller if `h` is not a multiple.
fn row_groups(h: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..h).step_by(ROWS).map(move |y| (y, ROWS.min(h - y)))
}

/// Columns taken a strip at a time by the filters along y: a strip of the rows one output row
/// reads (8 planes × 21 rows × 512 columns × 4 bytes = 344 KiB) stays in the L2 cache from
/// one row to the next, where whole rows (2.5 MiB at 3840 columns) would not.
const STRIP: usize = 512;

fn strips(w: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..w)
        .step_by(STRIP)
        .map(move |x0| (x0, (x0 + STRIP).min(w)))
}

/// How a `w × h` image's planes are laid out for the kernel: row by row (x along memory), or
/// column by column (`Transposed`: y along memory) when it is narrow, fewer than [`NARROW`]
/// columns and more rows. The filters along x, then along y, run over the planes as they lie,
/// each along whichever axis it filters, so every value is the same sum in the same order
/// either way (`narrow_images_transposed_are_the_same_map` checks it bit for bit); laid out by
/// columns, a narrow image's rows cost no overhead each (a 1 × 4194304 pair took 26 s of CPU
/// row by row, 3.2 s by columns; idiff 3.3 s to 8.7 s on a shared 2-core machine).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    Rows,
    Transposed,
}

/// Images narrower than this (and higher than wide) are laid out by columns.
const NARROW: usize = 64;

/// The filter `f` along the axis that is not memory's, into whole planes: `dst[j]` is `src`
/// (w × h as laid out) convolved along y (as laid out) with `filters[j]`, edges clamped.
#[inline(always)]
fn across_planes(src: &[f32], w: usize, h: usize, filters: &[&[f32]], dst: &mut [Vec<f32>]) {
    for (f, d) in filters.iter().zip(dst.iter_mut()) {
        *d = plane(w * h);
        for cols in strips(w) {
            for (y0, count) in row_groups(h) {
                let (head, tail) = d.split_at_mut((y0 + 1) * w);
                match count {
                    ROWS => {
                        let out = [&mut head[y0 * w + cols.0..], &mut tail[cols.0..]];
                        along_y_rows(out, src, w, h, y0, cols, f)
                    }
                    _ => along_y(&mut head[y0 * w + cols.0..], src, w, h, y0, cols, f),
                }
            }
        }
    }
}

/// Columns `cols` of `row` convolved along the row with `f`, edges clamped, into `out`: the
/// values [`along_x`] gives them.
#[inline(always)]
fn along_row(out: &mut [f32], row: &[f32], cols: (usize, usize), f: &[f32], pad: &mut Vec<f32>) {
    let r = f.len() / 2;
    let n = cols.1 - cols.0;
    let last = row.len() - 1;
    pad.clear();
    pad.extend((0..n + 2 * r).map(|i| row[(cols.0 + i).saturating_sub(r).min(last)]));
    let taps: [&[f32]; 64] = std::array::from_fn(|k| &pad[k.min(2 * r)..]);
    weighted_sum(&mut out[..n], f, &taps[..2 * r + 1]);
}

/// The filters along x of `src(i)` (pixel i of the planes as laid out) into whole planes:
/// `dst[j]` takes `filters[j]` (all of one radius).
#[inline(always)]
fn first_pass(
    layout: Layout,
    src: impl Fn(usize) -> f32,
    w: usize,
    h: usize,
    filters: &[&[f32]],
    dst: &mut [Vec<f32>],
) {
    match layout {
        Layout::Rows => along_x(src, w, h, filters, dst),
        Layout::Transposed => {
            let mut p = plane(w * h);
            p.iter_mut().enumerate().for_each(|(i, v)| *v = src(i));
            across_planes(&p, w, h, filters, dst);
            give_back([p]);
        }
    }
}

/// The filter along y of plane `m` for rows `y0..y0 + count` (at most [`ROWS`]), columns
/// `cols` (as laid out), into `accs[i][p]`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn second_pass(
    layout: Layout,
    accs: &mut [Vec<Vec<f32>>; ROWS],
    p: usize,
    m: &[f32],
    (w, h): (usize, usize),
    (y0, count): (usize, usize),
    cols: (usize, usize),
    f: &[f32],
    pad: &mut Vec<f32>,
) {
    match (layout, count) {
        (Layout::Rows, ROWS) => {
            along_y_rows(accs.each_mut().map(|a| &mut a[p][..]), m, w, h, y0, cols, f)
        }
        (Layout::Rows, _) => {
            (0..count).for_each(|i| along_y(&mut accs[i][p], m, w, h, y0 + i, cols, f))
        }
        (Layout::Transposed, _) => (0..count).for_each(|i| {
            let y = y0 + i;
            along_row(&mut accs[i][p], &m[y * w..(y + 1) * w], cols, f, pad)
        }),
    }
}

/// `v` (`w × h`, `per` values a pixel, row by row) column by column: `h × w`.
fn transpose<T: Copy>(v: &[T], w: usize, h: usize, per: usize) -> Vec<T> {
    let mut t = Vec::with_capacity(v.len());
    for x in 0..w {
        for y in 0..h {
            t.extend_from_slice(&v[(y * w + x) * per..(y * w + x + 1) * per]);
        }
    }
    t
}

/// The LDR-ꟻLIP error map of two `w × h` images given as 8-bit sRGB triples, at `ppd` pixels
/// per degree.
/// The same operations run on whichever vector unit [`cpu`](crate::numerics::cpu) allows: they
/// give the same bits on each (no operation is fused; `the_kernel_is_nv_flips` runs them all).
pub fn flip_rgb8(w: usize, h: usize, reference: &[u8], test: &[u8], ppd: f32) -> Vec<f32> {
    #[cfg(target_arch = "x86_64")]
    {
        use crate::numerics::cpu;
        if cpu::avx512() {
            // SAFETY: the CPU has AVX-512 F/VL/DQ (checked just above)
            return unsafe { flip_avx512(w, h, reference, test, ppd) };
        }
        if cpu::avx2() {
            // SAFETY: the CPU has AVX2 (checked just above)
            return unsafe { flip_avx2(w, h, reference, test, ppd) };
        }
    }
    flip_impl(w, h, reference, test, ppd)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq")]
fn flip_avx512(w: usize, h: usize, reference: &[u8], test: &[u8], ppd: f32) -> Vec<f32> {
    flip_impl(w, h, reference, test, ppd)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn flip_avx2(w: usize, h: usize, reference: &[u8], test: &[u8], ppd: f32) -> Vec<f32> {
    flip_impl(w, h, reference, test, ppd)
}

#[inline(always)]
fn flip_impl(w: usize, h: usize, reference: &[u8], test: &[u8], ppd: f32) -> Vec<f32> {
    assert!(reference.len() == w * h * 3 && test.len() == w * h * 3);
    if w == 0 || h == 0 {
        return vec![];
    }
    match w < NARROW && w < h {
        true => kernel(Layout::Transposed, w, h, reference, test, ppd),
        false => kernel(Layout::Rows, w, h, reference, test, ppd),
    }
}

/// The map of [`flip_impl`], the planes laid out as `layout` says.
#[inline(always)]
fn kernel(layout: Layout, w: usize, h: usize, reference: &[u8], test: &[u8], ppd: f32) -> Vec<f32> {
    if layout == Layout::Transposed {
        let (r, t) = (transpose(reference, w, h, 3), transpose(test, w, h, 3));
        let o = kernel_as_laid_out(layout, h, w, &r, &t, ppd);
        return transpose(&o, h, w, 1);
    }
    kernel_as_laid_out(layout, w, h, reference, test, ppd)
}

/// The map of planes laid out `w × h` (x along memory, or y when `Transposed`), as laid out.
#[inline(always)]
fn kernel_as_laid_out(
    layout: Layout,
    w: usize,
    h: usize,
    reference: &[u8],
    test: &[u8],
    ppd: f32,
) -> Vec<f32> {
    let lin = linear_table();
    let (r, t) = (ycxcz_planes(reference, &lin), ycxcz_planes(test, &lin));
    let color = color_difference(layout, &r, &t, w, h, ppd);
    let o = features_and_error(layout, &r[0], &t[0], color, w, h, ppd);
    give_back(r.into_iter().chain(t));
    o
}

/// The colour difference remapped to [0, 1] (`computeColorDifference`).
#[inline(always)]
fn color_difference(
    layout: Layout,
    r: &[Vec<f32>; 3],
    t: &[Vec<f32>; 3],
    w: usize,
    h: usize,
    ppd: f32,
) -> Vec<f32> {
    let cmax = max_distance();
    let pccmax = GPC * cmax;
    let [fy, fcx, fz1, fz2] = spatial_filters(ppd);
    // Along x: Y·gY, Cx·gCx, Cz·gCz1, Cz·gCz2 of each image
    let mut mid: Vec<Vec<f32>> = vec![vec![]; 8];
    for (img, m) in [r, t].into_iter().zip(mid.chunks_mut(4)) {
        first_pass(layout, |i| img[0][i], w, h, &[&fy], &mut m[0..1]);
        first_pass(layout, |i| img[1][i], w, h, &[&fcx], &mut m[1..2]);
        first_pass(layout, |i| img[2][i], w, h, &[&fz1, &fz2], &mut m[2..4]);
    }
    let filters = [&fy, &fcx, &fz1, &fz2, &fy, &fcx, &fz1, &fz2];
    let s = STRIP.min(w);
    let mut accs: [Vec<Vec<f32>>; ROWS] = std::array::from_fn(|_| vec![vec![0f32; s]; 8]);
    let mut out = vec![0f32; w * h];
    let mut lab_r = vec![0f32; s];
    let (mut lr, mut lt) = (
        [vec![0f32; s], vec![0f32; s], vec![0f32; s]],
        [vec![0f32; s], vec![0f32; s], vec![0f32; s]],
    );
    let mut pad = vec![];
    for cols in strips(w) {
        for rows in row_groups(h) {
            let y0 = rows.0;
            for (p, (m, f)) in mid.iter().zip(filters).enumerate() {
                second_pass(layout, &mut accs, p, m, (w, h), rows, cols, f, &mut pad);
            }
            let count = rows.1;
            for (i, acc) in accs[..count].iter().enumerate() {
                let y = y0 + i;
                // Every column without a branch, so that the loop vectorises
                let row = &mut out[y * w + cols.0..y * w + cols.1];
                let n = row.len();
                let (a0, a1, a2, a3) = (&acc[0][..n], &acc[1][..n], &acc[2][..n], &acc[3][..n]);
                let (a4, a5, a6, a7) = (&acc[4][..n], &acc[5][..n], &acc[6][..n], &acc[7][..n]);
                for x in 0..n {
                    row[x] = a2[x] + a3[x];
                    lab_r[x] = a6[x] + a7[x];
                }
                lab_rows(a0, a1, row, &mut lr);
                lab_rows(a4, a5, &lab_r, &mut lt);
                for x in 0..n {
                    row[x] = hyab(
                        [lr[0][x], lr[1][x], lr[2][x]],
                        [lt[0][x], lt[1][x], lt[2][x]],
                    );
                }
                for o in row.iter_mut() {
                    let d = pow(*o, GQC);
                    let (low, high) = (
                        d * (GPT / pccmax),
                        GPT + ((d - pccmax) / (cmax - pccmax)) * (1.0 - GPT),
                    );
                    *o = if d < pccmax { low } else { high };
                }
            }
        }
    }
    give_back(mid);
    out
}

/// The feature difference and the final error (`computeFeatureDifferenceAndFinalError`):
/// `color` becomes the error map.
#[inline(always)]
fn features_and_error(
    layout: Layout,
    r: &[f32],
    t: &[f32],
    mut color: Vec<f32>,
    w: usize,
    h: usize,
    ppd: f32,
) -> Vec<f32> {
    let norm = 1.0 / 2f32.sqrt();
    let [g, dg, ddg] = feature_filters(ppd);
    let (one_116, sixteen_116) = (1.0f32 / 116.0, 16.0f32 / 116.0);
    // Along x: the normalised Y by dg, ddg and g, for each image
    let mut mid: Vec<Vec<f32>> = vec![vec![]; 6];
    for (img, m) in [r, t].into_iter().zip(mid.chunks_mut(3)) {
        first_pass(
            layout,
            |i| img[i] * one_116 + sixteen_116,
            w,
            h,
            &[&dg, &ddg, &g],
            m,
        );
    }
    // Along y: dx = g∗(dg-along-x), ddx = g∗(ddg-along-x), dy = dg∗(g-along-x), ddy = ddg∗(…)
    let plan: [(usize, &[f32]); 8] = [
        (0, &g),
        (1, &g),
        (2, &dg),
        (2, &ddg),
        (3, &g),
        (4, &g),
        (5, &dg),
        (5, &ddg),
    ];
    let s = STRIP.min(w);
    let mut accs: [Vec<Vec<f32>>; ROWS] = std::array::from_fn(|_| vec![vec![0f32; s]; 8]);
    let mut pad = vec![];
    for cols in strips(w) {
        for rows in row_groups(h) {
            let y0 = rows.0;
            for (p, &(m, f)) in plan.iter().enumerate() {
                second_pass(
                    layout,
                    &mut accs,
                    p,
                    &mid[m],
                    (w, h),
                    rows,
                    cols,
                    f,
                    &mut pad,
                );
            }
            let count = rows.1;
            for (i, acc) in accs[..count].iter().enumerate() {
                let y = y0 + i;
                // Every column without a branch, so that the loop vectorises
                let row = &mut color[y * w + cols.0..y * w + cols.1];
                let n = row.len();
                let (a0, a1, a2, a3) = (&acc[0][..n], &acc[1][..n], &acc[2][..n], &acc[3][..n]);
                let (a4, a5, a6, a7) = (&acc[4][..n], &acc[5][..n], &acc[6][..n], &acc[7][..n]);
                for x in 0..n {
                    let c = &mut row[x];
                    let (dxr, ddxr, dyr, ddyr) = (a0[x], a1[x], a2[x], a3[x]);
                    let (dxt, ddxt, dyt, ddyt) = (a4[x], a5[x], a6[x], a7[x]);
                    let edge_r = (dxr * dxr + dyr * dyr).sqrt();
                    let edge_t = (dxt * dxt + dyt * dyt).sqrt();
                    let point_r = (ddxr * ddxr + ddyr * ddyr).sqrt();
                    let point_t = (ddxt * ddxt + ddyt * ddyt).sqrt();
                    let m = max((edge_r - edge_t).abs(), (point_r - point_t).abs());
                    // The feature difference: (·)^GQF with GQF = ½ is the square root (correctly rounded,
                    // as `powf` is but for its rare last-ulp slips). Y normalised lies in [0, 1] and
                    // each derivative filter's positive and negative weights sum to ±1, so |dx|, |dy|,
                    // |ddx|, |ddy| ≤ 1, m ≤ √2 and the exponent 1 − √(m/√2) lies in [0, 1]
                    let e = 1.0 - (norm * m).sqrt();
                    *c = pow(*c, e);
                }
            }
        }
    }
    give_back(mid);
    color
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(n: usize, seed: u64) -> Vec<u8> {
        let mut s = seed | 1;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 56) as u8
            })
            .collect()
    }

    /// [`cbrt`] on every f32 of its range against the correctly rounded power (glibc's f64
    /// `pow`, rounded once more: a double rounding only within 1e-16 of a midpoint) and
    /// against glibc's `powf`: one ulp at most, and as often the power the C++ gets as the
    /// correctly rounded one is (the module's analysis).
    #[test]
    fn cube_root_is_powf() {
        let c = 1.0f32 / 3.0;
        let lo = (6.0f32 / 29.0).powi(3).to_bits() + 1;
        let (mut off_cr, mut off_powf, mut powf_off_cr) = (0u64, 0u64, 0u64);
        for b in lo..2f32.to_bits() {
            let x = f32::from_bits(b);
            let (ours, cr) = (cbrt(x), (x as f64).powf(c as f64) as f32);
            let powf = std::hint::black_box(x).powf(std::hint::black_box(c));
            assert!(
                ours.to_bits().abs_diff(cr.to_bits()) <= 1,
                "{x:e}: {ours:e} {cr:e}"
            );
            off_cr += (ours != cr) as u64;
            off_powf += (ours != powf) as u64;
            powf_off_cr += (powf != cr) as u64;
        }
        assert!(off_cr <= 20, "{off_cr} not correctly rounded");
        assert!(
            off_powf <= powf_off_cr + 20,
            "{off_powf} differ from powf's"
        );
    }

    /// The kernel against nv-flip's C++ on images with flat areas, edges and noise, odd sizes,
    /// a one-pixel row and one wider than a strip: every pixel within 1e-4 (the module's
    /// analysis), at least 98 % bit for bit, on each instruction set this machine has.
    #[test]
    fn the_kernel_is_nv_flips() {
        assert_eq!(nv_flip::DEFAULT_PIXELS_PER_DEGREE, 67.0);
        for (w, h, seed) in [
            (37usize, 29usize, 1u64),
            (64, 3, 2),
            (1, 40, 3),
            (90, 1, 4),
            (53, 61, 5),
            // wider than a block of columns and a strip, an odd number of rows
            (700, 23, 6),
            // narrow and tall: laid out by columns
            (6, 150, 7),
        ] {
            let a = noise(w * h * 3, seed);
            // flat blocks, a bright edge and small changes
            let mut b = a.clone();
            let mut a2 = a.clone();
            for (i, v) in a2.iter_mut().enumerate() {
                let x = (i / 3) % w;
                if x < w / 3 {
                    *v = 40;
                } else if x < w / 2 {
                    *v = 230;
                }
            }
            for (i, v) in b.iter_mut().enumerate() {
                let x = (i / 3) % w;
                *v = match x < w / 3 {
                    true if i % 7 == 0 => 41,
                    true => 40,
                    _ if x < w / 2 => 230,
                    _ => v.wrapping_add((i % 5) as u8),
                };
            }
            let ours = flip_impl(w, h, &a2, &b, 67.0);
            // Each vector unit gives the baseline's bits
            #[cfg(target_arch = "x86_64")]
            {
                use crate::numerics::cpu;
                if cpu::avx2() {
                    assert!(unsafe { flip_avx2(w, h, &a2, &b, 67.0) } == ours);
                }
                if cpu::avx512() {
                    assert!(unsafe { flip_avx512(w, h, &a2, &b, 67.0) } == ours);
                }
            }
            let theirs = nv_flip::flip(
                nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, &a2),
                nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, &b),
                67.0,
            )
            .to_vec();
            let differ = ours
                .iter()
                .zip(&theirs)
                .filter(|(x, y)| x.to_bits() != y.to_bits())
                .count();
            let worst = ours
                .iter()
                .zip(&theirs)
                .map(|(x, y)| (x - y).abs())
                .fold(0f32, f32::max);
            // The module's figures (`--nocapture`)
            println!(
                "{w}×{h}: worst {worst:e}, {differ} of {} pixels differ",
                w * h
            );
            assert!(worst <= 1e-4, "{w}×{h}: worst difference {worst:e}");
            assert!(
                differ * 50 <= w * h,
                "{w}×{h}: {differ} of {} pixels differ",
                w * h
            );
            assert!(ours.iter().any(|&v| v > 0.0));
        }
    }

    /// A narrow image laid out by columns gives the map it gives laid out by rows, bit for bit
    /// (and a wide one transposed too): one column, a few, one under [`NARROW`], longer than a
    /// strip, an odd number of rows, and shorter than a filter.
    #[test]
    fn narrow_images_transposed_are_the_same_map() {
        for (w, h, seed) in [
            (1usize, 700usize, 11u64),
            (3, 200, 12),
            (17, 301, 13),
            (NARROW - 1, 90, 14),
            (5, 5, 15),
            (90, 4, 16),
        ] {
            let a = noise(w * h * 3, seed);
            let b: Vec<u8> = a
                .iter()
                .enumerate()
                .map(|(i, &v)| match (i / 3 / w) % 9 < 4 {
                    true => v.wrapping_add((i % 3) as u8),
                    false => v,
                })
                .collect();
            let rows = kernel(Layout::Rows, w, h, &a, &b, 67.0);
            let cols = kernel(Layout::Transposed, w, h, &a, &b, 67.0);
            assert!(rows.iter().any(|&v| v > 0.0));
            let differ = rows
                .iter()
                .zip(&cols)
                .filter(|(x, y)| x.to_bits() != y.to_bits())
                .count();
            assert_eq!(differ, 0, "{w}×{h}");
        }
    }
}
