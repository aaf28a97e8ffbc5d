//! Receivers: the points whose visibility an estimator computes.
//!
//! Either the camera's G-buffer (one receiver per pixel, in image layout) or a user's own arrays of
//! points and normals. Estimators never care where they came from; those that exploit screen-space
//! coherence (pixel packets) use [`Receivers::layout`] when present and fall back to per-receiver
//! work when it is absent.
use crate::{bvh::SceneBvh, scene::Scene, Error, Result};
use glam::Vec3;
use rayon::prelude::*;

/// Image layout of receivers that come from an image: receiver `j * width + i` is pixel (i, j).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageLayout {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

/// A set of receivers. Inactive receivers (background pixels) keep their slot so the image layout
/// is preserved; every estimator writes NaN for them (the contract's background V).
#[derive(Debug, Clone, Default)]
pub struct Receivers {
    /// World positions.
    pub position: Vec<Vec3>,
    /// Unit geometric normals, on the side the receiver is seen from (the contract: light behind
    /// this tangent plane is blocked).
    pub normal: Vec<Vec3>,
    /// Whether each slot holds a receiver (a camera hit).
    pub active: Vec<bool>,
    /// View depth per receiver (distance along the camera's view axis; +inf for background),
    /// present for G-buffer receivers.
    pub view_depth: Option<Vec<f32>>,
    /// Image layout, when the receivers are pixels.
    pub layout: Option<ImageLayout>,
}

impl Receivers {
    /// Receivers from a user's own arrays (no image layout). Normals are normalised; every value
    /// must be finite and normals non-zero.
    pub fn from_points(position: Vec<Vec3>, normal: Vec<Vec3>) -> Result<Self> {
        if position.len() != normal.len() {
            return Err(Error::Receivers(format!(
                "{} positions but {} normals",
                position.len(),
                normal.len()
            )));
        }
        let mut n = normal;
        for (k, (p, nn)) in position.iter().zip(n.iter_mut()).enumerate() {
            if !p.is_finite() {
                return Err(Error::Receivers(format!("position {k} is not finite: {p}")));
            }
            *nn = nn
                .try_normalize()
                .ok_or_else(|| Error::Receivers(format!("normal {k} is zero or not finite")))?;
        }
        let len = position.len();
        Ok(Receivers {
            position,
            normal: n,
            active: vec![true; len],
            view_depth: None,
            layout: None,
        })
    }

    /// Attaches an image layout (`width * height` must equal the receiver count).
    pub fn with_layout(mut self, layout: ImageLayout) -> Result<Self> {
        if layout.width as usize * layout.height as usize != self.len() {
            return Err(Error::Receivers(format!(
                "layout {}x{} does not match {} receivers",
                layout.width,
                layout.height,
                self.len()
            )));
        }
        self.layout = Some(layout);
        Ok(self)
    }

    /// The camera's G-buffer: one ray per pixel exactly as the contract defines it, closest hit
    /// through the BVH; normals face the camera.
    pub fn from_camera(scene: &Scene, bvh: &SceneBvh) -> Self {
        let cam = &scene.camera;
        let basis = cam.basis();
        let (w, h) = (cam.width, cam.height);
        let px: Vec<(Vec3, Vec3, bool, f32)> = (0..w * h)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % w, k / w);
                let d = cam.ray_dir(&basis, i, j);
                match bvh.closest_hit(cam.eye, d, 0.0, f32::INFINITY) {
                    Some(hit) => {
                        let p = cam.eye + d * hit.t;
                        let mut n = bvh.normal(hit.triangle);
                        if n.dot(d) > 0.0 {
                            n = -n;
                        }
                        (p, n, true, hit.t * d.dot(basis.forward))
                    }
                    None => (Vec3::ZERO, Vec3::Z, false, f32::INFINITY),
                }
            })
            .collect();
        let mut r = Receivers {
            position: Vec::with_capacity(px.len()),
            normal: Vec::with_capacity(px.len()),
            active: Vec::with_capacity(px.len()),
            view_depth: Some(Vec::with_capacity(px.len())),
            layout: Some(ImageLayout {
                width: w,
                height: h,
            }),
        };
        for (p, n, a, z) in px {
            r.position.push(p);
            r.normal.push(n);
            r.active.push(a);
            if let Some(v) = r.view_depth.as_mut() {
                v.push(z);
            }
        }
        r
    }

    /// Number of slots.
    pub fn len(&self) -> usize {
        self.position.len()
    }
    /// No slots.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }
    /// Number of active receivers.
    pub fn active_count(&self) -> usize {
        self.active.iter().filter(|&&a| a).count()
    }
    /// Fails with [`Error::Receivers`] unless `v` has one output slot per receiver.
    pub fn check_output(&self, v: &[f32]) -> Result<()> {
        if v.len() != self.len() {
            return Err(Error::Receivers(format!(
                "output has {} slots for {} receivers",
                v.len(),
                self.len()
            )));
        }
        Ok(())
    }
}
