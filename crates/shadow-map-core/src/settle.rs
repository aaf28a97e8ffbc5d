//! Receivers settled without a map (docs/methods.md §1 "Receivers outside every view").
//!
//! A receiver p sees the light through its *light pyramid*: the convex hull of p and the light
//! (for a disk, the regular octagon circumscribing it; for a sphere, the octagon circumscribing
//! the contract's silhouette disk, perpendicular to p -> centre). Every ray from p to a light
//! point stays inside it, so when no scene triangle meets the pyramid in front of p's tangent
//! plane, nothing can shadow p and its visibility is exactly the facing fraction
//! ([`crate::Light::front_fraction_world`]). The test is conservative: a triangle that touches the
//! pyramid counts as a possible caster, and "not settled" only means "not proven unshadowed".
//!
//! Caster-aware fitting ([`crate::cascades::Casters`]) settles every receiver it can this way
//! and fits the views to the rest. Accumulation also uses it for the receivers no light view can
//! hold (beyond [`crate::light_view::MAX_TAN`] off the
//! light's axis, or nearer the light's plane than a sphere light's silhouette reaches): seen from
//! the light they lie almost in its plane, so the only geometry that can shadow them lies almost
//! in that plane too, and a scene rarely has any there.
use crate::{
    bvh::SceneBvh,
    light::default_tangent,
    light_view::{Plane, Polygon},
    Light, LightShape, Receivers, Scene,
};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Vertices of the polygon standing in for a disk (circumscribed, so it contains the disk).
pub const DISK_POLYGON: usize = 8;

/// Proves receivers unshadowed by testing their light pyramids against the scene's BVH.
pub struct Settler {
    bvh: SceneBvh,
    light: Light,
    /// Centre of the scene's bounds (a directional light's pyramid must reach past them).
    centre: Vec3,
}

impl Settler {
    /// Builds the scene's BVH (once; every test reuses it).
    pub fn new(scene: &Scene) -> Self {
        let b = scene.bounds();
        Settler {
            bvh: SceneBvh::new(scene),
            light: *scene.light(),
            centre: 0.5 * (b.min + b.max),
        }
    }

    /// How far from p a directional light's pyramid must reach to pass every scene triangle:
    /// beyond the scene's bounding sphere seen from p.
    fn reach(&self, p: Vec3) -> f32 {
        (p - self.centre).length() + self.bvh.scale + 1.0
    }

    /// True when no scene triangle meets the light pyramid of the world point `p` (unit normal
    /// `n`) strictly in front of its tangent plane: V at p is then its facing fraction exactly.
    /// False when something may shadow p, or when the pyramid is degenerate (p in the light's
    /// plane or at its centre).
    pub fn unshadowed(&self, p: Vec3, n: Vec3) -> bool {
        let reach = self.reach(p);
        let poly = light_polygon(&self.light, p, reach);
        let Some(planes) = pyramid(&self.light, &poly, p, n, self.bvh.scale, reach) else {
            return false;
        };
        let (mut lo, mut hi) = (p, p);
        for c in &poly {
            lo = lo.min(*c);
            hi = hi.max(*c);
        }
        !self
            .bvh
            .any_in_convex(lo, hi, &planes, |t| Polygon::triangle(t).clip(&planes))
    }

    /// Per receiver, its visibility when [`Settler::unshadowed`] proves it (the facing fraction,
    /// exact), else `None` (inactive receivers too). Receivers are tested in parallel.
    pub fn settle(&self, receivers: &Receivers) -> Vec<Option<f32>> {
        (0..receivers.len())
            .into_par_iter()
            .map(|i| {
                let (p, n) = (receivers.position()[i], receivers.normal()[i]);
                (receivers.active()[i] && self.unshadowed(p, n))
                    .then(|| self.light.front_fraction_world(p, n))
            })
            .collect()
    }
}

/// The light as a convex polygon seen from p (world space, counter-clockwise or clockwise):
/// a rect's 4 corners, or the [`DISK_POLYGON`]-gon circumscribing a disk (the sphere's
/// silhouette disk, perpendicular to p -> centre; a directional light's disk of directions
/// carried `reach` from p, beyond which no scene geometry lies: pass the scene's diagonal).
pub fn light_polygon(light: &Light, p: Vec3, reach: f32) -> Vec<Vec3> {
    let f = light.frame();
    let ngon = |c: Vec3, e1: Vec3, e2: Vec3, r: f32| -> Vec<Vec3> {
        let m = DISK_POLYGON as f32;
        let rr = r / (std::f32::consts::PI / m).cos();
        (0..DISK_POLYGON)
            .map(|k| {
                let phi = 2.0 * std::f32::consts::PI * k as f32 / m;
                c + (e1 * phi.cos() + e2 * phi.sin()) * rr
            })
            .collect()
    };
    match light.shape {
        LightShape::Rect { size } => {
            let (hx, hy) = (0.5 * size[0], 0.5 * size[1]);
            [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
                .iter()
                .map(|&(x, y)| f.to_world(Vec3::new(x, y, 0.0)))
                .collect()
        }
        LightShape::Disk { radius } => ngon(light.center, f.ex, f.ey, radius),
        LightShape::Sphere { radius } => {
            let a = (p - light.center).normalize_or(f.ez);
            let e1 = default_tangent(a);
            ngon(light.center, e1, a.cross(e1), radius)
        }
        LightShape::Directional { .. } => {
            ngon(p - f.ez * reach, f.ex, f.ey, light.shape.tan_half() * reach)
        }
    }
}

/// The planes bounding p's light pyramid over the light polygon `poly` ([`light_polygon`] with
/// the same `reach`) in front of its tangent plane, each `[a, b, c, d]` with
/// `a x + b y + c z + d >= 0` inside: one per polygon edge through p, the light polygon's own
/// plane (p's side), and the tangent plane moved `1e-5 |p - centre| + 1e-6 scale` towards the
/// light (the receiver's own surface lies in it). `None` when degenerate.
fn pyramid(
    light: &Light,
    poly: &[Vec3],
    p: Vec3,
    n: Vec3,
    scale: f32,
    reach: f32,
) -> Option<Vec<Plane>> {
    let poly: Vec<DVec3> = poly.iter().map(|v| v.as_dvec3()).collect();
    let pd = p.as_dvec3();
    // The light's centre: for a directional light, the centre of its polygon.
    let c = if light.is_directional() {
        (p - light.normal * reach).as_dvec3()
    } else {
        light.center.as_dvec3()
    };
    let dist = (pd - c).length();
    if !(dist > 0.0) {
        return None;
    }
    let plane = |m: DVec3, through: DVec3| -> Plane { [m.x, m.y, m.z, -m.dot(through)] };
    let side = |pl: &Plane, x: DVec3| pl[0] * x.x + pl[1] * x.y + pl[2] * x.z + pl[3];
    let mut planes = Vec::with_capacity(poly.len() + 2);
    for k in 0..poly.len() {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        let m = (a - pd).cross(b - pd);
        let mut pl = plane(m, pd);
        let s = side(&pl, c);
        // The centre must lie clearly inside (relative to |m| |c - p|), else p is (almost) in the
        // light's plane and the pyramid has no interior.
        if !(s.abs() > 1e-9 * m.length() * dist) {
            return None;
        }
        if s < 0.0 {
            pl = pl.map(|x| -x);
        }
        planes.push(pl);
    }
    // The polygon's plane, p's side.
    let e = (poly[1] - poly[0]).cross(poly[2] - poly[0]);
    let mut base = plane(e, c);
    if side(&base, pd) < 0.0 {
        base = base.map(|x| -x);
    }
    planes.push(base);
    // The tangent plane, moved towards the light by eps: casters lie strictly in front of it.
    let nd = n.as_dvec3();
    let eps = 1e-5 * dist + 1e-6 * scale as f64;
    let mut tangent = plane(nd, pd);
    tangent[3] -= eps;
    planes.push(tangent);
    planes
        .iter()
        .all(|pl| pl.iter().all(|x| x.is_finite()))
        .then_some(planes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{camera::Camera, scene::Scene};

    fn scene(light: Light, tris: Vec<[Vec3; 3]>) -> Scene {
        let camera = Camera {
            eye: Vec3::new(0.0, 5.0, 30.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 8,
            height: 8,
        };
        Scene::from_meshes("settle", camera, light, vec![(tris, 1.0)]).unwrap()
    }

    fn light(center: Vec3, normal: Vec3, shape: LightShape) -> Light {
        Light {
            shape,
            center,
            normal,
            tangent: default_tangent(normal),
        }
    }

    fn ground() -> Vec<[Vec3; 3]> {
        crate::test_geometry::square(0.0, 50.0)
    }

    /// A light facing +x at height 1 above a ground that runs past its plane: ground points far
    /// to the side are unshadowed (the ground itself lies in their tangent plane) until a wall
    /// stands between them and the light.
    #[test]
    fn grazing_receivers_settle_until_a_wall_blocks() {
        for shape in [
            LightShape::Rect { size: [1.0, 1.0] },
            LightShape::Disk { radius: 0.5 },
            LightShape::Sphere { radius: 0.5 },
        ] {
            let light = light(Vec3::new(0.0, 1.0, 0.0), Vec3::X, shape);
            let open = Settler::new(&scene(light, ground()));
            // 89.4 degrees off the light's axis (x = 0.2, 20 m to the side).
            let p = Vec3::new(0.2, 0.0, 20.0);
            assert!(open.unshadowed(p, Vec3::Y), "{shape:?}");
            // A wall across the path at z = 10, x in [-1, 1], y in [0, 2].
            let mut tris = ground();
            let (a, b, c, d) = (
                Vec3::new(-1.0, 0.0, 10.0),
                Vec3::new(1.0, 0.0, 10.0),
                Vec3::new(1.0, 2.0, 10.0),
                Vec3::new(-1.0, 2.0, 10.0),
            );
            tris.push([a, b, c]);
            tris.push([a, c, d]);
            let walled = Settler::new(&scene(light, tris.clone()));
            assert!(!walled.unshadowed(p, Vec3::Y), "{shape:?}");
            // The same wall far off the path does not block.
            let moved: Vec<[Vec3; 3]> = tris
                .iter()
                .map(|t| {
                    t.map(|v| {
                        if v.z == 10.0 {
                            v + Vec3::new(0.0, 0.0, -30.0)
                        } else {
                            v
                        }
                    })
                })
                .collect();
            assert!(
                Settler::new(&scene(light, moved)).unshadowed(p, Vec3::Y),
                "{shape:?}"
            );
        }
    }

    /// The culled traversal finds a caster exactly when testing every triangle does: random
    /// boxes scattered around a tilted light, receivers on the ground.
    #[test]
    fn culled_traversal_matches_testing_every_triangle() {
        use proptest::{
            prelude::Rng,
            test_runner::{RngAlgorithm, TestRng},
        };
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        let mut next = move || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        let mut tris = ground();
        for _ in 0..60 {
            let c = Vec3::new(next() * 20.0 - 10.0, next() * 3.0, next() * 20.0 - 10.0);
            let h = Vec3::new(0.1 + next() * 0.5, 0.1 + next() * 0.5, 0.1 + next() * 0.5);
            for (a, b, d) in [(0usize, 1usize, 2usize), (1, 2, 0), (2, 0, 1)] {
                for s in [-1.0f32, 1.0] {
                    let mut q = [Vec3::ZERO; 4];
                    for (k, (u, v)) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                        .into_iter()
                        .enumerate()
                    {
                        let mut o = [0.0f32; 3];
                        o[a] = s * h[a];
                        o[b] = u * h[b];
                        o[d] = v * h[d];
                        q[k] = c + Vec3::from(o);
                    }
                    tris.push([q[0], q[1], q[2]]);
                    tris.push([q[0], q[2], q[3]]);
                }
            }
        }
        let light = light(
            Vec3::new(1.0, 6.0, -2.0),
            Vec3::new(0.2, -1.0, 0.3).normalize(),
            LightShape::Rect { size: [2.0, 1.0] },
        );
        let s = Settler::new(&scene(light, tris.clone()));
        let (mut settled, mut total) = (0, 0);
        for _ in 0..400 {
            let p = Vec3::new(next() * 30.0 - 15.0, 0.0, next() * 30.0 - 15.0);
            let reach = s.reach(p);
            let poly = light_polygon(&light, p, reach);
            let planes = pyramid(&light, &poly, p, Vec3::Y, s.bvh.scale, reach).unwrap();
            let brute = tris.iter().any(|t| Polygon::triangle(t).clip(&planes));
            assert_eq!(s.unshadowed(p, Vec3::Y), !brute, "{p}");
            total += 1;
            settled += usize::from(!brute);
        }
        // Both outcomes occur.
        assert!(settled > 20 && settled < total - 20, "{settled} of {total}");
    }

    /// Under the sun (a directional light, its pyramid reaching past the scene): a ground point
    /// is settled in the open, not under a roof on its path to the sun, settled again when the
    /// roof moves aside; and its V is the facing fraction (1 on flat ground, the sun high).
    #[test]
    fn the_sun_settles_open_ground_only() {
        let sun = Light::directional(Vec3::new(0.3, -1.0, 0.1), 2.0);
        let p = Vec3::new(0.0, 0.0, 0.0);
        let open = Settler::new(&scene(sun, ground()));
        assert!(open.unshadowed(p, Vec3::Y));
        assert_eq!(sun.front_fraction_world(p, Vec3::Y), 1.0);
        // A roof 10 up, over the point's path towards the sun (which lies towards -x).
        let roof = |x: f32| {
            let (a, b, c, d) = (
                Vec3::new(x - 2.0, 10.0, -2.0),
                Vec3::new(x + 2.0, 10.0, -2.0),
                Vec3::new(x + 2.0, 10.0, 2.0),
                Vec3::new(x - 2.0, 10.0, 2.0),
            );
            let mut t = ground();
            t.push([a, b, c]);
            t.push([a, c, d]);
            t
        };
        assert!(!Settler::new(&scene(sun, roof(-3.0))).unshadowed(p, Vec3::Y));
        assert!(Settler::new(&scene(sun, roof(20.0))).unshadowed(p, Vec3::Y));
    }

    /// Degenerate receivers (in the light's plane, at the centre) are never settled.
    #[test]
    fn degenerate_pyramids_are_not_settled() {
        let light = light(
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::X,
            LightShape::Rect { size: [1.0, 1.0] },
        );
        let s = Settler::new(&scene(light, ground()));
        assert!(!s.unshadowed(Vec3::new(0.0, 0.0, 5.0), Vec3::Y));
        assert!(!s.unshadowed(Vec3::new(0.0, 1.0, 0.0), Vec3::Y));
    }
}
