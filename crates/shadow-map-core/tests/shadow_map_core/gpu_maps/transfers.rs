//! The MSSM family on uploaded CPU maps, forced chunking, device limits, and depth-map,
//! receiver and light-space transfers, against the CPU.
use super::{box_tris, gpu, proptest_config, rect_light, same_bits, scene_of, TestResult};
use crate::common::{quad_uv, unit_light, unit_view};
use glam::Vec3;
use proptest::prelude::*;
use proptest::test_runner::TestRunner;
use shadow_map_core::{
    gpu::{
        mssm::MinMaxRequest,
        read_depth_map,
        receivers::RECEIVER_BYTES,
        shared::{pack_receivers, LightViewUniform},
        upload_depth_map, GpuContext, GpuDepthMap, GpuReceivers, GpuScene, GpuShadowMapper,
    },
    mssm::{DualMssm, MinMaxPyramid, Mssm},
    DepthMap, Error, LightSpace, LightSpaceRequest, RasterOptions, Receivers,
};

/// Random depth maps: finite depths, empty texels and NaNs (sanitised to empty on both sides).
fn arb_depth_map() -> impl Strategy<Value = DepthMap> {
    (1u32..=70).prop_flat_map(|s| {
        prop::collection::vec(
            prop_oneof![
                8 => 0.1f32..100.0,
                2 => Just(f32::INFINITY),
                1 => Just(f32::NAN),
            ],
            (s * s) as usize,
        )
        .prop_map(move |depth| DepthMap { size: s, depth })
    })
}

fn check_minmax_bit_identical(
    ctx: &GpuContext,
    mapper: &GpuShadowMapper,
    map: &DepthMap,
    max_level: u32,
    binding_cap: Option<u64>,
) -> Result<(), TestCaseError> {
    let fail = |e: Error| TestCaseError::fail(e.to_string());
    let g = upload_depth_map(ctx, map).map_err(fail)?;
    let mut builder = mapper.mssm_builder().clone();
    builder.set_max_binding_bytes(binding_cap);
    let set = builder
        .build(
            ctx,
            &g,
            MinMaxRequest {
                mssm_levels: Some(max_level),
                dual_mssm_levels: Some(max_level),
                pyramid: true,
            },
        )
        .map_err(fail)?;
    let (s, d) = (map.size, &map.depth);
    let mssm = Mssm::build(d, s, max_level);
    let dual = DualMssm::build(d, s, max_level);
    let pyr = MinMaxPyramid::build(d, s);
    let g_mssm = set.mssm.ok_or_else(|| TestCaseError::fail("no mssm"))?;
    let g_dual = set
        .dual_mssm
        .ok_or_else(|| TestCaseError::fail("no dual"))?;
    let g_pyr = set
        .pyramid
        .ok_or_else(|| TestCaseError::fail("no pyramid"))?;
    prop_assert_eq!(g_mssm.levels(), mssm.levels());
    prop_assert_eq!(g_dual.levels(), dual.levels());
    prop_assert_eq!(g_pyr.levels(), pyr.levels());
    prop_assert_eq!(g_mssm.bytes(), mssm.bytes());
    prop_assert_eq!(g_dual.bytes(), dual.bytes());
    prop_assert_eq!(g_pyr.bytes(), pyr.bytes());
    for (l, (mn, mx)) in g_mssm.read_levels(ctx).map_err(fail)?.iter().enumerate() {
        let (a, b) = mssm.level(l as u32);
        prop_assert!(
            same_bits(mn, a) && same_bits(mx, b),
            "mssm level {} size {}",
            l,
            s
        );
    }
    for (l, (mn, mx)) in g_dual.read_levels(ctx).map_err(fail)?.iter().enumerate() {
        let (a, b) = dual.level(l as u32);
        prop_assert!(
            same_bits(mn, a) && same_bits(mx, b),
            "dual level {} size {}",
            l,
            s
        );
    }
    for (l, (mn, mx)) in g_pyr.read_levels(ctx).map_err(fail)?.iter().enumerate() {
        let (a, b) = pyr.level(l as u32);
        prop_assert_eq!(g_pyr.level_size(l as u32), pyr.level_size(l as u32));
        prop_assert!(
            same_bits(mn, a) && same_bits(mx, b),
            "pyramid level {} size {}",
            l,
            s
        );
    }
    Ok(())
}

#[test]
fn mssm_family_is_bit_identical_on_uploaded_cpu_maps() -> TestResult {
    let Some((ctx, mapper)) = gpu("mssm_family_is_bit_identical_on_uploaded_cpu_maps")? else {
        return Ok(());
    };
    let mut runner = TestRunner::new(proptest_config(24));
    runner
        .run(&(arb_depth_map(), 0u32..=8), |(map, max_level)| {
            check_minmax_bit_identical(&ctx, &mapper, &map, max_level, None)
        })
        .map_err(|e| e.to_string())?;
    Ok(())
}

#[test]
fn forced_chunking_is_bit_identical() -> TestResult {
    let Some((ctx, mapper)) = gpu("forced_chunking_is_bit_identical")? else {
        return Ok(());
    };
    let align = ctx.limits().min_storage_buffer_offset_alignment as u64;
    // Deterministic values (proptest's seeded generator).
    let mut rng = proptest::test_runner::TestRng::deterministic_rng(
        proptest::test_runner::RngAlgorithm::ChaCha,
    );
    let mut next = move || proptest::prelude::Rng::next_u64(&mut rng);
    for &(size, cap_rows) in &[(67u32, 1u64), (67, 5), (128, 3), (33, 2), (1, 1)] {
        let depth: Vec<f32> = (0..size * size)
            .map(|_| {
                let v = next();
                match v % 10 {
                    0 => f32::INFINITY,
                    1 => f32::NAN,
                    _ => 0.1 + (v >> 40) as f32 / (1u64 << 24) as f32 * 50.0,
                }
            })
            .collect();
        let map = DepthMap { size, depth };
        // Room for `cap_rows` rows of the widest binding (two source rows of a reduction) plus
        // the offset alignment: far below one plane, so every level is built in chunks.
        let cap = 2 * size as u64 * 4 * cap_rows + align;
        assert!(
            size == 1 || cap < size as u64 * size as u64 * 4,
            "cap must force chunks"
        );
        check_minmax_bit_identical(&ctx, &mapper, &map, 8, Some(cap))
            .map_err(|e| format!("size {size}, cap {cap}: {e}"))?;
    }
    // A cap below one row (plus alignment) is a limit error, not a panic or a wrong result.
    let map = DepthMap {
        size: 64,
        depth: vec![1.0; 64 * 64],
    };
    let g = upload_depth_map(&ctx, &map)?;
    let builder = mapper.mssm_builder().clone().with_max_binding_bytes(64);
    assert_limit(builder.build_mssm(&ctx, &g, 3));
    Ok(())
}

#[test]
fn texture_larger_than_the_device_limit_is_a_limit_error() -> TestResult {
    let Some((ctx, mapper)) = gpu("texture_larger_than_the_device_limit_is_a_limit_error")? else {
        return Ok(());
    };
    let max = ctx.limits().max_texture_dimension_2d;
    let scene = scene_of(unit_light(), quad_uv(1.0, 1.0, 3.0, 3.0, 2.0))?;
    let gscene = GpuScene::upload(&ctx, &scene)?;
    let mut req = LightSpaceRequest::single(max + 1);
    req.layers = 2;
    match mapper.render_layers(&ctx, &gscene, &unit_view(max + 1), &req) {
        Err(Error::Limit {
            requested, max: m, ..
        }) => {
            assert_eq!((requested, m), (max as u64 + 1, max as u64));
        }
        other => panic!("expected Error::Limit, got {other:?}"),
    }
    assert_limit(GpuDepthMap::new(&ctx, max + 1, "too large"));
    Ok(())
}

#[test]
fn depth_maps_round_trip_bit_for_bit() -> TestResult {
    let Some((ctx, _)) = gpu("depth_maps_round_trip_bit_for_bit")? else {
        return Ok(());
    };
    // Sizes whose rows are not a multiple of 256 bytes exercise the readback padding.
    for size in [1u32, 3, 64, 65, 100] {
        let depth: Vec<f32> = (0..size * size)
            .map(|k| match k % 7 {
                0 => f32::INFINITY,
                1 => -0.0,
                2 => f32::NAN,
                _ => k as f32 * 0.37,
            })
            .collect();
        let map = DepthMap { size, depth };
        let back = read_depth_map(&ctx, &upload_depth_map(&ctx, &map)?)?;
        assert_eq!(back.size, size);
        assert!(same_bits(&back.depth, &map.depth), "size {size}");
    }
    let bad = DepthMap {
        size: 4,
        depth: vec![1.0; 3],
    };
    assert!(upload_depth_map(&ctx, &bad).is_err());
    Ok(())
}

#[test]
fn receivers_upload_wrap_and_chunk() -> TestResult {
    let Some((ctx, _)) = gpu("receivers_upload_wrap_and_chunk")? else {
        return Ok(());
    };
    let pos: Vec<Vec3> = (0..37).map(|k| Vec3::new(k as f32, 1.0, -2.0)).collect();
    let nrm = vec![Vec3::new(0.0, 2.0, 0.0); pos.len()];
    let mut recv = Receivers::from_points(pos, nrm)?;
    recv.active_mut()[5] = false;
    let g = GpuReceivers::upload(&ctx, &recv)?;
    assert_eq!(g.count, 37);
    assert_eq!(g.read(&ctx)?, pack_receivers(&recv));
    // A user's buffer: wrapped as is, checked for usage and size.
    let user = GpuReceivers::from_buffer(g.buffer.clone(), 30)?;
    assert_eq!(user.read(&ctx)?, pack_receivers(&recv)[..30].to_vec());
    assert!(matches!(
        GpuReceivers::from_buffer(g.buffer.clone(), 38),
        Err(Error::Receivers(_))
    ));
    let not_storage = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("not storage"),
        size: 64 * RECEIVER_BYTES,
        usage: wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    assert!(GpuReceivers::from_buffer(not_storage, 2).is_err());
    let no_copy = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("no copy_src"),
        size: 4 * RECEIVER_BYTES,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    assert!(matches!(
        GpuReceivers::from_buffer(no_copy, 4)?.read(&ctx),
        Err(Error::Receivers(_))
    ));
    // Chunks cover 0..count with aligned starts and bindings within the cap.
    let chunks = g.chunks(10 * RECEIVER_BYTES, 256);
    assert_eq!(chunks.first().map(|c| c.start), Some(0));
    assert_eq!(chunks.last().map(|c| c.end), Some(37));
    for w in chunks.windows(2) {
        assert_eq!(w[0].end, w[1].start);
    }
    for c in &chunks {
        assert_eq!(c.start as u64 * RECEIVER_BYTES % 256, 0);
        assert!((c.end - c.start) as u64 * RECEIVER_BYTES <= 10 * RECEIVER_BYTES);
    }
    assert_eq!(g.chunks(u64::MAX, 256), vec![0..37]);
    Ok(())
}

#[test]
fn render_fits_like_the_cpu_and_to_cpu_reads_every_part() -> TestResult {
    let Some((ctx, mapper)) = gpu("render_fits_like_the_cpu_and_to_cpu_reads_every_part")? else {
        return Ok(());
    };
    let light = rect_light(Vec3::new(0.0, 5.0, 0.0), -Vec3::Y, [1.0, 1.0]);
    let mut tris = box_tris(Vec3::new(0.0, 1.0, 0.0), Vec3::splat(0.5), 0.3);
    let g = 4.0;
    tris.push([
        Vec3::new(-g, 0.0, -g),
        Vec3::new(g, 0.0, g),
        Vec3::new(g, 0.0, -g),
    ]);
    tris.push([
        Vec3::new(-g, 0.0, -g),
        Vec3::new(-g, 0.0, g),
        Vec3::new(g, 0.0, g),
    ]);
    let scene = scene_of(light, tris)?;
    let pts = vec![Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 0.0, 2.0)];
    let recv = Receivers::from_points(pts, vec![Vec3::Y; 2])?;
    let req = LightSpaceRequest {
        resolution: 48,
        layers: 2,
        midpoints: Some(0.2),
        mssm_levels: Some(3),
        dual_mssm_levels: Some(2),
        pyramid: true,
        raster: RasterOptions::default(),
        opacity: false,
    };
    let cpu = LightSpace::build(&scene, &recv, &req)?;
    let gscene = GpuScene::upload(&ctx, &scene)?;
    assert_eq!(gscene.triangles as usize, scene.triangles().len());
    let gls = mapper.render(&ctx, &scene, &gscene, &recv, &req)?;
    assert_eq!(gls.view, cpu.view);
    assert_eq!(gls.fit, cpu.fit);
    assert_eq!(gls.bytes(), cpu.bytes());
    let bytes = std::mem::size_of::<LightViewUniform>() as u64;
    let uniform: Vec<LightViewUniform> = ctx.read_buffer(&gls.view_uniform, bytes)?;
    assert_eq!(uniform, vec![LightViewUniform::from(&cpu.view)]);
    let back = gls.to_cpu(&ctx)?;
    assert_eq!(back.layers.len(), 2);
    assert_eq!(back.midpoints.len(), 2);
    assert_eq!(back.bytes(), cpu.bytes());
    let levels = |m: &Option<Mssm>| m.as_ref().map(Mssm::levels);
    assert_eq!(levels(&back.mssm), levels(&cpu.mssm));
    assert_eq!(
        back.dual_mssm.as_ref().map(DualMssm::levels),
        cpu.dual_mssm.as_ref().map(DualMssm::levels)
    );
    assert_eq!(
        back.pyramid.as_ref().map(MinMaxPyramid::levels),
        cpu.pyramid.as_ref().map(MinMaxPyramid::levels)
    );
    Ok(())
}

/// Fails unless `r` is an [`Error::Limit`].
fn assert_limit<T: std::fmt::Debug>(r: Result<T, Error>) {
    match r {
        Err(Error::Limit { .. }) => {}
        other => panic!("expected Error::Limit, got {other:?}"),
    }
}
