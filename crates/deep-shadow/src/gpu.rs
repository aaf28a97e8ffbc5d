//! Deep shadow maps on the engine path: [`DeepShadowFrame`], prepared once, then each
//! frame recorded into the caller's command encoder from the caller's casters and receiver buffer,
//! V written into the caller's buffer; nothing submitted, waited for or read back.
//!
//! Per sub-light view, in turn (one view for the default S = 1), for **opaque casters**:
//! 1. the core's raster pass renders the casters into one R32Float layer
//!    ([`GpuMapFrame`]: the hardware rasteriser, as every other engine path; the CPU twin's
//!    opaque path reads the core's CPU raster of the same view). The hardware rasteriser snaps
//!    vertices to sub-texel steps (8 bits on lavapipe), so a texel centre within about 1/256
//!    texel of an edge can be covered here and not on the CPU, or the reverse;
//! 2. `frame_head` turns the layer into the opaque path's head buffer (the nearest depth's bits,
//!    `NIL` where empty);
//! 3. `frame_lookup` makes each receiver's query on the GPU (the twin of [`crate::math::view::query`]:
//!    facing, light-space position, projection, caster test) and adds its filtered transmittance
//!    (`opaque_transmittance` in `deep_shadow.wgsl`, the twin of
//!    [`crate::math::transmittance_opaque_plane`]) into a per-receiver sum.
//!
//! For **semi-transparent casters** (the caster buffer's w, each mesh's opacity), steps 1 and 2
//! build lists instead, as the paper does (§1.3.1 to §1.3.3): `clear` (heads to `NIL`), the
//! insert pass (`insert.wgsl`: the core's vertex stage, and a fragment stage that appends each
//! fragment's (z, opacity) to its texel's list with `atomicAdd` and `atomicExchange`; fully
//! transparent casters are skipped, as [`crate::cpu::raster::prepare`] drops them), `process` (sort,
//! tau, truncation) and `link`, then `frame_lookup` walks the lists (`list_transmittance`). The
//! element buffer is allocated at the first semi-transparent frame (`capacity` elements, 0: four
//! per texel, at most `max_capacity` and the device's binding limit); a frame whose fragments
//! overflow it (or wrap the u32 element counter), or whose `process` or `link` the loop budget
//! cut, leaves every active receiver NaN and counted as cut (status word 2): nothing is lost
//! silently, and the callers that read V back (the CLI, the GPU estimator) redo them with the
//! CPU twin in the same views.
//!
//! Then `frame_finish` writes `V = sum / views` ([`crate::cpu::finish`]).
//!
//! Receivers looked up outside some view's map (no map holds their casters, [`crate::cpu::mark_outside`])
//! skip the later views and go to the core's settle passes ([`shadow_map_core::gpu::settle`]),
//! which give them their facing fraction where no caster triangle lies in their light pyramid
//! and leave them NaN elsewhere, as the CPU twin's `settle_outside` settles or refuses them.
//!
//! The status buffer (four u32, cleared by each `encode`): `[0]` receivers looked up outside
//! some view's map (each once), `[1]` non-finite V written as 0, `[2]` receivers the device's
//! loop budget cut short (`loop_limit_hit`, lavapipe's 65535 loop iterations per invocation:
//! PCSS's blocker search and filter at large kernels), `[3]` of `[0]`, those left NaN: V left NaN,
//! for the caller to redo (the CLI redoes NaN actives with the CPU twin in the same views).
//!
//! The registry's GPU estimator is this frame run by the core's `FrameTwin` (receivers uploaded,
//! one frame, V read back, the NaN actives redone by [`FrameEstimator::cpu_twin`]).
//! [`DeepShadowFrame::read_map`] reads the last view's map back for tests and tools.
use crate::cpu::dsm::{BuildStats, DeepShadowMap};
use crate::cpu::{CpuDeepShadow, Tally};
use crate::math::view::{lookup_settings, sublight_points, truncation_window, view_light};
use crate::math::{Node, NIL};
use crate::settings::{Filter, Settings, NAME};
use bytemuck::{Pod, Zeroable};
use shadow_map_core::gpu::estimate::CELLS_WGSL;
use shadow_map_core::{
    gpu::{
        depth_map::DEPTH_MAP_FORMAT,
        estimate::{EstimateUniform, LIGHT_HEAD_WGSL, LIGHT_RECT, OVERRIDES},
        frame::{
            check_per_receiver, check_prepared_inputs, compute_pass, compute_pass_indirect,
            cpu_twin_v, status_buffer, FrameEstimator, FrameInputs, ReceiverRange, Views,
        },
        kernel::{shader_module, uniform_buffer, BindGroupCache, Binding, SpecializedKernel},
        raster::{RASTER_WGSL, VERTEX_BUFFERS},
        receivers::{ActiveLists, ACTIVE_WGSL},
        settle::{GpuSettler, OPEN_WGSL},
        shared::LightViewUniform,
        GpuContext, GpuMapFrame, GpuScene, GpuShadowMapper,
    },
    raster::{RasterOptions, PEEL_EPS_REL},
    DepthMap, Error, LightView, Params, Receivers, Result, Scene,
};
use std::sync::{
    atomic::{AtomicBool, Ordering},
    Arc, Mutex,
};

mod kernel;
#[cfg(test)]
mod tests;

use kernel::{
    capacity_cap, initial_capacity, lookup_switches, lookup_uniform, workgroups, OWN_OVERRIDES,
};
pub use kernel::{DsUniform, COUNTER_BYTES, DEEP_SHADOW_WGSL, NODE_WGSL};

/// Every shader module of the crate as `(name, parts)` (validated with naga by a unit test).
pub const SHADERS: &[(&str, &[&str])] = &[
    ("deep_shadow_frame", FRAME_SHADER_PARTS),
    ("deep_shadow_insert", INSERT_SHADER_PARTS),
];

/// The engine path's own WGSL (appended to [`FRAME_SHADER_PARTS`]' others).
pub const FRAME_WGSL: &str = include_str!("frame.wgsl");

/// The engine path's module, in order: the core's light head ([`LIGHT_HEAD_WGSL`]: shared
/// structs, estimate uniform and math), the core's cells, the list element ([`NODE_WGSL`]), [`DEEP_SHADOW_WGSL`], the
/// core's active-list reader ([`ACTIVE_WGSL`]), then [`FRAME_WGSL`].
pub const FRAME_SHADER_PARTS: &[&str] = &[
    LIGHT_HEAD_WGSL,
    CELLS_WGSL,
    NODE_WGSL,
    DEEP_SHADOW_WGSL,
    ACTIVE_WGSL,
    OPEN_WGSL,
    FRAME_WGSL,
];

/// The frame's settings as `frame.wgsl` reads them (`DsFrameUniform`), 32 bytes.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, Default)]
pub struct DsFrameUniform {
    /// Constant bias b0 ([`Settings::bias`]).
    pub bias: f32,
    /// Slope bias b1 ([`Settings::slope_bias`]).
    pub slope_bias: f32,
    /// 1: receiver-plane rejection ([`Settings::receiver_plane`]).
    pub receiver_plane: u32,
    /// 1: `filter=pcss`, whose facing factor is the fraction of the view's light in front.
    pub pcss: u32,
    /// `1 / views`.
    pub inv_views: f32,
    /// 1: semi-transparent casters, looked up in the lists (`insert.wgsl`); 0: the opaque path.
    pub lists: u32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// The list path (semi-transparent casters): the insert pass, `clear`, `process` and `link`,
/// the element buffer (allocated at the first semi-transparent frame, `capacity` elements) and
/// the counters.
struct Lists {
    insert: wgpu::RenderPipeline,
    /// Per view slot: the insert pass's group 0 (the slot's view uniform).
    view_groups: Vec<wgpu::BindGroup>,
    /// Group 1 of the insert pass: head, elements, counters.
    layout: wgpu::BindGroupLayout,
    clear: wgpu::ComputePipeline,
    process: wgpu::ComputePipeline,
    link: wgpu::ComputePipeline,
    capacity: u64,
    nodes: Mutex<wgpu::Buffer>,
    counters: wgpu::Buffer,
    /// Tests only: counter words copied over the cleared counters before each view's insert
    /// pass, so that a small scene reaches the u32 wrap a scene of 2^32 fragments would.
    #[cfg(test)]
    counter_start: Mutex<Option<wgpu::Buffer>>,
}

/// The insert pass's WGSL, after the core's [`RASTER_WGSL`] (its `vs_main`).
pub const INSERT_WGSL: &str = include_str!("insert.wgsl");

/// The insert pass's module, in order: the core's rasteriser ([`RASTER_WGSL`]), the list
/// element ([`NODE_WGSL`]), then [`INSERT_WGSL`].
pub const INSERT_SHADER_PARTS: &[&str] = &[RASTER_WGSL, NODE_WGSL, INSERT_WGSL];

impl Lists {
    fn prepare(
        ctx: &GpuContext,
        s: &Settings,
        map: &GpuMapFrame,
        mk: &dyn Fn(&str) -> Result<wgpu::ComputePipeline>,
    ) -> Result<Lists> {
        let texels = s.resolution as u64 * s.resolution as u64;
        let capacity = initial_capacity(s, texels, capacity_cap(ctx, s));
        let module = shader_module(ctx, "deep-shadow insert", INSERT_SHADER_PARTS)?;
        let view_layout = ctx.scoped("deep-shadow insert layout", || {
            ctx.device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("deep-shadow insert view"),
                    entries: &[Binding::Uniform.entry_in(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
                })
        })?;
        let layout = ctx.scoped("deep-shadow insert layout", || {
            let rw = |k| Binding::StorageRw.entry_in(k, wgpu::ShaderStages::FRAGMENT);
            ctx.device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("deep-shadow insert lists"),
                    entries: &[rw(0), rw(1), rw(2)],
                })
        })?;
        let constants = [
            ("PEEL_EPS_REL", PEEL_EPS_REL as f64),
            ("PEEL", 0.0),
            ("NIL", NIL as f64),
        ];
        let options = || wgpu::PipelineCompilationOptions {
            constants: &constants,
            ..Default::default()
        };
        let insert = ctx.scoped("deep-shadow insert", || {
            let pl = ctx
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("deep-shadow insert"),
                    bind_group_layouts: &[Some(&view_layout), Some(&layout)],
                    immediate_size: 0,
                });
            ctx.device
                .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("deep-shadow insert"),
                    layout: Some(&pl),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vs_main"),
                        compilation_options: options(),
                        buffers: VERTEX_BUFFERS,
                    },
                    primitive: wgpu::PrimitiveState::default(),
                    depth_stencil: None,
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some("fs_insert"),
                        compilation_options: options(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format: DEPTH_MAP_FORMAT,
                            blend: None,
                            write_mask: wgpu::ColorWrites::empty(),
                        })],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
        })?;
        let view_groups = (0..map.slots())
            .map(|slot| {
                ctx.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("deep-shadow insert view"),
                    layout: &view_layout,
                    entries: &[wgpu::BindGroupEntry {
                        binding: 0,
                        resource: map.view_uniform(slot).as_entire_binding(),
                    }],
                })
            })
            .collect();
        Ok(Lists {
            insert,
            view_groups,
            layout,
            clear: mk("clear")?,
            process: mk("process")?,
            link: mk("link")?,
            capacity,
            nodes: Mutex::new(storage_buffer(
                ctx,
                "deep-shadow frame elements (none yet)",
                32,
            )),
            counters: storage_buffer(ctx, "deep-shadow frame counters", COUNTER_BYTES),
            #[cfg(test)]
            counter_start: Mutex::new(None),
        })
    }

    /// The element buffer; allocated at `capacity` elements on the first call that `grow`s.
    fn nodes(&self, ctx: &GpuContext, grow: bool) -> Result<wgpu::Buffer> {
        let mut nodes = self.nodes.lock().map_err(|_| Error::Gpu {
            stage: "deep-shadow frame".into(),
            reason: "element buffer lock poisoned".into(),
        })?;
        let bytes = self.capacity * std::mem::size_of::<Node>() as u64;
        if grow && nodes.size() < bytes {
            ctx.check_storage_bytes("deep-shadow list element bytes", bytes)?;
            *nodes = storage_buffer(ctx, "deep-shadow frame elements", bytes);
        }
        Ok(nodes.clone())
    }

    /// Records one view's lists: counters cleared, heads cleared, the insert pass (through
    /// `lists`, the insert pass's group 1) into `target`, then `process` and `link` (through
    /// `group`, the frame's bindings).
    fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        (group, lists): (&wgpu::BindGroup, &wgpu::BindGroup),
        slot: usize,
        casters: &GpuScene,
        target: &wgpu::TextureView,
        texels: u64,
    ) {
        enc.clear_buffer(&self.counters, 0, None);
        #[cfg(test)]
        if let Some(start) = &*self.counter_start.lock().expect("counter start") {
            enc.copy_buffer_to_buffer(start, 0, &self.counters, 0, COUNTER_BYTES);
        }
        compute_pass(
            enc,
            "deep-shadow frame clear",
            &self.clear,
            group,
            workgroups(texels),
        );
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("deep-shadow frame insert"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if casters.triangles > 0 {
                pass.set_pipeline(&self.insert);
                pass.set_bind_group(0, &self.view_groups[slot], &[]);
                pass.set_bind_group(1, lists, &[]);
                pass.set_vertex_buffer(0, casters.vertices.slice(..));
                pass.draw(0..3 * casters.triangles, 0..1);
            }
        }
        compute_pass(
            enc,
            "deep-shadow frame process",
            &self.process,
            group,
            workgroups(texels),
        );
        compute_pass(
            enc,
            "deep-shadow frame link",
            &self.link,
            group,
            workgroups(texels),
        );
    }
}

/// Per view slot: the lookup uniform and the view's light.
struct Slot {
    ds: wgpu::Buffer,
    light: wgpu::Buffer,
}

/// Deep shadow maps on the engine path (module documentation).
pub struct DeepShadowFrame {
    ctx: Arc<GpuContext>,
    groups: BindGroupCache,
    params: Params,
    settings: Settings,
    map: GpuMapFrame,
    head_pipe: wgpu::ComputePipeline,
    /// `frame_lookup` and `frame_finish`, specialised for the light's shape at each encode.
    kernel: SpecializedKernel,
    lists: Lists,
    head: wgpu::Buffer,
    slots: Vec<Slot>,
    light: wgpu::Buffer,
    frame: wgpu::Buffer,
    acc: wgpu::Buffer,
    status: wgpu::Buffer,
    /// Each range's active receivers, listed every frame: the per-receiver passes run over them.
    active: ActiveLists,
    /// The settle passes over the receivers no view's map holds.
    settler: GpuSettler,
    max_receivers: u32,
    /// Whether the last `encode` built lists (semi-transparent casters), for [`Self::read_map`].
    last_lists: AtomicBool,
}

/// The map of one view as the frame's lookups read it ([`DeepShadowFrame::read_map`]).
#[derive(Debug, Clone, PartialEq)]
pub enum FrameMap {
    /// Semi-transparent casters: the processed and linked lists, as the CPU twin's structure.
    Lists(DeepShadowMap),
    /// Opaque casters: the nearest depth of each texel (+inf where empty).
    Depths(DepthMap),
}

/// A storage buffer the frame clears (`COPY_DST`) and [`DeepShadowFrame::read_map`] reads back
/// (`COPY_SRC`).
fn storage_buffer(ctx: &GpuContext, label: &str, bytes: u64) -> wgpu::Buffer {
    shadow_map_core::gpu::kernel::storage_buffer(ctx, label, bytes.max(16))
}

impl DeepShadowFrame {
    /// Compiles the pipelines and allocates the map (one view slot per sub-light), the head
    /// buffer, the uniforms and the per-receiver sums for `max_receivers`, for `params` (a table
    /// of deep-shadow's specs). Errors: the parameters' own, a resolution beyond the device's
    /// limits ([`Error::Limit`]).
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params, max_receivers: u32) -> Result<Self> {
        let settings = Settings::from_params(params)?;
        let r = settings.resolution;
        let texels = r as u64 * r as u64;
        let head_bytes = 4 * texels;
        ctx.check_storage_bytes(
            "deep-shadow head buffer bytes (max_storage_buffer_binding_size)",
            head_bytes,
        )?;
        check_per_receiver(
            &ctx,
            "deep-shadow frame sums bytes (max_storage_buffer_binding_size)",
            max_receivers,
        )?;
        let views = settings.sublights * settings.sublights;
        let map = GpuShadowMapper::new(&ctx)?.map_frame(
            &ctx,
            r,
            RasterOptions::default(),
            views,
            false,
        )?;
        let overrides: Vec<(&str, f64)> = OVERRIDES.iter().chain(OWN_OVERRIDES).copied().collect();
        let kernel = SpecializedKernel::new(
            &ctx,
            "deep-shadow frame",
            FRAME_SHADER_PARTS,
            "frame_lookup",
            &overrides,
        )?;
        // The per-texel passes read no light: their pipelines are made once, with the rect's
        // shape code; `frame_lookup` and `frame_finish` are specialised per frame.
        let texel_shape = [("LIGHT_SHAPE", LIGHT_RECT as f64)];
        let mk = |entry: &str| kernel.entry_pipeline(&ctx, entry, &texel_shape);
        let head_pipe = mk("frame_head")?;
        let lists = Lists::prepare(&ctx, &settings, &map, &mk)?;
        let ds_bytes = std::mem::size_of::<DsUniform>() as u64;
        let est_bytes = std::mem::size_of::<EstimateUniform>() as u64;
        let slots = (0..views)
            .map(|_| Slot {
                ds: uniform_buffer(&ctx, "deep-shadow frame lookup uniform", ds_bytes),
                light: uniform_buffer(&ctx, "deep-shadow frame view light", est_bytes),
            })
            .collect();
        Ok(DeepShadowFrame {
            groups: BindGroupCache::default(),
            active: ActiveLists::new(&ctx)?,
            settler: GpuSettler::new(&ctx)?,
            head: storage_buffer(&ctx, "deep-shadow frame head", head_bytes),
            light: uniform_buffer(&ctx, "deep-shadow frame light", est_bytes),
            frame: uniform_buffer(
                &ctx,
                "deep-shadow frame uniform",
                std::mem::size_of::<DsFrameUniform>() as u64,
            ),
            acc: storage_buffer(&ctx, "deep-shadow frame sums", 4 * max_receivers as u64),
            status: status_buffer(&ctx, "deep-shadow frame status", 4),
            params: params.clone(),
            settings,
            map,
            head_pipe,
            kernel,
            lists,
            slots,
            max_receivers,
            last_lists: AtomicBool::new(false),
            ctx,
        })
    }

    /// The map of the last view the last submitted frame encoded, read back (blocking: for tests
    /// and tools, not per frame): the lists (elements past the capacity dropped, `BuildStats`
    /// from the counters: fragments, kept, longest list) or the opaque path's heads as depths.
    /// Errors: lists that break the map's invariant ([`DeepShadowMap::from_parts`]), a failed
    /// readback.
    pub fn read_map(&self) -> Result<FrameMap> {
        let ctx = &self.ctx;
        let r = self.map.r;
        let head: Vec<u32> = ctx.read_buffer(&self.head, 4 * r as u64 * r as u64)?;
        if !self.last_lists.load(Ordering::Relaxed) {
            let depth = head
                .into_iter()
                .map(|b| {
                    if b == NIL {
                        f32::INFINITY
                    } else {
                        f32::from_bits(b)
                    }
                })
                .collect();
            return Ok(FrameMap::Depths(DepthMap { size: r, depth }));
        }
        let c: Vec<u32> = ctx.read_buffer(&self.lists.counters, COUNTER_BYTES)?;
        let nodes_buf = self.lists.nodes(ctx, false)?;
        let mut nodes: Vec<Node> = ctx.read_buffer(&nodes_buf, nodes_buf.size())?;
        let capacity = self.lists.capacity;
        nodes.truncate((c[0] as u64).min(capacity) as usize);
        let stats = BuildStats {
            fragments: c[0] as u64,
            capacity,
            passes: 1,
            kept: c[4] as u64,
            max_len: c[5],
            lists: head.iter().filter(|&&h| h != NIL).count() as u64,
        };
        Ok(FrameMap::Lists(DeepShadowMap::from_parts(
            r, head, nodes, stats,
        )?))
    }

    /// Tests only: start each view's element counter at `start` instead of 0.
    #[cfg(test)]
    fn set_counter_start(&self, start: u32) {
        use shadow_map_core::gpu::kernel::BufferInitExt;
        let mut words = [0u32; COUNTER_BYTES as usize / 4];
        words[0] = start;
        let b = (start != 0).then(|| {
            self.ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("deep-shadow counter start"),
                    contents: bytemuck::cast_slice(&words),
                    usage: wgpu::BufferUsages::COPY_SRC,
                })
        });
        *self.lists.counter_start.lock().expect("counter start") = b;
    }

    fn group(
        &self,
        ds: &wgpu::Buffer,
        view: &wgpu::Buffer,
        light: &wgpu::Buffer,
        nodes: &wgpu::Buffer,
        inputs: &FrameInputs<'_>,
        (range, list, open): (ReceiverRange, &wgpu::Buffer, &wgpu::Buffer),
    ) -> wgpu::BindGroup {
        let e = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        self.groups.get(
            &self.ctx,
            "deep-shadow frame",
            &self.kernel.layout,
            &[
                e(0, ds.as_entire_binding()),
                e(3, self.head.as_entire_binding()),
                e(4, nodes.as_entire_binding()),
                e(5, self.lists.counters.as_entire_binding()),
                e(8, view.as_entire_binding()),
                e(9, light.as_entire_binding()),
                e(10, wgpu::BindingResource::TextureView(&self.map.layer.view)),
                e(11, range.receivers(inputs.receivers)),
                e(12, range.words(&self.acc)),
                e(13, range.words(inputs.v)),
                e(14, self.status.as_entire_binding()),
                e(15, self.frame.as_entire_binding()),
                e(16, list.as_entire_binding()),
                e(17, open.as_entire_binding()),
            ],
        )
    }
}

impl FrameEstimator for DeepShadowFrame {
    fn name(&self) -> &'static str {
        NAME
    }

    /// One view per sub-light point, as the estimator's `estimate` fits them
    /// ([`Tally::fit_view`]: the filter margin, and under `filter=pcss` the reach of the view's
    /// light). A sub-light no receiver is in front of fails the fit, as on the CPU.
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.ctx.check_lost()?;
        let mut tally = Tally::default();
        sublight_points(scene, self.settings.sublights)
            .into_iter()
            .map(|y| Ok(Some(tally.fit_view(scene, receivers, y, &self.settings)?.0)))
            .collect()
    }

    /// The map, the list heads and the element buffer as allocated now.
    fn light_space_bytes(&self) -> usize {
        let nodes = self.lists.nodes.lock().map_or(0, |b| b.size());
        self.map.layer.bytes() + (self.head.size() + nodes) as usize
    }

    fn status(&self) -> Option<&wgpu::Buffer> {
        Some(&self.status)
    }

    /// Semi-transparent casters are modelled: their fragments go into lists.
    fn models_opacity(&self) -> bool {
        true
    }

    /// Per view: the raster pass, `frame_head`, `frame_lookup`; then `frame_finish`. Errors
    /// also for views missing or more than the sub-lights ([`Error::LightView`]) and more
    /// receivers than `max_receivers` ([`Error::Limit`]).
    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let n = check_prepared_inputs(
            &self.ctx,
            inputs,
            self.max_receivers,
            "receivers per deep-shadow frame (max_receivers at prepare)",
        )?;
        self.groups.next_encode();
        let views: Vec<&LightView> = inputs.views.iter().flatten().collect();
        if views.len() != inputs.views.len() || views.len() != self.slots.len() {
            return Err(Error::LightView(format!(
                "deep-shadow renders one view per sub-light ({}), {} given ({} present)",
                self.slots.len(),
                inputs.views.len(),
                views.len()
            )));
        }
        if let Some(v) = views.iter().find(|v| v.r != self.map.r) {
            return Err(Error::LightView(format!(
                "a sub-light view has resolution {} but the map was prepared at {}",
                v.r, self.map.r
            )));
        }
        let ctx = &self.ctx;
        let s = &self.settings;
        let light = inputs.light;
        // Semi-transparent casters: lists (the insert pass), else the opaque path's heads.
        let lists = !inputs.casters.is_opaque();
        self.last_lists.store(lists, Ordering::Relaxed);
        let eu = EstimateUniform::new(light, s.bias, s.slope_bias);
        ctx.write_in(enc, &self.light, 0, bytemuck::bytes_of(&eu));
        let fu = DsFrameUniform {
            bias: s.bias,
            slope_bias: s.slope_bias,
            receiver_plane: u32::from(s.receiver_plane),
            pcss: u32::from(s.filter == Filter::Pcss),
            inv_views: 1.0 / views.len().max(1) as f32,
            lists: u32::from(lists),
            ..Default::default()
        };
        ctx.write_in(enc, &self.frame, 0, bytemuck::bytes_of(&fu));
        enc.clear_buffer(&self.status, 0, None);
        enc.clear_buffer(&self.acc, 0, None);
        if n == 0 {
            return Ok(());
        }
        let shape = [eu.shape_switch()];
        let finish_pipe = self.kernel.entry_pipeline(ctx, "frame_finish", &shape)?;
        let texels = self.map.r as u64 * self.map.r as u64;
        // The per-receiver passes run once per range of receivers (its own bind group); the
        // per-texel passes bind the first range's group, whose receivers they do not read.
        // Each range's active receivers, listed once for every view's lookup and the finish
        // (inactive ones NaN).
        let ranges =
            self.active
                .encode_ranges(ctx, enc, inputs.count, inputs.receivers, inputs.v)?;
        let open: Vec<wgpu::Buffer> = ranges
            .iter()
            .enumerate()
            .map(|(index, (range, _))| self.settler.open_list(ctx, enc, index, *range))
            .collect();
        let nodes = self.lists.nodes(&self.ctx, lists)?;
        let list_group = lists.then(|| {
            let entries: Vec<_> = [&self.head, &nodes, &self.lists.counters]
                .into_iter()
                .enumerate()
                .map(|(k, b)| wgpu::BindGroupEntry {
                    binding: k as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            self.groups.get(
                &self.ctx,
                "deep-shadow insert lists",
                &self.lists.layout,
                &entries,
            )
        });
        inputs.mark(enc, "start");
        for (slot, (view, bufs)) in views.iter().zip(&self.slots).enumerate() {
            let ls = lookup_settings(view, light, s);
            let mut u = lookup_uniform(view.r, 0, &ls);
            if lists {
                // What `process` reads besides.
                u.capacity = self.lists.capacity as u32;
                u.epsilon = s.epsilon;
                u.trunc_window = truncation_window(view, s);
            }
            ctx.write_in(enc, &bufs.ds, 0, bytemuck::bytes_of(&u));
            let lookup_pipe = self.kernel.entry_pipeline(
                ctx,
                "frame_lookup",
                &lookup_switches(&u, lists, shape[0]),
            )?;
            let vl = view_light(light, view, s.sublights);
            ctx.write_in(
                enc,
                &bufs.light,
                0,
                bytemuck::bytes_of(&EstimateUniform::new(&vl, s.bias, s.slope_bias)),
            );
            let groups: Vec<_> = ranges
                .iter()
                .zip(&open)
                .map(|((r, list), open)| {
                    self.group(
                        &bufs.ds,
                        self.map.view_uniform(slot),
                        &bufs.light,
                        &nodes,
                        inputs,
                        (*r, list, open),
                    )
                })
                .collect();
            let group = &groups[0];
            if let Some(list_group) = &list_group {
                ctx.write_in(
                    enc,
                    self.map.view_uniform(slot),
                    0,
                    bytemuck::bytes_of(&LightViewUniform::from(*view)),
                );
                self.lists.encode(
                    enc,
                    (group, list_group),
                    slot,
                    inputs.casters,
                    &self.map.layer.view,
                    texels,
                );
                inputs.mark(enc, "lists");
            } else {
                self.map.encode(ctx, enc, inputs.casters, view, slot)?;
                inputs.mark(enc, "raster");
                compute_pass(
                    enc,
                    "deep-shadow frame head",
                    &self.head_pipe,
                    group,
                    workgroups(texels),
                );
                inputs.mark(enc, "heads");
            }
            for ((_, list), group) in ranges.iter().zip(&groups) {
                compute_pass_indirect(enc, "deep-shadow frame lookup", &lookup_pipe, group, list);
            }
            inputs.mark(enc, "lookup");
        }
        for ((range, list), open) in ranges.iter().zip(&open) {
            let group = self.group(
                &self.slots[0].ds,
                self.map.view_uniform(0),
                &self.light,
                &nodes,
                inputs,
                (*range, list, open),
            );
            compute_pass_indirect(enc, "deep-shadow frame finish", &finish_pipe, &group, list);
        }
        inputs.mark(enc, "finish");
        // The receivers no view's map holds: their facing fraction where no caster can shadow
        // them, else NaN (status word 3), as the CPU twin's settle_outside.
        for ((range, _), open) in ranges.iter().zip(&open) {
            self.settler.encode(
                ctx,
                enc,
                (&eu, &self.light),
                inputs.casters,
                *range,
                open,
                (inputs.receivers, inputs.v),
                (&self.status, 3),
            )?;
        }
        inputs.mark(enc, "settle");
        Ok(())
    }

    /// The CPU twin in the same views.
    fn cpu_twin(&self, scene: &Scene, receivers: &Receivers, views: &Views) -> Result<Vec<f32>> {
        let views: Vec<LightView> = views.iter().flatten().copied().collect();
        cpu_twin_v(CpuDeepShadow::new()?, &self.params, receivers, |e, v| {
            e.estimate_in_views(scene, receivers, &views, v)
        })
    }
}
