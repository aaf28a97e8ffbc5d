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

/// The kernel: its (search-area) width in texels along one axis (docs/methods.md §2 "Search area"; Bavoil
/// §2 `w_0`, Yang eq. 1):
///
/// `W = alpha * l * (1/z_m - 1/z_p)`, `alpha = n r / w`,
///
/// where `l` is the light's extent on that axis, `z_m` a lower bound of the occluder depths and
/// `z_p` the receiver depth. With `z_m = n` this is Bavoil's `w_0`. Returns 0 when `z_m >= z_p`
/// (nothing between), and never NaN: non-positive `z_m` is treated as the smallest positive
/// float (the kernel then saturates at `f32::MAX`).
/// The WGSL twin is `kernel_width` in `gpu/math.wgsl`; backprojection and packet-hsm both use
/// this one.
#[inline]
pub fn kernel_width(alpha: f32, l: f32, z_m: f32, z_p: f32) -> f32 {
    if !(z_m < z_p) {
        return 0.0;
    }
    let zm = z_m.max(f32::MIN_POSITIVE);
    let w = alpha * l * (1.0 / zm - 1.0 / z_p);
    if w.is_finite() {
        w.max(0.0)
    } else {
        f32::MAX
    }
}

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

/// The accessors [`Mssm`] and [`DualMssm`] share, on their [`Anchored`] levels (field `0`):
/// `grid` names what `size` counts the side of, `level` and `fetch` document those two.
macro_rules! anchored_accessors {
    (grid: $grid:literal, level: $level:literal, fetch: $fetch:literal $(,)?) => {
        /// Number of levels built (`min(max_level, floor(log2(size))) + 1`, or 0
        /// for `size == 0`).
        pub fn levels(&self) -> u32 {
            self.0.levels()
        }

        #[doc = concat!("Side length of the ", $grid, " (0 if the map could not be built).")]
        pub fn size(&self) -> u32 {
            self.0.size()
        }

        #[doc = $level]
        pub fn level(&self, l: u32) -> (&[f32], &[f32]) {
            self.0.level(l)
        }

        #[doc = $fetch]
        pub fn fetch(&self, l: u32, x: u32, y: u32) -> MinMax {
            self.0.fetch(l, x, y)
        }

        /// Heap bytes used by the level planes.
        pub fn bytes(&self) -> usize {
            self.0.bytes()
        }
    };
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
pub struct Mssm(Anchored);

impl Mssm {
    /// Builds levels `0..=max_level`, with `max_level` clamped to
    /// `floor(log2(size))`. Rows of each level are computed in parallel
    /// (rayon). See the [module docs](self) for length mismatches, `NaN`s
    /// and `size == 0` (no levels).
    pub fn build(depth: &[f32], size: u32, max_level: u32) -> Mssm {
        Mssm(Anchored::build(depth, size, max_level, |d, _| Planes {
            min: d,
            max: None,
        }))
    }

    anchored_accessors! {
        grid: "map",
        level: "The `(min, max)` planes of level `l`, each `size x size` row-major (for level 0 both \
            slices are the depth map). Empty slices if `l` is out of range.",
        fetch: "`M_l(x, y)`: min/max over `[x, x+2^l) x [y, y+2^l)` clamped to the map. \
            [`MinMax::EMPTY`] if `l`, `x` or `y` is out of range.",
    }

    /// Exact min/max over the half-open rectangle `[x0, x1) x [y0, y1)`,
    /// clamped to the map; [`MinMax::EMPTY`] if empty after clamping.
    ///
    /// Uses level `l = min(floor(log2(min(W, H))), levels - 1)`, `h = 2^l`,
    /// and unions the windows anchored at `x0, x0 + h, ..., x1 - h` times
    /// `y0, y0 + h, ..., y1 - h` (the last window of each axis always starts
    /// at `x1 - h`, so the tiling is exact). See [`Mssm::fetch_count`].
    pub fn query(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> MinMax {
        self.0.query(x0, y0, x1, y1)
    }

    /// Number of level fetches [`Mssm::query`] performs for this rectangle
    /// (0 if it is empty after clamping; saturates at `u32::MAX`).
    pub fn fetch_count(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> u32 {
        self.0.fetch_count(x0, y0, x1, y1)
    }
}

/// Most rounds of [`refine_kernel`].
pub const REFINE_ROUNDS: u32 = 16;

/// A blocker-search kernel refined with the MSSM (Bavoil et al. 2008 §5, Yang et al. 2009 §3:
/// the kernel's extent follows from the nearest caster depth it may hold). Starting from
/// `kernel(z_near)`, the minimum depth `zmin` over the kernel's texels bounds how near a caster
/// can be, so the kernel shrinks to `kernel(zmin)` while that shrinks its area, at most
/// [`REFINE_ROUNDS`] rounds. `None` when no texel of the kernel can occlude (`zmin >=
/// bound(kernel)`, `bound` a conservative caster-depth threshold: the receiver is lit); without
/// an MSSM, `kernel(z_near)` unless `bound` rules it out.
pub fn refine_kernel(
    mssm: Option<&Mssm>,
    z_near: f32,
    kernel: impl Fn(f32) -> [i32; 4],
    bound: impl Fn(&[i32; 4]) -> f32,
) -> Option<[i32; 4]> {
    let area = |r: &[i32; 4]| (r[2] - r[0]) as i64 * (r[3] - r[1]) as i64;
    let mut zm = z_near;
    let mut rect = kernel(zm);
    for _ in 0..REFINE_ROUNDS {
        let zmin = match mssm {
            Some(m) => m.query(rect[0], rect[1], rect[2], rect[3]).min,
            None => f32::NEG_INFINITY,
        };
        if zmin >= bound(&rect) {
            return None;
        }
        // `!(a > b)`: a NaN minimum stops the refinement, as an equal one does.
        if !(zmin > zm) {
            break;
        }
        zm = zmin;
        let next = kernel(zm);
        if area(&next) >= area(&rect) {
            break;
        }
        rect = next;
    }
    Some(rect)
}

mod anchored;
mod dual;
mod pyramid;
#[cfg(test)]
mod tests;

use anchored::Anchored;
pub use dual::DualMssm;
pub use pyramid::MinMaxPyramid;
