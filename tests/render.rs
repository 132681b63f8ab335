//! The renderer: analytic radiance checks, effect analysis, ray counts, every reference scene
//! free of NaN/Inf, and bad scene input.

use crate::common::rayproof;
use rayproof::render::scene::{self, Scene};
use rayproof::render::{render, Effects, Overrides, Render};
use rayproof::shapes::sphere::methods::METHODS;
use std::path::Path;

fn scene(text: &str) -> Scene {
    scene::parse(text, Path::new("test.toml")).expect("valid scene")
}

fn draw(s: &Scene) -> Render {
    render(s, &Overrides::default())
}

const CAMERA_DOWN: &str = r#"
[camera]
position = [0.0, 4.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
fov = 60.0
width = 33
height = 25
"#;

#[test]
fn diffuse_plane_matches_lambert_per_pixel() {
    // Plane y = 0, albedo ρ, one light I at (1, 2, 0.5): L = ρ/π · I · cosθ / d²
    let text = format!(
        "{CAMERA_DOWN}\n[[lights]]\nposition = [1.0, 2.0, 0.5]\nintensity = [10.0, 5.0, 2.5]\n\
         [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.25, 0.8]\n\
         [[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"m\"\n"
    );
    let s = scene(&text);
    let r = draw(&s);
    // The camera model documented in render/mod.rs
    let (w, h) = (33.0, 25.0);
    let half_w = (30f64).to_radians().tan();
    let half_h = half_w * h / w;
    let (fwd, right, up) = (
        glam::DVec3::new(0.0, -1.0, 0.0),
        glam::DVec3::new(1.0, 0.0, 0.0),
        glam::DVec3::new(0.0, 0.0, -1.0),
    );
    assert_eq!(right, fwd.cross(up).normalize());
    let light = glam::DVec3::new(1.0, 2.0, 0.5);
    let mut worst = 0.0f64;
    for y in 0..25 {
        for x in 0..33 {
            let u = (x as f64 + 0.5) / w;
            let v = (y as f64 + 0.5) / h;
            let d = (fwd + right * ((2.0 * u - 1.0) * half_w) + up * ((1.0 - 2.0 * v) * half_h))
                .normalize();
            let p = glam::DVec3::new(0.0, 4.0, 0.0) + d * (4.0 / -d.y);
            let to = light - p;
            let cos = to.y / to.length();
            for (k, (rho, i)) in [(0.5, 10.0), (0.25, 5.0), (0.8, 2.5)]
                .into_iter()
                .enumerate()
            {
                let want = rho / std::f64::consts::PI * i * cos / to.length_squared();
                let got = r.beauty[y * 33 + x][k] as f64;
                worst = worst.max(((got - want) / want).abs());
            }
        }
    }
    assert!(worst < 1e-6, "relative error {worst:e}");
    assert_eq!(
        r.counts.shadow, 0,
        "a lone plane cannot shadow itself: no shadow rays"
    );
}

fn mirror_scene(with_mirror: bool, camera_z: f64, look_z: f64) -> String {
    let mirror = if with_mirror {
        "[materials.mir]\ntype = \"mirror\"\nreflectance = [0.6, 0.6, 0.6]\n[[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nmaterial = \"mir\"\n"
    } else {
        ""
    };
    format!(
        "[camera]\nposition = [0.0, 1.0, {camera_z}]\nlook_at = [0.0, 1.0, {look_z}]\nfov = 40.0\nwidth = 40\nheight = 30\n\
         [render]\nmax_depth = 2\n\
         [[lights]]\nposition = [2.0, 3.0, 2.0]\nintensity = [20.0, 20.0, 20.0]\n\
         [materials.red]\ntype = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0.3, 1.2, 7.0]\nradius = 1.5\nmaterial = \"red\"\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [-1.5, 0.4, 8.0]\nradius = 0.8\nmaterial = \"red\"\n{mirror}"
    )
}

#[test]
fn mirror_shows_r_times_the_mirrored_image() {
    // Camera at z = 5 facing a mirror at z = 0; the mirrored camera at z = −5 faces +z
    let a = draw(&scene(&mirror_scene(true, 5.0, 0.0)));
    let b = draw(&scene(&mirror_scene(false, -5.0, 0.0)));
    let (w, h) = (40, 30);
    let mut bad = 0;
    let mut lit = 0;
    for y in 0..h {
        for x in 0..w {
            // The mirror image is flipped left–right
            let (pa, pb) = (a.beauty[y * w + x], b.beauty[y * w + (w - 1 - x)]);
            for k in 0..3 {
                let want = 0.6 * pb[k] as f64;
                lit += (want > 0.0) as usize;
                if (pa[k] as f64 - want).abs() > 1e-6 * want.max(1e-3) {
                    bad += 1;
                }
            }
        }
    }
    assert!(
        lit > 300,
        "the spheres must be visible ({lit} lit channels)"
    );
    assert!(
        bad == 0,
        "{bad} channels differ from 0.6 × the mirrored image"
    );
}

#[test]
fn glass_at_normal_incidence_transmits_one_minus_f_squared() {
    let scene_text = |glass: bool| {
        let g = if glass {
            "[materials.g]\ntype = \"glass\"\nior = 1.5\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"g\"\n"
        } else {
            ""
        };
        format!(
            "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 10.0\nwidth = 5\nheight = 5\n\
             [render]\nmax_depth = 3\nglass_shadows = \"transmissive\"\n\
             [[lights]]\nposition = [0.0, 0.0, -2.0]\nintensity = [10.0, 10.0, 10.0]\n\
             [materials.wall]\ntype = \"diffuse\"\nalbedo = [0.7, 0.7, 0.7]\n\
             [[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, -4.0]\nnormal = [0.0, 0.0, 1.0]\nmaterial = \"wall\"\n{g}"
        )
    };
    let with = draw(&scene(&scene_text(true)));
    let without = draw(&scene(&scene_text(false)));
    // The centre pixel's ray runs along the axis: in and out at normal incidence
    let f = ((1.5f64 - 1.0) / (1.5 + 1.0)).powi(2);
    let ratio = with.beauty[12][0] as f64 / without.beauty[12][0] as f64;
    assert!(
        (ratio - (1.0 - f).powi(2)).abs() < 1e-6,
        "ratio {ratio} vs (1−F)² = {}",
        (1.0 - f).powi(2)
    );
}

// ---- effect analysis: each effect on exactly when the scene needs it ----

fn effects(shapes: &str, materials: &str, lights: bool, grid: u32) -> (Effects, Render) {
    let light = if lights {
        "[[lights]]\nposition = [0.0, 5.0, 0.0]\nintensity = [1.0, 1.0, 1.0]\n"
    } else {
        ""
    };
    let text = format!(
        "[camera]\nposition = [0.0, 1.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 50.0\nwidth = 8\nheight = 6\ngrid = {grid}\n\
         [render]\nmax_depth = 4\n{light}{materials}{shapes}"
    );
    let s = scene(&text);
    (Effects::analyse(&s), draw(&s))
}

const MATS: &str = "[materials.d]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n[materials.m]\ntype = \"mirror\"\nreflectance = [1.0, 1.0, 1.0]\n[materials.g]\ntype = \"glass\"\nior = 1.5\n";

fn plane(mat: &str) -> String {
    format!("[[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"{mat}\"\n")
}
fn sphere_far(mat: &str) -> String {
    // Outside the view, but it can occlude in principle
    format!("[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 50.0, 50.0]\nradius = 1.0\nmaterial = \"{mat}\"\n")
}
fn wall(mat: &str) -> String {
    // A plane filling the view, facing the camera
    format!("[[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, -1.0]\nnormal = [0.0, 0.0, 1.0]\nmaterial = \"{mat}\"\n")
}

#[test]
fn shadows_only_when_a_light_can_be_occluded() {
    let (e, r) = effects(&plane("d"), MATS, true, 1);
    assert!(!e.shadows && r.counts.shadow == 0);
    let (e, r) = effects(&(plane("d") + &sphere_far("d")), MATS, true, 1);
    assert!(e.shadows);
    // Every pixel sees the lit plane (light above it): one shadow ray per primary ray
    let (e2, r2) = effects(&(wall("d") + &sphere_far("d")), MATS, true, 1);
    assert!(
        e2.shadows && r2.counts.shadow == r2.counts.primary,
        "{:?}",
        r2.counts
    );
    assert!(r.counts.shadow > 0);
    let (e, _) = effects(&(plane("d") + &sphere_far("d")), MATS, false, 1);
    assert!(!e.shadows, "no light, no shadow rays");
}

#[test]
fn reflection_only_when_a_material_reflects() {
    let (e, r) = effects(&wall("d"), MATS, true, 1);
    assert!(!e.reflection && !e.refraction && e.depth == 1);
    assert_eq!((r.counts.reflection, r.counts.refraction), (0, 0));
    let (e, r) = effects(&wall("m"), MATS, true, 1);
    assert!(e.reflection && !e.refraction && e.depth == 4);
    // Every primary ray hits the mirror wall and spawns exactly one reflection ray
    assert_eq!(r.counts.reflection, r.counts.primary);
    assert_eq!(r.counts.shadow, 0);
}

#[test]
fn refraction_only_when_a_material_transmits() {
    let (e, r) = effects(&wall("g"), MATS, true, 1);
    assert!(e.reflection && e.refraction);
    // Each primary ray splits once at the glass wall (nothing lies behind it)
    assert_eq!(r.counts.refraction, r.counts.primary);
    assert_eq!(r.counts.reflection, r.counts.primary);
}

#[test]
fn supersampling_only_with_a_larger_grid() {
    let (e, r) = effects(&wall("d"), MATS, true, 1);
    assert!(!e.supersampling && r.counts.primary == 48);
    let (e, r) = effects(&wall("d"), MATS, true, 3);
    assert!(e.supersampling && r.counts.primary == 48 * 9);
}

#[test]
fn explain_names_every_effect() {
    let (e, _) = effects(&wall("m"), MATS, true, 2);
    let text = e.reasons.join("\n");
    for word in [
        "shadows",
        "reflection",
        "refraction",
        "depth",
        "supersampling",
    ] {
        assert!(text.contains(word), "{text}");
    }
}

// ---- every reference scene, every method and precision: finite pixels ----

#[test]
fn reference_scenes_render_without_nan_or_inf() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let s = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        for m in METHODS {
            for p in ["f32", "f64"] {
                let ov = Overrides {
                    method: Some(m),
                    precision: Some(p),
                    size: Some((24, 18)),
                    grid: Some(1),
                    ..Default::default()
                };
                let r = render(&s, &ov);
                assert!(
                    r.beauty
                        .iter()
                        .flatten()
                        .all(|v| v.is_finite() && *v >= 0.0),
                    "{} with {} {p}: a NaN, Inf or negative pixel",
                    path.display(),
                    m.name
                );
            }
        }
        n += 1;
    }
    assert!(n >= 6, "expected the six reference scenes, found {n}");
}

// ---- bad input ----

fn one_line_error(o: &std::process::Output, what: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    for w in what {
        assert!(err.contains(w), "'{w}' missing from: {err}");
    }
}

#[test]
fn bad_scenes_get_file_line_field_and_exit_2() {
    let dir = std::env::temp_dir().join(format!("rayproof-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    };
    let good = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes/diffuse.toml"),
    )
    .unwrap();
    // Syntax error on line 3
    let f = write(
        "syntax.toml",
        "[camera]\nposition = [0.0, 1.0\nlook_at = 3\n",
    );
    one_line_error(&rayproof(&["render", &f]), &["syntax.toml:"]);
    // Unknown material, named with its shape and line
    let f = write(
        "mat.toml",
        &good.replace("material = \"blue\"", "material = \"gold\""),
    );
    one_line_error(
        &rayproof(&["render", &f]),
        &["mat.toml:", "unknown material 'gold'", "shapes[2].material"],
    );
    // Unknown material type
    let f = write(
        "type.toml",
        &good.replace(
            "type = \"diffuse\"\nalbedo = [0.8, 0.15, 0.1]",
            "type = \"velvet\"\nalbedo = [0.8, 0.15, 0.1]",
        ),
    );
    one_line_error(&rayproof(&["render", &f]), &["type.toml:", "velvet"]);
    // Missing mesh file
    let f = write(
        "mesh.toml",
        &(good.clone()
            + "\n[[shapes]]\ntype = \"mesh\"\nfile = \"nope.obj\"\nmaterial = \"red\"\n"),
    );
    one_line_error(
        &rayproof(&["render", &f]),
        &["mesh.toml:", "shapes[3].file", "nope.obj"],
    );
    // Zero-size image
    let f = write("zero.toml", &good.replace("width = 256", "width = 0"));
    one_line_error(&rayproof(&["render", &f]), &["zero.toml:7", "camera.width"]);
    // A failed render leaves an existing output untouched
    let out = dir.join("out.exr");
    std::fs::write(&out, b"previous").unwrap();
    let f = write("bad.toml", "nonsense");
    one_line_error(
        &rayproof(&["render", &f, "-o", &out.display().to_string()]),
        &["bad.toml"],
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"previous");
    // Bad flags
    one_line_error(&rayproof(&["render", "x.toml", "--spp", "3"]), &["--spp"]);
    one_line_error(
        &rayproof(&["render", "/no/such/scene.toml"]),
        &["/no/such/scene.toml"],
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn render_writes_exr_png_and_stats() {
    let dir = std::env::temp_dir().join(format!("rayproof-out-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (exr, png) = (dir.join("d.exr"), dir.join("d.png"));
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes/diffuse.toml");
    let o = rayproof(&[
        "render",
        &scene.display().to_string(),
        "-o",
        &exr.display().to_string(),
        "--png",
        &png.display().to_string(),
        "--spp",
        "1",
        "--layers",
        "depth,normal,rays",
        "--explain",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("shadows: on") && text.contains("seed budget (m+1)·d·M·N"),
        "{text}"
    );
    // The EXR holds the beauty and the layers asked for
    let img = exr::prelude::read_all_flat_layers_from_file(&exr).unwrap();
    let names: Vec<String> = img.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    for n in ["R", "G", "B", "depth.Z", "normal.X", "rays.Y"] {
        assert!(names.iter().any(|x| x == n), "{names:?}");
    }
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("d.exr.json")).unwrap()).unwrap();
    assert_eq!(stats["rays"]["primary"], 256 * 256);
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn obj_meshes_render_and_block_light() {
    // A tetrahedron (OBJ) above a plane, lit from the side: seen in the centre, and it shadows
    let dir = std::env::temp_dir().join(format!("rayproof-mesh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("tet.obj"),
        "v -1 0.5 -1\nv 1 0.5 -1\nv 0 0.5 1\nv 0 2 0\nf 1 2 3\nf 1 2 4\nf 2 3 4\nf 3 1 4\n",
    )
    .unwrap();
    let text = |mesh: bool| {
        let m = if mesh {
            "[[shapes]]\ntype = \"mesh\"\nfile = \"tet.obj\"\nmaterial = \"m\"\n"
        } else {
            ""
        };
        format!(
            "{CAMERA_DOWN}\n[[lights]]\nposition = [6.0, 6.0, 0.0]\nintensity = [100.0, 100.0, 100.0]\n\
             [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
             [[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"m\"\n\
             [[shapes]]\ntype = \"sphere\"\ncenter = [0.0, -50.0, 0.0]\nradius = 1.0\nmaterial = \"m\"\n{m}"
        )
    };
    let path = dir.join("mesh.toml");
    std::fs::write(&path, text(true)).unwrap();
    let with = scene::load(&path).unwrap();
    assert_eq!(with.meshes.values().next().unwrap().len(), 4);
    std::fs::write(&path, text(false)).unwrap();
    let without = scene::load(&path).unwrap();
    let (a, b) = (draw(&with), draw(&without));
    // Centre pixel: the camera (y = 4) sees the mesh (top at y = 2) before the plane (depth 4)
    let centre = 12 * 33 + 16;
    assert!(
        a.depth[centre] < 2.5 && b.depth[centre] > 3.9,
        "{} {}",
        a.depth[centre],
        b.depth[centre]
    );
    // Plane point (−1.96, 0, 0): its path to the light crosses the mesh
    let shadowed = 12 * 33 + 2;
    assert!(
        b.beauty[shadowed][0] > 0.01 && a.beauty[shadowed][0] == 0.0,
        "{:?} {:?}",
        a.beauty[shadowed],
        b.beauty[shadowed]
    );
    std::fs::remove_dir_all(&dir).ok();
}

// ---- boxes, cylinders, ellipsoids, tori ----

/// A 5×5 view along −z from `c` + (0, 0, 5) (or down −y from `c` + (0, 5, 0)) at a shape; the
/// centre pixel's ray passes exactly through `c`.
fn solo(shape: &str, c: [f64; 3], from_above: bool) -> Render {
    let (pos, up) = if from_above {
        ([c[0], c[1] + 5.0, c[2]], "[0.0, 0.0, -1.0]")
    } else {
        ([c[0], c[1], c[2] + 5.0], "[0.0, 1.0, 0.0]")
    };
    let text = format!(
        "[camera]\nposition = {pos:?}\nlook_at = {c:?}\nup = {up}\nfov = 30.0\nwidth = 5\nheight = 5\n\
         [[lights]]\nposition = [2.0, 9.0, 9.0]\nintensity = [50.0, 50.0, 50.0]\n\
         [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[shapes]]\n{shape}\nmaterial = \"m\"\n"
    );
    draw(&scene(&text))
}

/// Depth and normal of the centre pixel.
fn centre(r: &Render) -> (f32, [f32; 3]) {
    let k = 2 * r.width + 2;
    (r.depth[k], r.normal[k])
}

#[test]
fn new_shapes_are_hit_where_expected_with_their_normals() {
    let c = [0.3, -0.2, 0.1];
    let f = |v: [f64; 3]| format!("[{}, {}, {}]", v[0], v[1], v[2]);
    let off = |d: [f64; 3]| f([c[0] + d[0], c[1] + d[1], c[2] + d[2]]);
    // (shape, from above, expected depth (0 = miss), expected normal)
    let cases = [
        (
            format!(
                "type = \"box\"\nmin = {}\nmax = {}",
                off([-1.0, -0.5, -0.25]),
                off([1.0, 0.5, 0.25])
            ),
            false,
            4.75,
            [0.0, 0.0, 1.0],
        ),
        (
            format!(
                "type = \"box\"\nmin = {}\nmax = {}",
                off([-1.0, -0.5, -0.25]),
                off([1.0, 0.5, 0.25])
            ),
            true,
            4.5,
            [0.0, 1.0, 0.0],
        ),
        // Side view: the lateral surface at radius 1 from the axis
        (
            format!(
                "type = \"cylinder\"\nbase = {}\nradius = 1.0\nheight = 2.0",
                off([0.0, -1.0, 0.0])
            ),
            false,
            4.0,
            [0.0, 0.0, 1.0],
        ),
        // Top view: the top cap 1 above the centre
        (
            format!(
                "type = \"cylinder\"\nbase = {}\nradius = 1.0\nheight = 2.0",
                off([0.0, -1.0, 0.0])
            ),
            true,
            4.0,
            [0.0, 1.0, 0.0],
        ),
        (
            format!(
                "type = \"ellipsoid\"\ncenter = {}\nradii = [2.0, 1.0, 0.5]",
                f(c)
            ),
            false,
            4.5,
            [0.0, 0.0, 1.0],
        ),
        (
            format!(
                "type = \"ellipsoid\"\ncenter = {}\nradii = [2.0, 1.0, 0.5]",
                f(c)
            ),
            true,
            4.0,
            [0.0, 1.0, 0.0],
        ),
        // The torus lies in the xz plane: seen from the side the centre ray meets the tube at
        // z = major + minor; seen from above it passes through the hole
        (
            format!(
                "type = \"torus\"\ncenter = {}\nmajor = 1.0\nminor = 0.25",
                f(c)
            ),
            false,
            3.75,
            [0.0, 0.0, 1.0],
        ),
        (
            format!(
                "type = \"torus\"\ncenter = {}\nmajor = 1.0\nminor = 0.25",
                f(c)
            ),
            true,
            0.0,
            [0.0, 0.0, 0.0],
        ),
    ];
    for (shape, above, depth, normal) in cases {
        let r = solo(&shape, c, above);
        let (d, n) = centre(&r);
        assert!(
            (d as f64 - depth).abs() < 1e-5,
            "{shape} (above: {above}): depth {d}, expected {depth}"
        );
        for k in 0..3 {
            assert!(
                (n[k] as f64 - normal[k]).abs() < 1e-5,
                "{shape} (above: {above}): normal {n:?}, expected {normal:?}"
            );
        }
        // Lit from above and in front: a hit is not black
        assert_eq!(r.beauty[2 * r.width + 2][0] > 0.0, depth > 0.0, "{shape}");
    }
}

#[test]
fn the_torus_hole_and_rim_from_above() {
    // A row of pixels from 5 above a torus (major 1, minor 0.5) at the origin. A ray whose
    // distance ρ₀ from the axis at y = 0 is within the tube's half-width hits it; one that stays
    // outside ρ ∈ [0.5, 1.5] over the tube's height (ρ = ρ₀(5 − y)/5, |y| ≤ 0.5) misses.
    let text = "[camera]\nposition = [0.0, 5.0, 0.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\n\
                fov = 60.0\nwidth = 101\nheight = 1\n\
                [[lights]]\nposition = [0.0, 9.0, 0.0]\nintensity = [50.0, 50.0, 50.0]\n\
                [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
                [[shapes]]\ntype = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = 1.0\nminor = 0.5\nmaterial = \"m\"\n";
    let r = draw(&scene(text));
    let half = 30f64.to_radians().tan();
    let (mut hits, mut misses) = (0, 0);
    for x in 0..101 {
        let rho0 = (((x as f64 + 0.5) / 101.0 * 2.0 - 1.0) * half * 5.0).abs();
        let d = r.depth[x] as f64;
        if (rho0 - 1.0).abs() < 0.45 {
            assert!(d > 4.0 && d < 5.5, "pixel {x} (ρ₀ = {rho0}): depth {d}");
            hits += 1;
        } else if rho0 * 0.9 > 1.5 || rho0 * 1.1 < 0.5 {
            assert_eq!(d, 0.0, "pixel {x} (ρ₀ = {rho0}) should miss, depth {d}");
            misses += 1;
        }
    }
    assert!(hits >= 20 && misses >= 10, "{hits} hits, {misses} misses");
}

#[test]
fn a_lone_torus_can_shadow_itself() {
    let text = format!(
        "{CAMERA_DOWN}\n[[lights]]\nposition = [3.0, 1.0, 0.0]\nintensity = [10.0, 10.0, 10.0]\n\
         [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[shapes]]\ntype = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = 1.0\nminor = 0.3\nmaterial = \"m\"\n"
    );
    let e = Effects::analyse(&scene(&text));
    assert!(e.shadows, "{:?}", e.reasons);
    let text = text.replace(
        "type = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = 1.0\nminor = 0.3",
        "type = \"ellipsoid\"\ncenter = [0.0, 0.0, 0.0]\nradii = [1.0, 0.5, 2.0]",
    );
    assert!(!Effects::analyse(&scene(&text)).shadows);
}

#[test]
fn new_shapes_parse_and_bad_values_name_their_line() {
    let head = "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 40.0\nwidth = 8\nheight = 8\n\
                [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n";
    // Line 11 is the [[shapes]] header, 12 the type, 13 and on the fields
    let good = [
        "type = \"box\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 2.0, 3.0]",
        "type = \"cylinder\"\nbase = [0.0, 0.0, 0.0]\nradius = 1.0\nheight = 2.0",
        "type = \"ellipsoid\"\ncenter = [0.0, 0.0, 0.0]\nradii = [1.0, 2.0, 3.0]",
        "type = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = 1.0\nminor = 0.25",
    ];
    let text = |body: &str| format!("{head}\n[[shapes]]\n{body}\nmaterial = \"m\"\n");
    for g in good {
        let s = scene::parse(&text(g), Path::new("t.toml")).unwrap_or_else(|e| panic!("{g}: {e}"));
        assert_eq!(s.file.shapes.len(), 1);
    }
    // (body, expected error text with its line)
    let bad = [
        (
            "type = \"box\"\nmin = [1.0, -1.0, -1.0]\nmax = [1.0, 2.0, 3.0]",
            "t.toml:14: shapes[0].max: must exceed min",
        ),
        (
            "type = \"box\"\nmin = [nan, -1.0, -1.0]\nmax = [1.0, 2.0, 3.0]",
            "t.toml:13: shapes[0].min: must be finite",
        ),
        (
            "type = \"cylinder\"\nbase = [0.0, 0.0, 0.0]\nradius = -1.0\nheight = 2.0",
            "t.toml:14: shapes[0].radius: must be a finite number > 0, got -1",
        ),
        (
            "type = \"cylinder\"\nbase = [0.0, 0.0, 0.0]\nradius = 1.0\nheight = 0.0",
            "t.toml:15: shapes[0].height",
        ),
        (
            "type = \"cylinder\"\nbase = [0.0, inf, 0.0]\nradius = 1.0\nheight = 1.0",
            "t.toml:13: shapes[0].base: must be finite",
        ),
        (
            "type = \"ellipsoid\"\ncenter = [0.0, 0.0, 0.0]\nradii = [1.0, 0.0, 3.0]",
            "t.toml:14: shapes[0].radii: must be a finite number > 0, got 0",
        ),
        (
            "type = \"ellipsoid\"\ncenter = [0.0, 0.0, 0.0]\nradii = [1.0, 2.0, inf]",
            "t.toml:14: shapes[0].radii",
        ),
        (
            "type = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = 1.0\nminor = 1.5",
            "t.toml:15: shapes[0].minor: must be below major",
        ),
        (
            "type = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = nan\nminor = 0.5",
            "t.toml:14: shapes[0].major",
        ),
        // Missing and unknown fields come from the TOML layer, still with a line
        (
            "type = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = 1.0",
            "missing field `minor`",
        ),
        (
            "type = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nradius = 2.0",
            "unknown field `radius`",
        ),
        (
            "type = \"cylinder\"\nbase = [0.0, 0.0]\nradius = 1.0\nheight = 1.0",
            "t.toml:",
        ),
    ];
    for (body, want) in bad {
        let e = scene::parse(&text(body), Path::new("t.toml"))
            .err()
            .unwrap_or_else(|| panic!("{body} was accepted"))
            .to_string();
        assert!(e.contains(want), "{body}: got '{e}', expected '{want}'");
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(!e.starts_with("t.toml:0:"), "no line: {e}");
    }
}

#[test]
fn rays_from_inside_and_degenerate_directions_never_panic() {
    // The camera inside each solid: the exit surface is hit (or nothing, never NaN)
    for shape in [
        "type = \"box\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 7.0]",
        "type = \"cylinder\"\nbase = [0.0, -1.0, 0.0]\nradius = 7.0\nheight = 2.0",
        "type = \"ellipsoid\"\ncenter = [0.0, 0.0, 0.0]\nradii = [1.0, 1.0, 7.0]",
        "type = \"torus\"\ncenter = [0.0, 0.0, 0.0]\nmajor = 5.0\nminor = 0.5",
    ] {
        let r = solo(shape, [0.0, 0.0, 0.0], false);
        assert!(
            r.beauty.iter().flatten().all(|v| v.is_finite())
                && r.depth.iter().all(|v| v.is_finite()),
            "{shape}"
        );
    }
}

/// Rays the renderer asks its robust routines about in the `shapes` scene, judged by each
/// routine's exact oracle: camera rays towards random points of each solid's bounds, and
/// secondary rays spawned from their hits (origin offset along the normal by the renderer's
/// `auto` rule, random direction on either side). Ill-posed cases are skipped; the ellipsoid
/// has no audit shape of the same form (see `routine_input`) and is checked by the hit tests.
#[test]
fn renderer_calls_agree_with_the_exact_oracles() {
    use rand::SeedableRng;
    use rayproof::audit::Judgement;
    use rayproof::audit::{judge, Truth};
    use rayproof::numerics::Precision;
    use rayproof::render::geom::{routine_input, sample_rays, solid_hit};
    use rayproof::shapes::shape_by_name;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes/shapes.toml");
    let s = scene::load(&path).unwrap();
    let (geo, _) = rayproof::render::build_geometry(&s);
    let cam = glam::DVec3::from_array(s.file.camera.position);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
    let mut judged = 0;
    for obj in &geo.objects {
        let prim = &obj.prim;
        let Some((name, _)) = routine_input(prim, cam, glam::DVec3::X) else {
            continue;
        };
        let shape = shape_by_name(name).expect("registered shape");
        let (mut ok, mut ill, mut max_ulps, mut wrong) = (0, 0, 0, vec![]);
        let mut max_eoc = 0.0f64;
        let mut worst_line = String::new();
        let mut judge_ray = |o: glam::DVec3, d: glam::DVec3| {
            let (_, input) = routine_input(prim, o, d).unwrap();
            let answer = match solid_hit(prim, o, d) {
                Some((t, _)) => rayproof::shapes::shape::Answer::hit(vec![t]),
                None => rayproof::shapes::shape::Answer::miss(),
            };
            let truth = shape.oracle(&input, Precision::F64);
            if matches!(&truth, Truth::Answer(e) if e.ill_posed) {
                ill += 1;
                return;
            }
            match judge(&truth, &answer, shape.info(), Precision::F64) {
                Judgement::Ok { ulps } => {
                    ok += 1;
                    if let Truth::Answer(e) = &truth {
                        let cond = e.cond.unwrap_or(1.0).max(1.0);
                        max_eoc = max_eoc.max(ulps.unwrap_or(0) as f64 / cond);
                    }
                    if ulps.unwrap_or(0) > max_ulps {
                        max_ulps = ulps.unwrap_or(0);
                        worst_line = format!(
                            "{max_ulps} ulps at t = {:?}: {}",
                            answer.values,
                            rayproof::shapes::shape::probe_line(
                                shape.name(),
                                Precision::F64,
                                &input
                            )
                        );
                    }
                }
                j => wrong.push(format!(
                    "{j:?}: {}",
                    rayproof::shapes::shape::probe_line(shape.name(), Precision::F64, &input)
                )),
            }
        };
        for (o, d) in sample_rays(prim, cam, 60, &mut rng) {
            judge_ray(o, d);
        }
        println!(
            "{name}: {ok} right (max {max_ulps} ulps), {} wrong, {ill} ill-posed; worst: {worst_line}",
            wrong.len()
        );
        assert!(wrong.is_empty(), "{name}:\n{}", wrong.join("\n"));
        assert!(ok >= 60, "{name}: only {ok} judged");
        // The routine's own bound for its `generic` class (the renderer's rays are generic; the
        // torus table notes that origins close to the surface, as secondary rays have, cost it
        // the most there)
        let info = shape.info();
        let robust = info.methods.iter().find(|m| m.robust).unwrap();
        let table = rayproof::audit::tolerance::Table::built_in();
        let rule = table
            .rule(info.name, robust.name, Precision::F64, "generic")
            .expect("the robust rows have a rule");
        assert!(
            rule.max_ulps.is_some() || rule.max_err_over_cond.is_some(),
            "the robust rows hold a bound"
        );
        if let Some(bound) = rule.max_ulps {
            assert!(
                max_ulps <= bound,
                "{name}: {max_ulps} ulps > {bound}; {worst_line}"
            );
        }
        if let Some(bound) = rule.max_err_over_cond {
            assert!(
                max_eoc <= bound,
                "{name}: err/cond {max_eoc} > {bound}; {worst_line}"
            );
        }
        judged += 1;
    }
    assert_eq!(judged, 3, "box, cylinder side and torus");
}
