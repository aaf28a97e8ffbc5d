//! [`DualMssm`]: the MSSM on the dual grid of depth samples (Yang et al. 2009, §4.2).
use super::{anchored_step, Anchored, MinMax, Planes};

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
pub struct DualMssm(Anchored);

impl DualMssm {
    /// Builds levels `0..=max_level`, with `max_level` clamped to
    /// `floor(log2(size))`, rows in parallel (rayon). See the
    /// [module docs](super) for degenerate inputs.
    pub fn build(depth: &[f32], size: u32, max_level: u32) -> DualMssm {
        DualMssm(Anchored::build(depth, size, max_level, |d, s| {
            // Y_0 is one anchored step with h = 1 applied to the samples.
            let (min, max) = anchored_step(&d, &d, s, 1);
            Planes {
                min,
                max: Some(max),
            }
        }))
    }

    anchored_accessors! {
        grid: "sample grid",
        level: "The `(min, max)` planes of level `l` (`size x size` anchors, row-major). Empty \
            slices if `l` is out of range.",
        fetch: "`Y_l(x, y)`: min/max over samples `[x, x+2^l] x [y, y+2^l]` (inclusive, clamped to \
            the map). [`MinMax::EMPTY`] if `l`, `x` or `y` is out of range.",
    }

    /// Exact min/max over all samples touched by the dual cells anchored in
    /// `[cx0, cx1) x [cy0, cy1)`: after clamping the anchors to
    /// `[0, size)`, that is the inclusive sample window
    /// `[cx0, cx1] x [cy0, cy1]` intersected with the map.
    /// [`MinMax::EMPTY`] if no anchor remains after clamping.
    ///
    /// Same tiling as [`Mssm::query`](super::Mssm::query): level
    /// `l = min(floor(log2(min(W, H))), levels - 1)` with anchors
    /// `cx0, cx0 + 2^l, ..., cx1 - 2^l` (likewise `y`).
    pub fn query_cells(&self, cx0: i32, cy0: i32, cx1: i32, cy1: i32) -> MinMax {
        self.0.query(cx0, cy0, cx1, cy1)
    }

    /// Number of level fetches [`DualMssm::query_cells`] performs (0 if the
    /// cell rectangle is empty after clamping; saturates at `u32::MAX`).
    pub fn fetch_count(&self, cx0: i32, cy0: i32, cx1: i32, cy1: i32) -> u32 {
        self.0.fetch_count(cx0, cy0, cx1, cy1)
    }
}
