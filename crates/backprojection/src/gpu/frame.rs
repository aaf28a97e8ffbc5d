//! The engine path: [`BackprojectionFrame`], recorded into the caller's command encoder.

use super::{specialization, uniforms, BitTable, BpKernel, BpUniform, KernelUniforms};
use crate::cpu::{plan, CpuBackprojection};
use shadow_map_core::{
    gpu::{
        estimate::EstimateUniform,
        frame::{
            check_buffers, cpu_twin_v, single_view, status_buffer, FrameEstimator, FrameInputs,
            Views,
        },
        layout::ViewMaps,
        GpuContext,
    },
    light_view::LightView,
    Receivers, Report, Result, Scene, SoftShadowEstimator,
};
use std::sync::Arc;

/// Backprojection on the engine path: per frame, recorded into the caller's command
/// encoder from the caller's casters and receiver buffer, V into the caller's buffer, with no
/// submit, no wait and no readback.
///
/// ```text
/// let frame = BackprojectionFrame::prepare(ctx, &params)?;   // once: pipelines, maps, uniforms
/// loop {
///     let mut enc = device.create_command_encoder(&Default::default());
///     frame.encode(&mut enc, &FrameInputs { casters, views, light, receivers, count, v })?;
///     queue.submit([enc.finish()]);                          // the caller's submit
/// }
/// ```
///
/// A frame records the depth-peeling passes, the midpoint pass (clamped for the frame's view as
/// [`request`](crate::cpu::request) clamps it), the anchored MSSM of layer 0 (every level up to
/// `ceil(log2 r)`, at most 10, allocated once: the kernel's minimum query is exact whatever the
/// number of levels, so V equals the CPU twin's which builds only the levels the view needs),
/// the copies into the kernel's texture arrays, and the kernel over `count` receivers in one
/// dispatch. The kernel's counters (receivers outside the light frustum, non-finite results
/// replaced by 0, receivers cut short by the loop budget and left NaN) go to
/// [`FrameEstimator::status`]. The loop budget: some devices bound the loop iterations of one
/// invocation (llvmpipe, i.e. lavapipe, ends every loop once 65535 iterations in all have run),
/// which would silently truncate a large kernel's walk (`max_nspp` up to 4096 samples, up to 4
/// layers, up to 256 occlusion bits each); the kernel ends with the core's two-trip probe and
/// leaves a cut receiver NaN for the caller to redo (`FrameTwin` redoes it with the CPU twin in
/// the same view, `shadow_map_core::gpu::frame::finish_on_cpu`). Semi-transparent casters
/// (a [`GpuScene`](shadow_map_core::gpu::raster::GpuScene) whose casters are not all
/// opaque) are modelled as on the CPU: the peeling passes also write each layer's opacity
/// plane (the opacity of the caster each texel's depth came from), the layout copies them after
/// the midpoints, and the kernel weights each backprojected micropatch by the opacity of its
/// layers in front of the receiver with `auto` settings resolved as for a semi-transparent
/// scene (additive occlusion, the deepest layer, no gap filling); an opaque frame writes and
/// copies no opacity plane (the planes are allocated at `prepare`, one per depth layer). The
/// light view is the caller's: [`FrameEstimator::fit_views`] fits one on the CPU as `build`
/// does.
pub struct BackprojectionFrame {
    ctx: Arc<GpuContext>,
    /// The parameters (a CPU twin configured with them: its settings, and the template of
    /// [`FrameEstimator::cpu_twin`]).
    cpu: CpuBackprojection,
    kernel: BpKernel,
    /// The layers, midpoints, opacity planes and MSSM, laid out for the kernel.
    maps: ViewMaps,
    bufs: KernelUniforms,
    status: wgpu::Buffer,
}

impl BackprojectionFrame {
    /// Compiles the pipelines and allocates the layers, the kernel's texture arrays, the
    /// uniforms and the status buffer for the parameters `params` (a table of backprojection's
    /// specs). Errors: the parameters' own; device limits as
    /// [`Error::Limit`](shadow_map_core::Error::Limit).
    pub fn prepare(ctx: Arc<GpuContext>, params: &shadow_map_core::Params) -> Result<Self> {
        let mut cpu = CpuBackprojection::new()?;
        shadow_map_core::estimator::configure(&mut cpu, params)?;
        let s = cpu.settings();
        let r = s.resolution;
        let req = shadow_map_core::LightSpaceRequest {
            resolution: r,
            layers: s.layers,
            midpoints: s.shadow.midpoint().then_some(0.0),
            mssm_levels: Some((r as f32).log2().ceil().clamp(1.0, 10.0) as u32),
            dual_mssm_levels: None,
            pyramid: false,
            raster: shadow_map_core::RasterOptions::default(),
            opacity: true,
        };
        let maps = ViewMaps::prepare(&ctx, "backprojection", &req)?;
        let kernel = BpKernel::new(&ctx)?;
        let uniform = |label, size: usize| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let bufs = KernelUniforms {
            view: maps.layers.view_uniform().clone(),
            est: uniform("estimate uniform", std::mem::size_of::<EstimateUniform>()),
            bp: uniform("backprojection uniform", std::mem::size_of::<BpUniform>()),
            bits: uniform("backprojection bit table", std::mem::size_of::<BitTable>()),
        };
        let status = status_buffer(&ctx, "backprojection frame status", 3);
        Ok(BackprojectionFrame {
            ctx,
            cpu,
            kernel,
            maps,
            bufs,
            status,
        })
    }

    /// The maps the last submitted frame rendered: what a test reads back
    /// (`maps().layers.light_space(view).to_cpu(ctx)`) to run the CPU twin on the very maps the
    /// kernel read.
    pub fn maps(&self) -> &ViewMaps {
        &self.maps
    }
}

impl FrameEstimator for BackprojectionFrame {
    fn name(&self) -> &'static str {
        "backprojection"
    }

    /// The view the estimator's own `build` fits for `receivers` ([`plan`]).
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.ctx.check_lost()?;
        let (view, _, _) = plan(self.cpu.settings(), scene, receivers)?;
        Ok(vec![Some(view)])
    }

    fn light_space_bytes(&self) -> usize {
        self.maps.layers.bytes()
    }

    /// Three u32: receivers outside the light frustum, non-finite results (written as 0),
    /// receivers cut short by the loop budget (left NaN).
    fn status(&self) -> Option<&wgpu::Buffer> {
        Some(&self.status)
    }

    /// Opacity planes per layer (see [`BackprojectionFrame`]).
    fn models_opacity(&self) -> bool {
        true
    }

    /// `occlusion=bitmask` on a semi-transparent scene: the bits carry no opacity.
    fn scene_warnings(&self, scene: &Scene) -> Vec<shadow_map_core::Warning> {
        let mut report = Report::default();
        crate::cpu::warn_bitmask_opacity(&mut report, self.cpu.settings(), scene);
        report.warnings
    }

    /// The layers (with their opacity for semi-transparent casters), midpoints and MSSM
    /// rendered in the one view, laid out, then the kernel.
    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let view = single_view(inputs.views)?;
        let n = inputs.count as u64;
        check_buffers(&self.ctx, inputs.receivers, inputs.v, n)?;
        let ctx = &*self.ctx;
        let settings = self.cpu.settings();
        let clamp = settings.shadow.midpoint_clamp(view).unwrap_or(0.0);
        inputs.mark(enc, "start");
        // The MSSM levels the widest kernel of this view needs (crate::cpu::request's rule): the
        // levels above only speed up queries no kernel makes, and each costs a pass over r^2.
        let planes = crate::cpu::request(settings, view, inputs.light.half_extent()).mssm_planes();
        let semi = self.maps.encode(ctx, enc, inputs, view, clamp, planes)?;
        let (eu, mut bpu, table) = uniforms(settings, &self.maps.km, semi, inputs.light);
        bpu.mssm_levels = bpu.mssm_levels.min(planes);
        ctx.write_in(enc, &self.bufs.est, 0, bytemuck::bytes_of(&eu));
        ctx.write_in(enc, &self.bufs.bp, 0, bytemuck::bytes_of(&bpu));
        ctx.write_in(enc, &self.bufs.bits, 0, bytemuck::bytes_of(&table));
        enc.clear_buffer(&self.status, 0, None);
        self.kernel.encode(
            ctx,
            enc,
            &specialization(&eu, &bpu),
            &self.bufs,
            &self.maps.km,
            inputs.receivers,
            inputs.v,
            inputs.count,
            &self.status,
        )?;
        inputs.mark(enc, "estimate");
        Ok(())
    }

    fn caster_passes(&self, _views: &Views) -> u32 {
        self.maps.layers.passes()
    }

    /// [`CpuBackprojection::build_in_view`], then its estimate.
    fn cpu_twin(&self, scene: &Scene, receivers: &Receivers, views: &Views) -> Result<Vec<f32>> {
        let view = *single_view(views)?;
        cpu_twin_v(
            CpuBackprojection::new()?,
            self.cpu.params(),
            receivers,
            |e, v| {
                e.build_in_view(scene, receivers, view)?;
                e.estimate(scene, receivers, v)
            },
        )
    }
}
