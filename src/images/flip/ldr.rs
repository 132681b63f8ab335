//! LDR-ꟻLIP of two 8-bit sRGB images, computed as NVIDIA's C++ computes it and several times
//! faster.
//!
//! The reference is `FLIP::image<float>::FLIP` of NVlabs/flip (`cpp/CPP/image.h`, as vendored in
//! nv-flip-sys 0.1.1 `extern/cpp/CPP/`): sRGB → YCxCz, the separated spatial filters (a Gaussian
//! each for Y and Cx, two for Cz), YCxCz → linear RGB clamped → CIELab with Hunt's adjustment,
//! HyAB, the feature filters (a Gaussian and its first and second derivatives on Y), and
//! `colour^(1 − feature)`. Every value is computed with the same f32 operations in the same
//! order, so the map is the C++ map (`the_kernel_is_nv_flips`: bit for bit on random images
//! with edges). What differs is only how it is laid out:
//! - planes instead of colour triples, and each row padded with its edge pixels instead of a
//!   clamped index per tap, so the filters' inner loops run along a row and vectorise;
//! - sRGB → linear through a 256-entry table (the input has 256 values per channel);
//! - where the filtered colours of both images are equal, the colour difference is 0 without
//!   its seven `powf`s, and where their features are equal the error is the colour difference
//!   without two more. Both are exact: `powf(0, y) = 0` for y > 0 and `powf(x, 1) = x`.

/// ꟻLIP's constants (`sharedflip.h` `FLIPConstants`).
const GQC: f32 = 0.7;
const GPC: f32 = 0.4;
const GPT: f32 = 0.95;
const GW: f32 = 0.082;
const GQF: f32 = 0.5;
const PI: f32 = 3.141_592_653_589_79;

/// D65 white and its inverse (`color.h` `DEFAULT_ILLUMINANT`, `INV_DEFAULT_ILLUMINANT`).
const WHITE: [f32; 3] = [0.950_428_545, 1.0, 1.088_900_371];
const INV_WHITE: [f32; 3] = [1.052_156_925, 1.0, 0.918_357_670];

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
    A.map(|a| a[0] * r + a[1] * g + a[2] * b)
}

fn xyz_to_linear([x, y, z]: [f32; 3]) -> [f32; 3] {
    const A: [[f32; 3]; 3] = [
        [3.241_003_275, -1.537_398_934, -0.498_615_861],
        [-0.969_224_334, 1.875_930_071, 0.041_554_224],
        [0.055_639_423, -0.204_011_202, 1.057_148_933],
    ];
    A.map(|a| a[0] * x + a[1] * y + a[2] * z)
}

fn xyz_to_ycxcz(xyz: [f32; 3]) -> [f32; 3] {
    let [x, y, z] = [
        xyz[0] * INV_WHITE[0],
        xyz[1] * INV_WHITE[1],
        xyz[2] * INV_WHITE[2],
    ];
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

fn ycxcz_to_xyz([yy, cx, cz]: [f32; 3]) -> [f32; 3] {
    let y = (yy + 16.0) / 116.0;
    let (cx, cz) = (cx / 500.0, cz / 200.0);
    [(y + cx) * WHITE[0], y * WHITE[1], (y - cz) * WHITE[2]]
}

fn xyz_to_lab(xyz: [f32; 3]) -> [f32; 3] {
    let delta = 6.0f32 / 29.0;
    let delta_square = delta * delta;
    let delta_cube = delta * delta_square;
    let factor = 1.0 / (3.0 * delta_square);
    let term = 4.0f32 / 29.0;
    let f = |v: f32| match v > delta_cube {
        true => v.powf(1.0 / 3.0),
        false => factor * v + term,
    };
    let [x, y, z] = [
        f(xyz[0] * INV_WHITE[0]),
        f(xyz[1] * INV_WHITE[1]),
        f(xyz[2] * INV_WHITE[2]),
    ];
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

/// The C++ `Max` and `Min` macros (a NaN falls to the second argument).
fn max(x: f32, y: f32) -> f32 {
    if x > y {
        x
    } else {
        y
    }
}

fn min(x: f32, y: f32) -> f32 {
    if x > y {
        y
    } else {
        x
    }
}

fn clamp01(v: f32) -> f32 {
    min(max(v, 0.0), 1.0)
}

/// CIELab with Hunt's adjustment of a and b.
fn lab_hunt(ycxcz: [f32; 3]) -> [f32; 3] {
    let rgb = xyz_to_linear(ycxcz_to_xyz(ycxcz)).map(clamp01);
    let [l, a, b] = xyz_to_lab(linear_to_xyz(rgb));
    [l, 0.01 * l * a, 0.01 * l * b]
}

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
fn ycxcz_planes(rgb8: &[u8], lin: &[f32; 256]) -> [Vec<f32>; 3] {
    let n = rgb8.len() / 3;
    let mut p: [Vec<f32>; 3] = std::array::from_fn(|_| Vec::with_capacity(n));
    for px in rgb8.chunks_exact(3) {
        let c = xyz_to_ycxcz(linear_to_xyz([
            lin[px[0] as usize],
            lin[px[1] as usize],
            lin[px[2] as usize],
        ]));
        for k in 0..3 {
            p[k].push(c[k]);
        }
    }
    p
}

/// Columns summed at once: as many accumulators as keep the vector units busy (4 AVX-512
/// registers, 8 AVX2, 16 SSE), all in registers.
const BLOCK: usize = 64;

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
    let mut padded = vec![0f32; w + 2 * r];
    for d in dst.iter_mut() {
        d.resize(w * h, 0.0);
    }
    for y in 0..h {
        for (i, p) in padded.iter_mut().enumerate() {
            *p = src(y * w + i.saturating_sub(r).min(w - 1));
        }
        let taps: Vec<&[f32]> = (0..2 * r + 1).map(|k| &padded[k..]).collect();
        for (f, d) in filters.iter().zip(dst.iter_mut()) {
            weighted_sum(&mut d[y * w..(y + 1) * w], f, &taps);
        }
    }
}

/// Row `y` of `src` (w × h) convolved along y with `f`, edges clamped, into `out`.
#[inline(always)]
fn along_y(out: &mut [f32], src: &[f32], w: usize, h: usize, y: usize, f: &[f32]) {
    let r = f.len() / 2;
    let rows: Vec<&[f32]> = (0..f.len())
        .map(|k| {
            let yy = (y + k).saturating_sub(r).min(h - 1);
            &src[yy * w..(yy + 1) * w]
        })
        .collect();
    weighted_sum(out, f, &rows);
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
    let lin = linear_table();
    let (r, t) = (ycxcz_planes(reference, &lin), ycxcz_planes(test, &lin));
    let color = color_difference(&r, &t, w, h, ppd);
    features_and_error(&r[0], &t[0], color, w, h, ppd)
}

/// The colour difference remapped to [0, 1] (`computeColorDifference`).
#[inline(always)]
fn color_difference(
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
        along_x(|i| img[0][i], w, h, &[&fy], &mut m[0..1]);
        along_x(|i| img[1][i], w, h, &[&fcx], &mut m[1..2]);
        along_x(|i| img[2][i], w, h, &[&fz1, &fz2], &mut m[2..4]);
    }
    let filters = [&fy, &fcx, &fz1, &fz2, &fy, &fcx, &fz1, &fz2];
    let mut acc = vec![vec![0f32; w]; 8];
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        for ((a, m), f) in acc.iter_mut().zip(&mid).zip(filters) {
            along_y(a, m, w, h, y, f);
        }
        for x in 0..w {
            let fr = [acc[0][x], acc[1][x], acc[2][x] + acc[3][x]];
            let ft = [acc[4][x], acc[5][x], acc[6][x] + acc[7][x]];
            // Equal filtered colours: HyAB 0, and 0^GQC = 0
            if fr == ft {
                continue;
            }
            let mut d = hyab(lab_hunt(fr), lab_hunt(ft)).powf(GQC);
            if d < pccmax {
                d *= GPT / pccmax;
            } else {
                d = GPT + ((d - pccmax) / (cmax - pccmax)) * (1.0 - GPT);
            }
            out[y * w + x] = d;
        }
    }
    out
}

/// The feature difference and the final error (`computeFeatureDifferenceAndFinalError`):
/// `color` becomes the error map.
#[inline(always)]
fn features_and_error(
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
        along_x(
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
    let mut acc = vec![vec![0f32; w]; 8];
    for y in 0..h {
        for (a, &(m, f)) in acc.iter_mut().zip(&plan) {
            along_y(a, &mid[m], w, h, y, f);
        }
        for x in 0..w {
            let [dxr, ddxr, dyr, ddyr, dxt, ddxt, dyt, ddyt] = std::array::from_fn(|k| acc[k][x]);
            let edge_r = (dxr * dxr + dyr * dyr).sqrt();
            let edge_t = (dxt * dxt + dyt * dyt).sqrt();
            let point_r = (ddxr * ddxr + ddyr * ddyr).sqrt();
            let point_t = (ddxt * ddxt + ddyt * ddyt).sqrt();
            let m = max((edge_r - edge_t).abs(), (point_r - point_t).abs());
            let c = &mut color[y * w + x];
            // Equal features: the feature difference is 0^GQF = 0, and c^1 = c
            if m == 0.0 {
                continue;
            }
            let e = 1.0 - (norm * m).powf(GQF);
            *c = match *c == 0.0 {
                // 0^e: 0 for e > 0, 1 for e = 0, ∞ below
                true if e > 0.0 => 0.0,
                _ => c.powf(e),
            };
        }
    }
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

    /// The kernel against nv-flip's C++ on images with flat areas, edges and noise, odd sizes
    /// and a one-pixel row: bit for bit.
    #[test]
    fn the_kernel_is_nv_flips() {
        assert_eq!(nv_flip::DEFAULT_PIXELS_PER_DEGREE, 67.0);
        for (w, h, seed) in [
            (37usize, 29usize, 1u64),
            (64, 3, 2),
            (1, 40, 3),
            (90, 1, 4),
            (53, 61, 5),
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
            let ours = flip_rgb8(w, h, &a2, &b, 67.0);
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
            assert_eq!(differ, 0, "{w}×{h}: {differ} of {} pixels differ", w * h);
            assert!(ours.iter().any(|&v| v > 0.0));
        }
    }
}
