//! wgpu twin of [`CpuAccumulation`] (cargo feature `gpu`, on by default): the same name,
//! description and parameters, and the same light view and request ([`crate::cpu::plan`]).
//!
//! **Build.** As the backprojection twin: the light-space data (peeled layers, the MSSM for the
//! adaptive kernel) are built on the CPU exactly as [`CpuAccumulation`] builds them and uploaded
//! as two `R32Float` texture arrays, so both twins read identical maps.
//!
//! **Estimate.** One compute dispatch per chunk of receivers (`accumulation.wgsl`, one
//! invocation per receiver). The exact variant keeps its occlusion-bit mask in registers
//! (`array<u32, 8>`, up to 16 x 16 bits). The light patch's hull and bit points are computed on the
//! CPU ([`crate::math::LightPatch::hull_local`], [`crate::math::LightPatch::bit_local`]) and
//! uploaded, so no trigonometry differs between the twins.
//!
//! The WGSL follows `cpu.rs` and [`crate::math`] step by step in f32. Known differences: the
//! facing factor is f32 here and f64 inside the CPU's `front_fraction` (about 1e-7); the driver
//! may fuse a multiply and an add, which can flip a depth comparison, a caster centre on the
//! footprint's edge or a bit on a caster square's edge when it is a tie to within f32 rounding
//! (the twin test explains every such receiver).
use crate::cpu::{
    note_settings, ring_phase, settle_outside, CpuAccumulation, KernelMode, Settings, Variant,
    MAX_BITS,
};
use crate::math::{sun_lift, LightPatch, PatchShape, SphereModel, DISK_BOUNDARY_POINTS};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use shadow_map_core::gpu::kernel::BufferInitExt;
use shadow_map_core::{
    gpu::{
        estimate::{EstimateUniform, BITMASK_WGSL, ESTIMATE_HEAD_WGSL, OVERRIDES, WORKGROUP_SIZE},
        frame::{
            buffer_range, check_buffers, single_view, status_buffer, FrameEstimator, FrameInputs,
        },
        kernel::{max_chunk, upload_planes, Binding, Kernel},
        layout::{GpuLayout, KernelMaps},
        raster::{GpuLayersFrame, GpuShadowMapper},
        receivers::{RECEIVERS_WGSL, RECEIVER_BYTES},
        redo_cut_receivers,
        shared::{pack_receivers, LightViewUniform},
        GpuContext,
    },
    light_space::LightSpace,
    light_view::LightView,
    Error, LightShape, Receivers, Report, Result, Scene, SoftShadowEstimator,
};
use std::{sync::Arc, time::Instant};

/// The estimator's own WGSL (after the parts in [`SHADER_PARTS`]' head).
pub const ACCUMULATION_WGSL: &str = include_str!("accumulation.wgsl");

/// The WGSL parts of the kernel, in order.
pub const SHADER_PARTS: [&str; 4] = [
    ESTIMATE_HEAD_WGSL,
    RECEIVERS_WGSL,
    BITMASK_WGSL,
    ACCUMULATION_WGSL,
];

/// Hull-point slots at the head of the tables buffer (WGSL `HULL_SLOTS`).
pub const HULL_SLOTS: usize = DISK_BOUNDARY_POINTS as usize;

/// The settings the kernel reads besides the light view and the light (mirrors `AccUniform` in
/// `accumulation.wgsl`).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct AccUniform {
    /// `1 / A_L` as [`crate::math::Footprint::new`] computes it.
    pub inv_area: f32,
    /// Hull points used (4 or [`DISK_BOUNDARY_POINTS`]).
    pub n_hull: u32,
    /// Bit-grid side B.
    pub bits: u32,
    /// `B^2`.
    pub nbits: u32,
    /// Kernel size K.
    pub k: u32,
    /// 0 fixed, 1 adaptive, 2 lexels.
    pub kernel: u32,
    /// 0 additive, 1 exact.
    pub variant: u32,
    /// Layers read per tap.
    pub layers: u32,
    /// 1 for a sphere light under the contract's model.
    pub sphere_contract: u32,
    /// 1 for a rectangular patch, 0 for a disk.
    pub patch_rect: u32,
    /// Additive: 1 for the overlap area, 0 for the paper's centre test.
    pub overlap: u32,
    /// Lattice index of texel 0 the adaptive kernel's cells align to, x ([`ring_phase`]).
    pub phase_x: i32,
    /// Rect half extents, or (R, R).
    pub half: [f32; 2],
    /// Constant receiver bias (texel footprints).
    pub b0: f32,
    /// Slope-scaled receiver bias.
    pub b1: f32,
    /// 1 when the light-space data hold an MSSM.
    pub mssm_present: u32,
    /// MSSM levels (array layers of the MSSM texture).
    pub mssm_levels: u32,
    /// MSSM side in texels.
    pub mssm_size: u32,
    /// Lattice index of texel 0, y ([`ring_phase`]).
    pub phase_y: i32,
    /// The loop-limit probe's bound, always
    /// [`LOOP_PROBE`](shadow_map_core::gpu::shared::LOOP_PROBE): a receiver whose kernel runs out
    /// of the device's loop budget comes back flagged and is redone with the CPU code on the same
    /// light-space data (`loop_limit_cpu_fallbacks` in the report).
    pub probe: u32,
    /// 1 for the sun: footprints in [`crate::math::SunFrame`]s.
    pub sun: u32,
    /// The sun: L ([`crate::math::sun_lift`] of the view's far), else 0.
    pub lift: f32,
    /// Padding.
    pub _pad: u32,
}

/// The uniform and the point tables (hull points padded to [`HULL_SLOTS`], then `B^2` bits) for
/// the light-space data `ls`.
pub fn uniform_and_tables(
    s: &Settings,
    shape: &LightShape,
    ls: &LightSpace,
) -> (AccUniform, Vec<[f32; 2]>) {
    let mssm = ls.mssm.as_ref().map(|m| (m.levels(), m.size()));
    uniform_and_tables_in(s, shape, &ls.view, ls.layers.len(), mssm)
}

/// [`uniform_and_tables`] for maps known by their view, their number of layers and their MSSM's
/// `(levels, size)`.
pub fn uniform_and_tables_in(
    s: &Settings,
    shape: &LightShape,
    view: &LightView,
    layers: usize,
    mssm: Option<(u32, u32)>,
) -> (AccUniform, Vec<[f32; 2]>) {
    // One patch for every receiver: the sun's is the disk L above each in its footprint's frame
    // (Footprint::for_light).
    let sun = matches!(shape, LightShape::Directional { .. });
    let lift = if sun { sun_lift(view.far) } else { 0.0 };
    let at = if sun {
        Vec3::new(0.0, 0.0, lift)
    } else {
        Vec3::Z
    };
    let patch = LightPatch::for_receiver(shape, SphereModel::Paper, at);
    let (patch_rect, half) = match patch.shape {
        PatchShape::Rect(h) => (1, [h.x, h.y]),
        PatchShape::Disk(r) => (0, [r, r]),
    };
    let bits = s.bits.min(MAX_BITS);
    let mut tables = vec![[0.0f32; 2]; HULL_SLOTS];
    for k in 0..patch.hull_points() {
        tables[k as usize] = patch.hull_local(k).to_array();
    }
    for k in 0..bits * bits {
        tables.push(patch.bit_local(k % bits, k / bits, bits).to_array());
    }
    let phase = ring_phase(view, s.view.fit);
    let u = AccUniform {
        inv_area: 1.0 / patch.area(),
        n_hull: patch.hull_points(),
        bits,
        nbits: bits * bits,
        k: s.k,
        kernel: match s.kernel {
            KernelMode::Fixed => 0,
            KernelMode::Adaptive => 1,
            KernelMode::Lexels => 2,
        },
        variant: u32::from(s.variant == Variant::Exact),
        layers: (s.peeled_layers() as usize).min(layers).max(1) as u32,
        sphere_contract: u32::from(
            matches!(shape, LightShape::Sphere { .. }) && s.sphere == SphereModel::Contract,
        ),
        patch_rect,
        overlap: u32::from(s.overlap()),
        phase_x: phase[0],
        half,
        b0: s.bias,
        b1: s.slope_bias,
        mssm_present: u32::from(mssm.is_some()),
        mssm_levels: mssm.map_or(0, |m| m.0),
        mssm_size: mssm.map_or(0, |m| m.1),
        phase_y: phase[1],
        probe: shadow_map_core::gpu::shared::LOOP_PROBE,
        sun: u32::from(sun),
        lift,
        _pad: 0,
    };
    (u, tables)
}

/// The GPU twin of [`CpuAccumulation`].
pub struct GpuAccumulation {
    ctx: Arc<GpuContext>,
    cpu: CpuAccumulation,
    kernel: Kernel,
    report: Report,
    chunk_cap: usize,
}

const LABEL: &str = "accumulation estimate";

/// Everything one estimate needs on the device: maps, uniforms, receiver chunks and their bind
/// groups. [`GpuAccumulation::dispatch`] may run many times (benchmarks time it without readback).
pub struct Prepared {
    groups: Vec<(usize, usize, wgpu::BindGroup, wgpu::Buffer)>,
    counters: wgpu::Buffer,
    bytes: usize,
}

impl Prepared {
    /// Light-space bytes on the device.
    pub fn bytes(&self) -> usize {
        self.bytes
    }
}

impl GpuAccumulation {
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
                Binding::Storage,
                Binding::StorageRw,
                Binding::StorageRw,
            ],
            OVERRIDES,
        )?;
        Ok(GpuAccumulation {
            ctx,
            cpu: CpuAccumulation::new()?,
            kernel,
            report: Report::default(),
            chunk_cap: usize::MAX,
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

    /// The CPU twin holding the parameters and, after `build`, the light-space data.
    pub fn cpu(&self) -> &CpuAccumulation {
        &self.cpu
    }

    /// Uploads the maps, uniforms and receivers for [`GpuAccumulation::dispatch`].
    pub fn prepare(
        &self,
        ls: &LightSpace,
        light: &shadow_map_core::Light,
        receivers: &Receivers,
    ) -> Result<Prepared> {
        let ctx = &*self.ctx;
        let s = self.cpu.settings();
        let r = ls.view.r;
        let planes: Vec<&[f32]> = ls.layers.iter().map(|d| d.depth.as_slice()).collect();
        let dummy = vec![f32::INFINITY; r as usize * r as usize];
        let planes = if planes.is_empty() {
            vec![&dummy[..]]
        } else {
            planes
        };
        let maps = upload_planes(ctx, "accumulation layers", r, &planes)?;
        let one = [f32::INFINITY];
        let (mssm_planes, mssm_size): (Vec<&[f32]>, u32) = match &ls.mssm {
            Some(m) if m.levels() > 0 => {
                ((0..m.levels()).map(|l| m.level(l).0).collect(), m.size())
            }
            _ => (vec![&one[..]], 1),
        };
        let mssm = upload_planes(ctx, "accumulation mssm", mssm_size, &mssm_planes)?;
        let (au, tables) = uniform_and_tables(&s, &light.shape, ls);
        let mut eu = EstimateUniform::new(light, s.bias, s.slope_bias);
        eu.receiver_plane = u32::from(s.receiver_plane);
        let chunk = max_chunk(ctx, WORKGROUP_SIZE, self.chunk_cap);
        let packed = pack_receivers(receivers);
        let (groups, counters) = ctx.scoped(LABEL, || {
            let init = |label, contents: &[u8], usage| {
                ctx.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents,
                        usage,
                    })
            };
            let view_buf = init(
                "light view",
                bytemuck::bytes_of(&LightViewUniform::from(&ls.view)),
                wgpu::BufferUsages::UNIFORM,
            );
            let est_buf = init(
                "estimate uniform",
                bytemuck::bytes_of(&eu),
                wgpu::BufferUsages::UNIFORM,
            );
            let acc_buf = init(
                "accumulation uniform",
                bytemuck::bytes_of(&au),
                wgpu::BufferUsages::UNIFORM,
            );
            let tab_buf = init(
                "accumulation tables",
                bytemuck::cast_slice(&tables),
                wgpu::BufferUsages::STORAGE,
            );
            let counters = init(
                "accumulation counters",
                bytemuck::cast_slice(&[0u32; 3]),
                wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            );
            let mut groups = Vec::new();
            for (c, part) in packed.chunks(chunk).enumerate() {
                let rec = init(
                    "accumulation receivers",
                    bytemuck::cast_slice(part),
                    wgpu::BufferUsages::STORAGE,
                );
                let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("accumulation V"),
                    size: (part.len() * 4) as u64,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                let group = self.kernel.bind_group(
                    ctx,
                    LABEL,
                    &[
                        view_buf.as_entire_binding(),
                        est_buf.as_entire_binding(),
                        acc_buf.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&maps.view),
                        wgpu::BindingResource::TextureView(&mssm.view),
                        tab_buf.as_entire_binding(),
                        rec.as_entire_binding(),
                        out.as_entire_binding(),
                        counters.as_entire_binding(),
                    ],
                );
                groups.push((c * chunk, part.len(), group, out));
            }
            (groups, counters)
        })?;
        Ok(Prepared {
            groups,
            counters,
            bytes: maps.bytes + mssm.bytes,
        })
    }

    /// Runs the kernel `repeats` times over every chunk in one submission and waits (no readback).
    /// Returns wall-clock milliseconds from submission to completion.
    pub fn dispatch(&self, prep: &Prepared, repeats: u32) -> Result<f64> {
        let ctx = &*self.ctx;
        let t = Instant::now();
        ctx.scoped(LABEL, || {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(LABEL) });
            enc.clear_buffer(&prep.counters, 0, None);
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(LABEL),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&self.kernel.pipeline);
                for _ in 0..repeats.max(1) {
                    for (_, len, group, _) in &prep.groups {
                        pass.set_bind_group(0, group, &[]);
                        pass.dispatch_workgroups(
                            len.div_ceil(WORKGROUP_SIZE as usize) as u32,
                            1,
                            1,
                        );
                    }
                }
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        ctx.wait()?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }

    /// Estimates V from light-space data the caller made (as [`CpuAccumulation`] builds them), so
    /// both twins can see identical data. Replaces the report.
    pub fn estimate_with(
        &mut self,
        ls: &LightSpace,
        scene: &Scene,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        receivers.check_output(v)?;
        self.report = Report::default();
        if receivers.is_empty() {
            return Ok(());
        }
        let t = Instant::now();
        let prep = self.prepare(ls, scene.light(), receivers)?;
        self.report
            .stages
            .push(("upload".into(), t.elapsed().as_secs_f64() * 1e3));
        self.report.light_space_bytes = prep.bytes;
        let est_ms = self.dispatch(&prep, 1)?;
        self.report.stages.push(("estimate".into(), est_ms));
        let t = Instant::now();
        let ctx = &*self.ctx;
        for (start, len, _, out) in &prep.groups {
            let part: Vec<f32> = ctx.read_buffer(out, (*len * 4) as u64)?;
            v[*start..*start + *len].copy_from_slice(&part);
        }
        let c: Vec<u32> = ctx.read_buffer(&prep.counters, 12)?;
        self.report
            .stages
            .push(("readback".into(), t.elapsed().as_secs_f64() * 1e3));
        // Receivers the device's loop budget cut short: the CPU code on the same data.
        let t = Instant::now();
        let counted = c.get(2).copied().unwrap_or(0) as usize;
        let cpu = &self.cpu;
        let redone = redo_cut_receivers(v, receivers, counted, LABEL, |sub, vs| {
            cpu.estimate_with(ls, scene, sub, vs).map(|_| ())
        })?;
        if redone > 0 {
            self.report.stages.push((
                "estimate: CPU fallback".into(),
                t.elapsed().as_secs_f64() * 1e3,
            ));
            self.report.note("loop_limit_cpu_fallbacks", redone);
        }
        let s = self.cpu.settings();
        note_settings(&mut self.report, &s, ls, scene.light(), receivers, 0);
        self.report
            .warn_all(shadow_map_core::Warning::opaque_casters(scene));
        let nonfinite = c.get(1).copied().unwrap_or(0) as usize;
        if nonfinite > 0 {
            return Err(Error::Receivers(format!(
                "{nonfinite} receivers got a non-finite V (a bug; replaced by 0)"
            )));
        }
        // Lit receivers outside the frustum (counters[0], left NaN): settled as the CPU twin does.
        if c.first().copied().unwrap_or(0) > 0 {
            let t = Instant::now();
            let n = settle_outside(scene, receivers, v)?;
            self.report
                .stages
                .push(("settle".into(), t.elapsed().as_secs_f64() * 1e3));
            self.report.note("settled_without_map", n);
        }
        Ok(())
    }
}

/// Accumulation on the engine path: per frame, recorded into the caller's command
/// encoder from the caller's casters and receiver buffer, V into the caller's buffer, with no
/// submit, no wait and no readback ([`FrameEstimator`]).
///
/// A frame records the depth-peeling passes (the exact variant's layers), the anchored MSSM of
/// layer 0 for the adaptive kernel (every level up to `ceil(log2 r)`, at most
/// [`MAX_MSSM_LEVEL`](crate::cpu::MAX_MSSM_LEVEL), allocated once: the minimum query is exact
/// whatever the number of levels), the copies into the kernel's texture arrays
/// ([`shadow_map_core::gpu::layout`]) and the kernel over `count` receivers in one dispatch. The
/// status holds the kernel's three counters: lit receivers outside the light frustum (left NaN:
/// the CPU twin settles them by ray casting, which the frame path cannot; fit the view to the
/// receivers, or to bounds holding them, and there are none), non-finite results (written as 0),
/// receivers cut by the device's loop budget (`CUT_BITS` in V, not redone on the CPU).
pub struct AccumulationFrame {
    gpu: GpuAccumulation,
    layers: GpuLayersFrame,
    km: KernelMaps,
    acc: wgpu::Buffer,
    est: wgpu::Buffer,
    tables: wgpu::Buffer,
    status: wgpu::Buffer,
}

impl AccumulationFrame {
    /// Compiles the pipelines and allocates the layers, the kernel's texture arrays, the
    /// uniforms and the status buffer for the parameters `params` (a table of accumulation's
    /// specs). Errors: the parameters' own; device limits as [`Error::Limit`].
    pub fn prepare(ctx: Arc<GpuContext>, params: &shadow_map_core::Params) -> Result<Self> {
        let mut gpu = GpuAccumulation::new(ctx.clone())?;
        shadow_map_core::estimator::configure(&mut gpu, params)?;
        let s = gpu.cpu.settings();
        let r = s.resolution;
        let levels = (r as f32)
            .log2()
            .ceil()
            .clamp(1.0, crate::cpu::MAX_MSSM_LEVEL as f32) as u32;
        let req = shadow_map_core::LightSpaceRequest {
            resolution: r,
            layers: s.peeled_layers().max(1),
            midpoints: None,
            mssm_levels: (s.kernel == KernelMode::Adaptive).then_some(levels),
            dual_mssm_levels: None,
            pyramid: false,
            raster: shadow_map_core::RasterOptions::default(),
            opacity: false,
        };
        let layers = GpuShadowMapper::new(&ctx)?.layers_frame(&ctx, r, &req)?;
        let km = GpuLayout::new(&ctx)?.prepare(
            &ctx,
            "accumulation",
            r,
            layers.layers(),
            &[],
            &[],
            layers.min_max().mssm.as_ref(),
        )?;
        let buffer = |label, size: usize, usage| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let uniform = wgpu::BufferUsages::UNIFORM;
        let est = buffer(
            "estimate uniform",
            std::mem::size_of::<EstimateUniform>(),
            uniform,
        );
        let acc = buffer(
            "accumulation uniform",
            std::mem::size_of::<AccUniform>(),
            uniform,
        );
        let max_points = HULL_SLOTS + (MAX_BITS * MAX_BITS) as usize;
        let tables = buffer(
            "accumulation tables",
            8 * max_points,
            wgpu::BufferUsages::STORAGE,
        );
        let status = status_buffer(&ctx, "accumulation frame status", 3);
        Ok(AccumulationFrame {
            gpu,
            layers,
            km,
            acc,
            est,
            tables,
            status,
        })
    }
}

impl AccumulationFrame {
    /// The maps the last submitted frame rendered, in `view` (the frame's): what a test reads
    /// back ([`GpuLightSpace::to_cpu`](shadow_map_core::gpu::GpuLightSpace::to_cpu)) to run the
    /// CPU twin on the very maps the kernel read.
    pub fn light_space(&self, view: &LightView) -> shadow_map_core::gpu::GpuLightSpace {
        self.layers.light_space(view)
    }
}

impl FrameEstimator for AccumulationFrame {
    fn name(&self) -> &'static str {
        "accumulation"
    }

    /// The view the estimator's own `build` fits for `receivers` ([`plan`](crate::cpu::plan)).
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.gpu.ctx.check_lost()?;
        let s = self.gpu.cpu.settings();
        let (view, _, _) = crate::cpu::plan(scene, receivers, &s, s.resolution)?;
        Ok(vec![Some(view)])
    }

    /// Three u32: lit receivers outside the light frustum (left NaN), non-finite results
    /// (written as 0), receivers cut by the device's loop budget (`CUT_BITS` in V).
    fn light_space_bytes(&self) -> usize {
        self.layers.bytes()
    }

    fn status(&self) -> Option<&wgpu::Buffer> {
        Some(&self.status)
    }

    /// Receivers outside the one frustum are left NaN (for the caller to settle or redo), as
    /// are those the loop budget cut.
    fn decode_status(&self, words: &[u32]) -> shadow_map_core::gpu::frame::FrameStatus {
        let w = |k: usize| words.get(k).copied().unwrap_or(0);
        shadow_map_core::gpu::frame::FrameStatus {
            outside: 0,
            nonfinite: w(1),
            left_nan: w(0) + w(2),
        }
    }

    /// The layers (and MSSM) rendered in the one view, laid out, then the kernel.
    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let view = single_view(inputs.views)?;
        let n = inputs.count as u64;
        check_buffers(&self.gpu.ctx, inputs.receivers, inputs.v, n)?;
        let ctx = &*self.gpu.ctx;
        let queue = &ctx.queue;
        inputs.mark(enc, "start");
        self.layers.encode(queue, enc, inputs.casters, view, 0.0)?;
        inputs.mark(enc, "layers");
        self.km.record(enc, false);
        inputs.mark(enc, "layout");
        let s = self.gpu.cpu.settings();
        let mssm = self.km.mssm_levels.map(|l| (l, self.km.mssm.size));
        let (au, tables) =
            uniform_and_tables_in(&s, &inputs.light.shape, view, self.km.layers as usize, mssm);
        let mut eu = EstimateUniform::new(inputs.light, s.bias, s.slope_bias);
        eu.receiver_plane = u32::from(s.receiver_plane);
        queue.write_buffer(&self.est, 0, bytemuck::bytes_of(&eu));
        queue.write_buffer(&self.acc, 0, bytemuck::bytes_of(&au));
        queue.write_buffer(&self.tables, 0, bytemuck::cast_slice(&tables));
        enc.clear_buffer(&self.status, 0, None);
        if n == 0 {
            return Ok(());
        }
        let group = self.gpu.kernel.bind_group(
            ctx,
            LABEL,
            &[
                self.layers.view_uniform().as_entire_binding(),
                self.est.as_entire_binding(),
                self.acc.as_entire_binding(),
                wgpu::BindingResource::TextureView(&self.km.maps.view),
                wgpu::BindingResource::TextureView(&self.km.mssm.view),
                self.tables.as_entire_binding(),
                buffer_range(inputs.receivers, n * RECEIVER_BYTES),
                buffer_range(inputs.v, n * 4),
                self.status.as_entire_binding(),
            ],
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(LABEL),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.gpu.kernel.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(inputs.count.div_ceil(WORKGROUP_SIZE), 1, 1);
        drop(pass);
        inputs.mark(enc, "estimate");
        Ok(())
    }

    fn caster_passes(&self, _views: &[Option<LightView>]) -> u32 {
        self.layers.passes()
    }

    /// [`CpuAccumulation::build_in_view`], then its estimate (outside receivers settled).
    fn cpu_twin(
        &self,
        scene: &Scene,
        receivers: &Receivers,
        views: &[Option<LightView>],
    ) -> Result<Vec<f32>> {
        let mut cpu = CpuAccumulation::new()?;
        shadow_map_core::estimator::configure(&mut cpu, self.gpu.cpu.params())?;
        cpu.build_in_view(scene, receivers, *single_view(views)?)?;
        let mut v = vec![0.0; receivers.len()];
        cpu.estimate(scene, receivers, &mut v)?;
        Ok(v)
    }
}

impl SoftShadowEstimator for GpuAccumulation {
    shadow_map_core::estimator_identity!(twin of cpu, Gpu);
    /// Builds the light-space data on the CPU, exactly as [`CpuAccumulation`] does.
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        // The device first: a lost one, or a resolution its texture arrays cannot hold, is
        // refused before the CPU builds anything.
        self.ctx.check_lost()?;
        self.ctx.check_resolution(self.cpu.settings().resolution)?;
        self.cpu.build(scene, receivers)?;
        self.report = self.cpu.report();
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        self.cpu.cancel().check()?;
        let build = self.report.clone();
        let ls = shadow_map_core::estimator::built(self.cpu.light_space().cloned())?;
        let out = self.estimate_with(&ls, scene, receivers, v);
        let mut stages = build.stages;
        stages.append(&mut self.report.stages);
        self.report.stages = stages;
        out
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shadow_map_core::gpu::kernel::shader_source;
    use test_support::wgsl::assert_shaders_valid;

    #[test]
    fn shader_validates_with_naga() {
        assert_shaders_valid([("accumulation", shader_source(&SHADER_PARTS))]);
    }

    #[test]
    fn uniform_layout_matches_wgsl() {
        test_support::assert_wgsl_layout!(
            shader_source(&SHADER_PARTS),
            AccUniform {
                inv_area,
                n_hull,
                bits,
                nbits,
                k,
                kernel,
                variant,
                layers,
                sphere_contract,
                patch_rect,
                overlap,
                phase_x,
                half,
                b0,
                b1,
                mssm_present,
                mssm_levels,
                mssm_size,
                phase_y,
                probe,
                sun,
                lift,
            },
            pad _pad: 1
        );
    }
}
