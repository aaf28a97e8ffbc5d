//! [`MinMaxPyramid`]: the hierarchical min/max mip chain (Dmitriev & Uralsky 2007).
use super::{ceil_log2, clamp_rect, sanitized_level0, MinMax, Planes};
use rayon::prelude::*;

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
    /// [module docs](super) for degenerate inputs (`size == 0` gives no
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
    pub(super) fn plan(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> Option<(usize, [usize; 4])> {
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
