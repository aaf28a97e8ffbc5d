//! The kernel the engine path ([`crate::gpu`]) runs after its set-up pass, the twin of
//! [`crate::cpu::pixel_value`] in f32 (`packet_hsm.wgsl`, `packet_hsm_passes.wgsl`): `prepare`
//! (one invocation per receiver: the tight kernel from the MSSM, the fully lit / fully occluded
//! classification over the padded dual-grid MSSM, the centre status; a penumbra receiver is
//! queued), then `pixels`, dispatched indirectly with one invocation per queued receiver
//! (per-pixel GBP07: flat scan, or Yang's Algorithm 3 when `hierarchy`). Receivers in a buffer
//! carry no image layout, so the GPU has no packets.
//!
//! Work per receiver, beside the CPU twin's ([`crate::cpu`]): the same kernel search, trivial
//! classification and centre status; a penumbra receiver then visits the nodes the CPU's
//! per-pixel walk visits, in the same order (roots row-major, children row-major), and sums the
//! same cells' edge terms in that order. Where the CPU walks with a stack, the kernel walks
//! without one, along each root's Morton code (a node after a pruned subtree or a cell is the
//! next code at the highest level it is aligned to), so a lane holds three integers, not a
//! stack in private memory. Nodes starting outside the kernel cost a step and no fetch. The
//! pruning bound on a node's true depths is four taps of the anchored MSSM at the node's level,
//! which may be lower than the CPU's exact query: a node is then walked into and its cells
//! add nothing (V unchanged). A cell's contour edges, the Liang-Barsky clip and a rect sector's
//! corner order take no loop (on lavapipe every loop trip costs its full price, needed by a
//! lane or not, and counts against the invocation's budget, [`LOOP_LIMIT`]). A walk takes at
//! most [`WALK_BUDGET`] steps a round; a longer one is re-queued with its place for the next
//! round, so the long tail runs in later rounds with full workgroups. The CPU groups
//! pixels into packets (Yang §4.1) and extracts a coherent packet's contour once; the GPU does
//! not, so it walks more nodes per receiver than the CPU's `visited_per_penumbra_pixel` says.
//!
//! Known differences from the CPU: f32 light-plane geometry and sums (f64 on the CPU), a
//! backprojection gap floored at `1e-7 z_p` (CPU: `1e-12 z_p`), the cell-boundary nudge added
//! in f32; the receiver plane's caster test is the same product and comparison in f32 (a fused
//! multiply-add can flip a tie).
use crate::math::radial::Emitter;
use crate::settings::Config;
use bytemuck::{Pod, Zeroable};
use shadow_map_core::{
    gpu::{
        kernel::{BindGroupCache, SpecializedKernel},
        GpuContext,
    },
    LightView, Result,
};
use std::sync::Arc;

/// The kernel's own WGSL: bindings, helpers, contour cells and radial integration.
pub const PACKET_HSM_WGSL: &str = include_str!("../packet_hsm.wgsl");
/// The kernel's entry points (`prepare`, `pixels`), after [`PACKET_HSM_WGSL`].
pub const PACKET_HSM_PASSES_WGSL: &str = include_str!("../packet_hsm_passes.wgsl");
/// [`RecIn`] in WGSL, which the kernel reads and the frame's set-up pass writes.
pub const REC_IN_WGSL: &str = include_str!("../rec_in.wgsl");
/// The WGSL parts of the kernel, in order: the core's disk edge term
/// ([`DISK_EDGE_WGSL`](shadow_map_core::gpu::estimate::DISK_EDGE_WGSL)) and silhouette carry
/// ([`SILHOUETTE_WGSL`](shadow_map_core::gpu::estimate::SILHOUETTE_WGSL)), [`REC_IN_WGSL`], then
/// [`PACKET_HSM_WGSL`] and [`PACKET_HSM_PASSES_WGSL`].
pub const SHADER_PARTS: [&str; 5] = [
    shadow_map_core::gpu::estimate::DISK_EDGE_WGSL,
    shadow_map_core::gpu::estimate::SILHOUETTE_WGSL,
    REC_IN_WGSL,
    PACKET_HSM_WGSL,
    PACKET_HSM_PASSES_WGSL,
];

/// [`HsmUniform::shape`] of a rect (sub-)light.
pub const SHAPE_RECT: u32 = 0;
/// [`HsmUniform::shape`] of a disk light (radius `hx`).
pub const SHAPE_DISK: u32 = 1;
/// [`HsmUniform::shape`] of a sphere light (radius `hx`; [`RecIn`]'s silhouette).
pub const SHAPE_SPHERE: u32 = 2;

/// The kernel's uniform for one view (mirrors `HsmUniform` in `packet_hsm.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct HsmUniform {
    /// Shadow-map side r.
    pub r: u32,
    /// Padded side r + 2 of the dual-grid MSSM.
    pub padded: u32,
    /// Anchored MSSM levels the view reads.
    pub mssm_levels: u32,
    /// Dual-grid MSSM levels the view reads.
    pub dual_levels: u32,
    /// `alpha = n r / w`.
    pub alpha: f32,
    /// Near plane n.
    pub n: f32,
    /// `k = w / (n r)` (texel pitch over n).
    pub k: f32,
    /// 1: hierarchical extraction.
    pub hierarchy: u32,
    /// Sub-light half extent x.
    pub hx: f32,
    /// Sub-light half extent y.
    pub hy: f32,
    /// Steps of a receiver's walk one round of `pixels` takes at most ([`WALK_BUDGET`]).
    pub walk_budget: u32,
    /// Always 2: the trip count of the shader's loop-limit probe.
    pub probe: u32,
    /// 1: receiver-plane rejection (`receiver_plane=true`, [`RecIn`]'s plane).
    pub receiver_plane: u32,
    /// 1: the classification depths are the true depths (`self_shadow=bias`).
    pub class_is_depth: u32,
    /// The light: [`SHAPE_RECT`], [`SHAPE_DISK`] (radius `hx`, docs/methods.md §3 "Disk
    /// lights") or [`SHAPE_SPHERE`] (radius `hx`, §3 "Sphere lights").
    pub shape: u32,
    /// 1 for an orthographic view (the sun): `k` is the texel pitch ([`crate::math::radial::Scale`]),
    /// kernels are the occluder prism's width, and a receiver's plane holds `(cu, cv)` where a
    /// perspective one holds `(gu, gv)`.
    pub ortho: u32,
}

/// Per-receiver state between the passes (mirrors `PrepGpu`): kernel cells, nudged texel
/// coordinates, state (0 done, 2 penumbra still to evaluate), centre status, and the walk's
/// place between rounds of `pixels`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct PrepGpu {
    /// Kernel cells `[x0, y0, x1, y1)`.
    pub cr: [i32; 4],
    /// Nudged `(u_p, v_p)`.
    pub q: [f32; 2],
    /// State.
    pub state: u32,
    /// Centre status.
    pub centre: u32,
    /// Flat: the next cell; hierarchy: the root, Morton code and level of the next node; then
    /// the nodes or cells visited so far.
    pub walk: [u32; 4],
}

/// One receiver as the kernel reads it and the frame's set-up pass writes it (mirrors `RecIn`
/// in `rec_in.wgsl`): texel coordinates, `z_p` and the classification threshold `t_p`;
/// `zp <= 0` for receivers the set-up settled.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct RecIn {
    /// `(u_p, v_p)`.
    pub uv: [f32; 2],
    /// `z_p`.
    pub zp: f32,
    /// `t_p`.
    pub t: f32,
    /// [`ReceiverPlane::g0`](shadow_map_core::ReceiverPlane::g0) (0 without the plane).
    pub g0: f32,
    /// [`ReceiverPlane::gu`](shadow_map_core::ReceiverPlane::gu).
    pub gu: f32,
    /// [`ReceiverPlane::gv`](shadow_map_core::ReceiverPlane::gv).
    pub gv: f32,
    /// [`ReceiverPlane::c`](shadow_map_core::ReceiverPlane::c).
    pub c: f32,
    /// A sphere light's [`Silhouette`](shadow_map_core::silhouette::Silhouette) seen from the
    /// receiver (zeros otherwise): `(a, dist)`.
    pub sil_a: [f32; 4],
    /// `(e1, radius)`.
    pub sil_e1: [f32; 4],
    /// `(e2, 0)`.
    pub sil_e2: [f32; 4],
    /// [`Silhouette::clip`](shadow_map_core::silhouette::Silhouette::clip).
    pub sil_clip: [f32; 4],
}

/// Steps of a receiver's walk (nodes, or cells of a flat scan) one round of `pixels` takes at
/// most: half of llvmpipe's loop budget ([`LOOP_LIMIT`]), so no invocation is cut; a longer
/// walk goes on in the next round.
pub const WALK_BUDGET: u32 = 1 << 15;
/// Rounds of `pixels` a view records at most: a receiver whose walk is longer than this many
/// budgets is left NaN and counted as cut.
pub const MAX_ROUNDS: u32 = 64;

/// Words before the queue's list: its count and the indirect dispatch's `(x, y, z)`, which
/// start at byte [`QUEUE_ARGS_OFFSET`].
pub(crate) const QUEUE_HEADER: u64 = 4;
/// Byte offset of the `pixels` dispatch's workgroup counts in the queue.
pub(crate) const QUEUE_ARGS_OFFSET: u64 = 4;

/// Threads per workgroup of every pass (the core's `WG` override).
pub(crate) const WORKGROUP: u32 = 64;

/// Why a long walk is split: some devices bound the loop iterations of one shader invocation
/// (llvmpipe, i.e. lavapipe, ends every loop once 65535 iterations in all have run: gallivm's
/// `LP_MAX_TGSI_LOOP_ITERATIONS`), which would silently truncate a long contour walk. `pixels`
/// takes at most [`WALK_BUDGET`] steps of a walk a round and re-queues the rest for the next
/// round (up to [`MAX_ROUNDS`] a view, as many as the view's widest kernel can need), so no
/// invocation nears it. A two-trip probe loop with a uniform bound still checks each round
/// (it trips once when the budget is spent); a receiver it catches, or one whose walk outlasts
/// the rounds, is left NaN and counted as cut (status word 2), never returned as V.
pub const LOOP_LIMIT: &str = "llvmpipe: 65535 loop iterations per invocation";

/// The kernel's module, its `prepare` and `pixels` pipelines specialised per view
/// ([`switches`]) and compiled at their first use, and its bind groups.
pub(crate) struct Kernel {
    pub ctx: Arc<GpuContext>,
    pub kernel: SpecializedKernel,
    /// The bind groups [`group`](Self::group) made, kept while their buffers stay the same.
    pub groups: BindGroupCache,
}

impl Kernel {
    /// Compiles [`SHADER_PARTS`] on `ctx`'s device.
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self> {
        let constants = [("WG", WORKGROUP as f64)];
        let kernel = SpecializedKernel::new(
            &ctx,
            "packet-hsm kernel",
            &SHADER_PARTS,
            "prepare",
            &constants,
        )?;
        Ok(Kernel {
            ctx,
            kernel,
            groups: BindGroupCache::default(),
        })
    }

    /// The `prepare` and `pixels` pipelines of a view whose uniform is `u`.
    pub fn pipelines(
        &self,
        u: &HsmUniform,
    ) -> Result<(wgpu::ComputePipeline, wgpu::ComputePipeline)> {
        let s = switches(u);
        Ok((
            self.kernel.entry_pipeline(&self.ctx, "prepare", &s)?,
            self.kernel.entry_pipeline(&self.ctx, "pixels", &s)?,
        ))
    }

    /// A bind group over `bufs`, bound in order from 0: the uniform, depth, classification,
    /// MSSM, dual min, dual max, receivers, V out, prep (these three one range of receivers:
    /// the passes run over `arrayLength(&prep)`), the queue of penumbra receivers `prepare`
    /// fills and a round of `pixels` reads, and the next round's ([`QUEUE_HEADER`] words, then
    /// one per receiver of the range).
    pub fn group(&self, bufs: [wgpu::BindingResource<'_>; 11]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = bufs
            .into_iter()
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource,
            })
            .collect();
        self.groups.get(
            &self.ctx,
            "packet-hsm kernel",
            &self.kernel.layout,
            &entries,
        )
    }
}

/// What the kernel's uniform takes from one view: the view, the sub-light's half extents and
/// emitter, and the sizes of its hierarchies.
pub(crate) struct SubLightShape {
    pub view: LightView,
    pub half: glam::Vec2,
    pub emitter: Emitter,
    /// Side of the padded dual-grid MSSM, `r + 2`.
    pub padded: u32,
    /// Levels of the anchored MSSM and of the dual-grid MSSM.
    pub mssm_levels: u32,
    pub dual_levels: u32,
    /// The classification depths are the true depths.
    pub class_is_depth: bool,
    /// The widest kernel of the view, in cells ([`crate::cpu::SubView::levels`]).
    pub max_cells: u32,
}

impl SubLightShape {
    /// The rounds of `pixels` that finish every walk of the view at `budget` steps a round
    /// (at most [`MAX_ROUNDS`]): a flat scan visits at most `max_cells^2` cells, the hierarchy
    /// at most 4/3 of the cells as nodes inside the kernel, and up to 3 siblings outside it
    /// per node walked into, so `6 (max_cells + 2)^2` steps.
    pub fn rounds(&self, hierarchy: bool, budget: u32) -> u32 {
        let m = self.max_cells as u64 + 2;
        let steps = if hierarchy { 6 * m * m } else { m * m };
        steps
            .div_ceil(budget.max(1) as u64)
            .clamp(1, MAX_ROUNDS as u64) as u32
    }
}

/// The view's switches the kernel takes as pipeline overrides (`HSM_*` in `packet_hsm.wgsl`):
/// `u`'s light shape, projection, receiver plane, classification and hierarchy. The uniform
/// keeps the same fields.
pub(crate) fn switches(u: &HsmUniform) -> [(&'static str, f64); 5] {
    [
        ("HSM_SHAPE", u.shape as f64),
        ("HSM_ORTHO", u.ortho as f64),
        ("HSM_PLANE", u.receiver_plane as f64),
        ("HSM_CLASS_IS_DEPTH", u.class_is_depth as f64),
        ("HSM_HIERARCHY", u.hierarchy as f64),
    ]
}

/// The kernel's uniform for the view `sv`.
pub(crate) fn hsm_uniform(sv: &SubLightShape, cfg: &Config) -> HsmUniform {
    let view = &sv.view;
    HsmUniform {
        r: view.r,
        padded: sv.padded,
        mssm_levels: sv.mssm_levels.max(1),
        dual_levels: sv.dual_levels.max(1),
        alpha: view.alpha(),
        n: view.n,
        k: crate::math::radial::Scale::of(view).k as f32,
        hierarchy: cfg.hierarchy as u32,
        hx: sv.half.x,
        hy: sv.half.y,
        walk_budget: WALK_BUDGET,
        probe: 2,
        receiver_plane: cfg.shadow.receiver_plane as u32,
        class_is_depth: sv.class_is_depth as u32,
        shape: match sv.emitter {
            Emitter::Rect(_) => SHAPE_RECT,
            Emitter::Disk(_) => SHAPE_DISK,
            Emitter::Sphere(_) => SHAPE_SPHERE,
        },
        ortho: u32::from(view.is_ortho()),
    }
}

#[cfg(test)]
mod tests {
    use super::{HsmUniform, PrepGpu, RecIn, SHADER_PARTS};

    /// Every mirrored struct agrees with the WGSL by member name and offset, and in size.
    #[test]
    fn mirrored_structs_match_the_wgsl() {
        test_support::assert_wgsl_layout!(
            SHADER_PARTS.concat(),
            HsmUniform {
                r,
                padded,
                mssm_levels,
                dual_levels,
                alpha,
                n,
                k,
                hierarchy,
                hx,
                hy,
                walk_budget,
                probe,
                receiver_plane,
                class_is_depth,
                shape,
                ortho,
            }
        );
        test_support::assert_wgsl_layout!(
            SHADER_PARTS.concat(),
            PrepGpu {
                cr,
                q,
                state,
                centre,
                walk,
            }
        );
        test_support::assert_wgsl_layout!(
            SHADER_PARTS.concat(),
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

    /// The kernel parses and validates with naga (no device needed).
    #[test]
    fn wgsl_validates_with_naga() {
        test_support::wgsl::assert_shaders_valid([("packet_hsm", SHADER_PARTS.concat())]);
    }
}
