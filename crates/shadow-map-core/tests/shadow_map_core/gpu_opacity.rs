//! The engine path's opacity planes ([`GpuLayersFrame::opacity`]) against the CPU's
//! `peel_with_opacity` ([`LightSpace::opacity`]): the peeling passes of a frame prepared with
//! opacity write, for semi-transparent casters, the opacity of the caster each layer texel's depth
//! came from (the caster buffer's w) and 0 where a layer is empty.
//!
//! On the strands (one mesh of opacity 0.4 over an opaque ground) and the hair (four meshes of
//! opacity 0.2 to 0.5), per layer: every texel both rasterisers leave empty has opacity 0 on the
//! GPU, and every texel where both hold the same surface (depths within 1e-4 relative) has the
//! CPU's opacity, but for texels where two meshes meet at one depth (the rasterisers may keep
//! either), at most 0.5% of them plus 2.
#![cfg(feature = "gpu")]

use crate::common;
use common::fixture;

use shadow_map_core::{
    gpu::{read_depth_map, GpuScene, GpuShadowMapper},
    light_view::ViewOptions,
    Error, LightSpace, LightSpaceRequest, Receivers, SceneBvh,
};

#[test]
fn layer_opacity_planes_match_the_cpu() -> Result<(), Error> {
    let Some(ctx) = common::context_for_tests("layer_opacity_planes_match_the_cpu")? else {
        return Ok(());
    };
    let mapper = GpuShadowMapper::new(&ctx)?;
    let req = LightSpaceRequest {
        layers: 3,
        opacity: true,
        ..LightSpaceRequest::single(128)
    };
    for name in ["strands", "hair"] {
        let scene = fixture(name, 64, 48);
        assert!(!scene.is_opaque(), "{name}: a semi-transparent fixture");
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        let (view, fit) = req.fit_view(&scene, &rec, &ViewOptions::default())?;
        let cpu = LightSpace::build_in_view(&scene, view, fit, &req);
        assert_eq!(
            cpu.opacity.len(),
            cpu.layers.len(),
            "{name}: CPU opacity planes"
        );

        let frame = mapper.layers_frame(&ctx, view.r, &req)?;
        let casters = GpuScene::upload(&ctx, &scene)?;
        assert!(!casters.is_opaque(), "{name}: the upload keeps the opacity");
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        frame.encode(&ctx, &mut enc, &casters, &view, 0.0)?;
        ctx.queue.submit([enc.finish()]);
        assert_eq!(frame.opacity().len(), frame.layers().len(), "{name}");

        let (mut same, mut tied, mut empty, mut translucent) = (0usize, 0usize, 0usize, 0usize);
        for (m, (cpu_depth, cpu_alpha)) in cpu.layers.iter().zip(&cpu.opacity).enumerate() {
            let depth = read_depth_map(&ctx, &frame.layers()[m])?.depth;
            let alpha = read_depth_map(&ctx, &frame.opacity()[m])?.depth;
            for t in 0..depth.len() {
                let (g, c) = (depth[t], cpu_depth.depth[t]);
                if g.is_infinite() && c.is_infinite() {
                    assert_eq!(alpha[t], 0.0, "{name}: layer {m} texel {t}: empty, opacity");
                    empty += 1;
                } else if (g - c).abs() <= 1e-4 * c.abs() {
                    if alpha[t] == cpu_alpha[t] {
                        same += 1;
                        translucent += usize::from(alpha[t] < 1.0);
                    } else {
                        tied += 1;
                    }
                }
            }
        }
        println!(
            "{name}: {same} texels with the CPU's opacity ({translucent} below 1), {tied} at a \
             tie between meshes, {empty} empty"
        );
        assert!(
            same > 0 && translucent > 0,
            "{name}: nothing translucent compared"
        );
        assert!(
            tied <= same / 200 + 2,
            "{name}: {tied} texels with another opacity than the CPU's, of {same}"
        );
    }
    Ok(())
}

/// One opacity level per view slot, all recorded into one encoder
/// ([`GpuLayersFrame::encode_slot`](shadow_map_core::gpu::GpuLayersFrame::encode_slot)): after
/// each slot's layers a copy of layer 0 is recorded, and each copy must be the CPU's layer 0 of
/// the level's scene ([`Scene::with_opacity_at_least`](shadow_map_core::Scene)) in that
/// slot's view, not the last slot's (its view and `min_opacity` are staged per slot). On the
/// hair: a view shifted per slot, and the level with no caster (min_opacity +inf) empty.
#[test]
fn layer_slots_render_each_opacity_level_in_its_own_view() -> Result<(), Error> {
    let Some(ctx) =
        common::context_for_tests("layer_slots_render_each_opacity_level_in_its_own_view")?
    else {
        return Ok(());
    };
    use shadow_map_core::gpu::{GpuDepthMap, LayersSlot};
    let mapper = GpuShadowMapper::new(&ctx)?;
    let req = LightSpaceRequest::single(64);
    let scene = fixture("hair", 32, 24);
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let (view, _) = req.fit_view(&scene, &rec, &ViewOptions::default())?;
    let levels = scene.opacity_levels();
    assert!(levels.len() >= 3, "hair: {levels:?}");
    let slots = levels.len();
    let frame = mapper.layers_frame_slots(&ctx, view.r, &req, slots as u32)?;
    let casters = GpuScene::upload(&ctx, &scene)?;
    assert_eq!(casters.opacity_levels(), levels.as_slice());
    // Each slot's view shifted by a few texels, so a slot rendered in another's view shows.
    let views: Vec<_> = (0..slots)
        .map(|k| {
            let mut v = view;
            v.window_min.x += 3.0 * k as f32 * v.delta();
            v
        })
        .collect();
    let copies: Vec<GpuDepthMap> = (0..slots)
        .map(|k| GpuDepthMap::new(&ctx, view.r, &format!("slot {k}")))
        .collect::<Result<_, _>>()?;
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    for (k, level) in levels.iter().enumerate() {
        let slot = LayersSlot {
            view: &views[k],
            max_bias: 0.0,
            min_opacity: level.min_opacity,
            slot: k,
            mssm_levels: None,
            mssm_max: true,
            timestamps: None,
        };
        frame.encode_slot(&ctx, &mut enc, &casters, &slot)?;
        enc.copy_texture_to_texture(
            frame.layers()[0].texture.as_image_copy(),
            copies[k].texture.as_image_copy(),
            wgpu::Extent3d {
                width: view.r,
                height: view.r,
                depth_or_array_layers: 1,
            },
        );
    }
    ctx.queue.submit([enc.finish()]);
    for (k, level) in levels.iter().enumerate() {
        let level_scene = scene.with_opacity_at_least(level.min_opacity);
        let cpu = LightSpace::build_in_view(&level_scene, views[k], Default::default(), &req);
        let cpu = &cpu.layers[0].depth;
        let gpu = read_depth_map(&ctx, &copies[k])?.depth;
        let filled = cpu.iter().filter(|d| d.is_finite()).count();
        let differ = cpu
            .iter()
            .zip(&gpu)
            .filter(|(c, g)| {
                c.is_finite() != g.is_finite()
                    || (c.is_finite() && (*c - *g).abs() > 1e-4 * c.abs())
            })
            .count();
        println!(
            "hair slot {k} (min opacity {}): {filled} texels filled on the CPU, {differ} differ",
            level.min_opacity
        );
        if level.min_opacity.is_infinite() {
            assert_eq!(filled, 0, "slot {k}: the level without casters");
        }
        assert!(filled == 0 || filled > 20, "slot {k}: {filled} texels");
        // Thin strands: the hardware's fill rule differs from the CPU's at sub-texel ties.
        assert!(
            differ <= filled / 20 + 2,
            "slot {k}: {differ} of {filled} texels differ from the CPU's level"
        );
    }
    Ok(())
}
