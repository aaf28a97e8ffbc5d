//! The compute-kernel layer every method's frame builds on: shader modules assembled from WGSL
//! parts, bind-group layouts read from the WGSL itself ([`bindings_of`]: what the shader
//! declares is what the layout holds, so the two cannot disagree), bind groups, compute
//! pipelines with their override constants, all inside labelled error scopes; uniform buffers;
//! planes in texture arrays.
//!
//! One kernel in three lines:
//!
//! ```no_run
//! use shadow_map_core::gpu::{kernel::SpecializedKernel, GpuContext};
//! # fn demo(ctx: &GpuContext, wgsl: &str) -> shadow_map_core::Result<()> {
//! let k = SpecializedKernel::new(ctx, "my estimate", &[wgsl], "estimate", &[("WG", 64.0)])?;
//! let k = k.fixed(ctx)?; // one pipeline, no switch left
//! # let _ = k; Ok(()) }
//! ```
use super::{depth_map::texture_desc, GpuContext};
use crate::Result;

/// What one binding of a compute kernel is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binding {
    /// `var<uniform>`.
    Uniform,
    /// `var<storage, read>`.
    Storage,
    /// `var<storage, read_write>`.
    StorageRw,
    /// `texture_2d<f32>`, not filterable (R32Float maps).
    Texture2d,
    /// `texture_2d_array<f32>`, not filterable (layers, MSSM levels).
    Texture2dArray,
    /// `texture_depth_2d` (a caller's depth attachment, read with `textureLoad`).
    TextureDepth2d,
    /// `texture_storage_2d_array<r32float, write>`.
    StorageTexture2dArrayR32Write,
    /// `texture_storage_2d<r32float, write>`.
    StorageTexture2dR32Write,
}

impl Binding {
    /// The layout entry of this binding at `binding` (compute stage only).
    pub fn entry(self, binding: u32) -> wgpu::BindGroupLayoutEntry {
        self.entry_in(binding, wgpu::ShaderStages::COMPUTE)
    }

    /// The layout entry of this binding at `binding`, visible to `visibility`.
    pub fn entry_in(
        self,
        binding: u32,
        visibility: wgpu::ShaderStages,
    ) -> wgpu::BindGroupLayoutEntry {
        let buffer = |ty| wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let texture = |view_dimension| wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension,
            multisampled: false,
        };
        let ty = match self {
            Binding::Uniform => buffer(wgpu::BufferBindingType::Uniform),
            Binding::Storage => buffer(wgpu::BufferBindingType::Storage { read_only: true }),
            Binding::StorageRw => buffer(wgpu::BufferBindingType::Storage { read_only: false }),
            Binding::Texture2d => texture(wgpu::TextureViewDimension::D2),
            Binding::Texture2dArray => texture(wgpu::TextureViewDimension::D2Array),
            Binding::TextureDepth2d => wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Depth,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            Binding::StorageTexture2dArrayR32Write => wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format: wgpu::TextureFormat::R32Float,
                view_dimension: wgpu::TextureViewDimension::D2Array,
            },
            Binding::StorageTexture2dR32Write => wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format: wgpu::TextureFormat::R32Float,
                view_dimension: wgpu::TextureViewDimension::D2,
            },
        };
        wgpu::BindGroupLayoutEntry {
            binding,
            visibility,
            ty,
            count: None,
        }
    }
}

/// Concatenates WGSL parts (shared structs first) into one module source.
pub fn shader_source(parts: &[&str]) -> String {
    parts.concat()
}

/// Creates a shader module from its parts inside an error scope named after `label`.
pub fn shader_module(ctx: &GpuContext, label: &str, parts: &[&str]) -> Result<wgpu::ShaderModule> {
    let src = shader_source(parts);
    ctx.scoped(label, || wgsl_module(&ctx.device, label, &src))
}

/// Creates the shader module `label` from WGSL source (in the caller's error scope).
pub fn wgsl_module(device: &wgpu::Device, label: &str, src: &str) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    })
}

/// The group-0 bindings `parts` (joined in order) declare, by binding number: what a compute
/// kernel's layout holds. Errors: WGSL that does not parse, or a resource kind no kernel here
/// uses ([`Error::Gpu`](crate::Error::Gpu), named after `label`).
pub fn bindings_of(label: &str, parts: &[&str]) -> Result<Vec<(u32, Binding)>> {
    use naga::{AddressSpace, ImageClass, ImageDimension, StorageAccess, TypeInner};
    const R32: naga::StorageFormat = naga::StorageFormat::R32Float;
    const WRITE: StorageAccess = StorageAccess::STORE;
    let err = |reason: String| crate::Error::Gpu {
        stage: label.to_string(),
        reason,
    };
    let module = naga::front::wgsl::parse_str(&shader_source(parts))
        .map_err(|e| err(format!("WGSL does not parse: {e}")))?;
    let mut out = Vec::new();
    for (_, var) in module.global_variables.iter() {
        let Some(rb) = var.binding.as_ref().filter(|rb| rb.group == 0) else {
            continue;
        };
        let inner = &module.types[var.ty].inner;
        let kind = match (var.space, inner) {
            (AddressSpace::Uniform, _) => Binding::Uniform,
            (AddressSpace::Storage { access }, _) if access.contains(StorageAccess::STORE) => {
                Binding::StorageRw
            }
            (AddressSpace::Storage { .. }, _) => Binding::Storage,
            (
                AddressSpace::Handle,
                TypeInner::Image {
                    dim: ImageDimension::D2,
                    arrayed,
                    class,
                },
            ) => match (class, arrayed) {
                (ImageClass::Sampled { multi: false, .. }, false) => Binding::Texture2d,
                (ImageClass::Sampled { multi: false, .. }, true) => Binding::Texture2dArray,
                (ImageClass::Depth { multi: false }, false) => Binding::TextureDepth2d,
                (
                    ImageClass::Storage {
                        format: R32,
                        access,
                    },
                    arrayed,
                ) if *access == WRITE => {
                    if *arrayed {
                        Binding::StorageTexture2dArrayR32Write
                    } else {
                        Binding::StorageTexture2dR32Write
                    }
                }
                _ => return Err(err(format!("binding {}: {class:?}", rb.binding))),
            },
            (space, _) => return Err(err(format!("binding {}: {space:?}", rb.binding))),
        };
        out.push((rb.binding, kind));
    }
    out.sort_by_key(|&(k, _)| k);
    Ok(out)
}

/// The bind-group layout of what `parts` declare ([`bindings_of`]).
pub fn bind_group_layout_of(
    ctx: &GpuContext,
    label: &str,
    parts: &[&str],
) -> Result<wgpu::BindGroupLayout> {
    let bindings = bindings_of(label, parts)?;
    ctx.scoped(label, || bind_group_layout_at(ctx, label, &bindings))
}

/// The bind-group layout of `bindings` (binding `k` is `bindings[k]`).
pub fn bind_group_layout(
    ctx: &GpuContext,
    label: &str,
    bindings: &[Binding],
) -> wgpu::BindGroupLayout {
    let indexed: Vec<_> = (0u32..).zip(bindings.iter().copied()).collect();
    bind_group_layout_at(ctx, label, &indexed)
}

/// The bind-group layout of `(binding index, kind)` pairs, for layouts whose indices are not
/// `0..n` (a frame's bindings numbered as its WGSL declares them).
pub fn bind_group_layout_at(
    ctx: &GpuContext,
    label: &str,
    bindings: &[(u32, Binding)],
) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = bindings.iter().map(|&(k, b)| b.entry(k)).collect();
    ctx.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &entries,
        })
}

/// A compute pipeline for entry point `entry` of `module` over one bind group of `layout`, with
/// the pipeline-overridable `constants` set, inside an error scope named after `label`.
pub fn compute_pipeline(
    ctx: &GpuContext,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    entry: &str,
    constants: &[(&str, f64)],
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
                    constants,
                    zero_initialize_workgroup_memory: true,
                },
                cache: None,
            })
    })
}

/// One compiled compute kernel: its bind-group layout and pipeline.
#[derive(Debug, Clone)]
pub struct Kernel {
    /// The layout of its one bind group.
    pub layout: wgpu::BindGroupLayout,
    /// The pipeline.
    pub pipeline: wgpu::ComputePipeline,
}

impl Kernel {
    /// A bind group of this kernel's layout: `resources[k]` at binding `k`.
    pub fn bind_group(
        &self,
        ctx: &GpuContext,
        label: &str,
        resources: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        bind_group(ctx, label, &self.layout, resources)
    }
}

/// A kernel whose pipelines are specialised per frame: what it switches on per frame but never
/// per receiver (the light's shape, a setting's variant) is a WGSL override constant rather than
/// a uniform, so the driver's compiler drops the branches not taken. A lane-predicated device
/// (lavapipe) pays for both sides of a uniform branch (docs/gpu.md, "Specialised kernels"); on
/// other devices it saves registers. Each entry point and combination of switches is compiled at
/// its first use and kept.
#[derive(Debug)]
pub struct SpecializedKernel {
    /// The layout of its one bind group.
    pub layout: wgpu::BindGroupLayout,
    label: String,
    module: wgpu::ShaderModule,
    entry: String,
    constants: Vec<(String, f64)>,
    /// Keyed by the entry point and the switches' names and values (as bits).
    pipelines: std::sync::Mutex<std::collections::HashMap<PipelineKey, wgpu::ComputePipeline>>,
}

type PipelineKey = (String, Vec<(String, u64)>);

impl SpecializedKernel {
    /// Compiles `parts` (joined in order) for bind groups of the bindings they declare
    /// ([`bindings_of`]); the pipelines of `entry` (and of the module's other entry points),
    /// with the override `constants` set, come from [`pipeline`](Self::pipeline) and
    /// [`entry_pipeline`](Self::entry_pipeline).
    pub fn new(
        ctx: &GpuContext,
        label: &str,
        parts: &[&str],
        entry: &str,
        constants: &[(&str, f64)],
    ) -> Result<Self> {
        let module = shader_module(ctx, label, parts)?;
        let layout = bind_group_layout_of(ctx, label, parts)?;
        Ok(SpecializedKernel {
            layout,
            label: label.to_string(),
            module,
            entry: entry.to_string(),
            constants: constants.iter().map(|&(k, v)| (k.to_string(), v)).collect(),
            pipelines: Default::default(),
        })
    }

    /// The kernel with no switch left: the pipeline of its entry point with the constants given
    /// at [`new`](Self::new), and its layout.
    pub fn fixed(self, ctx: &GpuContext) -> Result<Kernel> {
        let pipeline = self.pipeline(ctx, &[])?;
        Ok(Kernel {
            layout: self.layout,
            pipeline,
        })
    }

    /// The pipeline of the kernel's entry point with the override constants `switches` set
    /// besides those given at [`new`](Self::new), compiled on the first call with these values.
    pub fn pipeline(
        &self,
        ctx: &GpuContext,
        switches: &[(&str, f64)],
    ) -> Result<wgpu::ComputePipeline> {
        self.entry_pipeline(ctx, &self.entry, switches)
    }

    /// [`pipeline`](Self::pipeline) of another entry point of the module.
    pub fn entry_pipeline(
        &self,
        ctx: &GpuContext,
        entry: &str,
        switches: &[(&str, f64)],
    ) -> Result<wgpu::ComputePipeline> {
        let key: PipelineKey = (
            entry.to_string(),
            switches
                .iter()
                .map(|&(k, v)| (k.to_string(), v.to_bits()))
                .collect(),
        );
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = pipelines.get(&key) {
            return Ok(p.clone());
        }
        let mut constants: Vec<(&str, f64)> = self
            .constants
            .iter()
            .map(|(k, v)| (k.as_str(), *v))
            .collect();
        constants.extend_from_slice(switches);
        let label = if entry == self.entry {
            self.label.clone()
        } else {
            format!("{} {entry}", self.label)
        };
        let p = compute_pipeline(ctx, &label, &self.module, &self.layout, entry, &constants)?;
        pipelines.insert(key, p.clone());
        Ok(p)
    }

    /// How many pipelines it has compiled.
    pub fn compiled(&self) -> usize {
        self.pipelines.lock().map_or(0, |p| p.len())
    }
}

/// Encodes a group unused for this many encodes of its frame is kept through
/// ([`BindGroupCache::next_encode`]): room for a few frames recorded in turn from other buffers
/// (two lights, two cameras) without holding a caller's old buffers for long.
const KEEP_ENCODES: u64 = 4;

/// The bind groups a frame's `encode` makes, kept while what they bind stays the same (the
/// same layout, and per binding the same buffer range, texture view or sampler), so a frame
/// recorded every frame from the same buffers makes none after the first. A cached group holds
/// the resources it binds: groups not asked for during the last 4 encodes are
/// dropped, and with them the buffers a caller has since replaced.
#[derive(Debug, Default)]
pub struct BindGroupCache {
    inner: std::sync::Mutex<CacheInner>,
}

#[derive(Debug, Default)]
struct CacheInner {
    encode: u64,
    groups: std::collections::HashMap<GroupKey, (wgpu::BindGroup, u64)>,
}

#[derive(Debug, PartialEq, Eq, Hash)]
struct GroupKey {
    layout: wgpu::BindGroupLayout,
    entries: Vec<(u32, Bound)>,
}

#[derive(Debug, PartialEq, Eq, Hash)]
enum Bound {
    Buffer(wgpu::Buffer, u64, Option<std::num::NonZeroU64>),
    View(wgpu::TextureView),
    Sampler(wgpu::Sampler),
}

impl BindGroupCache {
    /// Marks the start of an encode: groups no encode asked for during the last
    /// 4 are dropped.
    pub fn next_encode(&self) {
        let mut c = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        c.encode += 1;
        let oldest = c.encode.saturating_sub(KEEP_ENCODES);
        c.groups.retain(|_, (_, used)| *used >= oldest);
    }

    /// The bind group of `layout` with `entries`, made on `ctx` only when no cached group binds
    /// the same; entries of resource arrays are never cached.
    pub fn get(
        &self,
        ctx: &GpuContext,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        entries: &[wgpu::BindGroupEntry<'_>],
    ) -> wgpu::BindGroup {
        let make = || {
            ctx.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries,
            })
        };
        let bound: Option<Vec<(u32, Bound)>> = entries
            .iter()
            .map(|e| {
                Some((
                    e.binding,
                    match &e.resource {
                        wgpu::BindingResource::Buffer(b) => {
                            Bound::Buffer(b.buffer.clone(), b.offset, b.size)
                        }
                        wgpu::BindingResource::TextureView(v) => Bound::View((*v).clone()),
                        wgpu::BindingResource::Sampler(s) => Bound::Sampler((*s).clone()),
                        _ => return None,
                    },
                ))
            })
            .collect();
        let Some(entries) = bound else {
            return make();
        };
        let key = GroupKey {
            layout: layout.clone(),
            entries,
        };
        let mut c = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let now = c.encode;
        let (group, used) = c.groups.entry(key).or_insert_with(|| (make(), now));
        *used = now;
        group.clone()
    }

    /// [`get`](Self::get) with `resources[k]` at binding `k`.
    pub fn get_dense(
        &self,
        ctx: &GpuContext,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        resources: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        self.get(ctx, label, layout, &dense_entries(resources))
    }
}

/// `resources[k]` as the entry of binding `k`.
fn dense_entries<'a>(resources: &[wgpu::BindingResource<'a>]) -> Vec<wgpu::BindGroupEntry<'a>> {
    resources
        .iter()
        .zip(0u32..)
        .map(|(r, k)| wgpu::BindGroupEntry {
            binding: k,
            resource: r.clone(),
        })
        .collect()
}

/// A bind group of `layout`: `resources[k]` at binding `k`.
pub fn bind_group(
    ctx: &GpuContext,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: &[wgpu::BindingResource<'_>],
) -> wgpu::BindGroup {
    ctx.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &dense_entries(resources),
    })
}

/// A buffer of `usage` holding `contents` (the bytes of a Pod value or slice), made as
/// [`BufferInitExt::create_buffer_init`] makes it (no panic on a lost device).
pub fn buffer_init(
    device: &wgpu::Device,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
}

/// An unmapped `UNIFORM | COPY_DST` buffer of `bytes` bytes (written with `write_buffer`).
pub fn uniform_buffer(ctx: &GpuContext, label: &str, bytes: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// An unmapped `STORAGE | COPY_SRC | COPY_DST` buffer of `bytes` bytes: written by kernels or
/// cleared and filled from the CPU, and read back.
pub fn storage_buffer(ctx: &GpuContext, label: &str, bytes: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// wgpu's `DeviceExt::create_buffer_init`, without its panic when the device is lost: wgpu's
/// version expects the mapping of the new buffer, which fails (a panic) for a buffer of a
/// device that was destroyed or lost and not yet reported as such. Here the buffer is then
/// returned as made (invalid, like every object of a lost device), and the loss is reported
/// by the next check ([`GpuContext::check_lost`], [`GpuContext::scoped`]) as
/// [`Error::DeviceLost`](crate::Error::DeviceLost). Import it in place of `DeviceExt`
/// (`use shadow_map_core::gpu::kernel::BufferInitExt;`).
pub trait BufferInitExt {
    /// A buffer of `desc.usage` holding `desc.contents` (padded to `COPY_BUFFER_ALIGNMENT`, at
    /// least 4 bytes; none for empty contents).
    fn create_buffer_init(&self, desc: &wgpu::util::BufferInitDescriptor<'_>) -> wgpu::Buffer;
}

impl BufferInitExt for wgpu::Device {
    fn create_buffer_init(&self, desc: &wgpu::util::BufferInitDescriptor<'_>) -> wgpu::Buffer {
        let len = desc.contents.len() as u64;
        if len == 0 {
            return self.create_buffer(&wgpu::BufferDescriptor {
                label: desc.label,
                size: 0,
                usage: desc.usage,
                mapped_at_creation: false,
            });
        }
        let align = wgpu::COPY_BUFFER_ALIGNMENT;
        let buffer = self.create_buffer(&wgpu::BufferDescriptor {
            label: desc.label,
            size: len.div_ceil(align).max(1) * align,
            usage: desc.usage,
            mapped_at_creation: true,
        });
        let mapped = match buffer.get_mapped_range_mut(..) {
            Ok(mut view) => {
                view.slice(..len as usize).copy_from_slice(desc.contents);
                true
            }
            Err(_) => false,
        };
        if mapped {
            buffer.unmap();
        }
        buffer
    }
}

/// A uniform buffer holding `value`.
pub fn uniform<T: bytemuck::Pod>(ctx: &GpuContext, label: &str, value: &T) -> wgpu::Buffer {
    buffer_init(
        &ctx.device,
        label,
        bytemuck::bytes_of(value),
        wgpu::BufferUsages::UNIFORM,
    )
}

/// `size x size` R32Float planes in one texture array.
#[derive(Debug, Clone)]
pub struct PlaneArray {
    /// The `D2` texture, one array layer a plane.
    pub texture: wgpu::Texture,
    /// Its `D2Array` view.
    pub view: wgpu::TextureView,
    /// Side of every plane.
    pub size: u32,
    /// Bytes on the device.
    pub bytes: usize,
}

/// Allocates `count` planes of side `size` (usages: read by kernels as a texture, written by
/// copies and by storage-texture stores); sizes beyond the device's limits are
/// [`Error::Limit`](crate::Error::Limit).
pub fn plane_array(ctx: &GpuContext, label: &str, size: u32, count: u32) -> Result<PlaneArray> {
    let l = ctx.limits();
    crate::Error::check_in_range(
        "texture-array side (max_texture_dimension_2d)",
        size,
        l.max_texture_dimension_2d,
    )?;
    crate::Error::check_in_range(
        "texture-array layers (max_texture_array_layers)",
        count,
        l.max_texture_array_layers,
    )?;
    ctx.scoped(label, || {
        let texture = ctx.device.create_texture(&texture_desc(
            label,
            size,
            size,
            count,
            wgpu::TextureFormat::R32Float,
            wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::STORAGE_BINDING,
        ));
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        PlaneArray {
            texture,
            view,
            size,
            bytes: size as usize * size as usize * count as usize * 4,
        }
    })
}

/// Uploads CPU planes (each `size x size`, row-major) into one texture array.
pub fn upload_planes(
    ctx: &GpuContext,
    label: &str,
    size: u32,
    planes: &[&[f32]],
) -> Result<PlaneArray> {
    let array = plane_array(ctx, label, size, planes.len() as u32)?;
    let texels = size as usize * size as usize;
    let mut data = Vec::with_capacity(texels * planes.len());
    for p in planes {
        if p.len() != texels {
            return Err(crate::Error::Gpu {
                stage: format!("{label} upload"),
                reason: format!("{} depths for a {size}x{size} plane", p.len()),
            });
        }
        data.extend_from_slice(p);
    }
    ctx.scoped(label, || {
        super::depth_map::write_planes(ctx, &array.texture, size, planes.len() as u32, &data);
    })?;
    Ok(array)
}
