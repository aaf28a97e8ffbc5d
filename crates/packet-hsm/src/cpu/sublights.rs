//! The CPU twin's sub-light loop (Yang §5): opacity levels, the S x S sub-lights and each
//! sub-light's [`SubView`] (map, MSSM, padded dual-grid MSSM, own-plane bounds).
use super::extract::PaddedDualMssm;
use super::fit::DualFit;
use super::{prepare_receiver, Prep};
use crate::math::{contour::SampleGrid, radial::Emitter, sublight_centre};
use crate::settings::Config;
use glam::Vec2;
use rayon::prelude::*;
use shadow_map_core::{
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitReport, LightView},
    mssm::Mssm,
    Light, LightShape, OpacityLevel, RasterOptions, Receivers, Report, Result, Scene, Warning,
};

/// The opacity levels the CPU twin and the engine path run ([`Scene::opacity_levels`]): each level's scene (its
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
        let (run, needed) = levels_run(&all, max);
        let levels = run
            .into_iter()
            .map(|l| {
                let s = if l.min_opacity > 0.0 {
                    std::borrow::Cow::Owned(scene.with_opacity_at_least(l.min_opacity))
                } else {
                    std::borrow::Cow::Borrowed(scene)
                };
                (s, l.weight)
            })
            .collect();
        OpacityLevels { levels, needed }
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

/// The levels run for casters whose opacity levels are `all` ([`Scene::opacity_levels`], empty
/// when opaque), at most `max` of them: `all`, or one level of weight 1 casting every caster
/// (`min_opacity` 0) when opaque or when `all` has more than `max` (then also `(needed, max)`).
pub fn levels_run(all: &[OpacityLevel], max: u32) -> (Vec<OpacityLevel>, Option<(usize, usize)>) {
    let too_many = all.len() > max as usize;
    if all.is_empty() || too_many {
        let every = OpacityLevel {
            min_opacity: 0.0,
            weight: 1.0,
        };
        (vec![every], too_many.then_some((all.len(), max as usize)))
    } else {
        (all.to_vec(), None)
    }
}

/// The CPU twin's sub-light loop (Yang §5): the S x S sub-lights' [`SubView`]s built one at a
/// time, V summed over them with weight 1 / S^2, and what the report says about the fits.
pub struct SubLights {
    /// V summed so far, per receiver.
    pub acc: Vec<f32>,
    /// Weight of one sub-light, `1 / S^2`.
    pub weight: f32,
    /// Build time over the sub-lights (ms).
    pub t_build: f64,
    /// Estimate time over the sub-lights (ms), added by the estimator.
    pub t_est: f64,
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
            OwnPlane::Auto,
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
    /// and the notes the CPU twin gives; `outside`: receivers the estimate found outside a view.
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
        let (levels, _) = Self::levels(&view, half);
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
        let mut sv = SubView::in_maps(ls, scene.light(), half, cfg);
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
    /// The data of a sub-light of half extents `half` of `light` on maps already rendered in
    /// their view (layer 0, and its midpoints for `self_shadow=midpoint`: the CPU raster's, or
    /// the engine path's read back): the MSSM and the padded dual-grid MSSM built from them as
    /// [`SubView::build_in_view`] builds them, without the own-plane bounds.
    pub fn in_maps(ls: LightSpace, light: &Light, half: Vec2, cfg: &Config) -> SubView {
        let (levels, max_cells) = Self::levels(&ls.view, half);
        let l0 = &ls.layers[0];
        let mssm = Mssm::build(&l0.depth, l0.size, levels);
        let class = if cfg.shadow.midpoint() {
            ls.midpoints.first().map_or(&l0.depth, |m| &m.depth)
        } else {
            &l0.depth
        };
        let dual = PaddedDualMssm::build(class, l0.size, max_cells);
        let (emitter, shape) = emitter_of(light, half);
        SubView {
            ls,
            mssm,
            dual,
            fit: None,
            half,
            emitter,
            shape,
            light: *light,
        }
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
                match prepare_receiver(self, &grid, cfg, receivers, k).0 {
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
