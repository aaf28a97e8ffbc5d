//! The MSSM family on the GPU (`mssm.wgsl`), the twin of [`crate::mssm`]: the anchored MSSM
//! ([`Mssm`]), the dual-grid MSSM ([`DualMssm`]) and the min/max pyramid ([`MinMaxPyramid`]),
//! built level by level by compute dispatches from a depth map (layer 0).
//!
//! **Storage.** Every level is a [`GpuMinMaxLevel`]: a `min` and a `max` storage buffer of `f32`,
//! `size x size` row-major (the level side for the pyramid), exactly the planes of the CPU
//! structures: level 0 of [`GpuMssm`] and of [`GpuMinMaxPyramid`] is the (sanitised) depth map,
//! stored once (`min` and `max` are the same buffer), as on the CPU. min and max are exact
//! operations, so every plane is bit-identical to the CPU's for the same depth map.
//!
//! **Chunking.** A level plane may be larger than one storage binding
//! (`max_storage_buffer_binding_size`, or [`GpuMssmBuilder::with_max_binding_bytes`]): then the
//! work is split into chunks of rows, each dispatch binding only the rows it reads and writes
//! (ranges start at offsets aligned to `min_storage_buffer_offset_alignment`; the shader gets the
//! element index of its first row inside each range). Work larger than a binding is split, not
//! refused; only a plane larger than `max_buffer_size`, or a single row (plus the offset
//! alignment) larger than the binding limit, is an [`Error::Limit`].
//!
//! [`Mssm`]: crate::mssm::Mssm
//! [`DualMssm`]: crate::mssm::DualMssm
//! [`MinMaxPyramid`]: crate::mssm::MinMaxPyramid
use super::{
    depth_map::GpuDepthMap,
    kernel::{storage_buffer, uniform_buffer, wgsl_module, Binding},
    GpuContext,
};
use crate::{Error, Result};
use bytemuck::{Pod, Zeroable};
use std::num::NonZeroU64;

/// WGSL source of the MSSM stage (it uses no shared struct, so nothing is prepended).
pub const MSSM_WGSL: &str = include_str!("mssm.wgsl");

/// Workgroup size (x and y) of every MSSM dispatch, passed as WGSL overrides `WG_X`, `WG_Y`.
pub const MSSM_WORKGROUP: u32 = 16;

/// Outputs per axis of one `anchored_block` invocation (WGSL `BLOCK`).
pub const BLOCK: u32 = 4;

/// Invocations per axis of an `anchored_block` dispatch over a level of side `s` with window
/// offset `h`: each of the `h` phases of the axis takes `ceil(s / (h BLOCK))` blocks.
pub fn block_invocations(s: u32, h: u32) -> u32 {
    let h = h.max(1);
    h.saturating_mul(s.div_ceil(h.saturating_mul(BLOCK)))
}

/// Uniform of one MSSM dispatch (one chunk of rows of one level); mirrors `MinMaxParams` in
/// `mssm.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct MinMaxParams {
    /// Side of the source level.
    pub size: u32,
    /// Side of the output level.
    pub out_size: u32,
    /// Window offset `h = 2^l` of an anchored step.
    pub h: u32,
    /// First output row of the chunk.
    pub row0: u32,
    /// Output rows in the chunk.
    pub rows: u32,
    /// Element index of the chunk's first source row in its bound range.
    pub top_base: u32,
    /// Element index of source row `row0 + h` in its bound range (anchored step).
    pub bot_base: u32,
    /// Element index of the chunk's first output row in its bound range.
    pub out_base: u32,
    /// Depth of an empty texel (+inf).
    pub empty_depth: f32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
    /// Padding.
    pub _pad2: u32,
}

/// One level: `min` and `max` planes, `size x size` `f32`, row-major, in storage buffers
/// (usages `STORAGE | COPY_SRC | COPY_DST`).
#[derive(Debug, Clone)]
pub struct GpuMinMaxLevel {
    /// Side of the level.
    pub size: u32,
    /// The min plane.
    pub min: wgpu::Buffer,
    /// The max plane (the same buffer as `min` for a depth-map level, where both are the depths).
    pub max: wgpu::Buffer,
    single_plane: bool,
}

impl GpuMinMaxLevel {
    /// Texels in one plane.
    pub fn texels(&self) -> u64 {
        self.size as u64 * self.size as u64
    }
    /// True when `min` and `max` are one buffer (a depth-map level).
    pub fn is_single_plane(&self) -> bool {
        self.single_plane
    }
    /// Bytes of the planes (one plane when `min` and `max` are one buffer), as the CPU counts.
    pub fn bytes(&self) -> usize {
        let planes = if self.single_plane { 1 } else { 2 };
        self.texels() as usize * 4 * planes
    }
    /// Reads the `(min, max)` planes back.
    pub fn read(&self, ctx: &GpuContext) -> Result<(Vec<f32>, Vec<f32>)> {
        let bytes = self.texels() * 4;
        let min: Vec<f32> = ctx.read_buffer(&self.min, bytes)?;
        let max = if self.single_plane {
            min.clone()
        } else {
            ctx.read_buffer(&self.max, bytes)?
        };
        Ok((min, max))
    }
}

macro_rules! level_stack {
    ($(#[$doc:meta])* $name:ident, $cpu:literal) => {
        $(#[$doc])*
        #[derive(Debug, Clone)]
        pub struct $name {
            /// Side of the depth map it was built from.
            pub size: u32,
            /// The levels, finest first.
            pub levels: Vec<GpuMinMaxLevel>,
        }

        impl $name {
            #[doc = concat!("Number of levels built (as `", $cpu, "::levels`).")]
            pub fn levels(&self) -> u32 {
                self.levels.len() as u32
            }
            #[doc = concat!("Bytes of the level planes (as `", $cpu, "::bytes`).")]
            pub fn bytes(&self) -> usize {
                self.levels.iter().map(GpuMinMaxLevel::bytes).sum()
            }
            #[doc = concat!("Reads every level back as `(min, max)` planes, comparable with `", $cpu, "::level`.")]
            pub fn read_levels(&self, ctx: &GpuContext) -> Result<Vec<(Vec<f32>, Vec<f32>)>> {
                self.levels.iter().map(|l| l.read(ctx)).collect()
            }
        }
    };
}

level_stack!(
    /// Anchored MSSM on the GPU, the twin of [`crate::mssm::Mssm`]: level `l` holds min/max over
    /// the `2^l x 2^l` window anchored at each texel (clamped to the map); level 0 is the depth map.
    GpuMssm,
    "Mssm"
);
level_stack!(
    /// Dual-grid MSSM on the GPU, the twin of [`crate::mssm::DualMssm`]: level `l` holds min/max
    /// over the samples `[x, x + 2^l] x [y, y + 2^l]`.
    GpuDualMssm,
    "DualMssm"
);
level_stack!(
    /// Min/max pyramid on the GPU, the twin of [`crate::mssm::MinMaxPyramid`]: level `l` has
    /// `ceil(size / 2^l)` texels per side; level 0 is the depth map.
    GpuMinMaxPyramid,
    "MinMaxPyramid"
);

impl GpuMinMaxPyramid {
    /// Texels per side of level `l` (0 if out of range).
    pub fn level_size(&self, l: u32) -> u32 {
        self.levels.get(l as usize).map_or(0, |lv| lv.size)
    }
}

/// Which structures to build from one depth map.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MinMaxRequest {
    /// Anchored MSSM up to this level (inclusive, clamped to `floor(log2(size))`).
    pub mssm_levels: Option<u32>,
    /// Dual-grid MSSM up to this level (inclusive, clamped likewise).
    pub dual_mssm_levels: Option<u32>,
    /// The min/max pyramid.
    pub pyramid: bool,
}

impl MinMaxRequest {
    /// The anchored MSSM alone, up to `levels`.
    pub fn mssm(levels: u32) -> Self {
        MinMaxRequest {
            mssm_levels: Some(levels),
            ..Default::default()
        }
    }

    /// The dual-grid MSSM alone, up to `levels`.
    pub fn dual_mssm(levels: u32) -> Self {
        MinMaxRequest {
            dual_mssm_levels: Some(levels),
            ..Default::default()
        }
    }

    /// The min/max pyramid alone.
    pub fn pyramid() -> Self {
        MinMaxRequest {
            pyramid: true,
            ..Default::default()
        }
    }
}

/// The structures built by [`GpuMssmBuilder::encode`].
#[derive(Debug, Clone, Default)]
pub struct GpuMinMaxSet {
    /// Anchored MSSM, when requested.
    pub mssm: Option<GpuMssm>,
    /// Dual-grid MSSM, when requested.
    pub dual_mssm: Option<GpuDualMssm>,
    /// Min/max pyramid, when requested.
    pub pyramid: Option<GpuMinMaxPyramid>,
}

/// The MSSM compute pipelines (label `mssm`), created once per context.
#[derive(Debug, Clone)]
pub struct GpuMssmBuilder {
    load_layout: wgpu::BindGroupLayout,
    step_layout: wgpu::BindGroupLayout,
    reduce_layout: wgpu::BindGroupLayout,
    load: wgpu::ComputePipeline,
    step: wgpu::ComputePipeline,
    /// `anchored_step` writing the min planes only (`MIN_ONLY`).
    step_min: wgpu::ComputePipeline,
    /// `anchored_block`: the step over a level bound whole, both planes and min only.
    block: wgpu::ComputePipeline,
    block_min: wgpu::ComputePipeline,
    reduce: wgpu::ComputePipeline,
    max_binding_bytes: Option<u64>,
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Load,
    Step,
    /// An anchored step over a level bound whole, by `anchored_block`.
    Block,
    Reduce,
}

/// A bound range of a buffer.
struct Range {
    buffer: wgpu::Buffer,
    offset: u64,
    size: u64,
}

struct Dispatch {
    kind: Kind,
    params: MinMaxParams,
    texture: Option<wgpu::TextureView>,
    buffers: Vec<(u32, Range)>,
    groups: (u32, u32),
    /// The index of the level it builds in its structure's level list.
    level: u32,
}

/// Plans the dispatches of one build: buffers are created while planning, bind groups and the
/// pass are recorded by [`Recorder::record`].
struct Recorder<'a> {
    ctx: &'a GpuContext,
    /// Largest storage binding, bytes.
    limit: u64,
    /// Storage-buffer offset alignment, bytes.
    align: u64,
    dispatches: Vec<Dispatch>,
    /// The level index the next dispatches build.
    level: u32,
}

/// `floor(log2(n))` for `n >= 1`.
fn floor_log2(n: u32) -> u32 {
    31 - n.max(1).leading_zeros()
}

impl<'a> Recorder<'a> {
    /// A bound range over elements `[first, first + count)` of `buffer`, starting at an aligned
    /// offset; returns it with the element index of `first` inside it.
    fn range(&self, buffer: &wgpu::Buffer, first: u64, count: u64) -> (Range, u32) {
        let start = first * 4;
        let offset = start / self.align * self.align;
        let range = Range {
            buffer: buffer.clone(),
            offset,
            size: start + count.max(1) * 4 - offset,
        };
        (range, ((start - offset) / 4) as u32)
    }

    /// Output rows per chunk when each row of a binding spans `row_bytes` and the largest plane
    /// bound is `plane_bytes`; all rows when the plane fits one binding.
    fn rows_per_chunk(&self, plane_bytes: u64, row_bytes: u64, out_rows: u32) -> Result<u32> {
        if plane_bytes <= self.limit {
            return Ok(out_rows.max(1));
        }
        let rows = self.limit.saturating_sub(self.align) / row_bytes.max(1);
        if rows == 0 {
            return Err(Error::Limit {
                what: "MSSM row bytes with offset alignment (max_storage_buffer_binding_size)",
                requested: row_bytes + self.align,
                max: self.limit,
            });
        }
        Ok(rows.min(out_rows.max(1) as u64) as u32)
    }

    fn plane(&self, size: u32, label: &str) -> Result<wgpu::Buffer> {
        let bytes = size as u64 * size as u64 * 4;
        let max = self.ctx.limits().max_buffer_size;
        if bytes > max {
            return Err(Error::Limit {
                what: "MSSM level plane (bytes, GPU max_buffer_size)",
                requested: bytes,
                max,
            });
        }
        Ok(storage_buffer(self.ctx, label, bytes.max(4)))
    }

    fn params(size: u32, out_size: u32, h: u32, row0: u32, rows: u32) -> MinMaxParams {
        MinMaxParams {
            size,
            out_size,
            h,
            row0,
            rows,
            top_base: 0,
            bot_base: 0,
            out_base: 0,
            empty_depth: f32::INFINITY,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }

    /// Two level planes of side `size`, labelled `{label}.min` and `{label}.max`.
    fn planes(&self, size: u32, label: &str) -> Result<(wgpu::Buffer, wgpu::Buffer)> {
        Ok((
            self.plane(size, &format!("{label}.min"))?,
            self.plane(size, &format!("{label}.max"))?,
        ))
    }

    /// [`range`](Self::range) over the same elements of a `min` and a `max` plane; the element
    /// index is the same in both (equal offsets in equally aligned buffers).
    fn ranges(
        &self,
        (min, max): (&wgpu::Buffer, &wgpu::Buffer),
        first: u64,
        count: u64,
    ) -> (Range, Range, u32) {
        let (rmin, base) = self.range(min, first, count);
        let (rmax, _) = self.range(max, first, count);
        (rmin, rmax, base)
    }

    /// Plans one dispatch per chunk of output rows of an `out_size`-sided level (chunks sized by
    /// [`rows_per_chunk`](Self::rows_per_chunk)); `plan` gets the chunk's first row and row count
    /// and returns the dispatch's kind, parameters, texture and bindings.
    fn chunked(
        &mut self,
        (plane_bytes, row_bytes): (u64, u64),
        out_size: u32,
        mut plan: impl FnMut(
            &Self,
            u32,
            u32,
        ) -> (
            Kind,
            MinMaxParams,
            Option<wgpu::TextureView>,
            Vec<(u32, Range)>,
        ),
    ) -> Result<()> {
        let per = self.rows_per_chunk(plane_bytes, row_bytes, out_size)?;
        let mut row0 = 0;
        while row0 < out_size {
            let rows = per.min(out_size - row0);
            let (kind, params, texture, buffers) = plan(self, row0, rows);
            self.dispatches.push(Dispatch {
                kind,
                params,
                texture,
                buffers,
                groups: match kind {
                    Kind::Block => {
                        let n = block_invocations(out_size, params.h).div_ceil(MSSM_WORKGROUP);
                        (n, n)
                    }
                    _ => (
                        out_size.div_ceil(MSSM_WORKGROUP),
                        rows.div_ceil(MSSM_WORKGROUP),
                    ),
                },
                level: self.level,
            });
            row0 += rows;
        }
        Ok(())
    }

    /// `mssm::sanitized_level0`: the depth map as a single-plane level.
    fn load(&mut self, depth: &GpuDepthMap, label: &str) -> Result<GpuMinMaxLevel> {
        let s = depth.size;
        let out = self.plane(s, label)?;
        let row = s as u64 * 4;
        self.chunked((row * s as u64, row), s, |r, row0, rows| {
            let (o, out_base) = r.range(&out, row0 as u64 * s as u64, rows as u64 * s as u64);
            let mut params = Self::params(s, s, 0, row0, rows);
            params.out_base = out_base;
            (Kind::Load, params, Some(depth.view.clone()), vec![(7, o)])
        })?;
        Ok(GpuMinMaxLevel {
            size: s,
            min: out.clone(),
            max: out,
            single_plane: true,
        })
    }

    /// `mssm::anchored_step` with window offset `h`.
    fn step(&mut self, src: &GpuMinMaxLevel, h: u32, label: &str) -> Result<GpuMinMaxLevel> {
        let s = src.size;
        let (omin, omax) = self.planes(s, label)?;
        let row = s as u64 * 4;
        let su = s as u64;
        let source = (&src.min, &src.max);
        self.chunked((row * su, row), s, |r, row0, rows| {
            let n = rows as u64 * su;
            let (tmin, tmax, top_base) = r.ranges(source, row0 as u64 * su, n);
            // Rows [row0 + h, min(row0 + rows + h, s)) exist only when row0 + h < s; otherwise the
            // shader never reads them and the top rows stand in for the binding.
            let b0 = row0 as u64 + h as u64;
            let (bmin, bmax, bot_base) = if b0 < su {
                let bn = (su - b0).min(rows as u64) * su;
                r.ranges(source, b0 * su, bn)
            } else {
                let (bmin, bmax, _) = r.ranges(source, row0 as u64 * su, n);
                (bmin, bmax, 0)
            };
            let (outmin, outmax, out_base) = r.ranges((&omin, &omax), row0 as u64 * su, n);
            let mut params = Self::params(s, s, h, row0, rows);
            params.top_base = top_base;
            params.bot_base = bot_base;
            params.out_base = out_base;
            let buffers = vec![
                (3, tmin),
                (4, tmax),
                (5, bmin),
                (6, bmax),
                (7, outmin),
                (8, outmax),
            ];
            // A level bound whole (one chunk) is stepped in blocks (whose rows reach beyond the
            // chunk's) while a block's lattice fits in the level; wider offsets leave most of a
            // block outside, and the plain step does less work there.
            let kind = if row0 == 0 && rows == s && h.saturating_mul(BLOCK) <= s {
                Kind::Block
            } else {
                Kind::Step
            };
            (kind, params, None, buffers)
        })?;
        Ok(GpuMinMaxLevel {
            size: s,
            min: omin,
            max: omax,
            single_plane: false,
        })
    }

    /// `MinMaxPyramid::reduce`: one 2x2 reduction to `ceil(size / 2)`.
    fn reduce(&mut self, src: &GpuMinMaxLevel, label: &str) -> Result<GpuMinMaxLevel> {
        let sp = src.size;
        let sd = sp.div_ceil(2);
        let (omin, omax) = self.planes(sd, label)?;
        let spu = sp as u64;
        let row = 2 * spu * 4;
        self.chunked((spu * spu * 4, row), sd, |r, row0, rows| {
            let src_first = 2 * row0 as u64;
            let src_rows = (2 * rows as u64).min(spu - src_first);
            let (tmin, tmax, top_base) =
                r.ranges((&src.min, &src.max), src_first * spu, src_rows * spu);
            let n = rows as u64 * sd as u64;
            let (outmin, outmax, out_base) = r.ranges((&omin, &omax), row0 as u64 * sd as u64, n);
            let mut params = Self::params(sp, sd, 0, row0, rows);
            params.top_base = top_base;
            params.out_base = out_base;
            let buffers = vec![(3, tmin), (4, tmax), (7, outmin), (8, outmax)];
            (Kind::Reduce, params, None, buffers)
        })?;
        Ok(GpuMinMaxLevel {
            size: sd,
            min: omin,
            max: omax,
            single_plane: false,
        })
    }

    /// Writes all parameters into one uniform buffer (one aligned slot per dispatch) and creates
    /// the bind groups: the pass, ready to record any number of times.
    fn finish(self, b: &GpuMssmBuilder) -> GpuMinMaxPass {
        if self.dispatches.is_empty() {
            return GpuMinMaxPass {
                builder: b.clone(),
                dispatches: Vec::new(),
            };
        }
        let device = &self.ctx.device;
        let psize = std::mem::size_of::<MinMaxParams>() as u64;
        let ualign = self.ctx.limits().min_uniform_buffer_offset_alignment as u64;
        let stride = psize.div_ceil(ualign.max(1)) * ualign.max(1);
        let mut bytes = vec![0u8; (stride * self.dispatches.len() as u64) as usize];
        for (k, d) in self.dispatches.iter().enumerate() {
            let at = k * stride as usize;
            bytes[at..at + psize as usize].copy_from_slice(bytemuck::bytes_of(&d.params));
        }
        let params = uniform_buffer(self.ctx, "mssm.params", bytes.len() as u64);
        self.ctx.queue.write_buffer(&params, 0, &bytes);
        let dispatches = self
            .dispatches
            .iter()
            .enumerate()
            .map(|(k, d)| {
                let mut entries = vec![wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &params,
                        offset: k as u64 * stride,
                        size: NonZeroU64::new(psize),
                    }),
                }];
                if let Some(t) = &d.texture {
                    entries.push(wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(t),
                    });
                }
                for (binding, r) in &d.buffers {
                    entries.push(wgpu::BindGroupEntry {
                        binding: *binding,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &r.buffer,
                            offset: r.offset,
                            size: NonZeroU64::new(r.size),
                        }),
                    });
                }
                let layout = match d.kind {
                    Kind::Load => &b.load_layout,
                    Kind::Step | Kind::Block => &b.step_layout,
                    Kind::Reduce => &b.reduce_layout,
                };
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("mssm"),
                    layout,
                    entries: &entries,
                });
                (d.kind, group, d.groups, d.level)
            })
            .collect();
        GpuMinMaxPass {
            builder: b.clone(),
            dispatches,
        }
    }
}

/// The recorded form of one MSSM build ([`GpuMssmBuilder::prepare`]): its parameters written and
/// its bind groups created once, so [`record`](Self::record) only records the compute pass (the
/// engine path records it every frame, after the depth map it reads is rendered).
#[derive(Debug)]
pub struct GpuMinMaxPass {
    builder: GpuMssmBuilder,
    /// Kind, bind group, workgroups, and the index of the level built.
    dispatches: Vec<(Kind, wgpu::BindGroup, (u32, u32), u32)>,
}

impl GpuMinMaxPass {
    /// Records the pass into `encoder` (nothing when no structure was requested).
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder) {
        self.record_levels(encoder, u32::MAX, true);
    }

    /// Records the dispatches that build each structure's first `levels` levels (level 0 is
    /// the depth map, or the dual-grid MSSM's first level): a view whose kernels are small
    /// reads no more, and the higher levels are the same cost each as the first. Without `max`
    /// the anchored MSSM's levels get their min planes only (for kernels that query no maximum:
    /// half the traffic of each level; the max planes keep whatever they held).
    pub fn record_levels(&self, encoder: &mut wgpu::CommandEncoder, levels: u32, max: bool) {
        if self.dispatches.iter().all(|d| d.3 >= levels) {
            return;
        }
        let b = &self.builder;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("mssm"),
            timestamp_writes: None,
        });
        for (kind, group, (x, y), _) in self.dispatches.iter().filter(|d| d.3 < levels) {
            pass.set_pipeline(match kind {
                Kind::Load => &b.load,
                Kind::Step if max => &b.step,
                Kind::Step => &b.step_min,
                Kind::Block if max => &b.block,
                Kind::Block => &b.block_min,
                Kind::Reduce => &b.reduce,
            });
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(*x, *y, 1);
        }
    }
}

impl GpuMssmBuilder {
    /// Compiles the three pipelines (`load_depth`, `anchored_step`, `reduce`).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        ctx.scoped("mssm", || {
            let device = &ctx.device;
            let module = wgsl_module(device, "mssm", MSSM_WGSL);
            let uniform = wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: NonZeroU64::new(std::mem::size_of::<MinMaxParams>() as u64),
                },
                count: None,
            };
            let storage = |binding, read_only| match read_only {
                true => Binding::Storage.entry(binding),
                false => Binding::StorageRw.entry(binding),
            };
            let texture = Binding::Texture2d.entry(1);
            let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
                device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some(label),
                    entries,
                })
            };
            let load_layout = layout("mssm.load_depth", &[uniform, texture, storage(7, false)]);
            let step_layout = layout(
                "mssm.anchored_step",
                &[
                    uniform,
                    storage(3, true),
                    storage(4, true),
                    storage(5, true),
                    storage(6, true),
                    storage(7, false),
                    storage(8, false),
                ],
            );
            let reduce_layout = layout(
                "mssm.reduce",
                &[
                    uniform,
                    storage(3, true),
                    storage(4, true),
                    storage(7, false),
                    storage(8, false),
                ],
            );
            let wg = MSSM_WORKGROUP as f64;
            let pipeline = |label: &str, bgl: &wgpu::BindGroupLayout, min_only: bool| {
                let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(label),
                    bind_group_layouts: &[Some(bgl)],
                    immediate_size: 0,
                });
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: Some(&pl),
                    module: &module,
                    entry_point: label.strip_prefix("mssm."),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &[
                            ("WG_X", wg),
                            ("WG_Y", wg),
                            ("MIN_ONLY", f64::from(u8::from(min_only))),
                        ],
                        ..Default::default()
                    },
                    cache: None,
                })
            };
            GpuMssmBuilder {
                load: pipeline("mssm.load_depth", &load_layout, false),
                step: pipeline("mssm.anchored_step", &step_layout, false),
                step_min: pipeline("mssm.anchored_step", &step_layout, true),
                block: pipeline("mssm.anchored_block", &step_layout, false),
                block_min: pipeline("mssm.anchored_block", &step_layout, true),
                reduce: pipeline("mssm.reduce", &reduce_layout, false),
                load_layout,
                step_layout,
                reduce_layout,
                max_binding_bytes: None,
            }
        })
    }

    /// Caps the storage-binding size used to plan chunks at `bytes` (the device limit still
    /// applies). A test knob: a tiny cap forces chunked builds on any device.
    pub fn with_max_binding_bytes(mut self, bytes: u64) -> Self {
        self.max_binding_bytes = Some(bytes);
        self
    }

    /// Sets or clears the binding-size cap of [`GpuMssmBuilder::with_max_binding_bytes`].
    pub fn set_max_binding_bytes(&mut self, bytes: Option<u64>) {
        self.max_binding_bytes = bytes;
    }

    /// The storage-binding size chunks are planned against: the device's
    /// `max_storage_buffer_binding_size`, capped by the knob.
    pub fn binding_limit(&self, ctx: &GpuContext) -> u64 {
        let device = ctx.limits().max_storage_buffer_binding_size;
        self.max_binding_bytes.map_or(device, |b| b.min(device))
    }

    /// Records the requested structures over `depth` into `encoder` (one compute pass; nothing
    /// is submitted). The returned buffers hold their values once the encoder is submitted.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        depth: &GpuDepthMap,
        req: MinMaxRequest,
    ) -> Result<GpuMinMaxSet> {
        let (set, pass) = self.prepare(ctx, depth, req)?;
        pass.record(encoder);
        Ok(set)
    }

    /// Allocates the requested structures over `depth` and prepares the pass that builds them
    /// ([`GpuMinMaxPass::record`], as often as `depth` changes). The buffers hold their values
    /// once a recorded pass is submitted.
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        depth: &GpuDepthMap,
        req: MinMaxRequest,
    ) -> Result<(GpuMinMaxSet, GpuMinMaxPass)> {
        if req.mssm_levels.is_none() && req.dual_mssm_levels.is_none() && !req.pyramid {
            let pass = GpuMinMaxPass {
                builder: self.clone(),
                dispatches: Vec::new(),
            };
            return Ok((GpuMinMaxSet::default(), pass));
        }
        let mut rec = Recorder {
            ctx,
            limit: self.binding_limit(ctx),
            align: ctx.limits().min_storage_buffer_offset_alignment.max(4) as u64,
            dispatches: Vec::new(),
            level: 0,
        };
        let s = depth.size;
        let top = floor_log2(s);
        let base = rec.load(depth, "mssm.depth")?;
        let mut set = GpuMinMaxSet::default();
        if let Some(max_level) = req.mssm_levels {
            let mut levels = vec![base.clone()];
            for l in 0..max_level.min(top) {
                let Some(prev) = levels.last() else { break };
                rec.level = l + 1;
                let next = rec.step(prev, 1 << l, &format!("mssm.level{}", l + 1))?;
                levels.push(next);
            }
            set.mssm = Some(GpuMssm { size: s, levels });
        }
        if let Some(max_level) = req.dual_mssm_levels {
            rec.level = 0;
            let mut levels = vec![rec.step(&base, 1, "dual_mssm.level0")?];
            for l in 0..max_level.min(top) {
                let Some(prev) = levels.last() else { break };
                rec.level = l + 1;
                let next = rec.step(prev, 1 << l, &format!("dual_mssm.level{}", l + 1))?;
                levels.push(next);
            }
            set.dual_mssm = Some(GpuDualMssm { size: s, levels });
        }
        if req.pyramid {
            let mut levels = vec![base.clone()];
            while let Some(prev) = levels.last() {
                if prev.size <= 1 {
                    break;
                }
                rec.level = levels.len() as u32;
                let next = rec.reduce(prev, &format!("pyramid.level{}", levels.len()))?;
                levels.push(next);
            }
            set.pyramid = Some(GpuMinMaxPyramid { size: s, levels });
        }
        Ok((set, rec.finish(self)))
    }

    /// Builds the requested structures over `depth` and submits the work.
    pub fn build(
        &self,
        ctx: &GpuContext,
        depth: &GpuDepthMap,
        req: MinMaxRequest,
    ) -> Result<GpuMinMaxSet> {
        ctx.scoped("mssm", || {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("mssm"),
                });
            let set = self.encode(ctx, &mut enc, depth, req)?;
            ctx.queue.submit([enc.finish()]);
            Ok(set)
        })?
    }

    /// Builds the anchored MSSM up to `max_level` (see [`crate::mssm::Mssm::build`]).
    pub fn build_mssm(
        &self,
        ctx: &GpuContext,
        depth: &GpuDepthMap,
        max_level: u32,
    ) -> Result<GpuMssm> {
        let req = MinMaxRequest::mssm(max_level);
        self.build(ctx, depth, req)?.mssm.ok_or_else(missing)
    }

    /// Builds the dual-grid MSSM up to `max_level` (see [`crate::mssm::DualMssm::build`]).
    pub fn build_dual_mssm(
        &self,
        ctx: &GpuContext,
        depth: &GpuDepthMap,
        max_level: u32,
    ) -> Result<GpuDualMssm> {
        let req = MinMaxRequest::dual_mssm(max_level);
        self.build(ctx, depth, req)?.dual_mssm.ok_or_else(missing)
    }

    /// Builds the min/max pyramid (see [`crate::mssm::MinMaxPyramid::build`]).
    pub fn build_pyramid(&self, ctx: &GpuContext, depth: &GpuDepthMap) -> Result<GpuMinMaxPyramid> {
        self.build(ctx, depth, MinMaxRequest::pyramid())?
            .pyramid
            .ok_or_else(missing)
    }
}

fn missing() -> Error {
    Error::Gpu {
        stage: "mssm".into(),
        reason: "requested structure was not built".into(),
    }
}
