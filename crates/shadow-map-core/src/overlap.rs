//! Areas of overlap between a light and the image of a caster on the light's plane (docs/methods.md
//! §9 "Polygon ∩ disk"), shared by every estimator that measures occlusion as an area of the light:
//! accumulation's caster quadrilaterals, backprojection's micropatches on disk and sphere lights.
//! Each has a WGSL twin in `gpu/overlap.wgsl` with the same operation order.
use glam::Vec2;

/// Shoelace area of a polygon (corners in order, either orientation).
#[inline]
pub fn poly_area(q: &[Vec2]) -> f32 {
    let m = q.len();
    let mut a = 0.0f32;
    for k in 0..m {
        a += q[k].perp_dot(q[(k + 1) % m]);
    }
    (0.5 * a).abs()
}

/// Area of a convex quadrilateral (corners in order, either orientation) inside the disk of
/// radius `r` at the origin (docs/methods.md §9, "Polygon ∩ disk"): per directed edge, pieces
/// inside the circle add `cross(P, Q) / 2`, pieces outside add `r^2 atan2(cross, dot) / 2`; the
/// sum is the signed area. Shortcuts: bounding boxes apart (0), every corner inside (the shoelace
/// area), the disk inside the quadrilateral (`pi r^2`). Never NaN for finite inputs.
pub fn quad_disk_area(q: [Vec2; 4], r: f32) -> f32 {
    poly_disk_area(&q, r)
}

/// [`quad_disk_area`] for any convex polygon (corners in order, either orientation; up to
/// of them; accumulation's quadrilateral clipped by the receiver's tangent plane takes it).
pub fn poly_disk_area(q: &[Vec2], r: f32) -> f32 {
    let m = q.len();
    if !(r > 0.0) || m < 3 {
        return 0.0;
    }
    let mut lo = q[0];
    let mut hi = q[0];
    for p in &q[1..] {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if !(lo.x < r && lo.y < r && hi.x > -r && hi.y > -r) {
        return 0.0;
    }
    let full = std::f32::consts::PI * r * r;
    if q.iter().all(|p| p.length_squared() <= r * r) {
        let mut a = 0.0f32;
        for k in 0..m {
            a += q[k].perp_dot(q[(k + 1) % m]);
        }
        return (0.5 * a).abs().min(full);
    }
    // The disk inside the polygon: the centre at least r inside every edge (signed by the
    // orientation).
    let mut a2 = 0.0f32;
    for k in 0..m {
        a2 += q[k].perp_dot(q[(k + 1) % m]);
    }
    let orient = if a2 < 0.0 { -1.0f32 } else { 1.0 };
    let mut contains = true;
    for k in 0..m {
        let e = q[(k + 1) % m] - q[k];
        // Signed distance of the origin from the edge line, positive inside.
        let d = orient * e.perp_dot(-q[k]);
        if !(d >= r * e.length()) {
            contains = false;
        }
    }
    if contains {
        return full;
    }
    let mut area = 0.0f32;
    for k in 0..m {
        area += edge_disk_area(q[k], q[(k + 1) % m], r);
    }
    area.abs().min(full)
}

/// Signed area of the disk of radius `r` at the origin inside the angular wedge swept from
/// direction `p` to direction `q` the short way: `r^2 atan2(cross(p, q), dot(p, q)) / 2`
/// (docs/methods.md §9 "Polygon ∩ disk"; the "sector" of §3 "Disk lights"). Positive for a
/// counter-clockwise sweep; 0 when either point is the origin.
#[inline]
pub fn disk_wedge(p: Vec2, q: Vec2, r: f32) -> f32 {
    0.5 * r * r * p.perp_dot(q).atan2(p.dot(q))
}

/// Signed area of the triangle `(0, p0, p1)` inside the disk of radius `r` at the origin, the
/// per-edge term of [`poly_disk_area`] (docs/methods.md §9 "Polygon ∩ disk", §3 "Disk lights"):
/// the chord of the segment inside the circle, `p0 + t (p1 - p0)` for `t` in `[t1, t2]` (the roots
/// of `|p0 + t d|^2 = r^2` clamped to `[0, 1]`, the disk being convex), adds the triangle
/// `cross(q1, q2) / 2`; the pieces before and after it, outside the circle, add their
/// [`disk_wedge`]s. Positive for a counter-clockwise sweep `p0 -> p1` seen from the origin.
///
/// Summed over a closed polygon's directed edges it is the polygon's signed area inside the disk;
/// minus `disk_wedge(p0, p1, r)` it is the radial-integration term `tri - sector` of one contour
/// edge on a disk light (packet-hsm): the outside pieces cancel, leaving
/// `cross(q1, q2) / 2 - disk_wedge(q1, q2, r)`. Never NaN for finite inputs (a degenerate or
/// missing chord falls back to the wedge alone); inputs whose squares overflow f32 are the
/// caller's to clip first.
#[inline]
pub fn edge_disk_area(p0: Vec2, p1: Vec2, r: f32) -> f32 {
    let d = p1 - p0;
    let a = d.dot(d);
    let b = p0.dot(d);
    let cc = p0.dot(p0) - r * r;
    let disc = b * b - a * cc;
    if !(disc > 0.0) || !(a > 0.0) {
        return disk_wedge(p0, p1, r);
    }
    let sq = disc.sqrt();
    let t1 = ((-b - sq) / a).clamp(0.0, 1.0);
    let t2 = ((-b + sq) / a).clamp(0.0, 1.0);
    let q1 = p0 + d * t1;
    let q2 = p0 + d * t2;
    let mut area = 0.0f32;
    if t1 > 0.0 {
        area += disk_wedge(p0, q1, r);
    }
    if t2 > t1 {
        area += 0.5 * q1.perp_dot(q2);
    }
    if t2 < 1.0 {
        area += disk_wedge(q2, p1, r);
    }
    area
}

/// Area of the axis-aligned rectangle `[x0, x1] x [y0, y1]` inside the disk of radius `r` at
/// the origin ([`quad_disk_area`] of its corners; 0 for an empty or inverted rectangle).
#[inline]
pub fn rect_disk_area(x0: f32, y0: f32, x1: f32, y1: f32, r: f32) -> f32 {
    if !(x1 > x0 && y1 > y0) {
        return 0.0;
    }
    quad_disk_area(
        [
            Vec2::new(x0, y0),
            Vec2::new(x1, y0),
            Vec2::new(x1, y1),
            Vec2::new(x0, y1),
        ],
        r,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn centred(c: Vec2, ax: f32, ay: f32, r: f32) -> f32 {
        rect_disk_area(c.x - ax, c.y - ay, c.x + ax, c.y + ay, r)
    }

    #[test]
    fn rect_disk_area_matches_a_grid() {
        let r = 0.7;
        for (c, ax, ay) in [
            (Vec2::new(0.1, -0.2), 0.3, 0.5),
            (Vec2::new(0.6, 0.5), 0.4, 0.2),
            (Vec2::new(-0.9, 0.0), 0.3, 0.3),
            (Vec2::new(0.0, 0.0), 2.0, 0.1),
            (Vec2::new(0.2, 0.1), 3.0, 3.0),
            (Vec2::new(3.0, 0.1), 0.5, 0.5),
        ] {
            let m = 1000;
            let mut hit = 0u32;
            for j in 0..m {
                for i in 0..m {
                    let p = Vec2::new(
                        c.x - ax + 2.0 * ax * (i as f32 + 0.5) / m as f32,
                        c.y - ay + 2.0 * ay * (j as f32 + 0.5) / m as f32,
                    );
                    if p.length_squared() <= r * r {
                        hit += 1;
                    }
                }
            }
            let grid = 4.0 * ax * ay * hit as f32 / (m * m) as f32;
            let a = centred(c, ax, ay, r);
            assert!((a - grid).abs() < 2e-3, "{c} {ax} {ay}: {a} vs {grid}");
        }
    }

    /// `edge_disk_area(a, b) - disk_wedge(a, b)` by numeric integration in polar coordinates
    /// (f64, 20000 midpoint steps): along the direction at angle theta of the sweep the triangle
    /// reaches `rho = cross(a, b) / cross(dir, b - a)`, so the term is
    /// `integral of (min(rho, r)^2 - r^2) / 2 dtheta` over the signed sweep.
    fn edge_sector_numeric(a: Vec2, b: Vec2, r: f32) -> f64 {
        let (a, b, r) = (a.as_dvec2(), b.as_dvec2(), r as f64);
        let sweep = a.perp_dot(b).atan2(a.dot(b));
        let th0 = a.y.atan2(a.x);
        let n = 20000;
        let step = sweep / n as f64;
        let mut sum = 0.0;
        for k in 0..n {
            let th = th0 + (k as f64 + 0.5) * step;
            let d = glam::DVec2::new(th.cos(), th.sin());
            let rho = (a.perp_dot(b) / d.perp_dot(b - a)).abs();
            let m = rho.min(r);
            sum += 0.5 * (m * m - r * r) * step;
        }
        sum
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]
        /// The edge-sector area (packet-hsm's disk term) against numeric integration: edges
        /// inside the circle, crossing it, outside it (chord or none), and passing next to the
        /// centre on either side; an edge exactly through the centre stays finite.
        #[test]
        fn edge_sector_matches_numeric_integration(
            kind in 0u32..5,
            r in 0.1f32..2.0,
            u in proptest::array::uniform4(-1.0f32..1.0),
            side in proptest::bool::ANY,
        ) {
            let s = |x: f32, y: f32, k: f32| Vec2::new(x, y) * (k * r);
            let (a, b) = match kind {
                0 => (s(u[0], u[1], 0.7), s(u[2], u[3], 0.7)),      // inside
                1 => (s(u[0], u[1], 0.6), s(u[2], u[3], 3.0)),      // one end inside
                2 => (s(u[0], u[1], 3.0), s(u[2], u[3], 3.0)),      // both ends anywhere
                3 => {
                    // Next to the centre: b almost opposite a.
                    let a = s(u[0], u[1], 2.0) + Vec2::splat(0.05 * r);
                    let off = if side { 1e-3 } else { -1e-3 } * r;
                    (a, -a * (0.5 + u[2].abs()) + a.perp().normalize() * off)
                }
                _ => (s(u[0], u[1], 1.5) + Vec2::new(1.6 * r, 0.0), s(u[2], u[3], 1.5) + Vec2::new(1.6 * r, 0.0)),
            };
            let got = edge_disk_area(a, b, r) - disk_wedge(a, b, r);
            let want = edge_sector_numeric(a, b, r);
            proptest::prop_assert!(got.is_finite());
            proptest::prop_assert!(
                (got as f64 - want).abs() <= 2e-5 * (r * r) as f64,
                "{a} {b} r={r}: {got} vs {want}"
            );
            // Exactly through the centre: finite (the receiver is nudged off such edges).
            let t = edge_disk_area(a, -a, r) - disk_wedge(a, -a, r);
            proptest::prop_assert!(t.is_finite());
        }
    }

    /// Rectangles far apart from, inside and around the disk, and inverted ones.
    #[test]
    fn rect_disk_area_limits() {
        let r = 0.5f32;
        let full = std::f32::consts::PI * r * r;
        assert_eq!(rect_disk_area(2.0, 2.0, 3.0, 3.0, r), 0.0);
        assert_eq!(rect_disk_area(0.3, 0.0, 0.1, 1.0, r), 0.0);
        assert!((rect_disk_area(-1e30, -1e30, 1e30, 1e30, r) - full).abs() < 1e-6);
        assert!((rect_disk_area(-0.1, -0.1, 0.1, 0.1, r) - 0.04).abs() < 1e-7);
        // The half plane x > 0 holds half the disk.
        assert!((rect_disk_area(0.0, -9.0, 9.0, 9.0, r) - 0.5 * full).abs() < 1e-6);
    }
}
