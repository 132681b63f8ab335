//! Effect analysis: which effects a scene needs (shadows, reflection, refraction, sphere
//! tracing) and why, the rays a render traces by kind, and the seed paper's ray budget beside them.

use super::*;

/// The effects a scene needs, with the reason for each choice.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Effects {
    /// Whether shadow rays are traced (some light can be occluded).
    pub shadows: bool,
    /// Whether mirror reflection rays are traced.
    pub reflection: bool,
    /// Whether refraction rays are traced (some glass is visible).
    pub refraction: bool,
    /// Ray segments per path actually needed (at most `render.max_depth`).
    pub depth: u32,
    /// Whether pixels take more than one sample (an n×n grid with n > 1).
    pub supersampling: bool,
    /// One line per choice above, saying why (what `render --explain` prints).
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
    /// Camera rays.
    pub primary: u64,
    /// Shadow rays, one per light and diffuse hit.
    pub shadow: u64,
    /// Mirror and glass reflection rays.
    pub reflection: u64,
    /// Glass transmission rays.
    pub refraction: u64,
    /// Rays of each kind that hit nothing (a shadow ray that reaches its light counts here).
    pub primary_miss: u64,
    /// Shadow rays that reach their light.
    pub shadow_miss: u64,
    /// Reflection rays that hit nothing.
    pub reflection_miss: u64,
    /// Refraction rays that hit nothing.
    pub refraction_miss: u64,
    /// Reflection and refraction rays not traced because their camera sample's path tree
    /// already had [`MAX_TREE_SEGMENTS`] segments (0 for every scene of `max_depth` ≤ 12).
    pub budget_cut: u64,
    /// Intersection tests and BVH visits of all these rays.
    #[serde(flatten)]
    pub tests: TestCounts,
    /// Segments the current camera sample's path tree may still spawn.
    #[serde(skip)]
    pub(super) left: u32,
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
        self.budget_cut += o.budget_cut;
        self.tests += o.tests;
    }
}

impl RayCounts {
    /// All rays traced: primary, shadow, reflection and refraction.
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection + self.refraction
    }
}

/// The most ray segments one camera sample's path tree may have (the primary ray and every
/// reflection and refraction ray spawned under it; shadow rays are not counted). A glass surface
/// splits a ray in two, so a tree can double at every segment: 40 glass and mirror spheres took
/// 0.45 s at `max_depth` 32, 33 s at 48 and would take years at 256 (16×16 pixels, measured).
/// With 4096 = 2^12 a tree of depth ≤ 12 is never cut (it has at most 2^12 − 1 segments), so
/// no scene of `max_depth` ≤ 12 changes (every reference scene has ≤ 10); beyond it, the rays
/// a sample would spawn past its budget are not traced and count as black, like a ray past
/// `max_depth`, in the order the renderer walks the tree (depth first, reflection before
/// refraction), which is the same every run. They are counted in the sidecar's
/// `rays.budget_cut`, and `render` prints how many.
pub const MAX_TREE_SEGMENTS: u32 = 4096;

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

/// What `rayproof render` prints about a finished render: size, method and time, the rays by
/// kind, the tests, sphere tracing's work, the tree budget's cuts and the seed paper's budget.
pub fn summary(r: &Render, lights: usize) -> String {
    let c = &r.counts;
    let mut s = format!(
        "{}×{} with {} in {}: {:.3} s\nrays: primary {}, shadow {}, reflection {}, refraction {} (total {})\n\
         missing every shape: primary {}, shadow (light reached) {}, reflection {}, refraction {}\n\
         tests: sphere {} ({} hits), other {}, BVH nodes {}\n",
        r.width, r.height, r.method, r.precision, r.seconds, c.primary, c.shadow, c.reflection, c.refraction, c.total(),
        c.primary_miss, c.shadow_miss, c.reflection_miss, c.refraction_miss,
        c.tests.sphere_tests, c.tests.sphere_hits, c.tests.other_tests, c.tests.bvh_nodes
    );
    if c.tests.implicit_tests > 0 {
        s += &format!(
            "sphere tracing: {} implicit tests, {} field evaluations\n",
            c.tests.implicit_tests, c.tests.march_steps
        );
    }
    if c.budget_cut > 0 {
        s += &format!(
            "tree budget: {} reflection/refraction rays not traced (black): a camera sample's path tree has at most {} segments\n",
            c.budget_cut, MAX_TREE_SEGMENTS
        );
    }
    s + &budget_line(r, lights) + "\n"
}
