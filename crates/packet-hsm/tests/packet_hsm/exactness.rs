//! The heart of the crate: packets, the hierarchy and the coherence test change speed, never V.
//!
//! For random small scenes (a ground quad, random squares and tilted triangles, a random rect,
//! disk or sphere light), every packet size 1x1..8x8 times hierarchy on/off times coherence on/off gives the V of
//! per-pixel GBP07 with a flat scan of every kernel cell ([`reference_pixel`]).
//!
//! Tolerance: 1e-5 absolute. Every path integrates exactly the same edges with the same
//! arithmetic per edge (f64 on a rect, the core's f32 edge term on a disk and on each receiver's
//! sphere silhouette); only the order of the f64 sum over edges differs (and the f32 rounding of
//! the result). Measured maximum differences are printed.
use crate::common;
use common::*;
use glam::Vec3;
use packet_hsm::cpu::{estimate_sublight, reference_pixel, Counters, PixelDiag, SubView};
use packet_hsm::settings::{Config, PACKETS};
use proptest::prelude::*;
use shadow_map_core::{run, Cancel, Receivers, Scene, SceneBvh, SoftShadowEstimator};

const TOL: f32 = 1e-5;

/// Asserts `|got - want| <= TOL` at every active receiver of `rec`, `what` naming the case in a
/// failure; returns the largest difference.
fn assert_active_within_tol(what: &str, rec: &Receivers, got: &[f32], want: &[f32]) -> f32 {
    let mut worst = 0.0f32;
    for k in (0..rec.len()).filter(|&k| rec.active()[k]) {
        let d = (got[k] - want[k]).abs();
        worst = worst.max(d);
        assert!(d <= TOL, "{what} receiver {k}: {} vs {}", got[k], want[k]);
    }
    worst
}

/// Steps 5-8 of the CPU twin for the one sub-light `sv` with weight 1: V, the diagnostics and
/// the counters.
fn one_sublight(
    sv: &SubView,
    cfg: &Config,
    rec: &Receivers,
) -> (Vec<f32>, Vec<PixelDiag>, Counters) {
    let mut acc = vec![0.0f32; rec.len()];
    let mut diag = vec![PixelDiag::default(); rec.len()];
    let counters = Counters::default();
    let cancel = Cancel::new();
    estimate_sublight(sv, cfg, rec, 1.0, &mut acc, &mut diag, &counters, &cancel).unwrap();
    (acc, diag, counters)
}

fn random_scene(
    light: f32,
    height: f32,
    squares: &[(f32, f32, f32, f32)],
    tris: &[[f32; 9]],
    shape: u8,
) -> Scene {
    // A fixed square so every scene has a penumbra for packets to work on.
    let mut meshes = vec![
        (quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0),
        (quad(SQUARE.0, SQUARE.1, SQUARE.2, SQUARE.3, SQUARE.4), 1.0),
    ];
    for &(x, z, s, y) in squares {
        meshes.push((quad(x, z, x + s, z + s, y), 1.0));
    }
    for t in tris {
        meshes.push((
            vec![[
                Vec3::new(t[0], t[1], t[2]),
                Vec3::new(t[3], t[4], t[5]),
                Vec3::new(t[6], t[7], t[8]),
            ]],
            1.0,
        ));
    }
    let l = light_of_shape(shape, light, height);
    Scene::from_meshes("random", camera(24, 18), l, meshes).unwrap()
}

fn check_all_combinations(scene: &Scene, res: u32, self_shadow: &str) -> f32 {
    let bvh = SceneBvh::new(scene);
    let rec = Receivers::from_camera(scene, &bvh);
    let base = hsm(&[("self_shadow", self_shadow)]);
    let cfg0 = Config::from_params(base.params()).unwrap();
    let sv = SubView::build(
        scene,
        &rec,
        (res, glam::Vec2::ZERO, scene.light().half_extent()),
        &cfg0,
        packet_hsm::cpu::OwnPlane::Always,
    )
    .unwrap();
    let reference: Vec<f32> = (0..rec.len())
        .map(|k| {
            if rec.active()[k] {
                reference_pixel(&sv, &cfg0, rec.position()[k], rec.normal()[k])
            } else {
                0.0
            }
        })
        .collect();
    let mut worst = 0.0f32;
    let mut packet_evals = 0u64;
    for p in PACKETS {
        for hierarchy in [false, true] {
            for coherence in [false, true] {
                let e = hsm(&[
                    ("packet", p),
                    ("hierarchy", &hierarchy.to_string()),
                    ("coherence", &coherence.to_string()),
                    ("self_shadow", self_shadow),
                ]);
                let cfg = Config::from_params(e.params()).unwrap();
                let (acc, _, counters) = one_sublight(&sv, &cfg, &rec);
                packet_evals += counters.coherent.load(std::sync::atomic::Ordering::Relaxed);
                let what = format!("packet {p} hierarchy {hierarchy} coherence {coherence}");
                worst = worst.max(assert_active_within_tol(&what, &rec, &acc, &reference));
            }
        }
    }
    // The scenes must exercise the packet path at all.
    assert!(packet_evals > 0, "no coherent packet in any combination");
    worst
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10, .. ProptestConfig::default() })]
    #[test]
    fn every_combination_equals_per_pixel_gbp07(
        light in 0.5f32..2.0,
        height in 2.5f32..4.0,
        squares in prop::collection::vec((-1.5f32..1.0, -1.5f32..1.0, 0.2f32..1.0, 0.05f32..2.0), 0..4),
        tris in prop::collection::vec(prop::array::uniform9(-1.5f32..1.5), 0..3),
        res in prop::sample::select(vec![32u32, 64, 96]),
        bias in any::<bool>(),
        shape in 0u8..3,
    ) {
        let tris: Vec<[f32; 9]> = tris
            .into_iter()
            .map(|mut t| {
                for k in [1, 4, 7] {
                    t[k] = (t[k] + 1.5) * 0.7 + 0.05; // heights 0.05..2.15
                }
                t
            })
            .collect();
        let s = random_scene(light, height, &squares, &tris, shape);
        let worst = check_all_combinations(&s, res, if bias { "bias" } else { "midpoint" });
        eprintln!("exactness (shape {shape}): worst |dV| {worst:e}");
    }
}

/// Through the estimator trait, with sub-lights: every packet and switch gives the V of packet
/// 1x1 with a flat scan (same tolerance).
#[test]
fn trait_level_combinations_agree() {
    let s = scene_with(
        rect_light(1.2, 3.0),
        &[
            SQUARE,
            (0.7, -1.0, 1.3, -0.2, 0.6),
            (-1.4, 0.2, -0.8, 0.9, 2.2),
        ],
        32,
        24,
    );
    let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
    for sl in ["1", "2"] {
        let base = run(
            &mut hsm(&[
                ("resolution", "96"),
                ("sublights", sl),
                ("packet", "1x1"),
                ("hierarchy", "false"),
            ]),
            &s,
            &rec,
        )
        .unwrap()
        .0;
        for p in ["2x2", "3x3", "4x4", "8x8", "5x2"] {
            for h in ["true", "false"] {
                let mut e = hsm(&[
                    ("resolution", "96"),
                    ("sublights", sl),
                    ("packet", p),
                    ("hierarchy", h),
                ]);
                let (v, rep) = run(&mut e, &s, &rec).unwrap();
                assert_active_within_tol(&format!("S={sl} {p} {h}"), &rec, &v, &base);
                for (k, x) in v.iter().enumerate() {
                    assert!(rec.active()[k] || x.is_nan(), "S={sl} {p} {h} {k}: {x}");
                }
                assert!(rep.notes.iter().any(|n| n.0 == "packets_coherent"));
            }
        }
    }
}

/// Receivers without an image layout are processed pixel-wise: same V, no packet.
#[test]
fn point_receivers_go_pixel_wise() {
    let s = scene_with(rect_light(1.0, 3.0), &[SQUARE], 8, 8);
    let r = line_receivers();
    let (v1, _) = run(
        &mut hsm(&[("resolution", "128"), ("packet", "1x1")]),
        &s,
        &r,
    )
    .unwrap();
    let mut e = hsm(&[("resolution", "128"), ("packet", "4x4")]);
    let (v4, rep) = run(&mut e, &s, &r).unwrap();
    assert_eq!(v1, v4);
    let packets = rep.notes.iter().find(|n| n.0 == "packets").unwrap();
    assert_eq!(packets.1, "0");
    assert!(e
        .diagnostics()
        .iter()
        .all(|d| d.class != packet_hsm::cpu::CLASS_PACKET));
}

/// Own-plane pruning (`packet_hsm::fit`, docs/methods.md §4) on a ground lit 5 degrees above its
/// plane with thin posts (the grazing-posts kind): with the bounds, the hierarchy gives the V of
/// the flat scan and of the hierarchy without them, and visits well under half their nodes.
#[test]
fn own_plane_pruning_is_exact_and_prunes_a_grazing_ground() {
    let t = 5.0f32.to_radians();
    let normal = Vec3::new(0.0, -t.sin(), t.cos());
    let light = shadow_map_core::Light {
        shape: shadow_map_core::LightShape::Rect { size: [1.0, 1.0] },
        center: -normal * 8.0,
        normal,
        tangent: Vec3::X,
    };
    let mut meshes = vec![(quad(-3.0, -3.0, 3.0, 3.0, 0.0), 1.0)];
    for (x, z) in [(-1.5f32, -1.0f32), (0.4, -0.3), (1.2, 0.9)] {
        meshes.push((
            test_support::fixtures::cuboid(
                Vec3::new(x - 0.03, 0.0, z - 0.03),
                Vec3::new(x + 0.03, 0.8, z + 0.03),
            ),
            1.0,
        ));
    }
    let scene = Scene::from_meshes("grazing", camera(48, 36), light, meshes).unwrap();
    let bvh = SceneBvh::new(&scene);
    let rec = Receivers::from_camera(&scene, &bvh);
    let run_with = |hierarchy: bool, own_plane: bool| {
        let e = hsm(&[("hierarchy", &hierarchy.to_string())]);
        let cfg = Config::from_params(e.params()).unwrap();
        let sv = SubView::build(
            &scene,
            &rec,
            (512, glam::Vec2::ZERO, scene.light().half_extent()),
            &cfg,
            if own_plane {
                packet_hsm::cpu::OwnPlane::Always
            } else {
                packet_hsm::cpu::OwnPlane::Off
            },
        )
        .unwrap();
        assert_eq!(sv.fit.is_some(), own_plane);
        let (acc, _, counters) = one_sublight(&sv, &cfg, &rec);
        let visited = counters.visited.load(std::sync::atomic::Ordering::Relaxed);
        (acc, visited)
    };
    let (flat, _) = run_with(false, false);
    let (without, n_without) = run_with(true, false);
    let (with, n_with) = run_with(true, true);
    assert_active_within_tol("own-plane pruning against flat", &rec, &with, &flat);
    assert_active_within_tol("own-plane pruning against none", &rec, &with, &without);
    eprintln!("own-plane pruning: {n_without} -> {n_with} nodes");
    assert!(
        2 * n_with < n_without,
        "own-plane pruning visited {n_with} nodes, {n_without} without"
    );
}
