//! Implicit surfaces (seed 004, Wu & Pan): signed distance functions, POV-Ray's blob field and
//! an MPU implicit fitted to the Stanford bunny, rendered by sphere tracing (Hart 1996) with a
//! stated Lipschitz bound per field, and image-space subdivision (§2) checked pixel by pixel
//! against per-pixel tracing.

pub mod field;
pub mod march;
pub mod mpu;
pub mod subdiv;

use crate::render::scene::Shape;
use field::Field;
use std::path::Path;
use std::sync::Arc;

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
            let (p, n) = mpu::Mpu::load_points(&path).map_err(|e| format!("points: {e:#}"))?;
            if p.len() < 4 {
                return Err(format!(
                    "points: {} has {} point(s); an MPU fit needs at least 4",
                    path.display(),
                    p.len()
                ));
            }
            Field::Mpu(Arc::new(mpu::Mpu::fit(&p, &n, &mpu::MpuOptions::default())))
        }
        _ => return Ok(None),
    }))
}
pub mod check;
