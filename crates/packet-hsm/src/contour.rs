//! Per-pixel contour backprojection (Guennebaud, Barthe, Paulin 2007, "GBP07"; docs/methods.md §3),
//! the exact baseline every acceleration of this crate reproduces, and the hierarchical contour
//! extraction over the dual-grid MSSM (Yang et al. 2009 §4.2, Algorithm 3).
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
//!   none / some of them see it ([`Planes`]).
//! - **Contour edges**: marching squares on the dual cell with corners c0 = (i, j),
//!   c1 = (i+1, j), c2 = (i+1, j+1), c3 = (i, j+1) (counter-clockwise); one vertex at the
//!   midpoint of each side whose corners differ, with the depth of the side's occluder sample;
//!   edges oriented from an occluder-to-free crossing X to a free-to-occluder crossing E (occluded
//!   side on the left); saddles use the *connected* rule (X on side s joins E on side s+1). See
//!   [`cell_edges`].
//! - **Backprojection** of a vertex `(u, v, z_s)` seen from the receiver `(u_p, v_p, z_p)`:
//!   `x_L = k z_s z_p (u - u_p) / (z_p - z_s)`, likewise y, `k = w / (n r)` ([`backproject`]).
//! - **Radial integration** (Assarsson & Akenine-Möller 2003): each projected edge clipped to the
//!   light contributes `tri(a', b') - sector(a', b')`; `A_occ = c A_L + sum`, with c the centre
//!   status of `(u_p, v_p)` taken from the contour ([`centre_status`]);
//!   `V = 1 - clamp01(A_occ / A_L)` ([`edge_area`], [`visibility_from_area`]). The light is an
//!   [`Emitter`]: a rectangle, a disk (docs/methods.md §3 "Disk lights": the chord inside the
//!   circle and the circular sector, [`disk_edge_term`]), or a sphere's silhouette disk seen from
//!   the receiver, onto which each backprojected edge is carried first (§3 "Sphere lights",
//!   [`sphere_edge_term`]).
//!
//! All light-plane geometry of a rect light is in f64; a disk's per-edge term is the core's f32
//! [`edge_disk_area`](shadow_map_core::overlap::edge_disk_area) after an f64 clip to the disk's
//! bounding square. Each edge's term is a pure function of the edge and the receiver, so the only
//! difference between evaluation orders (per pixel, per packet, flat or hierarchical) is the order
//! of an f64 sum.
use crate::fit::DualFit;
use glam::{DVec2, Vec2};
use shadow_map_core::{
    mssm::{DualMssm, Mssm},
    silhouette::Silhouette,
    ReceiverPlane,
};

mod radial;
pub use radial::{
    backproject, clip_to_rect, disk_edge_term, edge_area, sector_rect, sector_rect_by_angle,
    sphere_edge_term, visibility_from_area, Emitter, Scale,
};

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
const CORNERS: [(i32, i32); 4] = [(0, 0), (1, 0), (1, 1), (0, 1)];
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
    match corner_bounds(members, rect) {
        None => (f32::NEG_INFINITY, f32::INFINITY),
        Some(b) => {
            let (lo, hi) = b.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (l, h)| {
                (lo.min(l), hi.max(h))
            });
            (lo - lo.abs() * PRUNE_MARGIN, hi + hi.abs() * PRUNE_MARGIN)
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
    match corner_bounds(members, rect) {
        None => (f32::INFINITY, f32::NEG_INFINITY),
        Some(b) => {
            let (lo, hi) = b.fold((f32::NEG_INFINITY, f32::INFINITY), |(lo, hi), (l, h)| {
                (lo.max(l), hi.min(h))
            });
            (lo + lo.abs() * PRUNE_MARGIN, hi - hi.abs() * PRUNE_MARGIN)
        }
    }
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
    /// A sphere light's silhouette disk seen from this receiver ([`Emitter::Sphere`]); `None`
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

/// The dual-grid MSSM of the classification depths over the map padded by one ring of empty
/// (+inf) samples, so that cells reaching outside the map (anchors -1 and r-1) are exact nodes too.
/// Padded anchor = unpadded anchor + 1.
#[derive(Debug, Clone)]
pub struct PaddedDualMssm {
    /// The structure over the `(r + 2)^2` padded samples.
    pub mssm: DualMssm,
}

impl PaddedDualMssm {
    /// Builds levels `0..=L` over the padded classification depths, with
    /// `L = min(floor(log2(r + 2)), ceil(log2(max_cells)))`: no kernel spans more than
    /// `max_cells` cells, so its start node is a single node of level `<= L` and higher levels
    /// would only cost memory (`2 (L + 1) (r + 2)^2 4` bytes). Missing depths (a short slice) are
    /// empty samples.
    pub fn build(class: &[f32], r: u32, max_cells: u32) -> PaddedDualMssm {
        let p = r as usize + 2;
        let mut padded = vec![f32::INFINITY; p * p];
        for j in 0..r as usize {
            for i in 0..r as usize {
                if let Some(&c) = class.get(j * r as usize + i) {
                    padded[(j + 1) * p + 1 + i] = c;
                }
            }
        }
        let need = 32 - (max_cells.max(1) - 1).leading_zeros();
        let levels = ((p as f64).log2().floor() as u32).min(need);
        PaddedDualMssm {
            mssm: DualMssm::build(&padded, p as u32, levels),
        }
    }
    /// Exact min/max of the classification depths of every sample touched by the cells of `cr`.
    pub fn query(&self, cr: &CellRect) -> shadow_map_core::mssm::MinMax {
        self.mssm
            .query_cells(cr[0] + 1, cr[1] + 1, cr[2] + 1, cr[3] + 1)
    }
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.mssm.bytes()
    }
}

/// How the contour of a kernel is extracted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Traversal {
    /// Every 2x2 block (dual cell) of the kernel, one after the other (GBP07).
    Flat,
    /// Yang's Algorithm 3 over the dual-grid MSSM with an explicit stack.
    Hierarchical,
}

/// Largest number of nodes the explicit stack ever holds: 3 per level plus the roots.
pub const STACK_CAPACITY: usize = 3 * 32 + 64;

/// Extracts the contour of the cells in `cr` for the threshold range `[t_min, t_max]` (one
/// receiver: equal), calling `emit(i, j, edge)` for every edge, and returns `false` as soon as a
/// null status is met (the packet's contours diverge; Yang §4.1). `visited` counts the nodes
/// (hierarchical) or cells (flat) examined.
///
/// Hierarchical (Yang §4.2, Algorithm 3): start at the node of the lowest level `L` covering the
/// kernel with the kernel's top-left corner as anchor (`L = ceil(log2(max(W, H)))`; above the top
/// built level, the kernel is tiled with top-level nodes); a node whose depth range is entirely
/// below `t_min` (every sample occludes: Fig. 6 case 5) or entirely at or above `t_max` (none
/// occludes: case 4) holds no contour and is pruned; otherwise (cases 1-3, 6) its four children
/// `(x, y), (x+h, y), (x, y+h), (x+h, y+h)`, `h = 2^(l-1)`, that start inside the kernel are
/// pushed; level-0 nodes are cells. The stack is explicit (no recursion, as in WGSL).
#[allow(clippy::too_many_arguments)]
pub fn extract(
    grid: &SampleGrid,
    dm: &PaddedDualMssm,
    cr: &CellRect,
    [t_min, t_max]: [f32; 2],
    planes: Planes<'_>,
    traversal: Traversal,
    visited: &mut u64,
    mut emit: impl FnMut(i32, i32, &Edge),
) -> bool {
    let members = planes.members;
    // The plane bounds over the whole kernel (cells [x0, x1) touch samples [x0, x1]): quick
    // statuses and prunes before the per-member, per-node work.
    let kb = if members.is_empty() {
        (f32::NEG_INFINITY, f32::INFINITY)
    } else {
        plane_threshold_range(members, [cr[0], cr[1], cr[2], cr[3]])
    };
    // And the other ends over the kernel (largest lower, smallest upper bound): a node's own
    // range reaches them, so a node failing them fails its own too.
    let kb_inner = if members.is_empty() {
        (f32::NEG_INFINITY, f32::INFINITY)
    } else {
        plane_inner_range(members, [cr[0], cr[1], cr[2], cr[3]])
    };
    let mut cell = |i: i32, j: i32| -> bool {
        let mut occ = [false; 4];
        let mut z = [0.0f32; 4];
        for (k, (di, dj)) in CORNERS.iter().enumerate() {
            let (zs, cs) = grid.at(i + di, j + dj);
            let st = if members.is_empty() {
                status(cs, t_min, t_max)
            } else {
                planes.status(i + di, j + dj, zs, cs, [t_min, t_max], kb)
            };
            match st {
                Status::Occluder => occ[k] = true,
                Status::Free => {}
                Status::Null => return false,
            }
            z[k] = zs;
        }
        let (edges, n) = cell_edges(i, j, occ, z);
        for e in &edges[..n] {
            emit(i, j, e);
        }
        true
    };
    if cr[0] >= cr[2] || cr[1] >= cr[3] {
        return true;
    }
    match traversal {
        Traversal::Flat => {
            for j in cr[1]..cr[3] {
                for i in cr[0]..cr[2] {
                    *visited += 1;
                    if !cell(i, j) {
                        return false;
                    }
                }
            }
            true
        }
        Traversal::Hierarchical => {
            let m = &dm.mssm;
            let top = m.levels().saturating_sub(1);
            let span = (cr[2] - cr[0]).max(cr[3] - cr[1]) as u32;
            let want = 32 - (span.max(1) - 1).leading_zeros(); // ceil(log2(span))
            let l0 = want.min(top);
            let step = 1i32 << l0;
            // Padded anchors.
            let (x0, y0, x1, y1) = (cr[0] + 1, cr[1] + 1, cr[2] + 1, cr[3] + 1);
            let mut stack: Vec<(i32, i32, u32)> = Vec::with_capacity(STACK_CAPACITY);
            let mut y = y0;
            while y < y1 {
                let mut x = x0;
                while x < x1 {
                    stack.push((x, y, l0));
                    x += step;
                }
                y += step;
            }
            // Pop in the pushed order's reverse; order only changes the f64 sum.
            while let Some((x, y, l)) = stack.pop() {
                *visited += 1;
                let mm = m.fetch(l, x as u32, y as u32);
                if members.is_empty() {
                    if mm.max < t_min || !(mm.min < t_max) {
                        continue; // Fig. 6 cases 4 and 5: no contour below this node
                    }
                } else {
                    // The node's samples, unpadded: [x - 1, x - 1 + 2^l] x [y - 1, y - 1 + 2^l].
                    if planes.prunable(mm.min, mm.max, [t_min, t_max], (l, x, y), kb, kb_inner) {
                        continue;
                    }
                }
                if l == 0 {
                    if !cell(x - 1, y - 1) {
                        return false;
                    }
                    continue;
                }
                let h = 1i32 << (l - 1);
                for (dx, dy) in [(h, h), (0, h), (h, 0), (0, 0)] {
                    let (cx, cy) = (x + dx, y + dy);
                    if cx < x1 && cy < y1 {
                        stack.push((cx, cy, l - 1));
                    }
                }
            }
            true
        }
    }
}

/// The receiver-plane part of an extraction's occluder test: empty for the classic test (the
/// status from the threshold range alone, Yang eq. 3).
#[derive(Debug, Clone, Copy, Default)]
pub struct Planes<'a> {
    /// One [`OccluderTest`] per receiver the extraction serves (one for a pixel, the penumbra
    /// pixels of a packet), each with its plane; a sample is an occluder when it occludes every
    /// one, free when none, null otherwise.
    pub members: &'a [OccluderTest],
    /// The classification depths are the true depths (`self_shadow=bias`): the dual MSSM then
    /// bounds the plane test's depths too, and a node can be pruned as free from the planes'
    /// thresholds. With midpoints (classification >= true depth) the "every sample occludes"
    /// pruning may use the dual MSSM, the "none occludes" one needs [`depth`](Self::depth).
    pub class_is_depth: bool,
    /// The anchored MSSM of the true depths (the sub-view's), for the "none occludes" pruning
    /// when the classification depths are midpoints; `None`: no such pruning.
    pub depth: Option<&'a Mssm>,
    /// The affine bounds of the reciprocal true depths ([`DualFit`]): nodes on the members' own
    /// plane are proved free, and (built with minima) a lower bound on a node's true depths is
    /// one fetch instead of a [`depth`](Self::depth) query. `None`: neither.
    pub fit: Option<&'a DualFit>,
}

impl Planes<'_> {
    /// The status of sample (i, j) (true depth `zs`, classification depth `cs`) for every
    /// member; `[t_min, t_max]` the members' threshold range, `kb` the members'
    /// [`plane_threshold_range`] over the kernel holding the sample (quick answers; the same as
    /// the per-member tests, which they bound).
    #[inline]
    fn status(
        &self,
        i: i32,
        j: i32,
        zs: f32,
        cs: f32,
        [t_min, t_max]: [f32; 2],
        kb: (f32, f32),
    ) -> Status {
        if !(cs < t_max) || zs >= kb.1 {
            return Status::Free;
        }
        if cs < t_min && zs < kb.0 {
            return Status::Occluder;
        }
        let mut any = false;
        let mut all = true;
        for m in self.members {
            let o = m.occludes(i, j, zs, cs);
            any |= o;
            all &= o;
        }
        match (any, all) {
            (true, true) => Status::Occluder,
            (false, _) => Status::Free,
            _ => Status::Null,
        }
    }
    /// True when node `(l, x, y)` (padded anchor: samples `[x - 1, x - 1 + 2^l]` unpadded, likewise
    /// y), whose classification depths span `[min, max]`, holds no contour for any member: no
    /// sample occludes any member, or every sample occludes every member. Conservative (never
    /// prunes a node the per-cell tests would find a contour in).
    /// `kb`: the members' [`plane_threshold_range`] over the whole kernel (tried first, it
    /// bounds the node's).
    fn prunable(
        &self,
        min: f32,
        max: f32,
        [t_min, t_max]: [f32; 2],
        (l, x, y): (u32, i32, i32),
        kb: (f32, f32),
        kb_inner: (f32, f32),
    ) -> bool {
        if !(min < t_max) {
            return true;
        }
        // Every classification test passes, and every plane test too when the node's largest
        // true depth (at most its largest classification depth) is below every lower bound.
        let all_class = max < t_min;
        if all_class && max < kb.0 {
            return true;
        }
        if l == 0 {
            // A single cell: its evaluation costs what the bounds below would, with the same
            // answer (no contour in a prunable node).
            return false;
        }
        let s = [x - 1, y - 1, x - 1 + (1 << l), y - 1 + (1 << l)];
        let fit = || self.fit.is_some_and(|f| f.free_for(self.members, l, x, y));
        match self.depth_bounds(min, max, all_class, s, (l, x, y), kb, kb_inner) {
            Bounds::Settled => true,
            Bounds::Unsettled => fit(),
            // The own-plane proof first: it settles what the per-node range cannot.
            Bounds::NodeRange { tm, occ_possible } => {
                fit() || {
                    let (lo, hi) = plane_threshold_range(self.members, s);
                    (occ_possible && max < lo) || tm >= hi
                }
            }
        }
    }

    /// [`prunable`](Self::prunable)'s depth-bound part: the node settled by its smallest true
    /// and largest classification depth against the kernel's plane thresholds, or the node's own
    /// thresholds still to compute.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn depth_bounds(
        &self,
        min: f32,
        max: f32,
        all_class: bool,
        s: [i32; 4],
        (l, x, y): (u32, i32, i32),
        kb: (f32, f32),
        kb_inner: (f32, f32),
    ) -> Bounds {
        // The node's smallest lower bound is at most the kernel's largest (`kb_inner.0`), its
        // largest upper bound at least the kernel's smallest (`kb_inner.1`): nodes that cannot
        // pass their own tests are settled without computing them. The smallest true depth is
        // at most the classification minimum.
        let occ_possible = all_class && max < kb_inner.0;
        let free_possible = min >= kb_inner.1;
        if !occ_possible && !free_possible {
            return Bounds::Unsettled;
        }
        // No plane test passes: the node's smallest true depth reaches every upper bound.
        let tm = if !free_possible {
            f32::NEG_INFINITY
        } else {
            // With midpoints, the fit's block minimum (one fetch) before an MSSM query.
            self.fit
                .filter(|_| !self.class_is_depth)
                .and_then(|f| f.min_bound(l, x, y))
                .unwrap_or_else(|| true_min(self.class_is_depth, self.depth, min, s))
        };
        if tm >= kb.1 {
            return Bounds::Settled;
        }
        if !occ_possible && !(tm >= kb_inner.1) {
            return Bounds::Unsettled;
        }
        Bounds::NodeRange { tm, occ_possible }
    }
}

/// What the kernel-wide depth bounds say about a node ([`Planes::prunable`]).
enum Bounds {
    /// No contour: pruned.
    Settled,
    /// The node's own plane thresholds cannot settle it either.
    Unsettled,
    /// Settled when the node's own [`plane_threshold_range`] `(lo, hi)` has
    /// `occ_possible && max < lo` or `tm >= hi` (`tm` a lower bound on its true depths).
    NodeRange { tm: f32, occ_possible: bool },
}

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

/// Per-pixel GBP07 on a kernel `cr` and the light `em`: the visibility (before the receiver-facing factor) of one
/// receiver, and the nodes visited.
#[allow(clippy::too_many_arguments)]
pub fn pixel_visibility(
    grid: &SampleGrid,
    dm: &PaddedDualMssm,
    depth: Option<&Mssm>,
    fit: Option<&DualFit>,
    cr: &CellRect,
    rec: &Receiver,
    k: impl Into<Scale>,
    em: &Emitter,
    traversal: Traversal,
) -> (f32, u64) {
    let k = k.into();
    let mut sum = 0.0f64;
    let mut visited = 0u64;
    let test = [rec.test()];
    let planes = Planes {
        members: if rec.plane.is_some() { &test } else { &[] },
        class_is_depth: grid.class_is_depth(),
        depth,
        fit,
    };
    extract(
        grid,
        dm,
        cr,
        [rec.t, rec.t],
        planes,
        traversal,
        &mut visited,
        |_, _, e| {
            sum += edge_area(e, rec, k, em);
        },
    );
    (visibility_from_area(rec.centre, sum, em), visited)
}

#[cfg(test)]
mod tests;
