//! The CPU twin, [`CpuDeepShadow`], and the per-view set-up both twins share: sub-light points,
//! the fitted view of each, and what each receiver looks up in it.
use crate::dsm::{transmittance_opaque_plane, DeepShadowMap, Filter, LookupSettings, SoftLookup};
use crate::params::{self, Settings, DESCRIPTION, NAME, SPECS};
use crate::raster::{fragments, prepare};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use shadow_map_core::soft_transmittance::is_disk;
use shadow_map_core::{
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitMode, FitReport, ViewOptions, MAX_TAN},
    Cancel, DepthMap, Light, LightShape, LightView, Params, ReceiverPlane, Receivers, Report,
    Result, Scene, SoftShadowEstimator,
};
use std::time::Instant;

/// The sub-light points, light-plane coordinates relative to the light centre: S = 1 is the centre
/// (the paper's point light); S > 1 the S x S stratum centres (`Light::stratified_points` without
/// jitter; concentric-mapped for disks and spheres).
pub fn sublight_points(scene: &Scene, s: u32) -> Vec<Vec2> {
    if s <= 1 {
        vec![Vec2::ZERO]
    } else {
        scene.light().stratified_points(s, |_| Vec2::splat(0.5))
    }
}

/// The view of the point light at `y` (light-plane coordinates) with the default light-view
/// options: [`sublight_view_with`] and [`ViewOptions::default`].
pub fn sublight_view(
    scene: &Scene,
    receivers: &Receivers,
    y: Vec2,
    r: u32,
    margin: u32,
) -> Result<(LightView, FitReport)> {
    sublight_view_with(scene, receivers, y, r, margin, &ViewOptions::default())
}

/// The view of the point light at `y` (light-plane coordinates): centre of projection there, axes
/// parallel to the light frame, fitted to the receivers by [`LightView::fit_with`] with `opts`
/// (`fit`, `nearfar`), then given `margin` texels on every side (keeping r), so an N x N filter
/// kernel (`margin = N / 2`) around any receiver stays inside the map (docs/methods.md §1
/// "Coverage": the window must hold every receiver's projection plus half its kernel).
///
/// `fit=receivers` and `fit=scene`: the window is widened by `margin` texels of the widened map on
/// every side. `fit=stable`: widening would change the texel pitch and leave the fit's fixed
/// lattice, so the margin is made on that lattice instead ([`stable_margin`]): the window is
/// shifted by whole texels, or, where the receivers' projections plus the margins span more than
/// r texels, its side doubled (the next power of two, corner snapped to the coarser lattice).
/// The report's `window_scale` is the final window's.
pub fn sublight_view_with(
    scene: &Scene,
    receivers: &Receivers,
    y: Vec2,
    r: u32,
    margin: u32,
    opts: &ViewOptions,
) -> Result<(LightView, FitReport)> {
    sublight_view_reaching(scene, receivers, y, Vec2::ZERO, r, margin, opts)
}

/// [`sublight_view_with`] for a view that stands for a light of half extent `half` (per axis,
/// light-plane units) around `y`: [`LightView::fit_with`] grows each receiver's footprint by the
/// cut of its pyramid to that light (docs/methods.md §1 "Coverage"), so `filter=pcss`'s blocker
/// search and kernel, which stay inside that cut, stay inside the map. `half = 0`: the point
/// light at `y`.
pub fn sublight_view_reaching(
    scene: &Scene,
    receivers: &Receivers,
    y: Vec2,
    half: Vec2,
    r: u32,
    margin: u32,
    opts: &ViewOptions,
) -> Result<(LightView, FitReport)> {
    let frame = shadow_map_core::light_space::point_frame(scene.light(), y)?;
    let (mut view, mut fit) = LightView::fit_with(scene, receivers, frame, half, r, opts)?;
    if margin == 0 || r <= 2 * margin {
        return Ok((view, fit));
    }
    let w0 = view.w;
    if opts.fit == FitMode::Stable {
        if let Some(v) = stable_margin(&view, receivers, margin) {
            view = v;
        }
    } else {
        let w = view.w * r as f32 / (r - 2 * margin) as f32;
        view.window_min -= Vec2::splat(margin as f32 * w / r as f32);
        view.w = w;
    }
    if w0 > 0.0 {
        fit.window_scale *= view.w / w0;
    }
    Ok((view, fit))
}

/// Texels of slack in [`stable_margin`]'s bounds, for the f32 rounding of the receivers'
/// projections (the kernels are placed from `floor(u)`).
const MARGIN_SLACK: f64 = 0.01;

/// The margin of `margin` texels for a `fit=stable` view, on its texel lattice: the window's
/// corner and side are whole multiples of the pitch `d = s / r` in `x/z` units (s, the side in
/// `x/z` units, a power of two), so the same world point keeps the same texels, and V, while the
/// camera pans. The window is shifted by the fewest whole texels that put every texel of every
/// receiver's `(2 margin + 1)^2` kernel inside it; where the kernels span more than r texels, s is
/// doubled (and the corner snapped down to the coarser lattice) until they fit. Receivers counted:
/// active, nearer the light than n, within [`MAX_TAN`] (those the fit covers). `None` when the
/// view is not on a power-of-two lattice (a fit with no receiver in front of the light) or
/// nothing fits within 64 doublings: the caller keeps the view.
///
/// An orthographic view (the sun) has its lattice in world units: the same rule with `x, y` for
/// `x/z, y/z` and 1 for n.
pub fn stable_margin(view: &LightView, receivers: &Receivers, margin: u32) -> Option<LightView> {
    let ortho = view.is_ortho();
    let n = if ortho { 1.0 } else { view.n as f64 };
    let r = view.r as i64;
    let h = margin as i64;
    // The receivers' bounds in x/z units.
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for (k, pw) in receivers.position().iter().enumerate() {
        if !receivers.active()[k] {
            continue;
        }
        let p = view.frame.to_light(*pw);
        if !(p.z > view.n) {
            continue;
        }
        let t = if ortho {
            [p.x as f64, p.y as f64]
        } else {
            [p.x as f64 / p.z as f64, p.y as f64 / p.z as f64]
        };
        let in_frustum = t[0].abs() <= MAX_TAN as f64 && t[1].abs() <= MAX_TAN as f64;
        if !(ortho || in_frustum) {
            continue;
        }
        for a in 0..2 {
            lo[a] = lo[a].min(t[a]);
            hi[a] = hi[a].max(t[a]);
        }
    }
    if !(lo[0] <= hi[0] && lo[1] <= hi[1] && n > 0.0) || r < 1 {
        return None;
    }
    // The fit's lattice: s a power of two, the corner a whole number of pitches.
    let s0 = view.w as f64 / n;
    let mut s = 2f64.powi(s0.log2().round() as i32);
    if !(s.is_finite() && s > 0.0) || (s0 / s - 1.0).abs() > 1e-4 {
        return None;
    }
    let mut d = s / r as f64;
    let c = [
        view.window_min.x as f64 / n / d,
        view.window_min.y as f64 / n / d,
    ];
    if c.iter()
        .any(|c| !c.is_finite() || (c - c.round()).abs() > 1e-3)
    {
        return None;
    }
    let mut k0 = [c[0].round() as i64, c[1].round() as i64];
    for _ in 0..64 {
        let mut corner = [0i64; 2];
        let mut fits = true;
        for a in 0..2 {
            // Lattice indices of the first and last texel any kernel reads.
            let first = (lo[a] / d - MARGIN_SLACK).floor() as i64 - h;
            let last = (hi[a] / d + MARGIN_SLACK).floor() as i64 + h;
            if last - first + 1 > r {
                fits = false;
                break;
            }
            // The corner index K keeps [first, last] inside [K, K + r - 1], nearest the fit's.
            corner[a] = k0[a].clamp(last - r + 1, first);
        }
        if fits {
            // As the fit computes it: (k d) n, in f64, then f32.
            let at = |k: i64| (k as f64 * d * n) as f32;
            return Some(LightView {
                window_min: Vec2::new(at(corner[0]), at(corner[1])),
                w: (s * n) as f32,
                ..*view
            });
        }
        s *= 2.0;
        d *= 2.0;
        k0 = [k0[0].div_euclid(2), k0[1].div_euclid(2)];
    }
    None
}

/// Texels of filter margin a view needs: `N / 2` for PCF and EDSM, 0 otherwise (`pcss` reads
/// texels outside the map as empty, as PCSS does).
pub fn kernel_margin(s: &Settings) -> u32 {
    match s.filter {
        Filter::Pcf | Filter::Edsm => s.kernel / 2,
        _ => 0,
    }
}

/// What one receiver needs from one view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Query {
    /// A fixed transmittance, no lookup: 0 when the point light is behind the receiver's tangent
    /// plane (`filter=pcss`: the view's light wholly behind it) or the receiver behind the light
    /// point; the facing factor (1 but under `pcss`) when the receiver is nearer than n (nothing
    /// recorded is nearer).
    Fixed(f32),
    /// Look up at continuous texel coordinates `uv` with the receiver's caster test.
    Look {
        /// Texel coordinates.
        uv: Vec2,
        /// Which fragments attenuate: receiver-plane rejection, or the classic `z < z_p - eps`
        /// with `receiver_plane=false` ([`ReceiverPlane::new`]).
        plane: ReceiverPlane,
        /// The factor the filtered transmittance is multiplied by: 1, or under `filter=pcss` the
        /// fraction of the view's light in front of the receiver's tangent plane
        /// ([`facing`]).
        facing: f32,
    },
}

/// The tangent-plane factor of the receiver at `pw` with normal `nw` in `view`: 1 when the
/// view's point is in front of the tangent plane, 0 otherwise; under `filter=pcss` the exact
/// fraction of the view's light ([`view_light`]) in front of it, as PCSS weights its filter
/// (`Light::front_fraction_world`; docs/methods.md §8 "Percentage-closer soft transmittance").
pub fn facing(view: &LightView, light: &Light, pw: Vec3, nw: Vec3, s: &Settings) -> f32 {
    // The sun: the view looks along its (sub-)direction e_z; light arrives from -e_z.
    let towards = if view.is_ortho() {
        -view.frame.ez
    } else {
        view.frame.origin - pw
    };
    if s.filter == Filter::Pcss {
        view_light(light, view, s.sublights).front_fraction_world(pw, nw)
    } else if nw.dot(towards) > 0.0 {
        1.0
    } else {
        0.0
    }
}

/// The query of a receiver at world position `pw`, normal `nw`, in `view` (centre of projection
/// `view.frame.origin`) of `light`.
pub fn query(view: &LightView, light: &Light, pw: Vec3, nw: Vec3, s: &Settings) -> Query {
    let facing = facing(view, light, pw, nw, s);
    if !(facing > 0.0) {
        return Query::Fixed(0.0);
    }
    let p = view.frame.to_light(pw);
    if !(p.z > 0.0) {
        return Query::Fixed(0.0);
    }
    if p.z <= view.n {
        return Query::Fixed(facing);
    }
    let n = view.frame.dir_to_light(nw);
    Query::Look {
        uv: view.project(p),
        plane: ReceiverPlane::new(s.receiver_plane, view, p, n, (s.bias, s.slope_bias), 0.0),
        facing,
    }
}

/// Marks in `outside` every active receiver that looks up outside `view`'s map (beyond the
/// light view's reach, [`MAX_TAN`] off the light's axis): no map holds its casters there.
pub fn mark_outside(
    view: &LightView,
    light: &Light,
    receivers: &Receivers,
    s: &Settings,
    outside: &mut [bool],
) {
    outside.par_iter_mut().enumerate().for_each(|(k, o)| {
        if receivers.active()[k] && !*o {
            if let Query::Look { uv, .. } = query(
                view,
                light,
                receivers.position()[k],
                receivers.normal()[k],
                s,
            ) {
                *o = !view.contains(uv);
            }
        }
    });
}

/// The receivers [`mark_outside`] found: each one the core's
/// [`Settler`](shadow_map_core::settle::Settler) proves unshadowed (no scene triangle in its light
/// pyramid) gets its facing fraction, exactly; any other fails the estimate with
/// [`shadow_map_core::Error::Receivers`] naming the count (a map-less transmittance of 1 would be
/// a silent guess). Returns how many were settled.
pub fn settle_outside(
    scene: &Scene,
    receivers: &Receivers,
    outside: &[bool],
    v: &mut [f32],
) -> Result<usize> {
    let idx: Vec<usize> = (0..outside.len()).filter(|&k| outside[k]).collect();
    if idx.is_empty() {
        return Ok(0);
    }
    let settler = shadow_map_core::settle::Settler::new(scene);
    let proven: Vec<bool> = idx
        .par_iter()
        .map(|&k| settler.unshadowed(receivers.position()[k], receivers.normal()[k]))
        .collect();
    let unproven = proven.iter().filter(|p| !**p).count();
    if unproven > 0 {
        return Err(shadow_map_core::Error::Receivers(format!(
            "{unproven} lit receivers lie outside deep-shadow's light view (beyond {:.0} degrees off the light's axis) and scene geometry lies between them and the light, so no map defines their transmittance: aim the light's normal at them, or use the CLI's cascades (it splits such views)",
            MAX_TAN.atan().to_degrees()
        )));
    }
    for &k in &idx {
        v[k] = scene
            .light()
            .front_fraction_world(receivers.position()[k], receivers.normal()[k]);
    }
    Ok(idx.len())
}

/// EDSM's `c'` in world units for `view`: `c / (far - n)`.
pub fn c_world(view: &LightView, s: &Settings) -> f32 {
    s.c / (view.far - view.n).max(f32::MIN_POSITIVE)
}

/// The depth window the lists keep behind their truncation point in `view`
/// ([`crate::dsm::truncation_window`] for the settings' filter).
pub fn truncation_window(view: &LightView, s: &Settings) -> f32 {
    crate::dsm::truncation_window(s.filter, c_world(view, s))
}

/// Lookup settings for a view of `light`: `c' = c / (far - n)` turns the notes' c over normalised
/// depth into world units; `filter=pcss` sizes its regions by the light each view stands for
/// ([`view_light_extent`]).
pub fn lookup_settings(view: &LightView, light: &Light, s: &Settings) -> LookupSettings {
    LookupSettings {
        filter: s.filter,
        kernel: s.kernel,
        c_world: c_world(view, s),
        traversal: s.traversal,
        soft: SoftLookup {
            light: view_light_extent(light, s.sublights),
            near: view.n,
            to_texels: view.r as f32 / view.w,
            max_taps: s.max_taps,
            disk: is_disk(light),
            ortho: view.is_ortho(),
        },
    }
}

/// The part of `light` one view stands for (docs/methods.md §8 "Percentage-closer soft
/// transmittance"): the light itself for S = 1; for S x S sub-lights, the light's shape scaled
/// by 1/S around the view's centre of projection (one stratum's size, so the sub-lights' penumbrae
/// tile the light's instead of each spanning it; for disks and spheres a disk of the stratum's
/// area-equivalent scale, an approximation of the concentric-mapped stratum).
///
/// The sun: the stratum of its disk of directions around the view's direction `e_z`.
pub fn view_light(light: &Light, view: &LightView, sublights: u32) -> Light {
    if sublights <= 1 {
        return *light;
    }
    let scaled = light.scaled(1.0 / sublights as f32);
    if light.is_directional() {
        return Light {
            normal: view.frame.ez,
            tangent: view.frame.ex,
            ..scaled
        };
    }
    Light {
        center: view.frame.origin,
        ..scaled
    }
}

/// The extent `l` (per axis, light-plane units) of [`view_light`] for S = `sublights`: PCSS's
/// `l` (`2 half_extent`: rect sides, disk and sphere diameters) divided by S.
pub fn view_light_extent(light: &Light, sublights: u32) -> Vec2 {
    2.0 * light.half_extent() / sublights.max(1) as f32
}

/// Builds, processes and links the deep shadow map of `scene` in `view` on the CPU (§1.3.1 to
/// §1.3.3).
pub fn build_deep_map(scene: &Scene, view: &LightView, s: &Settings) -> Result<DeepShadowMap> {
    build_deep_map_timed(scene, view, s, &mut [0.0; 4])
}

/// [`build_deep_map`], adding the milliseconds of its stages to `ms`: rasterise, insert (with any
/// rebuilds), process, link.
pub fn build_deep_map_timed(
    scene: &Scene,
    view: &LightView,
    s: &Settings,
    ms: &mut [f64; 4],
) -> Result<DeepShadowMap> {
    let t = Instant::now();
    let tris = prepare(scene, view);
    let frags = fragments(&tris, view.r);
    ms[0] += t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let mut dsm = DeepShadowMap::build(&frags, view.r, s.capacity, s.max_capacity)?;
    ms[1] += t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    dsm.process(s.epsilon, truncation_window(view, s));
    ms[2] += t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    dsm.link();
    ms[3] += t.elapsed().as_secs_f64() * 1e3;
    Ok(dsm)
}

/// Deep shadow maps on the CPU (Fürst et al.), with soft transmittance from S x S sub-lights.
///
/// Per sub-light point y: a deep shadow map from y ([`build_deep_map`]), then for each receiver p
/// `T_y(p)` = the filtered transmittance of the fragments that are casters for p (receiver-plane
/// rejection, or `z < z_p - eps` with `receiver_plane=false`; [`DeepShadowMap::transmittance_plane`]),
/// 0 when y is behind p's tangent plane. `V(p) = (1/S^2) sum_y T_y(p)`, 0 behind a one-sided light.
/// One map is alive at a time.
///
/// A fully opaque scene builds no lists: each view is the core's ordinary shadow map, read by the
/// same filters (`--stats` note `path`).
pub struct CpuDeepShadow {
    params: Params,
    /// `params`, typed (re-read on every `set_param`).
    settings: Settings,
    report: Report,
    cancel: Cancel,
}

impl CpuDeepShadow {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        let params = Params::new(SPECS)?;
        Ok(CpuDeepShadow {
            settings: Settings::from_params(&params)?,
            params,
            report: Report::default(),
            cancel: Cancel::new(),
        })
    }
    /// The current settings.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// V in the given sub-light views (one per sub-light point, as [`Tally::fit_view`] fits
    /// them; the engine path's views, `crate::DeepShadowFrame`), each map built and read in turn.
    pub fn estimate_in_views(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        views: &[LightView],
        v: &mut [f32],
    ) -> Result<()> {
        receivers.check_output(v)?;
        let mut tally = Tally::default();
        let views: Vec<(LightView, FitReport)> = views
            .iter()
            .map(|view| {
                tally.add_planes(view);
                (*view, FitReport::default())
            })
            .collect();
        self.estimate_views(scene, receivers, &views, tally, 0.0, v)
    }

    /// The estimate in fitted `views` (`t_fit`: the fit's milliseconds, for the report).
    fn estimate_views(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        views: &[(LightView, FitReport)],
        mut tally: Tally,
        t_fit: f64,
        v: &mut [f32],
    ) -> Result<()> {
        self.report = Report::default();
        let s = self.settings();
        let opaque = scene.is_opaque();
        let mut acc = vec![0.0f32; receivers.len()];
        let mut outside = vec![false; receivers.len()];
        let mut t_est = 0.0;
        let mut t_stages = [0.0f64; 4];
        let mut t_build = t_fit;
        for &(view, fit) in views {
            self.cancel.check()?;
            let t = Instant::now();
            let map = if opaque {
                let ls = LightSpace::try_build_in_view(
                    scene,
                    view,
                    fit,
                    &LightSpaceRequest::single(s.resolution),
                )?;
                Source::Opaque(
                    ls.layers
                        .into_iter()
                        .next()
                        .unwrap_or_else(|| DepthMap::empty(s.resolution)),
                )
            } else {
                let dsm = build_deep_map_timed(scene, &view, &s, &mut t_stages)?;
                tally.fragments += dsm.stats().fragments;
                tally.kept += dsm.stats().kept;
                tally.capacity = tally.capacity.max(dsm.stats().capacity);
                tally.passes += dsm.stats().passes;
                tally.max_len = tally.max_len.max(dsm.stats().max_len);
                Source::Deep(dsm)
            };
            tally.peak = tally.peak.max(match &map {
                Source::Opaque(m) => m.bytes(),
                Source::Deep(d) => d.bytes(),
            });
            t_build += t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let ls = lookup_settings(&view, scene.light(), &s);
            mark_outside(&view, scene.light(), receivers, &s, &mut outside);
            let (lookups, steps) = self.cancel.par_map_reduce(
                &mut acc,
                |k, a| {
                    if !receivers.active()[k] {
                        return (0u64, 0u64);
                    }
                    match query(
                        &view,
                        scene.light(),
                        receivers.position()[k],
                        receivers.normal()[k],
                        &s,
                    ) {
                        Query::Fixed(x) => {
                            *a += x;
                            (0, 0)
                        }
                        Query::Look { uv, plane, facing } => match &map {
                            Source::Opaque(m) => {
                                *a += facing * transmittance_opaque_plane(m, uv, &plane, &ls);
                                (1, 0)
                            }
                            Source::Deep(dsm) => {
                                let (tr, st) = dsm.transmittance_plane(uv, &plane, &ls);
                                *a += facing * tr;
                                (1, st as u64)
                            }
                        },
                    }
                },
                || (0, 0),
                |x, y| (x.0 + y.0, x.1 + y.1),
            )?;
            tally.lookups += lookups;
            tally.steps += steps;
            t_est += t.elapsed().as_secs_f64() * 1e3;
        }
        let bad = finish(scene, receivers, &acc, views.len(), v);
        let settled = settle_outside(scene, receivers, &outside, v)?;
        if opaque {
            self.report.stages.push(("build".into(), t_build));
        } else {
            // The build's parts (their sum is the build; `total_ms("build")` adds them up).
            let rest = t_build - t_stages.iter().sum::<f64>() - t_fit;
            self.report.stages.push(("build: fit view".into(), t_fit));
            for (k, name) in ["raster", "insert", "process", "link"].iter().enumerate() {
                self.report
                    .stages
                    .push((format!("build: {name}"), t_stages[k]));
            }
            self.report
                .stages
                .push(("build: other".into(), rest.max(0.0)));
        }
        self.report.stages.push(("estimate".into(), t_est));
        tally.note(&mut self.report, scene, opaque, views.len());
        self.report.note("non_finite", bad);
        self.report
            .warn(shadow_map_core::Warning::NonFiniteV { receivers: bad });
        if settled > 0 {
            self.report.note("settled_outside", settled);
        }
        Ok(())
    }
}

/// Writes `V = acc / views` (NaN for inactive receivers, 0 behind a one-sided light), clamped to
/// [0, 1]; returns how many were not finite (written as 0; a non-zero count is a bug, reported).
pub fn finish(
    scene: &Scene,
    receivers: &Receivers,
    acc: &[f32],
    views: usize,
    v: &mut [f32],
) -> usize {
    let inv = 1.0 / views.max(1) as f32;
    let frame = scene.light().frame();
    let one_sided = scene.light().one_sided();
    let mut bad = 0;
    for (k, out) in v.iter_mut().enumerate() {
        *out = if !receivers.active()[k] {
            f32::NAN
        } else if one_sided && frame.to_light(receivers.position()[k]).z <= 0.0 {
            0.0
        } else {
            let x = acc[k] * inv;
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                bad += 1;
                0.0
            }
        };
    }
    bad
}

/// Notes of one deep map for `--stats`, summed over views.
#[derive(Debug, Default, Clone, Copy)]
pub struct Tally {
    /// Fragments.
    pub fragments: u64,
    /// Kept elements.
    pub kept: u64,
    /// Largest capacity used.
    pub capacity: u64,
    /// Build passes.
    pub passes: u32,
    /// Longest list.
    pub max_len: u32,
    /// Lookups.
    pub lookups: u64,
    /// Elements visited by lookups.
    pub steps: u64,
    /// Receivers out of the frustum (max over views).
    pub out_of_frustum: usize,
    /// Final window side over the tightest one (`FitReport::window_scale`, max over views).
    pub window_scale: f32,
    /// Near and far planes: the smallest n and the largest far over views.
    pub planes: Option<(f32, f32)>,
    /// Peak bytes.
    pub peak: usize,
}

impl Tally {
    /// The view of sub-light point `y` as both twins fit it ([`sublight_view_reaching`] with the
    /// filter margin, `s.view`, and for `filter=pcss` the half extent of the view's light), its fit folded into the tally (out-of-frustum count, window
    /// scale, near and far planes).
    pub fn fit_view(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        y: Vec2,
        s: &Settings,
    ) -> Result<(LightView, FitReport)> {
        let half = if s.filter == Filter::Pcss {
            0.5 * view_light_extent(scene.light(), s.sublights)
        } else {
            Vec2::ZERO
        };
        let (view, fit) = sublight_view_reaching(
            scene,
            receivers,
            y,
            half,
            s.resolution,
            kernel_margin(s),
            &s.view,
        )?;
        self.out_of_frustum = self.out_of_frustum.max(fit.out_of_frustum);
        self.window_scale = self.window_scale.max(fit.window_scale);
        self.add_planes(&view);
        Ok((view, fit))
    }
    /// Takes a view's near and far planes into [`Tally::planes`].
    pub fn add_planes(&mut self, view: &LightView) {
        let (n, f) = self.planes.unwrap_or((view.n, view.far));
        self.planes = Some((n.min(view.n), f.max(view.far)));
    }
    /// Adds the notes to a report.
    pub fn note(&self, rep: &mut Report, scene: &Scene, opaque: bool, views: usize) {
        if matches!(scene.light().shape, LightShape::Sphere { .. }) {
            rep.note(
                "approximation",
                "sphere light sampled on the disk through its centre perpendicular to the light normal",
            );
        }
        rep.note(
            "path",
            if opaque {
                "opaque scene: ordinary shadow map per view, no lists"
            } else {
                "deep lists"
            },
        );
        rep.note("views", views);
        if !opaque {
            rep.note("fragments", self.fragments);
            rep.note("elements_kept", self.kept);
            rep.note("truncated", self.fragments - self.kept.min(self.fragments));
            rep.note("capacity", self.capacity);
            rep.note("build_passes", self.passes);
            rep.note("max_list", self.max_len);
            if self.lookups > 0 {
                rep.note(
                    "elements_per_lookup",
                    format!("{:.2}", self.steps as f64 / self.lookups as f64),
                );
            }
        }
        rep.note("out_of_frustum", self.out_of_frustum);
        rep.note("window_scale", self.window_scale);
        if let Some((n, f)) = self.planes {
            rep.note("near", n);
            rep.note("far", f);
        }
        rep.light_space_bytes = self.peak;
    }
}

impl SoftShadowEstimator for CpuDeepShadow {
    shadow_map_core::estimator_identity!(NAME, DESCRIPTION, Cpu, params);
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.settings = params::set(&mut self.params, key, value)?;
        Ok(())
    }
    fn set_cancel(&mut self, cancel: Cancel) {
        self.cancel = cancel;
    }
    fn build(&mut self, _scene: &Scene, _receivers: &Receivers) -> Result<()> {
        // Multi-view: each sub-light's map is built inside `estimate`, one at a time.
        self.report = Report::default();
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        let s = self.settings();
        let mut tally = Tally::default();
        let t = Instant::now();
        let views = sublight_points(scene, s.sublights)
            .into_iter()
            .map(|y| tally.fit_view(scene, receivers, y, &s))
            .collect::<Result<Vec<_>>>()?;
        let t_fit = t.elapsed().as_secs_f64() * 1e3;
        self.estimate_views(scene, receivers, &views, tally, t_fit, v)
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}

/// The light-space data of one view.
enum Source {
    Opaque(DepthMap),
    Deep(DeepShadowMap),
}
