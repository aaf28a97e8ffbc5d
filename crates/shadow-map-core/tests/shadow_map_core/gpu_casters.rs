//! Casters from the caller's vertex and index buffers (`gpu::casters`): the bunny
//! fixture's triangles split into three meshes stored three ways (interleaved vertices with
//! `u32` indices, a shifted vertex range with `u16` indices and a `base_vertex`, plain
//! non-indexed positions), drawn as five instances. With identity transforms the built buffer is
//! bit for bit what `GpuScene::upload` writes for the scene (so every raster pass sees the same
//! casters); with moved instances each triangle is the CPU's `transform * p` within 1e-5 of the
//! scene's size. Bad meshes, instances and capacities are one-line errors before anything is
//! recorded.
#![cfg(feature = "gpu")]

use crate::common;

use glam::{Mat4, Quat, Vec3};
use shadow_map_core::{
    gpu::{
        casters::{CasterIndices, CasterInstance, CasterMesh, GpuCasterBuilder},
        GpuContext, GpuScene,
    },
    Error, Scene,
};
use std::path::PathBuf;
use wgpu::util::DeviceExt;

fn storage(ctx: &GpuContext, bytes: &[u8]) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("caller's mesh"),
            contents: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::VERTEX,
        })
}

/// The caller's three meshes holding `tris` in order: (vertex buffer, stride, offset, indices,
/// first index, count, base vertex) as plain data.
struct Meshes {
    a_vertices: wgpu::Buffer,
    a_indices: wgpu::Buffer,
    b_vertices: wgpu::Buffer,
    b_indices: wgpu::Buffer,
    c_vertices: wgpu::Buffer,
    counts: [u32; 3],
}

impl Meshes {
    fn new(ctx: &GpuContext, tris: &[[Vec3; 3]]) -> Meshes {
        let n = tris.len();
        let (a, rest) = tris.split_at(n / 2);
        let (b, c) = rest.split_at((rest.len() / 2).min(20_000));
        // Mesh A: 8-float vertices (normal, position, uv), every vertex once, listed backwards;
        // u32 indices point at them.
        let mut va = Vec::new();
        let verts_a: Vec<Vec3> = a.iter().flatten().copied().collect();
        for p in verts_a.iter().rev() {
            va.extend_from_slice(&[0.0, 1.0, 0.0, p.x, p.y, p.z, 0.5, 0.5]);
        }
        let ia: Vec<u32> = (0..verts_a.len() as u32)
            .map(|i| verts_a.len() as u32 - 1 - i)
            .collect();
        // Mesh B: 4-float vertices after 7 junk ones, u16 indices from 0, base_vertex 7, and
        // 5 junk indices before the first.
        let mut vb = vec![f32::NAN; 7 * 4];
        for p in b.iter().flatten() {
            vb.extend_from_slice(&[p.x, p.y, p.z, 1.0]);
        }
        let mut ib: Vec<u16> = vec![9999; 5];
        ib.extend((0..3 * b.len() as u32).map(|i| i as u16));
        if ib.len() % 2 == 1 {
            ib.push(0);
        }
        // Mesh C: packed positions (12-byte vertices), not indexed.
        let vc: Vec<f32> = c.iter().flatten().flat_map(|p| [p.x, p.y, p.z]).collect();
        Meshes {
            a_vertices: storage(ctx, bytemuck::cast_slice(&va)),
            a_indices: storage(ctx, bytemuck::cast_slice(&ia)),
            b_vertices: storage(ctx, bytemuck::cast_slice(&vb)),
            b_indices: storage(ctx, bytemuck::cast_slice(&ib)),
            c_vertices: storage(ctx, bytemuck::cast_slice(&vc)),
            counts: [3 * a.len() as u32, 3 * b.len() as u32, 3 * c.len() as u32],
        }
    }

    fn list(&self) -> Vec<CasterMesh<'_>> {
        vec![
            CasterMesh {
                vertices: &self.a_vertices,
                vertex_stride: 32,
                position_offset: 12,
                indices: CasterIndices::U32(&self.a_indices),
                first_index: 0,
                index_count: self.counts[0],
                base_vertex: 0,
                opacity: 1.0,
            },
            CasterMesh {
                vertices: &self.b_vertices,
                vertex_stride: 16,
                position_offset: 0,
                indices: CasterIndices::U16(&self.b_indices),
                first_index: 5,
                index_count: self.counts[1],
                base_vertex: 7,
                opacity: 1.0,
            },
            CasterMesh {
                vertices: &self.c_vertices,
                vertex_stride: 12,
                position_offset: 0,
                indices: CasterIndices::None,
                first_index: 0,
                index_count: self.counts[2],
                base_vertex: 0,
                opacity: 1.0,
            },
        ]
    }
}

fn read(ctx: &GpuContext, s: &GpuScene) -> Result<Vec<[f32; 4]>, Error> {
    ctx.read_buffer(&s.vertices, 48 * s.triangles as u64)
}

#[test]
fn caller_meshes_and_instances_build_the_casters() -> Result<(), Error> {
    let Some(ctx) = common::context_for_tests("caller_meshes_and_instances_build_the_casters")?
    else {
        return Ok(());
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bunny/bunny.toml");
    let scene = Scene::load(&path)?;
    let meshes = Meshes::new(&ctx, scene.triangles());
    let mut list = meshes.list();
    let builder = GpuCasterBuilder::new(&ctx, 4, 8)?;

    // Identity instances in mesh order: the scene's own triangles, bit for bit.
    let id: Vec<CasterInstance> = (0..3)
        .map(|mesh| CasterInstance {
            mesh,
            transform: Mat4::IDENTITY,
        })
        .collect();
    let mut out = GpuScene::with_capacity(&ctx, scene.triangles().len() as u32 * 2)?;
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    builder.encode(&ctx, &mut enc, &list, &id, &mut out)?;
    ctx.queue.submit([enc.finish()]);
    assert_eq!(out.triangles as usize, scene.triangles().len());
    let uploaded = GpuScene::upload(&ctx, &scene)?;
    let (got, want) = (read(&ctx, &out)?, read(&ctx, &uploaded)?);
    let same = got
        .iter()
        .zip(&want)
        .filter(|(a, b)| bytemuck::bytes_of(*a) == bytemuck::bytes_of(*b))
        .count();
    assert_eq!(same, want.len(), "identity casters differ from the upload");
    assert!(out.is_opaque() && uploaded.is_opaque());

    // An opacity outside [0, 1] is refused before anything is recorded.
    list[1].opacity = 1.5;
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let err = builder
        .encode(&ctx, &mut enc, &list, &id, &mut out)
        .expect_err("opacity 1.5");
    assert!(err.to_string().contains("opacity 1.5"), "{err}");
    // Mesh 1 semi-transparent from here on: its opacity is each of its vertices' w.
    list[1].opacity = 0.25;

    // Moved instances: mesh 0 twice (the second turned and shifted), mesh 2 scaled, mesh 1
    // shifted; the output lists mesh 0's instances, then mesh 1's, then mesh 2's.
    let turn =
        Mat4::from_rotation_translation(Quat::from_rotation_y(0.7), Vec3::new(2.0, 0.0, -1.0));
    let instances = [
        CasterInstance {
            mesh: 2,
            transform: Mat4::from_scale(Vec3::new(1.5, 0.5, 2.0)),
        },
        CasterInstance {
            mesh: 0,
            transform: Mat4::IDENTITY,
        },
        CasterInstance {
            mesh: 1,
            transform: Mat4::from_translation(Vec3::new(0.0, 3.0, 0.0)),
        },
        CasterInstance {
            mesh: 0,
            transform: turn,
        },
    ];
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    builder.encode(&ctx, &mut enc, &list, &instances, &mut out)?;
    ctx.queue.submit([enc.finish()]);
    let mut expect: Vec<Vec3> = Vec::new();
    let mut expect_w: Vec<f32> = Vec::new();
    let ranges = [
        0..list[0].index_count as usize / 3,
        list[0].index_count as usize / 3..(list[0].index_count + list[1].index_count) as usize / 3,
        (list[0].index_count + list[1].index_count) as usize / 3..scene.triangles().len(),
    ];
    for (mesh, r) in ranges.iter().enumerate() {
        for inst in instances.iter().filter(|i| i.mesh == mesh) {
            for t in &scene.triangles()[r.clone()] {
                expect.extend(t.iter().map(|p| inst.transform.transform_point3(*p)));
                expect_w.extend([list[mesh].opacity; 3]);
            }
        }
    }
    assert_eq!(out.triangles as usize * 3, expect.len());
    let got = read(&ctx, &out)?;
    let diag = scene.bounds().diagonal();
    let mut worst = 0.0f32;
    for (k, (g, e)) in got.iter().zip(&expect).enumerate() {
        assert_eq!(g[3], expect_w[k], "vertex {k}: w (its mesh's opacity)");
        let d = (Vec3::new(g[0], g[1], g[2]) - *e).abs().max_element();
        worst = worst.max(d);
        assert!(d <= 1e-5 * diag, "vertex {k}: {g:?} vs {e}");
    }
    assert!(
        !out.is_opaque(),
        "a mesh of opacity 0.25 makes the casters semi-transparent"
    );
    println!(
        "{} triangles from 4 instances of 3 meshes, largest error {worst:.1e} (scene diagonal {diag:.2})",
        out.triangles
    );

    // Bad input: one line each.
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let mut small = GpuScene::with_capacity(&ctx, 10)?;
    let expect_err = |r: Result<(), Error>, what: &str| {
        let e = r.expect_err(what).to_string();
        assert!(e.contains(what), "{e}");
        assert!(!e.contains('\n'), "{e}");
    };
    let one = |mesh| {
        [CasterInstance {
            mesh,
            transform: Mat4::IDENTITY,
        }]
    };
    expect_err(
        builder.encode(&ctx, &mut enc, &list, &one(3), &mut out),
        "names mesh 3 of 3",
    );
    expect_err(
        builder.encode(&ctx, &mut enc, &list, &one(0), &mut small),
        "GpuScene::with_capacity",
    );
    let mut bad = list.clone();
    bad[1].vertex_stride = 14;
    expect_err(
        builder.encode(&ctx, &mut enc, &bad, &one(1), &mut out),
        "multiples of 4",
    );
    let mut bad = list.clone();
    bad[1].first_index = 40_000_000;
    expect_err(
        builder.encode(&ctx, &mut enc, &bad, &one(1), &mut out),
        "beyond the buffer",
    );
    let mut bad = list.clone();
    bad[2].index_count = 4;
    expect_err(
        builder.encode(&ctx, &mut enc, &bad, &one(2), &mut out),
        "whole triangles",
    );
    let plain = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 1200,
        usage: wgpu::BufferUsages::VERTEX,
        mapped_at_creation: false,
    });
    let mut bad = list.clone();
    bad[2].vertices = &plain;
    bad[2].index_count = 3;
    expect_err(
        builder.encode(&ctx, &mut enc, &bad, &one(2), &mut out),
        "STORAGE usage",
    );
    let nan = [CasterInstance {
        mesh: 0,
        transform: Mat4::from_scale(Vec3::splat(f32::NAN)),
    }];
    expect_err(
        builder.encode(&ctx, &mut enc, &list, &nan, &mut out),
        "non-finite transform",
    );
    let many = [one(0)[0]; 9];
    expect_err(
        builder.encode(&ctx, &mut enc, &list, &many, &mut out),
        "GpuCasterBuilder::new",
    );
    Ok(())
}
