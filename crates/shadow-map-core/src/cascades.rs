//! Cascades along the camera's depth (common techniques, "cascaded shadow maps"; the practical
//! split scheme of Zhang et al. 2006) and the texel-density figure (docs/methods.md §1,
//! "Cascades and texel density").
//!
//! One light view from the light centre, fitted to every receiver, spends its texels evenly over
//! the receivers' directions; a camera close to a long ground needs many texels near it and few
//! far away. [`Cascaded`] runs any estimator once per slice of the receivers' camera depth, each
//! run fitting its own view(s) to that slice only (the estimator's own fit, near/far and texel
//! snapping apply per slice), so every estimator, on either backend, gets cascades without
//! knowing of them. Receivers in a blend band at each split are estimated by both neighbouring
//! cascades and V is blended linearly across the band, so it is continuous there; the report
//! gives the largest and mean difference between the two cascades over the band (the jump the
//! blend hides). Penumbra sizes are world-space quantities in every soft estimator here, so they
//! do not change at a split; only what the resolution resolves does. One cascade's maps are alive
//! at a time.
use crate::{
    camera::Camera,
    estimator::{Backend, Report, SoftShadowEstimator},
    light_view::{LightView, ViewOptions, RESOLUTION},
    params::{ParamKind, ParamSpec, Params},
    receivers::Receivers,
    scene::Scene,
    Result,
};
use std::cell::OnceCell;
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

mod tiles;
pub use tiles::{direction_tiles, Tiles};
#[cfg(test)]
mod tests;

/// `cascades`: how many camera-depth slices ([`Cascaded`]).
pub const CASCADES: ParamSpec = ParamSpec::int(0, 8, "0").named("cascades", "camera-depth cascades, one light view (set) fitted to each slice of the receivers: 0 = auto (one view unless the receivers' far/near camera-depth ratio exceeds 8 and one view's texel density p95 exceeds 2 pixels per texel; then ceil(log4 ratio), 2 to 4)");
/// `cascade_lambda`: the practical split scheme's weight ([`practical_splits`]).
pub const CASCADE_LAMBDA: ParamSpec = ParamSpec::float(0.0, 1.0, "0.75").named("cascade_lambda", "split scheme: lambda times the logarithmic split plus (1 - lambda) times the uniform one (Zhang et al. 2006)");
/// `cascade_blend`: the blend band's half width ([`cascade_weights`]).
pub const CASCADE_BLEND: ParamSpec = ParamSpec::float(0.0, 0.5, "0.1").named("cascade_blend", "blend band at each split, half width as a fraction of the nearer slice's depth range; V blends linearly across it");

/// `tiles`: how many light views by direction per cascade ([`direction_tiles`]).
pub const TILES: ParamSpec = ParamSpec::int(0, 16, "0").named("tiles", "light views by direction from the light centre per cascade, each fitted to the receivers of one tile of directions: 0 = auto (one view unless the receivers' directions span more than tile_span in tan space and one view's texel density p95 exceeds 2 pixels per texel; then up to 8 tiles of at most tile_span), 1 = one view, k = k tiles. Each tile costs a full view build");
/// `tile_span`: the largest extent in tan space one tile keeps under `tiles=0`.
pub const TILE_SPAN: ParamSpec = ParamSpec::float(0.25, 40.0, "2").named("tile_span", "tiles=0: a tile of directions is split while its receivers span more than this in tan space (x/z or y/z in the light frame; 2 is +-45 degrees about its centre direction)");
/// Most tiles `tiles=0` (auto) picks.
pub const MAX_AUTO_TILES: usize = 8;

/// Caster-aware fitting (`--param casters=...`; docs/methods.md §1 "Caster-aware
/// fitting"): which receivers the views are fitted to.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Casters {
    /// [`Casters::On`] where one view's texel-density p95 exceeds [`AUTO_MAX_DENSITY`] (where the
    /// window is too wide for its receivers), else [`Casters::Off`] (the default).
    #[default]
    Auto,
    /// Receivers no caster can shadow are settled without a map
    /// ([`Settler`](crate::settle::Settler): V is their facing fraction, exactly), and the views
    /// are fitted to the others only, so texels go where shadows can fall.
    On,
    /// Every active receiver is served by a view.
    Off,
}

crate::param_words!(Casters { Auto = "auto", On = "on", Off = "off" });

/// `casters`: caster-aware fitting ([`Casters`]).
pub const CASTERS: ParamSpec = ParamSpec::choice(Casters::WORDS, "auto").named("casters", "caster-aware fitting: on = receivers whose light pyramid holds no geometry in front of their tangent plane get their facing fraction (exact, no map) and the views fit only the others; off = every receiver in a view; auto = on where one view's texel density p95 exceeds 2 pixels per texel");

/// Most cascades (the [`CASCADES`] range).
pub const MAX_CASCADES: u32 = 8;
const _: () =
    assert!(matches!(CASCADES.kind, ParamKind::Int { max, .. } if max == MAX_CASCADES as i64));
/// Most cascades `cascades=0` (auto) picks.
pub const MAX_AUTO_CASCADES: u32 = 4;

crate::typed_params! {
    /// The cascade settings [`Cascaded`] adds to an estimator's parameters.
    pub struct CascadeSettings {
        /// Number of slices (0: [`auto_count`]).
        cascades: u32 = CASCADES,
        /// Split scheme weight.
        cascade_lambda: f32 = CASCADE_LAMBDA,
        /// Blend band half width, relative.
        cascade_blend: f32 = CASCADE_BLEND,
        /// Views by direction per cascade (0: auto, [`direction_tiles`]).
        tiles: u32 = TILES,
        /// Largest tan-space extent of one tile under `tiles=0`.
        tile_span: f32 = TILE_SPAN,
        /// Caster-aware fitting.
        casters: Casters = CASTERS,
    }
}

/// Camera-depth ratio at or below which `cascades=0` keeps one view.
pub const AUTO_MIN_RATIO: f32 = 8.0;
/// 95th percentile of the one-view texel density (camera pixels per texel side) at or below
/// which `cascades=0` keeps one view.
pub const AUTO_MAX_DENSITY: f32 = 2.0;

/// The number of cascades `cascades=0` picks for receivers between camera depths `near` and
/// `far` whose one view has a texel-density 95th percentile `p95` (computed only when needed):
/// one view while the depth ratio is at most [`AUTO_MIN_RATIO`] or the one view already gives
/// a texel per [`AUTO_MAX_DENSITY`] pixels or less (measured: on `overlapping` and
/// `stacked`, depth ratio 5.3 and p95 1.3 and 0.9, two cascades cost 1.5 to 2.8x the time for no
/// gain); else `clamp(ceil(log4(far / near)), 2, 4)`, a depth ratio of about 4 per view.
pub fn auto_count(near: f32, far: f32, p95: impl FnOnce() -> Option<f32>) -> u32 {
    if !(near > 0.0 && far / near > AUTO_MIN_RATIO) {
        return 1;
    }
    if !p95().is_some_and(|d| d > AUTO_MAX_DENSITY) {
        return 1;
    }
    let k = ((far / near).ln() / 4f32.ln()).ceil();
    (k as u32).clamp(2, MAX_AUTO_CASCADES)
}

/// The practical split scheme (Zhang et al. 2006): `k + 1` depths from `near` to `far`,
/// `s_i = lambda near (far / near)^(i / k) + (1 - lambda) (near + (far - near) i / k)`; the
/// first is `near` and the last `far` exactly.
pub fn practical_splits(near: f32, far: f32, k: u32, lambda: f32) -> Vec<f32> {
    let k = k.max(1);
    let (n, f) = (near as f64, far as f64);
    let mut s: Vec<f32> = (0..=k)
        .map(|i| {
            let t = i as f64 / k as f64;
            let log = if n > 0.0 {
                n * (f / n).powf(t)
            } else {
                n + (f - n) * t
            };
            let uni = n + (f - n) * t;
            (lambda as f64 * log + (1.0 - lambda as f64) * uni) as f32
        })
        .collect();
    s[0] = near;
    s[k as usize] = far;
    s
}

/// Half width of the blend band at each inner split `s_i` (index 1..k-1 of `splits`):
/// `blend (s_i - s_{i-1})`, at most half of either neighbouring slice. Index 0 and k are 0.
pub fn blend_half_widths(splits: &[f32], blend: f32) -> Vec<f32> {
    let k = splits.len().saturating_sub(1);
    (0..=k)
        .map(|i| {
            if i == 0 || i == k {
                return 0.0;
            }
            let below = splits[i] - splits[i - 1];
            let above = splits[i + 1] - splits[i];
            (blend * below).min(0.5 * below).min(0.5 * above).max(0.0)
        })
        .collect()
}

/// The cascades a receiver at camera depth `d` belongs to, with their weights (summing to 1):
/// one cascade away from the splits, two in a blend band, where the nearer cascade's weight
/// falls linearly from 1 to 0 across `[s_i - h_i, s_i + h_i]`.
pub fn cascade_weights(d: f32, splits: &[f32], half: &[f32]) -> [(usize, f32); 2] {
    let k = splits.len() - 1;
    let mut c = 0;
    while c + 1 < k && d >= splits[c + 1] {
        c += 1;
    }
    // Blend with the cascade below near its lower split, or with the one above near its upper.
    if c > 0 && d < splits[c] + half[c] && half[c] > 0.0 {
        let w_below = ((splits[c] + half[c] - d) / (2.0 * half[c])).clamp(0.0, 1.0);
        return [(c - 1, w_below), (c, 1.0 - w_below)];
    }
    if c + 1 < k && d > splits[c + 1] - half[c + 1] && half[c + 1] > 0.0 {
        let w_here = ((splits[c + 1] + half[c + 1] - d) / (2.0 * half[c + 1])).clamp(0.0, 1.0);
        return [(c, w_here), (c + 1, 1.0 - w_here)];
    }
    [(c, 1.0), (c, 0.0)]
}

/// Camera depth of every receiver (`view_depth` when the receivers carry it, else the distance
/// along `camera`'s view axis); `None` for inactive receivers.
pub fn camera_depths(camera: &Camera, receivers: &Receivers) -> Vec<Option<f32>> {
    let fwd = camera.basis().forward;
    (0..receivers.len())
        .map(|k| {
            if !receivers.active()[k] {
                return None;
            }
            let d = match receivers.view_depth() {
                Some(vd) if vd[k].is_finite() => vd[k],
                _ => (receivers.position()[k] - camera.eye).dot(fwd),
            };
            Some(d)
        })
        .collect()
}

/// Texel density of `view` at each receiver, in camera pixels: the linear size of the patch of
/// the receiver's surface one shadow-map texel covers, over that of the patch one camera pixel
/// covers (the square root of the area ratio; 1: a texel per pixel, 10: ten pixels per texel
/// side). A tan-space area `a` seen at angle `alpha` off an axis covers `a z^2 cos(alpha) /
/// cos(beta)` of a surface at axial depth z whose normal makes `beta` with the ray; the texel's is
/// `a = (w / (n r))^2`, the pixel's `a = (2 tan(fov_y / 2) / height)^2`. NaN for inactive
/// receivers and receivers outside the view.
pub fn texel_density(view: &LightView, camera: &Camera, receivers: &Receivers) -> Vec<f32> {
    let basis = camera.basis();
    let t_pix = 2.0 * (camera.fov_y_deg.to_radians() * 0.5).tan() / camera.height.max(1) as f32;
    let t_tex = view.delta() / view.n;
    (0..receivers.len())
        .map(|k| {
            if !receivers.active()[k] {
                return f32::NAN;
            }
            let (p, nrm) = (receivers.position()[k], receivers.normal()[k]);
            let q = view.frame.to_light(p);
            if !(q.z > 0.0) || !view.contains(view.project(q)) {
                return f32::NAN;
            }
            let area = |t: f32, axial: f32, dist: f32, ray: glam::Vec3| {
                let cos_a = (axial / dist).max(1e-6);
                let cos_b = nrm.dot(ray).abs().max(1e-3);
                t * t * axial * axial * cos_a / cos_b
            };
            let texel = if view.is_ortho() {
                // The sun: a texel is delta^2 across e_z wherever it lies.
                let cos_b = nrm.dot(view.frame.ez).abs().max(1e-3);
                view.delta() * view.delta() / cos_b
            } else {
                let lr = (p - view.frame.origin).normalize_or_zero();
                area(t_tex, q.z, q.length(), lr)
            };
            let cr = p - camera.eye;
            let pixel = area(
                t_pix,
                cr.dot(basis.forward),
                cr.length(),
                cr.normalize_or_zero(),
            );
            (texel / pixel).sqrt()
        })
        .collect()
}

/// Median and 95th percentile of the finite values of `d` (None when there are none).
pub fn median_p95(d: &[f32]) -> Option<(f32, f32)> {
    let mut v: Vec<f32> = d.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f32::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    Some((at(0.5), at(0.95)))
}

/// The parameter table of `inner` followed by [`CascadeSettings::SPECS`], made once per table.
fn combined_specs(inner: &'static [ParamSpec]) -> &'static [ParamSpec] {
    static TABLES: OnceLock<Mutex<HashMap<usize, &'static [ParamSpec]>>> = OnceLock::new();
    let tables = TABLES.get_or_init(|| Mutex::new(HashMap::new()));
    let mut t = tables.lock().unwrap_or_else(|e| e.into_inner());
    t.entry(inner.as_ptr() as usize).or_insert_with(|| {
        let mut v = inner.to_vec();
        v.extend_from_slice(CascadeSettings::SPECS);
        Box::leak(v.into_boxed_slice())
    })
}

/// The split depths (k + 1 of them) `settings` gives receivers at camera depths `depths`: one
/// slice (the nearest and farthest depth) unless `cascades` or [`auto_count`] (with the one-view
/// density `p95`) asks for more.
pub fn plan_splits(
    settings: &CascadeSettings,
    depths: &[Option<f32>],
    p95: impl FnOnce() -> Option<f32>,
) -> Vec<f32> {
    let (mut near, mut far) = (f32::INFINITY, 0.0f32);
    for d in depths.iter().flatten() {
        near = near.min(*d);
        far = far.max(*d);
    }
    let near = near.max(1e-6 * far);
    let k = match settings.cascades {
        0 => auto_count(near, far, p95),
        k => k,
    };
    if !(far > near) || k <= 1 {
        return vec![near, far];
    }
    practical_splits(near, far, k, settings.cascade_lambda)
}

/// What [`Cascaded`] runs: the split depths, per receiver the cascades it belongs to with their
/// weights ([`cascade_weights`]; `None` for inactive receivers), and per cascade its tiles of
/// directions ([`direction_tiles`]).
#[derive(Debug, Clone)]
pub struct Plan {
    /// `k + 1` split depths.
    pub splits: Vec<f32>,
    /// Per receiver, its (cascade, weight) pairs.
    pub weights: Vec<Option<[(usize, f32); 2]>>,
    /// Per cascade, its tiles.
    pub tiles: Vec<Tiles>,
}

impl Plan {
    /// One cascade of one tile: the inner estimator runs on every receiver, untouched.
    pub fn is_one_view(&self) -> bool {
        self.splits.len() == 2 && self.tiles.first().is_none_or(|t| t.count == 1)
    }
    /// Number of cascades.
    pub fn cascades(&self) -> usize {
        self.splits.len() - 1
    }
    /// The receivers of cascade `c`, tile `t` (the others inactive).
    pub fn receivers(&self, receivers: &Receivers, c: usize, t: usize) -> Receivers {
        let mut sub = cascade_receivers(receivers, &self.weights, c);
        if let Some(tiles) = self.tiles.get(c) {
            for (i, a) in sub.active_mut().iter_mut().enumerate() {
                *a &= tiles.of.get(i).is_some_and(|&x| x as usize == t);
            }
        }
        sub
    }
}

/// The [`Plan`] for `receivers` of `scene`, for an estimator whose own parameters are `inner`:
/// `cascade_p95` gives the one-view texel-density p95 that decides `cascades=0` (called only
/// when needed; [`one_view_p95`] over every receiver of the frame, settled or not, since the
/// views that serve the rest must resolve the shadows near the camera as finely as cascades over
/// every receiver would), and each cascade's own one-view p95 decides its `tiles=0`.
pub fn plan(
    settings: &CascadeSettings,
    scene: &Scene,
    receivers: &Receivers,
    inner: &Params,
    cascade_p95: impl FnOnce() -> Option<f32>,
) -> Plan {
    let depths = camera_depths(scene.camera(), receivers);
    let splits = plan_splits(settings, &depths, cascade_p95);
    let half = blend_half_widths(&splits, settings.cascade_blend);
    let weights: Vec<_> = depths
        .iter()
        .map(|d| d.map(|d| cascade_weights(d, &splits, &half)))
        .collect();
    let tiles = (0..splits.len() - 1)
        .map(|c| {
            let sub = cascade_receivers(receivers, &weights, c);
            direction_tiles(settings, scene, &sub, || one_view_p95(scene, &sub, inner))
        })
        .collect();
    Plan {
        splits,
        weights,
        tiles,
    }
}

/// `receivers` with only those of cascade `c` active.
fn cascade_receivers(
    receivers: &Receivers,
    weights: &[Option<[(usize, f32); 2]>],
    c: usize,
) -> Receivers {
    let mut sub = receivers.clone();
    for (i, w) in weights.iter().enumerate() {
        sub.active_mut()[i] = w.is_some_and(|w| w.iter().any(|(cc, x)| *cc == c && *x > 0.0));
    }
    sub
}

/// Whether [`Cascaded`] with the parameters `params` (its table: the inner estimator's and the
/// cascade keys) serves `receivers` with one view of the inner estimator (parameters `inner`)
/// and settles none of them without a map: the decisions its `build` makes ([`settle`],
/// [`plan`]), so an engine path that renders the inner estimator's one view set can stand in
/// for it exactly.
pub fn is_one_view(
    params: &Params,
    scene: &Scene,
    receivers: &Receivers,
    inner: &Params,
) -> Result<bool> {
    let settings = CascadeSettings::from_params(params)?;
    let all_p95 = OnceCell::new();
    let p95 = || *all_p95.get_or_init(|| one_view_p95(scene, receivers, inner));
    if settle(&settings, scene, receivers, p95).is_some() {
        return Ok(false);
    }
    Ok(plan(&settings, scene, receivers, inner, p95).is_one_view())
}

/// The 95th percentile of the texel density of the one light-centre view an estimator with
/// parameters `inner` fits for `receivers` (`None` without a map, or with no receiver inside).
pub fn one_view_p95(scene: &Scene, receivers: &Receivers, inner: &Params) -> Option<f32> {
    median_p95(&view_density(scene, receivers, inner)?).map(|m| m.1)
}

/// What caster-aware fitting ([`settle`]) decided for one frame.
#[derive(Debug, Clone)]
pub struct Settled {
    /// Per receiver, its exact V when settled without a map, else `None`.
    pub v: Vec<Option<f32>>,
}

impl Settled {
    /// Receivers settled.
    pub fn count(&self) -> usize {
        self.v.iter().filter(|x| x.is_some()).count()
    }
    /// `receivers` without the settled ones (the receivers the views serve).
    pub fn unsettled(&self, receivers: &Receivers) -> Receivers {
        let mut sub = receivers.clone();
        for (a, x) in sub.active_mut().iter_mut().zip(&self.v) {
            *a &= x.is_none();
        }
        sub
    }
}

/// The receivers caster-aware fitting settles without a map under `settings` ([`Casters`]);
/// `None` when nothing is settled (`casters=off`, or `auto` where one view over every receiver
/// already has a texel-density p95, `p95` (called only under `auto`: [`one_view_p95`]), of at
/// most [`AUTO_MAX_DENSITY`]).
pub fn settle(
    settings: &CascadeSettings,
    scene: &Scene,
    receivers: &Receivers,
    p95: impl FnOnce() -> Option<f32>,
) -> Option<Settled> {
    match settings.casters {
        Casters::Off => return None,
        Casters::Auto if !p95().is_some_and(|d| d > AUTO_MAX_DENSITY) => return None,
        Casters::Auto | Casters::On => {}
    }
    let v = crate::settle::Settler::new(scene).settle(receivers);
    v.iter().any(Option::is_some).then_some(Settled { v })
}

/// The texel density ([`texel_density`]) at each receiver of the light-centre view(s) an
/// estimator with parameters `params` fits: its `resolution`, `fit` and `nearfar`, per cascade
/// when `params` holds [`CascadeSettings`] (the receivers of a blend band take the farther
/// cascade's). Estimators over sub-lights fit slightly smaller views of the same kind. `None`
/// for an estimator without a map. Receivers settled by caster-aware fitting ([`settle`]) are
/// served by no view and get NaN.
pub fn texel_density_of(scene: &Scene, receivers: &Receivers, params: &Params) -> Option<Vec<f32>> {
    let Ok(settings) = CascadeSettings::from_params(params) else {
        return view_density(scene, receivers, params);
    };
    let all_p95 = OnceCell::new();
    let p95 = || *all_p95.get_or_init(|| one_view_p95(scene, receivers, params));
    let served = settle(&settings, scene, receivers, p95).map(|s| s.unsettled(receivers));
    let receivers = served.as_ref().unwrap_or(receivers);
    let plan = plan(&settings, scene, receivers, params, p95);
    let mut out = vec![f32::NAN; receivers.len()];
    for c in 0..plan.cascades() {
        for t in 0..plan.tiles[c].count {
            let sub = plan.receivers(receivers, c, t);
            for (i, x) in view_density(scene, &sub, params)?.into_iter().enumerate() {
                if sub.active()[i] && x.is_finite() {
                    out[i] = x;
                }
            }
        }
    }
    Some(out)
}

/// Median and 95th percentile of [`texel_density_of`]: the figure `--stats` and the report give
/// (`None` for an estimator without a map, or with no receiver inside its views).
pub fn texel_density_summary(
    scene: &Scene,
    receivers: &Receivers,
    params: &Params,
) -> Option<(f32, f32)> {
    median_p95(&texel_density_of(scene, receivers, params)?)
}

/// The texel density of the one light-centre view an estimator with parameters `params` fits
/// for `receivers` (`None` without a map or when the fit fails).
fn view_density(scene: &Scene, receivers: &Receivers, params: &Params) -> Option<Vec<f32>> {
    let r: u32 = params.typed(&RESOLUTION).ok()?;
    let opts = ViewOptions::from_params(params).ok()?;
    let light = scene.light();
    let (view, _) = LightView::fit_with(
        scene,
        receivers,
        light.frame(),
        light.half_extent(),
        r,
        &opts,
    )
    .ok()?;
    Some(texel_density(&view, scene.camera(), receivers))
}

/// Any estimator run once per camera-depth cascade (see the module documentation); with one
/// cascade it is the estimator itself (and a `cascades` note).
pub struct Cascaded {
    inner: Box<dyn SoftShadowEstimator>,
    params: Params,
    settings: CascadeSettings,
    /// The plan of the last build (one slice: the inner estimator was built on every receiver
    /// the views serve).
    plan: Option<Plan>,
    /// What caster-aware fitting settled in the last build ([`settle`]).
    settled: Option<Settled>,
    /// Milliseconds the last build spent settling receivers.
    settle_ms: f64,
    /// Checked between cascades and tiles (the inner estimator holds a clone).
    cancel: crate::Cancel,
    report: Report,
}

impl Cascaded {
    /// `inner` with the cascade parameters appended to its table, at their defaults.
    pub fn new(inner: Box<dyn SoftShadowEstimator>) -> Result<Self> {
        let mut params = Params::new(combined_specs(inner.params().specs()))?;
        for s in inner.params().specs() {
            if let Some(v) = inner.params().get(s.key) {
                params.set(s.key, &v.to_string())?;
            }
        }
        Ok(Cascaded {
            settings: CascadeSettings::from_params(&params)?,
            inner,
            params,
            plan: None,
            settled: None,
            settle_ms: 0.0,
            cancel: crate::Cancel::new(),
            report: Report::default(),
        })
    }
}

impl SoftShadowEstimator for Cascaded {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn description(&self) -> &'static str {
        self.inner.description()
    }
    fn backend(&self) -> Backend {
        self.inner.backend()
    }
    fn params(&self) -> &Params {
        &self.params
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        if CascadeSettings::SPECS.iter().any(|s| s.key == key) {
            let mut p = self.params.clone();
            p.set(key, value)?;
            self.settings = CascadeSettings::from_params(&p)?;
            self.params = p;
            return Ok(());
        }
        self.inner.set_param(key, value)?;
        self.params.set(key, value)
    }
    fn set_cancel(&mut self, cancel: crate::Cancel) {
        self.inner.set_cancel(cancel.clone());
        self.cancel = cancel;
    }
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        self.plan = None;
        // The one view's texel-density p95 over every receiver, computed at most once: it
        // decides both `casters=auto` and `cascades=0`.
        let inner = self.inner.params().clone();
        let all_p95 = OnceCell::new();
        let p95 = || *all_p95.get_or_init(|| one_view_p95(scene, receivers, &inner));
        let t = Instant::now();
        self.settled = settle(&self.settings, scene, receivers, p95);
        self.settle_ms = t.elapsed().as_secs_f64() * 1e3;
        let Some(settled) = &self.settled else {
            return self.build_views(scene, receivers, p95);
        };
        let sub = settled.unsettled(receivers);
        if !sub.active().iter().any(|a| *a) {
            return Ok(()); // every receiver settled: no view to build
        }
        self.build_views(scene, &sub, p95)
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        self.cancel.check()?;
        let Some(settled) = self.settled.take() else {
            return self.estimate_views(scene, receivers, v);
        };
        if settled.v.len() != receivers.len() {
            let n = settled.v.len();
            self.settled = Some(settled);
            return Err(crate::Error::Receivers(format!(
                "estimate has {} receivers, the build had {n}",
                receivers.len()
            )));
        }
        let sub = settled.unsettled(receivers);
        let out = if sub.active().iter().any(|a| *a) {
            self.estimate_views(scene, &sub, v)
        } else {
            v.fill(f32::NAN);
            self.report = Report::default();
            Ok(())
        };
        for (x, s) in v.iter_mut().zip(&settled.v) {
            if let Some(s) = s {
                *x = *s;
            }
        }
        let n = settled.count();
        self.settled = Some(settled);
        out?;
        self.report
            .stages
            .insert(0, ("settle".into(), self.settle_ms));
        // Receivers the inner estimator settled itself (accumulation's, beyond its view) count too.
        self.report.add_count("settled_without_map", n);
        Ok(())
    }
}

impl Cascaded {
    /// Plans the views for the receivers they serve and builds the one view at once (several
    /// are built inside [`Cascaded::estimate_views`], one at a time). `cascade_p95`: [`plan`]'s.
    fn build_views(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        cascade_p95: impl FnOnce() -> Option<f32>,
    ) -> Result<()> {
        let plan = plan(
            &self.settings,
            scene,
            receivers,
            self.inner.params(),
            cascade_p95,
        );
        let one = plan.is_one_view();
        self.plan = Some(plan);
        if one {
            return self.inner.build(scene, receivers);
        }
        Ok(()) // each cascade is built inside `estimate`, one at a time
    }

    /// V of the receivers the views serve (the others NaN).
    fn estimate_views(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        let plan = crate::estimator::built(self.plan.as_ref())?;
        let (splits, weights) = (&plan.splits, &plan.weights);
        if weights.len() != receivers.len() {
            return Err(crate::Error::Receivers(format!(
                "estimate has {} receivers, the build had {}",
                receivers.len(),
                weights.len()
            )));
        }
        if plan.is_one_view() {
            self.inner.estimate(scene, receivers, v)?;
            self.report = self.inner.report();
            self.report.note("cascades", 1);
            return Ok(());
        }
        let k = plan.cascades();
        let mut acc = vec![0.0f32; receivers.len()];
        // V of the previous cascade, for the jump over each band.
        let mut prev: Vec<f32> = Vec::new();
        let (mut jump_max, mut jump_sum, mut jump_n) = (0.0f32, 0.0f64, 0usize);
        let mut report = Report::default();
        let mut ms = Vec::with_capacity(k);
        let mut out_of_frustum = 0usize;
        for c in 0..k {
            let t = Instant::now();
            let mut vc = vec![f32::NAN; receivers.len()];
            for tile in 0..plan.tiles[c].count {
                let sub = plan.receivers(receivers, c, tile);
                let mut vt = vec![f32::NAN; receivers.len()];
                self.cancel.check()?;
                if sub.active().iter().any(|a| *a) {
                    self.inner.build(scene, &sub)?;
                    self.inner.estimate(scene, &sub, &mut vt)?;
                }
                for (i, x) in vt.into_iter().enumerate() {
                    if sub.active()[i] {
                        vc[i] = x;
                    }
                }
                let r = self.inner.report();
                for (name, t) in r.stages {
                    match report.stages.iter_mut().find(|s| s.0 == name) {
                        Some(s) => s.1 += t,
                        None => report.stages.push((name, t)),
                    }
                }
                report.light_space_bytes = report.light_space_bytes.max(r.light_space_bytes);
                report.warn_all(r.warnings.iter().copied());
                out_of_frustum += r
                    .notes
                    .iter()
                    .find(|(n, _)| n == "out_of_frustum")
                    .and_then(|(_, x)| x.parse::<usize>().ok())
                    .unwrap_or(0);
                if c == 0 && tile == 0 {
                    report.notes = r.notes;
                }
            }
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            for (i, w) in weights.iter().enumerate() {
                let Some(w) = w else { continue };
                for (cc, x) in w {
                    if *cc == c && *x > 0.0 {
                        acc[i] += x * vc[i];
                        if c > 0 && w[0].0 == c - 1 && w[0].1 > 0.0 && prev[i].is_finite() {
                            let j = (prev[i] - vc[i]).abs();
                            jump_max = jump_max.max(j);
                            jump_sum += j as f64;
                            jump_n += 1;
                        }
                    }
                }
            }
            prev = vc;
        }
        for (i, out) in v.iter_mut().enumerate() {
            *out = if receivers.active()[i] {
                acc[i].clamp(0.0, 1.0)
            } else {
                f32::NAN
            };
        }
        report.note("cascades", k);
        if let Some(n) = report.notes.iter_mut().find(|(n, _)| n == "out_of_frustum") {
            n.1 = out_of_frustum.to_string();
        }
        let tiles: Vec<String> = plan.tiles.iter().map(|t| t.count.to_string()).collect();
        report.note("light_tiles", tiles.join(","));
        let list = |x: &[f32]| {
            x.iter()
                .map(|s| format!("{s:.3}"))
                .collect::<Vec<_>>()
                .join(",")
        };
        report.note("cascade_splits", list(splits));
        let ms32: Vec<f32> = ms.iter().map(|x| *x as f32).collect();
        report.note("cascade_ms", list(&ms32));
        report.note("cascade_jump_max", format!("{jump_max:.4}"));
        report.note(
            "cascade_jump_mean",
            format!("{:.4}", jump_sum / jump_n.max(1) as f64),
        );
        report.note("cascade_band_receivers", jump_n);
        self.report = report;
        Ok(())
    }
}
