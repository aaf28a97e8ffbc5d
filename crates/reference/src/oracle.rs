//! Closed-form visibility for configurations simple enough to integrate exactly: the test oracles
//! of docs/methods.md §10 (items 1-3), built on the disk geometry of §9.
//!
//! Everything here works in **light space** (docs/methods.md §1): the light centre is the origin,
//! the light lies in the plane `z = 0` and emits towards `+z`; a receiver `p` has `z_p > 0`.
//! V is the contract's area fraction of a uniform emitter (not a solid-angle fraction).
//!
//! The oracles assume the receiver faces the light: its tangent plane does not cut the light, so
//! the contract's tangent-plane rule never blocks a sample. A receiver behind or in the light plane
//! (`z_p <= 0`) gets V = 0, as a one-sided rect or disk light gives it.
//!
//! Arithmetic is in `f64`, so the oracles are exact to ~1e-12 for any reasonable input and serve
//! to measure the `f32` ray tracer (and every estimator) without sampling noise of their own.
use glam::{DVec2, Vec2, Vec3};
use std::f64::consts::PI;

/// An axis-aligned rectangle occluder parallel to the light, in light space: it covers
/// `[min.x, max.x] x [min.y, max.y]` at depth `z` (the planar light-space coordinate, `z > 0`
/// between the light and the receiver).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectOccluder {
    /// Lower corner `(a0, b0)`.
    pub min: Vec2,
    /// Upper corner `(a1, b1)`.
    pub max: Vec2,
    /// Depth `z_o` of its plane.
    pub z: f32,
}

impl RectOccluder {
    /// The rectangle `[min.x, max.x] x [min.y, max.y]` at depth `z`.
    pub const fn new(min: Vec2, max: Vec2, z: f32) -> Self {
        RectOccluder { min, max, z }
    }
}

/// Central projection from the receiver `p` onto the light plane `z = 0` of a point at depth `z_o`:
/// the scale `s = z_p / (z_p - z_o)` (docs/methods.md §10 item 1, §9). A point `q` at depth `z_o`
/// projects to `p_xy + s (q - p_xy)`.
#[inline]
pub fn projection_scale(z_p: f64, z_o: f64) -> f64 {
    z_p / (z_p - z_o)
}

/// Area of the union of axis-aligned rectangles `[x0, x1] x [y0, y1]`, exactly, by a sweep over
/// the sorted x coordinates: in every slab between consecutive x coordinates the covered length in
/// y is the union of the y intervals of the rectangles spanning the slab. `O(n^2 log n)`.
/// Empty or inverted rectangles contribute nothing.
pub fn union_area(rects: &[[f64; 4]]) -> f64 {
    let rects: Vec<[f64; 4]> = rects
        .iter()
        .copied()
        .filter(|r| r[1] > r[0] && r[3] > r[2])
        .collect();
    let mut xs: Vec<f64> = rects.iter().flat_map(|r| [r[0], r[1]]).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let mut area = 0.0;
    let mut spans: Vec<(f64, f64)> = Vec::with_capacity(rects.len());
    for w in xs.windows(2) {
        let (xa, xb) = (w[0], w[1]);
        spans.clear();
        spans.extend(
            rects
                .iter()
                .filter(|r| r[0] <= xa && r[1] >= xb)
                .map(|r| (r[2], r[3])),
        );
        if spans.is_empty() {
            continue;
        }
        spans.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut covered = 0.0;
        let (mut lo, mut hi) = spans[0];
        for &(a, b) in &spans[1..] {
            if a > hi {
                covered += hi - lo;
                lo = a;
                hi = b;
            } else if b > hi {
                hi = b;
            }
        }
        covered += hi - lo;
        area += (xb - xa) * covered;
    }
    area
}

/// Visibility of a rectangle light `[-h_x, h_x] x [-h_y, h_y]` (light space, `z = 0`, centred at the
/// origin, `light_half = (h_x, h_y)`) from the receiver `p` behind any number of axis-aligned
/// rectangle occluders parallel to it.
///
/// Background.md §10 item 1: with `s = z_p / (z_p - z_o)` an occluder `[a0, a1] x [b0, b1]` at depth
/// `z_o` projects to `[p_x + (a0 - p_x) s, p_x + (a1 - p_x) s] x [p_y + (b0 - p_y) s, p_y + (b1 - p_y) s]`
/// and `V = 1 - area(union of projections ∩ light) / A_L`. The union is exact ([`union_area`]).
///
/// Occluders not strictly between the light and the receiver (`z_o <= 0` or `z_o >= z_p`) block
/// nothing. `z_p <= 0` (receiver behind or in the light plane) gives 0; a light of zero area gives 1
/// when nothing applies (no area can be covered). Result in `[0, 1]`.
pub fn rect_occluder_visibility(light_half: Vec2, occluders: &[RectOccluder], p: Vec3) -> f64 {
    let (hx, hy) = (light_half.x.abs() as f64, light_half.y.abs() as f64);
    let (px, py, pz) = (p.x as f64, p.y as f64, p.z as f64);
    if pz <= 0.0 {
        return 0.0;
    }
    let light_area = 4.0 * hx * hy;
    if light_area <= 0.0 {
        return 1.0;
    }
    let clipped: Vec<[f64; 4]> = occluders
        .iter()
        .filter(|o| (o.z as f64) > 0.0 && (o.z as f64) < pz)
        .map(|o| {
            let s = projection_scale(pz, o.z as f64);
            let x0 = px + (o.min.x as f64 - px) * s;
            let x1 = px + (o.max.x as f64 - px) * s;
            let y0 = py + (o.min.y as f64 - py) * s;
            let y1 = py + (o.max.y as f64 - py) * s;
            [
                x0.min(x1).max(-hx),
                x0.max(x1).min(hx),
                y0.min(y1).max(-hy),
                y0.max(y1).min(hy),
            ]
        })
        .collect();
    (1.0 - union_area(&clipped) / light_area).clamp(0.0, 1.0)
}

/// Area of the intersection ("lens") of two disks of radii `r1`, `r2` whose centres are `d` apart
/// (docs/methods.md §9):
///
/// ```text
/// d >= r1 + r2:     A = 0
/// d <= |r1 - r2|:   A = pi min(r1, r2)^2
/// otherwise:        A = r1^2 acos((d^2 + r1^2 - r2^2)/(2 d r1)) + r2^2 acos((d^2 + r2^2 - r1^2)/(2 d r2))
///                       - 0.5 sqrt((-d + r1 + r2)(d + r1 - r2)(d - r1 + r2)(d + r1 + r2))
/// ```
///
/// The acos arguments are clamped to `[-1, 1]` and the square root's argument to `>= 0`. Negative
/// radii count as their absolute value; a zero radius gives 0.
pub fn lens_area(r1: f64, r2: f64, d: f64) -> f64 {
    let (r1, r2, d) = (r1.abs(), r2.abs(), d.abs());
    if r1 == 0.0 || r2 == 0.0 || d >= r1 + r2 {
        return 0.0;
    }
    if d <= (r1 - r2).abs() {
        let r = r1.min(r2);
        return PI * r * r;
    }
    let a1 = ((d * d + r1 * r1 - r2 * r2) / (2.0 * d * r1))
        .clamp(-1.0, 1.0)
        .acos();
    let a2 = ((d * d + r2 * r2 - r1 * r1) / (2.0 * d * r2))
        .clamp(-1.0, 1.0)
        .acos();
    let k = (-d + r1 + r2) * (d + r1 - r2) * (d - r1 + r2) * (d + r1 + r2);
    (r1 * r1 * a1 + r2 * r2 * a2 - 0.5 * k.max(0.0).sqrt()).max(0.0)
}

/// Visibility of a disk light of radius `R_L = light_radius` (light space, centred at the origin in
/// `z = 0`) from the receiver `p` behind a parallel disk occluder of radius `r_o = occ_radius`,
/// centre `c_o = occ_center_xy` at depth `z_o = occ_z`.
///
/// Background.md §9 ("Disk light behind a parallel disk occluder") and §10 item 2: the occluder
/// projects onto the light plane as the disk of centre `c' = p_xy + s (c_o - p_xy)` and radius
/// `r' = s r_o`, `s = z_p / (z_p - z_o)`, and `V = 1 - lens(R_L, r', |c'|) / (pi R_L^2)`
/// ([`lens_area`]).
///
/// An occluder not strictly between light and receiver (`z_o <= 0` or `z_o >= z_p`) blocks nothing;
/// `z_p <= 0` gives 0 (one-sided light); a zero-radius light gives 1. Result in `[0, 1]`.
pub fn disk_occluder_visibility(
    light_radius: f32,
    occ_center_xy: Vec2,
    occ_radius: f32,
    occ_z: f32,
    p: Vec3,
) -> f64 {
    parallel_occluder_visibility(light_radius, occ_z, p, |r_l, s, pxy| {
        let c = pxy + (occ_center_xy.as_dvec2() - pxy) * s;
        let r = s * occ_radius.abs() as f64;
        lens_area(r_l, r, c.length())
    })
}

/// What [`disk_occluder_visibility`] and [`polygon_occluder_disk_visibility`] share: with
/// `R_L = |light_radius|`, 0 for `z_p <= 0`, 1 for a zero-radius light or an occluder not
/// strictly between light and receiver, else `1 - blocked(R_L, s, p_xy) / (pi R_L^2)` clamped
/// to `[0, 1]`, where `blocked` is the area of the light the occluder's projection from `p`
/// (scale `s = z_p / (z_p - z_o)` about `p_xy`) covers.
fn parallel_occluder_visibility(
    light_radius: f32,
    occ_z: f32,
    p: Vec3,
    blocked: impl FnOnce(f64, f64, DVec2) -> f64,
) -> f64 {
    let r_l = light_radius.abs() as f64;
    let (pz, zo) = (p.z as f64, occ_z as f64);
    if pz <= 0.0 {
        return 0.0;
    }
    if r_l == 0.0 || zo <= 0.0 || zo >= pz {
        return 1.0;
    }
    let s = projection_scale(pz, zo);
    let pxy = DVec2::new(p.x as f64, p.y as f64);
    (1.0 - blocked(r_l, s, pxy) / (PI * r_l * r_l)).clamp(0.0, 1.0)
}

/// Area of `polygon ∩ disk`, the disk of radius `radius` centred at the origin, for a simple
/// polygon given by its vertices in order (either orientation).
///
/// Background.md §9 ("Polygon ∩ disk"): each directed edge `(a, b)` is split where it crosses the
/// circle; a piece `(P, Q)` inside the disk adds `cross(P, Q) / 2`, a piece outside adds
/// `R^2 atan2(cross(P, Q), dot(P, Q)) / 2`. The sum is the signed area of the intersection; its
/// absolute value is returned. Exact up to rounding.
pub fn polygon_disk_area(polygon: &[DVec2], radius: f64) -> f64 {
    let r = radius.abs();
    let n = polygon.len();
    if n < 3 || r == 0.0 {
        return 0.0;
    }
    let r2 = r * r;
    let mut sum = 0.0;
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        // Parameters in (0, 1) where |a + t (b - a)| = r.
        let d = b - a;
        let (qa, qb, qc) = (d.dot(d), 2.0 * a.dot(d), a.dot(a) - r2);
        let mut ts = [0.0, 1.0, 1.0, 1.0];
        let mut m = 1;
        let disc = qb * qb - 4.0 * qa * qc;
        if qa > 0.0 && disc > 0.0 {
            let sq = disc.sqrt();
            for t in [(-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)] {
                if t > 0.0 && t < 1.0 {
                    ts[m] = t;
                    m += 1;
                }
            }
        }
        ts[m] = 1.0;
        for k in 0..m {
            let p = a + d * ts[k];
            let q = a + d * ts[k + 1];
            let mid = a + d * (0.5 * (ts[k] + ts[k + 1]));
            let cross = p.perp_dot(q);
            if mid.length_squared() <= r2 {
                sum += 0.5 * cross;
            } else {
                sum += 0.5 * r2 * cross.atan2(p.dot(q));
            }
        }
    }
    sum.abs()
}

/// Visibility of a disk light of radius `light_radius` (light space, origin, `z = 0`) from the
/// receiver `p` behind a planar polygon occluder parallel to the light at depth `occ_z`, vertices
/// `polygon` (light-space x, y, in order). Exact for the polygon (the 64-gon a test mesh really
/// is), where [`disk_occluder_visibility`] is exact for the round disk the polygon approximates.
///
/// The polygon projects from `p` to the polygon with vertices `p_xy + s (v - p_xy)`,
/// `s = z_p / (z_p - z_o)` (docs/methods.md §10 item 1), and
/// `V = 1 - area(projection ∩ light) / (pi R^2)` ([`polygon_disk_area`]). Same edge cases as
/// [`disk_occluder_visibility`].
pub fn polygon_occluder_disk_visibility(
    light_radius: f32,
    polygon: &[Vec2],
    occ_z: f32,
    p: Vec3,
) -> f64 {
    parallel_occluder_visibility(light_radius, occ_z, p, |r_l, s, pxy| {
        let proj: Vec<DVec2> = polygon
            .iter()
            .map(|v| pxy + (v.as_dvec2() - pxy) * s)
            .collect();
        polygon_disk_area(&proj, r_l)
    })
}

/// Visibility of a sphere light (contract convention: the disk of radius `R = light_radius` through
/// the light centre, perpendicular to the direction from the receiver to the centre) behind a sphere
/// occluder of radius `rho = occ_radius` centred on that axis.
///
/// Background.md §9 ("Sphere light (contract convention)") and §10 item 3: with `D_L` the distance
/// from the receiver to the light centre and `D_o` the distance to the occluder's centre, the
/// occluder casts a circle of radius `D_L rho / sqrt(D_o^2 - rho^2)` onto the light disk, so
/// `V = 1 - min(1, (D_L rho / (R sqrt(D_o^2 - rho^2)))^2)`.
///
/// Returns `None` outside the formula's domain: the receiver inside the occluder (`D_o <= rho`), or
/// the occluder reaching the light disk's plane (`D_o + rho > D_L`), or a non-positive `R` or `D_L`.
pub fn sphere_occluder_on_axis_visibility(
    light_radius: f64,
    light_distance: f64,
    occ_radius: f64,
    occ_distance: f64,
) -> Option<f64> {
    let (r, d_l, rho, d_o) = (light_radius, light_distance, occ_radius.abs(), occ_distance);
    if !(r > 0.0 && d_l > 0.0 && d_o > rho && d_o + rho <= d_l) {
        return None;
    }
    let cast = d_l * rho / (d_o * d_o - rho * rho).sqrt();
    Some(1.0 - ((cast / r) * (cast / r)).min(1.0))
}

/// Visibility of a directional light (the sun; the contract's disk of directions of radius
/// `tan_half = tan(angle / 2)` at unit distance, area-uniform) from a point on a plane facing it,
/// under an opaque half plane parallel to that plane at height `h > 0` above it whose edge lies
/// at signed distance `x` from the point's foot (`x > 0`: the point lies on the open side), the
/// sun overhead (travelling along the planes' normal). A direction `n + a T + b B` (`T` across the
/// edge) passes the half plane where `x + a h > 0`, so V is the fraction of the disk with
/// `a > -x / h`: the circular segment `(acos u - u sqrt(1 - u^2)) / pi`, `u = clamp(-x / (h tan_half))`
/// (docs/methods.md §10, "The sun over a half plane"). 0.5 at the edge's foot.
pub fn half_plane_sun_visibility(x: f64, h: f64, tan_half: f64) -> f64 {
    if !(h > 0.0 && tan_half > 0.0) {
        return if x > 0.0 { 1.0 } else { 0.0 };
    }
    let u = (-x / (h * tan_half)).clamp(-1.0, 1.0);
    ((u.acos() - u * (1.0 - u * u).sqrt()) / PI).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Midpoint-rule integration over an `n x n` grid of the light: the fraction of light points
    /// `y` for which the segment p -> y misses every occluder (direct geometry, no formula shared
    /// with the oracle beyond the definition of V).
    fn brute_rect(light_half: Vec2, occ: &[RectOccluder], p: Vec3, n: usize) -> f64 {
        let (hx, hy) = (light_half.x as f64, light_half.y as f64);
        let (px, py, pz) = (p.x as f64, p.y as f64, p.z as f64);
        let mut free = 0usize;
        for i in 0..n {
            for j in 0..n {
                let x = -hx + 2.0 * hx * (i as f64 + 0.5) / n as f64;
                let y = -hy + 2.0 * hy * (j as f64 + 0.5) / n as f64;
                // Segment from (x, y, 0) to p crosses depth z at parameter t = z / pz.
                let blocked = occ.iter().any(|o| {
                    let z = o.z as f64;
                    if z <= 0.0 || z >= pz {
                        return false;
                    }
                    let t = z / pz;
                    let (qx, qy) = (x + t * (px - x), y + t * (py - y));
                    qx >= o.min.x as f64
                        && qx <= o.max.x as f64
                        && qy >= o.min.y as f64
                        && qy <= o.max.y as f64
                });
                if !blocked {
                    free += 1;
                }
            }
        }
        free as f64 / (n * n) as f64
    }

    #[test]
    fn union_area_cases() {
        assert_eq!(union_area(&[]), 0.0);
        assert!((union_area(&[[0.0, 2.0, 0.0, 1.0]]) - 2.0).abs() < 1e-15);
        // Two overlapping unit squares offset by (0.5, 0.5): 2 - 0.25.
        let a = union_area(&[[0.0, 1.0, 0.0, 1.0], [0.5, 1.5, 0.5, 1.5]]);
        assert!((a - 1.75).abs() < 1e-15, "{a}");
        // Nested, disjoint and a cross.
        let a = union_area(&[
            [0.0, 4.0, 0.0, 4.0],
            [1.0, 2.0, 1.0, 2.0],
            [10.0, 11.0, 0.0, 1.0],
        ]);
        assert!((a - 17.0).abs() < 1e-12, "{a}");
        let a = union_area(&[[0.0, 3.0, 1.0, 2.0], [1.0, 2.0, 0.0, 3.0]]);
        assert!((a - 5.0).abs() < 1e-12, "{a}");
    }

    #[test]
    fn rect_oracle_matches_brute_force() {
        let half = Vec2::new(0.6, 0.4);
        let occ = [
            RectOccluder::new(Vec2::new(-0.4, -0.3), Vec2::new(0.6, 0.5), 1.5),
            RectOccluder::new(Vec2::new(0.2, -1.0), Vec2::new(0.9, -0.1), 0.8),
            RectOccluder::new(Vec2::new(-2.0, 0.7), Vec2::new(-0.5, 1.2), 2.2),
        ];
        let mut worst = 0.0f64;
        for k in 0..60 {
            let p = Vec3::new(
                -2.0 + k as f32 * 0.07,
                0.3 - k as f32 * 0.02,
                2.5 + (k % 5) as f32 * 0.3,
            );
            let v = rect_occluder_visibility(half, &occ, p);
            let b = brute_rect(half, &occ, p, 600);
            worst = worst.max((v - b).abs());
        }
        // Midpoint rule on 600^2 points: edge error <= perimeter / (600 * side) ~ 0.005.
        assert!(worst < 0.005, "worst {worst}");
    }

    #[test]
    fn rect_oracle_edge_cases() {
        let half = Vec2::splat(0.5);
        let occ = [RectOccluder::new(
            Vec2::splat(-10.0),
            Vec2::splat(10.0),
            1.0,
        )];
        assert_eq!(
            rect_occluder_visibility(half, &occ, Vec3::new(0.0, 0.0, 2.0)),
            0.0
        );
        // Behind the receiver: no effect.
        assert_eq!(
            rect_occluder_visibility(half, &occ, Vec3::new(0.0, 0.0, 0.5)),
            1.0
        );
        // Receiver behind the light.
        assert_eq!(
            rect_occluder_visibility(half, &[], Vec3::new(0.0, 0.0, -1.0)),
            0.0
        );
        assert_eq!(
            rect_occluder_visibility(half, &[], Vec3::new(0.0, 0.0, 1.0)),
            1.0
        );
        // Concentric half-width occluder halfway: projection doubles, covers everything.
        let occ = [RectOccluder::new(
            Vec2::splat(-0.25),
            Vec2::splat(0.25),
            1.0,
        )];
        assert!(rect_occluder_visibility(half, &occ, Vec3::new(0.0, 0.0, 2.0)).abs() < 1e-12);
        // Quarter-width occluder: covers (0.5 / 1)^2 = 1/4 of the light.
        let occ = [RectOccluder::new(
            Vec2::splat(-0.125),
            Vec2::splat(0.125),
            1.0,
        )];
        let v = rect_occluder_visibility(half, &occ, Vec3::new(0.0, 0.0, 2.0));
        assert!((v - 0.75).abs() < 1e-12, "{v}");
    }

    #[test]
    fn lens_cases() {
        assert_eq!(lens_area(1.0, 1.0, 2.0), 0.0);
        assert_eq!(lens_area(1.0, 0.5, 3.0), 0.0);
        assert!((lens_area(1.0, 0.5, 0.2) - PI * 0.25).abs() < 1e-12);
        // Two unit disks at distance 1: 2 pi / 3 - sqrt(3) / 2.
        let a = lens_area(1.0, 1.0, 1.0);
        assert!(
            (a - (2.0 * PI / 3.0 - 3f64.sqrt() / 2.0)).abs() < 1e-12,
            "{a}"
        );
        // Continuous at both ends.
        assert!(lens_area(1.0, 0.5, 1.5 - 1e-9) < 1e-6);
        assert!((lens_area(1.0, 0.5, 0.5 + 1e-9) - PI * 0.25).abs() < 1e-6);
        // Symmetric.
        assert!((lens_area(0.7, 1.3, 1.1) - lens_area(1.3, 0.7, 1.1)).abs() < 1e-12);
    }

    #[test]
    fn lens_matches_polygon_disk() {
        // A fine polygon for the second disk gives nearly the lens area.
        for &(r1, r2, d) in &[
            (1.0, 1.0, 1.0),
            (1.0, 0.4, 0.9),
            (0.6, 1.2, 1.1),
            (1.0, 0.3, 0.2),
        ] {
            let n = 20000;
            let poly: Vec<DVec2> = (0..n)
                .map(|k| {
                    let t = 2.0 * PI * k as f64 / n as f64;
                    DVec2::new(d + r2 * t.cos(), r2 * t.sin())
                })
                .collect();
            let a = polygon_disk_area(&poly, r1);
            let l = lens_area(r1, r2, d);
            assert!((a - l).abs() < 1e-6, "{r1} {r2} {d}: {a} vs {l}");
        }
    }

    #[test]
    fn polygon_disk_cases() {
        let sq = |h: f64| {
            vec![
                DVec2::new(-h, -h),
                DVec2::new(h, -h),
                DVec2::new(h, h),
                DVec2::new(-h, h),
            ]
        };
        // Square inside the disk, disk inside the square, reversed orientation.
        assert!((polygon_disk_area(&sq(0.5), 1.0) - 1.0).abs() < 1e-12);
        assert!((polygon_disk_area(&sq(2.0), 1.0) - PI).abs() < 1e-12);
        let mut rev = sq(0.5);
        rev.reverse();
        assert!((polygon_disk_area(&rev, 1.0) - 1.0).abs() < 1e-12);
        // Half plane x > 0 of the unit disk.
        let half = vec![
            DVec2::new(0.0, -2.0),
            DVec2::new(2.0, -2.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 2.0),
        ];
        assert!((polygon_disk_area(&half, 1.0) - PI / 2.0).abs() < 1e-12);
        // Far away.
        let far: Vec<DVec2> = sq(0.5).iter().map(|v| *v + DVec2::new(5.0, 0.0)).collect();
        assert!(polygon_disk_area(&far, 1.0).abs() < 1e-12);
    }

    #[test]
    fn disk_oracle_cases() {
        // Concentric: V = 1 - min(1, (s r_o / R_L)^2).
        let v = disk_occluder_visibility(1.0, Vec2::ZERO, 0.25, 1.0, Vec3::new(0.0, 0.0, 2.0));
        assert!((v - 0.75).abs() < 1e-12, "{v}");
        let v = disk_occluder_visibility(1.0, Vec2::ZERO, 0.6, 1.0, Vec3::new(0.0, 0.0, 2.0));
        assert!(v.abs() < 1e-12, "{v}");
        assert_eq!(
            disk_occluder_visibility(1.0, Vec2::ZERO, 0.6, 1.0, Vec3::new(0.0, 0.0, -1.0)),
            0.0
        );
        assert_eq!(
            disk_occluder_visibility(1.0, Vec2::ZERO, 0.6, 3.0, Vec3::new(0.0, 0.0, 2.0)),
            1.0
        );
        // Agrees with the exact polygon oracle for a fine polygon.
        let poly: Vec<Vec2> = (0..4096)
            .map(|k| {
                let t = std::f32::consts::TAU * k as f32 / 4096.0;
                Vec2::new(0.1 + 0.3 * t.cos(), -0.2 + 0.3 * t.sin())
            })
            .collect();
        for k in 0..20 {
            let p = Vec3::new(
                -1.0 + 0.1 * k as f32,
                0.05 * k as f32,
                2.0 + 0.05 * k as f32,
            );
            let a = disk_occluder_visibility(0.5, Vec2::new(0.1, -0.2), 0.3, 1.2, p);
            let b = polygon_occluder_disk_visibility(0.5, &poly, 1.2, p);
            assert!((a - b).abs() < 1e-4, "{p}: {a} vs {b}");
        }
    }

    #[test]
    fn sphere_oracle_cases() {
        assert_eq!(sphere_occluder_on_axis_visibility(1.0, 3.0, 0.5, 0.4), None);
        assert_eq!(sphere_occluder_on_axis_visibility(1.0, 3.0, 0.5, 2.8), None);
        // Cast radius 3 * 0.3 / sqrt(1.5^2 - 0.09) = 0.6124; V = 1 - 0.375.
        let v = sphere_occluder_on_axis_visibility(1.0, 3.0, 0.3, 1.5).unwrap_or(f64::NAN);
        assert!((v - (1.0 - 0.81 / 2.16)).abs() < 1e-12, "{v}");
        let v = sphere_occluder_on_axis_visibility(0.2, 3.0, 0.3, 1.5).unwrap_or(f64::NAN);
        assert_eq!(v, 0.0);
    }
}
