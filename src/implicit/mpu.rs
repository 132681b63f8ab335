//! Multi-level partition of unity implicits (Ohtake et al. 2003). Being written on branch
//! h-mpu; until it lands, loading an MPU shape is an error.

use glam::DVec3;

#[derive(Debug, Clone, Default)]
pub struct MpuOptions;

#[derive(Debug)]
pub struct Mpu;

impl Mpu {
    pub fn fit(_points: &[DVec3], _normals: &[DVec3], _opts: &MpuOptions) -> Mpu {
        Mpu
    }
    pub fn load_points(path: &std::path::Path) -> anyhow::Result<(Vec<DVec3>, Vec<DVec3>)> {
        anyhow::bail!(
            "{}: MPU surfaces are not available in this build",
            path.display()
        )
    }
    pub fn eval(&self, _p: DVec3) -> f64 {
        f64::INFINITY
    }
    pub fn gradient(&self, _p: DVec3) -> DVec3 {
        DVec3::ZERO
    }
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (DVec3::ZERO, DVec3::ZERO)
    }
    pub fn lipschitz(&self) -> f64 {
        1.0
    }
}
