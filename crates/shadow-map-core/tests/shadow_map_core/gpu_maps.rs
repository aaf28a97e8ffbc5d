//! GPU twins of the shadow-map core against the CPU: peeled layers, midpoints, the MSSM family,
//! depth-map and receiver transfers, chunked builds and limits.
//!
//! Every test takes the shared context from `context_for_tests`: without a Vulkan adapter it
//! prints `SKIPPED (no Vulkan adapter): <test>` and returns, and under
//! `SOFTSHADOW_REQUIRE_GPU=1` it fails instead.
//!
//! **Tolerance of the layer comparison.** A GPU texel matches the CPU when both are empty (+inf)
//! or both are finite within [`DEPTH_REL_TOL`] relative plus the depth change across
//! [`SNAP_TEXELS`] of a texel (the local CPU depth gradient times 1/16: the GPU snaps vertices to
//! its sub-pixel grid, at least 1/16 texel by Vulkan's minimum `subPixelPrecisionBits`, which
//! shifts a triangle's depth plane by up to 1/22.6 texel of its gradient, and that matters on
//! steep triangles, whose depth changes fast across a texel). The rasterisers differ only in
//! arithmetic (f32 with snapped vertices on the GPU, f64 on the CPU), so a texel may differ
//! beyond that only where it *straddles*: its centre lies within one texel of a projected triangle
//! edge (coverage can flip), or its GPU depth is a depth the CPU found at that texel or a
//! neighbour in some layer (near-coincident surfaces, e.g. along an intersection line, peeled in
//! a different order). Every mismatch must straddle, and straddling mismatches must stay below
//! [`STRADDLE_BOUND`] of the covered texels (plus [`STRADDLE_SLACK`] texels per case, for tiny
//! maps, plus the length of every triangle seen almost edge-on, narrower than a texel, whose
//! every texel may flip: see `edge_mask`). Measured fractions are printed.
#![cfg(feature = "gpu")]
#![allow(clippy::needless_range_loop)] // texel loops read clearer with indices

use crate::common;

use common::{quad_uv, unit_light, unit_view};
use glam::{DVec2, DVec3, Vec3};
use proptest::prelude::*;
use proptest::test_runner::{Config, FileFailurePersistence, TestRunner};
use shadow_map_core::{
    gpu::{GpuContext, GpuScene, GpuShadowMapper},
    light_view::{FitReport, LightView},
    mssm::{DualMssm, MinMaxPyramid, Mssm},
    peeling::midpoint,
    Camera, Cull, DepthBias, DepthMap, Error, Light, LightFrame, LightShape, LightSpace,
    LightSpaceRequest, RasterOptions, Receivers, Scene,
};
use std::sync::{Arc, Mutex, OnceLock};

mod transfers;

type TestResult = Result<(), Box<dyn std::error::Error>>;

/// Relative depth tolerance of GPU vs CPU layers (f32 perspective interpolation vs f64).
const DEPTH_REL_TOL: f32 = 1e-5;
/// Texels of depth change allowed for the GPU's vertex snapping (see the module docs): Vulkan
/// guarantees only `subPixelPrecisionBits >= 4`, vertices on a 1/16 texel grid, so rounding moves
/// each by up to 1/32 texel per axis and the depth plane, at any point inside the triangle, by at
/// most its gradient times sqrt(2)/32 = 1/22.6 texel (the shift is a barycentric blend of the
/// vertices' shifts). Measured on lavapipe: up to 1/75 texel on a large tilted triangle.
const SNAP_TEXELS: f32 = 1.0 / 16.0;
/// Largest fraction of covered texels that may straddle (differ at an edge).
const STRADDLE_BOUND: f64 = 0.02;
/// Absolute slack in straddling texels per case (maps as small as 8x8).
const STRADDLE_SLACK: usize = 2;

/// The shared context and the mapper of the whole binary.
type Gpu = (Arc<GpuContext>, Arc<GpuShadowMapper>);

/// The shared context and one mapper for the whole binary, or `None` after a loud skip.
fn gpu(test: &str) -> Result<Option<Gpu>, Error> {
    static MAPPER: OnceLock<Result<Arc<GpuShadowMapper>, String>> = OnceLock::new();
    common::gpu_with(test, &MAPPER, "test mapper", GpuShadowMapper::new)
}

fn proptest_config(default_cases: u32) -> Config {
    let cases = std::env::var("SOFTSHADOW_PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default_cases);
    Config {
        cases,
        source_file: Some(file!()),
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource(
            "proptest-regressions",
        ))),
        ..Config::default()
    }
}

fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 6.0, 8.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: 8,
        height: 8,
    }
}

fn rect_light(center: Vec3, normal: Vec3, size: [f32; 2]) -> Light {
    let frame = LightFrame::new(center, normal, Vec3::X).expect("valid light frame");
    Light {
        shape: LightShape::Rect { size },
        center,
        normal: frame.ez,
        tangent: frame.ex,
    }
}

fn scene_of(light: Light, tris: Vec<[Vec3; 3]>) -> Result<Scene, Error> {
    Scene::from_meshes("gpu-test", camera(), light, vec![(tris, 1.0)])
}

fn cpu_and_gpu(
    ctx: &GpuContext,
    mapper: &GpuShadowMapper,
    scene: &Scene,
    view: LightView,
    req: &LightSpaceRequest,
) -> Result<(LightSpace, LightSpace), Error> {
    let cpu = LightSpace::build_in_view(scene, view, FitReport::default(), req);
    let gscene = GpuScene::upload(ctx, scene)?;
    let gpu = mapper
        .render_layers(ctx, &gscene, &view, req)?
        .to_cpu(ctx)?;
    Ok((cpu, gpu))
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The GPU's `(min, max)` level planes against the CPU's `cpu(l)`, bit for bit; `what` names
/// the structure in the failure.
fn same_level_bits<'a>(
    what: &str,
    gpu: &[(Vec<f32>, Vec<f32>)],
    cpu: impl Fn(u32) -> (&'a [f32], &'a [f32]),
) -> Result<(), TestCaseError> {
    for (l, (mn, mx)) in gpu.iter().enumerate() {
        let (cmn, cmx) = cpu(l as u32);
        prop_assert!(
            same_bits(mn, cmn) && same_bits(mx, cmx),
            "{} level {}",
            what,
            l
        );
    }
    Ok(())
}

fn close(a: f32, b: f32) -> bool {
    (a.is_infinite() && b.is_infinite() && a.signum() == b.signum())
        || (a.is_finite() && b.is_finite() && (a - b).abs() <= DEPTH_REL_TOL * a.abs().max(b.abs()))
}

#[test]
fn empty_texels_are_infinite_and_quad_matches_cpu_exactly() -> TestResult {
    let Some((ctx, mapper)) = gpu("empty_texels_are_infinite_and_quad_matches_cpu_exactly")? else {
        return Ok(());
    };
    // Quad edges on texel centres (ties: top-left rule) and between centres.
    let mut tris = quad_uv(2.5, 1.5, 9.5, 6.0, 3.0);
    tris.extend(quad_uv(10.25, 8.0, 14.75, 13.5, 2.0));
    let scene = scene_of(unit_light(), tris)?;
    let req = LightSpaceRequest::single(16);
    let (cpu, gpu) = cpu_and_gpu(&ctx, &mapper, &scene, unit_view(16), &req)?;
    let (c, g) = (&cpu.layers[0].depth, &gpu.layers[0].depth);
    assert!(g.iter().any(|d| d.is_infinite()) && g.iter().any(|d| d.is_finite()));
    for k in 0..c.len() {
        assert!(close(c[k], g[k]), "texel {k}: cpu {} gpu {}", c[k], g[k]);
    }
    // An empty scene region is exactly +inf, not a large finite clear value.
    assert_eq!(g[15 * 16].to_bits(), f32::INFINITY.to_bits());
    Ok(())
}

#[test]
fn culling_matches_cpu_through_the_framebuffer_flip() -> TestResult {
    let Some((ctx, mapper)) = gpu("culling_matches_cpu_through_the_framebuffer_flip")? else {
        return Ok(());
    };
    let facing = quad_uv(1.0, 1.0, 7.0, 7.0, 2.0);
    let away: Vec<[Vec3; 3]> = facing.iter().map(|t| [t[0], t[2], t[1]]).collect();
    for (name, tris, facing_light) in [("facing", facing, true), ("away", away, false)] {
        let scene = scene_of(unit_light(), tris)?;
        for cull in [Cull::None, Cull::Back, Cull::Front] {
            let mut req = LightSpaceRequest::single(8);
            req.raster.cull = cull;
            let (cpu, gpu) = cpu_and_gpu(&ctx, &mapper, &scene, unit_view(8), &req)?;
            let covered = |d: &DepthMap| d.depth.iter().filter(|z| z.is_finite()).count();
            let expect = match cull {
                Cull::None => true,
                Cull::Back => facing_light,
                Cull::Front => !facing_light,
            };
            assert_eq!(covered(&cpu.layers[0]) > 0, expect, "cpu {name} {cull:?}");
            assert_eq!(
                covered(&gpu.layers[0]),
                covered(&cpu.layers[0]),
                "gpu {name} {cull:?}"
            );
        }
    }
    Ok(())
}

#[test]
fn near_plane_clip_and_bias_match_cpu() -> TestResult {
    let Some((ctx, mapper)) = gpu("near_plane_clip_and_bias_match_cpu")? else {
        return Ok(());
    };
    // A slanted triangle crossing z = n (and z = 0): clipped at the near plane on both sides.
    let tri = [
        Vec3::new(-2.0, -2.0, -1.0),
        Vec3::new(100.0, 20.0, 4.0),
        Vec3::new(20.0, 100.0, 3.5),
    ];
    let scene = scene_of(unit_light(), vec![tri])?;
    for bias in [
        DepthBias::default(),
        DepthBias {
            constant: 0.01,
            slope: 0.5,
        },
    ] {
        let mut req = LightSpaceRequest::single(32);
        req.raster.bias = bias;
        let (cpu, gpu) = cpu_and_gpu(&ctx, &mapper, &scene, unit_view(32), &req)?;
        let view = unit_view(32);
        let (edges, _) = edge_mask(&scene, &view);
        let (c, g) = (&cpu.layers[0].depth, &gpu.layers[0].depth);
        let mut off_edge = 0;
        for k in 0..c.len() {
            if !close(c[k], g[k]) && !edges[k] {
                off_edge += 1;
                eprintln!("texel {k}: cpu {} gpu {}", c[k], g[k]);
            }
        }
        assert_eq!(off_edge, 0, "bias {bias:?}");
        assert!(c.iter().filter(|z| z.is_finite()).count() > 50);
    }
    Ok(())
}

/// Texels whose centre lies within about one texel of a projected (near-clipped) triangle edge,
/// and the sliver allowance: the summed length in texels (plus 2 each) of the projected triangles
/// narrower than a texel (twice the area over the longest side below 1). Such a triangle, seen
/// almost edge-on from the light, covers texels only by sub-texel positions, so the GPU's vertex
/// snapping may flip every texel along it.
fn edge_mask(scene: &Scene, view: &LightView) -> (Vec<bool>, usize) {
    let r = view.r as i64;
    let n = view.n as f64;
    let delta = view.delta() as f64;
    let x0 = DVec2::new(view.window_min.x as f64, view.window_min.y as f64);
    let mut mask = vec![false; (r * r) as usize];
    let mut sliver = 0usize;
    let mut mark = |p: DVec2| {
        let (i, j) = (p.x.floor() as i64, p.y.floor() as i64);
        for dj in -1..=1 {
            for di in -1..=1 {
                let (a, b) = (i + di, j + dj);
                if a >= 0 && b >= 0 && a < r && b < r {
                    mask[(b * r + a) as usize] = true;
                }
            }
        }
    };
    for t in scene.triangles() {
        let l: Vec<DVec3> = t
            .iter()
            .map(|v| view.frame.to_light(*v).as_dvec3())
            .collect();
        let mut poly = Vec::new();
        for k in 0..3 {
            let (a, b) = (l[k], l[(k + 1) % 3]);
            if a.z >= n {
                poly.push(a);
            }
            if (a.z >= n) != (b.z >= n) {
                let s = (n - a.z) / (b.z - a.z);
                let mut p = a + (b - a) * s;
                p.z = n;
                poly.push(p);
            }
        }
        let uv: Vec<DVec2> = poly
            .iter()
            .map(|p| (DVec2::new(p.x, p.y) * (n / p.z) - x0) / delta)
            .collect();
        if uv.len() >= 3 {
            let m = uv.len();
            let twice: f64 = (0..m).map(|k| uv[k].perp_dot(uv[(k + 1) % m])).sum();
            let longest = (0..m)
                .map(|k| (uv[(k + 1) % m] - uv[k]).length())
                .fold(0.0f64, f64::max);
            if longest > 0.0 && twice.abs() / longest < 1.0 {
                sliver += longest.min(4.0 * r as f64).ceil() as usize + 2;
            }
        }
        for k in 0..uv.len() {
            let (mut p, mut q) = (uv[k], uv[(k + 1) % uv.len()]);
            // Clip the segment to the map plus a margin (Liang-Barsky) before walking it.
            let (lo, hi) = (-2.0, r as f64 + 2.0);
            let d = q - p;
            let (mut t0, mut t1) = (0.0f64, 1.0f64);
            let mut inside = true;
            for (pk, qk) in [
                (-d.x, p.x - lo),
                (d.x, hi - p.x),
                (-d.y, p.y - lo),
                (d.y, hi - p.y),
            ] {
                if pk == 0.0 {
                    if qk < 0.0 {
                        inside = false;
                    }
                } else {
                    let t = qk / pk;
                    if pk < 0.0 {
                        t0 = t0.max(t);
                    } else {
                        t1 = t1.min(t);
                    }
                }
            }
            if !inside || t0 > t1 {
                continue;
            }
            (p, q) = (p + d * t0, p + d * t1);
            let steps = ((q - p).length() * 4.0).ceil() as usize + 1;
            for s in 0..=steps {
                mark(p + (q - p) * (s as f64 / steps as f64));
            }
        }
    }
    (mask, sliver)
}

/// Per-case comparison counts.
#[derive(Debug, Default, Clone, Copy)]
struct Counts {
    compared: usize,
    covered: usize,
    mismatched: usize,
    at_edges: usize,
    near_surface: usize,
    /// Texels within tolerance only thanks to the snapping term (grazing triangles).
    grazing: usize,
}

/// Local depth gradient of a CPU layer at texel (i, j), in depth per texel: per axis the smaller
/// one-sided difference to a finite neighbour (so a depth discontinuity on one side does not
/// count), the larger of the two axes.
fn cpu_gradient(l: &DepthMap, i: i32, j: i32) -> f32 {
    let a = l.at(i, j);
    let axis = |d: [(i32, i32); 2]| {
        d.iter()
            .map(|&(di, dj)| l.at(i + di, j + dj))
            .filter(|z| z.is_finite())
            .map(|z| (z - a).abs())
            .fold(f32::INFINITY, f32::min)
    };
    let g = axis([(-1, 0), (1, 0)]).max(axis([(0, -1), (0, 1)]));
    if g.is_finite() {
        g
    } else {
        // No finite neighbour on some axis: a one-texel sliver, which lies at an edge anyway.
        0.0
    }
}

/// Compares GPU layers with CPU layers (see the module docs); `cpu_all` holds every CPU layer
/// (including the extra ones), for the near-surface explanation.
fn compare_layers(
    cpu: &[DepthMap],
    gpu: &[DepthMap],
    cpu_all: &[DepthMap],
    edges: &[bool],
    what: &str,
) -> Result<Counts, TestCaseError> {
    let mut c = Counts::default();
    prop_assert_eq!(cpu.len(), gpu.len(), "{} count", what);
    for (m, (cl, gl)) in cpu.iter().zip(gpu).enumerate() {
        let r = cl.size as i32;
        prop_assert_eq!(cl.size, gl.size);
        for j in 0..r {
            for i in 0..r {
                let k = (j * r + i) as usize;
                let (a, b) = (cl.depth[k], gl.depth[k]);
                c.compared += 1;
                c.covered += usize::from(a.is_finite());
                if close(a, b) {
                    continue;
                }
                if a.is_finite()
                    && b.is_finite()
                    && (a - b).abs()
                        <= DEPTH_REL_TOL * a.abs().max(b.abs())
                            + SNAP_TEXELS * cpu_gradient(cl, i, j)
                {
                    c.grazing += 1;
                    continue;
                }
                c.mismatched += 1;
                if edges[k] {
                    c.at_edges += 1;
                    continue;
                }
                let near = cpu_all
                    .iter()
                    .any(|l| (-1..=1).any(|dj| (-1..=1).any(|di| close(l.at(i + di, j + dj), b))));
                prop_assert!(
                    near,
                    "{} layer {} texel ({}, {}): cpu {} gpu {} (CPU gradient {} per texel) is \
                     neither at an edge nor a nearby CPU surface",
                    what,
                    m,
                    i,
                    j,
                    a,
                    b,
                    cpu_gradient(cl, i, j)
                );
                c.near_surface += 1;
            }
        }
    }
    Ok(c)
}

/// A random scene: a ground quad, boxes (some sunk into the ground), loose triangles, a rect
/// light of random size and tilt above, receivers on the ground, and a random request.
#[derive(Debug, Clone)]
struct Case {
    light: Light,
    tris: Vec<[Vec3; 3]>,
    receivers: Vec<Vec3>,
    req: LightSpaceRequest,
}

fn box_tris(c: Vec3, h: Vec3, angle: f32) -> Vec<[Vec3; 3]> {
    let rot = glam::Quat::from_rotation_y(angle);
    let p = |x: f32, y: f32, z: f32| c + rot * (Vec3::new(x, y, z) * h);
    let mut out = Vec::new();
    // Each face as two triangles with an outward winding normal.
    for axis in 0..3 {
        for s in [-1.0f32, 1.0] {
            let corner = |a: f32, b: f32| match axis {
                0 => p(s, a, b),
                1 => p(b, s, a),
                _ => p(a, b, s),
            };
            let (q0, q1, q2, q3) = (
                corner(-1.0, -1.0),
                corner(1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, 1.0),
            );
            let mut t = [[q0, q1, q2], [q0, q2, q3]];
            let centre = (q0 + q2) * 0.5;
            let nrm = (q1 - q0).cross(q2 - q0);
            if nrm.dot(centre - c) < 0.0 {
                for tri in &mut t {
                    tri.swap(1, 2);
                }
            }
            out.extend(t);
        }
    }
    out
}

fn arb_case() -> impl Strategy<Value = Case> {
    let v3 = |lo: f32, hi: f32, ylo: f32, yhi: f32| (lo..hi, ylo..yhi, lo..hi);
    (
        (
            v3(-1.5, 1.5, 4.0, 8.0),
            (-0.3f32..0.3, -0.3f32..0.3),
            (0.05f32..3.0, 0.05f32..3.0),
        ),
        prop::collection::vec(
            (
                v3(-2.0, 2.0, -0.3, 2.5),
                v3(0.1, 1.0, 0.1, 1.0),
                0.0f32..std::f32::consts::PI,
            ),
            0..4,
        ),
        prop::collection::vec(
            (
                v3(-3.0, 3.0, 0.1, 3.5),
                v3(-3.0, 3.0, 0.1, 3.5),
                v3(-3.0, 3.0, 0.1, 3.5),
            ),
            0..6,
        ),
        prop::collection::vec((-4.0f32..4.0, -4.0f32..4.0), 2..10),
        (
            8u32..=128,
            1u32..=3,
            prop::option::of(0.01f32..1.0),
            0u8..3,
            prop::option::of((0.0f32..0.05, 0.0f32..2.0)),
            prop::option::of(0u32..8),
            prop::option::of(0u32..8),
            any::<bool>(),
        ),
    )
        .prop_map(|(light, boxes, loose, recv, req)| {
            let ((lx, ly, lz), (tx, tz), (sx, sy)) = light;
            let light = rect_light(
                Vec3::new(lx, ly, lz),
                Vec3::new(tx, -1.0, tz).normalize(),
                [sx, sy],
            );
            let g = 6.0;
            let (a, b, c, d) = (
                Vec3::new(-g, 0.0, -g),
                Vec3::new(g, 0.0, -g),
                Vec3::new(g, 0.0, g),
                Vec3::new(-g, 0.0, g),
            );
            // Ground facing up (+y), towards the light.
            let mut tris = vec![[a, c, b], [a, d, c]];
            for ((cx, cy, cz), (hx, hy, hz), ang) in boxes {
                tris.extend(box_tris(Vec3::new(cx, cy, cz), Vec3::new(hx, hy, hz), ang));
            }
            for (p, q, r) in loose {
                tris.push([p.into(), q.into(), r.into()]);
            }
            let receivers = recv
                .into_iter()
                .map(|(x, z)| Vec3::new(x, 0.0, z))
                .collect();
            let (res, layers, mids, cull, bias, mssm, dual, pyramid) = req;
            let req = LightSpaceRequest {
                resolution: res,
                layers,
                midpoints: mids,
                mssm_levels: mssm,
                dual_mssm_levels: dual,
                pyramid,
                raster: RasterOptions {
                    bias: bias.map_or(DepthBias::default(), |(constant, slope)| DepthBias {
                        constant,
                        slope,
                    }),
                    cull: [Cull::None, Cull::Back, Cull::Front][cull as usize],
                },
                opacity: false,
            };
            Case {
                light,
                tris,
                receivers,
                req,
            }
        })
}

#[test]
fn gpu_layers_and_midpoints_match_cpu_on_random_scenes() -> TestResult {
    let Some((ctx, mapper)) = gpu("gpu_layers_and_midpoints_match_cpu_on_random_scenes")? else {
        return Ok(());
    };
    let totals = Mutex::new((Counts::default(), 0usize, 0.0f64));
    let mut runner = TestRunner::new(proptest_config(24));
    let result = runner.run(&arb_case(), |case| {
        let fail = |e: Error| TestCaseError::fail(e.to_string());
        let scene = scene_of(case.light, case.tris.clone()).map_err(fail)?;
        let normals = vec![Vec3::Y; case.receivers.len()];
        let receivers = Receivers::from_points(case.receivers.clone(), normals).map_err(fail)?;
        let Ok((view, fit)) = LightView::fit(
            &scene,
            &receivers,
            scene.light().frame(),
            scene.light().half_extent(),
            case.req.resolution,
        ) else {
            return Ok(());
        };
        let req = case.req;
        let k = req.layers.max(1);
        // The CPU with every layer the midpoints need, for the near-surface explanation.
        let all_req = LightSpaceRequest {
            layers: k + 1,
            midpoints: None,
            ..req
        };
        let cpu = LightSpace::build_in_view(&scene, view, fit, &req);
        let cpu_all = LightSpace::build_in_view(&scene, view, fit, &all_req);
        let gscene = GpuScene::upload(&ctx, &scene).map_err(fail)?;
        let gls = mapper
            .render_layers(&ctx, &gscene, &view, &req)
            .map_err(fail)?;
        prop_assert_eq!(gls.bytes(), cpu.bytes());
        let gpu = gls.to_cpu(&ctx).map_err(fail)?;
        let gpu_all = mapper
            .render_layers(&ctx, &gscene, &view, &all_req)
            .map_err(fail)?
            .to_cpu(&ctx)
            .map_err(fail)?;
        let (edges, sliver) = edge_mask(&scene, &view);

        // Layers 0..k against the CPU.
        let counts = compare_layers(&cpu.layers, &gpu.layers, &cpu_all.layers, &edges, "layer")?;
        // The GPU is deterministic: the same layers with or without the extra one.
        for m in 0..k as usize {
            prop_assert!(same_bits(&gpu.layers[m].depth, &gpu_all.layers[m].depth));
        }
        // Midpoints: the compute pass is the CPU formula bit for bit on the GPU's own layers,
        // and within the layer tolerance of the CPU's midpoints away from straddles.
        if let Some(max_bias) = req.midpoints {
            prop_assert_eq!(gpu.midpoints.len(), k as usize);
            for m in 0..k as usize {
                let (a, b) = (&gpu_all.layers[m].depth, &gpu_all.layers[m + 1].depth);
                let want: Vec<f32> = a
                    .iter()
                    .zip(b)
                    .map(|(&x, &y)| midpoint(x, y, max_bias))
                    .collect();
                prop_assert!(same_bits(&gpu.midpoints[m].depth, &want), "midpoint {}", m);
                let (cm, gm) = (&cpu.midpoints[m].depth, &gpu.midpoints[m].depth);
                for t in 0..cm.len() {
                    let straddle = !close(cpu_all.layers[m].depth[t], a[t])
                        || !close(cpu_all.layers[m + 1].depth[t], b[t]);
                    prop_assert!(
                        straddle || close(cm[t], gm[t]),
                        "midpoint {} texel {}: cpu {} gpu {}",
                        m,
                        t,
                        cm[t],
                        gm[t]
                    );
                }
            }
        }
        // The MSSM family of the GPU's layer 0, bit-identical to the CPU's build over it.
        let l0 = &gpu.layers[0];
        if let (Some(g), Some(levels)) = (&gls.mssm, req.mssm_levels) {
            let c = Mssm::build(&l0.depth, l0.size, levels);
            prop_assert_eq!(g.levels(), c.levels());
            same_level_bits("mssm", &g.read_levels(&ctx).map_err(fail)?, |l| c.level(l))?;
        }
        if let (Some(g), Some(levels)) = (&gls.dual_mssm, req.dual_mssm_levels) {
            let c = DualMssm::build(&l0.depth, l0.size, levels);
            prop_assert_eq!(g.levels(), c.levels());
            same_level_bits("dual", &g.read_levels(&ctx).map_err(fail)?, |l| c.level(l))?;
        }
        if let Some(g) = &gls.pyramid {
            let c = MinMaxPyramid::build(&l0.depth, l0.size);
            prop_assert_eq!(g.levels(), c.levels());
            same_level_bits("pyramid", &g.read_levels(&ctx).map_err(fail)?, |l| {
                c.level(l)
            })?;
        }

        let straddles = counts.mismatched;
        let bound = (STRADDLE_BOUND * counts.covered as f64) as usize
            + STRADDLE_SLACK
            + sliver * k as usize;
        prop_assert!(
            straddles <= bound,
            "{} straddling texels of {} covered (bound {}): {:?}",
            straddles,
            counts.covered,
            bound,
            counts
        );
        let frac = straddles as f64 / counts.covered.max(1) as f64;
        if let Ok(mut t) = totals.lock() {
            t.0.compared += counts.compared;
            t.0.covered += counts.covered;
            t.0.mismatched += counts.mismatched;
            t.0.at_edges += counts.at_edges;
            t.0.near_surface += counts.near_surface;
            t.0.grazing += counts.grazing;
            t.1 += 1;
            if counts.covered >= 1000 {
                t.2 = t.2.max(frac);
            }
        }
        Ok(())
    });
    let (t, cases, worst) = *totals.lock().map_err(|e| e.to_string())?;
    eprintln!(
        "GPU vs CPU layers over {cases} scenes: {} texels compared, {} covered, {} straddling \
         ({:.4}% of covered; {} at edges, {} near-coincident surfaces); worst case with >= 1000 covered {:.4}%; \
         {} grazing texels matched only with the snapping term",
        t.compared,
        t.covered,
        t.mismatched,
        100.0 * t.mismatched as f64 / t.covered.max(1) as f64,
        t.at_edges,
        t.near_surface,
        100.0 * worst,
        t.grazing
    );
    result.map_err(|e| e.to_string())?;
    assert!(cases > 0, "no case ran");
    Ok(())
}

/// A frame told to build fewer MSSM levels than it was prepared for (`LayersSlot::mssm_levels`)
/// hands out those levels alone, each bit for bit the CPU's over the same layer; told nothing
/// again, it hands out every level. Told to build the min planes only (`mssm_max: false`, what
/// backprojection's and accumulation's frames do), its min planes are still the CPU's.
#[test]
fn a_frame_building_fewer_mssm_levels_hands_out_only_those() -> TestResult {
    let Some((ctx, mapper)) = gpu("a_frame_building_fewer_mssm_levels_hands_out_only_those")?
    else {
        return Ok(());
    };
    use shadow_map_core::gpu::LayersSlot;
    let mut tris = quad_uv(2.5, 1.5, 9.5, 6.0, 3.0);
    tris.extend(quad_uv(10.25, 8.0, 14.75, 13.5, 2.0));
    let scene = scene_of(unit_light(), tris)?;
    let req = LightSpaceRequest {
        mssm_levels: Some(4),
        ..LightSpaceRequest::single(16)
    };
    let view = unit_view(16);
    let frame = mapper.layers_frame_slots(&ctx, 16, &req, 1)?;
    // Renders `casters` into the frame, building `cap` MSSM levels (max planes too: `mssm_max`).
    let build = |casters: &GpuScene, cap: Option<u32>, mssm_max: bool| -> Result<(), Error> {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let slot = LayersSlot {
            view: &view,
            max_bias: 0.0,
            min_opacity: 0.0,
            slot: 0,
            mssm_levels: cap,
            mssm_max,
            timestamps: None,
        };
        frame.encode_slot(&ctx, &mut enc, casters, &slot)?;
        ctx.queue.submit([enc.finish()]);
        Ok(())
    };
    let casters = GpuScene::upload(&ctx, &scene)?;
    // Each level's (min, max) planes.
    type Planes = Vec<(Vec<f32>, Vec<f32>)>;
    let levels_after = |cap: Option<u32>| -> Result<Planes, Error> {
        build(&casters, cap, true)?;
        frame
            .light_space(&view)
            .mssm
            .expect("an MSSM")
            .read_levels(&ctx)
    };
    let all = levels_after(None)?;
    assert_eq!(all.len(), 5, "levels 0 to 4");
    let l0 = frame.light_space(&view).to_cpu(&ctx)?.layers[0].clone();
    let cpu = Mssm::build(&l0.depth, l0.size, 4);
    let three = levels_after(Some(3))?;
    assert_eq!(three.len(), 3);
    for (l, (mn, mx)) in three.iter().enumerate() {
        let (cmn, cmx) = cpu.level(l as u32);
        assert!(same_bits(mn, cmn) && same_bits(mx, cmx), "level {l}");
    }
    assert_eq!(levels_after(None)?.len(), 5);
    // Min planes only: a scene with other casters, so that a level the pass skipped would keep
    // the first scene's minima.
    let mut tris = quad_uv(1.0, 1.0, 4.0, 4.0, 1.5);
    tris.extend(quad_uv(8.0, 2.0, 15.0, 7.0, 2.5));
    build(
        &GpuScene::upload(&ctx, &scene_of(unit_light(), tris)?)?,
        None,
        false,
    )?;
    let l0 = frame.light_space(&view).to_cpu(&ctx)?.layers[0].clone();
    let cpu = Mssm::build(&l0.depth, l0.size, 4);
    let ls = frame.light_space(&view);
    let mins = ls.mssm.expect("an MSSM").read_levels(&ctx)?;
    assert_eq!(mins.len(), 5);
    for (l, (mn, _)) in mins.iter().enumerate() {
        assert!(same_bits(mn, cpu.level(l as u32).0), "min-only level {l}");
    }
    Ok(())
}
