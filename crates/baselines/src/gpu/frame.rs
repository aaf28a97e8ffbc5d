//! The engine path ([`FrameEstimator`]) of hard, PCF, PCSS ([`MapFrame`]) and multi-sample
//! ([`MultiSampleFrame`]): shadow maps and their filter recorded every frame into the
//! caller's command encoder, from the caller's casters and receiver buffer, V written into the
//! caller's buffer. Nothing is submitted, nothing waits, nothing is read back: the loop-budget
//! and frustum counters go to a status buffer the caller may read when it likes
//! ([`FrameEstimator::status`]).
//!
//! The light views are the caller's ([`FrameEstimator::fit_views`] fits them on the CPU, as the
//! CPU twin's `build` does). Under `depth=unorm16` each rendered layer is encoded into 16-bit
//! codes by the core's [`GpuUnorm16Frame`] within the frame (the codes the CPU's
//! `Unorm16Map::encode` gives for the same layer), and the filter reads the codes. Receivers the
//! device's loop budget cuts short keep the `CUT_BITS` NaN payload in V and are counted in the
//! status, for the caller to redo (the registry's GPU estimator, the core's `FrameTwin`, redoes
//! them with the CPU twin in the same views).
use super::{
    kernel,
    map_estimator::{shader_parts, GpuFilter},
    multi_sample::Kernels as MultiSampleKernels,
};
use crate::{
    cpu::{MapEstimator, MultiSample},
    math::{inv_samples, jitter},
    settings::{MapSettings, MultiSampleParams},
};
pub use shadow_map_core::gpu::frame::{FrameEstimator, FrameInputs};
use shadow_map_core::{
    gpu::{
        estimate::{EstimateUniform, OVERRIDES},
        frame::{
            check_buffers, check_per_receiver, check_prepared_inputs, compute_pass,
            compute_pass_indirect, cpu_twin_v, receiver_ranges, single_view, status_buffer,
            ReceiverRange, Views,
        },
        kernel::{storage_buffer, BindGroupCache, SpecializedKernel},
        receivers::{ActiveLists, ListKind},
        GpuContext, GpuLightSpace, GpuMapFrame, GpuShadowMapper, GpuUnorm16Frame,
    },
    light_space::point_frame,
    light_view::{FitReport, LightView},
    DepthPrecision, Error, Params, Receivers, Result, Scene, SoftShadowEstimator,
};
use std::sync::Arc;

/// How a map frame's estimate kernel covers the receivers (one per frame, held inline).
#[allow(clippy::large_enum_variant)]
enum Slots {
    /// Each range's active receivers, listed every frame, the kernel dispatched over the list.
    Listed(ActiveLists),
    /// One invocation per slot (`estimate_slots`), this placeholder bound in the list's place.
    Every(wgpu::Buffer),
}

/// Hard, PCF or PCSS (`F`) on the engine path (module documentation).
pub struct MapFrame<F: GpuFilter> {
    ctx: Arc<GpuContext>,
    params: Params,
    settings: MapSettings,
    filter: F,
    map: FrameMap,
    /// The estimate kernel, specialised for the light's shape.
    kernel: SpecializedKernel,
    est: wgpu::Buffer,
    status: wgpu::Buffer,
    /// How the estimate kernel covers the receivers ([`GpuFilter::ACTIVE_LIST`]).
    slots: Slots,
    groups: BindGroupCache,
}

impl<F: GpuFilter> MapFrame<F> {
    /// Compiles the raster and estimate pipelines and allocates the map (and its 16-bit codes
    /// under `depth=unorm16`), the uniforms and the status buffer for the parameters `params` (a
    /// table of `F::SPECS`). Errors: the parameters' own; device limits as [`Error::Limit`].
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params) -> Result<Self> {
        let settings = MapSettings::from_params(params)?;
        let filter = F::from_params(params)?;
        let map = FrameMap::new(&ctx, &settings, 1, F::FEW_TAPS)?;
        let label = format!("{} frame", F::NAME);
        let kernel = SpecializedKernel::new(
            &ctx,
            &label,
            &shader_parts::<F>(settings.depth),
            "estimate",
            OVERRIDES,
        )?;
        let est = uniform_buffer(&ctx, "frame estimate uniform");
        let status = status_buffer(&ctx, "frame status", 4);
        let slots = match F::ACTIVE_LIST {
            true => Slots::Listed(ActiveLists::new(&ctx)?),
            false => Slots::Every(storage_buffer(&ctx, "frame estimate: no active list", 16)),
        };
        Ok(MapFrame {
            slots,
            groups: BindGroupCache::default(),
            ctx,
            params: params.clone(),
            settings,
            filter,
            map,
            kernel,
            est,
            status,
        })
    }

    /// The map the last submitted frame rendered, in `view` (the frame's; as linear depths: the
    /// depth test written into the layer under `depth=f32`, the layer from which the frame
    /// encodes its codes under `depth=unorm16`): what a test reads back
    /// ([`GpuLightSpace::to_cpu`]) to run the CPU filter on the very map the kernel read
    /// ([`MapEstimator::set_light_space`]).
    pub fn light_space(&self, view: &LightView) -> Result<GpuLightSpace> {
        self.map.light_space(&self.ctx, 0, view)
    }

    /// The estimate kernel's bind group over `range` of the frame's receivers, reading `list`.
    fn estimate_group(
        &self,
        inputs: &FrameInputs<'_>,
        range: ReceiverRange,
        list: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        self.groups.get_dense(
            &self.ctx,
            LABEL,
            &self.kernel.layout,
            &[
                self.map.raster.view_uniform(0).as_entire_binding(),
                self.est.as_entire_binding(),
                self.map.binding(),
                range.receivers(inputs.receivers),
                range.words(inputs.v),
                self.status.as_entire_binding(),
                list.as_entire_binding(),
            ],
        )
    }
}

/// The label of a map frame's estimate passes.
const LABEL: &str = "frame estimate";

impl<F: GpuFilter> FrameEstimator for MapFrame<F> {
    fn name(&self) -> &'static str {
        F::NAME
    }

    /// The view the estimator's own `build` fits for `receivers`.
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.ctx.check_lost()?;
        let (view, _) = self
            .settings
            .request()
            .fit_view(scene, receivers, &self.settings.view)?;
        Ok(vec![Some(view)])
    }

    /// The map and, under `depth=unorm16`, its 16-bit codes.
    fn light_space_bytes(&self) -> usize {
        self.map.bytes()
    }

    /// Three u32: receivers outside the light frustum, non-finite results (written as 0),
    /// receivers cut by the device's loop budget (`CUT_BITS` in V).
    fn status(&self) -> Option<&wgpu::Buffer> {
        Some(&self.status)
    }

    /// The status cleared, the map rendered in the one view, then the filter over the receivers.
    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let view = single_view(inputs.views)?;
        let n = inputs.count as u64;
        check_buffers(&self.ctx, inputs.receivers, inputs.v, n)?;
        let ctx = &self.ctx;
        self.groups.next_encode();
        inputs.mark(enc, "start");
        self.map.raster.encode(ctx, enc, inputs.casters, view, 0)?;
        inputs.mark(enc, "raster");
        let mut u = estimate_uniform(&self.settings, inputs.light);
        self.filter.set_uniform(&mut u);
        if let Some(codes) = &self.map.unorm16 {
            u.depth_step = codes.encode(&self.ctx, enc, 0, view.n, view.far)?;
            inputs.mark(enc, "unorm16");
        }
        ctx.write_in(enc, &self.est, 0, bytemuck::bytes_of(&u));
        enc.clear_buffer(&self.status, 0, None);
        if n == 0 {
            return Ok(());
        }
        let shape = u.shape_switch();
        let lists = match &self.slots {
            Slots::Listed(lists) => lists,
            Slots::Every(placeholder) => {
                // One invocation per slot, the placeholder bound in the list's place.
                let pipeline = self
                    .kernel
                    .entry_pipeline(ctx, "estimate_slots", &[shape])?;
                for range in receiver_ranges(ctx, inputs.count) {
                    let group = self.estimate_group(inputs, range, placeholder);
                    compute_pass(enc, LABEL, &pipeline, &group, range.workgroups());
                }
                inputs.mark(enc, "estimate");
                return Ok(());
            }
        };
        // Over the active list; a filter with a wide pass defers its receivers of wide regions
        // to it, a workgroup each.
        let (first, wide) = match self.filter.wide_cells() {
            Some(cells) => {
                let switches = [shape, ("WIDE_CELLS", cells as f64)];
                (
                    self.kernel.entry_pipeline(ctx, "estimate", &switches)?,
                    Some(
                        self.kernel
                            .entry_pipeline(ctx, "estimate_wide", &switches)?,
                    ),
                )
            }
            None => (self.kernel.entry_pipeline(ctx, "estimate", &[shape])?, None),
        };
        lists.dispatch_passes(
            ctx,
            enc,
            LABEL,
            (&first, wide.as_ref().map(|p| (ListKind::DeferredWide, p))),
            inputs.count,
            (inputs.receivers, inputs.v),
            |_, range, list| self.estimate_group(inputs, range, list),
        )?;
        inputs.mark(enc, "estimate");
        Ok(())
    }

    fn caster_passes(&self, _views: &Views) -> u32 {
        1
    }

    fn cpu_twin(&self, scene: &Scene, receivers: &Receivers, views: &Views) -> Result<Vec<f32>> {
        let view = *single_view(views)?;
        cpu_twin_v(
            MapEstimator::<F>::new()?,
            &self.params,
            receivers,
            |e, v| {
                e.build_in_view(scene, view)?;
                e.estimate(scene, receivers, v)
            },
        )
    }
}

/// The map a frame renders its views into (one view slot each), and its 16-bit codes under
/// `depth=unorm16`.
struct FrameMap {
    raster: GpuMapFrame,
    /// The layer's 16-bit codes under `depth=unorm16`, re-encoded after each view's raster.
    unorm16: Option<GpuUnorm16Frame>,
}

impl FrameMap {
    /// The map at `settings`' resolution, raster options and precision, with `views` slots,
    /// read by kernels of `few_taps` per receiver or not ([`kernel::map_is_depth_test`]: then
    /// the depth test itself, the pass without a fragment stage; else the linear layer the
    /// fragment stage writes, from which the 16-bit codes are encoded).
    fn new(ctx: &GpuContext, settings: &MapSettings, views: u32, few_taps: bool) -> Result<Self> {
        let mapper = GpuShadowMapper::new(ctx)?;
        let depth_only = kernel::map_is_depth_test(settings.depth, few_taps);
        let raster = mapper.map_frame(
            ctx,
            settings.resolution,
            settings.raster(),
            views,
            depth_only,
        )?;
        let unorm16 = match settings.depth {
            DepthPrecision::F32 => None,
            DepthPrecision::Unorm16 => {
                Some(GpuUnorm16Frame::new(ctx, &raster.layer, raster.slots())?)
            }
        };
        Ok(FrameMap { raster, unorm16 })
    }

    /// The map and, under `depth=unorm16`, its 16-bit codes.
    fn bytes(&self) -> usize {
        self.raster.layer.bytes() + self.unorm16.as_ref().map_or(0, GpuUnorm16Frame::bytes)
    }

    /// What the filter kernels bind as the map: the layer (f32) or its codes (`depth=unorm16`).
    fn binding(&self) -> wgpu::BindingResource<'_> {
        match &self.unorm16 {
            Some(codes) => codes.binding(),
            None if self.raster.depth_only() => self.raster.depth_binding(),
            None => wgpu::BindingResource::TextureView(&self.raster.layer.view),
        }
    }

    /// The layer as light-space data in `view` (sharing the frame's texture), with the view
    /// uniform of `slot`: a depth-only map's layer written from its depth test first (submitted).
    fn light_space(
        &self,
        ctx: &GpuContext,
        slot: usize,
        view: &LightView,
    ) -> Result<GpuLightSpace> {
        self.raster.fill_layer(ctx, slot)?;
        Ok(GpuLightSpace {
            view: *view,
            fit: FitReport::default(),
            view_uniform: self.raster.view_uniform(slot).clone(),
            layers: vec![self.raster.layer.clone()],
            opacity: Vec::new(),
            midpoints: Vec::new(),
            mssm: None,
            dual_mssm: None,
            pyramid: None,
        })
    }
}

/// The estimate uniform of a frame's kernels: the light, the receiver bias and the caster test
/// of `settings` (each method adds its own fields).
fn estimate_uniform(settings: &MapSettings, light: &shadow_map_core::Light) -> EstimateUniform {
    let (b0, b1) = settings.biases();
    let mut u = EstimateUniform::new(light, b0, b1);
    u.receiver_plane = u32::from(settings.receiver_plane);
    u
}

/// A buffer for one [`EstimateUniform`], written each frame.
fn uniform_buffer(ctx: &GpuContext, label: &str) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: std::mem::size_of::<EstimateUniform>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Multi-sample shadows on the engine path: per frame, the S x S sub-light maps rendered in turn
/// into one layer, each followed by the `accumulate` dispatch that reads it, then `finalize`
/// into the caller's V (module documentation). The per-receiver counts live in a buffer
/// allocated at `prepare` for at most `max_receivers`.
pub struct MultiSampleFrame {
    ctx: Arc<GpuContext>,
    params: Params,
    settings: MapSettings,
    own: MultiSampleParams,
    map: FrameMap,
    kernels: MultiSampleKernels,
    /// One estimate uniform per view slot (the code step is the sub-light view's own).
    est: Vec<wgpu::Buffer>,
    acc: wgpu::Buffer,
    max_receivers: u32,
    /// Each range's active receivers, listed once per frame for every sub-light's pass.
    active: ActiveLists,
    groups: BindGroupCache,
}

impl MultiSampleFrame {
    /// Compiles the pipelines and allocates the map (one view slot per sub-light), the uniform
    /// and the counts for `max_receivers`, for the parameters `params` (a table of
    /// multi-sample's specs). Errors as [`MapFrame::prepare`], and [`Error::Limit`] for counts
    /// beyond the device's `max_storage_buffer_binding_size`.
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params, max_receivers: u32) -> Result<Self> {
        let settings = MapSettings::from_params(params)?;
        let own = MultiSampleParams::from_params(params)?;
        check_per_receiver(
            &ctx,
            "multi-sample frame counts bytes (max_storage_buffer_binding_size)",
            max_receivers,
        )?;
        let map = FrameMap::new(&ctx, &settings, own.sublights * own.sublights, true)?;
        let kernels = MultiSampleKernels::new(&ctx, settings.depth)?;
        let est = (0..map.raster.slots())
            .map(|_| uniform_buffer(&ctx, "multi-sample frame uniform"))
            .collect();
        let acc = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("multi-sample frame counts"),
            size: 4 * max_receivers.max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(MultiSampleFrame {
            active: ActiveLists::new(&ctx)?,
            groups: BindGroupCache::default(),
            ctx,
            params: params.clone(),
            settings,
            own,
            map,
            kernels,
            est,
            acc,
            max_receivers,
        })
    }

    /// The map of the last view present in `views` (the frame renders its sub-lights in turn
    /// into one layer), as the last submitted frame recorded with `views` left it; `None` with no
    /// view present. Recorded with one sub-light's view present, that sub-light's map: what a
    /// test reads back ([`GpuLightSpace::to_cpu`]) to run the CPU twin on
    /// ([`MultiSample::estimate_in_light_spaces`]).
    pub fn light_space(&self, views: &Views) -> Result<Option<GpuLightSpace>> {
        let last = views
            .iter()
            .enumerate()
            .rev()
            .find_map(|(slot, v)| v.as_ref().map(|v| (slot, v)));
        match last {
            Some((slot, view)) if slot < self.map.raster.slots() => {
                self.map.light_space(&self.ctx, slot, view).map(Some)
            }
            _ => Ok(None),
        }
    }
}

impl FrameEstimator for MultiSampleFrame {
    fn name(&self) -> &'static str {
        "multi-sample"
    }

    /// The sub-light views the estimator fits for `receivers` (CPU work, as its `estimate`
    /// does): one per jittered stratum of the light, `None` where no receiver is in front (a
    /// sub-light that lights nothing but counts in N, as on the CPU).
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.ctx.check_lost()?;
        let MultiSampleParams { sublights, seed } = self.own;
        let light = scene.light();
        light
            .stratified_points(sublights, |k| jitter(seed, k))
            .into_iter()
            .map(|y| {
                let frame = point_frame(light, y)?;
                match LightView::fit_with(
                    scene,
                    receivers,
                    frame,
                    glam::Vec2::ZERO,
                    self.settings.resolution,
                    &self.settings.view,
                ) {
                    Ok((view, _)) => Ok(Some(view)),
                    Err(Error::LightView(_)) => Ok(None),
                    Err(e) => Err(e),
                }
            })
            .collect()
    }

    /// The map and, under `depth=unorm16`, its 16-bit codes.
    fn light_space_bytes(&self) -> usize {
        self.map.bytes()
    }

    /// Keeps no counters.
    fn status(&self) -> Option<&wgpu::Buffer> {
        None
    }

    /// The sub-light maps rendered in turn, each followed by its `accumulate` pass, then
    /// `finalize`. Errors also for more views than sub-lights ([`Error::LightView`]) and more
    /// receivers than `max_receivers` ([`Error::Limit`]).
    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let n = check_prepared_inputs(
            &self.ctx,
            inputs,
            self.max_receivers,
            "receivers per multi-sample frame (max_receivers at prepare)",
        )?;
        self.groups.next_encode();
        let slots = self.map.raster.slots();
        if inputs.views.len() > slots {
            return Err(Error::LightView(format!(
                "{} views for {} sub-lights",
                inputs.views.len(),
                slots
            )));
        }
        let r = self.map.raster.r;
        if let Some(v) = inputs.views.iter().flatten().find(|v| v.r != r) {
            return Err(Error::LightView(format!(
                "a sub-light view has resolution {} but the map was prepared at {}",
                v.r, r
            )));
        }
        let ctx = &self.ctx;
        let mut u = estimate_uniform(&self.settings, inputs.light);
        u.inv_samples = inv_samples(inputs.views.len());
        ctx.write_in(enc, &self.est[0], 0, bytemuck::bytes_of(&u));
        enc.clear_buffer(&self.acc, 0, None);
        if n == 0 {
            return Ok(());
        }
        let k = &self.kernels;
        let shape = [u.shape_switch()];
        let accumulate = k.kernel.entry_pipeline(ctx, "accumulate", &shape)?;
        let finalize = k.kernel.entry_pipeline(ctx, "finalize", &shape)?;
        // Each range's active receivers, listed once for every pass (inactive ones NaN).
        let ranges =
            self.active
                .encode_ranges(ctx, enc, inputs.count, inputs.receivers, inputs.v)?;
        // One pass of `pipe` per range of receivers over its active list, its bind group over
        // the range's receivers, sums, V and list.
        let passes = |enc: &mut wgpu::CommandEncoder,
                      label: &str,
                      pipe: &wgpu::ComputePipeline,
                      (view, est, map): (
            &wgpu::Buffer,
            &wgpu::Buffer,
            wgpu::BindingResource<'_>,
        )| {
            for (range, list) in &ranges {
                let group = self.groups.get_dense(
                    &self.ctx,
                    "multi-sample frame",
                    &k.kernel.layout,
                    &[
                        view.as_entire_binding(),
                        est.as_entire_binding(),
                        map.clone(),
                        range.receivers(inputs.receivers),
                        range.words(&self.acc),
                        range.words(inputs.v),
                        list.as_entire_binding(),
                    ],
                );
                compute_pass_indirect(enc, label, pipe, &group, list);
            }
        };
        inputs.mark(enc, "start");
        for (slot, view) in inputs.views.iter().enumerate() {
            let Some(view) = view else { continue };
            self.map
                .raster
                .encode(ctx, enc, inputs.casters, view, slot)?;
            inputs.mark(enc, "raster");
            if let Some(codes) = &self.map.unorm16 {
                let mut us = u;
                us.depth_step = codes.encode(&self.ctx, enc, slot, view.n, view.far)?;
                ctx.write_in(enc, &self.est[slot], 0, bytemuck::bytes_of(&us));
                inputs.mark(enc, "unorm16");
            }
            let est = if self.map.unorm16.is_some() {
                &self.est[slot]
            } else {
                &self.est[0]
            };
            let at = (self.map.raster.view_uniform(slot), est, self.map.binding());
            passes(enc, "multi-sample frame accumulate", &accumulate, at);
            inputs.mark(enc, "estimate");
        }
        // The finalize kernel reads no view or map: slot 0 and the map fill the layout.
        let at = (
            self.map.raster.view_uniform(0),
            &self.est[0],
            self.map.binding(),
        );
        passes(enc, "multi-sample frame finalize", &finalize, at);
        inputs.mark(enc, "finalize");
        Ok(())
    }

    fn cpu_twin(&self, scene: &Scene, receivers: &Receivers, views: &Views) -> Result<Vec<f32>> {
        cpu_twin_v(MultiSample::new()?, &self.params, receivers, |e, v| {
            e.estimate_in_views(scene, receivers, views, v)
        })
    }
}
