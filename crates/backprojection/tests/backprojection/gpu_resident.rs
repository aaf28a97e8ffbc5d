//! The resident path of the GPU twin (`build_resident`, `estimate_resident`): receivers in a
//! plain wgpu buffer of the test's own, V written into another, read back here only to compare.
//!
//! - With the light space of the ordinary `build`, the resident dispatch gives V bit for bit equal
//!   to the CPU-receivers path's (same kernel, same chunk-independent arithmetic), also in small
//!   aligned chunks.
//! - With `build_resident` the view is fitted to the receivers' bounding box: a larger window on
//!   another texel lattice, so V differs where the estimator is sensitive to the lattice (depth
//!   ties, silhouettes), by the order of what `fit=scene` changes, and is as accurate. Measured on
//!   lavapipe, default parameters (resolution 1024), over active camera receivers:
//!
//!   | fixture | max abs dV | RMSE dV | abs dV > 0.1 | RMSE vs reference, ordinary / resident | `fit=scene` vs ordinary, RMSE |
//!   |---|---|---|---|---|---|
//!   | parallel-squares | 0.119 | 0.0171 | 0.09% | 0.0106 / 0.0111 | 0.0067 |
//!   | stacked | 0.635 | 0.0425 | 2.57% | 0.1116 / 0.1114 | 0.0502 |
//!   | bunny | 1.000 | 0.0391 | 2.12% | 0.0595 / 0.0546 | 0.0224 |
//!
//!   (reference: the ray tracer at 256 spp.) The test allows an RMSE of [`MAX_RMSE`], a
//!   fraction [`MAX_OVER`] beyond 0.1 and a loss against the reference of [`MAX_LOSS`].
//! - Bad inputs are typed errors: buffers without `STORAGE`, a too small V buffer, bounds crossing
//!   the light plane, a call before a build.
//! - Disk and sphere lights take the resident path, bit for bit equal to the ordinary path.
#![cfg(feature = "gpu")]

use backprojection::GpuBackprojection;
use glam::Vec3;
use reference::ReferenceEstimator;
use shadow_map_core::{
    gpu::{kernel::buffer_init, receivers::GpuReceivers, shared::pack_receivers, GpuContext},
    light_view::receiver_bounds,
    run,
    scene::Aabb,
    Error, Receivers, Scene, SceneBvh, SoftShadowEstimator,
};
use std::sync::Arc;
use test_support::gate::context_for_tests;

/// Largest RMSE between the bounds-fitted resident path and the ordinary path.
const MAX_RMSE: f64 = 0.06;
/// Largest fraction of active receivers where they differ by more than 0.1.
const MAX_OVER: f64 = 0.05;
/// Largest increase of the RMSE against the ray-traced reference (256 spp) that the bounds fit
/// may cost.
const MAX_LOSS: f64 = 0.005;

fn gpu(test: &str) -> Option<Arc<GpuContext>> {
    match context_for_tests(test) {
        Ok(c) => c,
        Err(e) => panic!("{test}: {e}"),
    }
}

fn fixture(name: &str) -> Scene {
    let path = format!(
        "{}/../../fixtures/{name}/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    Scene::load(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The user's receiver buffer: a plain buffer, filled as their G-buffer pass would.
fn user_receivers(ctx: &GpuContext, rec: &Receivers) -> GpuReceivers {
    let packed = pack_receivers(rec);
    let buffer = buffer_init(
        &ctx.device,
        "user receivers",
        bytemuck::cast_slice(&packed),
        wgpu::BufferUsages::STORAGE,
    );
    GpuReceivers::from_buffer(buffer, rec.len() as u32).expect("user receivers")
}

/// The user's V buffer of `count` f32.
fn user_v(ctx: &GpuContext, count: usize) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("user V"),
        size: (count.max(1) * 4) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

fn ordinary(g: &mut GpuBackprojection, scene: &Scene, rec: &Receivers) -> Vec<f32> {
    g.build(scene, rec).expect("build");
    let mut v = vec![0.0; rec.len()];
    g.estimate(scene, rec, &mut v).expect("estimate");
    v
}

fn resident_v(
    ctx: &GpuContext,
    g: &mut GpuBackprojection,
    scene: &Scene,
    rec: &GpuReceivers,
) -> Vec<f32> {
    let v_buf = user_v(ctx, rec.count as usize);
    g.estimate_resident(scene, rec, &v_buf)
        .expect("estimate_resident");
    ctx.read_buffer(&v_buf, rec.count as u64 * 4)
        .expect("read V")
}

/// (max |dV|, RMSE) over active receivers; NaN exactly at inactive ones in both.
fn compare(a: &[f32], b: &[f32], rec: &Receivers, what: &str) -> (f32, f64) {
    assert_eq!(a.len(), b.len());
    let (mut max, mut sq, mut n) = (0.0f32, 0.0f64, 0usize);
    for k in 0..a.len() {
        if !rec.active()[k] {
            assert!(
                a[k].is_nan() && b[k].is_nan(),
                "{what} #{k}: {} {}",
                a[k],
                b[k]
            );
            continue;
        }
        assert!(
            (0.0..=1.0).contains(&a[k]) && (0.0..=1.0).contains(&b[k]),
            "{what} #{k}: {} {}",
            a[k],
            b[k]
        );
        let d = (a[k] - b[k]).abs();
        max = max.max(d);
        sq += (d as f64) * (d as f64);
        n += 1;
    }
    assert!(n > 0, "{what}: no active receiver");
    (max, (sq / n as f64).sqrt())
}

#[test]
fn resident_dispatch_matches_the_ordinary_path_bit_for_bit() {
    let Some(ctx) = gpu("resident_dispatch_matches_the_ordinary_path_bit_for_bit") else {
        return;
    };
    let scene = fixture("stacked");
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let mut g = GpuBackprojection::new(ctx.clone()).expect("gpu twin");
    let v_ref = ordinary(&mut g, &scene, &rec);
    let gr = user_receivers(&ctx, &rec);
    // The same light space (the ordinary build), the resident dispatch: whole, then in chunks
    // whose starts are multiples of the offset alignment.
    let v_whole = resident_v(&ctx, &mut g, &scene, &gr);
    let report_len = |g: &GpuBackprojection| {
        let r = g.report();
        (r.stages.len(), r.notes.len())
    };
    let len_whole = report_len(&g);
    g.set_max_chunk(13).unwrap();
    let v_chunked = resident_v(&ctx, &mut g, &scene, &gr);
    assert_eq!(report_len(&g), len_whole, "the report grows per call");
    let chunks = gr.chunks(
        13 * 32,
        ctx.limits().min_storage_buffer_offset_alignment * 8,
    );
    assert!(chunks.len() > 1, "{chunks:?}");
    let mut shadowed = 0;
    for k in 0..rec.len() {
        assert_eq!(v_ref[k].to_bits(), v_whole[k].to_bits(), "#{k}");
        assert_eq!(v_ref[k].to_bits(), v_chunked[k].to_bits(), "chunked #{k}");
        shadowed += usize::from(v_ref[k] < 1.0);
    }
    assert!(shadowed > 0, "the fixture casts no shadow");
    let report = g.report();
    assert!(
        report.notes.iter().any(|(k, _)| k == "resident"),
        "{report:?}"
    );
    let c: Vec<u32> = ctx
        .read_buffer(g.resident_counters().expect("counters"), 8)
        .expect("read counters");
    assert_eq!(c, [0, 0]);
}

/// Bounds fit against receivers fit on three fixtures, both also against the ray-traced reference
/// (figures in the module documentation; printed with `--nocapture`).
#[test]
fn resident_with_bounds_agrees_with_the_ordinary_path() {
    let Some(ctx) = gpu("resident_with_bounds_agrees_with_the_ordinary_path") else {
        return;
    };
    for name in ["parallel-squares", "stacked", "bunny"] {
        let scene = fixture(name);
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        let mut g = GpuBackprojection::new(ctx.clone()).expect("gpu twin");
        let v_ref = ordinary(&mut g, &scene, &rec);
        let gr = user_receivers(&ctx, &rec);
        let mut gb = GpuBackprojection::new(ctx.clone()).expect("gpu twin");
        gb.build_resident(&scene, &receiver_bounds(&rec))
            .expect("build_resident");
        let v = resident_v(&ctx, &mut gb, &scene, &gr);
        let (max, rmse) = compare(&v, &v_ref, &rec, name);
        let over = v
            .iter()
            .zip(&v_ref)
            .filter(|(a, b)| (*a - *b).abs() > 0.1)
            .count() as f64
            / rec.active_count() as f64;
        let mut re = ReferenceEstimator::new().expect("reference");
        re.set_progress(false);
        re.set_param("spp", "256").expect("spp");
        let (v_rt, _) = run(&mut re, &scene, &rec).expect("reference");
        let (_, err_ordinary) = compare(&v_ref, &v_rt, &rec, name);
        let (_, err_resident) = compare(&v, &v_rt, &rec, name);
        println!(
            "{name}: resident (bounds fit) vs ordinary: max |dV| {max:.4}, RMSE {rmse:.4}, \
             |dV| > 0.1 on {:.2}%; RMSE vs reference: ordinary {err_ordinary:.4}, resident \
             {err_resident:.4}",
            100.0 * over
        );
        assert!(rmse <= MAX_RMSE, "{name}: RMSE {rmse}");
        assert!(over <= MAX_OVER, "{name}: |dV| > 0.1 on {over}");
        assert!(
            err_resident <= err_ordinary + MAX_LOSS,
            "{name}: RMSE vs reference {err_resident} (ordinary {err_ordinary})"
        );
        let c: Vec<u32> = ctx
            .read_buffer(gb.resident_counters().expect("counters"), 8)
            .expect("read counters");
        assert_eq!(
            c,
            [0, 0],
            "{name}: every receiver is inside the bounds' window"
        );
    }
}

/// A receiver outside the bounds the view was fitted to is counted in the counters left on the
/// GPU, and lit (as the CPU path treats receivers outside the frustum).
#[test]
fn receivers_outside_the_bounds_are_counted_on_the_gpu() {
    let Some(ctx) = gpu("receivers_outside_the_bounds_are_counted_on_the_gpu") else {
        return;
    };
    let scene = fixture("parallel-squares");
    let inside: Vec<Vec3> = (0..40)
        .map(|k| Vec3::new(-0.8 + 0.04 * k as f32, 0.0, 0.1))
        .collect();
    let bounds = Aabb {
        min: Vec3::new(-1.0, 0.0, -0.2),
        max: Vec3::new(1.0, 0.0, 0.2),
    };
    let mut pos = inside.clone();
    pos.push(Vec3::new(3.5, 0.0, 3.5));
    let rec = Receivers::from_points(pos.clone(), vec![Vec3::Y; pos.len()]).expect("receivers");
    let mut g = GpuBackprojection::new(ctx.clone()).expect("gpu twin");
    g.build_resident(&scene, &bounds).expect("build_resident");
    let gr = user_receivers(&ctx, &rec);
    let v = resident_v(&ctx, &mut g, &scene, &gr);
    let c: Vec<u32> = ctx
        .read_buffer(g.resident_counters().expect("counters"), 8)
        .expect("read counters");
    assert_eq!(c, [1, 0]);
    let last = *v.last().expect("V");
    assert!(last > 0.0 && last <= 1.0, "{last}");
    assert!(
        v[..40].iter().any(|&x| x < 0.5),
        "no umbra under the occluder: {v:?}"
    );
}

#[test]
fn bad_resident_inputs_are_typed_errors() {
    let Some(ctx) = gpu("bad_resident_inputs_are_typed_errors") else {
        return;
    };
    let scene = fixture("parallel-squares");
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let n = rec.len();
    let gr = user_receivers(&ctx, &rec);
    let v_buf = user_v(&ctx, n);
    let mut g = GpuBackprojection::new(ctx.clone()).expect("gpu twin");

    // Before any build.
    match g.estimate_resident(&scene, &gr, &v_buf) {
        Err(Error::Param { key, .. }) => assert_eq!(key, "build"),
        other => panic!("estimate before build: {other:?}"),
    }
    // Bounds crossing the light plane (the light is at y = 3, facing down).
    let crossing = Aabb {
        min: Vec3::new(-1.0, 0.0, -1.0),
        max: Vec3::new(1.0, 4.0, 1.0),
    };
    match g.build_resident(&scene, &crossing) {
        Err(Error::LightView(m)) => assert!(m.contains("cross the light plane"), "{m}"),
        other => panic!("crossing bounds: {other:?}"),
    }
    match g.build_resident(&scene, &Aabb::EMPTY) {
        Err(Error::Receivers(m)) => assert!(m.contains("empty"), "{m}"),
        other => panic!("empty bounds: {other:?}"),
    }
    g.build_resident(&scene, &receiver_bounds(&rec))
        .expect("build_resident");

    let plain = |usage, size| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bad"),
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    let receivers_err = |r: shadow_map_core::Result<()>, needle: &str| match r {
        Err(Error::Receivers(m)) => assert!(m.contains(needle), "{m}"),
        other => panic!("expected Error::Receivers({needle}): {other:?}"),
    };
    // A receiver buffer without STORAGE: refused by from_buffer, and by estimate_resident when
    // the struct is built by hand.
    let no_storage = plain(
        wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        n as u64 * 32,
    );
    assert!(matches!(
        GpuReceivers::from_buffer(no_storage.clone(), n as u32),
        Err(Error::Receivers(_))
    ));
    let by_hand = GpuReceivers {
        buffer: no_storage,
        count: n as u32,
    };
    receivers_err(g.estimate_resident(&scene, &by_hand, &v_buf), "STORAGE");
    let short = GpuReceivers {
        buffer: gr.buffer.clone(),
        count: n as u32 + 1,
    };
    receivers_err(g.estimate_resident(&scene, &short, &v_buf), "too small");
    // V buffers: without STORAGE, and one f32 short.
    let v_no_storage = plain(
        wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        n as u64 * 4,
    );
    receivers_err(g.estimate_resident(&scene, &gr, &v_no_storage), "STORAGE");
    let v_short = plain(wgpu::BufferUsages::STORAGE, (n as u64 - 1) * 4);
    receivers_err(g.estimate_resident(&scene, &gr, &v_short), "too small");
    // The valid call still works after the refusals.
    g.estimate_resident(&scene, &gr, &v_buf)
        .expect("valid call");
    let v: Vec<f32> = ctx.read_buffer(&v_buf, n as u64 * 4).expect("read V");
    assert!(v.iter().zip(rec.active()).all(|(x, &a)| if a {
        (0.0..=1.0).contains(x)
    } else {
        x.is_nan()
    }));
}

/// Disk and sphere lights (issue 18) take the resident path too: with the light space of the
/// ordinary `build`, the resident dispatch gives the ordinary path's V bit for bit (the sphere's
/// silhouette disk turns per receiver inside the same kernel).
#[test]
fn resident_dispatch_serves_disk_and_sphere_lights() {
    let Some(ctx) = gpu("resident_dispatch_serves_disk_and_sphere_lights") else {
        return;
    };
    for name in ["strands", "sphere-light"] {
        let scene = fixture(name);
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        let mut g = GpuBackprojection::new(ctx.clone()).expect("gpu twin");
        let v_ref = ordinary(&mut g, &scene, &rec);
        let gr = user_receivers(&ctx, &rec);
        let v = resident_v(&ctx, &mut g, &scene, &gr);
        let mut shadowed = 0;
        for k in 0..rec.len() {
            assert_eq!(v_ref[k].to_bits(), v[k].to_bits(), "{name} #{k}");
            shadowed += usize::from(v_ref[k] < 1.0);
        }
        assert!(shadowed > 0, "{name}: the fixture casts no shadow");
        g.build_resident(&scene, &receiver_bounds(&rec))
            .unwrap_or_else(|e| panic!("{name}: build_resident: {e}"));
    }
}
