//! Pure geometry of micropatch backprojection (docs/methods.md §2; Bavoil 2008 eq. 1, §3).
//!
//! Conventions: light space with the light centre at the origin, light plane z = 0, shadow-map
//! plane z = n, texel coordinates `u = (n x / z - x0) / delta` (see
//! [`shadow_map_core::LightView`]). Lengths returned on the light plane are world units relative
//! to the light centre.

/// Largest magnitude a backprojected bound may take. Bounds that would overflow (a sample almost
/// at the receiver's depth) are clamped to +-`FAR_BOUND`, which keeps them finite and keeps their
/// limit meaning: a micropatch containing the receiver's projection covers the whole light, the
/// others leave it.
pub const FAR_BOUND: f32 = 1e30;

pub use shadow_map_core::mssm::kernel_width;

/// Scale of a backprojected texel on the light plane (docs/methods.md §2 "Backprojected
/// micropatch"; Bavoil eq. 1 before his division by l):
///
/// `S = k z_s z_p / (z_p - z_s)`, `k = w / (n r)` (the texel pitch over n).
///
/// Guarded: `z_p - z_s` is floored at `1e-7 z_p` (the f32 resolution of depths near `z_p`) so S
/// stays finite (its limit is +inf); samples at or behind the receiver (`z_s >= z_p`) or at or
/// behind the light (`z_s <= 0`) return 0 (they block nothing). Never NaN for finite inputs.
#[inline]
pub fn micropatch_scale(k: f32, z_s: f32, z_p: f32) -> f32 {
    if !(z_s > 0.0) || !(z_s < z_p) || !(k > 0.0) {
        return 0.0;
    }
    let gap = (z_p - z_s).max(1e-7 * z_p).max(f32::MIN_POSITIVE);
    let s = k * z_s * (z_p / gap);
    if s.is_finite() {
        s
    } else {
        f32::MAX
    }
}

/// An axis-aligned rectangle `[x0, x1] x [y0, y1]` on the light plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    /// Smallest x.
    pub x0: f32,
    /// Smallest y.
    pub y0: f32,
    /// Largest x.
    pub x1: f32,
    /// Largest y.
    pub y1: f32,
}

/// Backprojects the micropatch covering the texel span `[i0, i1] x [j0, j1]` (texel coordinates;
/// `[i, i+1] x [j, j+1]` for one texel, wider for the adaptive step of Bavoil §5) at depth `z_s`
/// from the receiver at texel coordinates `(u_p, v_p)` and depth `z_p` onto the light plane
/// (docs/methods.md §2, exact closed form; Bavoil eq. 1):
///
/// `B_s = [(i0 - u_p) S, (i1 - u_p) S] x [(j0 - v_p) S, (j1 - v_p) S]`, S from
/// [`micropatch_scale`].
///
/// Bounds are clamped to +-[`FAR_BOUND`]: when `z_p - z_s` is tiny, a micropatch whose span
/// contains `(u_p, v_p)` becomes a rectangle containing the whole light (the limit), and one that
/// does not moves off to infinity. Never NaN or inf for finite inputs.
#[inline]
pub fn backprojected_micropatch(
    span: [f32; 4],
    uv_p: [f32; 2],
    k: f32,
    z_s: f32,
    z_p: f32,
) -> Rect {
    let s = micropatch_scale(k, z_s, z_p);
    let b = |t: f32, c: f32| {
        let d = t - c;
        if d == 0.0 || s == 0.0 {
            0.0
        } else {
            (d * s).clamp(-FAR_BOUND, FAR_BOUND)
        }
    };
    Rect {
        x0: b(span[0], uv_p[0]),
        x1: b(span[1], uv_p[0]),
        y0: b(span[2], uv_p[1]),
        y1: b(span[3], uv_p[1]),
    }
}

/// Area of `rect ∩ L` for the rectangle light `L = [-l_x/2, l_x/2] x [-l_y/2, l_y/2]`
/// (docs/methods.md §2 "Estimator": `area(B_s(p) ∩ L)`). 0 for empty or inverted rectangles.
#[inline]
pub fn light_overlap_area(rect: &Rect, half: [f32; 2]) -> f64 {
    let dx = (rect.x1.min(half[0]) as f64 - rect.x0.max(-half[0]) as f64).max(0.0);
    let dy = (rect.y1.min(half[1]) as f64 - rect.y0.max(-half[1]) as f64).max(0.0);
    dx * dy
}

/// Smallest carried overlap, relative to the silhouette disk's area, that counts as a contribution
/// ([`Emitter::contributes`]).
pub const CONTRIBUTION_REL: f32 = 1e-6;

/// Vertices of the polygon circumscribing a disk whose images bound the kernel of a sphere light
/// ([`Silhouette::kernel_bounds`]).
pub const SILHOUETTE_HULL: u32 = 8;

/// The emitting surface as backprojection measures it (docs/methods.md §2 "Disk and sphere
/// lights"): occlusion is the area of each backprojected micropatch `B_s` (a rectangle on the
/// light plane z = 0) inside the light, over the light's area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Emitter {
    /// `[-hx, hx] x [-hy, hy]` in the light plane.
    Rect {
        /// Half extents.
        half: [f32; 2],
    },
    /// The disk of this radius at the origin of the light plane.
    Disk {
        /// Radius.
        radius: f32,
    },
    /// The contract's sphere: per receiver p, the disk of this radius through the centre,
    /// perpendicular to p ([`Silhouette`]).
    Sphere {
        /// Radius.
        radius: f32,
    },
}

/// The contract's silhouette disk of a sphere light seen from the light-space receiver p: radius
/// R through the origin, unit normal `a = p / |p|`, in-plane axes `e1`, `e2`. Backprojection
/// carries `B_s` (on z = 0) onto it by the central projection from p: a point Y of z = 0 goes to
/// `X = p + (Y - p) t`, `t = |p| / (|p| - a.Y)`, whose in-plane coordinates are
/// `t (Y.e1, Y.e2)` (p is perpendicular to e1 and e2). The projection maps the rectangle to a
/// convex quadrilateral, so the overlap is [`shadow_map_core::overlap::quad_disk_area`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Silhouette {
    /// Unit normal, p / |p|.
    pub a: glam::Vec3,
    /// First in-plane axis.
    pub e1: glam::Vec3,
    /// Second in-plane axis.
    pub e2: glam::Vec3,
    /// |p|.
    pub dist: f32,
    /// Radius R.
    pub radius: f32,
    /// The rectangle of z = 0 holding the disk's image from p (`[x0, y0, x1, y1]`): `B_s` is
    /// clipped to it before it is carried over, which keeps every point carried in front of p.
    pub clip: [f32; 4],
}

impl Silhouette {
    /// The silhouette disk seen from p (light space, `p.z > 0`); `None` when a hull point of the
    /// disk lies at or beyond p's depth (no central projection onto z = 0 holds it).
    pub fn new(p: glam::Vec3, radius: f32) -> Option<Silhouette> {
        let dist = p.length();
        let a = p.try_normalize()?;
        let e1 = shadow_map_core::light::default_tangent(a);
        let e2 = a.cross(e1);
        let mut clip = [
            f32::INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
        ];
        for k in 0..SILHOUETTE_HULL {
            let x = hull_point(e1, e2, radius, k);
            if !(x.z < p.z) {
                return None;
            }
            // Where the line from p through x meets z = 0.
            let y = p + (x - p) * (p.z / (p.z - x.z));
            clip = [
                clip[0].min(y.x),
                clip[1].min(y.y),
                clip[2].max(y.x),
                clip[3].max(y.y),
            ];
        }
        clip.iter().all(|c| c.is_finite()).then_some(Silhouette {
            a,
            e1,
            e2,
            dist,
            radius,
            clip,
        })
    }

    /// Area of `rect` (on z = 0) carried onto the silhouette disk, inside the disk.
    #[inline]
    pub fn overlap(&self, rect: &Rect) -> f32 {
        let x0 = rect.x0.max(self.clip[0]);
        let y0 = rect.y0.max(self.clip[1]);
        let x1 = rect.x1.min(self.clip[2]);
        let y1 = rect.y1.min(self.clip[3]);
        if !(x1 > x0 && y1 > y0) {
            return 0.0;
        }
        let carry = |x: f32, y: f32| {
            let yv = glam::Vec3::new(x, y, 0.0);
            let t = self.dist / (self.dist - self.a.dot(yv));
            glam::Vec2::new(yv.dot(self.e1), yv.dot(self.e2)) * t
        };
        shadow_map_core::overlap::quad_disk_area(
            [carry(x0, y0), carry(x1, y0), carry(x1, y1), carry(x0, y1)],
            self.radius,
        )
    }
}

impl Silhouette {
    /// Continuous texel bounds `[u0, v0, u1, v1]` of the kernel for occluder depths `>= z_m`
    /// (docs/methods.md §2 "Disk and sphere lights"): the images at depth `z_m` of the lines from
    /// p to the hull points (along each line the texel coordinate is monotone in depth, from the
    /// hull point's image at `z_m` to p's own, which the hull's images surround). `None` when a hull
    /// point is not nearer the light than `z_m` (then the whole map).
    pub fn kernel_bounds(
        &self,
        view: &shadow_map_core::LightView,
        p: glam::Vec3,
        z_m: f32,
    ) -> Option<[f32; 4]> {
        let mut b = [
            f32::INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
        ];
        let zm = z_m.max(f32::MIN_POSITIVE);
        for k in 0..SILHOUETTE_HULL {
            let x = hull_point(self.e1, self.e2, self.radius, k);
            if !(x.z < zm) || !(zm < p.z) {
                return None;
            }
            let c = p + (x - p) * ((p.z - zm) / (p.z - x.z));
            let t = (glam::Vec2::new(c.x, c.y) * (view.n / zm) - view.window_min) / view.delta();
            b = [b[0].min(t.x), b[1].min(t.y), b[2].max(t.x), b[3].max(t.y)];
        }
        b.iter().all(|x| x.is_finite()).then_some(b)
    }
}

/// `cos(pi/4)` in f32, the octagon's diagonal directions (both twins use these constants, not a
/// driver's trigonometry).
const S45: f32 = std::f32::consts::FRAC_1_SQRT_2;
/// Unit directions of the hull's [`SILHOUETTE_HULL`] vertices, `(cos, sin)` of `k pi / 4`.
pub const HULL_DIRS: [[f32; 2]; SILHOUETTE_HULL as usize] = [
    [1.0, 0.0],
    [S45, S45],
    [0.0, 1.0],
    [-S45, S45],
    [-1.0, 0.0],
    [-S45, -S45],
    [0.0, -1.0],
    [S45, -S45],
];
/// `1 / cos(pi/8)`: the circumscribed octagon's vertex radius over the disk's radius.
pub const HULL_SCALE: f32 = 1.082_392_2;

/// Hull point `k` of the disk of radius r spanned by e1, e2: the vertices of the regular
/// [`SILHOUETTE_HULL`]-gon circumscribing it.
#[inline]
pub fn hull_point(e1: glam::Vec3, e2: glam::Vec3, r: f32, k: u32) -> glam::Vec3 {
    let d = HULL_DIRS[k as usize];
    let rr = r * HULL_SCALE;
    e1 * (d[0] * rr) + e2 * (d[1] * rr)
}

impl Emitter {
    /// The emitter of a light.
    pub fn of(shape: &shadow_map_core::LightShape) -> Emitter {
        match *shape {
            shadow_map_core::LightShape::Rect { size } => Emitter::Rect {
                half: [0.5 * size[0], 0.5 * size[1]],
            },
            shadow_map_core::LightShape::Disk { radius } => Emitter::Disk { radius },
            shadow_map_core::LightShape::Sphere { radius } => Emitter::Sphere { radius },
        }
    }

    /// Area `A_L` (f64; a sphere's silhouette disk).
    pub fn area(&self) -> f64 {
        match *self {
            Emitter::Rect { half } => 4.0 * half[0] as f64 * half[1] as f64,
            Emitter::Disk { radius } | Emitter::Sphere { radius } => {
                std::f64::consts::PI * radius as f64 * radius as f64
            }
        }
    }

    /// Whether `B_s` covers part of the light (Bavoil §4.2's "non-zero contribution",
    /// `layer_rule=first_nonzero`), decided without the cancellation of a small overlap area:
    /// a rect's overlap is exact; a disk is met when the rectangle's point nearest the centre
    /// lies strictly inside it; on a sphere's silhouette the carried overlap must exceed
    /// [`CONTRIBUTION_REL`] of the disk's area (rounding in the edge sum is about 1e-7 of it).
    #[inline]
    pub fn contributes(&self, rect: &Rect, sil: Option<&Silhouette>) -> bool {
        match *self {
            Emitter::Rect { half } => light_overlap_area(rect, half) > 0.0,
            Emitter::Disk { radius } => {
                if !(rect.x1 > rect.x0 && rect.y1 > rect.y0) {
                    return false;
                }
                let cx = 0.0f32.clamp(rect.x0, rect.x1);
                let cy = 0.0f32.clamp(rect.y0, rect.y1);
                cx * cx + cy * cy < radius * radius
            }
            Emitter::Sphere { radius } => {
                let a = std::f32::consts::PI * radius * radius;
                sil.is_some_and(|s| s.overlap(rect) > CONTRIBUTION_REL * a)
            }
        }
    }

    /// `area(B_s ∩ L)` for a light in the plane z = 0 (rect, disk), or on the silhouette `sil`
    /// (sphere; 0 without one).
    #[inline]
    pub fn overlap(&self, rect: &Rect, sil: Option<&Silhouette>) -> f64 {
        match *self {
            Emitter::Rect { half } => light_overlap_area(rect, half),
            Emitter::Disk { radius } => {
                // Clipped to the disk's bounding square first, which keeps the corners finite.
                shadow_map_core::overlap::rect_disk_area(
                    rect.x0.max(-radius),
                    rect.y0.max(-radius),
                    rect.x1.min(radius),
                    rect.y1.min(radius),
                    radius,
                ) as f64
            }
            Emitter::Sphere { .. } => sil.map_or(0.0, |s| s.overlap(rect) as f64),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed form agrees with projecting the micropatch corners from p onto z = 0.
    #[test]
    fn closed_form_matches_direct_projection() {
        // View: n = 1, window [-1, 1], r = 64.
        let (n, x0, w, r) = (1.0f64, -1.0f64, 2.0f64, 64.0f64);
        let delta = w / r;
        let p = [0.13f64, -0.2, 3.0];
        let u_p = (n * p[0] / p[2] - x0) / delta;
        let v_p = (n * p[1] / p[2] - x0) / delta;
        let (i, j, zs) = (30.0f64, 27.0f64, 1.7f64);
        let world = |u: f64| (u * delta + x0) * zs / n; // x of the sample at texel coord u
        let proj = |xs: f64, xp: f64| (p[2] * xs - zs * xp) / (p[2] - zs);
        let b = backprojected_micropatch(
            [i as f32, i as f32 + 1.0, j as f32, j as f32 + 1.0],
            [u_p as f32, v_p as f32],
            (w / (n * r)) as f32,
            zs as f32,
            p[2] as f32,
        );
        let ex0 = proj(world(i), p[0]);
        let ey1 = proj(world(j + 1.0), p[1]);
        assert!((b.x0 as f64 - ex0).abs() < 1e-5, "{} vs {ex0}", b.x0);
        assert!((b.y1 as f64 - ey1).abs() < 1e-5, "{} vs {ey1}", b.y1);
    }

    #[test]
    fn degenerate_depths_stay_finite() {
        let b = backprojected_micropatch([3.0, 4.0, 3.0, 4.0], [3.5, 3.5], 0.01, 2.0, 2.0);
        assert_eq!(light_overlap_area(&b, [0.5, 0.5]), 0.0);
        let b = backprojected_micropatch([3.0, 4.0, 3.0, 4.0], [3.5, 3.5], 0.01, 1.999_999_9, 2.0);
        assert!(b.x0.is_finite() && b.x1.is_finite());
        assert!((light_overlap_area(&b, [0.5, 0.5]) - 1.0).abs() < 1e-6);
        assert_eq!(kernel_width(100.0, 1.0, 0.0, 1.0), f32::MAX);
        assert_eq!(kernel_width(100.0, 1.0, 2.0, 1.0), 0.0);
        assert_eq!(micropatch_scale(0.01, 0.0, 1.0), 0.0);
    }
}
