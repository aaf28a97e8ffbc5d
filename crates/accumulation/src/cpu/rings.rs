//! The adaptive kernel's cells: the [`Kernel`] a receiver reads and the multi-resolution rings
//! ([`for_each_ring_cell`]) aligned to the light-view lattice ([`ring_phase`]).
use shadow_map_core::light_view::{FitMode, LightView};

/// A receiver's kernel: the cells whose centre texels are read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    /// `step x step` blocks tiling `rect` (`[x0, y0, x1, y1)`, the last ones clipped).
    Uniform {
        /// The texel rectangle.
        rect: [i32; 4],
        /// Block side in texels.
        step: u32,
    },
    /// Multi-resolution rings ([`for_each_ring_cell`]) around `centre`, clipped to `bound`.
    Rings {
        /// The texel rectangle the cells are clipped to.
        bound: [i32; 4],
        /// The texel corner nearest the receiver's projection.
        centre: [i32; 2],
        /// Ring width in cells.
        m: i32,
        /// Lattice index of texel 0 the cells align to ([`ring_phase`]).
        phase: [i32; 2],
    },
}

/// Ring width of the adaptive kernel for kernel size K: `ceil(K / 4)` cells, so each level's
/// square is about K cells wide.
pub fn ring_width(k: u32) -> i32 {
    k.div_ceil(4).max(1) as i32
}

/// Lattice index of the map's texel 0 (modulo 2^20), where the adaptive kernel's cells of side
/// `2^l` align: `round(x0 / delta)` per axis under `fit=stable`, whose window corner is a whole
/// number of texels on a fixed lattice, so a receiver's cells, and its V, do not change when the
/// camera pans and the corner moves by an odd number of texels; `[0, 0]` (cells aligned to the
/// map) otherwise. Cells never reach 2^20 texels (r <= 16384), so the modulus changes nothing.
pub fn ring_phase(view: &LightView, fit: FitMode) -> [i32; 2] {
    if fit != FitMode::Stable {
        return [0, 0];
    }
    let delta = view.w as f64 / view.r as f64;
    let k = |x0: f32| {
        let k = (x0 as f64 / delta).round();
        if k.is_finite() {
            (k.rem_euclid((1u32 << 20) as f64)) as i32
        } else {
            0
        }
    };
    [k(view.window_min.x), k(view.window_min.y)]
}

fn floor_to(x: i32, a: i32) -> i32 {
    x.div_euclid(a) * a
}

fn ceil_to(x: i32, a: i32) -> i32 {
    -((-x).div_euclid(a) * a)
}

/// The adaptive kernel's cells: level 0 is single texels in `[c - m, c + m)^2`; level l has cells
/// of side `s = 2^l` aligned to multiples of s (in lattice indices: texel i is `i + phase`,
/// [`ring_phase`]), filling the ring between the previous level's
/// square (extended to multiples of s) and that square grown by `m s` on every side; levels stop
/// once a square covers `bound`. The cells tile the square exactly (no overlap, no gap), fine near
/// the receiver's projection, where a caster close to the receiver is magnified most (its image
/// scale `size` grows as `1 / (z_p - c_z)`), and coarse further out, where only casters near the
/// light (small `size`) can reach the footprint. Every cell is clipped to `bound`. `f` returns
/// true to stop.
pub fn for_each_ring_cell(
    bound: [i32; 4],
    c: [i32; 2],
    m: i32,
    phase: [i32; 2],
    mut f: impl FnMut(i32, i32, i32, i32) -> bool,
) {
    // In lattice indices; the cells are handed back in map indices.
    let [px, py] = phase;
    let bound = [bound[0] + px, bound[1] + py, bound[2] + px, bound[3] + py];
    let c = [c[0] + px, c[1] + py];
    let mut f = |i0: i32, i1: i32, j0: i32, j1: i32| f(i0 - px, i1 - px, j0 - py, j1 - py);
    let covers =
        |r: &[i32; 4]| r[0] <= bound[0] && r[1] <= bound[1] && r[2] >= bound[2] && r[3] >= bound[3];
    let mut raw = [c[0] - m, c[1] - m, c[0] + m, c[1] + m];
    let mut inner = [c[0], c[1], c[0], c[1]];
    let mut s = 1i32;
    for _ in 0..32 {
        let last = covers(&raw);
        let a = if last { s } else { 2 * s };
        let outer = [
            floor_to(raw[0], a),
            floor_to(raw[1], a),
            ceil_to(raw[2], a),
            ceil_to(raw[3], a),
        ];
        let (x0, x1) = (outer[0].max(floor_to(bound[0], s)), outer[2].min(bound[2]));
        let (y0, y1) = (outer[1].max(floor_to(bound[1], s)), outer[3].min(bound[3]));
        let mut y = y0;
        while y < y1 {
            let mut x = x0;
            while x < x1 {
                let in_inner =
                    x >= inner[0] && x + s <= inner[2] && y >= inner[1] && y + s <= inner[3];
                if !in_inner {
                    let (i0, i1) = (x.max(bound[0]), (x + s).min(bound[2]));
                    let (j0, j1) = (y.max(bound[1]), (y + s).min(bound[3]));
                    if i0 < i1 && j0 < j1 && f(i0, i1, j0, j1) {
                        return;
                    }
                }
                x += s;
            }
            y += s;
        }
        if last || covers(&outer) {
            return;
        }
        inner = outer;
        s *= 2;
        raw = [
            outer[0] - m * s,
            outer[1] - m * s,
            outer[2] + m * s,
            outer[3] + m * s,
        ];
    }
}
