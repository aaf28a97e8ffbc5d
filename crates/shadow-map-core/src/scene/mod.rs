//! The scene model: world-space triangles with per-mesh opacity, one area light, one camera.
//!
//! Model only what a scene needs (docs/methods.md §11): no materials, no textures, no scene graph.
mod obj;
mod toml;

use crate::{camera::Camera, light::Light};
use glam::Vec3;
use std::path::{Path, PathBuf};

pub use obj::load_obj_triangles;

/// One mesh's bookkeeping: where it came from and how much light its surfaces pass.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshInfo {
    /// The OBJ file (as resolved), or a name for meshes built in code.
    pub source: PathBuf,
    /// Opacity in [0, 1]: every surface of this mesh passes `1 - opacity` of the light.
    pub opacity: f32,
    /// Range of this mesh's triangles in [`Scene::triangles`].
    pub triangles: std::ops::Range<usize>,
}

/// A loaded scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The scene file, for messages (or a name for scenes built in code).
    pub path: PathBuf,
    /// The camera.
    pub camera: Camera,
    /// The light.
    pub light: Light,
    /// World-space triangles of all meshes, mesh after mesh.
    pub triangles: Vec<[Vec3; 3]>,
    /// Index into [`Scene::meshes`] per triangle.
    pub triangle_mesh: Vec<u32>,
    /// The meshes.
    pub meshes: Vec<MeshInfo>,
    /// Zero-area (or non-finite) triangles dropped while loading.
    pub skipped_degenerate: usize,
}

/// Axis-aligned bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (min = +inf, max = -inf).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::INFINITY,
        max: Vec3::NEG_INFINITY,
    };
    /// Grows the box by a point.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    /// Length of the diagonal (0 for the empty box).
    pub fn diagonal(&self) -> f32 {
        if self.min.x > self.max.x {
            0.0
        } else {
            (self.max - self.min).length()
        }
    }
}

/// Relative area below which a triangle counts as degenerate: `|cross| < DEGENERATE_REL * diag^2`.
pub const DEGENERATE_REL: f32 = 1e-12;

impl Scene {
    /// A scene with its camera and light and no meshes yet (meshes are added with `push_mesh`).
    pub(crate) fn empty(path: PathBuf, camera: Camera, light: Light) -> Scene {
        Scene {
            path,
            camera,
            light,
            triangles: Vec::new(),
            triangle_mesh: Vec::new(),
            meshes: Vec::new(),
            skipped_degenerate: 0,
        }
    }

    /// Loads a scene file exactly as the contract defines it (docs/methods.md §11, "Scene file").
    /// Every error names the file and the key or line; nothing is written.
    pub fn load(path: impl AsRef<Path>) -> crate::Result<Scene> {
        toml::load(path.as_ref())
    }

    /// Builds a scene from meshes given in code: `(triangles, opacity)` per mesh. Zero-area
    /// triangles are skipped and counted, as when loading.
    pub fn from_meshes(
        name: &str,
        camera: Camera,
        light: Light,
        meshes: Vec<(Vec<[Vec3; 3]>, f32)>,
    ) -> crate::Result<Scene> {
        let mut scene = Scene::empty(PathBuf::from(name), camera, light);
        for (k, (tris, opacity)) in meshes.into_iter().enumerate() {
            if !(0.0..=1.0).contains(&opacity) {
                return Err(crate::Error::Scene {
                    path: scene.path.clone(),
                    key: Some(format!("mesh[{k}].opacity")),
                    reason: format!("must be in [0, 1], got {opacity}"),
                });
            }
            scene.push_mesh(PathBuf::from(format!("{name}#mesh{k}")), opacity, tris);
        }
        if scene.triangles.is_empty() {
            return Err(crate::Error::EmptyScene {
                path: scene.path,
                skipped: scene.skipped_degenerate,
            });
        }
        Ok(scene)
    }

    pub(crate) fn push_mesh(&mut self, source: PathBuf, opacity: f32, tris: Vec<[Vec3; 3]>) {
        let mut bb = Aabb::EMPTY;
        for t in &tris {
            for v in t {
                if v.is_finite() {
                    bb.grow(*v);
                }
            }
        }
        let diag = bb.diagonal().max(f32::MIN_POSITIVE);
        let start = self.triangles.len();
        let id = self.meshes.len() as u32;
        for t in tris {
            let area2 = (t[1] - t[0]).cross(t[2] - t[0]).length();
            let finite = t[0].is_finite() && t[1].is_finite() && t[2].is_finite();
            if !(finite && area2 > DEGENERATE_REL * diag * diag) {
                self.skipped_degenerate += 1;
                continue;
            }
            self.triangles.push(t);
            self.triangle_mesh.push(id);
        }
        self.meshes.push(MeshInfo {
            source,
            opacity,
            triangles: start..self.triangles.len(),
        });
    }

    /// Bounds of all triangles.
    pub fn bounds(&self) -> Aabb {
        let mut bb = Aabb::EMPTY;
        for t in &self.triangles {
            for v in t {
                bb.grow(*v);
            }
        }
        bb
    }

    /// Opacity of the mesh triangle `t` belongs to.
    #[inline]
    pub fn triangle_opacity(&self, t: usize) -> f32 {
        self.meshes[self.triangle_mesh[t] as usize].opacity
    }

    /// True when every mesh is fully opaque (opacity 1): estimators then need no transmittance.
    pub fn is_opaque(&self) -> bool {
        self.meshes.iter().all(|m| m.opacity >= 1.0)
    }
}
