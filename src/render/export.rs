//! Scene exporters for the reference renderers, following the measured recipe under which
//! POV-Ray 3.7, Mitsuba 3 and rayproof render the same image (`../shared/notes/reference-matching.md`):
//!
//! - **POV-Ray** is left-handed, so every z is negated (geometry, lights, camera). The camera is
//!   given by explicit `direction`/`right`/`up` vectors so pixel centres map exactly as ours.
//!   Point lights use the fade trick: colour I/(2π·fd²), `fade_distance fd`, `fade_power 2`
//!   gives 2/(1+(d/fd)²)·I/(2π·fd²) ≈ I/(π·d²); the 1/π is Lambert's, because POV-Ray's diffuse
//!   term has none. Glass uses `conserve_energy`; opaque glass shadows get a hidden caster.
//!   `max_trace_level` = our `max_depth`, `adc_bailout 0`. Sampling is done outside the file:
//!   render at n·W × n·H without anti-aliasing and box-average n×n blocks (`rayproof downsample`).
//!   Boxes, cylinders and tori are POV-Ray's own `box`, `cylinder` (closed) and `torus` (in its
//!   xz plane around +y, as ours); an ellipsoid is a unit `sphere` scaled to its semi-axes.
//! - **Mitsuba** is right-handed like rayproof, so nothing is mirrored. The sensor is
//!   `perspective` with `fov_axis = x`, a `stratified` sampler without jitter (n² samples at the
//!   cell centres), a `box` filter and a float32 `hdrfilm`. The integrator is `whitted`, which
//!   `scripts/mitsuba_whitted.py` registers (built from Mitsuba's own parts). A box is Mitsuba's
//!   exact `cube`, a closed cylinder its open `cylinder` plus two `disk` caps; ellipsoids and tori
//!   have no Mitsuba shape (its `sphere` refuses non-uniform scaling) and are written as PLY
//!   tessellations into [`mesh_dir`], at most [`TESS_TOL`] of their size off the exact surface.
//!
//! ```text
//! rayproof export --to povray|mitsuba SCENE [--width W] [--grid N] > scene.pov|scene.xml
//! rayproof downsample BIG.exr --factor N -o OUT.exr
//! ```
//!
//! # How the three renderers are made to agree
//!
//! Details of the recipe above, with what was measured:
//! - POV-Ray's pixel centres are ours: `tests/export.rs` checks the explicit camera vectors
//!   numerically.
//! - The fade trick gives I/(π(d² + fd²)), with the π of Lambert's law. The note's fd = 0.01 left
//!   an error of 1e-4 at d = 1 and 1 % at d = 0.1 (`tests/export.rs` found it). With fd = 1e-4 the
//!   error is at most 1e-8 beyond d = 1.
//! - With `glass_shadows = "opaque"` a hidden, slightly smaller black caster goes inside each
//!   glass sphere.
//! - The 8×8 grid is made exactly: POV-Ray renders at 8W×8H without anti-aliasing, and
//!   `rayproof downsample` averages the 8×8 blocks. Mitsuba's `far_clip` is set beyond the scene,
//!   because the default 1e4 made the `far` scene's spheres vanish.
//! - Mitsuba has no Whitted integrator, so `scripts/mitsuba_whitted.py` builds one from its parts:
//!   `scene.ray_intersect`, `emitter.sample_direction` + `scene.ray_test` + `bsdf.eval` at diffuse
//!   hits, and `bsdf.sample` restricted to one lobe for the mirror and for both glass branches.
//!   With `llvm_ad_rgb` it traces compacted wavefronts; with `scalar_rgb` it recurses per ray.
//!
//! The references made this way, and how rayproof's renders compare with them: [`crate::golden`].

use crate::render::scene::{Frame, GlassShadows, Material, Scene, Shape};
use std::f64::consts::PI;
use std::fmt::Write;

/// POV-Ray's fade distance for point lights; the residual relative error is (fd/d)², ≤ 1e-8
/// beyond d = 1 (0.01 left 1e-4 at d = 1 and 1 % at d = 0.1, measured with POV-Ray 3.7).
const FADE_DISTANCE: f64 = 1e-4;

/// Text safe inside an XML attribute.
fn xml(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Shortest round-trip decimal of each number, comma-separated.
fn v3(a: [f64; 3]) -> String {
    format!("{}, {}, {}", a[0], a[1], a[2])
}

/// POV-Ray vector of a rayproof point or direction (z mirrored).
fn pov(a: [f64; 3]) -> String {
    format!("<{}, {}, {}>", a[0], a[1], -a[2])
}

/// The scene as POV-Ray 3.7 source.
pub fn povray(s: &Scene, fr: Frame) -> String {
    let f = &s.file;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "// Exported by rayproof {} from {} (right-handed scene; z mirrored for POV-Ray).\n\
         // Render at {}x{} with -A and box-average {}x{} blocks to get {}x{} with a {}x{} grid.",
        env!("CARGO_PKG_VERSION"),
        s.path.display(),
        fr.width * fr.grid,
        fr.height * fr.grid,
        fr.grid,
        fr.grid,
        fr.width,
        fr.height,
        fr.grid,
        fr.grid
    );
    // Global settings: linear, the scene's ambient (0 unless render.ambient), Whitted depth, no
    // adaptive bailout
    let lit_ambient = f.render.ambient != [0.0; 3];
    let _ = writeln!(
        o,
        "#version 3.7;\nglobal_settings {{ assumed_gamma 1.0 ambient_light {} max_trace_level {} adc_bailout 0 }}\nbackground {{ rgb 0 }}",
        if lit_ambient {
            format!("rgb <{}>", v3(f.render.ambient))
        } else {
            "0".into()
        },
        f.render.max_depth
    );
    // Camera: explicit vectors; pixel (x, y) → direction + ((x+½)/W − ½)·right + (½ − (y+½)/H)·up
    let cam = &f.camera;
    let pos = glam::DVec3::from_array(cam.position);
    let fwd = (glam::DVec3::from_array(cam.look_at) - pos).normalize();
    let right = fwd.cross(glam::DVec3::from_array(cam.up)).normalize();
    let up = right.cross(fwd);
    let aspect = fr.width as f64 / fr.height as f64;
    let dir = fwd * (0.5 * aspect / (cam.fov.to_radians() * 0.5).tan());
    let _ = writeln!(
        o,
        "camera {{ perspective location {} direction {} right {} up {} }}",
        pov(cam.position),
        pov(dir.to_array()),
        pov((right * aspect).to_array()),
        pov(up.to_array())
    );
    // Lights: the fade trick turns POV-Ray's unattenuated light into I/(π d²)
    for l in &f.lights {
        let c = l
            .intensity
            .map(|i| i / (2.0 * PI * FADE_DISTANCE * FADE_DISTANCE));
        let _ = writeln!(
            o,
            "light_source {{ {} color rgb <{}> fade_distance {} fade_power 2 }}",
            pov(l.position),
            v3(c),
            FADE_DISTANCE
        );
    }
    // Directional lights: parallel, unattenuated; POV-Ray's diffuse has no 1/π, so E/π
    for l in &f.directional {
        let d = glam::DVec3::from_array(l.direction).normalize();
        let _ = writeln!(
            o,
            "light_source {{ {} color rgb <{}> parallel point_at <0, 0, 0> }}",
            pov((-d * 1e4).to_array()),
            v3(l.irradiance.map(|e| e / PI))
        );
    }
    // Shapes with their materials
    for (i, sh) in f.shapes.iter().enumerate() {
        let mat = &f.materials[sh.material()];
        let tex = match mat {
            Material::Diffuse { albedo } => format!(
                "pigment {{ rgb <{}> }} finish {{ ambient {} emission 0 diffuse 1 }}",
                v3(*albedo),
                lit_ambient as u8
            ),
            Material::Mirror { reflectance } => format!(
                "pigment {{ rgb 0 }} finish {{ ambient 0 emission 0 diffuse 0 reflection {{ rgb <{}> }} }}",
                v3(*reflectance)
            ),
            Material::Glass { ior } => format!(
                "pigment {{ rgbf <1, 1, 1, 1> }} finish {{ ambient 0 emission 0 diffuse 0 reflection {{ 0, 1 fresnel on }} conserve_energy }} interior {{ ior {ior} }}"
            ),
        };
        let Some(geo) = pov_object(s, i, sh, 0.0) else {
            continue;
        };
        let _ = writeln!(o, "{geo}\n  {tex}\n}}");
        // Opaque glass shadows: a hidden, slightly smaller black caster inside the glass
        if let (Material::Glass { .. }, GlassShadows::Opaque) = (mat, f.render.glass_shadows) {
            match pov_object(s, i, sh, CASTER_SHRINK) {
                Some(inner) if sh.is_solid() => {
                    let _ = writeln!(
                        o,
                        "{inner} no_image no_reflection pigment {{ rgb 0 }} finish {{ ambient 0 diffuse 0 }} }}"
                    );
                }
                _ => {
                    let _ = writeln!(
                        o,
                        "// warning: shape {i} is glass but has no hidden caster; POV-Ray lets its shadow rays through"
                    );
                }
            }
        }
    }
    o
}

/// Relative size by which a hidden shadow caster is smaller than its glass shape.
const CASTER_SHRINK: f64 = 1e-5;

/// The opening of a shape's POV-Ray object (the caller adds the texture and the closing brace),
/// shrunk by the relative amount `shrink` about its centre (0 = as is; discs, planes and meshes
/// are never shrunk). `None` for a mesh that was not loaded.
fn pov_object(s: &Scene, i: usize, sh: &Shape, shrink: f64) -> Option<String> {
    let k = 1.0 - shrink;
    let dv = glam::DVec3::from_array;
    Some(match sh {
        Shape::Sphere { center, radius, .. } => {
            format!("sphere {{ {}, {}", pov(*center), radius * k)
        }
        Shape::Disc {
            center,
            normal,
            radius,
            ..
        } => format!("disc {{ {}, {}, {radius}", pov(*center), pov(*normal)),
        Shape::Plane { point, normal, .. } => {
            let n = dv(*normal).normalize();
            let d = n.dot(dv(*point));
            format!("plane {{ {}, {d}", pov(n.to_array()))
        }
        // An MPU surface exports as its source mesh (an approximation of the fit: compared,
        // not matched)
        Shape::Mesh { .. } | Shape::Mpu { .. } => {
            let mut m = String::from("mesh {");
            for t in s.meshes.get(&i)? {
                let _ = write!(
                    m,
                    "\n  triangle {{ {}, {}, {} }}",
                    pov(t[0]),
                    pov(t[1]),
                    pov(t[2])
                );
            }
            m
        }
        // Corners: z mirroring swaps which corner has the smaller z
        Shape::Box { min, max, .. } => {
            let (lo, hi) = (dv(*min), dv(*max));
            let inset = (hi - lo) * (shrink * 0.5);
            format!(
                "box {{ {}, {}",
                pov((lo + inset).to_array()),
                pov((hi - inset).to_array())
            )
        }
        // POV-Ray's cylinder is closed (caps included) unless `open` is given
        Shape::Cylinder {
            base,
            radius,
            height,
            ..
        } => {
            let b = dv(*base) + glam::DVec3::Y * (height * shrink * 0.5);
            let top = b + glam::DVec3::Y * (height * k);
            format!(
                "cylinder {{ {}, {}, {}",
                pov(b.to_array()),
                pov(top.to_array()),
                radius * k
            )
        }
        // The unit sphere scaled to the semi-axes (signs are not mirrored: radii are lengths)
        Shape::Ellipsoid { center, radii, .. } => format!(
            "sphere {{ <0, 0, 0>, 1 scale <{}> translate {}",
            v3(radii.map(|r| r * k)),
            pov(*center)
        ),
        // POV-Ray's torus lies in its xz plane around +y, as ours (mirroring z keeps it)
        Shape::Torus {
            center,
            major,
            minor,
            ..
        } => format!("torus {{ {major}, {} translate {}", minor * k, pov(*center)),
        // A hard union of SDF parts is a CSG union (a smooth blend has no POV-Ray equivalent:
        // see `unsupported`)
        Shape::Sdf { parts, .. } => {
            use crate::implicit::field::SdfPart;
            let mut u = String::from("union {");
            for p in parts {
                let _ = match *p {
                    SdfPart::Sphere { center, radius } => {
                        write!(u, "\n  sphere {{ {}, {radius} }}", pov(center))
                    }
                    SdfPart::Torus {
                        center,
                        major,
                        minor,
                    } => write!(
                        u,
                        "\n  torus {{ {major}, {minor} translate {} }}",
                        pov(center)
                    ),
                    SdfPart::Box { min, max } => {
                        write!(u, "\n  box {{ {}, {} }}", pov(min), pov(max))
                    }
                };
            }
            u
        }
        // POV-Ray's blob has the same field: strength·(1 − r²/radius²)² against the threshold
        Shape::Blob {
            threshold,
            components,
            ..
        } => {
            let mut b = format!("blob {{ threshold {threshold}");
            for c in components {
                let _ = write!(
                    b,
                    "\n  sphere {{ {}, {}, {} }}",
                    pov(c.center),
                    c.radius,
                    c.strength
                );
            }
            b
        }
    })
}

/// Why the scene cannot be exported to `to` ("povray" or "mitsuba"), if it cannot.
pub fn unsupported(s: &Scene, to: &str) -> Option<String> {
    s.file
        .shapes
        .iter()
        .enumerate()
        .find_map(|(i, sh)| match (sh, to) {
            (Shape::Sdf { blend, .. }, "povray") if *blend > 0.0 => Some(format!(
                "shapes[{i}]: a smooth SDF union (blend {blend}) has no POV-Ray equivalent"
            )),
            (Shape::Mpu { mesh: None, .. }, "povray") => Some(format!(
            "shapes[{i}]: an MPU surface exports to POV-Ray only as its source mesh; give `mesh`"
        )),
            (sh, "mitsuba") if sh.is_implicit() => Some(format!(
                "shapes[{i}]: implicit surfaces have no Mitsuba 3 equivalent (export to POV-Ray)"
            )),
            _ => None,
        })
        .or_else(|| {
            let f = &s.file;
            (to == "mitsuba" && (!f.directional.is_empty() || f.render.ambient != [0.0; 3]))
                .then(|| "directional lights and render.ambient are not exported to Mitsuba 3 (its Whitted script has point lights only)".to_string())
        })
}

/// A far clipping distance beyond every shape and light: twice the farthest extent, rounded up
/// to a power of ten (planes count as 1e6, the size of their stand-in rectangle).
fn far_clip(s: &Scene) -> f64 {
    let cam = glam::DVec3::from_array(s.file.camera.position);
    let d = |p: [f64; 3], r: f64| (glam::DVec3::from_array(p) - cam).length() + r;
    let mut far = s
        .file
        .lights
        .iter()
        .map(|l| d(l.position, 0.0))
        .fold(1e4, f64::max);
    for (i, sh) in s.file.shapes.iter().enumerate() {
        far = far.max(match sh {
            Shape::Sphere { center, radius, .. } => d(*center, *radius),
            Shape::Disc { center, radius, .. } => d(*center, *radius),
            Shape::Plane { point, .. } => d(*point, 1e6),
            Shape::Mesh { .. } => s.meshes[&i]
                .iter()
                .flatten()
                .map(|p| d(*p, 0.0))
                .fold(0.0, f64::max),
            Shape::Box { min, max, .. } => {
                let (lo, hi) = (glam::DVec3::from_array(*min), glam::DVec3::from_array(*max));
                d(((lo + hi) * 0.5).to_array(), (hi - lo).length() * 0.5)
            }
            Shape::Cylinder {
                base,
                radius,
                height,
                ..
            } => d(*base, radius + height),
            Shape::Ellipsoid { center, radii, .. } => {
                d(*center, radii[0].max(radii[1]).max(radii[2]))
            }
            Shape::Torus {
                center,
                major,
                minor,
                ..
            } => d(*center, major + minor),
            Shape::Sdf { .. } | Shape::Blob { .. } | Shape::Mpu { .. } => {
                let (lo, hi) = s.implicits[&i].bounds();
                d(((lo + hi) * 0.5).to_array(), (hi - lo).length() * 0.5)
            }
        });
    }
    10f64.powf((2.0 * far).log10().ceil())
}

/// The scene as Mitsuba 3 XML (integrator `whitted` from `scripts/mitsuba_whitted.py`).
pub fn mitsuba(s: &Scene, fr: Frame) -> String {
    let f = &s.file;
    let mut o = String::new();
    // Header and integrator
    mitsuba_integrator(&mut o, s);
    // Sensor: horizontal fov, n×n cell centres (stratified, no jitter), box filter, float32;
    // far_clip (default 1e4) beyond everything in the scene
    mitsuba_sensor(&mut o, s, fr);
    // Point lights
    for l in &f.lights {
        let _ = writeln!(
            o,
            "  <emitter type=\"point\">\n    <point name=\"position\" value=\"{}\"/>\n    <rgb name=\"intensity\" value=\"{}\"/>\n  </emitter>",
            v3(l.position),
            v3(l.intensity)
        );
    }
    // Materials
    for (name, m) in &f.materials {
        let _ = writeln!(o, "  {}", mitsuba_bsdf(name, m));
    }
    // Shapes
    let dir = s.path.parent().unwrap_or(std::path::Path::new("."));
    for sh in &f.shapes {
        if let Some(body) = mitsuba_shape(sh, dir) {
            let _ = writeln!(o, "  {body}");
        }
    }
    o.push_str("</scene>\n");
    o
}

/// The XML header, the opening `<scene>` and the `whitted` integrator.
fn mitsuba_integrator(o: &mut String, s: &Scene) {
    let f = &s.file;
    let shadows = match f.render.glass_shadows {
        GlassShadows::Opaque => "opaque",
        GlassShadows::Transmissive => "transmissive",
    };
    let _ = writeln!(
        o,
        "<!-- Exported by rayproof {} from {}; needs the 'whitted' integrator of scripts/mitsuba_whitted.py -->\n\
         <scene version=\"3.0.0\">\n  <integrator type=\"whitted\">\n    <integer name=\"max_depth\" value=\"{}\"/>\n    <string name=\"glass_shadows\" value=\"{shadows}\"/>\n  </integrator>",
        env!("CARGO_PKG_VERSION"),
        s.path.display(),
        f.render.max_depth
    );
}

/// The perspective sensor with its sampler and film.
fn mitsuba_sensor(o: &mut String, s: &Scene, fr: Frame) {
    let cam = &s.file.camera;
    let _ = writeln!(
        o,
        "  <sensor type=\"perspective\">\n    <string name=\"fov_axis\" value=\"x\"/>\n    <float name=\"fov\" value=\"{}\"/>\n    <float name=\"far_clip\" value=\"{:e}\"/>\n    <transform name=\"to_world\">\n      <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n    </transform>\n    <sampler type=\"stratified\">\n      <integer name=\"sample_count\" value=\"{}\"/>\n      <boolean name=\"jitter\" value=\"false\"/>\n    </sampler>\n    <film type=\"hdrfilm\">\n      <integer name=\"width\" value=\"{}\"/>\n      <integer name=\"height\" value=\"{}\"/>\n      <string name=\"pixel_format\" value=\"rgb\"/>\n      <string name=\"component_format\" value=\"float32\"/>\n      <rfilter type=\"box\"/>\n    </film>\n  </sensor>",
        cam.fov,
        far_clip(s),
        v3(cam.position),
        v3(cam.look_at),
        v3(cam.up),
        fr.grid * fr.grid,
        fr.width,
        fr.height
    );
}

/// A material's `<bsdf>` with the material's name as its id; diffuse is two-sided (rayproof
/// shades the side the ray sees).
fn mitsuba_bsdf(name: &str, m: &Material) -> String {
    let name = xml(name);
    match m {
        Material::Diffuse { albedo } => format!(
            "<bsdf type=\"twosided\" id=\"{name}\">\n    <bsdf type=\"diffuse\">\n      <rgb name=\"reflectance\" value=\"{}\"/>\n    </bsdf>\n  </bsdf>",
            v3(*albedo)
        ),
        Material::Mirror { reflectance } => format!(
            "<bsdf type=\"conductor\" id=\"{name}\">\n    <string name=\"material\" value=\"none\"/>\n    <rgb name=\"specular_reflectance\" value=\"{}\"/>\n  </bsdf>",
            v3(*reflectance)
        ),
        Material::Glass { ior } => format!(
            "<bsdf type=\"dielectric\" id=\"{name}\">\n    <float name=\"int_ior\" value=\"{ior}\"/>\n    <float name=\"ext_ior\" value=\"1.0\"/>\n  </bsdf>"
        ),
    }
}

/// A shape's XML (mesh files relative to `dir`); `None` if a tessellated shape has no mesh.
fn mitsuba_shape(sh: &Shape, dir: &std::path::Path) -> Option<String> {
    let r = format!("<ref id=\"{}\"/>", xml(sh.material()));
    Some(match sh {
        Shape::Sphere { center, radius, .. } => format!(
            "<shape type=\"sphere\">\n    <point name=\"center\" value=\"{}\"/>\n    <float name=\"radius\" value=\"{radius}\"/>\n    {r}\n  </shape>",
            v3(*center)
        ),
        Shape::Disc {
            center,
            normal,
            radius,
            ..
        } => {
            // The unit disk in z = 0, scaled, then turned so +z becomes the normal
            let c = glam::DVec3::from_array(*center);
            let n = glam::DVec3::from_array(*normal).normalize();
            format!(
                "<shape type=\"disk\">\n    <transform name=\"to_world\">\n      <scale value=\"{radius}\"/>\n      <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n    </transform>\n    {r}\n  </shape>",
                v3(*center),
                v3((c + n).to_array()),
                v3(n.any_orthonormal_vector().to_array())
            )
        }
        Shape::Plane { point, normal, .. } => {
            // Mitsuba has no infinite plane: a rectangle 1e6 wide stands in for it
            let c = glam::DVec3::from_array(*point);
            let n = glam::DVec3::from_array(*normal).normalize();
            format!(
                "<shape type=\"rectangle\">\n    <transform name=\"to_world\">\n      <scale value=\"1e6\"/>\n      <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n    </transform>\n    {r}\n  </shape>",
                v3(*point),
                v3((c + n).to_array()),
                v3(n.any_orthonormal_vector().to_array())
            )
        }
        Shape::Mesh { file, .. } => {
            let p = dir.join(file);
            let p = p.canonicalize().unwrap_or(p);
            format!(
                "<shape type=\"obj\">\n    <string name=\"filename\" value=\"{}\"/>\n    <boolean name=\"face_normals\" value=\"true\"/>\n    {r}\n  </shape>",
                xml(&p.display().to_string())
            )
        }
        // Mitsuba's cube is the exact [-1, 1]³ (12 triangles, face normals)
        Shape::Box { min, max, .. } => {
            let (lo, hi) = (glam::DVec3::from_array(*min), glam::DVec3::from_array(*max));
            format!(
                "<shape type=\"cube\">\n    <transform name=\"to_world\">\n      <scale value=\"{}\"/>\n      <translate value=\"{}\"/>\n    </transform>\n    {r}\n  </shape>",
                v3(((hi - lo) * 0.5).to_array()),
                v3(((lo + hi) * 0.5).to_array())
            )
        }
        Shape::Cylinder {
            base,
            radius,
            height,
            ..
        } => mitsuba_cylinder(*base, *radius, *height, &r),
        // Implicit surfaces: refused by `unsupported` before export
        Shape::Sdf { .. } | Shape::Blob { .. } | Shape::Mpu { .. } => {
            format!("<!-- {}: implicit, no Mitsuba equivalent -->", sh.material())
        }
        Shape::Ellipsoid { .. } | Shape::Torus { .. } => mitsuba_tessellated(sh, &r)?,
    })
}

/// A closed cylinder: Mitsuba's cylinder is open, so the caps are two disks, normals outward
/// (±y); `r` is the material reference.
fn mitsuba_cylinder(base: [f64; 3], radius: f64, height: f64, r: &str) -> String {
    let b = glam::DVec3::from_array(base);
    let top = b + glam::DVec3::Y * height;
    let disk = |c: glam::DVec3, n: glam::DVec3| {
        format!(
            "<shape type=\"disk\">\n    <transform name=\"to_world\">\n      <scale value=\"{radius}\"/>\n      <lookat origin=\"{}\" target=\"{}\" up=\"1, 0, 0\"/>\n    </transform>\n    {r}\n  </shape>",
            v3(c.to_array()),
            v3((c + n).to_array())
        )
    };
    format!(
        "<shape type=\"cylinder\">\n    <point name=\"p0\" value=\"{}\"/>\n    <point name=\"p1\" value=\"{}\"/>\n    <float name=\"radius\" value=\"{radius}\"/>\n    {r}\n  </shape>\n  {}\n  {}",
        v3(base),
        v3(top.to_array()),
        disk(b, -glam::DVec3::Y),
        disk(top, glam::DVec3::Y)
    )
}

/// An ellipsoid or a torus, which Mitsuba has no analytic shape for: a fine tessellation
/// written as a PLY file into [`mesh_dir`] (`None` for other shapes); `r` is the material
/// reference.
fn mitsuba_tessellated(sh: &Shape, r: &str) -> Option<String> {
    let (path, note) = match tessellate(sh).map(|m| m.write_ply(&mesh_dir())) {
        Some(Ok(p)) => (p, String::new()),
        Some(Err((p, e))) => (
            p,
            format!("<!-- error: cannot write the mesh: {} -->\n  ", xml(&e)),
        ),
        None => return None,
    };
    Some(format!(
        "{note}<shape type=\"ply\">\n    <string name=\"filename\" value=\"{}\"/>\n    {r}\n  </shape>",
        xml(&path.display().to_string())
    ))
}

/// Tessellations for Mitsuba are made so that every vertex lies on the exact surface and no
/// point of a triangle is farther than `TESS_TOL` × the shape's size (largest radius) from it:
/// along each parameter the chord sagitta ρ(1 − cos(Δ/2)) of the largest curvature radius ρ
/// per angular step Δ is held to half of it, and a diagonal edge sags by at most the sum.
pub const TESS_TOL: f64 = 2e-5;

/// An indexed triangle mesh with per-vertex unit normals (outward, counter-clockwise faces).
#[derive(Clone, Debug, Default)]
pub struct Tessellation {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Per-vertex unit normals, one per position.
    pub normals: Vec<[f64; 3]>,
    /// Triangles as indices into `positions`, counter-clockwise seen from outside.
    pub faces: Vec<[u32; 3]>,
}

/// Angular steps over `span` radians for a curve of curvature radius ≤ `rho` such that the
/// chord sagitta stays below `tol`: a multiple of 4, at least 8.
fn steps(span: f64, rho: f64, tol: f64) -> u32 {
    let max_step = 2.0 * (1.0 - (tol / rho).min(1.0)).acos();
    let n = (span / max_step).ceil().max(8.0) as u32;
    n.div_ceil(4) * 4
}

/// The tessellation of an ellipsoid or torus at [`TESS_TOL`] (world space); `None` for other
/// shapes.
pub fn tessellate(sh: &Shape) -> Option<Tessellation> {
    match sh {
        Shape::Ellipsoid { center, radii, .. } => {
            let a = radii[0].max(radii[1]).max(radii[2]);
            let tol = 0.5 * TESS_TOL * a;
            Some(ellipsoid_mesh(
                *center,
                *radii,
                steps(2.0 * PI, a, tol),
                steps(PI, a, tol),
            ))
        }
        Shape::Torus {
            center,
            major,
            minor,
            ..
        } => {
            let tol = 0.5 * TESS_TOL * (major + minor);
            Some(torus_mesh(
                *center,
                *major,
                *minor,
                steps(2.0 * PI, major + minor, tol),
                steps(2.0 * PI, *minor, tol),
            ))
        }
        _ => None,
    }
}

/// A UV ellipsoid: `nu` steps around +y, `nv` from pole to pole (poles as single vertices).
pub fn ellipsoid_mesh(c: [f64; 3], radii: [f64; 3], nu: u32, nv: u32) -> Tessellation {
    let mut m = Tessellation::default();
    let mut vertex = |u: [f64; 3]| {
        // Point on the unit sphere → ellipsoid; the normal is the gradient u/r, normalised
        let p = glam::DVec3::from_array(u) * glam::DVec3::from_array(radii);
        let n = (glam::DVec3::from_array(u) / glam::DVec3::from_array(radii)).normalize();
        m.positions
            .push((p + glam::DVec3::from_array(c)).to_array());
        m.normals.push(n.to_array());
    };
    vertex([0.0, 1.0, 0.0]);
    for j in 1..nv {
        let th = PI * j as f64 / nv as f64;
        for i in 0..nu {
            let ph = 2.0 * PI * i as f64 / nu as f64;
            vertex([th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()]);
        }
    }
    vertex([0.0, -1.0, 0.0]);
    let ring = |j: u32, i: u32| 1 + (j - 1) * nu + i % nu;
    let bottom = 1 + (nv - 1) * nu;
    for i in 0..nu {
        m.faces.push([0, ring(1, i + 1), ring(1, i)]);
        for j in 1..nv - 1 {
            let (a, b, c, d) = (
                ring(j, i),
                ring(j, i + 1),
                ring(j + 1, i + 1),
                ring(j + 1, i),
            );
            m.faces.push([a, b, c]);
            m.faces.push([a, c, d]);
        }
        m.faces.push([ring(nv - 1, i), ring(nv - 1, i + 1), bottom]);
    }
    m
}

/// A torus in the xz plane around +y: `nu` steps around the major circle, `nv` around the minor.
pub fn torus_mesh(c: [f64; 3], major: f64, minor: f64, nu: u32, nv: u32) -> Tessellation {
    let mut m = Tessellation::default();
    for i in 0..nu {
        let (sp, cp) = (2.0 * PI * i as f64 / nu as f64).sin_cos();
        for j in 0..nv {
            let (st, ct) = (2.0 * PI * j as f64 / nv as f64).sin_cos();
            let rho = major + minor * ct;
            m.positions
                .push([c[0] + rho * cp, c[1] + minor * st, c[2] + rho * sp]);
            m.normals.push([ct * cp, st, ct * sp]);
        }
    }
    let at = |i: u32, j: u32| (i % nu) * nv + j % nv;
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            m.faces.push([a, d, c]);
            m.faces.push([a, c, b]);
        }
    }
    m
}

/// Where the Mitsuba exporter writes its PLY files: `$RAYPROOF_MESH_DIR`, or
/// `<temp>/rayproof-meshes`. Files are named by the SHA-256 of their bytes, so a file that is
/// there already is the same mesh.
pub fn mesh_dir() -> std::path::PathBuf {
    std::env::var_os("RAYPROOF_MESH_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("rayproof-meshes"))
}

impl Tessellation {
    /// Binary little-endian PLY with float32 positions and normals.
    pub fn ply(&self) -> Vec<u8> {
        let mut b = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            self.positions.len(),
            self.faces.len()
        )
        .into_bytes();
        for (p, n) in self.positions.iter().zip(&self.normals) {
            for x in p.iter().chain(n) {
                b.extend((*x as f32).to_le_bytes());
            }
        }
        for f in &self.faces {
            b.push(3);
            for i in f {
                b.extend((*i as i32).to_le_bytes());
            }
        }
        b
    }

    /// Writes the PLY into `dir` (atomically, named by its hash); the path, or it with the error.
    pub fn write_ply(
        &self,
        dir: &std::path::Path,
    ) -> Result<std::path::PathBuf, (std::path::PathBuf, String)> {
        use sha2::{Digest, Sha256};
        let bytes = self.ply();
        let hash: String = Sha256::digest(&bytes)[..12]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        let path = dir.join(format!("mesh-{hash}.ply"));
        if std::fs::metadata(&path).is_ok_and(|m| m.len() == bytes.len() as u64) {
            return Ok(path);
        }
        std::fs::create_dir_all(dir)
            .map_err(anyhow::Error::from)
            .and_then(|_| crate::output::write_atomic(&path, &bytes))
            .map_err(|e| (path.clone(), format!("{e:#}")))?;
        Ok(path)
    }
}

/// Averages n×n blocks of an image's R, G, B (in f64); the size must divide by n.
pub fn downsample(img: &crate::images::Image, n: usize) -> anyhow::Result<crate::images::Image> {
    let (w, h, nch) = (img.width, img.height, img.channels.len());
    anyhow::ensure!(
        w % n == 0 && h % n == 0,
        "{w}×{h} is not divisible into {n}×{n} blocks"
    );
    let rgb = ["R", "G", "B"].map(|c| img.channels.iter().position(|k| k == c));
    let [Some(r), Some(g), Some(b)] = rgb else {
        anyhow::bail!("the image has no R, G, B channels");
    };
    let (ow, oh) = (w / n, h / n);
    let mut out = Vec::with_capacity(ow * oh * 3);
    for i in 0..ow * oh {
        let (bx, by) = (i % ow * n, i / ow * n);
        let mut sum = [0f64; 3];
        for y in by..by + n {
            for x in bx..bx + n {
                let p = &img.data[(y * w + x) * nch..];
                for (k, c) in [r, g, b].into_iter().enumerate() {
                    sum[k] += p[c] as f64;
                }
            }
        }
        out.extend(sum.map(|s| (s / (n * n) as f64) as f32));
    }
    Ok(crate::images::Image::rgb(ow, oh, out))
}
