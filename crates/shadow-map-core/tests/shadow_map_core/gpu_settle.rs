//! The device's settle passes (`gpu::settle::GpuSettler`) against their CPU twin,
//! `settle::Settler::unshadowed`: under each light shape, receivers on a ground among random
//! boxes (some under them, some in the open, some grazing) are settled (V = the facing
//! fraction) where the CPU settles them, and left NaN, counted, where it does not; never settled
//! where the CPU is not, and left NaN where the CPU settles for at most 1 in 500 (a triangle that
//! touches the pyramid to within f32 rounding); receivers not in the open list are left as they
//! were.
#![cfg(feature = "gpu")]

use crate::common;

use glam::Vec3;
use proptest::{
    prelude::Rng,
    test_runner::{RngAlgorithm, TestRng},
};
use shadow_map_core::{
    camera::Camera,
    gpu::{
        frame::ReceiverRange,
        kernel::{buffer_init, storage_buffer, uniform},
        raster::GpuScene,
        settle::GpuSettler,
        shared::ReceiverGpu,
        EstimateUniform,
    },
    light::default_tangent,
    settle::Settler,
    Error, Light, LightShape, Scene,
};

/// V of receivers outside the open list: never touched.
const UNTOUCHED: u32 = 0x1234_5678;

/// A ground of 60 m and 40 random boxes (12 triangles each) within 12 m of the origin.
fn casters(next: &mut impl FnMut() -> f32) -> Vec<[Vec3; 3]> {
    let g = 30.0;
    let mut tris = test_support::fixtures::quad(-g, -g, g, g, 0.0);
    for _ in 0..40 {
        let c = Vec3::new(next() * 24.0 - 12.0, next() * 3.0, next() * 24.0 - 12.0);
        let h = Vec3::new(0.1 + next() * 0.6, 0.1 + next() * 0.6, 0.1 + next() * 0.6);
        tris.extend(test_support::fixtures::cuboid(c - h, c + h));
    }
    tris
}

fn lights() -> Vec<(&'static str, Light)> {
    let area = |shape, center: Vec3, normal: Vec3| {
        let normal = normal.normalize();
        Light {
            shape,
            center,
            normal,
            tangent: default_tangent(normal),
        }
    };
    vec![
        (
            "rect",
            area(
                LightShape::Rect { size: [2.0, 1.0] },
                Vec3::new(1.0, 6.0, -2.0),
                Vec3::new(0.2, -1.0, 0.3),
            ),
        ),
        (
            "disk",
            area(
                LightShape::Disk { radius: 0.8 },
                Vec3::new(-3.0, 5.0, 1.0),
                Vec3::new(0.5, -1.0, 0.0),
            ),
        ),
        (
            "sphere",
            area(
                LightShape::Sphere { radius: 0.7 },
                Vec3::new(2.0, 4.0, 3.0),
                Vec3::new(0.0, -1.0, 0.0),
            ),
        ),
        ("sun", Light::directional(Vec3::new(0.3, -1.0, 0.1), 2.0)),
    ]
}

#[test]
fn settle_passes_match_the_cpu_settler() -> Result<(), Error> {
    let Some(ctx) = common::context_for_tests("settle_passes_match_the_cpu_settler")? else {
        return Ok(());
    };
    let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
    let mut next = move || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
    let tris = casters(&mut next);
    let settler = GpuSettler::new(&ctx)?;
    for (name, light) in lights() {
        let camera = Camera {
            eye: Vec3::new(0.0, 5.0, 30.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 8,
            height: 8,
        };
        let scene = Scene::from_meshes("settle", camera, light, vec![(tris.clone(), 1.0)])?;
        // Receivers on the ground, their normals tilted up to 60 degrees; every fifth left out
        // of the open list.
        let n = 1500u32;
        let recs: Vec<ReceiverGpu> = (0..n)
            .map(|_| {
                let p = Vec3::new(next() * 40.0 - 20.0, 0.0, next() * 40.0 - 20.0);
                let t = Vec3::new(next() - 0.5, 0.0, next() - 0.5) * 1.7;
                let nrm = (Vec3::Y + t).normalize();
                ReceiverGpu {
                    position: p.to_array(),
                    active: 1,
                    normal: nrm.to_array(),
                    _pad0: 0.0,
                }
            })
            .collect();
        let open: Vec<u32> = (0..n).filter(|k| k % 5 != 0).collect();
        let casters = GpuScene::upload(&ctx, &scene)?;
        let eu = EstimateUniform::new(&light, 0.0, 0.0);
        let est = uniform(&ctx, "settle test light", &eu);
        let receivers = buffer_init(
            &ctx.device,
            "settle test receivers",
            bytemuck::cast_slice(&recs),
            wgpu::BufferUsages::STORAGE,
        );
        let v0: Vec<u32> = (0..n)
            .map(|k| if k % 5 == 0 { UNTOUCHED } else { 0x7fc0_0000 })
            .collect();
        let v = buffer_init(
            &ctx.device,
            "settle test v",
            bytemuck::cast_slice(&v0),
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );
        let counters = storage_buffer(&ctx, "settle test counters", 8);
        let range = ReceiverRange { first: 0, count: n };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        enc.clear_buffer(&counters, 0, None);
        let list = settler.open_list(&ctx, &mut enc, 0, range);
        let mut words = vec![open.len() as u32];
        words.extend(&open);
        ctx.write_in(&mut enc, &list, 0, bytemuck::cast_slice(&words));
        settler.encode(
            &ctx,
            &mut enc,
            (&eu, &est),
            &casters,
            range,
            &list,
            (&receivers, &v),
            (&counters, 1),
        )?;
        ctx.queue.submit([enc.finish()]);
        let got: Vec<u32> = ctx.read_buffer(&v, 4 * n as u64)?;
        let count: Vec<u32> = ctx.read_buffer(&counters, 8)?;
        let cpu = Settler::new(&scene);
        let (mut settled, mut unsettled) = (0usize, 0usize);
        // Receivers the CPU settles and the GPU leaves NaN: a triangle touching the pyramid to
        // within f32 rounding (conservative, as a NaN is redone by the caller).
        let mut stricter = Vec::new();
        for k in 0..n as usize {
            let (p, nrm) = (Vec3::from(recs[k].position), Vec3::from(recs[k].normal));
            let g = f32::from_bits(got[k]);
            if k % 5 == 0 {
                assert_eq!(got[k], UNTOUCHED, "{name}: #{k} is not in the open list");
                continue;
            }
            if cpu.unshadowed(p, nrm) {
                let want = light.front_fraction_world(p, nrm).clamp(0.0, 1.0);
                if got[k] == 0x7fc0_0000 {
                    stricter.push(k);
                } else {
                    assert!(
                        (g - want).abs() <= 1e-5,
                        "{name}: #{k} at {p} normal {nrm}: settled on the CPU (V {want}), GPU {g}"
                    );
                }
                settled += 1;
            } else {
                assert_eq!(
                    got[k], 0x7fc0_0000,
                    "{name}: #{k} at {p} normal {nrm}: not settled on the CPU, settled on the GPU ({g})"
                );
                unsettled += 1;
            }
        }
        println!(
            "{name}: {settled} settled, {unsettled} left NaN, {} settled on the CPU only: {stricter:?}",
            stricter.len()
        );
        assert!(
            stricter.len() * 500 <= open.len(),
            "{name}: {} of {} receivers settled on the CPU only",
            stricter.len(),
            open.len()
        );
        let gpu_nan = open
            .iter()
            .filter(|&&k| got[k as usize] == 0x7fc0_0000)
            .count();
        assert_eq!(count, vec![0, gpu_nan as u32], "{name}: counters");
        // Both outcomes occur.
        assert!(
            settled > 50 && unsettled > 10,
            "{name}: {settled} settled, {unsettled} not"
        );
    }
    Ok(())
}
