//! Scene files (TOML). Right-handed, +y up, as in Mitsuba; the POV-Ray exporter mirrors z.
//!
//! ```toml
//! [camera]
//! position = [0.0, 1.5, 6.0]
//! look_at = [0.0, 0.7, 0.0]
//! up = [0.0, 1.0, 0.0]
//! fov = 40.0            # horizontal field of view, degrees
//! width = 320
//! height = 240
//! grid = 1              # n×n sub-pixel samples at cell centres, box filter
//!
//! [render]
//! max_depth = 10        # ray segments (POV-Ray's max_trace_level): primary + 9 bounces
//! glass_shadows = "opaque"   # or "transmissive" (POV-Ray: shadow rays pass through glass)
//! method = "rtg7"       # any ray–sphere method of the audit
//! precision = "f64"     # f32 or f64
//! offset = "auto"       # secondary-ray origin offset: "auto", "none", or a number
//!
//! [[lights]]
//! position = [3.0, 6.0, 4.0]
//! intensity = [40.0, 40.0, 40.0]   # W/sr; radiance falls off as 1/r²
//!
//! [materials.red]
//! type = "diffuse"      # Lambert, albedo/π
//! albedo = [0.8, 0.2, 0.2]
//! [materials.chrome]
//! type = "mirror"
//! reflectance = [0.9, 0.9, 0.9]
//! [materials.glass]
//! type = "glass"        # exact unpolarised Fresnel, total internal reflection
//! ior = 1.5
//!
//! [[shapes]]
//! type = "sphere"       # also: disc {center, normal, radius}, plane {point, normal},
//! center = [0.0, 1.0, 0.0]   #       mesh {file (OBJ, relative to the scene file)},
//! radius = 1.0               #       box {min, max} (axis-aligned),
//! material = "red"           #       cylinder {base, radius, height} (closed, along +y),
//!                            #       ellipsoid {center, radii} (semi-axes along x, y, z),
//!                            #       torus {center, major, minor} (in the xz plane, around +y,
//!                            #       as POV-Ray's torus; 0 < minor < major)
//! ```

use crate::implicit::field::{BlobComponent, Field, SdfPart};

/// The largest image side, in pixels (a scene's camera, `--width`, or a size an aspect makes).
pub const MAX_SIDE: u32 = 16_384;
/// The most pixels of one image (8192 × 8192), rendered or read.
pub use crate::images::MAX_PIXELS;
/// The largest n of the n×n sub-pixel grid.
pub const MAX_GRID: u32 = 64;
/// The range of a glass's index of refraction (real materials lie within 1–4; beyond 1e154
/// the refraction's η² overflows and pixels turn NaN, found by tests/fuzz.rs).
pub const MIN_IOR: f64 = 0.01;
/// The largest index of refraction a glass may have.
pub const MAX_IOR: f64 = 100.0;
/// The most ray segments per path (`render.max_depth`; POV-Ray's `max_trace_level` stops at 256).
pub const MAX_DEPTH: u32 = 256;
pub use crate::input::MAX_MAGNITUDE;
/// The largest light intensity (W/sr), directional irradiance and ambient radiance, per channel:
/// 1e30 (the Sun's intensity is about 3e25 W/sr). A diffuse pixel's radiance is then far below
/// f32's largest value (3.4e38) unless a point light is closer than 5e-5 to the surface it lights
/// (a pixel above f32's range is stored as its largest value, see [`crate::render`]). At 1e300,
/// 132–143 of a 16×16 image's pixels were Inf.
pub const MAX_RADIANCE: f64 = 1e30;
/// The most triangles one OBJ file may give (2^22; the bunny has 3,851). Together with the file
/// size cap ([`crate::input::MAX_MESH_BYTES`]) it bounds a mesh's memory: a face line of n
/// repeated indices is n − 2 triangles of 72 bytes each.
pub const MAX_TRIANGLES: usize = 1 << 22;

/// Image size and sub-pixel grid of a render or an export (the references are made at a fixed
/// size).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// `n` of the n×n sub-pixel grid (cell centres, box filter).
    pub grid: u32,
}

impl Frame {
    /// The scene's own frame, or `width` wide with the scene's aspect ratio, and its n×n grid or
    /// `grid`, within the documented limits ([`check_frame`]): one line if not.
    pub fn of(s: &Scene, width: Option<u32>, grid: Option<u32>) -> Result<Frame, String> {
        let (w, h) = (
            *s.file.camera.width.get_ref(),
            *s.file.camera.height.get_ref(),
        );
        let width = width.unwrap_or(w);
        let height = (width as f64 * h as f64 / w as f64)
            .round()
            .clamp(1.0, u32::MAX as f64) as u32;
        let grid = grid.unwrap_or(*s.file.camera.grid.get_ref());
        check_frame(width, height, grid)?;
        Ok(Frame {
            width,
            height,
            grid,
        })
    }
}

/// Checks an image's size and sampling grid against the documented limits: one line naming
/// what is too large.
pub fn check_frame(width: u32, height: u32, grid: u32) -> Result<(), String> {
    if width == 0 || height == 0 || grid == 0 {
        return Err(format!(
            "an image of {width}×{height} with a {grid}×{grid} grid: every size must be at least 1"
        ));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(format!(
            "an image of {width}×{height} pixels: each side may be at most {MAX_SIDE}"
        ));
    }
    if width as u64 * height as u64 > MAX_PIXELS {
        return Err(format!(
            "an image of {width}×{height} = {} pixels: at most {MAX_PIXELS} (8192²)",
            width as u64 * height as u64
        ));
    }
    if grid > MAX_GRID {
        return Err(format!(
            "a {grid}×{grid} sub-pixel grid: n may be at most {MAX_GRID}"
        ));
    }
    Ok(())
}
use crate::implicit::mpu::{Mpu, MpuOptions};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use toml::Spanned;

/// A scene file as written: camera, render settings, lights, materials and shapes (TOML).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// The camera: `[camera]`.
    pub camera: Camera,
    /// `[render]`: depth, glass shadows, sphere method and precision, offset, ambient.
    #[serde(default)]
    pub render: RenderSettings,
    /// Point lights: `[[lights]]`.
    #[serde(default)]
    pub lights: Vec<Light>,
    /// Directional lights (seed 004's Table 1 lighting).
    #[serde(default)]
    pub directional: Vec<DirectionalLight>,
    /// Materials by name: `[materials.NAME]`.
    #[serde(default)]
    pub materials: BTreeMap<String, Material>,
    /// Shapes, each naming its material: `[[shapes]]`.
    #[serde(default)]
    pub shapes: Vec<Shape>,
}

/// A pinhole camera.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Eye position.
    pub position: [f64; 3],
    /// The point the camera looks at.
    pub look_at: [f64; 3],
    /// Up direction (default +y); it need not be perpendicular to the view direction.
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    /// Horizontal field of view in degrees.
    pub fov: f64,
    /// Image width in pixels (with its place in the file, for error messages).
    pub width: Spanned<u32>,
    /// Image height in pixels (with its place in the file, for error messages).
    pub height: Spanned<u32>,
    /// n×n stratified sub-pixel grid, sampled at cell centres, box filter.
    #[serde(default = "one")]
    pub grid: Spanned<u32>,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
fn one() -> Spanned<u32> {
    Spanned::new(0..0, 1)
}

/// Shadow rule for glass.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum GlassShadows {
    /// Glass blocks light like any surface (Mitsuba's visibility test, physical).
    #[default]
    Opaque,
    /// Shadow rays pass straight through glass, unrefracted (POV-Ray's rule for clear glass).
    Transmissive,
}

/// `[render]`: how the scene is rendered.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSettings {
    /// Ray segments, POV-Ray's `max_trace_level`: 1 = primary rays only.
    pub max_depth: u32,
    /// How shadow rays treat glass.
    pub glass_shadows: GlassShadows,
    /// Ray–sphere method name (default `rtg7`).
    pub method: Spanned<String>,
    /// Precision of the sphere tests, `"f32"` or `"f64"` (default `f64`).
    pub precision: Spanned<String>,
    /// Secondary-ray origin offset along the geometric normal: "auto", "none" or a distance.
    pub offset: toml::Value,
    /// Ambient radiance: a uniform, never occluded sky; a diffuse surface adds albedo × ambient
    /// (POV-Ray's `ambient_light` with `finish { ambient 1 }`).
    pub ambient: [f64; 3],
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            max_depth: 10,
            glass_shadows: GlassShadows::Opaque,
            method: Spanned::new(0..0, "rtg7".into()),
            precision: Spanned::new(0..0, "f64".into()),
            offset: toml::Value::String("auto".into()),
            ambient: [0.0; 3],
        }
    }
}

/// A point light.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Light {
    /// Position.
    pub position: [f64; 3],
    /// Radiant intensity, W/sr, per RGB channel.
    pub intensity: [f64; 3],
}

/// A light at infinity: irradiance `E` (W/m², per RGB channel) on a surface facing it, arriving
/// along `direction` (the way the light travels). A diffuse surface reflects albedo/π·E·cosθ.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectionalLight {
    /// Direction the light travels (need not be unit length).
    pub direction: [f64; 3],
    /// Irradiance on a surface facing the light, W/m², per RGB channel.
    pub irradiance: [f64; 3],
}

/// A surface material.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Material {
    /// Lambertian: reflects `albedo/π` per RGB channel, lit by the lights.
    Diffuse {
        /// Reflectance per RGB channel, 0–1.
        albedo: [f64; 3],
    },
    /// A perfect mirror.
    Mirror {
        /// Reflectance per RGB channel, 0–1.
        reflectance: [f64; 3],
    },
    /// Clear glass: Fresnel-weighted reflection and refraction.
    Glass {
        /// Index of refraction (within [`MIN_IOR`, `MAX_IOR`]).
        ior: f64,
    },
}

/// A shape of the scene; every kind names its material.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Shape {
    /// A sphere.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius (> 0).
        radius: f64,
        /// Material name.
        material: String,
    },
    /// A flat disc.
    Disc {
        /// Centre.
        center: [f64; 3],
        /// Normal (need not be unit length).
        normal: [f64; 3],
        /// Radius (> 0).
        radius: f64,
        /// Material name.
        material: String,
    },
    /// An infinite plane.
    Plane {
        /// A point on the plane.
        point: [f64; 3],
        /// Normal (need not be unit length).
        normal: [f64; 3],
        /// Material name.
        material: String,
    },
    /// A triangle mesh read from an OBJ file.
    Mesh {
        /// Path of the OBJ file, relative to the scene file.
        file: String,
        /// Material name.
        material: String,
    },
    /// Axis-aligned box, `min < max` on every axis.
    Box {
        /// Minimum corner.
        min: [f64; 3],
        /// Maximum corner.
        max: [f64; 3],
        /// Material name.
        material: String,
    },
    /// Closed cylinder: lateral surface from `base` up `height` along +y, and two cap discs.
    Cylinder {
        /// Centre of the bottom cap.
        base: [f64; 3],
        /// Radius (> 0).
        radius: f64,
        /// Height along +y (> 0).
        height: f64,
        /// Material name.
        material: String,
    },
    /// Ellipsoid with semi-axes `radii` along x, y, z.
    Ellipsoid {
        /// Centre.
        center: [f64; 3],
        /// Semi-axes along x, y, z (each > 0).
        radii: [f64; 3],
        /// Material name.
        material: String,
    },
    /// Ring torus in the xz plane around the +y axis through `center`.
    Torus {
        /// Centre.
        center: [f64; 3],
        /// Distance from the centre to the tube's centre line.
        major: f64,
        /// Tube radius (below `major`: a ring torus).
        minor: f64,
        /// Material name.
        material: String,
    },
    /// Implicit: signed-distance parts (`kind` sphere, torus, box) joined by a smooth union of
    /// blend width `blend` (0: a hard union). Sphere traced.
    Sdf {
        /// The signed-distance parts.
        parts: Vec<SdfPart>,
        /// Smooth-union blend width (0: a hard union).
        #[serde(default)]
        blend: f64,
        /// Material name.
        material: String,
    },
    /// Implicit: POV-Ray's blob, `Σ strength·(1 − r²/radius²)² = threshold`. Sphere traced.
    Blob {
        /// Field value of the surface.
        threshold: f64,
        /// The blob's components.
        components: Vec<BlobComponent>,
        /// Material name.
        material: String,
    },
    /// Implicit: an MPU surface fitted to `points` (lines `x y z nx ny nz`); `mesh` (OBJ) is
    /// the source mesh POV-Ray renders in its place. Sphere traced.
    Mpu {
        /// Path of the oriented point cloud, relative to the scene file.
        points: String,
        /// Path of the source mesh (OBJ) that POV-Ray renders in the MPU's place.
        #[serde(default)]
        mesh: Option<String>,
        /// Material name.
        material: String,
    },
}

impl Shape {
    /// The name of the shape's material.
    pub fn material(&self) -> &String {
        match self {
            Shape::Sphere { material, .. }
            | Shape::Disc { material, .. }
            | Shape::Plane { material, .. }
            | Shape::Mesh { material, .. }
            | Shape::Box { material, .. }
            | Shape::Cylinder { material, .. }
            | Shape::Ellipsoid { material, .. }
            | Shape::Torus { material, .. }
            | Shape::Sdf { material, .. }
            | Shape::Blob { material, .. }
            | Shape::Mpu { material, .. } => material,
        }
    }

    /// A closed solid with an inside (a hidden shadow caster fits in it).
    pub fn is_solid(&self) -> bool {
        matches!(
            self,
            Shape::Sphere { .. }
                | Shape::Box { .. }
                | Shape::Cylinder { .. }
                | Shape::Ellipsoid { .. }
                | Shape::Torus { .. }
        )
    }

    /// An implicit surface (sphere traced).
    pub fn is_implicit(&self) -> bool {
        matches!(
            self,
            Shape::Sdf { .. } | Shape::Blob { .. } | Shape::Mpu { .. }
        )
    }

    /// The first problem with the shape's values, as (field, message); `None` if it is valid.
    /// NaN and ±inf are rejected everywhere; sizes must be positive.
    pub fn problem(&self) -> Option<(&'static str, String)> {
        let finite3 = |name: &'static str, v: &[f64; 3]| {
            (!v.iter().all(|x| x.is_finite())).then(|| (name, format!("must be finite, got {v:?}")))
        };
        let positive = |name: &'static str, x: f64| {
            (!(x.is_finite() && x > 0.0))
                .then(|| (name, format!("must be a finite number > 0, got {x:?}")))
        };
        match self {
            Shape::Box { min, max, .. } => finite3("min", min)
                .or_else(|| finite3("max", max))
                .or_else(|| {
                    (0..3).find(|&k| min[k] >= max[k]).map(|k| {
                        (
                            "max",
                            format!(
                                "must exceed min on every axis, got min {min:?}, max {max:?} (axis {})",
                                ["x", "y", "z"][k]
                            ),
                        )
                    })
                }),
            Shape::Cylinder {
                base,
                radius,
                height,
                ..
            } => finite3("base", base)
                .or_else(|| positive("radius", *radius))
                .or_else(|| positive("height", *height)),
            Shape::Ellipsoid { center, radii, .. } => finite3("center", center)
                .or_else(|| radii.iter().find_map(|&r| positive("radii", r))),
            Shape::Torus {
                center,
                major,
                minor,
                ..
            } => finite3("center", center)
                .or_else(|| positive("major", *major))
                .or_else(|| positive("minor", *minor))
                .or_else(|| {
                    (minor >= major).then(|| {
                        (
                            "minor",
                            format!("must be below major ({major:?}) for a ring torus, got {minor:?}"),
                        )
                    })
                }),
            Shape::Sdf { parts, blend, .. } => (parts.is_empty())
                .then(|| ("parts", "needs at least one part".to_string()))
                .or_else(|| parts.iter().find_map(|p| p.problem().map(|m| ("parts", m))))
                .or_else(|| {
                    (!(blend.is_finite() && *blend >= 0.0))
                        .then(|| ("blend", format!("must be a finite number ≥ 0, got {blend:?}")))
                }),
            Shape::Blob {
                threshold,
                components,
                ..
            } => positive("threshold", *threshold)
                .or_else(|| {
                    components
                        .is_empty()
                        .then(|| ("components", "needs at least one component".to_string()))
                })
                .or_else(|| {
                    components.iter().find_map(|c| {
                        finite3("components", &c.center)
                            .or_else(|| positive("components", c.radius))
                            .or_else(|| {
                                (!(c.strength.is_finite() && c.strength != 0.0)).then(|| {
                                    ("components", format!("strength must be finite and non-zero, got {:?}", c.strength))
                                })
                            })
                    })
                })
                .or_else(|| {
                    (!components.iter().any(|c| c.strength > 0.0))
                        .then(|| ("components", "needs a component of positive strength".to_string()))
                }),
            Shape::Sphere { center, radius, .. } => {
                finite3("center", center).or_else(|| positive("radius", *radius))
            }
            Shape::Disc {
                center,
                normal,
                radius,
                ..
            } => finite3("center", center)
                .or_else(|| nonzero3("normal", normal))
                .or_else(|| positive("radius", *radius)),
            Shape::Plane { point, normal, .. } => {
                finite3("point", point).or_else(|| nonzero3("normal", normal))
            }
            Shape::Mesh { .. } | Shape::Mpu { .. } => None,
        }
    }
}

/// A finite vector that is not zero and that has a direction (its normalisation is finite: a
/// vector as short as 1e-200 is not zero, but its squared length underflows to 0).
fn nonzero3(name: &'static str, v: &[f64; 3]) -> Option<(&'static str, String)> {
    glam::DVec3::from_array(*v)
        .try_normalize()
        .is_none()
        .then(|| {
            (
                name,
                format!("must be finite, not zero and normalisable, got {v:?}"),
            )
        })
}

/// A colour: three finite numbers in `[0, max]` (1 for an albedo or a reflectance,
/// [`MAX_RADIANCE`] for a light or the ambient).
fn colour_problem(v: &[f64; 3], max: f64) -> Option<String> {
    let ok = |x: &f64| x.is_finite() && *x >= 0.0 && *x <= max;
    let top = if max == 1.0 {
        "1".to_string()
    } else {
        format!("{max:e}")
    };
    (!v.iter().all(ok)).then(|| format!("must be three finite numbers in [0, {top}], got {v:?}"))
}

/// The first number of a scene's text (already known to parse) whose magnitude is finite but
/// beyond [`MAX_MAGNITUDE`]: its dotted path (`shapes[2].center[0]`), its line and its value.
/// (NaN and ±inf are left to the field checks, which name them.)
fn too_large(text: &str) -> Option<(String, usize, f64)> {
    use toml::de::{DeTable, DeValue};
    fn walk(path: String, v: &toml::Spanned<DeValue>, text: &str) -> Option<(String, usize, f64)> {
        match v.get_ref() {
            DeValue::Float(f) => {
                let x: f64 = f.as_str().replace('_', "").parse().ok()?;
                (x.is_finite() && x.abs() > MAX_MAGNITUDE)
                    .then(|| (path, line_of(text, v.span().start), x))
            }
            DeValue::Array(a) => a
                .iter()
                .enumerate()
                .find_map(|(i, e)| walk(format!("{path}[{i}]"), e, text)),
            DeValue::Table(t) => t.iter().find_map(|(k, e)| {
                let key = if path.is_empty() {
                    k.get_ref().to_string()
                } else {
                    format!("{path}.{}", k.get_ref())
                };
                walk(key, e, text)
            }),
            // Integers are i64: far below the limit
            _ => None,
        }
    }
    let doc = DeTable::parse(text).ok()?;
    doc.get_ref()
        .iter()
        .find_map(|(k, e)| walk(k.get_ref().to_string(), e, text))
}

/// The field of an implicit scene shape (`None` for other shapes). MPU points are read
/// relative to the scene file and fitted here.
pub fn field_of(shape: &Shape, scene: &Path) -> Result<Option<Field>, String> {
    Ok(Some(match shape {
        Shape::Sdf { parts, blend, .. } => Field::Sdf {
            parts: parts.clone(),
            blend: *blend,
        },
        Shape::Blob {
            threshold,
            components,
            ..
        } => Field::blob(*threshold, components.clone()),
        Shape::Mpu { points, .. } => {
            let path = scene.parent().unwrap_or(Path::new(".")).join(points);
            let (p, n) = Mpu::load_points(&path).map_err(|e| format!("points: {e:#}"))?;
            if p.len() < 4 {
                return Err(format!(
                    "points: {} has {} point(s); an MPU fit needs at least 4",
                    path.display(),
                    p.len()
                ));
            }
            Field::Mpu(Arc::new(Mpu::fit(&p, &n, &MpuOptions::default())))
        }
        _ => return Ok(None),
    }))
}

/// The line of `field = …` inside the table whose header is on line `header` (1-based), or the
/// header's line if the field is not written there.
fn field_line(text: &str, header: usize, field: &str) -> usize {
    text.lines()
        .enumerate()
        .skip(header)
        .take_while(|(_, l)| !l.trim_start().starts_with('['))
        .find(|(_, l)| {
            l.trim_start()
                .strip_prefix(field)
                .is_some_and(|r| r.trim_start().starts_with('='))
        })
        .map_or(header, |(i, _)| i + 1)
}

/// A scene-file error: file, line and field, one line.
#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct SceneError {
    /// The scene file's path as given.
    pub file: String,
    /// Line of the offending field (1-based; 0 when the file could not be read).
    pub line: usize,
    /// What is wrong, in one line.
    pub message: String,
}

/// A parsed, checked scene with its meshes loaded.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The file as parsed.
    pub file: SceneFile,
    /// Triangles of each mesh shape, by shape index.
    pub meshes: BTreeMap<usize, Vec<[[f64; 3]; 3]>>,
    /// The field of each implicit shape, by shape index (MPU surfaces are fitted on load).
    pub implicits: BTreeMap<usize, Field>,
    /// Where the scene was read from (meshes and point clouds are relative to it).
    pub path: PathBuf,
}

impl Scene {
    /// Every file the scene was read from: the scene file, its meshes and point clouds (no
    /// output of a run may replace one).
    pub fn files(&self) -> Vec<PathBuf> {
        let dir = self.path.parent().unwrap_or(Path::new("."));
        let mut v = vec![self.path.clone()];
        for s in &self.file.shapes {
            match s {
                Shape::Mesh { file, .. } => v.push(dir.join(file)),
                Shape::Mpu { points, mesh, .. } => {
                    v.push(dir.join(points));
                    v.extend(mesh.iter().map(|m| dir.join(m)));
                }
                _ => {}
            }
        }
        v
    }
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// Reads, parses and checks a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let name = path.display().to_string();
    let err = |line: usize, message: String| SceneError {
        file: name.clone(),
        line,
        message,
    };
    let text = crate::input::read_text(
        path,
        crate::input::MAX_TEXT_BYTES,
        crate::input::Kind::Stream,
    )
    .map_err(|e| err(0, format!("cannot read: {e}")))?;
    parse(&text, path)
}

/// Parses and checks scene text (`path` names it in errors and anchors mesh files).
pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
    let name = path.display().to_string();
    let err = |line: usize, message: String| SceneError {
        file: name.clone(),
        line,
        message,
    };
    let file: SceneFile = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start)).unwrap_or(0);
        err(line, e.message().trim().replace('\n', " "))
    })?;
    // Field checks
    let at = |s: &std::ops::Range<usize>| {
        if s.end == 0 {
            0
        } else {
            line_of(text, s.start)
        }
    };
    let cam = &file.camera;
    for (field, v) in [
        ("camera.width", &cam.width),
        ("camera.height", &cam.height),
        ("camera.grid", &cam.grid),
    ] {
        if *v.get_ref() == 0 {
            return Err(err(at(&v.span()), format!("{field} must be at least 1")));
        }
    }
    if let Err(e) = check_frame(
        *cam.width.get_ref(),
        *cam.height.get_ref(),
        *cam.grid.get_ref(),
    ) {
        return Err(err(at(&cam.width.span()), format!("camera: {e}")));
    }
    let finite = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    for (field, v) in [
        ("position", &cam.position),
        ("look_at", &cam.look_at),
        ("up", &cam.up),
    ] {
        if !finite(v) {
            return Err(err(
                field_line(text, 0, field),
                format!("camera.{field} must be finite, got {v:?}"),
            ));
        }
    }
    let view: Vec<f64> = (0..3).map(|k| cam.look_at[k] - cam.position[k]).collect();
    if view.iter().all(|x| *x == 0.0) {
        return Err(err(
            field_line(text, 0, "look_at"),
            "camera.look_at must differ from camera.position".into(),
        ));
    }
    let up = cam.up;
    let cross = [
        view[1] * up[2] - view[2] * up[1],
        view[2] * up[0] - view[0] * up[2],
        view[0] * up[1] - view[1] * up[0],
    ];
    if cross.iter().all(|x| *x == 0.0) {
        return Err(err(
            field_line(text, 0, "up"),
            format!("camera.up must be non-zero and not along the view direction, got {up:?}"),
        ));
    }
    if !(cam.fov > 0.0 && cam.fov < 180.0) {
        return Err(err(
            0,
            format!("camera.fov must be in (0, 180) degrees, got {:?}", cam.fov),
        ));
    }
    let m = &file.render.method;
    if crate::shapes::sphere::methods::method_by_name(m.get_ref()).is_none() {
        return Err(err(
            at(&m.span()),
            format!("render.method: unknown method '{}'", m.get_ref()),
        ));
    }
    let p = &file.render.precision;
    if !matches!(p.get_ref().as_str(), "f32" | "f64") {
        return Err(err(
            at(&p.span()),
            format!("render.precision: '{}' is not f32 or f64", p.get_ref()),
        ));
    }
    if !(1..=MAX_DEPTH).contains(&file.render.max_depth) {
        return Err(err(
            field_line(text, 0, "max_depth"),
            format!(
                "render.max_depth must be in 1..={MAX_DEPTH}, got {}",
                file.render.max_depth
            ),
        ));
    }
    // Lights and materials
    for (i, l) in file.lights.iter().enumerate() {
        if !finite(&l.position) {
            return Err(err(
                0,
                format!("lights[{i}].position must be finite, got {:?}", l.position),
            ));
        }
        if let Some(m) = colour_problem(&l.intensity, MAX_RADIANCE) {
            let header = text
                .lines()
                .enumerate()
                .filter(|(_, l)| l.trim_start().starts_with("[[lights]]"))
                .nth(i)
                .map_or(0, |(k, _)| k + 1);
            return Err(err(
                field_line(text, header, "intensity"),
                format!("lights[{i}].intensity {m}"),
            ));
        }
    }
    for (name, m) in &file.materials {
        let problem = match m {
            Material::Diffuse { albedo } => {
                colour_problem(albedo, 1.0).map(|e| format!("albedo {e}"))
            }
            Material::Mirror { reflectance } => {
                colour_problem(reflectance, 1.0).map(|e| format!("reflectance {e}"))
            }
            Material::Glass { ior } => (!(MIN_IOR..=MAX_IOR).contains(ior))
                .then(|| format!("ior must be in [{MIN_IOR}, {MAX_IOR}], got {ior:?}")),
        };
        if let Some(p) = problem {
            let header = text
                .lines()
                .position(|l| l.trim() == format!("[materials.{name}]"))
                .map_or(0, |i| i + 1);
            return Err(err(header, format!("materials.{name}.{p}")));
        }
    }
    offset_value(&file.render.offset).map_err(|e| err(0, format!("render.offset: {e}")))?;
    if let Some(m) = colour_problem(&file.render.ambient, MAX_RADIANCE) {
        return Err(err(
            field_line(text, 0, "ambient"),
            format!("render.ambient {m}"),
        ));
    }
    for (i, l) in file.directional.iter().enumerate() {
        let d = l.direction;
        if nonzero3("direction", &d).is_some()
            || colour_problem(&l.irradiance, MAX_RADIANCE).is_some()
        {
            return Err(err(
                0,
                format!("directional[{i}]: needs a finite non-zero direction and three finite irradiances in [0, {MAX_RADIANCE:e}], got {d:?}, {:?}", l.irradiance),
            ));
        }
    }
    // Every number within the magnitude limit (NaN and ±inf were refused above or are refused
    // by the shapes' checks below, with their field)
    if let Some((path, line, x)) = too_large(text) {
        return Err(err(
            line,
            format!("{path} = {x:e}: a scene's numbers may be at most {MAX_MAGNITUDE:e} in magnitude (squared distances must stay finite)"),
        ));
    }
    // The camera's frame, as the renderer and the exporters compute it, is finite
    let frame = {
        let pos = glam::DVec3::from_array(cam.position);
        let fwd = (glam::DVec3::from_array(cam.look_at) - pos).normalize();
        let right = fwd.cross(glam::DVec3::from_array(cam.up)).normalize();
        [fwd, right, right.cross(fwd)]
    };
    if !frame.iter().all(|v| v.is_finite()) {
        return Err(err(
            field_line(text, 0, "up"),
            format!(
                "camera: position {:?}, look_at {:?} and up {:?} give no finite view direction and frame (a vector too short to normalise)",
                cam.position, cam.look_at, cam.up
            ),
        ));
    }
    // Lines of the [[shapes]] headers (spans are lost inside tagged tables)
    let shape_lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.trim_start().starts_with("[[shapes]]"))
        .map(|(i, _)| i + 1)
        .collect();
    let mut meshes = BTreeMap::new();
    let mut implicits = BTreeMap::new();
    for (i, shape) in file.shapes.iter().enumerate() {
        let line = shape_lines.get(i).copied().unwrap_or(0);
        let mat = shape.material();
        if !file.materials.contains_key(mat) {
            return Err(err(
                line,
                format!("shapes[{i}].material: unknown material '{mat}'"),
            ));
        }
        if let Some((field, message)) = shape.problem() {
            return Err(err(
                field_line(text, line, field),
                format!("shapes[{i}].{field}: {message}"),
            ));
        }
        if let Shape::Mesh { file: f, .. } | Shape::Mpu { mesh: Some(f), .. } = shape {
            let mesh_path = path.parent().unwrap_or(Path::new(".")).join(f);
            let tris =
                load_obj(&mesh_path).map_err(|e| err(line, format!("shapes[{i}].file: {e}")))?;
            meshes.insert(i, tris);
        }
        if let Some(field) =
            field_of(shape, path).map_err(|e| err(line, format!("shapes[{i}]: {e}")))?
        {
            implicits.insert(i, field);
        }
    }
    Ok(Scene {
        file,
        meshes,
        implicits,
        path: path.to_path_buf(),
    })
}

/// The offset setting as `None` (auto) or a fixed distance (0 for "none").
pub fn offset_value(v: &toml::Value) -> Result<Option<f64>, String> {
    match v {
        toml::Value::String(s) if s == "auto" => Ok(None),
        toml::Value::String(s) if s == "none" => Ok(Some(0.0)),
        toml::Value::Float(x) if *x >= 0.0 => Ok(Some(*x)),
        toml::Value::Integer(x) if *x >= 0 => Ok(Some(*x as f64)),
        other => Err(format!(
            "expected \"auto\", \"none\" or a distance ≥ 0, got {other}"
        )),
    }
}

/// Triangles of an OBJ file (polygons are triangulated by tobj). The file must be a regular file
/// of at most [`crate::input::MAX_MESH_BYTES`] giving at most [`MAX_TRIANGLES`] triangles; its
/// material library (`mtllib`) is never read: materials come from the scene.
fn load_obj(path: &Path) -> Result<Vec<[[f64; 3]; 3]>, String> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let bytes = crate::input::read_capped(
        path,
        crate::input::MAX_MESH_BYTES,
        crate::input::Kind::Regular,
    )
    .map_err(|e| format!("cannot load {}: {e}", path.display()))?;
    let (models, _) = tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &opts, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| format!("cannot load {}: {e}", path.display()))?;
    let count: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    if count > MAX_TRIANGLES {
        return Err(format!(
            "{}: {count} triangles; a mesh may have at most {MAX_TRIANGLES}",
            path.display()
        ));
    }
    let mut tris = vec![];
    for m in models {
        let p = &m.mesh.positions;
        let v = |i: u32| {
            [
                p[3 * i as usize] as f64,
                p[3 * i as usize + 1] as f64,
                p[3 * i as usize + 2] as f64,
            ]
        };
        if let Some(bad) = p.iter().position(|x| !x.is_finite()) {
            return Err(format!(
                "{}: vertex {} of '{}' is not finite ({})",
                path.display(),
                bad / 3 + 1,
                m.name,
                p[bad]
            ));
        }
        for f in m.mesh.indices.chunks_exact(3) {
            tris.push([v(f[0]), v(f[1]), v(f[2])]);
        }
    }
    if tris.is_empty() {
        return Err(format!("{} has no triangles", path.display()));
    }
    Ok(tris)
}
