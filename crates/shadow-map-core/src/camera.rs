//! The contract's pinhole camera (docs/methods.md §11, "Scene file").
use glam::Vec3;

/// Pinhole, right-handed camera looking from `eye` to `target`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// Look-at point.
    pub target: Vec3,
    /// Up hint.
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// The camera's orthonormal basis.
#[derive(Debug, Clone, Copy)]
pub struct CameraBasis {
    /// `normalize(target - eye)`.
    pub forward: Vec3,
    /// `normalize(cross(forward, up))`.
    pub right: Vec3,
    /// `cross(right, forward)`.
    pub true_up: Vec3,
}

impl Camera {
    /// The basis, exactly as the contract defines it.
    pub fn basis(&self) -> CameraBasis {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let true_up = right.cross(forward);
        CameraBasis {
            forward,
            right,
            true_up,
        }
    }

    /// Unit direction of the ray through the centre of pixel (i, j): i the column from the left,
    /// j the row from the top. `ndc_x = (i + 0.5)/width*2 - 1`, `ndc_y = 1 - (j + 0.5)/height*2`,
    /// `dir = normalize(forward + ndc_x t aspect right + ndc_y t true_up)`, `t = tan(fov_y/2)`.
    pub fn ray_dir(&self, basis: &CameraBasis, i: u32, j: u32) -> Vec3 {
        let t = (self.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = self.width as f32 / self.height as f32;
        let ndc_x = (i as f32 + 0.5) / self.width as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - (j as f32 + 0.5) / self.height as f32 * 2.0;
        (basis.forward + ndc_x * t * aspect * basis.right + ndc_y * t * basis.true_up).normalize()
    }
}
