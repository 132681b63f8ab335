//! The pinhole camera.

use super::*;

/// The pinhole camera: right-handed, horizontal field of view, `w × h` pixels.
#[derive(Clone, Copy, Debug)]
pub struct Lens {
    /// Eye position.
    pub pos: DVec3,
    pub(super) fwd: DVec3,
    pub(super) right: DVec3,
    pub(super) up: DVec3,
    pub(super) half_w: f64,
    pub(super) half_h: f64,
    pub(super) w: f64,
    pub(super) h: f64,
}

impl Lens {
    /// The camera of scene `s` for a `w × h` image.
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
        self.dir_from(self.across(x), self.down(y))
    }

    /// The image plane's horizontal offset at `x` pixels from the left edge.
    #[inline]
    pub(super) fn across(&self, x: f64) -> DVec3 {
        self.right * ((2.0 * (x / self.w) - 1.0) * self.half_w)
    }

    /// The image plane's vertical offset at `y` pixels from the top edge.
    #[inline]
    pub(super) fn down(&self, y: f64) -> DVec3 {
        self.up * ((1.0 - 2.0 * (y / self.h)) * self.half_h)
    }

    /// The unit direction from its two offsets ([`Lens::across`], [`Lens::down`]), which the
    /// render loop computes once per column and once per row.
    #[inline]
    pub(super) fn dir_from(&self, across: DVec3, down: DVec3) -> DVec3 {
        (self.fwd + across + down).normalize()
    }
}
