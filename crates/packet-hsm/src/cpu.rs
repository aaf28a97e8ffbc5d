//! The CPU estimator: Yang et al. 2009, Algorithm 1, steps 2-8, over the exact per-pixel contour
//! backprojection of [`crate::contour`].
use crate::contour::Scale;
use crate::contour::{
    edge_area, extract, pixel_visibility, plane_threshold_range, true_min, visibility_from_area,
    CellRect, Edge, Emitter, OccluderTest, PaddedDualMssm, Planes, Receiver, SampleGrid, Traversal,
};
use crate::fit::DualFit;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use shadow_map_core::{
    light::front_fraction,
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitReport, LightView, ViewOptions, RESOLUTION},
    mssm::Mssm,
    params::FromParam,
    peeling::SelfShadowSettings,
    silhouette::Silhouette,
    Cancel, Error, Light, LightShape, ParamKind, ParamSpec, ParamValue, Params, RasterOptions,
    ReceiverPlane, Receivers, Report, Result, Scene, SoftShadowEstimator, Warning,
};
use std::sync::atomic::{AtomicU64, Ordering};

/// Registry name (shared with the GPU twin).
pub const NAME: &str = "packet-hsm";
/// One-line description (shared with the GPU twin).
pub const DESCRIPTION: &str = "packet-based hierarchical soft shadow mapping: contour backprojection over a dual-grid MSSM, pixel packets, coherence test, S x S sub-lights (Yang 2009, GBP07)";

/// Every packet size from 1x1 to 8x8 (`WxH`).
pub const PACKETS: &[&str] = &[
    "1x1", "1x2", "1x3", "1x4", "1x5", "1x6", "1x7", "1x8", "2x1", "2x2", "2x3", "2x4", "2x5",
    "2x6", "2x7", "2x8", "3x1", "3x2", "3x3", "3x4", "3x5", "3x6", "3x7", "3x8", "4x1", "4x2",
    "4x3", "4x4", "4x5", "4x6", "4x7", "4x8", "5x1", "5x2", "5x3", "5x4", "5x5", "5x6", "5x7",
    "5x8", "6x1", "6x2", "6x3", "6x4", "6x5", "6x6", "6x7", "6x8", "7x1", "7x2", "7x3", "7x4",
    "7x5", "7x6", "7x7", "7x8", "8x1", "8x2", "8x3", "8x4", "8x5", "8x6", "8x7", "8x8",
];

/// Parameters of [`CpuPacketHsm`] (shared with the GPU twin).
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
    /// The cancellation token `estimate` checks ([`SoftShadowEstimator::set_cancel`]), shared
    /// with the GPU twin.
    pub fn cancel(&self) -> &Cancel {
        &self.cancel
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
        /// Packet size.
        packet: Packet = ParamSpec {
            key: "packet",
            kind: ParamKind::Choice(PACKETS),
            default: "3x3",
            help: "packet of WxH neighbouring pixels (Yang §4.1; 1x1 = per pixel); receivers without an image layout are processed pixel-wise",
        },
        /// Sub-lights per side S.
        sublights: u32 = ParamSpec {
            key: "sublights",
            kind: ParamKind::Int { min: 1, max: 4 },
            default: "1",
            help: "S: the light is split into S x S equal sub-lights, one shadow map + MSSM each, V averaged (Yang §5)",
        },
        /// Most opacity levels.
        opacity_levels: u32 = ParamSpec {
            key: "opacity_levels",
            kind: ParamKind::Int { min: 1, max: 16 },
            default: "2",
            help: "most opacity levels, one pass each, for semi-transparent meshes (docs/methods.md §3 \"Semi-transparent occluders\"): V = sum of level weights times V with only the meshes of at least that opacity as casters; a scene needing more levels (its distinct opacities, plus one without casters when no mesh is opaque) is treated as opaque; 1 = always opaque",
        },
        /// Td.
        td: f64 = ParamSpec {
            key: "td",
            kind: ParamKind::Float { min: 0.0, max: 1.0 },
            default: "0.8",
            help: "Td: a packet whose diverging probability P_d (Yang eq. 5) exceeds Td is processed pixel-wise",
        },
        /// Hierarchical extraction.
        hierarchy: bool = ParamSpec {
            key: "hierarchy",
            kind: ParamKind::Bool,
            default: "true",
            help: "hierarchical contour extraction over the dual-grid MSSM (Yang §4.2, Algorithm 3); false: every 2x2 block of the kernel (GBP07)",
        },
        /// Coherence test.
        coherence: bool = ParamSpec {
            key: "coherence",
            kind: ParamKind::Bool,
            default: "true",
            help: "coherence test (Yang §4.3: P_d > Td or cost ratio eq. 6 > 1 sends a packet pixel-wise); false: every packet is tried packet-wise",
        },
        /// Q_e.
        qe: f64 = ParamSpec {
            key: "qe",
            kind: ParamKind::Float { min: 0.0, max: 1e6 },
            default: "2.0",
            help: "Q_e of the cost model (eq. 6): cost of extracting an edge, in units of Q_n = 1 (a node)",
        },
        /// Q_v.
        qv: f64 = ParamSpec {
            key: "qv",
            kind: ParamKind::Float { min: 0.0, max: 1e6 },
            default: "4.0",
            help: "Q_v of the cost model (eq. 6): cost of backprojecting and integrating an edge for one pixel",
        },
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

/// The opacity levels both twins run ([`Scene::opacity_levels`]): each level's scene (its
/// casters, the meshes of at least its opacity) and weight.
pub struct OpacityLevels<'a> {
    levels: Vec<(std::borrow::Cow<'a, Scene>, f32)>,
    /// Levels the scene needed when more than allowed (treated as opaque), and the cap.
    needed: Option<(usize, usize)>,
}

impl<'a> OpacityLevels<'a> {
    /// The levels of `scene`, at most `max` of them: itself with weight 1 when opaque, or when
    /// it needs more than `max` (then every mesh is treated as opaque: `too_many` says so).
    pub fn new(scene: &'a Scene, max: u32) -> Self {
        let all = if scene.is_opaque() {
            Vec::new()
        } else {
            scene.opacity_levels()
        };
        let needed = all.len();
        let too_many = needed > max as usize;
        let levels = if all.is_empty() || too_many {
            vec![(std::borrow::Cow::Borrowed(scene), 1.0)]
        } else {
            all.into_iter()
                .map(|l| {
                    let s = scene.with_opacity_at_least(l.min_opacity);
                    (std::borrow::Cow::Owned(s), l.weight)
                })
                .collect()
        };
        OpacityLevels {
            levels,
            needed: too_many.then_some((needed, max as usize)),
        }
    }
    /// Each level's scene and weight.
    pub fn iter(&self) -> impl Iterator<Item = (&Scene, f32)> + '_ {
        self.levels.iter().map(|(s, w)| (s.as_ref(), *w))
    }
    /// Notes the level count when there is more than one, or warns that the scene was treated
    /// as opaque because it needed more.
    pub fn note(&self, rep: &mut Report) {
        if let Some((needed, allowed)) = self.needed {
            rep.warn(Warning::OpacityLevelsCapped { needed, allowed });
        } else if self.levels.len() > 1 {
            rep.note("opacity_levels_run", self.levels.len());
        }
    }
}

/// The sub-light loop both twins run (Yang §5): the S x S sub-lights' [`SubView`]s built one at a
/// time, V summed over them with weight 1 / S^2, and what the report says about the fits.
pub struct SubLights {
    /// V summed so far, per receiver.
    pub acc: Vec<f32>,
    /// Weight of one sub-light, `1 / S^2`.
    pub weight: f32,
    /// Build time over the sub-lights (ms).
    pub t_build: f64,
    /// Estimate time over the sub-lights (ms), added by the twin.
    pub t_est: f64,
    /// Whether each sub-view builds its own-plane bounds ([`SubView::fit`]; `Auto` by default).
    /// The GPU twin turns them off: its traversal does not read them, and its CPU fallback does
    /// without.
    pub own_plane: OwnPlane,
    peak: usize,
    // Largest window side over the tightest one, smallest near and largest far plane, and the
    // largest out-of-frustum count, over the sub-lights' fits.
    window_scale: f32,
    near: f32,
    far: f32,
    out_of_frustum: usize,
}

impl SubLights {
    /// For `receivers` receivers.
    pub fn new(cfg: &Config, receivers: usize) -> Self {
        SubLights {
            acc: vec![0.0; receivers],
            weight: 1.0 / (cfg.sublights * cfg.sublights) as f32,
            t_build: 0.0,
            t_est: 0.0,
            own_plane: OwnPlane::Auto,
            peak: 0,
            window_scale: 0.0,
            near: f32::INFINITY,
            far: 0.0,
            out_of_frustum: 0,
        }
    }
    /// Builds sub-light (a, b)'s view and maps, timed, its fit folded into the tally.
    pub fn build(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        cfg: &Config,
        (a, b): (u32, u32),
    ) -> Result<SubView> {
        let t = std::time::Instant::now();
        let s = cfg.sublights;
        let half = scene.light().half_extent() / s as f32;
        let c = sublight_centre(scene.light().half_extent(), s, a, b);
        let sv = SubView::build(
            scene,
            receivers,
            (cfg.resolution, c, half),
            cfg,
            self.own_plane,
        )?;
        self.t_build += t.elapsed().as_secs_f64() * 1e3;
        self.peak = self.peak.max(sv.bytes());
        self.out_of_frustum = self.out_of_frustum.max(sv.ls.fit.out_of_frustum);
        self.window_scale = self.window_scale.max(sv.ls.fit.window_scale);
        self.near = self.near.min(sv.ls.view.n);
        self.far = self.far.max(sv.ls.view.far);
        Ok(sv)
    }
    /// Writes V (NaN for inactive receivers, the sum clamped to [0, 1], a non-finite sum as 0)
    /// and the notes both twins give; `outside`: receivers the estimate found outside a view.
    pub fn finish(
        self,
        cfg: &Config,
        receivers: &Receivers,
        v: &mut [f32],
        outside: usize,
        rep: &mut Report,
    ) {
        let mut nonfinite = 0usize;
        for (k, out) in v.iter_mut().enumerate() {
            *out = if !receivers.active()[k] {
                f32::NAN
            } else if self.acc[k].is_finite() {
                self.acc[k].clamp(0.0, 1.0)
            } else {
                nonfinite += 1;
                0.0
            };
        }
        rep.stages.push(("build".into(), self.t_build));
        rep.stages.push(("estimate".into(), self.t_est));
        rep.light_space_bytes = self.peak;
        rep.note("resolution", cfg.resolution);
        rep.note("sublights", cfg.sublights * cfg.sublights);
        rep.note("packet", cfg.packet);
        rep.note("hierarchy", cfg.hierarchy);
        rep.note("coherence", cfg.coherence);
        rep.note("out_of_frustum", outside + self.out_of_frustum);
        rep.note("near", self.near);
        rep.note("far", self.far);
        rep.note("window_scale", self.window_scale);
        rep.warn(Warning::NonFiniteV {
            receivers: nonfinite,
        });
        rep.warn(Warning::OutsideViews { receivers: outside });
    }
}

/// Centre of sub-light (a, b) of S x S in light-plane coordinates, for a light of half extents
/// `half`.
pub fn sublight_centre(half: Vec2, s: u32, a: u32, b: u32) -> Vec2 {
    let f = |k: u32, h: f32| ((k as f32 + 0.5) / s as f32 - 0.5) * 2.0 * h;
    Vec2::new(f(a, half.x), f(b, half.y))
}

/// Kernel cells per padded map sample ([`SubView::kernel_cells_estimate`] over `(r + 2)^2`)
/// above which the own-plane bounds are built: below, the extraction walks fewer cells than the
/// map has samples, and the bounds (about 90 single-thread instructions per sample to build)
/// would cost more than they save. Measured on the fixtures: 0.0004 to 0.64 on long-ground,
/// long-yard, backlit-stone and hover-sphere; 1.2 on hover-boxes; 5.6 to 6.2 on the grazing
/// fixtures; 24 to 4334 on the rest.
pub const OWN_PLANE_WORTH: f64 = 1.0;

/// Whether a [`SubView`] builds its own-plane bounds (with receiver-plane rejection only).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OwnPlane {
    /// Never.
    Off,
    /// When the kernels are large enough for them to pay ([`OWN_PLANE_WORTH`]).
    Auto,
    /// Always (tests).
    Always,
}

/// One sub-light's light-space data: the map, its MSSM, the padded dual-grid MSSM of the
/// classification depths. Only one is alive at a time.
pub struct SubView {
    /// The view and layers (layer 0; midpoints when asked for).
    pub ls: LightSpace,
    /// Anchored MSSM of the true depths (kernels).
    pub mssm: Mssm,
    /// Padded dual-grid MSSM of the classification depths (classification, pruning).
    pub dual: PaddedDualMssm,
    /// Affine bounds of the reciprocal true depths over blocks of the map (own-plane pruning,
    /// [`DualFit`]; with midpoints also each block's smallest true depth); `None` without
    /// receiver-plane rejection (where they would prove nothing the classic test needs), when not
    /// asked for, or when the kernels are too small for them to pay ([`OWN_PLANE_WORTH`]).
    pub fit: Option<DualFit>,
    /// Sub-light half extents (of the bounding square for disk and sphere lights; a disk's kernel,
    /// docs/methods.md §3 "Disk lights").
    pub half: Vec2,
    /// The (sub-)light the radial integration measures: the rect sub-light, the disk, or the
    /// sphere (its silhouette disk per receiver).
    pub emitter: Emitter,
    /// The (sub-)light's shape in its frame, for the facing fraction of rect and disk lights.
    pub shape: LightShape,
    /// The scene's light (a sphere's facing fraction is taken in world space,
    /// [`Light::front_fraction_world`]).
    pub light: Light,
}

impl SubView {
    /// Builds the data of the sub-light centred at `centre` (light-plane coordinates) with half
    /// extents `half` on an `r x r` map, its view fitted with the `fit` and `nearfar` choices of
    /// `cfg.view` ([`LightView::fit_with`]); `own_plane`: whether to build the own-plane bounds
    /// too.
    pub fn build(
        scene: &Scene,
        receivers: &Receivers,
        (r, centre, half): (u32, Vec2, Vec2),
        cfg: &Config,
        own_plane: OwnPlane,
    ) -> Result<SubView> {
        let (view, fit) = Self::fit(scene, receivers, (r, centre, half), cfg)?;
        Self::build_in_view(scene, receivers, view, fit, half, cfg, own_plane)
    }

    /// The view [`SubView::build`] fits for the sub-light centred at `centre` with half extents
    /// `half` on an `r x r` map.
    pub fn fit(
        scene: &Scene,
        receivers: &Receivers,
        (r, centre, half): (u32, Vec2, Vec2),
        cfg: &Config,
    ) -> Result<(LightView, FitReport)> {
        let frame = shadow_map_core::light_space::point_frame(scene.light(), centre)?;
        LightView::fit_with(scene, receivers, frame, half, r, &cfg.view)
    }

    /// The MSSM's levels and the most dual cells a kernel spans ([`PaddedDualMssm::build`]'s
    /// `max_cells`) for a sub-light of half extents `half` in `view`: what the view alone decides.
    pub fn levels(view: &LightView, half: Vec2) -> (u32, u32) {
        let r = view.r;
        let l = 2.0 * half.max_element();
        let wmax = view.kernel_texels(l, view.n, view.far).clamp(1.0, r as f32) + 2.0;
        let levels = (wmax.log2().ceil() as u32).clamp(1, 16);
        let max_cells = (wmax.ceil() as u32).saturating_add(3).min(r + 2);
        (levels, max_cells)
    }

    /// [`SubView::build`] in a given `view` (fitted by [`SubView::fit`] or by the caller: the
    /// engine path's CPU twin).
    pub fn build_in_view(
        scene: &Scene,
        receivers: &Receivers,
        view: LightView,
        fit: FitReport,
        half: Vec2,
        cfg: &Config,
        own_plane: OwnPlane,
    ) -> Result<SubView> {
        let r = view.r;
        let (levels, max_cells) = Self::levels(&view, half);
        let req = LightSpaceRequest {
            resolution: r,
            layers: 1,
            midpoints: cfg.shadow.midpoint_clamp(&view),
            mssm_levels: None,
            dual_mssm_levels: None,
            pyramid: false,
            raster: RasterOptions::default(),
            opacity: false,
        };
        // The light space, the MSSM and the padded dual-grid MSSM (two planes a level), refused
        // together before any is allocated when they cannot fit in host memory.
        let p = r as u64 + 2;
        let dual_levels = (p as f64).log2().floor() as u64 + 1;
        shadow_map_core::light_space::check_host_bytes(
            "packet-hsm light-space bytes (half the host memory available)",
            req.host_bytes(r)
                + 4 * r as u64 * r as u64 * (levels as u64 + 1)
                + 8 * p * p * dual_levels,
        )?;
        let ls = LightSpace::build_in_view(scene, view, fit, &req);
        let l0 = &ls.layers[0];
        let mssm = Mssm::build(&l0.depth, l0.size, levels);
        let class = if cfg.shadow.midpoint() {
            ls.midpoints.first().map_or(&l0.depth, |m| &m.depth)
        } else {
            &l0.depth
        };
        let dual = PaddedDualMssm::build(class, l0.size, max_cells);
        let (emitter, shape) = emitter_of(scene.light(), half);
        let mut sv = SubView {
            ls,
            mssm,
            dual,
            fit: None,
            half,
            emitter,
            shape,
            light: *scene.light(),
        };
        // The own-plane bounds are affine bounds of 1/z, a perspective view's planar depth
        // term; an orthographic view (the sun) has planes affine in z itself: not built there.
        let build = cfg.shadow.receiver_plane
            && !sv.ls.view.is_ortho()
            && match own_plane {
                OwnPlane::Off => false,
                OwnPlane::Always => true,
                OwnPlane::Auto => {
                    let walk = sv.kernel_cells_estimate(cfg, receivers);
                    walk > OWN_PLANE_WORTH * (r as f64 + 2.0).powi(2)
                }
            };
        if build {
            let l0 = &sv.ls.layers[0];
            sv.fit = Some(DualFit::build(
                &l0.depth,
                l0.size,
                sv.dual.mssm.levels() + 1,
                cfg.shadow.midpoint(),
            ));
        }
        Ok(sv)
    }
    /// The dual cells of the penumbra receivers' kernels summed, from every 8th receiver
    /// (times 8): the most cells the extraction could walk. Decides whether the own-plane bounds
    /// are worth building ([`OWN_PLANE_WORTH`]).
    pub fn kernel_cells_estimate(&self, cfg: &Config, receivers: &Receivers) -> f64 {
        const STEP: usize = 8;
        let grid = self.grid(cfg);
        let cells: u64 = (0..receivers.len().div_ceil(STEP))
            .into_par_iter()
            .map(|i| {
                let k = i * STEP;
                if !receivers.active()[k] {
                    return 0;
                }
                let mut out = false;
                match prepare(
                    self,
                    &grid,
                    cfg,
                    receivers.position()[k],
                    receivers.normal()[k],
                    &mut out,
                ) {
                    Prep::Penumbra { cr, .. } => {
                        ((cr[2] - cr[0]).max(0) as u64) * ((cr[3] - cr[1]).max(0) as u64)
                    }
                    Prep::Done(_) => 0,
                }
            })
            .sum();
        cells as f64 * STEP as f64
    }
    /// The sample grid (true and classification depths).
    pub fn grid(&self, cfg: &Config) -> SampleGrid<'_> {
        let l0 = &self.ls.layers[0];
        let class = if cfg.shadow.midpoint() {
            self.ls.midpoints.first().map_or(&l0.depth, |m| &m.depth)
        } else {
            &l0.depth
        };
        SampleGrid {
            size: l0.size,
            depth: &l0.depth,
            class,
        }
    }
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.ls.bytes()
            + self.mssm.bytes()
            + self.dual.bytes()
            + self.fit.as_ref().map_or(0, DualFit::bytes)
    }
}

/// The (sub-)light the radial integration measures, and its shape in the sub-light's frame (for
/// the facing fraction), for a sub-light of half extents `half` of `light`.
pub fn emitter_of(light: &Light, half: Vec2) -> (Emitter, LightShape) {
    match light.shape {
        LightShape::Disk { radius } => (Emitter::Disk(radius as f64), light.shape),
        // The sun: its disk of directions at unit distance (docs/methods.md §14).
        LightShape::Directional { .. } => {
            (Emitter::Disk(light.shape.tan_half() as f64), light.shape)
        }
        LightShape::Sphere { radius } => (Emitter::Sphere(radius as f64), light.shape),
        _ => (
            Emitter::Rect(half.as_dvec2()),
            LightShape::Rect {
                size: [2.0 * half.x, 2.0 * half.y],
            },
        ),
    }
}

/// The outcome of step 5 for one receiver and one sub-light.
#[derive(Debug, Clone, Copy)]
pub enum Prep {
    /// V (with the facing factor) is known: behind, outside, fully lit or fully occluded.
    Done(f32),
    /// A penumbra receiver.
    Penumbra {
        /// The receiver as the contour sees it.
        rec: Receiver,
        /// Its kernel in dual cells.
        cr: CellRect,
        /// The facing fraction of the sub-light.
        facing: f32,
    },
}

/// The per-receiver setup that needs no map (shared by the CPU and GPU twins).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReceiverSetup {
    /// V (with the facing factor) is known: behind the light, facing away, nearer than n.
    Settled(f32),
    /// Projects outside the map (counted): V = facing.
    Outside(f32),
    /// Needs the map: texel coordinates, depth, classification threshold, facing fraction.
    Map {
        /// `(u_p, v_p)`.
        uv: Vec2,
        /// `z_p`.
        zp: f32,
        /// `t_p` (`z_p` with midpoints or the receiver plane, `z_p - eps` with the bias).
        t: f32,
        /// Fraction of the sub-light in front of the receiver's tangent plane.
        facing: f32,
        /// The receiver plane (`receiver_plane=true`): a sample occludes only if it also passes
        /// [`ReceiverPlane::caster`] on its true depth (with the bias, instead of the bias test).
        plane: Option<ReceiverPlane>,
        /// A sphere light's silhouette disk seen from the receiver.
        sil: Option<Silhouette>,
    },
}

/// Step 5, the part without maps: light-space transform, facing fraction of the sub-light (the
/// contract's tangent-plane term), projection, classification threshold.
pub fn setup_receiver(sv: &SubView, cfg: &Config, pw: Vec3, nw: Vec3) -> ReceiverSetup {
    let view = &sv.ls.view;
    let p = view.frame.to_light(pw);
    let n = view.frame.dir_to_light(nw);
    let (facing, sil) = match sv.emitter {
        Emitter::Sphere(r) => {
            // Two-sided: the contract's silhouette disk in world space; a receiver behind the
            // map's plane or whose silhouette reaches its depth is outside every view (V = facing,
            // as backprojection does).
            let facing = sv.light.front_fraction_world(pw, nw);
            if !(facing > 0.0) {
                return ReceiverSetup::Settled(0.0);
            }
            match Silhouette::new(p, r as f32).filter(|_| p.z > 0.0) {
                Some(s) => (facing, Some(s)),
                None => return ReceiverSetup::Outside(facing),
            }
        }
        // The sun: its disk of directions one unit from p (Light::front_fraction_world).
        _ if view.is_ortho() => (front_fraction(&sv.shape, Vec3::Z, n), None),
        _ => {
            if !(p.z > 0.0) {
                return ReceiverSetup::Settled(0.0);
            }
            (front_fraction(&sv.shape, p, n), None)
        }
    };
    if !(facing > 0.0) {
        return ReceiverSetup::Settled(0.0);
    }
    if p.z <= view.n {
        return ReceiverSetup::Settled(facing);
    }
    let uv = view.project(p);
    if !view.contains(uv) {
        return ReceiverSetup::Outside(facing);
    }
    let t = if cfg.shadow.midpoint() || cfg.shadow.receiver_plane {
        p.z
    } else {
        p.z - view.receiver_bias(p, n, cfg.shadow.bias, cfg.shadow.slope_bias)
    };
    let plane = cfg
        .shadow
        .receiver_plane
        .then(|| ReceiverPlane::plane(view, p, n, cfg.shadow.bias, 0.0));
    ReceiverSetup::Map {
        uv,
        zp: p.z,
        t,
        facing,
        plane,
        sil,
    }
}

/// [`setup_receiver`] for every receiver (inactive ones: `Settled(0)`), in parallel.
pub fn prepare_setup(sv: &SubView, cfg: &Config, receivers: &Receivers) -> Vec<ReceiverSetup> {
    (0..receivers.len())
        .into_par_iter()
        .map(|k| {
            if receivers.active()[k] {
                setup_receiver(sv, cfg, receivers.position()[k], receivers.normal()[k])
            } else {
                ReceiverSetup::Settled(0.0)
            }
        })
        .collect()
}

/// Step 5 for one receiver: [`setup_receiver`], then the tight kernel from the MSSM and the
/// trivial classification. `outside` is set when the receiver projects outside the map.
pub fn prepare(
    sv: &SubView,
    grid: &SampleGrid,
    cfg: &Config,
    pw: Vec3,
    nw: Vec3,
    outside: &mut bool,
) -> Prep {
    let (uv, zp, t, facing, plane, sil) = match setup_receiver(sv, cfg, pw, nw) {
        ReceiverSetup::Settled(x) => return Prep::Done(x),
        ReceiverSetup::Outside(x) => {
            *outside = true;
            return Prep::Done(x);
        }
        ReceiverSetup::Map {
            uv,
            zp,
            t,
            facing,
            plane,
            sil,
        } => (uv, zp, t, facing, plane, sil),
    };
    let Some(cr) = kernel_cells(
        &sv.ls.view,
        &sv.mssm,
        uv,
        zp,
        kernel_light(sv, sil.as_ref()),
    ) else {
        return Prep::Done(facing);
    };
    let mm = sv.dual.query(&cr);
    let test = OccluderTest { t, plane };
    let (lit, umbra) = trivial(mm.min, mm.max, &test, &cr, || {
        true_min(
            grid.class_is_depth(),
            Some(&sv.mssm),
            mm.min,
            [cr[0], cr[1], cr[2], cr[3]],
        )
    });
    if lit {
        return Prep::Done(facing); // fully lit
    }
    if umbra {
        return Prep::Done(0.0); // fully occluded (umbra)
    }
    let mut rec = Receiver::with_test(grid, uv.as_dvec2(), zp as f64, test);
    rec.sil = sil;
    Prep::Penumbra { rec, cr, facing }
}

/// The light size `l` of a receiver's kernel ([`kernel_cells`]): the (sub-)light's bounding
/// rectangle (a disk's bounding square is conservative, docs/methods.md §3 "Disk lights"), or for
/// a sphere the smallest rectangle centred on the light's centre holding [`Silhouette::clip`]
/// (the image on z = 0 of the silhouette disk seen from the receiver: every sample whose
/// backprojection meets the disk's image lies in that kernel; §3 "Sphere lights").
pub fn kernel_light(sv: &SubView, sil: Option<&Silhouette>) -> Vec2 {
    match sil {
        Some(s) => {
            2.0 * Vec2::new(
                s.clip[0].abs().max(s.clip[2].abs()),
                s.clip[1].abs().max(s.clip[3].abs()),
            )
        }
        None => 2.0 * sv.half,
    }
}

/// Step 5's trivial classification of a kernel `cr` whose classification depths span
/// `[min, max]`: `(fully lit, fully occluded)`. Classic test: `min >= t` / `max < t`. With a
/// receiver plane, fully occluded also needs `max` below the plane's smallest threshold over the
/// kernel's samples, and fully lit also holds when the kernel's smallest true depth
/// (`true_min()`, see [`true_min`]) reaches its largest threshold ([`plane_threshold_range`],
/// conservative).
pub fn trivial(
    min: f32,
    max: f32,
    test: &OccluderTest,
    cr: &CellRect,
    true_min: impl FnOnce() -> f32,
) -> (bool, bool) {
    if test.plane.is_none() {
        return (!(min < test.t), max < test.t);
    }
    if !(min < test.t) {
        return (true, false);
    }
    // Cells [x0, x1) touch samples [x0, x1] (inclusive).
    let (lo, hi) = plane_threshold_range(std::slice::from_ref(test), [cr[0], cr[1], cr[2], cr[3]]);
    if true_min() >= hi {
        return (true, false);
    }
    (false, max < test.t && max < lo)
}

/// The tight kernel of a receiver in dual cells (Yang eq. 1 with the MSSM, docs/methods.md §2
/// "Refining the kernel"), or `None` when no sample it could see is nearer than `z_p` (lit).
///
/// Samples rect `[x0, x1)` from `W = alpha l (1/z_m - 1/z_p)` around `(u_p, v_p)`, starting at
/// `z_m = n`; `z_m` is then the exact minimum depth over the samples touched by the cells
/// `[x0 - 1, x1)` (the cells touching the rect), until the kernel stops shrinking. Cells are
/// clamped to anchors `[-1, r)`.
pub fn kernel_cells(view: &LightView, mssm: &Mssm, uv: Vec2, zp: f32, l: Vec2) -> Option<CellRect> {
    let r = view.r as f32;
    let rect = |zm: f32| -> [i32; 4] {
        let (wx, wy) = (
            view.kernel_texels(l.x, zm, zp),
            view.kernel_texels(l.y, zm, zp),
        );
        let lo = |c: f32, w: f32| (c - 0.5 * w).floor().clamp(0.0, r) as i32;
        let hi = |c: f32, w: f32| (c + 0.5 * w).ceil().clamp(0.0, r) as i32;
        [lo(uv.x, wx), lo(uv.y, wy), hi(uv.x, wx), hi(uv.y, wy)]
    };
    let area = |q: &[i32; 4]| (q[2] - q[0]) as i64 * (q[3] - q[1]) as i64;
    let mut zm = view.n;
    let mut s = rect(zm);
    for _ in 0..16 {
        let zmin = mssm.query(s[0] - 1, s[1] - 1, s[2] + 1, s[3] + 1).min;
        if !(zmin < zp) {
            return None;
        }
        if !(zmin > zm) {
            break;
        }
        zm = zmin;
        let next = rect(zm);
        if area(&next) >= area(&s) {
            break;
        }
        s = next;
    }
    if s[0] >= s[2] || s[1] >= s[3] {
        return None;
    }
    Some([s[0] - 1, s[1] - 1, s[2], s[3]])
}

/// Side of a kernel in cells (`w_i` of eq. 6).
#[inline]
pub fn kernel_side(cr: &CellRect) -> u32 {
    (cr[2] - cr[0]).max(cr[3] - cr[1]).max(0) as u32
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
/// traversal (the GPU twin's fallback for receivers the device cut short).
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
    /// are not cut into S x S sub-lights: an [`Error::Param`] with key `sublights`; both twins).
    pub(crate) fn check_light(scene: &Scene, cfg: &Config) -> Result<()> {
        match scene.light().shape {
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
        Self::check_light(scene, &Config::from_params(&self.params)?)
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        let cfg = Config::from_params(&self.params)?;
        Self::check_light(scene, &cfg)?;
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
