//! GPU twin of [`crate::map_estimator`]: one shadow map at the light centre, filtered per receiver
//! by a compute kernel (`map_estimator.wgsl` + the filter's WGSL), one invocation per receiver.
use super::{
    kernel::{self, ReceiverChunk},
    maps::{GpuMaps, MapBuilder, MapDepth, MapOrigin},
};
use crate::{
    common::MapSettings,
    map_estimator::{filter_all, Filter},
};
use shadow_map_core::gpu::kernel::BufferInitExt;
use shadow_map_core::{
    gpu::{
        estimate::{EstimateUniform, ESTIMATE_HEAD_WGSL, OVERRIDES, WORKGROUP_SIZE},
        receivers::RECEIVERS_WGSL,
        redo_cut_receivers,
        shared::LightViewUniform,
        GpuContext, GpuScene,
    },
    Cancel, DepthPrecision, Error, Light, Params, Receivers, Report, Result, Scene,
    SoftShadowEstimator, Warning,
};
use shadow_map_core::{light_space::LightSpace, Unorm16Map};
use std::{marker::PhantomData, sync::Arc, time::Instant};

/// WGSL of the frame shared by hard, PCF and PCSS (bindings, `estimate` entry point).
pub const MAP_ESTIMATOR_WGSL: &str = include_str!("map_estimator.wgsl");

pub use shadow_map_core::gpu::estimate::CELLS_WGSL;

/// The GPU side of a [`Filter`]: WGSL defining `fn facing(p_world, n_world) -> f32` and
/// `fn visibility(r: ReceiverSample) -> f32` exactly as the CPU filter computes them, and the
/// filter's settings in the uniform.
pub trait GpuFilter: Filter {
    /// The filter's WGSL (appended after [`MAP_ESTIMATOR_WGSL`]).
    const WGSL: &'static str;
    /// Writes the filter's settings (as the CPU filter's own `from_params` read them).
    fn set_uniform(&self, _u: &mut EstimateUniform) {}
}

/// The WGSL parts of the kernel of filter `F` reading a map of precision `depth`, in order.
pub const fn shader_parts<F: GpuFilter>(depth: DepthPrecision) -> [&'static str; 6] {
    [
        ESTIMATE_HEAD_WGSL,
        RECEIVERS_WGSL,
        kernel::depth_wgsl(depth),
        CELLS_WGSL,
        MAP_ESTIMATOR_WGSL,
        F::WGSL,
    ]
}

/// One compiled kernel: the bind-group layout and the pipeline for one depth precision.
pub(crate) struct Kernel {
    pub layout: wgpu::BindGroupLayout,
    pub pipeline: wgpu::ComputePipeline,
}

fn precision_index(d: DepthPrecision) -> usize {
    match d {
        DepthPrecision::F32 => 0,
        DepthPrecision::Unorm16 => 1,
    }
}

/// The GPU twin of [`MapEstimator`](crate::map_estimator::MapEstimator): same name, description and parameters; light-space data
/// from [`MapBuilder`], V from one compute dispatch per chunk of receivers.
pub struct GpuMapEstimator<F: GpuFilter> {
    ctx: Arc<GpuContext>,
    params: Params,
    /// Kernels per depth precision (f32, unorm16), compiled on first use.
    kernels: [Option<Kernel>; 2],
    maps: Option<GpuMaps>,
    builder: MapBuilder,
    report: Report,
    chunk_cap: usize,
    /// Checked before the dispatch and by the CPU redo of cut receivers.
    cancel: Cancel,
    _f: PhantomData<fn() -> F>,
}

/// What one kernel run found besides V.
struct RunStats {
    outside: usize,
    nonfinite: usize,
    cut: usize,
    estimate_ms: f64,
    readback_ms: f64,
}

impl<F: GpuFilter> GpuMapEstimator<F> {
    /// With default parameters, compiling the f32 kernel on `ctx`'s device (the 16-bit one on
    /// first use).
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self> {
        let builder = MapBuilder::new(&ctx)?;
        let mut e = GpuMapEstimator {
            builder,
            params: Params::new(F::SPECS)?,
            ctx,
            kernels: [None, None],
            maps: None,
            report: Report::default(),
            chunk_cap: usize::MAX,
            cancel: Cancel::new(),
            _f: PhantomData,
        };
        e.kernel(DepthPrecision::F32)?;
        Ok(e)
    }

    /// The kernel reading maps of precision `depth`, compiled on first use.
    fn kernel(&mut self, depth: DepthPrecision) -> Result<&Kernel> {
        let slot = &mut self.kernels[precision_index(depth)];
        if slot.is_none() {
            let label = format!("{} estimate", F::NAME);
            let module = kernel::shader_module(&self.ctx, &label, &shader_parts::<F>(depth))?;
            let layout = kernel::map_layout(&self.ctx, &label, depth);
            let pipeline = kernel::compute_pipeline(
                &self.ctx, &label, &module, &layout, "estimate", OVERRIDES,
            )?;
            *slot = Some(Kernel { layout, pipeline });
        }
        slot.as_ref().ok_or_else(|| Error::Gpu {
            stage: "kernel".into(),
            reason: "kernel missing after compilation".into(),
        })
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

    /// The light-space data of the last build.
    pub fn maps(&self) -> Option<&GpuMaps> {
        self.maps.as_ref()
    }

    /// Estimates V from light-space data the caller made (e.g. [`LightSpace::build`] with the
    /// CPU twin's request, or the CPU twin's own maps): its view and layer 0 are uploaded (and
    /// encoded on the GPU under `depth=unorm16`) instead of built, so both twins can see identical
    /// data. Replaces the report. Errors: `v` not one per receiver, an upload the device refuses.
    pub fn estimate_with(
        &mut self,
        ls: &LightSpace,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        let depth = MapSettings::from_params(&self.params)?.depth;
        self.run_uploaded(light, receivers, v, |e| {
            GpuMaps::upload(&e.ctx, ls, depth, e.builder.encoder(&e.ctx)?)
        })
    }

    /// Estimates V from the view of `ls` and CPU 16-bit codes uploaded as they are (e.g. the CPU
    /// twin's [`unorm16`](crate::map_estimator::MapEstimator::unorm16) map), so both twins can
    /// see identical codes. Replaces the report. Errors: as [`estimate_with`](Self::estimate_with).
    pub fn estimate_with_unorm16(
        &mut self,
        ls: &LightSpace,
        map: &Unorm16Map,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        self.run_uploaded(light, receivers, v, |e| {
            GpuMaps::upload_unorm16(&e.ctx, ls, map)
        })
    }

    /// The common part of `estimate_with*`: a fresh report, the upload timed, then [`run`](Self::run).
    fn run_uploaded(
        &mut self,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
        upload: impl FnOnce(&Self) -> Result<GpuMaps>,
    ) -> Result<()> {
        receivers.check_output(v)?;
        self.report = Report::default();
        let t = Instant::now();
        let maps = upload(self)?;
        self.report
            .stages
            .push(("upload".into(), t.elapsed().as_secs_f64() * 1e3));
        self.report.light_space_bytes = maps.bytes();
        self.run(&maps, light, receivers, v)
    }

    /// Runs the kernel over all receivers and appends stages and notes to the report (as the
    /// CPU twin's `estimate` does).
    fn run(
        &mut self,
        maps: &GpuMaps,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        self.cancel.check()?;
        let settings = MapSettings::from_params(&self.params)?;
        let (b0, b1) = settings.biases();
        let mut u = EstimateUniform::new(light, b0, b1);
        u.receiver_plane = u32::from(settings.receiver_plane);
        F::from_params(&self.params)?.set_uniform(&mut u);
        u.depth_step = maps.depth.step();
        self.kernel(maps.depth.precision())?;
        let stats = self.dispatch(maps, &u, receivers, v)?;
        let view = &maps.view;
        self.report
            .stages
            .push(("estimate".into(), stats.estimate_ms));
        if stats.cut > 0 {
            let t = Instant::now();
            self.redo_cut(maps, light, receivers, v, stats.cut)?;
            self.report.stages.push((
                "estimate: CPU fallback".into(),
                t.elapsed().as_secs_f64() * 1e3,
            ));
            self.report.note("loop_limit_cpu_fallbacks", stats.cut);
        }
        self.report
            .stages
            .push(("readback".into(), stats.readback_ms));
        self.report.note("resolution", view.r);
        self.report.note("near", view.n);
        self.report.note("far", view.far);
        self.report
            .note("out_of_frustum", stats.outside + maps.fit.out_of_frustum);
        self.report.note("window_scale", maps.fit.window_scale);
        if let MapDepth::Unorm16(m) = &maps.depth {
            self.report.note("depth_step", m.step);
        }
        self.report.warn(Warning::NonFiniteV {
            receivers: stats.nonfinite,
        });
        self.report.warn(Warning::OutsideViews {
            receivers: stats.outside,
        });
        Ok(())
    }

    /// Re-evaluates the receivers the device's loop budget cut short (flagged with
    /// [`CUT_BITS`](shadow_map_core::gpu::shared::CUT_BITS), `expected` of them as the kernel
    /// counted) with the CPU filter on the map read back from the GPU.
    fn redo_cut(
        &self,
        maps: &GpuMaps,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
        expected: usize,
    ) -> Result<()> {
        let filter = F::from_params(&self.params)?;
        let biases = MapSettings::from_params(&self.params)?.caster_test();
        let ctx = &*self.ctx;
        let cancel = &self.cancel;
        let stage = format!("{} estimate", F::NAME);
        redo_cut_receivers(v, receivers, expected, &stage, |sub, vs| {
            match &maps.depth {
                MapDepth::F32(t) => {
                    let g = shadow_map_core::gpu::GpuDepthMap {
                        size: t.size,
                        texture: t.texture.clone(),
                        view: t.view.clone(),
                    };
                    let map = shadow_map_core::gpu::read_depth_map(ctx, &g)?;
                    filter_all(
                        cancel, &filter, &maps.view, &map, 0.0, light, sub, vs, biases,
                    )?;
                }
                MapDepth::Unorm16(m) => {
                    let map = m.read(ctx)?;
                    let half = map.half_step();
                    filter_all(
                        cancel, &filter, &maps.view, &map, half, light, sub, vs, biases,
                    )?;
                }
            }
            Ok(())
        })?;
        Ok(())
    }

    fn dispatch(
        &self,
        maps: &GpuMaps,
        u: &EstimateUniform,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<RunStats> {
        let mut stats = RunStats {
            outside: 0,
            nonfinite: 0,
            cut: 0,
            estimate_ms: 0.0,
            readback_ms: 0.0,
        };
        if receivers.is_empty() {
            return Ok(stats);
        }
        let ctx = &*self.ctx;
        let label = format!("{} estimate", F::NAME);
        let k = self.kernels[precision_index(maps.depth.precision())]
            .as_ref()
            .ok_or_else(|| Error::Gpu {
                stage: label.clone(),
                reason: "kernel not compiled".into(),
            })?;
        let t = Instant::now();
        let chunk = kernel::max_chunk(ctx, WORKGROUP_SIZE, self.chunk_cap);
        let (chunks, counters) =
            ctx.scoped(&label, || -> Result<(Vec<ReceiverChunk>, wgpu::Buffer)> {
                let view_buf =
                    kernel::uniform(ctx, "light view", &LightViewUniform::from(&maps.view));
                let est_buf = kernel::uniform(ctx, "estimate uniform", u);
                let counters = ctx
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("baselines counters"),
                        contents: bytemuck::cast_slice(&[0u32; 3]),
                        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    });
                let chunks = kernel::upload_receivers(ctx, "baselines", receivers, chunk, false);
                let groups: Vec<wgpu::BindGroup> = chunks
                    .iter()
                    .map(|c| {
                        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                            label: Some(&label),
                            layout: &k.layout,
                            entries: &[
                                entry(0, view_buf.as_entire_binding()),
                                entry(1, est_buf.as_entire_binding()),
                                entry(2, maps.depth.binding()),
                                entry(3, c.receivers.as_entire_binding()),
                                entry(4, c.out.as_entire_binding()),
                                entry(5, counters.as_entire_binding()),
                            ],
                        })
                    })
                    .collect();
                let mut enc = ctx
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some(&label),
                    });
                {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(&label),
                        timestamp_writes: None,
                    });
                    pass.set_pipeline(&k.pipeline);
                    for (c, g) in chunks.iter().zip(&groups) {
                        pass.set_bind_group(0, g, &[]);
                        pass.dispatch_workgroups(c.workgroups(WORKGROUP_SIZE), 1, 1);
                    }
                }
                ctx.queue.submit([enc.finish()]);
                ctx.wait()?;
                Ok((chunks, counters))
            })??;
        stats.estimate_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        kernel::read_v(ctx, &chunks, v)?;
        let c: Vec<u32> = ctx.read_buffer(&counters, 12)?;
        stats.outside = c.first().copied().unwrap_or(0) as usize;
        stats.nonfinite = c.get(1).copied().unwrap_or(0) as usize;
        stats.cut = c.get(2).copied().unwrap_or(0) as usize;
        stats.readback_ms = t.elapsed().as_secs_f64() * 1e3;
        Ok(stats)
    }
}

/// A bind-group entry.
pub(crate) fn entry(binding: u32, resource: wgpu::BindingResource<'_>) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource }
}

impl<F: GpuFilter> SoftShadowEstimator for GpuMapEstimator<F> {
    shadow_map_core::estimator_identity!(F::NAME, F::DESCRIPTION, Gpu, params);
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.params.set(key, value)
    }
    fn set_cancel(&mut self, cancel: Cancel) {
        self.cancel = cancel;
    }
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        self.maps = None;
        let settings = MapSettings::from_params(&self.params)?;
        let (req, opts, depth) = (settings.request(), settings.view, settings.depth);
        let ctx = self.ctx.clone();
        let builder = &self.builder;
        let maps = self.report.time("build", || {
            let gpu_scene = GpuScene::upload(&ctx, scene)?;
            builder.build(
                &ctx,
                &gpu_scene,
                scene,
                receivers,
                MapOrigin::LightCentre,
                &req,
                &opts,
                depth,
            )
        })?;
        self.report.light_space_bytes = maps.bytes();
        self.maps = Some(maps);
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        let maps = shadow_map_core::estimator::built(self.maps.take())?;
        let out = self.run(&maps, scene.light(), receivers, v);
        self.maps = Some(maps);
        out?;
        self.report.warn_all(Warning::opaque_casters(scene));
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}
