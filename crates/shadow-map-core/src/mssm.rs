//! Min/max acceleration structures over a square depth map.
//!
//! All structures in this module are built from a square depth map `D` of
//! *linear light-space depths*: `size x size` `f32` values in row-major order,
//! texel `(x, y)` stored at index `y * size + x`.
//!
//! # Empty texels
//!
//! Texels that saw no geometry hold `f32::INFINITY`. They take part in the
//! min/max like any other depth, so a window containing only empty texels
//! has `min = max = +inf`, and a window mixing geometry and empty texels has
//! `max = +inf`. `NaN` depths are treated as empty (`+inf`) everywhere,
//! including [`brute_force`], so every structure stays consistent with it.
//!
//! # Degenerate inputs (no panics)
//!
//! * If `depth.len() != size * size`, missing texels are treated as empty
//!   and surplus values are ignored.
//! * If `size * size` texels cannot even be addressed in memory
//!   (`size * size * 4` overflows `isize`), the structure is built with
//!   `size() == 0`. Every query on a size-0 structure returns
//!   [`MinMax::EMPTY`].
//! * Query rectangles are *clamped* to the map; a rectangle that is empty
//!   after clamping (zero or negative width/height, or entirely outside)
//!   returns [`MinMax::EMPTY`] (`min = +inf, max = -inf`), the identity of
//!   [`MinMax::union`]. Nothing in this module returns `Option` for an empty
//!   rectangle except [`MinMaxPyramid::covered_rect`].
//! * Single-texel fetches with an out-of-range level or coordinate return
//!   [`MinMax::EMPTY`]; level slices with an out-of-range level are empty.
//!
//! # Structures
//!
//! * [`Mssm`]: the anchored multi-scale shadow map of Schwarz & Stamminger
//!   (2007), i.e. an N-buffer (Décoret 2005) that stores min *and* max.
//!   Exact rectangle queries with at most 4 fetches for square windows.
//! * [`DualMssm`]: the same construction on the dual grid of depth samples
//!   (Yang et al. 2009, §4.2): level 0 covers the 2x2 samples of one dual
//!   cell.
//! * [`MinMaxPyramid`]: the hierarchical min/max mip chain of Dmitriev &
//!   Uralsky (2007); 4/3 the memory of the depth map, conservative queries.
//!
//! References:
//!
//! * M. Schwarz, M. Stamminger. *Bitmask Soft Shadows*. Computer Graphics
//!   Forum 26(3) (Eurographics 2007).
//! * X. Décoret. *N-Buffers for efficient depth map query*. Computer
//!   Graphics Forum 24(3) (Eurographics 2005).
//! * B. Yang, J. Feng, G. Guennebaud, X. Liu. *Packet-based Hierarchical
//!   Soft Shadow Mapping*. Computer Graphics Forum 28(4) (EGSR 2009), §4.2.
//! * K. Dmitriev, Y. Uralsky. *Soft shadows using hierarchical min-max
//!   shadow maps*. Game Developers Conference 2007.
#![deny(missing_docs)]

use rayon::prelude::*;

/// A depth interval `[min, max]` over a set of texels.
///
/// A single texel of depth `d` is `MinMax { min: d, max: d }` (see
/// [`MinMax::from_depth`]); an empty texel (`d = +inf`) therefore gives
/// `min = max = +inf`. The union of sets is the component-wise
/// `(min(a.min, b.min), max(a.max, b.max))`, whose identity is
/// [`MinMax::EMPTY`] (`min = +inf, max = -inf`), the value of the empty set
/// of texels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MinMax {
    /// Smallest depth of the set (`+inf` if the set is empty or holds only
    /// empty texels).
    pub min: f32,
    /// Largest depth of the set (`-inf` for the empty set, `+inf` if any
    /// texel of the set is empty).
    pub max: f32,
}

impl MinMax {
    /// The empty set of texels: `min = +inf, max = -inf`, identity of
    /// [`MinMax::union`].
    pub const EMPTY: MinMax = MinMax {
        min: f32::INFINITY,
        max: f32::NEG_INFINITY,
    };

    /// Returns [`MinMax::EMPTY`].
    #[inline]
    pub const fn empty() -> Self {
        Self::EMPTY
    }

    /// The interval of a single texel of depth `d` (`min = max = d`).
    /// `NaN` is treated as an empty texel (`+inf`).
    #[inline]
    pub fn from_depth(d: f32) -> Self {
        let d = sanitize(d);
        MinMax { min: d, max: d }
    }

    /// Union of two texel sets: `(min(a.min, b.min), max(a.max, b.max))`.
    #[inline]
    #[must_use]
    pub fn union(self, other: MinMax) -> MinMax {
        MinMax {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// `true` for the empty set of texels (`min > max`, e.g.
    /// [`MinMax::EMPTY`]). A window of empty texels (`+inf/+inf`) is *not*
    /// empty in this sense.
    #[inline]
    pub fn is_empty(&self) -> bool {
        // NaN components also count as empty.
        self.min > self.max || self.min.is_nan() || self.max.is_nan()
    }

    /// `true` if the set holds no finite depth, i.e. it is empty or made of
    /// empty texels only (`min == +inf`).
    #[inline]
    pub fn is_unoccupied(&self) -> bool {
        self.min == f32::INFINITY
    }

    /// `true` if `self` is a conservative bound of `other`:
    /// `self.min <= other.min && self.max >= other.max`. Every interval
    /// contains [`MinMax::EMPTY`].
    #[inline]
    pub fn contains(&self, other: &MinMax) -> bool {
        self.min <= other.min && self.max >= other.max
    }
}

impl Default for MinMax {
    /// [`MinMax::EMPTY`].
    fn default() -> Self {
        Self::EMPTY
    }
}

/// Maps NaN to an empty texel (`+inf`).
#[inline]
fn sanitize(d: f32) -> f32 {
    if d.is_nan() {
        f32::INFINITY
    } else {
        d
    }
}

/// Number of texels of a `size x size` map, or `None` if its `f32` storage
/// could not be addressed (`size * size * 4 > isize::MAX`).
fn texel_count(size: u32) -> Option<usize> {
    let s = usize::try_from(size).ok()?;
    let n = s.checked_mul(s)?;
    let bytes = n.checked_mul(std::mem::size_of::<f32>())?;
    if bytes > isize::MAX as usize {
        None
    } else {
        Some(n)
    }
}

/// Level 0 of every structure: `size x size` sanitized depths (missing
/// texels empty, surplus ignored). Returns `(size, texels)`, with size 0 if
/// the map is not addressable.
fn sanitized_level0(depth: &[f32], size: u32) -> (usize, Vec<f32>) {
    let Some(n) = texel_count(size) else {
        return (0, Vec::new());
    };
    let s = size as usize;
    let mut out = vec![f32::INFINITY; n];
    if s > 0 {
        out.par_chunks_mut(s).enumerate().for_each(|(y, row)| {
            let start = y * s;
            let src = depth.get(start..).unwrap_or(&[]);
            for (dst, &d) in row.iter_mut().zip(src.iter()) {
                *dst = sanitize(d);
            }
        });
    }
    (s, out)
}

/// `floor(log2(n))` for `n >= 1`; 0 for `n == 0`.
#[inline]
fn floor_log2(n: usize) -> u32 {
    if n == 0 {
        0
    } else {
        usize::BITS - 1 - n.leading_zeros()
    }
}

/// `ceil(log2(n))` for `n >= 1`; 0 for `n <= 1`.
#[inline]
fn ceil_log2(n: usize) -> u32 {
    if n <= 1 {
        0
    } else {
        floor_log2(n - 1) + 1
    }
}

/// Clamps the half-open rectangle `[x0, x1) x [y0, y1)` to `[0, size)^2`.
/// Returns `None` if it is empty after clamping.
fn clamp_rect(size: usize, x0: i32, y0: i32, x1: i32, y1: i32) -> Option<[usize; 4]> {
    let s = i64::try_from(size).unwrap_or(i64::MAX);
    let c = |v: i32| (v as i64).clamp(0, s) as usize;
    let (x0, y0, x1, y1) = (c(x0), c(y0), c(x1), c(y1));
    if x0 < x1 && y0 < y1 {
        Some([x0, y0, x1, y1])
    } else {
        None
    }
}

/// Start positions `lo, lo + h, lo + 2h, ... (< hi - h), hi - h` of windows
/// of width `h` that exactly tile `[lo, hi)` (the last one may overlap its
/// predecessor). Requires `1 <= h <= hi - lo`.
#[inline]
fn window_starts(lo: usize, hi: usize, h: usize) -> impl Iterator<Item = usize> + Clone {
    let h = h.max(1);
    let last = hi.saturating_sub(h).max(lo);
    (lo..last).step_by(h).chain(std::iter::once(last))
}

/// Number of items [`window_starts`] yields.
#[inline]
fn window_start_count(lo: usize, hi: usize, h: usize) -> u64 {
    let h = h.max(1);
    let last = hi.saturating_sub(h).max(lo);
    ((last - lo).div_ceil(h) + 1) as u64
}

/// Brute-force min/max over the half-open texel rectangle
/// `[x0, x1) x [y0, y1)` of `depth` (`size x size`, row-major), clamped to
/// the map. Returns [`MinMax::EMPTY`] if the rectangle is empty after
/// clamping. Texels beyond `depth.len()` and `NaN`s count as empty (`+inf`).
///
/// This is the reference every other structure is tested against; its cost
/// is proportional to the clamped area.
pub fn brute_force(depth: &[f32], size: u32, x0: i32, y0: i32, x1: i32, y1: i32) -> MinMax {
    let Ok(s) = usize::try_from(size) else {
        return MinMax::EMPTY;
    };
    let Some([x0, y0, x1, y1]) = clamp_rect(s, x0, y0, x1, y1) else {
        return MinMax::EMPTY;
    };
    let mut acc = MinMax::EMPTY;
    for y in y0..y1 {
        for x in x0..x1 {
            let d = y
                .checked_mul(s)
                .and_then(|r| r.checked_add(x))
                .and_then(|i| depth.get(i).copied())
                .unwrap_or(f32::INFINITY);
            acc = acc.union(MinMax::from_depth(d));
        }
    }
    acc
}

/// One anchored doubling step, shared by [`Mssm`] and [`DualMssm`]:
///
/// `out(x, y) = union(src(x, y), src(x+h, y), src(x, y+h), src(x+h, y+h))`,
/// fetches outside `[0, s)^2` skipped. Parallel over rows.
fn anchored_step(src_min: &[f32], src_max: &[f32], s: usize, h: usize) -> (Vec<f32>, Vec<f32>) {
    let n = s * s;
    let mut out_min = vec![f32::INFINITY; n];
    let mut out_max = vec![f32::NEG_INFINITY; n];
    if s == 0 || src_min.len() < n || src_max.len() < n {
        return (out_min, out_max);
    }
    // Columns x < split have an in-map right neighbour x + h.
    let split = s.saturating_sub(h);
    out_min
        .par_chunks_mut(s)
        .zip(out_max.par_chunks_mut(s))
        .enumerate()
        .for_each(|(y, (omin, omax))| {
            // Row y: out = union(src(x, y), src(x + h, y)).
            let amin = &src_min[y * s..(y + 1) * s];
            let amax = &src_max[y * s..(y + 1) * s];
            for x in 0..split {
                omin[x] = amin[x].min(amin[x + h]);
                omax[x] = amax[x].max(amax[x + h]);
            }
            omin[split..].copy_from_slice(&amin[split..]);
            omax[split..].copy_from_slice(&amax[split..]);
            // Row y + h (if inside the map): out ∪= union(src(x, y+h), src(x+h, y+h)).
            let r = y + h;
            if r < s {
                let bmin = &src_min[r * s..(r + 1) * s];
                let bmax = &src_max[r * s..(r + 1) * s];
                for x in 0..split {
                    omin[x] = omin[x].min(bmin[x].min(bmin[x + h]));
                    omax[x] = omax[x].max(bmax[x].max(bmax[x + h]));
                }
                for x in split..s {
                    omin[x] = omin[x].min(bmin[x]);
                    omax[x] = omax[x].max(bmax[x]);
                }
            }
        });
    (out_min, out_max)
}

/// Storage of one full-resolution level: separate `min` and `max` planes,
/// each `size x size` row-major. `max == None` means the max plane is the
/// min plane (level 0 of [`Mssm`], where both equal the depth map).
#[derive(Clone, Debug)]
struct Planes {
    min: Vec<f32>,
    max: Option<Vec<f32>>,
}

impl Planes {
    #[inline]
    fn min(&self) -> &[f32] {
        &self.min
    }
    #[inline]
    fn max(&self) -> &[f32] {
        self.max.as_deref().unwrap_or(&self.min)
    }
    #[inline]
    fn get(&self, i: usize) -> MinMax {
        match (self.min().get(i), self.max().get(i)) {
            (Some(&min), Some(&max)) => MinMax { min, max },
            _ => MinMax::EMPTY,
        }
    }
    fn bytes(&self) -> usize {
        (self.min.len() + self.max.as_ref().map_or(0, Vec::len)) * std::mem::size_of::<f32>()
    }
}

/// Anchored multi-scale shadow map (MSSM) with min *and* max per texel.
///
/// Introduced by Schwarz & Stamminger (2007, *Bitmask Soft Shadows*) as a
/// min/max variant of Décoret's N-buffers (2005). Every level is full
/// resolution (`size x size`). Level `l` stores, for every texel `(x, y)`,
///
/// ```text
/// M_l(x, y) = ( min D(u, v), max D(u, v) )   over (u, v) in W_l(x, y)
/// W_l(x, y) = [x, min(x + 2^l, N)) x [y, min(y + 2^l, N))
/// ```
///
/// i.e. the `2^l x 2^l` window *anchored* at its top-left texel, clamped to
/// the map border (`N = size`). It is built by the recursion
///
/// ```text
/// M_0 = D
/// M_{l+1}(x, y) = M_l(x, y) ∪ M_l(x+h, y) ∪ M_l(x, y+h) ∪ M_l(x+h, y+h),  h = 2^l
/// ```
///
/// where fetches outside the map are skipped (identity [`MinMax::EMPTY`]).
///
/// Any half-open rectangle of width `W` and height `H` is answered exactly
/// with windows of level `l = min(floor(log2(min(W, H))), levels - 1)`
/// placed at `x0, x0 + h, ..., x1 - h` (same for `y`): one fetch for a
/// power-of-two square (if that level was built), at most 4 for any square.
///
/// Storage: one `min` and one `max` plane (`Vec<f32>`, `size x size`,
/// row-major) per level, except level 0, where both equal the depth map and
/// are stored once. Memory: `(2 * levels - 1) * size^2 * 4` bytes.
#[derive(Clone, Debug)]
pub struct Mssm {
    size: usize,
    levels: Vec<Planes>,
}

impl Mssm {
    /// Builds levels `0..=max_level`, with `max_level` clamped to
    /// `floor(log2(size))`. Rows of each level are computed in parallel
    /// (rayon). See the [module docs](self) for length mismatches, `NaN`s
    /// and `size == 0` (no levels).
    pub fn build(depth: &[f32], size: u32, max_level: u32) -> Mssm {
        let (s, d) = sanitized_level0(depth, size);
        if s == 0 {
            return Mssm {
                size: 0,
                levels: Vec::new(),
            };
        }
        let top = max_level.min(floor_log2(s));
        let mut levels = Vec::with_capacity(top as usize + 1);
        levels.push(Planes { min: d, max: None });
        for l in 0..top {
            let h = 1usize << l;
            let Some(prev) = levels.last() else { break };
            let (min, max) = anchored_step(prev.min(), prev.max(), s, h);
            levels.push(Planes {
                min,
                max: Some(max),
            });
        }
        Mssm { size: s, levels }
    }

    /// Number of levels built (`min(max_level, floor(log2(size))) + 1`, or 0
    /// for `size == 0`).
    pub fn levels(&self) -> u32 {
        self.levels.len() as u32
    }

    /// Side length of the map (0 if the map could not be built).
    pub fn size(&self) -> u32 {
        self.size as u32
    }

    /// The `(min, max)` planes of level `l`, each `size x size` row-major
    /// (for level 0 both slices are the depth map). Empty slices if `l` is
    /// out of range.
    pub fn level(&self, l: u32) -> (&[f32], &[f32]) {
        match self.levels.get(l as usize) {
            Some(p) => (p.min(), p.max()),
            None => (&[], &[]),
        }
    }

    /// `M_l(x, y)`: min/max over `[x, x+2^l) x [y, y+2^l)` clamped to the
    /// map. [`MinMax::EMPTY`] if `l`, `x` or `y` is out of range.
    pub fn fetch(&self, l: u32, x: u32, y: u32) -> MinMax {
        let (x, y) = (x as usize, y as usize);
        match self.levels.get(l as usize) {
            Some(p) if x < self.size && y < self.size => p.get(y * self.size + x),
            _ => MinMax::EMPTY,
        }
    }

    /// Level used for a clamped rectangle, and its window size `h = 2^l`.
    #[inline]
    fn query_level(&self, r: &[usize; 4]) -> (usize, usize) {
        let m = (r[2] - r[0]).min(r[3] - r[1]);
        let l = floor_log2(m).min(self.levels().saturating_sub(1)) as usize;
        (l, 1usize << l)
    }

    /// Exact min/max over the half-open rectangle `[x0, x1) x [y0, y1)`,
    /// clamped to the map; [`MinMax::EMPTY`] if empty after clamping.
    ///
    /// Uses level `l = min(floor(log2(min(W, H))), levels - 1)`, `h = 2^l`,
    /// and unions the windows anchored at `x0, x0 + h, ..., x1 - h` times
    /// `y0, y0 + h, ..., y1 - h` (the last window of each axis always starts
    /// at `x1 - h`, so the tiling is exact). See [`Mssm::fetch_count`].
    pub fn query(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> MinMax {
        let Some(r) = clamp_rect(self.size, x0, y0, x1, y1) else {
            return MinMax::EMPTY;
        };
        let (l, h) = self.query_level(&r);
        let Some(p) = self.levels.get(l) else {
            return MinMax::EMPTY;
        };
        let xs = window_starts(r[0], r[2], h);
        let mut acc = MinMax::EMPTY;
        for y in window_starts(r[1], r[3], h) {
            let row = y * self.size;
            for x in xs.clone() {
                acc = acc.union(p.get(row + x));
            }
        }
        acc
    }

    /// Number of level fetches [`Mssm::query`] performs for this rectangle
    /// (0 if it is empty after clamping; saturates at `u32::MAX`).
    pub fn fetch_count(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> u32 {
        let Some(r) = clamp_rect(self.size, x0, y0, x1, y1) else {
            return 0;
        };
        if self.levels.is_empty() {
            return 0;
        }
        let (_, h) = self.query_level(&r);
        let n = window_start_count(r[0], r[2], h).saturating_mul(window_start_count(r[1], r[3], h));
        u32::try_from(n).unwrap_or(u32::MAX)
    }

    /// Heap bytes used by the level planes.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(Planes::bytes).sum()
    }
}

/// Dual-grid anchored MSSM (Yang et al. 2009, *Packet-based Hierarchical
/// Soft Shadow Mapping*, §4.2).
///
/// Depth samples are treated as the *vertices* of a dual grid; the dual cell
/// anchored at sample `(x, y)` spans samples `(x..=x+1, y..=y+1)`. Level `l`
/// covers the `2^l x 2^l` dual cells anchored in `[x, x+2^l) x [y, y+2^l)`,
/// i.e. the inclusive sample window
///
/// ```text
/// S_l(x, y) = [x, x + 2^l] x [y, y + 2^l]   (∩ [0, N)^2)
/// Y_l(x, y) = ( min D(u, v), max D(u, v) )  over (u, v) in S_l(x, y)
/// ```
///
/// built by
///
/// ```text
/// Y_0(x, y)     = D(x, y) ∪ D(x+1, y) ∪ D(x, y+1) ∪ D(x+1, y+1)
/// Y_{l+1}(x, y) = Y_l(x, y) ∪ Y_l(x+h, y) ∪ Y_l(x, y+h) ∪ Y_l(x+h, y+h),  h = 2^l
/// ```
///
/// with out-of-map fetches skipped. Only `(size-1) x (size-1)` dual cells
/// are complete; for simplicity every level stores `size x size` anchors, and
/// the anchors on the last row/column hold *partial* cells (their
/// out-of-map samples skipped). [`DualMssm::query_cells`] accepts anchors in
/// `[0, size)`, so on a 1x1 map the single partial cell is the one sample.
///
/// Storage: separate `min` and `max` planes (`Vec<f32>`, `size x size`,
/// row-major) for every level: `2 * levels * size^2 * 4` bytes.
#[derive(Clone, Debug)]
pub struct DualMssm {
    size: usize,
    levels: Vec<Planes>,
}

impl DualMssm {
    /// Builds levels `0..=max_level`, with `max_level` clamped to
    /// `floor(log2(size))`, rows in parallel (rayon). See the
    /// [module docs](self) for degenerate inputs.
    pub fn build(depth: &[f32], size: u32, max_level: u32) -> DualMssm {
        let (s, d) = sanitized_level0(depth, size);
        if s == 0 {
            return DualMssm {
                size: 0,
                levels: Vec::new(),
            };
        }
        let top = max_level.min(floor_log2(s));
        let mut levels = Vec::with_capacity(top as usize + 1);
        // Y_0 is one anchored step with h = 1 applied to the samples.
        let (min, max) = anchored_step(&d, &d, s, 1);
        drop(d);
        levels.push(Planes {
            min,
            max: Some(max),
        });
        for l in 0..top {
            let h = 1usize << l;
            let Some(prev) = levels.last() else { break };
            let (min, max) = anchored_step(prev.min(), prev.max(), s, h);
            levels.push(Planes {
                min,
                max: Some(max),
            });
        }
        DualMssm { size: s, levels }
    }

    /// Number of levels built (`min(max_level, floor(log2(size))) + 1`, or 0
    /// for `size == 0`).
    pub fn levels(&self) -> u32 {
        self.levels.len() as u32
    }

    /// Side length of the sample grid (0 if the map could not be built).
    pub fn size(&self) -> u32 {
        self.size as u32
    }

    /// The `(min, max)` planes of level `l` (`size x size` anchors,
    /// row-major). Empty slices if `l` is out of range.
    pub fn level(&self, l: u32) -> (&[f32], &[f32]) {
        match self.levels.get(l as usize) {
            Some(p) => (p.min(), p.max()),
            None => (&[], &[]),
        }
    }

    /// `Y_l(x, y)`: min/max over samples `[x, x+2^l] x [y, y+2^l]`
    /// (inclusive, clamped to the map). [`MinMax::EMPTY`] if `l`, `x` or `y`
    /// is out of range.
    pub fn fetch(&self, l: u32, x: u32, y: u32) -> MinMax {
        let (x, y) = (x as usize, y as usize);
        match self.levels.get(l as usize) {
            Some(p) if x < self.size && y < self.size => p.get(y * self.size + x),
            _ => MinMax::EMPTY,
        }
    }

    /// Clamped cell rectangle and its level / window size.
    fn plan(&self, cx0: i32, cy0: i32, cx1: i32, cy1: i32) -> Option<([usize; 4], usize, usize)> {
        let r = clamp_rect(self.size, cx0, cy0, cx1, cy1)?;
        if self.levels.is_empty() {
            return None;
        }
        let m = (r[2] - r[0]).min(r[3] - r[1]);
        let l = floor_log2(m).min(self.levels() - 1) as usize;
        Some((r, l, 1usize << l))
    }

    /// Exact min/max over all samples touched by the dual cells anchored in
    /// `[cx0, cx1) x [cy0, cy1)`: after clamping the anchors to
    /// `[0, size)`, that is the inclusive sample window
    /// `[cx0, cx1] x [cy0, cy1]` intersected with the map.
    /// [`MinMax::EMPTY`] if no anchor remains after clamping.
    ///
    /// Same tiling as [`Mssm::query`]: level
    /// `l = min(floor(log2(min(W, H))), levels - 1)` with anchors
    /// `cx0, cx0 + 2^l, ..., cx1 - 2^l` (likewise `y`).
    pub fn query_cells(&self, cx0: i32, cy0: i32, cx1: i32, cy1: i32) -> MinMax {
        let Some((r, l, h)) = self.plan(cx0, cy0, cx1, cy1) else {
            return MinMax::EMPTY;
        };
        let Some(p) = self.levels.get(l) else {
            return MinMax::EMPTY;
        };
        let xs = window_starts(r[0], r[2], h);
        let mut acc = MinMax::EMPTY;
        for y in window_starts(r[1], r[3], h) {
            let row = y * self.size;
            for x in xs.clone() {
                acc = acc.union(p.get(row + x));
            }
        }
        acc
    }

    /// Number of level fetches [`DualMssm::query_cells`] performs (0 if the
    /// cell rectangle is empty after clamping; saturates at `u32::MAX`).
    pub fn fetch_count(&self, cx0: i32, cy0: i32, cx1: i32, cy1: i32) -> u32 {
        let Some((r, _, h)) = self.plan(cx0, cy0, cx1, cy1) else {
            return 0;
        };
        let n = window_start_count(r[0], r[2], h).saturating_mul(window_start_count(r[1], r[3], h));
        u32::try_from(n).unwrap_or(u32::MAX)
    }

    /// Heap bytes used by the level planes.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(Planes::bytes).sum()
    }
}

/// Hierarchical min/max shadow map: a min/max mip chain (Dmitriev & Uralsky
/// 2007, *Soft shadows using hierarchical min-max shadow maps*).
///
/// Level 0 is the depth map (`N x N`, `N = size`). Level `l + 1` has
/// `ceil(N_l / 2)` texels per side, each the union of its 2x2 children at
/// level `l` (children beyond the border skipped):
///
/// ```text
/// P_0 = D
/// P_{l+1}(x, y) = P_l(2x, 2y) ∪ P_l(2x+1, 2y) ∪ P_l(2x, 2y+1) ∪ P_l(2x+1, 2y+1)
/// ```
///
/// so `P_l(x, y)` is the min/max over the level-0 block
/// `[x 2^l, (x+1) 2^l) x [y 2^l, (y+1) 2^l)` clamped to the map, and level
/// `l` has `N_l = ceil(N / 2^l)` texels per side. The chain ends at a single
/// texel: `1 + ceil(log2(N))` levels.
///
/// Storage: level 0 is stored once (min = max = depth); every other level
/// has separate `min` and `max` planes (`Vec<f32>`, `N_l x N_l`, row-major).
/// Memory is about `(1 + 2/3) * N^2 * 4` bytes.
///
/// Queries are *conservative*, not exact: see [`MinMaxPyramid::query`].
#[derive(Clone, Debug)]
pub struct MinMaxPyramid {
    size: usize,
    sizes: Vec<usize>,
    levels: Vec<Planes>,
}

impl MinMaxPyramid {
    /// Builds the whole chain down to 1x1, rows in parallel (rayon). See the
    /// [module docs](self) for degenerate inputs (`size == 0` gives no
    /// levels).
    pub fn build(depth: &[f32], size: u32) -> MinMaxPyramid {
        let (s, d) = sanitized_level0(depth, size);
        if s == 0 {
            return MinMaxPyramid {
                size: 0,
                sizes: Vec::new(),
                levels: Vec::new(),
            };
        }
        let mut sizes = vec![s];
        let mut levels = vec![Planes { min: d, max: None }];
        while let (Some(&sp), Some(prev)) = (sizes.last(), levels.last()) {
            if sp <= 1 {
                break;
            }
            let sd = sp.div_ceil(2);
            let (min, max) = Self::reduce(prev.min(), prev.max(), sp, sd);
            sizes.push(sd);
            levels.push(Planes {
                min,
                max: Some(max),
            });
        }
        MinMaxPyramid {
            size: s,
            sizes,
            levels,
        }
    }

    /// One 2x2 reduction from `sp x sp` to `sd x sd`, `sd = ceil(sp / 2)`.
    fn reduce(src_min: &[f32], src_max: &[f32], sp: usize, sd: usize) -> (Vec<f32>, Vec<f32>) {
        let mut out_min = vec![f32::INFINITY; sd * sd];
        let mut out_max = vec![f32::NEG_INFINITY; sd * sd];
        if sd == 0 || src_min.len() < sp * sp || src_max.len() < sp * sp {
            return (out_min, out_max);
        }
        out_min
            .par_chunks_mut(sd)
            .zip(out_max.par_chunks_mut(sd))
            .enumerate()
            .for_each(|(y, (omin, omax))| {
                for r in [2 * y, 2 * y + 1] {
                    if r >= sp {
                        continue;
                    }
                    let amin = &src_min[r * sp..(r + 1) * sp];
                    let amax = &src_max[r * sp..(r + 1) * sp];
                    for x in 0..sd {
                        let c0 = 2 * x;
                        let mut lo = amin[c0];
                        let mut hi = amax[c0];
                        if c0 + 1 < sp {
                            lo = lo.min(amin[c0 + 1]);
                            hi = hi.max(amax[c0 + 1]);
                        }
                        omin[x] = omin[x].min(lo);
                        omax[x] = omax[x].max(hi);
                    }
                }
            });
        (out_min, out_max)
    }

    /// Number of levels (`1 + ceil(log2(size))`, or 0 for `size == 0`).
    pub fn levels(&self) -> u32 {
        self.levels.len() as u32
    }

    /// Side length of level 0 (0 if the map could not be built).
    pub fn size(&self) -> u32 {
        self.size as u32
    }

    /// Texels per side of level `l` (`ceil(size / 2^l)`), 0 if `l` is out of
    /// range.
    pub fn level_size(&self, l: u32) -> u32 {
        self.sizes.get(l as usize).map_or(0, |&s| s as u32)
    }

    /// The `(min, max)` planes of level `l` (`level_size(l)^2` texels,
    /// row-major; for level 0 both are the depth map). Empty slices if `l`
    /// is out of range.
    pub fn level(&self, l: u32) -> (&[f32], &[f32]) {
        match self.levels.get(l as usize) {
            Some(p) => (p.min(), p.max()),
            None => (&[], &[]),
        }
    }

    /// `P_l(x, y)`: min/max over the level-0 block
    /// `[x 2^l, (x+1) 2^l) x [y 2^l, (y+1) 2^l)` (clamped).
    /// [`MinMax::EMPTY`] if `l`, `x` or `y` is out of range.
    pub fn fetch(&self, l: u32, x: u32, y: u32) -> MinMax {
        let (x, y) = (x as usize, y as usize);
        match (self.levels.get(l as usize), self.sizes.get(l as usize)) {
            (Some(p), Some(&s)) if x < s && y < s => p.get(y * s + x),
            _ => MinMax::EMPTY,
        }
    }

    /// Query plan: `(level, [tx0, ty0, tx1, ty1])` with the inclusive texel
    /// range of that level that [`MinMaxPyramid::query`] fetches.
    fn plan(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> Option<(usize, [usize; 4])> {
        let r = clamp_rect(self.size, x0, y0, x1, y1)?;
        let top = self.levels.len().checked_sub(1)?;
        let extent = (r[2] - r[0]).max(r[3] - r[1]);
        let l = (ceil_log2(extent) as usize).min(top);
        let t = [r[0] >> l, r[1] >> l, (r[2] - 1) >> l, (r[3] - 1) >> l];
        Some((l, t))
    }

    /// Conservative min/max over the half-open rectangle
    /// `[x0, x1) x [y0, y1)` (clamped; [`MinMax::EMPTY`] if empty after
    /// clamping): the result always satisfies `result.min <= true min` and
    /// `result.max >= true max`.
    ///
    /// Uses level `L = min(ceil(log2(max(W, H))), levels - 1)`. Its blocks
    /// are `2^L >= max(W, H)` texels wide (or the top level covers the whole
    /// map), so the rectangle overlaps at most 2x2 of them; the union of all
    /// overlapped blocks is returned. It equals the exact min/max over
    /// [`MinMaxPyramid::covered_rect`].
    pub fn query(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> MinMax {
        let Some((l, t)) = self.plan(x0, y0, x1, y1) else {
            return MinMax::EMPTY;
        };
        let (Some(p), Some(&s)) = (self.levels.get(l), self.sizes.get(l)) else {
            return MinMax::EMPTY;
        };
        let mut acc = MinMax::EMPTY;
        for ty in t[1]..=t[3] {
            for tx in t[0]..=t[2] {
                if tx < s && ty < s {
                    acc = acc.union(p.get(ty * s + tx));
                }
            }
        }
        acc
    }

    /// The half-open level-0 rectangle `(x0, y0, x1, y1)` actually covered
    /// by [`MinMaxPyramid::query`] (the union of the fetched blocks, clamped
    /// to the map), or `None` if the query rectangle is empty after
    /// clamping.
    pub fn covered_rect(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> Option<(u32, u32, u32, u32)> {
        let (l, t) = self.plan(x0, y0, x1, y1)?;
        let s = self.size as u64;
        let lo = |v: usize| ((v as u64) << l).min(s) as u32;
        let hi = |v: usize| (((v as u64) + 1) << l).min(s) as u32;
        Some((lo(t[0]), lo(t[1]), hi(t[2]), hi(t[3])))
    }

    /// How many level-0 texels [`MinMaxPyramid::query`] covered for this
    /// rectangle (area of [`MinMaxPyramid::covered_rect`], 0 if empty).
    pub fn covered_texels(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> u64 {
        self.covered_rect(x0, y0, x1, y1)
            .map_or(0, |(a, b, c, d)| u64::from(c - a) * u64::from(d - b))
    }

    /// Heap bytes used by the level planes.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(Planes::bytes).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    type Rect = (i32, i32, i32, i32);

    fn depth_value() -> impl Strategy<Value = f32> {
        prop_oneof![4 => 0.1f32..100.0f32, 1 => Just(f32::INFINITY)]
    }

    fn rect(s: u32) -> BoxedStrategy<Rect> {
        let s = s as i32;
        prop_oneof![
            // Arbitrary corners: partly/fully outside, inverted, zero-sized.
            6 => (-8..s + 8, -8..s + 8, -8..s + 8, -8..s + 8),
            // Non-empty and inside.
            4 => (0..s, 0..s, 1..=s, 1..=s).prop_map(|(x, y, w, h)| (x, y, x + w, y + h)),
            1 => Just((0, 0, s, s)),
            1 => Just((-3, -5, s + 7, s + 2)),
            // Zero width / zero height.
            1 => (-8..s + 8, -8..s + 8, 0..s + 8).prop_map(|(x, y, h)| (x, y, x, y + h)),
            1 => (-8..s + 8, -8..s + 8, 0..s + 8).prop_map(|(x, y, w)| (x, y, x + w, y)),
            1 => Just((i32::MIN, i32::MIN, i32::MAX, i32::MAX)),
        ]
        .boxed()
    }

    /// (size, depth, max_level, rectangles)
    fn case() -> impl Strategy<Value = (u32, Vec<f32>, u32, Vec<Rect>)> {
        (1u32..=70).prop_flat_map(|s| {
            (
                Just(s),
                prop::collection::vec(depth_value(), (s * s) as usize),
                0u32..=8,
                prop::collection::vec(rect(s), 1..12),
            )
        })
    }

    /// Clamp a dual-cell rectangle to anchors `[0, s)` and return the
    /// brute-force min/max over the samples it touches.
    fn brute_cells(depth: &[f32], s: u32, r: Rect) -> MinMax {
        let c = |v: i32| v.clamp(0, s as i32);
        let (x0, y0, x1, y1) = (c(r.0), c(r.1), c(r.2), c(r.3));
        if x0 >= x1 || y0 >= y1 {
            return MinMax::EMPTY;
        }
        brute_force(depth, s, x0, y0, x1 + 1, y1 + 1)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// (a) + (b)
        #[test]
        fn mssm_levels_and_queries_match_brute_force((s, depth, max_level, rects) in case()) {
            let m = Mssm::build(&depth, s, max_level);
            prop_assert_eq!(m.size(), s);
            prop_assert_eq!(m.levels(), max_level.min(floor_log2(s as usize)) + 1);
            for l in 0..m.levels() {
                let w = 1i32 << l;
                let (lmin, lmax) = m.level(l);
                prop_assert_eq!(lmin.len(), (s * s) as usize);
                prop_assert_eq!(lmax.len(), (s * s) as usize);
                for y in 0..s {
                    for x in 0..s {
                        let (xi, yi) = (x as i32, y as i32);
                        let want = brute_force(&depth, s, xi, yi, xi + w, yi + w);
                        let got = m.fetch(l, x, y);
                        prop_assert_eq!(got, want, "level {} texel ({}, {})", l, x, y);
                        let i = (y * s + x) as usize;
                        prop_assert_eq!(MinMax { min: lmin[i], max: lmax[i] }, want);
                    }
                }
            }
            for r in rects {
                let want = brute_force(&depth, s, r.0, r.1, r.2, r.3);
                prop_assert_eq!(m.query(r.0, r.1, r.2, r.3), want, "rect {:?}", r);
                if want.is_empty() {
                    prop_assert_eq!(m.fetch_count(r.0, r.1, r.2, r.3), 0);
                } else {
                    prop_assert!(m.fetch_count(r.0, r.1, r.2, r.3) >= 1);
                }
            }
        }

        /// (c)
        #[test]
        fn dual_mssm_matches_brute_force((s, depth, max_level, rects) in case()) {
            let m = DualMssm::build(&depth, s, max_level);
            prop_assert_eq!(m.levels(), max_level.min(floor_log2(s as usize)) + 1);
            for l in 0..m.levels() {
                let w = 1i32 << l;
                for y in 0..s {
                    for x in 0..s {
                        let (xi, yi) = (x as i32, y as i32);
                        // Inclusive sample window [x, x+2^l] x [y, y+2^l].
                        let want = brute_force(&depth, s, xi, yi, xi + w + 1, yi + w + 1);
                        prop_assert_eq!(m.fetch(l, x, y), want, "level {} anchor ({}, {})", l, x, y);
                    }
                }
            }
            for r in rects {
                let want = brute_cells(&depth, s, r);
                prop_assert_eq!(m.query_cells(r.0, r.1, r.2, r.3), want, "cells {:?}", r);
            }
        }

        /// (d)
        #[test]
        fn pyramid_levels_exact_and_query_conservative((s, depth, _ml, rects) in case()) {
            let p = MinMaxPyramid::build(&depth, s);
            prop_assert_eq!(p.levels(), 1 + ceil_log2(s as usize));
            prop_assert_eq!(p.level_size(p.levels() - 1), 1);
            for l in 0..p.levels() {
                let n = p.level_size(l);
                prop_assert_eq!(n, s.div_ceil(1 << l));
                prop_assert_eq!(p.level(l).0.len(), (n * n) as usize);
                let b = 1i32 << l;
                for y in 0..n as i32 {
                    for x in 0..n as i32 {
                        let want = brute_force(&depth, s, x * b, y * b, (x + 1) * b, (y + 1) * b);
                        prop_assert_eq!(p.fetch(l, x as u32, y as u32), want);
                    }
                }
            }
            for r in rects {
                let truth = brute_force(&depth, s, r.0, r.1, r.2, r.3);
                let got = p.query(r.0, r.1, r.2, r.3);
                prop_assert!(got.contains(&truth), "rect {:?}: {:?} vs {:?}", r, got, truth);
                match p.covered_rect(r.0, r.1, r.2, r.3) {
                    None => {
                        prop_assert!(truth.is_empty());
                        prop_assert_eq!(got, MinMax::EMPTY);
                        prop_assert_eq!(p.covered_texels(r.0, r.1, r.2, r.3), 0);
                    }
                    Some((a, b, c, d)) => {
                        let cov = brute_force(&depth, s, a as i32, b as i32, c as i32, d as i32);
                        prop_assert_eq!(got, cov);
                        let clamped = clamp_rect(s as usize, r.0, r.1, r.2, r.3).unwrap();
                        prop_assert!(a as usize <= clamped[0] && b as usize <= clamped[1]);
                        prop_assert!(c as usize >= clamped[2] && d as usize >= clamped[3]);
                        let (l, t) = p.plan(r.0, r.1, r.2, r.3).unwrap();
                        prop_assert!(t[2] - t[0] <= 1 && t[3] - t[1] <= 1, "level {} texels {:?}", l, t);
                        prop_assert_eq!(
                            p.covered_texels(r.0, r.1, r.2, r.3),
                            u64::from(c - a) * u64::from(d - b)
                        );
                    }
                }
            }
        }

        /// (e)
        #[test]
        fn mssm_square_query_fetch_counts(
            (s, depth, squares) in (1u32..=70).prop_flat_map(|s| (
                Just(s),
                prop::collection::vec(depth_value(), (s * s) as usize),
                prop::collection::vec((0u32..=6, 1u32..=70, 0u32..70, 0u32..70), 1..16),
            ))
        ) {
            let m = Mssm::build(&depth, s, u32::MAX);
            for (k, w, ox, oy) in squares {
                // Power-of-two square inside the map: exactly one fetch.
                let p = 1u32 << k;
                if p <= s {
                    let (x0, y0) = ((ox % (s - p + 1)) as i32, (oy % (s - p + 1)) as i32);
                    let p = p as i32;
                    prop_assert_eq!(m.fetch_count(x0, y0, x0 + p, y0 + p), 1);
                    prop_assert_eq!(
                        m.query(x0, y0, x0 + p, y0 + p),
                        brute_force(&depth, s, x0, y0, x0 + p, y0 + p)
                    );
                }
                // Any square inside the map: at most 4 fetches.
                let w = 1 + (w - 1) % s;
                let (x0, y0) = ((ox % (s - w + 1)) as i32, (oy % (s - w + 1)) as i32);
                let w = w as i32;
                let n = m.fetch_count(x0, y0, x0 + w, y0 + w);
                prop_assert!((1..=4).contains(&n), "square {} at ({}, {}): {} fetches", w, x0, y0, n);
                prop_assert_eq!(
                    m.query(x0, y0, x0 + w, y0 + w),
                    brute_force(&depth, s, x0, y0, x0 + w, y0 + w)
                );
            }
        }
    }

    #[test]
    fn minmax_basics() {
        let e = MinMax::EMPTY;
        assert!(e.is_empty());
        assert!(e.is_unoccupied());
        assert_eq!(MinMax::empty(), e);
        assert_eq!(MinMax::default(), e);
        let a = MinMax::from_depth(2.0);
        assert_eq!(e.union(a), a);
        assert_eq!(a.union(e), a);
        let inf = MinMax::from_depth(f32::INFINITY);
        assert_eq!(
            inf,
            MinMax {
                min: f32::INFINITY,
                max: f32::INFINITY
            }
        );
        assert!(!inf.is_empty());
        assert!(inf.is_unoccupied());
        assert_eq!(inf.union(inf), inf);
        assert_eq!(
            a.union(inf),
            MinMax {
                min: 2.0,
                max: f32::INFINITY
            }
        );
        assert_eq!(MinMax::from_depth(f32::NAN), inf);
        assert!(a.contains(&e));
    }

    #[test]
    fn all_empty_map_gives_inf_inf() {
        let s = 9u32;
        let d = vec![f32::INFINITY; 81];
        let inf = MinMax {
            min: f32::INFINITY,
            max: f32::INFINITY,
        };
        assert_eq!(brute_force(&d, s, 0, 0, 9, 9), inf);
        assert_eq!(Mssm::build(&d, s, 10).query(1, 2, 7, 5), inf);
        assert_eq!(DualMssm::build(&d, s, 10).query_cells(1, 2, 7, 5), inf);
        assert_eq!(MinMaxPyramid::build(&d, s).query(1, 2, 7, 5), inf);
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        // size 0
        let m = Mssm::build(&[], 0, 5);
        assert_eq!((m.levels(), m.size(), m.bytes()), (0, 0, 0));
        assert_eq!(m.query(0, 0, 10, 10), MinMax::EMPTY);
        assert_eq!(m.fetch_count(0, 0, 10, 10), 0);
        assert_eq!(m.fetch(0, 0, 0), MinMax::EMPTY);
        assert_eq!(m.level(0), (&[][..], &[][..]));
        let dm = DualMssm::build(&[], 0, 5);
        assert_eq!(dm.levels(), 0);
        assert_eq!(dm.query_cells(0, 0, 1, 1), MinMax::EMPTY);
        assert_eq!(dm.fetch_count(0, 0, 1, 1), 0);
        let p = MinMaxPyramid::build(&[], 0);
        assert_eq!((p.levels(), p.level_size(0)), (0, 0));
        assert_eq!(p.query(0, 0, 1, 1), MinMax::EMPTY);
        assert_eq!(p.covered_rect(0, 0, 1, 1), None);
        assert_eq!(brute_force(&[], 0, 0, 0, 1, 1), MinMax::EMPTY);

        // Length mismatch: missing texels are empty, extra ignored.
        let short = [1.0f32, 2.0, 3.0];
        let m = Mssm::build(&short, 2, 1);
        assert_eq!(m.fetch(0, 1, 1), MinMax::from_depth(f32::INFINITY));
        assert_eq!(
            m.query(0, 0, 2, 2),
            MinMax {
                min: 1.0,
                max: f32::INFINITY
            }
        );
        assert_eq!(brute_force(&short, 2, 0, 0, 2, 2), m.query(0, 0, 2, 2));
        let long = [1.0f32, 2.0, 3.0, 4.0, -100.0];
        let m = Mssm::build(&long, 2, 1);
        assert_eq!(m.query(0, 0, 2, 2), MinMax { min: 1.0, max: 4.0 });
        assert_eq!(
            MinMaxPyramid::build(&long, 2).query(0, 0, 2, 2),
            MinMax { min: 1.0, max: 4.0 }
        );
        assert_eq!(
            DualMssm::build(&long, 2, 3).query_cells(0, 0, 1, 1),
            MinMax { min: 1.0, max: 4.0 }
        );

        // Unaddressable size: empty structure instead of a panic.
        if usize::BITS == 64 {
            let m = Mssm::build(&short, u32::MAX, 3);
            assert_eq!(m.size(), 0);
            assert_eq!(m.query(0, 0, 5, 5), MinMax::EMPTY);
        }

        // Out-of-range fetches / levels.
        let d: Vec<f32> = (0..16).map(|i| i as f32).collect();
        let m = Mssm::build(&d, 4, 99);
        assert_eq!(m.levels(), 3);
        assert_eq!(m.fetch(3, 0, 0), MinMax::EMPTY);
        assert_eq!(m.fetch(0, 4, 0), MinMax::EMPTY);
        assert_eq!(
            m.fetch(2, 0, 0),
            MinMax {
                min: 0.0,
                max: 15.0
            }
        );
        assert_eq!(
            m.query(i32::MIN, i32::MIN, i32::MAX, i32::MAX),
            MinMax {
                min: 0.0,
                max: 15.0
            }
        );
        assert_eq!(m.query(3, 3, 1, 1), MinMax::EMPTY);
        assert_eq!(m.query(-5, -5, 0, 0), MinMax::EMPTY);
        assert_eq!(m.query(4, 0, 9, 4), MinMax::EMPTY);
        let p = MinMaxPyramid::build(&d, 4);
        assert_eq!(p.fetch(0, 4, 0), MinMax::EMPTY);
        assert_eq!(p.fetch(1, 2, 0), MinMax::EMPTY);
        assert_eq!(p.level_size(9), 0);
        let dm = DualMssm::build(&d, 4, 99);
        assert_eq!(dm.fetch(9, 0, 0), MinMax::EMPTY);
        assert_eq!(dm.fetch(0, 3, 3), MinMax::from_depth(15.0));
    }

    #[test]
    fn memory_accounting() {
        let s = 16u32;
        let d = vec![1.0f32; 256];
        let m = Mssm::build(&d, s, 4);
        assert_eq!(m.levels(), 5);
        assert_eq!(m.bytes(), (2 * 5 - 1) * 256 * 4);
        let dm = DualMssm::build(&d, s, 4);
        assert_eq!(dm.bytes(), 2 * 5 * 256 * 4);
        let p = MinMaxPyramid::build(&d, s);
        assert_eq!(p.bytes(), (256 + 2 * (64 + 16 + 4 + 1)) * 4);
    }

    #[test]
    fn single_texel_map() {
        let d = [3.5f32];
        let one = MinMax::from_depth(3.5);
        let m = Mssm::build(&d, 1, 4);
        assert_eq!(m.levels(), 1);
        assert_eq!(m.query(-1, -1, 2, 2), one);
        assert_eq!(m.fetch_count(-1, -1, 2, 2), 1);
        let dm = DualMssm::build(&d, 1, 4);
        assert_eq!(dm.query_cells(0, 0, 1, 1), one);
        let p = MinMaxPyramid::build(&d, 1);
        assert_eq!(p.levels(), 1);
        assert_eq!(p.query(0, 0, 1, 1), one);
        assert_eq!(p.covered_texels(0, 0, 5, 5), 1);
    }
}
