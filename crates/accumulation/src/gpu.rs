//! Accumulation on the GPU (cargo feature `gpu`, on by default): [`AccumulationFrame`], the
//! engine path, which is also the registry's GPU estimator (run by the core's `FrameTwin`). It
//! takes [`CpuAccumulation`]'s parameters and fits its light view and request
//! ([`crate::cpu::plan`]).
//!
//! **Build.** The frame rasterises the light-space data on the device: the peeled layers (the
//! exact variant's) and, for the adaptive kernel, the anchored MSSM of layer 0.
//!
//! **Estimate.** One compute dispatch over the receivers (`accumulation.wgsl`, one invocation
//! per receiver). The exact variant keeps its occlusion-bit mask in registers (`array<u32, 8>`,
//! up to 16 x 16 bits).
//!
//! **Work per receiver**, the CPU twin's: the kernel's bounds refined on the MSSM (a receiver
//! whose kernel holds no caster in front of it stops there), then the kernel's cells (rings,
//! fixed or lexel blocks), each a depth fetch and a caster test per layer, and each caster found
//! its term (overlap, centre or occlusion bits). The kernel walks the cells in one flat loop.
//! Where a term is costly (a disk patch's clipped quad, the exact variant's bits) that loop only
//! finds casters and queues up to 16, then sums their terms in a loop of its own in the same
//! order: on lavapipe a loop's body costs as much on a trip no lane needs, so the costly terms
//! are kept out of the loop over the cells; a rect patch's additive term is cheaper than the
//! queue and is summed in place (`QUEUE_TERMS`). The settings and the light's shape are the
//! pipeline's override constants ([`specialization`]), so the kernel holds only the branches it
//! takes (measured in docs/gpu.md). The light patch's hull and bit points are computed on the CPU
//! ([`crate::math::LightPatch::hull_local`], [`crate::math::LightPatch::bit_local`]) and uploaded,
//! so no trigonometry differs from the CPU twin.
//!
//! The WGSL follows `cpu.rs` and [`crate::math`] step by step in f32. Known differences on the
//! same maps: the facing factor is f32 here and f64 inside the CPU's `front_fraction` (about
//! 1e-7); the driver may fuse a multiply and an add, which can flip a depth comparison, a caster
//! centre on the footprint's edge or a bit on a caster square's edge when it is a tie to within
//! f32 rounding (the conformance test explains every such receiver).
use crate::cpu::{ring_phase, CpuAccumulation, MAX_BITS};
use crate::math::{sun_lift, LightPatch, PatchShape, DISK_BOUNDARY_POINTS};
use crate::settings::{KernelMode, Settings, SphereModel, Variant};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use shadow_map_core::{
    gpu::{
        estimate::{EstimateUniform, BITMASK_WGSL, ESTIMATE_HEAD_WGSL, OVERRIDES},
        frame::{
            check_buffers, cpu_twin_v, single_view, status_buffer, FrameEstimator, FrameInputs,
            Views,
        },
        kernel::{BindGroupCache, SpecializedKernel},
        layout::ViewMaps,
        receivers::RECEIVERS_WGSL,
        receivers::{ActiveLists, ListKind},
        settle::{GpuSettler, OPEN_WGSL},
        GpuContext,
    },
    light_view::LightView,
    LightShape, Params, Receivers, Result, Scene, SoftShadowEstimator,
};
use std::sync::Arc;

/// The estimator's own WGSL (after the parts in [`SHADER_PARTS`]' head).
pub const ACCUMULATION_WGSL: &str = include_str!("accumulation.wgsl");

/// The WGSL parts of the kernel, in order.
pub const SHADER_PARTS: [&str; 5] = [
    ESTIMATE_HEAD_WGSL,
    RECEIVERS_WGSL,
    BITMASK_WGSL,
    ACCUMULATION_WGSL,
    OPEN_WGSL,
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
    /// of the device's loop budget comes back flagged (`CUT_BITS` in V) and counted in the
    /// frame's status, for the caller to redo on the CPU.
    pub probe: u32,
    /// 1 for the sun: footprints in [`crate::math::SunFrame`]s.
    pub sun: u32,
    /// The sun: L ([`crate::math::sun_lift`] of the view's far), else 0.
    pub lift: f32,
    /// Padding.
    pub _pad: u32,
}

/// The kernel's override constants (the core's `LIGHT_SHAPE`, `accumulation.wgsl`'s
/// `PATCH_RECT` to `LAYERS`) for the switches of `eu` and `u`: the kernel branches on these,
/// never on the uniforms' fields.
pub fn specialization(eu: &EstimateUniform, u: &AccUniform) -> [(&'static str, f64); 8] {
    [
        eu.shape_switch(),
        ("PATCH_RECT", u.patch_rect as f64),
        ("SUN", u.sun as f64),
        ("SPHERE_CONTRACT", u.sphere_contract as f64),
        ("EXACT", u.variant as f64),
        ("OVERLAP", u.overlap as f64),
        ("KERNEL_MODE", u.kernel as f64),
        ("LAYERS", u.layers as f64),
    ]
}

fn kernel_mode(k: KernelMode) -> u32 {
    match k {
        KernelMode::Fixed => 0,
        KernelMode::Adaptive => 1,
        KernelMode::Lexels => 2,
    }
}

/// The uniform and the point tables (hull points padded to [`HULL_SLOTS`], then `B^2` bits) for
/// maps in `view` with `layers` peeled layers and an MSSM of `(levels, size)`, if any.
pub fn uniform_and_tables(
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
        kernel: kernel_mode(s.kernel),
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

const LABEL: &str = "accumulation estimate";

/// Accumulation on the engine path: per frame, recorded into the caller's command
/// encoder from the caller's casters and receiver buffer, V into the caller's buffer, with no
/// submit, no wait and no readback ([`FrameEstimator`]). The registry runs it as the method's
/// GPU estimator too (the core's `FrameTwin`, which redoes the receivers it leaves NaN with
/// [`FrameEstimator::cpu_twin`]).
///
/// A frame records the depth-peeling passes (the exact variant's layers), the anchored MSSM of
/// layer 0 for the adaptive kernel (every level up to `ceil(log2 r)`, at most
/// [`MAX_MSSM_LEVEL`](crate::cpu::MAX_MSSM_LEVEL), allocated once: the minimum query is exact
/// whatever the number of levels), the copies into the kernel's texture arrays
/// ([`shadow_map_core::gpu::layout`]), the kernel over each range's active receivers, and the
/// settle passes over the lit receivers outside the light frustum ([`GpuSettler`]: the facing
/// fraction where no caster triangle lies in the receiver's light pyramid, as the CPU twin's
/// `settle_outside`). The status holds four counters: lit receivers outside the frustum,
/// non-finite results (written as 0), receivers cut by the device's loop budget (`CUT_BITS` in
/// V, left for the caller to redo), outside receivers something may shadow (left NaN: the CPU
/// twin refuses them).
pub struct AccumulationFrame {
    ctx: Arc<GpuContext>,
    /// The parameters, as the CPU twin holds them (validated by it at `prepare`).
    params: Params,
    settings: Settings,
    kernel: SpecializedKernel,
    /// The layers and MSSM, laid out for the kernel.
    maps: ViewMaps,
    acc: wgpu::Buffer,
    est: wgpu::Buffer,
    tables: wgpu::Buffer,
    status: wgpu::Buffer,
    /// Each range's active receivers, listed every frame: the kernel runs over them only.
    active: ActiveLists,
    /// The outside receivers' settle passes.
    settler: GpuSettler,
    groups: BindGroupCache,
}

impl AccumulationFrame {
    /// Compiles the pipelines and allocates the layers, the kernel's texture arrays, the
    /// uniforms and the status buffer for the parameters `params` (a table of accumulation's
    /// specs). Errors: the parameters' own; device limits as [`Error::Limit`](shadow_map_core::Error::Limit).
    pub fn prepare(ctx: Arc<GpuContext>, params: &Params) -> Result<Self> {
        let mut cpu = CpuAccumulation::new()?;
        shadow_map_core::estimator::configure(&mut cpu, params)?;
        let s = cpu.settings();
        let kernel = SpecializedKernel::new(&ctx, LABEL, &SHADER_PARTS, "estimate", OVERRIDES)?;
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
        let maps = ViewMaps::prepare(&ctx, "accumulation", &req)?;
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
        let status = status_buffer(&ctx, "accumulation frame status", 4);
        Ok(AccumulationFrame {
            active: ActiveLists::new(&ctx)?,
            settler: GpuSettler::new(&ctx)?,
            groups: BindGroupCache::default(),
            ctx,
            params: cpu.params().clone(),
            settings: s,
            kernel,
            maps,
            acc,
            est,
            tables,
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

impl FrameEstimator for AccumulationFrame {
    fn name(&self) -> &'static str {
        "accumulation"
    }

    /// The view the estimator's own `build` fits for `receivers` ([`plan`](crate::cpu::plan)).
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>> {
        self.ctx.check_lost()?;
        let s = &self.settings;
        let (view, _, _) = crate::cpu::plan(scene, receivers, s, s.resolution)?;
        Ok(vec![Some(view)])
    }

    /// The peeled layers' and the MSSM's device bytes.
    fn light_space_bytes(&self) -> usize {
        self.maps.layers.bytes()
    }

    /// Four u32: lit receivers outside the light frustum, non-finite results (written as 0),
    /// receivers cut by the device's loop budget (`CUT_BITS` in V), outside receivers left NaN.
    fn status(&self) -> Option<&wgpu::Buffer> {
        Some(&self.status)
    }

    /// The layers (and MSSM) rendered in the one view, laid out, then the kernel.
    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()> {
        let view = single_view(inputs.views)?;
        let n = inputs.count as u64;
        check_buffers(&self.ctx, inputs.receivers, inputs.v, n)?;
        let ctx = &*self.ctx;
        self.groups.next_encode();
        inputs.mark(enc, "start");
        let s = &self.settings;
        // The MSSM levels the widest kernel of this view needs (crate::cpu::request's rule):
        // the levels above only speed up queries no kernel makes, and each costs a pass over
        // r^2 to build and one to copy. The contract's sphere model widens the kernel by the
        // receivers, which the frame does not see: it keeps every level prepared.
        let planes = match (&inputs.light.shape, s.sphere) {
            (LightShape::Sphere { .. }, SphereModel::Contract) => u32::MAX,
            _ => crate::cpu::request(s, view, inputs.light.half_extent()).mssm_planes(),
        };
        self.maps.encode(ctx, enc, inputs, view, 0.0, planes)?;
        let km = &self.maps.km;
        let mssm = km.mssm_levels.map(|l| (l.min(planes), km.mssm.size));
        let (au, tables) =
            uniform_and_tables(s, &inputs.light.shape, view, km.layers as usize, mssm);
        let mut eu = EstimateUniform::new(inputs.light, s.bias, s.slope_bias);
        eu.receiver_plane = u32::from(s.receiver_plane);
        ctx.write_in(enc, &self.est, 0, bytemuck::bytes_of(&eu));
        ctx.write_in(enc, &self.acc, 0, bytemuck::bytes_of(&au));
        ctx.write_in(enc, &self.tables, 0, bytemuck::cast_slice(&tables));
        enc.clear_buffer(&self.status, 0, None);
        if n == 0 {
            return Ok(());
        }
        let switches = specialization(&eu, &au);
        // Under the adaptive kernel, two passes over each range: the first finishes every
        // receiver the MSSM test lights (or that lies outside, behind) and defers the rest,
        // which the second runs over densely. The other kernels have no such test: one pass.
        let mut first = switches.to_vec();
        first.push(("DEFER_CELLS", 1.0));
        let whole = self.kernel.pipeline(ctx, &switches)?;
        let deferring = match au.kernel == kernel_mode(KernelMode::Adaptive) {
            true => Some(self.kernel.pipeline(ctx, &first)?),
            false => None,
        };
        let passes = match &deferring {
            Some(first) => (first, Some((ListKind::Deferred, &whole))),
            None => (&whole, None),
        };
        let ranges = shadow_map_core::gpu::frame::receiver_ranges(ctx, inputs.count);
        let open: Vec<wgpu::Buffer> = ranges
            .iter()
            .enumerate()
            .map(|(index, &range)| self.settler.open_list(ctx, enc, index, range))
            .collect();
        // Dispatches per range of receivers (a 4K view is two under the default limits).
        self.active.dispatch_passes(
            ctx,
            enc,
            LABEL,
            passes,
            inputs.count,
            (inputs.receivers, inputs.v),
            |index, range, list| {
                self.groups.get_dense(
                    ctx,
                    LABEL,
                    &self.kernel.layout,
                    &[
                        self.maps.layers.view_uniform().as_entire_binding(),
                        self.est.as_entire_binding(),
                        self.acc.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&km.maps.view),
                        wgpu::BindingResource::TextureView(&km.mssm.view),
                        self.tables.as_entire_binding(),
                        range.receivers(inputs.receivers),
                        range.words(inputs.v),
                        self.status.as_entire_binding(),
                        list.as_entire_binding(),
                        open[index].as_entire_binding(),
                    ],
                )
            },
        )?;
        inputs.mark(enc, "estimate");
        for (range, list) in ranges.into_iter().zip(&open) {
            self.settler.encode(
                ctx,
                enc,
                (&eu, &self.est),
                inputs.casters,
                range,
                list,
                (inputs.receivers, inputs.v),
                (&self.status, 3),
            )?;
        }
        inputs.mark(enc, "settle");
        Ok(())
    }

    fn caster_passes(&self, _views: &Views) -> u32 {
        self.maps.layers.passes()
    }

    /// [`CpuAccumulation::build_in_view`], then its estimate (outside receivers settled).
    fn cpu_twin(&self, scene: &Scene, receivers: &Receivers, views: &Views) -> Result<Vec<f32>> {
        let view = *single_view(views)?;
        cpu_twin_v(CpuAccumulation::new()?, &self.params, receivers, |e, v| {
            e.build_in_view(scene, receivers, view)?;
            e.estimate(scene, receivers, v)
        })
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
