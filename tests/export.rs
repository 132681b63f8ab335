//! The exporters and `downsample` (`src/export.rs`), checked against what the other side does:
//!
//! - POV-Ray: the exported camera, traced with POV-Ray's own pixel mapping at the supersampled
//!   size the render script uses, gives rayproof's primary rays (to 1e-12); the fade trick gives
//!   I/(π d²); opaque glass shadows get hidden casters; the global settings of the recipe.
//! - Mitsuba: well-formed XML (a small strict parser), the sensor/sampler/film settings of the
//!   recipe, far_clip beyond the far spheres, nothing mirrored, names escaped, `--width`/`--grid`.
//! - `rayproof downsample`: block means, and one-line errors (exit 2) that leave nothing behind.
//! - `rayproof export`: one-line errors for a bad target and a missing scene.

use crate::common::{rayproof, stderr};
use glam::DVec3;
use rayproof::render::export::{mitsuba, povray};
use rayproof::render::scene::Frame;
use rayproof::render::scene::{self, Material, Scene, Shape};
use std::collections::BTreeSet;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::process::Output;

// ---------------------------------------------------------------- shared helpers

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scene_path(name: &str) -> PathBuf {
    root().join("reference/scenes").join(format!("{name}.toml"))
}

fn load(name: &str) -> Scene {
    let p = scene_path(name);
    scene::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Oblique camera, up hint not orthogonal to the view direction, fov 73°, 320×200; transmissive
/// glass shadows and max_depth 7 (so neither is the reference scenes' value).
const OBLIQUE: &str = r#"
[camera]
position = [3.7, -2.1, 5.3]
look_at = [-1.2, 0.4, -0.9]
up = [0.3, 1.0, 0.45]
fov = 73.0
width = 320
height = 200
grid = 3

[render]
max_depth = 7
glass_shadows = "transmissive"

[[lights]]
position = [-2.5, 4.0, -3.25]
intensity = [12.0, 7.5, 3.0]

[[lights]]
position = [6.0, 0.5, 2.0]
intensity = [0.75, 1.5, 2.25]

[materials.matte]
type = "diffuse"
albedo = [0.5, 0.6, 0.7]

[materials.water]
type = "glass"
ior = 1.33

[[shapes]]
type = "sphere"
center = [0.5, 0.25, -1.5]
radius = 0.75
material = "water"

[[shapes]]
type = "sphere"
center = [-1.0, 0.0, 1.0]
radius = 0.5
material = "matte"
"#;

fn oblique() -> Scene {
    scene::parse(OBLIQUE, &root().join("reference/scenes/oblique.toml")).expect("valid scene")
}

/// Every reference scene (and the oblique one), by name.
fn all_scenes() -> Vec<(String, Scene)> {
    let mut names: Vec<String> = std::fs::read_dir(root().join("reference/scenes"))
        .expect("reference/scenes")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    for want in ["diffuse", "fan30", "far", "floor", "glass", "mirror"] {
        assert!(
            names.iter().any(|n| n == want),
            "reference/scenes/{want}.toml missing"
        );
    }
    let mut v: Vec<(String, Scene)> = names.into_iter().map(|n| (n.clone(), load(&n))).collect();
    v.push(("oblique".into(), oblique()));
    v
}

/// A usage error: exit code 2, exactly one line on stderr naming every one of `what`, no
/// panic, nothing on stdout.
fn assert_one_line_error(o: &Output, what: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    for w in what {
        assert!(err.contains(w), "'{w}' not named in: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        o.stdout.is_empty(),
        "stdout: {}",
        String::from_utf8_lossy(&o.stdout)
    );
}

/// A fresh directory under the system temp dir, named after the test and this process;
/// removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!("rayproof-export-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("create temp dir");
        TempDir(p)
    }
    fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
    /// Names of the files in the directory.
    fn listing(&self) -> BTreeSet<String> {
        std::fs::read_dir(&self.0)
            .expect("temp dir")
            .map(|e| {
                e.expect("dir entry")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn set(names: &[&str]) -> BTreeSet<String> {
    names.iter().map(|s| s.to_string()).collect()
}

// ---------------------------------------------------------------- POV-Ray text parsing

/// The text right after `key` in `line`.
fn after<'a>(line: &'a str, key: &str) -> &'a str {
    let i = line
        .find(key)
        .unwrap_or_else(|| panic!("'{key}' not in: {line}"));
    &line[i + key.len()..]
}

/// The `<x, y, z>` vector right after `key`, as written (POV-Ray's frame).
fn vec_after(line: &str, key: &str) -> [f64; 3] {
    let rest = after(line, key).trim_start();
    assert!(rest.starts_with('<'), "no vector after '{key}' in: {line}");
    let body = &rest[1..rest.find('>').expect("closing '>'")];
    let v: Vec<f64> = body
        .split(',')
        .map(|t| {
            t.trim()
                .parse()
                .unwrap_or_else(|_| panic!("bad number '{t}' in: {line}"))
        })
        .collect();
    assert_eq!(v.len(), 3, "not a 3-vector after '{key}' in: {line}");
    [v[0], v[1], v[2]]
}

/// The number right after `key`.
fn num_after(line: &str, key: &str) -> f64 {
    let t = after(line, key)
        .split(|c: char| c.is_whitespace() || c == ',' || c == '}')
        .find(|t| !t.is_empty())
        .expect("a number");
    t.parse()
        .unwrap_or_else(|_| panic!("bad number '{t}' after '{key}' in: {line}"))
}

/// POV-Ray (left-handed) to rayproof (right-handed): z back.
fn mirror(a: [f64; 3]) -> DVec3 {
    DVec3::new(a[0], a[1], -a[2])
}

fn lines_starting<'a>(text: &'a str, prefix: &str) -> Vec<&'a str> {
    text.lines()
        .filter(|l| l.trim_start().starts_with(prefix))
        .collect()
}

// ---------------------------------------------------------------- 1. POV-Ray camera

/// rayproof's primary ray for sub-cell (i, j) of pixel (x, y) in a W×H image with an n×n grid
/// (the camera model of `render::run`, written out independently).
fn rayproof_ray(
    s: &Scene,
    (w, h, n): (u32, u32, u32),
    (x, y, i, j): (u32, u32, u32, u32),
) -> DVec3 {
    let cam = &s.file.camera;
    let pos = DVec3::from_array(cam.position);
    let fwd = (DVec3::from_array(cam.look_at) - pos).normalize();
    let right = fwd.cross(DVec3::from_array(cam.up)).normalize();
    let up = right.cross(fwd);
    let t = (cam.fov.to_radians() / 2.0).tan();
    let u = (x as f64 + (i as f64 + 0.5) / n as f64) / w as f64;
    let v = (y as f64 + (j as f64 + 0.5) / n as f64) / h as f64;
    (fwd + right * ((2.0 * u - 1.0) * t) + up * ((1.0 - 2.0 * v) * t * h as f64 / w as f64))
        .normalize()
}

/// Checks the exported camera of `s` in frame `fr`, traced by POV-Ray at n·W × n·H without
/// anti-aliasing, against rayproof's rays at W×H with an n×n grid.
fn check_pov_camera(name: &str, s: &Scene, fr: Frame, n: u32) {
    let text = povray(s, fr);
    let cams = lines_starting(&text, "camera");
    assert_eq!(cams.len(), 1, "{name}: one camera line expected");
    let line = cams[0];
    assert!(
        line.contains("camera { perspective location <"),
        "{name}: {line}"
    );
    // Location maps back to the camera position
    let loc = vec_after(line, "location");
    assert_eq!(
        mirror(loc).to_array(),
        s.file.camera.position,
        "{name}: location {loc:?} is not the mirrored camera position"
    );
    let (dir, right, up) = (
        DVec3::from_array(vec_after(line, "direction")),
        DVec3::from_array(vec_after(line, "right")),
        DVec3::from_array(vec_after(line, "up")),
    );
    // Pixels at the supersampled size: corners, centre and a few off-centre ones
    let (sw, sh) = (fr.width * n, fr.height * n);
    let xs = [0, 1, sw / 2, sw / 3 + 1, sw - 1];
    let ys = [0, 1, sh / 2, 2 * sh / 3 + 1, sh - 1];
    for &px in &xs {
        for &py in &ys {
            // POV-Ray's tracepixel mapping, in POV-Ray's frame, then mirrored back
            let xf = (px as f64 + 0.5) / sw as f64 - 0.5;
            let yf = 0.5 - (py as f64 + 0.5) / sh as f64;
            let pov_ray = dir + right * xf + up * yf;
            let theirs = mirror(pov_ray.to_array()).normalize();
            let ours = rayproof_ray(
                s,
                (fr.width, fr.height, n),
                (px / n, py / n, px % n, py % n),
            );
            let err = (theirs - ours).abs().max_element();
            assert!(
                err <= 1e-12,
                "{name} at {}x{} (grid {n}): pixel ({px}, {py}) POV-Ray {theirs:?} vs rayproof {ours:?}, error {err:e}",
                fr.width,
                fr.height
            );
        }
    }
}

#[test]
fn povray_camera_gives_rayproof_primary_rays() {
    for (name, s) in all_scenes() {
        // The scene's own frame, traced at 8× as the render script does
        let fr = Frame::of(&s, None, None).unwrap();
        assert_eq!(
            (fr.width, fr.height),
            (
                *s.file.camera.width.get_ref(),
                *s.file.camera.height.get_ref()
            )
        );
        check_pov_camera(&name, &s, fr, 8);
        // The render script's frame: 256 wide with the scene's aspect, 8×8 grid
        let fr = Frame::of(&s, Some(256), Some(8)).unwrap();
        check_pov_camera(&name, &s, fr, fr.grid);
    }
    // The oblique scene at 256 wide is 256×160 (same aspect as 320×200)
    let fr = Frame::of(&oblique(), Some(256), None).unwrap();
    assert_eq!((fr.width, fr.height, fr.grid), (256, 160, 3));
}

#[test]
fn povray_cli_matches_the_library_for_width_and_grid() {
    // `rayproof export --to povray SCENE --width 256 --grid 8` is povray(Frame::of(.., 256, 8))
    let p = scene_path("floor");
    let o = rayproof(&[
        "export",
        "--to",
        "povray",
        p.to_str().unwrap(),
        "--width",
        "256",
        "--grid",
        "8",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = scene::load(&p).expect("floor.toml");
    let want = povray(&s, Frame::of(&s, Some(256), Some(8)).unwrap());
    assert_eq!(String::from_utf8(o.stdout).expect("UTF-8"), want);
    assert!(want.contains("Render at 2048x1536 with -A"), "{want}");
}

// ---------------------------------------------------------------- 2. POV-Ray lights

#[test]
fn povray_light_fade_gives_inverse_square_over_pi() {
    let mut mirrored_z = false;
    for (name, s) in all_scenes() {
        let text = povray(&s, Frame::of(&s, None, None).unwrap());
        let lights = lines_starting(&text, "light_source");
        assert_eq!(
            lights.len(),
            s.file.lights.len(),
            "{name}: one light_source per light"
        );
        for (line, l) in lights.iter().zip(&s.file.lights) {
            // Position: z mirrored, x and y as they are
            let p = vec_after(line, "light_source {");
            assert_eq!(mirror(p).to_array(), l.position, "{name}: {line}");
            mirrored_z |= l.position[2] != 0.0;
            // POV-Ray's attenuation 2/(1 + (d/fd)^power) times the colour is I/(π d²)
            let c = vec_after(line, "color rgb");
            let fd = num_after(line, "fade_distance");
            let power = num_after(line, "fade_power");
            assert_eq!(power, 2.0, "{name}: {line}");
            for d in [1.0, 10.0, 1e3] {
                let atten = 2.0 / (1.0 + (d / fd).powf(power));
                for (k, (ck, ik)) in c.iter().zip(l.intensity).enumerate() {
                    let got = ck * atten;
                    let want = ik / (PI * d * d);
                    let rel = (got - want).abs() / want.abs();
                    assert!(
                        rel <= 1e-6,
                        "{name}: channel {k} at d = {d}: POV-Ray gives {got:e}, I/(πd²) = {want:e} (relative {rel:e}); {line}"
                    );
                }
            }
        }
    }
    assert!(
        mirrored_z,
        "no light with z ≠ 0: the mirroring went unchecked"
    );
}

// ---------------------------------------------------------------- 3. POV-Ray glass shadows

/// The hidden shadow casters of a POV-Ray export: (centre as written, radius).
fn casters(text: &str) -> Vec<([f64; 3], f64)> {
    text.lines()
        .filter(|l| l.contains("no_image"))
        .map(|l| {
            assert!(
                l.starts_with("sphere {") && l.contains("no_image no_reflection"),
                "{l}"
            );
            (vec_after(l, "sphere {"), num_after(after(l, ">"), ","))
        })
        .collect()
}

fn glass_spheres(s: &Scene) -> Vec<([f64; 3], f64)> {
    s.file
        .shapes
        .iter()
        .filter_map(|sh| match sh {
            Shape::Sphere {
                center,
                radius,
                material,
            } => matches!(s.file.materials[material], Material::Glass { .. })
                .then_some((*center, *radius)),
            _ => None,
        })
        .collect()
}

#[test]
fn povray_opaque_glass_shadows_get_hidden_casters() {
    // Opaque (glass.toml, fan30.toml): one caster per glass sphere, radius r(1 − 1e-5)
    for name in ["glass", "fan30"] {
        let s = load(name);
        let glass = glass_spheres(&s);
        assert!(!glass.is_empty(), "{name} has glass spheres");
        let got = casters(&povray(&s, Frame::of(&s, None, None).unwrap()));
        assert_eq!(
            got.len(),
            glass.len(),
            "{name}: one caster per glass sphere"
        );
        for ((c, r), (gc, gr)) in got.iter().zip(&glass) {
            assert_eq!(mirror(*c).to_array(), *gc, "{name}: caster centre");
            let want = gr * (1.0 - 1e-5);
            assert!(
                (r - want).abs() <= 1e-15 * gr && *r < *gr,
                "{name}: caster radius {r} for r = {gr}"
            );
        }
    }
    // The same scene text with transmissive shadows: none
    let p = scene_path("glass");
    let text = std::fs::read_to_string(&p).expect("glass.toml");
    assert!(text.contains("glass_shadows = \"opaque\""));
    let s = scene::parse(
        &text.replace(
            "glass_shadows = \"opaque\"",
            "glass_shadows = \"transmissive\"",
        ),
        &p,
    )
    .expect("valid scene");
    assert!(!glass_spheres(&s).is_empty());
    let out = povray(&s, Frame::of(&s, None, None).unwrap());
    assert!(
        casters(&out).is_empty(),
        "transmissive glass got a caster:\n{out}"
    );
    assert!(!out.contains("no_image"));
}

#[test]
fn povray_global_settings_follow_the_recipe() {
    for (name, s) in all_scenes() {
        let text = povray(&s, Frame::of(&s, None, None).unwrap());
        assert!(text.contains("#version 3.7;"), "{name}");
        let g = lines_starting(&text, "global_settings");
        assert_eq!(g.len(), 1, "{name}: one global_settings");
        let g = g[0];
        assert_eq!(
            num_after(g, "max_trace_level"),
            s.file.render.max_depth as f64,
            "{name}: {g}"
        );
        assert_eq!(num_after(g, "adc_bailout"), 0.0, "{name}: {g}");
        assert_eq!(num_after(g, "assumed_gamma"), 1.0, "{name}: {g}");
        assert!(g.contains("assumed_gamma 1.0"), "{name}: {g}");
        assert_eq!(num_after(g, "ambient_light"), 0.0, "{name}: {g}");
    }
    // max_trace_level follows the scene (7 in the oblique scene, 1 in far.toml)
    assert!(
        povray(&oblique(), Frame::of(&oblique(), None, None).unwrap())
            .contains("max_trace_level 7 ")
    );
    assert!(
        povray(&load("far"), Frame::of(&load("far"), None, None).unwrap())
            .contains("max_trace_level 1 ")
    );
}

// ---------------------------------------------------------------- 4. Mitsuba

/// One XML element: tag, unescaped attributes, parent element index.
#[derive(Debug)]
struct Elem {
    tag: String,
    attrs: Vec<(String, String)>,
    parent: Option<usize>,
}

impl Elem {
    fn attr(&self, k: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| v.as_str())
    }
}

fn unescape(v: &str) -> String {
    let mut out = String::new();
    let mut rest = v;
    while let Some(i) = rest.find('&') {
        out.push_str(&rest[..i]);
        let ent = [
            ("&amp;", '&'),
            ("&quot;", '"'),
            ("&lt;", '<'),
            ("&gt;", '>'),
            ("&apos;", '\''),
        ]
        .into_iter()
        .find(|(e, _)| rest[i..].starts_with(e))
        .unwrap_or_else(|| panic!("bare '&' in attribute value: {v}"));
        out.push(ent.1);
        rest = &rest[i + ent.0.len()..];
    }
    out + rest
}

/// A strict parser for the exporter's XML: comments, elements, double-quoted attributes,
/// whitespace between tags. Panics on anything malformed; checks that every opened element of
/// the exporter's tags is closed by its own tag (counts and nesting) under one `<scene>`.
fn parse_xml(text: &str) -> Vec<Elem> {
    let mut elems: Vec<Elem> = vec![];
    let mut stack: Vec<usize> = vec![];
    let (mut opened, mut closed) = (
        std::collections::BTreeMap::new(),
        std::collections::BTreeMap::new(),
    );
    let mut rest = text;
    loop {
        let lt = match rest.find('<') {
            Some(i) => i,
            None => {
                assert!(rest.trim().is_empty(), "text outside elements: {rest:?}");
                break;
            }
        };
        assert!(
            rest[..lt].trim().is_empty(),
            "text between tags: {:?}",
            &rest[..lt]
        );
        rest = &rest[lt..];
        // Comment
        if rest.starts_with("<!--") {
            let end = rest.find("-->").expect("unterminated comment");
            assert!(!rest[4..end].contains("--"), "'--' inside a comment");
            rest = &rest[end + 3..];
            continue;
        }
        // Closing tag
        if let Some(r) = rest.strip_prefix("</") {
            let gt = r.find('>').expect("unterminated closing tag");
            let name = r[..gt].trim();
            let open = stack
                .pop()
                .unwrap_or_else(|| panic!("</{name}> closes nothing"));
            assert_eq!(
                elems[open].tag, name,
                "<{}> closed by </{name}>",
                elems[open].tag
            );
            *closed.entry(name.to_string()).or_insert(0) += 1;
            rest = &r[gt + 1..];
            continue;
        }
        // Opening or self-closing tag
        let mut r = &rest[1..];
        let name_len = r
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .expect("tag name");
        assert!(
            name_len > 0,
            "empty tag name at: {}",
            &rest[..rest.len().min(40)]
        );
        let tag = r[..name_len].to_string();
        r = &r[name_len..];
        let mut attrs: Vec<(String, String)> = vec![];
        let self_closing = loop {
            let t = r.trim_start();
            if let Some(t) = t.strip_prefix("/>") {
                r = t;
                break true;
            }
            if let Some(t) = t.strip_prefix('>') {
                r = t;
                break false;
            }
            assert!(
                t.len() < r.len(),
                "<{tag}: attributes must be separated by whitespace: {:?}",
                &r[..r.len().min(40)]
            );
            let eq = t.find('=').unwrap_or_else(|| {
                panic!("<{tag}: attribute without '=': {:?}", &t[..t.len().min(40)])
            });
            let key = &t[..eq];
            assert!(
                !key.is_empty() && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'),
                "<{tag}: bad attribute name {key:?}"
            );
            let v = t[eq + 1..]
                .strip_prefix('"')
                .unwrap_or_else(|| panic!("<{tag} {key}=: value not double-quoted"));
            let q = v.find('"').expect("unterminated attribute value");
            let raw = &v[..q];
            assert!(
                !raw.contains('<') && !raw.contains('>'),
                "<{tag} {key}=: unescaped '<' or '>' in {raw:?}"
            );
            assert!(
                attrs.iter().all(|(k, _)| k != key),
                "<{tag}: duplicate attribute {key}"
            );
            attrs.push((key.to_string(), unescape(raw)));
            r = &v[q + 1..];
        };
        let parent = stack.last().copied();
        assert!(
            parent.is_some() || elems.is_empty(),
            "a second top-level element <{tag}>"
        );
        elems.push(Elem {
            tag: tag.clone(),
            attrs,
            parent,
        });
        if !self_closing {
            stack.push(elems.len() - 1);
            *opened.entry(tag).or_insert(0) += 1;
        }
        rest = r;
    }
    assert!(
        stack.is_empty(),
        "unclosed: {:?}",
        stack.iter().map(|&i| &elems[i].tag).collect::<Vec<_>>()
    );
    assert_eq!(
        elems.first().map(|e| e.tag.as_str()),
        Some("scene"),
        "the root is <scene>"
    );
    for tag in [
        "scene",
        "shape",
        "bsdf",
        "emitter",
        "sensor",
        "film",
        "sampler",
        "integrator",
        "transform",
    ] {
        assert_eq!(
            opened.get(tag),
            closed.get(tag),
            "<{tag}> opened and closed a different number of times"
        );
    }
    elems
}

/// Elements with this tag whose `name` attribute is `name`.
fn named<'a>(e: &'a [Elem], tag: &str, name: &str) -> Vec<&'a Elem> {
    e.iter()
        .filter(|x| x.tag == tag && x.attr("name") == Some(name))
        .collect()
}

/// The one element `<tag name="name" value="…"/>`, its value; `within` is its parent's tag.
fn value(e: &[Elem], tag: &str, name: &str, within: &str) -> String {
    let v = named(e, tag, name);
    assert_eq!(
        v.len(),
        1,
        "one <{tag} name=\"{name}\"> expected, got {}",
        v.len()
    );
    let parent = v[0].parent.map(|p| e[p].tag.as_str());
    assert_eq!(
        parent,
        Some(within),
        "<{tag} name=\"{name}\"> is not inside <{within}>"
    );
    v[0].attr("value").expect("value attribute").to_string()
}

fn f3(s: &str) -> [f64; 3] {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse().expect("number"))
        .collect();
    assert_eq!(v.len(), 3, "not a 3-vector: {s}");
    [v[0], v[1], v[2]]
}

fn of_type<'a>(e: &'a [Elem], tag: &str, ty: &str) -> Vec<&'a Elem> {
    e.iter()
        .filter(|x| x.tag == tag && x.attr("type") == Some(ty))
        .collect()
}

/// The farthest sphere or disc point from the camera.
fn farthest_point(s: &Scene) -> f64 {
    let cam = DVec3::from_array(s.file.camera.position);
    s.file
        .shapes
        .iter()
        .filter_map(|sh| match sh {
            Shape::Sphere { center, radius, .. } | Shape::Disc { center, radius, .. } => {
                Some((DVec3::from_array(*center) - cam).length() + radius)
            }
            _ => None,
        })
        .fold(0.0, f64::max)
}

#[test]
fn mitsuba_export_is_well_formed_and_follows_the_recipe() {
    for (name, s) in all_scenes() {
        let f = &s.file;
        let fr = Frame::of(&s, None, None).unwrap();
        let e = parse_xml(&mitsuba(&s, fr));
        let ctx = |what: &str| format!("{name}: {what}");
        // Integrator
        let int = of_type(&e, "integrator", "whitted");
        assert_eq!(int.len(), 1, "{}", ctx("one whitted integrator"));
        assert_eq!(
            value(&e, "integer", "max_depth", "integrator"),
            f.render.max_depth.to_string()
        );
        // Sensor: horizontal fov, far_clip beyond the farthest sphere, not mirrored
        assert_eq!(
            of_type(&e, "sensor", "perspective").len(),
            1,
            "{}",
            ctx("one perspective sensor")
        );
        assert_eq!(
            value(&e, "string", "fov_axis", "sensor"),
            "x",
            "{}",
            ctx("fov_axis")
        );
        assert_eq!(
            value(&e, "float", "fov", "sensor").parse::<f64>().unwrap(),
            f.camera.fov
        );
        let far: f64 = value(&e, "float", "far_clip", "sensor")
            .parse()
            .expect("far_clip");
        assert!(
            far > 2.0 * farthest_point(&s),
            "{}",
            ctx(&format!(
                "far_clip {far:e} vs farthest {:e}",
                farthest_point(&s)
            ))
        );
        let look: Vec<&Elem> = e.iter().filter(|x| x.tag == "lookat").collect();
        let cam_look = look
            .iter()
            .find(|x| {
                x.parent
                    .is_some_and(|p| e[p].parent.is_some_and(|q| e[q].tag == "sensor"))
            })
            .expect("sensor lookat");
        assert_eq!(
            f3(cam_look.attr("origin").unwrap()),
            f.camera.position,
            "{}",
            ctx("lookat origin (not mirrored)")
        );
        assert_eq!(
            f3(cam_look.attr("target").unwrap()),
            f.camera.look_at,
            "{}",
            ctx("lookat target (not mirrored)")
        );
        assert_eq!(
            f3(cam_look.attr("up").unwrap()),
            f.camera.up,
            "{}",
            ctx("lookat up (not mirrored)")
        );
        // Sampler: n² cell centres, no jitter
        assert_eq!(
            of_type(&e, "sampler", "stratified").len(),
            1,
            "{}",
            ctx("stratified sampler")
        );
        let g = *f.camera.grid.get_ref();
        assert_eq!(
            value(&e, "integer", "sample_count", "sampler"),
            (g * g).to_string(),
            "{}",
            ctx("sample_count")
        );
        assert_eq!(
            value(&e, "boolean", "jitter", "sampler"),
            "false",
            "{}",
            ctx("jitter")
        );
        // Film: float32, box filter, the scene's size
        assert_eq!(
            of_type(&e, "film", "hdrfilm").len(),
            1,
            "{}",
            ctx("hdrfilm")
        );
        assert_eq!(
            value(&e, "string", "component_format", "film"),
            "float32",
            "{}",
            ctx("component_format")
        );
        assert_eq!(value(&e, "integer", "width", "film"), fr.width.to_string());
        assert_eq!(
            value(&e, "integer", "height", "film"),
            fr.height.to_string()
        );
        let rf: Vec<&Elem> = e.iter().filter(|x| x.tag == "rfilter").collect();
        assert_eq!(rf.len(), 1, "{}", ctx("one rfilter"));
        assert_eq!(rf[0].attr("type"), Some("box"), "{}", ctx("box rfilter"));
        assert_eq!(rf[0].parent.map(|p| e[p].tag.as_str()), Some("film"));
        // Emitters: one point per light, positions not mirrored
        let em = of_type(&e, "emitter", "point");
        assert_eq!(em.len(), f.lights.len(), "{}", ctx("one emitter per light"));
        let positions: Vec<[f64; 3]> = named(&e, "point", "position")
            .iter()
            .map(|p| f3(p.attr("value").unwrap()))
            .collect();
        let intensities: Vec<[f64; 3]> = named(&e, "rgb", "intensity")
            .iter()
            .map(|p| f3(p.attr("value").unwrap()))
            .collect();
        assert_eq!(
            positions,
            f.lights.iter().map(|l| l.position).collect::<Vec<_>>(),
            "{}",
            ctx("light positions")
        );
        assert_eq!(
            intensities,
            f.lights.iter().map(|l| l.intensity).collect::<Vec<_>>(),
            "{}",
            ctx("light intensities")
        );
        // Glass: dielectric with ext_ior 1.0 and the scene's ior
        let glass: Vec<(&String, f64)> = f
            .materials
            .iter()
            .filter_map(|(n, m)| match m {
                Material::Glass { ior } => Some((n, *ior)),
                _ => None,
            })
            .collect();
        let diel = of_type(&e, "bsdf", "dielectric");
        assert_eq!(
            diel.len(),
            glass.len(),
            "{}",
            ctx("one dielectric per glass material")
        );
        for (n, ior) in &glass {
            let b = e
                .iter()
                .position(|x| {
                    x.tag == "bsdf"
                        && x.attr("type") == Some("dielectric")
                        && x.attr("id") == Some(n.as_str())
                })
                .unwrap_or_else(|| panic!("{}", ctx(&format!("no dielectric with id {n}"))));
            let kids = |k: &str| {
                e.iter()
                    .filter(|x| x.parent == Some(b) && x.attr("name") == Some(k))
                    .map(|x| x.attr("value").unwrap().to_string())
                    .collect::<Vec<_>>()
            };
            assert_eq!(kids("ext_ior"), ["1.0"], "{}", ctx("ext_ior"));
            assert_eq!(
                kids("int_ior")
                    .iter()
                    .map(|v| v.parse::<f64>().unwrap())
                    .collect::<Vec<_>>(),
                [*ior],
                "{}",
                ctx("int_ior")
            );
        }
        // Spheres: centres not mirrored
        let centres: Vec<[f64; 3]> = named(&e, "point", "center")
            .iter()
            .map(|p| f3(p.attr("value").unwrap()))
            .collect();
        let want: Vec<[f64; 3]> = f
            .shapes
            .iter()
            .filter_map(|sh| match sh {
                Shape::Sphere { center, .. } => Some(*center),
                _ => None,
            })
            .collect();
        assert_eq!(centres, want, "{}", ctx("sphere centres"));
        assert_eq!(of_type(&e, "shape", "sphere").len(), want.len());
    }
}

#[test]
fn mitsuba_far_clip_reaches_the_far_spheres() {
    // far.toml has a sphere 1e6 away; Mitsuba's default far_clip (1e4) once hid it
    let s = load("far");
    let far_point = farthest_point(&s);
    assert!(
        far_point > 1e6,
        "far.toml's farthest sphere point is {far_point}"
    );
    let e = parse_xml(&mitsuba(&s, Frame::of(&s, None, None).unwrap()));
    let far: f64 = value(&e, "float", "far_clip", "sensor").parse().unwrap();
    assert!(
        far.is_finite() && far > 2.0 * far_point,
        "far_clip {far:e} vs 2 × {far_point:e}"
    );
}

#[test]
fn mitsuba_escapes_material_names() {
    let name = r#"he said "hi" <b> & left"#;
    let text = format!(
        "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 40.0\nwidth = 8\nheight = 8\n\
         [[lights]]\nposition = [1.0, 2.0, 3.0]\nintensity = [1.0, 1.0, 1.0]\n\
         [materials.'{name}']\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = '{name}'\n"
    );
    let s = scene::parse(&text, Path::new("escape.toml")).expect("valid scene");
    assert!(s.file.materials.contains_key(name));
    let xml = mitsuba(&s, Frame::of(&s, None, None).unwrap());
    assert!(!xml.contains(name), "raw name in the XML:\n{xml}");
    let e = parse_xml(&xml);
    // The id and the reference both read back as the name
    let ids: Vec<&str> = e
        .iter()
        .filter(|x| x.tag == "bsdf")
        .filter_map(|x| x.attr("id"))
        .collect();
    assert_eq!(ids, [name]);
    let refs: Vec<&str> = e
        .iter()
        .filter(|x| x.tag == "ref")
        .filter_map(|x| x.attr("id"))
        .collect();
    assert_eq!(refs, [name]);
}

/// `rayproof export --to mitsuba` of a reference scene with extra arguments, parsed.
fn mitsuba_cli(scene: &str, extra: &[&str]) -> Vec<Elem> {
    let p = scene_path(scene);
    let mut args = vec!["export", "--to", "mitsuba", p.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = rayproof(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    parse_xml(&String::from_utf8(o.stdout).expect("UTF-8"))
}

#[test]
fn mitsuba_cli_width_and_grid() {
    let size = |e: &[Elem]| {
        (
            value(e, "integer", "width", "film"),
            value(e, "integer", "height", "film"),
            value(e, "integer", "sample_count", "sampler"),
        )
    };
    // fan30 is 1024×1024 with grid 1 in the file
    assert_eq!(
        size(&mitsuba_cli("fan30", &[])),
        ("1024".into(), "1024".into(), "1".into())
    );
    assert_eq!(
        size(&mitsuba_cli("fan30", &["--width", "256", "--grid", "8"])),
        ("256".into(), "256".into(), "64".into())
    );
    // floor is 256×192: 128 wide keeps the aspect
    assert_eq!(
        size(&mitsuba_cli("floor", &["--width", "128"])),
        ("128".into(), "96".into(), "1".into())
    );
}

// ---------------------------------------------------------------- 5. downsample

/// A 4×6 test image whose 2×2 block means are exact in f32, different per channel and position.
fn test_pixels() -> (usize, usize, Vec<[f32; 3]>) {
    let (w, h) = (4, 6);
    let px = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            [
                x + 4.0 * y,
                0.5 * x * x - 3.0 * y,
                1000.0 - 7.0 * x * y + 0.25 * y * y,
            ]
        })
        .collect();
    (w, h, px)
}

/// A float32 R, G, B EXR, written atomically by the library's writer.
fn write_rgb(path: &Path, w: usize, h: usize, px: &[[f32; 3]]) -> anyhow::Result<()> {
    let data = px.iter().flatten().copied().collect();
    rayproof::images::write_exr_rgb(path, &rayproof::images::Image::rgb(w, h, data))
}

#[test]
fn downsample_averages_blocks() {
    let dir = TempDir::new("downsample_averages_blocks");
    let (input, output) = (dir.join("in.exr"), dir.join("out.exr"));
    let (w, h, px) = test_pixels();
    write_rgb(&input, w, h, &px).expect("write EXR");
    assert_eq!(
        dir.listing(),
        set(&["in.exr"]),
        "write_rgb_exr left a temporary file"
    );
    let o = rayproof(&[
        "downsample",
        input.to_str().unwrap(),
        "--factor",
        "2",
        "-o",
        output.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(dir.listing(), set(&["in.exr", "out.exr"]));
    let img = rayproof::images::read_image(&output).expect("read the output");
    assert_eq!((img.width, img.height), (2, 3));
    assert_eq!(img.channels, ["R", "G", "B"]);
    for oy in 0..3 {
        for ox in 0..2 {
            // The block's mean in f64 (exact for these values), then f32
            let mut sum = [0f64; 3];
            for (i, j) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                for (s, v) in sum.iter_mut().zip(px[(2 * oy + j) * w + 2 * ox + i]) {
                    *s += v as f64;
                }
            }
            let want = sum.map(|s| (s / 4.0) as f32);
            let got = &img.data[(oy * 2 + ox) * 3..][..3];
            assert_eq!(got, want, "pixel ({ox}, {oy})");
        }
    }
}

#[test]
fn downsample_factor_must_divide_the_size() {
    let dir = TempDir::new("downsample_factor_must_divide_the_size");
    let (input, output) = (dir.join("in.exr"), dir.join("out.exr"));
    let (w, h, px) = test_pixels();
    write_rgb(&input, w, h, &px).expect("write EXR");
    let o = rayproof(&[
        "downsample",
        input.to_str().unwrap(),
        "--factor",
        "3",
        "-o",
        output.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, &["in.exr", "3"]);
    assert_eq!(
        dir.listing(),
        set(&["in.exr"]),
        "output or temporary file left behind"
    );
}

#[test]
fn downsample_rejects_corrupt_input() {
    let dir = TempDir::new("downsample_rejects_corrupt_input");
    // A valid EXR cut in half, and a file that is no EXR at all: one line, exit 4
    let (w, h, px) = test_pixels();
    let good = dir.join("good.exr");
    write_rgb(&good, w, h, &px).expect("write EXR");
    let bytes = std::fs::read(&good).expect("read EXR");
    std::fs::remove_file(&good).expect("remove");
    std::fs::write(dir.join("cut.exr"), &bytes[..bytes.len() / 2]).expect("write");
    std::fs::write(dir.join("text.exr"), b"this is not an OpenEXR file\n").expect("write");
    for bad in ["cut.exr", "text.exr"] {
        let output = dir.join("out.exr");
        let o = rayproof(&[
            "downsample",
            dir.join(bad).to_str().unwrap(),
            "--factor",
            "2",
            "-o",
            output.to_str().unwrap(),
        ]);
        // An unreadable image exits 4, as in `diff` (the Limits table's code for image files)
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(4), "stderr: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
        assert!(err.contains(bad) && !err.contains("panicked"), "{err}");
        assert!(o.stdout.is_empty());
        assert_eq!(
            dir.listing(),
            set(&["cut.exr", "text.exr"]),
            "{bad}: output or temporary file left behind"
        );
    }
}

#[test]
fn downsample_missing_output_directory_fails_first() {
    let dir = TempDir::new("downsample_missing_output_directory_fails_first");
    let input = dir.join("in.exr");
    let (w, h, px) = test_pixels();
    write_rgb(&input, w, h, &px).expect("write EXR");
    let output = dir.join("no-such-dir").join("out.exr");
    let o = rayproof(&[
        "downsample",
        input.to_str().unwrap(),
        "--factor",
        "2",
        "-o",
        output.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, &["no-such-dir"]);
    assert_eq!(dir.listing(), set(&["in.exr"]), "something was written");
    // Checked before the input is read: an unreadable input still gets the directory error
    std::fs::write(dir.join("bad.exr"), b"not an EXR\n").expect("write");
    let o = rayproof(&[
        "downsample",
        dir.join("bad.exr").to_str().unwrap(),
        "--factor",
        "2",
        "-o",
        output.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, &["no-such-dir", "does not exist"]);
    assert_eq!(
        dir.listing(),
        set(&["bad.exr", "in.exr"]),
        "something was written"
    );
}

// ---------------------------------------------------------------- 6. export errors

#[test]
fn export_unknown_target_names_the_possible_values() {
    let p = scene_path("diffuse");
    let o = rayproof(&["export", "--to", "blender", p.to_str().unwrap()]);
    assert_one_line_error(&o, &["blender", "povray", "mitsuba"]);
}

#[test]
fn export_missing_scene_is_named() {
    let dir = TempDir::new("export_missing_scene_is_named");
    let missing = dir.join("missing-scene.toml");
    for to in ["povray", "mitsuba"] {
        let o = rayproof(&["export", "--to", to, missing.to_str().unwrap()]);
        assert_one_line_error(&o, &["missing-scene.toml"]);
    }
}

// ---------------------------------------------------------------- 7. boxes, cylinders, ellipsoids, tori

/// A scene with one shape of each new kind, off-centre in every axis, in `material`.
fn solids(material: &str, shadows: &str) -> Scene {
    let text = format!(
        "[camera]\nposition = [0.0, 2.0, 8.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 40.0\nwidth = 64\nheight = 48\n\
         [render]\nglass_shadows = \"{shadows}\"\n\
         [[lights]]\nposition = [1.0, 5.0, 2.0]\nintensity = [9.0, 9.0, 9.0]\n\
         [materials.m]\n{material}\n\
         [[shapes]]\ntype = \"box\"\nmin = [-3.0, 0.25, -2.0]\nmax = [-1.5, 1.0, -0.75]\nmaterial = \"m\"\n\
         [[shapes]]\ntype = \"cylinder\"\nbase = [2.0, -0.5, 1.25]\nradius = 0.75\nheight = 1.5\nmaterial = \"m\"\n\
         [[shapes]]\ntype = \"ellipsoid\"\ncenter = [0.5, 1.5, -2.5]\nradii = [1.0, 0.5, 0.25]\nmaterial = \"m\"\n\
         [[shapes]]\ntype = \"torus\"\ncenter = [-0.5, 0.25, 2.0]\nmajor = 1.0\nminor = 0.375\nmaterial = \"m\"\n"
    );
    scene::parse(&text, &root().join("reference/scenes/solids.toml")).expect("valid scene")
}

const DIFFUSE: &str = "type = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]";

#[test]
fn povray_writes_native_primitives_mirrored_in_z() {
    let s = solids(DIFFUSE, "opaque");
    let out = povray(&s, Frame::of(&s, None, None).unwrap());
    let objects: Vec<&str> = out
        .lines()
        .filter(|l| {
            ["box", "cylinder", "sphere", "torus"]
                .iter()
                .any(|k| l.starts_with(&format!("{k} {{")))
        })
        .collect();
    assert_eq!(
        objects,
        [
            // z ∈ [−2, −0.75] becomes [0.75, 2]: the corners keep x, y and negate z
            "box { <-3, 0.25, 2>, <-1.5, 1, 0.75>",
            // POV-Ray's cylinder is closed unless `open`: base and top along +y
            "cylinder { <2, -0.5, -1.25>, <2, 1, -1.25>, 0.75",
            // Radii are lengths (not mirrored); the centre is
            "sphere { <0, 0, 0>, 1 scale <1, 0.5, 0.25> translate <0.5, 1.5, 2.5>",
            // POV-Ray's torus is in its xz plane around +y, like ours
            "torus { 1, 0.375 translate <-0.5, 0.25, -2>",
        ],
        "{out}"
    );
    assert!(!out.contains(" open"), "{out}");
    // Diffuse: no hidden casters
    assert!(!out.contains("no_image"));
}

#[test]
fn povray_glass_solids_get_hidden_casters_inside_them() {
    let glass = "type = \"glass\"\nior = 1.5";
    let out = povray(
        &solids(glass, "opaque"),
        Frame::of(&solids(glass, "opaque"), None, None).unwrap(),
    );
    let casters: Vec<&str> = out.lines().filter(|l| l.contains("no_image")).collect();
    let k = 1.0 - 1e-5;
    let want = [
        format!(
            "box {{ <{}, {}, {}>, <{}, {}, {}>",
            -3.0 + 1.5 * 0.5e-5,
            0.25 + 0.75 * 0.5e-5,
            -(-2.0 + 1.25 * 0.5e-5),
            -1.5 - 1.5 * 0.5e-5,
            1.0 - 0.75 * 0.5e-5,
            -(-0.75 - 1.25 * 0.5e-5)
        ),
        format!(
            "cylinder {{ <2, {}, -1.25>, <2, {}, -1.25>, {}",
            -0.5 + 1.5 * 0.5e-5,
            -0.5 + 1.5 * 0.5e-5 + 1.5 * k,
            0.75 * k
        ),
        format!(
            "sphere {{ <0, 0, 0>, 1 scale <{}, {}, {}> translate <0.5, 1.5, 2.5>",
            k,
            0.5 * k,
            0.25 * k
        ),
        format!("torus {{ 1, {} translate <-0.5, 0.25, -2>", 0.375 * k),
    ];
    assert_eq!(casters.len(), 4, "{out}");
    for (c, w) in casters.iter().zip(&want) {
        assert!(
            c.starts_with(w.as_str()) && c.contains("no_image no_reflection"),
            "{c}\nexpected {w}"
        );
    }
    // Transmissive glass shadows: none
    let t = solids(glass, "transmissive");
    assert!(!povray(&t, Frame::of(&t, None, None).unwrap()).contains("no_image"));
}

/// The PLY files a Mitsuba export refers to, read back: (vertex count, face count, positions,
/// normals, faces).
type Ply = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[i32; 3]>);

fn read_ply(path: &Path) -> Ply {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("PLY header")
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    let count = |el: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {el} ")))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    assert_eq!(bytes.len(), end + nv * 24 + nf * 13, "PLY size");
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let (mut pos, mut nrm, mut faces) = (vec![], vec![], vec![]);
    for v in 0..nv {
        let o = end + v * 24;
        pos.push([f32_at(o), f32_at(o + 4), f32_at(o + 8)]);
        nrm.push([f32_at(o + 12), f32_at(o + 16), f32_at(o + 20)]);
    }
    for f in 0..nf {
        let o = end + nv * 24 + f * 13;
        assert_eq!(bytes[o], 3);
        let i =
            |k: usize| i32::from_le_bytes(bytes[o + 1 + 4 * k..o + 5 + 4 * k].try_into().unwrap());
        faces.push([i(0), i(1), i(2)]);
    }
    (pos, nrm, faces)
}

#[test]
fn mitsuba_uses_cube_cylinder_disks_and_closed_ply_meshes() {
    let s = solids(DIFFUSE, "opaque");
    let e = parse_xml(&mitsuba(&s, Frame::of(&s, None, None).unwrap()));
    // Box: the cube [-1, 1]³ scaled to the half extents and moved to the centre
    assert_eq!(of_type(&e, "shape", "cube").len(), 1);
    let cube = e
        .iter()
        .position(|x| x.tag == "shape" && x.attr("type") == Some("cube"))
        .unwrap();
    let in_cube = |tag: &str| {
        let x = e
            .iter()
            .find(|x| x.tag == tag && x.parent.is_some_and(|p| e[p].parent == Some(cube)))
            .unwrap_or_else(|| panic!("no <{tag}> in the cube's transform"));
        f3(x.attr("value").unwrap())
    };
    assert_eq!(in_cube("scale"), [0.75, 0.375, 0.625]);
    assert_eq!(in_cube("translate"), [-2.25, 0.625, -1.375]);
    // Cylinder: p0, p1 along +y, radius, plus two disks (the caps)
    assert_eq!(of_type(&e, "shape", "cylinder").len(), 1);
    assert_eq!(f3(&value(&e, "point", "p0", "shape")), [2.0, -0.5, 1.25]);
    assert_eq!(f3(&value(&e, "point", "p1", "shape")), [2.0, 1.0, 1.25]);
    assert_eq!(of_type(&e, "shape", "disk").len(), 2);
    // Ellipsoid and torus: PLY files that exist, closed (every edge in exactly two faces),
    // vertices on the exact surface, outward normals
    let files: Vec<String> = named(&e, "string", "filename")
        .iter()
        .map(|x| x.attr("value").unwrap().to_string())
        .collect();
    assert_eq!(files.len(), 2);
    let on_surface: [&dyn Fn([f64; 3]) -> f64; 2] = [
        &|p| {
            // Ellipsoid: |(p − c)/r| − 1
            ((p[0] - 0.5) / 1.0)
                .hypot((p[1] - 1.5) / 0.5)
                .hypot((p[2] + 2.5) / 0.25)
                - 1.0
        },
        &|p| {
            // Torus: distance to the tube's centre circle − minor
            let (x, y, z) = (p[0] + 0.5, p[1] - 0.25, p[2] - 2.0);
            (x.hypot(z) - 1.0).hypot(y) - 0.375
        },
    ];
    for (file, f) in files.iter().zip(on_surface) {
        let (pos, nrm, faces) = read_ply(Path::new(file));
        let mut edges = std::collections::HashMap::new();
        for t in &faces {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                // Each directed edge once: consistent winding
                assert!(a != b, "degenerate face {t:?}");
            }
            let p = |i: i32| DVec3::from_array(pos[i as usize].map(|x| x as f64));
            let g = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
            let n = DVec3::from_array(nrm[t[0] as usize].map(|x| x as f64));
            assert!(g.dot(n) > 0.0, "{file}: face {t:?} winds inward");
        }
        assert!(edges.values().all(|&c| c == 2), "{file}: not closed");
        let worst = pos
            .iter()
            .map(|p| f(p.map(|x| x as f64)).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{file}: a vertex is {worst} off the surface");
        for n in &nrm {
            let l = DVec3::from_array(n.map(|x| x as f64)).length();
            assert!((l - 1.0).abs() < 1e-6, "{file}: normal length {l}");
        }
    }
}

#[test]
fn tessellations_stay_within_their_tolerance_of_the_exact_surface() {
    use rayproof::render::export::{tessellate, TESS_TOL};
    // Exact distance to the torus; for the ellipsoid an upper bound on it: the distance to the
    // radial projection p/|p/r| onto the surface
    let s = solids(DIFFUSE, "opaque");
    for sh in &s.file.shapes {
        let (size, dist): (f64, Box<dyn Fn(DVec3) -> f64>) = match sh {
            Shape::Ellipsoid { center, radii, .. } => {
                let (c, r) = (DVec3::from_array(*center), DVec3::from_array(*radii));
                (
                    r.max_element(),
                    Box::new(move |p: DVec3| {
                        let q = p - c;
                        let k = (q / r).length();
                        (q - q / k).length()
                    }),
                )
            }
            Shape::Torus {
                center,
                major,
                minor,
                ..
            } => {
                let (c, big, small) = (DVec3::from_array(*center), *major, *minor);
                (
                    big + small,
                    Box::new(move |p: DVec3| {
                        let q = p - c;
                        ((q.x.hypot(q.z) - big).hypot(q.y) - small).abs()
                    }),
                )
            }
            _ => {
                assert!(tessellate(sh).is_none());
                continue;
            }
        };
        let m = tessellate(sh).expect("a tessellation");
        // Worst deviation over each face's edge midpoints and centroid
        let mut worst = 0f64;
        for f in &m.faces {
            let v = f.map(|i| DVec3::from_array(m.positions[i as usize]));
            for p in [
                (v[0] + v[1]) * 0.5,
                (v[1] + v[2]) * 0.5,
                (v[2] + v[0]) * 0.5,
                (v[0] + v[1] + v[2]) / 3.0,
            ] {
                worst = worst.max(dist(p));
            }
        }
        let rel = worst / size;
        println!(
            "{}: {} vertices, {} faces, worst deviation {worst:.3e} = {rel:.3e} of its size (tolerance {TESS_TOL:e})",
            match sh {
                Shape::Torus { .. } => "torus",
                _ => "ellipsoid",
            },
            m.positions.len(),
            m.faces.len()
        );
        assert!(rel <= TESS_TOL, "deviation {rel:e} of the size");
        assert!(rel > 0.05 * TESS_TOL, "suspiciously exact: {rel:e}");
    }
}
