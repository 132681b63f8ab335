//! Scene geometry in `f64`, a BVH over every bounded shape, and the ray–shape tests.
//!
//! Spheres go through the audited method and precision chosen for the render: the ray and the
//! sphere are rounded to that precision, the method runs, and its `t` comes back as `f64`.
//! Discs, planes and triangles (Möller–Trumbore) are intersected in `f64`. Boxes, cylinder
//! sides, ellipsoids and tori go through the audited robust routines of [`crate::shapes::shape`] in
//! `f64`, with the ray moved into each routine's object space: translated by the shape's
//! centre (or base), and for the cylinder and torus, whose routines are around z, with y and z
//! swapped (a reflection: `t` is unchanged, and normals are swapped back).
//!
//! The BVH is built with the surface area heuristic (binned; an object's test is weighed as
//! four box tests, so leaves mostly hold one object), then collapsed into a 4-wide tree whose
//! nodes hold their children's boxes side by side, tested at once. The nearest hit's search
//! enters the children nearest first and skips any put aside that starts beyond the hit found
//! so far; shadow rays ask [`Geometry::occluded`], which stops at the first blocker. The box
//! test is conservative: pbrt's padding of the far distance, and a ray running exactly in a
//! face's plane counts as entering the box. Each ray picks once per axis which corner it meets
//! first (from the sign of `1/d`), so a lane costs two differences, two products, a max and a
//! min. Both queries are one body compiled twice, for the baseline x86-64 (two `f64` lanes per
//! instruction) and for AVX2 (four), chosen at run time; neither build contracts or reorders
//! an operation, so they answer the same bit for bit. Counters: `bvh_nodes` counts boxes tested
//! (one per child a wide node holds), as it counted nodes visited in the binary tree.

use crate::shapes::sphere::methods::{Method, PickPrecision, Ray as MRay, Sphere as MSphere};
use glam::DVec3;

/// A bounded primitive.
#[derive(Clone, Copy, Debug)]
pub enum Prim {
    /// A sphere.
    Sphere {
        /// Centre.
        c: DVec3,
        /// Radius.
        r: f64,
    },
    /// A flat disc (a cylinder's cap).
    Disc {
        /// Centre.
        c: DVec3,
        /// Unit normal.
        n: DVec3,
        /// Radius.
        r: f64,
    },
    /// A triangle `v0, v0 + e1, v0 + e2`.
    Tri {
        /// First vertex.
        v0: DVec3,
        /// Edge from `v0` to the second vertex.
        e1: DVec3,
        /// Edge from `v0` to the third vertex.
        e2: DVec3,
    },
    /// Axis-aligned box.
    Box {
        /// Minimum corner.
        lo: DVec3,
        /// Maximum corner.
        hi: DVec3,
    },
    /// The lateral surface of a cylinder from `base` up `h` along +y (caps are discs).
    CylinderSide {
        /// Centre of the bottom cap.
        base: DVec3,
        /// Radius.
        r: f64,
        /// Height along +y.
        h: f64,
    },
    /// Ellipsoid with semi-axes `radii` along x, y, z.
    Ellipsoid {
        /// Centre.
        c: DVec3,
        /// Semi-axes along x, y, z.
        radii: DVec3,
    },
    /// Torus in the xz plane around +y through `c`.
    Torus {
        /// Centre.
        c: DVec3,
        /// Distance from the centre to the tube's centre line.
        major: f64,
        /// Tube radius.
        minor: f64,
    },
    /// An implicit surface: sphere traced by marcher `k` of the geometry, inside `[lo, hi]`
    /// grown by the marcher's margin.
    Implicit {
        /// Index of the marcher in [`Geometry`]'s list of implicit fields.
        k: usize,
        /// Minimum corner of the field's bounding box.
        lo: DVec3,
        /// Maximum corner of the field's bounding box.
        hi: DVec3,
    },
}

/// A primitive with its material index.
#[derive(Clone, Copy, Debug)]
pub struct Object {
    /// The primitive.
    pub prim: Prim,
    /// Index into the scene's materials.
    pub material: usize,
}

/// An infinite plane (kept out of the BVH).
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    /// A point on the plane.
    pub p: DVec3,
    /// Unit normal.
    pub n: DVec3,
    /// Index into the scene's materials.
    pub material: usize,
}

/// The nearest hit: distance, geometric normal (unit, not yet faced), material.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Ray parameter of the hit (the point is `o + t·d`).
    pub t: f64,
    /// Unit geometric normal, not yet turned to face the ray.
    pub n: DVec3,
    /// Index into the scene's materials.
    pub material: usize,
    /// Index of the object hit; for plane `i`, `usize::MAX − i`.
    pub object: usize,
}

/// Counters of intersection tests, kept per tile and summed.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct TestCounts {
    /// Ray–sphere tests run (by the chosen sphere method).
    pub sphere_tests: u64,
    /// Sphere tests the method answered with a hit (any `t`, before the nearest-hit choice).
    pub sphere_hits: u64,
    /// Intersection tests against every other primitive kind.
    pub other_tests: u64,
    /// BVH nodes whose box was tested: each child of a 4-wide node visited (as each node
    /// visited of the binary tree this renderer used before).
    pub bvh_nodes: u64,
    /// Rays sphere traced against an implicit shape, and their field evaluations.
    pub implicit_tests: u64,
    /// Field evaluations (sphere-tracing steps) over those rays.
    pub march_steps: u64,
}

impl std::ops::AddAssign for TestCounts {
    fn add_assign(&mut self, o: Self) {
        self.sphere_tests += o.sphere_tests;
        self.sphere_hits += o.sphere_hits;
        self.other_tests += o.other_tests;
        self.bvh_nodes += o.bvh_nodes;
        self.implicit_tests += o.implicit_tests;
        self.march_steps += o.march_steps;
    }
}

type SphereFn<F> =
    fn(&MRay<F>, &MSphere<F>) -> Option<crate::shapes::sphere::methods::SphereHit<F>>;

/// Intersects a sphere through the audited method in precision `F`.
#[inline]
fn sphere_t<F: PickPrecision>(f: SphereFn<F>, o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<f64> {
    let v = |x: DVec3| F::vec3(F::from_f64(x.x), F::from_f64(x.y), F::from_f64(x.z));
    f(
        &MRay {
            origin: v(o),
            dir: v(d),
        },
        &MSphere {
            center: v(c),
            radius: F::from_f64(r),
        },
    )
    .map(|h| h.t.to_f64())
}

/// Axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: DVec3,
    hi: DVec3,
}

impl Aabb {
    fn empty() -> Self {
        Aabb {
            lo: DVec3::splat(f64::INFINITY),
            hi: DVec3::splat(f64::NEG_INFINITY),
        }
    }
    fn grow(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
    fn centre(self) -> DVec3 {
        (self.lo + self.hi) * 0.5
    }
    /// Half the surface area (the SAH's weight); 0 for an empty box.
    fn half_area(self) -> f64 {
        let e = (self.hi - self.lo).max(DVec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

fn bounds(p: &Prim) -> Aabb {
    match *p {
        Prim::Sphere { c, r } => Aabb {
            lo: c - DVec3::splat(r),
            hi: c + DVec3::splat(r),
        },
        Prim::Disc { c, n, r } => {
            // Extent of a disc along each axis: r·sqrt(1 − n_i²)
            let e = DVec3::new(
                (1.0 - n.x * n.x).max(0.0).sqrt(),
                (1.0 - n.y * n.y).max(0.0).sqrt(),
                (1.0 - n.z * n.z).max(0.0).sqrt(),
            ) * r;
            Aabb {
                lo: c - e,
                hi: c + e,
            }
        }
        Prim::Tri { v0, e1, e2 } => {
            let (v1, v2) = (v0 + e1, v0 + e2);
            Aabb {
                lo: v0.min(v1).min(v2),
                hi: v0.max(v1).max(v2),
            }
        }
        Prim::Box { lo, hi } => Aabb { lo, hi },
        Prim::CylinderSide { base, r, h } => Aabb {
            lo: base - DVec3::new(r, 0.0, r),
            hi: base + DVec3::new(r, h, r),
        },
        Prim::Ellipsoid { c, radii } => Aabb {
            lo: c - radii,
            hi: c + radii,
        },
        Prim::Torus { c, major, minor } => {
            let e = DVec3::new(major + minor, minor, major + minor);
            Aabb {
                lo: c - e,
                hi: c + e,
            }
        }
        Prim::Implicit { lo, hi, .. } => Aabb { lo, hi },
    }
}

/// Rays a renderer asks about a routine primitive `p` ([`solid_hit`]): `n` camera rays from `cam` towards uniform points of its
/// bounds (padded by 10 % on each side), and for each hit three secondary rays spawned from the
/// hit point, offset along the normal by the renderer's `auto` rule (16 ulps × max(1, |p|∞)),
/// in uniform random directions on the side they leave on. Deterministic for a given `rng`.
pub fn sample_rays(
    p: &Prim,
    cam: DVec3,
    n: usize,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> Vec<(DVec3, DVec3)> {
    use rand::Rng;
    let b = bounds(p);
    let uniform = |rng: &mut rand_chacha::ChaCha8Rng, lo: f64, hi: f64| {
        DVec3::new(
            rng.random_range(lo..hi),
            rng.random_range(lo..hi),
            rng.random_range(lo..hi),
        )
    };
    let mut rays = vec![];
    for _ in 0..n {
        let d = (b.lo + (b.hi - b.lo) * uniform(rng, -0.1, 1.1) - cam).normalize();
        rays.push((cam, d));
        let Some((t, nrm)) = solid_hit(p, cam, d) else {
            continue;
        };
        let hit = cam + t * d;
        let eps = 16.0 * f64::EPSILON * hit.abs().max_element().max(1.0);
        for _ in 0..3 {
            // A uniform direction: rejection from the cube
            let w = loop {
                let v = uniform(rng, -1.0, 1.0);
                if v.length_squared() > 1e-6 && v.length_squared() <= 1.0 {
                    break v.normalize();
                }
            };
            let side = if w.dot(nrm) >= 0.0 { nrm } else { -nrm };
            rays.push((hit + side * eps, w));
        }
    }
    rays
}

/// World (x, y, z) → the object space of a routine around z: (x, z, y). Its own inverse.
#[inline]
fn swap_yz(v: DVec3) -> [f64; 3] {
    [v.x, v.z, v.y]
}

/// A unit normal from a gradient, or `None` if it is zero or not finite.
#[inline]
fn unit(g: DVec3) -> Option<DVec3> {
    let n = g.normalize_or_zero();
    (n != DVec3::ZERO).then_some(n)
}

/// The outward normal of the box face nearest to `p` (relative to each axis' extent).
fn box_normal(p: DVec3, lo: DVec3, hi: DVec3) -> DVec3 {
    let ext = hi - lo;
    let (mut best, mut n) = (f64::INFINITY, DVec3::X);
    for k in 0..3 {
        for (face, sign) in [(lo[k], -1.0), (hi[k], 1.0)] {
            let gap = (p[k] - face).abs() / ext[k];
            if gap < best {
                best = gap;
                n = DVec3::ZERO;
                n[k] = sign;
            }
        }
    }
    n
}

/// A ray in a primitive's object space, as its robust routine receives it: translated by the
/// centre (the cylinder's base), with y and z swapped for the cylinder and torus (routines
/// around z); a box stays in world space.
pub fn object_ray(p: &Prim, o: DVec3, d: DVec3) -> ([f64; 3], [f64; 3]) {
    match *p {
        Prim::CylinderSide { base, .. } => (swap_yz(o - base), swap_yz(d)),
        Prim::Torus { c, .. } => (swap_yz(o - c), swap_yz(d)),
        Prim::Ellipsoid { c, .. } => ((o - c).to_array(), d.to_array()),
        _ => (o.to_array(), d.to_array()),
    }
}

/// The input of the audit shape (`crate::shapes::shape_by_name`) that asks exactly what
/// [`solid_hit`] asks its routine, for replay (`rayproof probe`) and the exact oracle. `None`
/// for the ellipsoid, whose routine takes semi-axes while the audit's shape is
/// x² + m²y² + n²z² = r² (1/m = b/a is not exact in general), and for non-routine primitives.
pub fn routine_input(p: &Prim, o: DVec3, d: DVec3) -> Option<(&'static str, Vec<f64>)> {
    let (ob, db) = object_ray(p, o, d);
    let ray = ob.into_iter().chain(db);
    match *p {
        Prim::Box { lo, hi } => Some((
            "box",
            ray.chain(lo.to_array()).chain(hi.to_array()).collect(),
        )),
        Prim::CylinderSide { r, h, .. } => Some(("cylinder", ray.chain([r, 1.0, h]).collect())),
        Prim::Torus { major, minor, .. } => Some(("torus", ray.chain([major, minor]).collect())),
        _ => None,
    }
}

/// The robust routines' hits, in world space: `t` and the unit outward normal (`None` for a
/// miss, and for primitives that are not intersected by a routine).
#[inline]
pub fn solid_hit(p: &Prim, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    use crate::shapes::{aabb, quadric, torus};
    let (ob, db) = object_ray(p, o, d);
    let at = |t: f64| DVec3::from_array(ob) + t * DVec3::from_array(db);
    match *p {
        Prim::Box { lo, hi } => {
            let t = aabb::box_robust(ob, db, lo.to_array(), hi.to_array())?;
            Some((t, box_normal(o + t * d, lo, hi)))
        }
        Prim::CylinderSide { r, h, .. } => {
            let t = quadric::cylinder_robust(ob, db, r, h)?;
            // Radial direction of the hit point (object x, y = world x, z)
            let q = at(t);
            Some((t, unit(DVec3::new(q.x, 0.0, q.y))?))
        }
        Prim::Ellipsoid { radii, .. } => {
            let t = quadric::ellipsoid_robust(ob, db, radii.to_array())?;
            let g = quadric::ellipsoid_normal(at(t).to_array(), radii.to_array());
            Some((t, unit(DVec3::from_array(g))?))
        }
        Prim::Torus { major, minor, .. } => {
            // The routine's own hit point is accurate near the torus even for far origins
            let (t, q) = torus::torus_robust_hit(ob, db, major, minor)?;
            let g = torus::torus_normal(q, major, minor);
            Some((t, unit(DVec3::from_array(swap_yz(DVec3::from_array(g))))?))
        }
        _ => None,
    }
}

#[derive(Clone, Copy, Debug)]
struct Node {
    b: Aabb,
    /// Leaf: first object and count; inner: index of the right child (left is next).
    start: u32,
    count: u32,
}

/// A node of the 4-wide tree the renderer walks: up to four children's boxes side by side, one
/// lane each (structure of arrays, so that one box test covers the four lanes at once).
#[derive(Clone, Copy, Debug)]
struct Node4 {
    /// Corners: `b[0][axis][lane]` the minimum, `b[1][axis][lane]` the maximum.
    b: [[[f64; 4]; 3]; 2],
    /// Per lane: a leaf's first object, or an inner child's node index.
    child: [u32; 4],
    /// Per lane: a leaf's object count, or 0 for an inner child.
    count: [u32; 4],
    /// Lanes in use (the others hold boxes no ray enters).
    lanes: u32,
}

/// What the slab tests need of a ray, computed once per ray: origin, reciprocal direction, and
/// per axis which corner (`b[near[k]]`) is the plane the ray meets first (the minimum when
/// `1/d` has its sign bit clear, so −0 counts as negative).
#[derive(Clone, Copy, Debug)]
struct Slabs {
    o: [f64; 3],
    inv_d: [f64; 3],
    near: [usize; 3],
}

impl Slabs {
    #[inline(always)]
    fn new(o: DVec3, d: DVec3) -> Slabs {
        let inv_d = d.recip().to_array();
        Slabs {
            o: o.to_array(),
            inv_d,
            near: inv_d.map(|x| x.is_sign_negative() as usize),
        }
    }
}

impl Node4 {
    /// The four lanes' slab tests at once, with pbrt's far-distance padding (1 + 2γ₃): the
    /// entry distance (clamped at 0) of each lane the ray meets before `tmax`, `+∞` for the
    /// others. A NaN slab distance (0·∞: the ray runs in a face's plane) leaves the interval as
    /// it is, so such a ray counts as meeting the box.
    #[inline(always)]
    fn enter(&self, r: &Slabs, tmax: f64) -> [f64; 4] {
        // The interval starts as [0, tmax]; each slab narrows it. The near and far planes are
        // the ray's (no per-lane swap), and the updates are written as comparisons, so that a
        // NaN loses and each is one min or max instruction
        let (mut tn, mut tf) = ([0.0; 4], [tmax; 4]);
        for k in 0..3 {
            let (pn, pf) = (&self.b[r.near[k]][k], &self.b[1 - r.near[k]][k]);
            for i in 0..4 {
                let near = (pn[i] - r.o[k]) * r.inv_d[k];
                let far = (pf[i] - r.o[k]) * r.inv_d[k];
                tn[i] = if near > tn[i] { near } else { tn[i] };
                tf[i] = if far < tf[i] { far } else { tf[i] };
            }
        }
        let mut t = [f64::INFINITY; 4];
        for i in 0..4 {
            let met = tn[i] <= tf[i] * (1.0 + 2.0 * 3.0 * f64::EPSILON) && tn[i] < tmax;
            t[i] = if met { tn[i] } else { f64::INFINITY };
        }
        t
    }
}

/// One recorded ray–sphere test: origin, direction, centre, radius (as given to the method).
pub type RecordedTest = [f64; 10];

/// The scene's geometry: BVH over objects (or a flat list), plus infinite planes.
#[derive(Clone, Debug)]
pub struct Geometry {
    /// The bounded primitives, in BVH order.
    pub objects: Vec<Object>,
    /// The infinite planes, tested apart from the BVH.
    pub planes: Vec<Plane>,
    nodes: Vec<Node4>,
    /// Test every object for every ray, as renderers without acceleration did (seed 000's era),
    /// `passes` times over (a second pass changes no hit: it measures the tests' own cost).
    flat: bool,
    passes: u32,
    /// Keep every n-th sphere test's inputs (n, store), to replay them in a timing loop.
    record: Option<(u64, std::sync::Arc<std::sync::Mutex<Vec<RecordedTest>>>)>,
    /// One sphere tracer per implicit shape, for [`Prim::Implicit`].
    pub marchers: Vec<crate::implicit::march::Marcher>,
    /// Whether the CPU runs the AVX2 build of the queries (the same code, four `f64` box lanes
    /// per instruction instead of two; the same results bit for bit).
    #[cfg(target_arch = "x86_64")]
    avx2: bool,
}

impl Geometry {
    /// Builds the BVH with the surface area heuristic (binned, `SAH_BINS` bins per axis).
    pub fn new(objects: Vec<Object>, planes: Vec<Plane>) -> Geometry {
        let mut binary = vec![];
        let mut items: Vec<Item> = objects
            .iter()
            .enumerate()
            .map(|(k, o)| {
                let b = bounds(&o.prim);
                Item {
                    b,
                    c: b.centre(),
                    k,
                }
            })
            .collect();
        if !items.is_empty() {
            build(&mut items, 0, 0, &mut binary);
        }
        let mut nodes = vec![];
        if !binary.is_empty() {
            widen(&binary, 0, &mut nodes);
        }
        // Objects in leaf order
        let objects = items.iter().map(|it| objects[it.k]).collect();
        Geometry {
            objects,
            planes,
            nodes,
            flat: false,
            passes: 1,
            record: None,
            marchers: vec![],
            #[cfg(target_arch = "x86_64")]
            avx2: crate::numerics::cpu::avx2(),
        }
    }

    /// The sphere tracers of the [`Prim::Implicit`] objects (by their `k`).
    pub fn with_marchers(mut self, marchers: Vec<crate::implicit::march::Marcher>) -> Geometry {
        self.marchers = marchers;
        self
    }

    /// The same objects without the BVH: every ray tests every object, `passes` (≥ 1) times.
    pub fn flat(mut self, passes: u32) -> Geometry {
        self.flat = true;
        self.passes = passes.max(1);
        self
    }

    /// Records the inputs of every `every`-th sphere test (each image row counts its own) into
    /// `store`.
    pub fn recording(
        mut self,
        every: u64,
        store: std::sync::Arc<std::sync::Mutex<Vec<RecordedTest>>>,
    ) -> Geometry {
        self.record = (every > 0).then_some((every, store));
        self
    }

    /// Tests object `k` (recording the test if asked): its `t` and unit normal, any sign of `t`.
    #[inline]
    fn test<F: PickPrecision>(
        &self,
        f: SphereFn<F>,
        k: usize,
        o: DVec3,
        d: DVec3,
        counts: &mut TestCounts,
    ) -> Option<(f64, DVec3)> {
        let obj = &self.objects[k];
        if let (Some((every, store)), Prim::Sphere { c, r }) = (&self.record, obj.prim) {
            if counts.sphere_tests.is_multiple_of(*every) {
                if let Ok(mut v) = store.lock() {
                    v.push([o.x, o.y, o.z, d.x, d.y, d.z, c.x, c.y, c.z, r]);
                }
            }
        }
        prim_hit::<F>(f, &obj.prim, o, d, counts, &self.marchers)
    }

    /// Walks the BVH, calling `leaf(objects, limit)` on each leaf whose box the ray enters
    /// before `limit`; `leaf` may lower `limit`, or return `true` to stop. `NEAREST_FIRST`
    /// visits the children hit in order of entry (the nearest hit's search); without it they go
    /// in stored order (the any-hit search, for which order saves nothing and sorting costs).
    #[inline(always)]
    fn traverse<const NEAREST_FIRST: bool>(
        &self,
        o: DVec3,
        d: DVec3,
        limit: &mut f64,
        counts: &mut TestCounts,
        mut leaf: impl FnMut(std::ops::Range<usize>, &mut f64, &mut TestCounts) -> bool,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let slabs = Slabs::new(o, d);
        // Children put aside (child, count, entry distance); three per level at most. Only the
        // entries below `sp` are ever read, so the array is left uninitialised (zeroing it cost
        // more than a box test per ray)
        let mut stack = [const { std::mem::MaybeUninit::<(u32, u32, f64)>::uninit() }; STACK];
        let mut sp = 0;
        let (mut child, mut count) = (0u32, 0u32);
        loop {
            if count > 0 {
                let start = child as usize;
                if leaf(start..start + count as usize, limit, counts) {
                    return;
                }
            } else {
                // The four boxes at once; the lanes hit, nearest last
                let node = &self.nodes[child as usize];
                counts.bvh_nodes += node.lanes as u64;
                let t = node.enter(&slabs, *limit);
                let mut hits = [(0.0f64, 0u32, 0u32); 4];
                let mut n = 0;
                for (i, &ti) in t.iter().enumerate().take(node.lanes as usize) {
                    if ti < f64::INFINITY {
                        let mut j = n;
                        while NEAREST_FIRST && j > 0 && hits[j - 1].0 < ti {
                            hits[j] = hits[j - 1];
                            j -= 1;
                        }
                        hits[j] = (ti, node.child[i], node.count[i]);
                        n += 1;
                    }
                }
                if n > 0 {
                    for &(t, c, k) in &hits[..n - 1] {
                        stack[sp].write((c, k, t));
                        sp += 1;
                    }
                    (child, count) = (hits[n - 1].1, hits[n - 1].2);
                    continue;
                }
            }
            // The nearest child put aside that the ray still enters before `limit`
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                // SAFETY: every entry below the old `sp` was written above
                let (c, k, t) = unsafe { stack[sp].assume_init() };
                if t < *limit {
                    (child, count) = (c, k);
                    break;
                }
            }
        }
    }

    /// The nearest hit with `t` in (0, tmax), if any.
    pub fn intersect<F: PickPrecision>(
        &self,
        m: &Method,
        o: DVec3,
        d: DVec3,
        tmax: f64,
        counts: &mut TestCounts,
    ) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (detected in `new`)
            return unsafe { self.intersect_avx2::<F>(m, o, d, tmax, counts) };
        }
        self.nearest_hit::<F>(m, o, d, tmax, counts)
    }

    /// [`Geometry::intersect`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn intersect_avx2<F: PickPrecision>(
        &self,
        m: &Method,
        o: DVec3,
        d: DVec3,
        tmax: f64,
        counts: &mut TestCounts,
    ) -> Option<Hit> {
        self.nearest_hit::<F>(m, o, d, tmax, counts)
    }

    /// The body of [`Geometry::intersect`].
    #[inline(always)]
    fn nearest_hit<F: PickPrecision>(
        &self,
        m: &Method,
        o: DVec3,
        d: DVec3,
        tmax: f64,
        counts: &mut TestCounts,
    ) -> Option<Hit> {
        let f = F::pick(m);
        let mut best: Option<Hit> = None;
        let mut limit = tmax;
        // Planes
        for (i, pl) in self.planes.iter().enumerate() {
            counts.other_tests += 1;
            if let Some(t) = plane_t(pl, o, d).filter(|&t| t > 0.0 && t < limit) {
                limit = t;
                best = Some(Hit {
                    t,
                    n: pl.n,
                    material: pl.material,
                    object: usize::MAX - i,
                });
            }
        }
        // Objects: keeps the nearer hit
        let mut nearest = |ks: std::ops::Range<usize>, limit: &mut f64, counts: &mut TestCounts| {
            for k in ks {
                if let Some((t, n)) = self.test::<F>(f, k, o, d, counts) {
                    if t > 0.0 && t < *limit {
                        *limit = t;
                        best = Some(Hit {
                            t,
                            n,
                            material: self.objects[k].material,
                            object: k,
                        });
                    }
                }
            }
            false
        };
        if self.flat {
            for _ in 0..self.passes {
                nearest(0..self.objects.len(), &mut limit, counts);
            }
        } else {
            self.traverse::<true>(o, d, &mut limit, counts, nearest);
        }
        best
    }

    /// Whether some object or plane whose material `blocks` is hit with `t` in (0, tmax): the
    /// shadow rays' any-hit query, which stops at the first such hit. Objects that do not block
    /// are not tested (flat lists test every object, as for [`Geometry::intersect`]).
    pub fn occluded<F: PickPrecision>(
        &self,
        m: &Method,
        o: DVec3,
        d: DVec3,
        tmax: f64,
        blocks: impl Fn(usize) -> bool,
        counts: &mut TestCounts,
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (detected in `new`)
            return unsafe { self.occluded_avx2::<F>(m, o, d, tmax, blocks, counts) };
        }
        self.any_hit::<F>(m, o, d, tmax, blocks, counts)
    }

    /// [`Geometry::occluded`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn occluded_avx2<F: PickPrecision>(
        &self,
        m: &Method,
        o: DVec3,
        d: DVec3,
        tmax: f64,
        blocks: impl Fn(usize) -> bool,
        counts: &mut TestCounts,
    ) -> bool {
        self.any_hit::<F>(m, o, d, tmax, blocks, counts)
    }

    /// The body of [`Geometry::occluded`].
    #[inline(always)]
    fn any_hit<F: PickPrecision>(
        &self,
        m: &Method,
        o: DVec3,
        d: DVec3,
        tmax: f64,
        blocks: impl Fn(usize) -> bool,
        counts: &mut TestCounts,
    ) -> bool {
        let f = F::pick(m);
        for pl in &self.planes {
            counts.other_tests += 1;
            if blocks(pl.material) && plane_t(pl, o, d).is_some_and(|t| t > 0.0 && t < tmax) {
                return true;
            }
        }
        let mut hit = false;
        if self.flat {
            for _ in 0..self.passes {
                for k in 0..self.objects.len() {
                    let t = self.test::<F>(f, k, o, d, counts);
                    hit |= blocks(self.objects[k].material)
                        && t.is_some_and(|(t, _)| t > 0.0 && t < tmax);
                }
            }
            return hit;
        }
        let mut limit = tmax;
        self.traverse::<false>(o, d, &mut limit, counts, |ks, _, counts| {
            hit = ks.into_iter().any(|k| {
                blocks(self.objects[k].material)
                    && self
                        .test::<F>(f, k, o, d, counts)
                        .is_some_and(|(t, _)| t > 0.0 && t < tmax)
            });
            hit
        });
        hit
    }
}

/// Where a ray meets a plane (`None` if parallel).
#[inline]
fn plane_t(pl: &Plane, o: DVec3, d: DVec3) -> Option<f64> {
    let dn = d.dot(pl.n);
    (dn != 0.0).then(|| (pl.p - o).dot(pl.n) / dn)
}

/// Bins per axis of the SAH build.
const SAH_BINS: usize = 16;
/// Cost of testing an object, in box tests (a node visit tests two boxes).
const SAH_TEST_COST: f64 = 4.0;
/// Deepest level of the tree: below it every node is a leaf (the traversal stack's size).
const MAX_DEPTH: usize = 48;

/// An object while building: bounds, centroid, index in the scene's list.
#[derive(Clone, Copy)]
struct Item {
    b: Aabb,
    c: DVec3,
    k: usize,
}

/// Builds the subtree over `items` (reordered in place into leaf order, starting at object
/// `first`); returns its node index. A node is split where the SAH finds the cheapest binned
/// split, and kept as a leaf when that costs more than testing its objects (always above four
/// objects unless the centroids coincide, and never below [`MAX_DEPTH`]).
fn build(items: &mut [Item], first: usize, depth: usize, nodes: &mut Vec<Node>) -> usize {
    let n = items.len();
    let b = items.iter().fold(Aabb::empty(), |a, it| a.grow(it.b));
    let me = nodes.len();
    nodes.push(Node {
        b,
        start: first as u32,
        count: n as u32,
    });
    if n <= 1 || depth >= MAX_DEPTH {
        return me;
    }
    // Cheapest binned split over the three axes of the centroids' box
    let cb = items
        .iter()
        .fold(Aabb::empty(), |a, it| a.grow(Aabb { lo: it.c, hi: it.c }));
    let bin = |axis: usize, c: DVec3| {
        let (lo, ext) = (cb.lo[axis], cb.hi[axis] - cb.lo[axis]);
        (((c[axis] - lo) / ext * SAH_BINS as f64) as usize).min(SAH_BINS - 1)
    };
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        // Flat (or NaN) along this axis: no split there
        let ext = cb.hi[axis] - cb.lo[axis];
        if ext.is_nan() || ext <= 0.0 {
            continue;
        }
        let mut boxes = [Aabb::empty(); SAH_BINS];
        let mut counts = [0usize; SAH_BINS];
        for it in items.iter() {
            let i = bin(axis, it.c);
            boxes[i] = boxes[i].grow(it.b);
            counts[i] += 1;
        }
        // Right-side costs from the top bin down, then the left side upwards
        let mut right = [0.0; SAH_BINS];
        let (mut rb, mut rn) = (Aabb::empty(), 0);
        for i in (1..SAH_BINS).rev() {
            rb = rb.grow(boxes[i]);
            rn += counts[i];
            right[i] = rb.half_area() * rn as f64;
        }
        let (mut lb, mut ln) = (Aabb::empty(), 0);
        for i in 1..SAH_BINS {
            lb = lb.grow(boxes[i - 1]);
            ln += counts[i - 1];
            let cost = lb.half_area() * ln as f64 + right[i];
            if ln > 0 && ln < n && best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, i));
            }
        }
    }
    let split = match best {
        Some((cost, axis, i)) => {
            let split_cost = 2.0 * b.half_area() + SAH_TEST_COST * cost;
            let leaf_cost = SAH_TEST_COST * b.half_area() * n as f64;
            if split_cost >= leaf_cost && n <= 4 {
                return me;
            }
            // Partition by bin
            let mut mid = 0;
            for j in 0..n {
                if bin(axis, items[j].c) < i {
                    items.swap(j, mid);
                    mid += 1;
                }
            }
            mid
        }
        // Every centroid in one point: halves
        None if n <= 4 => return me,
        None => n / 2,
    };
    let (left, right) = items.split_at_mut(split);
    build(left, first, depth + 1, nodes);
    let r = build(right, first + split, depth + 1, nodes);
    nodes[me].start = r as u32;
    nodes[me].count = 0;
    me
}

/// Stack entries of the 4-wide traversal: three put aside per level.
const STACK: usize = 3 * MAX_DEPTH;

/// Turns binary node `i` (inner) into a 4-wide node: its children, with the inner one of
/// largest area opened while there is room; returns the new node's index.
fn widen(binary: &[Node], i: usize, out: &mut Vec<Node4>) -> usize {
    // Children, or a lone leaf at the root
    let mut kids = if binary[i].count > 0 {
        vec![i]
    } else {
        vec![i + 1, binary[i].start as usize]
    };
    while kids.len() < 4 {
        let inner = (0..kids.len())
            .filter(|&j| binary[kids[j]].count == 0)
            .max_by(|&a, &b| {
                let area = |j: usize| binary[kids[j]].b.half_area();
                area(a).total_cmp(&area(b))
            });
        let Some(j) = inner else { break };
        let k = kids.swap_remove(j);
        kids.extend([k + 1, binary[k].start as usize]);
    }
    let me = out.len();
    // Unused lanes: a box at +∞, which no ray enters before a finite or infinite `tmax`
    out.push(Node4 {
        b: [[[f64::INFINITY; 4]; 3]; 2],
        child: [0; 4],
        count: [0; 4],
        lanes: kids.len() as u32,
    });
    for (lane, &k) in kids.iter().enumerate() {
        let b = binary[k].b;
        for axis in 0..3 {
            out[me].b[0][axis][lane] = b.lo[axis];
            out[me].b[1][axis][lane] = b.hi[axis];
        }
        let (child, count) = if binary[k].count > 0 {
            (binary[k].start, binary[k].count)
        } else {
            (widen(binary, k, out) as u32, 0)
        };
        out[me].child[lane] = child;
        out[me].count[lane] = count;
    }
    me
}

/// One primitive test: `t` and the unit geometric normal.
#[inline]
fn prim_hit<F: PickPrecision>(
    f: SphereFn<F>,
    p: &Prim,
    o: DVec3,
    d: DVec3,
    counts: &mut TestCounts,
    marchers: &[crate::implicit::march::Marcher],
) -> Option<(f64, DVec3)> {
    match *p {
        Prim::Implicit { k, .. } => {
            // A hit is a sign change (see `Marcher::trace`), so a secondary ray leaving its own
            // surface does not see it again
            let m = &marchers[k];
            counts.implicit_tests += 1;
            let r = m.trace(o, d, 0.0);
            counts.march_steps += r.steps as u64;
            let (t, i) = r.hit?;
            Some((t, m.normal(i, o + t * d)))
        }
        Prim::Sphere { c, r } => {
            counts.sphere_tests += 1;
            let t = sphere_t::<F>(f, o, d, c, r)?;
            counts.sphere_hits += 1;
            Some((t, ((o + t * d) - c) / r))
        }
        Prim::Disc { c, n, r } => {
            counts.other_tests += 1;
            let dn = d.dot(n);
            if dn == 0.0 {
                return None;
            }
            let t = (c - o).dot(n) / dn;
            ((o + t * d - c).length_squared() <= r * r).then_some((t, n))
        }
        Prim::Tri { v0, e1, e2 } => {
            // Möller–Trumbore
            counts.other_tests += 1;
            let pv = d.cross(e2);
            let det = e1.dot(pv);
            if det == 0.0 {
                return None;
            }
            let inv = 1.0 / det;
            let tv = o - v0;
            let u = tv.dot(pv) * inv;
            if !(0.0..=1.0).contains(&u) {
                return None;
            }
            let qv = tv.cross(e1);
            let v = d.dot(qv) * inv;
            if v < 0.0 || u + v > 1.0 {
                return None;
            }
            Some((e2.dot(qv) * inv, e1.cross(e2).normalize()))
        }
        Prim::Box { .. }
        | Prim::CylinderSide { .. }
        | Prim::Ellipsoid { .. }
        | Prim::Torus { .. } => {
            counts.other_tests += 1;
            solid_hit(p, o, d)
        }
    }
}
