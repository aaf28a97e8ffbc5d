//! The area light and its light-space frame (docs/methods.md §1).
use glam::{Vec2, Vec3};

/// Shape of the area light, in the light's own frame (see [`LightFrame`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightShape {
    /// Rectangle `|x| <= size[0]/2, |y| <= size[1]/2` in the light plane z = 0. One-sided.
    Rect {
        /// Width along the tangent `e_x`, height along `e_y`.
        size: [f32; 2],
    },
    /// Disk `x^2 + y^2 <= radius^2` in the light plane. One-sided.
    Disk {
        /// Radius.
        radius: f32,
    },
    /// Sphere of this radius around the centre. Per the contract, the visible fraction is taken
    /// over the sphere's silhouette disk seen from the shaded point: the disk of the sphere's radius
    /// through the centre, perpendicular to the direction from the point to the centre.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// A distant light, the sun (the contract's `shape = "directional"`): every point sees the
    /// same disk of directions, of angular diameter `angle_deg` around the light's travel
    /// direction ([`Light::normal`]). V is the visible fraction of that disk's area at unit
    /// distance from the point (radius [`LightShape::tan_half`], perpendicular to the direction,
    /// area-uniform). No point is behind it.
    Directional {
        /// Angular diameter in degrees, in (0, 90).
        angle_deg: f32,
    },
}

impl LightShape {
    /// For a directional light, `tan(angle_deg / 2)`: the radius of its disk of directions at
    /// unit distance; 0 for the other shapes.
    pub fn tan_half(&self) -> f32 {
        match *self {
            LightShape::Directional { angle_deg } => (0.5 * angle_deg).to_radians().tan(),
            _ => 0.0,
        }
    }
    /// The contract's word for the shape (`rect`, `disk`, `sphere`, `directional`).
    pub fn word(&self) -> &'static str {
        match self {
            LightShape::Rect { .. } => "rect",
            LightShape::Disk { .. } => "disk",
            LightShape::Sphere { .. } => "sphere",
            LightShape::Directional { .. } => "directional",
        }
    }
}

/// A uniform area light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// Its shape and size.
    pub shape: LightShape,
    /// The light centre C.
    pub center: Vec3,
    /// The direction the light emits into (`e_z`), unit length.
    pub normal: Vec3,
    /// `e_x`: for rect lights the direction of the first side (orthonormalised against the
    /// normal); for disk and sphere lights derived from the world axis least aligned with the
    /// normal (docs/methods.md §1). Unit length.
    pub tangent: Vec3,
}

/// Right-handed orthonormal light-space frame: origin at the light centre, `e_z` the light normal,
/// `e_x` the tangent, `e_y = e_z x e_x`. A world point P has light-space coordinates
/// `((P-C).e_x, (P-C).e_y, (P-C).e_z)` (docs/methods.md §1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightFrame {
    /// The origin C.
    pub origin: Vec3,
    /// First axis.
    pub ex: Vec3,
    /// Second axis.
    pub ey: Vec3,
    /// Third axis, the light normal.
    pub ez: Vec3,
}

impl LightFrame {
    /// Builds the frame from an origin, a normal and a tangent hint (not necessarily orthogonal).
    /// Returns `None` when the two are parallel or not finite.
    pub fn new(origin: Vec3, normal: Vec3, tangent: Vec3) -> Option<Self> {
        let ez = normal.try_normalize()?;
        let ex = (tangent - tangent.dot(ez) * ez).try_normalize()?;
        let ey = ez.cross(ex);
        Some(LightFrame { origin, ex, ey, ez })
    }
    /// World to light space.
    #[inline]
    pub fn to_light(&self, p: Vec3) -> Vec3 {
        let d = p - self.origin;
        Vec3::new(d.dot(self.ex), d.dot(self.ey), d.dot(self.ez))
    }
    /// World direction to light space.
    #[inline]
    pub fn dir_to_light(&self, d: Vec3) -> Vec3 {
        Vec3::new(d.dot(self.ex), d.dot(self.ey), d.dot(self.ez))
    }
    /// Light space to world.
    #[inline]
    pub fn to_world(&self, q: Vec3) -> Vec3 {
        self.origin + q.x * self.ex + q.y * self.ey + q.z * self.ez
    }
}

/// The tangent used for disk and sphere lights: the world axis least aligned with the normal,
/// orthonormalised (docs/methods.md §1). Results must not depend on it.
pub fn default_tangent(normal: Vec3) -> Vec3 {
    let n = normal.abs();
    let a = if n.x <= n.y && n.x <= n.z {
        Vec3::X
    } else if n.y <= n.z {
        Vec3::Y
    } else {
        Vec3::Z
    };
    (a - a.dot(normal) * normal).normalize_or(Vec3::X)
}

impl Light {
    /// The light-space frame.
    pub fn frame(&self) -> LightFrame {
        let ez = self.normal;
        let ex = self.tangent;
        LightFrame {
            origin: self.center,
            ex,
            ey: ez.cross(ex),
            ez,
        }
    }
    /// A directional light travelling along `direction` (normalised) with angular diameter
    /// `angle_deg` ([`LightShape::Directional`]); its centre is unused (the origin).
    pub fn directional(direction: Vec3, angle_deg: f32) -> Light {
        let normal = direction.normalize_or(Vec3::NEG_Y);
        Light {
            shape: LightShape::Directional { angle_deg },
            center: Vec3::ZERO,
            normal,
            tangent: default_tangent(normal),
        }
    }
    /// Whether this is a directional light (the sun).
    pub fn is_directional(&self) -> bool {
        matches!(self.shape, LightShape::Directional { .. })
    }
    /// Area of the emitting surface (for a sphere: of its silhouette disk, per the contract; for
    /// a directional light: of its disk of directions at unit distance).
    pub fn area(&self) -> f32 {
        match self.shape {
            LightShape::Rect { size } => size[0] * size[1],
            LightShape::Disk { radius } | LightShape::Sphere { radius } => {
                std::f32::consts::PI * radius * radius
            }
            LightShape::Directional { .. } => {
                let t = self.shape.tan_half();
                std::f32::consts::PI * t * t
            }
        }
    }
    /// Half extents of the light's bounding rectangle in the light plane (`l_x/2, l_y/2`; for a
    /// directional light, of its disk of directions at unit distance).
    pub fn half_extent(&self) -> Vec2 {
        match self.shape {
            LightShape::Rect { size } => Vec2::new(size[0], size[1]) * 0.5,
            LightShape::Disk { radius } | LightShape::Sphere { radius } => Vec2::splat(radius),
            LightShape::Directional { .. } => Vec2::splat(self.shape.tan_half()),
        }
    }
    /// Largest extent of the light (rect: its diagonal; disk, sphere: the diameter; directional:
    /// the diameter of its disk of directions at unit distance).
    pub fn diameter(&self) -> f32 {
        match self.shape {
            LightShape::Rect { size } => Vec2::new(size[0], size[1]).length(),
            LightShape::Disk { radius } | LightShape::Sphere { radius } => 2.0 * radius,
            LightShape::Directional { .. } => 2.0 * self.shape.tan_half(),
        }
    }
    /// Rect and disk lights emit only into the half-space their normal points to.
    pub fn one_sided(&self) -> bool {
        matches!(
            self.shape,
            LightShape::Rect { .. } | LightShape::Disk { .. }
        )
    }
    /// The same light scaled down or up by `f` (used by convergence tests: light size to 0; a
    /// directional light's disk of directions scales its radius `tan(angle / 2)`).
    pub fn scaled(&self, f: f32) -> Light {
        let shape = match self.shape {
            LightShape::Rect { size } => LightShape::Rect {
                size: [size[0] * f, size[1] * f],
            },
            LightShape::Disk { radius } => LightShape::Disk { radius: radius * f },
            LightShape::Sphere { radius } => LightShape::Sphere { radius: radius * f },
            LightShape::Directional { .. } => LightShape::Directional {
                angle_deg: 2.0 * (self.shape.tan_half() * f).atan().to_degrees(),
            },
        };
        Light { shape, ..*self }
    }

    /// `s x s` stratified points on the light, in light-plane coordinates (x, y) relative to the
    /// centre, jittered by `jitter(k) in [0,1)^2` per stratum (pass `|_| Vec2::splat(0.5)` for the
    /// regular grid of stratum centres). Rect: jittered grid; disk and sphere: the grid mapped by
    /// Shirley's concentric square-to-disk map (docs/methods.md §6), which keeps strata compact.
    pub fn stratified_points(&self, s: u32, mut jitter: impl FnMut(u32) -> Vec2) -> Vec<Vec2> {
        let mut out = Vec::with_capacity((s * s) as usize);
        for b in 0..s {
            for a in 0..s {
                let j = jitter(b * s + a);
                let u = Vec2::new((a as f32 + j.x) / s as f32, (b as f32 + j.y) / s as f32);
                out.push(self.map_unit_square(u));
            }
        }
        out
    }

    /// Maps `u in [0,1]^2` uniformly (in area) onto the light's shape in light-plane coordinates.
    pub fn map_unit_square(&self, u: Vec2) -> Vec2 {
        match self.shape {
            LightShape::Rect { size } => (u - 0.5) * Vec2::new(size[0], size[1]),
            LightShape::Disk { radius } | LightShape::Sphere { radius } => {
                concentric_disk(u) * radius
            }
            LightShape::Directional { .. } => concentric_disk(u) * self.shape.tan_half(),
        }
    }
}

/// Shirley & Chiu's concentric map from `[0,1]^2` to the unit disk (area preserving).
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = u * 2.0 - 1.0;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (
            o.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y),
        )
    };
    Vec2::new(r * theta.cos(), r * theta.sin())
}

/// Fraction of the light's area (rect or disk in the light plane, light-space coordinates) that
/// lies strictly in front of the receiver's tangent plane `{ y : n.(y - p) > 0 }`. The contract
/// counts light samples behind the receiver's own surface as blocked; shadow-map estimators
/// multiply their visibility by this factor (an analytic, exact term for planar lights). `p` and
/// `n` are in light space. For a sphere light, pass the disk of the silhouette (`p` and `n` in a
/// frame whose z axis is the direction from p to the centre) or use the light-frame disk as an
/// approximation.
pub fn front_fraction(shape: &LightShape, p: Vec3, n: Vec3) -> f32 {
    // Points y = (x, y, 0): n.x*x + n.y*y > n.p  (light plane z = 0).
    let c = n.dot(p);
    let a = Vec2::new(n.x, n.y);
    let la = a.length();
    match *shape {
        LightShape::Rect { size } => {
            let (hx, hy) = (0.5 * size[0], 0.5 * size[1]);
            if la < 1e-12 {
                return if 0.0 > c { 1.0 } else { 0.0 };
            }
            // Clip the rectangle polygon by the half-plane a.y > c.
            let poly = [
                Vec2::new(-hx, -hy),
                Vec2::new(hx, -hy),
                Vec2::new(hx, hy),
                Vec2::new(-hx, hy),
            ];
            let mut area = 0.0f64;
            let f = |q: Vec2| (a.dot(q) - c) as f64;
            let mut clipped: Vec<Vec2> = Vec::with_capacity(6);
            for i in 0..4 {
                let p0 = poly[i];
                let p1 = poly[(i + 1) % 4];
                let (f0, f1) = (f(p0), f(p1));
                if f0 > 0.0 {
                    clipped.push(p0);
                }
                if (f0 > 0.0) != (f1 > 0.0) {
                    let t = (f0 / (f0 - f1)) as f32;
                    clipped.push(p0 + (p1 - p0) * t);
                }
            }
            for i in 0..clipped.len() {
                let p0 = clipped[i];
                let p1 = clipped[(i + 1) % clipped.len()];
                area += (p0.x as f64) * (p1.y as f64) - (p1.x as f64) * (p0.y as f64);
            }
            let total = (size[0] as f64) * (size[1] as f64);
            if total <= 0.0 {
                return if 0.0 > c { 1.0 } else { 0.0 };
            }
            ((0.5 * area) / total).clamp(0.0, 1.0) as f32
        }
        LightShape::Disk { .. } | LightShape::Sphere { .. } | LightShape::Directional { .. } => {
            let radius = match *shape {
                LightShape::Disk { radius } | LightShape::Sphere { radius } => radius,
                _ => shape.tan_half(),
            };
            if la < 1e-12 || radius <= 0.0 {
                return if 0.0 > c { 1.0 } else { 0.0 };
            }
            // Signed distance of the line from the disk centre, along a/|a|: points with
            // t = a.y/|a| > d are in front.
            let d = (c / la) as f64;
            let r = radius as f64;
            let t = (d / r).clamp(-1.0, 1.0);
            // Area of the segment beyond t (unit disk): (acos t - t sqrt(1-t^2)) / pi.
            let seg = (t.acos() - t * (1.0 - t * t).sqrt()) / std::f64::consts::PI;
            seg.clamp(0.0, 1.0) as f32
        }
    }
}

impl Light {
    /// Fraction of the light's area in front of the tangent plane of a world point `p` with unit
    /// normal `n` (see [`front_fraction`]). For rect and disk lights, 0 when p is behind or in the
    /// light plane (one-sided emitters). For a sphere light the area is that of the contract's
    /// silhouette disk (through the centre, perpendicular to p -> centre).
    pub fn front_fraction_world(&self, p: Vec3, n: Vec3) -> f32 {
        match self.shape {
            LightShape::Rect { .. } | LightShape::Disk { .. } => {
                let f = self.frame();
                let pl = f.to_light(p);
                if pl.z <= 0.0 {
                    return 0.0;
                }
                front_fraction(&self.shape, pl, f.dir_to_light(n))
            }
            LightShape::Sphere { .. } => {
                let d = self.center - p;
                let Some(dz) = (-d).try_normalize() else {
                    return 0.0;
                };
                // Frame at the centre whose z axis points from the light towards p.
                let ex = default_tangent(dz);
                let f = LightFrame {
                    origin: self.center,
                    ex,
                    ey: dz.cross(ex),
                    ez: dz,
                };
                front_fraction(&self.shape, f.to_light(p), f.dir_to_light(n))
            }
            LightShape::Directional { .. } => {
                // The disk of directions at unit distance towards the light: a disk light of
                // radius tan(angle / 2) one unit from p, facing it.
                let f = LightFrame {
                    origin: p - self.normal,
                    ex: self.tangent,
                    ey: self.normal.cross(self.tangent),
                    ez: self.normal,
                };
                front_fraction(&self.shape, Vec3::Z, f.dir_to_light(n))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn front_fraction_rect_half_and_full() {
        let shape = LightShape::Rect { size: [2.0, 1.0] };
        // Receiver far below, facing the light: everything in front.
        let f = front_fraction(&shape, Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 0.0, -1.0));
        assert!((f - 1.0).abs() < 1e-6);
        // Vertical receiver plane through x = 0, facing +x: half the light.
        let f = front_fraction(&shape, Vec3::new(0.0, 0.0, 5.0), Vec3::new(1.0, 0.0, 0.0));
        assert!((f - 0.5).abs() < 1e-6, "{f}");
        // Plane x = 0.5 facing +x: a quarter of the width 2.
        let f = front_fraction(&shape, Vec3::new(0.5, 0.0, 5.0), Vec3::new(1.0, 0.0, 0.0));
        assert!((f - 0.25).abs() < 1e-6, "{f}");
    }

    #[test]
    fn front_fraction_disk_half() {
        let shape = LightShape::Disk { radius: 1.0 };
        let f = front_fraction(&shape, Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 1.0, 0.0));
        assert!((f - 0.5).abs() < 1e-6, "{f}");
        let f = front_fraction(&shape, Vec3::new(0.0, 2.0, 5.0), Vec3::new(0.0, 1.0, 0.0));
        assert!(f.abs() < 1e-6, "{f}");
    }

    #[test]
    fn concentric_map_stays_in_disk() {
        for i in 0..=20 {
            for j in 0..=20 {
                let d = concentric_disk(Vec2::new(i as f32 / 20.0, j as f32 / 20.0));
                assert!(d.length() <= 1.0 + 1e-6);
            }
        }
    }
}
