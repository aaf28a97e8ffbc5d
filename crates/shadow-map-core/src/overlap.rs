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
    let outside = |p: Vec2, e: Vec2| 0.5 * r * r * p.perp_dot(e).atan2(p.dot(e));
    let mut area = 0.0f32;
    for k in 0..m {
        let p0 = q[k];
        let p1 = q[(k + 1) % m];
        let d = p1 - p0;
        let a = d.dot(d);
        let b = p0.dot(d);
        let cc = p0.dot(p0) - r * r;
        let disc = b * b - a * cc;
        if !(disc > 0.0) || !(a > 0.0) {
            area += outside(p0, p1);
            continue;
        }
        let sq = disc.sqrt();
        let t1 = ((-b - sq) / a).clamp(0.0, 1.0);
        let t2 = ((-b + sq) / a).clamp(0.0, 1.0);
        let q1 = p0 + d * t1;
        let q2 = p0 + d * t2;
        if t1 > 0.0 {
            area += outside(p0, q1);
        }
        if t2 > t1 {
            area += 0.5 * q1.perp_dot(q2);
        }
        if t2 < 1.0 {
            area += outside(q2, p1);
        }
    }
    area.abs().min(full)
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
