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

/// `cascades`: how many camera-depth slices ([`Cascaded`]).
pub const CASCADES: ParamSpec = ParamSpec {
    key: "cascades",
    kind: ParamKind::Int { min: 0, max: 8 },
    default: "0",
    help: "camera-depth cascades, one light view (set) fitted to each slice of the receivers: 0 = auto (one view unless the receivers' far/near camera-depth ratio exceeds 8 and one view's texel density p95 exceeds 2 pixels per texel; then ceil(log4 ratio), 2 to 4)",
};
/// `cascade_lambda`: the practical split scheme's weight ([`practical_splits`]).
pub const CASCADE_LAMBDA: ParamSpec = ParamSpec {
    key: "cascade_lambda",
    kind: ParamKind::Float { min: 0.0, max: 1.0 },
    default: "0.75",
    help: "split scheme: lambda times the logarithmic split plus (1 - lambda) times the uniform one (Zhang et al. 2006)",
};
/// `cascade_blend`: the blend band's half width ([`cascade_weights`]).
pub const CASCADE_BLEND: ParamSpec = ParamSpec {
    key: "cascade_blend",
    kind: ParamKind::Float { min: 0.0, max: 0.5 },
    default: "0.1",
    help: "blend band at each split, half width as a fraction of the nearer slice's depth range; V blends linearly across it",
};

/// `tiles`: how many light views by direction per cascade ([`direction_tiles`]).
pub const TILES: ParamSpec = ParamSpec {
    key: "tiles",
    kind: ParamKind::Int { min: 0, max: 16 },
    default: "0",
    help: "light views by direction from the light centre per cascade, each fitted to the receivers of one tile of directions: 0 = auto (one view unless the receivers' directions span more than tile_span in tan space and one view's texel density p95 exceeds 2 pixels per texel; then up to 8 tiles of at most tile_span), 1 = one view, k = k tiles. Each tile costs a full view build",
};
/// `tile_span`: the largest extent in tan space one tile keeps under `tiles=0`.
pub const TILE_SPAN: ParamSpec = ParamSpec {
    key: "tile_span",
    kind: ParamKind::Float { min: 0.25, max: 40.0 },
    default: "2",
    help: "tiles=0: a tile of directions is split while its receivers span more than this in tan space (x/z or y/z in the light frame; 2 is +-45 degrees about its centre direction)",
};
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
pub const CASTERS: ParamSpec = ParamSpec {
    key: "casters",
    kind: ParamKind::Choice(Casters::WORDS),
    default: "auto",
    help: "caster-aware fitting: on = receivers whose light pyramid holds no geometry in front of their tangent plane get their facing fraction (exact, no map) and the views fit only the others; off = every receiver in a view; auto = on where one view's texel density p95 exceeds 2 pixels per texel",
};

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

/// The tiles of directions of one cascade: `count` of them, `of[i]` the tile of receiver `i`
/// (receivers behind the light plane, and inactive ones, in tile 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Tiles {
    /// Number of tiles (at least 1).
    pub count: usize,
    /// Tile of each receiver.
    pub of: Vec<u32>,
}

/// Splits the active `receivers` by their direction from the light centre (several views where
/// one cannot serve). In the light frame a receiver at `p` (in front, `p_z > 0`) has
/// the tan-space position `t = p_xy / p_z`; a tile is a box of `t`, and each tile's view is the
/// estimator's own light-centre view fitted to that tile's receivers only, so every formula that
/// assumes the map plane parallel to the light plane holds, while texels go where the tile's
/// receivers are. The split is a k-d tree on `t`: the tile with the widest extent is cut at the
/// median of its receivers along its longer side. Receivers beyond
/// [`MAX_TAN`](crate::light_view::MAX_TAN), outside every view, stay in tile 0 and count in no
/// extent.
///
/// `tiles = k >= 1`: k tiles (fewer when the receivers run out). `tiles = 0`: one tile unless
/// the receivers span more than `tile_span` and one view's texel-density p95 (`p95`, computed
/// only then) exceeds [`AUTO_MAX_DENSITY`]; then tiles are split while one spans more than
/// `tile_span`, up to [`MAX_AUTO_TILES`].
pub fn direction_tiles(
    settings: &CascadeSettings,
    scene: &Scene,
    receivers: &Receivers,
    p95: impl FnOnce() -> Option<f32>,
) -> Tiles {
    let frame = scene.light().frame();
    let mut pts: Vec<(usize, [f32; 2])> = Vec::new();
    for i in 0..receivers.len() {
        if !receivers.active()[i] {
            continue;
        }
        let p = frame.to_light(receivers.position()[i]);
        if scene.light().is_directional() {
            // The sun: one direction; tiles split the receivers by position across it.
            pts.push((i, [p.x, p.y]));
            continue;
        }
        let t = [p.x / p.z, p.y / p.z];
        // Receivers outside every view (beyond MAX_TAN) would only stretch the extents.
        if p.z > 0.0 && t.iter().all(|x| x.abs() <= crate::light_view::MAX_TAN) {
            pts.push((i, t));
        }
    }
    let one = Tiles {
        count: 1,
        of: vec![0; receivers.len()],
    };
    let extent = |t: &[(usize, [f32; 2])]| -> (f32, usize, f32) {
        // (largest side, its axis, its middle)
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for (_, q) in t {
            for a in 0..2 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        let a = if hi[1] - lo[1] > hi[0] - lo[0] { 1 } else { 0 };
        (hi[a] - lo[a], a, 0.5 * (lo[a] + hi[a]))
    };
    let (want, span) = match settings.tiles {
        // The sun's views are orthographic: no direction to tile, and cascades resolve depth.
        0 if scene.light().is_directional() => return one,
        0 => {
            if pts.len() < 2 || !(extent(&pts).0 > settings.tile_span) {
                return one;
            }
            if !p95().is_some_and(|d| d > AUTO_MAX_DENSITY) {
                return one;
            }
            (MAX_AUTO_TILES, settings.tile_span)
        }
        k => (k as usize, 0.0),
    };
    let mut tiles: Vec<Vec<(usize, [f32; 2])>> = vec![pts];
    while tiles.len() < want {
        let Some((w, (e, a, mid))) = tiles
            .iter()
            .enumerate()
            .filter(|(_, t)| t.len() >= 2)
            .map(|(w, t)| (w, extent(t)))
            .max_by(|x, y| x.1 .0.total_cmp(&y.1 .0))
        else {
            break;
        };
        if !(e > span) {
            break;
        }
        let mut t = tiles.swap_remove(w);
        // At the median along the longer side (balanced tiles); the middle of the extent when
        // the median sits at an end (many receivers at one direction).
        t.sort_by(|x, y| x.1[a].total_cmp(&y.1[a]));
        let m = t.len() / 2;
        let cut = if t[m].1[a] > t[0].1[a] {
            t[m].1[a]
        } else {
            mid
        };
        let (lo, hi): (Vec<_>, Vec<_>) = t.into_iter().partition(|(_, q)| q[a] < cut);
        if lo.is_empty() || hi.is_empty() {
            break; // every receiver at one direction
        }
        tiles.push(lo);
        tiles.push(hi);
    }
    let mut of = vec![0u32; receivers.len()];
    for (k, t) in tiles.iter().enumerate() {
        for (i, _) in t {
            of[*i] = k as u32;
        }
    }
    Tiles {
        count: tiles.len(),
        of,
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

#[cfg(test)]
mod tests {
    /// Direction tiles: receivers spread over tan-space [-8, 8] x [-1, 1] under a light looking
    /// down. `tiles=0` splits only when asked by the density, into tiles of at most `tile_span`
    /// (or 8 of them), `tiles=k` gives k, receivers behind the light go to tile 0, and every tile
    /// holds receivers.
    #[test]
    fn direction_tiles_split_wide_receiver_sets() {
        use crate::light::{Light, LightShape};
        use glam::Vec3;
        let light = Light {
            shape: LightShape::Rect { size: [1.0, 1.0] },
            center: Vec3::new(0.0, 10.0, 0.0),
            normal: -Vec3::Y,
            tangent: Vec3::X,
        };
        let mut pos = Vec::new();
        for a in 0..=64 {
            for b in 0..=8 {
                // Light space: x = world x, y = world z (or its negative), z = 10 - world y.
                pos.push(Vec3::new(
                    -8.0 + a as f32 * 0.25,
                    9.0,
                    -1.0 + b as f32 * 0.25,
                ));
            }
        }
        pos.push(Vec3::new(0.0, 11.0, 0.0)); // behind the light
        let n = pos.len();
        let rec = Receivers::from_points(pos, vec![Vec3::Y; n]).unwrap();
        let mut scene = crate::scene::Scene::from_meshes(
            "tiles",
            Camera {
                eye: Vec3::new(0.0, 5.0, 5.0),
                target: Vec3::ZERO,
                up: Vec3::Y,
                fov_y_deg: 45.0,
                width: 8,
                height: 8,
            },
            light,
            vec![(vec![[Vec3::ZERO, Vec3::X, Vec3::Z]], 1.0)],
        )
        .unwrap();
        scene.set_light(light).unwrap();
        let settings = |tiles: u32| CascadeSettings {
            cascades: 0,
            cascade_lambda: 0.75,
            cascade_blend: 0.1,
            tiles,
            tile_span: 2.0,
            casters: Casters::Off,
        };
        let dense = || Some(5.0);
        assert_eq!(
            direction_tiles(&settings(0), &scene, &rec, || Some(1.5)).count,
            1
        );
        assert_eq!(direction_tiles(&settings(1), &scene, &rec, dense).count, 1);
        let t = direction_tiles(&settings(0), &scene, &rec, dense);
        assert_eq!(t.count, 8, "16 wide over a span of 2: the cap");
        let t4 = direction_tiles(&settings(4), &scene, &rec, dense);
        assert_eq!(t4.count, 4);
        for t in [&t, &t4] {
            let mut seen = vec![0usize; t.count];
            for &k in &t.of {
                seen[k as usize] += 1;
            }
            assert!(seen.iter().all(|&s| s > 0), "an empty tile: {seen:?}");
            assert_eq!(t.of[n - 1], 0, "behind the light: tile 0");
        }
        // A narrow set keeps one tile.
        let narrow =
            Receivers::from_points(vec![Vec3::new(0.5, 0.0, 0.5); 3], vec![Vec3::Y; 3]).unwrap();
        assert_eq!(
            direction_tiles(&settings(0), &scene, &narrow, dense).count,
            1
        );
    }

    use super::*;

    #[test]
    fn splits_run_from_near_to_far_and_mix_log_and_uniform() {
        let s = practical_splits(1.0, 16.0, 4, 1.0);
        for (a, b) in s.iter().zip([1.0, 2.0, 4.0, 8.0, 16.0]) {
            assert!((a - b).abs() < 1e-5, "{s:?}");
        }
        let u = practical_splits(1.0, 17.0, 4, 0.0);
        for (a, b) in u.iter().zip([1.0, 5.0, 9.0, 13.0, 17.0]) {
            assert!((a - b).abs() < 1e-5, "{u:?}");
        }
        let m = practical_splits(1.0, 16.0, 4, 0.5);
        assert!((m[1] - 0.5 * (2.0 + 4.75)).abs() < 1e-5, "{m:?}");
    }

    #[test]
    fn auto_count_follows_the_depth_ratio() {
        let dense = || Some(6.0);
        assert_eq!(auto_count(1.0, 8.0, dense), 1);
        assert_eq!(auto_count(1.0, 8.1, dense), 2);
        assert_eq!(auto_count(1.0, 60.0, dense), 3);
        assert_eq!(auto_count(0.7, 190.0, dense), 4);
        assert_eq!(auto_count(0.0, 1.0, dense), 1);
        assert_eq!(auto_count(1.0, 60.0, || Some(1.9)), 1);
        assert_eq!(auto_count(1.0, 60.0, || None), 1);
    }

    #[test]
    fn weights_sum_to_one_and_are_continuous() {
        let s = practical_splits(1.0, 64.0, 3, 0.75);
        let h = blend_half_widths(&s, 0.1);
        let mut last: Option<f32> = None;
        let mut d = 1.0f32;
        while d <= 64.0 {
            let w = cascade_weights(d, &s, &h);
            assert!((w[0].1 + w[1].1 - 1.0).abs() < 1e-6, "{d}: {w:?}");
            // The weight of cascade 0 as a function of d moves by at most the band's slope.
            let w0: f32 = w.iter().filter(|x| x.0 == 0).map(|x| x.1).sum();
            if let Some(l) = last {
                assert!((w0 - l).abs() <= 0.01 / (2.0 * h[1]) + 1e-4, "{d}");
            }
            last = Some(w0);
            d += 0.01;
        }
        assert_eq!(cascade_weights(1.0, &s, &h), [(0, 1.0), (0, 0.0)]);
        assert_eq!(cascade_weights(64.0, &s, &h)[0], (2, 1.0));
    }

    /// Light and camera both straight above a ground point, looking down: one texel covers
    /// `(w / (n r)) H` on the ground, one pixel `2 tan(fov / 2) / height * Hc`.
    #[test]
    fn texel_density_has_its_closed_form_on_axis() {
        use crate::light::LightFrame;
        use glam::{Vec2, Vec3};
        let (h, hc) = (10.0f32, 4.0f32);
        let frame = LightFrame {
            origin: Vec3::new(0.0, h, 0.0),
            ex: Vec3::X,
            ey: Vec3::Z,
            ez: -Vec3::Y,
        };
        let view = LightView {
            frame,
            n: 1.0,
            far: 20.0,
            window_min: Vec2::splat(-0.5),
            w: 1.0,
            r: 100,
            projection: Default::default(),
        };
        let camera = Camera {
            eye: Vec3::new(0.0, hc, 0.0),
            target: Vec3::ZERO,
            up: Vec3::Z,
            fov_y_deg: 60.0,
            width: 80,
            height: 60,
        };
        let rec =
            Receivers::from_points(vec![Vec3::ZERO, Vec3::new(0.0, 0.0, 9.0)], vec![Vec3::Y; 2])
                .unwrap();
        let d = texel_density(&view, &camera, &rec);
        let want = (0.01 * h) / (2.0 * 30f32.to_radians().tan() / 60.0 * hc);
        assert!((d[0] - want).abs() < 1e-4 * want, "{} vs {want}", d[0]);
        assert!(d[1].is_nan(), "outside the window: {}", d[1]);
    }

    #[test]
    fn median_and_p95_ignore_nan() {
        let d: Vec<f32> = (1..=100).map(|x| x as f32).chain([f32::NAN]).collect();
        let (m, p) = median_p95(&d).unwrap();
        assert!(
            (50.0..=51.0).contains(&m) && (95.0..=96.0).contains(&p),
            "{m} {p}"
        );
        assert!(median_p95(&[f32::NAN]).is_none());
    }
}
