//! What every baseline kernel needs on the wgpu side: shader modules assembled from their WGSL
//! parts, the one bind-group layout they share, and receivers split into chunks that fit the
//! device's limits (storage-binding size, buffer size, workgroups per dispatch dimension).
use super::shared::{OVERRIDES, WORKGROUP_SIZE};
use shadow_map_core::{
    gpu::{shared::pack_receivers, GpuContext},
    DepthPrecision, Receivers, Result,
};
use wgpu::util::DeviceExt;

/// WGSL of binding 2 and `fn depth_texel(i, j) -> f32` for an R32Float map (`depth=f32`).
pub const DEPTH_F32_WGSL: &str = include_str!("depth_f32.wgsl");
/// WGSL of binding 2 and `fn depth_texel(i, j) -> f32` for packed 16-bit codes (`depth=unorm16`).
pub const DEPTH_UNORM16_WGSL: &str = include_str!("depth_unorm16.wgsl");

/// The depth-access WGSL part for a precision.
pub const fn depth_wgsl(depth: DepthPrecision) -> &'static str {
    match depth {
        DepthPrecision::F32 => DEPTH_F32_WGSL,
        DepthPrecision::Unorm16 => DEPTH_UNORM16_WGSL,
    }
}

/// Concatenates WGSL parts (the core's `SHARED_WGSL` first) into one module source.
pub fn shader_source(parts: &[&str]) -> String {
    parts.concat()
}

/// Creates a shader module from its parts inside an error scope named after `label`.
pub(crate) fn shader_module(
    ctx: &GpuContext,
    label: &str,
    parts: &[&str],
) -> Result<wgpu::ShaderModule> {
    let src = shader_source(parts);
    ctx.scoped(label, || {
        ctx.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            })
    })
}

/// The bind-group layout of every baseline kernel:
/// 0 light view (uniform), 1 [`EstimateUniform`](super::shared::EstimateUniform) (uniform),
/// 2 depth map (`texture_2d<f32>`, R32Float, under `depth=f32`; read-only storage of packed
/// 16-bit codes under `depth=unorm16`), 3 receivers (read-only storage),
/// 4 and 5 read-write storage (V bits and counters, or accumulator and V bits).
pub(crate) fn bind_group_layout(
    ctx: &GpuContext,
    label: &str,
    depth: DepthPrecision,
) -> wgpu::BindGroupLayout {
    let buffer = |binding, ty| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let storage = |read_only| wgpu::BufferBindingType::Storage { read_only };
    ctx.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &[
                buffer(0, wgpu::BufferBindingType::Uniform),
                buffer(1, wgpu::BufferBindingType::Uniform),
                match depth {
                    DepthPrecision::F32 => wgpu::BindGroupLayoutEntry {
                        binding: 2,
                        visibility: wgpu::ShaderStages::COMPUTE,
                        ty: wgpu::BindingType::Texture {
                            sample_type: wgpu::TextureSampleType::Float { filterable: false },
                            view_dimension: wgpu::TextureViewDimension::D2,
                            multisampled: false,
                        },
                        count: None,
                    },
                    DepthPrecision::Unorm16 => buffer(2, storage(true)),
                },
                buffer(3, storage(true)),
                buffer(4, storage(false)),
                buffer(5, storage(false)),
            ],
        })
}

/// A compute pipeline for entry point `entry` of `module`, with the baselines' overrides set.
pub(crate) fn compute_pipeline(
    ctx: &GpuContext,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    entry: &str,
) -> Result<wgpu::ComputePipeline> {
    ctx.scoped(label, || {
        let pl = ctx
            .device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(layout)],
                immediate_size: 0,
            });
        ctx.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: Some(&pl),
                module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: OVERRIDES,
                    zero_initialize_workgroup_memory: true,
                },
                cache: None,
            })
    })
}

/// A uniform buffer holding `value`.
pub(crate) fn uniform<T: bytemuck::Pod>(ctx: &GpuContext, label: &str, value: &T) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::bytes_of(value),
            usage: wgpu::BufferUsages::UNIFORM,
        })
}

/// Most receivers one dispatch may cover on this device: limited by the storage-binding and
/// buffer sizes (32 bytes per receiver) and by 1D dispatch (`max workgroups per dimension x
/// WORKGROUP_SIZE`), and by `cap` (tests pass small values to exercise chunking).
pub fn max_chunk(ctx: &GpuContext, cap: usize) -> usize {
    let l = ctx.limits();
    let per = std::mem::size_of::<shadow_map_core::gpu::shared::ReceiverGpu>() as u64;
    let by_binding = l.max_storage_buffer_binding_size / per;
    let by_buffer = l.max_buffer_size / per;
    let by_dispatch = l.max_compute_workgroups_per_dimension as u64 * WORKGROUP_SIZE as u64;
    let m = by_binding.min(by_buffer).min(by_dispatch).min(cap as u64);
    (m as usize).max(1)
}

/// One chunk of receivers: its slice of the receiver array and its own buffers.
pub(crate) struct ReceiverChunk {
    /// First receiver index of the chunk.
    pub start: usize,
    /// Receivers in the chunk (> 0).
    pub len: usize,
    /// `array<ReceiverGpu>` of the chunk.
    pub receivers: wgpu::Buffer,
    /// `array<u32>`: V bits per receiver (copied back).
    pub out: wgpu::Buffer,
    /// `array<f32>` per receiver, zeroed (multi-sample's accumulator), when asked for.
    pub acc: Option<wgpu::Buffer>,
}

impl ReceiverChunk {
    /// Workgroups covering the chunk (at most the device's per-dimension limit, by
    /// [`max_chunk`]).
    pub fn workgroups(&self) -> u32 {
        self.len.div_ceil(WORKGROUP_SIZE as usize) as u32
    }
}

/// Packs and uploads the receivers in chunks of at most `chunk` (none for zero receivers).
pub(crate) fn upload_receivers(
    ctx: &GpuContext,
    receivers: &Receivers,
    chunk: usize,
    with_acc: bool,
) -> Vec<ReceiverChunk> {
    let packed = pack_receivers(receivers);
    let chunk = chunk.max(1);
    packed
        .chunks(chunk)
        .enumerate()
        .map(|(c, part)| {
            let len = part.len();
            let receivers = ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("baselines receivers"),
                    contents: bytemuck::cast_slice(part),
                    usage: wgpu::BufferUsages::STORAGE,
                });
            let storage = |label| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: (len * 4) as u64,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    // Zeroed by wgpu on creation.
                    mapped_at_creation: false,
                })
            };
            ReceiverChunk {
                start: c * chunk,
                len,
                receivers,
                out: storage("baselines V"),
                acc: with_acc.then(|| storage("baselines accumulator")),
            }
        })
        .collect()
}

/// Reads every chunk's V back into `v` (f32 bits; NaN bits for inactive receivers).
pub(crate) fn read_v(ctx: &GpuContext, chunks: &[ReceiverChunk], v: &mut [f32]) -> Result<()> {
    for c in chunks {
        let part: Vec<f32> = ctx.read_buffer(&c.out, (c.len * 4) as u64)?;
        v[c.start..c.start + c.len].copy_from_slice(&part);
    }
    Ok(())
}
