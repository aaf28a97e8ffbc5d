//! Own-plane pruning: a per-node affine bound of the reciprocal true depth over the padded dual
//! grid, so that the hierarchy of Yang et al. 2009 §4.2 can prove a node free of casters when it
//! lies on the receiver's own sloped surface (this crate's addition; docs/methods.md §4
//! "Own-plane pruning").
//!
//! **Why.** With receiver-plane rejection ([`shadow_map_core::receiver_plane`]) the samples of a
//! receiver's own plane are not casters, but their depths run through the receiver's depth
//! threshold inside one kernel, so a min/max depth bound can never show that a node of them holds
//! no caster: the hierarchy walks such a kernel cell by cell.
//!
//! **The bound.** In a perspective light view a sample stored in texel `u` at linear depth `z` is
//! `z d(u)`, `d(u) = (affine in u, 1)`, so on any plane the reciprocal depth `w = 1/z` is affine
//! in texel coordinates. The receiver's caster test with `g(u) > 0` and `c > 0` is
//! `(z + hs) g(u) < c`, so a sample with `z g(u) >= c`, that is `w <= g(u) / c`, is never a caster
//! (`hs >= 0`), and `g / c` is affine too. A block of samples stores `dev >= |w - F|` over its
//! samples, `F` the affine function through three of its corner samples; both sides being affine,
//! the block is free for a receiver when `F + dev <= g / c` at its four corners (with the rounding
//! margins of [`DualFit::free_for`]). On an exactly planar surface `dev` is rounding-small, so
//! whole blocks of the receiver's own plane are settled at once; the tolerance `tau` of the plane
//! test (at least `2^-16` of the receiver's distance, module docs of `receiver_plane`) is what
//! keeps them on the free side.
//!
//! **Blocks.** Level `m >= 2` holds the blocks of side `2^m` (padded samples `[x, x + 2^m]`) at
//! anchors on a stride of `2^(m-1)` (half-overlapping), so any traversal node of side `2^l`,
//! `l >= 1`, at any anchor `x` lies inside the level-`(l + 1)` block at anchor
//! `2^l floor(x / 2^l)`: a block proved free proves every node inside it free. Level 1 (side 2,
//! stride 2) only feeds level 2; single cells (traversal level 0) are evaluated, which costs what
//! a proof would. The levels cost about `2/3 (r + 2)^2` values per plane, where blocks at every
//! anchor of every level (the dual MSSM's layout) would cost `levels (r + 2)^2`.
//!
//! **Build.** Level 1, `dev = max |w - F|` over the block's 3 x 3 samples; a block from its four
//! half-size children `C` (level `m - 1`, anchors offset by `{0, 2^(m-1)}`) by the triangle
//! inequality
//! `dev_P = max_C (dev_C + max over C's corners |F_C - F_P|)` (an affine difference: its
//! extreme over C is at C's corners). Blocks reaching past the padded grid store `+inf`.
use crate::math::contour::OccluderTest;
use rayon::prelude::*;

/// Relative margin of [`DualFit::free_for`] on the f32 caster test's slope and product.
const F32_MARGIN: f64 = 1.0 / 1_048_576.0;
/// Relative allowance for the f32 rounding of `w = 1/z` (2^-24) and the f64 rounding of the build
/// and of the query's affine evaluation.
const W_SLACK: f64 = 1.0 / 4_194_304.0;

/// One level: the deviation bound of every block, and (with midpoints) the smallest true depth of
/// its samples; `q x q` blocks, row-major, block `(k, j)` at padded anchor `(k, j) * stride`.
#[derive(Debug, Clone)]
struct Level {
    /// `log2` of the anchor stride (indices by shifts: this runs per block).
    shift: u32,
    q: usize,
    dev: Vec<f32>,
    zmin: Option<Vec<f32>>,
}

/// The affine deviation bounds of the reciprocal true depths over blocks of the padded dual grid
/// (module docs), with the padding of [`crate::cpu::extract::PaddedDualMssm`].
#[derive(Debug, Clone)]
pub struct DualFit {
    /// Padded side `r + 2`.
    p: usize,
    /// Padded reciprocal true depths, rounded to f32 (0 for empty samples and the padding ring).
    /// The bounds hold for these values; the query's slack covers their distance (2^-24
    /// relative) from the exact `1/z`.
    w: Vec<f32>,
    levels: Vec<Level>,
}

/// A non-negative `f64` bound as an `f32` no smaller (round to nearest loses at most 2^-24 of it).
#[inline]
fn up(d: f64) -> f32 {
    (d * (1.0 + 1.0 / 4_194_304.0)) as f32
}

/// The reciprocal depth a block's bound is built on: `1/z`, 0 for empty (`+inf`) samples, and
/// `f32::MAX` for depths that are not positive or NaN (the f32 caster test calls them casters, so
/// no block holding one can be proved free; the build stays finite).
#[inline]
fn recip(z: f32) -> f32 {
    if z > 0.0 {
        (1.0 / z).min(f32::MAX)
    } else {
        f32::MAX
    }
}

/// `dev` of a block from its four children's `dc` (order (0,0), (h,0), (0,h), (h,h)) and the
/// reciprocal depths `q[b][a]` on the lattice of its children's corners, offsets
/// `(a h, b h)` (module docs). With `F_P` through `q[0][0]`, `q[0][2]`, `q[2][0]` and
/// `r = q - F_P` on the lattice, `F_C - F_P` is the affine function through `r` at a child's
/// first three corners, so its extreme over the child is the largest of those three and
/// `r(a+1, b) + r(a, b+1) - r(a, b)` at the fourth.
#[inline]
fn parent_dev(q: [[f64; 3]; 3], dc: [f32; 4]) -> f64 {
    let (w0, du, dv) = (q[0][0], q[0][2] - q[0][0], q[2][0] - q[0][0]);
    let r = |a: usize, b: usize| q[b][a] - (w0 + 0.5 * a as f64 * du + 0.5 * b as f64 * dv);
    let mut dev = 0.0f64;
    for (k, (a, b)) in [(0usize, 0usize), (1, 0), (0, 1), (1, 1)]
        .into_iter()
        .enumerate()
    {
        let (r0, r1, r3) = (r(a, b), r(a + 1, b), r(a, b + 1));
        let e = r0
            .abs()
            .max(r1.abs())
            .max(r3.abs())
            .max((r1 + r3 - r0).abs());
        dev = dev.max(dc[k] as f64 + e);
    }
    dev
}

impl DualFit {
    /// Builds levels `0..levels` over the true depths `depth` (`r x r`, row-major; a short slice
    /// leaves the missing samples empty). `with_min` also stores each block's smallest true depth
    /// ([`min_bound`](Self::min_bound)), for classification depths that are not the true depths.
    /// A traversal over dual-MSSM levels `0..L` needs `L + 1` levels here.
    pub fn build(depth: &[f32], r: u32, levels: u32, with_min: bool) -> DualFit {
        let p = r as usize + 2;
        let mut z = vec![f32::INFINITY; p * p];
        for (j, row) in depth.chunks(r as usize).take(r as usize).enumerate() {
            z[(j + 1) * p + 1..(j + 1) * p + 1 + row.len()].copy_from_slice(row);
        }
        let w: Vec<f32> = z.iter().map(|&d| recip(d)).collect();
        // Level 0 (single cells) is never queried: a cell costs what its proof would.
        let mut out: Vec<Level> = vec![Level {
            shift: 0,
            q: 0,
            dev: Vec::new(),
            zmin: None,
        }];
        for m in 1..levels as usize {
            let n = 1usize << m; // block side in samples
                                 // Level 1 only feeds level 2, whose children sit on even anchors.
            let shift = if m == 1 { 1 } else { m as u32 - 1 };
            let stride = 1usize << shift;
            let q = p.div_ceil(stride);
            let prev = &out[m - 1];
            let wa = |yy: usize, xx: usize| w[yy * p + xx] as f64;
            let mut dev = vec![f32::INFINITY; q * q];
            dev.par_chunks_mut(q).enumerate().for_each(|(j, row)| {
                let y = j * stride;
                if y + n >= p {
                    return;
                }
                for (k, d) in row.iter_mut().enumerate() {
                    let x = k * stride;
                    if x + n >= p {
                        break;
                    }
                    *d = if m == 1 {
                        // F through (0, 0), (2, 0), (0, 2); the other six samples' distances.
                        let (w0, w1, w3) = (wa(y, x), wa(y, x + 2), wa(y + 2, x));
                        let (du, dv) = (0.5 * (w1 - w0), 0.5 * (w3 - w0));
                        let mut e = 0.0f64;
                        for (a, b) in [(1usize, 0usize), (0, 1), (1, 1), (2, 1), (1, 2), (2, 2)] {
                            let f = w0 + a as f64 * du + b as f64 * dv;
                            e = e.max((wa(y + b, x + a) - f).abs());
                        }
                        up(e)
                    } else {
                        let h = n / 2;
                        let ci = |xx: usize, yy: usize| {
                            prev.dev[(yy >> prev.shift) * prev.q + (xx >> prev.shift)]
                        };
                        let lat = |b: usize| {
                            let yy = y + b * h;
                            [wa(yy, x), wa(yy, x + h), wa(yy, x + n)]
                        };
                        up(parent_dev(
                            [lat(0), lat(1), lat(2)],
                            [ci(x, y), ci(x + h, y), ci(x, y + h), ci(x + h, y + h)],
                        ))
                    };
                }
            });
            let zmin = with_min.then(|| {
                // Level 1 from its 3 x 3 samples, level m from its four children (clamped to
                // the padded grid).
                let (offs, h): (&[(usize, usize)], usize) = if m == 1 {
                    (
                        &[
                            (0, 0),
                            (1, 0),
                            (2, 0),
                            (0, 1),
                            (1, 1),
                            (2, 1),
                            (0, 2),
                            (1, 2),
                            (2, 2),
                        ],
                        1,
                    )
                } else {
                    (&[(0, 0), (1, 0), (0, 1), (1, 1)], n / 2)
                };
                let (src, ss, sq): (&[f32], u32, usize) = match &prev.zmin {
                    Some(pm) if m > 1 => (pm, prev.shift, prev.q),
                    _ => (&z, 0, p),
                };
                let mut zm = vec![f32::INFINITY; q * q];
                zm.par_chunks_mut(q).enumerate().for_each(|(j, row)| {
                    let y = j * stride;
                    for (k, o) in row.iter_mut().enumerate() {
                        let x = k * stride;
                        for &(a, b) in offs {
                            let (xx, yy) = (x + a * h, y + b * h);
                            if xx < p && yy < p {
                                *o = o.min(src[(yy >> ss) * sq + (xx >> ss)]);
                            }
                        }
                    }
                });
                zm
            });
            out.push(Level {
                shift,
                q,
                dev,
                zmin,
            });
        }
        DualFit { p, w, levels: out }
    }

    /// Number of levels built.
    pub fn levels(&self) -> u32 {
        self.levels.len() as u32
    }

    /// The level-`(l + 1)` block holding traversal node `(l, x, y)` (padded anchor, samples
    /// `[x, x + 2^l]^2`): `(level, block index, block anchor)`.
    #[inline]
    fn container(&self, l: u32, x: i32, y: i32) -> Option<(&Level, usize, (usize, usize))> {
        if l == 0 {
            return None; // single cells are evaluated, not proved
        }
        let lv = self.levels.get(l as usize + 1)?;
        let (x, y) = (usize::try_from(x).ok()?, usize::try_from(y).ok()?);
        let (k, j) = (x >> lv.shift, y >> lv.shift);
        if k >= lv.q || j >= lv.q {
            return None;
        }
        Some((lv, j * lv.q + k, (k << lv.shift, j << lv.shift)))
    }

    /// A lower bound on the true depths of traversal node `(l, x, y)` (padded anchor, samples
    /// `[x, x + 2^l]^2`): the smallest true depth of the block holding it, when built
    /// `with_min`.
    #[inline]
    pub fn min_bound(&self, l: u32, x: i32, y: i32) -> Option<f32> {
        let (lv, i, _) = self.container(l, x, y)?;
        lv.zmin.as_ref().map(|m| m[i])
    }

    /// True when traversal node `(l, x, y)` (padded anchor, samples `[x, x + 2^l]^2`) holds no
    /// caster for any of `members`, proved on the block holding it: every member has a receiver
    /// plane with `c > 0`, and at each of the block's corner texel centres
    /// `F + dev + 2^-22 (|w| + dev)` is at most `g_lo / (c (1 + 2^-20))`, `g_lo` the slope lowered
    /// by `2^-20` of its terms' magnitudes (f32 evaluation of [`ReceiverPlane::slope_at`]) and
    /// positive. Then for every sample `z g32 >= c (1 + 2^-20)` and the f32 test
    /// `(z + hs) g32 < c` fails (module docs).
    ///
    /// [`ReceiverPlane::slope_at`]: shadow_map_core::ReceiverPlane::slope_at
    pub fn free_for(&self, members: &[OccluderTest], l: u32, x: i32, y: i32) -> bool {
        let Some((lv, i, (x, y))) = self.container(l, x, y) else {
            return false;
        };
        let dev = lv.dev[i] as f64;
        if !(dev < f64::INFINITY) {
            return false;
        }
        let (p, n) = (self.p, 2usize << lv.shift);
        let k = y * p + x;
        let (w0, w1, w3) = (
            self.w[k] as f64,
            self.w[k + n] as f64,
            self.w[k + n * p] as f64,
        );
        let w2 = w1 + w3 - w0;
        let scale = w0.abs().max(w1.abs()).max(w3.abs()) + dev;
        let lift = dev + W_SLACK * scale;
        // Corner texel centres, unpadded: padded sample x is texel x - 1, centre x - 1/2.
        let (u0, v0) = (x as f64 - 0.5, y as f64 - 0.5);
        let (u1, v1) = (u0 + n as f64, v0 + n as f64);
        let corners = [(u0, v0, w0), (u1, v0, w1), (u0, v1, w3), (u1, v1, w2)];
        members.iter().all(|m| {
            let Some(pl) = m.plane.as_ref() else {
                return false;
            };
            let c = pl.c as f64;
            if !(c > 0.0) {
                return false;
            }
            let (g0, gu, gv) = (pl.g0 as f64, pl.gu as f64, pl.gv as f64);
            let cm = c * (1.0 + F32_MARGIN);
            // `f + lift <= g / cm` with `cm > 0`, multiplied out.
            corners.iter().all(|&(u, v, f)| {
                let (tu, tv) = (gu * u, gv * v);
                let g = g0 + tu + tv - F32_MARGIN * (g0.abs() + tu.abs() + tv.abs());
                g > 0.0 && (f + lift) * cm <= g
            })
        })
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.w.len() * 4
            + self
                .levels
                .iter()
                .map(|l| 4 * (l.dev.len() + l.zmin.as_ref().map_or(0, Vec::len)))
                .sum::<usize>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use shadow_map_core::{LightView, ReceiverPlane};

    /// A view down the world's z axis (window [-1, 1]^2, near 0.5, far 40).
    fn view(r: u32) -> LightView {
        LightView {
            n: 0.5,
            far: 40.0,
            ..LightView::placeholder(r)
        }
    }

    /// Depths of the plane through `p` with normal `n` at every texel centre (inf where the ray
    /// misses it on the far side).
    fn plane_depths(v: &LightView, p: Vec3, n: Vec3) -> Vec<f32> {
        let r = v.r;
        let s = v.delta() / v.n;
        let o = v.window_min / v.n;
        let mut d = vec![f32::INFINITY; (r * r) as usize];
        for j in 0..r {
            for i in 0..r {
                let dir = Vec3::new((i as f32 + 0.5) * s + o.x, (j as f32 + 0.5) * s + o.y, 1.0);
                let z = n.dot(p) / n.dot(dir);
                if z > 0.0 && z.is_finite() {
                    d[(j * r + i) as usize] = z;
                }
            }
        }
        d
    }

    fn test_of(v: &LightView, p: Vec3, n: Vec3) -> OccluderTest {
        OccluderTest {
            t: p.z,
            plane: Some(ReceiverPlane::plane(v, p, n, 0.0, 0.0)),
        }
    }

    /// Brute force: no sample of node (l, x, y) is a caster for `m`.
    fn node_free(d: &[f32], r: u32, m: &OccluderTest, l: u32, x: i32, y: i32) -> bool {
        let n = 1 << l;
        let pl = m.plane.unwrap();
        for b in 0..=n {
            for a in 0..=n {
                let (i, j) = (x - 1 + a, y - 1 + b);
                if i < 0 || j < 0 || i >= r as i32 || j >= r as i32 {
                    continue;
                }
                if pl.caster(i, j, d[(j as u32 * r + i as u32) as usize]) {
                    return false;
                }
            }
        }
        true
    }

    /// A receiver on a plane lit at 60 to 89 degrees proves whole high-level nodes of its own
    /// plane free; no node it proves free holds a caster (brute force), with bumps lifted off the
    /// plane by 1e-3 of their depth.
    #[test]
    fn own_plane_nodes_prove_free_and_casters_never_do() {
        let r = 128u32;
        let v = view(r);
        for deg in [60.0f32, 75.0, 85.0, 89.0] {
            let t = deg.to_radians();
            // Light looks down +z; the plane's normal tilts from -z by `deg`.
            let n = Vec3::new(t.sin(), 0.0, -t.cos()).normalize();
            let p = Vec3::new(0.0, 0.0, 10.0);
            let mut d = plane_depths(&v, p, n);
            let fit = DualFit::build(&d, r, 8, true);
            // Receivers on the plane (which the rays with x > 1/tan(deg) do not meet).
            let rec: Vec<OccluderTest> = [(-0.3f32, 0.1f32), (-1.2, -0.2), (-0.6, 0.3)]
                .iter()
                .map(|&(a, b)| {
                    let dir = Vec3::new(a, b, 1.0);
                    let z = n.dot(p) / n.dot(dir);
                    test_of(&v, dir * z, n)
                })
                .collect();
            let mut proved = 0;
            // Nodes whose blocks lie on the visible part of the plane (texels i < 64) and off the
            // padding ring.
            for l in [2u32, 3, 4] {
                for (x, y) in [(17, 20), (20, 40), (30, 70)] {
                    let ok = fit.free_for(&rec, l, x, y);
                    if ok {
                        proved += 1;
                    }
                }
            }
            assert_eq!(proved, 9, "{deg} deg: own-plane nodes proved free");
            // Bumps: samples nearer than the plane by 1e-3 z are casters; no node holding one
            // may be proved free.
            for k in [(30u32, 30u32), (70, 33), (100, 90)] {
                let i = (k.1 * r + k.0) as usize;
                d[i] *= 0.999;
            }
            let fit = DualFit::build(&d, r, 8, true);
            for l in 0..7 {
                for y in (0..(r as i32 + 2)).step_by(3) {
                    for x in (0..(r as i32 + 2)).step_by(5) {
                        for m in &rec {
                            if fit.free_for(std::slice::from_ref(m), l, x, y) {
                                assert!(
                                    node_free(&d, r, m, l, x, y),
                                    "{deg} deg: node ({l}, {x}, {y}) proved free holds a caster"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// `min_bound` is at most the brute-force minimum of every node's samples, and exactly that
    /// of the block holding it.
    #[test]
    fn min_bound_bounds_every_node() {
        let r = 20u32;
        let d: Vec<f32> = (0..r * r).map(|k| 1.0 + ((k * 37) % 101) as f32).collect();
        let fit = DualFit::build(&d, r, 5, true);
        let brute = |x: i32, y: i32, n: i32| {
            let mut m = f32::INFINITY;
            for b in 0..=n {
                for a in 0..=n {
                    let (i, j) = (x - 1 + a, y - 1 + b);
                    if i >= 0 && j >= 0 && i < r as i32 && j < r as i32 {
                        m = m.min(d[(j * r as i32 + i) as usize]);
                    }
                }
            }
            m
        };
        for l in 1..4u32 {
            let n = 1 << l;
            for y in 0..(r as i32 + 2) {
                for x in 0..(r as i32 + 2) {
                    let got = fit.min_bound(l, x, y).unwrap();
                    assert!(got <= brute(x, y, n), "({l}, {x}, {y})");
                    let (bx, by) = (n * (x / n), n * (y / n));
                    assert_eq!(got, brute(bx, by, 2 * n), "({l}, {x}, {y})");
                }
            }
        }
    }
}
