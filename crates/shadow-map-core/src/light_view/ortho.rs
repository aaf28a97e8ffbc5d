//! The sun's light view: orthographic along the light's travel direction, fitted to what the
//! receivers need (docs/methods.md §14 "The orthographic view"), with the same window and
//! near/far choices as the perspective fit ([`FitMode`], [`NearFar`]).
//!
//! **Frame.** Axes from the light (e_z the travel direction); origin `c - 2 R e_z` with c and R
//! the centre and half diagonal of the scene's box, so every depth lies in `[R, 3 R]`: positive,
//! far from 0, and independent of the camera (what `fit=stable` needs for a fixed texel
//! lattice). Receivers off the scene's surfaces that would lie nearer than R grow the box.
//!
//! **Window.** A caster can shadow the receiver p only inside p's occluder prism: the directions
//! within the sun's disk, `|(x, y) - p_xy| <= (z_p - z) t` per axis at depth z (t = tan(angle/2),
//! the half extent of the disk of directions at unit distance). Cut at the near plane n it is
//! the square `p_xy +- (z_p - n) t`; the window is the bounding square of these (world units).
//!
//! **Near and far** (`nearfar=clipped`, the default): the union of the prisms is bounded by the
//! four planes `x >= min(p_x - z_p t) + z t` (and the three like it); n is the nearest geometry
//! inside them (nothing nearer can shadow a receiver), at most just in front of the nearest
//! receiver; far is the farthest geometry in the window's column.
use super::{check_resolution, ViewOptions};
use super::{snap_stable, FitMode, FitReport, LightView, NearFar, Plane, Polygon, Projection};
use crate::{light::LightFrame, receivers::Receivers, scene::Aabb, scene::Scene, Result};
use glam::{DVec2, Vec2, Vec3};

/// Fits an orthographic view along `frame.ez` (its origin is replaced, see the module
/// documentation) to the active receivers, for a disk of directions of half extent `tan_half`
/// (per axis, at unit distance; zero for a single direction).
pub(super) fn fit(
    scene: &Scene,
    receivers: &Receivers,
    frame: LightFrame,
    tan_half: Vec2,
    r: u32,
    opts: &ViewOptions,
) -> Result<(LightView, FitReport)> {
    check_resolution(r)?;
    let mut rep = FitReport::default();
    // The scene's box alone (so the frame stays put while the camera moves), grown by the
    // receivers only when one would lie less than R in front of the origin (receivers off the
    // scene's surfaces).
    let placed = |bounds: Aabb| {
        let bounds = if bounds.min.is_finite() && bounds.max.is_finite() {
            bounds
        } else {
            Aabb {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            }
        };
        let radius = (0.5 * bounds.diagonal()).max(1e-6);
        let centre = 0.5 * (bounds.min + bounds.max);
        let f = LightFrame {
            origin: centre - frame.ez * (2.0 * radius),
            ..frame
        };
        (f, radius)
    };
    let active = || {
        receivers
            .position()
            .iter()
            .zip(receivers.active())
            .filter(|(p, &a)| a && p.is_finite())
            .map(|(p, _)| *p)
    };
    let (mut frame, mut radius) = placed(scene.bounds());
    if active().any(|p| frame.to_light(p).z < radius) {
        let mut bounds = scene.bounds();
        active().for_each(|p| bounds.grow(p));
        (frame, radius) = placed(bounds);
    }
    let z_eps = 1e-6 * radius;
    let h = tan_half.as_dvec2();
    let rec: Vec<(DVec2, f64)> = receivers
        .position()
        .iter()
        .zip(receivers.active())
        .filter(|(_, &a)| a)
        .filter_map(|(p, _)| {
            let q = frame.to_light(*p);
            (q.z > z_eps).then(|| (DVec2::new(q.x as f64, q.y as f64), q.z as f64))
        })
        .collect();
    rep.behind = receivers.active().iter().filter(|&&a| a).count() - rec.len();
    if rec.is_empty() {
        let n = radius;
        let view = LightView {
            frame,
            n,
            far: 3.0 * radius,
            window_min: Vec2::splat(-1e-3 * radius),
            w: 2e-3 * radius,
            r,
            projection: Projection::Orthographic,
        };
        return Ok((view, rep));
    }
    let tris: Vec<[Vec3; 3]> = scene
        .triangles()
        .iter()
        .map(|t| t.map(|v| frame.to_light(v)))
        .collect();
    let zr_min = rec.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    let zr_max = rec.iter().map(|r| r.1).fold(0.0, f64::max);
    // Just in front of the nearest receiver: 1e-4 of the scene's size.
    let n_cap = (zr_min - 1e-4 * radius as f64).max(z_eps as f64) as f32;
    let hull = occluder_hull(&rec, h);
    let all_geometry = geometry_range(&tris, z_eps, None);
    let n = match (opts.nearfar, opts.fit) {
        (NearFar::Frustum, _) => n_cap,
        (NearFar::Aabb, _) => aabb_near(scene, frame).min(n_cap).max(z_eps),
        // Receiver-independent: the lattice and the kernels do not move with the camera.
        (NearFar::Clipped, FitMode::Stable) => all_geometry.0.min(n_cap),
        (NearFar::Clipped, _) => geometry_range(&tris, z_eps, Some(&hull)).0.min(n_cap),
    };
    let footprints = |n: f32| {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for &(p, z) in &rec {
            let f = h * (z - n as f64).max(0.0);
            lo = lo.min(p - f);
            hi = hi.max(p + f);
        }
        (lo, hi)
    };
    let (mut lo, mut hi) = footprints(n);
    let tight = (hi - lo).max_element().max(1e-9 * radius as f64);
    if opts.fit == FitMode::Scene {
        for v in tris.iter().flatten() {
            let q = DVec2::new(v.x as f64, v.y as f64);
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    let side = (hi - lo).max_element().max(1e-9 * radius as f64) * (1.0 + 1e-6);
    let c = (lo + hi) * 0.5;
    (lo, hi) = (c - DVec2::splat(side * 0.5), c + DVec2::splat(side * 0.5));
    if opts.fit == FitMode::Stable && r >= 2 {
        (lo, hi) = snap_stable(lo, hi, r);
    }
    let side = hi.x - lo.x;
    rep.window_scale = (side / tight) as f32;
    let far = match (opts.nearfar, opts.fit) {
        (NearFar::Frustum, _) => zr_max as f32,
        (NearFar::Clipped, FitMode::Stable) => all_geometry.1,
        _ => {
            let column = window_planes(lo, hi);
            geometry_range(&tris, n, Some(&column)).1
        }
    }
    .max(zr_max as f32);
    let view = LightView {
        frame,
        n,
        far,
        window_min: lo.as_vec2(),
        w: side as f32,
        r,
        projection: Projection::Orthographic,
    };
    Ok((view, rep))
}

/// The four planes bounding every receiver's occluder prism (module documentation).
fn occluder_hull(rec: &[(DVec2, f64)], h: DVec2) -> [Plane; 4] {
    let (mut a_lo, mut a_hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for &(p, z) in rec {
        a_lo = a_lo.min(p - h * z);
        a_hi = a_hi.max(p + h * z);
    }
    [
        [1.0, 0.0, -h.x, -a_lo.x],
        [-1.0, 0.0, -h.x, a_hi.x],
        [0.0, 1.0, -h.y, -a_lo.y],
        [0.0, -1.0, -h.y, a_hi.y],
    ]
}

/// The column over the window `[lo, hi]` (world units in the frame's x and y).
fn window_planes(lo: DVec2, hi: DVec2) -> [Plane; 4] {
    [
        [1.0, 0.0, 0.0, -lo.x],
        [-1.0, 0.0, 0.0, hi.x],
        [0.0, 1.0, 0.0, -lo.y],
        [0.0, -1.0, 0.0, hi.y],
    ]
}

/// Nearest and farthest geometry beyond `n_floor`, each triangle clipped to `planes` when given
/// (`(+inf, 0)` when none).
fn geometry_range(tris: &[[Vec3; 3]], n_floor: f32, planes: Option<&[Plane; 4]>) -> (f32, f32) {
    let floor: [Plane; 1] = [[0.0, 0.0, 1.0, -(n_floor as f64)]];
    let (mut zmin, mut zmax) = (f32::INFINITY, 0.0f32);
    for t in tris {
        let mut p = Polygon::triangle(t);
        if !p.clip(&floor) || !planes.is_none_or(|pl| p.clip(pl)) {
            continue;
        }
        let (a, b) = p.depth_range();
        zmin = zmin.min(a.max(n_floor));
        zmax = zmax.max(b);
    }
    (zmin, zmax)
}

/// `nearfar=aabb`: the nearest of the scene box's corners.
fn aabb_near(scene: &Scene, frame: LightFrame) -> f32 {
    let b = scene.bounds();
    (0..8)
        .map(|k| {
            let c = Vec3::new(
                if k & 1 == 0 { b.min.x } else { b.max.x },
                if k & 2 == 0 { b.min.y } else { b.max.y },
                if k & 4 == 0 { b.min.z } else { b.max.z },
            );
            frame.to_light(c).z
        })
        .fold(f32::INFINITY, f32::min)
}

#[cfg(test)]
mod tests {
    use crate::{
        camera::Camera,
        light::Light,
        light_view::{FitMode, LightView, NearFar, Projection, ViewOptions},
        receivers::Receivers,
        scene::Scene,
        test_geometry::square,
    };
    use glam::{Vec2, Vec3};

    /// A 20 x 20 ground and a 1 x 1 x 1 box standing on it, under a 4-degree sun.
    fn scene() -> Scene {
        let cam = Camera {
            eye: Vec3::new(0.0, 5.0, 8.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 40.0,
            width: 8,
            height: 8,
        };
        let light = Light::directional(Vec3::new(0.3, -1.0, 0.2), 4.0);
        Scene::from_meshes(
            "sun-box",
            cam,
            light,
            vec![(square(0.0, 10.0), 1.0), (square(1.0, 0.5), 1.0)],
        )
        .unwrap()
    }

    /// Ground receivers on a grid of pitch 0.05 from (x0, z0).
    fn ground(x0: f32, z0: f32) -> Receivers {
        let mut p = Vec::new();
        for j in 0..40 {
            for i in 0..40 {
                p.push(Vec3::new(x0 + 0.05 * i as f32, 0.0, z0 + 0.05 * j as f32));
            }
        }
        let n = vec![Vec3::Y; p.len()];
        Receivers::from_points(p, n).unwrap()
    }

    fn fit(s: &Scene, r: &Receivers, opts: &ViewOptions) -> LightView {
        let l = s.light();
        LightView::fit_with(s, r, l.frame(), l.half_extent(), 512, opts)
            .unwrap()
            .0
    }

    /// The window holds every receiver's occluder prism cut at the near plane, the near plane is
    /// at or in front of the box (the only caster over the receivers) and of every receiver, and
    /// depths are positive.
    #[test]
    fn the_window_holds_every_occluder_prism() {
        let s = scene();
        let rec = ground(-1.0, -1.0);
        let v = fit(&s, &rec, &ViewOptions::default());
        assert_eq!(v.projection, Projection::Orthographic);
        let t = s.light().shape.tan_half();
        let box_top = v.frame.to_light(Vec3::new(0.0, 1.0, 0.0)).z;
        assert!(v.n > 0.0 && v.n <= box_top, "n {} box {box_top}", v.n);
        for p in rec.position() {
            let q = v.frame.to_light(*p);
            assert!(q.z > v.n && q.z <= v.far, "{q} n {} far {}", v.n, v.far);
            let reach = Vec2::splat(t * (q.z - v.n));
            for c in [q.truncate() - reach, q.truncate() + reach] {
                let uv = (c - v.window_min) / v.delta();
                assert!(
                    uv.min_element() >= -1e-3 && uv.max_element() <= v.r as f32 + 1e-3,
                    "{uv}"
                );
            }
        }
    }

    /// `fit=stable`: panning the receivers keeps the texel pitch, the lattice (the window's
    /// corner a whole number of texels from the last one) and the depths.
    #[test]
    fn the_stable_window_keeps_its_lattice_when_the_receivers_pan() {
        let s = scene();
        let opts = ViewOptions {
            fit: FitMode::Stable,
            nearfar: NearFar::Clipped,
        };
        let a = fit(&s, &ground(-1.0, -1.0), &opts);
        let b = fit(&s, &ground(-0.63, -0.81), &opts);
        assert_eq!((a.w, a.n, a.far, a.frame), (b.w, b.n, b.far, b.frame));
        let k = (b.window_min - a.window_min) / a.delta();
        assert!(
            (k - k.round()).abs().max_element() < 1e-3,
            "corner moved by {k} texels"
        );
    }
}
