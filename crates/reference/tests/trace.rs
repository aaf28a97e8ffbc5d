//! The ray tracer against the closed forms of docs/methods.md §9-§10, and the contract's rules
//! (one-sided lights, tangent plane, transmittance, empty scenes).
use glam::{Vec2, Vec3};
use proptest::{prelude::*, test_runner::FileFailurePersistence};
use reference::{
    disk_occluder_visibility, polygon_occluder_disk_visibility, rect_occluder_visibility,
    sphere_occluder_on_axis_visibility, visibility, RectOccluder, ReferenceEstimator, TraceOptions,
};
use shadow_map_core::{
    camera::Camera, run, Cancel, Light, LightFrame, LightShape, Receivers, Scene, SceneBvh,
    SoftShadowEstimator,
};

/// |V - oracle| allowed at 1024 samples per receiver (sampling noise only).
const TOL_1024: f64 = 0.01;

fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 4.0, 8.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 45.0,
        width: 64,
        height: 48,
    }
}

fn rect_light(size: [f32; 2], center: Vec3, normal: Vec3, tangent: Vec3) -> Light {
    let f = LightFrame::new(center, normal, tangent).expect("valid light frame");
    Light {
        shape: LightShape::Rect { size },
        center,
        normal: f.ez,
        tangent: f.ex,
    }
}

/// The standard test light: 1 x 1 at y = 3 pointing down, tangent +x. Its frame maps world
/// (x, y, z) to light space (x, z, 3 - y).
fn down_light() -> Light {
    rect_light([1.0, 1.0], Vec3::new(0.0, 3.0, 0.0), Vec3::NEG_Y, Vec3::X)
}

/// Two triangles covering the light-space rectangle `[min, max]` at depth z.
fn quad(frame: &LightFrame, min: Vec2, max: Vec2, z: f32) -> Vec<[Vec3; 3]> {
    let c = |x: f32, y: f32| frame.to_world(Vec3::new(x, y, z));
    let (a, b, cc, d) = (
        c(min.x, min.y),
        c(max.x, min.y),
        c(max.x, max.y),
        c(min.x, max.y),
    );
    vec![[a, b, cc], [a, cc, d]]
}

/// A planar polygon (fan) at light-space depth z.
fn polygon_mesh(frame: &LightFrame, poly: &[Vec2], z: f32) -> Vec<[Vec3; 3]> {
    let w = |v: Vec2| frame.to_world(v.extend(z));
    (1..poly.len() - 1)
        .map(|k| [w(poly[0]), w(poly[k]), w(poly[k + 1])])
        .collect()
}

fn ngon(center: Vec2, radius: f32, n: usize) -> Vec<Vec2> {
    (0..n)
        .map(|k| {
            let t = std::f32::consts::TAU * k as f32 / n as f32;
            center + radius * Vec2::new(t.cos(), t.sin())
        })
        .collect()
}

/// A far-away triangle, so that a scene "without occluders" still has geometry.
fn far_triangle() -> Vec<[Vec3; 3]> {
    vec![[
        Vec3::new(50.0, -20.0, 50.0),
        Vec3::new(51.0, -20.0, 50.0),
        Vec3::new(50.0, -20.0, 51.0),
    ]]
}

fn trace(scene: &Scene, receivers: &Receivers, opts: TraceOptions) -> Vec<f32> {
    let bvh = SceneBvh::new(scene);
    let mut v = vec![f32::NAN; receivers.len()];
    visibility(scene, &bvh, receivers, &opts, &mut v, false, &Cancel::new()).expect("trace");
    v
}

fn spp(samples: u32) -> TraceOptions {
    TraceOptions::from_spp(samples, 1)
}

/// Receivers on the ground y = 0, x in [-2, 2], a few z rows, facing up.
fn ground_receivers() -> Vec<Vec3> {
    let mut p = Vec::new();
    for &z in &[-0.9f32, -0.35, 0.1, 0.45, 0.8] {
        for i in 0..=40 {
            p.push(Vec3::new(-2.0 + 0.1 * i as f32, 0.0, z));
        }
    }
    p
}

/// Max and RMS of |V - oracle|.
fn errors(v: &[f32], oracle: &[f64]) -> (f64, f64) {
    let mut max = 0.0f64;
    let mut sq = 0.0f64;
    for (a, b) in v.iter().zip(oracle) {
        let e = (*a as f64 - b).abs();
        max = max.max(e);
        sq += e * e;
    }
    (max, (sq / v.len().max(1) as f64).sqrt())
}

/// Scene (a): the down light, an opaque rectangle occluder at y = 1.5, a ground plane at y = 0 on
/// which the receivers lie (so the ray offset is exercised too), plus optional extra occluders.
fn rect_scene(light: Light, occluders: &[RectOccluder], ground: bool) -> Scene {
    let f = light.frame();
    let mut meshes: Vec<(Vec<[Vec3; 3]>, f32)> = occluders
        .iter()
        .map(|o| (quad(&f, o.min, o.max, o.z), 1.0))
        .collect();
    if ground {
        let g = vec![
            [
                Vec3::new(-6.0, 0.0, -6.0),
                Vec3::new(6.0, 0.0, 6.0),
                Vec3::new(6.0, 0.0, -6.0),
            ],
            [
                Vec3::new(-6.0, 0.0, -6.0),
                Vec3::new(-6.0, 0.0, 6.0),
                Vec3::new(6.0, 0.0, 6.0),
            ],
        ];
        meshes.push((g, 1.0));
    }
    if meshes.is_empty() {
        meshes.push((far_triangle(), 1.0));
    }
    Scene::from_meshes("test", camera(), light, meshes).expect("scene")
}

/// The standard occluded scene: [`down_light`], one opaque rectangle occluder at light depth 1.5
/// and the ground plane.
fn occluded_scene() -> (Light, [RectOccluder; 1], Scene) {
    let light = down_light();
    let occ = [RectOccluder::new(
        Vec2::new(-0.4, -0.3),
        Vec2::new(0.6, 0.5),
        1.5,
    )];
    let scene = rect_scene(light, &occ, true);
    (light, occ, scene)
}

/// One polygon occluder (opaque) at light-space depth z of `frame` under `light`.
fn polygon_scene(name: &str, light: Light, frame: &LightFrame, poly: &[Vec2], z: f32) -> Scene {
    Scene::from_meshes(
        name,
        camera(),
        light,
        vec![(polygon_mesh(frame, poly, z), 1.0)],
    )
    .expect("scene")
}

/// Receivers at `pos`, all facing up (+y).
fn facing_up(pos: &[Vec3]) -> Receivers {
    Receivers::from_points(pos.to_vec(), vec![Vec3::Y; pos.len()]).expect("receivers")
}

/// The RMS error against `oracle` at 16, 64, 256 and 1024 spp, printed under `what`; asserts it
/// falls at every step and by more than 4 x from 16 to 1024 spp.
fn assert_error_falls(what: &str, scene: &Scene, r: &Receivers, oracle: &[f64]) {
    let mut rms = Vec::new();
    for n in [16u32, 64, 256, 1024] {
        let (_, e) = errors(&trace(scene, r, spp(n)), oracle);
        rms.push(e);
    }
    println!("{what} RMS error at 16/64/256/1024 spp: {rms:?}");
    assert!(rms.windows(2).all(|w| w[1] < w[0]), "{rms:?}");
    assert!(rms[3] < rms[0] / 4.0, "{rms:?}");
}

#[test]
fn a_rect_light_rect_occluder_matches_closed_form() {
    let (light, occ, scene) = occluded_scene();
    let pos = ground_receivers();
    let f = light.frame();
    let oracle: Vec<f64> = pos
        .iter()
        .map(|p| rect_occluder_visibility(Vec2::splat(0.5), &occ, f.to_light(*p)))
        .collect();
    // The line crosses umbra, penumbra and lit regions.
    assert!(oracle.contains(&0.0) && oracle.contains(&1.0));
    assert!(oracle.iter().filter(|&&o| o > 0.05 && o < 0.95).count() > 50);
    let r = facing_up(&pos);
    let v = trace(&scene, &r, spp(1024));
    let (max, rms) = errors(&v, &oracle);
    println!(
        "rect light / rect occluder, 1024 spp, {} receivers: max |dV| = {max:.5}, rms = {rms:.5}",
        v.len()
    );
    assert!(max <= TOL_1024, "max |dV| = {max}");
}

#[test]
fn a_tilted_rect_light_with_two_occluders_matches_closed_form() {
    // A light in a general orientation; occluders and receivers placed in its frame.
    let light = rect_light(
        [1.4, 0.8],
        Vec3::new(0.3, 4.0, -0.2),
        Vec3::new(0.3, -1.0, 0.2),
        Vec3::new(1.0, 0.2, 0.5),
    );
    let f = light.frame();
    let occ = [
        RectOccluder::new(Vec2::new(-0.5, -0.2), Vec2::new(0.3, 0.6), 1.2),
        RectOccluder::new(Vec2::new(0.0, -0.7), Vec2::new(0.9, 0.1), 2.0),
    ];
    let scene = rect_scene(light, &occ, false);
    let mut lp = Vec::new();
    for i in 0..=30 {
        for &y in &[-0.6f32, 0.0, 0.4] {
            lp.push(Vec3::new(
                -2.0 + 0.13 * i as f32,
                y + 0.01 * i as f32,
                3.0 + 0.02 * i as f32,
            ));
        }
    }
    let pos: Vec<Vec3> = lp.iter().map(|q| f.to_world(*q)).collect();
    let oracle: Vec<f64> = lp
        .iter()
        .map(|q| rect_occluder_visibility(Vec2::new(0.7, 0.4), &occ, *q))
        .collect();
    let r = Receivers::from_points(pos.clone(), vec![-f.ez; pos.len()]).expect("receivers");
    let v = trace(&scene, &r, spp(1024));
    let (max, rms) = errors(&v, &oracle);
    println!("tilted rect light / 2 occluders, 1024 spp, {} receivers: max |dV| = {max:.5}, rms = {rms:.5}", v.len());
    assert!(max <= TOL_1024, "max |dV| = {max}");
}

#[test]
fn b_disk_light_disk_occluder_matches_lens_formula() {
    let (r_l, r_o, z_o) = (0.6f32, 0.35f32, 1.5f32);
    let c_o = Vec2::new(0.1, -0.05);
    let light = Light {
        shape: LightShape::Disk { radius: r_l },
        center: Vec3::new(0.0, 3.0, 0.0),
        normal: Vec3::NEG_Y,
        tangent: shadow_map_core::light::default_tangent(Vec3::NEG_Y),
    };
    let f = light.frame();
    let poly = ngon(c_o, r_o, 64);
    let scene = polygon_scene("disk", light, &f, &poly, z_o);
    let pos = ground_receivers();
    let lp: Vec<Vec3> = pos.iter().map(|p| f.to_light(*p)).collect();
    let lens: Vec<f64> = lp
        .iter()
        .map(|q| disk_occluder_visibility(r_l, c_o, r_o, z_o, *q))
        .collect();
    let exact: Vec<f64> = lp
        .iter()
        .map(|q| polygon_occluder_disk_visibility(r_l, &poly, z_o, *q))
        .collect();
    // The 64-gon is inscribed in the disk: it misses the fraction 1 - 64 sin(2 pi/64) / (2 pi)
    // = 0.0016 of its area, so |V(64-gon) - V(disk)| <= 0.0016 (s r_o / R_L)^2 = 0.0022 here (s = 2).
    let bound = (1.0 - 64.0 * (std::f64::consts::TAU / 64.0).sin() / std::f64::consts::TAU)
        * (2.0 * r_o as f64 / r_l as f64).powi(2);
    let poly_err = exact
        .iter()
        .zip(&lens)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        poly_err <= bound + 1e-6,
        "polygon error {poly_err} above bound {bound}"
    );
    let r = facing_up(&pos);
    let v = trace(&scene, &r, spp(1024));
    let (max, rms) = errors(&v, &lens);
    let (max_poly, rms_poly) = errors(&v, &exact);
    println!(
        "disk light / 64-gon occluder, 1024 spp, {} receivers: vs lens formula max |dV| = {max:.5} \
         (rms {rms:.5}); vs exact 64-gon oracle max {max_poly:.5} (rms {rms_poly:.5}); \
         polygon approximation <= {bound:.5} (measured {poly_err:.5})",
        v.len()
    );
    assert!(max <= TOL_1024, "max |dV| = {max}");
    assert!(max_poly <= TOL_1024, "max |dV| = {max_poly}");
}

/// A UV sphere with vertices on the sphere of radius `r` (an inscribed polyhedron).
fn uv_sphere(center: Vec3, r: f32, seg: usize, rings: usize) -> Vec<[Vec3; 3]> {
    let v = |i: usize, j: usize| {
        let th = std::f32::consts::PI * j as f32 / rings as f32;
        let ph = std::f32::consts::TAU * i as f32 / seg as f32;
        center + r * Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
    };
    let mut t = Vec::new();
    for j in 0..rings {
        for i in 0..seg {
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
            if j > 0 {
                t.push([a, b, c]);
            }
            if j + 1 < rings {
                t.push([a, c, d]);
            }
        }
    }
    t
}

#[test]
fn sphere_light_on_axis_sphere_occluder_matches_closed_form() {
    let (r_l, rho) = (0.5f32, 0.2f32);
    let center = Vec3::new(0.0, 3.0, 0.0);
    let axis = Vec3::new(0.4, -1.0, 0.25).normalize();
    let occ_center = center + axis * 1.4;
    let light = Light {
        shape: LightShape::Sphere { radius: r_l },
        center,
        normal: Vec3::NEG_Y,
        tangent: shadow_map_core::light::default_tangent(Vec3::NEG_Y),
    };
    let scene = Scene::from_meshes(
        "sphere",
        camera(),
        light,
        vec![(uv_sphere(occ_center, rho, 256, 128), 1.0)],
    )
    .expect("scene");
    let mut pos = Vec::new();
    let mut oracle = Vec::new();
    for k in 0..40 {
        let d_l = 1.75 + 0.1 * k as f32;
        pos.push(center + axis * d_l);
        let o = sphere_occluder_on_axis_visibility(
            r_l as f64,
            d_l as f64,
            rho as f64,
            (d_l - 1.4) as f64,
        );
        oracle.push(o.expect("in the formula's domain"));
    }
    assert!(oracle.contains(&0.0) && oracle.iter().any(|&o| o > 0.5));
    let r = Receivers::from_points(pos.clone(), vec![-axis; pos.len()]).expect("receivers");
    let v = trace(&scene, &r, spp(1024));
    let (max, rms) = errors(&v, &oracle);
    // The 256 x 128 UV sphere's silhouette is within rho (1 - cos(pi/128)) = 3e-4 rho of the sphere's.
    println!(
        "sphere light / on-axis sphere occluder, 1024 spp: max |dV| = {max:.5}, rms = {rms:.5}"
    );
    assert!(max <= TOL_1024, "max |dV| = {max}");
}

#[test]
fn c_stacked_semi_transparent_sheets_multiply() {
    let light = down_light();
    let f = light.frame();
    let big = (Vec2::splat(-4.0), Vec2::splat(4.0));
    let ground = vec![[
        Vec3::new(-6.0, 0.0, -6.0),
        Vec3::new(6.0, 0.0, 6.0),
        Vec3::new(6.0, 0.0, -6.0),
    ]];
    let scene = Scene::from_meshes(
        "sheets",
        camera(),
        light,
        vec![
            (quad(&f, big.0, big.1, 2.0), 0.3), // world y = 1
            (quad(&f, big.0, big.1, 1.0), 0.5), // world y = 2
            (ground, 1.0),
        ],
    )
    .expect("scene");
    let pos: Vec<Vec3> = (0..25)
        .map(|k| Vec3::new(-1.0 + 0.08 * k as f32, 0.0, 0.5 - 0.04 * k as f32))
        .collect();
    let r = facing_up(&pos);
    let v = trace(&scene, &r, spp(1024));
    let want = 0.7 * 0.5;
    for (p, x) in pos.iter().zip(&v) {
        assert!(
            (*x as f64 - want).abs() <= 1e-5,
            "{p}: V = {x}, want {want}"
        );
    }
    // Between the sheets only the upper one (opacity 0.5) counts.
    let r =
        Receivers::from_points(vec![Vec3::new(0.1, 1.5, 0.2)], vec![Vec3::Y]).expect("receivers");
    let v = trace(&scene, &r, spp(256));
    assert!((v[0] - 0.5).abs() <= 1e-5, "V = {}", v[0]);
}

#[test]
fn d_one_sided_lights_give_zero_behind() {
    let scene = rect_scene(down_light(), &[], false);
    let pos = vec![
        Vec3::new(0.0, 4.0, 0.0),
        Vec3::new(2.0, 3.0, 0.0),
        Vec3::new(0.2, 3.5, 0.1),
    ];
    let normals = vec![Vec3::NEG_Y, Vec3::Y, Vec3::new(0.3, -1.0, 0.0)];
    let r = Receivers::from_points(pos, normals).expect("receivers");
    let v = trace(&scene, &r, spp(64));
    assert_eq!(v, vec![0.0, 0.0, 0.0]);
    // A disk light too; a sphere light is not one-sided.
    let mut light = down_light();
    light.shape = LightShape::Disk { radius: 0.5 };
    let scene = rect_scene(light, &[], false);
    assert_eq!(trace(&scene, &r, spp(64)), vec![0.0, 0.0, 0.0]);
    light.shape = LightShape::Sphere { radius: 0.5 };
    let scene = rect_scene(light, &[], false);
    let r = Receivers::from_points(vec![Vec3::new(0.0, 5.0, 0.0)], vec![Vec3::NEG_Y])
        .expect("receivers");
    assert_eq!(trace(&scene, &r, spp(64)), vec![1.0]);
}

#[test]
fn e_tangent_plane_blocks_the_far_half() {
    let scene = rect_scene(down_light(), &[], false);
    let r = Receivers::from_points(
        vec![Vec3::ZERO, Vec3::ZERO, Vec3::new(0.25, 0.0, 0.0)],
        vec![Vec3::X, Vec3::NEG_Z, Vec3::X],
    )
    .expect("receivers");
    let v = trace(&scene, &r, spp(1024));
    println!("tangent-plane halves: {v:?}");
    assert!((v[0] - 0.5).abs() < 1e-3, "V = {}", v[0]);
    assert!((v[1] - 0.5).abs() < 1e-3, "V = {}", v[1]);
    // The plane x = 0.25 leaves the strip x in (0.25, 0.5): a quarter.
    assert!((v[2] - 0.25).abs() < 1e-3, "V = {}", v[2]);
    // A receiver facing away from the light sees nothing of it.
    let r = Receivers::from_points(vec![Vec3::ZERO], vec![Vec3::NEG_Y]).expect("receivers");
    assert_eq!(trace(&scene, &r, spp(64)), vec![0.0]);
}

#[test]
fn f_no_occluders_gives_exactly_one() {
    let pos = vec![
        Vec3::ZERO,
        Vec3::new(3.0, -1.0, 2.0),
        Vec3::new(-0.2, 2.0, 0.1),
        Vec3::new(10.0, 0.0, 0.0),
    ];
    // Normals facing up, so the whole light (at y = 3) is in front of every tangent plane.
    let normals = vec![
        Vec3::Y,
        Vec3::new(-0.3, 1.0, -0.2),
        Vec3::Y,
        Vec3::new(-1.0, 0.5, 0.0),
    ];
    let r = Receivers::from_points(pos, normals).expect("receivers");
    for shape in [
        LightShape::Rect { size: [1.0, 2.0] },
        LightShape::Disk { radius: 0.7 },
        LightShape::Sphere { radius: 0.7 },
    ] {
        let mut light = down_light();
        light.shape = shape;
        let scene = rect_scene(light, &[], false);
        for s in [1, 16, 1024] {
            assert_eq!(
                trace(&scene, &r, spp(s)),
                vec![1.0; 4],
                "{shape:?}, {s} spp"
            );
        }
    }
}

#[test]
fn g_error_falls_with_sample_count() {
    let (light, occ, scene) = occluded_scene();
    // The penumbra of the occluder's +x edge (x from 0.7 to 1.7 on the ground).
    let pos: Vec<Vec3> = (0..200)
        .map(|k| Vec3::new(0.72 + 0.0048 * k as f32, 0.0, 0.05 + 0.001 * k as f32))
        .collect();
    let f = light.frame();
    let oracle: Vec<f64> = pos
        .iter()
        .map(|p| rect_occluder_visibility(Vec2::splat(0.5), &occ, f.to_light(*p)))
        .collect();
    assert!(oracle.iter().all(|&o| o > 0.0 && o < 1.0));
    let r = facing_up(&pos);
    assert_error_falls("penumbra", &scene, &r, &oracle);

    // The same for a curved edge (disk light, 64-gon occluder vs its exact oracle), where
    // multi-jittering helps less.
    let mut disk = down_light();
    disk.shape = LightShape::Disk { radius: 0.6 };
    let fd = disk.frame();
    let poly = ngon(Vec2::new(0.1, -0.05), 0.35, 64);
    let scene = polygon_scene("disk", disk, &fd, &poly, 1.5);
    let pos: Vec<Vec3> = (0..200)
        .map(|k| Vec3::new(0.45 + 0.005 * k as f32, 0.0, 0.3 - 0.002 * k as f32))
        .collect();
    let oracle: Vec<f64> = pos
        .iter()
        .map(|p| polygon_occluder_disk_visibility(0.6, &poly, 1.5, fd.to_light(*p)))
        .collect();
    let r = facing_up(&pos);
    assert_error_falls("disk penumbra", &scene, &r, &oracle);
}

#[test]
fn inactive_receivers_get_nan_and_lengths_are_checked() {
    let scene = rect_scene(down_light(), &[], false);
    let mut r = Receivers::from_points(vec![Vec3::ZERO; 3], vec![Vec3::Y; 3]).expect("receivers");
    r.active_mut()[1] = false;
    let v = trace(&scene, &r, spp(16));
    assert_eq!(v[0], 1.0);
    assert!(v[1].is_nan());
    assert_eq!(v[2], 1.0);
    let bvh = SceneBvh::new(&scene);
    let mut short = vec![0.0; 2];
    assert!(visibility(
        &scene,
        &bvh,
        &r,
        &spp(16),
        &mut short,
        false,
        &Cancel::new()
    )
    .is_err());
    let bad = TraceOptions {
        samples_per_side: 0,
        seed: 0,
    };
    let mut v = vec![0.0; 3];
    assert!(visibility(&scene, &bvh, &r, &bad, &mut v, false, &Cancel::new()).is_err());
}

#[test]
fn camera_receivers_are_finite_in_range_and_deterministic() {
    let (_, _, scene) = occluded_scene();
    let bvh = SceneBvh::new(&scene);
    let r = Receivers::from_camera(&scene, &bvh);
    assert!(r.active_count() > 0 && r.active_count() < r.len());
    let opts = spp(64);
    let mut a = vec![0.0; r.len()];
    let mut b = vec![0.0; r.len()];
    visibility(&scene, &bvh, &r, &opts, &mut a, false, &Cancel::new()).expect("trace");
    visibility(&scene, &bvh, &r, &opts, &mut b, false, &Cancel::new()).expect("trace");
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(x.to_bits(), y.to_bits(), "slot {k}");
        if r.active()[k] {
            assert!((0.0..=1.0).contains(x), "slot {k}: {x}");
        } else {
            assert!(x.is_nan());
        }
    }
    // Some ground pixels are in the umbra, some (and the occluder's top) fully lit.
    assert!(a.contains(&0.0));
    assert!(a.contains(&1.0));
}

#[test]
fn estimator_runs_reports_and_validates() {
    let (_, _, scene) = occluded_scene();
    let pos = ground_receivers();
    let r = facing_up(&pos);
    let mut est = ReferenceEstimator::new()
        .expect("defaults parse")
        .with_progress(false);
    assert_eq!(est.name(), "reference");
    assert_eq!(est.backend(), shadow_map_core::Backend::Cpu);
    assert_eq!(
        est.options(),
        TraceOptions {
            samples_per_side: 32,
            seed: 1
        }
    );
    est.set_param("spp", "1000").expect("spp");
    est.set_param("seed", "7").expect("seed");
    assert!(est.set_param("spp", "0").is_err());
    assert!(est.set_param("spp", "70000").is_err());
    assert!(est.set_param("seed", "-1").is_err());
    assert!(est.set_param("bogus", "1").is_err());
    let (v, report) = run(&mut est, &scene, &r).expect("run");
    let names: Vec<&str> = report.stages.iter().map(|s| s.0.as_str()).collect();
    assert_eq!(names, ["build", "estimate"]);
    let note = |k: &str| report.notes.iter().find(|n| n.0 == k).map(|n| n.1.clone());
    assert_eq!(note("spp").as_deref(), Some("1024"));
    assert_eq!(note("samples_per_side").as_deref(), Some("32"));
    assert_eq!(note("seed").as_deref(), Some("7"));
    // Same as the free function with the same options.
    let direct = trace(
        &scene,
        &r,
        TraceOptions {
            samples_per_side: 32,
            seed: 7,
        },
    );
    assert_eq!(v, direct);
    let mut short = vec![0.0; 3];
    assert!(est.estimate(&scene, &r, &mut short).is_err());
}

#[test]
fn disk_light_result_does_not_depend_on_tangent() {
    let r_l = 0.6f32;
    let occ = ngon(Vec2::new(0.1, -0.05), 0.35, 64);
    let mut out = Vec::new();
    for tangent in [Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0).normalize()] {
        let light = Light {
            shape: LightShape::Disk { radius: r_l },
            center: Vec3::new(0.0, 3.0, 0.0),
            normal: Vec3::NEG_Y,
            tangent,
        };
        // The occluder is fixed in world space (built in the +x tangent frame).
        let f0 = LightFrame::new(light.center, light.normal, Vec3::X).expect("frame");
        let scene = polygon_scene("t", light, &f0, &occ, 1.5);
        let pos = ground_receivers();
        let r = facing_up(&pos);
        out.push(trace(&scene, &r, spp(1024)));
    }
    let first: Vec<f64> = out[0].iter().map(|&x| x as f64).collect();
    let (max, _) = errors(&out[1], &first);
    let (max2, _) = errors(&out[2], &first);
    assert!(
        max <= 2.0 * TOL_1024 && max2 <= 2.0 * TOL_1024,
        "{max} {max2}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 24,
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource("regressions"))),
        ..ProptestConfig::default()
    })]

    /// Random rect lights, 1-3 random rect occluders, random receivers facing the light:
    /// V in [0, 1], never NaN, within 0.02 of the closed form at 1024 spp. Up to three occluders put
    /// up to 12 edges across the light; jittered sampling's error per edge is about 0.3 N^-3/4
    /// (docs/methods.md §6), so 0.02 is about four standard deviations for the worst case (at 256
    /// spp a run of this property once measured 0.021: the bound must hold at every seed).
    #[test]
    fn h_random_rect_configurations_match_closed_form(
        size in (0.3f32..2.0, 0.3f32..2.0),
        occ in prop::collection::vec(((-1.5f32..1.0, -1.5f32..1.0), (0.1f32..1.5, 0.1f32..1.5), 0.3f32..2.5), 1..=3),
        recv in prop::collection::vec((-2.5f32..2.5, -2.5f32..2.5, 2.6f32..4.5), 8),
        seed in 0u64..1000,
    ) {
        let light = rect_light([size.0, size.1], Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, Vec3::X);
        let f = light.frame();
        let occ: Vec<RectOccluder> = occ
            .iter()
            .map(|&((x, y), (w, h), z)| RectOccluder::new(Vec2::new(x, y), Vec2::new(x + w, y + h), z))
            .collect();
        let scene = rect_scene(light, &occ, false);
        let lp: Vec<Vec3> = recv.iter().map(|&(x, y, z)| Vec3::new(x, y, z)).collect();
        let pos: Vec<Vec3> = lp.iter().map(|q| f.to_world(*q)).collect();
        let r = Receivers::from_points(pos, vec![-f.ez; lp.len()]).expect("receivers");
        let v = trace(&scene, &r, TraceOptions::from_spp(1024, seed));
        for (q, x) in lp.iter().zip(&v) {
            prop_assert!(!x.is_nan() && (0.0..=1.0).contains(x), "{q}: {x}");
            let o = rect_occluder_visibility(Vec2::new(size.0, size.1) * 0.5, &occ, *q);
            prop_assert!((*x as f64 - o).abs() <= 2.0 * TOL_1024, "{q}: V = {x}, oracle {o}");
        }
    }
}

/// The sun (the contract's directional light) over a half plane: an opaque half plane
/// `x < 0` at height h = 1 over a ground, the sun overhead with a 3-degree disk, receivers across
/// the penumbra (`|x| <= 1.5 h tan(angle/2)`) and beyond. At 1024 samples per receiver the ray
/// tracer matches the circular-segment closed form to RMSE <= 0.002 (and every receiver within
/// [`TOL_1024`]), at 3 and 1 degrees (receivers spread over each penumbra);
/// a tilted ground facing away from half the sun's disk (the tangent-plane rule) sees half of it.
#[test]
fn e_sun_over_a_half_plane_matches_the_circular_segment() {
    for angle in [3.0f32, 1.0] {
        let light = Light::directional(Vec3::NEG_Y, angle);
        let t = (0.5 * angle as f64).to_radians().tan();
        let (h, big) = (1.0f32, 50.0f32);
        let occluder = vec![
            [
                Vec3::new(-big, h, -big),
                Vec3::new(0.0, h, big),
                Vec3::new(0.0, h, -big),
            ],
            [
                Vec3::new(-big, h, -big),
                Vec3::new(-big, h, big),
                Vec3::new(0.0, h, big),
            ],
        ];
        let ground = vec![
            [
                Vec3::new(-big, 0.0, -big),
                Vec3::new(-big, 0.0, big),
                Vec3::new(big, 0.0, big),
            ],
            [
                Vec3::new(-big, 0.0, -big),
                Vec3::new(big, 0.0, big),
                Vec3::new(big, 0.0, -big),
            ],
        ];
        let scene = Scene::from_meshes(
            "sun-half-plane",
            camera(),
            light,
            vec![(occluder, 1.0), (ground, 1.0)],
        )
        .expect("scene");
        let reach = 1.5 * h as f64 * t;
        let xs: Vec<f64> = (0..=60)
            .map(|i| -reach + 2.0 * reach * i as f64 / 60.0)
            .collect();
        let pos: Vec<Vec3> = xs.iter().map(|&x| Vec3::new(x as f32, 0.0, 0.3)).collect();
        let rec = facing_up(&pos);
        let v = trace(&scene, &rec, spp(1024));
        let oracle: Vec<f64> = xs
            .iter()
            .map(|&x| reference::half_plane_sun_visibility(x, h as f64, t))
            .collect();
        let (max, rmse) = errors(&v, &oracle);
        println!("sun {angle} deg over a half plane: RMSE {rmse:.5}, max {max:.5}");
        assert!(rmse <= 0.002, "{angle} deg: RMSE {rmse}");
        assert!(max <= TOL_1024, "{angle} deg: max {max}");
        // Deep in the umbra and fully lit beyond the penumbra.
        assert!(v[0] == 0.0 && v[60] == 1.0, "{} {}", v[0], v[60]);
    }
    // The tangent-plane rule: a receiver whose plane contains the sun's direction sees the half
    // of the disk in front of it (nothing else in the scene).
    let light = Light::directional(Vec3::NEG_Y, 2.0);
    let scene = Scene::from_meshes("sun-alone", camera(), light, vec![(far_triangle(), 1.0)])
        .expect("scene");
    let rec = Receivers::from_points(vec![Vec3::ZERO], vec![Vec3::X]).expect("receivers");
    let v = trace(&scene, &rec, spp(1024));
    assert!((v[0] - 0.5).abs() <= 0.02, "{}", v[0]);
    assert!(
        (scene.light().front_fraction_world(Vec3::ZERO, Vec3::X) - 0.5).abs() < 1e-6,
        "front fraction"
    );
}
