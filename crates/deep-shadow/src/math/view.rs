//! The per-view set-up both twins share: sub-light points, the fitted view of each (with the
//! filter margin), what each receiver looks up in it, and the lookup settings of a view.
use crate::math::{LookupSettings, SoftLookup};
use crate::settings::{Filter, Settings};
use glam::{Vec2, Vec3};
use shadow_map_core::soft_transmittance::is_disk;
use shadow_map_core::{
    light_view::{FitMode, FitReport, ViewOptions, MAX_TAN},
    Light, LightView, ReceiverPlane, Receivers, Result, Scene,
};

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

/// EDSM's `c'` in world units for `view`: `c / (far - n)`.
pub fn c_world(view: &LightView, s: &Settings) -> f32 {
    s.c / (view.far - view.n).max(f32::MIN_POSITIVE)
}

/// The depth window the lists keep behind their truncation point in `view`
/// ([`crate::math::truncation_window`] for the settings' filter).
pub fn truncation_window(view: &LightView, s: &Settings) -> f32 {
    crate::math::truncation_window(s.filter, c_world(view, s))
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
