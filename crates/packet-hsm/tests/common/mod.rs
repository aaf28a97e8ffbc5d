//! Scenes shared by the integration tests: a ground quad, square occluders, a rect light.
#![allow(dead_code)]
use glam::{Vec2, Vec3};
use packet_hsm::CpuPacketHsm;
use reference::oracle::{rect_occluder_visibility, RectOccluder};
use shadow_map_core::{Camera, Light, LightShape, Receivers, Scene, SoftShadowEstimator};

pub fn camera(w: u32, h: u32) -> Camera {
    Camera {
        eye: Vec3::new(0.0, 4.0, 5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: w,
        height: h,
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

pub fn rect_light(l: f32, height: f32) -> Light {
    Light {
        shape: LightShape::Rect { size: [l, l] },
        center: Vec3::new(0.0, height, 0.0),
        normal: -Vec3::Y,
        tangent: Vec3::X,
    }
}

/// Square occluders as `(x0, z0, x1, z1, height)`.
pub type Occ = (f32, f32, f32, f32, f32);

pub const SQUARE: Occ = (-0.5, -0.5, 0.5123, 0.5, 1.5);

pub fn scene_with(light: Light, occ: &[Occ], w: u32, h: u32) -> Scene {
    let mut meshes = vec![(quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0)];
    for o in occ {
        meshes.push((quad(o.0, o.1, o.2, o.3, o.4), 1.0));
    }
    Scene::from_meshes("test", camera(w, h), light, meshes).unwrap()
}

/// Ground receivers on a line through the umbra, penumbra and lit region.
pub fn line_receivers() -> Receivers {
    let pos: Vec<Vec3> = (0..241)
        .map(|k| Vec3::new(-1.5 + k as f32 * 0.0125, 0.0, 0.13))
        .collect();
    Receivers::from_points(pos.clone(), vec![Vec3::Y; pos.len()]).unwrap()
}

pub fn oracle(scene: &Scene, occ: &[Occ], r: &Receivers) -> Vec<f64> {
    let f = scene.light.frame();
    let occs: Vec<RectOccluder> = occ
        .iter()
        .map(|o| {
            let c = [Vec3::new(o.0, o.4, o.1), Vec3::new(o.2, o.4, o.3)].map(|c| f.to_light(c));
            let (a, b) = (Vec2::new(c[0].x, c[0].y), Vec2::new(c[1].x, c[1].y));
            RectOccluder {
                min: a.min(b),
                max: a.max(b),
                z: c[0].z,
            }
        })
        .collect();
    r.position
        .iter()
        .map(|p| rect_occluder_visibility(scene.light.half_extent(), &occs, f.to_light(*p)))
        .collect()
}

pub fn hsm(kv: &[(&str, &str)]) -> CpuPacketHsm {
    let mut e = CpuPacketHsm::new().unwrap();
    for (k, v) in kv {
        e.set_param(k, v).unwrap();
    }
    e
}

pub fn errors(v: &[f32], o: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = v
        .iter()
        .zip(o)
        .map(|(a, b)| (*a as f64 - b).abs())
        .collect();
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    (rms, d.iter().cloned().fold(0.0, f64::max))
}

pub fn assert_valid(v: &[f32], what: &str) {
    for (k, x) in v.iter().enumerate() {
        assert!(
            x.is_finite() && (0.0..=1.0).contains(x),
            "{what}: V[{k}] = {x}"
        );
    }
}
