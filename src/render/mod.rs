//! A Whitted ray tracer that simulates only the effects a scene calls for.
//!
//! 1. [`Effects::analyse`] derives from the scene which effects it needs (shadow rays,
//!    reflection, refraction with Fresnel, the depth, supersampling), each with its reason.
//! 2. [`render`] picks the integrator instantiated for exactly that set: the effects are const
//!    generic parameters, so a diffuse-only scene runs a kernel with no specular code in it.
//! 3. Rays are counted by kind, tests by shape kind; the seed paper's budget (m+1)·d·M·N is
//!    reported beside the measured counts.
//!
//! Conventions (shared with the exporters of later work): right-handed, +y up; horizontal
//! field of view; pixel (x, y) samples at ((x + (i+½)/n)/W, (y + (j+½)/n)/H) for the n×n grid,
//! box filtered; point lights of intensity I (W/sr) give I·cosθ/d², directional lights of
//! irradiance E give E·cosθ, the ambient radiance A adds albedo·A; diffuse is albedo/π;
//! glass reflects F and transmits 1−F (exact unpolarised Fresnel, no η² factor), total internal
//! reflection reflects everything; `max_depth` counts ray segments, and a ray past it is black.
//!
//! **Ray-origin offset.** A secondary ray (shadow, reflection, refraction) starts at the hit
//! point moved along the geometric normal, to the side the ray leaves on, by `offset`:
//! `auto` = 16 ulps of the render precision × max(1, |p|∞), `none` = 0 (shows acne), or a
//! fixed distance.

pub mod export;
pub mod geom;
pub mod output;
pub mod scene;

use crate::shapes::sphere::methods::{method_by_name, Method, PickPrecision};
use geom::{Geometry, Object, Plane, Prim, TestCounts};
use glam::DVec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::{GlassShadows, Material, Scene, Shape};
use serde::Serialize;

/// The effects a scene needs, with the reason for each choice.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Effects {
    pub shadows: bool,
    pub reflection: bool,
    pub refraction: bool,
    pub depth: u32,
    pub supersampling: bool,
    pub reasons: Vec<String>,
}

impl Effects {
    /// Derives the needed effects from the scene.
    pub fn analyse(s: &Scene) -> Effects {
        let f = &s.file;
        let mut reasons = vec![];
        let mats = || f.shapes.iter().map(|sh| &f.materials[sh.material()]);
        let diffuse_lit = !(f.lights.is_empty() && f.directional.is_empty())
            && mats().any(|m| matches!(m, Material::Diffuse { .. }));
        // A lone convex shape or plane cannot shadow itself: occlusion needs two shapes, a mesh
        // or a torus (not convex)
        let occluders = f.shapes.len() >= 2
            || f.shapes
                .iter()
                .any(|s| matches!(s, Shape::Mesh { .. } | Shape::Torus { .. }) || s.is_implicit());
        let shadows = diffuse_lit && occluders;
        reasons.push(match (diffuse_lit, occluders) {
            (true, true) => format!(
                "shadows: on — {} light(s) light diffuse surfaces and {} shape(s) can occlude them",
                f.lights.len() + f.directional.len(),
                f.shapes.len()
            ),
            (false, _) => "shadows: off — no light reaches a diffuse surface".into(),
            (true, false) => {
                "shadows: off — a single convex shape or plane cannot occlude its own light".into()
            }
        });
        let reflection =
            mats().any(|m| matches!(m, Material::Mirror { .. } | Material::Glass { .. }));
        reasons.push(if reflection {
            "reflection: on — a mirror or glass material is used".into()
        } else {
            "reflection: off — no material reflects".into()
        });
        let refraction = mats().any(|m| matches!(m, Material::Glass { .. }));
        reasons.push(if refraction {
            "refraction + Fresnel: on — a glass material is used".into()
        } else {
            "refraction + Fresnel: off — no material transmits".into()
        });
        let implicit: Vec<&str> = f
            .shapes
            .iter()
            .filter(|s| s.is_implicit())
            .map(|s| match s {
                Shape::Sdf { .. } => "sdf",
                Shape::Blob { .. } => "blob",
                _ => "mpu",
            })
            .collect();
        reasons.push(if implicit.is_empty() {
            "sphere tracing: off — no implicit shape".into()
        } else {
            format!(
                "sphere tracing: on — {} implicit shape(s) ({})",
                implicit.len(),
                implicit.join(", ")
            )
        });
        let depth = if reflection { f.render.max_depth } else { 1 };
        reasons.push(if reflection {
            format!("depth: {depth} segments (render.max_depth)")
        } else {
            format!(
                "depth: 1 segment — nothing is specular (render.max_depth = {} is not needed)",
                f.render.max_depth
            )
        });
        let grid = *f.camera.grid.get_ref();
        let supersampling = grid > 1;
        reasons.push(if supersampling {
            format!("supersampling: on — {grid}×{grid} sub-pixel grid")
        } else {
            "supersampling: off — 1 sample per pixel".into()
        });
        Effects {
            shadows,
            reflection,
            refraction,
            depth,
            supersampling,
            reasons,
        }
    }

    /// Every effect on, at the scene's full depth (for measuring what specialisation saves).
    pub fn all(s: &Scene) -> Effects {
        let mut e = Effects::analyse(s);
        (e.shadows, e.reflection, e.refraction, e.depth) =
            (true, true, true, s.file.render.max_depth);
        e.supersampling = *s.file.camera.grid.get_ref() > 1;
        e.reasons.push("forced: every effect on".into());
        e
    }
}

/// Rays by kind and tests by shape kind.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct RayCounts {
    pub primary: u64,
    pub shadow: u64,
    pub reflection: u64,
    pub refraction: u64,
    /// Rays of each kind that hit nothing (a shadow ray that reaches its light counts here).
    pub primary_miss: u64,
    pub shadow_miss: u64,
    pub reflection_miss: u64,
    pub refraction_miss: u64,
    #[serde(flatten)]
    pub tests: TestCounts,
}

impl std::ops::AddAssign for RayCounts {
    fn add_assign(&mut self, o: Self) {
        self.primary += o.primary;
        self.shadow += o.shadow;
        self.reflection += o.reflection;
        self.refraction += o.refraction;
        self.primary_miss += o.primary_miss;
        self.shadow_miss += o.shadow_miss;
        self.reflection_miss += o.reflection_miss;
        self.refraction_miss += o.refraction_miss;
        self.tests += o.tests;
    }
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection + self.refraction
    }
}

/// The rendered image and what it cost.
pub struct Render {
    pub width: usize,
    pub height: usize,
    pub beauty: Vec<[f32; 3]>,
    pub depth: Vec<f32>,
    pub normal: Vec<[f32; 3]>,
    pub rays: Vec<f32>,
    pub counts: RayCounts,
    pub effects: Effects,
    pub seconds: f64,
    /// Sampled sphere-test inputs, when [`Overrides::record_every`] asked for them.
    pub recorded: Vec<geom::RecordedTest>,
    pub method: &'static str,
    pub precision: &'static str,
}

/// Render-time options that override the scene file.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    pub method: Option<&'static Method>,
    pub precision: Option<&'static str>,
    pub grid: Option<u32>,
    /// Image size (width, height) instead of the camera's.
    pub size: Option<(u32, u32)>,
    pub force_all_effects: bool,
    pub progress: bool,
    /// Test every object for every ray (no BVH), as seed 000's renderer did.
    pub flat: bool,
    /// With `flat`: test every object this many times (0 or 1: once). The extra passes change
    /// no hit, so the time they add is the sphere tests' own in-frame cost.
    pub flat_passes: u32,
    /// Record the inputs of every n-th sphere test (0: none); costs time, so not for timed runs.
    pub record_every: u64,
}

/// Everything the integrator reads.
struct Ctx<'a> {
    geo: Geometry,
    materials: Vec<Material>,
    lights: &'a [scene::Light],
    directional: &'a [scene::DirectionalLight],
    ambient: DVec3,
    method: &'static Method,
    glass_shadows: GlassShadows,
    max_depth: u32,
    offset: Option<f64>,
    ulp16: f64,
}

impl<'a> Ctx<'a> {
    /// The scene's lights and settings around its geometry; `ulp` is the render precision's.
    fn new(
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

/// Builds the geometry list from the scene (materials by index).
pub fn build_geometry(s: &Scene) -> (Geometry, Vec<Material>) {
    let names: Vec<&String> = s.file.materials.keys().collect();
    let materials = s.file.materials.values().cloned().collect();
    let mi = |n: &String| names.iter().position(|k| *k == n).unwrap_or(0);
    let v = |a: [f64; 3]| DVec3::from_array(a);
    let (mut objects, mut planes, mut marchers) = (vec![], vec![], vec![]);
    for (i, sh) in s.file.shapes.iter().enumerate() {
        let material = mi(sh.material());
        match sh {
            Shape::Sphere { center, radius, .. } => objects.push(Object {
                prim: Prim::Sphere {
                    c: v(*center),
                    r: *radius,
                },
                material,
            }),
            Shape::Disc {
                center,
                normal,
                radius,
                ..
            } => objects.push(Object {
                prim: Prim::Disc {
                    c: v(*center),
                    n: v(*normal).normalize(),
                    r: *radius,
                },
                material,
            }),
            Shape::Plane { point, normal, .. } => planes.push(Plane {
                p: v(*point),
                n: v(*normal).normalize(),
                material,
            }),
            Shape::Mesh { .. } => {
                for t in &s.meshes[&i] {
                    let (a, b, c) = (v(t[0]), v(t[1]), v(t[2]));
                    objects.push(Object {
                        prim: Prim::Tri {
                            v0: a,
                            e1: b - a,
                            e2: c - a,
                        },
                        material,
                    });
                }
            }
            Shape::Box { min, max, .. } => objects.push(Object {
                prim: Prim::Box {
                    lo: v(*min),
                    hi: v(*max),
                },
                material,
            }),
            Shape::Cylinder {
                base,
                radius,
                height,
                ..
            } => {
                // Lateral surface and two cap discs, normals outward
                let b = v(*base);
                let top = b + DVec3::Y * *height;
                let side = Prim::CylinderSide {
                    base: b,
                    r: *radius,
                    h: *height,
                };
                let caps =
                    [(b, -DVec3::Y), (top, DVec3::Y)].map(|(c, n)| Prim::Disc { c, n, r: *radius });
                for prim in std::iter::once(side).chain(caps) {
                    objects.push(Object { prim, material });
                }
            }
            Shape::Ellipsoid { center, radii, .. } => objects.push(Object {
                prim: Prim::Ellipsoid {
                    c: v(*center),
                    radii: v(*radii),
                },
                material,
            }),
            Shape::Torus {
                center,
                major,
                minor,
                ..
            } => objects.push(Object {
                prim: Prim::Torus {
                    c: v(*center),
                    major: *major,
                    minor: *minor,
                },
                material,
            }),
            Shape::Sdf { .. } | Shape::Blob { .. } | Shape::Mpu { .. } => {
                let m = crate::implicit::march::Marcher::new(vec![s.implicits[&i].clone()]);
                let pad = 2.0 * (m.hi - m.lo).length() * 0.01;
                objects.push(Object {
                    prim: Prim::Implicit {
                        k: marchers.len(),
                        lo: m.lo - pad,
                        hi: m.hi + pad,
                    },
                    material,
                });
                marchers.push(m);
            }
        }
    }
    (
        Geometry::new(objects, planes).with_marchers(marchers),
        materials,
    )
}

/// Renders a scene with the integrator specialised to its effects.
pub fn render(s: &Scene, ov: &Overrides) -> Render {
    let effects = if ov.force_all_effects {
        Effects::all(s)
    } else {
        Effects::analyse(s)
    };
    let method = ov.method.unwrap_or_else(|| {
        method_by_name(s.file.render.method.get_ref())
            .unwrap_or(&crate::shapes::sphere::methods::METHODS[4])
    });
    let precision: &'static str =
        ov.precision
            .unwrap_or(if s.file.render.precision.get_ref() == "f32" {
                "f32"
            } else {
                "f64"
            });
    let grid = ov.grid.unwrap_or(*s.file.camera.grid.get_ref());
    let size = ov.size.unwrap_or((
        *s.file.camera.width.get_ref(),
        *s.file.camera.height.get_ref(),
    ));
    let size = (size.0.max(1) as usize, size.1.max(1) as usize);
    let mut effects = effects;
    effects.supersampling = grid > 1;
    let (geo, materials) = build_geometry(s);
    let store = std::sync::Arc::new(std::sync::Mutex::new(vec![]));
    let geo = if ov.flat {
        geo.flat(ov.flat_passes)
    } else {
        geo
    };
    let geo = geo.recording(ov.record_every, store.clone());
    let ulp = if precision == "f32" {
        f32::EPSILON as f64
    } else {
        f64::EPSILON
    };
    let ctx = Ctx::new(s, geo, materials, method, effects.depth, ulp);
    // Pick the kernel for exactly this set of effects
    macro_rules! kernel {
        ($($sh:literal, $rf:literal, $rr:literal);*) => {
            match (effects.shadows, effects.reflection, effects.refraction, precision) {
                $(
                    ($sh, $rf, $rr, "f32") => run::<f32, $sh, $rf, $rr>(&ctx, s, size, grid, ov.progress),
                    ($sh, $rf, $rr, _) => run::<f64, $sh, $rf, $rr>(&ctx, s, size, grid, ov.progress),
                )*
            }
        };
    }
    let start = std::time::Instant::now();
    let (beauty, depth, normal, rays, counts) = kernel!(
        false, false, false; true, false, false; false, true, false; true, true, false;
        false, true, true; true, true, true; false, false, true; true, false, true
    );
    let seconds = start.elapsed().as_secs_f64();
    let recorded = std::mem::take(&mut *store.lock().unwrap_or_else(|e| e.into_inner()));
    Render {
        width: size.0,
        height: size.1,
        beauty,
        depth,
        normal,
        rays,
        counts,
        effects,
        seconds,
        recorded,
        method: method.name,
        precision,
    }
}

/// The pinhole camera: right-handed, horizontal field of view, `w × h` pixels.
#[derive(Clone, Copy, Debug)]
pub struct Lens {
    pub pos: DVec3,
    fwd: DVec3,
    right: DVec3,
    up: DVec3,
    half_w: f64,
    half_h: f64,
    w: f64,
    h: f64,
}

impl Lens {
    pub fn new(s: &Scene, w: usize, h: usize) -> Lens {
        let cam = &s.file.camera;
        let pos = DVec3::from_array(cam.position);
        let fwd = (DVec3::from_array(cam.look_at) - pos).normalize();
        let right = fwd.cross(DVec3::from_array(cam.up)).normalize();
        let up = right.cross(fwd);
        let half_w = (cam.fov.to_radians() * 0.5).tan();
        Lens {
            pos,
            fwd,
            right,
            up,
            half_w,
            half_h: half_w * h as f64 / w as f64,
            w: w as f64,
            h: h as f64,
        }
    }

    /// The unit direction through image point `(x, y)` in pixels (pixel centres at `+½`).
    #[inline]
    pub fn dir(&self, x: f64, y: f64) -> DVec3 {
        let (u, v) = (x / self.w, y / self.h);
        (self.fwd
            + self.right * ((2.0 * u - 1.0) * self.half_w)
            + self.up * ((1.0 - 2.0 * v) * self.half_h))
            .normalize()
    }
}

type Planes = (Vec<[f32; 3]>, Vec<f32>, Vec<[f32; 3]>, Vec<f32>, RayCounts);

/// The render loop: rows in parallel, one kernel instantiation per effect set.
fn run<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
    ctx: &Ctx,
    s: &Scene,
    (w, h): (usize, usize),
    grid: u32,
    progress: bool,
) -> Planes {
    let lens = Lens::new(s, w, h);
    let pos = lens.pos;
    let bar = if progress {
        ProgressBar::new(h as u64)
    } else {
        ProgressBar::hidden()
    };
    let rows: Vec<Planes> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut counts = RayCounts::default();
            let mut row = (
                vec![[0f32; 3]; w],
                vec![0f32; w],
                vec![[0f32; 3]; w],
                vec![0f32; w],
            );
            for x in 0..w {
                let before = counts.total();
                let (mut sum, mut dsum, mut nsum, mut hits) = (DVec3::ZERO, 0.0, DVec3::ZERO, 0u32);
                for j in 0..grid {
                    for i in 0..grid {
                        // Sub-pixel cell centre
                        let d = lens.dir(
                            x as f64 + (i as f64 + 0.5) / grid as f64,
                            y as f64 + (j as f64 + 0.5) / grid as f64,
                        );
                        counts.primary += 1;
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
                row.0[x] = (sum * k).as_vec3().to_array();
                row.1[x] = if hits > 0 {
                    (dsum / hits as f64) as f32
                } else {
                    0.0
                };
                row.2[x] = if hits > 0 {
                    (nsum / hits as f64).as_vec3().to_array()
                } else {
                    [0.0; 3]
                };
                row.3[x] = (counts.total() - before) as f32;
            }
            bar.inc(1);
            (row.0, row.1, row.2, row.3, counts)
        })
        .collect();
    bar.finish_and_clear();
    let mut out: Planes = (
        Vec::with_capacity(w * h),
        Vec::with_capacity(w * h),
        Vec::with_capacity(w * h),
        Vec::with_capacity(w * h),
        RayCounts::default(),
    );
    for r in rows {
        out.0.extend(r.0);
        out.1.extend(r.1);
        out.2.extend(r.2);
        out.3.extend(r.3);
        out.4 += r.4;
    }
    out
}

/// Radiance along a ray at segment `depth`; also the first hit's distance and normal.
fn radiance<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
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
fn shade<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
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
                if cos <= 0.0 {
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
                counts.reflection += 1;
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
                    counts.reflection += 1;
                    secondary::<F, SH, RF, RR>(ctx, p + nf * eps, r, depth, false, counts)
                } else {
                    let cos_t = (1.0 - sin2_t).sqrt();
                    let f = fresnel(eta, cos_i, cos_t);
                    counts.reflection += 1;
                    counts.refraction += 1;
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
    fn rows<const SH: bool, const RF: bool, const RR: bool>(
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
                        shade::<f64, SH, RF, RR>(ctx, lens.pos, d, &hit, 1, &mut counts)
                            .as_vec3()
                            .to_array()
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

/// A reflected or refracted ray from segment `depth`: its radiance, its miss counted by kind.
fn secondary<F: PickPrecision, const SH: bool, const RF: bool, const RR: bool>(
    ctx: &Ctx,
    o: DVec3,
    d: DVec3,
    depth: u32,
    refracted: bool,
    counts: &mut RayCounts,
) -> DVec3 {
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

/// Is anything between `o` and the light at distance `dist`? Glass may let the ray through.
fn occluded<F: PickPrecision>(
    ctx: &Ctx,
    o: DVec3,
    wl: DVec3,
    dist: f64,
    counts: &mut RayCounts,
) -> bool {
    let mut o = o;
    let mut left = dist;
    loop {
        let Some(h) = ctx
            .geo
            .intersect::<F>(ctx.method, o, wl, left, &mut counts.tests)
        else {
            return false;
        };
        let glass = matches!(ctx.materials[h.material], Material::Glass { .. });
        if !(glass && ctx.glass_shadows == GlassShadows::Transmissive) {
            return true;
        }
        // POV-Ray's rule: continue straight through the glass, unrefracted
        let p = o + h.t * wl;
        let step = h.t + ctx.ulp16 * p.abs().max_element().max(1.0);
        o += wl * step;
        left -= step;
        if left <= 0.0 {
            return false;
        }
    }
}

/// The seed paper's budget (m+1)·d·M·N beside the measured counts.
pub fn budget_line(r: &Render, lights: usize) -> String {
    let eye = r.counts.primary + r.counts.reflection + r.counts.refraction;
    let d = eye as f64 / r.counts.primary.max(1) as f64;
    let mn = r.counts.primary;
    let formula = (lights as f64 + 1.0) * d * mn as f64;
    format!(
        "seed budget (m+1)·d·M·N with m = {lights} light(s), d = {d:.3} measured eye rays per primary, M·N = {mn} samples: {formula:.0}; measured total {} ({:.3}× the budget)",
        r.counts.total(),
        r.counts.total() as f64 / formula.max(1.0)
    )
}
