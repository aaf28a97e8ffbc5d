//! The engine path of hard, PCF, PCSS ([`MapFrame`]) and multi-sample ([`MultiSampleFrame`])
//! (issue 20, first step): shadow maps and their filter recorded every frame into the caller's
//! command encoder, from the caller's casters and receiver buffer, V written into the caller's
//! buffer. Nothing is submitted, nothing waits,
//! nothing is read back: the loop-budget and frustum counters go to a status buffer the caller
//! may read when it likes ([`MapFrame::status`]).
//!
//! ```text
//! let frame = MapFrame::<Pcss>::prepare(ctx, &params)?;        // once: pipelines, map, uniforms
//! loop {
//!     let mut enc = device.create_command_encoder(&Default::default());
//!     frame.encode(&mut enc, &FrameInputs { casters, view, light, receivers, v })?;
//!     queue.submit([enc.finish()]);                             // the caller's submit
//! }
//! ```
//!
//! The light view is the caller's ([`MapFrame::fit_view`] fits one on the CPU, as the
//! estimator's `build` does); `depth=unorm16` is not in the frame path yet (an error naming the
//! key). Receivers the device's loop budget cuts short keep the `CUT_BITS` NaN payload in V and
//! are counted in the status; the frame path does not redo them on the CPU.
use super::{
    kernel,
    map_estimator::{entry, shader_parts, GpuFilter},
    multi_sample::Kernels as MultiSampleKernels,
};
use crate::{
    common::MapSettings,
    multi_sample::{jitter, MultiSampleParams},
};
use shadow_map_core::{
    gpu::{
        estimate::{EstimateUniform, OVERRIDES, WORKGROUP_SIZE},
        receivers::RECEIVER_BYTES,
        GpuContext, GpuMapFrame, GpuScene, GpuShadowMapper,
    },
    light_space::point_frame,
    light_view::{FitReport, LightView},
    DepthPrecision, Error, Light, Params, Receivers, Result, Scene,
};
use std::{marker::PhantomData, num::NonZeroU64, sync::Arc};

/// What one frame reads and writes, all the caller's.
#[derive(Debug, Clone, Copy)]
pub struct FrameInputs<'a> {
    /// The casters' triangles (a [`GpuScene`]: `vec4` positions, three per triangle).
    pub casters: &'a GpuScene,
    /// The frame's light view, at the resolution the frame was prepared with.
    pub view: &'a LightView,
    /// The light.
    pub light: &'a Light,
    /// The receivers: an array of the core's `ReceiverGpu` (32 bytes each), `STORAGE` usage.
    pub receivers: &'a wgpu::Buffer,
    /// How many receivers the buffer holds (from its start).
    pub count: u32,
    /// V per receiver as f32 bits (NaN for inactive receivers), `STORAGE` usage, at least
    /// `4 count` bytes.
    pub v: &'a wgpu::Buffer,
}

/// Hard, PCF or PCSS (`F`) on the engine path (module documentation).
pub struct MapFrame<F: GpuFilter> {
    ctx: Arc<GpuContext>,
    settings: MapSettings,
    uniform: EstimateUniform,
    map: GpuMapFrame,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    est: wgpu::Buffer,
    status: wgpu::Buffer,
    _f: PhantomData<fn() -> F>,
}

impl<F: GpuFilter> MapFrame<F> {
    /// Compiles the raster and estimate pipelines and allocates the map, the uniforms and the
    /// status buffer for the parameters `params` (a table of `F::SPECS`). Errors: the
    /// parameters' own; [`Error::Param`] for `depth=unorm16`; device limits as [`Error::Limit`].
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params) -> Result<Self> {
        let settings = MapSettings::from_params(params)?;
        if settings.depth != DepthPrecision::F32 {
            return Err(Error::param(
                "depth",
                "the frame path renders f32 maps only so far (use depth=f32)",
            ));
        }
        let filter = F::from_params(params)?;
        let (b0, b1) = settings.biases();
        // The light is written per frame; these are the settings around it.
        let mut uniform = EstimateUniform::new(&Light::directional(glam::Vec3::NEG_Y, 1.0), b0, b1);
        uniform.receiver_plane = u32::from(settings.receiver_plane);
        filter.set_uniform(&mut uniform);
        let mapper = GpuShadowMapper::new(&ctx)?;
        let map = mapper.map_frame(&ctx, settings.resolution, settings.raster(), 1)?;
        let label = format!("{} frame", F::NAME);
        let module = kernel_module(&ctx, &label, &shader_parts::<F>(DepthPrecision::F32))?;
        let layout = kernel::map_layout(&ctx, &label, DepthPrecision::F32);
        let pipeline = shadow_map_core::gpu::kernel::compute_pipeline(
            &ctx, &label, &module, &layout, "estimate", OVERRIDES,
        )?;
        let usage = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST;
        let est = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame estimate uniform"),
            size: std::mem::size_of::<EstimateUniform>() as u64,
            usage,
            mapped_at_creation: false,
        });
        let status = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame status"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(MapFrame {
            ctx,
            settings,
            uniform,
            map,
            layout,
            pipeline,
            est,
            status,
            _f: PhantomData,
        })
    }

    /// The view the estimator's own `build` fits for `receivers` (CPU work over the scene's
    /// triangles: the engine path's GPU fit is still to come).
    pub fn fit_view(&self, scene: &Scene, receivers: &Receivers) -> Result<(LightView, FitReport)> {
        self.settings
            .request()
            .fit_view(scene, receivers, &self.settings.view)
    }

    /// The status of the last frame the caller submitted, three u32: receivers outside the
    /// light frustum, non-finite results (written as 0), receivers cut by the device's loop
    /// budget (`CUT_BITS` in V). `COPY_SRC`: the caller copies it out when it likes.
    pub fn status(&self) -> &wgpu::Buffer {
        &self.status
    }

    /// Records one frame into `enc`: the status cleared, the map rendered in `inputs.view`, then
    /// the filter over `inputs.count` receivers writing V. Stages the view and the light with
    /// `queue.write_buffer` (they take effect at the caller's next submit: one `encode` per
    /// submit). Errors, before anything is recorded: a view of another resolution
    /// ([`Error::LightView`]); a receiver count beyond one dispatch
    /// (`65535 x WORKGROUP_SIZE`) or buffers smaller than the count needs ([`Error::Limit`]).
    pub fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let n = inputs.count as u64;
        let max = 65_535 * WORKGROUP_SIZE as u64;
        if n > max {
            return Err(Error::Limit {
                what: "receivers per frame (one dispatch)",
                requested: n,
                max,
            });
        }
        for (what, have, need) in [
            (
                "receiver buffer bytes",
                inputs.receivers.size(),
                n * RECEIVER_BYTES,
            ),
            ("V buffer bytes", inputs.v.size(), n * 4),
        ] {
            if have < need {
                return Err(Error::Limit {
                    what,
                    requested: need,
                    max: have,
                });
            }
        }
        let queue = &self.ctx.queue;
        self.map
            .encode(queue, enc, inputs.casters, inputs.view, 0)?;
        let mut u = EstimateUniform::new(inputs.light, 0.0, 0.0);
        u.bias = self.uniform.bias;
        u.slope_bias = self.uniform.slope_bias;
        u.receiver_plane = self.uniform.receiver_plane;
        u.kernel_half = self.uniform.kernel_half;
        u.max_taps = self.uniform.max_taps;
        u.inv_samples = self.uniform.inv_samples;
        queue.write_buffer(&self.est, 0, bytemuck::bytes_of(&u));
        enc.clear_buffer(&self.status, 0, None);
        if n == 0 {
            return Ok(());
        }
        let group = self
            .ctx
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("frame estimate"),
                layout: &self.layout,
                entries: &[
                    entry(0, self.map.view_uniform(0).as_entire_binding()),
                    entry(1, self.est.as_entire_binding()),
                    entry(2, wgpu::BindingResource::TextureView(&self.map.layer.view)),
                    entry(3, buffer_range(inputs.receivers, n * RECEIVER_BYTES)),
                    entry(4, buffer_range(inputs.v, n * 4)),
                    entry(5, self.status.as_entire_binding()),
                ],
            });
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("frame estimate"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(inputs.count.div_ceil(WORKGROUP_SIZE), 1, 1);
        Ok(())
    }
}

/// Checks one frame's receiver count against one dispatch (`65535 x WORKGROUP_SIZE`) and the
/// caller's buffers against the count ([`Error::Limit`]).
fn check_buffers(receivers: &wgpu::Buffer, v: &wgpu::Buffer, n: u64) -> Result<()> {
    let max = 65_535 * WORKGROUP_SIZE as u64;
    if n > max {
        return Err(Error::Limit {
            what: "receivers per frame (one dispatch)",
            requested: n,
            max,
        });
    }
    for (what, have, need) in [
        (
            "receiver buffer bytes",
            receivers.size(),
            n * RECEIVER_BYTES,
        ),
        ("V buffer bytes", v.size(), n * 4),
    ] {
        if have < need {
            return Err(Error::Limit {
                what,
                requested: need,
                max: have,
            });
        }
    }
    Ok(())
}

/// What one multi-sample frame reads and writes: [`FrameInputs`] with one view per sub-light
/// ([`MultiSampleFrame::fit_views`]; `None`: a sub-light no receiver is in front of, which
/// lights nothing but counts in N, as on the CPU).
#[derive(Debug, Clone, Copy)]
pub struct MultiSampleInputs<'a> {
    /// The casters.
    pub casters: &'a GpuScene,
    /// One view per sub-light, in [`MultiSampleFrame::fit_views`]' order.
    pub views: &'a [Option<LightView>],
    /// The light.
    pub light: &'a Light,
    /// The receivers (`ReceiverGpu` array).
    pub receivers: &'a wgpu::Buffer,
    /// How many receivers.
    pub count: u32,
    /// V per receiver as f32 bits.
    pub v: &'a wgpu::Buffer,
}

/// Multi-sample shadows on the engine path: per frame, the S x S sub-light maps rendered in turn
/// into one layer, each followed by the `accumulate` dispatch that reads it, then `finalize`
/// into the caller's V (module documentation). The per-receiver counts live in a buffer
/// allocated at `prepare` for at most `max_receivers`.
pub struct MultiSampleFrame {
    ctx: Arc<GpuContext>,
    settings: MapSettings,
    own: MultiSampleParams,
    map: GpuMapFrame,
    kernels: MultiSampleKernels,
    est: wgpu::Buffer,
    acc: wgpu::Buffer,
    max_receivers: u32,
}

impl MultiSampleFrame {
    /// Compiles the pipelines and allocates the map (one view slot per sub-light), the uniform
    /// and the counts for `max_receivers`, for the parameters `params` (a table of
    /// multi-sample's specs). Errors as [`MapFrame::prepare`].
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params, max_receivers: u32) -> Result<Self> {
        let settings = MapSettings::from_params(params)?;
        if settings.depth != DepthPrecision::F32 {
            return Err(Error::param(
                "depth",
                "the frame path renders f32 maps only so far (use depth=f32)",
            ));
        }
        let own = MultiSampleParams::from_params(params)?;
        let mapper = GpuShadowMapper::new(&ctx)?;
        let views = own.sublights * own.sublights;
        let map = mapper.map_frame(&ctx, settings.resolution, settings.raster(), views)?;
        let kernels = MultiSampleKernels::new(&ctx, DepthPrecision::F32)?;
        let est = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("multi-sample frame uniform"),
            size: std::mem::size_of::<EstimateUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let acc = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("multi-sample frame counts"),
            size: 4 * max_receivers.max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(MultiSampleFrame {
            ctx,
            settings,
            own,
            map,
            kernels,
            est,
            acc,
            max_receivers,
        })
    }

    /// The sub-light views the estimator fits for `receivers` (CPU work, as its `estimate`
    /// does): one per jittered stratum of the light, `None` where no receiver is in front.
    pub fn fit_views(
        &self,
        scene: &Scene,
        receivers: &Receivers,
    ) -> Result<Vec<Option<LightView>>> {
        let MultiSampleParams { sublights, seed } = self.own;
        let light = &scene.light;
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

    /// Records one frame into `enc` (one `encode` per submit; module documentation). Errors,
    /// before anything is recorded: more views than sub-lights, views of another resolution
    /// ([`Error::LightView`]), more receivers than `max_receivers` or than the caller's buffers
    /// hold ([`Error::Limit`]).
    pub fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        inputs: &MultiSampleInputs<'_>,
    ) -> Result<()> {
        let n = inputs.count as u64;
        check_buffers(inputs.receivers, inputs.v, n)?;
        if inputs.count > self.max_receivers {
            return Err(Error::Limit {
                what: "receivers per multi-sample frame (max_receivers at prepare)",
                requested: n,
                max: self.max_receivers as u64,
            });
        }
        if inputs.views.len() > self.map.slots() {
            return Err(Error::LightView(format!(
                "{} views for {} sub-lights",
                inputs.views.len(),
                self.map.slots()
            )));
        }
        if let Some(v) = inputs.views.iter().flatten().find(|v| v.r != self.map.r) {
            return Err(Error::LightView(format!(
                "a sub-light view has resolution {} but the map was prepared at {}",
                v.r, self.map.r
            )));
        }
        let queue = &self.ctx.queue;
        let (b0, b1) = self.settings.biases();
        let mut u = EstimateUniform::new(inputs.light, b0, b1);
        u.receiver_plane = u32::from(self.settings.receiver_plane);
        u.inv_samples = 1.0 / inputs.views.len().max(1) as f32;
        queue.write_buffer(&self.est, 0, bytemuck::bytes_of(&u));
        enc.clear_buffer(&self.acc, 0, None);
        if n == 0 {
            return Ok(());
        }
        let k = &self.kernels;
        let groups = |view: &wgpu::Buffer, map: wgpu::BindingResource<'_>| {
            self.ctx
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("multi-sample frame"),
                    layout: &k.layout,
                    entries: &[
                        entry(0, view.as_entire_binding()),
                        entry(1, self.est.as_entire_binding()),
                        entry(2, map),
                        entry(3, buffer_range(inputs.receivers, n * RECEIVER_BYTES)),
                        entry(4, buffer_range(&self.acc, n * 4)),
                        entry(5, buffer_range(inputs.v, n * 4)),
                    ],
                })
        };
        let wg = inputs.count.div_ceil(WORKGROUP_SIZE);
        for (slot, view) in inputs.views.iter().enumerate() {
            let Some(view) = view else { continue };
            self.map.encode(queue, enc, inputs.casters, view, slot)?;
            let group = groups(
                self.map.view_uniform(slot),
                wgpu::BindingResource::TextureView(&self.map.layer.view),
            );
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("multi-sample frame accumulate"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&k.accumulate);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(wg, 1, 1);
        }
        // The finalize kernel reads no view or map: slot 0 and the placeholder fill the layout.
        let group = groups(self.map.view_uniform(0), k.placeholder.binding());
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("multi-sample frame finalize"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&k.finalize);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(wg, 1, 1);
        Ok(())
    }
}

/// The first `bytes` of `b` as a binding.
fn buffer_range(b: &wgpu::Buffer, bytes: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer: b,
        offset: 0,
        size: NonZeroU64::new(bytes),
    })
}

fn kernel_module(ctx: &GpuContext, label: &str, parts: &[&str]) -> Result<wgpu::ShaderModule> {
    shadow_map_core::gpu::kernel::shader_module(ctx, label, parts)
}
