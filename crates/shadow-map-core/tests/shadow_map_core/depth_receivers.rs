//! Receivers from a caller's depth and normal textures (`gpu::depth_receivers`) against
//! the CPU's ray-traced [`Receivers::from_camera`] on the bunny and on sun-street (camera depths
//! from 0.5 m to 150 m), under both depth conventions and both normal encodings.
//!
//! The textures are made from the CPU receivers with `depth_receivers::depth_texture` (each
//! hit's NDC depth, the camera's projection of its position) and `normal_texture`
//! (`Rgba32Float` signed, or `Rgb10a2Unorm` as `n * 0.5 + 0.5`, Bevy's prepass encoding), a
//! stored normal turned away from the eye half the time (the pass must turn it back). The pass must then give back the same active pixels,
//! each position within `POS_TOL` of its distance from the eye (f32 depth), and the normal
//! within 1e-5 (float) or 2.5e-3 (10-bit unorm) per component.
#![cfg(feature = "gpu")]

use crate::common;
use common::fixture;

use glam::Vec3;
use shadow_map_core::{
    gpu::{
        depth_receivers::{
            depth_texture, normal_texture, DepthCamera, DepthConvention, GpuDepthReceivers,
            NormalEncoding,
        },
        shared::ReceiverGpu,
    },
    Error, Receivers, SceneBvh,
};

/// Position tolerance relative to the receiver's distance from the eye.
const POS_TOL: f32 = 2e-4;

#[test]
fn depth_and_normal_textures_give_the_camera_receivers() -> Result<(), Error> {
    let Some(ctx) =
        common::context_for_tests("depth_and_normal_textures_give_the_camera_receivers")?
    else {
        return Ok(());
    };
    let pass = GpuDepthReceivers::new(&ctx)?;
    for (name, w, h, near, far) in [
        ("bunny", 64, 48, 0.05, 20.0),
        ("sun-street", 80, 60, 0.1, 400.0),
    ] {
        let scene = fixture(name, w, h);
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        for depth in [DepthConvention::ZeroToOne, DepthConvention::ReverseZ] {
            for normals in [NormalEncoding::Signed, NormalEncoding::Unorm] {
                let label = format!("{name} {depth:?} {normals:?}");
                let far = if depth == DepthConvention::ReverseZ && name == "sun-street" {
                    f32::INFINITY
                } else {
                    far
                };
                let cam = DepthCamera::perspective(scene.camera(), near, far, depth, normals)?;
                let background = if depth == DepthConvention::ZeroToOne {
                    1.0
                } else {
                    0.0
                };
                let (mut d, mut n) = (Vec::new(), Vec::new());
                for k in 0..rec.len() {
                    if rec.active()[k] {
                        let c = cam.view_proj * rec.position()[k].extend(1.0);
                        d.push(c.z / c.w);
                        // Half the stored normals face away from the eye.
                        n.push(if k % 2 == 0 {
                            rec.normal()[k]
                        } else {
                            -rec.normal()[k]
                        });
                    } else {
                        d.push(background);
                        n.push(Vec3::Z);
                    }
                }
                let unorm = normals == NormalEncoding::Unorm;
                let dt = depth_texture(&ctx, w, h, &d)?;
                let nt = normal_texture(&ctx, w, h, &n, normals)?;
                let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("caller's receivers"),
                    size: 32 * rec.len() as u64,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                pass.encode(&ctx, &mut enc, &cam, &dt, &nt, &out)?;
                ctx.queue.submit([enc.finish()]);
                let got: Vec<ReceiverGpu> = ctx.read_buffer(&out, out.size())?;
                let n_tol = if unorm { 2.5e-3 } else { 1e-5 };
                let (mut worst_p, mut worst_n, mut active) = (0.0f32, 0.0f32, 0);
                for (k, g) in got.iter().enumerate() {
                    assert_eq!(
                        g.active == 1,
                        rec.active()[k],
                        "{label}: receiver {k} active"
                    );
                    if !rec.active()[k] {
                        assert_eq!(
                            Vec3::from(g.position),
                            Vec3::ZERO,
                            "{label}: background {k}"
                        );
                        continue;
                    }
                    active += 1;
                    let dist = (rec.position()[k] - scene.camera().eye).length();
                    let ep = (Vec3::from(g.position) - rec.position()[k]).length() / dist;
                    let en = (Vec3::from(g.normal) - rec.normal()[k]).abs().max_element();
                    worst_p = worst_p.max(ep);
                    worst_n = worst_n.max(en);
                    assert!(
                        ep <= POS_TOL,
                        "{label}: receiver {k}: position off by {ep} of its distance"
                    );
                    assert!(
                        en <= n_tol,
                        "{label}: receiver {k}: normal {:?} vs {}",
                        g.normal,
                        rec.normal()[k]
                    );
                }
                assert!(active > rec.len() / 4, "{label}: {active} active");
                println!("{label}: {active} receivers, position error <= {worst_p:.1e} of the distance, normal <= {worst_n:.1e}");
            }
        }
    }
    // Bad input: one line each, nothing recorded.
    let scene = fixture("bunny", 8, 6);
    let cam = DepthCamera::perspective(
        scene.camera(),
        0.05,
        20.0,
        DepthConvention::ZeroToOne,
        NormalEncoding::Signed,
    )?;
    let dt = depth_texture(&ctx, 8, 6, &[1.0; 48])?;
    let e = depth_texture(&ctx, 8, 6, &[1.0; 47]).unwrap_err();
    assert!(e.to_string().contains("47 depths for 8x6"), "{e}");
    let small = normal_texture(&ctx, 4, 6, &[Vec3::Z; 24], NormalEncoding::Signed)?;
    let nt = normal_texture(&ctx, 8, 6, &[Vec3::Z; 48], NormalEncoding::Signed)?;
    let e = normal_texture(&ctx, 8, 6, &[Vec3::Z; 47], NormalEncoding::Unorm).unwrap_err();
    assert!(e.to_string().contains("47 normals for 8x6"), "{e}");
    let buf = |bytes| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    };
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let e = pass
        .encode(&ctx, &mut enc, &cam, &dt, &small, &buf(32 * 48))
        .unwrap_err();
    assert!(e.to_string().contains("normal texture is 4x6"), "{e}");
    let e = pass
        .encode(&ctx, &mut enc, &cam, &dt, &nt, &buf(32 * 47))
        .unwrap_err();
    assert!(e.to_string().contains("need 1536"), "{e}");
    let mut singular = cam;
    singular.view_proj = glam::Mat4::ZERO;
    let e = pass
        .encode(&ctx, &mut enc, &singular, &dt, &nt, &buf(32 * 48))
        .unwrap_err();
    assert!(e.to_string().contains("singular"), "{e}");
    Ok(())
}
