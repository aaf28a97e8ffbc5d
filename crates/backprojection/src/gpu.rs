//! The GPU implementation of [`CpuBackprojection`](crate::CpuBackprojection) (cargo feature
//! `gpu`, on by default): its engine path, [`BackprojectionFrame`], which the registry also runs
//! as its GPU estimator (the core's `FrameTwin`, through [`DESCRIPTOR`](crate::DESCRIPTOR)).
//! A frame records depth peeling, midpoints, the anchored MSSM of layer 0, the copies into the
//! kernel's texture arrays (`shadow_map_core::gpu::layout`) and the kernel into the caller's
//! command encoder; this module holds what the kernel reads: its WGSL and its uniforms.
//!
//! The WGSL follows `cpu.rs` and [`crate::math`] step by step in f32. Known differences: the CPU
//! sums the overlap areas in f64, the kernel in Kahan-compensated f32 (about 1e-7 of the light
//! area); the driver may fuse a multiply and an add, which can flip a depth comparison that is a
//! tie to within f32 rounding. The GPU rasteriser's layers match the CPU's up to the ties that
//! `shadow-map-core`'s `tests/gpu_maps.rs` explains (texel centres exactly on an edge).
use crate::math::{emitter_bits, Emitter};
use crate::settings::{Occlusion, Settings};
use bytemuck::{Pod, Zeroable};
use shadow_map_core::{
    gpu::{
        estimate::{
            EstimateUniform, BITMASK_WGSL, CELLS_WGSL, ESTIMATE_HEAD_WGSL, OVERRIDES,
            SILHOUETTE_SETUP_WGSL,
        },
        kernel::{BindGroupCache, SpecializedKernel},
        layout::KernelMaps,
        receivers::RECEIVERS_WGSL,
        receivers::{ActiveLists, ListKind},
        GpuContext,
    },
    Light, Result,
};

mod frame;
pub use frame::BackprojectionFrame;

/// The estimator's own WGSL (appended after the parts in [`SHADER_PARTS`]' head).
pub const BACKPROJECTION_WGSL: &str = include_str!("backprojection.wgsl");

/// The WGSL parts of the kernel, in order (the Kahan `Sum` comes from the core's cells part).
pub const SHADER_PARTS: [&str; 6] = [
    ESTIMATE_HEAD_WGSL,
    CELLS_WGSL,
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
    /// [`LOOP_PROBE`](shadow_map_core::gpu::shared::LOOP_PROBE) (receivers cut short by a
    /// device's loop budget: see [`BackprojectionFrame`]).
    pub probe: u32,
    /// Padding.
    pub _pad1: u32,
    /// Padding.
    pub _pad2: u32,
}

/// The kernel's pipeline (`backprojection.wgsl`, one invocation per receiver) and how one
/// dispatch of it is bound and recorded.
struct BpKernel {
    kernel: SpecializedKernel,
    /// Each range's active receivers, listed every frame: the kernel runs over them only.
    active: ActiveLists,
    groups: BindGroupCache,
}

const LABEL: &str = "backprojection estimate";

impl BpKernel {
    /// Compiles the kernel's module on `ctx`'s device (its pipelines at their first encode).
    fn new(ctx: &GpuContext) -> Result<Self> {
        let kernel = SpecializedKernel::new(ctx, LABEL, &SHADER_PARTS, "estimate", OVERRIDES)?;
        Ok(BpKernel {
            kernel,
            active: ActiveLists::new(ctx)?,
            groups: BindGroupCache::default(),
        })
    }

    /// Records the kernel's passes into `enc`: one dispatch per
    /// [`receiver_ranges`](shadow_map_core::gpu::frame::receiver_ranges) range of the
    /// first `count` receivers of `receivers`, V bits into `v`, the counters added to
    /// `counters` (nothing dispatched for no receivers), with the pipeline specialised for
    /// `switches`.
    #[allow(clippy::too_many_arguments)]
    fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        switches: &[(&str, f64)],
        bufs: &KernelUniforms,
        maps: &KernelMaps,
        receivers: &wgpu::Buffer,
        v: &wgpu::Buffer,
        count: u32,
        counters: &wgpu::Buffer,
    ) -> Result<()> {
        // Two passes over each range: the first finishes every receiver whose kernel holds no
        // block loop (lit by the MSSM test, outside, behind) and defers the rest, which the
        // second runs over densely.
        let mut first = switches.to_vec();
        first.push(("DEFER_BLOCKS", 1.0));
        let first = self.kernel.pipeline(ctx, &first)?;
        let second = self.kernel.pipeline(ctx, switches)?;
        self.groups.next_encode();
        self.active.dispatch_passes(
            ctx,
            enc,
            LABEL,
            (&first, Some((ListKind::Deferred, &second))),
            count,
            (receivers, v),
            |_, range, list| {
                self.groups.get_dense(
                    ctx,
                    LABEL,
                    &self.kernel.layout,
                    &[
                        bufs.view.as_entire_binding(),
                        bufs.est.as_entire_binding(),
                        bufs.bp.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&maps.maps.view),
                        wgpu::BindingResource::TextureView(&maps.mssm.view),
                        range.receivers(receivers),
                        range.words(v),
                        counters.as_entire_binding(),
                        bufs.bits.as_entire_binding(),
                        list.as_entire_binding(),
                    ],
                )
            },
        )?;
        Ok(())
    }
}

/// The kernel's override constants (the core's `LIGHT_SHAPE`, `backprojection.wgsl`'s `BITMASK` to `LAYERS`) for the
/// switches of `eu` and `bpu`: the kernel branches on these, never on the uniforms' fields.
fn specialization(eu: &EstimateUniform, bpu: &BpUniform) -> [(&'static str, f64); 9] {
    let flag = |b: bool| f64::from(u8::from(b));
    [
        eu.shape_switch(),
        ("BITMASK", flag(bpu.nbits > 0)),
        ("MIDPOINT", bpu.midpoint as f64),
        ("GAP_FILLING", bpu.gap_filling as f64),
        // A row of blocks is at most max_nspp long at step 1 and ceil(sqrt(max_nspp)) past it.
        (
            "ROW_BUFFER",
            flag(bpu.gap_filling != 0 && bpu.max_nspp <= ROW_BUFFER_LINE),
        ),
        ("FIRST_NONZERO", bpu.first_nonzero as f64),
        ("OPACITY", bpu.opacity as f64),
        ("PLANE_ON", eu.receiver_plane as f64),
        ("LAYERS", bpu.layers as f64),
    ]
}

/// Blocks of one row `backprojection.wgsl` keeps under gap filling (its `LINE`).
const ROW_BUFFER_LINE: u32 = 128;

/// The kernel's four uniforms: the light view, the estimate uniform, [`BpUniform`], the
/// [`BitTable`].
struct KernelUniforms {
    view: wgpu::Buffer,
    est: wgpu::Buffer,
    bp: wgpu::Buffer,
    bits: wgpu::Buffer,
}

/// The kernel's uniforms for the laid-out `maps` (`opacity`: their opacity planes are read, a
/// semi-transparent frame), the settings `s` and `light`.
fn uniforms(
    s: &Settings,
    maps: &KernelMaps,
    opacity: bool,
    light: &Light,
) -> (EstimateUniform, BpUniform, BitTable) {
    let res = s.resolve(opacity);
    let mut table = BitTable::zeroed();
    let mut nbits = 0;
    if res.occlusion == Occlusion::Bitmask {
        let pts = emitter_bits(&Emitter::of(&light.shape), s.bits);
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
        area: Emitter::of(&light.shape).area() as f32,
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
        opacity: u32::from(opacity),
        probe: shadow_map_core::gpu::shared::LOOP_PROBE,
        _pad1: 0,
        _pad2: 0,
    };
    let mut eu = EstimateUniform::new(light, bpu.b0, bpu.b1);
    eu.receiver_plane = u32::from(s.shadow.receiver_plane);
    (eu, bpu, table)
}

#[cfg(test)]
mod tests;
