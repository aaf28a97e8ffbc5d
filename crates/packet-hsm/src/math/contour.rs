//! The contours of per-pixel contour backprojection (Guennebaud, Barthe, Paulin 2007, "GBP07";
//! docs/methods.md §3), the exact baseline every acceleration of this crate reproduces: the
//! occluder status, a dual cell's contour edges, the centre status and the receiver-plane bounds
//! the pruning of the extraction ([`crate::cpu::extract`]) relies on.
//!
//! Conventions (docs/methods.md §1): light space with the light (or sub-light) centre at the
//! origin, light plane z = 0, continuous texel coordinates `(u, v)`, sample (i, j) centred at
//! `(i + 1/2, j + 1/2)`. Samples outside the map are non-occluders (+inf).
//!
//! - **Occluder status** (Yang eq. 3): for a threshold range `[t_min, t_max]` (one receiver:
//!   `t_min = t_max = t_p`), a sample with classification depth `c_s` has status
//!   `f(s) = 1` if `c_s < t_min`, `0` if `c_s >= t_max`, and *null* otherwise. The paper writes
//!   `z_s <= z_pmin` for status 1; this crate uses the strict `<` so that a one-pixel packet has
//!   exactly the per-pixel classification `c_s < t_p` (docs/methods.md §3 "Classification") and a
//!   null never arises for it. See [`Status`]. With receiver-plane rejection a sample occludes a
//!   receiver only if it also passes the receiver's plane test on its true depth
//!   ([`OccluderTest`]); a packet's status is then occluder / free / null as every member /
//!   none / some of them see it ([`Planes`](crate::cpu::extract::Planes)).
//! - **Contour edges**: marching squares on the dual cell with corners c0 = (i, j),
//!   c1 = (i+1, j), c2 = (i+1, j+1), c3 = (i, j+1) (counter-clockwise); one vertex at the
//!   midpoint of each side whose corners differ, with the depth of the side's occluder sample;
//!   edges oriented from an occluder-to-free crossing X to a free-to-occluder crossing E (occluded
//!   side on the left); saddles use the *connected* rule (X on side s joins E on side s+1). See
//!   [`cell_edges`].
//! - **Backprojection** of a vertex `(u, v, z_s)` seen from the receiver `(u_p, v_p, z_p)`:
//!   `x_L = k z_s z_p (u - u_p) / (z_p - z_s)`, likewise y, `k = w / (n r)` ([`backproject`](super::radial::backproject)).
//! - **Radial integration** (Assarsson & Akenine-Möller 2003): each projected edge clipped to the
//!   light contributes `tri(a', b') - sector(a', b')`; `A_occ = c A_L + sum`, with c the centre
//!   status of `(u_p, v_p)` taken from the contour ([`centre_status`]);
//!   `V = 1 - clamp01(A_occ / A_L)` ([`edge_area`](super::radial::edge_area),
//!   [`visibility_from_area`](super::radial::visibility_from_area)). The light is an
//!   [`Emitter`](super::radial::Emitter): a rectangle, a disk (docs/methods.md §3 "Disk lights": the chord inside the
//!   circle and the circular sector, [`disk_edge_term`](super::radial::disk_edge_term)), or a sphere's silhouette disk seen from
//!   the receiver, onto which each backprojected edge is carried first (§3 "Sphere lights",
//!   [`sphere_edge_term`](super::radial::sphere_edge_term)).
//!
//! All light-plane geometry of a rect light is in f64; a disk's per-edge term is the core's f32
//! [`edge_disk_area`](shadow_map_core::overlap::edge_disk_area) after an f64 clip to the disk's
//! bounding square. Each edge's term is a pure function of the edge and the receiver, so the only
//! difference between evaluation orders (per pixel, per packet, flat or hierarchical) is the order
//! of an f64 sum.
use glam::{DVec2, Vec2};
use shadow_map_core::{mssm::Mssm, silhouette::Silhouette, ReceiverPlane};

/// Texel coordinates and depths a cell is read from: the true depth (for backprojection) and the
/// classification depth (for the occluder status: the true depth, or Bavoil's midpoint between the
/// first two layers) of every sample.
#[derive(Debug, Clone, Copy)]
pub struct SampleGrid<'a> {
    /// Side r of the map.
    pub size: u32,
    /// True linear depths, `r x r`, row-major.
    pub depth: &'a [f32],
    /// Classification depths, `r x r`, row-major.
    pub class: &'a [f32],
}

impl SampleGrid<'_> {
    /// True when the classification depths are the true depths (one slice for both).
    pub fn class_is_depth(&self) -> bool {
        std::ptr::eq(self.depth, self.class)
    }
    /// `(true depth, classification depth)` of sample (i, j); `(+inf, +inf)` outside the map.
    #[inline]
    pub fn at(&self, i: i32, j: i32) -> (f32, f32) {
        let r = self.size as i32;
        if i < 0 || j < 0 || i >= r || j >= r {
            (f32::INFINITY, f32::INFINITY)
        } else {
            let k = j as usize * r as usize + i as usize;
            (self.depth[k], self.class[k])
        }
    }
}

/// Occluder status of one sample for a threshold range (Yang eq. 3, strict form; module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Occludes every receiver of the range (`c_s < t_min`).
    Occluder,
    /// Occludes none (`c_s >= t_max`).
    Free,
    /// Occludes some receivers of the packet and not others: the packet's contours diverge.
    Null,
}

/// The status `f(s)` of a classification depth `c` for the threshold range `[t_min, t_max]`.
#[inline]
pub fn status(c: f32, t_min: f32, t_max: f32) -> Status {
    if c < t_min {
        Status::Occluder
    } else if !(c < t_max) {
        Status::Free
    } else {
        Status::Null
    }
}

/// A contour edge in texel coordinates: from `a` (depth `za`) to `b` (depth `zb`), occluded side
/// on the left.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// Start (an occluder-to-free crossing X).
    pub a: [f32; 2],
    /// End (a free-to-occluder crossing E).
    pub b: [f32; 2],
    /// Depth of the start vertex (its side's occluder sample).
    pub za: f32,
    /// Depth of the end vertex.
    pub zb: f32,
}

/// Corner offsets c0..c3, counter-clockwise.
pub(crate) const CORNERS: [(i32, i32); 4] = [(0, 0), (1, 0), (1, 1), (0, 1)];
/// Side midpoints (s from corner s to corner s+1) relative to `(i, j)`, in texel coordinates.
const SIDES: [(f32, f32); 4] = [(1.0, 0.5), (1.5, 1.0), (1.0, 1.5), (0.5, 1.0)];

/// Contour edges of dual cell (i, j) from its corner occluder flags and true depths (module docs):
/// 0, 1 or 2 edges.
#[inline]
pub fn cell_edges(i: i32, j: i32, occ: [bool; 4], z: [f32; 4]) -> ([Edge; 2], usize) {
    let empty = Edge {
        a: [0.0; 2],
        b: [0.0; 2],
        za: 0.0,
        zb: 0.0,
    };
    let mut out = [empty; 2];
    let n_occ = occ.iter().filter(|&&o| o).count();
    if n_occ == 0 || n_occ == 4 {
        return (out, 0);
    }
    let vertex = |s: usize| -> ([f32; 2], f32) {
        let (du, dv) = SIDES[s];
        let occ_corner = if occ[s] { s } else { (s + 1) % 4 };
        ([i as f32 + du, j as f32 + dv], z[occ_corner])
    };
    let saddle = n_occ == 2 && occ[0] == occ[2];
    let mut n = 0;
    for s in 0..4 {
        // X: occluder -> free walking counter-clockwise.
        if occ[s] && !occ[(s + 1) % 4] {
            let e = if saddle {
                (s + 1) % 4
            } else {
                // The unique E side.
                (0..4)
                    .find(|&t| !occ[t] && occ[(t + 1) % 4])
                    .unwrap_or((s + 1) % 4)
            };
            let (a, za) = vertex(s);
            let (b, zb) = vertex(e);
            out[n] = Edge { a, b, za, zb };
            n += 1;
        }
    }
    (out, n)
}

/// What makes a sample an occluder of one receiver: its classification depth below the
/// threshold `t` and, with receiver-plane rejection ([`shadow_map_core::receiver_plane`]), its
/// true depth in front of the receiver's tangent plane ([`ReceiverPlane::caster`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OccluderTest {
    /// Classification threshold `t_p`.
    pub t: f32,
    /// The receiver plane (`receiver_plane=true`), or `None` for the classic test `c_s < t_p`.
    pub plane: Option<ReceiverPlane>,
}

impl OccluderTest {
    /// The classic test `c_s < t`.
    pub fn classic(t: f32) -> Self {
        OccluderTest { t, plane: None }
    }
    /// True when the sample (i, j) with true depth `zs` and classification depth `cs` occludes.
    #[inline]
    pub fn occludes(&self, i: i32, j: i32, zs: f32, cs: f32) -> bool {
        cs < self.t && self.plane.as_ref().is_none_or(|p| p.caster(i, j, zs))
    }
}

/// Relative margin of the plane-threshold pruning bounds: [`ReceiverPlane::threshold_at`] divides
/// where [`ReceiverPlane::caster`] multiplies, so a bound is widened by a few ulps (2^-20 of it)
/// and a pruned node never holds a sample the per-cell test would classify otherwise.
pub const PRUNE_MARGIN: f32 = 1.0 / 1_048_576.0;

/// Depth bounds of one plane's caster test on the ray through `uv`: `(lower, upper)` with every
/// finite sample `z < lower` a caster and no sample `z >= upper` one.
///
/// With slope `g > 0` both are `min(c / g - hs, z_p)`. With `g <= 0` the casters are the
/// samples `z > c / g` nearer than `z_p`: `upper = z_p` (the core's
/// [`ReceiverPlane::threshold_at`]), and `lower = z_p` when `c > 0` (every sample nearer than
/// `z_p`), else `-inf` (a receiver whose tangent plane passes above the light's centre: only
/// samples deeper than `c / g` are casters there).
#[inline]
pub fn caster_bounds(p: &ReceiverPlane, uv: Vec2) -> (f32, f32) {
    let g = p.slope_at(uv);
    let c = p.height_at(uv);
    if g > 0.0 {
        let t = (c / g - p.hs).min(p.zp);
        (t, t)
    } else if c > 0.0 {
        (p.zp, p.zp)
    } else {
        (f32::NEG_INFINITY, p.zp)
    }
}

/// `(min lower, max upper)` of [`caster_bounds`] over the centres of samples `[i0, i1] x
/// [j0, j1]` (inclusive) for every plane of `members`, widened by [`PRUNE_MARGIN`] (min lowered,
/// max raised): every sample whose true depth is below the first is a caster for every member,
/// none at or above the second for any. Both bounds are monotone in the plane's affine slope
/// (a sign change of `g` inside the rectangle shows at a corner), so the extremes are at the
/// rectangle's corners.
pub fn plane_threshold_range(members: &[OccluderTest], rect: [i32; 4]) -> (f32, f32) {
    corner_range(members, rect, 1.0)
}

/// The range of [`caster_bounds`] over the corners of `rect` for every plane of `members`:
/// `outer = 1` the outer ends (min lower, max upper) widened outwards by [`PRUNE_MARGIN`],
/// `outer = -1` the inner ends (max lower, min upper) narrowed inwards by it; `(-inf, inf)`
/// (outer) or `(inf, -inf)` (inner) when a member has no plane.
#[inline]
fn corner_range(members: &[OccluderTest], rect: [i32; 4], outer: f32) -> (f32, f32) {
    let inf = outer * f32::INFINITY;
    match corner_bounds(members, rect) {
        None => (-inf, inf),
        Some(b) => {
            let (lo, hi) = b.fold((inf, -inf), |(lo, hi), (l, h)| {
                if outer > 0.0 {
                    (lo.min(l), hi.max(h))
                } else {
                    (lo.max(l), hi.min(h))
                }
            });
            (
                lo - outer * lo.abs() * PRUNE_MARGIN,
                hi + outer * hi.abs() * PRUNE_MARGIN,
            )
        }
    }
}

/// [`caster_bounds`] at the four corner sample centres of `[i0, i1] x [j0, j1]` for every plane
/// of `members`; `None` when a member has no plane (the classic test: no depth bound applies).
fn corner_bounds(
    members: &[OccluderTest],
    [i0, j0, i1, j1]: [i32; 4],
) -> Option<impl Iterator<Item = (f32, f32)> + '_> {
    let (u0, u1) = (i0 as f32 + 0.5, i1 as f32 + 0.5);
    let (v0, v1) = (j0 as f32 + 0.5, j1 as f32 + 0.5);
    if members.iter().any(|m| m.plane.is_none()) {
        return None;
    }
    // No allocation: this runs once per hierarchy node.
    Some(
        members
            .iter()
            .filter_map(|m| m.plane.as_ref())
            .flat_map(move |p| {
                [
                    Vec2::new(u0, v0),
                    Vec2::new(u1, v0),
                    Vec2::new(u0, v1),
                    Vec2::new(u1, v1),
                ]
                .map(|uv| caster_bounds(p, uv))
            }),
    )
}

/// `(max lower, min upper)` of [`caster_bounds`] over the same corners as
/// [`plane_threshold_range`], widened the other way (max raised, min lowered): every node inside
/// the rectangle has its own `plane_threshold_range` lower bound at most the first and upper
/// bound at least the second.
pub fn plane_inner_range(members: &[OccluderTest], rect: [i32; 4]) -> (f32, f32) {
    corner_range(members, rect, -1.0)
}

/// Occluder flags and true depths of the corners of cell (i, j) for one receiver's test.
#[inline]
pub fn cell_corners(
    grid: &SampleGrid,
    i: i32,
    j: i32,
    test: &OccluderTest,
) -> ([bool; 4], [f32; 4]) {
    let mut occ = [false; 4];
    let mut z = [0.0f32; 4];
    for (k, (di, dj)) in CORNERS.iter().enumerate() {
        let (zs, cs) = grid.at(i + di, j + dj);
        occ[k] = test.occludes(i + di, j + dj, zs, cs);
        z[k] = zs;
    }
    (occ, z)
}

/// Which side of the edge the point q is on: `cross(b - a, q - a)` (> 0: left, occluded).
#[inline]
fn side(e: &Edge, q: DVec2) -> f64 {
    let a = DVec2::new(e.a[0] as f64, e.a[1] as f64);
    let b = DVec2::new(e.b[0] as f64, e.b[1] as f64);
    (b - a).perp_dot(q - a)
}

/// Centre status c of the receiver's projection `q = (u_p, v_p)` taken from the contour
/// (docs/methods.md §3 "Centre status"): in the dual cell `floor(q - 1/2)`, all corners agreeing
/// give their status; otherwise q is occluded when it is left of its edge (two edges, connected
/// rule: left of both). Returns `None` when q lies on a cell boundary or exactly on an edge (the
/// caller nudges q, see [`Receiver::new`]).
pub fn centre_status(grid: &SampleGrid, q: DVec2, test: &OccluderTest) -> Option<bool> {
    let (fi, fj) = ((q.x - 0.5).floor(), (q.y - 0.5).floor());
    if fi == q.x - 0.5 || fj == q.y - 0.5 {
        return None;
    }
    let (i, j) = (fi as i32, fj as i32);
    let (occ, z) = cell_corners(grid, i, j, test);
    let (edges, n) = cell_edges(i, j, occ, z);
    if n == 0 {
        return Some(occ[0]);
    }
    let mut inside = true;
    for e in &edges[..n] {
        let s = side(e, q);
        if s == 0.0 {
            return None;
        }
        inside &= s > 0.0;
    }
    Some(inside)
}

/// One receiver as the contour integration sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Receiver {
    /// Texel coordinates `(u_p, v_p)` (possibly nudged off cell boundaries and edges).
    pub uv: DVec2,
    /// Light-space depth `z_p` (backprojection).
    pub zp: f64,
    /// Classification threshold `t_p`: a sample occludes when its classification depth is below.
    pub t: f32,
    /// Centre status c (1: the light centre is occluded).
    pub centre: bool,
    /// The receiver plane of its occluder test ([`OccluderTest::plane`]).
    pub plane: Option<ReceiverPlane>,
    /// A sphere light's silhouette disk seen from this receiver ([`Emitter::Sphere`](super::radial::Emitter::Sphere)); `None`
    /// for rect and disk lights.
    pub sil: Option<Silhouette>,
}

impl Receiver {
    /// Evaluates the centre status, nudging `uv` by a fixed `(2^-12, 2^-13)` texels (up to 8 times)
    /// while it lies on a cell boundary or exactly on a contour edge (docs/methods.md §3 "Centre
    /// status": nudge q by a fixed tiny offset, and use the nudged q for both the status test and
    /// the projection). The classic occluder test `c_s < t`.
    pub fn new(grid: &SampleGrid, uv: DVec2, zp: f64, t: f32) -> Receiver {
        Self::with_test(grid, uv, zp, OccluderTest::classic(t))
    }
    /// [`new`](Self::new) with the occluder test `test` (receiver-plane rejection when it holds
    /// a plane).
    pub fn with_test(grid: &SampleGrid, uv: DVec2, zp: f64, test: OccluderTest) -> Receiver {
        let t = test.t;
        let plane = test.plane;
        let mut q = uv;
        for _ in 0..8 {
            if let Some(c) = centre_status(grid, q, &test) {
                return Receiver {
                    uv: q,
                    zp,
                    t,
                    centre: c,
                    plane,
                    sil: None,
                };
            }
            q += DVec2::new(1.0 / 4096.0, 1.0 / 8192.0);
        }
        // Unreachable in practice; take the nearest-sample status.
        let (i, j) = (q.x.floor() as i32, q.y.floor() as i32);
        let (zs, c) = grid.at(i, j);
        Receiver {
            uv: q,
            zp,
            t,
            centre: test.occludes(i, j, zs, c),
            plane,
            sil: None,
        }
    }
    /// The receiver's occluder test.
    #[inline]
    pub fn test(&self) -> OccluderTest {
        OccluderTest {
            t: self.t,
            plane: self.plane,
        }
    }
}

/// A rectangle of dual cells `[x0, x1) x [y0, y1)` (anchors, unpadded: cell (i, j) has corners
/// (i..=i+1, j..=j+1); anchors run over `[-1, r)` so cells touching the map border are included).
pub type CellRect = [i32; 4];

/// The smallest true depth over the samples `s` (inclusive texel rectangle): `class_min` (the
/// classification minimum) when the classification depths are the true depths, else from the
/// true-depth MSSM `depth`, else `-inf` (unknown).
#[inline]
pub fn true_min(class_is_depth: bool, depth: Option<&Mssm>, class_min: f32, s: [i32; 4]) -> f32 {
    if class_is_depth {
        class_min
    } else {
        depth.map_or(f32::NEG_INFINITY, |m| {
            m.query(s[0], s[1], s[2] + 1, s[3] + 1).min
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_edges_orientation() {
        // Only c0 occludes: the edge cuts corner c0 with c0 on the left.
        let (e, n) = cell_edges(0, 0, [true, false, false, false], [1.0; 4]);
        assert_eq!(n, 1);
        let c0 = DVec2::new(0.5, 0.5);
        assert!(side(&e[0], c0) > 0.0);
        assert!(side(&e[0], DVec2::new(1.5, 1.5)) < 0.0);
        // Saddle: two edges, each cutting a free corner.
        let (e, n) = cell_edges(0, 0, [true, false, true, false], [1.0; 4]);
        assert_eq!(n, 2);
        for ed in &e[..2] {
            assert!(
                side(ed, DVec2::new(1.0, 1.0)) > 0.0,
                "centre occluded (connected)"
            );
        }
    }
}
