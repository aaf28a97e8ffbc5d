//! The scene model: world-space triangles with per-mesh opacity, one area light, one camera.
//!
//! Model only what a scene needs (docs/methods.md §11): no materials, no textures, no scene graph.
mod gltf;
mod obj;
mod toml;

use crate::{
    camera::Camera,
    light::{Light, LightShape},
};
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
///
/// The fields are private so every scene passes the constructors' checks: one mesh index per
/// triangle, each naming a mesh, mesh ranges inside the triangles, finite vertices, opacities in
/// [0, 1], a valid camera and light. Read them through the accessors; change the camera, light
/// or opacities through the checked setters.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The scene file, for messages (or a name for scenes built in code).
    path: PathBuf,
    /// The camera.
    camera: Camera,
    /// The light.
    light: Light,
    /// World-space triangles of all meshes, mesh after mesh.
    triangles: Vec<[Vec3; 3]>,
    /// Index into [`Scene::meshes`] per triangle.
    triangle_mesh: Vec<u32>,
    /// The meshes.
    meshes: Vec<MeshInfo>,
    /// Zero-area (or non-finite) triangles dropped while loading.
    skipped_degenerate: usize,
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

    /// A scene from its parts, checked: `triangle_mesh` has one entry per triangle, each an index
    /// into `meshes`; every mesh's range lies inside `triangles` and holds only its own
    /// triangles; vertices are finite, opacities in [0, 1]; the camera and light pass
    /// [`Scene::set_camera`] and [`Scene::set_light`]. An empty scene is allowed (a level with no
    /// casters); [`Scene::from_meshes`] refuses one.
    pub fn from_parts(
        path: PathBuf,
        camera: Camera,
        light: Light,
        triangles: Vec<[Vec3; 3]>,
        triangle_mesh: Vec<u32>,
        meshes: Vec<MeshInfo>,
        skipped_degenerate: usize,
    ) -> crate::Result<Scene> {
        let err = |key: String, reason: String| crate::Error::Scene {
            path: path.clone(),
            key: Some(key),
            reason,
        };
        if triangle_mesh.len() != triangles.len() {
            return Err(err(
                "triangle_mesh".into(),
                format!(
                    "{} entries for {} triangles",
                    triangle_mesh.len(),
                    triangles.len()
                ),
            ));
        }
        if let Some(t) = triangles
            .iter()
            .position(|t| !t.iter().all(|v| v.is_finite()))
        {
            return Err(err(format!("triangles[{t}]"), "not finite".into()));
        }
        if let Some(t) = triangle_mesh
            .iter()
            .position(|&m| m as usize >= meshes.len())
        {
            return Err(err(
                format!("triangle_mesh[{t}]"),
                format!("mesh {} of {} meshes", triangle_mesh[t], meshes.len()),
            ));
        }
        for (k, m) in meshes.iter().enumerate() {
            check_opacity(&path, k, m.opacity)?;
            let r = &m.triangles;
            if r.start > r.end
                || r.end > triangles.len()
                || triangle_mesh[r.clone()].iter().any(|&x| x as usize != k)
            {
                return Err(err(
                    format!("mesh[{k}].triangles"),
                    format!(
                        "range {r:?} is not this mesh's triangles (of {})",
                        triangles.len()
                    ),
                ));
            }
        }
        check_camera(&path, &camera)?;
        check_light(&path, &light)?;
        Ok(Scene {
            path,
            camera,
            light,
            triangles,
            triangle_mesh,
            meshes,
            skipped_degenerate,
        })
    }

    /// The scene file, for messages (or a name for scenes built in code).
    #[inline]
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// The camera.
    #[inline]
    pub fn camera(&self) -> &Camera {
        &self.camera
    }
    /// The light.
    #[inline]
    pub fn light(&self) -> &Light {
        &self.light
    }
    /// World-space triangles of all meshes, mesh after mesh.
    #[inline]
    pub fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }
    /// Index into [`Scene::meshes`] per triangle.
    #[inline]
    pub fn triangle_mesh(&self) -> &[u32] {
        &self.triangle_mesh
    }
    /// The meshes.
    #[inline]
    pub fn meshes(&self) -> &[MeshInfo] {
        &self.meshes
    }
    /// Zero-area (or non-finite) triangles dropped while loading.
    #[inline]
    pub fn skipped_degenerate(&self) -> usize {
        self.skipped_degenerate
    }

    /// Replaces the camera. Fails with [`crate::Error::Scene`] (the scene unchanged) unless eye,
    /// target and up are finite, the target differs from the eye, up is not parallel to the view,
    /// the field of view is in (0, 180) degrees and the image sides in 1..=`MAX_IMAGE_SIDE`.
    pub fn set_camera(&mut self, camera: Camera) -> crate::Result<()> {
        check_camera(&self.path, &camera)?;
        self.camera = camera;
        Ok(())
    }

    /// Sets the camera's image size (as [`Scene::set_camera`]).
    pub fn set_resolution(&mut self, width: u32, height: u32) -> crate::Result<()> {
        self.set_camera(Camera {
            width,
            height,
            ..self.camera
        })
    }

    /// Replaces the light. Fails with [`crate::Error::Scene`] (the scene unchanged) unless its
    /// centre is finite, its normal and tangent finite unit vectors and its size finite and
    /// non-negative (a directional light's angle below 90 degrees).
    pub fn set_light(&mut self, light: Light) -> crate::Result<()> {
        check_light(&self.path, &light)?;
        self.light = light;
        Ok(())
    }

    /// Sets mesh `k`'s opacity. Fails with [`crate::Error::Scene`] for a mesh index past
    /// [`Scene::meshes`] or an opacity outside [0, 1].
    pub fn set_mesh_opacity(&mut self, k: usize, opacity: f32) -> crate::Result<()> {
        if k >= self.meshes.len() {
            return Err(crate::Error::Scene {
                path: self.path.clone(),
                key: Some(format!("mesh[{k}]")),
                reason: format!("no such mesh (the scene has {})", self.meshes.len()),
            });
        }
        check_opacity(&self.path, k, opacity)?;
        self.meshes[k].opacity = opacity;
        Ok(())
    }

    /// This scene with every mesh fully opaque (opacity 1).
    pub fn opaque(&self) -> Scene {
        let mut s = self.clone();
        for m in &mut s.meshes {
            m.opacity = 1.0;
        }
        s
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
        let path = PathBuf::from(name);
        check_camera(&path, &camera)?;
        check_light(&path, &light)?;
        let mut scene = Scene::empty(path, camera, light);
        for (k, (tris, opacity)) in meshes.into_iter().enumerate() {
            check_opacity(&scene.path, k, opacity)?;
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

    /// How many meshes are semi-transparent (opacity below 1).
    pub fn semi_transparent_meshes(&self) -> usize {
        self.meshes.iter().filter(|m| m.opacity < 1.0).count()
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
        OpacityLevel::of(
            self.meshes
                .iter()
                .filter(|m| !m.triangles.is_empty())
                .map(|m| m.opacity),
        )
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

/// Fails unless `opacity` (of mesh `k`) is in [0, 1].
fn check_opacity(path: &Path, k: usize, opacity: f32) -> crate::Result<()> {
    if (0.0..=1.0).contains(&opacity) {
        return Ok(());
    }
    Err(crate::Error::Scene {
        path: path.to_path_buf(),
        key: Some(format!("mesh[{k}].opacity")),
        reason: format!("must be in [0, 1], got {opacity}"),
    })
}

/// The camera checks of the scene file, for cameras given in code.
fn check_camera(path: &Path, c: &Camera) -> crate::Result<()> {
    let err = |key: &str, reason: String| {
        Err(crate::Error::Scene {
            path: path.to_path_buf(),
            key: Some(format!("camera.{key}")),
            reason,
        })
    };
    for (key, v) in [("eye", c.eye), ("target", c.target), ("up", c.up)] {
        if !v.is_finite() {
            return err(key, format!("every number must be finite, got {v}"));
        }
    }
    let forward = (c.target - c.eye).normalize_or_zero();
    if forward == Vec3::ZERO {
        return err("target", "must differ from camera.eye".into());
    }
    if forward.cross(c.up).length() < 1e-6 * c.up.length() || c.up == Vec3::ZERO {
        return err("up", "must not be parallel to the view direction".into());
    }
    if !(c.fov_y_deg.is_finite() && c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0) {
        return err(
            "fov_y_deg",
            format!("must be in (0, 180), got {}", c.fov_y_deg),
        );
    }
    for (key, v) in [("width", c.width), ("height", c.height)] {
        if v == 0 || v > toml::MAX_IMAGE_SIDE {
            return err(
                key,
                format!("must be in 1..={}, got {v}", toml::MAX_IMAGE_SIDE),
            );
        }
    }
    Ok(())
}

/// Finite light geometry: the centre, unit normal and tangent, a finite non-negative size.
fn check_light(path: &Path, l: &Light) -> crate::Result<()> {
    let err = |key: &str, reason: String| {
        Err(crate::Error::Scene {
            path: path.to_path_buf(),
            key: Some(format!("light.{key}")),
            reason,
        })
    };
    if !l.center.is_finite() {
        return err("center", format!("must be finite, got {}", l.center));
    }
    for (key, v) in [("normal", l.normal), ("tangent", l.tangent)] {
        if !(v.is_finite() && (v.length() - 1.0).abs() <= 1e-3) {
            return err(key, format!("must be a finite unit vector, got {v}"));
        }
    }
    let (key, sizes, max) = match l.shape {
        LightShape::Rect { size } => ("size", size.to_vec(), f32::INFINITY),
        LightShape::Disk { radius } | LightShape::Sphere { radius } => {
            ("radius", vec![radius], f32::INFINITY)
        }
        LightShape::Directional { angle_deg } => ("angle_deg", vec![angle_deg], 90.0),
    };
    if !sizes.iter().all(|&x| x.is_finite() && x >= 0.0 && x < max) {
        return err(
            key,
            format!("must be finite, >= 0 and < {max}, got {sizes:?}"),
        );
    }
    Ok(())
}

/// One level of [`Scene::opacity_levels`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpacityLevel {
    /// Meshes of at least this opacity cast shadows at this level (+inf: none).
    pub min_opacity: f32,
    /// The level's weight in V.
    pub weight: f32,
}

impl OpacityLevel {
    /// The levels of casters with these `opacities` ([`Scene::opacity_levels`]; opacities
    /// above 1 count as 1, those at or below 0 cast nothing).
    pub fn of(opacities: impl IntoIterator<Item = f32>) -> Vec<OpacityLevel> {
        let mut a: Vec<f32> = opacities
            .into_iter()
            .map(|o| o.min(1.0))
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

    /// Scenes cannot be put in a state the estimators would index out of range or divide by:
    /// `from_parts` and every setter refuse what the public fields used to allow.
    #[test]
    fn from_parts_and_setters_reject_invalid_scenes() {
        let s = scene(&[1.0, 0.5]);
        let parts = |tris: Vec<[Vec3; 3]>, ids: Vec<u32>, meshes: Vec<MeshInfo>| {
            Scene::from_parts(
                s.path().to_path_buf(),
                *s.camera(),
                *s.light(),
                tris,
                ids,
                meshes,
                0,
            )
        };
        let (tris, ids, meshes) = (
            s.triangles().to_vec(),
            s.triangle_mesh().to_vec(),
            s.meshes().to_vec(),
        );
        let ok = parts(tris.clone(), ids.clone(), meshes.clone()).unwrap();
        assert_eq!(ok.triangles(), s.triangles());
        let invalid = |r: crate::Result<Scene>| matches!(r, Err(crate::Error::Scene { .. }));
        // Mismatched lengths, a mesh index out of range, a range past the triangles or over
        // another mesh's triangles, a non-finite vertex, an opacity outside [0, 1].
        assert!(invalid(parts(
            tris.clone(),
            ids[..1].to_vec(),
            meshes.clone()
        )));
        assert!(invalid(parts(tris.clone(), vec![0, 2], meshes.clone())));
        let mut m = meshes.clone();
        m[1].triangles = 1..3;
        assert!(invalid(parts(tris.clone(), ids.clone(), m)));
        let mut m = meshes.clone();
        m[1].triangles = 0..2;
        assert!(invalid(parts(tris.clone(), ids.clone(), m)));
        let mut t = tris.clone();
        t[0][1] = Vec3::NAN;
        assert!(invalid(parts(t, ids.clone(), meshes.clone())));
        let mut m = meshes.clone();
        m[0].opacity = 1.5;
        assert!(invalid(parts(tris, ids, m)));
        // Setters leave the scene unchanged on error.
        let mut s2 = s.clone();
        assert!(s2.set_mesh_opacity(2, 0.5).is_err());
        assert!(s2.set_mesh_opacity(0, f32::NAN).is_err());
        s2.set_mesh_opacity(0, 0.25).unwrap();
        assert_eq!(s2.meshes()[0].opacity, 0.25);
        assert!(s2.set_resolution(0, 4).is_err());
        assert_eq!(s2.camera(), s.camera());
        s2.set_resolution(8, 2).unwrap();
        assert_eq!((s2.camera().width, s2.camera().height), (8, 2));
        let mut cam = *s.camera();
        cam.target = cam.eye;
        assert!(s2.set_camera(cam).is_err());
        let mut light = *s.light();
        light.center = Vec3::INFINITY;
        assert!(s2.set_light(light).is_err());
        light = *s.light();
        light.normal = Vec3::ZERO;
        assert!(s2.set_light(light).is_err());
        light = *s.light();
        light.shape = crate::light::LightShape::Disk { radius: -1.0 };
        assert!(s2.set_light(light).is_err());
        assert_eq!(s2.light(), s.light());
        assert!(s.opaque().is_opaque());
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
