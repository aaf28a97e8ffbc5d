//! The CPU twin: Yang et al. 2009, Algorithm 1, steps 2-8, over the exact per-pixel contour
//! backprojection ([`extract`](mod@extract), on the geometry of [`crate::math`]).
//!
//! - `setup`: step 5 for one receiver (set-up, tight kernel, trivial classification);
//! - `sublights`: the opacity levels and S x S sub-lights, one [`SubView`] (maps, MSSM, padded
//!   dual-grid MSSM) at a time;
//! - [`extract`](mod@extract): the padded dual-grid MSSM and the contour extraction over it (flat, or Yang's
//!   Algorithm 3), and the per-pixel GBP07;
//! - [`fit`]: the own-plane bounds the extraction's pruning may use.
use crate::math::contour::{CellRect, Edge, OccluderTest, Receiver, SampleGrid};
use crate::math::radial::{edge_area, visibility_from_area, Scale};
use crate::math::{diverging_probability, kernel_side, p_null, packet_pays};
use crate::settings::{Config, DESCRIPTION, NAME};
use extract::{extract, pixel_visibility, PaddedDualMssm, Planes};
use glam::Vec3;
use rayon::prelude::*;
use shadow_map_core::{
    Cancel, Configured, Error, LightShape, Receivers, Report, Result, Scene, SoftShadowEstimator,
};
use std::sync::atomic::{AtomicU64, Ordering};

pub mod extract;
pub mod fit;
mod setup;
mod sublights;
pub use setup::{
    kernel_light, prepare, prepare_receiver, setup_receiver, trivial, Prep, ReceiverSetup,
};
pub use sublights::{
    emitter_of, levels_run, OpacityLevels, OwnPlane, SubLights, SubView, OWN_PLANE_WORTH,
};

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
    /// The parameters and their typed settings.
    config: Configured<Config>,
    report: Report,
    diagnostics: Vec<PixelDiag>,
    cancel: Cancel,
}

impl CpuPacketHsm {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(CpuPacketHsm {
            config: Configured::new()?,
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

/// Yang §4.3, the coherence test of a packet with extended kernel `k` (cells), threshold range
/// `[t_min, t_max]` and member kernel sides `w_i`: [`p_null`] (eq. 4) over the packet kernel's
/// depth range (empty samples counted at `far`), non-coherent when the [`diverging_probability`]
/// (eq. 5) exceeds Td, or when the cost ratio (eq. 6, [`packet_pays`]) exceeds 1.
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
    let z = [mm.min.min(far) as f64, mm.max.min(far) as f64];
    let p_null = p_null(z, [t_min as f64, t_max as f64]);
    let wbar = kernel_side(k).max(1) as f64;
    if diverging_probability(p_null, wbar) > cfg.td {
        return false;
    }
    packet_pays(wbar, sides, cfg.qe, cfg.qv)
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
                        let (prep, out) = prepare_receiver(sv, &grid, cfg, receivers, gi);
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
    shadow_map_core::estimator_identity!(NAME, DESCRIPTION, Cpu, config: config, cancel: cancel);
    fn build(&mut self, scene: &Scene, _receivers: &Receivers) -> Result<()> {
        // Multi-view: each sub-light's map is built inside `estimate`, one at a time.
        self.report = Report::default();
        Self::check_light(scene.light(), self.config.settings())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        let cfg = *self.config.settings();
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
