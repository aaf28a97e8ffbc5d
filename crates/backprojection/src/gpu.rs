//! wgpu twin of [`CpuBackprojection`] (cargo feature `gpu`, on by default): the same name,
//! description and parameters, and the same light view and request ([`crate::cpu::plan`]).
//!
//! **Build, on the GPU.** The scene is uploaded and rasterised from the light by
//! [`GpuShadowMapper::render_layers`] (peeled layers, midpoint layers and the anchored MSSM of
//! layer 0, all in one submission); the layers are copied into one `R32Float` texture array and
//! the MSSM levels into another (`shadow_map_core::gpu::layout`), the layout `backprojection.wgsl` reads.
//! Nothing is read back. [`GpuBackprojection::set_light_space_on_cpu`] switches to building the
//! maps on the CPU exactly as the CPU twin does and uploading them (what
//! [`GpuBackprojection::estimate_with`] does for given maps), so both twins see identical data.
//!
//! **Estimate.** One compute dispatch per chunk of receivers (`backprojection.wgsl`, one
//! invocation per receiver), modelled on the baselines' GPU twins (`baselines::gpu`).
//!
//! **Receivers on the GPU.** Inside a user's renderer the receivers are already in a GPU buffer
//! (their G-buffer pass) and V is wanted there too: that is the engine path,
//! [`BackprojectionFrame`] (the frame API), which records everything into the caller's command
//! encoder and reads nothing back.
//!
//! The WGSL follows `cpu.rs` and [`crate::math`] step by step in f32. Known differences: the CPU
//! sums the overlap areas in f64, the kernel in Kahan-compensated f32 (about 1e-7 of the light
//! area); the driver may fuse a multiply and an add, which can flip a depth comparison that is a
//! tie to within f32 rounding. The GPU rasteriser's layers match the CPU's up to the ties that
//! `shadow-map-core`'s `tests/gpu_maps.rs` explains (texel centres exactly on an edge).
use crate::cpu::{emitter_bits, plan, CpuBackprojection, Occlusion};
use bytemuck::{Pod, Zeroable};
use shadow_map_core::gpu::kernel::BufferInitExt;
use shadow_map_core::{
    gpu::{
        estimate::{
            EstimateUniform, BITMASK_WGSL, ESTIMATE_HEAD_WGSL, OVERRIDES, SILHOUETTE_SETUP_WGSL,
            WORKGROUP_SIZE,
        },
        kernel::{max_chunk, upload_planes, Binding, Kernel, PlaneArray},
        layout::{GpuLayout, KernelMaps},
        light_space::GpuLightSpace,
        raster::{GpuScene, GpuShadowMapper},
        receivers::RECEIVERS_WGSL,
        shared::{pack_receivers, LightViewUniform},
        GpuContext,
    },
    light_space::LightSpace,
    light_view::LightView,
    Error, Light, Receivers, Report, Result, Scene, SoftShadowEstimator, Warning,
};
use std::{sync::Arc, time::Instant};

mod frame;
pub use frame::BackprojectionFrame;

/// The estimator's own WGSL (appended after the parts in [`SHADER_PARTS`]' head).
pub const BACKPROJECTION_WGSL: &str = include_str!("backprojection.wgsl");

/// The WGSL parts of the kernel, in order.
pub const SHADER_PARTS: [&str; 5] = [
    ESTIMATE_HEAD_WGSL,
    SILHOUETTE_SETUP_WGSL,
    RECEIVERS_WGSL,
    BITMASK_WGSL,
    BACKPROJECTION_WGSL,
];

/// The bit points of `occlusion=bitmask` ([`emitter_bits`]), two per `vec4` (mirrors `BitTable`
/// in `backprojection.wgsl`); zeros when additive.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BitTable {
    /// Bit `k` is `pts[k / 2][2 (k % 2)..][..2]`.
    pub pts: [[f32; 4]; BIT_TABLE_VEC4S],
}

/// `vec4`s of [`BitTable`]: [`shadow_map_core::bitmask::MAX_BITS`]^2 points, two per `vec4`.
pub const BIT_TABLE_VEC4S: usize =
    (shadow_map_core::bitmask::MAX_BITS * shadow_map_core::bitmask::MAX_BITS / 2) as usize;

/// The settings the kernel reads besides the light view and the light (mirrored in
/// `backprojection.wgsl`).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BpUniform {
    /// `Light::half_extent()`.
    pub half: [f32; 2],
    /// Light area `A_L` ([`crate::math::Emitter::area`], f64 rounded to f32; a sphere's
    /// silhouette disk).
    pub area: f32,
    /// Constant receiver bias (texel footprints).
    pub b0: f32,
    /// Slope-scaled receiver bias.
    pub b1: f32,
    /// 1: classify by midpoints; 0: by the receiver bias.
    pub midpoint: u32,
    /// 1: gap filling on.
    pub gap_filling: u32,
    /// Most samples per receiver.
    pub max_nspp: u32,
    /// `sqrt(max_nspp)` as the CPU computes it (correctly rounded).
    pub sqrt_nspp: f32,
    /// Depth layers in the layer texture array.
    pub layers: u32,
    /// Midpoint layers, after the depth layers in the same array.
    pub midpoints: u32,
    /// 1 when the light-space data hold an MSSM.
    pub mssm_present: u32,
    /// MSSM levels (array layers of the MSSM texture).
    pub mssm_levels: u32,
    /// MSSM side in texels.
    pub mssm_size: u32,
    /// 1: `layer_rule=first_nonzero` (Bavoil §4.2); 0: `deepest`.
    pub first_nonzero: u32,
    /// `occlusion=bitmask`: bits `B^2` (in [`BitTable`]); 0: additive.
    pub nbits: u32,
    /// 1: one opacity plane per depth layer follows the midpoints in the layer array
    /// (semi-transparent scenes); 0: every occluder is opaque.
    pub opacity: u32,
    /// The loop-budget probe's trip count, always
    /// [`LOOP_PROBE`](shadow_map_core::gpu::shared::LOOP_PROBE) ([`LOOP_LIMIT`]).
    pub probe: u32,
    /// Padding.
    pub _pad1: u32,
    /// Padding.
    pub _pad2: u32,
}

/// Light-space data on the device in the layout the kernel reads: depth layers then midpoint
/// layers in one texture array, the MSSM min planes in another (a 1x1 dummy when there is none).
struct DeviceMaps {
    view: LightView,
    out_of_frustum: usize,
    window_scale: f32,
    maps: PlaneArray,
    mssm: PlaneArray,
    layers: u32,
    midpoints: u32,
    /// One opacity plane per depth layer follows the midpoints.
    opacity: bool,
    mssm_levels: Option<u32>,
}

impl DeviceMaps {
    fn bytes(&self) -> usize {
        self.maps.bytes + self.mssm.bytes
    }

    /// The arrays of `km` (rendered maps, opaque) in `view`.
    fn laid_out(km: &KernelMaps, view: LightView) -> Self {
        DeviceMaps {
            view,
            out_of_frustum: 0,
            window_scale: 0.0,
            maps: km.maps.clone(),
            mssm: km.mssm.clone(),
            layers: km.layers,
            midpoints: km.midpoints,
            opacity: false,
            mssm_levels: km.mssm_levels,
        }
    }

    /// Uploads light-space data built on the CPU.
    fn upload(ctx: &GpuContext, ls: &LightSpace, midpoint: bool) -> Result<Self> {
        let r = ls.view.r;
        // Layers, then midpoints; a dummy plane keeps the array non-empty.
        let dummy = vec![f32::INFINITY; r as usize * r as usize];
        let mut planes: Vec<&[f32]> = ls.layers.iter().map(|d| d.depth.as_slice()).collect();
        let midpoints = if midpoint { ls.midpoints.len() } else { 0 };
        planes.extend(ls.midpoints[..midpoints].iter().map(|d| d.depth.as_slice()));
        // Semi-transparent scenes: the layers' opacity planes.
        let opacity = !ls.opacity.is_empty();
        planes.extend(ls.opacity.iter().map(Vec::as_slice));
        if planes.is_empty() {
            planes.push(&dummy);
        }
        let maps = upload_planes(ctx, "backprojection layers", r, &planes)?;
        let one = [f32::INFINITY];
        let (mssm_planes, mssm_size): (Vec<&[f32]>, u32) = match &ls.mssm {
            Some(m) if m.levels() > 0 => {
                ((0..m.levels()).map(|l| m.level(l).0).collect(), m.size())
            }
            _ => (vec![&one[..]], 1),
        };
        let mssm = upload_planes(ctx, "backprojection mssm", mssm_size, &mssm_planes)?;
        Ok(DeviceMaps {
            view: ls.view,
            out_of_frustum: ls.fit.out_of_frustum,
            window_scale: ls.fit.window_scale,
            maps,
            mssm,
            layers: ls.layers.len() as u32,
            midpoints: midpoints as u32,
            opacity,
            mssm_levels: ls.mssm.as_ref().map(|m| m.levels()),
        })
    }
}

/// What one CPU-receivers dispatch returns: receivers outside the light frustum, non-finite
/// results replaced by 0, receivers cut short by the loop budget ([`LOOP_LIMIT`]), and the
/// estimate's and readback's milliseconds.
#[derive(Debug, Default)]
struct Dispatched {
    outside: usize,
    nonfinite: usize,
    cut: usize,
    est_ms: f64,
    read_ms: f64,
}

/// Why a receiver can come back flagged: some devices bound the loop iterations of one shader
/// invocation (llvmpipe, i.e. lavapipe, ends every loop once 65535 iterations in all have run),
/// which would silently truncate a large kernel's walk (`max_nspp` up to 4096 samples, up to 4
/// layers, up to 64 occlusion bits each). The kernel ends with the core's two-trip probe
/// (`loop_limit_hit`): a cut receiver is written as `CUT_BITS` and counted, and
/// [`GpuBackprojection`] redoes it with the CPU twin (`loop_limit_cpu_fallbacks` in the report);
/// the engine path leaves it NaN and counts it in its status.
pub const LOOP_LIMIT: &str = "llvmpipe: 65535 loop iterations per invocation";

/// The GPU twin of [`CpuBackprojection`].
pub struct GpuBackprojection {
    ctx: Arc<GpuContext>,
    cpu: CpuBackprojection,
    kernel: Kernel,
    layout: GpuLayout,
    mapper: Option<GpuShadowMapper>,
    maps: Option<DeviceMaps>,
    light_space_on_cpu: bool,
    report: Report,
    chunk_cap: usize,
    /// Whether the last `build` made the light-space data on the CPU (the loop-limit redo then
    /// reuses them).
    maps_on_cpu: bool,
}

const LABEL: &str = "backprojection estimate";

impl GpuBackprojection {
    /// With default parameters, compiling the kernel on `ctx`'s device.
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self> {
        let kernel = Kernel::new(
            &ctx,
            LABEL,
            &SHADER_PARTS,
            "estimate",
            &[
                Binding::Uniform,
                Binding::Uniform,
                Binding::Uniform,
                Binding::Texture2dArray,
                Binding::Texture2dArray,
                Binding::Storage,
                Binding::StorageRw,
                Binding::StorageRw,
                Binding::Uniform,
            ],
            OVERRIDES,
        )?;
        let layout = GpuLayout::new(&ctx)?;
        Ok(GpuBackprojection {
            ctx,
            cpu: CpuBackprojection::new()?,
            kernel,
            layout,
            mapper: None,
            maps: None,
            light_space_on_cpu: false,
            report: Report::default(),
            chunk_cap: usize::MAX,
            maps_on_cpu: false,
        })
    }

    /// `true`: [`build`](SoftShadowEstimator::build) makes the light-space data on the CPU
    /// exactly as [`CpuBackprojection`] does and uploads them (the CPU twin's maps, at the CPU
    /// raster's cost); `false` (the default): renders them on the GPU. Semi-transparent scenes
    /// take the CPU path either way.
    pub fn set_light_space_on_cpu(&mut self, on: bool) {
        self.light_space_on_cpu = on;
    }

    /// Renders the light-space data for this frame on the GPU and lays them out for the kernel;
    /// one submission, nothing read back.
    fn build_on_gpu(&mut self, scene: &Scene, receivers: &Receivers) -> Result<DeviceMaps> {
        let (view, fit, req) = plan(self.cpu.settings(), scene, receivers)?;
        let ctx = self.ctx.clone();
        let ctx = &*ctx;
        if self.mapper.is_none() {
            self.mapper = Some(GpuShadowMapper::new(ctx)?);
        }
        let Some(mapper) = self.mapper.as_ref() else {
            return Err(Error::Gpu {
                stage: "raster".into(),
                reason: "shadow mapper missing".into(),
            });
        };
        let gpu_scene = GpuScene::upload(ctx, scene)?;
        let gls = mapper.render_layers(ctx, &gpu_scene, &view, &req)?;
        let mut maps = self.lay_out(ctx, &gls)?;
        maps.out_of_frustum = fit.out_of_frustum;
        maps.window_scale = fit.window_scale;
        Ok(maps)
    }

    /// Copies rendered light-space data into the kernel's texture arrays (GPU to GPU).
    fn lay_out(&self, ctx: &GpuContext, gls: &GpuLightSpace) -> Result<DeviceMaps> {
        let km = self.layout.prepare(
            ctx,
            "backprojection",
            gls.view.r,
            &gls.layers,
            &gls.midpoints,
            &[],
            gls.mssm.as_ref(),
        )?;
        ctx.scoped("backprojection layout", || {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("backprojection layout"),
                });
            km.record(&mut enc, false);
            ctx.queue.submit([enc.finish()]);
        })?;
        Ok(DeviceMaps::laid_out(&km, gls.view))
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

    /// Estimates V from light-space data the caller made (as [`CpuBackprojection`] builds them:
    /// layers, midpoints in midpoint mode, MSSM), uploaded instead of built, so both twins can see
    /// identical data. Replaces the report. Errors: `v` not one per receiver, an upload the
    /// device refuses, and the estimate's errors.
    pub fn estimate_with(
        &mut self,
        ls: &LightSpace,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        receivers.check_output(v)?;
        self.report = Report::default();
        let t = Instant::now();
        let midpoint = self.cpu.settings().shadow.midpoint();
        let maps = DeviceMaps::upload(&self.ctx, ls, midpoint)?;
        self.report
            .stages
            .push(("upload".into(), t.elapsed().as_secs_f64() * 1e3));
        let params = self.cpu.params().clone();
        let cancel = self.cpu.cancel().clone();
        self.estimate_maps(&maps, light, receivers, v, |sub, vs| {
            // The CPU twin on the same light-space data.
            let mut cpu = CpuBackprojection::new()?;
            shadow_map_core::estimator::configure(&mut cpu, &params)?;
            cpu.set_cancel(cancel);
            cpu.set_light_space(ls.clone());
            cpu.estimate_light(light, sub, vs)
        })
    }

    /// V from maps already on the device; appends to the report. Receivers the loop budget
    /// cut short ([`LOOP_LIMIT`]) are redone by `redo` (the CPU twin on the same light-space
    /// data, or in the same view), given just those receivers.
    fn estimate_maps(
        &mut self,
        maps: &DeviceMaps,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
        redo: impl FnOnce(&Receivers, &mut [f32]) -> Result<()>,
    ) -> Result<()> {
        receivers.check_output(v)?;
        self.cpu.cancel().check()?;
        let (eu, bpu, table) = self.uniforms(maps, light);
        let Dispatched {
            outside,
            nonfinite,
            cut,
            est_ms,
            read_ms,
        } = self.dispatch(maps, &eu, &bpu, &table, receivers, v)?;
        self.report.stages.push(("estimate".into(), est_ms));
        self.report.stages.push(("readback".into(), read_ms));
        let t = Instant::now();
        let redone = shadow_map_core::gpu::redo_cut_receivers(v, receivers, cut, LABEL, redo)?;
        if redone > 0 {
            self.report.stages.push((
                "estimate: CPU fallback".into(),
                t.elapsed().as_secs_f64() * 1e3,
            ));
            self.report.note("loop_limit_cpu_fallbacks", redone);
        }
        self.note_estimate(maps);
        self.report
            .note("out_of_frustum", outside + maps.out_of_frustum);
        self.report.note("window_scale", maps.window_scale);
        self.report.warn(Warning::NonFiniteV {
            receivers: nonfinite,
        });
        self.report
            .warn(Warning::OutsideViews { receivers: outside });
        self.report.warn(Warning::KernelClipped {
            receivers: shadow_map_core::light_view::beyond_sphere_window(
                &maps.view, light, receivers,
            ),
        });
        Ok(())
    }

    /// The kernel's uniforms for `maps` and the current parameters.
    fn uniforms(&self, maps: &DeviceMaps, light: &Light) -> (EstimateUniform, BpUniform, BitTable) {
        let s = self.cpu.settings();
        let res = s.resolve(maps.opacity);
        let mut table = BitTable::zeroed();
        let mut nbits = 0;
        if res.occlusion == Occlusion::Bitmask {
            let pts = emitter_bits(&crate::math::Emitter::of(&light.shape), s.bits);
            nbits = pts.len() as u32;
            for (k, p) in pts.iter().enumerate() {
                table.pts[k / 2][2 * (k % 2)] = p.x;
                table.pts[k / 2][2 * (k % 2) + 1] = p.y;
            }
        }
        let midpoint = s.shadow.midpoint();
        let h = light.half_extent();
        let max_nspp = s.max_nspp;
        let bpu = BpUniform {
            half: [h.x, h.y],
            area: crate::math::Emitter::of(&light.shape).area() as f32,
            b0: s.shadow.bias,
            b1: s.shadow.slope_bias,
            midpoint: u32::from(midpoint),
            gap_filling: u32::from(res.gap_filling),
            max_nspp,
            sqrt_nspp: (max_nspp as f32).sqrt(),
            layers: maps.layers,
            midpoints: if midpoint { maps.midpoints } else { 0 },
            mssm_present: u32::from(maps.mssm_levels.is_some()),
            mssm_levels: maps.mssm_levels.unwrap_or(0),
            mssm_size: if maps.mssm_levels.is_some() {
                maps.mssm.size
            } else {
                0
            },
            first_nonzero: u32::from(res.first_nonzero),
            nbits,
            opacity: u32::from(maps.opacity),
            probe: shadow_map_core::gpu::shared::LOOP_PROBE,
            _pad1: 0,
            _pad2: 0,
        };
        let mut eu = EstimateUniform::new(light, bpu.b0, bpu.b1);
        eu.receiver_plane = u32::from(s.shadow.receiver_plane);
        (eu, bpu, table)
    }

    /// The report notes both estimate paths share.
    fn note_estimate(&mut self, maps: &DeviceMaps) {
        let view = maps.view;
        let self_shadow = self.cpu.settings().shadow.self_shadow;
        self.report.light_space_bytes = maps.bytes();
        self.report.note("resolution", view.r);
        self.report.note("layers", maps.layers);
        self.report.note("self_shadow", self_shadow);
        let res = self.cpu.settings().resolve(maps.opacity);
        crate::cpu::note_resolved(&mut self.report, self.cpu.settings(), res);
        self.report
            .note("receiver_plane", self.cpu.settings().shadow.receiver_plane);
        self.report.note("near", view.n);
        self.report.note("far", view.far);
    }

    /// CPU receivers: uploads them chunk by chunk (a receiver and a V buffer per chunk, so any
    /// chunk size works), runs [`submit_kernel`](Self::submit_kernel), waits and reads V and the
    /// counters back. Returns (outside the frustum, non-finite replaced, estimate ms, readback
    /// ms).
    fn dispatch(
        &self,
        maps: &DeviceMaps,
        eu: &EstimateUniform,
        bpu: &BpUniform,
        table: &BitTable,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<Dispatched> {
        if receivers.is_empty() {
            return Ok(Dispatched::default());
        }
        let ctx = &*self.ctx;
        let t = Instant::now();
        let chunk = max_chunk(ctx, WORKGROUP_SIZE, self.chunk_cap);
        let packed = pack_receivers(receivers);
        let (parts, counters) = ctx.scoped(LABEL, || {
            let counters = counters_buffer(ctx);
            let parts: Vec<(usize, usize, wgpu::Buffer, wgpu::Buffer)> = packed
                .chunks(chunk)
                .enumerate()
                .map(|(c, part)| {
                    let rec = ctx
                        .device
                        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                            label: Some("backprojection receivers"),
                            contents: bytemuck::cast_slice(part),
                            usage: wgpu::BufferUsages::STORAGE,
                        });
                    let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("backprojection V"),
                        size: (part.len() * 4) as u64,
                        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                        mapped_at_creation: false,
                    });
                    (c * chunk, part.len(), rec, out)
                })
                .collect();
            (parts, counters)
        })?;
        let chunks: Vec<KernelChunk> = parts
            .iter()
            .map(|(_, len, rec, out)| KernelChunk {
                receivers: rec.as_entire_binding(),
                v: out.as_entire_binding(),
                len: *len as u32,
            })
            .collect();
        self.submit_kernel(maps, eu, bpu, table, &chunks, &counters)?;
        ctx.wait()?;
        let est_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        for (start, len, _, out) in &parts {
            let part: Vec<f32> = ctx.read_buffer(out, (*len * 4) as u64)?;
            v[*start..*start + *len].copy_from_slice(&part);
        }
        let c: Vec<u32> = ctx.read_buffer(&counters, 12)?;
        Ok(Dispatched {
            outside: c[0] as usize,
            nonfinite: c[1] as usize,
            cut: c[2] as usize,
            est_ms,
            read_ms: t.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// The dispatch both paths share: one submission with one compute dispatch per chunk
    /// (`backprojection.wgsl`, one invocation per receiver), the kernel writing V bits into each
    /// chunk's V binding and adding to `counters`. Nothing is waited for or read back.
    fn submit_kernel(
        &self,
        maps: &DeviceMaps,
        eu: &EstimateUniform,
        bpu: &BpUniform,
        table: &BitTable,
        chunks: &[KernelChunk],
        counters: &wgpu::Buffer,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        ctx.scoped(LABEL, || {
            let uniform = |label, contents: &[u8]| {
                ctx.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents,
                        usage: wgpu::BufferUsages::UNIFORM,
                    })
            };
            let bufs = KernelUniforms {
                view: uniform(
                    "light view",
                    bytemuck::bytes_of(&LightViewUniform::from(&maps.view)),
                ),
                est: uniform("estimate uniform", bytemuck::bytes_of(eu)),
                bp: uniform("backprojection uniform", bytemuck::bytes_of(bpu)),
                bits: uniform("backprojection bit table", bytemuck::bytes_of(table)),
            };
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(LABEL) });
            self.encode_kernel(&mut enc, &bufs, maps, chunks, counters);
            ctx.queue.submit([enc.finish()]);
        })
    }

    /// Records the kernel's pass into `enc`: one dispatch per chunk, bound to `bufs`.
    fn encode_kernel(
        &self,
        enc: &mut wgpu::CommandEncoder,
        bufs: &KernelUniforms,
        maps: &DeviceMaps,
        chunks: &[KernelChunk],
        counters: &wgpu::Buffer,
    ) {
        let ctx = &*self.ctx;
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(LABEL),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.kernel.pipeline);
        for chunk in chunks.iter().filter(|c| c.len > 0) {
            let group = self.kernel.bind_group(
                ctx,
                LABEL,
                &[
                    bufs.view.as_entire_binding(),
                    bufs.est.as_entire_binding(),
                    bufs.bp.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&maps.maps.view),
                    wgpu::BindingResource::TextureView(&maps.mssm.view),
                    chunk.receivers.clone(),
                    chunk.v.clone(),
                    counters.as_entire_binding(),
                    bufs.bits.as_entire_binding(),
                ],
            );
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(
                (chunk.len as usize).div_ceil(WORKGROUP_SIZE as usize) as u32,
                1,
                1,
            );
        }
    }
}

/// The kernel's four uniforms: the light view, the estimate uniform, [`BpUniform`], the
/// [`BitTable`].
struct KernelUniforms {
    view: wgpu::Buffer,
    est: wgpu::Buffer,
    bp: wgpu::Buffer,
    bits: wgpu::Buffer,
}

/// One chunk of receivers for [`GpuBackprojection::submit_kernel`]: its receiver binding, its V
/// binding (`len` u32) and its length.
struct KernelChunk<'a> {
    receivers: wgpu::BindingResource<'a>,
    v: wgpu::BindingResource<'a>,
    len: u32,
}

/// The kernel's two counters, zeroed: receivers outside the frustum, non-finite results.
fn counters_buffer(ctx: &GpuContext) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("backprojection counters"),
            contents: bytemuck::cast_slice(&[0u32; 3]),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        })
}

impl SoftShadowEstimator for GpuBackprojection {
    shadow_map_core::estimator_identity!(twin of cpu, Gpu);
    /// Builds the light-space data on the GPU (or, after
    /// [`set_light_space_on_cpu`](GpuBackprojection::set_light_space_on_cpu), on the CPU and
    /// uploads them).
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.maps = None;
        self.report = Report::default();
        let t = Instant::now();
        // Semi-transparent scenes need each layer's opacity, which the GPU raster does not
        // write: their light-space data are built on the CPU and uploaded.
        let on_cpu = self.light_space_on_cpu || !scene.is_opaque();
        self.maps_on_cpu = on_cpu;
        let maps = if on_cpu {
            self.cpu.build(scene, receivers)?;
            self.report = self.cpu.report();
            let ls = self
                .cpu
                .light_space()
                .ok_or_else(|| Error::param("build", "CPU light space missing"))?;
            let midpoint = self.cpu.settings().shadow.midpoint();
            let t = Instant::now();
            let maps = DeviceMaps::upload(&self.ctx, ls, midpoint)?;
            self.ctx.wait()?;
            if !self.light_space_on_cpu {
                self.report
                    .note("light_space", "cpu (semi-transparent scene)");
            }
            self.report
                .stages
                .push(("upload".into(), t.elapsed().as_secs_f64() * 1e3));
            maps
        } else {
            let maps = self.build_on_gpu(scene, receivers)?;
            self.ctx.wait()?;
            self.report
                .stages
                .push(("build".into(), t.elapsed().as_secs_f64() * 1e3));
            self.report.note("light_space", "gpu");
            maps
        };
        self.report.light_space_bytes = maps.bytes();
        self.maps = Some(maps);
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        let maps = shadow_map_core::estimator::built(self.maps.take())?;
        let view = maps.view;
        let on_cpu = self.maps_on_cpu;
        let cpu_ls = if on_cpu {
            self.cpu.light_space().cloned()
        } else {
            None
        };
        let params = self.cpu.params().clone();
        let cancel = self.cpu.cancel().clone();
        let out = self.estimate_maps(&maps, scene.light(), receivers, v, |sub, vs| {
            // The CPU twin on the same data when the build was the CPU's, else in the same view
            // (its own raster: equal up to texel-centre ties, tests/gpu_maps.rs).
            let mut cpu = CpuBackprojection::new()?;
            shadow_map_core::estimator::configure(&mut cpu, &params)?;
            cpu.set_cancel(cancel);
            match cpu_ls {
                Some(ls) => cpu.set_light_space(ls),
                None => cpu.build_in_view(scene, receivers, view)?,
            }
            cpu.estimate(scene, sub, vs)
        });
        self.maps = Some(maps);
        out?;
        crate::cpu::warn_bitmask_opacity(&mut self.report, self.cpu.settings(), scene);
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}

#[cfg(test)]
mod tests;
