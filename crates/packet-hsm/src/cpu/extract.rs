//! The contour extraction of a kernel over the padded dual-grid MSSM (Yang et al. 2009 §4.2,
//! Algorithm 3, or every 2x2 block: GBP07) and the per-pixel GBP07 built on it; the geometry of
//! a cell's contour and its radial integration are [`crate::math::contour`] and
//! [`crate::math::radial`].
use super::fit::DualFit;
use crate::math::contour::{
    cell_edges, plane_inner_range, plane_threshold_range, status, true_min, CellRect, Edge,
    OccluderTest, Receiver, SampleGrid, Status, CORNERS,
};
use crate::math::radial::{edge_area, visibility_from_area, Emitter, Scale};
use shadow_map_core::mssm::{DualMssm, Mssm};

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
