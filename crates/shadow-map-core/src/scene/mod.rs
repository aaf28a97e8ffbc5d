//! The scene model: world-space triangles with per-mesh opacity, one area light, one camera.
//!
//! Model only what a scene needs (docs/methods.md §11): no materials, no textures, no scene graph.
mod gltf;
mod obj;
mod toml;

use crate::{camera::Camera, light::Light};
use glam::Vec3;
use std::path::{Path, PathBuf};

pub use gltf::load_gltf_triangles;
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

    /// The scene's opacities as levels (docs/methods.md §3 "Semi-transparent occluders"): with
    /// the distinct mesh opacities `0 < a_1 < ... < a_L`, level k keeps the meshes of opacity
    /// `>= a_k` as opaque casters and weighs `a_k - a_{k-1}` (`a_0 = 0`); when `a_L < 1` a last
    /// level with no caster weighs `1 - a_L`. The weights sum to 1, and for one light sample the
    /// weighted sum of the levels' visibilities is `1 - max` of the opacities its ray crosses:
    /// exact for one semi-transparent surface per ray (the reference multiplies transmittances
    /// where several overlap). An opaque scene is one level of weight 1.
    pub fn opacity_levels(&self) -> Vec<OpacityLevel> {
        let mut a: Vec<f32> = self
            .meshes
            .iter()
            .filter(|m| !m.triangles.is_empty())
            .map(|m| m.opacity.min(1.0))
            .filter(|&o| o > 0.0)
            .collect();
        a.sort_by(f32::total_cmp);
        a.dedup();
        let mut levels = Vec::with_capacity(a.len() + 1);
        let mut prev = 0.0f32;
        for &ak in &a {
            levels.push(OpacityLevel {
                min_opacity: ak,
                weight: ak - prev,
            });
            prev = ak;
        }
        if prev < 1.0 {
            levels.push(OpacityLevel {
                min_opacity: f32::INFINITY,
                weight: 1.0 - prev,
            });
        }
        levels
    }

    /// This scene with only the meshes of opacity `>= min_opacity` (mesh indices renumbered,
    /// each keeping its opacity): the casters of one [`OpacityLevel`].
    pub fn with_opacity_at_least(&self, min_opacity: f32) -> Scene {
        let mut out = Scene {
            path: self.path.clone(),
            camera: self.camera,
            light: self.light,
            triangles: Vec::new(),
            triangle_mesh: Vec::new(),
            meshes: Vec::new(),
            skipped_degenerate: self.skipped_degenerate,
        };
        for m in self.meshes.iter().filter(|m| m.opacity >= min_opacity) {
            let id = out.meshes.len() as u32;
            let start = out.triangles.len();
            out.triangles
                .extend_from_slice(&self.triangles[m.triangles.clone()]);
            out.triangle_mesh.resize(out.triangles.len(), id);
            out.meshes.push(MeshInfo {
                source: m.source.clone(),
                opacity: m.opacity,
                triangles: start..out.triangles.len(),
            });
        }
        out
    }
}

/// One level of [`Scene::opacity_levels`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpacityLevel {
    /// Meshes of at least this opacity cast shadows at this level (+inf: none).
    pub min_opacity: f32,
    /// The level's weight in V.
    pub weight: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{camera::Camera, light::Light};

    fn tri(y: f32) -> Vec<[Vec3; 3]> {
        vec![[
            Vec3::new(0.0, y, 0.0),
            Vec3::new(1.0, y, 0.0),
            Vec3::new(0.0, y, 1.0),
        ]]
    }

    fn scene(opacities: &[f32]) -> Scene {
        let camera = Camera {
            eye: Vec3::new(0.0, 5.0, 5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 40.0,
            width: 4,
            height: 4,
        };
        let meshes = opacities
            .iter()
            .enumerate()
            .map(|(k, &o)| (tri(k as f32), o))
            .collect();
        let light = Light {
            shape: crate::light::LightShape::Rect { size: [1.0, 1.0] },
            center: Vec3::new(0.0, 3.0, 0.0),
            normal: Vec3::NEG_Y,
            tangent: Vec3::X,
        };
        Scene::from_meshes("levels", camera, light, meshes).unwrap()
    }

    #[test]
    fn opacity_levels_weigh_to_one() {
        let levels = |o: &[f32]| -> Vec<(f32, f32)> {
            scene(o)
                .opacity_levels()
                .iter()
                .map(|l| (l.min_opacity, l.weight))
                .collect()
        };
        assert_eq!(levels(&[1.0, 1.0]), vec![(1.0, 1.0)]);
        assert_eq!(levels(&[1.0, 0.4]), vec![(0.4, 0.4), (1.0, 0.6)]);
        // No opaque mesh: a last level without casters; opacity 0 casts nothing.
        let l = levels(&[0.5, 0.0, 0.25, 0.5]);
        assert_eq!(l, vec![(0.25, 0.25), (0.5, 0.25), (f32::INFINITY, 0.5)]);
        let s = scene(&[0.5, 0.0, 0.25, 0.5]);
        for (a, n) in [(0.25, 3), (0.5, 2), (f32::INFINITY, 0)] {
            let k = s.with_opacity_at_least(a);
            assert_eq!(k.meshes.len(), n);
            assert_eq!(k.triangles.len(), n);
            assert!(k.meshes.iter().all(|m| m.opacity >= a));
            assert!((0..k.triangles.len()).all(|t| k.triangle_opacity(t) >= a));
        }
    }
}
