//! Scenes shared by the tests: `test-support`'s fixtures with this crate's camera and light, and
//! stacks of semi-transparent sheets.
#![allow(dead_code, unused_imports)]
use glam::Vec3;
use shadow_map_core::{Camera, Light, Params, Receivers, Scene};
pub use test_support::fixtures::{
    check_contract, fixture, fixture_names, max_abs_diff, note, note_as, quad, rmse,
};

/// deep-shadow's parameter table with `kv` set; panics on a key or value it refuses (a test's
/// bug).
pub fn params(kv: &[(&str, &str)]) -> Params {
    test_support::fixtures::param_table(deep_shadow::settings::SPECS, kv)
}

/// The fixed scenes' camera, 8 x 8 pixels.
pub fn camera() -> Camera {
    test_support::fixtures::camera(8, 8)
}

/// An `l x l` rect light at height 3, pointing down.
pub fn rect_light(l: f32) -> Light {
    test_support::fixtures::rect_light(l, 3.0)
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

/// Beyond the light view's reach: a 0.5 x 0.5 rect light at height 1 pointing down,
/// a ground `[-100, 100]^2`, a semi-transparent sheet under the light and a wall (opacity 0.8)
/// at x = 20, 2 high. Receivers: one under the light, and one on the ground 40 away, 88.6
/// degrees off the light's axis (beyond `MAX_TAN`), on the wall's side (`walled`, shadowed) or
/// the open side.
pub fn beyond_reach(walled: bool) -> (Scene, Receivers) {
    let light = test_support::fixtures::rect_light(0.5, 1.0);
    let meshes = vec![
        (quad(-100.0, -100.0, 100.0, 100.0, 0.0), 1.0),
        (quad(-0.2, -0.2, 0.2, 0.2, 0.5), 0.5),
        (
            test_support::fixtures::cuboid(Vec3::new(20.0, 0.0, -5.0), Vec3::new(20.2, 2.0, 5.0)),
            0.8,
        ),
    ];
    let scene = Scene::from_meshes("beyond reach", camera(), light, meshes).unwrap();
    let far = if walled { 40.0 } else { -40.0 };
    let pos = vec![Vec3::new(0.05, 0.0, 0.03), Vec3::new(far, 0.0, 0.0)];
    (
        scene,
        Receivers::from_points(pos, vec![Vec3::Y; 2]).unwrap(),
    )
}
