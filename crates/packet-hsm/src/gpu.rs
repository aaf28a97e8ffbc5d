//! Packet-hsm on the engine path: [`PacketHsmFrame`], prepared once, then each frame
//! recorded into the caller's command encoder from the caller's casters and receiver buffer, V
//! written into the caller's buffer; nothing submitted, waited for or read back.
//!
//! One frame renders one view per sub-light and opacity level (Yang §5; docs/methods.md §3
//! "Semi-transparent occluders"), in the CPU twin's order (sub-light rows, sub-lights, levels),
//! each fitted by [`FrameEstimator::fit_views`] as [`SubView::fit`] fits it. Per view, its
//! uniforms written in the encoder's order ([`GpuContext::write_in`]):
//! 1. the core's raster, midpoint and MSSM passes ([`GpuLayersFrame::encode_slot`]): layer 0
//!    of the casters of at least the level's opacity (the caster buffer's w), its midpoints when
//!    the classification takes them, the anchored MSSM of layer 0 (only the levels the view's
//!    kernels read, [`SubView::levels`]: each level costs a pass over r^2 texels);
//! 2. the classification layer copied into the interior of an `(r + 2)^2` map whose one-texel
//!    ring holds +inf (written once at `prepare`), and the core's dual-grid MSSM pass over it:
//!    the padded dual-grid MSSM of [`crate::cpu::extract::PaddedDualMssm`], on the GPU (its
//!    levels likewise);
//! 3. `frame_maps` (`packet_hsm_frame.wgsl`): the depth and classification layers as the row-major buffers
//!    `packet_hsm.wgsl` reads; the MSSM levels the view needs ([`SubView::levels`]) copied level
//!    after level into one buffer each;
//! 4. `frame_setup`: each receiver's set-up on the GPU, the twin of
//!    [`crate::cpu::setup_receiver`] (light-space transform, the sub-light's facing fraction, a
//!    sphere light's silhouette disk, projection, bias or receiver plane);
//! 5. the kernel's `prepare` and `pixels` passes ([`kernel`]: the per-pixel GBP07 with
//!    Yang's hierarchy; receivers in a buffer carry no image layout, so no packets): `prepare`
//!    queues the penumbra receivers; each round of `pixels` (as many as the view's widest
//!    kernel can need, `SubLightShape::rounds` in [`kernel`]) runs over the last queue alone (its
//!    header copied into the indirect dispatch's arguments), walking at most
//!    [`kernel::WALK_BUDGET`] steps per receiver and queueing those with more for the next;
//! 6. `frame_finish`: the view's V (facing x the kernel's V, or what the set-up settled) times
//!    the view's weight (`1 / S^2` times the level's) added to each receiver's sum; after the
//!    last view, V = the sum clamped to [0, 1], as [`crate::cpu::SubLights::finish`] does.
//!
//! Steps 4 to 6 run once per range of receivers ([`ReceiverRange`]: the caller's receivers and
//! V and the frame's sums bound at the range, the scratch of steps 4 and 5 from its start, sized
//! at `prepare` for one range), so a frame takes any receiver count the caller's buffers hold.
//!
//! The views a frame may render are bounded at `prepare` (`sublights^2 x opacity_levels`
//! slots); casters needing more levels than `opacity_levels` are cast opaque in one level, with
//! [`Warning::OpacityLevelsCapped`], as on the CPU. Rect lights take any `sublights`; disk,
//! sphere and directional lights `sublights=1` ([`FrameEstimator::refuses`], as the CPU twin).
//!
//! The status buffer (three u32, cleared by each `encode`): `[0]` receivers projecting outside
//! a view (summed over views; V = facing there), `[1]` non-finite V written as 0, `[2]`
//! receivers cut short in some view, by the device's loop budget or by a walk longer than
//! [`kernel::MAX_ROUNDS`] rounds ([`crate::gpu::kernel::LOOP_LIMIT`]; none on the fixtures): V
//! left NaN for the caller to redo (the CLI and the registry's estimator redo NaN actives with
//! the CPU twin in the same views).
//!
//! For tests and tools, [`PacketHsmFrame::encode_view_maps`] records one view's maps alone and
//! [`PacketHsmFrame::light_space`] hands them out to read back; [`PacketHsmFrame::cpu_twin_in_maps`]
//! runs the CPU twin on maps read back, so the kernel can be compared with the CPU on the very
//! maps it read.
use crate::cpu::{
    emitter_of, levels_run, pixel_value, setup_receiver, CpuPacketHsm, OpacityLevels, OwnPlane,
    ReceiverSetup, SubView,
};
use crate::math::sublight_centre;
use crate::settings::Config;
use bytemuck::{Pod, Zeroable};
use kernel::{
    hsm_uniform, HsmUniform, Kernel, PrepGpu, RecIn, SubLightShape, QUEUE_ARGS_OFFSET,
    QUEUE_HEADER, WORKGROUP,
};
use shadow_map_core::{
    gpu::{
        depth_map::write_planes,
        estimate::{
            EstimateUniform, LIGHT_HEAD_WGSL, LIGHT_RECT, OVERRIDES, SILHOUETTE_SETUP_WGSL,
            SILHOUETTE_WGSL, WORKGROUP_SIZE,
        },
        frame::{
            check_prepared_inputs, compute_pass, compute_pass_indirect, range_capacity,
            receiver_ranges_binding, status_buffer, FrameEstimator, FrameInputs, ReceiverRange,
            Views,
        },
        kernel::{BindGroupCache, SpecializedKernel},
        mssm::{GpuDualMssm, GpuMinMaxPass, GpuMssmBuilder, MinMaxRequest},
        GpuContext, GpuDepthMap, GpuLayersFrame, GpuLightSpace, GpuShadowMapper, LayersSlot,
    },
    light_view::FitReport,
    Error, Light, LightShape, LightSpace, LightSpaceRequest, LightView, OpacityLevel, Params,
    RasterOptions, Receivers, Result, Scene, Warning,
};
use std::sync::Arc;

pub mod kernel;

/// The engine path's own WGSL.
pub const FRAME_WGSL: &str = include_str!("packet_hsm_frame.wgsl");

/// The engine path's set-up module, in order: the core's light head ([`LIGHT_HEAD_WGSL`]: shared
/// structs, estimate uniform, math) and a sphere light's silhouette set-up, the kernel's `RecIn`, then [`FRAME_WGSL`].
pub const FRAME_SHADER_PARTS: &[&str] = &[
    LIGHT_HEAD_WGSL,
    SILHOUETTE_WGSL,
    SILHOUETTE_SETUP_WGSL,
    kernel::REC_IN_WGSL,
    FRAME_WGSL,
];

// One workgroup size for the core's `WG` override this module takes and the kernel's.
const _: () = assert!(WORKGROUP_SIZE == WORKGROUP);

/// The frame's settings as `packet_hsm_frame.wgsl` reads them (`HsmFrameUniform`), 32 bytes.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, Default)]
pub struct HsmFrameUniform {
    /// Constant bias b0.
    pub bias: f32,
    /// Slope bias b1.
    pub slope_bias: f32,
    /// 1: midpoint classification.
    pub midpoint: u32,
    /// 1: receiver-plane rejection.
    pub receiver_plane: u32,
    /// Padding (the passes' receiver count is the bound range's, `arrayLength(&v_out)`).
    pub _pad0: u32,
    /// Map side r.
    pub r: u32,
    /// This view's weight in V: `1 / S^2` times its opacity level's.
    pub weight: f32,
    /// [`FIRST_VIEW`] and [`LAST_VIEW`] of the frame's views.
    pub flags: u32,
}

/// [`HsmFrameUniform::flags`]: the frame's first view (the sums start at 0).
pub const FIRST_VIEW: u32 = 1;
/// [`HsmFrameUniform::flags`]: the frame's last view (V written from the sums).
pub const LAST_VIEW: u32 = 2;

/// Packet-hsm recorded into the caller's frame (module docs).
pub struct PacketHsmFrame {
    kernel: Kernel,
    groups: BindGroupCache,
    cfg: Config,
    layers: GpuLayersFrame,
    padded: GpuDepthMap,
    dual_pass: GpuMinMaxPass,
    dual: GpuDualMssm,
    depth: wgpu::Buffer,
    class: wgpu::Buffer,
    mssm: wgpu::Buffer,
    dual_min: wgpu::Buffer,
    dual_max: wgpu::Buffer,
    /// Scratch of one range of receivers (sized at `prepare` for the most one holds:
    /// [`range_capacity`] of `RecIn`, the widest element bound per range): the set-up's `RecIn`
    /// and decision, the kernel's V and state.
    recs: wgpu::Buffer,
    setup: wgpu::Buffer,
    out: wgpu::Buffer,
    prep: wgpu::Buffer,
    /// The penumbra receivers `prepare` queues for `pixels` (kernel.rs [`QUEUE_HEADER`]), and
    /// the indirect dispatch's arguments copied from its header.
    queues: [wgpu::Buffer; 2],
    args: wgpu::Buffer,
    hsm: wgpu::Buffer,
    light: wgpu::Buffer,
    frame: wgpu::Buffer,
    status: wgpu::Buffer,
    /// Per receiver: V summed over the views so far, and 1 once a view was cut.
    acc: wgpu::Buffer,
    maps_pipe: wgpu::ComputePipeline,
    /// `frame_setup` and `frame_finish`, specialised for the light's shape at each encode.
    frame_kernel: SpecializedKernel,
    max_receivers: u32,
    /// Steps of a walk a round of `pixels` takes ([`kernel::WALK_BUDGET`]).
    walk_budget: u32,
}

/// A frame's bind groups: the per-texel pass's, and per range of receivers the frame passes'
/// and the kernel's.
struct RangeGroups {
    maps: wgpu::BindGroup,
    /// Per range: the frame passes' group, and the kernel's reading queue 0 and queue 1.
    ranges: Vec<(ReceiverRange, wgpu::BindGroup, [wgpu::BindGroup; 2])>,
}

fn buffer(ctx: &GpuContext, label: &str, bytes: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn floor_log2(n: u32) -> u32 {
    31 - n.max(1).leading_zeros()
}

impl PacketHsmFrame {
    /// Compiles the pipelines and allocates the layers, the MSSMs, the kernel's buffers for
    /// `max_receivers` receivers and the uniforms, for `params` (a table of packet-hsm's specs).
    /// Errors: the parameters' own, device limits ([`Error::Limit`]). `sublights` other than 1
    /// with a light that is not a rect is [`FrameEstimator::refuses`]'s (and `encode`'s) to
    /// report.
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params, max_receivers: u32) -> Result<Self> {
        let cfg = Config::from_params(params)?;
        let slots = cfg.sublights * cfg.sublights * cfg.opacity_levels.max(1);
        let r = cfg.resolution;
        let p = r + 2;
        let kernel = Kernel::new(ctx.clone())?;
        let req = LightSpaceRequest {
            resolution: r,
            layers: 1,
            midpoints: cfg.shadow.midpoint().then_some(0.0),
            mssm_levels: Some(floor_log2(r)),
            dual_mssm_levels: None,
            pyramid: false,
            raster: RasterOptions::default(),
            opacity: false,
        };
        let layers = GpuShadowMapper::new(&ctx)?.layers_frame_slots(&ctx, r, &req, slots)?;
        let padded = GpuDepthMap::new(&ctx, p, "packet-hsm padded classification")?;
        // The ring stays +inf: only the interior is copied each frame.
        let inf = vec![f32::INFINITY; (p * p) as usize];
        write_planes(&ctx, &padded.texture, p, 1, &inf);
        let (set, dual_pass) = GpuMssmBuilder::new(&ctx)?.prepare(
            &ctx,
            &padded,
            MinMaxRequest::dual_mssm(floor_log2(p)),
        )?;
        let dual = set
            .dual_mssm
            .ok_or_else(|| Error::param("resolution", "no dual-grid MSSM was built"))?;
        let mssm_bytes = 4 * (r as u64 * r as u64) * (floor_log2(r) as u64 + 1);
        let dual_bytes = 4 * (p as u64 * p as u64) * dual.levels.len() as u64;
        let n = max_receivers.max(1) as u64;
        // The scratch buffers hold one range of receivers.
        let range = range_capacity(
            &ctx,
            "packet-hsm frame receiver bytes of one range (max_storage_buffer_binding_size)",
            size_of::<RecIn>() as u64,
        )?
        .min(n);
        for (what, bytes) in [
            (
                "packet-hsm frame MSSM bytes (max_storage_buffer_binding_size)",
                mssm_bytes,
            ),
            (
                "packet-hsm frame dual-grid MSSM bytes (max_storage_buffer_binding_size)",
                dual_bytes,
            ),
            (
                "packet-hsm frame sum bytes (max_storage_buffer_binding_size)",
                8 * n,
            ),
        ] {
            ctx.check_storage_bytes(what, bytes)?;
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let texels = 4 * r as u64 * r as u64;
        let frame_kernel = SpecializedKernel::new(
            &ctx,
            "packet-hsm frame",
            FRAME_SHADER_PARTS,
            "frame_setup",
            OVERRIDES,
        )?;
        // `frame_maps` reads no light: its pipeline is made once, with the rect's shape code;
        // `frame_setup` and `frame_finish` are specialised per frame.
        let maps_pipe = frame_kernel.entry_pipeline(
            &ctx,
            "frame_maps",
            &[("LIGHT_SHAPE", LIGHT_RECT as f64)],
        )?;
        Ok(PacketHsmFrame {
            groups: BindGroupCache::default(),
            depth: buffer(&ctx, "packet-hsm frame depth", texels, storage),
            class: buffer(&ctx, "packet-hsm frame classification", texels, storage),
            mssm: buffer(&ctx, "packet-hsm frame MSSM", mssm_bytes, storage),
            dual_min: buffer(&ctx, "packet-hsm frame dual min", dual_bytes, storage),
            dual_max: buffer(&ctx, "packet-hsm frame dual max", dual_bytes, storage),
            recs: buffer(
                &ctx,
                "packet-hsm frame receivers",
                range * size_of::<RecIn>() as u64,
                storage,
            ),
            setup: buffer(&ctx, "packet-hsm frame set-up", 8 * range, storage),
            out: buffer(&ctx, "packet-hsm frame kernel V", 8 * range, storage),
            prep: buffer(
                &ctx,
                "packet-hsm frame prep",
                range * size_of::<PrepGpu>() as u64,
                storage,
            ),
            queues: [
                "packet-hsm frame penumbra queue",
                "packet-hsm frame walk queue",
            ]
            .map(|l| {
                buffer(
                    &ctx,
                    l,
                    4 * (QUEUE_HEADER + range),
                    storage | wgpu::BufferUsages::COPY_SRC,
                )
            }),
            args: buffer(
                &ctx,
                "packet-hsm frame pixels dispatch",
                12,
                wgpu::BufferUsages::INDIRECT,
            ),
            hsm: buffer(
                &ctx,
                "packet-hsm frame kernel uniform",
                std::mem::size_of::<HsmUniform>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            light: buffer(
                &ctx,
                "packet-hsm frame light",
                std::mem::size_of::<EstimateUniform>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            frame: buffer(
                &ctx,
                "packet-hsm frame uniform",
                std::mem::size_of::<HsmFrameUniform>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            status: status_buffer(&ctx, "packet-hsm frame status", 3),
            acc: buffer(&ctx, "packet-hsm frame sums", 8 * n, storage),
            kernel,
            cfg,
            layers,
            padded,
            dual_pass,
            dual,
            maps_pipe,
            frame_kernel,
            max_receivers,
            walk_budget: kernel::WALK_BUDGET,
        })
    }

    /// What the kernel's uniform takes from one view of the sub-light of half extents `half`
    /// ([`SubView::levels`], the padded dual-grid MSSM's levels as
    /// [`crate::cpu::extract::PaddedDualMssm::build`] chooses them).
    fn shape(&self, view: &LightView, light: &Light, half: glam::Vec2) -> SubLightShape {
        let (emitter, _) = emitter_of(light, half);
        let r = view.r;
        let p = r + 2;
        let (levels, max_cells) = SubView::levels(view, half);
        let need = 32 - (max_cells.max(1) - 1).leading_zeros();
        let dual_max = floor_log2(p).min(need);
        SubLightShape {
            view: *view,
            half,
            emitter,
            padded: p,
            mssm_levels: levels.min(floor_log2(r)) + 1,
            dual_levels: dual_max.min(floor_log2(p)) + 1,
            class_is_depth: !self.cfg.shadow.midpoint(),
            max_cells,
        }
    }

    /// The sub-lights' half extents (`1 / S` of the light's; [`SubLights::build`]).
    ///
    /// [`SubLights::build`]: crate::cpu::SubLights::build
    fn sub_half(&self, light: &Light) -> glam::Vec2 {
        light.half_extent() / self.cfg.sublights as f32
    }

    /// The levels a frame of `casters` renders, and `(needed, allowed)` when they were capped.
    fn levels(&self, casters: &[OpacityLevel]) -> (Vec<OpacityLevel>, Option<(usize, usize)>) {
        levels_run(casters, self.cfg.opacity_levels)
    }

    /// The frame passes' bind group over `range`: the caller's receivers and V, and the sums, at
    /// the range's offset; the scratch buffers from their start.
    fn group(&self, inputs: &FrameInputs<'_>, range: ReceiverRange) -> wgpu::BindGroup {
        let e = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        let class = match self.layers.midpoints().first() {
            Some(m) if self.cfg.shadow.midpoint() => &m.view,
            _ => &self.layers.layers()[0].view,
        };
        self.groups.get(
            &self.kernel.ctx,
            "packet-hsm frame",
            &self.frame_kernel.layout,
            &[
                e(0, self.layers.view_uniform().as_entire_binding()),
                e(1, self.light.as_entire_binding()),
                e(2, self.frame.as_entire_binding()),
                e(3, range.receivers(inputs.receivers)),
                e(4, self.scratch(&self.recs, range, size_of::<RecIn>())),
                e(5, self.scratch(&self.setup, range, 8)),
                e(6, self.scratch(&self.out, range, 8)),
                e(7, range.words(inputs.v)),
                e(8, self.status.as_entire_binding()),
                e(
                    9,
                    wgpu::BindingResource::TextureView(&self.layers.layers()[0].view),
                ),
                e(10, wgpu::BindingResource::TextureView(class)),
                e(11, self.depth.as_entire_binding()),
                e(12, self.class.as_entire_binding()),
                e(13, range.bind(&self.acc, 8)),
            ],
        )
    }

    /// The kernel's bind group over `range` (its scratch from the start), reading queue `from`
    /// and filling the other.
    fn kernel_group(&self, range: ReceiverRange, from: usize) -> wgpu::BindGroup {
        self.kernel.group([
            self.hsm.as_entire_binding(),
            self.depth.as_entire_binding(),
            self.class.as_entire_binding(),
            self.mssm.as_entire_binding(),
            self.dual_min.as_entire_binding(),
            self.dual_max.as_entire_binding(),
            self.scratch(&self.recs, range, size_of::<RecIn>()),
            self.scratch(&self.out, range, 8),
            self.scratch(&self.prep, range, size_of::<PrepGpu>()),
            self.queues[from].as_entire_binding(),
            self.queues[1 - from].as_entire_binding(),
        ])
    }

    /// `range.count` elements of `stride` bytes from the start of scratch buffer `b`.
    fn scratch<'a>(
        &self,
        b: &'a wgpu::Buffer,
        range: ReceiverRange,
        stride: usize,
    ) -> wgpu::BindingResource<'a> {
        ReceiverRange { first: 0, ..range }.bind(b, stride as u64)
    }
}

/// The workgroups of one pass over `threads` invocations, in one row (the kernel's entry points
/// index by `global_invocation_id.x` alone).
fn workgroups(threads: u64) -> [u32; 3] {
    [threads.div_ceil(WORKGROUP as u64).max(1) as u32, 1, 1]
}

impl PacketHsmFrame {
    /// Records the maps of view `slot` (steps 1 and 2 of the module docs): the layers, their
    /// midpoints and MSSM, and the padded dual-grid MSSM of the classification layer; with
    /// `shape`, only the MSSM levels its kernels read (else every level prepared).
    fn encode_maps(
        &self,
        enc: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        (slot, view): (usize, &LightView),
        level: &OpacityLevel,
        shape: Option<&SubLightShape>,
    ) -> Result<()> {
        let ctx = &self.kernel.ctx;
        let cfg = &self.cfg;
        let layers = LayersSlot {
            view,
            max_bias: cfg.shadow.midpoint_clamp(view).unwrap_or(0.0),
            min_opacity: level.min_opacity,
            slot,
            mssm_levels: shape.map(|s| s.mssm_levels),
            mssm_max: true,
            timestamps: inputs.timestamps,
        };
        self.layers.encode_slot(ctx, enc, inputs.casters, &layers)?;
        // The classification layer into the padded map's interior, then its dual-grid MSSM.
        let class = match self.layers.midpoints().first() {
            Some(m) if cfg.shadow.midpoint() => m,
            _ => &self.layers.layers()[0],
        };
        let r = view.r;
        enc.copy_texture_to_texture(
            class.texture.as_image_copy(),
            wgpu::TexelCopyTextureInfo {
                texture: &self.padded.texture,
                mip_level: 0,
                origin: wgpu::Origin3d { x: 1, y: 1, z: 0 },
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::Extent3d {
                width: r,
                height: r,
                depth_or_array_layers: 1,
            },
        );
        self.dual_pass
            .record_levels(enc, shape.map_or(u32::MAX, |s| s.dual_levels), true);
        Ok(())
    }

    /// Records view `slot` of `views`: its maps, set-up, kernel and its share of V.
    fn encode_view(
        &self,
        enc: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        groups: &RangeGroups,
        (slot, views, view): (usize, usize, &LightView),
        level: &OpacityLevel,
    ) -> Result<()> {
        let ctx = &self.kernel.ctx;
        let cfg = &self.cfg;
        let half = self.sub_half(inputs.light);
        let shape = self.shape(view, inputs.light, half);
        let r = view.r;
        self.encode_maps(enc, inputs, (slot, view), level, Some(&shape))?;
        // The levels the view needs, each after the last, as packet_hsm.wgsl reads them.
        let mssm = self
            .layers
            .min_max()
            .mssm
            .as_ref()
            .ok_or_else(|| Error::param("resolution", "no MSSM was built"))?;
        let plane = 4 * r as u64 * r as u64;
        for (l, level) in mssm
            .levels
            .iter()
            .take(shape.mssm_levels as usize)
            .enumerate()
        {
            enc.copy_buffer_to_buffer(&level.min, 0, &self.mssm, l as u64 * plane, plane);
        }
        let pplane = 4 * shape.padded as u64 * shape.padded as u64;
        for (l, level) in self
            .dual
            .levels
            .iter()
            .take(shape.dual_levels as usize)
            .enumerate()
        {
            let at = l as u64 * pplane;
            enc.copy_buffer_to_buffer(&level.min, 0, &self.dual_min, at, pplane);
            enc.copy_buffer_to_buffer(&level.max, 0, &self.dual_max, at, pplane);
        }
        let hu = HsmUniform {
            walk_budget: self.walk_budget,
            ..hsm_uniform(&shape, cfg)
        };
        let rounds = shape.rounds(cfg.hierarchy, hu.walk_budget);
        let (prepare_pipe, pixels_pipe) = self.kernel.pipelines(&hu)?;
        ctx.write_in(enc, &self.hsm, 0, bytemuck::bytes_of(&hu));
        let mut eu = EstimateUniform::new(inputs.light, cfg.shadow.bias, cfg.shadow.slope_bias);
        if let LightShape::Rect { .. } = inputs.light.shape {
            // The sub-light's rectangle, for its facing fraction (SubView::shape).
            eu.light_size_x = 2.0 * half.x;
            eu.light_size_y = 2.0 * half.y;
        }
        ctx.write_in(enc, &self.light, 0, bytemuck::bytes_of(&eu));
        let shape = [eu.shape_switch()];
        let setup_pipe = self
            .frame_kernel
            .entry_pipeline(ctx, "frame_setup", &shape)?;
        let finish_pipe = self
            .frame_kernel
            .entry_pipeline(ctx, "frame_finish", &shape)?;
        let s2 = (cfg.sublights * cfg.sublights) as f32;
        let fu = HsmFrameUniform {
            bias: cfg.shadow.bias,
            slope_bias: cfg.shadow.slope_bias,
            midpoint: u32::from(cfg.shadow.midpoint()),
            receiver_plane: u32::from(cfg.shadow.receiver_plane),
            r,
            weight: (1.0 / s2) * level.weight,
            flags: if slot == 0 { FIRST_VIEW } else { 0 }
                | if slot + 1 == views { LAST_VIEW } else { 0 },
            ..Default::default()
        };
        ctx.write_in(enc, &self.frame, 0, bytemuck::bytes_of(&fu));
        let texels = r as u64 * r as u64;
        let maps = (&self.maps_pipe, &groups.maps);
        compute_pass(
            enc,
            "packet-hsm frame maps",
            maps.0,
            maps.1,
            workgroups(texels),
        );
        // Two marks a view (a frame may render many): the maps, then the rest.
        inputs.mark(enc, "maps");
        for (range, group, kernel) in &groups.ranges {
            let n = range.count as u64;
            // No stale kernel state from the last view or range for receivers the set-up settles.
            enc.clear_buffer(&self.prep, 0, Some(n * size_of::<PrepGpu>() as u64));
            // `prepare` fills queue 0 (the requeue of the group reading queue 1), then rounds of
            // `pixels`, each over the queue the last one left.
            enc.clear_buffer(&self.queues[0], 0, Some(4 * QUEUE_HEADER));
            let wg = workgroups(n);
            compute_pass(enc, "packet-hsm frame set-up", &setup_pipe, group, wg);
            compute_pass(enc, "packet-hsm prepare", &prepare_pipe, &kernel[1], wg);
            for round in 0..rounds {
                let from = round as usize % 2;
                enc.clear_buffer(&self.queues[1 - from], 0, Some(4 * QUEUE_HEADER));
                enc.copy_buffer_to_buffer(&self.queues[from], QUEUE_ARGS_OFFSET, &self.args, 0, 12);
                let (pixels, group) = (&pixels_pipe, &kernel[from]);
                compute_pass_indirect(enc, "packet-hsm pixels", pixels, group, &self.args);
            }
            compute_pass(enc, "packet-hsm frame finish", &finish_pipe, group, wg);
        }
        inputs.mark(enc, "estimate");
        Ok(())
    }
}

impl PacketHsmFrame {
    /// Sets the steps of a receiver's walk one round of `pixels` takes (default
    /// [`kernel::WALK_BUDGET`]; at least 1): V is the same at any budget, only the rounds
    /// differ (up to [`kernel::MAX_ROUNDS`] a view). For tests and tools.
    pub fn set_walk_budget(&mut self, steps: u32) {
        self.walk_budget = steps.max(1);
    }

    /// [`FrameEstimator::encode`]'s checks of `inputs`: the receiver count (returned), the light,
    /// one present view per sub-light and opacity level; and the levels the frame renders.
    fn checked(&self, inputs: &FrameInputs<'_>) -> Result<(u64, Vec<OpacityLevel>)> {
        let n = check_prepared_inputs(
            &self.kernel.ctx,
            inputs,
            self.max_receivers,
            "receivers per frame (packet-hsm frame prepared for fewer)",
        )?;
        CpuPacketHsm::check_light(inputs.light, &self.cfg)?;
        let (levels, _) = self.levels(inputs.casters.opacity_levels());
        let s = self.cfg.sublights as usize;
        let views = inputs.views;
        if views.len() != s * s * levels.len() {
            return Err(Error::LightView(format!(
                "{} views for {} sub-lights x {} opacity levels",
                views.len(),
                s * s,
                levels.len()
            )));
        }
        if views.iter().any(Option::is_none) {
            return Err(Error::LightView(
                "packet-hsm's frame needs every sub-light's view".into(),
            ));
        }
        Ok((n, levels))
    }

    /// Records only the maps [`FrameEstimator::encode`] renders for view `slot` of
    /// `inputs.views` (its layers, midpoints and MSSM, and the padded dual-grid MSSM), for
    /// [`light_space`](Self::light_space) to hand out once submitted: a frame renders its views
    /// in turn into the same maps, so only the last one's survive a whole frame. Errors as
    /// `encode`'s, and [`Error::LightView`] for a slot beyond the views.
    pub fn encode_view_maps(
        &self,
        enc: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        slot: usize,
    ) -> Result<()> {
        let (_, levels) = self.checked(inputs)?;
        let view =
            inputs.views.get(slot).copied().flatten().ok_or_else(|| {
                Error::LightView(format!("no view {slot} of {}", inputs.views.len()))
            })?;
        self.encode_maps(
            enc,
            inputs,
            (slot, &view),
            &levels[slot % levels.len()],
            None,
        )
    }

    /// The maps the last submitted [`encode`](FrameEstimator::encode) rendered for its last view
    /// (or [`encode_view_maps`](Self::encode_view_maps) for its view), in `view`: what a test
    /// reads back ([`GpuLightSpace::to_cpu`]) to run the CPU twin on the very maps the kernel
    /// read ([`cpu_twin_in_maps`](Self::cpu_twin_in_maps)).
    pub fn light_space(&self, view: &LightView) -> GpuLightSpace {
        self.layers.light_space(view)
    }

    /// [`FrameEstimator::cpu_twin`] on given maps, one per view in the frame's order (each its
    /// view and layer 0, with midpoints for `self_shadow=midpoint`; say the frame's own, read
    /// back): the MSSM and padded dual-grid MSSM built from them, then each receiver's set-up
    /// and per-pixel GBP07, weighted and summed as [`crate::cpu::SubLights`] sums them.
    pub fn cpu_twin_in_maps(
        &self,
        scene: &Scene,
        receivers: &Receivers,
        maps: Vec<LightSpace>,
    ) -> Result<Vec<f32>> {
        let half = self.sub_half(scene.light());
        let cfg = &self.cfg;
        let mut maps: Vec<Option<LightSpace>> = maps.into_iter().map(Some).collect();
        self.cpu_sum(scene, receivers, maps.len(), |slot, _| {
            let ls = maps[slot]
                .take()
                .ok_or_else(|| Error::LightView(format!("the maps of view {slot} were taken")))?;
            Ok(SubView::in_maps(ls, scene.light(), half, cfg))
        })
    }

    /// The CPU twin's V over `views` views, each on the [`SubView`] that `sub_view` gives for
    /// (its slot, its opacity level's scene): each receiver's [`setup_receiver`], then
    /// [`pixel_value`], weighted and summed as [`crate::cpu::SubLights`] sums them.
    fn cpu_sum(
        &self,
        scene: &Scene,
        receivers: &Receivers,
        views: usize,
        mut sub_view: impl FnMut(usize, &Scene) -> Result<SubView>,
    ) -> Result<Vec<f32>> {
        CpuPacketHsm::check_light(scene.light(), &self.cfg)?;
        let cfg = &self.cfg;
        let levels = OpacityLevels::new(scene, cfg.opacity_levels);
        let levels: Vec<(&Scene, f32)> = levels.iter().collect();
        let s2 = (cfg.sublights * cfg.sublights) as usize;
        if views != s2 * levels.len() {
            return Err(Error::LightView(format!(
                "{views} views for {s2} sub-lights x {} opacity levels",
                levels.len()
            )));
        }
        let mut acc = vec![0.0f32; receivers.len()];
        for slot in 0..views {
            let (level, lw) = levels[slot % levels.len()];
            let sv = sub_view(slot, level)?;
            let w = (1.0 / s2 as f32) * lw;
            for (k, a) in acc.iter_mut().enumerate() {
                if !receivers.active()[k] {
                    continue;
                }
                let (pw, nw) = (receivers.position()[k], receivers.normal()[k]);
                let x = match setup_receiver(&sv, cfg, pw, nw) {
                    ReceiverSetup::Settled(x) | ReceiverSetup::Outside(x) => x,
                    ReceiverSetup::Map { .. } => pixel_value(&sv, cfg, pw, nw),
                };
                *a += w * x;
            }
        }
        Ok(acc
            .iter()
            .enumerate()
            .map(|(k, &x)| {
                if !receivers.active()[k] {
                    f32::NAN
                } else if x.is_finite() {
                    x.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .collect())
    }
}

impl FrameEstimator for PacketHsmFrame {
    fn name(&self) -> &'static str {
        "packet-hsm"
    }

    /// One view per sub-light and opacity level, in the CPU twin's order, each fitted by
    /// [`SubView::fit`] on the level's casters.
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.kernel.ctx.check_lost()?;
        CpuPacketHsm::check_light(scene.light(), &self.cfg)?;
        let s = self.cfg.sublights;
        let half = self.sub_half(scene.light());
        let levels = OpacityLevels::new(scene, self.cfg.opacity_levels);
        let mut views = Vec::with_capacity((s * s) as usize);
        for b in 0..s {
            for a in 0..s {
                let c = sublight_centre(scene.light().half_extent(), s, a, b);
                for (level, _) in levels.iter() {
                    let (view, _) =
                        SubView::fit(level, receivers, (self.cfg.resolution, c, half), &self.cfg)?;
                    views.push(Some(view));
                }
            }
        }
        Ok(views)
    }

    /// Three u32 (module docs).
    /// The layers and their MSSM, the padded classification map and its dual-grid MSSM.
    fn light_space_bytes(&self) -> usize {
        self.layers.bytes() + self.padded.bytes() + self.dual.bytes()
    }

    fn status(&self) -> Option<&wgpu::Buffer> {
        Some(&self.status)
    }

    /// `sublights` other than 1 with a light that is not a rect (as the CPU twin).
    fn refuses(&self, scene: &Scene) -> Option<String> {
        CpuPacketHsm::check_light(scene.light(), &self.cfg)
            .err()
            .map(|e| e.to_string())
    }

    /// One pass per opacity level (module docs).
    fn models_opacity(&self) -> bool {
        true
    }

    /// [`Warning::OpacityLevelsCapped`] when the scene needs more levels than `opacity_levels`.
    fn scene_warnings(&self, scene: &Scene) -> Vec<Warning> {
        let all = if scene.is_opaque() {
            Vec::new()
        } else {
            scene.opacity_levels()
        };
        self.levels(&all)
            .1
            .map(|(needed, allowed)| Warning::OpacityLevelsCapped { needed, allowed })
            .into_iter()
            .collect()
    }

    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let (n, levels) = self.checked(inputs)?;
        self.groups.next_encode();
        self.kernel.groups.next_encode();
        let views = inputs.views;
        inputs.mark(enc, "start");
        enc.clear_buffer(&self.status, 0, None);
        let ranges = receiver_ranges_binding(&self.kernel.ctx, n as u32, size_of::<RecIn>() as u64);
        let groups = RangeGroups {
            // The per-texel pass reads no receivers: any range's group (one receiver for none).
            maps: self.group(
                inputs,
                ranges
                    .first()
                    .copied()
                    .unwrap_or(ReceiverRange { first: 0, count: 1 }),
            ),
            ranges: ranges
                .iter()
                .map(|&r| {
                    let kernel = [self.kernel_group(r, 0), self.kernel_group(r, 1)];
                    (r, self.group(inputs, r), kernel)
                })
                .collect(),
        };
        for (slot, view) in views.iter().flatten().enumerate() {
            let level = &levels[slot % levels.len()];
            let at = (slot, views.len(), view);
            self.encode_view(enc, inputs, &groups, at, level)?;
        }
        Ok(())
    }

    /// The CPU twin's per-pixel path in the same views, on each view's opacity level: each
    /// receiver's [`setup_receiver`], then [`pixel_value`] (the per-pixel GBP07 with the
    /// configured traversal, what the kernel computes without packets), weighted and summed as
    /// [`crate::cpu::SubLights`] sums them.
    fn cpu_twin(&self, scene: &Scene, receivers: &Receivers, views: &Views) -> Result<Vec<f32>> {
        let half = self.sub_half(scene.light());
        let cfg = &self.cfg;
        self.cpu_sum(scene, receivers, views.len(), |slot, level| {
            let view = views[slot].ok_or_else(|| {
                Error::LightView("packet-hsm's frame needs every sub-light's view".into())
            })?;
            let fit = FitReport::default();
            SubView::build_in_view(level, receivers, view, fit, half, cfg, OwnPlane::Off)
        })
    }
}

#[cfg(test)]
mod tests;
