//! GPU twin of [`crate::multi_sample`]: per sub-light, one shadow map from [`MapBuilder`] and one
//! `accumulate` dispatch into a per-receiver count on the GPU, one map alive at a time; a
//! `finalize` dispatch divides by the number of sub-lights at the end.
use super::{
    kernel::{self, ReceiverChunk},
    map_estimator::entry,
    maps::{GpuMaps, MapBuilder, MapDepth, MapOrigin},
};
use crate::{
    common::MapSettings,
    multi_sample::{jitter, note_run, MultiSampleParams, DESCRIPTION, NAME, SPECS},
};
use bytemuck::Zeroable;
use shadow_map_core::{
    gpu::{
        estimate::{EstimateUniform, ESTIMATE_HEAD_WGSL, OVERRIDES, WORKGROUP_SIZE},
        shared::LightViewUniform,
        GpuContext, GpuScene,
    },
    light_space::LightSpaceRequest,
    Cancel, DepthPrecision, Error, Light, Params, Receivers, Report, Result, Scene,
    SoftShadowEstimator,
};
use std::{sync::Arc, time::Instant};

/// WGSL of the multi-sample kernels (`accumulate`, `finalize`).
pub const MULTI_SAMPLE_WGSL: &str = include_str!("multi_sample.wgsl");

/// The WGSL parts of the multi-sample kernels reading maps of precision `depth`, in order.
pub const fn shader_parts(depth: DepthPrecision) -> [&'static str; 3] {
    [
        ESTIMATE_HEAD_WGSL,
        kernel::depth_wgsl(depth),
        MULTI_SAMPLE_WGSL,
    ]
}

/// The kernels for one depth precision (also the frame path's, [`super::frame`]).
pub(crate) struct Kernels {
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) accumulate: wgpu::ComputePipeline,
    pub(crate) finalize: wgpu::ComputePipeline,
    /// A 1x1 map bound where a kernel reads none (`finalize`).
    pub(crate) placeholder: MapDepth,
}

impl Kernels {
    pub(crate) fn new(ctx: &GpuContext, depth: DepthPrecision) -> Result<Self> {
        let label = "multi-sample";
        let module = kernel::shader_module(ctx, label, &shader_parts(depth))?;
        let layout = kernel::map_layout(ctx, label, depth);
        let accumulate = kernel::compute_pipeline(
            ctx,
            "multi-sample accumulate",
            &module,
            &layout,
            "accumulate",
            OVERRIDES,
        )?;
        let finalize = kernel::compute_pipeline(
            ctx,
            "multi-sample finalize",
            &module,
            &layout,
            "finalize",
            OVERRIDES,
        )?;
        Ok(Kernels {
            layout,
            accumulate,
            finalize,
            placeholder: MapDepth::placeholder(ctx, depth)?,
        })
    }
}

/// Multi-sample shadows on the GPU (twin of [`MultiSample`](crate::MultiSample)): same name,
/// description and parameters, the same sub-light points (stratified, jittered by
/// [`jitter`]) and the same per-sample test.
pub struct GpuMultiSample {
    ctx: Arc<GpuContext>,
    params: Params,
    /// The shared settings, as `params` holds them (re-read on every `set_param`).
    map: MapSettings,
    /// The own settings, as `params` holds them (re-read on every `set_param`).
    own: MultiSampleParams,
    /// Kernels per depth precision (f32, unorm16), compiled on first use.
    kernels: [Option<Arc<Kernels>>; 2],
    builder: Arc<MapBuilder>,
    report: Report,
    chunk_cap: usize,
    /// Checked before each sub-light's map and dispatch.
    cancel: Cancel,
}

impl GpuMultiSample {
    /// With default parameters, compiling the f32 kernels on `ctx`'s device (the 16-bit ones
    /// on first use).
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self> {
        let builder = Arc::new(MapBuilder::new(&ctx)?);
        let params = Params::new(SPECS)?;
        let mut e = GpuMultiSample {
            builder,
            map: MapSettings::from_params(&params)?,
            own: MultiSampleParams::from_params(&params)?,
            params,
            ctx,
            kernels: [None, None],
            report: Report::default(),
            chunk_cap: usize::MAX,
            cancel: Cancel::new(),
        };
        e.kernels(DepthPrecision::F32)?;
        Ok(e)
    }

    /// The kernels for maps of precision `depth`, compiled on first use.
    fn kernels(&mut self, depth: DepthPrecision) -> Result<Arc<Kernels>> {
        let i = match depth {
            DepthPrecision::F32 => 0,
            DepthPrecision::Unorm16 => 1,
        };
        if let Some(k) = &self.kernels[i] {
            return Ok(k.clone());
        }
        let k = Arc::new(Kernels::new(&self.ctx, depth)?);
        self.kernels[i] = Some(k.clone());
        Ok(k)
    }

    /// Caps the receivers of one dispatch at `receivers` (default: as many as the device's limits
    /// allow). Smaller dispatches bound the run time of each, e.g. under a display driver's
    /// watchdog; V is the same for any cap. Errors: 0 ([`Error::Param`]).
    pub fn set_max_chunk(&mut self, receivers: usize) -> Result<()> {
        if receivers == 0 {
            return Err(Error::param("max_chunk", "must be at least 1 receiver"));
        }
        self.chunk_cap = receivers;
        Ok(())
    }

    /// The shadow-map request of every sub-light (resolution and culling from the parameters).
    pub fn request(&self) -> LightSpaceRequest {
        self.map.request()
    }

    /// The sub-light points (light-plane coordinates), exactly as the CPU twin draws them.
    pub fn sub_light_points(&self, light: &Light) -> Vec<glam::Vec2> {
        let MultiSampleParams { sublights, seed } = self.own;
        light.stratified_points(sublights, |k| jitter(seed, k))
    }

    /// Estimates V from given light-space data, one item per sub-light, consumed one at a time
    /// (e.g. the CPU twin's own maps: `LightSpace::build_point` at each of
    /// [`sub_light_points`](Self::sub_light_points) with [`request`](Self::request)). An item
    /// `Err(Error::LightView(_))` is a sub-light no receiver is in front of: it lights nothing but
    /// counts in N, as on the CPU; any other error is returned. Replaces the report.
    pub fn estimate_with(
        &mut self,
        sub_lights: impl IntoIterator<Item = Result<shadow_map_core::LightSpace>>,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        let ctx = self.ctx.clone();
        let depth = self.map.depth;
        let builder = self.builder.clone();
        let maps = sub_lights.into_iter().map(move |ls| {
            ls.and_then(|ls| GpuMaps::upload(&ctx, &ls, depth, builder.encoder(&ctx)?))
        });
        self.run(maps, light, receivers, v)
    }

    /// Accumulates every sub-light's map into the per-receiver counts, then finalizes V.
    fn run(
        &mut self,
        mut sub_lights: impl Iterator<Item = Result<GpuMaps>>,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        receivers.check_output(v)?;
        self.report = Report::default();
        let kernels = self.kernels(self.map.depth)?;
        let ctx = &*self.ctx;
        let (b0, b1) = self.map.biases();
        let mut u = EstimateUniform::new(light, b0, b1);
        u.receiver_plane = u32::from(self.map.receiver_plane);
        let chunks = ctx.scoped("multi-sample receivers", || {
            kernel::upload_receivers(
                ctx,
                "baselines",
                receivers,
                kernel::max_chunk(ctx, WORKGROUP_SIZE, self.chunk_cap),
                true,
            )
        })?;
        let (mut t_build, mut t_est) = (0.0, 0.0);
        let (mut peak, mut behind, mut n_points) = (0usize, 0usize, 0usize);
        loop {
            self.cancel.check()?;
            let t = Instant::now();
            let Some(item) = sub_lights.next() else {
                break;
            };
            n_points += 1;
            let maps = match item {
                Ok(m) => m,
                // No receiver in front of this light point: it lights nothing.
                Err(Error::LightView(_)) => continue,
                Err(e) => return Err(e),
            };
            t_build += t.elapsed().as_secs_f64() * 1e3;
            peak = peak.max(maps.bytes());
            behind = behind.max(maps.fit.out_of_frustum);
            let t = Instant::now();
            if !chunks.is_empty() {
                let view = LightViewUniform::from(&maps.view);
                u.depth_step = maps.depth.step();
                self.dispatch(
                    &kernels,
                    &kernels.accumulate,
                    "multi-sample accumulate",
                    &view,
                    &maps.depth,
                    &u,
                    &chunks,
                )?;
            }
            t_est += t.elapsed().as_secs_f64() * 1e3;
            // `maps` is dropped here, after its work is done: one map alive at a time.
        }
        u.inv_samples = 1.0 / n_points.max(1) as f32;
        let t = Instant::now();
        if !chunks.is_empty() {
            // The finalize kernel reads no map: the placeholder fills the layout.
            let view = LightViewUniform::zeroed();
            self.dispatch(
                &kernels,
                &kernels.finalize,
                "multi-sample finalize",
                &view,
                &kernels.placeholder,
                &u,
                &chunks,
            )?;
        }
        t_est += t.elapsed().as_secs_f64() * 1e3;
        kernel::read_v(ctx, &chunks, v)?;
        let s = self.own.sublights;
        note_run(&mut self.report, (t_build, t_est), peak, s, behind, light);
        Ok(())
    }

    /// One dispatch of `pipeline` over every chunk with a view and its map bound; waits for it.
    #[allow(clippy::too_many_arguments)]
    fn dispatch(
        &self,
        kernels: &Kernels,
        pipeline: &wgpu::ComputePipeline,
        label: &str,
        view: &LightViewUniform,
        depth: &MapDepth,
        u: &EstimateUniform,
        chunks: &[ReceiverChunk],
    ) -> Result<()> {
        let ctx = &*self.ctx;
        ctx.scoped(label, || -> Result<()> {
            let view_buf = kernel::uniform(ctx, "light view", view);
            let est_buf = kernel::uniform(ctx, "estimate uniform", u);
            let mut groups = Vec::with_capacity(chunks.len());
            for c in chunks {
                let acc = c.acc.as_ref().ok_or_else(|| Error::Gpu {
                    stage: label.into(),
                    reason: "receiver chunk without an accumulator".into(),
                })?;
                groups.push(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(label),
                    layout: &kernels.layout,
                    entries: &[
                        entry(0, view_buf.as_entire_binding()),
                        entry(1, est_buf.as_entire_binding()),
                        entry(2, depth.binding()),
                        entry(3, c.receivers.as_entire_binding()),
                        entry(4, acc.as_entire_binding()),
                        entry(5, c.out.as_entire_binding()),
                    ],
                }));
            }
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(label),
                    timestamp_writes: None,
                });
                pass.set_pipeline(pipeline);
                for (c, g) in chunks.iter().zip(&groups) {
                    pass.set_bind_group(0, g, &[]);
                    pass.dispatch_workgroups(c.workgroups(WORKGROUP_SIZE), 1, 1);
                }
            }
            ctx.queue.submit([enc.finish()]);
            ctx.wait()
        })?
    }
}

impl SoftShadowEstimator for GpuMultiSample {
    shadow_map_core::estimator_identity!(NAME, DESCRIPTION, Gpu, params);
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.params.set(key, value)?;
        self.map = MapSettings::from_params(&self.params)?;
        self.own = MultiSampleParams::from_params(&self.params)?;
        Ok(())
    }
    fn set_cancel(&mut self, cancel: Cancel) {
        self.cancel = cancel;
    }
    fn build(&mut self, _scene: &Scene, _receivers: &Receivers) -> Result<()> {
        // Multi-view: each sub-light's map is built inside `estimate`, one at a time.
        self.report = Report::default();
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        let req = self.request();
        let points = self.sub_light_points(scene.light());
        let (opts, depth) = (self.map.view, self.map.depth);
        let ctx = self.ctx.clone();
        let gpu_scene = GpuScene::upload(&ctx, scene)?;
        let builder = self.builder.clone();
        let maps = points.into_iter().map(|y| {
            builder.build(
                &ctx,
                &gpu_scene,
                scene,
                receivers,
                MapOrigin::Point(y),
                &req,
                &opts,
                depth,
            )
        });
        self.run(maps, scene.light(), receivers, v)?;
        self.report
            .warn_all(shadow_map_core::Warning::opaque_casters(scene));
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}
