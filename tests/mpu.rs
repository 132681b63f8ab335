//! MPU implicit (src/implicit/mpu.rs) on a sphere and on the committed bunny points.

use glam::DVec3;
use rayproof::implicit::mpu::{Mpu, MpuOptions};
use std::path::Path;
use std::time::Instant;

fn bunny() -> (Vec<DVec3>, Vec<DVec3>) {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/implicit/bunny/bunny.pts");
    Mpu::load_points(&p).expect("bunny.pts")
}

#[test]
#[ignore]
fn probe() {
    let (p, n) = bunny();
    let t = Instant::now();
    let m = Mpu::fit(&p, &n, &MpuOptions::default());
    println!("fit {:?} cells {} leaves {}", t.elapsed(), m.cells(), m.leaves());
    println!("{:#?} L={}", m.stats(), m.lipschitz());
    let (lo, hi) = m.bounds();
    let diag = (hi - lo).length();
    let mut maxf: f64 = 0.0;
    let (mut ok_in, mut ok_out) = (0, 0);
    let eps = 0.005 * diag;
    for (pp, nn) in p.iter().zip(&n) {
        maxf = maxf.max(m.eval(*pp).abs());
        if m.eval(*pp - eps * *nn) < 0.0 {
            ok_in += 1;
        }
        if m.eval(*pp + eps * *nn) > 0.0 {
            ok_out += 1;
        }
    }
    println!("max|f| at points {maxf} ({} of diag), in {ok_in} out {ok_out} of {}", maxf / diag, p.len());
    let k = 1_000_000;
    let mut s = 0.0;
    let t = Instant::now();
    for i in 0..k {
        let u = (i as f64 * 0.618034) % 1.0;
        let v = (i as f64 * 0.7548777) % 1.0;
        let w = (i as f64 * 0.5698403) % 1.0;
        s += m.eval(lo + (hi - lo) * DVec3::new(u, v, w));
    }
    println!("eval {:.1} ns (sum {s})", t.elapsed().as_nanos() as f64 / k as f64);
    let t = Instant::now();
    for i in 0..k {
        let j = i % p.len();
        s += m.eval(p[j] + 0.01 * n[j]);
    }
    println!("eval near surface {:.1} ns (sum {s})", t.elapsed().as_nanos() as f64 / k as f64);
}

#[test]
#[ignore]
fn probe_cost() {
    let (p, n) = bunny();
    let m = Mpu::fit(&p, &n, &MpuOptions::default());
    let (lo, hi) = m.bounds();
    let (mut v, mut u) = (0, 0);
    let k = 10000;
    for i in 0..k {
        let a = (i as f64 * 0.618034) % 1.0;
        let b = (i as f64 * 0.7548777) % 1.0;
        let c = (i as f64 * 0.5698403) % 1.0;
        let (x, y) = m.eval_cost(lo + (hi - lo) * DVec3::new(a, b, c));
        v += x;
        u += y;
    }
    println!("random: visited {} used {}", v as f64 / k as f64, u as f64 / k as f64);
    let (mut v, mut u) = (0, 0);
    for i in 0..p.len() {
        let (x, y) = m.eval_cost(p[i] + 0.01 * n[i]);
        v += x;
        u += y;
    }
    println!("near: visited {} used {}", v as f64 / p.len() as f64, u as f64 / p.len() as f64);
}

#[test]
#[ignore]
fn probe_eps() {
    let (p, n) = bunny();
    for eps in [0.001, 0.002, 0.005, 0.01] {
        let o = MpuOptions { max_error: eps, ..Default::default() };
        let t = Instant::now();
        let m = Mpu::fit(&p, &n, &o);
        let ft = t.elapsed();
        let (lo, hi) = m.bounds();
        let diag = (hi - lo).length();
        let maxf = p.iter().map(|q| m.eval(*q).abs()).fold(0.0, f64::max);
        let (mut v, mut u) = (0, 0);
        for i in 0..p.len() {
            let (x, y) = m.eval_cost(p[i] + 0.01 * n[i]);
            v += x;
            u += y;
        }
        let k = 300_000;
        let mut s = 0.0;
        let t = Instant::now();
        for i in 0..k {
            let j = i % p.len();
            s += m.eval(p[j] + 0.05 * n[j]);
        }
        let ns = t.elapsed().as_nanos() as f64 / k as f64;
        let st = m.stats();
        println!("eps {eps}: fit {ft:?} cells {} leaves {} (biv {} gen {} off {} empty {} split {}) depth {} maxf/diag {:.5} L {:.3} at {:?} shell {:.3} near visited {:.0} used {:.1} eval {ns:.0} ns {s:.1}",
            m.cells(), m.leaves(), st.bivariate, st.general, st.general_offsets, st.empty, st.empty_split_vote, st.depth, maxf / diag, m.lipschitz(), st.max_gradient_at, st.shell_min,
            v as f64 / p.len() as f64, u as f64 / p.len() as f64);
    }
}

fn bunny_mesh() -> (Vec<DVec3>, Vec<[usize; 3]>) {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/implicit/bunny/bunny.obj");
    let text = std::fs::read_to_string(p).unwrap();
    let (mut v, mut f) = (Vec::new(), Vec::new());
    for l in text.lines() {
        let t: Vec<&str> = l.split_whitespace().collect();
        match t.first() {
            Some(&"v") => v.push(DVec3::new(t[1].parse().unwrap(), t[2].parse().unwrap(), t[3].parse().unwrap())),
            Some(&"f") => f.push([1, 2, 3].map(|k| t[k].parse::<usize>().unwrap() - 1)),
            _ => {}
        }
    }
    (v, f)
}

/// Generalised winding number of a closed mesh at `x` (1 inside, 0 outside).
fn winding(v: &[DVec3], f: &[[usize; 3]], x: DVec3) -> f64 {
    let mut s = 0.0;
    for t in f {
        let (a, b, c) = (v[t[0]] - x, v[t[1]] - x, v[t[2]] - x);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let num = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        s += 2.0 * num.atan2(den);
    }
    s / (4.0 * std::f64::consts::PI)
}

#[test]
#[ignore]
fn probe_ghost() {
    use rayon::prelude::*;
    let (p, n) = bunny();
    let (mv, mf) = bunny_mesh();
    let m = Mpu::fit(&p, &n, &MpuOptions::default());
    let (lo, hi) = m.bounds();
    let g = 40;
    let bins = [0.0, 0.1, 0.2, 0.4, 0.8, 1.6, 100.0];
    let res: Vec<(f64, f64, bool, f64)> = (0..g * g * g).into_par_iter().map(|i| {
        let x = lo + (hi - lo) * DVec3::new((i % g) as f64 + 0.5, ((i / g) % g) as f64 + 0.5, (i / g / g) as f64 + 0.5) / g as f64;
        let d = p.iter().map(|q| (*q - x).length()).fold(f64::INFINITY, f64::min);
        let inside = winding(&mv, &mf, x) > 0.5;
        let (f, gr) = m.eval_grad(x);
        (d, f, inside, gr.length())
    }).collect();
    for w in bins.windows(2) {
        let sel: Vec<_> = res.iter().filter(|r| r.0 >= w[0] && r.0 < w[1]).collect();
        let wrong_out = sel.iter().filter(|r| !r.2 && r.1 <= 0.0).count();
        let wrong_in = sel.iter().filter(|r| r.2 && r.1 >= 0.0).count();
        let nin = sel.iter().filter(|r| r.2).count();
        let maxg = sel.iter().map(|r| r.3).fold(0.0, f64::max);
        let maxratio = sel.iter().filter(|r| !r.2).map(|r| r.1 / r.0).fold(0.0, f64::max);
        println!("dist [{}, {}): {} pts ({} inside): f<=0 outside {}, f>=0 inside {}, max|grad| {:.3}, max f/d outside {:.3}", w[0], w[1], sel.len(), nin, wrong_out, wrong_in, maxg, maxratio);
    }
}

#[test]
#[ignore]
fn probe_at() {
    let (p, n) = bunny();
    let m = Mpu::fit(&p, &n, &MpuOptions::default());
    let at = m.stats().max_gradient_at;
    println!("at {at:?} f,g = {:?}", m.eval_grad(at));
    for l in m.debug_contrib(at) { println!("{l}"); }
}
