//! Fitting to receiver bounds: for receivers that stay on the GPU (a user's G-buffer), where
//! the CPU knows only a world-space box that holds them.
use super::*;
use crate::scene::Aabb;

/// The world-space box of the active receivers ([`Aabb::EMPTY`] when none is active): the bounds
/// [`LightView::fit_bounds`] takes when the receivers themselves stay on the GPU.
pub fn receiver_bounds(receivers: &Receivers) -> Aabb {
    let mut b = Aabb::EMPTY;
    for (p, &a) in receivers.position().iter().zip(receivers.active()) {
        if a {
            b.grow(*p);
        }
    }
    b
}

/// The 8 corners of `bounds` as receivers (normals `+z`, unused by the fit), checked for a light
/// view at `frame` in `scene`: what [`LightView::fit_bounds`] fits.
///
/// Errors, never a panic: [`Error::Receivers`] for an inverted or empty box (`min > max` on an
/// axis, as [`Aabb::EMPTY`]) or a non-finite one; [`Error::LightView`] for a box with a corner at
/// or behind the light plane (light-space `z <= 1e-6` of the scene diagonal, where
/// [`LightView::fit_with`] counts a receiver as behind the light) or beyond the frustum
/// (`|x/z| > MAX_TAN`), whose receivers no window could cover.
pub fn bounds_receivers(scene: &Scene, bounds: &Aabb, frame: LightFrame) -> Result<Receivers> {
    let (min, max) = checked_bounds(bounds)?;
    let z_eps = 1e-6 * scene.bounds().diagonal().max(1e-6);
    let mut corners = Vec::with_capacity(8);
    for c in box_corners(min, max) {
        let q = frame.to_light(c);
        if !q.is_finite() {
            return Err(Error::Receivers(format!(
                "receiver bounds corner {c} overflows in light space ({q})"
            )));
        }
        if q.z <= z_eps {
            return Err(Error::LightView(format!(
                "receiver bounds cross the light plane: corner {c} is at light-space z = {z} \
                 (must be > {z_eps}); pass tighter bounds holding only the receivers in front of \
                 the light (those behind it are unlit), or use fit=scene with the receivers on \
                 the CPU",
                z = q.z
            )));
        }
        let t = DVec2::new(q.x as f64, q.y as f64) / q.z as f64;
        if t.abs().max_element() > MAX_TAN as f64 {
            return Err(Error::LightView(format!(
                "receiver bounds leave the light frustum: corner {c} is at |x/z| = {} > {MAX_TAN} \
                 in light space; pass tighter bounds",
                t.abs().max_element()
            )));
        }
        corners.push(c);
    }
    Receivers::from_points(corners, vec![Vec3::Z; 8])
}

/// `bounds` checked: not inverted or empty, finite.
fn checked_bounds(bounds: &Aabb) -> Result<(Vec3, Vec3)> {
    let (min, max) = (bounds.min, bounds.max);
    if min.cmpgt(max).any() {
        return Err(Error::Receivers(format!(
            "receiver bounds are inverted or empty (min {min} > max {max} on some axis; no active \
             receiver?)"
        )));
    }
    if !(min.is_finite() && max.is_finite()) {
        return Err(Error::Receivers(format!(
            "receiver bounds are not finite (min {min}, max {max})"
        )));
    }
    Ok((min, max))
}

/// The 8 corners of the box `[min, max]`.
fn box_corners(min: Vec3, max: Vec3) -> impl Iterator<Item = Vec3> {
    (0..8).map(move |k| {
        Vec3::new(
            if k & 1 == 0 { min.x } else { max.x },
            if k & 2 == 0 { min.y } else { max.y },
            if k & 4 == 0 { min.z } else { max.z },
        )
    })
}

/// The 8 corners of `bounds` as the receivers a view fit at `frame` in `scene` takes:
/// [`bounds_receivers`], or under the sun [`sun_bounds_receivers`] (an orthographic view has no
/// light plane to cross and no frustum to leave).
fn corner_receivers(scene: &Scene, bounds: &Aabb, frame: LightFrame) -> Result<Receivers> {
    if scene.light().is_directional() {
        sun_bounds_receivers(bounds)
    } else {
        bounds_receivers(scene, bounds, frame)
    }
}

/// [`bounds_receivers`] under the sun: the corners of a checked box (an orthographic view has
/// no light plane to cross and no frustum to leave).
fn sun_bounds_receivers(bounds: &Aabb) -> Result<Receivers> {
    let (min, max) = checked_bounds(bounds)?;
    Receivers::from_points(box_corners(min, max).collect(), vec![Vec3::Z; 8])
}

impl LightView {
    /// [`fit_with`](Self::fit_with) for receivers known only by a world-space box that holds
    /// every one of them (`bounds`, e.g. [`receiver_bounds`] or the bounds of a user's G-buffer):
    /// the fit runs over the box's 8 corners ([`bounds_receivers`], which also lists the errors).
    ///
    /// Conservative: for a receiver p in the box, the window edges its footprint reaches,
    /// `(x_p -+ h_x) / z_p + h_x / n` (and likewise in y), are linear-fractional in p with `z_p >
    /// 0`, so over the box they are extreme at corners; n is at most the nearest corner depth
    /// (the nearest depth in the box) and far at least the farthest. So the window holds every
    /// footprint of a receiver inside the box, and in `x/z` units it holds the window
    /// [`fit_with`](Self::fit_with) fits to such receivers when n is not raised above theirs (the
    /// unit tests check both). The price is texel density: the box's footprint is usually larger
    /// than the receivers'.
    pub fn fit_bounds(
        scene: &Scene,
        bounds: &Aabb,
        frame: LightFrame,
        light_half: Vec2,
        r: u32,
        opts: &ViewOptions,
    ) -> Result<(LightView, FitReport)> {
        let corners = corner_receivers(scene, bounds, frame)?;
        Self::fit_with(scene, &corners, frame, light_half, r, opts)
    }
}

/// A stand-in, made from two world-space boxes alone, for the CPU scene and receivers an
/// estimator's view fit reads (`FrameEstimator::fit_views`, [`LightView::fit_with`]): a scene
/// whose casters are the 12 triangles of `casters` (the box holding every caster; the fit's near
/// plane lands at or in front of the real casters, so nothing is clipped, only some depth
/// precision is spent) under `light`, seen by `camera` (unused by the fit), and the 8 corners of
/// `receivers` ([`bounds_receivers`], or the plain corners under the sun). For a renderer whose
/// geometry and receivers stay on the GPU: fitting views to the stand-in costs the same for any
/// number of triangles and receivers, and the views hold every receiver in the box, as
/// [`LightView::fit_bounds`] explains; the price is texel density. A box flat on one axis (a
/// ground) is thickened by 1e-6 of its diagonal. Errors: the boxes' ([`bounds_receivers`]'s).
pub fn bounds_stand_in(
    light: &crate::Light,
    camera: &crate::Camera,
    casters: &Aabb,
    receivers: &Aabb,
) -> Result<(Scene, Receivers)> {
    let (min, max) = checked_bounds(casters)?;
    let pad = Vec3::splat(1e-6 * (max - min).length().max(1e-6));
    let (min, max) = (min - pad, max + pad);
    let c: Vec<Vec3> = box_corners(min, max).collect();
    // Corner k has bit 0 for x, 1 for y, 2 for z; two triangles per face.
    let faces = [
        [0, 2, 6, 4],
        [1, 5, 7, 3],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 6, 7, 5],
    ];
    let tris: Vec<[Vec3; 3]> = faces
        .iter()
        .flat_map(|f| [[c[f[0]], c[f[1]], c[f[2]]], [c[f[0]], c[f[2]], c[f[3]]]])
        .collect();
    let scene = Scene::from_meshes("casters' bounds", *camera, *light, vec![(tris, 1.0)])?;
    let corners = corner_receivers(&scene, receivers, light.frame())?;
    Ok((scene, corners))
}
