//! wgpu twin of [`CpuPacketHsm`] (cargo feature `gpu`, on by default): the same name,
//! description and parameters.
//!
//! **What runs where.** For each sub-light, one at a time, the light-space data are built on the
//! CPU exactly as the CPU twin builds them ([`SubView::build`]: shadow map, midpoints, MSSM, padded
//! dual-grid MSSM) and uploaded as storage buffers. The per-receiver setup that needs no map
//! (light-space transform, facing fraction, projection, bias threshold, the behind / near /
//! outside cases) is done on the CPU with the CPU twin's code ([`crate::cpu::setup_receiver`]); everything
//! from the kernel on runs on the GPU (`packet_hsm.wgsl`), in three passes: `prepare` (one
//! invocation per receiver: the tight kernel from the MSSM, the fully lit / fully occluded
//! classification over the dual-grid MSSM, the centre status), `packets` (one invocation per
//! w x h packet of the image layout: extended kernel, coherence test, ternary contour extraction,
//! per-pixel backprojection and radial integration; a null status leaves the packet's pixels to
//! the next pass), `pixels` (per-pixel GBP07 for every penumbra receiver left). Contour
//! extraction is flat or Yang's Algorithm 3 with an explicit stack (`hierarchy`). Receivers
//! without an image layout skip the packets pass.
//!
//! **Not on the GPU:** rasterising the maps and building the MSSMs (uploaded from the CPU).
//!
//! Known differences from the CPU: f32 light-plane geometry and sums (f64 on the CPU), a
//! backprojection gap floored at `1e-7 z_p` (CPU: `1e-12 z_p`), the cell-boundary nudge added in
//! f32; see `tests/gpu_twin.rs` for the measured agreement. The receiver plane
//! (`receiver_plane=true`) is built on the CPU by [`crate::cpu::setup_receiver`] and passed in
//! [`RecIn`]; the shader's caster test is the same product and comparison in f32 (a fused
//! multiply-add can flip a tie).
use crate::contour::Emitter;
use crate::cpu::{pixel_value, prepare_setup, ReceiverSetup};
use crate::cpu::{Config, CpuPacketHsm, OpacityLevels, OwnPlane, SubLights, SubView};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use shadow_map_core::gpu::kernel::BufferInitExt;
use shadow_map_core::{
    gpu::{
        kernel::{bind_group_layout, compute_pipeline, shader_module, Binding},
        GpuContext,
    },
    silhouette::Silhouette,
    Error, ImageLayout, LightView, ReceiverPlane, Receivers, Report, Result, Scene,
    SoftShadowEstimator,
};
use std::sync::Arc;

/// The kernel's own WGSL: bindings, helpers, contour cells and radial integration.
pub const PACKET_HSM_WGSL: &str = include_str!("packet_hsm.wgsl");
/// The kernel's three entry points (`prepare`, `pixels`, `packets`), after [`PACKET_HSM_WGSL`].
pub const PACKET_HSM_PASSES_WGSL: &str = include_str!("packet_hsm_passes.wgsl");
/// [`RecIn`] in WGSL, which the kernel reads and the frame's set-up pass writes.
pub const REC_IN_WGSL: &str = include_str!("rec_in.wgsl");
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

/// Uniform of one dispatch (mirrors `HsmUniform` in `packet_hsm.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct HsmUniform {
    /// Shadow-map side r.
    pub r: u32,
    /// Padded side r + 2 of the dual-grid MSSM.
    pub padded: u32,
    /// Anchored MSSM levels uploaded.
    pub mssm_levels: u32,
    /// Dual-grid MSSM levels uploaded.
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
    /// Receivers in this dispatch.
    pub count: u32,
    /// First receiver of this dispatch.
    pub base: u32,
    /// Image width (packets; 0 without an image layout).
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Packet width w.
    pub pw: u32,
    /// Packet height h.
    pub ph: u32,
    /// Packets per image row.
    pub packets_x: u32,
    /// Packets in all.
    pub packets: u32,
    /// 1: coherence test on.
    pub coherence: u32,
    /// Td.
    pub td: f32,
    /// Q_e.
    pub qe: f32,
    /// Q_v.
    pub qv: f32,
    /// Far plane (empty samples' depth in eq. 4).
    pub far: f32,
    /// Always 2: the trip count of the shader's loop-limit probe.
    pub probe: u32,
    /// 1: receiver-plane rejection (`receiver_plane=true`, [`RecIn`]'s plane).
    pub receiver_plane: u32,
    /// 1: the classification depths are the true depths (`self_shadow=bias`).
    pub class_is_depth: u32,
    /// The light: [`SHAPE_RECT`], [`SHAPE_DISK`] (radius `hx`, docs/methods.md §3 "Disk
    /// lights") or [`SHAPE_SPHERE`] (radius `hx`, §3 "Sphere lights").
    pub shape: u32,
    /// 1 for an orthographic view (the sun): `k` is the texel pitch ([`crate::contour::Scale`]),
    /// kernels are the occluder prism's width, and a receiver's plane holds `(cu, cv)` where a
    /// perspective one holds `(gu, gv)`.
    pub ortho: u32,
}

/// Per-receiver state between the passes (mirrors `PrepGpu`): kernel cells, nudged texel
/// coordinates, state (0 done, 2 penumbra still to evaluate), centre status.
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
}

/// One receiver as the kernel reads it (mirrors `RecIn`): texel coordinates, `z_p` and the
/// classification threshold `t_p`; `zp <= 0` for receivers settled on the CPU.
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
    /// A sphere light's [`Silhouette`] seen from the receiver (zeros otherwise): `(a, dist)`.
    pub sil_a: [f32; 4],
    /// `(e1, radius)`.
    pub sil_e1: [f32; 4],
    /// `(e2, 0)`.
    pub sil_e2: [f32; 4],
    /// [`Silhouette::clip`].
    pub sil_clip: [f32; 4],
}

impl RecIn {
    /// A receiver the CPU settled (`zp = 0`: not evaluated on the device).
    const SETTLED: RecIn = RecIn {
        uv: [0.0; 2],
        zp: 0.0,
        t: 0.0,
        g0: 0.0,
        gu: 0.0,
        gv: 0.0,
        c: 0.0,
        sil_a: [0.0; 4],
        sil_e1: [0.0; 4],
        sil_e2: [0.0; 4],
        sil_clip: [0.0; 4],
    };
}

const LABEL: &str = "packet-hsm estimate";
pub(crate) const WORKGROUP: u32 = 64;

/// The GPU twin of [`CpuPacketHsm`].
pub struct GpuPacketHsm {
    pub(crate) ctx: Arc<GpuContext>,
    cpu: CpuPacketHsm,
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) prepare: wgpu::ComputePipeline,
    packets: wgpu::ComputePipeline,
    pub(crate) pixels: wgpu::ComputePipeline,
    report: Report,
}

/// What one sub-light's dispatches return: per receiver (V before the facing factor, visited
/// nodes; visited < 0: the device cut the work short, see [`LOOP_LIMIT`]), and the packet
/// counters (packets, coherent, rejected, diverged, cut short).
pub type SublightOutput = (Vec<[f32; 2]>, [u32; 5]);

/// Why a receiver can come back flagged: some devices bound the loop iterations of one shader
/// invocation (llvmpipe, i.e. lavapipe, ends every loop once 65535 iterations in all have run:
/// gallivm's `LP_MAX_TGSI_LOOP_ITERATIONS`), which would silently truncate a long contour scan
/// (a large kernel without the hierarchy, or a large packet). The kernel detects it (a loop that
/// did not finish, and a two-trip probe loop with a uniform bound that trips once when the budget
/// is spent) and flags the receiver; [`GpuPacketHsm`] then evaluates it with the CPU twin's code
/// on the same data (exact, the same V) and reports the count as `loop_limit_cpu_fallbacks`.
/// A packet cut short leaves its pixels to the per-pixel pass.
pub const LOOP_LIMIT: &str = "llvmpipe: 65535 loop iterations per invocation";

impl GpuPacketHsm {
    /// With default parameters, compiling the kernel on `ctx`'s device.
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self> {
        let module = shader_module(&ctx, LABEL, &SHADER_PARTS)?;
        let layout = ctx.scoped(LABEL, || {
            let mut bindings = vec![Binding::Uniform];
            bindings.extend([Binding::Storage; 6]);
            bindings.extend([Binding::StorageRw; 3]);
            bind_group_layout(&ctx, LABEL, &bindings)
        })?;
        let constants = [("WG", WORKGROUP as f64)];
        let make = |entry: &str| compute_pipeline(&ctx, LABEL, &module, &layout, entry, &constants);
        let (prepare, packets, pixels) = (make("prepare")?, make("packets")?, make("pixels")?);
        Ok(GpuPacketHsm {
            ctx,
            cpu: CpuPacketHsm::new()?,
            layout,
            prepare,
            packets,
            pixels,
            report: Report::default(),
        })
    }

    fn storage(&self, label: &str, data: &[u8], limit: u64) -> Result<wgpu::Buffer> {
        if data.len() as u64 > limit {
            return Err(Error::Limit {
                what: "packet-hsm storage binding bytes (max_storage_buffer_binding_size)",
                requested: data.len() as u64,
                max: limit,
            });
        }
        // Never bind a zero-size buffer.
        let dummy = [0u8; 16];
        let contents = if data.is_empty() { &dummy[..] } else { data };
        self.ctx.scoped(label, || {
            self.ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                })
        })
    }

    /// V before the facing factor and the visited nodes of every receiver of `recs` for one
    /// sub-light, on the GPU: `prepare`, then `packets` when `layout` is given and the packet is
    /// larger than 1x1, then `pixels`; and the packet counters.
    pub fn run_sublight(
        &self,
        sv: &SubView,
        cfg: &Config,
        recs: &[RecIn],
        layout: Option<ImageLayout>,
    ) -> Result<SublightOutput> {
        let ctx = &*self.ctx;
        let limit = ctx.limits().max_storage_buffer_binding_size;
        let grid = sv.grid(cfg);
        let r = grid.size;
        let (mssm, dmin, dmax) = flatten_hierarchies(sv, r);
        if recs.is_empty() {
            return Ok((Vec::new(), [0; 5]));
        }
        let b_depth = self.storage("packet-hsm depth", bytemuck::cast_slice(grid.depth), limit)?;
        let b_class = self.storage("packet-hsm class", bytemuck::cast_slice(grid.class), limit)?;
        let b_mssm = self.storage("packet-hsm mssm", bytemuck::cast_slice(&mssm), limit)?;
        let b_dmin = self.storage("packet-hsm dual min", bytemuck::cast_slice(&dmin), limit)?;
        let b_dmax = self.storage("packet-hsm dual max", bytemuck::cast_slice(&dmax), limit)?;
        let b_recs = self.storage("packet-hsm receivers", bytemuck::cast_slice(recs), limit)?;
        let zero_prep = vec![PrepGpu::zeroed(); recs.len()];
        let b_prep = self.storage("packet-hsm prep", bytemuck::cast_slice(&zero_prep), limit)?;
        let b_count = self.storage("packet-hsm counters", &[0u8; 20], limit)?;
        let out_bytes = (recs.len() * 8) as u64;
        if out_bytes > limit {
            return Err(Error::Limit {
                what: "packet-hsm output bytes (max_storage_buffer_binding_size)",
                requested: out_bytes,
                max: limit,
            });
        }
        let out = ctx.scoped(LABEL, || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("packet-hsm v"),
                size: out_bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        })?;
        let max_groups = ctx.limits().max_compute_workgroups_per_dimension.max(1);
        let per = (max_groups * WORKGROUP) as usize;
        let plan = PacketPlan::new(cfg, layout, per)?;
        let uniform = |count: usize, base: usize| hsm_uniform(sv, cfg, r, &plan, count, base);
        let bufs = [
            &b_depth, &b_class, &b_mssm, &b_dmin, &b_dmax, &b_recs, &out, &b_prep, &b_count,
        ];
        self.submit_stages(recs.len(), per, &plan, &uniform, bufs)?;
        let v: Vec<[f32; 2]> = ctx.read_buffer(&out, out_bytes)?;
        let c: Vec<u32> = ctx.read_buffer(&b_count, 20)?;
        Ok((v, [c[0], c[1], c[2], c[3], c[4]]))
    }

    /// Encodes and submits `prepare` (in chunks of `per` receivers), `packets` (in packet mode)
    /// and `pixels` (in chunks), each with its own uniform over the nine storage buffers `bufs`.
    fn submit_stages(
        &self,
        n_recs: usize,
        per: usize,
        plan: &PacketPlan,
        uniform: &dyn Fn(usize, usize) -> HsmUniform,
        bufs: [&wgpu::Buffer; 9],
    ) -> Result<()> {
        let ctx = &*self.ctx;
        let [b_depth, b_class, b_mssm, b_dmin, b_dmax, b_recs, out, b_prep, b_count] = bufs;
        let (packet_mode, packets) = (plan.packet_mode, plan.packets);
        ctx.scoped(LABEL, || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            let mut keep = Vec::new();
            let mut dispatch = |enc: &mut wgpu::CommandEncoder,
                                pipe: &wgpu::ComputePipeline,
                                un: HsmUniform,
                                groups: u32| {
                let ub = ctx
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("packet-hsm uniform"),
                        contents: bytemuck::bytes_of(&un),
                        usage: wgpu::BufferUsages::UNIFORM,
                    });
                let bufs = [
                    &ub, b_depth, b_class, b_mssm, b_dmin, b_dmax, b_recs, out, b_prep, b_count,
                ];
                let entries: Vec<wgpu::BindGroupEntry> = bufs
                    .iter()
                    .enumerate()
                    .map(|(i, b)| wgpu::BindGroupEntry {
                        binding: i as u32,
                        resource: b.as_entire_binding(),
                    })
                    .collect();
                let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(LABEL),
                    layout: &self.layout,
                    entries: &entries,
                });
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(LABEL),
                    timestamp_writes: None,
                });
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &group, &[]);
                pass.dispatch_workgroups(groups.max(1), 1, 1);
                drop(pass);
                keep.push(ub);
            };
            let chunks = |f: &mut dyn FnMut(usize, usize)| {
                let mut base = 0usize;
                while base < n_recs {
                    let count = (n_recs - base).min(per);
                    f(count, base);
                    base += count;
                }
            };
            chunks(&mut |count, base| {
                dispatch(
                    &mut enc,
                    &self.prepare,
                    uniform(count, base),
                    (count as u32).div_ceil(WORKGROUP),
                )
            });
            if packet_mode && packets > 0 {
                dispatch(
                    &mut enc,
                    &self.packets,
                    uniform(0, 0),
                    packets.div_ceil(WORKGROUP),
                );
            }
            chunks(&mut |count, base| {
                dispatch(
                    &mut enc,
                    &self.pixels,
                    uniform(count, base),
                    (count as u32).div_ceil(WORKGROUP),
                )
            });
            ctx.queue.submit([enc.finish()]);
        })
    }
}

/// The sub-light's MSSM levels (minima) and padded dual MSSM levels (minima, maxima), each
/// flattened level after level.
fn flatten_hierarchies(sv: &SubView, r: u32) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let m = &sv.mssm;
    let mut mssm = Vec::with_capacity(m.levels() as usize * (r * r) as usize);
    for l in 0..m.levels() {
        mssm.extend_from_slice(m.level(l).0);
    }
    let d = &sv.dual.mssm;
    let (mut dmin, mut dmax) = (Vec::new(), Vec::new());
    for l in 0..d.levels() {
        let (a, b) = d.level(l);
        dmin.extend_from_slice(a);
        dmax.extend_from_slice(b);
    }
    (mssm, dmin, dmax)
}

/// The packet pass of one [`GpuPacketHsm::run_sublight`]: whether it runs and over what grid.
pub(crate) struct PacketPlan {
    /// True when an image layout is given and the packet is larger than 1x1.
    packet_mode: bool,
    /// Image size (0 x 0 without a layout).
    width: u32,
    height: u32,
    /// Packet size.
    pw: u32,
    ph: u32,
    /// Packets per image row, and in all (0 outside packet mode).
    packets_x: u32,
    packets: u32,
}

impl PacketPlan {
    /// Plans the packet pass; [`Error::Limit`] when the packets exceed one dispatch of `per`.
    pub(crate) fn new(cfg: &Config, layout: Option<ImageLayout>, per: usize) -> Result<Self> {
        let (pw, ph) = cfg.packet.size();
        let packet_mode = layout.is_some() && (pw, ph) != (1, 1);
        let (width, height) = layout.map_or((0, 0), |l| (l.width, l.height));
        let packets_x = if packet_mode { width.div_ceil(pw) } else { 0 };
        let packets = if packet_mode {
            packets_x * height.div_ceil(ph)
        } else {
            0
        };
        if packets as usize > per {
            return Err(Error::Limit {
                what: "packet-hsm packets per dispatch",
                requested: packets as u64,
                max: per as u64,
            });
        }
        Ok(PacketPlan {
            packet_mode,
            width,
            height,
            pw,
            ph,
            packets_x,
            packets,
        })
    }
}

/// What the kernel's uniform takes from one sub-light: its view, half extents and emitter, and
/// the sizes of its hierarchies (a [`SubView`]'s, or on the engine path what the view decides).
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
}

impl SubLightShape {
    fn of(sv: &SubView, cfg: &Config) -> Self {
        SubLightShape {
            view: sv.ls.view,
            half: sv.half,
            emitter: sv.emitter,
            padded: sv.dual.mssm.size(),
            mssm_levels: sv.mssm.levels(),
            dual_levels: sv.dual.mssm.levels(),
            class_is_depth: sv.grid(cfg).class_is_depth(),
        }
    }
}

/// The uniform of one dispatch over `count` receivers from `base` (0, 0 for the packet pass).
fn hsm_uniform(
    sv: &SubView,
    cfg: &Config,
    r: u32,
    plan: &PacketPlan,
    count: usize,
    base: usize,
) -> HsmUniform {
    hsm_uniform_of(&SubLightShape::of(sv, cfg), cfg, r, plan, count, base)
}

/// [`hsm_uniform`] from a [`SubLightShape`].
pub(crate) fn hsm_uniform_of(
    sv: &SubLightShape,
    cfg: &Config,
    r: u32,
    plan: &PacketPlan,
    count: usize,
    base: usize,
) -> HsmUniform {
    let view = &sv.view;
    HsmUniform {
        r,
        padded: sv.padded,
        mssm_levels: sv.mssm_levels.max(1),
        dual_levels: sv.dual_levels.max(1),
        alpha: view.alpha(),
        n: view.n,
        k: crate::contour::Scale::of(view).k as f32,
        hierarchy: cfg.hierarchy as u32,
        hx: sv.half.x,
        hy: sv.half.y,
        count: count as u32,
        base: base as u32,
        width: plan.width,
        height: plan.height,
        pw: plan.pw,
        ph: plan.ph,
        packets_x: plan.packets_x,
        packets: plan.packets,
        coherence: cfg.coherence as u32,
        td: cfg.td as f32,
        qe: cfg.qe as f32,
        qv: cfg.qv as f32,
        far: view.far,
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

impl SoftShadowEstimator for GpuPacketHsm {
    shadow_map_core::estimator_identity!(twin of cpu, Gpu);
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        self.cpu.build(scene, receivers)
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        let cfg = Config::from_params(self.cpu.params())?;
        CpuPacketHsm::check_light(scene.light(), &cfg)?;
        let s = cfg.sublights;
        let mut subs = SubLights::new(&cfg, receivers.len());
        subs.own_plane = OwnPlane::Off;
        let mut visited = 0f64;
        let mut outside = 0usize;
        let mut counts = [0u64; 5];
        let mut fallbacks = 0usize;
        let levels = OpacityLevels::new(scene, cfg.opacity_levels);
        for b in 0..s {
            for a in 0..s {
                for (level, lw) in levels.iter() {
                    // Between sub-lights (the CPU twin's token, `set_cancel`).
                    self.cpu.cancel().check()?;
                    let sv = subs.build(level, receivers, &cfg, (a, b))?;
                    let t = std::time::Instant::now();
                    let setups: Vec<ReceiverSetup> = prepare_setup(&sv, &cfg, receivers);
                    let recs: Vec<RecIn> = setups
                        .iter()
                        .map(|s| match s {
                            ReceiverSetup::Settled(_) | ReceiverSetup::Outside(_) => RecIn::SETTLED,
                            ReceiverSetup::Map {
                                uv,
                                zp,
                                t,
                                plane,
                                sil,
                                ..
                            } => {
                                let pl = plane.unwrap_or(ReceiverPlane {
                                    g0: 0.0,
                                    gu: 0.0,
                                    gv: 0.0,
                                    c: 0.0,
                                    cu: 0.0,
                                    cv: 0.0,
                                    zp: *zp,
                                    hs: 0.0,
                                });
                                let s = sil.unwrap_or(Silhouette {
                                    a: Vec3::ZERO,
                                    e1: Vec3::ZERO,
                                    e2: Vec3::ZERO,
                                    dist: 0.0,
                                    radius: 0.0,
                                    clip: [0.0; 4],
                                });
                                RecIn {
                                    uv: [uv.x, uv.y],
                                    zp: *zp,
                                    t: *t,
                                    g0: pl.g0,
                                    // Orthographic planes have gu = gv = 0 and vary their
                                    // height (cu, cv) instead (HsmUniform::ortho).
                                    gu: if sv.ls.view.is_ortho() { pl.cu } else { pl.gu },
                                    gv: if sv.ls.view.is_ortho() { pl.cv } else { pl.gv },
                                    c: pl.c,
                                    sil_a: s.a.extend(s.dist).to_array(),
                                    sil_e1: s.e1.extend(s.radius).to_array(),
                                    sil_e2: s.e2.extend(0.0).to_array(),
                                    sil_clip: s.clip,
                                }
                            }
                        })
                        .collect();
                    let (out, c) = self.run_sublight(&sv, &cfg, &recs, receivers.layout())?;
                    for (a, b) in counts.iter_mut().zip(c) {
                        *a += b as u64;
                    }
                    for (k, su) in setups.iter().enumerate() {
                        let x = match su {
                            ReceiverSetup::Settled(x) => *x,
                            ReceiverSetup::Outside(x) => {
                                outside += 1;
                                *x
                            }
                            ReceiverSetup::Map { facing, .. } => {
                                if out[k][1] < 0.0 {
                                    fallbacks += 1;
                                    pixel_value(
                                        &sv,
                                        &cfg,
                                        receivers.position()[k],
                                        receivers.normal()[k],
                                    )
                                } else {
                                    visited += out[k][1] as f64;
                                    facing * out[k][0]
                                }
                            }
                        };
                        subs.acc[k] += subs.weight * lw * x;
                    }
                    subs.t_est += t.elapsed().as_secs_f64() * 1e3;
                }
            }
        }
        let rep = &mut self.report;
        levels.note(rep);
        subs.finish(&cfg, receivers, v, outside, rep);
        rep.note("packets", counts[0]);
        rep.note("packets_coherent", counts[1]);
        rep.note("packets_rejected", counts[2]);
        rep.note("packets_diverged", counts[3]);
        rep.note("packets_loop_limit", counts[4]);
        rep.note("loop_limit_cpu_fallbacks", fallbacks);
        rep.note("visited_nodes", visited as u64);
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
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
                count,
                base,
                width,
                height,
                pw,
                ph,
                packets_x,
                packets,
                coherence,
                td,
                qe,
                qv,
                far,
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
