//! Scenes shared by the tests.
#![allow(dead_code)]
use glam::Vec3;
use shadow_map_core::{Camera, Light, LightShape, Receivers, Scene, SceneBvh};

pub fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 4.0, 5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: 8,
        height: 8,
    }
}

/// A horizontal quad at height y, facing up (+y).
pub fn quad(x0: f32, z0: f32, x1: f32, z1: f32, y: f32) -> Vec<[Vec3; 3]> {
    let (a, b, c, d) = (
        Vec3::new(x0, y, z0),
        Vec3::new(x0, y, z1),
        Vec3::new(x1, y, z1),
        Vec3::new(x1, y, z0),
    );
    vec![[a, b, c], [a, c, d]]
}

pub fn rect_light(l: f32) -> Light {
    Light {
        shape: LightShape::Rect { size: [l, l] },
        center: Vec3::new(0.0, 3.0, 0.0),
        normal: -Vec3::Y,
        tangent: Vec3::X,
    }
}

/// k sheets `[-1, 1]^2` at heights 1.0, 1.1, ... with the given opacities, over an opaque ground.
pub fn sheets(alphas: &[f32], l: f32) -> Scene {
    let mut meshes = vec![(quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0)];
    for (k, &a) in alphas.iter().enumerate() {
        meshes.push((quad(-1.0, -1.0, 1.0, 1.0, 1.0 + 0.1 * k as f32), a));
    }
    Scene::from_meshes("sheets", camera(), rect_light(l), meshes).unwrap()
}

/// Receivers on a grid of the square `[-h, h]^2` at height y, facing up.
pub fn grid(h: f32, y: f32, n: usize) -> Receivers {
    let mut pos = Vec::new();
    for a in 0..n {
        for b in 0..n {
            let s = |k: usize| -h + 2.0 * h * (k as f32 + 0.5) / n as f32;
            pos.push(Vec3::new(s(a), y, s(b)));
        }
    }
    Receivers::from_points(pos.clone(), vec![Vec3::Y; pos.len()]).unwrap()
}

pub fn fixture(name: &str, w: u32, h: u32) -> (Scene, Receivers) {
    let path = format!(
        "{}/../../fixtures/{name}/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut scene = Scene::load(path).unwrap();
    scene.camera.width = w;
    scene.camera.height = h;
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    (scene, rec)
}

pub fn rmse(a: &[f32], b: &[f32], active: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for k in 0..a.len() {
        if active[k] {
            let d = a[k] as f64 - b[k] as f64;
            s += d * d;
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// Every active V in [0, 1], finite; inactive NaN.
pub fn check_contract(v: &[f32], r: &Receivers) {
    for (k, x) in v.iter().enumerate() {
        if r.active[k] {
            assert!(
                x.is_finite() && (0.0..=1.0).contains(x),
                "receiver {k}: V = {x}"
            );
        } else {
            assert!(x.is_nan(), "inactive receiver {k}: V = {x}");
        }
    }
}
