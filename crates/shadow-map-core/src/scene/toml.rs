//! The contract's scene TOML (docs/methods.md §11, "Scene file"), parsed with `toml` + `serde`
//! and validated key by key.
use super::Scene;
use crate::{
    camera::Camera,
    light::{default_tangent, Light, LightShape},
    Error, Result,
};
use glam::Vec3;
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    camera: CameraFile,
    light: LightFile,
    #[serde(default)]
    mesh: Vec<MeshFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    eye: [f32; 3],
    target: [f32; 3],
    up: [f32; 3],
    fov_y_deg: f32,
    width: u32,
    height: u32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightFile {
    shape: String,
    center: Option<[f32; 3]>,
    normal: Option<[f32; 3]>,
    tangent: Option<[f32; 3]>,
    size: Option<[f32; 2]>,
    radius: Option<f32>,
    direction: Option<[f32; 3]>,
    angle_deg: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshFile {
    path: String,
    scale: Option<f32>,
    rotate_y_deg: Option<f32>,
    translate: Option<[f32; 3]>,
    opacity: Option<f32>,
}

/// Largest image side the loader accepts.
pub const MAX_IMAGE_SIDE: u32 = 16384;

struct Ctx<'a> {
    path: &'a Path,
}

impl Ctx<'_> {
    fn err(&self, key: &str, reason: impl Into<String>) -> Error {
        Error::Scene {
            path: self.path.to_path_buf(),
            key: Some(key.to_string()),
            reason: reason.into(),
        }
    }
    fn finite<const N: usize>(&self, key: &str, v: [f32; N]) -> Result<[f32; N]> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(v)
        } else {
            Err(self.err(key, format!("every number must be finite, got {v:?}")))
        }
    }
    fn vec3(&self, key: &str, v: [f32; 3]) -> Result<Vec3> {
        Ok(Vec3::from_array(self.finite(key, v)?))
    }
    fn unit(&self, key: &str, v: [f32; 3]) -> Result<Vec3> {
        self.vec3(key, v)?
            .try_normalize()
            .ok_or_else(|| self.err(key, "must not be the zero vector"))
    }
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

pub(super) fn load(path: &Path) -> Result<Scene> {
    let file = read_scene_file(path)?;
    let cx = Ctx { path };
    let camera = parse_camera(&cx, &file.camera)?;
    let light = parse_light(&cx, &file.light)?;

    let mut scene = Scene::empty(path.to_path_buf(), camera, light);
    if file.mesh.is_empty() {
        return Err(cx.err("mesh", "the scene has no [[mesh]] entries"));
    }
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    for (k, m) in file.mesh.iter().enumerate() {
        let (obj_path, opacity, tris) = load_mesh(&cx, &dir, k, m)?;
        scene.push_mesh(obj_path, opacity, tris);
    }
    if scene.triangles.is_empty() {
        return Err(Error::EmptyScene {
            path: path.to_path_buf(),
            skipped: scene.skipped_degenerate,
        });
    }
    Ok(scene)
}

/// Reads `path` and parses it as a [`SceneFile`], TOML errors prefixed with their line.
fn read_scene_file(path: &Path) -> Result<SceneFile> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    ::toml::from_str(&text).map_err(|e| {
        let line = e
            .span()
            .map(|s| format!("line {}: ", line_of(&text, s.start)))
            .unwrap_or_default();
        Error::Scene {
            path: path.to_path_buf(),
            key: None,
            reason: format!("{line}{}", e.message().replace('\n', " ")),
        }
    })
}

/// Validates the `[camera]` table into a [`Camera`].
fn parse_camera(cx: &Ctx<'_>, c: &CameraFile) -> Result<Camera> {
    let eye = cx.vec3("camera.eye", c.eye)?;
    let target = cx.vec3("camera.target", c.target)?;
    let up = cx.unit("camera.up", c.up)?;
    if (target - eye).length() <= 0.0 {
        return Err(cx.err("camera.target", "must differ from camera.eye"));
    }
    let forward = (target - eye).normalize();
    if forward.cross(up).length() < 1e-6 {
        return Err(cx.err("camera.up", "must not be parallel to the view direction"));
    }
    if !(c.fov_y_deg.is_finite() && c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0) {
        return Err(cx.err(
            "camera.fov_y_deg",
            format!("must be in (0, 180), got {}", c.fov_y_deg),
        ));
    }
    for (k, v) in [("camera.width", c.width), ("camera.height", c.height)] {
        if v == 0 || v > MAX_IMAGE_SIDE {
            return Err(cx.err(k, format!("must be in 1..={MAX_IMAGE_SIDE}, got {v}")));
        }
    }
    Ok(Camera {
        eye,
        target,
        up,
        fov_y_deg: c.fov_y_deg,
        width: c.width,
        height: c.height,
    })
}

/// Validates the `[light]` table into a [`Light`].
fn parse_light(cx: &Ctx<'_>, l: &LightFile) -> Result<Light> {
    if l.shape == "directional" {
        return directional_light(cx, l);
    }
    for (k, present) in [
        ("light.direction", l.direction.is_some()),
        ("light.angle_deg", l.angle_deg.is_some()),
    ] {
        if present {
            return Err(cx.err(k, format!("not used by {} lights", l.shape)));
        }
    }
    let required = |key: &str, v: Option<[f32; 3]>| {
        v.ok_or_else(|| cx.err(key, format!("missing (required for {} lights)", l.shape)))
    };
    let center = cx.vec3("light.center", required("light.center", l.center)?)?;
    let normal = cx.unit("light.normal", required("light.normal", l.normal)?)?;
    let (shape, tangent) = match l.shape.as_str() {
        "rect" => rect_light(cx, l, normal)?,
        "disk" | "sphere" => round_light(cx, l, normal)?,
        other => {
            return Err(cx.err(
                "light.shape",
                format!("must be \"rect\", \"disk\", \"sphere\" or \"directional\", got {other:?}"),
            ))
        }
    };
    Ok(Light {
        shape,
        center,
        normal,
        tangent,
    })
}

/// Validates a directional light (the contract: `direction` and `angle_deg` only): the light
/// travels along the unit `direction` ([`Light::normal`]), its disk of directions has the angular
/// diameter `angle_deg` in (0, 90); the centre is unused (the origin).
fn directional_light(cx: &Ctx<'_>, l: &LightFile) -> Result<Light> {
    for (k, present) in [
        ("light.center", l.center.is_some()),
        ("light.normal", l.normal.is_some()),
        ("light.tangent", l.tangent.is_some()),
        ("light.size", l.size.is_some()),
        ("light.radius", l.radius.is_some()),
    ] {
        if present {
            return Err(cx.err(
                k,
                "not used by directional lights (use `direction` and `angle_deg`)",
            ));
        }
    }
    let d = l.direction.ok_or_else(|| {
        cx.err(
            "light.direction",
            "missing (required for directional lights)",
        )
    })?;
    let direction = cx.unit("light.direction", d)?;
    let a = l.angle_deg.ok_or_else(|| {
        cx.err(
            "light.angle_deg",
            "missing (required for directional lights)",
        )
    })?;
    if !(a.is_finite() && a > 0.0 && a < 90.0) {
        return Err(cx.err(
            "light.angle_deg",
            format!("must be a finite angle in (0, 90) degrees, got {a}"),
        ));
    }
    Ok(Light::directional(direction, a))
}

/// Checks that the light parameter `v` (at `key`) is a finite number > 0.
fn positive(cx: &Ctx<'_>, key: &str, v: f32) -> Result<f32> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(cx.err(key, format!("must be a finite number > 0, got {v}")))
    }
}

/// Validates a rect light's `size` and `tangent` (made orthogonal to `normal`).
fn rect_light(cx: &Ctx<'_>, l: &LightFile, normal: Vec3) -> Result<(LightShape, Vec3)> {
    if l.radius.is_some() {
        return Err(cx.err("light.radius", "not used by rect lights (use `size`)"));
    }
    let size = l
        .size
        .ok_or_else(|| cx.err("light.size", "missing (required for rect lights)"))?;
    let size = [
        positive(cx, "light.size", size[0])?,
        positive(cx, "light.size", size[1])?,
    ];
    let t = l
        .tangent
        .ok_or_else(|| cx.err("light.tangent", "missing (required for rect lights)"))?;
    let t = cx.unit("light.tangent", t)?;
    let ortho = t - t.dot(normal) * normal;
    let t = ortho
        .try_normalize()
        .filter(|_| ortho.length() > 1e-4)
        .ok_or_else(|| cx.err("light.tangent", "must not be parallel to light.normal"))?;
    Ok((LightShape::Rect { size }, t))
}

/// Validates a disk or sphere light's `radius` (no `size`, no `tangent`).
fn round_light(cx: &Ctx<'_>, l: &LightFile, normal: Vec3) -> Result<(LightShape, Vec3)> {
    for (k, present) in [
        ("light.size", l.size.is_some()),
        ("light.tangent", l.tangent.is_some()),
    ] {
        if present {
            return Err(cx.err(k, format!("not used by {} lights (use `radius`)", l.shape)));
        }
    }
    let r = l.radius.ok_or_else(|| {
        cx.err(
            "light.radius",
            format!("missing (required for {} lights)", l.shape),
        )
    })?;
    let r = positive(cx, "light.radius", r)?;
    let shape = if l.shape == "disk" {
        LightShape::Disk { radius: r }
    } else {
        LightShape::Sphere { radius: r }
    };
    Ok((shape, default_tangent(normal)))
}

/// Validates `[[mesh]]` entry `k` and loads its OBJ or glTF 2.0 file (`.gltf`, `.glb`; relative
/// to `dir`) into world space.
fn load_mesh(
    cx: &Ctx<'_>,
    dir: &Path,
    k: usize,
    m: &MeshFile,
) -> Result<(PathBuf, f32, Vec<[Vec3; 3]>)> {
    let key = |f: &str| format!("mesh[{k}].{f}");
    let scale = m.scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale != 0.0) {
        return Err(cx.err(
            &key("scale"),
            format!("must be finite and non-zero, got {scale}"),
        ));
    }
    let rot = m.rotate_y_deg.unwrap_or(0.0);
    if !rot.is_finite() {
        return Err(cx.err(&key("rotate_y_deg"), format!("must be finite, got {rot}")));
    }
    let translate = cx.vec3(&key("translate"), m.translate.unwrap_or([0.0; 3]))?;
    let opacity = m.opacity.unwrap_or(1.0);
    if !(0.0..=1.0).contains(&opacity) {
        return Err(cx.err(&key("opacity"), format!("must be in [0, 1], got {opacity}")));
    }
    let obj_path: PathBuf = dir.join(&m.path);
    let gltf = obj_path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
    let local = if gltf {
        super::gltf::load_gltf_triangles(&obj_path)?
    } else {
        super::obj::load_obj_triangles(&obj_path)?
    };
    let rotation = glam::Quat::from_rotation_y(rot.to_radians());
    let tris = local
        .into_iter()
        .map(|t| t.map(|v| rotation * (v * scale) + translate))
        .collect();
    Ok((obj_path, opacity, tris))
}
