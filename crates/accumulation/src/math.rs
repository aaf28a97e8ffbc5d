//! Geometry of shadow accumulation (Aszódi & Szirmay-Kalos 2006, §1.1; docs/methods.md §9,
//! "Aszodi's mapping, corrected").
//!
//! Conventions: light space with the light centre at the origin and `e_z` the light normal; the
//! shadow-map plane is z = n, its window `[x0, x0 + w] x [y0, y0 + w]` split in `r x r` lexels of
//! pitch `delta = w / r` (see [`shadow_map_core::LightView`]). Points on the plane are 2-D
//! (x, y) at z = n, in world units.
//!
//! # The normalisation, derived (every quantity an area on the shadow-map plane)
//!
//! The paper's shadowing factor of caster c for receiver r is `s(c, r) = |D_c ∩ D| / |D|`
//! (§1.1): D the rays from r that reach the light, D_c those that hit c. The contract measures
//! these sets by **area on the light** (a uniform emitter; the sphere's silhouette disk), so map
//! every ray from r to its intersection with the plane z = n:
//!
//! * D becomes the light's **footprint** F: the light projected from r onto the plane.
//! * An elementary caster (one lexel l at depth `c_z`, eq. 4 `l = c n / c_z`) becomes the
//!   square `Q_c` of centre `l_r` and side `size * delta` ([`caster`]):
//!   `size = ((r_z - n)/(r_z - c_z)) (c_z / n)`, `l_r = ((n - c_z)/(r_z - c_z)) r_xy + size l`.
//!   `size` is dimensionless (plane length per plane length); `delta` (world units) turns it into
//!   a length, so `|Q_c| = (size delta)^2` is an area on the plane.
//!
//! A light point X and its image P on the plane are related by the central projection from r.
//! With the Jacobian `J(P) = |dA_X / dA_P|` of that map ([`Footprint::to_patch`]) the fraction
//! of the light's area hidden by c is
//!
//! `s(c, r) = (1 / A_L) ∫_{Q_c ∩ F} J(P) dP`.
//!
//! For a light in a plane parallel to the map (rect, disk, and the paper's model of the sphere:
//! a disk of radius R perpendicular to the light normal) the projection is a uniform scaling by
//! `t = (r_z - n) / r_z`, so `J = 1 / t^2` and `A_L t^2 = |F|`: the factor is a ratio of two
//! areas on the plane, `s(c, r) = |Q_c ∩ F| / |F|`, with `|F| = pi R'^2`, `R' = R t` for a disk
//! (the paper's R') and `|F| = t^2 l_x l_y` for a rectangle.
//!
//! The paper's additive variant (eq. 2 and its pseudo-code) replaces `|Q_c ∩ F|` by
//! `|Q_c| [l_r ∈ F]`, which gives, summed over the kernel,
//!
//! `s = sum_c (size_c delta)^2 [l_r ∈ F] / (pi R'^2)`       ([`Footprint::additive_term`])
//!
//! i.e. the printed `s += size*size; s /= R'*R'*PI/K/K` is right only when `R'` is measured in
//! lexels (`R' / delta`) and the `K^2` is dropped; as printed it mixes lexel counts with world
//! units. For the contract's sphere (silhouette disk perpendicular to `r`, tilted against the
//! plane) `J` varies over F and the term is `|Q_c| J(l_r) / A_L`, which reduces to the line above
//! for the parallel lights. The unit test `half_occluder_gives_one_half` checks the result: a
//! flat occluder covering exactly half the footprint gives s = 0.5 (rect, disk, paper sphere and
//! an off-axis contract sphere).
//!
//! The centre test is all or nothing per caster: when a backprojected lexel is larger than the
//! footprint (small lights) it gives 0 or `|Q_c| / |F| >> 1`. The `coverage = overlap` form
//! ([`Footprint::overlap_term`], the default) uses `|Q_c ∩ F|` itself, so the additive sum
//! converges to the hard shadow test as R -> 0; `coverage = centre` is the paper's test.
//!
//! The exact variant (eq. 1, the "obit" algorithm) puts B x B equal-area bits on the light
//! ([`LightPatch::bit_point`]), projects each onto the plane ([`Footprint::to_plane`]) and sets it
//! when a caster square contains it; `s = popcount / B^2` counts every occluded bit once (a
//! union, not a sum), and equal-area bits make it an area fraction of the light.
use crate::settings::SphereModel;
use glam::{Vec2, Vec3};
pub use shadow_map_core::overlap::{poly_area, poly_disk_area, quad_disk_area};
use shadow_map_core::LightShape;

/// Points on a disk's boundary used to bound its projections ([`Footprint::texel_bounds`]).
pub const DISK_BOUNDARY_POINTS: u32 = 16;

/// The emitting shape in its own plane through the light centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PatchShape {
    /// A disk of this radius.
    Disk(f32),
    /// A rectangle with these half extents along `e1`, `e2`.
    Rect(Vec2),
}

/// The light as accumulation sees it: a planar patch through the origin (light space) with unit
/// normal `a` and in-plane orthonormal axes `e1`, `e2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightPatch {
    /// Unit normal of the patch plane (light space).
    pub a: Vec3,
    /// First in-plane axis.
    pub e1: Vec3,
    /// Second in-plane axis.
    pub e2: Vec3,
    /// Its shape.
    pub shape: PatchShape,
}

impl LightPatch {
    /// The patch seen from the light-space receiver position `r`: rect and disk lights (and the
    /// paper's sphere) lie in the plane z = 0; the contract's sphere is the disk perpendicular to
    /// `r` (the direction from the centre to the receiver).
    pub fn for_receiver(shape: &LightShape, sphere: SphereModel, r: Vec3) -> LightPatch {
        let flat = |shape| LightPatch {
            a: Vec3::Z,
            e1: Vec3::X,
            e2: Vec3::Y,
            shape,
        };
        match *shape {
            LightShape::Rect { size } => flat(PatchShape::Rect(Vec2::new(size[0], size[1]) * 0.5)),
            LightShape::Disk { radius } => flat(PatchShape::Disk(radius)),
            // The sun: its disk of directions r_z above the receiver, which is on the axis of
            // the footprint's own frame (Footprint::for_sun).
            LightShape::Directional { .. } => flat(PatchShape::Disk(shape.tan_half() * r.z)),
            LightShape::Sphere { radius } => match sphere {
                SphereModel::Paper => flat(PatchShape::Disk(radius)),
                SphereModel::Contract => {
                    let Some(a) = r.try_normalize() else {
                        return flat(PatchShape::Disk(radius));
                    };
                    let e1 = shadow_map_core::light::default_tangent(a);
                    LightPatch {
                        a,
                        e1,
                        e2: a.cross(e1),
                        shape: PatchShape::Disk(radius),
                    }
                }
            },
        }
    }

    /// Area `A_L` of the patch.
    pub fn area(&self) -> f32 {
        match self.shape {
            PatchShape::Disk(r) => std::f32::consts::PI * r * r,
            PatchShape::Rect(h) => 4.0 * h.x * h.y,
        }
    }

    /// True when in-plane coordinates (along `e1`, `e2`) lie on the patch (boundary included).
    #[inline]
    pub fn contains(&self, local: Vec2) -> bool {
        match self.shape {
            PatchShape::Disk(r) => local.length_squared() <= r * r,
            PatchShape::Rect(h) => local.x.abs() <= h.x && local.y.abs() <= h.y,
        }
    }

    /// Bit `(i, j)` of a `b x b` grid of equal-area cells on the patch, in in-plane coordinates:
    /// the cell centres of a regular grid on a rectangle, the same grid mapped by Shirley &
    /// Chiu's concentric map on a disk (area preserving, so every bit stands for `A_L / b^2`).
    pub fn bit_local(&self, i: u32, j: u32, b: u32) -> Vec2 {
        match self.shape {
            PatchShape::Disk(r) => shadow_map_core::bitmask::disk_bit(r, i, j, b),
            PatchShape::Rect(h) => shadow_map_core::bitmask::rect_bit(h, i, j, b),
        }
    }

    /// In-plane coordinates to light space: `e1 x + e2 y`.
    #[inline]
    pub fn embed(&self, local: Vec2) -> Vec3 {
        self.e1 * local.x + self.e2 * local.y
    }

    /// [`LightPatch::bit_local`] in light space.
    pub fn bit_point(&self, i: u32, j: u32, b: u32) -> Vec3 {
        self.embed(self.bit_local(i, j, b))
    }

    /// In-plane coordinates of hull point `k`: points whose convex hull contains the patch, its
    /// 4 corners, or the [`DISK_BOUNDARY_POINTS`] vertices of the polygon circumscribing the disk.
    pub fn hull_local(&self, k: u32) -> Vec2 {
        match self.shape {
            PatchShape::Disk(r) => {
                let m = DISK_BOUNDARY_POINTS as f32;
                let rr = r / (std::f32::consts::PI / m).cos();
                let phi = 2.0 * std::f32::consts::PI * k as f32 / m;
                Vec2::new(phi.cos(), phi.sin()) * rr
            }
            PatchShape::Rect(h) => match k {
                0 => Vec2::new(-h.x, -h.y),
                1 => Vec2::new(h.x, -h.y),
                2 => Vec2::new(h.x, h.y),
                _ => Vec2::new(-h.x, h.y),
            },
        }
    }

    /// [`LightPatch::hull_local`] in light space.
    pub fn hull_point(&self, k: u32) -> Vec3 {
        self.embed(self.hull_local(k))
    }

    /// Number of [`LightPatch::hull_point`]s.
    pub fn hull_points(&self) -> u32 {
        match self.shape {
            PatchShape::Disk(_) => DISK_BOUNDARY_POINTS,
            PatchShape::Rect(_) => 4,
        }
    }

    /// Largest light-space z over the patch (0 for patches in the light plane).
    pub fn max_z(&self) -> f32 {
        match self.shape {
            PatchShape::Disk(r) => r * (1.0 - self.a.z * self.a.z).max(0.0).sqrt(),
            PatchShape::Rect(h) => h.x * self.e1.z.abs() + h.y * self.e2.z.abs(),
        }
    }
}

/// One receiver's view of the light through the plane z = n.
///
/// **The sun** (an orthographic view, docs/methods.md §14 "Accumulation"): the rays from the
/// receiver p towards the sun's disk of directions (radius t at unit distance) are the rays from
/// p towards a disk of radius `t L` at distance L above it, for any L. The footprint works in a
/// frame of its own ([`SunFrame`]): moved by `(p_x, p_y, p_z - L)`, so the receiver is at
/// `r = (0, 0, L)` and that disk lies in the plane z = 0 around the axis, with L = 2 far (every
/// caster, at view depth `n <= c_z < p_z`, then lies in `(0, L)`) and the footprint's own plane
/// at `L / 2`. Every term below then applies unchanged, with one disk for every receiver (the GPU
/// kernel's uniform patch). What differs is the caster: an orthographic lexel at plane point l and
/// depth c_z is the world point `(l, c_z)` ([`Footprint::caster`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// The receiver (light space, `r_z > n`); for the sun, in the footprint's frame (`(0, 0, p_z)`).
    pub r: Vec3,
    /// The plane distance n.
    pub n: f32,
    /// The light patch.
    pub patch: LightPatch,
    /// `1 / A_L`.
    pub inv_area: f32,
    /// The sun: the footprint's frame in the view ([`SunFrame`]). `None` for the perspective
    /// views of area lights.
    pub sun: Option<SunFrame>,
}

/// Where a sun footprint's frame lies in its orthographic view: view point `(x, y, z)` is
/// `(x - o.x, y - o.y, z - dz)` there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunFrame {
    /// The receiver's `(x, y)` in the view.
    pub o: Vec2,
    /// `p_z - L`.
    pub dz: f32,
}

/// The distance L of the sun's virtual disk above each receiver in its footprint's frame
/// ([`Footprint`]): `2 far` of the view, beyond every caster's distance from any receiver.
#[inline]
pub fn sun_lift(far: f32) -> f32 {
    2.0 * far.max(f32::MIN_POSITIVE)
}

impl Footprint {
    /// The footprint of a light of shape `shape` seen from the light-space receiver `p` through
    /// the plane z = `n` of its view: [`Footprint::new`] of [`LightPatch::for_receiver`], or for
    /// the sun the receiver-centred frame of the type's documentation.
    /// `p` and `n` of the view; for the sun `far` sets L ([`sun_lift`]).
    pub fn for_light(
        shape: &LightShape,
        sphere: SphereModel,
        p: Vec3,
        (n, far): (f32, f32),
    ) -> Footprint {
        if !matches!(shape, LightShape::Directional { .. }) {
            return Footprint::new(LightPatch::for_receiver(shape, sphere, p), p, n);
        }
        let lift = sun_lift(far);
        let r = Vec3::new(0.0, 0.0, lift);
        Footprint {
            sun: Some(SunFrame {
                o: Vec2::new(p.x, p.y),
                dz: p.z - lift,
            }),
            ..Footprint::new(LightPatch::for_receiver(shape, sphere, r), r, 0.5 * lift)
        }
    }

    /// The receiver's light-space position in the view (`r`, moved back for the sun).
    #[inline]
    pub fn receiver(&self) -> Vec3 {
        match self.sun {
            Some(f) => self.r + f.o.extend(f.dz),
            None => self.r,
        }
    }

    /// The image on the plane of the lexel at plane point `l` and view depth `c_z` ([`caster`]),
    /// in the footprint's frame: `(l_r, size)`. For the sun the orthographic lexel is the point
    /// `(l - o, c_z - dz)` of that frame and a lexel of side `delta` is `delta` wide at any depth:
    /// `l_r = (l - o) size`, `size = (r_z - n) / (r_z - c)`, `c = c_z - dz`, with [`caster`]'s
    /// guards.
    #[inline]
    pub fn caster(&self, l: Vec2, c_z: f32) -> Option<(Vec2, f32)> {
        let Some(f) = self.sun else {
            return caster(self.r, self.n, l, c_z);
        };
        let (r, c) = (self.r, c_z - f.dz);
        if !(c > 0.0) || !(c < r.z) {
            return None;
        }
        let gap = (r.z - c).max(1e-7 * r.z);
        let size = (r.z - self.n) / gap;
        let lr = (l - f.o) * size;
        (size.is_finite() && lr.is_finite()).then_some((lr, size))
    }

    /// The footprint of `patch` seen from `r` on the plane z = `n`.
    pub fn new(patch: LightPatch, r: Vec3, n: f32) -> Footprint {
        Footprint {
            r,
            n,
            patch,
            inv_area: 1.0 / patch.area(),
            sun: None,
        }
    }

    /// True when every ray from r to the light crosses the plane z = n in front of r (the light
    /// lies nearer the light plane than the receiver, with a margin of 1e-4 r_z): the one
    /// frustum's coverage condition. Outside it V is not defined by one map.
    pub fn covered(&self) -> bool {
        self.r.z > self.n && self.patch.max_z() < self.r.z * (1.0 - 1e-4)
    }

    /// Centre of the footprint, `q = n r_xy / r_z` (the receiver's projection).
    pub fn q(&self) -> Vec2 {
        Vec2::new(self.r.x, self.r.y) * (self.n / self.r.z)
    }

    /// The image on the plane of the light point `x` (light space): the central projection from
    /// r, `P = r + (x - r) (r_z - n) / (r_z - x_z)`.
    #[inline]
    pub fn to_plane(&self, x: Vec3) -> Vec2 {
        self.at_depth(x, self.n)
    }

    /// The point at depth `c` on the line from r through the light point `x`, as (x, y).
    #[inline]
    pub fn at_depth(&self, x: Vec3, c: f32) -> Vec2 {
        let s = (self.r.z - c) / (self.r.z - x.z);
        let r = Vec2::new(self.r.x, self.r.y);
        r + (Vec2::new(x.x, x.y) - r) * s
    }

    /// Backprojects a plane point P onto the light patch: `(in-plane coordinates, J(P) / A_L)`,
    /// where `J = |dA_X / dA_P| = u^2 |D_z| / |D . a|` is the area ratio of the central projection
    /// from r (`D = P - r`, `X = r + u D` on the patch plane). `None` when the ray from r through P
    /// does not meet the patch plane in front of r.
    #[inline]
    pub fn to_patch(&self, p: Vec2) -> Option<(Vec2, f32)> {
        let a = self.patch.a;
        let d = Vec3::new(p.x - self.r.x, p.y - self.r.y, self.n - self.r.z);
        let da = d.dot(a);
        let u = -self.r.dot(a) / da;
        if !(u > 0.0) || !u.is_finite() {
            return None;
        }
        let x = self.r + d * u;
        let local = Vec2::new(x.dot(self.patch.e1), x.dot(self.patch.e2));
        let jac = u * u * (d.z.abs() / da.abs());
        Some((local, jac * self.inv_area))
    }

    /// The additive variant's shadowing factor of one caster square of centre `lr` and area
    /// `area` (plane units): `area J(lr) / A_L` when `lr` lies in the footprint, else 0.
    #[inline]
    pub fn additive_term(&self, lr: Vec2, area: f32) -> f32 {
        self.additive_term_front(lr, area, &FrontEdge::EVERYTHING)
    }

    /// [`Footprint::additive_term`] on the part of the light in front of the receiver's tangent
    /// plane: 0 unless `lr` backprojects onto the patch in front of `front`.
    #[inline]
    pub fn additive_term_front(&self, lr: Vec2, area: f32, front: &FrontEdge) -> f32 {
        match self.to_patch(lr) {
            Some((local, w))
                if self.patch.contains(local) && (front.whole || front.front(local)) =>
            {
                area * w
            }
            _ => 0.0,
        }
    }

    /// The additive variant's factor with the overlap area instead of the centre test: the caster
    /// rectangle of centre `lr` and half sides `(hx, hy)` (plane units) carried to the patch and
    /// intersected with it, exactly: on a rectangle light (parallel to the plane) it is the
    /// rectangle of half sides `sqrt(J) (hx, hy)` around the backprojected centre; on a disk its
    /// four corners are backprojected ([`Footprint::to_patch`], the central projection maps the
    /// square to a quadrilateral) and intersected with the disk ([`quad_disk_area`]).
    /// Unlike the centre test it stays right when a caster is larger than the footprint (small
    /// lights, R -> 0: the hard-shadow limit).
    #[inline]
    pub fn overlap_term(&self, lr: Vec2, hx: f32, hy: f32) -> f32 {
        self.overlap_term_front(lr, hx, hy, &FrontEdge::EVERYTHING)
    }

    /// [`Footprint::overlap_term`] on the part of the light in front of the receiver's tangent
    /// plane: the caster's image on the patch clipped by `front` ([`FrontEdge::clip`]) before
    /// its area is taken (not clipped when the whole patch is in front).
    #[inline]
    pub fn overlap_term_front(&self, lr: Vec2, hx: f32, hy: f32, front: &FrontEdge) -> f32 {
        let area = match self.patch.shape {
            PatchShape::Rect(h) => {
                let Some((local, w)) = self.to_patch(lr) else {
                    return 0.0;
                };
                // w = J / A_L, so J = w / inv_area.
                let sj = (w / self.inv_area).sqrt();
                let (ax, ay) = (hx * sj, hy * sj);
                let (x0, x1) = ((local.x - ax).max(-h.x), (local.x + ax).min(h.x));
                let (y0, y1) = ((local.y - ay).max(-h.y), (local.y + ay).min(h.y));
                let dx = (x1 - x0).max(0.0);
                let dy = (y1 - y0).max(0.0);
                if front.whole || dx * dy == 0.0 {
                    dx * dy
                } else {
                    let q = [
                        Vec2::new(x0, y0),
                        Vec2::new(x1, y0),
                        Vec2::new(x1, y1),
                        Vec2::new(x0, y1),
                    ];
                    let mut c = [Vec2::ZERO; MAX_CLIP];
                    let m = front.clip(&q, &mut c);
                    poly_area(&c[..m])
                }
            }
            PatchShape::Disk(r) => {
                let mut q = [Vec2::ZERO; 4];
                for (k, s) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .into_iter()
                    .enumerate()
                {
                    let Some((local, _)) = self.to_patch(lr + Vec2::new(s.0 * hx, s.1 * hy)) else {
                        return 0.0;
                    };
                    q[k] = local;
                }
                if front.whole {
                    quad_disk_area(q, r)
                } else {
                    let mut c = [Vec2::ZERO; MAX_CLIP];
                    let m = front.clip(&q, &mut c);
                    poly_disk_area(&c[..m], r)
                }
            }
        };
        area * self.inv_area
    }

    /// The caster rectangle of centre `lr` and half sides `(hx, hy)` on the plane, backprojected
    /// onto the patch: its four corners (counter-clockwise on the plane) in in-plane coordinates,
    /// exact (the central projection maps the rectangle to a quadrilateral). `None` when a corner's
    /// ray misses the patch plane.
    #[inline]
    pub fn caster_quad(&self, lr: Vec2, hx: f32, hy: f32) -> Option<[Vec2; 4]> {
        let mut q = [Vec2::ZERO; 4];
        for (k, s) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .into_iter()
            .enumerate()
        {
            q[k] = self.to_patch(lr + Vec2::new(s.0 * hx, s.1 * hy))?.0;
        }
        Some(q)
    }

    /// Bounding box, in continuous texel coordinates of the view (`(u - x0) / delta` with the
    /// view's `n`, `x0`, `delta`), of the tan-space directions of every point at depth `c` that
    /// lies between r and the light: the texels whose casters at depth `>= c` can occlude r.
    /// Returns `[u_min, v_min, u_max, v_max]`.
    pub fn texel_bounds(&self, c: f32, window_min: Vec2, delta: f32) -> [f32; 4] {
        // The sun: view depth c is c - dz in the footprint's frame.
        let c = match self.sun {
            Some(f) => c - f.dz,
            None => c,
        }
        .max(f32::MIN_POSITIVE);
        let mut lo = Vec2::splat(f32::INFINITY);
        let mut hi = Vec2::splat(f32::NEG_INFINITY);
        for k in 0..self.patch.hull_points() {
            let at = self.at_depth(self.patch.hull_point(k), c);
            // Perspective: the point's direction on the plane z = n; the sun: its view (x, y).
            let y = match self.sun {
                Some(f) => at + f.o,
                None => at * (self.n / c),
            };
            let t = (y - window_min) / delta;
            lo = lo.min(t);
            hi = hi.max(t);
        }
        [lo.x, lo.y, hi.x, hi.y]
    }
}

/// Most corners of a convex quadrilateral clipped by one half-plane.
pub const MAX_CLIP: usize = 5;

/// The trace of the receiver's tangent plane on the light patch, in the patch's in-plane
/// coordinates: the light point `X = e1 x + e2 y` lies in front of the plane through `p` with
/// normal `nrm` (`nrm.(X - p) > 0`) when `a.(x, y) > c`, `a = (nrm.e1, nrm.e2)`, `c = nrm.p`.
///
/// Only light in front of the plane reaches the receiver, and a caster can hide only that part
/// (the line from p through a caster in front of the plane meets the light in front of it), so
/// the estimators measure occlusion on the front part: `s_front`, the occluded fraction of the
/// light's area that lies in front, and `V = facing - s_front` (docs: [`crate::cpu`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrontEdge {
    /// `(nrm.e1, nrm.e2)`.
    pub a: Vec2,
    /// `nrm.p`.
    pub c: f32,
    /// The whole patch is in front (every hull point): nothing to clip.
    pub whole: bool,
    /// The fraction of the patch's area in front of the plane
    /// ([`shadow_map_core::light::front_fraction`] on the patch).
    pub fraction: f32,
}

impl FrontEdge {
    /// No plane: the whole light counts (the plain [`Footprint::overlap_term`]).
    pub const EVERYTHING: FrontEdge = FrontEdge {
        a: Vec2::ZERO,
        c: -1.0,
        whole: true,
        fraction: 1.0,
    };
    /// The tangent plane of the receiver `p` (light space) with unit normal `nrm`, on `patch`.
    pub fn new(patch: &LightPatch, p: Vec3, nrm: Vec3) -> FrontEdge {
        let a = Vec2::new(nrm.dot(patch.e1), nrm.dot(patch.e2));
        let c = nrm.dot(p);
        let whole = (0..patch.hull_points()).all(|k| a.dot(patch.hull_local(k)) > c);
        let fraction = if whole {
            1.0
        } else {
            let shape = match patch.shape {
                PatchShape::Disk(r) => LightShape::Disk { radius: r },
                PatchShape::Rect(h) => LightShape::Rect {
                    size: [2.0 * h.x, 2.0 * h.y],
                },
            };
            let pl = Vec3::new(p.dot(patch.e1), p.dot(patch.e2), p.dot(patch.a));
            let nl = Vec3::new(a.x, a.y, nrm.dot(patch.a));
            shadow_map_core::light::front_fraction(&shape, pl, nl)
        };
        FrontEdge {
            a,
            c,
            whole,
            fraction,
        }
    }
    /// The patch plane's point `local` (in-plane coordinates) lies in front.
    #[inline]
    pub fn front(&self, local: Vec2) -> bool {
        self.a.dot(local) > self.c
    }
    /// The convex polygon `q` clipped to the front (Sutherland-Hodgman, one edge): its corners
    /// in `out`, their count returned (0 when `q` lies behind).
    #[inline]
    pub fn clip(&self, q: &[Vec2; 4], out: &mut [Vec2; MAX_CLIP]) -> usize {
        let mut m = 0;
        for k in 0..4 {
            let p0 = q[k];
            let p1 = q[(k + 1) % 4];
            let f0 = self.a.dot(p0) - self.c;
            let f1 = self.a.dot(p1) - self.c;
            if f0 > 0.0 {
                out[m] = p0;
                m += 1;
            }
            if (f0 > 0.0) != (f1 > 0.0) {
                out[m] = p0 + (p1 - p0) * (f0 / (f0 - f1));
                m += 1;
            }
        }
        m
    }
}

/// True when `b` lies in the convex quadrilateral `q` (the core's occlusion-bit geometry,
/// shared with `backprojection`).
pub use shadow_map_core::bitmask::quad_contains;

/// The elementary caster of a lexel (§1.1, the pseudo-code's `size` and `lr`; docs/methods.md §9
/// with its corrections): the caster point `c = (l, n) c_z / n` behind plane point `l` seen from
/// r lands on the plane at
///
/// `l_r = ((n - c_z)/(r_z - c_z)) r_xy + size l`,  `size = ((r_z - n)/(r_z - c_z)) (c_z / n)`,
///
/// and a lexel of side `delta` becomes a square of side `size delta` there. Valid for any
/// `0 < c_z < r_z`, also `c_z < n` (a caster between the light and the plane: the line from r
/// through c still meets the plane). Returns `None` for `c_z` outside that range (the caster is
/// not between the light and r) or non-finite results. `r_z - c_z` is floored at `1e-7 r_z`.
#[inline]
pub fn caster(r: Vec3, n: f32, l: Vec2, c_z: f32) -> Option<(Vec2, f32)> {
    if !(c_z > 0.0) || !(c_z < r.z) {
        return None;
    }
    let gap = (r.z - c_z).max(1e-7 * r.z);
    let size = ((r.z - n) / gap) * (c_z / n);
    let lr = Vec2::new(r.x, r.y) * ((n - c_z) / gap) + l * size;
    (size.is_finite() && lr.is_finite()).then_some((lr, size))
}

/// First lexel index of the paper's fixed K-lexel kernel along one axis, centred on the
/// continuous texel coordinate `u`: the K lexels whose centres lie in `[u - K/2, u + K/2)`.
#[inline]
pub fn fixed_kernel_start(u: f32, k: u32) -> i32 {
    (u - 0.5 * k as f32 - 0.5).ceil() as i32
}

/// The paper's plane distance for a fixed kernel (§1.1, assumption 1: "n proportional to R so
/// that a K x K kernel covers the footprint"): the lexel pitch on the plane equals `2R/K`, so
/// `n = 2 R r / (K S)` with S the window side in tan space (`w / n` of the fitted view). The
/// K x K kernel then covers the footprint on that plane, i.e. every caster with `c_z >= n_paper`
/// (up to the receiver's own depth); casters nearer the light than `n_paper` project further than
/// the kernel and are missed (what the adaptive kernel fixes).
pub fn paper_plane_distance(radius: f32, r: u32, k: u32, tan_window: f32) -> f32 {
    2.0 * radius * r as f32 / (k as f32 * tan_window)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sums the additive and exact shadowing factors of a flat occluder at depth `c` over the
    /// lexels whose centre ray (from the light centre) is on the occluded side `side(l) < 0`.
    fn flat_occluder(
        fp: &Footprint,
        delta: f32,
        c: f32,
        side: impl Fn(Vec2) -> f32,
        bits: u32,
    ) -> (f32, f32, f32) {
        let q = fp.q();
        let [u0, v0, u1, v1] = fp.texel_bounds(c, q, delta);
        let mut s_add = 0.0f64;
        let mut s_ovl = 0.0f64;
        let mut casters = Vec::new();
        for j in (v0.floor() as i32 - 1)..=(v1.ceil() as i32 + 1) {
            for i in (u0.floor() as i32 - 1)..=(u1.ceil() as i32 + 1) {
                let l = q + Vec2::new(i as f32 + 0.5, j as f32 + 0.5) * delta;
                if side(l) >= 0.0 {
                    continue;
                }
                let (lr, size) = caster(fp.r, fp.n, l, c).unwrap();
                let side_len = size * delta;
                s_add += fp.additive_term(lr, side_len * side_len) as f64;
                s_ovl += fp.overlap_term(lr, 0.5 * side_len, 0.5 * side_len) as f64;
                casters.push((lr, 0.5 * side_len));
            }
        }
        let mut hit = 0u32;
        for j in 0..bits {
            for i in 0..bits {
                let p = fp.to_plane(fp.patch.bit_point(i, j, bits));
                if casters
                    .iter()
                    .any(|(lr, h)| (p.x - lr.x).abs() <= *h && (p.y - lr.y).abs() <= *h)
                {
                    hit += 1;
                }
            }
        }
        (
            s_add as f32,
            hit as f32 / (bits * bits) as f32,
            s_ovl as f32,
        )
    }

    #[test]
    fn half_occluder_gives_one_half() {
        let n = 0.5;
        let c = 2.0;
        let lights = [
            LightShape::Rect { size: [1.0, 0.6] },
            LightShape::Disk { radius: 0.5 },
            LightShape::Sphere { radius: 0.5 },
        ];
        for (shape, model, r) in [
            (lights[0], SphereModel::Contract, Vec3::new(0.3, -0.2, 4.0)),
            (lights[1], SphereModel::Contract, Vec3::new(0.3, -0.2, 4.0)),
            (lights[2], SphereModel::Paper, Vec3::new(0.3, -0.2, 4.0)),
            (lights[2], SphereModel::Contract, Vec3::new(2.0, 1.0, 3.0)),
        ] {
            let patch = LightPatch::for_receiver(&shape, model, r);
            let fp = Footprint::new(patch, r, n);
            // The plane through the light centre, r and the direction e_x (the occluder's edge
            // seen from r crosses the light through its centre): exactly half the light.
            let normal = r.cross(Vec3::X);
            let side = |l: Vec2| normal.dot(Vec3::new(l.x, l.y, n));
            let delta = 2e-3;
            let near = |what: &str, got: f32, want: f32, tol: f32| {
                assert!(
                    (got - want).abs() < tol,
                    "{shape:?} {model:?}: {what} {got}"
                )
            };
            let (s_add, s_exact, s_ovl) = flat_occluder(&fp, delta, c, side, 16);
            near("overlap", s_ovl, 0.5, 0.01);
            near("additive", s_add, 0.5, 0.01);
            near("exact", s_exact, 0.5, 0.04);
            // A full occluder: every square tiles the footprint once.
            let (s_full, e_full, o_full) = flat_occluder(&fp, delta, c, |_| -1.0, 8);
            near("overlap full", o_full, 1.0, 0.01);
            near("full", s_full, 1.0, 0.01);
            assert_eq!(e_full, 1.0);
        }
    }

    /// The plane distance n is a convention: a caster nearer the light than the plane
    /// (`c_z < n`) lands on the same light point whichever n is used.
    #[test]
    fn caster_mapping_is_independent_of_n() {
        let r = Vec3::new(0.4, -0.3, 5.0);
        let c = Vec3::new(0.1, 0.05, 0.7);
        let patch =
            LightPatch::for_receiver(&LightShape::Disk { radius: 0.5 }, SphereModel::Contract, r);
        let mut hits = Vec::new();
        for n in [0.2f32, 0.7, 1.5, 3.0] {
            let l = Vec2::new(c.x, c.y) * (n / c.z);
            let (lr, size) = caster(r, n, l, c.z).unwrap();
            let fp = Footprint::new(patch, r, n);
            let (local, _) = fp.to_patch(lr).unwrap();
            hits.push(local);
            assert!(size > 0.0);
        }
        // Direct: the line from r through c meets z = 0 at r + (c - r) r_z / (r_z - c_z).
        let x = r + (c - r) * (r.z / (r.z - c.z));
        for h in hits {
            assert!((h - Vec2::new(x.x, x.y)).length() < 1e-4, "{h} vs {x}");
        }
    }

    /// Off-axis, the paper's sphere model (disk perpendicular to the light normal) is
    /// foreshortened against the contract's silhouette disk: the footprint areas differ by about
    /// cos(theta).
    #[test]
    fn paper_sphere_model_is_foreshortened_off_axis() {
        let shape = LightShape::Sphere { radius: 0.3 };
        let n = 0.5;
        for (r, cos_theta) in [
            (Vec3::new(0.0, 0.0, 3.0), 1.0f32),
            (Vec3::new(3.0, 0.0, 3.0), std::f32::consts::FRAC_1_SQRT_2),
        ] {
            let area = |model| {
                let fp = Footprint::new(LightPatch::for_receiver(&shape, model, r), r, n);
                // Footprint area on the plane = A_L / mean J: integrate 1[P in F] on a grid.
                let [u0, v0, u1, v1] = fp.texel_bounds(n, Vec2::ZERO, 1e-3);
                let mut a = 0.0f64;
                for j in v0 as i32..=v1 as i32 {
                    for i in u0 as i32..=u1 as i32 {
                        let p = Vec2::new(i as f32 + 0.5, j as f32 + 0.5) * 1e-3;
                        if let Some((local, _)) = fp.to_patch(p) {
                            if fp.patch.contains(local) {
                                a += 1e-6;
                            }
                        }
                    }
                }
                a
            };
            let ratio = area(SphereModel::Paper) / area(SphereModel::Contract);
            assert!(
                (ratio - cos_theta as f64).abs() < 0.03,
                "paper/contract footprint area {ratio}, cos theta {cos_theta}"
            );
        }
    }

    #[test]
    fn degenerate_casters_are_rejected() {
        let r = Vec3::new(0.0, 0.0, 2.0);
        assert!(caster(r, 1.0, Vec2::ZERO, 2.0).is_none());
        assert!(caster(r, 1.0, Vec2::ZERO, 0.0).is_none());
        assert!(caster(r, 1.0, Vec2::ZERO, f32::NAN).is_none());
        let (_, size) = caster(r, 1.0, Vec2::ZERO, 1.999_999).unwrap();
        assert!(size.is_finite());
        assert_eq!(fixed_kernel_start(10.5, 10), 5);
        assert_eq!(fixed_kernel_start(10.2, 3), 9);
    }
}
