//! The wgpu twin, [`GpuDeepShadow`] (cargo feature `gpu`, on by default): the same name,
//! description and parameters as [`CpuDeepShadow`](crate::CpuDeepShadow), and the same stages in
//! `deep_shadow.wgsl`.
//!
//! **Why a compute rasteriser** (and not a fragment shader with storage-buffer atomics): it runs
//! the CPU twin's fill rule exactly (texel centres, top-left rule, perspective-correct 1/z, no
//! sub-pixel vertex snapping, which hardware rasterisers apply at 8 bits on lavapipe), needs no
//! render target, and its work is balanced by splitting every triangle's bounding box into
//! 16 x 16-texel work items, so one large ground triangle does not serialise the pass. The edge
//! functions run in f32 where the CPU uses f64, so a texel centre within about 1e-6 texel of an
//! edge may be covered by one twin and not the other; depths agree to f32 rounding.
//!
//! Stages: `clear` (head = NIL), `raster` (Listing 1.2: `atomicAdd` on the counter,
//! `atomicExchange` on the head; past the capacity only the counter moves), a counter readback
//! (capacity check: grow and rebuild, or [`Error::Limit`]; the counter is a u32, so the
//! invocation that takes index `u32::MAX` also counts a wrap in a third word, and a wrapped pass
//! needs more than `u32::MAX` elements: [`Error::Limit`], never a wrapped count taken for a small
//! one), `process` (sort, tau, prev, truncation),
//! `link`, then `lookup` per receiver. The receivers' light-space queries (texel coordinates,
//! caster test, facing) are computed on the CPU with the CPU twin's code
//! ([`crate::cpu::query`]) and uploaded. A fully opaque scene takes `raster_opaque` (an
//! `atomicMin` of the depth bits into the head buffer: an ordinary shadow map, no lists) and
//! `lookup_opaque`.
use crate::cpu::{finish, lookup_settings, query, sublight_points, Query, Tally};
use crate::dsm::{BuildStats, DeepShadowMap, Filter, LookupSettings, Traversal};
use crate::params::{self, Settings, SPECS};
use crate::raster::prepare;
use crate::shared::{DsUniform, Node, Tri};
use glam::Vec2;
use shadow_map_core::gpu::estimate::CELLS_WGSL;
use shadow_map_core::gpu::kernel::BufferInitExt;
use shadow_map_core::{
    gpu::{
        kernel::{bind_group_layout, compute_pipeline, shader_module, Binding},
        shared::{CUT_BITS, LOOP_PROBE, SHARED_WGSL},
        GpuContext,
    },
    raster::DepthMap,
    Cancel, Error, LightView, Params, ReceiverPlane, Receivers, Report, Result, Scene,
    SoftShadowEstimator,
};
use std::{sync::Arc, time::Instant};

mod estimator;
mod query;
#[cfg(test)]
mod tests;

pub(crate) use query::lookup_uniform;
pub use query::{pack_depth_query, pack_query, unpack_look, PackedQuery};

/// The WGSL of every stage.
pub const DEEP_SHADOW_WGSL: &str = include_str!("deep_shadow.wgsl");

/// The list element `Node` and the empty index `NIL`, the part before [`DEEP_SHADOW_WGSL`] and
/// before the insert pass's WGSL.
pub const NODE_WGSL: &str = include_str!("node.wgsl");

/// Every shader of the crate as `(name, source)` (validated with naga by a unit test).
pub const SHADERS: &[(&str, &[&str])] = &[
    ("deep_shadow", SHADER_PARTS),
    ("deep_shadow_frame", crate::frame::FRAME_SHADER_PARTS),
    ("deep_shadow_insert", crate::frame::INSERT_SHADER_PARTS),
];

/// The WGSL parts of the module, in order: the workgroup size's declaration ([`WG_WGSL`]), the
/// core's shared structs and loop-budget probe ([`SHARED_WGSL`]), the core's `cells` and Kahan
/// `Sum` (the PCSS sampling `filter=pcss` shares), the list element ([`NODE_WGSL`]), then
/// [`DEEP_SHADOW_WGSL`].
pub const SHADER_PARTS: &[&str] = &[
    WG_WGSL,
    SHARED_WGSL,
    CELLS_WGSL,
    NODE_WGSL,
    DEEP_SHADOW_WGSL,
];

/// The workgroup size's declaration, `override WG` ([`WORKGROUP_SIZE`]): its own part, since the
/// engine path's module takes it from the core's `estimate.wgsl` instead.
pub const WG_WGSL: &str = "override WG: u32;\n";

/// The constants the kernels share with the CPU twin, passed as pipeline overrides (never copied
/// into the WGSL by hand).
/// The twin's module adds `WG` ([`WORKGROUP_SIZE`]); the engine path's takes `WG` and the light
/// codes from the core's estimate overrides.
pub(crate) const OWN_OVERRIDES: &[(&str, f64)] = &[
    ("NIL", crate::shared::NIL as f64),
    ("EDSM_CUTOFF", crate::dsm::EDSM_CUTOFF as f64),
];

/// Workgroup size of every entry point (`WG` in the WGSL).
pub const WORKGROUP_SIZE: u32 = 64;

/// Tile side of a raster work item.
pub const TILE: u32 = 16;

struct Pipelines {
    layout: wgpu::BindGroupLayout,
    clear: wgpu::ComputePipeline,
    raster: wgpu::ComputePipeline,
    raster_opaque: wgpu::ComputePipeline,
    process: wgpu::ComputePipeline,
    link: wgpu::ComputePipeline,
    lookup: wgpu::ComputePipeline,
    lookup_opaque: wgpu::ComputePipeline,
    ceiling_insert: wgpu::ComputePipeline,
}

/// A deep shadow map (or, for an opaque scene, a plain depth map) living on the GPU.
pub struct GpuMap {
    /// Resolution.
    pub r: u32,
    /// Head buffer (`r^2` u32; for the opaque path, the nearest depth's bits).
    pub head: wgpu::Buffer,
    /// Element buffer.
    pub nodes: wgpu::Buffer,
    /// Counters (fragments, lookup steps).
    pub counters: wgpu::Buffer,
    /// True for the opaque path (no lists).
    pub opaque: bool,
    /// Build statistics (`lists` is not measured on the GPU).
    pub stats: BuildStats,
    /// Texels whose `process` or `link` the device's loop budget cut short ([`LOOP_LIMIT`]); when
    /// non-zero the lists are the CPU twin's, built for this view and uploaded.
    pub cut_texels: u64,
}

/// Deep shadow maps through wgpu; see the module documentation.
pub struct GpuDeepShadow {
    ctx: Arc<GpuContext>,
    params: Params,
    /// `params`, typed (re-read on every `set_param`).
    settings: Settings,
    report: Report,
    pipes: Pipelines,
    /// The fragment counter's value before each raster pass: 0, except in tests that reach the
    /// u32 wrap without 2^32 fragments (`set_counter_start`, in the unit tests).
    counter_start: u32,
    /// Checked between sub-light views.
    cancel: Cancel,
}

/// Why a stage can be cut short: some devices bound the loop iterations of one shader invocation
/// (llvmpipe, i.e. lavapipe, ends every loop once 65535 iterations in all have run), which would
/// silently leave a long list half sorted or a lookup's walk half done. Every stage that loops over
/// lists ends with the core's two-trip probe (`loop_limit_hit`) and counts a cut: a cut `process`
/// or `link` texel makes [`GpuDeepShadow::build_map`] build that view's map with the CPU twin and
/// upload it in the GPU's layout; a cut lookup is written as `CUT_BITS` and redone by
/// [`GpuDeepShadow::lookup`] with the CPU twin's lookup on the same map (both reported as
/// `loop_limit_cpu_fallbacks`).
pub const LOOP_LIMIT: &str = "llvmpipe: 65535 loop iterations per invocation";

/// Bytes of the counter buffer: the element counter, the step counter, the element counter's
/// wraps, the invocations cut short by the loop budget, the elements kept after truncation and
/// the longest list (`Counters` in `deep_shadow.wgsl`).
pub const COUNTER_BYTES: u64 = 24;

pub(crate) fn dispatch(pass: &mut wgpu::ComputePass<'_>, threads: u64) {
    let [x, y, z] = workgroups(threads);
    pass.dispatch_workgroups(x, y, z);
}

/// The largest element capacity `ctx`'s device can bind.
fn device_capacity(ctx: &GpuContext) -> u64 {
    let l = ctx.limits();
    l.max_storage_buffer_binding_size.min(l.max_buffer_size) / std::mem::size_of::<Node>() as u64
}

/// The most list elements a map may take under `s`: `max_capacity`, the device's binding and the
/// u32 element index (below `NIL`), whichever is least.
pub(crate) fn capacity_cap(ctx: &GpuContext, s: &Settings) -> u64 {
    s.max_capacity
        .min(device_capacity(ctx))
        .min(u32::MAX as u64 - 1)
}

/// Workgroups covering `threads` invocations: one row up to 65535 workgroups, then rows of 65535.
pub(crate) fn workgroups(threads: u64) -> [u32; 3] {
    let groups = threads.div_ceil(WORKGROUP_SIZE as u64).max(1);
    let x = groups.min(65535);
    let y = groups.div_ceil(x);
    [x as u32, y as u32, 1]
}

impl GpuDeepShadow {
    /// Compiles the pipelines on `ctx`.
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self> {
        let module = shader_module(&ctx, "deep_shadow.wgsl", SHADER_PARTS)?;
        let layout = ctx.scoped("deep-shadow pipelines", || {
            bind_group_layout(
                &ctx,
                "deep-shadow",
                &[
                    Binding::Uniform,
                    Binding::Storage,
                    Binding::Storage,
                    Binding::StorageRw,
                    Binding::StorageRw,
                    Binding::StorageRw,
                    Binding::Storage,
                    Binding::StorageRw,
                ],
            )
        })?;
        let overrides: Vec<(&str, f64)> = OWN_OVERRIDES
            .iter()
            .copied()
            .chain([("WG", WORKGROUP_SIZE as f64)])
            .collect();
        let mk = |entry: &str| compute_pipeline(&ctx, entry, &module, &layout, entry, &overrides);
        let pipes = Pipelines {
            clear: mk("clear")?,
            raster: mk("raster")?,
            raster_opaque: mk("raster_opaque")?,
            process: mk("process")?,
            link: mk("link")?,
            lookup: mk("lookup")?,
            lookup_opaque: mk("lookup_opaque")?,
            ceiling_insert: mk("ceiling_insert")?,
            layout,
        };
        let params = Params::new(SPECS)?;
        Ok(GpuDeepShadow {
            ctx,
            settings: Settings::from_params(&params)?,
            params,
            report: Report::default(),
            pipes,
            counter_start: 0,
            cancel: Cancel::new(),
        })
    }

    /// Tests only: start the list builds' fragment counter at `start` instead of 0, so that a
    /// small scene reaches the u32 wrap a scene of 2^32 fragments would.
    #[cfg(test)]
    fn set_counter_start(&mut self, start: u32) {
        self.counter_start = start;
    }

    /// The current settings.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    fn storage(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        let pad;
        let contents = if bytes.is_empty() {
            pad = [0u8; 16];
            &pad[..]
        } else {
            bytes
        };
        self.ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            })
    }

    fn uniform(&self, u: &DsUniform) -> wgpu::Buffer {
        self.ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("deep-shadow uniform"),
                contents: bytemuck::bytes_of(u),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    #[allow(clippy::too_many_arguments)]
    fn group(
        &self,
        u: &wgpu::Buffer,
        tris: &wgpu::Buffer,
        items: &wgpu::Buffer,
        map: &GpuMap,
        queries: &wgpu::Buffer,
        out: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        fn e(binding: u32, b: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            }
        }
        self.ctx
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("deep-shadow"),
                layout: &self.pipes.layout,
                entries: &[
                    e(0, u),
                    e(1, tris),
                    e(2, items),
                    e(3, &map.head),
                    e(4, &map.nodes),
                    e(5, &map.counters),
                    e(6, queries),
                    e(7, out),
                ],
            })
    }

    /// The largest element capacity the device can bind.
    pub fn device_capacity(&self) -> u64 {
        device_capacity(&self.ctx)
    }

    /// Builds, processes and links the deep shadow map of `scene` in `view` on the GPU (or, for an
    /// opaque scene, the nearest-depth map).
    pub fn build_map(&self, scene: &Scene, view: &LightView, s: &Settings) -> Result<GpuMap> {
        self.build_impl(scene, view, s, scene.is_opaque())
    }

    /// Builds lists even for an opaque scene (as [`crate::cpu::build_deep_map`] does; for the
    /// twin tests).
    pub fn build_lists(&self, scene: &Scene, view: &LightView, s: &Settings) -> Result<GpuMap> {
        self.build_impl(scene, view, s, false)
    }

    fn build_impl(
        &self,
        scene: &Scene,
        view: &LightView,
        s: &Settings,
        opaque: bool,
    ) -> Result<GpuMap> {
        let ctx = &self.ctx;
        let r = view.r;
        let texels = r as u64 * r as u64;
        self.check_head_bytes(texels)?;
        let prepared = prepare(scene, view);
        let tris = Self::gpu_triangles(&prepared);
        let items = Self::raster_items(&prepared, r);
        let max_cap = capacity_cap(ctx, s);
        let mut capacity = Self::initial_capacity(s, opaque, texels, max_cap);
        let tri_buf = self.storage("deep-shadow triangles", bytemuck::cast_slice(&tris));
        let item_buf = self.storage("deep-shadow raster items", bytemuck::cast_slice(&items));
        let dummy = self.storage("deep-shadow unused (read)", &[0u8; 16]);
        let dummy_rw = self.storage("deep-shadow unused (write)", &[0u8; 16]);
        let (head, counters) = self.head_and_counters(texels)?;
        let mut passes = 0;
        let mut map;
        loop {
            passes += 1;
            let nodes = self.element_buffer(capacity)?;
            map = GpuMap {
                r,
                head: head.clone(),
                nodes,
                counters: counters.clone(),
                opaque,
                stats: BuildStats::default(),
                cut_texels: 0,
            };
            let u = self.uniform(&DsUniform {
                r,
                capacity: capacity as u32,
                n_items: items.len() as u32,
                n_queries: 0,
                epsilon: s.epsilon,
                filter_mode: 0,
                kernel: 1,
                traversal: 0,
                c_world: 0.0,
                ortho: u32::from(view.is_ortho()),
                probe: LOOP_PROBE,
                trunc_window: crate::cpu::truncation_window(view, s),
                ..Default::default()
            });
            let group = self.group(&u, &tri_buf, &item_buf, &map, &dummy, &dummy_rw);
            self.run_raster(&group, &counters, texels, items.len() as u64, opaque)?;
            let c = ctx.read_buffer::<u32>(&counters, COUNTER_BYTES)?;
            // Elements asked for: the wraps of the u32 counter (from the invocation that took
            // index u32::MAX) above its last value.
            let count = (c[2] as u64) << 32 | c[0] as u64;
            if opaque || count <= capacity {
                map.stats = BuildStats {
                    fragments: count,
                    capacity,
                    passes,
                    ..Default::default()
                };
                // Process and link (§1.3.2, §1.3.3).
                if !opaque {
                    self.run_process_link(&group, texels)?;
                    let c = ctx.read_buffer::<u32>(&counters, COUNTER_BYTES)?;
                    let cut = c[3] as u64;
                    map.stats.kept = c[4] as u64;
                    map.stats.max_len = c[5];
                    if cut > 0 {
                        self.upload_cpu_lists(scene, view, s, &mut map, cut)?;
                    }
                }
                ctx.wait()?;
                return Ok(map);
            }
            // Overflow: the counter holds the need.
            if count > max_cap {
                return Err(Error::Limit {
                    what: if max_cap < s.max_capacity.min(u32::MAX as u64 - 1) {
                        "deep shadow map list elements in one storage binding (max_storage_buffer_binding_size; lower resolution)"
                    } else {
                        "deep shadow map list elements (raise max_capacity, lower resolution)"
                    },
                    requested: count,
                    max: max_cap,
                });
            }
            capacity = count;
        }
    }

    /// The loop budget cut `cut` texels' `process` or `link` short ([`LOOP_LIMIT`]): the CPU
    /// twin builds, processes and links the lists of `view` ([`crate::cpu::build_deep_map`]) and
    /// they replace `map`'s head and element buffers (the same layout, [`Node`]).
    fn upload_cpu_lists(
        &self,
        scene: &Scene,
        view: &LightView,
        s: &Settings,
        map: &mut GpuMap,
        cut: u64,
    ) -> Result<()> {
        let ctx = &self.ctx;
        let dsm = crate::cpu::build_deep_map(scene, view, s)?;
        ctx.queue
            .write_buffer(&map.head, 0, bytemuck::cast_slice(dsm.head()));
        let nodes = self.element_buffer(dsm.nodes().len().max(1) as u64)?;
        if !dsm.nodes().is_empty() {
            ctx.queue
                .write_buffer(&nodes, 0, bytemuck::cast_slice(dsm.nodes()));
        }
        map.nodes = nodes;
        map.stats = BuildStats {
            passes: map.stats.passes,
            ..*dsm.stats()
        };
        map.cut_texels = cut;
        Ok(())
    }

    /// Fails with [`Error::Limit`] when the `texels`-entry head buffer exceeds what the device
    /// can allocate and bind.
    fn check_head_bytes(&self, texels: u64) -> Result<()> {
        let l = self.ctx.limits();
        if texels * 4 > l.max_storage_buffer_binding_size.min(l.max_buffer_size) {
            return Err(Error::Limit {
                what: "deep-shadow head buffer bytes (max_storage_buffer_binding_size; lower the resolution)",
                requested: texels * 4,
                max: l.max_storage_buffer_binding_size.min(l.max_buffer_size),
            });
        }
        Ok(())
    }

    /// Creates the head buffer (one entry per texel) and the counter buffer ([`COUNTER_BYTES`]:
    /// elements, steps, wraps of the element counter).
    fn head_and_counters(&self, texels: u64) -> Result<(wgpu::Buffer, wgpu::Buffer)> {
        let ctx = &self.ctx;
        let head = ctx.scoped("deep-shadow head", || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("deep-shadow head"),
                size: texels * 4,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        let counters = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("deep-shadow counters"),
            size: COUNTER_BYTES,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok((head, counters))
    }

    /// Creates the list element buffer of `capacity` nodes.
    fn element_buffer(&self, capacity: u64) -> Result<wgpu::Buffer> {
        let ctx = &self.ctx;
        ctx.scoped("deep-shadow element buffer", || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("deep-shadow elements"),
                size: capacity * std::mem::size_of::<Node>() as u64,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })
    }

    /// Submits the clear and raster stages (counters zeroed first), without waiting.
    fn run_raster(
        &self,
        group: &wgpu::BindGroup,
        counters: &wgpu::Buffer,
        texels: u64,
        n_items: u64,
        opaque: bool,
    ) -> Result<()> {
        let ctx = &self.ctx;
        ctx.scoped("deep-shadow raster", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            enc.clear_buffer(counters, 0, None);
            if self.counter_start != 0 {
                // The clear above runs first; this copy lands after it in the same encoder.
                let mut start = [0u32; COUNTER_BYTES as usize / 4];
                start[0] = self.counter_start;
                let staging = ctx
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("deep-shadow counter start"),
                        contents: bytemuck::cast_slice(&start),
                        usage: wgpu::BufferUsages::COPY_SRC,
                    });
                enc.copy_buffer_to_buffer(&staging, 0, counters, 0, COUNTER_BYTES);
            }
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("deep-shadow build"),
                    timestamp_writes: None,
                });
                pass.set_bind_group(0, group, &[]);
                pass.set_pipeline(&self.pipes.clear);
                dispatch(&mut pass, texels);
                pass.set_pipeline(if opaque {
                    &self.pipes.raster_opaque
                } else {
                    &self.pipes.raster
                });
                dispatch(&mut pass, n_items);
            }
            ctx.queue.submit([enc.finish()]);
        })
    }

    /// Submits the process and link stages over every texel, without waiting.
    fn run_process_link(&self, group: &wgpu::BindGroup, texels: u64) -> Result<()> {
        let ctx = &self.ctx;
        ctx.scoped("deep-shadow process", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("deep-shadow process"),
                    timestamp_writes: None,
                });
                pass.set_bind_group(0, group, &[]);
                pass.set_pipeline(&self.pipes.process);
                dispatch(&mut pass, texels);
                pass.set_pipeline(&self.pipes.link);
                dispatch(&mut pass, texels);
            }
            ctx.queue.submit([enc.finish()]);
        })
    }

    /// The prepared triangles as the shader's [`Tri`]s (texel coordinates and 1/z in f32).
    fn gpu_triangles(prepared: &[crate::raster::PreparedTri]) -> Vec<Tri> {
        prepared
            .iter()
            .map(|t| Tri {
                u0: t.uv[0].x as f32,
                v0: t.uv[0].y as f32,
                u1: t.uv[1].x as f32,
                v1: t.uv[1].y as f32,
                u2: t.uv[2].x as f32,
                v2: t.uv[2].y as f32,
                iz0: t.inv_z[0] as f32,
                iz1: t.inv_z[1] as f32,
                iz2: t.inv_z[2] as f32,
                alpha: t.alpha,
                _pad0: 0,
                _pad1: 0,
            })
            .collect()
    }

    /// The raster work items `[triangle, tile x, tile y, 0]`: one per `TILE x TILE` tile of an
    /// `r x r` map that a triangle's texel-centre bounding box touches.
    fn raster_items(prepared: &[crate::raster::PreparedTri], r: u32) -> Vec<[u32; 4]> {
        let mut items: Vec<[u32; 4]> = Vec::new();
        let rf = r as f64;
        for (k, t) in prepared.iter().enumerate() {
            let lo = t.uv[0].min(t.uv[1]).min(t.uv[2]);
            let hi = t.uv[0].max(t.uv[1]).max(t.uv[2]);
            let i0 = (lo.x - 0.5).ceil().clamp(0.0, rf) as u32;
            let i1 = ((hi.x - 0.5).floor() + 1.0).clamp(0.0, rf) as u32;
            let j0 = (lo.y - 0.5).ceil().clamp(0.0, rf) as u32;
            let j1 = ((hi.y - 0.5).floor() + 1.0).clamp(0.0, rf) as u32;
            if i0 >= i1 || j0 >= j1 {
                continue;
            }
            for ty in j0 / TILE..=(j1 - 1) / TILE {
                for tx in i0 / TILE..=(i1 - 1) / TILE {
                    items.push([k as u32, tx * TILE, ty * TILE, 0]);
                }
            }
        }
        items
    }

    /// The first build's element capacity: 1 for an opaque map, else the setting (0: four per
    /// texel, at least 1024), within `1..=max_cap`.
    pub(crate) fn initial_capacity(s: &Settings, opaque: bool, texels: u64, max_cap: u64) -> u64 {
        if opaque {
            1
        } else if s.capacity == 0 {
            (4 * texels).max(1024)
        } else {
            s.capacity
        }
        .min(max_cap)
        .max(1)
    }

    /// The in-run ceiling of the build: bare list inserts per second (`ceiling_insert` in the
    /// WGSL: counter, head exchange, one element write; `n` inserts into an `r x r` head buffer),
    /// the best of `reps` wall-clock runs of one submit and one wait.
    pub fn insert_ceiling(&self, r: u32, n: u32, reps: u32) -> Result<f64> {
        let ctx = &self.ctx;
        let texels = r as u64 * r as u64;
        let mk = |label, size: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let map = GpuMap {
            r,
            head: mk("ceiling head", texels * 4),
            nodes: mk(
                "ceiling elements",
                n as u64 * std::mem::size_of::<Node>() as u64,
            ),
            counters: mk("ceiling counters", COUNTER_BYTES),
            opaque: false,
            stats: BuildStats::default(),
            cut_texels: 0,
        };
        let u = self.uniform(&DsUniform {
            r,
            capacity: n,
            n_items: n,
            n_queries: 0,
            epsilon: 0.0,
            filter_mode: 0,
            kernel: 1,
            traversal: 0,
            c_world: 0.0,
            ..Default::default()
        });
        let dummy = self.storage("ceiling unused (read)", &[0u8; 16]);
        let dummy_rw = self.storage("ceiling unused (write)", &[0u8; 16]);
        let group = self.group(&u, &dummy, &dummy, &map, &dummy, &dummy_rw);
        let mut best = f64::INFINITY;
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            ctx.scoped("deep-shadow insert ceiling", || {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                enc.clear_buffer(&map.counters, 0, None);
                {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("deep-shadow insert ceiling"),
                        timestamp_writes: None,
                    });
                    pass.set_bind_group(0, &group, &[]);
                    pass.set_pipeline(&self.pipes.ceiling_insert);
                    dispatch(&mut pass, n as u64);
                }
                ctx.queue.submit([enc.finish()]);
            })?;
            ctx.wait()?;
            best = best.min(t.elapsed().as_secs_f64());
        }
        Ok(n as f64 / best)
    }

    /// Reads a GPU map back as the CPU twin's structure (the loop-limit redo's lists).
    fn read_map(&self, map: &GpuMap) -> Result<DeepShadowMap> {
        let head: Vec<u32> = self.ctx.read_buffer(&map.head, map.head.size())?;
        let mut nodes: Vec<Node> = self.ctx.read_buffer(&map.nodes, map.nodes.size())?;
        nodes.truncate(map.stats.fragments.min(map.stats.capacity) as usize);
        DeepShadowMap::from_parts(map.r, head, nodes, map.stats)
    }

    /// Filtered transmittance for each packed query ([`pack_query`]; fixed >= 0: no lookup), the
    /// list elements visited, and how many lookups the device's loop budget cut short and the
    /// CPU twin's lookup redid on the same map ([`LOOP_LIMIT`]).
    pub fn lookup(
        &self,
        map: &GpuMap,
        ls: &LookupSettings,
        queries: &[PackedQuery],
    ) -> Result<(Vec<f32>, u64, usize)> {
        let ctx = &self.ctx;
        let n = queries.len();
        if n == 0 {
            return Ok((Vec::new(), 0, 0));
        }
        let mut counted = 0usize;
        let max_q = (ctx.limits().max_storage_buffer_binding_size as usize)
            / std::mem::size_of::<PackedQuery>();
        let mut out = Vec::with_capacity(n);
        let mut steps = 0u64;
        for part in queries.chunks(max_q.max(1)) {
            let u = self.uniform(&lookup_uniform(
                map.r,
                map.stats.capacity as u32,
                part.len() as u32,
                ls,
            ));
            let q = self.storage("deep-shadow queries", bytemuck::cast_slice(part));
            let o = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("deep-shadow T"),
                size: (part.len() * 4) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let dummy = self.storage("deep-shadow unused", &[0u8; 16]);
            let group = self.group(&u, &dummy, &dummy, map, &q, &o);
            ctx.scoped("deep-shadow lookup", || {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                // Steps, wraps (unused here) and cut lookups.
                enc.clear_buffer(&map.counters, 4, Some(COUNTER_BYTES - 4));
                {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("deep-shadow lookup"),
                        timestamp_writes: None,
                    });
                    pass.set_bind_group(0, &group, &[]);
                    pass.set_pipeline(if map.opaque {
                        &self.pipes.lookup_opaque
                    } else {
                        &self.pipes.lookup
                    });
                    dispatch(&mut pass, part.len() as u64);
                }
                ctx.queue.submit([enc.finish()]);
            })?;
            out.extend(ctx.read_buffer::<f32>(&o, (part.len() * 4) as u64)?);
            let c = ctx.read_buffer::<u32>(&map.counters, COUNTER_BYTES)?;
            steps += c[1] as u64;
            counted += c[3] as usize;
        }
        let redone = self.redo_cut_lookups(map, ls, queries, &mut out, counted)?;
        Ok((out, steps, redone))
    }

    /// Lookups written as `CUT_BITS` ([`LOOP_LIMIT`]): the CPU twin's lookup on the same map,
    /// read back once. `counted` is the kernel's own count; a mismatch with the flags is an
    /// [`Error::Gpu`].
    fn redo_cut_lookups(
        &self,
        map: &GpuMap,
        ls: &LookupSettings,
        queries: &[PackedQuery],
        out: &mut [f32],
        counted: usize,
    ) -> Result<usize> {
        let cut: Vec<usize> = (0..out.len())
            .filter(|&k| out[k].to_bits() == CUT_BITS)
            .collect();
        if cut.len() != counted {
            return Err(Error::Gpu {
                stage: "deep-shadow lookup".into(),
                reason: format!(
                    "{counted} lookups counted as cut short by the loop limit, {} flagged",
                    cut.len()
                ),
            });
        }
        if cut.is_empty() {
            return Ok(0);
        }
        let lists = if map.opaque {
            None
        } else {
            Some(self.read_map(map)?)
        };
        let depth = if map.opaque {
            let head: Vec<u32> = self.ctx.read_buffer(&map.head, map.head.size())?;
            Some(DepthMap {
                size: map.r,
                depth: head
                    .into_iter()
                    .map(|b| {
                        if b == crate::shared::NIL {
                            f32::INFINITY
                        } else {
                            f32::from_bits(b)
                        }
                    })
                    .collect(),
            })
        } else {
            None
        };
        for &k in &cut {
            let (uv, plane, facing) = unpack_look(&queries[k], ls.soft.ortho);
            let t = match (&lists, &depth) {
                (Some(dsm), _) => dsm.transmittance_plane(uv, &plane, ls).0,
                (None, Some(m)) => crate::dsm::transmittance_opaque_plane(m, uv, &plane, ls),
                (None, None) => unreachable!("one of the two maps is read"),
            };
            out[k] = facing * t;
        }
        Ok(cut.len())
    }
}
