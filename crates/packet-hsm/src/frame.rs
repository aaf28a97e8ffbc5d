//! Packet-hsm on the engine path: [`PacketHsmFrame`], prepared once, then each frame
//! recorded into the caller's command encoder from the caller's casters and receiver buffer, V
//! written into the caller's buffer; nothing submitted, waited for or read back.
//!
//! One frame, in one light view (`sublights=1`; the frame's view fitted by
//! [`FrameEstimator::fit_views`] as [`SubView::fit`] fits it):
//! 1. the core's raster, midpoint and MSSM passes ([`GpuLayersFrame`]): layer 0, its midpoints
//!    when the classification takes them, the anchored MSSM of layer 0 (every level the map
//!    allows, allocated once);
//! 2. the classification layer copied into the interior of an `(r + 2)^2` map whose one-texel
//!    ring holds +inf (written once at `prepare`), and the core's dual-grid MSSM pass over it:
//!    the padded dual-grid MSSM of [`crate::contour::PaddedDualMssm`], on the GPU;
//! 3. `frame_maps` (`frame.wgsl`): the depth and classification layers as the row-major buffers
//!    `packet_hsm.wgsl` reads; the MSSM levels the view needs ([`SubView::levels`]) copied level
//!    after level into one buffer each (the layout [`GpuPacketHsm`]'s upload has);
//! 4. `frame_setup`: each receiver's set-up on the GPU, the twin of
//!    [`crate::cpu::setup_receiver`] (light-space transform, facing fraction, a sphere light's
//!    silhouette disk, projection, bias or receiver plane);
//! 5. `packet_hsm.wgsl`'s `prepare` and `pixels` passes, unchanged (the per-pixel GBP07 with
//!    Yang's hierarchy: receivers in a buffer carry no image layout, so no packets);
//! 6. `frame_finish`: V = facing x the kernel's V, or what the set-up settled.
//!
//! **What this path does not take.** Casters are opaque (a
//! [`GpuScene`](shadow_map_core::gpu::GpuScene) holds positions only; the opacity levels need
//! one pass per level). One view: rect lights with `sublights=1` (S x S sub-lights would need one
//! layer set per sub-light). Every light shape: a sphere light's silhouette disk is set up per
//! receiver by the core's `silhouette_setup.wgsl` (the twin of
//! [`Silhouette::new`](shadow_map_core::silhouette::Silhouette::new)).
//!
//! The status buffer (three u32, cleared by each `encode`): `[0]` receivers projecting outside
//! the map (V = facing), `[1]` non-finite V written as 0, `[2]` receivers the device's loop
//! budget cut short ([`crate::gpu::LOOP_LIMIT`]): V left NaN for the caller to redo (the CLI
//! redoes NaN actives with the CPU twin in the same view).
use crate::cpu::{
    emitter_of, pixel_value, setup_receiver, Config, OwnPlane, ReceiverSetup, SubView,
};
use crate::gpu::{
    hsm_uniform_of, GpuPacketHsm, HsmUniform, PacketPlan, PrepGpu, RecIn, SubLightShape, WORKGROUP,
};
use bytemuck::{Pod, Zeroable};
use shadow_map_core::{
    gpu::{
        estimate::{
            EstimateUniform, ESTIMATE_WGSL, MATH_WGSL, OVERRIDES, SILHOUETTE_SETUP_WGSL,
            SILHOUETTE_WGSL, WORKGROUP_SIZE,
        },
        frame::{
            buffer_range, check_prepared_inputs, compute_pass, single_view, status_buffer,
            FrameEstimator, FrameInputs,
        },
        kernel::{compute_pipeline, shader_module, Binding},
        mssm::{GpuDualMssm, GpuMinMaxPass, GpuMssmBuilder, MinMaxRequest},
        receivers::RECEIVER_BYTES,
        shared::SHARED_WGSL,
        GpuContext, GpuDepthMap, GpuLayersFrame, GpuShadowMapper,
    },
    light_view::FitReport,
    Error, LightSpaceRequest, LightView, Params, RasterOptions, Receivers, Result, Scene,
};
use std::sync::Arc;

/// The engine path's own WGSL.
pub const FRAME_WGSL: &str = include_str!("frame.wgsl");

/// The engine path's set-up module, in order: the core's shared structs, estimate uniform, math
/// and a sphere light's silhouette set-up, the kernel's `RecIn`, then [`FRAME_WGSL`].
pub const FRAME_SHADER_PARTS: &[&str] = &[
    SHARED_WGSL,
    ESTIMATE_WGSL,
    MATH_WGSL,
    SILHOUETTE_WGSL,
    SILHOUETTE_SETUP_WGSL,
    crate::gpu::REC_IN_WGSL,
    FRAME_WGSL,
];

// One workgroup size for the core's `WG` override this module takes and the kernel's.
const _: () = assert!(WORKGROUP_SIZE == WORKGROUP);

/// The frame's settings as `frame.wgsl` reads them (`HsmFrameUniform`), 32 bytes.
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
    /// Receivers this frame.
    pub count: u32,
    /// Map side r.
    pub r: u32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// `frame.wgsl`'s bindings.
const BINDINGS: [(u32, Binding); 13] = [
    (0, Binding::Uniform),
    (1, Binding::Uniform),
    (2, Binding::Uniform),
    (3, Binding::Storage),
    (4, Binding::StorageRw),
    (5, Binding::StorageRw),
    (6, Binding::Storage),
    (7, Binding::StorageRw),
    (8, Binding::StorageRw),
    (9, Binding::Texture2d),
    (10, Binding::Texture2d),
    (11, Binding::StorageRw),
    (12, Binding::StorageRw),
];

/// Packet-hsm recorded into the caller's frame (module docs).
pub struct PacketHsmFrame {
    gpu: GpuPacketHsm,
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
    recs: wgpu::Buffer,
    setup: wgpu::Buffer,
    out: wgpu::Buffer,
    prep: wgpu::Buffer,
    counters: wgpu::Buffer,
    hsm: wgpu::Buffer,
    light: wgpu::Buffer,
    frame: wgpu::Buffer,
    status: wgpu::Buffer,
    layout: wgpu::BindGroupLayout,
    maps_pipe: wgpu::ComputePipeline,
    setup_pipe: wgpu::ComputePipeline,
    finish_pipe: wgpu::ComputePipeline,
    max_receivers: u32,
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
    /// and sphere lights are [`FrameEstimator::refuses`]'s (and `encode`'s) to report.
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params, max_receivers: u32) -> Result<Self> {
        let cfg = Config::from_params(params)?;
        let r = cfg.resolution;
        let p = r + 2;
        let mut gpu = GpuPacketHsm::new(ctx.clone())?;
        shadow_map_core::estimator::configure(&mut gpu, params)?;
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
        let layers = GpuShadowMapper::new(&ctx)?.layers_frame(&ctx, r, &req)?;
        let padded = GpuDepthMap::new(&ctx, p, "packet-hsm padded classification")?;
        // The ring stays +inf: only the interior is copied each frame.
        let inf = vec![f32::INFINITY; (p * p) as usize];
        ctx.queue.write_texture(
            padded.texture.as_image_copy(),
            bytemuck::cast_slice(&inf),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * p),
                rows_per_image: Some(p),
            },
            wgpu::Extent3d {
                width: p,
                height: p,
                depth_or_array_layers: 1,
            },
        );
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
                "packet-hsm frame receiver bytes (max_storage_buffer_binding_size)",
                n * std::mem::size_of::<RecIn>() as u64,
            ),
            (
                "packet-hsm frame prep bytes (max_storage_buffer_binding_size)",
                n * std::mem::size_of::<PrepGpu>() as u64,
            ),
            (
                "packet-hsm frame kernel V bytes (max_storage_buffer_binding_size)",
                8 * n,
            ),
        ] {
            ctx.check_storage_bytes(what, bytes)?;
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let texels = 4 * r as u64 * r as u64;
        let module = shader_module(&ctx, "packet-hsm frame", FRAME_SHADER_PARTS)?;
        let layout = ctx.scoped("packet-hsm frame layout", || {
            let entries: Vec<_> = BINDINGS.iter().map(|(k, b)| b.entry(*k)).collect();
            ctx.device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("packet-hsm frame"),
                    entries: &entries,
                })
        })?;
        let mk = |entry: &str| compute_pipeline(&ctx, entry, &module, &layout, entry, OVERRIDES);
        let (maps_pipe, setup_pipe, finish_pipe) =
            (mk("frame_maps")?, mk("frame_setup")?, mk("frame_finish")?);
        Ok(PacketHsmFrame {
            depth: buffer(&ctx, "packet-hsm frame depth", texels, storage),
            class: buffer(&ctx, "packet-hsm frame classification", texels, storage),
            mssm: buffer(&ctx, "packet-hsm frame MSSM", mssm_bytes, storage),
            dual_min: buffer(&ctx, "packet-hsm frame dual min", dual_bytes, storage),
            dual_max: buffer(&ctx, "packet-hsm frame dual max", dual_bytes, storage),
            recs: buffer(
                &ctx,
                "packet-hsm frame receivers",
                n * std::mem::size_of::<RecIn>() as u64,
                storage,
            ),
            setup: buffer(&ctx, "packet-hsm frame set-up", 8 * n, storage),
            out: buffer(&ctx, "packet-hsm frame kernel V", 8 * n, storage),
            prep: buffer(
                &ctx,
                "packet-hsm frame prep",
                n * std::mem::size_of::<PrepGpu>() as u64,
                storage,
            ),
            counters: buffer(&ctx, "packet-hsm frame counters", 20, storage),
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
            gpu,
            cfg,
            layers,
            padded,
            dual_pass,
            dual,
            layout,
            maps_pipe,
            setup_pipe,
            finish_pipe,
            max_receivers,
        })
    }

    /// What the kernel's uniform takes from the frame's view ([`SubView::levels`], the padded
    /// dual-grid MSSM's levels as [`crate::contour::PaddedDualMssm::build`] chooses them).
    fn shape(&self, view: &LightView, light: &shadow_map_core::Light) -> Result<SubLightShape> {
        if let Some((key, why)) = self.refusal() {
            return Err(Error::param(key, why));
        }
        let half = light.half_extent();
        let (emitter, _) = emitter_of(light, half);
        let r = view.r;
        let p = r + 2;
        let (levels, max_cells) = SubView::levels(view, half);
        let need = 32 - (max_cells.max(1) - 1).leading_zeros();
        let dual_max = floor_log2(p).min(need);
        Ok(SubLightShape {
            view: *view,
            half,
            emitter,
            padded: p,
            mssm_levels: levels.min(floor_log2(r)) + 1,
            dual_levels: dual_max.min(floor_log2(p)) + 1,
            class_is_depth: !self.cfg.shadow.midpoint(),
        })
    }

    /// What this path does not model (module docs): `(parameter, reason)`.
    fn refusal(&self) -> Option<(&'static str, &'static str)> {
        (self.cfg.sublights != 1).then_some((
            "sublights",
            "packet-hsm's engine path renders one light view per frame: sublights=1",
        ))
    }

    fn group(&self, inputs: &FrameInputs<'_>, n: u64) -> wgpu::BindGroup {
        let e = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        let class = match self.layers.midpoints().first() {
            Some(m) if self.cfg.shadow.midpoint() => &m.view,
            _ => &self.layers.layers()[0].view,
        };
        self.gpu
            .ctx
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("packet-hsm frame"),
                layout: &self.layout,
                entries: &[
                    e(0, self.layers.view_uniform().as_entire_binding()),
                    e(1, self.light.as_entire_binding()),
                    e(2, self.frame.as_entire_binding()),
                    e(3, buffer_range(inputs.receivers, n * RECEIVER_BYTES)),
                    e(4, self.recs.as_entire_binding()),
                    e(5, self.setup.as_entire_binding()),
                    e(6, self.out.as_entire_binding()),
                    e(7, buffer_range(inputs.v, n * 4)),
                    e(8, self.status.as_entire_binding()),
                    e(
                        9,
                        wgpu::BindingResource::TextureView(&self.layers.layers()[0].view),
                    ),
                    e(10, wgpu::BindingResource::TextureView(class)),
                    e(11, self.depth.as_entire_binding()),
                    e(12, self.class.as_entire_binding()),
                ],
            })
    }

    fn kernel_group(&self) -> wgpu::BindGroup {
        let bufs = [
            &self.hsm,
            &self.depth,
            &self.class,
            &self.mssm,
            &self.dual_min,
            &self.dual_max,
            &self.recs,
            &self.out,
            &self.prep,
            &self.counters,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = bufs
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.gpu
            .ctx
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("packet-hsm frame kernel"),
                layout: &self.gpu.layout,
                entries: &entries,
            })
    }
}

/// One compute pass over `threads` invocations in one row of workgroups (the kernel's entry
/// points index by `global_invocation_id.x` alone).
fn run(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    pipe: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    threads: u64,
) {
    let x = threads.div_ceil(WORKGROUP as u64).max(1) as u32;
    compute_pass(enc, label, pipe, group, [x, 1, 1]);
}

impl FrameEstimator for PacketHsmFrame {
    fn name(&self) -> &'static str {
        "packet-hsm"
    }

    /// The view [`SubView::fit`] fits for the whole light (`sublights=1`).
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.gpu.ctx.check_lost()?;
        let half = scene.light().half_extent();
        let (view, _) = SubView::fit(
            scene,
            receivers,
            (self.cfg.resolution, glam::Vec2::ZERO, half),
            &self.cfg,
        )?;
        Ok(vec![Some(view)])
    }

    /// Three u32 (module docs).
    fn status(&self) -> Option<&wgpu::Buffer> {
        Some(&self.status)
    }

    /// `sublights` other than 1, or semi-transparent meshes (the frame's casters are opaque,
    /// the twin models opacity).
    fn refuses(&self, scene: &Scene) -> Option<String> {
        self.refusal()
            .map(|(key, why)| format!("{key}: {why}"))
            .or_else(|| shadow_map_core::gpu::frame::refuse_semi_transparent(scene))
    }

    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let view = single_view(inputs.views)?;
        let n = check_prepared_inputs(
            &self.gpu.ctx,
            inputs,
            self.max_receivers,
            "receivers per frame (packet-hsm frame prepared for fewer)",
        )?;
        let shape = self.shape(view, inputs.light)?;
        let ctx = &*self.gpu.ctx;
        let queue = &ctx.queue;
        let cfg = &self.cfg;
        let clamp = cfg.shadow.midpoint_clamp(view).unwrap_or(0.0);
        inputs.mark(enc, "start");
        self.layers
            .encode(queue, enc, inputs.casters, view, clamp)?;
        inputs.mark(enc, "layers");
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
        self.dual_pass.record(enc);
        // The levels the view needs, each after the last, as GpuPacketHsm uploads them.
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
        let plan = PacketPlan::new(cfg, None, usize::MAX)?;
        let hu = hsm_uniform_of(&shape, cfg, r, &plan, inputs.count as usize, 0);
        queue.write_buffer(&self.hsm, 0, bytemuck::bytes_of(&hu));
        let eu = EstimateUniform::new(inputs.light, cfg.shadow.bias, cfg.shadow.slope_bias);
        queue.write_buffer(&self.light, 0, bytemuck::bytes_of(&eu));
        let fu = HsmFrameUniform {
            bias: cfg.shadow.bias,
            slope_bias: cfg.shadow.slope_bias,
            midpoint: u32::from(cfg.shadow.midpoint()),
            receiver_plane: u32::from(cfg.shadow.receiver_plane),
            count: inputs.count,
            r,
            ..Default::default()
        };
        queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&fu));
        enc.clear_buffer(&self.status, 0, None);
        enc.clear_buffer(&self.counters, 0, None);
        // No stale kernel state from the last frame for receivers the set-up settles.
        enc.clear_buffer(&self.prep, 0, None);
        let group = self.group(inputs, n.max(1));
        run(
            enc,
            "packet-hsm frame maps",
            &self.maps_pipe,
            &group,
            r as u64 * r as u64,
        );
        if n == 0 {
            return Ok(());
        }
        inputs.mark(enc, "mssm");
        run(enc, "packet-hsm frame set-up", &self.setup_pipe, &group, n);
        let kernel = self.kernel_group();
        run(enc, "packet-hsm prepare", &self.gpu.prepare, &kernel, n);
        inputs.mark(enc, "set-up");
        run(enc, "packet-hsm pixels", &self.gpu.pixels, &kernel, n);
        inputs.mark(enc, "estimate");
        run(enc, "packet-hsm frame finish", &self.finish_pipe, &group, n);
        inputs.mark(enc, "finish");
        Ok(())
    }

    /// The CPU twin's per-pixel path in the same view, on the scene with every mesh opaque: each
    /// receiver's [`setup_receiver`], then [`pixel_value`] (the per-pixel GBP07 with the
    /// configured traversal, what the GPU twin's kernel computes without packets).
    fn cpu_twin(
        &self,
        scene: &Scene,
        receivers: &Receivers,
        views: &[Option<LightView>],
    ) -> Result<Vec<f32>> {
        let view = *single_view(views)?;
        if let Some((key, why)) = self.refusal() {
            return Err(Error::param(key, why));
        }
        let opaque = scene.opaque();
        let cfg = &self.cfg;
        let half = opaque.light().half_extent();
        let sv = SubView::build_in_view(
            &opaque,
            receivers,
            view,
            FitReport::default(),
            half,
            cfg,
            OwnPlane::Off,
        )?;
        Ok((0..receivers.len())
            .map(|k| {
                if !receivers.active()[k] {
                    return f32::NAN;
                }
                let (pw, nw) = (receivers.position()[k], receivers.normal()[k]);
                let x = match setup_receiver(&sv, cfg, pw, nw) {
                    ReceiverSetup::Settled(x) | ReceiverSetup::Outside(x) => x,
                    ReceiverSetup::Map { .. } => pixel_value(&sv, cfg, pw, nw),
                };
                if x.is_finite() {
                    x.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_structs_match_the_wgsl_layout() {
        let src = shadow_map_core::gpu::kernel::shader_source(FRAME_SHADER_PARTS);
        test_support::assert_wgsl_layout!(
            src,
            HsmFrameUniform {
                bias,
                slope_bias,
                midpoint,
                receiver_plane,
                count,
                r,
                _pad0,
                _pad1,
            }
        );
        test_support::assert_wgsl_layout!(
            src,
            RecIn {
                uv,
                zp,
                t,
                g0,
                gu,
                gv,
                c,
                sil_a,
                sil_e1,
                sil_e2,
                sil_clip,
            }
        );
    }

    #[test]
    fn frame_wgsl_validates_with_naga() {
        test_support::wgsl::assert_shaders_valid([(
            "packet_hsm_frame",
            shadow_map_core::gpu::kernel::shader_source(FRAME_SHADER_PARTS),
        )]);
    }
}
