//! The contract's silhouette disk of a sphere light seen from a receiver (docs/methods.md §2 "Disk
//! and sphere lights", §3 "Sphere lights", §9 "Sphere light"): the disk of the sphere's radius
//! through its centre, perpendicular to the direction to the receiver; the central projection from
//! the receiver that carries points of the light plane z = 0 onto it; the circumscribed octagon
//! whose images bound kernels. Shared by backprojection and packet-hsm. Light space (the light
//! frame at the sphere's centre), f32.

/// Vertices of the polygon circumscribing a disk whose images bound the kernel of a sphere light
/// ([`Silhouette::kernel_bounds`]).
pub const SILHOUETTE_HULL: u32 = 8;

/// The contract's silhouette disk of a sphere light seen from the light-space receiver p: radius
/// R through the origin, unit normal `a = p / |p|`, in-plane axes `e1`, `e2`. Estimators carry
/// what they measure on z = 0 (backprojection's `B_s`, packet-hsm's contour edges) onto it by the central projection from p: a point Y of z = 0 goes to
/// `X = p + (Y - p) t`, `t = |p| / (|p| - a.Y)`, whose in-plane coordinates are
/// `t (Y.e1, Y.e2)` (p is perpendicular to e1 and e2). The projection maps the rectangle to a
/// convex quadrilateral, so the overlap is [`crate::overlap::quad_disk_area`].
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
        let e1 = crate::light::default_tangent(a);
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

    /// The central projection from p of the point `(x, y, 0)` of z = 0 onto the silhouette plane,
    /// in-plane coordinates: `t (Y.e1, Y.e2)`, `t = |p| / (|p| - a.Y)`. Meant for points inside
    /// [`clip`](Self::clip) (there `t > 0`); a line of z = 0 goes to a line.
    #[inline]
    pub fn carry(&self, x: f32, y: f32) -> glam::Vec2 {
        let yv = glam::Vec3::new(x, y, 0.0);
        let t = self.dist / (self.dist - self.a.dot(yv));
        glam::Vec2::new(yv.dot(self.e1), yv.dot(self.e2)) * t
    }

    /// Area of the rectangle `[x0, x1] x [y0, y1]` of z = 0 carried onto the silhouette disk,
    /// inside the disk (clipped to [`clip`](Self::clip) first; 0 when nothing is left).
    #[inline]
    pub fn overlap_rect(&self, x0: f32, y0: f32, x1: f32, y1: f32) -> f32 {
        self.carry_rect(x0, y0, x1, y1)
            .map_or(0.0, |q| crate::overlap::quad_disk_area(q, self.radius))
    }

    /// The rectangle `[x0, x1] x [y0, y1]` of z = 0, clipped to [`Silhouette::clip`] (which keeps
    /// the corners finite and loses no point of the disk), carried onto the silhouette plane
    /// (in-plane coordinates, corners in order); `None` when the clipped rectangle is empty.
    pub fn carry_rect(&self, x0: f32, y0: f32, x1: f32, y1: f32) -> Option<[glam::Vec2; 4]> {
        let x0 = x0.max(self.clip[0]);
        let y0 = y0.max(self.clip[1]);
        let x1 = x1.min(self.clip[2]);
        let y1 = y1.min(self.clip[3]);
        if !(x1 > x0 && y1 > y0) {
            return None;
        }
        Some([
            self.carry(x0, y0),
            self.carry(x1, y0),
            self.carry(x1, y1),
            self.carry(x0, y1),
        ])
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
        view: &crate::LightView,
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
