//! [`Anchored`]: the levels [`Mssm`](super::Mssm) and [`DualMssm`](super::DualMssm) share, every
//! one full resolution with windows anchored at their top-left texel, and the queries that
//! tile a rectangle with them.
use super::{
    anchored_step, clamp_rect, floor_log2, sanitized_level0, window_start_count, window_starts,
    MinMax, Planes,
};

/// `size x size` planes per level; level `l + 1` is one anchored step of level `l` with the
/// window doubling (`h = 2^l`). Only level 0 differs between the two structures.
#[derive(Clone, Debug)]
pub(super) struct Anchored {
    size: usize,
    levels: Vec<Planes>,
}

impl Anchored {
    /// Levels `0..=min(max_level, floor(log2(size)))` over the sanitised `depth`, level 0 made
    /// by `level0` from the samples and the side; no levels when the map is empty.
    pub(super) fn build(
        depth: &[f32],
        size: u32,
        max_level: u32,
        level0: impl FnOnce(Vec<f32>, usize) -> Planes,
    ) -> Anchored {
        let (s, d) = sanitized_level0(depth, size);
        if s == 0 {
            return Anchored {
                size: 0,
                levels: Vec::new(),
            };
        }
        let top = max_level.min(floor_log2(s));
        let mut levels = Vec::with_capacity(top as usize + 1);
        levels.push(level0(d, s));
        for l in 0..top {
            let h = 1usize << l;
            let Some(prev) = levels.last() else { break };
            let (min, max) = anchored_step(prev.min(), prev.max(), s, h);
            levels.push(Planes {
                min,
                max: Some(max),
            });
        }
        Anchored { size: s, levels }
    }

    /// Number of levels built.
    pub(super) fn levels(&self) -> u32 {
        self.levels.len() as u32
    }

    /// Side length (0 if the map could not be built).
    pub(super) fn size(&self) -> u32 {
        self.size as u32
    }

    /// Level `l` as `(min, max)` planes; empty slices when out of range.
    pub(super) fn level(&self, l: u32) -> (&[f32], &[f32]) {
        match self.levels.get(l as usize) {
            Some(p) => (p.min(), p.max()),
            None => (&[], &[]),
        }
    }

    /// Anchor `(x, y)` of level `l`; [`MinMax::EMPTY`] when out of range.
    pub(super) fn fetch(&self, l: u32, x: u32, y: u32) -> MinMax {
        let (x, y) = (x as usize, y as usize);
        match self.levels.get(l as usize) {
            Some(p) if x < self.size && y < self.size => p.get(y * self.size + x),
            _ => MinMax::EMPTY,
        }
    }

    /// The anchors `[x0, x1) x [y0, y1)` clamped to the map, the level
    /// `l = min(floor(log2(min(W, H))), levels - 1)` that tiles them and its window `h = 2^l`;
    /// `None` when no anchor remains or no level was built.
    fn plan(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> Option<([usize; 4], usize, usize)> {
        let r = clamp_rect(self.size, x0, y0, x1, y1)?;
        if self.levels.is_empty() {
            return None;
        }
        let m = (r[2] - r[0]).min(r[3] - r[1]);
        let l = floor_log2(m).min(self.levels() - 1) as usize;
        Some((r, l, 1usize << l))
    }

    /// The union of the level-`l` windows anchored at `x0, x0 + h, ..., x1 - h` times
    /// `y0, y0 + h, ..., y1 - h` (see [`Anchored::plan`]); [`MinMax::EMPTY`] without anchors.
    pub(super) fn query(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> MinMax {
        let Some((r, l, h)) = self.plan(x0, y0, x1, y1) else {
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

    /// Number of windows [`Anchored::query`] unions (saturates at `u32::MAX`).
    pub(super) fn fetch_count(&self, x0: i32, y0: i32, x1: i32, y1: i32) -> u32 {
        let Some((r, _, h)) = self.plan(x0, y0, x1, y1) else {
            return 0;
        };
        let n = window_start_count(r[0], r[2], h).saturating_mul(window_start_count(r[1], r[3], h));
        u32::try_from(n).unwrap_or(u32::MAX)
    }

    /// Heap bytes used by the level planes.
    pub(super) fn bytes(&self) -> usize {
        self.levels.iter().map(Planes::bytes).sum()
    }
}
