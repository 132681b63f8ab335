//! The Whitted integrator: per pixel, the primary ray, direct light with shadow rays, and the
//! reflection and refraction trees, for each precision and method (const generics choose the
//! effects at compile time).

use super::*;

/// Everything the integrator reads.
pub(super) struct Ctx<'a> {
    pub(super) geo: Geometry,
    pub(super) materials: Vec<Material>,
    pub(super) lights: &'a [scene::Light],
    pub(super) directional: &'a [scene::DirectionalLight],
    pub(super) ambient: DVec3,
    pub(super) method: &'static Method,
    pub(super) glass_shadows: GlassShadows,
    pub(super) max_depth: u32,
    pub(super) offset: Option<f64>,
    ulp16: f64,
}

impl<'a> Ctx<'a> {
    /// The scene's lights and settings around its geometry; `ulp` is the render precision's.
    pub(super) fn new(
        s: &'a Scene,
        geo: Geometry,
        materials: Vec<Material>,
        method: &'static Method,
        max_depth: u32,
        ulp: f64,
    ) -> Ctx<'a> {
        Ctx {
            geo,
            materials,
            lights: &s.file.lights,
            directional: &s.file.directional,
            ambient: DVec3::from_array(s.file.render.ambient),
            method,
            glass_shadows: s.file.render.glass_shadows,
            max_depth,
            offset: scene::offset_value(&s.file.render.offset).unwrap_or(None),
            ulp16: 16.0 * ulp,
        }
    }
}

/// The render loop: rows in parallel, one kernel instantiation per effect set.
pub(super) fn run<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
    ctx: &Ctx,
    s: &Scene,
    (w, h): (usize, usize),
    grid: u32,
    ov: &Overrides,
) -> Planes {
    let lens = Lens::new(s, w, h);
    let pos = lens.pos;
    let bar = if ov.progress {
        ProgressBar::new(h as u64)
    } else {
        ProgressBar::hidden()
    };
    // The planes, filled row by row in place; the extra planes only when asked for
    let extra = if ov.beauty_only { 0 } else { w * h };
    let mut out: Planes = (
        vec![[0f32; 3]; w * h],
        vec![0f32; extra],
        vec![[0f32; 3]; extra],
        vec![0f32; extra],
        RayCounts::default(),
    );
    // Each row's slices: beauty, and the extra planes' if there are any
    let mut extra_rows = out
        .1
        .chunks_mut(w)
        .zip(out.2.chunks_mut(w))
        .zip(out.3.chunks_mut(w));
    let rows: Vec<_> = out
        .0
        .chunks_mut(w)
        .map(|beauty| (beauty, extra_rows.next()))
        .collect();
    // The sub-pixel cell centres' offsets on the image plane, per column and per row
    let g = grid as usize;
    let cell = |k: usize, i: usize| k as f64 + (i as f64 + 0.5) / grid as f64;
    let across: Vec<DVec3> = (0..w * g)
        .map(|c| lens.across(cell(c / g, c % g)))
        .collect();
    let down: Vec<DVec3> = (0..h * g).map(|r| lens.down(cell(r / g, r % g))).collect();
    let counts = rows
        .into_par_iter()
        .enumerate()
        .map(|(y, (beauty, mut extra))| {
            let mut counts = RayCounts::default();
            for x in 0..w {
                let before = counts.total();
                let (mut sum, mut dsum, mut nsum, mut hits) = (DVec3::ZERO, 0.0, DVec3::ZERO, 0u32);
                for j in 0..g {
                    for i in 0..g {
                        // Sub-pixel cell centre
                        let d = lens.dir_from(across[x * g + i], down[y * g + j]);
                        counts.primary += 1;
                        counts.left = MAX_TREE_SEGMENTS - 1;
                        let (l, first) = radiance::<F, SH, RF, RR>(ctx, pos, d, 1, &mut counts);
                        counts.primary_miss += first.is_none() as u64;
                        sum += l;
                        if let Some((t, n)) = first {
                            dsum += t;
                            nsum += n;
                            hits += 1;
                        }
                    }
                }
                let k = 1.0 / (grid * grid) as f64;
                beauty[x] = pixel(sum * k);
                if let Some(((depth, normal), rays)) = &mut extra {
                    if hits > 0 {
                        depth[x] = (dsum / hits as f64) as f32;
                        normal[x] = (nsum / hits as f64).as_vec3().to_array();
                    }
                    rays[x] = (counts.total() - before) as f32;
                }
            }
            bar.inc(1);
            counts
        })
        .reduce(RayCounts::default, |mut a, b| {
            a += b;
            a
        });
    out.4 = counts;
    bar.finish_and_clear();
    out
}

/// A pixel's radiance in f32; a value above f32's range (a surface next to a point light) is
/// stored as f32's largest value, not as Inf (NaN stays NaN: it is a bug, counted in the
/// sidecar's `nonfinite_pixels`).
#[inline]
pub(super) fn pixel(l: DVec3) -> [f32; 3] {
    l.as_vec3()
        .to_array()
        .map(|c| if c == f32::INFINITY { f32::MAX } else { c })
}

/// Radiance along a ray at segment `depth`; also the first hit's distance and normal.
pub(super) fn radiance<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
    ctx: &Ctx,
    o: DVec3,
    d: DVec3,
    depth: u32,
    counts: &mut RayCounts,
) -> (DVec3, Option<(f64, DVec3)>) {
    let Some(hit) = ctx
        .geo
        .intersect::<F>(ctx.method, o, d, f64::INFINITY, &mut counts.tests)
    else {
        return (DVec3::ZERO, None);
    };
    (
        shade::<F, SH, RF, RR>(ctx, o, d, &hit, depth, counts),
        Some((hit.t, hit.n)),
    )
}

/// Radiance leaving `hit` towards `−d` (the ray from `o` at segment `depth`).
pub(super) fn shade<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
    ctx: &Ctx,
    o: DVec3,
    d: DVec3,
    hit: &geom::Hit,
    depth: u32,
    counts: &mut RayCounts,
) -> DVec3 {
    let p = o + hit.t * d;
    // Face the normal towards the incoming ray
    let outside = hit.n.dot(d) < 0.0;
    let nf = if outside { hit.n } else { -hit.n };
    let eps = ctx
        .offset
        .unwrap_or(ctx.ulp16 * p.abs().max_element().max(1.0));
    match ctx.materials[hit.material] {
        Material::Diffuse { albedo } => {
            let mut sum = DVec3::ZERO;
            for light in ctx.lights {
                let to = DVec3::from_array(light.position) - p;
                let dist2 = to.length_squared();
                let wl = to / dist2.sqrt();
                let cos = nf.dot(wl);
                // (NaN when the light is exactly at the hit point: it lights nothing there)
                if cos.is_nan() || cos <= 0.0 {
                    continue;
                }
                if SH {
                    counts.shadow += 1;
                    if occluded::<F>(ctx, p + nf * eps, wl, dist2.sqrt(), counts) {
                        continue;
                    }
                    counts.shadow_miss += 1;
                }
                sum += DVec3::from_array(light.intensity) * (cos / dist2);
            }
            for light in ctx.directional {
                let wl = -DVec3::from_array(light.direction).normalize();
                let cos = nf.dot(wl);
                if cos <= 0.0 {
                    continue;
                }
                if SH {
                    counts.shadow += 1;
                    if occluded::<F>(ctx, p + nf * eps, wl, f64::INFINITY, counts) {
                        continue;
                    }
                    counts.shadow_miss += 1;
                }
                sum += DVec3::from_array(light.irradiance) * cos;
            }
            DVec3::from_array(albedo) * (std::f64::consts::FRAC_1_PI * sum + ctx.ambient)
        }
        Material::Mirror { reflectance } => {
            if RF && depth < ctx.max_depth {
                let r = d - 2.0 * d.dot(nf) * nf;
                DVec3::from_array(reflectance)
                    * secondary::<F, SH, RF, RR>(ctx, p + nf * eps, r, depth, false, counts)
            } else {
                DVec3::ZERO
            }
        }
        Material::Glass { ior } => {
            if (RF || RR) && depth < ctx.max_depth {
                let eta = if outside { 1.0 / ior } else { ior };
                let cos_i = -d.dot(nf);
                let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
                let r = d + 2.0 * cos_i * nf;
                if sin2_t >= 1.0 || !RR {
                    // Total internal reflection
                    secondary::<F, SH, RF, RR>(ctx, p + nf * eps, r, depth, false, counts)
                } else {
                    let cos_t = (1.0 - sin2_t).sqrt();
                    let f = fresnel(eta, cos_i, cos_t);
                    let t_dir = eta * d + (eta * cos_i - cos_t) * nf;
                    let lr = secondary::<F, SH, RF, RR>(ctx, p + nf * eps, r, depth, false, counts);
                    let lt =
                        secondary::<F, SH, RF, RR>(ctx, p - nf * eps, t_dir, depth, true, counts);
                    f * lr + (1.0 - f) * lt
                }
            } else {
                DVec3::ZERO
            }
        }
    }
}

/// Shades primary hits found by another visibility pass (the implicit surfaces' image-space
/// subdivision): pixel `i`'s ray through its centre from `lens`, its hit (distance, unit
/// outward normal, material index). Shadows as asked; the other effects as the scene needs.
/// Returns the beauty pass and the secondary rays' counts.
pub fn shade_primary(
    s: &Scene,
    lens: &Lens,
    (w, h): (usize, usize),
    hits: &[Option<(f64, DVec3, usize)>],
    shadows: bool,
) -> (Vec<[f32; 3]>, RayCounts) {
    let effects = Effects::analyse(s);
    let (geo, materials) = build_geometry(s);
    let method = method_by_name(s.file.render.method.get_ref())
        .unwrap_or(&crate::shapes::sphere::methods::METHODS[4]);
    let ctx = Ctx::new(s, geo, materials, method, effects.depth, f64::EPSILON);
    pub(super) fn rows<const SH: bool, const RF: bool, const RR: bool>(
        ctx: &Ctx,
        lens: &Lens,
        w: usize,
        h: usize,
        hits: &[Option<(f64, DVec3, usize)>],
    ) -> (Vec<[f32; 3]>, RayCounts) {
        let rows: Vec<(Vec<[f32; 3]>, RayCounts)> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut counts = RayCounts::default();
                let row = (0..w)
                    .map(|x| {
                        let Some((t, n, material)) = hits[y * w + x] else {
                            return [0.0; 3];
                        };
                        let d = lens.dir(x as f64 + 0.5, y as f64 + 0.5);
                        let hit = geom::Hit {
                            t,
                            n,
                            material,
                            object: usize::MAX,
                        };
                        counts.left = MAX_TREE_SEGMENTS - 1;
                        pixel(shade::<f64, SH, RF, RR>(
                            ctx,
                            lens.pos,
                            d,
                            &hit,
                            1,
                            &mut counts,
                        ))
                    })
                    .collect();
                (row, counts)
            })
            .collect();
        let mut out = (Vec::with_capacity(w * h), RayCounts::default());
        for (r, c) in rows {
            out.0.extend(r);
            out.1 += c;
        }
        out
    }
    match (shadows, effects.reflection, effects.refraction) {
        (false, false, false) => rows::<false, false, false>(&ctx, lens, w, h, hits),
        (true, false, false) => rows::<true, false, false>(&ctx, lens, w, h, hits),
        (false, true, false) => rows::<false, true, false>(&ctx, lens, w, h, hits),
        (true, true, false) => rows::<true, true, false>(&ctx, lens, w, h, hits),
        (false, _, true) => rows::<false, true, true>(&ctx, lens, w, h, hits),
        (true, _, true) => rows::<true, true, true>(&ctx, lens, w, h, hits),
    }
}

/// A reflected or refracted ray from segment `depth`: its radiance, the ray and its miss
/// counted by kind. Black and not traced when its camera sample's tree has no segment left
/// ([`MAX_TREE_SEGMENTS`]).
pub(super) fn secondary<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
    ctx: &Ctx,
    o: DVec3,
    d: DVec3,
    depth: u32,
    refracted: bool,
    counts: &mut RayCounts,
) -> DVec3 {
    if counts.left == 0 {
        counts.budget_cut += 1;
        return DVec3::ZERO;
    }
    counts.left -= 1;
    if refracted {
        counts.refraction += 1;
    } else {
        counts.reflection += 1;
    }
    let (l, first) = radiance::<F, SH, RF, RR>(ctx, o, d, depth + 1, counts);
    if first.is_none() {
        if refracted {
            counts.refraction_miss += 1;
        } else {
            counts.reflection_miss += 1;
        }
    }
    l
}

/// Exact unpolarised Fresnel reflectance for relative index `eta` = n_i/n_t.
pub fn fresnel(eta: f64, cos_i: f64, cos_t: f64) -> f64 {
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Is anything between `o` and the light at distance `dist`? Glass may let the ray through:
/// with transmissive glass shadows (POV-Ray's rule) shadow rays go straight through glass, so
/// only other materials block them. An any-hit query: it stops at the first blocker.
pub(super) fn occluded<F: PickPrecision>(
    ctx: &Ctx,
    o: DVec3,
    wl: DVec3,
    dist: f64,
    counts: &mut RayCounts,
) -> bool {
    let transmissive = ctx.glass_shadows == GlassShadows::Transmissive;
    let blocks = |m: usize| !(transmissive && matches!(ctx.materials[m], Material::Glass { .. }));
    ctx.geo
        .occluded::<F>(ctx.method, o, wl, dist, blocks, &mut counts.tests)
}
