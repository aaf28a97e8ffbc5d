//! The adapter's ceilings (`gpu_ceilings.wgsl`): taps/s, triangles/s and atomic inserts/s, the
//! plain kernel and nothing else, and the CPU twin of the tap kernel.
use crate::{
    config::Config,
    report::Row,
    timing::{time_cpu, Gpu, Stamp, StampAt, Timing},
    BenchResult,
};
use shadow_map_core::gpu::{
    depth_map::texture_desc,
    kernel::{buffer_init, shader_module},
    raster::VERTEX_BUFFERS,
    GpuContext,
};
use std::hint::black_box;
use wgpu::util::DeviceExt;

/// The ceiling kernels (taps, triangles, atomic inserts).
const CEILINGS_WGSL: &str = include_str!("../gpu_ceilings.wgsl");
/// Kernel side of the tap ceilings (`K` override of `taps_kernel`; the CPU twin uses it too).
pub const K: u32 = 15;
/// Workgroup side of `taps_kernel` (`WG` override).
const TAPS_WG: u32 = 8;
/// Workgroup size of `atomic_insert` (`WG_LINEAR` override).
const INSERT_WG: u32 = 256;

/// PCG hash, the twin of `pcg_hash` in `gpu_ceilings.wgsl`.
fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// `receiver_z` of `gpu_ceilings.wgsl`: exact in f32 on both sides.
fn receiver_z(k: u32) -> f32 {
    (pcg_hash(k) >> 8) as f32 / 16777216.0
}

/// A uniform float in [0, 1) from a hash stream.
fn unit(seed: u32, k: u32) -> f32 {
    receiver_z(pcg_hash(seed) ^ k.wrapping_mul(0x9e37_79b9))
}

/// Mirrors `TapsParams` in `gpu_ceilings.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct TapsParams {
    width: u32,
    height: u32,
    size: u32,
    _pad0: u32,
}

/// Mirrors `InsertParams` in `gpu_ceilings.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct InsertParams {
    count: u32,
    heads: u32,
    _pad0: u32,
    _pad1: u32,
}

pub fn ceilings_module(ctx: &GpuContext) -> BenchResult<wgpu::ShaderModule> {
    Ok(shader_module(ctx, "bench.ceilings", &[CEILINGS_WGSL])?)
}

fn compute_pipeline(
    ctx: &GpuContext,
    module: &wgpu::ShaderModule,
    entry: &str,
    constants: &[(&str, f64)],
) -> BenchResult<wgpu::ComputePipeline> {
    Ok(ctx.scoped(entry, || {
        ctx.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            })
    })?)
}

/// A uniform buffer holding `value`.
fn uniform<T: bytemuck::Pod>(ctx: &GpuContext, label: &str, value: &T) -> wgpu::Buffer {
    buffer_init(
        &ctx.device,
        label,
        bytemuck::bytes_of(value),
        wgpu::BufferUsages::UNIFORM,
    )
}

/// A bind group for group 0 of `pipeline` (its layout derived from the shader), from
/// `(binding, resource)` pairs.
fn bind_group(
    ctx: &GpuContext,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    entries: &[(u32, wgpu::BindingResource<'_>)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = entries
        .iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: resource.clone(),
        })
        .collect();
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    })
}

/// Records one compute pass of `pipeline` with `group` at 0, `(x, y)` workgroups, timestamps at
/// `stamp` when given.
fn compute_pass(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    stamp: Option<Stamp<'_>>,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    (x, y): (u32, u32),
) {
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: stamp.map(Stamp::compute),
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    pass.dispatch_workgroups(x, y, 1);
}

/// The random `r x r` map of the tap ceilings (depths in [0, 1)).
pub fn random_map(r: u32) -> Vec<f32> {
    (0..r * r).map(|k| unit(1, k)).collect()
}

/// Ceiling (a): `K x K` `textureLoad` taps per receiver over a `width x height` receiver grid
/// from a random `r x r` R32Float map. Returns the row and the total lit-tap count (read back
/// after timing, for the check against the CPU twin).
pub fn ceiling_taps(
    g: &Gpu,
    cfg: &Config,
    map: &[f32],
    module: &wgpu::ShaderModule,
) -> BenchResult<(Row, u64)> {
    let ctx = g.ctx;
    let (w, h, r) = (cfg.width, cfg.height, cfg.res);
    let pipeline = compute_pipeline(
        ctx,
        module,
        "taps_kernel",
        &[("K", K as f64), ("WG", TAPS_WG as f64)],
    )?;
    let (group, out) = ctx.scoped("taps_kernel", || {
        let texture = ctx.device.create_texture_with_data(
            &ctx.queue,
            &texture_desc(
                "bench.taps.map",
                r,
                r,
                1,
                wgpu::TextureFormat::R32Float,
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            ),
            wgpu::util::TextureDataOrder::LayerMajor,
            bytemuck::cast_slice(map),
        );
        let params = uniform(
            ctx,
            "bench.taps.params",
            &TapsParams {
                width: w,
                height: h,
                size: r,
                _pad0: 0,
            },
        );
        let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench.taps.out"),
            size: w as u64 * h as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let view = texture.create_view(&Default::default());
        let group = bind_group(
            ctx,
            "bench.taps",
            &pipeline,
            &[
                (0, params.as_entire_binding()),
                (1, wgpu::BindingResource::TextureView(&view)),
                (2, out.as_entire_binding()),
            ],
        );
        (group, out)
    })?;
    let groups = (w.div_ceil(TAPS_WG), h.div_ceil(TAPS_WG));
    let timing = g.time_encoded(StampAt::Pass, 0, |enc, stamp| {
        compute_pass(enc, "taps_kernel", stamp, &pipeline, &group, groups);
        Ok(())
    })?;
    let lit: Vec<u32> = ctx.read_buffer(&out, out.size())?;
    let total = lit.iter().map(|&v| v as u64).sum();
    Ok((taps_row("gpu", cfg, timing), total))
}

/// The CPU twin of `taps_kernel` (the CPU ceiling): the same receivers, map and kernel, rows in
/// parallel (rayon). Returns the total lit-tap count.
fn cpu_taps(map: &[f32], r: u32, w: u32, h: u32) -> u64 {
    use rayon::prelude::*;
    let half = (K / 2) as i32;
    let hi = r as i32 - 1;
    (0..h)
        .into_par_iter()
        .map(|y| {
            let mut lit = 0u64;
            for x in 0..w {
                let k = y * w + x;
                let cx = (x as u64 * r as u64 / w as u64) as i32;
                let cy = (y as u64 * r as u64 / h as u64) as i32;
                let z = receiver_z(k);
                let mut n = 0u32;
                for dj in -half..=half {
                    let row = (cy + dj).clamp(0, hi) as usize * r as usize;
                    for di in -half..=half {
                        let t = row + (cx + di).clamp(0, hi) as usize;
                        n += (map[t] >= z) as u32;
                    }
                }
                lit += n as u64;
            }
            lit
        })
        .sum()
}

/// The row of a tap ceiling on `backend` (`gpu` or `cpu`): W·H·K² taps per iteration.
fn taps_row(backend: &str, cfg: &Config, timing: Timing) -> Row {
    let (w, h, r) = (cfg.width, cfg.height, cfg.res);
    Row::new(
        format!("ceiling/{backend}/taps-{K}x{K}/{w}x{h}@{r}"),
        timing,
        w as f64 * h as f64 * (K * K) as f64,
        "taps",
        None,
    )
}

/// The CPU tap ceiling: [`cpu_taps`] timed over the same map and receivers as the GPU's. Returns
/// the row and the lit-tap count (to check against the GPU's).
pub fn ceiling_cpu_taps(budget_ms: f64, cfg: &Config, map: &[f32]) -> (Row, u64) {
    let (w, h, r) = (cfg.width, cfg.height, cfg.res);
    let mut lit = 0;
    let timing = time_cpu(budget_ms, || {
        lit = black_box(cpu_taps(black_box(map), r, w, h));
    });
    (taps_row("cpu", cfg, timing), lit)
}

/// Ceiling (b): `cfg.triangles` random small triangles (each within about 4 x 4 texels, random
/// depth) rendered depth-only into an `r x r` Depth32Float target, one render pass (clear,
/// draw, store) per iteration.
pub fn ceiling_triangles(g: &Gpu, cfg: &Config, module: &wgpu::ShaderModule) -> BenchResult<Row> {
    let ctx = g.ctx;
    let (m, r) = (cfg.triangles, cfg.res);
    let texel = 2.0 / r as f32;
    let mut verts: Vec<[f32; 4]> = Vec::with_capacity(3 * m as usize);
    for t in 0..m {
        let c = [unit(2, t) * 2.0 - 1.0, unit(3, t) * 2.0 - 1.0];
        let z = 0.05 + 0.9 * unit(4, t);
        for v in 0..3 {
            let s = 3 * t + v;
            verts.push([
                c[0] + (unit(5, s) * 4.0 - 2.0) * texel,
                c[1] + (unit(6, s) * 4.0 - 2.0) * texel,
                z,
                1.0,
            ]);
        }
    }
    let (pipeline, vertices, depth) = ctx.scoped("tri_vs", || {
        let pipeline = ctx
            .device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("bench.triangles"),
                layout: None,
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some("tri_vs"),
                    compilation_options: Default::default(),
                    buffers: VERTEX_BUFFERS,
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: None,
                multiview_mask: None,
                cache: None,
            });
        let vertices = buffer_init(
            &ctx.device,
            "bench.triangles.vertices",
            bytemuck::cast_slice(&verts),
            wgpu::BufferUsages::VERTEX,
        );
        let depth = ctx
            .device
            .create_texture(&texture_desc(
                "bench.triangles.depth",
                r,
                r,
                1,
                wgpu::TextureFormat::Depth32Float,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            ))
            .create_view(&Default::default());
        (pipeline, vertices, depth)
    })?;
    let timing = g.time_encoded(StampAt::Pass, 0, |enc, stamp| {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("bench.triangles"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: stamp.map(Stamp::render),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_vertex_buffer(0, vertices.slice(..));
        pass.draw(0..3 * m, 0..1);
        Ok(())
    })?;
    Ok(Row::new(
        format!("ceiling/gpu/triangles/{m}@{r}"),
        timing,
        m as f64,
        "triangles",
        None,
    ))
}

/// Ceiling (c): `cfg.inserts` linked-list inserts (one per thread: atomicAdd on a node counter,
/// atomicExchange on a list head, one node written) into `inserts / 4` lists. Counter and heads
/// are cleared before each pass (outside the timestamps, inside the wall clock). Returns the row
/// and the final counter (read back after timing; must equal the insert count).
pub fn ceiling_inserts(
    g: &Gpu,
    cfg: &Config,
    module: &wgpu::ShaderModule,
) -> BenchResult<(Row, u32)> {
    let ctx = g.ctx;
    let max_nodes = ctx.limits().max_storage_buffer_binding_size / 8;
    let count = (cfg.inserts as u64).min(max_nodes) as u32;
    let heads = (count / 4).max(1);
    let pipeline = compute_pipeline(
        ctx,
        module,
        "atomic_insert",
        &[("WG_LINEAR", INSERT_WG as f64)],
    )?;
    let (group, counter, head_buf) = ctx.scoped("atomic_insert", || {
        let params = uniform(
            ctx,
            "bench.inserts.params",
            &InsertParams {
                count,
                heads,
                _pad0: 0,
                _pad1: 0,
            },
        );
        let buffer = |label, size: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let counter = buffer("bench.inserts.counter", 4);
        let head_buf = buffer("bench.inserts.heads", heads as u64 * 4);
        let nodes = buffer("bench.inserts.nodes", count as u64 * 8);
        let group = bind_group(
            ctx,
            "bench.inserts",
            &pipeline,
            &[
                (3, params.as_entire_binding()),
                (4, counter.as_entire_binding()),
                (5, head_buf.as_entire_binding()),
                (6, nodes.as_entire_binding()),
            ],
        );
        (group, counter, head_buf)
    })?;
    let groups = count.div_ceil(INSERT_WG);
    let gx = groups.min(ctx.limits().max_compute_workgroups_per_dimension);
    let gy = groups.div_ceil(gx);
    let timing = g.time_encoded(StampAt::Pass, 0, |enc, stamp| {
        enc.clear_buffer(&counter, 0, None);
        enc.clear_buffer(&head_buf, 0, None);
        compute_pass(enc, "atomic_insert", stamp, &pipeline, &group, (gx, gy));
        Ok(())
    })?;
    let c: Vec<u32> = ctx.read_buffer(&counter, 4)?;
    Ok((
        Row::new(
            format!("ceiling/gpu/atomic-insert/{count}"),
            timing,
            count as f64,
            "inserts",
            None,
        ),
        c.first().copied().unwrap_or(0),
    ))
}
