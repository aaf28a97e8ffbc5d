//! The CPU estimator: Yang et al. 2009, Algorithm 1, steps 2-8, over the exact per-pixel contour
//! backprojection of [`crate::contour`].
use crate::contour::Scale;
use crate::contour::{
    edge_area, extract, pixel_visibility, visibility_from_area, CellRect, Edge, OccluderTest,
    PaddedDualMssm, Planes, Receiver, SampleGrid, Traversal,
};
use glam::Vec3;
use rayon::prelude::*;
use shadow_map_core::{
    light_view::{ViewOptions, RESOLUTION},
    params::FromParam,
    peeling::SelfShadowSettings,
    Cancel, Error, LightShape, ParamSpec, ParamValue, Params, Receivers, Report, Result, Scene,
    SoftShadowEstimator,
};
use std::sync::atomic::{AtomicU64, Ordering};

mod setup;
mod sublights;
pub use setup::{
    kernel_cells, kernel_light, kernel_side, prepare, setup_receiver, trivial, Prep, ReceiverSetup,
};
pub use sublights::{
    emitter_of, levels_run, sublight_centre, OpacityLevels, OwnPlane, SubLights, SubView,
    OWN_PLANE_WORTH,
};

/// Registry name (shared with the engine path).
pub const NAME: &str = "packet-hsm";
/// One-line description (shared with the registry's GPU estimator).
pub const DESCRIPTION: &str = "packet-based hierarchical soft shadow mapping: contour backprojection over a dual-grid MSSM, pixel packets, coherence test, S x S sub-lights (Yang 2009, GBP07)";

/// Every packet size from 1x1 to 8x8 (`WxH`).
pub const PACKETS: &[&str] = &[
    "1x1", "1x2", "1x3", "1x4", "1x5", "1x6", "1x7", "1x8", "2x1", "2x2", "2x3", "2x4", "2x5",
    "2x6", "2x7", "2x8", "3x1", "3x2", "3x3", "3x4", "3x5", "3x6", "3x7", "3x8", "4x1", "4x2",
    "4x3", "4x4", "4x5", "4x6", "4x7", "4x8", "5x1", "5x2", "5x3", "5x4", "5x5", "5x6", "5x7",
    "5x8", "6x1", "6x2", "6x3", "6x4", "6x5", "6x6", "6x7", "6x8", "7x1", "7x2", "7x3", "7x4",
    "7x5", "7x6", "7x7", "7x8", "8x1", "8x2", "8x3", "8x4", "8x5", "8x6", "8x7", "8x8",
];

/// Parameters of [`CpuPacketHsm`] (shared with the engine path, [`crate::frame`]).
pub const SPECS: &[ParamSpec] = Config::SPECS;

/// Per-receiver diagnostics of the last estimate (Yang Figs. 5 and 8): what the EXR channels of a
/// diagnostic image would hold.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PixelDiag {
    /// Largest kernel side in dual cells over the sub-lights (0: no kernel needed).
    pub kernel: f32,
    /// MSSM nodes (hierarchy) or 2x2 blocks (flat) visited for this pixel, summed over the
    /// sub-lights; a packet's visits are shared equally by its penumbra pixels.
    pub visited: f32,
    /// How the pixel was last evaluated (see the `CLASS_*` constants).
    pub class: u8,
}

/// [`PixelDiag::class`]: fully lit, fully occluded, or no shadow-map work (behind, outside).
pub const CLASS_TRIVIAL: u8 = 0;
/// [`PixelDiag::class`]: evaluated in a coherent packet.
pub const CLASS_PACKET: u8 = 1;
/// [`PixelDiag::class`]: evaluated pixel-wise (non-coherent or diverging packet, lone pixel,
/// packet 1x1 or no image layout).
pub const CLASS_PIXEL: u8 = 2;

/// Packet-based hierarchical soft shadow mapping (Yang, Feng, Guennebaud, Liu 2009, Algorithm 1)
/// on the CPU.
///
/// For each of the S x S sub-lights (step 2; S = `sublights`; sub-light (a, b) has centre
/// `((a + 1/2)/S - 1/2) l_x, ((b + 1/2)/S - 1/2) l_y` and size `l/S`), one at a time:
/// 3-4. a shadow map from the sub-light centre fitted to the receivers (`fit`, `nearfar`; plus
///    the second peeled layer for midpoints), its MSSM and the padded dual-grid MSSM of the
///    classification depths;
/// 5. per receiver p: the facing fraction of the sub-light (the contract's tangent-plane term),
///    the tight kernel from the MSSM (Yang eq. 1 with `z_m` the exact minimum depth over the
///    kernel, refined until it stops shrinking, SS07/GBP06), grown to every dual cell touching it;
///    fully lit when no sample of the kernel occludes, fully occluded when all do (exact for the
///    contour method; with `receiver_plane=true` a sample occludes only if its true depth also
///    passes the receiver's [`ReceiverPlane::caster`], and these tests, like the hierarchy's
///    pruning, bound it with the plane's per-texel thresholds, see [`trivial`]);
/// 6. packets of w x h pixels of the image layout; the coherence test
///    ([`coherence`]: P_null eq. 4, P_d eq. 5 against Td, cost ratio eq. 6);
/// 7. coherent packets: one contour extraction over the packet's extended kernel with the
///    ternary status (eq. 3); a null status aborts to step 8; otherwise each pixel integrates the
///    edges of the cells inside its own kernel;
/// 8. the remaining pixels: per-pixel GBP07 ([`pixel_visibility`]).
///
/// V is the mean over sub-lights of `facing_k (1 - clamp01(A_occ,k / A_k))`.
///
/// **Exactness.** Steps 6-8 and the `hierarchy` switch never change V beyond the order of an f64
/// sum: a packet pixel integrates exactly the edges its own per-pixel kernel yields (pruned nodes
/// hold no edge; the status of a non-null sample is the pixel's own).
///
/// Receivers without an image layout are processed pixel-wise (steps 5 and 8 only).
/// Rect lights; disk and sphere lights with `sublights=1` (docs/methods.md §3 "Disk lights": the
/// same contours, each edge's chord inside the disk and its circular sector; "Sphere lights": each
/// receiver's edges carried onto its own silhouette disk first, packets sharing only the
/// classification and extraction); other `sublights` are an [`Error::Param`] with key
/// `sublights`.
///
/// [`ReceiverPlane::caster`]: shadow_map_core::ReceiverPlane::caster
pub struct CpuPacketHsm {
    params: Params,
    report: Report,
    diagnostics: Vec<PixelDiag>,
    cancel: Cancel,
}

impl CpuPacketHsm {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(CpuPacketHsm {
            params: Params::new(SPECS)?,
            report: Report::default(),
            diagnostics: Vec::new(),
            cancel: Cancel::new(),
        })
    }
    /// Per-receiver diagnostics of the last estimate (kernel size, visited nodes, packet class).
    pub fn diagnostics(&self) -> &[PixelDiag] {
        &self.diagnostics
    }
}

/// The packet size `(w, h)` of a `WxH` parameter value.
pub fn parse_packet(s: &str) -> Result<(u32, u32)> {
    let bad = || {
        Error::param(
            "packet",
            format!("expected WxH with W, H in 1..=8, got {s:?}"),
        )
    };
    let (a, b) = s.split_once('x').ok_or_else(bad)?;
    let w: u32 = a.parse().map_err(|_| bad())?;
    let h: u32 = b.parse().map_err(|_| bad())?;
    if !(1..=8).contains(&w) || !(1..=8).contains(&h) {
        return Err(bad());
    }
    Ok((w, h))
}

pub use shadow_map_core::mssm::kernel_width;

/// A packet size `WxH` (the `packet` parameter).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Packet {
    /// Pixels per packet row, W.
    pub w: u32,
    /// Rows per packet, H.
    pub h: u32,
}

impl Packet {
    /// `(w, h)`.
    pub fn size(self) -> (u32, u32) {
        (self.w, self.h)
    }
}

impl std::fmt::Display for Packet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.w, self.h)
    }
}

impl FromParam for Packet {
    /// A `WxH` word ([`parse_packet`]); `None` for anything else.
    fn from_param(v: ParamValue) -> Option<Self> {
        match v {
            ParamValue::Choice(word) => parse_packet(word).ok().map(|(w, h)| Packet { w, h }),
            _ => None,
        }
    }
}

shadow_map_core::typed_params! {
    /// Settings of one estimate, one field a parameter ([`SPECS`]).
    pub struct Config {
        /// Shadow-map resolution r of each sub-light's map.
        resolution: u32 = ParamSpec {
            help: "shadow-map resolution r (texels per side) of each sub-light's map",
            ..RESOLUTION
        },
        /// packet of WxH neighbouring pixels (Yang §4.1; 1x1 = per pixel); receivers without an
        /// image layout are processed pixel-wise
        packet: Packet = ParamSpec::choice(PACKETS, "3x3"),
        /// S: the light is split into S x S equal sub-lights, one shadow map + MSSM each, V
        /// averaged (Yang §5)
        sublights: u32 = ParamSpec::int(1, 4, "1"),
        /// most opacity levels, one pass each, for semi-transparent meshes (docs/methods.md §3
        /// "Semi-transparent occluders"): V = sum of level weights times V with only the meshes of
        /// at least that opacity as casters; a scene needing more levels (its distinct opacities,
        /// plus one without casters when no mesh is opaque) is treated as opaque; 1 = always opaque
        opacity_levels: u32 = ParamSpec::int(1, 16, "2"),
        /// Td: a packet whose diverging probability P_d (Yang eq. 5) exceeds Td is processed
        /// pixel-wise
        td: f64 = ParamSpec::float(0.0, 1.0, "0.8"),
        /// hierarchical contour extraction over the dual-grid MSSM (Yang §4.2, Algorithm 3); false:
        /// every 2x2 block of the kernel (GBP07)
        hierarchy: bool = ParamSpec::flag(true),
        /// coherence test (Yang §4.3: P_d > Td or cost ratio eq. 6 > 1 sends a packet pixel-wise);
        /// false: every packet is tried packet-wise
        coherence: bool = ParamSpec::flag(true),
        /// Q_e of the cost model (eq. 6): cost of extracting an edge, in units of Q_n = 1 (a node)
        qe: f64 = ParamSpec::float(0.0, 1e6, "2.0"),
        /// Q_v of the cost model (eq. 6): cost of backprojecting and integrating an edge for one
        /// pixel
        qv: f64 = ParamSpec::float(0.0, 1e6, "4.0"),
        ;
        /// Midpoint classification or a receiver bias, and receiver-plane rejection.
        shadow: SelfShadowSettings,
        /// Light-view window and near/far choice of every sub-light's map.
        view: ViewOptions,
    }
}

impl Config {
    fn traversal(&self) -> Traversal {
        if self.hierarchy {
            Traversal::Hierarchical
        } else {
            Traversal::Flat
        }
    }
}

/// Yang §4.3, the coherence test of a packet with extended kernel `k` (cells), threshold range
/// `[t_min, t_max]` and member kernel sides `w_i`:
///
/// - `P_null = max(min(t_max, zbar_max) - max(t_min, zbar_min), 0) / (zbar_max - zbar_min)`
///   (eq. 4), with `[zbar_min, zbar_max]` the depth range of the packet kernel (empty samples
///   counted at `far`);
/// - `P_d = 1 - (1 - P_null)^(wbar^2)` (eq. 5), `wbar` the packet kernel side; non-coherent when
///   `P_d > Td`;
/// - cost ratio (eq. 6), `Q_n = 1`, log base 2:
///   `(log(wbar) wbar + (Q_e + Q_v n) wbar) / sum_i (log(w_i) w_i + (Q_e + Q_v) w_i)`;
///   non-coherent when it exceeds 1.
///
/// Returns true for a coherent packet. Only speed depends on it.
pub fn coherence(
    dual: &PaddedDualMssm,
    k: &CellRect,
    t_min: f32,
    t_max: f32,
    sides: &[u32],
    far: f32,
    cfg: &Config,
) -> bool {
    let mm = dual.query(k);
    let zmin = mm.min.min(far) as f64;
    let zmax = mm.max.min(far) as f64;
    let (tmin, tmax) = (t_min as f64, t_max as f64);
    let inter = (tmax.min(zmax) - tmin.max(zmin)).max(0.0);
    let range = zmax - zmin;
    let p_null = if range > 0.0 {
        (inter / range).min(1.0)
    } else if tmin <= zmin && zmin < tmax {
        1.0
    } else {
        0.0
    };
    let wbar = kernel_side(k).max(1) as f64;
    let p_d = 1.0 - (1.0 - p_null).powf(wbar * wbar);
    if p_d > cfg.td {
        return false;
    }
    let n = sides.len() as f64;
    let packet = wbar.log2() * wbar + (cfg.qe + cfg.qv * n) * wbar;
    let pixels: f64 = sides
        .iter()
        .map(|&w| {
            let w = w.max(1) as f64;
            w.log2() * w + (cfg.qe + cfg.qv) * w
        })
        .sum();
    packet <= pixels
}

/// Counters of one estimate.
#[derive(Debug, Default)]
pub struct Counters {
    /// Penumbra receiver evaluations (over sub-lights).
    pub penumbra: AtomicU64,
    /// Nodes or cells visited.
    pub visited: AtomicU64,
    /// Packets with at least two penumbra pixels.
    pub packets: AtomicU64,
    /// Packets evaluated packet-wise.
    pub coherent: AtomicU64,
    /// Packets the coherence test sent pixel-wise.
    pub rejected: AtomicU64,
    /// Packets whose contours diverged (null status) and went pixel-wise.
    pub diverged: AtomicU64,
    /// Receivers projecting outside a map.
    pub outside: AtomicU64,
}

/// Per-pixel GBP07 for one penumbra receiver: `facing * V`, visited nodes.
fn pixel_wise(
    sv: &SubView,
    grid: &SampleGrid,
    cfg: &Config,
    rec: &Receiver,
    cr: &CellRect,
    facing: f32,
) -> (f32, u64) {
    let k = Scale::of(&sv.ls.view);
    let (v, n) = pixel_visibility(
        grid,
        &sv.dual,
        Some(&sv.mssm),
        sv.fit.as_ref(),
        cr,
        rec,
        k,
        &sv.emitter,
        cfg.traversal(),
    );
    (facing * v, n)
}

/// Steps 5-8 for one sub-light: adds `weight * V_k` to `acc` and fills the diagnostics.
/// Checks `cancel` before each packet column of each band of receiver rows:
/// `Err(Cancelled)` once it is set (`acc` then incomplete).
#[allow(clippy::too_many_arguments)]
pub fn estimate_sublight(
    sv: &SubView,
    cfg: &Config,
    receivers: &Receivers,
    weight: f32,
    acc: &mut [f32],
    diag: &mut [PixelDiag],
    counters: &Counters,
    cancel: &Cancel,
) -> Result<()> {
    let grid = sv.grid(cfg);
    let k = Scale::of(&sv.ls.view);
    let em = &sv.emitter;
    let far = sv.ls.view.far;
    let (pw, ph) = match receivers.layout() {
        Some(_) => cfg.packet.size(),
        None => (1, 1),
    };
    let width = receivers.layout().map_or(256, |l| l.width as usize).max(1);
    let chunk = width * ph as usize;
    acc.par_chunks_mut(chunk)
        .zip(diag.par_chunks_mut(chunk))
        .enumerate()
        .for_each(|(row, (acc, diag))| {
            let base = row * chunk;
            let rows = acc.len() / width;
            let mut pens: Vec<(usize, Receiver, CellRect, f32)> = Vec::with_capacity(64);
            let mut sides: Vec<u32> = Vec::with_capacity(64);
            let mut edges: Vec<(i32, i32, Edge)> = Vec::new();
            let mut members: Vec<OccluderTest> = Vec::with_capacity(64);
            let mut outside = 0u64;
            let mut local = [0u64; 6]; // penumbra, visited, packets, coherent, rejected, diverged
            let mut bx = 0usize;
            while bx < width {
                if cancel.is_cancelled() {
                    return;
                }
                pens.clear();
                let bw = (pw as usize).min(width - bx);
                for dy in 0..rows.max(1) {
                    for dx in 0..bw {
                        let li = dy * width + bx + dx;
                        if li >= acc.len() {
                            continue;
                        }
                        let gi = base + li;
                        if !receivers.active()[gi] {
                            continue;
                        }
                        let mut out = false;
                        let prep = prepare(
                            sv,
                            &grid,
                            cfg,
                            receivers.position()[gi],
                            receivers.normal()[gi],
                            &mut out,
                        );
                        outside += out as u64;
                        match prep {
                            Prep::Done(v) => acc[li] += weight * v,
                            Prep::Penumbra { rec, cr, facing } => {
                                diag[li].kernel = diag[li].kernel.max(kernel_side(&cr) as f32);
                                pens.push((li, rec, cr, facing));
                            }
                        }
                    }
                }
                bx += bw;
                if pens.is_empty() {
                    continue;
                }
                local[0] += pens.len() as u64;
                let mut done = false;
                if pens.len() >= 2 {
                    local[2] += 1;
                    let mut kk = pens[0].2;
                    let (mut tmin, mut tmax) = (pens[0].1.t, pens[0].1.t);
                    sides.clear();
                    for (_, rec, cr, _) in &pens {
                        kk = [
                            kk[0].min(cr[0]),
                            kk[1].min(cr[1]),
                            kk[2].max(cr[2]),
                            kk[3].max(cr[3]),
                        ];
                        tmin = tmin.min(rec.t);
                        tmax = tmax.max(rec.t);
                        sides.push(kernel_side(cr));
                    }
                    let coherent =
                        !cfg.coherence || coherence(&sv.dual, &kk, tmin, tmax, &sides, far, cfg);
                    if !coherent {
                        local[4] += 1;
                    } else {
                        edges.clear();
                        members.clear();
                        if cfg.shadow.receiver_plane {
                            members.extend(pens.iter().map(|(_, rec, _, _)| rec.test()));
                        }
                        let planes = Planes {
                            members: &members,
                            class_is_depth: grid.class_is_depth(),
                            depth: Some(&sv.mssm),
                            fit: sv.fit.as_ref(),
                        };
                        let mut visited = 0u64;
                        let ok = extract(
                            &grid,
                            &sv.dual,
                            &kk,
                            [tmin, tmax],
                            planes,
                            cfg.traversal(),
                            &mut visited,
                            |i, j, e| {
                                edges.push((i, j, *e));
                            },
                        );
                        local[1] += visited;
                        let share = visited as f32 / pens.len() as f32;
                        for (li, _, _, _) in &pens {
                            diag[*li].visited += share;
                        }
                        if ok {
                            local[3] += 1;
                            for (li, rec, cr, facing) in &pens {
                                let mut sum = 0.0f64;
                                for (i, j, e) in &edges {
                                    if *i >= cr[0] && *i < cr[2] && *j >= cr[1] && *j < cr[3] {
                                        sum += edge_area(e, rec, k, em);
                                    }
                                }
                                acc[*li] +=
                                    weight * facing * visibility_from_area(rec.centre, sum, em);
                                diag[*li].class = CLASS_PACKET;
                            }
                            done = true;
                        } else {
                            local[5] += 1;
                        }
                    }
                }
                if !done {
                    for (li, rec, cr, facing) in &pens {
                        let (v, n) = pixel_wise(sv, &grid, cfg, rec, cr, *facing);
                        acc[*li] += weight * v;
                        diag[*li].visited += n as f32;
                        diag[*li].class = CLASS_PIXEL;
                        local[1] += n;
                    }
                }
            }
            counters.outside.fetch_add(outside, Ordering::Relaxed);
            counters.penumbra.fetch_add(local[0], Ordering::Relaxed);
            counters.visited.fetch_add(local[1], Ordering::Relaxed);
            counters.packets.fetch_add(local[2], Ordering::Relaxed);
            counters.coherent.fetch_add(local[3], Ordering::Relaxed);
            counters.rejected.fetch_add(local[4], Ordering::Relaxed);
            counters.diverged.fetch_add(local[5], Ordering::Relaxed);
            cancel.add_progress(acc.len());
        });
    cancel.check()
}

/// V (with the facing factor) of one receiver on one sub-light, per pixel with the configured
/// traversal (what the engine path's kernel computes; its CPU twin, which redoes the receivers
/// the device cut short).
pub fn pixel_value(sv: &SubView, cfg: &Config, pw: Vec3, nw: Vec3) -> f32 {
    let grid = sv.grid(cfg);
    let mut out = false;
    match prepare(sv, &grid, cfg, pw, nw, &mut out) {
        Prep::Done(v) => v,
        Prep::Penumbra { rec, cr, facing } => pixel_wise(sv, &grid, cfg, &rec, &cr, facing).0,
    }
}

/// Per-pixel GBP07 on one sub-light for a single receiver (the exact baseline; tests and
/// examples): `facing * V` of sub-light data `sv`.
pub fn reference_pixel(sv: &SubView, cfg: &Config, pw: Vec3, nw: Vec3) -> f32 {
    let grid = sv.grid(cfg);
    let mut out = false;
    match prepare(sv, &grid, cfg, pw, nw, &mut out) {
        Prep::Done(v) => v,
        Prep::Penumbra { rec, cr, facing } => {
            let flat = Config {
                hierarchy: false,
                ..*cfg
            };
            pixel_wise(sv, &grid, &flat, &rec, &cr, facing).0
        }
    }
}

impl CpuPacketHsm {
    /// Rect lights with any `sublights`; disk, sphere and directional lights with `sublights=1` only (they
    /// are not cut into S x S sub-lights: an [`Error::Param`] with key `sublights`; the engine path too).
    pub(crate) fn check_light(light: &shadow_map_core::Light, cfg: &Config) -> Result<()> {
        match light.shape {
            LightShape::Rect { .. } => Ok(()),
            _ if cfg.sublights == 1 => Ok(()),
            _ => Err(Error::param(
                "sublights",
                "packet-hsm cuts only rect lights into S x S sub-lights; disk, sphere and directional lights (the sun) need sublights=1",
            )),
        }
    }
}

impl SoftShadowEstimator for CpuPacketHsm {
    shadow_map_core::estimator_identity!(NAME, DESCRIPTION, Cpu, params);
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.params.set(key, value)
    }
    fn set_cancel(&mut self, cancel: Cancel) {
        self.cancel = cancel;
    }
    fn build(&mut self, scene: &Scene, _receivers: &Receivers) -> Result<()> {
        // Multi-view: each sub-light's map is built inside `estimate`, one at a time.
        self.report = Report::default();
        Self::check_light(scene.light(), &Config::from_params(&self.params)?)
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        let cfg = Config::from_params(&self.params)?;
        Self::check_light(scene.light(), &cfg)?;
        let s = cfg.sublights;
        let mut subs = SubLights::new(&cfg, receivers.len());
        let mut diag = vec![PixelDiag::default(); receivers.len()];
        let counters = Counters::default();
        // Semi-transparent meshes: one pass per opacity level (docs/methods.md §3
        // "Semi-transparent occluders"); an opaque scene is one level of weight 1.
        let levels = OpacityLevels::new(scene, cfg.opacity_levels);
        for b in 0..s {
            for a in 0..s {
                for (level, lw) in levels.iter() {
                    self.cancel.check()?;
                    let sv = subs.build(level, receivers, &cfg, (a, b))?;
                    let t = std::time::Instant::now();
                    let w = subs.weight * lw;
                    let (acc, cancel) = (&mut subs.acc, &self.cancel);
                    estimate_sublight(&sv, &cfg, receivers, w, acc, &mut diag, &counters, cancel)?;
                    subs.t_est += t.elapsed().as_secs_f64() * 1e3;
                }
            }
        }
        levels.note(&mut self.report);
        self.diagnostics = diag;
        let rep = &mut self.report;
        let outside = counters.outside.load(Ordering::Relaxed) as usize;
        subs.finish(&cfg, receivers, v, outside, rep);
        let pen = counters.penumbra.load(Ordering::Relaxed);
        let vis = counters.visited.load(Ordering::Relaxed);
        rep.note("penumbra_evaluations", pen);
        rep.note("visited_nodes", vis);
        rep.note(
            "visited_per_penumbra_pixel",
            format!("{:.1}", vis as f64 / pen.max(1) as f64),
        );
        rep.note("packets", counters.packets.load(Ordering::Relaxed));
        rep.note(
            "packets_coherent",
            counters.coherent.load(Ordering::Relaxed),
        );
        rep.note(
            "packets_rejected",
            counters.rejected.load(Ordering::Relaxed),
        );
        rep.note(
            "packets_diverged",
            counters.diverged.load(Ordering::Relaxed),
        );
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}
