//! The CPU twin, [`CpuDeepShadow`]: per sub-light view a deep shadow map built from the CPU
//! raster's fragments ([`raster`], [`dsm`]) or, for opaque scenes, the core's depth map, read by
//! each receiver's query ([`crate::math::view`]).
use crate::math::transmittance_opaque_plane;
use crate::math::view::{
    kernel_margin, lookup_settings, query, sublight_points, sublight_view_reaching,
    truncation_window, view_light_extent, Query,
};
use crate::settings::{self, Filter, Settings, DESCRIPTION, NAME};
use dsm::DeepShadowMap;
use glam::Vec2;
use raster::{fragments, prepare};
use rayon::prelude::*;
use shadow_map_core::{
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitReport, MAX_TAN},
    Cancel, Configured, DepthMap, Light, LightShape, LightView, Receivers, Report, Result, Scene,
    SoftShadowEstimator,
};
use std::time::Instant;

pub mod dsm;
pub mod raster;

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
    /// The parameters and their typed settings ([`settings::check`]ed).
    config: Configured<Settings>,
    report: Report,
    cancel: Cancel,
}

impl CpuDeepShadow {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(CpuDeepShadow {
            config: Configured::new()?,
            report: Report::default(),
            cancel: Cancel::new(),
        })
    }
    /// The current settings.
    pub fn settings(&self) -> Settings {
        *self.config.settings()
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
    shadow_map_core::estimator_identity!(NAME, DESCRIPTION, Cpu, config: config, cancel: cancel, check: settings::check);
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
