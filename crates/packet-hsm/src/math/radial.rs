//! Backprojection of contour edges onto the light and their radial integration (docs/methods.md
//! §3): the light-plane geometry of rect, disk and sphere emitters.
use super::contour::{Edge, Receiver};
use glam::DVec2;
use shadow_map_core::{
    overlap::{disk_wedge, edge_disk_area},
    silhouette::Silhouette,
};

/// How texel offsets scale onto the light when backprojected ([`backproject`]): `k = w / (n r)`
/// in a perspective view; the texel pitch `delta` in an orthographic one (the sun), whose
/// "light plane" is its disk of directions at unit distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    /// `w / (n r)`, or `delta` when `ortho`.
    pub k: f64,
    /// The view is orthographic (the sun).
    pub ortho: bool,
}

impl Scale {
    /// The scale of `view`.
    pub fn of(view: &shadow_map_core::LightView) -> Scale {
        if view.is_ortho() {
            Scale {
                k: view.delta() as f64,
                ortho: true,
            }
        } else {
            Scale {
                k: (view.delta() / view.n) as f64,
                ortho: false,
            }
        }
    }
}

impl From<f64> for Scale {
    /// A perspective view's `k`.
    fn from(k: f64) -> Scale {
        Scale { k, ortho: false }
    }
}

/// Backprojects a contour vertex at texel coordinates `uv` with depth `zs` from the receiver onto
/// the light plane (docs/methods.md §3): `x_L = k z_s z_p (u - u_p) / (z_p - z_s)`, `k = w/(n r)`.
/// Light-plane world coordinates relative to the (sub-)light centre. Finite for finite inputs
/// with `zs < zp` (the difference is floored at `1e-12 z_p`).
///
/// The sun (docs/methods.md §14 "Packet-hsm"): onto its disk of directions at unit distance,
/// `x_L = delta (u - u_p) / (z_p - z_s)`.
#[inline]
pub fn backproject(uv: [f32; 2], zs: f32, rec: &Receiver, k: Scale) -> DVec2 {
    let zs = zs as f64;
    let gap = (rec.zp - zs)
        .max(1e-12 * rec.zp.abs())
        .max(f64::MIN_POSITIVE);
    let s = if k.ortho {
        k.k / gap
    } else {
        k.k * zs * rec.zp / gap
    };
    DVec2::new(uv[0] as f64 - rec.uv.x, uv[1] as f64 - rec.uv.y) * s
}

/// Clips the segment `a -> b` to the rectangle `[-h.x, h.x] x [-h.y, h.y]` (Liang-Barsky);
/// `None` when nothing of it lies inside.
pub fn clip_to_rect(a: DVec2, b: DVec2, h: DVec2) -> Option<(DVec2, DVec2)> {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d.x, a.x + h.x),
        (d.x, h.x - a.x),
        (-d.y, a.y + h.y),
        (d.y, h.y - a.y),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if !(t0 <= t1) {
        return None;
    }
    Some((a + d * t0, a + d * t1))
}

/// Signed area of the rectangle light `[-h.x, h.x] x [-h.y, h.y]` inside the angular wedge swept
/// from direction `a` to direction `b` the short way (docs/methods.md §3): the shoelace area of
/// `0, a_R, (corners strictly inside the sweep, in sweep order), b_R`, where `a_R` is `a`
/// projected radially onto the border. Positive for a counter-clockwise sweep.
///
/// Sweeps narrower than a half turn (every edge but one through the centre) take no
/// trigonometry: with `s` the sweep's sign, a corner `c` is strictly inside when
/// `s a x c > 0` and `s c x b > 0`, and `c1` precedes `c2` when `s c1 x c2 > 0`. A half turn
/// (`a x b = 0`, `a . b < 0`, where the short way is decided by the sign of zero) takes
/// [`sector_rect_by_angle`].
pub fn sector_rect(a: DVec2, b: DVec2, h: DVec2) -> f64 {
    let cr = a.perp_dot(b);
    if a == DVec2::ZERO || b == DVec2::ZERO || (cr == 0.0 && a.dot(b) >= 0.0) {
        return 0.0;
    }
    if cr == 0.0 {
        return sector_rect_by_angle(a, b, h);
    }
    let sg = cr.signum();
    let to_border = |p: DVec2| p / (p.x.abs() / h.x).max(p.y.abs() / h.y);
    let mut corners = [DVec2::ZERO; 4];
    let mut n = 0;
    for c in rect_corners(h) {
        if sg * a.perp_dot(c) > 0.0 && sg * c.perp_dot(b) > 0.0 {
            // Insertion in sweep order.
            let mut k = n;
            while k > 0 && sg * c.perp_dot(corners[k - 1]) > 0.0 {
                corners[k] = corners[k - 1];
                k -= 1;
            }
            corners[k] = c;
            n += 1;
        }
    }
    let mut prev = to_border(a);
    let mut twice = 0.0;
    for c in &corners[..n] {
        twice += prev.perp_dot(*c);
        prev = *c;
    }
    twice += prev.perp_dot(to_border(b));
    0.5 * twice
}

/// The corners of the rectangle `[-h.x, h.x] x [-h.y, h.y]`, counter-clockwise from `(h.x, h.y)`.
fn rect_corners(h: DVec2) -> [DVec2; 4] {
    [
        DVec2::new(h.x, h.y),
        DVec2::new(-h.x, h.y),
        DVec2::new(-h.x, -h.y),
        DVec2::new(h.x, -h.y),
    ]
}

/// [`sector_rect`] by angles (`atan2`), for any sweep including the half turn; the reference
/// the fast path is tested against.
pub fn sector_rect_by_angle(a: DVec2, b: DVec2, h: DVec2) -> f64 {
    let dth = a.perp_dot(b).atan2(a.dot(b));
    if dth == 0.0 || a == DVec2::ZERO || b == DVec2::ZERO {
        return 0.0;
    }
    let to_border = |p: DVec2| p / (p.x.abs() / h.x).max(p.y.abs() / h.y);
    let (ar, br) = (to_border(a), to_border(b));
    let tha = a.y.atan2(a.x);
    let tau = std::f64::consts::TAU;
    let mut corners: [(f64, DVec2); 4] = [(0.0, DVec2::ZERO); 4];
    let mut n = 0;
    for c in rect_corners(h) {
        let thc = c.y.atan2(c.x);
        let o = if dth > 0.0 {
            (thc - tha).rem_euclid(tau)
        } else {
            (tha - thc).rem_euclid(tau)
        };
        if o > 0.0 && o < dth.abs() {
            corners[n] = (o, c);
            n += 1;
        }
    }
    corners[..n].sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut prev = ar;
    let mut twice = 0.0;
    for (_, c) in &corners[..n] {
        twice += prev.perp_dot(*c);
        prev = *c;
    }
    twice += prev.perp_dot(br);
    0.5 * twice
}

/// The light as the radial integration sees it, in light-plane coordinates centred on the
/// (sub-)light (docs/methods.md §3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Emitter {
    /// The rectangle `[-h.x, h.x] x [-h.y, h.y]` (half extents h).
    Rect(DVec2),
    /// The disk of this radius at the origin (docs/methods.md §3 "Disk lights").
    Disk(f64),
    /// A sphere of this radius at the origin: per receiver its silhouette disk
    /// ([`Receiver::sil`], docs/methods.md §3 "Sphere lights").
    Sphere(f64),
}

impl Emitter {
    /// Area `A_L`: `4 h.x h.y`, or `pi R^2`.
    #[inline]
    pub fn area(&self) -> f64 {
        match *self {
            Emitter::Rect(h) => 4.0 * h.x * h.y,
            Emitter::Disk(r) | Emitter::Sphere(r) => std::f64::consts::PI * r * r,
        }
    }
}

/// Contribution `tri(a', b') - sector(a', b')` of the backprojected edge `a -> b` to the occluded
/// area of a disk light of radius `r` (docs/methods.md §3 "Disk lights"): with `q1 -> q2` the chord
/// of the segment inside the circle, `cross(q1, q2) / 2 - r^2 atan2(cross(q1, q2), q1 . q2) / 2`;
/// 0 for a segment missing the disk. The segment is first clipped to the disk's bounding square
/// in f64 (its chord is unchanged, and the f32 squares below cannot overflow), then the core's
/// [`edge_disk_area`] minus [`disk_wedge`] (f32; the pieces outside the circle cancel) gives the
/// term, never NaN for finite inputs.
#[inline]
pub fn disk_edge_term(a: DVec2, b: DVec2, r: f64) -> f64 {
    match clip_to_rect(a, b, DVec2::splat(r)) {
        Some((a, b)) => {
            let (a, b, r) = (a.as_vec2(), b.as_vec2(), r as f32);
            (edge_disk_area(a, b, r) - disk_wedge(a, b, r)) as f64
        }
        None => 0.0,
    }
}

/// Contribution `tri(a', b') - sector(a', b')` of the backprojected edge `a -> b` (on z = 0) to
/// the occluded area of a sphere light's silhouette disk `s` (docs/methods.md §3 "Sphere lights"):
/// the edge is clipped in f64 to [`Silhouette::clip`] (the rectangle of z = 0 holding the disk's
/// image from p, so every point carried lies in front of p and pieces outside add nothing),
/// its ends are carried onto the silhouette plane by the central projection from p
/// ([`Silhouette::carry`], which maps the segment to a segment and the light's centre to the
/// disk's centre, orientation kept), and [`disk_edge_term`] measures it on the disk.
#[inline]
pub fn sphere_edge_term(a: DVec2, b: DVec2, s: &Silhouette) -> f64 {
    let lo = DVec2::new(s.clip[0] as f64, s.clip[1] as f64);
    let hi = DVec2::new(s.clip[2] as f64, s.clip[3] as f64);
    let (c, h) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    match clip_to_rect(a - c, b - c, h) {
        Some((a, b)) => {
            let (a, b) = (a + c, b + c);
            let ca = s.carry(a.x as f32, a.y as f32).as_dvec2();
            let cb = s.carry(b.x as f32, b.y as f32).as_dvec2();
            disk_edge_term(ca, cb, s.radius as f64)
        }
        None => 0.0,
    }
}

/// Contribution `tri(a', b') - sector(a', b')` of one contour edge to the occluded area of the
/// light `em`, seen from `rec` (docs/methods.md §3 "Radial integration", "Disk lights"); 0 for
/// edges entirely outside the light.
#[inline]
pub fn edge_area(e: &Edge, rec: &Receiver, k: Scale, em: &Emitter) -> f64 {
    let a = backproject(e.a, e.za, rec, k);
    let b = backproject(e.b, e.zb, rec, k);
    match *em {
        Emitter::Rect(h) => match clip_to_rect(a, b, h) {
            Some((a, b)) => 0.5 * a.perp_dot(b) - sector_rect(a, b, h),
            None => 0.0,
        },
        Emitter::Disk(r) => disk_edge_term(a, b, r),
        Emitter::Sphere(_) => rec.sil.as_ref().map_or(0.0, |s| sphere_edge_term(a, b, s)),
    }
}

/// `V = 1 - clamp01(A_occ / A_L)` with `A_occ = c A_L + sum` (docs/methods.md §3), `A_L` the
/// area of `em`.
#[inline]
pub fn visibility_from_area(centre: bool, sum: f64, em: &Emitter) -> f32 {
    let al = em.area();
    if !(al > 0.0) {
        return if centre { 0.0 } else { 1.0 };
    }
    let a = if centre { al } else { 0.0 } + sum;
    let f = a / al;
    if !f.is_finite() {
        return if centre { 0.0 } else { 1.0 };
    }
    (1.0 - f.clamp(0.0, 1.0)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sector_of_full_turn_is_light_area() {
        let h = DVec2::new(0.7, 0.3);
        // Four quarter turns around the origin.
        let pts = [
            DVec2::new(1.0, 0.1),
            DVec2::new(-0.1, 1.0),
            DVec2::new(-1.0, -0.1),
            DVec2::new(0.1, -1.0),
        ];
        let s: f64 = (0..4)
            .map(|i| sector_rect(pts[i], pts[(i + 1) % 4], h))
            .sum();
        assert!((s - 4.0 * h.x * h.y).abs() < 1e-12, "{s}");
        // Reversed sweep is negative.
        let s2 = sector_rect(pts[1], pts[0], h);
        assert!((s2 + sector_rect(pts[0], pts[1], h)).abs() < 1e-12);
    }

    /// The trigonometry-free sector equals the angle-based one on random sweeps, including
    /// corners on the sweep's rays and sweeps near a half turn.
    #[test]
    fn sector_fast_path_matches_angles() {
        let mut seed = 99u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for k in 0..20000 {
            let h = DVec2::new(0.1 + rnd().abs(), 0.1 + rnd().abs());
            let a = DVec2::new(rnd(), rnd()) * 3.0;
            let b = match k % 4 {
                0 => DVec2::new(h.x, -h.y) * (1.0 + rnd().abs()), // on a corner's ray
                1 => -a + DVec2::new(rnd(), rnd()) * 1e-9,        // nearly a half turn
                _ => DVec2::new(rnd(), rnd()) * 3.0,
            };
            let (f, r) = (sector_rect(a, b, h), sector_rect_by_angle(a, b, h));
            assert!(
                (f - r).abs() <= 1e-12 * (1.0 + h.x * h.y),
                "{a} {b} {h}: {f} vs {r}"
            );
        }
    }
}
