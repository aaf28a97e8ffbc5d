#![allow(clippy::needless_range_loop)] // texel loops read clearer with indices
//! The CPU shadow-map core: fill rule, orientation, perspective-correct linear depth, bias,
//! culling, peeling, midpoints and the light-view fit.
use crate::common;

use common::{quad_uv, unit_light, unit_view};
use glam::{Vec2, Vec3};
use proptest::prelude::*;
use shadow_map_core::{
    light_view::LightView,
    peeling::{midpoint, midpoints, peel},
    raster::{PreparedScene, PEEL_EPS_REL},
    Camera, Cull, DepthBias, Light, LightShape, Receivers, Scene,
};

fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 5.0, 5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: 8,
        height: 8,
    }
}

/// A scene of the one triangle `(a, b, c)`.
fn triangle_scene(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Scene {
    scene(vec![vec![[a, b, c].map(Vec3::from)]])
}

fn scene(meshes: Vec<Vec<[Vec3; 3]>>) -> Scene {
    Scene::from_meshes(
        "test",
        camera(),
        unit_light(),
        meshes.into_iter().map(|m| (m, 1.0)).collect(),
    )
    .unwrap()
}

fn quad(x0: f32, y0: f32, x1: f32, y1: f32, z: f32) -> Vec<[Vec3; 3]> {
    let (a, b, c, d) = (
        Vec3::new(x0, y0, z),
        Vec3::new(x1, y0, z),
        Vec3::new(x1, y1, z),
        Vec3::new(x0, y1, z),
    );
    // Winding with normal -z: facing the light at the origin.
    vec![[a, c, b], [a, d, c]]
}

fn covered(s: &Scene, view: &LightView) -> Vec<bool> {
    PreparedScene::new(s, view, Cull::None)
        .rasterize(DepthBias::default(), None)
        .depth
        .iter()
        .map(|d| d.is_finite())
        .collect()
}

#[test]
fn off_centre_triangle_orientation() {
    // A small triangle at x in [5, 7], y in [1, 2]: texels with u along +x, v along +y.
    let s = triangle_scene([5.0, 1.0, 1.0], [7.0, 1.0, 1.0], [5.0, 2.0, 1.0]);
    let cov = covered(&s, &unit_view(8));
    let set: Vec<(usize, usize)> = (0..64)
        .filter(|k| cov[*k])
        .map(|k| (k % 8, k / 8))
        .collect();
    // Centres (5.5, 1.5) inside (x + 2y <= 9 at the hypotenuse: 5.5 + 2*1.5*... ) only.
    assert_eq!(set, vec![(5, 1)]);
}

#[test]
fn shared_edge_centres_are_covered_exactly_once() {
    // A quad split along its diagonal, whose centres (i + 0.5, i + 0.5) lie exactly on the shared
    // edge: every texel inside must be covered by exactly one of the two triangles.
    let q = quad(0.0, 0.0, 8.0, 8.0, 1.0);
    for order in [[0usize, 1], [1, 0]] {
        let view = unit_view(8);
        let a = covered(&scene(vec![vec![q[order[0]]]]), &view);
        let b = covered(&scene(vec![vec![q[order[1]]]]), &view);
        for k in 0..64 {
            assert!(
                a[k] ^ b[k],
                "texel {k} covered {} times",
                a[k] as u8 + b[k] as u8
            );
        }
    }
    // Two quads sharing a vertical edge at x = 4 (centres never on it), and a horizontal one at
    // y = 4: no gap, no overlap.
    let view = unit_view(8);
    let l = covered(&scene(vec![quad(0.0, 0.0, 4.0, 8.0, 1.0)]), &view);
    let r = covered(&scene(vec![quad(4.0, 0.0, 8.0, 8.0, 1.0)]), &view);
    assert!((0..64).all(|k| l[k] ^ r[k]));
}

#[test]
fn top_left_rule_on_texel_aligned_edges() {
    // Edges through texel centres: x = 2.5 .. 5.5, y = 2.5 .. 5.5. The left and top (v smaller)
    // edges own their centres, the right and bottom do not: columns 2..=4, rows 2..=4.
    let s = scene(vec![quad(2.5, 2.5, 5.5, 5.5, 1.0)]);
    let cov = covered(&s, &unit_view(8));
    for k in 0..64 {
        let (i, j) = (k % 8, k / 8);
        assert_eq!(
            cov[k],
            (2..=4).contains(&i) && (2..=4).contains(&j),
            "texel ({i},{j})"
        );
    }
}

#[test]
fn depth_is_linear_light_space_z_perspective_correct() {
    // A plane tilted in x: z = 2 + 0.5 x. The depth at each texel centre must be the z where the
    // centre's ray meets the plane (not an affine interpolation of z).
    let tri = [
        Vec3::new(-1.0, -1.0, 1.5),
        Vec3::new(6.0, -1.0, 5.0),
        Vec3::new(-1.0, 6.0, 1.5),
    ];
    let s = scene(vec![vec![tri, [tri[1], Vec3::new(6.0, 6.0, 5.0), tri[2]]]]);
    let view = unit_view(8);
    let d = PreparedScene::new(&s, &view, Cull::None).rasterize(DepthBias::default(), None);
    for j in 0..8 {
        for i in 0..8 {
            let dir = view.unproject_dir(Vec2::new(i as f32 + 0.5, j as f32 + 0.5));
            // Ray t*dir with dir.z = 1: t = 2 + 0.5 t dir.x => t = 2 / (1 - 0.5 dir.x).
            let z = 2.0 / (1.0 - 0.5 * dir.x);
            let got = d.depth[j * 8 + i];
            let x = z * dir.x;
            let y = z * dir.y;
            if x > -1.0 && x < 6.0 && y > -1.0 && y < 6.0 {
                assert!((got - z).abs() <= 1e-5 * z, "texel ({i},{j}): {got} vs {z}");
            }
        }
    }
}

#[test]
fn near_plane_clipping_keeps_the_far_part() {
    // A triangle crossing z = n = 1: only the part at z >= 1 is recorded, never a depth below n.
    let s = triangle_scene([0.0, 0.0, 0.5], [8.0, 0.0, 3.0], [0.0, 8.0, 3.0]);
    let d = PreparedScene::new(&s, &unit_view(8), Cull::None).rasterize(DepthBias::default(), None);
    assert!(d
        .depth
        .iter()
        .filter(|z| z.is_finite())
        .all(|&z| z >= 1.0 - 1e-6));
    assert!(d.depth.iter().any(|z| z.is_finite()));
}

#[test]
fn slope_scaled_bias() {
    let flat = scene(vec![quad_uv(0.0, 0.0, 8.0, 8.0, 2.0)]);
    let view = unit_view(8);
    let p = PreparedScene::new(&flat, &view, Cull::None);
    let d0 = p.rasterize(DepthBias::default(), None);
    let d1 = p.rasterize(bias(0.25, 10.0), None);
    // Fronto-parallel: zero slope, only the constant.
    for (a, b) in d0.depth.iter().zip(&d1.depth) {
        assert!((b - a - 0.25).abs() < 1e-6);
    }
    // Tilted: the slope term adds more where |dz/du| is larger.
    let tri = [
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::new(8.0, 0.0, 6.0),
        Vec3::new(0.0, 8.0, 2.0),
    ];
    let tilted = scene(vec![vec![tri]]);
    let p = PreparedScene::new(&tilted, &view, Cull::None);
    let a = p.rasterize(DepthBias::default(), None);
    let b = p.rasterize(bias(0.0, 1.0), None);
    let k = 0;
    assert!(
        b.depth[k] > a.depth[k] + 0.1,
        "{} vs {}",
        b.depth[k],
        a.depth[k]
    );
}

#[test]
fn face_culling_uses_winding_as_seen_from_the_light() {
    let facing = scene(vec![quad(0.0, 0.0, 8.0, 8.0, 2.0)]);
    let away: Vec<[Vec3; 3]> = quad(0.0, 0.0, 8.0, 8.0, 3.0)
        .into_iter()
        .map(|[a, b, c]| [a, c, b])
        .collect();
    let away = scene(vec![away]);
    let view = unit_view(8);
    let count = |s: &Scene, c: Cull| PreparedScene::new(s, &view, c).len();
    assert_eq!(count(&facing, Cull::Back), 2);
    assert_eq!(count(&facing, Cull::Front), 0);
    assert_eq!(count(&away, Cull::Back), 0);
    assert_eq!(count(&away, Cull::Front), 2);
    assert_eq!(count(&away, Cull::None), 2);
}

#[test]
fn peeling_returns_layers_nearest_first_and_merges_coincident_surfaces() {
    let s = scene(vec![
        quad_uv(0.0, 0.0, 8.0, 8.0, 4.0),
        quad_uv(0.0, 0.0, 8.0, 8.0, 2.0),
        quad_uv(0.0, 0.0, 4.0, 8.0, 3.0),
        quad_uv(0.0, 0.0, 8.0, 8.0, 2.0 * (1.0 + 0.1 * PEEL_EPS_REL)), // z-fighting twin of z = 2
    ]);
    let p = PreparedScene::new(&s, &unit_view(8), Cull::None);
    let layers = peel(&p, DepthBias::default(), 4);
    assert_eq!(layers.len(), 4);
    for j in 0..8 {
        for i in 0..8 {
            let k = j * 8 + i;
            let expect: [f32; 4] = if i < 4 {
                [2.0, 3.0, 4.0, f32::INFINITY]
            } else {
                [2.0, 4.0, f32::INFINITY, f32::INFINITY]
            };
            for m in 0..4 {
                let got = layers[m].depth[k];
                assert!(
                    got == expect[m] || (got - expect[m]).abs() < 1e-5,
                    "({i},{j}) layer {m}: {got} vs {}",
                    expect[m]
                );
            }
        }
    }
    let mids = midpoints(&layers, 0.6);
    assert_eq!(mids.len(), 3);
    assert!((mids[0].depth[0] - 2.5).abs() < 1e-5); // (2 + 3) / 2
    assert!((mids[0].depth[7] - 2.6).abs() < 1e-5); // min((2 + 4)/2, 2 + 0.6)
    assert!((mids[1].depth[7] - 4.6).abs() < 1e-5); // lone surface: 4 + max bias
    assert!(mids[2].depth[7].is_infinite());
    assert_eq!(midpoint(f32::INFINITY, 3.0, 1.0), f32::INFINITY);
}

fn ground_scene(light: Light) -> Scene {
    let g = vec![
        [
            Vec3::new(-4.0, 0.0, -4.0),
            Vec3::new(-4.0, 0.0, 4.0),
            Vec3::new(4.0, 0.0, 4.0),
        ],
        [
            Vec3::new(-4.0, 0.0, -4.0),
            Vec3::new(4.0, 0.0, 4.0),
            Vec3::new(4.0, 0.0, -4.0),
        ],
    ];
    let occ = vec![
        [
            Vec3::new(-0.5, 1.0, -0.5),
            Vec3::new(0.5, 1.0, 0.5),
            Vec3::new(-0.5, 1.0, 0.5),
        ],
        [
            Vec3::new(-0.5, 1.0, -0.5),
            Vec3::new(0.5, 1.0, -0.5),
            Vec3::new(0.5, 1.0, 0.5),
        ],
    ];
    Scene::from_meshes("ground", camera(), light, vec![(g, 1.0), (occ, 1.0)]).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// The fitted window contains every receiver's projection plus the light's footprint on the
    /// near plane (what an area light needs), and n lies at or below every triangle that can
    /// shadow a receiver.
    #[test]
    fn fit_covers_every_receiver_footprint(
        pts in prop::collection::vec((-3.0f32..3.0, -3.0f32..3.0), 1..40),
        lx in 0.01f32..3.0, ly in 0.01f32..3.0, h in 1.5f32..6.0, r in 1u32..600,
    ) {
        let light = Light { shape: LightShape::Rect { size: [lx, ly] }, center: Vec3::new(0.2, h, -0.1), normal: -Vec3::Y, tangent: Vec3::X };
        let s = ground_scene(light);
        let pos: Vec<Vec3> = pts.iter().map(|&(x, z)| Vec3::new(x, 0.0, z)).collect();
        let rec = Receivers::from_points(pos.clone(), vec![Vec3::Y; pos.len()]).unwrap();
        let frame = light.frame();
        let (view, rep) = LightView::fit(&s, &rec, frame, light.half_extent(), r).unwrap();
        prop_assert_eq!(rep.behind + rep.out_of_frustum, 0);
        for p in &pos {
            let q = frame.to_light(*p);
            let f = light.half_extent() * (1.0 - view.n / q.z);
            let c = Vec2::new(q.x, q.y) * (view.n / q.z);
            for corner in [c - f, c + f] {
                let uv = (corner - view.window_min) / view.delta();
                // f32 rounding of plane coordinates, in texels (tiny windows far off-axis).
                let tol = 1e-3 + 8.0 * f32::EPSILON * corner.abs().max_element() / view.delta();
                prop_assert!(uv.x >= -tol && uv.y >= -tol && uv.x <= r as f32 + tol && uv.y <= r as f32 + tol, "{uv} outside 0..{r}");
            }
        }
        // Where the occluder (the square [-0.5, 0.5]^2 at height 1, light-space z = h - 1) meets
        // some receiver's pyramid to the light, it can shadow that receiver and n must not
        // exceed it (geometry between no receiver and the light may be clipped).
        let s_occ = (h - 1.0) / h; // fraction of the way from the light to the ground
        let meets = pos.iter().any(|p| {
            let c = light.center;
            let (ax, az) = (0.5 * lx * (1.0 - s_occ), 0.5 * ly * (1.0 - s_occ));
            let (mx, mz) = (c.x + s_occ * (p.x - c.x), c.z + s_occ * (p.z - c.z));
            mx - ax < 0.5 && mx + ax > -0.5 && mz - az < 0.5 && mz + az > -0.5
        });
        if meets {
            prop_assert!(view.n <= (h - 1.0) * 1.0001, "n = {} above the occluder at {}", view.n, h - 1.0);
        }
        prop_assert!(view.n > 0.0 && view.far >= h - 1e-3);
    }
}

/// A depth bias of `constant` plus `slope` times the depth slope.
fn bias(constant: f32, slope: f32) -> DepthBias {
    DepthBias { constant, slope }
}

#[test]
fn opacity_is_the_nearest_fragments_meshs() {
    // A semi-transparent quad (opacity 0.4) at z = 2 over u in [0, 4), v in [0, 8), in front of
    // an opaque one at z = 4 over u in [0, 6), v in [0, 4); 8 x 8 texels.
    let s = Scene::from_meshes(
        "opacity",
        camera(),
        unit_light(),
        vec![
            (quad(0.0, 0.0, 8.0, 16.0, 2.0), 0.4),
            (quad(0.0, 0.0, 24.0, 16.0, 4.0), 1.0),
        ],
    )
    .unwrap();
    let p = PreparedScene::new(&s, &unit_view(8), Cull::None);
    let plain = p.rasterize(DepthBias::default(), None);
    let (d, a) = p.rasterize_with_opacity(DepthBias::default(), None);
    assert_eq!(d, plain, "the depths do not depend on asking for opacity");
    let (d1, a1) = p.rasterize_with_opacity(DepthBias::default(), Some(&d));
    for j in 0..8 {
        for i in 0..8 {
            let k = j * 8 + i;
            let want = if i < 4 {
                0.4
            } else if i < 6 && j < 4 {
                1.0
            } else {
                0.0
            };
            assert_eq!(a[k], want, "layer 0, texel ({i},{j})");
            assert_eq!(a[k] > 0.0, d.depth[k].is_finite());
            // Behind the first layer: the opaque quad where it lies under the sheet.
            let want1 = if i < 4 && j < 4 { 1.0 } else { 0.0 };
            assert_eq!(a1[k], want1, "layer 1, texel ({i},{j})");
            assert_eq!(a1[k] > 0.0, d1.depth[k].is_finite());
        }
    }
}
